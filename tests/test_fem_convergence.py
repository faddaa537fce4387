"""Mesh convergence of the first longitudinal mode of a Langevin sandwich (steel / 4 PZT-8
rings poled +z/-z with interleaved electrodes / Al 7075), one refinement step (cross-section
4x4 -> 6x6 squares, axial size 5 mm -> 3.3 mm, P2): f_r and f_a change by < 0.5 %
(measured ~0.01 %). The default-design study is in benchmarks/bench_fem.py and the README."""

import numpy as np
import pytest

from fem.assembly import assemble
from fem.modal import modal_analysis
from test_fem_util import sandwich


def _first_longitudinal(n_r, dz):
    s = assemble(sandwich(n_r=n_r, dz=dz))
    res = modal_analysis(s, 22e3, 4)
    i = int(np.argmax(res.shares[:, 0]))
    assert res.shares[i, 0] > 0.9
    return res.f_r_hz[i], res.f_a_hz[i], res.k_eff[i]


def test_sandwich_longitudinal_mode_converges():
    coarse = _first_longitudinal(2, 0.005)
    fine = _first_longitudinal(3, 0.0033)
    assert fine[0] == pytest.approx(coarse[0], rel=0.005)
    assert fine[1] == pytest.approx(coarse[1], rel=0.005)
    assert 0.3 < fine[2] < 0.5          # a stack of PZT-8 rings: k_eff well below k33 = 0.7

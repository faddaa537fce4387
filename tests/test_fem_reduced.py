"""Reduced transducer (fem.reduced) against the direct harmonic solution.

Model: the free four-layer PZT-8 stack of tests/test_fem_harmonic.py (tip: the top electrode).
References: the direct complex solve (``working_point`` without a basis) for the steady tip
response and the admittance; the modal basis for the selection rule.
"""

import numpy as np
import pytest

from rpud_common import ParameterError
from fem.assembly import assemble
from fem.harmonic import LossModel, modal_basis, working_point
from fem.modal import modal_analysis
from fem.reduced import ReducedTransducer, reduce_transducer

from test_fem_harmonic import TIP, _stack


@pytest.fixture(scope="module")
def system():
    return assemble(_stack())


@pytest.fixture(scope="module")
def setup(system):
    modes = modal_analysis(system, 70e3, 8, open_circuit=False)
    f_r = float(modes.f_r_hz[int(np.argmax(modes.shares[:, 0]))])
    loss = LossModel(100.0, 0.004)
    basis = modal_basis(system, f_r, 8, loss=loss, modes=modes)
    return modes, f_r, loss, basis


@pytest.mark.parametrize("ratio", [0.995, 1.0, 1.01])
@pytest.mark.parametrize("n_modes", [None, 1, 3])
def test_steady_tip_and_charge_equal_the_direct_working_point(system, setup, ratio, n_modes):
    """Kept modes (viscous damping equivalent at the drive) + residual = direct solution:
    amplitude and phase within 0.5 %, for any number of kept modes."""
    _, f_r, loss, basis = setup
    f = ratio * f_r
    red = reduce_transducer(system, basis, f, tip_surface=TIP[0], n_modes=n_modes)
    direct = working_point(system, f, 3.0, loss=loss, surfaces=TIP)
    ref = direct.surfaces[TIP[0]]["axial"]
    got = red.tip_phasor(3.0)
    assert abs(got) == pytest.approx(abs(ref), rel=5e-3)
    assert abs(np.angle(got / ref)) <= 5e-3
    # admittance from the modal charges + blocked charge
    W = 2 * np.pi * f
    q = red.modal_amplitudes(3.0)
    Y = 1j * W * (red.coupling @ q + red.blocked_charge * 3.0) / 3.0
    assert abs(Y - direct.admittance) <= 5e-3 * abs(direct.admittance)


def test_selection_rule_and_plain_data(system, setup):
    _, f_r, _, basis = setup
    red = reduce_transducer(system, basis, f_r, tip_surface=TIP[0])
    s2 = red.tip ** 2
    assert np.all(s2 >= 0.01 * s2[red.working] * (1 - 1e-12))
    # every basis mode left out has a smaller tip participation than the rule's threshold
    from fem.harmonic import surface_functional
    a = np.asarray(surface_functional(system, TIP[0]).rows[0][:, basis.free].toarray()).ravel()
    s_all = basis.Phi.T @ a
    out = np.setdiff1d(np.arange(len(basis.lam)), red.mode_index)
    assert np.all(s_all[out] ** 2 < 0.01 * s2[red.working])
    # the working mode is the longitudinal resonance driven here
    assert red.omega[red.working] == pytest.approx(2 * np.pi * f_r, rel=1e-12)
    assert np.all(red.modal_mass == 1.0)
    np.testing.assert_allclose(red.stiffness, red.omega ** 2, rtol=1e-14)
    # plain data: a dict of lists and numbers, and back
    d = red.to_dict()
    assert all(isinstance(v, (list, int, float, str)) for v in d.values())
    back = ReducedTransducer.from_dict(d)
    assert back.tip_phasor(2.0) == red.tip_phasor(2.0)
    assert back.mode_index.dtype.kind == "i"


def test_bad_input(system, setup):
    _, f_r, _, basis = setup
    with pytest.raises(ParameterError, match="n_modes = 0"):
        reduce_transducer(system, basis, f_r, tip_surface=TIP[0], n_modes=0)
    with pytest.raises(ParameterError, match="n_modes = 99"):
        reduce_transducer(system, basis, f_r, tip_surface=TIP[0], n_modes=99)
    with pytest.raises(ParameterError, match="freq"):
        reduce_transducer(system, basis, -1.0, tip_surface=TIP[0])
    with pytest.raises(ParameterError, match="tip_share"):
        reduce_transducer(system, basis, f_r, tip_surface=TIP[0], tip_share=2.0)

"""The static tip compliance of the modes left out (results.coupled.static_residual) against the
modal sum of a dense generalised eigenproblem solved directly (numpy's eigh)."""

import numpy as np
import pytest
import scipy.sparse as sp

from results.coupled import static_residual
from rpud_common import ParameterError


def _pencil(n=60, seed=3):
    """A stiffness with one zero (rigid) mode, a positive mass, and their eigenpairs."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    K = A @ A.T / n
    r = rng.normal(size=n)
    K -= np.outer(K @ r, K @ r) / (r @ K @ r)          # K r = 0: a rigid mode
    K = (K + K.T) / 2
    M = np.diag(rng.uniform(0.5, 2.0, n))
    # eigenpairs of K x = lam M x, M-orthonormal
    Mh = np.diag(1 / np.sqrt(np.diag(M)))
    lam, V = np.linalg.eigh(Mh @ K @ Mh)
    return K, M, np.maximum(lam, 0.0), Mh @ V


@pytest.mark.parametrize("where", [-0.01, 0.02, 0.15, 0.4])
def test_series_is_the_modal_sum_of_the_modes_left_out(where):
    """g = sum over the modes above the cut of s_i^2 / lambda_i (the exact modal sum of the dense
    eigendecomposition) from solves at a shift ``sigma = where x lambda_cut``, negative or positive,
    deflated of the modes kept (the rigid one among them). The series stops at 1e-13 of its sum;
    the reference carries eigh's round-off ~1e-13 per term: tested at 1e-10."""
    K, M, lam, V = _pencil()
    a = np.random.default_rng(7).normal(size=len(lam))
    cut = 10
    lam_cut = 0.5 * (lam[cut - 1] + lam[cut])
    s = V.T @ a
    exact = float(np.sum(s[cut:] ** 2 / lam[cut:]))
    sigma = where * lam_cut
    Kf = np.linalg.inv(K - sigma * M)
    g = static_residual((lambda v: Kf @ v, sigma), sp.csr_matrix(M), a, (V[:, :cut], lam[:cut]), lam_cut=lam_cut)
    assert g == pytest.approx(exact, rel=1e-10)


def test_a_shift_at_half_the_cutoff_is_refused():
    """The series falls as sigma / (lambda - sigma) of the lowest mode left out: at sigma >= lambda_cut / 2
    it need not converge, and the call refuses the shift, naming it."""
    K, M, lam, V = _pencil()
    lam_cut = 0.5 * (lam[9] + lam[10])
    with pytest.raises(ParameterError, match="factor"):
        static_residual((lambda v: v, 0.5 * lam_cut), sp.csr_matrix(M), np.ones(len(lam)), (V[:, :10], lam[:10]),
                        lam_cut=lam_cut)

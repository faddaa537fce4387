"""fem.forms: each weak form against its closed-form value on fields the elements hold exactly.

Reference: a linear displacement ``u = G x`` has the uniform strain ``S = sym(G)`` and a linear
potential ``phi = g . x`` the uniform field ``-g``; P1 and P2 tetrahedra represent both exactly
(nodal interpolation of a linear function is the function), so on a box of volume ``V`` the
forms' values are the closed forms ``V S^T c S``, ``V S^T e^T g``, ``V g^T eps g`` and, for the
mass of ``u = (x, 0, 0)``, ``rho b c a^3 / 3``. Every integrand is then a polynomial of degree
<= 2 on affine cells, which the quadrature orders used (>= 2) integrate exactly. What is left is
floating-point round-off: a sum of about 10^4 products each rounded at 1.1e-16 relative, whose
bound grows like the number of terms times eps, ~1e-12 relative to the largest contribution:
that is the tolerance. A rigid rotation carries no strain, so its stiffness force must vanish
to the same round-off relative to the stiffness scale.

The fast assembly (:mod:`fem.fastasm`) equals these forms assembled by ``skfem.asm`` to round-off
(``tests/test_fem_assembly.py::test_fast_assembly_equals_plain_skfem``, which assembles through
``reference=True``, the path built on these forms)."""

import numpy as np
import pytest
from skfem import Basis, ElementTetP1, ElementTetP2, ElementVector, MeshTet, asm

from fem.forms import coupling, mass, permittivity, stiffness, voigt_strain
from fem.materials import piezo_matrices

A, B, C = 0.02, 0.004, 0.003          # box edges, m
V = A * B * C
RTOL = 1e-12                          # round-off of ~1e4 terms (module docstring)
PC = piezo_matrices("PZT-4", (0.3, -0.2, 0.93))   # a tilted poling: every tensor entry in play


@pytest.fixture(params=[ElementTetP1, ElementTetP2], ids=["P1", "P2"])
def bases(request):
    m = MeshTet.init_tensor(np.linspace(0, A, 5), np.linspace(0, B, 3), np.linspace(0, C, 3))
    e = request.param()
    return Basis(m, ElementVector(e), intorder=4), Basis(m, e, intorder=4)


def _vector(basis, G):
    """DOFs of ``u = G x`` (nodal interpolation: exact for a linear field)."""
    return basis.project(lambda x: np.einsum("ij,j...->i...", G, x))


def _voigt(G):
    S = (G + G.T) / 2
    return np.array([S[0, 0], S[1, 1], S[2, 2], 2 * S[1, 2], 2 * S[0, 2], 2 * S[0, 1]])


G = np.array([[2.0, 0.5, -0.3], [0.1, -1.0, 0.7], [0.4, 0.2, 1.5]]) * 1e-4
g = np.array([3.0, -1.0, 2.0]) * 1e4                       # V/m


def test_stiffness_of_a_uniform_strain(bases):
    bu, _ = bases
    K = asm(stiffness, bu, c=PC.c_E)
    u = _vector(bu, G)
    S = _voigt(G)
    assert u @ K @ u == pytest.approx(V * S @ PC.c_E @ S, rel=RTOL)


def test_a_rigid_rotation_has_no_stiffness_force(bases):
    bu, _ = bases
    K = asm(stiffness, bu, c=PC.c_E)
    W = np.array([[0.0, -1.0, 0.5], [1.0, 0.0, -2.0], [-0.5, 2.0, 0.0]])   # skew: a rotation
    u = _vector(bu, W)
    scale = abs(K).max() * abs(u).max()
    assert abs(K @ u).max() < RTOL * scale


def test_coupling_and_permittivity_of_uniform_fields(bases):
    bu, bp = bases
    Kup = asm(coupling, bp, bu, e=PC.e)
    Kpp = asm(permittivity, bp, eps=PC.eps_S)
    u, phi = _vector(bu, G), bp.project(lambda x: np.einsum("i,i...->...", g, x))
    assert u @ Kup @ phi == pytest.approx(V * _voigt(G) @ PC.e.T @ g, rel=RTOL)
    assert phi @ Kpp @ phi == pytest.approx(V * g @ PC.eps_S @ g, rel=RTOL)


def test_mass_of_a_linear_field(bases):
    bu, _ = bases
    rho = 7500.0
    M = asm(mass, bu, rho=rho)
    u = _vector(bu, np.diag([1.0, 0.0, 0.0]))               # u = (x, 0, 0)
    assert u @ M @ u == pytest.approx(rho * B * C * A ** 3 / 3, rel=RTOL)


def test_voigt_strain_orders_the_shears_as_the_materials_do(bases):
    """The engineering shears in the order 23, 13, 12, the order of the 6x6 tensors
    (``fem.materials``): a shear-only gradient puts its strain in the one slot."""
    bu, _ = bases
    Gs = np.zeros((3, 3))
    Gs[1, 2] = 1.0                                           # du_y/dz: S23 = 1/2, 2 S23 = 1
    field = bu.interpolate(_vector(bu, Gs))
    np.testing.assert_allclose(voigt_strain(field)[:, 0, 0], [0, 0, 0, 1, 0, 0], atol=1e-12)

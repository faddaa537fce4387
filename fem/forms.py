r"""The weak forms of the piezo-elastic model, written as scikit-fem bilinear forms.

Linear piezoelectricity in the stress-charge form (IEEE Std 176-1987, eq. 9):

.. math::

    T = c^E S - e^\mathsf{T} E, \qquad D = e S + \varepsilon^S E, \qquad E = -\nabla\phi,

with the strain in Voigt order :math:`S = (S_{11}, S_{22}, S_{33}, 2S_{23}, 2S_{13}, 2S_{12})`.
Virtual work of the stress and the electric displacement, with the inertia :math:`\rho\ddot u`,
gives for test functions :math:`v` (displacement) and :math:`\psi` (potential)

.. math::

    \int S(v)^\mathsf{T} c^E S(u) + \int S(v)^\mathsf{T} e^\mathsf{T} \nabla\phi
      - \omega^2 \int \rho\, v\cdot u = \int v \cdot f, \qquad
    \int \nabla\psi^\mathsf{T} e\, S(u) - \int \nabla\psi^\mathsf{T} \varepsilon^S \nabla\phi = -Q,

one bilinear form per term:

==================== ====================================================== ============
form                 integrand                                              block
==================== ====================================================== ============
:data:`stiffness`    :math:`S(v)^\mathsf{T} c^E S(u)`                       ``K_uu``
:data:`coupling`     :math:`S(v)^\mathsf{T} e^\mathsf{T} \nabla\phi`        ``K_uphi``
:data:`permittivity` :math:`\nabla\psi^\mathsf{T} \varepsilon^S \nabla\phi` ``K_phiphi``
:data:`mass`         :math:`\rho\, v \cdot u`                               ``M_uu``
==================== ====================================================== ============

The material enters as keyword arguments of :func:`skfem.asm` (``c`` 6x6 in Pa, ``e`` 3x6 in
C/m^2, ``eps`` 3x3 in F/m, ``rho`` in kg/m^3), constant over the cells assembled, as
:func:`fem.assembly.assemble` does region by region. :func:`fem.assembly.assemble` with
``reference=True`` assembles these forms with :func:`skfem.asm`; its default fast path
(:mod:`fem.fastasm`) evaluates the same integrands in batched numpy and is tested to give the
same matrices to round-off. The potential's sign and scale in the assembled system are set
there (:mod:`fem.assembly`).

Examples
--------
The mass form on a unit cube of density 2 holds the cube's mass once per component:

>>> import numpy as np
>>> from skfem import Basis, ElementTetP1, ElementVector, MeshTet, asm
>>> from fem.forms import mass
>>> basis = Basis(MeshTet(), ElementVector(ElementTetP1()))
>>> M = asm(mass, basis, rho=2.0)
>>> round(float(M.sum()) / 3, 12)
2.0
"""

from __future__ import annotations

import numpy as np
from skfem import BilinearForm
from skfem.helpers import dot, grad, sym_grad

__all__ = ["voigt_strain", "stiffness", "coupling", "permittivity", "mass"]


def voigt_strain(v) -> np.ndarray:
    """The strain of a vector field in Voigt order, engineering shears (factor 2).

    Parameters
    ----------
    v : skfem.element.DiscreteField
        A vector field (trial or test function) at the quadrature points.

    Returns
    -------
    numpy.ndarray
        ``(6, ...)``: ``S11, S22, S33, 2 S23, 2 S13, 2 S12`` at every quadrature point.
    """
    s = sym_grad(v)
    return np.array([s[0, 0], s[1, 1], s[2, 2], 2 * s[1, 2], 2 * s[0, 2], 2 * s[0, 1]])


def _quadratic(a, matrix, b) -> np.ndarray:
    """``a^T matrix b`` at every quadrature point (``matrix`` constant or per point)."""
    return np.einsum("i...,ij...,j...->...", a, np.asarray(matrix), b)


@BilinearForm
def stiffness(u, v, w):
    """Elastic stiffness ``S(v)^T c S(u)``; ``c``: the 6x6 stiffness at constant field, Pa."""
    return _quadratic(voigt_strain(v), w.c, voigt_strain(u))


@BilinearForm
def coupling(phi, v, w):
    """Piezoelectric coupling ``S(v)^T e^T grad(phi)``; trial: potential, test: displacement;
    ``e``: the 3x6 piezoelectric stress constants, C/m^2."""
    return _quadratic(voigt_strain(v), np.swapaxes(np.asarray(w.e), 0, 1), grad(phi))


@BilinearForm
def permittivity(phi, psi, w):
    """Dielectric ``grad(psi)^T eps grad(phi)``; ``eps``: the 3x3 permittivity at constant strain, F/m."""
    return _quadratic(grad(psi), w.eps, grad(phi))


@BilinearForm
def mass(u, v, w):
    """Consistent mass ``rho v . u``; ``rho``: density, kg/m^3."""
    return w.rho * dot(u, v)

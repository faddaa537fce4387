"""Constitutive matrices for the finite-element model.

The material *records* live in :mod:`geometry.materials` (stress-charge form for ceramics is
the single source of truth); this module turns them into matrices.

Conventions
-----------
* Voigt order ``xx, yy, zz, yz, xz, xy``; strains are *engineering* strains (gamma = 2 eps for
  shear), stresses are plain tensor components.
* Stress-charge form: ``T = c_E S - e^T E``, ``D = e S + eps_S E`` (SI: Pa, C/m^2, F/m).
* The material 3-axis is the poling direction. :func:`piezo_matrices` rotates the constants so
  that the 3-axis points along ``poling`` (a unit vector in mesh coordinates). With the rotation
  ``R`` (columns = material axes in global coordinates) and the stress Bond matrix ``M``
  (``T_global = M T_material``): ``c' = M c M^T``, ``e' = R e M^T``, ``eps' = R eps R^T``.
  Poling ``-z`` uses a half turn about x: ``e`` changes sign, ``c`` and ``eps`` do not.

API
---
``elastic_matrix(material) -> (6, 6)``
    isotropic stiffness from E, nu (a piezo record gives its unrotated ``c_E``).
``piezo_matrices(material, poling=(0, 0, 1)) -> PiezoConstants(c_E, e, eps_S)``
``strain_charge(pc) -> (s_E, d, eps_T)``
    ``s_E = c_E^-1``, ``d = e s_E``, ``eps_T = eps_S + d e^T`` (all absolute, F/m for eps).
``rotation_to(poling) -> (3, 3)``, ``bond_stress(R) -> (6, 6)``
``load_materials(extra_toml=None) -> dict[name, Material]`` (re-uses ``geometry.materials``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from rpud_common import ParameterError
from geometry import piezo_forms
from geometry.materials import EPS0, Material, get_material, load_library

__all__ = ["PiezoConstants", "elastic_matrix", "piezo_matrices", "strain_charge",
           "rotation_to", "bond_stress", "load_materials", "resolve", "EPS0", "VOIGT"]

VOIGT = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
"""Tensor index pairs of the Voigt components xx, yy, zz, yz, xz, xy."""


@dataclass(frozen=True, eq=False)
class PiezoConstants:
    """Stress-charge constants in global coordinates: ``c_E`` (6,6) Pa, ``e`` (3,6) C/m^2,
    ``eps_S`` (3,3) F/m (absolute)."""

    c_E: np.ndarray
    e: np.ndarray
    eps_S: np.ndarray


def load_materials(extra_toml=None) -> dict[str, Material]:
    """The material library (built-in ``geometry/materials.toml`` plus an optional user TOML)."""
    return load_library(extra_toml)


def resolve(material: Material | str, library: Mapping[str, Material] | None = None) -> Material:
    """A :class:`Material` from a record or a name (unknown names: ``ParameterError``)."""
    if isinstance(material, Material):
        return material
    return get_material(material, library)


def elastic_matrix(material: Material | str, library=None) -> np.ndarray:
    """(6, 6) stiffness in Pa (Voigt, engineering shear). Isotropic: from E and nu;
    piezo: its unrotated ``c_E``."""
    m = resolve(material, library)
    if m.is_piezo:
        return piezo_matrices(m).c_E
    E, nu = float(m.youngs_modulus), float(m.poisson_ratio)
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    c = np.zeros((6, 6))
    c[:3, :3] = lam
    c[np.arange(3), np.arange(3)] = lam + 2 * mu
    c[np.arange(3, 6), np.arange(3, 6)] = mu
    return c


def _material_frame(m: Material) -> PiezoConstants:
    return PiezoConstants(*m.voigt_matrices())


def rotation_to(poling) -> np.ndarray:
    """Proper rotation ``R`` whose third column is the unit vector ``poling``.

    ``+z`` gives the identity, ``-z`` the half turn about x (``diag(1, -1, -1)``); other
    directions use the shortest rotation taking z onto ``poling`` (Rodrigues).
    """
    p = np.asarray(poling, dtype=float).reshape(3)
    n = np.linalg.norm(p)
    if not np.isfinite(n) or n == 0:
        raise ParameterError("poling", tuple(p), "must be a non-zero vector")
    p = p / n
    z = np.array([0.0, 0.0, 1.0])
    cth = float(p @ z)
    if cth > 1 - 1e-14:
        return np.eye(3)
    if cth < -1 + 1e-14:
        return np.diag([1.0, -1.0, -1.0])
    axis = np.cross(z, p)
    s = np.linalg.norm(axis)
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - cth) * K @ K


def bond_stress(R: np.ndarray) -> np.ndarray:
    """Bond matrix ``M`` with ``T'_voigt = M T_voigt`` for ``T' = R T R^T`` (stress Voigt);
    engineering strains transform with ``M^-T``."""
    M = np.zeros((6, 6))
    for J, (k, l) in enumerate(VOIGT):
        T = np.zeros((3, 3))
        T[k, l] = T[l, k] = 1.0
        Tp = R @ T @ R.T
        M[:, J] = [Tp[i, j] for i, j in VOIGT]
    return M


def piezo_matrices(material: Material | str, poling=(0.0, 0.0, 1.0), library=None) -> PiezoConstants:
    """Stress-charge constants of a piezo record with its 3-axis along ``poling``."""
    m = resolve(material, library)
    if not m.is_piezo:
        raise ParameterError("material", m.name, "is not a piezoelectric material")
    pc = _material_frame(m)
    R = rotation_to(poling)
    if np.allclose(R, np.eye(3)):
        return pc
    M = bond_stress(R)
    return PiezoConstants(M @ pc.c_E @ M.T, R @ pc.e @ M.T, R @ pc.eps_S @ R.T)


def strain_charge(pc: PiezoConstants) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Strain-charge form ``(s_E (6,6) 1/Pa, d (3,6) C/N, eps_T (3,3) F/m)`` of ``pc``."""
    return piezo_forms.strain_charge(pc.c_E, pc.e, pc.eps_S)

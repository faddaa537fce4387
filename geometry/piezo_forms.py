"""Piezoelectric constants as tables and matrices, and the two constitutive forms.

A material record names its constants with IEEE subscripts (``c11``, ``e31``, ``eps33``...).
The 6mm set of a poled ceramic (``REQUIRED``) must be given; any other component of a fully
anisotropic material may be added (``c14``, ``c22``, ``e24``, ``eps12``...). A component left
out takes its transversely-isotropic value (``c22 = c11``, ``c23 = c13``, ``c55 = c44``,
``e32 = e31``, ``e24 = e15``, ``eps22 = eps11``; the same for ``s`` and ``d``) or 0.

Voigt order xx yy zz yz xz xy, engineering shear strains; SI units (Pa, 1/Pa, C/m^2, C/N),
permittivities *relative* to :data:`EPS0` in the tables and absolute (F/m) in the matrices.

Forms (``shared/references.md``):

- stress-charge ``T = c^E S - e^T E``, ``D = e S + eps^S E`` (the library's source of truth);
- strain-charge ``S = s^E T + d^T E``, ``D = d T + eps^T E``;
- ``c^E = (s^E)^-1``, ``e = d c^E``, ``eps^S = eps^T - d c^E d^T`` and back
  ``s^E = (c^E)^-1``, ``d = e s^E``, ``eps^T = eps^S + d e^T``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from rpud_common import ParameterError

__all__ = ["EPS0", "FORMS", "REQUIRED", "matrices", "tables", "stress_charge", "strain_charge",
           "check_positive_definite", "transverse_isotropy_defect", "allowed_keys"]

EPS0 = 8.854e-12
"""Vacuum permittivity in F/m, as used by the reference data."""

FORMS = {"stress-charge": ("c_E", "e", "eps_S"), "strain-charge": ("s_E", "d", "eps_T")}
"""The three tables of each constitutive form."""

REQUIRED = {
    "c_E": ("c11", "c12", "c13", "c33", "c44", "c66"), "e": ("e31", "e33", "e15"), "eps_S": ("eps11", "eps33"),
    "s_E": ("s11", "s12", "s13", "s33", "s44", "s66"), "d": ("d31", "d33", "d15"), "eps_T": ("eps11", "eps33"),
}
"""Keys every piezo record gives (the 6mm constants of a poled ceramic), per table."""

_PREFIX = {"c_E": "c", "s_E": "s", "e": "e", "d": "d", "eps_S": "eps", "eps_T": "eps"}

# implied equalities of a transversely isotropic (6mm) material: key -> the key it equals
_IMPLIED = {"c": {"22": "11", "23": "13", "55": "44"}, "s": {"22": "11", "23": "13", "55": "44"},
            "e": {"32": "31", "24": "15"}, "d": {"32": "31", "24": "15"}, "eps": {"22": "11"}}


def _index(table: str) -> list[tuple[str, tuple[int, int]]]:
    """``(subscript, (row, col))`` of every independent component of a table."""
    if table in ("c_E", "s_E"):
        return [(f"{i + 1}{j + 1}", (i, j)) for i in range(6) for j in range(i, 6)]
    if table in ("e", "d"):
        return [(f"{i + 1}{j + 1}", (i, j)) for i in range(3) for j in range(6)]
    return [(f"{i + 1}{j + 1}", (i, j)) for i in range(3) for j in range(i, 3)]


def allowed_keys(table: str) -> list[str]:
    """Every key a table accepts (``c11`` ... ``c66``, ``e11`` ... ``e36``, ``eps11`` ... ``eps33``)."""
    return [_PREFIX[table] + sub for sub, _ in _index(table)]


def matrices(tables_: Mapping[str, Mapping[str, float]], form: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The three matrices of a form from its tables: ``(6, 6)``, ``(3, 6)``, ``(3, 3)`` (the last
    in F/m). Missing keys take their transversely isotropic value or 0 (module docstring)."""
    out = []
    for table in FORMS[form]:
        given = tables_[table]
        pre = _PREFIX[table]
        shape = {"c": (6, 6), "s": (6, 6), "e": (3, 6), "d": (3, 6), "eps": (3, 3)}[pre]
        A = np.zeros(shape)
        for sub, (i, j) in _index(table):
            key = pre + sub
            if key in given:
                v = given[key]
            elif sub in _IMPLIED[pre]:
                v = given[pre + _IMPLIED[pre][sub]]
            else:
                continue
            A[i, j] = v
            if shape[0] == shape[1]:
                A[j, i] = v
        out.append(A)
    out[2] = out[2] * EPS0
    return out[0], out[1], out[2]


def tables(A: np.ndarray, B: np.ndarray, eps: np.ndarray, form: str, rtol: float = 1e-12) -> dict[str, dict]:
    """Tables of a form from its matrices (``eps`` in F/m): the required keys always, every other
    key only where the matrix differs from its transversely isotropic value by more than
    ``rtol`` of the matrix' largest entry (round-off of a conversion is not anisotropy)."""
    out = {}
    for table, M in zip(FORMS[form], (A, B, eps / EPS0)):
        pre = _PREFIX[table]
        tol = rtol * float(np.max(np.abs(M), initial=0.0))
        rec: dict[str, float] = {}
        full = {pre + sub: float(M[i, j]) for sub, (i, j) in _index(table)}
        for key in REQUIRED[table]:
            rec[key] = full[key]
        for sub, (i, j) in _index(table):
            key = pre + sub
            if key in rec:
                continue
            implied = full[pre + _IMPLIED[pre][sub]] if sub in _IMPLIED[pre] else 0.0
            if abs(full[key] - implied) > tol:
                rec[key] = full[key]
        out[table] = rec
    return out


def stress_charge(s_E: np.ndarray, d: np.ndarray, eps_T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stress-charge ``(c^E Pa, e C/m^2, eps^S F/m)`` from strain-charge ``(s^E 1/Pa, d C/N, eps^T F/m)``."""
    c_E = np.linalg.inv(s_E)
    c_E = 0.5 * (c_E + c_E.T)            # exactly symmetric: the inverse is, up to round-off
    e = d @ c_E
    eps_S = eps_T - d @ c_E @ d.T
    return c_E, e, 0.5 * (eps_S + eps_S.T)


def strain_charge(c_E: np.ndarray, e: np.ndarray, eps_S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Strain-charge ``(s^E 1/Pa, d C/N, eps^T F/m)`` from stress-charge ``(c^E Pa, e C/m^2, eps^S F/m)``."""
    s_E = np.linalg.inv(c_E)
    s_E = 0.5 * (s_E + s_E.T)
    d = e @ s_E
    eps_T = eps_S + d @ e.T
    return s_E, d, 0.5 * (eps_T + eps_T.T)


def check_positive_definite(name: str, A: np.ndarray, what: str) -> None:
    """:class:`ParameterError` naming ``name`` unless the symmetric matrix ``A`` is positive
    definite (its smallest eigenvalue > 1e-12 of its largest)."""
    w = np.linalg.eigvalsh(A)
    if not np.all(np.isfinite(w)) or w[0] <= 1e-12 * max(abs(w[-1]), 1e-300):
        raise ParameterError(name, f"smallest eigenvalue {w[0]:.4g}", f"is not positive definite: {what}")


def transverse_isotropy_defect(c_E: np.ndarray, e: np.ndarray, eps_S: np.ndarray) -> tuple[float, str]:
    """Largest departure of the constants from transverse isotropy about the 3 (poling) axis,
    relative to the largest entry of its matrix, and the component it is in. 0 for a 6mm
    ceramic with ``c66 = (c11 - c12) / 2``."""
    worst, where = 0.0, ""
    for label, M in (("c_E", c_E), ("e", e), ("eps_S", eps_S)):
        pre = _PREFIX[label]
        scale = float(np.max(np.abs(M), initial=0.0)) or 1.0
        for sub, (i, j) in _index(label):
            if pre + sub in REQUIRED[label] and sub != "66":
                continue
            if sub == "66":
                ref = 0.5 * (M[0, 0] - M[0, 1])
            elif sub in _IMPLIED[pre]:
                a, b = _IMPLIED[pre][sub]
                ref = M[int(a) - 1, int(b) - 1]
            else:
                ref = 0.0
            dev = abs(M[i, j] - ref) / scale
            if dev > worst:
                worst, where = dev, pre + sub
    return worst, where

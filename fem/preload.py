"""Static solutions: surface tractions, clamped or free-free static solve, the bolt preload.

Bolt preload (:func:`preload_solve`)
------------------------------------
A Langevin transducer's bolt squeezes the ceramic stack with a force ``P``. It is modelled as a
force pair on the stack's two end faces: the lower face is pushed along ``+axis`` and the upper
face along ``-axis`` by uniform tractions ``P / A`` (``A`` the face's area on the mesh), so that
every cross-section of the stack carries exactly ``-P`` (compression) and the parts beyond the
faces carry no net force (an idealised bolt whose heads bear on the stack; the bolt's own
stiffness in parallel with the stack is left out). By default the end faces are the outermost
electrode planes along the axis (the stack's end electrodes); any two facet sets may be named.
Electrodes are short-circuited (``V_hot = 0``, as when the bolt is torqued with the electrodes
shorted): the interior potential is free and the field it sets up is part of the solution.

Free-free static solve
----------------------
The load is first made self-equilibrated exactly (its components on the six rigid-body motions
are removed by ``f - M R (R^T M R)^-1 R^T f``; for an equilibrated pair this changes only
round-off), then ``(K + eps M) x = f`` is solved with ``eps = (2 pi 1 Hz)^2``. Because
``R^T f = 0`` and ``K R = 0`` the solution is M-orthogonal to the rigid modes (they are removed),
and the inertia term perturbs it by ``(1 Hz / f_1)^2`` relative (f_1 the first elastic mode:
below 1e-7 for any transducer here). The rigid component that round-off leaves in the
near-singular solve is projected out afterwards (it carries no strain).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from rpud_common import ParameterError, check_finite, check_nonnegative

from .assembly import PiezoSystem, _sub
from .solvers import factorize

__all__ = ["traction_load", "static_solve", "stack_end_faces", "preload_solve", "PreloadState", "face_area"]

log = logging.getLogger(__name__)

_SHIFT_HZ = 1.0
_NORMAL_TOL = 1e-6


def _facet_basis(system: PiezoSystem, name: str, vector: bool):
    from skfem import ElementVector

    from .facets import facet_basis

    facets = system.skmesh.boundaries.get(name) if system.skmesh.boundaries else None
    if facets is None:
        system.mesh.facets(name)            # the clear ParameterError for unknown names
    elem = ElementVector(system.basis.elem) if vector else system.basis.elem
    return facet_basis(system.skmesh, elem, facets, intorder=2 * system.order + 2)


def face_area(system: PiezoSystem, name: str) -> float:
    """Area of the facet set ``name`` on the mesh (curved facets included), m^2."""
    fb = _facet_basis(system, name, vector=False)
    return float(np.sum(fb.dx))


def _face_normal(system: PiezoSystem, name: str) -> np.ndarray:
    """The common unit normal of a planar facet set (sign arbitrary), or a ParameterError."""
    fb = _facet_basis(system, name, vector=False)
    n = fb.normals.reshape(3, -1).T
    ref = n[0]
    if np.max(np.linalg.norm(np.cross(n, ref), axis=1)) > _NORMAL_TOL:
        raise ParameterError(f"faces.{name}", name, "must be a plane face (its normals differ)")
    return ref / np.linalg.norm(ref)


def traction_load(system: PiezoSystem, name: str, traction) -> np.ndarray:
    """Consistent nodal forces (full-length vector, N) of a uniform traction (3,) Pa on a facet set."""
    from skfem import LinearForm, asm

    t = np.asarray(traction, float).reshape(3)
    if not np.all(np.isfinite(t)):
        raise ParameterError("traction", tuple(t), "must be three finite values in Pa")
    fb = _facet_basis(system, name, vector=True)

    @LinearForm
    def load(v, w):
        return t[0] * v[0] + t[1] * v[1] + t[2] * v[2]

    f = np.zeros(system.ndof)
    f[: system.n_u] = asm(load, fb)
    return f


def _rigid_modes(system: PiezoSystem) -> np.ndarray:
    """(ndof, 6): three translations and three rotations about the centroid (zero potential)."""
    x = system.nodes - system.nodes.mean(axis=0)
    R = np.zeros((system.ndof, 6))
    for c in range(3):
        R[c: system.n_u: 3, c] = 1.0
    for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        R[i: system.n_u: 3, 3 + k] = -x[:, j]
        R[j: system.n_u: 3, 3 + k] = x[:, i]
    return R


def static_solve(system: PiezoSystem, load: np.ndarray, *, clamp: Iterable[str] = (),
                 backend: str | None = None) -> np.ndarray:
    """Static solution ``x`` (full length) of ``K x = load`` with short-circuited electrodes.

    ``clamp``: facet sets with every displacement component fixed; without a clamp the body is
    free and the rigid-body modes are removed (see the module docstring).
    """
    f = np.asarray(load, float)
    if f.shape != (system.ndof,) or not np.all(np.isfinite(f)):
        raise ParameterError("load", f.shape, f"must be a finite vector of length {system.ndof}")
    clamp = (clamp,) if isinstance(clamp, str) else tuple(clamp)
    free = system.free_dofs("short", clamp)
    K = _sub(system.K, free)
    if not clamp:
        R = _rigid_modes(system)
        MR = system.M @ R
        f = f - MR @ np.linalg.solve(R.T @ MR, R.T @ f)
        K = (K + (2 * np.pi * _SHIFT_HZ) ** 2 * _sub(system.M, free)).tocsr()
    xf = factorize(K.tocsr(), backend=backend)(f[free])
    x = system.expand(xf, free, 0.0)
    if not clamp:
        # the exact solution is M-orthogonal to the rigid modes; the near-singular solve leaves a
        # rigid component of round-off amplified by 1/eps (~1e-5 of x): removed (no strain)
        x = x - R @ np.linalg.solve(R.T @ MR, MR.T @ x)
    return x


def stack_end_faces(system: PiezoSystem, axis=(0.0, 0.0, 1.0)) -> tuple[str, str]:
    """The electrode facet sets lowest and highest along ``axis`` (the stack's end faces)."""
    d = np.asarray(axis, float) / np.linalg.norm(axis)
    pos = {}
    for el in system.mesh.electrodes:
        tri = system.mesh.facets(el.name)
        pos[el.name] = float(np.mean(system.mesh.points[tri.ravel()] @ d))
    if len(pos) < 2 or max(pos.values()) - min(pos.values()) <= 0:
        raise ParameterError("preload faces", sorted(pos),
                             "need two electrode planes apart along the axis (or name the faces)")
    lo = min(pos, key=pos.get)
    hi = max(pos, key=pos.get)
    return lo, hi


@dataclass(eq=False)
class PreloadState:
    """A static preload: ``x`` the solution, ``force_n`` the bolt force, ``faces`` (lower, upper),
    ``areas_m2`` their mesh areas, ``axis``."""

    x: np.ndarray
    force_n: float
    faces: tuple[str, str]
    areas_m2: tuple[float, float]
    axis: tuple


def preload_solve(system: PiezoSystem, force_n: float, *, faces: Sequence[str] | None = None,
                  axis=(0.0, 0.0, 1.0), backend: str | None = None) -> PreloadState:
    """Static state of a bolt preload ``force_n`` (N, >= 0) squeezing the stack (module docstring).

    ``faces``: (lower, upper) facet sets along ``axis``; default :func:`stack_end_faces`.
    """
    check_finite("preload", force_n, "N")
    check_nonnegative("preload", force_n, "N")
    d = np.asarray(axis, float)
    if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
        raise ParameterError("axis", tuple(np.ravel(axis)), "must be a non-zero 3-vector")
    d = d / np.linalg.norm(d)
    lo, hi = tuple(faces) if faces is not None else stack_end_faces(system, d)
    if lo == hi:
        raise ParameterError("faces", (lo, hi), "must be two different facet sets")
    for name in (lo, hi):
        nrm = _face_normal(system, name)
        if abs(abs(nrm @ d) - 1.0) > _NORMAL_TOL:
            raise ParameterError(f"faces.{name}", name, "must be a plane face normal to the preload axis")
    pts = system.mesh.points
    z_lo = float(np.mean(pts[system.mesh.facets(lo).ravel()] @ d))
    z_hi = float(np.mean(pts[system.mesh.facets(hi).ravel()] @ d))
    if z_lo >= z_hi:
        raise ParameterError("faces", (lo, hi), "must be given lower first along the axis")
    a_lo, a_hi = face_area(system, lo), face_area(system, hi)
    f = traction_load(system, lo, d * force_n / a_lo) + traction_load(system, hi, -d * force_n / a_hi)
    x = static_solve(system, f, backend=backend)
    log.info("preload %.4g N on %s (%.4g mm^2) and %s (%.4g mm^2)", force_n, lo, a_lo * 1e6, hi, a_hi * 1e6)
    return PreloadState(x, float(force_n), (lo, hi), (a_lo, a_hi), tuple(d))

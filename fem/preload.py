"""Static solutions: surface tractions, clamped or free-free static solve, the bolt preload.

Bolt preload (:func:`preload_solve`)
------------------------------------
A Langevin transducer's bolt squeezes the ceramic stack with a force ``P``. Without a bolt part
in the mesh it is modelled as a force pair on the stack's two end faces: the lower face is
pushed along ``+axis`` and the upper face along ``-axis`` by uniform tractions ``P / A`` (``A``
the face's area on the mesh), so that every cross-section of the stack carries exactly ``-P``
(compression) and the parts beyond the faces carry no net force (an idealised bolt whose heads
bear on the stack). By default the end faces are the outermost electrode planes along the axis
(the stack's end electrodes); any two facet sets may be named.

With a bolt part (region :data:`BOLT_REGION`, bonded to the metal at both ends) a force pair
on the stack's faces would squeeze the bolt as well, in parallel with the stack. The bolt's
tension is then an eigenstrain instead: the bolt is given a uniform axial shrink strain
``eps0`` (as if it were cut shorter than the gap it bridges), whose load is
``f = int B^T C eps0 dV`` over the bolt; the solution puts the bolt in tension and the stack in
compression, the two forces equal (nothing else loads the free body). It is scaled so that the
stack carries ``P``: its mean axial stress over each ring, ``-P / A`` (``A`` the stack's end face
area), is the section force over the area. The bolt's own stress is ``C (eps(x) - eps0)``
(:meth:`PreloadState.field`).

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
import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from rpud_common import ParameterError, check_finite, check_nonnegative

from .assembly import PiezoSystem, submatrix
from .solvers import factorize

__all__ = ["BOLT_REGION", "ELASTIC_BOLT_FR_SHIFT", "BOLT_JOINT_FR_SHIFT", "traction_load", "eigenstrain_load", "static_solve", "stack_end_faces", "preload_solve", "PreloadState", "face_area",
           "ring_means", "RingWindow", "PreloadWindows", "preload_windows", "design_preload", "window_lines"]

log = logging.getLogger(__name__)

_SHIFT_HZ = 1.0
_NORMAL_TOL = 1e-6

BOLT_REGION = "bolt"
"""Name of the mesh region that is the stack's bolt (:attr:`geometry.design_rpud.StackRings.bolt_diameter`)."""

ELASTIC_BOLT_FR_SHIFT = (0.09996, 0.0008, 0.10073)
"""``(shift, its discretisation error, the bonded-face bolt's shift)``: the relative rise of the
working resonance of the article's drill (Table 1, no bolt part: ``geometry.examples.article_design``)
when an M12 steel bolt part (``stack.bolt_diameter`` 12 mm) is added at its matched lengths,
threaded 1.5 d into the coupler and the horn (``stack.bolt_joint = "thread"``, free shank), and the
same with the bolt bonded at the stack's faces. A documented measurement, quoted by the report of
a design run without a bolt part as the bolt's model-form effect (an extra modal solve per run
would cost ~25 % of the pipeline): k = 0 sector, refine 1 (two-level estimates against refine
1.4), f_r without / threaded / bonded faces 19 999.998 +- 6.8 / 21 999.16 +- 9.3 / 22 014.69 +- 15
Hz; the error is the two levels' relative errors summed (docs/theory/operating-point.md)."""

BOLT_JOINT_FR_SHIFT = (0.00511, 0.0019)
"""``(shift, its discretisation error)``: the relative rise of f_r when a bolt part bonded at the
stack's faces (``stack.bolt_joint = "faces"``) is engaged by its threads instead (``"thread"``,
1.5 d) at fixed lengths, measured on the ``bolted`` example (``geometry.examples.bolted_design``,
k = 0 sector, refine 1): f_r 20 000.38 +- 17 Hz bonded, 20 102.67 +- 21 Hz threaded (two-level
estimates against refine 1.4, summed). The report of a design with a bolt part quotes it as the
joint model's form error; the thread flanks' compliance is not modelled by either joint (both bond
the steel to the metal: upper bounds of the joint's stiffness)."""


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


def eigenstrain_load(system: PiezoSystem, region: str, strain, z_range=None) -> np.ndarray:
    """Consistent nodal forces (full-length vector, N) of a uniform eigenstrain ``strain`` (Voigt
    6-vector, engineering shear) in region ``region``: ``int B^T C strain dV`` over its cells
    (``z_range`` (z0, z1), m: only the cells whose centroid lies between)."""
    from skfem import Basis, ElementVector, LinearForm, asm

    names = [r.name for r in system.regions]
    if region not in names:
        raise ParameterError("eigenstrain region", region, "unknown region; known: " + ", ".join(names))
    rd = system.regions[names.index(region)]
    sig = rd.c @ np.asarray(strain, float).reshape(6)
    cells = np.flatnonzero(np.asarray(system.mesh.cell_region) == names.index(region))
    if z_range is not None:
        zc = system.mesh.points[np.asarray(system.mesh.cells)[cells, :4], 2].mean(axis=1)
        cells = cells[(zc > z_range[0]) & (zc < z_range[1])]
        if not len(cells):
            raise ParameterError("eigenstrain z_range", tuple(z_range), f"holds no cell of region {region}")
    basis = Basis(system.skmesh, ElementVector(system.basis.elem), elements=cells, intorder=system.intorder[0])

    @LinearForm
    def load(v, w):
        g = v.grad
        return (sig[0] * g[0, 0] + sig[1] * g[1, 1] + sig[2] * g[2, 2] + sig[3] * (g[1, 2] + g[2, 1])
                + sig[4] * (g[0, 2] + g[2, 0]) + sig[5] * (g[0, 1] + g[1, 0]))

    f = np.zeros(system.ndof)
    f[: system.n_u] = asm(load, basis)
    return f


def _rigid_modes(system: PiezoSystem, about=None) -> np.ndarray:
    """(ndof, 6): three translations and three rotations about the point ``about`` (default the
    centroid; zero potential)."""
    x = system.nodes - (system.nodes.mean(axis=0) if about is None else np.asarray(about, float))
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
    K = submatrix(system.K, free)
    if not clamp:
        kept = getattr(system, "kept", None)
        R = _rigid_modes(system, None if kept is None else (0.0, 0.0, 0.0))
        if kept is not None:
            # a k = 0 sector system (fem.sector_system) holds the axial translation and the
            # rotation about the axis (not about the sector's centroid) only; its vectors live
            # on the kept indices
            mask = np.zeros(system.ndof)
            mask[kept] = 1.0
            R = R[:, [2, 5]] * mask[:, None]
        MR = system.M @ R
        f = f - MR @ np.linalg.solve(R.T @ MR, R.T @ f)
        K = (K + (2 * np.pi * _SHIFT_HZ) ** 2 * submatrix(system.M, free)).tocsr()
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
    ``areas_m2`` their mesh areas, ``axis``; ``eigenstrain``: ``(region, Voigt strain, (z0, z1))``
    of a bolt part's shrink over its cells with centroids between z0 and z1 (None: the force pair
    on the faces)."""

    x: np.ndarray
    force_n: float
    faces: tuple[str, str]
    areas_m2: tuple[float, float]
    axis: tuple
    eigenstrain: tuple | None = None

    def scaled(self, factor: float) -> "PreloadState":
        """The same preload times ``factor`` (force, field and eigenstrain)."""
        eig = None if self.eigenstrain is None else (self.eigenstrain[0], self.eigenstrain[1] * factor,
                                                     self.eigenstrain[2])
        return PreloadState(self.x * factor, self.force_n * factor, self.faces, self.areas_m2, self.axis, eig)

    def field(self, recovery):
        """The state's :class:`fem.stress.StressField` from ``recovery`` (a
        :class:`fem.stress.StressRecovery` of the system solved), a bolt part's stress less its
        eigenstress ``C eps0``."""
        fld = recovery.field(self.x)
        if self.eigenstrain is not None:
            region, strain, (z0, z1) = self.eigenstrain
            r = [reg.name for reg in recovery.system.regions].index(region)
            zc = fld.points[:, :4, 2].mean(axis=1)
            sel = (fld.region == r) & (zc > z0) & (zc < z1)
            fld.stress[sel] -= recovery.system.regions[r].c @ strain
            fld.strain[sel] -= strain
        return fld


def preload_solve(system: PiezoSystem, force_n: float, *, faces: Sequence[str] | None = None,
                  axis=(0.0, 0.0, 1.0), backend: str | None = None) -> PreloadState:
    """Static state of a bolt preload ``force_n`` (N, >= 0) squeezing the stack (module docstring).

    ``faces``: (lower, upper) facet sets along ``axis``; default :func:`stack_end_faces`. On a
    :class:`fem.sector_system.SectorSystem` the force is the whole drill's (each sector carries
    its share) and ``areas_m2`` the whole faces'.
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
    n = int(getattr(system, "sectors", 1) or 1)
    bolted = BOLT_REGION in [r.name for r in system.regions]
    if bolted:
        if abs(d[2]) != 1.0:
            raise ParameterError("axis", tuple(d), "must be the z axis with a bolt part (the rings' means are zz)")
        strain = np.array([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])     # a unit axial shrink
        # of the shank between the stack's faces: a threaded bolt's ends are held by its threads
        f = eigenstrain_load(system, BOLT_REGION, strain, (z_lo, z_hi))
    else:
        # a sector carries 1/n of the force on 1/n of the area: the same traction
        f = traction_load(system, lo, d * force_n / (n * a_lo)) + traction_load(system, hi, -d * force_n / (n * a_hi))
    if n > 1:
        f = n * np.asarray(system.tie.T @ f).ravel()         # the whole drill's load on the k = 0 unknowns
        a_lo, a_hi = n * a_lo, n * a_hi
    x = static_solve(system, f, backend=backend)
    log.info("preload %.4g N on %s (%.4g mm^2) and %s (%.4g mm^2)", force_n, lo, a_lo * 1e6, hi, a_hi * 1e6)
    state = PreloadState(x, float(force_n), (lo, hi), (a_lo, a_hi), tuple(d))
    if not bolted:
        return state
    # the stack's force of the unit shrink: its rings' mean axial stress times the face area
    from .stress import StressRecovery

    means = ring_means(system, StressRecovery(system).field(x))
    stack_force = -float(np.mean([m[0].real for m in means.values()])) * 0.5 * (a_lo + a_hi)
    if not stack_force > 0:     # pragma: no cover - a bonded bolt's shrink compresses the stack
        raise ParameterError("preload", force_n, "the bolt's tension does not compress the stack")
    scale = force_n / stack_force
    return PreloadState(x * scale, float(force_n), (lo, hi), (a_lo, a_hi), tuple(d),
                        (BOLT_REGION, strain * scale, (z_lo, z_hi)))


# --------------------------------------------------------------------------- the preload window

WINDOW_COMPONENT = 2
"""Voigt component of the stack-axis normal stress (zz: the stack lies along z)."""


def ring_means(system: PiezoSystem, fld) -> dict[str, tuple[complex, complex]]:
    """Volume means over every piezoelectric region of the axial stress (Pa) and axial field
    (V/m) of a recovered field ``fld`` (:class:`fem.stress.StressField`, real or complex).

    The stress of a P2 displacement is linear on a straight cell, so a cell's mean is the mean of
    its four corner values. The volume mean of the axial stress over a ring is its section force
    over its area averaged along the ring: the quantity the 1-D Langevin design rules use, free of
    the singular peaks at the bonded ring edges (those are in the utilisation table)."""
    vol = np.asarray(system.basis.dx).sum(axis=1)[fld.cells]
    sz = fld.stress[:, :4, WINDOW_COMPONENT].mean(axis=1)
    ez = fld.efield[:, :4, WINDOW_COMPONENT].mean(axis=1)
    out = {}
    for r, reg in enumerate(system.regions):
        if not reg.piezo:
            continue
        sel = fld.region == r
        w = vol[sel] / vol[sel].sum()
        out[reg.name] = (complex(np.sum(sz[sel] * w)), complex(np.sum(ez[sel] * w)))
    return out


@dataclass(frozen=True)
class RingWindow:
    """The preload window of one ceramic ring at one drive.

    Attributes
    ----------
    region : str
    sigma_dyn_pa : float
        Amplitude of the ring's mean axial stress at the drive, Pa.
    static_per_newton_pa : float
        The ring's mean axial stress per newton of bolt preload, Pa/N (negative: compression).
    efield_v_per_m : float
        Amplitude of the ring's mean axial field at the drive, V/m.
    compressive_limit_pa, depolarisation_field : float or None
        The material's rated static compressive stress (Pa) and AC depoling field (V/m).
    """

    region: str
    sigma_dyn_pa: float
    static_per_newton_pa: float
    efield_v_per_m: float
    compressive_limit_pa: float | None
    depolarisation_field: float | None

    @property
    def p_min_n(self) -> float:
        """Least preload that keeps the ring's mean stress compressive over the whole cycle, N."""
        return self.sigma_dyn_pa / abs(self.static_per_newton_pa)

    @property
    def p_max_n(self) -> float:
        """Most preload whose static stress plus the dynamic compression peak stays within the
        rated compressive stress, N (inf without a rating)."""
        if self.compressive_limit_pa is None:
            return math.inf
        return (self.compressive_limit_pa - self.sigma_dyn_pa) / abs(self.static_per_newton_pa)

    @property
    def drive_factor_max(self) -> float:
        """Largest factor on the drive at which this ring still has a window and stays below its
        depoling field: the window closes where ``sigma_dyn`` reaches half the compressive rating."""
        f = math.inf
        if self.compressive_limit_pa is not None and self.sigma_dyn_pa > 0:
            f = min(f, self.compressive_limit_pa / (2 * self.sigma_dyn_pa))
        if self.depolarisation_field is not None and self.efield_v_per_m > 0:
            f = min(f, self.depolarisation_field / self.efield_v_per_m)
        return f

    def record(self) -> dict:
        return {"region": self.region, "sigma_dyn_pa": self.sigma_dyn_pa,
                "static_per_newton_pa": self.static_per_newton_pa, "efield_v_per_m": self.efield_v_per_m,
                "compressive_limit_pa": self.compressive_limit_pa,
                "depolarisation_field_v_per_m": self.depolarisation_field,
                "p_min_n": self.p_min_n, "p_max_n": _finite(self.p_max_n),
                "drive_factor_max": _finite(self.drive_factor_max)}


def _finite(v: float):
    return float(v) if math.isfinite(v) else None


@dataclass(frozen=True)
class PreloadWindows:
    """The preload windows of every ring at a drive, and the verdict on the design's bolt.

    ``voltage`` (V amplitude) and ``tip_amplitude_m`` describe the drive; ``preload_n`` is the
    design's bolt preload (N); ``rings`` one :class:`RingWindow` per ceramic region.
    """

    rings: tuple
    voltage: float
    tip_amplitude_m: float
    preload_n: float

    @property
    def p_min_n(self) -> float:
        return max(r.p_min_n for r in self.rings)

    @property
    def p_max_n(self) -> float:
        return min(r.p_max_n for r in self.rings)

    @property
    def drive_factor_max(self) -> float:
        return min(r.drive_factor_max for r in self.rings)

    @property
    def ok(self) -> bool:
        return self.p_min_n <= self.preload_n <= self.p_max_n and self.drive_factor_max >= 1.0

    def verdict(self) -> str:
        """One sentence: the window, the bolt's place in it, and when it fails why and the fix."""
        kn = 1e-3
        lo, hi = self.p_min_n, self.p_max_n
        f = self.drive_factor_max
        top = (f"largest drive with a window {f * self.voltage:.4g} V amplitude (tip {f * self.tip_amplitude_m * 1e6:.3g} "
               f"um)" if math.isfinite(f) else "no limit on the drive from the ratings")
        worst = max(self.rings, key=lambda r: r.p_min_n)
        if lo > hi:
            return (f"NO preload window at {self.voltage:.4g} V (tip {self.tip_amplitude_m * 1e6:.3g} um): {worst.region}'s "
                    f"dynamic stress {worst.sigma_dyn_pa * 1e-6:.1f} MPa needs at least {lo * kn:.1f} kN to stay in "
                    f"compression, and more than {hi * kn:.1f} kN exceeds the rated compressive stress; fix: drive "
                    f"at most {f * self.voltage:.4g} V (tip {f * self.tip_amplitude_m * 1e6:.3g} um), or lower the "
                    "stack's dynamic stress (a larger ring area or a smaller load on the stack)")
        where = (f"bolt preload {self.preload_n * kn:.1f} kN inside the window {lo * kn:.1f}-{hi * kn:.1f} kN"
                 if lo <= self.preload_n <= hi else
                 f"bolt preload {self.preload_n * kn:.1f} kN OUTSIDE the window {lo * kn:.1f}-{hi * kn:.1f} kN "
                 f"({'the rings go into tension' if self.preload_n < lo else 'the rated compressive stress is exceeded'}"
                 f"); fix: set the bolt preload within the window")
        if f < 1.0:
            where += (f"; the AC field exceeds the depoling field: drive at most {f * self.voltage:.4g} V")
        return f"{where}; {top}"

    def record(self) -> dict:
        return {"voltage_v": self.voltage, "tip_amplitude_m": self.tip_amplitude_m, "preload_n": self.preload_n,
                "p_min_n": self.p_min_n, "p_max_n": _finite(self.p_max_n),
                "drive_factor_max": _finite(self.drive_factor_max),
                "voltage_max_v": _finite(self.drive_factor_max * self.voltage),
                "tip_amplitude_max_m": _finite(self.drive_factor_max * self.tip_amplitude_m),
                "ok": self.ok, "verdict": self.verdict(), "rings": [r.record() for r in self.rings],
                "basis": "ring volume means of the axial stress and field (section force over area); the "
                         "singular peaks at bonded edges are in the utilisation table"}


def design_preload(design) -> float:
    """The design's bolt force on the stack, N (``stack.bolt_preload``; 0 for a design without a bolt)."""
    stack = getattr(design, "stack", None)
    return float(getattr(stack, "bolt_preload", 0.0) or 0.0)


def window_lines(win: PreloadWindows) -> list[str]:
    """The printed preload windows: one line per ring, then the verdict."""
    out = []
    for r in win.rings:
        hi = "no rating" if not math.isfinite(r.p_max_n) else f"{r.p_max_n * 1e-3:.1f} kN"
        out.append(f"  {r.region}: window {r.p_min_n * 1e-3:.1f} kN .. {hi} (mean axial stress amplitude "
                   f"{r.sigma_dyn_pa * 1e-6:.1f} MPa, field {r.efield_v_per_m * 1e-3:.0f} V/mm)")
    return out + [f"  {win.verdict()}"]


def preload_windows(system: PiezoSystem, x_dyn: np.ndarray, voltage: float, tip_amplitude_m: float,
                    preload_n: float = 0.0, *, recovery=None, unit_state: PreloadState | None = None,
                    backend: str | None = None) -> PreloadWindows:
    """The preload window of every ceramic ring for the harmonic state ``x_dyn`` (complex, at
    ``voltage`` V amplitude, tip amplitude ``tip_amplitude_m``; both scale with the drive).

    ``unit_state``: a :func:`preload_solve` of 1 N (solved here when not given); ``recovery`` a
    :class:`fem.stress.StressRecovery` of ``system`` to reuse.
    """
    from .stress import StressRecovery

    check_nonnegative("preload", preload_n, "N")
    rec = recovery or StressRecovery(system)
    unit = unit_state or preload_solve(system, 1.0, backend=backend)
    dyn = ring_means(system, rec.field(x_dyn))
    sta = ring_means(system, rec.field(unit.x / unit.force_n))
    rings = []
    for reg in system.regions:
        if reg.name not in dyn:
            continue
        mat = system.materials.get(reg.material)
        lim = mat.limits() if mat is not None else {}
        rings.append(RingWindow(reg.name, abs(dyn[reg.name][0]), sta[reg.name][0].real, abs(dyn[reg.name][1]),
                                lim.get("compressive_strength"), lim.get("depolarisation_field")))
    if not rings:
        raise ParameterError("preload window", "no ceramic", "the system has no piezoelectric region")
    return PreloadWindows(tuple(rings), float(voltage), float(tip_amplitude_m), float(preload_n))

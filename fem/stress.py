"""Stress, strain and electric field recovered from a solution ``x`` of :mod:`fem.assembly`.

Recovery
--------
The displacement gradient and the potential gradient are evaluated element by element at the
element's own nodes (the 10 nodes of a P2 tetrahedron, 4 of a P1 one; the geometry map of a
curved 10-node cell included), so that peaks on the surface, where fatigue cracks start, are
seen. Per region (constant constitutive data, :class:`fem.assembly.RegionData`):

* metals: ``T = c S``;
* ceramics (stress-charge form): ``T = c^E S - e^T E``, ``D = e S + eps^S E``, ``E = -grad(phi)``.

Voigt order ``xx yy zz yz xz xy``, engineering shear strains (:mod:`fem.materials`). Values are
per element and node (discontinuous between elements); :meth:`StressField.nodal_average`
averages them over the cells of one region that share a node.

Peaks over a cycle
------------------
A harmonic state ``sigma(t) = sigma0 + Re(sigma_hat exp(j w t))`` (``sigma0`` a static state,
e.g. a bolt preload) is a point on an ellipse in stress space. ``von_mises(t)^2`` and
``|E(t)|^2`` are quadratic forms, hence trigonometric polynomials of degree 2 in the phase
``theta = w t``: ``c0 + c1 cos + s1 sin + c2 cos 2theta + s2 sin 2theta``. Without a static part
the maximum is closed form, ``c0 + sqrt(c2^2 + s2^2)``; with one it is found on 72 phases and
refined by Newton steps on the exact derivative (converged to round-off: checked against 20 000
phases in the tests). Principal stresses are not polynomial in the phase: they are evaluated
(closed-form eigenvalues of the 3x3 tensor, checked against ``numpy.linalg.eigvalsh``) on 72
phases and refined by a parabola through the best three: the error is below 1e-5 of the dynamic
amplitude in the tests. Candidates for the peak of a region are preselected with a rigorous
upper bound (``lambda(sigma0) + sqrt(|a|_F^2 + |b|_F^2)``), so only a few points are sampled.

Accuracy of a peak
------------------
:func:`fem.stress_table.stress_table` takes its peaks on the recovered field (per region, the
element-node values averaged over the cells sharing the node; more accurate than the raw values:
1.6 % against 7 % on the cantilever test mesh) and gives, as the estimate of the discretisation
error, the difference between the recovered and the raw element values at the peak (the jump a
Zienkiewicz-Zhu recovery removes). At a re-entrant corner (the flange/horn edge, the horn step,
a slot root) the exact elastic stress is infinite: the peak there grows with mesh refinement and
is a mesh-dependent number; the estimate is then large, and the table gives the peak's location
so that it can be recognised.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from rpud_common import ParameterError

from .assembly import PiezoSystem

__all__ = ["StressRecovery", "StressField", "von_mises", "principal_values", "vm_cycle_peak",
           "efield_cycle_peak", "principal_cycle_extremes", "quadratic_peak", "VM_FORM", "N_PHASES"]

log = logging.getLogger(__name__)

N_PHASES = 72
"""Phases sampled over one cycle (every 5 degrees) before the refinement."""

_CHUNK = 3000          # cells per batch: keeps the (c, 10, 10, 3) gradient tables small

VM_FORM = np.zeros((6, 6))
"""``von_mises^2 = s^T VM_FORM s`` for a Voigt stress vector ``s``."""
VM_FORM[:3, :3] = -0.5
VM_FORM[np.arange(3), np.arange(3)] = 1.0
VM_FORM[np.arange(3, 6), np.arange(3, 6)] = 3.0


# --------------------------------------------------------------------------- tensor algebra


def von_mises(s: np.ndarray) -> np.ndarray:
    """Von Mises equivalent stress of real Voigt stresses ``s`` (..., 6), Pa."""
    s = np.asarray(s, dtype=float)
    return np.sqrt(np.maximum(np.einsum("...i,ij,...j->...", s, VM_FORM, s), 0.0))


def principal_values(s: np.ndarray) -> np.ndarray:
    """Principal values (..., 3), ascending, of real symmetric tensors in Voigt form (..., 6).

    Closed form (trigonometric solution of the characteristic cubic), vectorised; the tests
    compare it with ``numpy.linalg.eigvalsh``.
    """
    s = np.asarray(s, dtype=float)
    xx, yy, zz, yz, xz, xy = np.moveaxis(s, -1, 0)
    m = (xx + yy + zz) / 3.0
    a, b, c = xx - m, yy - m, zz - m
    p = (a * a + b * b + c * c + 2.0 * (xy * xy + xz * xz + yz * yz)) / 6.0
    det = a * (b * c - yz * yz) - xy * (xy * c - yz * xz) + xz * (xy * yz - b * xz)
    sp = np.sqrt(p)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(p > 0, det / (2.0 * np.where(p > 0, p, 1.0) * np.where(sp > 0, sp, 1.0)), 0.0)
    phi = np.arccos(np.clip(r, -1.0, 1.0)) / 3.0
    l1 = m + 2.0 * sp * np.cos(phi)
    l3 = m + 2.0 * sp * np.cos(phi + 2.0 * np.pi / 3.0)
    l2 = 3.0 * m - l1 - l3
    return np.stack([l3, l2, l1], axis=-1)


def _split(hat, static, width):
    hat = np.asarray(hat)
    a = np.real(hat).astype(float)
    b = np.imag(hat).astype(float) if np.iscomplexobj(hat) else np.zeros_like(a)
    s0 = np.zeros_like(a) if static is None else np.broadcast_to(np.asarray(static, float), a.shape)
    if a.shape[-1] != width:
        raise ParameterError("field", a.shape, f"must end in {width} components")
    return a, b, s0


def _trig_max(c0, c1, s1, c2, s2, n_phases=N_PHASES):
    """Max over theta of ``c0 + c1 cos + s1 sin + c2 cos 2 + s2 sin 2`` (arrays of one shape)."""
    c0, c1, s1, c2, s2 = (np.asarray(v, float).ravel() for v in (c0, c1, s1, c2, s2))
    out = np.empty_like(c0)
    theta_best = np.empty_like(c0)
    th = np.linspace(0.0, 2 * np.pi, n_phases, endpoint=False)
    basis = np.stack([np.cos(th), np.sin(th), np.cos(2 * th), np.sin(2 * th)])       # (4, n)
    step = 2 * np.pi / n_phases

    def f(t, k):
        return c0[k] + c1[k] * np.cos(t) + s1[k] * np.sin(t) + c2[k] * np.cos(2 * t) + s2[k] * np.sin(2 * t)

    for lo in range(0, len(c0), 20000):
        k = slice(lo, lo + 20000)
        vals = np.stack([c1[k], s1[k], c2[k], s2[k]], axis=1) @ basis
        j = np.argmax(vals, axis=1)
        t = th[j]
        best = f(t, k)
        for _ in range(6):      # Newton on f' from the best phase; kept only where f grows
            d1 = -c1[k] * np.sin(t) + s1[k] * np.cos(t) - 2 * c2[k] * np.sin(2 * t) + 2 * s2[k] * np.cos(2 * t)
            d2 = -c1[k] * np.cos(t) - s1[k] * np.sin(t) - 4 * c2[k] * np.cos(2 * t) - 4 * s2[k] * np.sin(2 * t)
            dt = np.where(d2 < 0, -d1 / np.where(d2 < 0, d2, -1.0), 0.0)
            tn = t + np.clip(dt, -step, step)
            fn = f(tn, k)
            better = fn > best
            t = np.where(better, tn, t)
            best = np.where(better, fn, best)
        out[k], theta_best[k] = best, t
    return out, theta_best


def _coefficients(P, hat, static, width):
    """Trigonometric coefficients ``(c0, c1, s1, c2, s2)`` of ``x(theta)^T P x(theta)`` for
    ``x = static + Re(hat exp(j theta))``; ``None`` for c1, s1 without a static part."""
    a, b, s0 = _split(hat, static, width)

    def q(x, y):
        return np.einsum("...i,ij,...j->...", x, P, y)

    qaa, qbb, qab = q(a, a), q(b, b), q(a, b)
    c0, c2, s2 = (qaa + qbb) / 2, (qaa - qbb) / 2, -qab
    if static is None or not np.any(s0):
        return c0, None, None, c2, s2
    return c0 + q(s0, s0), 2 * q(s0, a), -2 * q(s0, b), c2, s2


def _quadratic_cycle_max(P, hat, static, width):
    c0, c1, s1, c2, s2 = _coefficients(P, hat, static, width)
    if c1 is None:
        val = c0 + np.sqrt(c2 * c2 + s2 * s2)
        theta = 0.5 * np.arctan2(s2, c2)
        return np.sqrt(np.maximum(val, 0.0)), theta
    val, theta = _trig_max(c0, c1, s1, c2, s2)
    shape = np.shape(c0)
    return np.sqrt(np.maximum(val, 0.0)).reshape(shape), theta.reshape(shape)


def quadratic_peak(kind: str, hat, static=None) -> tuple[int, float]:
    """(index, value) of the largest cycle peak among the rows of ``hat`` (n, 6 or 3): ``kind``
    ``"von_mises"`` or ``"efield"``. Same result as the argmax of :func:`vm_cycle_peak` /
    :func:`efield_cycle_peak`, searching only the rows whose upper bound
    ``c0 + |(c1, s1)| + |(c2, s2)|`` reaches the best lower bound (four phases)."""
    P, width = (VM_FORM, 6) if kind == "von_mises" else (np.eye(3), 3)
    c0, c1, s1, c2, s2 = _coefficients(P, hat, static, width)
    if c1 is None:
        val = np.sqrt(np.maximum(c0 + np.sqrt(c2 * c2 + s2 * s2), 0.0))
        i = int(np.argmax(val))
        return i, float(val[i])
    ub = c0 + np.hypot(c1, s1) + np.hypot(c2, s2)
    lb = np.max([c0 + c1 + c2, c0 + s1 - c2, c0 - c1 + c2, c0 - s1 - c2], axis=0)
    cand = np.flatnonzero(ub >= lb.max())
    val, _ = _trig_max(c0[cand], c1[cand], s1[cand], c2[cand], s2[cand])
    k = int(np.argmax(val))
    return int(cand[k]), float(np.sqrt(max(val[k], 0.0)))


def vm_cycle_peak(hat, static=None) -> tuple[np.ndarray, np.ndarray]:
    """Peak over a cycle of the von Mises stress of ``static + Re(hat exp(j theta))``.

    ``hat`` (..., 6) complex amplitude (or real: a static state), ``static`` (..., 6) real or
    None; Pa. Returns ``(peak, theta)``: the peak and the phase (rad) where it occurs.
    """
    return _quadratic_cycle_max(VM_FORM, hat, static, 6)


def efield_cycle_peak(hat, static=None) -> tuple[np.ndarray, np.ndarray]:
    """Peak over a cycle of ``|E|`` for ``static + Re(hat exp(j theta))`` (..., 3), V/m."""
    return _quadratic_cycle_max(np.eye(3), hat, static, 3)


def principal_cycle_extremes(hat, static=None, n_phases: int = N_PHASES) -> tuple[np.ndarray, np.ndarray]:
    """Largest first and smallest third principal stress over a cycle (each (...,), Pa) of
    ``static + Re(hat exp(j theta))``: ``n_phases`` samples, refined by a parabola through the
    best sample and its neighbours (never below the best sample)."""
    a, b, s0 = _split(hat, static, 6)
    shape = a.shape[:-1]
    a, b, s0 = (x.reshape(-1, 6) for x in (a, b, s0))
    th = np.linspace(0.0, 2 * np.pi, n_phases, endpoint=False)
    h = th[1] - th[0]

    def at(t):          # principal values at phases t (n,) or (n, k)
        t = np.asarray(t)
        cs, sn = np.cos(t)[..., None], np.sin(t)[..., None]
        if t.ndim == 1:
            return principal_values(s0 + a * cs - b * sn)
        return principal_values(s0[:, None] + a[:, None] * cs - b[:, None] * sn)

    out = []
    for sign, col in ((1.0, 2), (-1.0, 0)):
        vals = sign * at(np.broadcast_to(th, (len(a), n_phases)))[..., col]
        j = np.argmax(vals, axis=1)
        rows = np.arange(len(a))
        f0 = vals[rows, j]
        fm, fp = vals[rows, (j - 1) % n_phases], vals[rows, (j + 1) % n_phases]
        den = fm - 2 * f0 + fp
        off = np.where(den < 0, 0.5 * (fm - fp) / np.where(den < 0, den, -1.0), 0.0) * h
        t_ref = th[j] + np.clip(off, -h, h)
        f_ref = sign * at(t_ref)[:, col]
        out.append(sign * np.maximum(f0, f_ref))
    return out[0].reshape(shape), out[1].reshape(shape)


# --------------------------------------------------------------------------- recovery


@dataclass(eq=False)
class StressField:
    """Element-node values of one solution (real: static; complex: harmonic amplitudes).

    ``cells`` (m,) cell indices; ``nodes`` (m, k) their global (P2) nodes; ``points`` (m, k, 3)
    m; ``region`` (m,) index into ``system.regions``; ``stress`` (m, k, 6) Pa; ``strain``
    (m, k, 6) (engineering shear); ``efield`` (m, k, 3) V/m and ``dfield`` (m, k, 3) C/m^2 (zero
    in metals).
    """

    system: PiezoSystem
    cells: np.ndarray
    nodes: np.ndarray
    points: np.ndarray
    region: np.ndarray
    stress: np.ndarray
    strain: np.ndarray
    efield: np.ndarray
    dfield: np.ndarray
    periodic: object = field(default=None, repr=False)
    _averages: dict = field(default_factory=dict, repr=False)

    def nodal_average(self, name: str = "stress") -> np.ndarray:
        """``name`` ("stress", "efield"...) averaged over the cells of each region that share a
        node, returned at every element node (same shape as the field; computed once).

        On a ``k = 0`` sector (``periodic``: its :class:`geometry.sector.SectorPairs`) a node
        on a cut face or on the axis is shared with the neighbouring sectors: its average takes
        their cells too, as the sector's own cells rotated (:func:`periodic_sums`), so that the
        recovered field is the whole drill's."""
        if name in self._averages:
            return self._averages[name]
        v = getattr(self, name)
        out = np.zeros_like(v)
        n = self.system.n_nodes
        for r in np.unique(self.region):
            sel = self.region == r
            keys = self.nodes[sel].ravel()
            vals = v[sel].reshape(-1, v.shape[-1])
            count = np.bincount(keys, minlength=n).astype(float)
            avg = np.zeros((n, v.shape[-1]), dtype=v.dtype)
            for c in range(v.shape[-1]):
                avg[:, c] = np.bincount(keys, weights=vals[:, c].real, minlength=n)
                if np.iscomplexobj(v):
                    avg[:, c] = avg[:, c] + 1j * np.bincount(keys, weights=vals[:, c].imag, minlength=n)
            if self.periodic is not None:
                avg, count = periodic_sums(avg, count, self.periodic)
            avg /= np.maximum(count, 1)[:, None]
            out[sel] = avg[self.nodes[sel]]
        self._averages[name] = out
        return out


def _rotate(v: np.ndarray, angle: float) -> np.ndarray:
    """Rows ``v`` (..., 6) Voigt tensors or (..., 3) vectors turned by ``angle`` (rad) about z."""
    from geometry.sector import rotation

    R = rotation(angle)
    if v.shape[-1] == 3:
        return v @ R.T
    i, j = (0, 1, 2, 1, 0, 0), (0, 1, 2, 2, 2, 1)
    T = np.zeros(v.shape[:-1] + (3, 3), dtype=v.dtype)
    for k, (a, b) in enumerate(zip(i, j)):
        T[..., a, b] = T[..., b, a] = v[..., k]
    T = np.einsum("ab,...bc,dc->...ad", R, T, R)
    return np.stack([T[..., a, b] for a, b in zip(i, j)], axis=-1)


def periodic_sums(sums: np.ndarray, count: np.ndarray, pairs) -> tuple[np.ndarray, np.ndarray]:
    """Per-node sums (n, c) and counts (n,) of one region on a ``k = 0`` sector completed with
    the cells of the neighbouring sectors (``pairs``: :class:`geometry.sector.SectorPairs`).

    A near cut-face node is the far node of the sector before, turned by ``-alpha``: its cells
    add the far node's sums turned back; the far node holds the near node's result turned by
    ``alpha``. An axis node is shared by all ``N`` copies: the mean of its sums turned by
    ``s alpha``. A field of harmonic ``k = 0`` makes this the whole drill's nodal average."""
    n_sec = int(pairs.sectors)
    alpha = 2 * np.pi / n_sec
    sums, count = sums.copy(), count.copy()
    near, far = pairs.near, pairs.far
    joined = sums[near] + _rotate(sums[far], -alpha)
    sums[near], sums[far] = joined, _rotate(joined, alpha)
    count[near] = count[far] = count[near] + count[far]
    ax = pairs.axis
    if len(ax):
        sums[ax] = np.mean([_rotate(sums[ax], s * alpha) for s in range(n_sec)], axis=0)
    return sums, count


class StressRecovery:
    """The gradient tables of a system, computed once; :meth:`field` applies them to a solution.

    Parameters
    ----------
    system : PiezoSystem
    """

    def __init__(self, system: PiezoSystem):
        from skfem import CellBasis

        self.system = system
        elem = system.basis.elem
        X = np.asarray(elem.doflocs, float).T                     # (3, k): the element's nodes
        W = np.full(X.shape[1], 1.0 / X.shape[1])                   # weights unused
        edofs = np.asarray(system.basis.element_dofs)
        self._chunks = []
        cell_region = np.asarray(system.mesh.cell_region)
        for r in range(len(system.regions)):
            cells = np.flatnonzero(cell_region == r)
            for lo in range(0, len(cells), _CHUNK):
                cc = cells[lo:lo + _CHUNK]
                b = CellBasis(system.skmesh, elem, quadrature=(X, W), elements=cc)
                # dN[c, q, j, k] = d N_j / d x_k at node q of cell c
                dN = np.stack([b.basis[j][0].grad for j in range(X.shape[1])], axis=0)   # (j, 3, c, q)
                dN = np.ascontiguousarray(np.transpose(dN, (2, 3, 0, 1)))
                self._chunks.append((r, cc, edofs[:, cc].T.copy(), dN))
        self.nodes = np.concatenate([ch[2] for ch in self._chunks]) if self._chunks else np.zeros((0, X.shape[1]), int)
        self.cells = np.concatenate([ch[1] for ch in self._chunks])
        self.region = np.concatenate([np.full(len(ch[1]), ch[0]) for ch in self._chunks])
        self.points = system.nodes[self.nodes]
        self.periodic = None
        if getattr(system, "sectors", 0) and getattr(system, "tie", None) is not None:
            from geometry.sector import sector_pairs

            self.periodic = sector_pairs(system.nodes, int(system.sectors))

    def field(self, x: np.ndarray) -> StressField:
        """Stress, strain, E and D of the solution ``x`` (real or complex, full length)."""
        sysm = self.system
        x = np.asarray(x)
        if x.shape != (sysm.ndof,):
            raise ParameterError("x", x.shape, f"must be one solution vector of length {sysm.ndof}")
        u = sysm.displacement(x)
        phi = np.nan_to_num(sysm.potential(x)) if sysm.has_piezo else None
        dtype = np.result_type(x.dtype, float)
        k = self.nodes.shape[1]
        m = len(self.cells)
        stress = np.zeros((m, k, 6), dtype)
        strain = np.zeros((m, k, 6), dtype)
        efield = np.zeros((m, k, 3), dtype)
        dfield = np.zeros((m, k, 3), dtype)
        pos = 0
        for r, cc, ed, dN in self._chunks:
            rd = sysm.regions[r]
            sl = slice(pos, pos + len(cc))
            pos += len(cc)
            G = np.einsum("cji,cqjk->cqik", u[ed], dN)
            S = np.stack([G[..., 0, 0], G[..., 1, 1], G[..., 2, 2], G[..., 1, 2] + G[..., 2, 1],
                          G[..., 0, 2] + G[..., 2, 0], G[..., 0, 1] + G[..., 1, 0]], axis=-1)
            T = S @ rd.c.T
            if rd.piezo:
                E = -np.einsum("cj,cqjk->cqk", phi[ed], dN)
                T = T - E @ rd.e
                efield[sl] = E
                dfield[sl] = S @ rd.e.T + E @ rd.eps.T
            stress[sl], strain[sl] = T, S
        return StressField(sysm, self.cells, self.nodes, self.points, self.region, stress, strain, efield, dfield,
                           self.periodic)

"""Peak stresses and fields per region, against the materials' limits: the utilisation table.

Rows (one per region and quantity), all peaks over one drive cycle of the harmonic state plus an
optional static state (bolt preload), see :mod:`fem.stress`:

* metal region: peak von Mises stress against ``fatigue_strength`` (the whole peak of static +
  dynamic stress against a fully reversed fatigue amplitude: conservative, no mean-stress
  correction);
* ceramic region: largest principal stress (tension) against ``tensile_strength``, most negative
  principal stress (compression) against ``compressive_strength``, peak ``|E|`` against
  ``depolarisation_field``.

Each peak is also given away from the singular edges (:func:`bonded_edge_nodes`: the cells
touching them left out), where the elastic solution is singular: a bonded interface of two
different materials (or polings) meeting the free surface (a ring's rim or bore on an electrode
plane, the rings on the flange), a sharp corner where two regions meet (an unfilleted
flange/horn edge), and a re-entrant crease of the surface inside one region (an unfilleted horn
step, the roots of the coupler's slots and teeth). That value converges with the mesh, the peak itself need not. A row whose
peak lies on such an edge is marked ``singular`` and its headline (:attr:`StressRow.headline`,
the utilisation, the worst row) is the off-edge value. A filleted corner
(:mod:`geometry.fillets`) is not singular: its peak is the headline. A limit the material record
does not give is ``None`` (``n/a``). Each row has the location of its peak and an estimate of its
discretisation error (:mod:`fem.stress`): peaks are taken on the recovered field (per region, the
element-node values averaged at each node), the estimate is the difference to the raw element
values at that node; :func:`converged_table` replaces it by the two-mesh (Richardson) estimate
from a coarser mesh's table.

:func:`stress_sweep` repeats the peaks along a harmonic sweep (modal superposition basis).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rpud_common import ParameterError
from rpud_common.result import Result

from .convergence import two_level_error
from .stress import (StressField, StressRecovery, efield_cycle_peak, principal_cycle_extremes,
                     principal_values, quadratic_peak, vm_cycle_peak)

__all__ = ["StressRow", "StressTable", "stress_table", "StressSweep", "stress_sweep", "QUANTITIES",
           "bonded_edge_nodes", "converged_table", "STRESS_ORDER", "CORNER_ANGLE_DEG", "OFF_EDGE_DISTANCE"]

STRESS_ORDER = 2.0
"""Convergence order of a recovered stress peak at a smooth point with P2 elements (the
displacement's h^3 less one derivative): the order of the two-mesh estimate of
:func:`converged_table`. Observed on the fillets of the (r, z) reference: 2.6-2.9
(tests/test_fillets.py)."""

OFF_EDGE_DISTANCE = 0.5e-3
"""The peak "off the singular edges" of a region leaves out the cells with a node within this
distance (m) of a singular edge, or within a tenth of the region's smallest extent if that is
less (a tenth of a default ring's thickness): a fixed distance, so that the off-edge peak
converges with the mesh (the cells touching an edge are micrometres wide on a graded mesh)."""

CORNER_ANGLE_DEG = 60.0
"""Two regions of one material meeting on the surface make a singular edge when their boundary
facets' mean normals at the shared node differ by more than this (a sharp corner turns by 90
degrees; a filleted junction, whose arc the two regions share, by the arc's turn over about one
element: at most 45 degrees with the free mesh's two elements per quarter arc)."""

QUANTITIES = {
    # key: (label, unit for display, display scale, limit field)
    "von_mises": ("von Mises", "MPa", 1e-6, "fatigue_strength"),
    "principal_max": ("max principal (tension)", "MPa", 1e-6, "tensile_strength"),
    "principal_min": ("min principal (compression)", "MPa", 1e-6, "compressive_strength"),
    "efield": ("|E|", "kV/mm", 1e-6, "depolarisation_field"),
}
_SI_UNIT = {"von_mises": "Pa", "principal_max": "Pa", "principal_min": "Pa", "efield": "V/m"}


@dataclass(frozen=True)
class StressRow:
    """One peak: ``value`` (SI: Pa or V/m; signed for the principal stresses), its ``location``
    (m), the material ``limit`` (SI, None if the record has none), ``error_estimate`` (SI,
    the jump between the element value and the region's nodal average at that node)."""

    region: str
    part: str
    material: str
    quantity: str
    value: float
    location: tuple
    limit: float | None
    error_estimate: float
    value_off_edges: float | None = None
    location_off_edges: tuple | None = None
    singular: bool = False

    @property
    def headline(self) -> float:
        """The value to read: the off-edge peak if the peak lies on a singular edge, else the peak."""
        return self.value_off_edges if self.singular and self.value_off_edges is not None else self.value

    @property
    def utilisation(self) -> float | None:
        """Headline / limit (a compressive peak by its magnitude, a tension peak only if > 0)."""
        if self.limit is None:
            return None
        v = -self.headline if self.quantity == "principal_min" else self.headline
        return max(v, 0.0) / self.limit

    @property
    def utilisation_off_edges(self) -> float | None:
        """The same for the peak away from the bonded free edges (None if n/a)."""
        if self.limit is None or self.value_off_edges is None:
            return None
        v = -self.value_off_edges if self.quantity == "principal_min" else self.value_off_edges
        return max(v, 0.0) / self.limit

    def record(self) -> dict:
        return {"region": self.region, "part": self.part, "material": self.material, "quantity": self.quantity,
                "unit": _SI_UNIT[self.quantity], "peak": self.value, "error_estimate": self.error_estimate,
                "location_m": list(self.location), "limit": self.limit,
                "limit_field": QUANTITIES[self.quantity][3], "utilisation": self.utilisation,
                "peak_off_edges": self.value_off_edges,
                "location_off_edges_m": None if self.location_off_edges is None else list(self.location_off_edges),
                "utilisation_off_edges": self.utilisation_off_edges, "singular": self.singular,
                "headline": self.headline}


@dataclass(repr=False)
class StressTable(Result):
    """The utilisation table of one state (see the module docstring).

    ``freq_hz``/``voltage`` describe the harmonic state (None for a static one), ``preload_n``
    the bolt preload added (0: none).
    """

    rows: tuple
    freq_hz: float | None
    voltage: float | None
    preload_n: float
    note: str = ""

    def worst(self) -> StressRow | None:
        rated = [r for r in self.rows if r.utilisation is not None]
        return max(rated, key=lambda r: r.utilisation) if rated else None

    def _headline(self) -> str:
        w = self.worst()
        state = f"{self.voltage:g} V at {self.freq_hz:.1f} Hz" if self.freq_hz else "static"
        if self.preload_n:
            state += f" + preload {self.preload_n:g} N"
        if w is None:
            return f"{state}: {len(self.rows)} peaks, no limits given"
        return (f"{state}: worst {w.region} {QUANTITIES[w.quantity][0]} "
                f"{_show(w.quantity, w.headline)}{' off a singular edge' if w.singular else ''} = "
                f"{100 * w.utilisation:.1f} % of its limit")

    def _record(self) -> dict:
        return {"freq_hz": self.freq_hz, "voltage_v": self.voltage, "preload_n": self.preload_n,
                "rows": [r.record() for r in self.rows], "note": self.note,
                "method": "recovered field (element-node values of P2 tetrahedra averaged per region at each "
                          "node); peak over the cycle (von Mises, |E|: exact; principal stresses: 72 phases + "
                          "parabolic refinement); error estimate = difference between recovered and raw element "
                          "values around the peak (ZZ), or the two-mesh Richardson estimate (converged tables); singular at "
                          "bonded bimaterial free edges and sharp region junctions (peak_off_edges leaves the cells "
                          "touching them out; a singular row's headline and utilisation are its off-edge values)"}

    def text(self) -> str:
        """The table as plain text (units in the header, location in mm)."""
        head = (f"{'region (part, material)':34s} {'quantity':28s} {'peak':>9s} {'± est':>8s} {'unit':6s} "
                f"{'location x, y, z (mm)':22s} {'off edges':>9s} {'limit':>7s} {'utilisation':>11s} {'off edges':>9s}")
        lines = [head, "-" * len(head)]
        for r in self.rows:
            label, unit, scale, _ = QUANTITIES[r.quantity]
            loc = ", ".join(f"{1e3 * c:.1f}" for c in r.location)
            lim = "n/a" if r.limit is None else f"{r.limit * scale:.4g}"
            off = "-" if r.value_off_edges is None else f"{r.value_off_edges * scale:.4g}"
            label = label + (" *" if r.singular else "")
            lines.append(f"{f'{r.region} ({r.part}, {r.material})':34s} {label:28s} {r.value * scale:9.4g} "
                         f"{r.error_estimate * scale:8.2g} {unit:6s} {loc:22s} {off:>9s} {lim:>7s} "
                         f"{_pct(r.utilisation):>11s} {_pct(r.utilisation_off_edges):>9s}")
        if any(r.singular for r in self.rows):
            lines.append("* peak on a singular edge (bonded bimaterial edge or sharp corner): the utilisation is "
                         "the off-edge value's")
        return "\n".join(lines)

    def markdown(self) -> str:
        """The table in Markdown (the pipeline report)."""
        lines = ["| region (part, material) | quantity | peak | ± est. | location x, y, z (mm) | peak off edges "
                 "| limit | utilisation | off edges |", "|---|---|---|---|---|---|---|---|---|"]
        for r in self.rows:
            label, unit, scale, _ = QUANTITIES[r.quantity]
            loc = ", ".join(f"{1e3 * c:.1f}" for c in r.location)
            lim = "n/a" if r.limit is None else f"{r.limit * scale:.4g} {unit}"
            off = "-" if r.value_off_edges is None else f"{r.value_off_edges * scale:.4g} {unit}"
            mark = " (on a singular edge: utilisation off it)" if r.singular else ""
            lines.append(f"| {r.region} ({r.part}, {r.material}) | {label} | {r.value * scale:.4g} {unit}{mark} "
                         f"| {r.error_estimate * scale:.2g} | {loc} | {off} | {lim} | {_pct(r.utilisation)} "
                         f"| {_pct(r.utilisation_off_edges)} |")
        return "\n".join(lines)


def _pct(u):
    return "n/a" if u is None else f"{100 * u:.1f} %"


def _show(q, v):
    _, unit, scale, _ = QUANTITIES[q]
    return f"{v * scale:.4g} {unit}"


def _frob(a, b):
    """sqrt(|a|_F^2 + |b|_F^2) of Voigt tensors (shear counted twice): bounds the spectral norm
    of ``a cos - b sin`` at every phase."""
    w = np.array([1, 1, 1, 2, 2, 2], float)
    return np.sqrt((a * a * w).sum(-1) + (b * b * w).sum(-1))


def _principal_peak(hat, s0, sign: float):
    """(index, value) of the largest sigma_1 (``sign`` +1) or of the most negative sigma_3
    (``sign`` -1) over the cycle among the rows of ``hat`` (n, 6) complex and ``s0`` (n, 6)
    real; only the rows whose rigorous bound reaches the best of eight sampled phases are
    searched (72 phases + refinement)."""
    a, b = hat.real, hat.imag
    col = 2 if sign > 0 else 0
    th = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    coarse = principal_values(s0[:, None] + a[:, None] * np.cos(th)[:, None] - b[:, None] * np.sin(th)[:, None])
    lb = (sign * coarse[..., col]).max(axis=1)
    ub = sign * principal_values(s0)[:, col] + _frob(a, b)
    cand = np.flatnonzero(ub >= lb.max())
    p1, p3 = principal_cycle_extremes(hat[cand], s0[cand])
    vals = sign * (p1 if sign > 0 else p3)
    k = int(np.argmax(vals))
    return int(cand[k]), float(sign * vals[k])


def bonded_edge_nodes(system) -> np.ndarray:
    """(n_nodes,) bool: the singular edges, nodes on the outer surface shared by cells of two or
    more regions that either differ in material or poling (a bonded bimaterial edge: ring bores
    and rims at the electrode planes, the rings on the flange) or meet at a sharp corner (their
    boundary facets' mean normals there differ by more than :data:`CORNER_ANGLE_DEG`: an
    unfilleted flange/horn edge), and the re-entrant creases of the surface whatever the regions
    (:func:`_reentrant_vertices`: an unfilleted horn step, a slot's root, a tooth's root). In the
    elastic solution the stress there is singular. Two regions of one material meeting on a
    smooth surface (a filleted flange/horn edge) and a fillet's arc are not singular."""
    n = system.n_nodes
    skm = system.skmesh
    bf = np.asarray(skm.boundary_facets())
    cell_region = np.asarray(system.mesh.cell_region)
    edofs = np.asarray(system.basis.element_dofs)
    regions = system.mesh.regions
    if not len(bf):     # pragma: no cover - a mesh has a surface
        return np.zeros(n, bool)
    # outward unit normals of the boundary facets (their corners), and each facet's region
    p = np.asarray(skm.p).T
    f = np.asarray(skm.facets)[:, bf]
    nrm = np.cross(p[f[1]] - p[f[0]], p[f[2]] - p[f[0]])
    cell = np.asarray(skm.f2t)[0, bf]
    out = p[f].mean(axis=0) - p[np.asarray(skm.t)[:, cell]].mean(axis=0)
    nrm *= np.sign(np.einsum("ij,ij->i", nrm, out))[:, None]
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    # a sector's cut faces are no surface, the whole drill continues there: facets on a plane
    # through the axis that bounds the whole mesh (a tooth's radial wall has metal beyond its
    # plane), with a partner on the other cut plane
    centre = p[f].mean(axis=0)
    cut = (np.abs(nrm[:, 2]) < 1e-6) & (np.abs(np.einsum("ij,ij->i", nrm[:, :2], centre[:, :2]))
                                         < 1e-6 * np.linalg.norm(centre[:, :2], axis=1) + 1e-12)
    if cut.any():
        u, inv = np.unique(np.round(nrm[cut, :2], 6), axis=0, return_inverse=True)
        reach = (p[:, :2] @ u.T).max(axis=0)
        cut[cut] = reach[inv.ravel()] <= 1e-9 * (1.0 + np.abs(p).max())
        cut[cut] = _periodic_partner(centre[cut])
    bf, f, nrm, cell = bf[~cut], f[:, ~cut], nrm[~cut], cell[~cut]
    cos_max = np.cos(np.radians(CORNER_ANGLE_DEG))
    out_mask = np.zeros(n, bool)
    out_mask[np.asarray(system.basis.nodal_dofs)[0, _reentrant_vertices(p, f, nrm, cos_max)]] = True
    # the nodes of each boundary facet: its corners, and its edges' mid nodes (P2)
    basis = system.basis
    fdofs = [np.asarray(basis.nodal_dofs)[0, f]]
    if np.asarray(basis.edge_dofs).size:
        fdofs.append(np.asarray(basis.edge_dofs)[0, np.asarray(skm.f2e)[:, bf]])
    fdofs = np.concatenate(fdofs)
    # per region: the summed normals of its boundary facets at each surface node
    present, sums = [], []
    for r in range(len(regions)):
        mark = np.zeros(n, bool)
        mark[np.unique(edofs[:, cell_region == r])] = True
        sel = cell_region[cell] == r
        acc = np.zeros((n, 3))
        for row in fdofs[:, sel]:
            np.add.at(acc, row, nrm[sel])
        present.append(mark & (np.linalg.norm(acc, axis=1) > 0))
        sums.append(acc)
    for a in range(len(regions)):
        for b in range(a + 1, len(regions)):
            both = present[a] & present[b]
            if not both.any():
                continue
            ra, rb = regions[a], regions[b]
            if (ra.material, ra.poling) != (rb.material, rb.poling):
                out_mask |= both
                continue
            na, nb = sums[a][both], sums[b][both]
            cos = np.einsum("ij,ij->i", na, nb) / (np.linalg.norm(na, axis=1) * np.linalg.norm(nb, axis=1))
            idx = np.flatnonzero(both)
            out_mask[idx[cos < cos_max]] = True
    return out_mask


def _periodic_partner(centre: np.ndarray) -> np.ndarray:
    """(n,) bool for facets (centroids ``centre`` (n, 3), m) on the planes through the axis: True
    where the other such plane has a facet at the same (r, z) (a sector's cut: its neighbour
    continues there), False where it has none (a real free face lying in a cut plane, e.g. a
    tooth's wall). With fewer than two planes every facet is a cut's."""
    from scipy.spatial import cKDTree

    out = np.ones(len(centre), bool)
    if not len(centre):
        return out
    theta = np.round(np.arctan2(centre[:, 1], centre[:, 0]), 6)
    planes = np.unique(theta)
    if len(planes) != 2:
        return out
    rz = np.c_[np.hypot(centre[:, 0], centre[:, 1]), centre[:, 2]]
    tol = 1e-9 * (1.0 + np.abs(rz).max())
    for a, b in ((planes[0], planes[1]), (planes[1], planes[0])):
        on, other = theta == a, theta == b
        if other.any():
            out[on] = cKDTree(rz[other]).query(rz[on])[0] < tol
        else:
            out[on] = False
    return out


def _reentrant_vertices(p: np.ndarray, f: np.ndarray, nrm: np.ndarray, cos_max: float) -> np.ndarray:
    """Mesh vertices on the re-entrant creases of the surface: the edges shared by two boundary
    facets (``f`` (3, n) vertex indices, ``nrm`` (n, 3) outward unit normals, ``p`` the vertices)
    whose normals turn by more than :data:`CORNER_ANGLE_DEG` (``cos_max``) and where each
    facet's centroid lies in front of the other's plane: a concave edge (270-degree material
    angle at a right-angled step), whose elastic stress is singular. A convex edge (centroids
    behind the planes) and a fillet's arc (at most 45 degrees between neighbouring facets) are
    not among them."""
    nf = f.shape[1]
    e = np.sort(np.concatenate([f[[0, 1]], f[[1, 2]], f[[2, 0]]], axis=1), axis=0)
    owner = np.tile(np.arange(nf), 3)
    key = e[0].astype(np.int64) * (int(e.max()) + 1) + e[1]
    order = np.argsort(key, kind="stable")
    pair = np.flatnonzero(key[order][1:] == key[order][:-1])
    i, j = owner[order[pair]], owner[order[pair + 1]]
    c = p[f].mean(axis=0)
    turn = np.einsum("ij,ij->i", nrm[i], nrm[j]) < cos_max
    concave = (np.einsum("ij,ij->i", nrm[i], c[j] - c[i]) > 0) & (np.einsum("ij,ij->i", nrm[j], c[i] - c[j]) > 0)
    return np.unique(e[:, order[pair[turn & concave]]])


def _region_limits(system):
    out = []
    for rd in system.regions:
        mat = system.materials.get(rd.material)
        out.append(mat.limits() if mat is not None and hasattr(mat, "limits") else {})
    return out

@dataclass(frozen=True)
class _CycleFields:
    """The stress and field amplitudes (``hat``) and static parts (``0``) at the element nodes:
    recovered (averaged over the region's cells sharing a node) and raw (the element's own)."""

    hat_s: np.ndarray
    hat_e: np.ndarray
    s0: np.ndarray
    e0: np.ndarray
    raw_hat_s: np.ndarray
    raw_hat_e: np.ndarray
    raw_s0: np.ndarray
    raw_e0: np.ndarray


def _cycle_fields(dynamic: StressField | None, static: StressField | None, ref: StressField) -> _CycleFields:
    """The peaks are taken on the recovered field (more accurate, e.g. 1.6 % vs 7 % on the
    cantilever test); the raw element values at the same node give the error estimate."""
    zs, ze = np.zeros(ref.stress.shape, complex), np.zeros(ref.efield.shape, complex)
    return _CycleFields(
        hat_s=dynamic.nodal_average("stress").astype(complex) if dynamic is not None else zs,
        hat_e=dynamic.nodal_average("efield").astype(complex) if dynamic is not None else ze,
        s0=static.nodal_average("stress").real if static is not None else zs.real,
        e0=static.nodal_average("efield").real if static is not None else ze.real,
        raw_hat_s=dynamic.stress.astype(complex) if dynamic is not None else zs,
        raw_hat_e=dynamic.efield.astype(complex) if dynamic is not None else ze,
        raw_s0=static.stress.real if static is not None else zs.real,
        raw_e0=static.efield.real if static is not None else ze.real)


def _edge_distances(system, edge: np.ndarray | None, pairs=None) -> np.ndarray | None:
    """Each node's distance to the nearest singular-edge node (None: no singular edge).

    On a ``k = 0`` sector (``pairs``: its :class:`geometry.sector.SectorPairs`) the edges are
    the whole drill's: a far cut-face node is its near partner turned (the whole drill has one
    node there, flagged as the near one is), and the neighbouring sectors' edges, the sector's
    own turned by +-360/N degrees, count too (a node near a cut can lie nearer to them)."""
    from scipy.spatial import cKDTree

    if edge is None:
        edge = bonded_edge_nodes(system)
    if pairs is not None:
        edge = edge.copy()
        edge[pairs.far] = edge[pairs.near]
    if not edge.any():
        return None
    pts = system.nodes[edge]
    if pairs is not None:
        from geometry.sector import rotation

        alpha = 2 * np.pi / pairs.sectors
        pts = np.concatenate([pts, pts @ rotation(alpha).T, pts @ rotation(-alpha).T])
    return cKDTree(pts).query(system.nodes)[0]


def _region_rows(ref: StressField, ri: int, rd, f: _CycleFields, lim: dict, detail: bool, off_edges: bool,
                 edge_distance: np.ndarray | None) -> list[StressRow]:
    """The rows of region ``ri``: von Mises for a passive part; the principal extremes and the
    field for a ceramic."""
    sel = np.flatnonzero(ref.region == ri)
    if len(sel) == 0:
        return []
    part = ref.system.mesh.regions[ri].part
    rows: list[StressRow] = []
    pts = ref.points[sel].reshape(-1, 3)
    hs, s0r = f.hat_s[sel].reshape(-1, 6), f.s0[sel].reshape(-1, 6)
    ahs, as0 = f.raw_hat_s[sel].reshape(-1, 6), f.raw_s0[sel].reshape(-1, 6)
    nodes_r = ref.nodes[sel]
    k = nodes_r.shape[1]

    def patch(i):
        """Element-node entries of the region's cells that touch the node of entry ``i``."""
        cells = np.flatnonzero((nodes_r == nodes_r.ravel()[i]).any(axis=1))
        return (cells[:, None] * k + np.arange(k)[None, :]).ravel()

    # entries of the cells whose nodes all lie farther than the region's band from every
    # singular edge: a fixed distance, so that the off-edge peak converges with the mesh (the
    # cells touching the edge alone are micrometres wide on a graded mesh)
    off, band = np.zeros(0, dtype=np.int64), 0.0
    if off_edges:
        band = min(OFF_EDGE_DISTANCE, 0.1 * float(np.ptp(pts, axis=0).min()))
        far = edge_distance[nodes_r] > band if edge_distance is not None else np.ones(nodes_r.shape, bool)
        off = np.flatnonzero(np.repeat(far.all(axis=1), k))

    def row(q, peak, fn, rec, raw):
        # error estimate: the largest difference between recovered and raw element values of
        # the quantity on the patch of cells around the peak node
        i, value = peak(*rec)
        est, v_off, loc_off = 0.0, None, None
        if detail:
            j = patch(i)
            est = np.max(np.abs(fn(*(a[j] for a in rec)) - fn(*(a[j] for a in raw))))
        if off_edges and len(off):
            i_off, v_off = peak(*(a[off] for a in rec))
            loc_off = tuple(float(c) for c in pts[off[i_off]])
        rows.append(StressRow(rd.name, part, rd.material, q, float(value), tuple(float(c) for c in pts[i]),
                              lim.get(QUANTITIES[q][3]), float(est), v_off, loc_off,
                              bool(edge_distance is not None and edge_distance[nodes_r.ravel()[i]] <= band)))

    if not rd.piezo:
        row("von_mises", lambda h, s: quadratic_peak("von_mises", h, s),
            lambda h, s: vm_cycle_peak(h, s)[0], (hs, s0r), (ahs, as0))
        return rows
    row("principal_max", lambda h, s: _principal_peak(h, s, 1.0),
        lambda h, s: principal_cycle_extremes(h, s)[0], (hs, s0r), (ahs, as0))
    row("principal_min", lambda h, s: _principal_peak(h, s, -1.0),
        lambda h, s: principal_cycle_extremes(h, s)[1], (hs, s0r), (ahs, as0))
    he, e0r = f.hat_e[sel].reshape(-1, 3), f.e0[sel].reshape(-1, 3)
    ahe, ae0 = f.raw_hat_e[sel].reshape(-1, 3), f.raw_e0[sel].reshape(-1, 3)
    row("efield", lambda h, s: quadratic_peak("efield", h, s),
        lambda h, s: efield_cycle_peak(h, s)[0], (he, e0r), (ahe, ae0))
    return rows


def stress_table(dynamic: StressField | None, static: StressField | None = None, *, freq_hz: float | None = None,
                 voltage: float | None = None, preload_n: float = 0.0, regions=None,
                 detail: bool = True, off_edges: bool | None = None, edge: np.ndarray | None = None) -> StressTable:
    """Peaks per region of ``static + Re(dynamic exp(j w t))`` over a cycle (see the module docstring).

    Parameters
    ----------
    dynamic : StressField of a harmonic solution (complex amplitudes), or None (static only)
    static : StressField of a static solution (e.g. :func:`fem.preload.preload_solve`), or None
    freq_hz, voltage : the harmonic state, for the record
    preload_n : the static state's bolt force, N, for the record
    regions : names of the regions to report (default: all)
    detail : also the error estimates (False: error estimate 0, as :func:`stress_sweep` uses them)
    off_edges : also the peaks off the singular edges and the rows' ``singular`` marks (default:
        ``detail``)
    edge : :func:`bonded_edge_nodes` of the system, if computed already
    """
    ref = dynamic if dynamic is not None else static
    if ref is None:
        raise ParameterError("dynamic", None, "give a harmonic or a static stress field (or both)")
    system = ref.system
    if dynamic is not None and static is not None and (dynamic.system is not static.system):
        raise ParameterError("static", "another system", "must come from the same assembled system")
    names = [r.name for r in system.regions]
    if regions is not None:
        unknown = sorted(set(regions) - set(names))
        if unknown:
            raise ParameterError("regions", unknown[0], "unknown; known: " + ", ".join(names))
    f = _cycle_fields(dynamic, static, ref)
    limits = _region_limits(system)
    off_edges = detail if off_edges is None else off_edges
    edge_distance = _edge_distances(system, edge, ref.periodic) if off_edges else None
    rows = []
    for ri, rd in enumerate(system.regions):
        if regions is None or rd.name in regions:
            rows += _region_rows(ref, ri, rd, f, limits[ri], detail, off_edges, edge_distance)
    return StressTable(tuple(rows), freq_hz, voltage, float(preload_n))


def converged_table(coarse: StressTable, fine: StressTable, ratio: float, order: float = STRESS_ORDER) -> StressTable:
    """The fine mesh's table with each row's error estimate from the coarse mesh's (Richardson).

    Parameters
    ----------
    coarse, fine : StressTable
        The same state on two meshes whose element sizes differ by ``ratio`` (coarse / fine > 1,
        e.g. the ratio of their ``refine`` factors).
    ratio : float
        Element-size ratio, dimensionless.
    order : float
        Convergence order of the peaks (:data:`STRESS_ORDER`).

    Returns
    -------
    StressTable
        Rows of ``fine``, ``error_estimate = |fine - coarse| / (ratio^order - 1)`` on the
        headline values (a singular row's off-edge peaks), SI. A row absent from the coarse table
        keeps its own estimate.
    """
    import dataclasses

    if not (isinstance(ratio, (int, float)) and ratio > 1.0):
        raise ParameterError("ratio", ratio, "must be the element-size ratio coarse / fine, > 1")
    if not (isinstance(order, (int, float)) and order > 0):
        raise ParameterError("order", order, "must be > 0")
    old = {(r.region, r.quantity): r for r in coarse.rows}
    rows = []
    for r in fine.rows:
        c = old.get((r.region, r.quantity))
        if c is None:
            rows.append(r)
            continue
        head_c = c.value_off_edges if r.singular and c.value_off_edges is not None else c.value
        est = two_level_error(r.headline, head_c, ratio, order)
        rows.append(dataclasses.replace(r, error_estimate=float(est)))
    note = (f"error estimates: two meshes (element sizes {ratio:g}:1), Richardson at order {order:g}"
            + (f"; {fine.note}" if fine.note else ""))
    return StressTable(tuple(rows), fine.freq_hz, fine.voltage, fine.preload_n, note)


# --------------------------------------------------------------------------- along a sweep


@dataclass(repr=False)
class StressSweep(Result):
    """Headline peaks (off the singular edges where a peak sits on one) along a harmonic sweep:
    ``peaks[(region, quantity)]`` (n_freq,) SI values, ``limits`` the same keys' limits (None if
    absent)."""

    freqs_hz: np.ndarray
    voltage: float
    preload_n: float
    peaks: dict
    limits: dict = field(default_factory=dict)

    def worst_utilisation(self) -> tuple[str, float, float] | None:
        """(``region/quantity``, frequency Hz, utilisation) of the highest utilisation in the band."""
        best = None
        for key, vals in self.peaks.items():
            lim = self.limits.get(key)
            if lim is None:
                continue
            v = -np.asarray(vals) if key[1] == "principal_min" else np.asarray(vals)
            i = int(np.argmax(v))
            u = max(float(v[i]), 0.0) / lim
            if best is None or u > best[2]:
                best = (f"{key[0]}/{key[1]}", float(self.freqs_hz[i]), u)
        return best

    def _headline(self) -> str:
        w = self.worst_utilisation()
        band = f"{len(self.freqs_hz)} frequencies {self.freqs_hz[0]:.0f}-{self.freqs_hz[-1]:.0f} Hz"
        if w is None:
            return band
        return f"{band}: worst {w[0]} {100 * w[2]:.1f} % at {w[1]:.1f} Hz"

    def _record(self) -> dict:
        return {"freqs_hz": self.freqs_hz, "voltage_v": self.voltage, "preload_n": self.preload_n,
                "peaks": [{"region": k[0], "quantity": k[1], "unit": _SI_UNIT[k[1]], "values": v,
                           "limit": self.limits.get(k)} for k, v in self.peaks.items()]}

    def _arrays(self) -> dict:
        return {"freqs_hz": self.freqs_hz, **{f"{k[0]}__{k[1]}": v for k, v in self.peaks.items()}}


def stress_sweep(system, basis, freqs_hz, voltage: float, *, static: StressField | None = None,
                 preload_n: float = 0.0, recovery: StressRecovery | None = None) -> StressSweep:
    """Headline (:attr:`StressRow.headline`: off the singular edges where the peak sits on one) of
    every row of :func:`stress_table` at each frequency of ``freqs_hz`` (Hz), from the modal
    superposition ``basis`` (:func:`fem.harmonic.modal_basis`) at ``voltage`` (V)."""
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    if f.ndim != 1 or len(f) == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ParameterError("freqs_hz", freqs_hz, "must be finite frequencies > 0 Hz")
    rec = recovery or StressRecovery(system)
    cols = basis.columns()
    W = basis.weights(f)
    peaks, limits = {}, {}
    edge = bonded_edge_nodes(system)
    for i in range(len(f)):
        x = system.expand(cols @ W[i] * voltage, basis.free, voltage)
        tab = stress_table(rec.field(x), static, freq_hz=float(f[i]), voltage=voltage, preload_n=preload_n,
                           detail=False, off_edges=True, edge=edge)
        for r in tab.rows:
            key = (r.region, r.quantity)
            peaks.setdefault(key, np.zeros(len(f)))[i] = r.headline
            limits[key] = r.limit
    return StressSweep(f, float(voltage), float(preload_n), peaks, limits)

"""Peak stresses and fields per region, against the materials' limits: the utilisation table.

Rows (one per region and quantity), all peaks over one drive cycle of the harmonic state plus an
optional static state (bolt preload), see :mod:`fem.stress`:

* metal region: peak von Mises stress against ``fatigue_strength`` (the whole peak of static +
  dynamic stress against a fully reversed fatigue amplitude: conservative, no mean-stress
  correction);
* ceramic region: largest principal stress (tension) against ``tensile_strength``, most negative
  principal stress (compression) against ``compressive_strength``, peak ``|E|`` against
  ``depolarisation_field``.

Each peak is also given away from the bonded free edges (:func:`bonded_edge_nodes`: the cells
touching them left out), where the elastic solution is singular; that value converges with the
mesh, the peak itself need not. A limit the material record does not give is ``None`` (``n/a``). Each row has the
location of its peak and an estimate of its discretisation error (:mod:`fem.stress`): peaks are
taken on the recovered field (per region, the element-node values averaged at each node), the
estimate is the difference to the raw element values at that node.

:func:`stress_sweep` repeats the peaks along a harmonic sweep (modal superposition basis).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rpud_common import ParameterError
from rpud_common.result import Result

from .stress import (StressField, StressRecovery, efield_cycle_peak, principal_cycle_extremes,
                     principal_values, quadratic_peak, vm_cycle_peak)

__all__ = ["StressRow", "StressTable", "stress_table", "StressSweep", "stress_sweep", "QUANTITIES",
           "bonded_edge_nodes"]

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

    @property
    def utilisation(self) -> float | None:
        """Peak / limit (a compressive peak by its magnitude, a tension peak only if > 0)."""
        if self.limit is None:
            return None
        v = -self.value if self.quantity == "principal_min" else self.value
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
                "utilisation_off_edges": self.utilisation_off_edges}


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
                f"{_show(w.quantity, w.value)} = {100 * w.utilisation:.1f} % of its limit")

    def _record(self) -> dict:
        return {"freq_hz": self.freq_hz, "voltage_v": self.voltage, "preload_n": self.preload_n,
                "rows": [r.record() for r in self.rows], "note": self.note,
                "method": "recovered field (element-node values of P2 tetrahedra averaged per region at each "
                          "node); peak over the cycle (von Mises, |E|: exact; principal stresses: 72 phases + "
                          "parabolic refinement); error estimate = difference between recovered and raw element "
                          "values around the peak (ZZ); singular at re-entrant corners and bonded free edges "
                          "(peak_off_edges leaves the cells touching those edges out)"}

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
            lines.append(f"{f'{r.region} ({r.part}, {r.material})':34s} {label:28s} {r.value * scale:9.4g} "
                         f"{r.error_estimate * scale:8.2g} {unit:6s} {loc:22s} {off:>9s} {lim:>7s} "
                         f"{_pct(r.utilisation):>11s} {_pct(r.utilisation_off_edges):>9s}")
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
            lines.append(f"| {r.region} ({r.part}, {r.material}) | {label} | {r.value * scale:.4g} {unit} "
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
    """(n_nodes,) bool: nodes on the outer surface shared by cells of two or more regions.

    These are the lines where a bonded interface meets a free surface (ring bores and rims at the
    electrode planes, the flange/horn corner): in the elastic solution the stress there is
    singular (a re-entrant corner or a bi-material edge). Re-entrant corners inside one region
    (the horn's step, slot roots) are not among them."""
    n = system.n_nodes
    surf = np.zeros(n, bool)
    bf = system.skmesh.boundary_facets()
    if len(bf):
        surf[np.unique(np.asarray(system.basis.get_dofs(facets=bf).all()))] = True
    count = np.zeros(n, np.int64)
    edofs = np.asarray(system.basis.element_dofs)
    cell_region = np.asarray(system.mesh.cell_region)
    for r in range(len(system.regions)):
        mark = np.zeros(n, bool)
        mark[np.unique(edofs[:, cell_region == r])] = True
        count += mark
    return surf & (count >= 2)


def _region_limits(system):
    out = []
    for rd in system.regions:
        mat = system.materials.get(rd.material)
        out.append(mat.limits() if mat is not None and hasattr(mat, "limits") else {})
    return out


def stress_table(dynamic: StressField | None, static: StressField | None = None, *, freq_hz: float | None = None,
                 voltage: float | None = None, preload_n: float = 0.0, regions=None,
                 detail: bool = True) -> StressTable:
    """Peaks per region of ``static + Re(dynamic exp(j w t))`` over a cycle (see the module docstring).

    Parameters
    ----------
    dynamic : StressField of a harmonic solution (complex amplitudes), or None (static only)
    static : StressField of a static solution (e.g. :func:`fem.preload.preload_solve`), or None
    freq_hz, voltage : the harmonic state, for the record
    preload_n : the static state's bolt force, N, for the record
    regions : names of the regions to report (default: all)
    detail : also the error estimates and the peaks off the bonded edges (False: peaks only,
        error estimate 0, as :func:`stress_sweep` uses them)
    """
    ref = dynamic if dynamic is not None else static
    if ref is None:
        raise ParameterError("dynamic", None, "give a harmonic or a static stress field (or both)")
    system = ref.system
    if dynamic is not None and static is not None and (dynamic.system is not static.system):
        raise ParameterError("static", "another system", "must come from the same assembled system")
    shape = ref.stress.shape
    # the peaks are taken on the recovered field (element-node values averaged over the cells of
    # the region sharing the node: more accurate, e.g. 1.6 % vs 7 % on the cantilever test); the
    # raw element values at the same node give the error estimate
    zs, ze = np.zeros(shape, complex), np.zeros(ref.efield.shape, complex)
    raw_hat_s = dynamic.stress.astype(complex) if dynamic is not None else zs
    raw_hat_e = dynamic.efield.astype(complex) if dynamic is not None else ze
    raw_s0 = static.stress.real if static is not None else zs.real
    raw_e0 = static.efield.real if static is not None else ze.real
    hat_s = dynamic.nodal_average("stress").astype(complex) if dynamic is not None else zs
    hat_e = dynamic.nodal_average("efield").astype(complex) if dynamic is not None else ze
    s0 = static.nodal_average("stress").real if static is not None else zs.real
    e0 = static.nodal_average("efield").real if static is not None else ze.real
    limits = _region_limits(system)
    names = [r.name for r in system.regions]
    if regions is not None:
        unknown = sorted(set(regions) - set(names))
        if unknown:
            raise ParameterError("regions", unknown[0], "unknown; known: " + ", ".join(names))
    edge = bonded_edge_nodes(system)
    rows = []
    for ri, rd in enumerate(system.regions):
        if regions is not None and rd.name not in regions:
            continue
        sel = np.flatnonzero(ref.region == ri)
        if len(sel) == 0:
            continue
        part = system.mesh.regions[ri].part
        pts = ref.points[sel].reshape(-1, 3)
        hs, s0r = hat_s[sel].reshape(-1, 6), s0[sel].reshape(-1, 6)
        ahs, as0 = raw_hat_s[sel].reshape(-1, 6), raw_s0[sel].reshape(-1, 6)
        lim = limits[ri]
        nodes_r = ref.nodes[sel]
        k = nodes_r.shape[1]

        def patch(i):
            """Element-node entries of the region's cells that touch the node of entry ``i``."""
            cells = np.flatnonzero((nodes_r == nodes_r.ravel()[i]).any(axis=1))
            return (cells[:, None] * k + np.arange(k)[None, :]).ravel()

        # entries of the cells that touch no bonded free edge (the singular lines of the model)
        off = np.flatnonzero(np.repeat(~edge[nodes_r].any(axis=1), k))

        def row(q, peak, fn, rec, raw):
            # error estimate: the largest difference between recovered and raw element values of
            # the quantity on the patch of cells around the peak node
            i, value = peak(*rec)
            est, v_off, loc_off = 0.0, None, None
            if detail:
                j = patch(i)
                est = np.max(np.abs(fn(*(a[j] for a in rec)) - fn(*(a[j] for a in raw))))
            if detail and len(off):
                i_off, v_off = peak(*(a[off] for a in rec))
                loc_off = tuple(float(c) for c in pts[off[i_off]])
            rows.append(StressRow(rd.name, part, rd.material, q, float(value), tuple(float(c) for c in pts[i]),
                                  lim.get(QUANTITIES[q][3]), float(est), v_off, loc_off))

        if not rd.piezo:
            row("von_mises", lambda h, s: quadratic_peak("von_mises", h, s),
                lambda h, s: vm_cycle_peak(h, s)[0], (hs, s0r), (ahs, as0))
            continue
        row("principal_max", lambda h, s: _principal_peak(h, s, 1.0),
            lambda h, s: principal_cycle_extremes(h, s)[0], (hs, s0r), (ahs, as0))
        row("principal_min", lambda h, s: _principal_peak(h, s, -1.0),
            lambda h, s: principal_cycle_extremes(h, s)[1], (hs, s0r), (ahs, as0))
        he, e0r = hat_e[sel].reshape(-1, 3), e0[sel].reshape(-1, 3)
        ahe, ae0 = raw_hat_e[sel].reshape(-1, 3), raw_e0[sel].reshape(-1, 3)
        row("efield", lambda h, s: quadratic_peak("efield", h, s),
            lambda h, s: efield_cycle_peak(h, s)[0], (he, e0r), (ahe, ae0))
    return StressTable(tuple(rows), freq_hz, voltage, float(preload_n))


# --------------------------------------------------------------------------- along a sweep


@dataclass(repr=False)
class StressSweep(Result):
    """Peaks along a harmonic sweep: ``peaks[(region, quantity)]`` (n_freq,) SI values,
    ``limits`` the same keys' limits (None if absent)."""

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
    """Peak of every row of :func:`stress_table` at each frequency of ``freqs_hz`` (Hz), from the
    modal superposition ``basis`` (:func:`fem.harmonic.modal_basis`) at ``voltage`` (V)."""
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    if f.ndim != 1 or len(f) == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ParameterError("freqs_hz", freqs_hz, "must be finite frequencies > 0 Hz")
    rec = recovery or StressRecovery(system)
    cols = basis.columns()
    W = basis.weights(f)
    peaks, limits = {}, {}
    for i in range(len(f)):
        x = system.expand(cols @ W[i] * voltage, basis.free, voltage)
        tab = stress_table(rec.field(x), static, freq_hz=float(f[i]), voltage=voltage, preload_n=preload_n,
                           detail=False)
        for r in tab.rows:
            key = (r.region, r.quantity)
            peaks.setdefault(key, np.zeros(len(f)))[i] = r.value
            limits[key] = r.limit
    return StressSweep(f, float(voltage), float(preload_n), peaks, limits)

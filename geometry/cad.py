"""A CAD design's STEP file read by Gmsh/OpenCASCADE and its rules applied (:mod:`geometry.design_cad`).

:func:`import_step` reads the solids (converted to metres: OCC honours the file's declared
length unit), glues touching solids into one conformal model (``fragment``; solids that overlap
are refused, and so are solids of no drill's size, :data:`SOLID_SIZE_RANGE`) and keeps their
labels; :func:`apply_rules` maps the solids to regions and the faces to facet sets by the rules
and refuses, with one line naming the rule, a rule that matches nothing, a volume rule that
matches several solids, two rules claiming one solid, and a solid no rule claims.
:func:`resolve` does both in a Gmsh session of its own and keeps what the design needs without
Gmsh (z range, region volumes per axial zone, electrode planes), cached per file and rule table.
The builder (:mod:`geometry.builder`) calls :func:`import_step` and :func:`apply_rules` in its
own session.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import signal
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rpud_common import ParameterError
from rpud_common import cli as common

__all__ = ["Resolved", "resolve", "zone_table", "import_step", "apply_rules", "gmsh_session", "face_point", "volume_point",
           "native_stdout_quiet", "SOLID_SIZE_RANGE"]

log = logging.getLogger(__name__)

SOLID_SIZE_RANGE = (1e-3, 2.0)
"""Largest bounding-box side of every solid of a STEP drawing, m: a ring, shim or tooth of a
drill measures a millimetre or more across (thin layers are thin in one direction only), a
whole drill at most two metres. Outside, the file's length unit is wrong (a drawing in m read
as mm) or the part is no drill part, and meshing it would take no or all of the budget."""

_CACHE: dict[tuple, "Resolved"] = {}
_CACHE_SIZE = 16
_session_ids = itertools.count()


@dataclass(frozen=True)
class Resolved:
    """What the rules found in the drawing (SI units, coordinates of the drawing).

    Attributes
    ----------
    z_range : (float, float)
        Axial extent of the whole drawing, m.
    region_z : dict
        Region -> (z0, z1), m.
    region_box : dict
        Region -> bounding box (xmin, ymin, zmin, xmax, ymax, zmax), m.
    zone_volumes : dict
        Region -> {zone label: volume m^3} over the drawn axial zones (the declared length bands
        ``length:<name>`` and the fixed stretches between them).
    surface_planes : dict
        Facet set -> [(axis, coordinate m)] of its faces that are flat across an axis.
    n_solids : int
    surface_faces : dict
        Facet set -> number of faces.
    """

    z_range: tuple[float, float]
    region_z: dict
    region_box: dict
    zone_volumes: dict
    surface_planes: dict
    n_solids: int
    surface_faces: dict


@contextlib.contextmanager
def gmsh_session():
    """A Gmsh model of its own: in a fresh Gmsh (initialised here, Python's signal handlers
    restored, finalised after) or, inside a running Gmsh, a temporary model."""
    import gmsh

    name = f"rpud-cad-{next(_session_ids)}"
    if gmsh.isInitialized():
        prev = gmsh.model.getCurrent()
        gmsh.model.add(name)
        try:
            yield gmsh
        finally:
            gmsh.model.remove()
            gmsh.model.setCurrent(prev)
        return
    if common.native_code_running():
        raise ParameterError("design", name, "an abandoned Gmsh run is still going in this process; start a new one")
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        # Gmsh installs its own native handlers (SIGTERM would kill the process): put Python's back
        for sig, handler in handlers.items():
            if handler is not None:
                signal.signal(sig, handler)
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 1)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add(name)
        yield gmsh
    finally:
        gmsh.finalize()


@contextlib.contextmanager
def native_stdout_quiet():
    """Silence what native code (OpenCASCADE's STEP translator) writes to file descriptor 1:
    its transfer statistics would mix with a command line's own output."""
    import sys

    with contextlib.suppress(Exception):
        sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _snap_z(gmsh, dim: int, tags, z_lo: float, z_hi: float) -> tuple[float, float]:
    """The z range of entities. OCC pads bounding boxes by its tolerance and bounds a curved
    face by its control polygon (a fillet arc's box reaches its centre's height), so the range
    is taken over points along the entities' curves (their end vertices and 31 points between):
    exact where the extremes lie at vertices (a drawn body of revolution: its arcs are monotone
    in z between their vertices), else within a curve's sagitta between samples. ``z_lo``,
    ``z_hi`` (the box) are kept for entities without curves."""
    ents = [(dim, t) for t in tags]
    while ents and ents[0][0] > 1:
        ents = list(dict.fromkeys(gmsh.model.getBoundary(ents, combined=False, oriented=False)))
        ents = [(d, abs(t)) for d, t in ents]
    zs = []
    for _d, c in ents:
        lo, hi = gmsh.model.getParametrizationBounds(1, c)
        zs.append(np.asarray(gmsh.model.getValue(1, c, np.linspace(lo[0], hi[0], 33))).reshape(-1, 3)[:, 2])
    if not zs:
        return float(z_lo), float(z_hi)
    zs = np.concatenate(zs)
    return float(zs.min()), float(zs.max())


# ============================================================================ import


def import_step(gmsh, path: str) -> tuple[list[int], dict[int, str]]:
    """Read the solids of a STEP file into the current model, in metres, glued conformally.

    Returns
    -------
    (volume tags, {volume tag: label})
        Labels are the STEP product names as Gmsh reads them (``Shapes/.../horn``), ``""`` if none.
    """
    occ = gmsh.model.occ
    gmsh.option.setString("Geometry.OCCTargetUnit", "M")   # OCC converts the file's declared unit
    gmsh.option.setNumber("Geometry.OCCImportLabels", 1)
    try:
        with native_stdout_quiet():
            dimtags = occ.importShapes(str(path), highestDimOnly=True)
        occ.synchronize()
    except Exception as exc:  # noqa: BLE001 - Gmsh raises bare Exceptions
        raise ParameterError("step", str(path), f"cannot be read as STEP ({exc})") from None
    vols = [t for d, t in dimtags if d == 3]
    if not vols:
        raise ParameterError("step", str(path), "holds no solid (only faces or curves): export solids")
    labels = {t: gmsh.model.getEntityName(3, t) for t in vols}
    _check_sizes(gmsh, str(path), vols, labels)
    if len(vols) == 1:
        return vols, labels
    # touching solids share faces only after fragmenting; an overlap would leave a piece of two
    _out, out_map = occ.fragment([(3, v) for v in vols], [])
    occ.synchronize()
    owner: dict[int, int] = {}
    for v, pieces in zip(vols, out_map):
        for d, t in pieces:
            if d != 3:
                continue
            if t in owner and owner[t] != v:
                a, b = (_label(labels[x]) or f"solid {x}" for x in (owner[t], v))
                raise ParameterError("step", str(path), f"solids {a!r} and {b!r} overlap: fix the drawing "
                                     "(pieces may touch, not intersect)")
            owner[t] = v
    new_labels = {t: labels[v] for t, v in owner.items()}
    return sorted(owner), new_labels


def _extent(gmsh, dim: int, tag: int) -> float:
    """Largest side of an entity's bounding box (``tag`` -1: the whole model), m."""
    bb = gmsh.model.getBoundingBox(dim, tag)
    return float(max(bb[3] - bb[0], bb[4] - bb[1], bb[5] - bb[2]))


def _check_sizes(gmsh, path: str, vols: list[int], labels: dict[int, str]) -> None:
    """Every solid, and the drawing, of a drill's size (:data:`SOLID_SIZE_RANGE`), before meshing."""
    lo, hi = SOLID_SIZE_RANGE
    for v in vols:
        size = _extent(gmsh, 3, v)
        if not lo <= size <= hi:
            raise ParameterError("step", path, f"{_describe_solid(gmsh, v, labels.get(v, ''))} measures "
                                 f"{size * 1e3:.4g} mm across: a drill part measures {lo * 1e3:g} mm to "
                                 f"{hi * 1e3:g} mm (check the file's length unit)")
    size = _extent(gmsh, -1, -1)
    if size > hi:
        raise ParameterError("step", path, f"the drawing measures {size * 1e3:.4g} mm across: a drill measures "
                             f"at most {hi * 1e3:g} mm (check the file's length unit)")


def _label(label: str) -> str:
    return label.rsplit("/", 1)[-1] if label else ""


# ============================================================================ rules


def _tol(gmsh) -> float:
    bb = gmsh.model.getBoundingBox(-1, -1)
    return 1e-6 + 1e-6 * max(abs(x) for x in bb)


def _bbox_inside(bb, box, tol) -> bool:
    return all(bb[i] >= box[i] - tol for i in range(3)) and all(bb[i + 3] <= box[i + 3] + tol for i in range(3))


def _face_has_point(gmsh, face: int, point, tol: float) -> bool:
    closest = gmsh.model.getClosestPoint(2, face, list(point))[0]
    if np.linalg.norm(np.asarray(closest) - point) > tol:
        return False
    # isInside on a face tests the trimmed region of the point's projection: the distance above
    # tells whether the point lies on the face's surface at all
    return bool(gmsh.model.isInside(2, face, list(point)))


def _face_in_plane(gmsh, face: int, plane, tol: float) -> bool:
    if gmsh.model.getType(2, face) != "Plane":
        return False
    lo, hi = gmsh.model.getParametrizationBounds(2, face)
    n = np.asarray(gmsh.model.getNormal(face, [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])]))
    if abs(float(n @ np.asarray(plane.normal))) < 1 - 1e-6:
        return False
    com = np.asarray(gmsh.model.occ.getCenterOfMass(2, face))
    return abs(float(com @ np.asarray(plane.normal)) - plane.offset) < tol


def _volume_matches(gmsh, v: int, label: str, sel, tol: float) -> bool:
    if sel.name is not None and sel.name not in (label, _label(label)):
        return False
    if sel.box is not None and not _bbox_inside(gmsh.model.getBoundingBox(3, v), sel.box, tol):
        return False
    if sel.point is not None and not gmsh.model.isInside(3, v, list(sel.point)):
        return False
    return True


def _describe_solid(gmsh, v: int, label: str) -> str:
    bb = np.asarray(gmsh.model.getBoundingBox(3, v)) * 1e3
    name = f"{_label(label)!r}, " if label else ""
    return f"solid {v} ({name}box {np.round(bb, 3).tolist()} mm)"


def apply_rules(gmsh, design, vols: list[int], labels: dict[int, str]):
    """Regions and facet sets of the imported drawing by the design's rules.

    Returns
    -------
    region_vols : dict region -> [volume tags]
    region_meta : dict region -> (part, material, poling vector or None)
    facet_surfs : dict facet set -> [face tags]
    """
    where = design.step
    tol = _tol(gmsh)
    claimed: dict[int, int] = {}
    region_vols: dict[str, list[int]] = {}
    for i, rule in enumerate(design.volumes):
        hits = [v for v in vols if _volume_matches(gmsh, v, labels.get(v, ""), rule.select, tol)]
        name = f"volumes[{i}] (region {rule.region})"
        if not hits:
            raise ParameterError(name, rule.select.describe(), f"matches no solid of {where} ({len(vols)} solids)")
        if len(hits) > 1:
            raise ParameterError(name, rule.select.describe(), f"matches {len(hits)} solids of {where}: "
                                 + "; ".join(_describe_solid(gmsh, v, labels.get(v, "")) for v in hits[:4])
                                 + " -- narrow the selection (one rule per solid)")
        v = hits[0]
        if v in claimed:
            j = claimed[v]
            raise ParameterError(name, rule.select.describe(), f"selects the solid volumes[{j}] (region "
                                 f"{design.volumes[j].region}) already took: {_describe_solid(gmsh, v, labels.get(v, ''))}")
        claimed[v] = i
        region_vols.setdefault(rule.region, []).append(v)
    free = [v for v in vols if v not in claimed]
    if free:
        raise ParameterError("volumes", where, f"{len(free)} solid(s) match no [[volumes]] rule: "
                             + "; ".join(_describe_solid(gmsh, v, labels.get(v, "")) for v in free[:4]))
    region_meta = {r: (rule.part, rule.material, rule.poling_vector) for r, rule in design.region_rules().items()}

    boundary: dict[str, set[int]] = {}
    for region, rv in region_vols.items():
        out = gmsh.model.getBoundary([(3, v) for v in rv], combined=False, oriented=False, recursive=False)
        boundary[region] = {abs(t) for d, t in out if d == 2}
    all_faces = sorted({f for faces in boundary.values() for f in faces})
    facet_surfs: dict[str, list[int]] = {}
    for i, rule in enumerate(design.surfaces):
        sel = rule.select
        faces = all_faces
        if sel.regions:
            faces = sorted(set().union(*(boundary[r] for r in sel.regions)))
        if sel.box is not None:
            faces = [f for f in faces if _bbox_inside(gmsh.model.getBoundingBox(2, f), sel.box, tol)]
        if sel.plane is not None:
            faces = [f for f in faces if _face_in_plane(gmsh, f, sel.plane, tol)]
        if sel.point is not None:
            faces = [f for f in faces if _face_has_point(gmsh, f, np.asarray(sel.point), tol)]
        if not faces:
            raise ParameterError(f"surfaces[{i}] ({rule.name})", sel.describe(), f"matches no face of {where}")
        acc = facet_surfs.setdefault(rule.name, [])
        acc += [f for f in faces if f not in acc]
    return region_vols, region_meta, facet_surfs


# ============================================================================ points inside


def volume_point(gmsh, v: int, margin: float) -> tuple[float, float, float] | None:
    """A point inside solid ``v`` at least ``margin`` (m) from its boundary along the axes, or None.

    Samples a grid in the solid's bounding box, nearest the middle first (a deterministic search).
    """
    bb = np.asarray(gmsh.model.getBoundingBox(3, v))
    lo, hi = bb[:3], bb[3:]
    axes = [lo[i] + (hi[i] - lo[i]) * np.linspace(0.05, 0.95, 19) for i in range(3)]
    mid = 0.5 * (lo + hi)
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    grid = grid[np.argsort(np.linalg.norm((grid - mid) / np.maximum(hi - lo, 1e-12), axis=1), kind="stable")]
    offsets = np.vstack([np.zeros(3), margin * np.eye(3), -margin * np.eye(3)])
    for p in grid:
        if all(gmsh.model.isInside(3, v, list(p + o)) for o in offsets):
            return tuple(float(x) for x in p)
    return None


def face_point(gmsh, face: int, tol: float) -> tuple[float, float, float] | None:
    """A point on face ``face`` away from its edges (sampled in its parameter space), or None."""
    lo, hi = gmsh.model.getParametrizationBounds(2, face)
    us = lo[0] + (hi[0] - lo[0]) * np.linspace(0.1, 0.9, 9)
    vs = lo[1] + (hi[1] - lo[1]) * np.linspace(0.1, 0.9, 9)
    cand = np.array([(u, w) for u in us for w in vs])
    cand = cand[np.argsort(np.hypot((cand[:, 0] - us.mean()) / (np.ptp(us) + 1e-30),
                                    (cand[:, 1] - vs.mean()) / (np.ptp(vs) + 1e-30)), kind="stable")]
    for uv in cand:
        p = np.asarray(gmsh.model.getValue(2, face, list(uv)))
        if _face_has_point(gmsh, face, p, tol):
            return tuple(float(x) for x in p)
    return None


# ============================================================================ resolve


def _key(design) -> tuple:
    p = Path(design.step).resolve()
    st = p.stat()
    bands = tuple((x.name, x.z0, x.z1) for x in design.lengths)
    return (str(p), st.st_mtime_ns, st.st_size, design.volumes, design.surfaces, bands)


def resolve(design) -> Resolved:
    """Apply a CAD design's rules to its STEP file (cached per file and rules; see the module)."""
    try:
        key = _key(design)
    except OSError as exc:
        raise ParameterError("step", design.step, f"cannot be read ({exc.strerror or exc})") from None
    if key in _CACHE:
        return _CACHE[key]
    with gmsh_session() as gmsh:
        vols, labels = import_step(gmsh, design.step)
        region_vols, _meta, facet_surfs = apply_rules(gmsh, design, vols, labels)
        tol = _tol(gmsh)
        bb = gmsh.model.getBoundingBox(-1, -1)
        z_range = _snap_z(gmsh, 3, vols, bb[2], bb[5])
        for x in design.lengths:
            if x.z0 < z_range[0] - tol or x.z1 > z_range[1] + tol:
                raise ParameterError(f"lengths.{x.name}", [x.z0, x.z1], f"lies outside the drawing's z range "
                                     f"[{z_range[0]:g}, {z_range[1]:g}] m")
        zones = zone_table(design.lengths, *z_range, drawn=True)
        region_z, region_box, zone_volumes = {}, {}, {}
        occ = gmsh.model.occ
        for region, rv in region_vols.items():
            boxes = [gmsh.model.getBoundingBox(3, v) for v in rv]
            region_box[region] = tuple(float(f(b[i] for b in boxes)) for f, i in
                                       ((min, 0), (min, 1), (min, 2), (max, 3), (max, 4), (max, 5)))
            region_z[region] = _snap_z(gmsh, 3, rv, region_box[region][2], region_box[region][5])
            vols_z: dict[str, float] = {}
            for v in rv:
                mass = occ.getMass(3, v)
                b = gmsh.model.getBoundingBox(3, v)
                inside = [z for z in zones if z[2] < b[5] - tol and z[3] > b[2] + tol]
                if len(inside) == 1:
                    vols_z[inside[0][0]] = vols_z.get(inside[0][0], 0.0) + mass
                    continue
                for label, _part, z0, z1 in inside:      # a solid across zones: its share in each
                    pad = 1.0 + max(abs(x) for x in b)
                    slab = occ.addBox(b[0] - pad, b[1] - pad, z0, b[3] - b[0] + 2 * pad, b[4] - b[1] + 2 * pad, z1 - z0)
                    cut, _ = occ.intersect([(3, v)], [(3, slab)], removeObject=False, removeTool=True)
                    vols_z[label] = vols_z.get(label, 0.0) + sum(occ.getMass(d, t) for d, t in cut if d == 3)
                    occ.remove(cut, recursive=True)
            zone_volumes[region] = vols_z
        planes: dict[str, list[tuple[str, float]]] = {}
        for name, faces in facet_surfs.items():
            out = set()
            for f in faces:
                fb = gmsh.model.getBoundingBox(2, f)
                for i, axis in enumerate("xyz"):
                    if fb[i + 3] - fb[i] < tol:
                        out.add((axis, round(0.5 * (fb[i] + fb[i + 3]), 12)))
            planes[name] = sorted(out)
        res = Resolved(z_range=z_range, region_z=region_z, region_box=region_box, zone_volumes=zone_volumes, surface_planes=planes,
                       n_solids=len(vols), surface_faces={k: len(v) for k, v in facet_surfs.items()})
    if len(_CACHE) >= _CACHE_SIZE:
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[key] = res
    log.info("resolved %s: %d solids, %d regions, %d facet sets", os.path.basename(design.step), res.n_solids,
             len(region_z), len(planes))
    return res


def zone_table(lengths, zmin: float, zmax: float, drawn: bool = False) -> list[tuple[str, str, float, float]]:
    """``(label, part, z0, z1)`` of the axial zones of a drawing spanning ``zmin..zmax`` (m): each
    declared length ``length:<name>`` (at its value, or its drawn length with ``drawn``) and the
    fixed stretches ``fixed_<k>`` between them, laid end to end from ``zmin``."""
    z, out, k, cursor = zmin, [], 0, zmin
    for x in sorted(lengths, key=lambda b: b.z0):
        if x.z0 > cursor + 1e-12:
            out.append((f"fixed_{k}", "", z, z + (x.z0 - cursor)))
            z += x.z0 - cursor
            k += 1
        size = x.drawn if drawn else x.value
        out.append((f"length:{x.name}", x.part, z, z + size))
        z += size
        cursor = x.z1
    if zmax > cursor + 1e-12 or not out:
        out.append((f"fixed_{k}", "", z, z + (zmax - cursor)))
    return out

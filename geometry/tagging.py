"""Solids of a parametric design (RPUD, stack), fragmented into one conformal Gmsh model, with
their regions and named faces (``horn_tip``, ``teeth_tops``, ``flange``, ``electrode_*``, ``top``...).

Used by the builder (:mod:`geometry.builder`) and the STEP export (:mod:`geometry.cad_export`);
gmsh is handed in, never imported here.
"""

from __future__ import annotations

import math

from rpud_common import ParameterError
from .design_base import DesignBase
from .design_rpud import RPUDDesign
from .solids import make_rpud, make_stack

__all__ = ["parametric_model", "surface_rules", "boundary_surfaces", "planar_at"]


def boundary_surfaces(gmsh, vols):
    """Sorted tags of the surfaces bounding the volumes ``vols`` of the Gmsh model."""
    out = gmsh.model.getBoundary([(3, v) for v in vols], combined=False, oriented=False, recursive=False)
    return sorted({abs(t) for dim, t in out if dim == 2})


def planar_at(gmsh, surf, axis: str, value: float, tol: float) -> bool:
    """True when surface ``surf`` is flat across ``axis`` at ``value`` (bounding box within ``tol``, m)."""
    bb = gmsh.model.getBoundingBox(2, surf)
    i = "xyz".index(axis)
    lo, hi = bb[i], bb[i + 3]
    return hi - lo < tol and abs(0.5 * (lo + hi) - value) < tol


def surface_rules(d: DesignBase) -> list[tuple[str, str, str, float, float]]:
    """(facet set, region, axis, coordinate, min outer radius of the face) rules."""
    rules = []
    if isinstance(d, RPUDDesign):
        ext = d.part_extents()
        rules.append(("horn_tip", "horn", "z", ext["horn"][1], 0.0))
        rules.append(("teeth_tops", "coupler", "z", ext["coupler"][0], 0.0))
        r_contact = max(d.stack.outer_diameter, d.horn.back_diameter) / 2
        zf0, zf1 = ext["flange"]
        rules.append(("flange", "flange_disc", "z", zf0, r_contact + 1e-4))
        rules.append(("flange", "flange_disc", "z", zf1, r_contact + 1e-4))
        rings = {r: (z0, z1) for r, kind, z0, z1 in d.stack_layers() if kind == "ring"}
        for name, planes in d.electrode_planes().items():
            for axis, value in planes:
                for ring, (z0, z1) in rings.items():
                    if math.isclose(value, z0, abs_tol=1e-9) or math.isclose(value, z1, abs_tol=1e-9):
                        rules.append((name, ring, axis, value, 0.0))
    else:
        ext = d.segment_extents()
        zmin = min(z0 for z0, _ in ext.values())
        zmax = max(z1 for _, z1 in ext.values())
        for seg in d.segments:
            z0, z1 = ext[seg.name]
            if math.isclose(z0, zmin, abs_tol=1e-12):
                rules.append(("bottom", seg.name, "z", zmin, 0.0))
            if math.isclose(z1, zmax, abs_tol=1e-12):
                rules.append(("top", seg.name, "z", zmax, 0.0))
        bynames = {s.name: s for s in d.segments}
        planes = d.electrode_planes()
        for e in d.electrodes:
            for axis, value in planes[e.name]:
                rules.append((e.name, bynames[e.segment].name, axis, value, 0.0))
    return rules


def parametric_model(gmsh, design: DesignBase, layers, revolve: int | None = None, sectors: int | None = None):
    """Solids of a parametric design, fragmented, with their regions and named faces
    (``revolve``: an RPUD's bodies of revolution swept, ``sectors``: one sector of them, see
    :func:`geometry.solids.make_rpud`).

    Returns ``(region_vols, region_meta, facet_surfs)``: region -> volume tags, region ->
    (part, material, poling), facet set -> face tags.
    """
    occ = gmsh.model.occ
    pieces = make_rpud(occ, design, revolve, sectors) if isinstance(design, RPUDDesign) else make_stack(occ, design, layers)
    all_tags = [dt for p in pieces for dt in p[4]]
    if len(all_tags) > 1:
        _out, out_map = occ.fragment(all_tags, [])
    else:  # nothing to glue (OCC returns no map for a lone solid)
        out_map = [[all_tags[0]]]
    occ.synchronize()
    region_vols: dict[str, list[int]] = {}
    k = 0
    for region, *_rest, dimtags in pieces:
        vols = []
        for _ in dimtags:
            vols += [t for dim, t in out_map[k] if dim == 3]
            k += 1
        if not vols:
            raise ParameterError("design", design.name, f"region {region} vanished when fragmenting")
        region_vols[region] = sorted(set(region_vols.get(region, []) + vols))     # a region of several pieces
    claimed = [v for vs in region_vols.values() for v in vs]
    if len(claimed) != len(set(claimed)):
        raise ParameterError("design", design.name, "overlapping parts: two regions share a volume")
    region_meta = {p[0]: p[1:4] for p in pieces}
    scale = max(abs(z) for _, z in design.axial_breakpoints()) + 1e-3
    tol = 1e-6 + 1e-6 * scale  # OCC boxes are padded by 1e-7 m
    facet_surfs: dict[str, list[int]] = {}
    for name, region, axis, value, rmin in surface_rules(design):
        for sf in boundary_surfaces(gmsh, region_vols[region]):
            if not planar_at(gmsh, sf, axis, value, tol):
                continue
            if rmin > 0:
                bb = gmsh.model.getBoundingBox(2, sf)
                if max(abs(bb[0]), abs(bb[3]), abs(bb[1]), abs(bb[4])) < rmin:
                    continue
            facet_surfs.setdefault(name, [])
            if sf not in facet_surfs[name]:
                facet_surfs[name].append(sf)
    expected = {r[0] for r in surface_rules(design)}
    missing = sorted(expected - set(facet_surfs))
    if missing:
        raise ParameterError("design", design.name, f"no surface found for {', '.join(missing)}")
    return region_vols, region_meta, facet_surfs

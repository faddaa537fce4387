"""OpenCASCADE solids of the designs, for :mod:`geometry.builder` (which fragments and meshes them).

``make_rpud`` and ``make_stack`` return ``(region, part, material, poling, dimtags)`` per region:
cylinders and annuli, cones, boxes, lofted horns, coupler slots as helical lofts and tooth gaps
as sector prisms (both cut away); thin stack layers come from :func:`geometry.layers.make_layer`.
Every function takes Gmsh's OCC kernel (``gmsh.model.occ``) as its first argument; gmsh itself is
never imported here.
"""

from __future__ import annotations

import math

import numpy as np

from .design_rpud import RPUDDesign
from .design_stack import StackDesign
from .layers import Layer, make_layer
from .fillets import exponential_base, flange_horn_outlines
from .revolve import revolved_parts, section_face, section_outlines, stack_regions

__all__ = ["make_rpud", "make_coupler", "make_stack"]


def _annular_cylinder(occ, z0, length, r_out, r_in):
    vol = occ.addCylinder(0, 0, z0, 0, 0, length, r_out)
    if r_in > 0:
        hole = occ.addCylinder(0, 0, z0 - 1e-3, 0, 0, length + 2e-3, r_in)
        out, _ = occ.cut([(3, vol)], [(3, hole)])
        return out
    return [(3, vol)]


def _sector_prism(occ, a1, a2, r_out, z0, height):
    """A pie-sector prism from angle a1 to a2 (rad), radius r_out, from z0 over height."""
    n = max(1, math.ceil((a2 - a1) / (math.pi / 2)))
    angles = np.linspace(a1, a2, n + 1)
    centre = occ.addPoint(0, 0, z0)
    pts = [occ.addPoint(r_out * math.cos(a), r_out * math.sin(a), z0) for a in angles]
    curves = [occ.addLine(centre, pts[0])]
    curves += [occ.addCircleArc(pts[i], centre, pts[i + 1]) for i in range(n)]
    curves.append(occ.addLine(pts[-1], centre))
    surf = occ.addPlaneSurface([occ.addCurveLoop(curves)])
    ext = occ.extrude([(2, surf)], 0, 0, height)
    return [dt for dt in ext if dt[0] == 3]


def _slot_wire(occ, c, z, phi, r_tool):
    """Closed wire of one slot's cross-section at height z, centred on angle phi."""
    R = c.outer_diameter / 2
    alpha = c.slot_width / (2 * R)
    centre = occ.addPoint(0, 0, z)
    if c.slot_profile == "rectangular":
        r1 = R - c.slot_depth
        pa = occ.addPoint(r1 * math.cos(phi - alpha), r1 * math.sin(phi - alpha), z)
        pb = occ.addPoint(r_tool * math.cos(phi - alpha), r_tool * math.sin(phi - alpha), z)
        pc = occ.addPoint(r_tool * math.cos(phi + alpha), r_tool * math.sin(phi + alpha), z)
        pd = occ.addPoint(r1 * math.cos(phi + alpha), r1 * math.sin(phi + alpha), z)
        curves = [occ.addLine(pa, pb), occ.addCircleArc(pb, centre, pc), occ.addLine(pc, pd),
                  occ.addCircleArc(pd, centre, pa)]
    else:
        apex = np.array([R - c.slot_depth, 0.0])
        ends = []
        for sgn in (-1, 1):
            edge = np.array([R * math.cos(alpha), sgn * R * math.sin(alpha)])
            d = edge - apex
            # |apex + t d| = r_tool, t > 0
            A, B, C = d @ d, 2 * apex @ d, apex @ apex - r_tool ** 2
            t = (-B + math.sqrt(B * B - 4 * A * C)) / (2 * A)
            ends.append(apex + t * d)
        rot = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
        p_apex = occ.addPoint(*(rot @ apex), z)
        pa = occ.addPoint(*(rot @ ends[0]), z)
        pb = occ.addPoint(*(rot @ ends[1]), z)
        curves = [occ.addLine(p_apex, pa), occ.addCircleArc(pa, centre, pb), occ.addLine(pb, p_apex)]
    return occ.addCurveLoop(curves)


def _slot_phase(c) -> float:
    """Start angle of slot 0: keeps phi = 0 (the OCC cylinder seam) clear of every slot if the
    slots leave an angular gap, else centres the seam between two slot starts."""
    R = c.outer_diameter / 2
    alpha = c.slot_width / (2 * R)
    pitch = 2 * math.pi / c.n_slots
    tw = c.slot_twist
    gap = pitch - abs(tw) - 2 * alpha
    if gap > 0:
        start = alpha + 0.5 * gap
        return start if tw >= 0 else start + abs(tw)
    return 0.5 * pitch


def _slot_tool(occ, c, z0, phi0):
    """One helical slot cutter over [z0, z0 + slot_length], starting at angle phi0."""
    R = c.outer_diameter / 2
    r_tool = R + max(1e-3, c.slot_depth)
    twist = c.slot_twist
    if abs(twist) < 1e-12:
        wire = _slot_wire(occ, c, z0, phi0, r_tool)
        surf = occ.addPlaneSurface([wire])
        return [dt for dt in occ.extrude([(2, surf)], 0, 0, c.slot_length) if dt[0] == 3]
    n = max(2, math.ceil(abs(twist) / math.radians(10.0))) + 1
    wires = [_slot_wire(occ, c, z0 + c.slot_length * i / (n - 1), phi0 + twist * i / (n - 1), r_tool)
             for i in range(n)]
    return occ.addThruSections(wires, makeSolid=True, makeRuled=False)


def _horn(occ, h, z0, bore):
    L = h.length
    if h.profile == "stepped":
        l1 = h.step_fraction * L
        a = occ.addCylinder(0, 0, z0, 0, 0, l1, h.back_diameter / 2)
        b = occ.addCylinder(0, 0, z0 + l1, 0, 0, L - l1, h.tip_diameter / 2)
        vols, _ = occ.fuse([(3, a)], [(3, b)])
    elif h.profile == "conical":
        vols = [(3, occ.addCone(0, 0, z0, 0, 0, L, h.back_diameter / 2, h.tip_diameter / 2))]
    else:
        n = 13
        wires = []
        for i in range(n):
            s = L * i / (n - 1)
            circ = occ.addCircle(0, 0, z0 + s, float(h.diameter_at(s)) / 2)
            wires.append(occ.addCurveLoop([circ]))
        vols = occ.addThruSections(wires, makeSolid=True, makeRuled=False)
    if bore > 0:
        hole = occ.addCylinder(0, 0, z0 - 1e-3, 0, 0, L + 2e-3, bore / 2)
        vols, _ = occ.cut(vols, [(3, hole)])
    return vols


def make_coupler(occ, d: RPUDDesign, sectors: int | None = None):
    """OCC solid(s) of the coupler (teeth gaps and slots cut away); ``sectors``: only its part
    in 0 <= theta <= 2 pi / sectors."""
    c = d.coupler
    # a threaded bolt's thread zone is swept with the stack (geometry.revolve.section_outlines)
    body = _annular_cylinder(occ, -c.length, c.length + d.coupler_top, c.outer_diameter / 2, d.coupler_bore / 2)
    thread = d.bolt_thread
    if thread is not None:      # the bore closed around the bolt's thread
        plug = occ.addCylinder(0, 0, thread[0], 0, 0, thread[1] - thread[0], d.coupler_bore / 2)
        body, _ = occ.fuse(body, [(3, plug)])
    tools = []
    R = c.outer_diameter / 2
    if c.n_teeth:
        pitch = 2 * math.pi / c.n_teeth
        half = c.tooth_width / (2 * R)
        for k in range(c.n_teeth):
            a = (k - 0.5) * pitch  # a gap centred on phi = 0, where OCC puts the cylinder's seam
            tools += _sector_prism(occ, a + half, a + pitch - half, R + 1e-3, -c.length - 1e-3, c.tooth_height + 1e-3)
    if c.n_slots:
        z_slot = -c.length + (c.tooth_height if c.n_teeth else 0.0) + c.slot_offset
        for k in range(c.n_slots):
            tools += _slot_tool(occ, c, z_slot, _slot_phase(c) + 2 * math.pi * k / c.n_slots)
    if tools:
        body, _ = occ.cut(body, tools)
    if sectors:
        wedge = _sector_prism(occ, 0.0, 2 * math.pi / sectors, R + 1e-3, -c.length - 1e-3, c.length + 2e-3)
        body, _ = occ.intersect(body, wedge)
    return body


def make_rpud(occ, d: RPUDDesign, revolve: int | None = None, sectors: int | None = None):
    """OCC solids of the RPUD: list of (region, part, material, poling, dimtags); with
    ``revolve`` (element layers per quarter turn) the stack, flange and horn are swept from
    their (r, z) section (:func:`geometry.revolve.revolved_parts`). ``sectors`` (free parts
    only): every part cut down to the sector 0 <= theta <= 2 pi / sectors (:mod:`geometry.sector`)."""
    s, f = d.stack, d.flange
    pieces = [("coupler", "coupler", d.coupler.material, None, make_coupler(occ, d))]
    if revolve:
        return pieces + revolved_parts(occ, d, revolve)
    if s.threaded:      # the bolt's thread zones and holes: every body of revolution from its outline
        return _sector(occ, d, pieces + [(*o[:4], _revolved(occ, o[4])) for o in section_outlines(d)], sectors)
    # ---- stack
    for *meta, z0, z1 in stack_regions(d):
        pieces.append((*meta, _annular_cylinder(occ, z0, z1 - z0, s.outer_diameter / 2, s.inner_diameter / 2)))
    if s.bolt_diameter:        # one cylinder per stack layer, as the swept section's (geometry.revolve)
        pieces.append(("bolt", "bolt", s.bolt_material, None,
                       [dt for _r, _k, z0, z1 in d.stack_layers()
                        for dt in _annular_cylinder(occ, z0, z1 - z0, s.bolt_diameter / 2, 0.0)]))
    zf = s.length
    if d.fillets():
        pieces += _filleted_flange_horn(occ, d)
        return _sector(occ, d, pieces, sectors)
    pieces.append(("flange_disc", "flange", f.material, None,
                   _annular_cylinder(occ, zf, f.thickness, f.outer_diameter / 2, d.bore_diameter / 2)))
    pieces.append(("horn", "horn", d.horn.material, None, _horn(occ, d.horn, zf + f.thickness, d.bore_diameter)))
    return _sector(occ, d, pieces, sectors)


def _revolved(occ, outline):
    """The solid of revolution (a full turn about z) of an (r, z) outline with arcs."""
    face = section_face(occ, outline)
    return [dt for dt in occ.revolve([(2, face)], 0, 0, 0, 0, 0, 1, 2 * math.pi) if dt[0] == 3]


def _filleted_flange_horn(occ, d: RPUDDesign):
    """The flange and the horn with their fillets, revolved from their (r, z) outlines
    (:mod:`geometry.fillets`); an exponential horn is its loft from the flange fillet's tangent
    point on, fused to the revolved base that carries the fillet."""
    f, h = d.flange, d.horn
    flange, horn = flange_horn_outlines(d)
    out = [("flange_disc", "flange", f.material, None, _revolved(occ, flange))]
    if horn is not None:
        return out + [("horn", "horn", h.material, None, _revolved(occ, horn))]
    base = exponential_base(d)
    z0 = d.stack.length + f.thickness
    s0 = base[3][1] - z0
    n = 13
    wires = []
    for i in range(n):
        s = s0 + (h.length - s0) * i / (n - 1)
        wires.append(occ.addCurveLoop([occ.addCircle(0, 0, z0 + s, float(h.diameter_at(s)) / 2)]))
    vols = occ.addThruSections(wires, makeSolid=True, makeRuled=False)
    if d.bore_diameter > 0:
        hole = occ.addCylinder(0, 0, z0 - 1e-3, 0, 0, h.length + 2e-3, d.bore_diameter / 2)
        vols, _ = occ.cut(vols, [(3, hole)])
    vols, _ = occ.fuse(_revolved(occ, base), vols)
    return out + [("horn", "horn", h.material, None, vols)]


def _sector(occ, d: RPUDDesign, pieces, sectors):
    """``pieces`` cut down to the sector 0 <= theta <= 2 pi / sectors (all of them: None)."""
    if not sectors:
        return pieces
    r = max(d.coupler.outer_diameter, d.stack.outer_diameter, d.flange.outer_diameter, d.horn.back_diameter,
            d.horn.tip_diameter) / 2
    z0, z1 = -d.coupler.length - 1e-3, d.stack.length + d.flange.thickness + d.horn.length + 1e-3
    out = []
    for region, part, material, poling, dimtags in pieces:
        wedge = _sector_prism(occ, 0.0, 2 * math.pi / sectors, r + 1e-3, z0, z1 - z0)
        kept, _ = occ.intersect(dimtags, wedge)
        out.append((region, part, material, poling, kept))
    return out


def make_stack(occ, d: StackDesign, layers: dict[str, Layer]):
    """OCC solids of a stack: list of (region, part, material, poling, dimtags); the segments in
    ``layers`` as structured layers."""
    pieces = []
    ext = d.segment_extents()
    for seg in d.segments:
        z0, z1 = ext[seg.name]
        if seg.name in layers:
            vols = make_layer(occ, d, layers[seg.name])
        elif seg.kind == "box":
            vols = [(3, occ.addBox(-seg.thickness / 2, -seg.width / 2, z0, seg.thickness, seg.width, seg.length))]
        elif seg.kind == "cone":
            vols = [(3, occ.addCone(0, 0, z0, 0, 0, seg.length, seg.outer_diameter / 2, seg.end_diameter / 2))]
            if seg.inner_diameter > 0:
                hole = occ.addCylinder(0, 0, z0 - 1e-3, 0, 0, seg.length + 2e-3, seg.inner_diameter / 2)
                vols, _ = occ.cut(vols, [(3, hole)])
        else:
            vols = _annular_cylinder(occ, z0, seg.length, seg.outer_diameter / 2, seg.inner_diameter / 2)
        pieces.append((seg.name, seg.part, seg.material, seg.poling_vector, vols))
    return pieces

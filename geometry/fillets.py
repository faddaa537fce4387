"""Fillet arcs of an RPUD's bodies of revolution, in the (r, z) section.

A machined horn has no sharp inner corners: where the horn's back meets the flange's front face
and at the step of a stepped horn the outline runs along a circular arc tangent to both faces
(:class:`FilletArc`). Both are concave corners of one piece of metal (flange and horn are one
part on the lathe), so with the arc the elastic stress there is finite and converges with the
mesh; the sharp corner (radius 0) is a 270-degree re-entrant corner with a singular stress.

The flange fillet is shared by two regions of the model (``flange_disc`` and ``horn``): the
collar of metal between the sharp corner and the arc is cut along the line from the sharp
corner through the arc's centre, its lower half goes to the flange and its upper half to the
horn. Both halves then meet the arc at right angles, so neither region has a zero-angle cusp
(which a cut along the flange's face plane would leave at the arc's tangent point).

Outlines are :class:`Outline` tuples of (r, z) vertices, counter-clockwise, whose ``arcs`` map
an edge index ``i`` (vertex ``i`` to ``i + 1``) to the centre (r, z) of its circular arc.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["FilletArc", "Outline", "flange_fillet", "step_fillet", "horn_fillets", "flange_horn_outlines", "exponential_base",
           "revolved_volume", "outline_area_centroid"]


class Outline(tuple):
    """A closed (r, z) outline (m): its vertices as a tuple, ``arcs`` edge index -> arc centre."""

    def __new__(cls, points, arcs=None):
        obj = super().__new__(cls, tuple((float(r), float(z)) for r, z in points))
        obj.arcs = dict(arcs or {})
        return obj


@dataclass(frozen=True)
class FilletArc:
    """A circular fillet in the (r, z) section (all m).

    ``start`` lies on the first face (the plane or surface below or outside the corner),
    ``end`` on the second; ``centre`` and ``radius`` define the arc (a quarter turn or less);
    ``corner`` is the sharp corner the arc replaces; ``mid`` the arc point on the line from the
    corner to the centre (where the flange and the horn regions meet); ``z_top`` the highest z
    the arc reaches.
    """

    name: str
    start: tuple[float, float]
    end: tuple[float, float]
    centre: tuple[float, float]
    radius: float
    corner: tuple[float, float]

    @property
    def mid(self) -> tuple[float, float]:
        c, p = np.asarray(self.centre), np.asarray(self.corner)
        d = p - c
        m = c + self.radius * d / np.hypot(*d)
        return float(m[0]), float(m[1])

    @property
    def z_top(self) -> float:
        return max(self.start[1], self.end[1])

    @property
    def angle(self) -> float:
        """Turning angle of the arc, rad."""
        c = np.asarray(self.centre)
        a, b = np.asarray(self.start) - c, np.asarray(self.end) - c
        return float(abs(math.atan2(a[0] * b[1] - a[1] * b[0], a @ b)))


def _tangent_point(radius: float, slope, s_max: float) -> float:
    """Arc length s (m, along z) from the corner at which a circle of ``radius`` resting on the
    plane z = 0 touches the surface r(s) whose slope dr/ds is ``slope(s)``: the root of
    ``s - radius (1 + r'(s) / sqrt(1 + r'(s)^2)) = 0`` (the centre's height equals the radius;
    the outward normal of the surface is (1, -r') / sqrt(1 + r'^2))."""
    def g(s):
        d = slope(s)
        return s - radius * (1.0 + d / math.sqrt(1.0 + d * d))
    lo, hi = 0.0, s_max
    if g(lo) > 0 or g(hi) < 0:       # pragma: no cover - the design's checks keep the root inside
        raise ValueError("no tangent point")
    for _ in range(200):             # bisection to round-off
        mid = 0.5 * (lo + hi)
        if g(mid) < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def flange_fillet(radius, r0, z0, profile_r, profile_slope, s_max, name="flange"):
    """The fillet between the plane z = ``z0`` (metal below, the flange's face) and the surface
    of revolution r = ``profile_r(s)``, z = ``z0 + s`` (metal inside, the horn), corner (r0, z0).

    Returns None for ``radius`` 0."""
    if radius <= 0:
        return None
    s = _tangent_point(radius, profile_slope, s_max)
    d = profile_slope(s)
    n = np.array([1.0, -d]) / math.sqrt(1.0 + d * d)
    centre = np.array([profile_r(s), z0 + s]) + radius * n
    return FilletArc(name, (float(centre[0]), z0), (float(profile_r(s)), z0 + s),
                     (float(centre[0]), float(centre[1])), float(radius), (r0, z0))


def step_fillet(radius, r_tip, z_step):
    """The fillet at a step down to a cylinder of radius ``r_tip`` at height ``z_step`` (m)."""
    if radius <= 0:
        return None
    return FilletArc("step", (r_tip + radius, z_step), (r_tip, z_step + radius), (r_tip + radius, z_step + radius),
                     float(radius), (r_tip, z_step))


def horn_fillets(d) -> dict[str, FilletArc]:
    """The fillets of an RPUD design ``d`` (``"flange"``, ``"step"``; absent when radius 0)."""
    h = d.horn
    z0 = d.stack.length + d.flange.thickness
    out = {}
    prof = h.profile_function()
    f = flange_fillet(h.flange_fillet, h.back_diameter / 2, z0, lambda s: prof(s)[0], lambda s: prof(s)[1],
                      min(h.length, 4 * h.flange_fillet))
    if f is not None:
        out["flange"] = f
    if h.profile == "stepped":
        st = step_fillet(h.step_fillet, h.tip_diameter / 2, z0 + h.step_fraction * h.length)
        if st is not None:
            out["step"] = st
    return out


def flange_horn_outlines(d) -> tuple[Outline, Outline | None]:
    """(flange outline, horn outline) of an RPUD with its fillets; the horn's is None for an
    exponential profile (a loft, not a polygon with arcs: see :func:`exponential_base`). A
    threaded bolt's hole (:attr:`geometry.design_rpud.RPUDDesign.bolt_hole`) bores the flange
    and ends in the horn."""
    s, f, h = d.stack, d.flange, d.horn
    hole = getattr(d, "bolt_hole", None)
    b = hole[0] if hole else d.bore_diameter / 2
    zf = s.length
    z0 = zf + f.thickness
    Rf = f.outer_diameter / 2
    fil = horn_fillets(d)
    ff, sf = fil.get("flange"), fil.get("step")
    R0, Rt, L = h.back_diameter / 2, h.tip_diameter / 2, h.length
    if ff is None:
        flange = Outline(((b, zf), (Rf, zf), (Rf, z0), (b, z0)))
        horn_start, horn_arcs = [(b, z0), (R0, z0)], {}
    else:
        flange = Outline(((b, zf), (Rf, zf), (Rf, z0), ff.start, ff.mid, ff.corner, (b, z0)), {3: ff.centre})
        horn_start, horn_arcs = [(b, z0), ff.corner, ff.mid, ff.end], {2: ff.centre}
    if h.profile == "exponential":
        return flange, None
    pts = list(horn_start)
    arcs = dict(horn_arcs)
    if h.profile == "stepped":
        l1 = h.step_fraction * L
        pts.append((R0, z0 + l1))
        if sf is None:
            pts.append((Rt, z0 + l1))
        else:
            pts.append(sf.start)
            arcs[len(pts) - 1] = sf.centre
            pts.append(sf.end)
    pts.append((Rt, z0 + L))
    pts += [(0.0, z0 + L), (0.0, hole[1]), (b, hole[1])] if hole else [(b, z0 + L)]
    return flange, Outline(pts, arcs)


def exponential_base(d) -> Outline | None:
    """The revolved base of an exponential horn with a flange fillet: bore, the horn's bottom up
    to the sharp corner, the upper half of the collar, the arc up to its tangent point on the
    horn, and back to the bore at that height; the loft continues from there. None without a
    flange fillet."""
    ff = horn_fillets(d).get("flange")
    if ff is None:
        return None
    b = d.bore_diameter / 2
    z0 = ff.corner[1]
    return Outline(((b, z0), ff.corner, ff.mid, ff.end, (b, ff.end[1])), {2: ff.centre})


def _arc_angles(a, b, c):
    """Angles (rad) of ``a`` and ``b`` seen from the centre ``c``, the second one taken the
    shorter way round (fillet arcs turn by less than a half turn)."""
    ta = math.atan2(a[1] - c[1], a[0] - c[0])
    tb = math.atan2(b[1] - c[1], b[0] - c[0])
    tb = ta + (tb - ta + math.pi) % (2 * math.pi) - math.pi
    return ta, tb


def _edge_integrals(a, b, centre):
    """(int r dz, int r^2 / 2 dz) along one edge from ``a`` to ``b`` (a straight line, or the arc
    about ``centre``): its share of the area and of the first moment about the axis."""
    if centre is None:
        (r1, z1), (r2, z2) = a, b
        dz = z2 - z1
        # r linear in t on [0, 1]: int r dz = dz (r1 + r2)/2, int r^2/2 dz = dz (r1^2 + r1 r2 + r2^2)/6
        return dz * (r1 + r2) / 2, dz * (r1 * r1 + r1 * r2 + r2 * r2) / 6
    rc, zc = centre
    rho = math.hypot(a[0] - rc, a[1] - zc)
    t1, t2 = _arc_angles(a, b, centre)
    # r = rc + rho cos t, dz = rho cos t dt
    def prim(t):
        s, c = math.sin(t), math.cos(t)
        i1 = rc * rho * s + rho * rho * (t / 2 + math.sin(2 * t) / 4)          # int r dz
        i2 = 0.5 * rho * (rc * rc * s + 2 * rc * rho * (t / 2 + math.sin(2 * t) / 4)
                          + rho * rho * (s - s ** 3 / 3))                          # int r^2/2 dz
        return i1, i2
    p1, p2 = prim(t1), prim(t2)
    return p2[0] - p1[0], p2[1] - p1[1]


def outline_area_centroid(outline: Outline) -> tuple[float, float]:
    """(area m^2, integral of r over the area m^3) of a counter-clockwise outline, exact on arcs
    (Green's theorem: area = closed integral of r dz, int r dA = closed integral of r^2 / 2 dz)."""
    area = moment = 0.0
    n = len(outline)
    arcs = getattr(outline, "arcs", {})
    for i in range(n):
        a, m = _edge_integrals(outline[i], outline[(i + 1) % n], arcs.get(i))
        area += a
        moment += m
    return area, moment


def revolved_volume(outline: Outline) -> float:
    """Volume (m^3) of the solid swept by an (r, z) outline around the axis (Pappus, exact)."""
    return 2 * math.pi * outline_area_centroid(outline)[1]

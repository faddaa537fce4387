"""Stress fields at the nodes, a surface picture (off-screen PNG) and a VTU for ParaView.

Node values come from the recovered field of :mod:`fem.stress_table` (per region, element-node
values averaged at each node); a node shared by two regions (a bonded interface) shows the
larger of their values (the smaller for the most negative principal stress). Fields, each the
peak over one cycle of ``static + Re(hat exp(j w t))``: ``von_mises`` (Pa, every region),
``principal_max`` / ``principal_min`` (Pa; 24 phases and a parabola, :data:`PICTURE_PHASES`)
and ``efield`` (V/m, zero in metals).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rpud_common import ParameterError, atomic_output

from .stress import StressField, efield_cycle_peak, principal_cycle_extremes, vm_cycle_peak

__all__ = ["node_fields", "whole_drill_fields", "write_stress_vtu", "render_stress", "peak_title", "FIELDS"]

FIELDS = ("von_mises", "principal_max", "principal_min", "efield")

PICTURE_PHASES = 24
"""Phases of the principal-stress node fields (then a parabola through the best three): the
fields are for pictures and ParaView; the utilisation table samples 72."""


def node_fields(dynamic: StressField | None, static: StressField | None = None) -> dict[str, np.ndarray]:
    """``{name: (n_nodes,)}`` peak fields over a cycle (see the module docstring)."""
    ref = dynamic if dynamic is not None else static
    if ref is None:
        raise ParameterError("dynamic", None, "give a harmonic or a static stress field (or both)")
    n = ref.system.n_nodes
    hs = dynamic.nodal_average("stress").astype(complex) if dynamic is not None else np.zeros(ref.stress.shape, complex)
    he = dynamic.nodal_average("efield").astype(complex) if dynamic is not None else np.zeros(ref.efield.shape, complex)
    s0 = static.nodal_average("stress").real if static is not None else np.zeros(ref.stress.shape)
    e0 = static.nodal_average("efield").real if static is not None else np.zeros(ref.efield.shape)
    out = {"von_mises": np.zeros(n), "principal_max": np.full(n, -np.inf), "principal_min": np.full(n, np.inf),
           "efield": np.zeros(n)}
    for r in np.unique(ref.region):
        sel = ref.region == r
        nodes = ref.nodes[sel].ravel()
        uniq, first = np.unique(nodes, return_index=True)
        h, s = hs[sel].reshape(-1, 6)[first], s0[sel].reshape(-1, 6)[first]
        vm, _ = vm_cycle_peak(h, s)
        p1, p3 = principal_cycle_extremes(h, s, n_phases=PICTURE_PHASES)
        ef, _ = efield_cycle_peak(he[sel].reshape(-1, 3)[first], e0[sel].reshape(-1, 3)[first])
        out["von_mises"][uniq] = np.maximum(out["von_mises"][uniq], vm)
        out["principal_max"][uniq] = np.maximum(out["principal_max"][uniq], p1)
        out["principal_min"][uniq] = np.minimum(out["principal_min"][uniq], p3)
        out["efield"][uniq] = np.maximum(out["efield"][uniq], ef)
    for key in ("principal_max", "principal_min"):
        out[key][~np.isfinite(out[key])] = 0.0
    return out


def whole_drill_fields(system, fields: dict[str, np.ndarray]) -> tuple:
    """``(mesh, fields)`` to draw and write: on a :class:`fem.sector_system.SectorSystem` the
    whole drill replicated from the sector (:meth:`~fem.sector_system.SectorSystem.whole_mesh`,
    a P2 mesh) with each node's value that of its image in the sector (the node fields are
    invariants of a ``k = 0`` state: every sector carries the same values); else ``system`` and
    ``fields`` as given."""
    from .cyclic import sector_images
    from .modeshape import p2_nodes
    from .sector_system import SectorSystem

    if not isinstance(system, SectorSystem):
        return system, fields
    whole, _ = system.whole_mesh()
    _, j = sector_images(system.nodes, p2_nodes(whole), system.sectors)
    return whole, {k: np.asarray(v)[j] for k, v in fields.items()}


def write_stress_vtu(mesh, fields: dict[str, np.ndarray], path) -> Path:
    """Write the node fields (``{name: (n_nodes,)}``, SI) of ``mesh`` (a system, on its own
    order, or a quadratic :class:`geometry.mesh.TaggedMesh`) to a VTU (atomic); cell data
    ``region`` and ``part`` as in :func:`fem.render.write_modes_vtu`."""
    import meshio

    from .modeshape import mesh_context

    path = Path(path)
    if path.suffix.lower() != ".vtu":
        raise ParameterError("path", str(path), "must end in .vtu")
    ctx = mesh_context(mesh)
    n = len(ctx.nodes)
    for name, v in fields.items():
        if np.shape(v) != (n,):
            raise ParameterError(f"fields.{name}", np.shape(v), f"must be ({n},) node values")
    mesh = ctx.mesh
    cells = np.asarray(ctx.basis.element_dofs.T, dtype=np.int64)
    cell_type = "tetra10" if cells.shape[1] == 10 else "tetra"
    part_of_region = np.array([mesh.parts.index(r.part) for r in mesh.regions], dtype=np.int64)
    out = meshio.Mesh(np.asarray(ctx.nodes, float), [(cell_type, cells)],
                      point_data={f"{k}_{'V_per_m' if k == 'efield' else 'Pa'}": np.ascontiguousarray(v, float)
                                  for k, v in fields.items()},
                      cell_data={"region": [mesh.cell_region.astype(np.int64)],
                                 "part": [part_of_region[mesh.cell_region]]})
    with atomic_output(path) as tmp:
        meshio.write(tmp, out, file_format="vtu")
    return path


def write_stress_files(mesh, fields: dict[str, np.ndarray], png, vtu, title: str = "", mark=None) -> dict:
    """The von Mises picture ``png`` (:func:`render_stress`, titled, ``mark`` drawn) and the node
    fields ``vtu`` (:func:`write_stress_vtu`) of ``mesh``; either may be None (not written).
    Returns ``{"png": path, "vtu": path}``."""
    out = {"png": None, "vtu": None}
    if png is not None:
        out["png"] = render_stress(mesh, fields["von_mises"], png, title=title, mark=mark)
    if vtu is not None:
        out["vtu"] = write_stress_vtu(mesh, fields, vtu)
    return out


def peak_title(state: str, table) -> tuple[str, tuple | None]:
    """Title of a stress picture (the state, the metal peak) and the location to mark."""
    metal = [r for r in table.rows if r.quantity == "von_mises"]
    top = max(metal, key=lambda r: r.value) if metal else None
    if top is None:
        return f"von Mises peak over a cycle, {state}", None
    return (f"von Mises peak over a cycle, {state}\nmetal peak {top.value * 1e-6:.3g} MPa in {top.region} "
            "(red dot; may lie on the far side)", top.location)


def render_stress(mesh, values: np.ndarray, path, *, title: str = "", label: str = "von Mises peak (MPa)",
                  scale: float = 1e-6, mark=None, window_size=(1200, 800), axis_dir=(0.0, 0.0, 1.0)) -> Path:
    """Off-screen PNG of the undeformed surface of ``mesh`` (a system or a quadratic
    :class:`geometry.mesh.TaggedMesh`) coloured by ``values`` (n_nodes,) x ``scale``.

    ``mark``: a point (3,) m drawn as a red dot (the peak's location).
    """
    from geometry.render import offscreen_plotter

    from .modeshape import mesh_context
    from .render import check_window_size, screenshot, render_surface, add_triad

    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ParameterError("path", str(path), "must end in .png")
    ctx = mesh_context(mesh)
    v = np.asarray(values, float)
    if v.shape != (len(ctx.nodes),) or not np.all(np.isfinite(v)):
        raise ParameterError("values", v.shape, f"must be ({len(ctx.nodes)},) finite node values")
    w, h = check_window_size(window_size)
    s = render_surface(ctx.mesh)
    surf = s.surf.copy()
    surf.point_data["value"] = v[s.ids] * scale
    pl = offscreen_plotter((w, h))
    try:
        pl.set_background("white")
        pl.add_mesh(surf, scalars="value", cmap="turbo", smooth_shading=False,
                    scalar_bar_args={"title": label, "color": "black", "vertical": True, "position_x": 0.87,
                                     "position_y": 0.2, "height": 0.6, "width": 0.05, "title_font_size": 14,
                                     "fmt": "%.3g"})
        if s.edges.n_points:
            pl.add_mesh(s.edges, color="gray", line_width=1.0, opacity=0.6)
        if mark is not None:
            pl.add_points(np.asarray(mark, float).reshape(1, 3), color="red", point_size=14,
                          render_points_as_spheres=True)
        if title:
            pl.add_text(title, position="upper_left", font_size=12, color="black")
        add_triad(pl)
        screenshot(pl, s, axis_dir, path)
    finally:
        pl.close()
    return path

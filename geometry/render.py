"""Off-screen pyvista picture of a tagged mesh, parts coloured (pyvista imported on use)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from rpud_common import atomic_output
from .design_base import DesignBase
from .design_rpud import RPUDDesign
from .mesh import TaggedMesh

__all__ = ["render_png", "design_title", "offscreen_plotter"]

log = logging.getLogger(__name__)

_COLOURS = ["#4C72B0", "#DD8452", "#55A868", "#C44E52", "#8172B3", "#937860", "#DA8BC3", "#8C8C8C",
            "#CCB974", "#64B5CD"]


def design_title(design: DesignBase) -> str:
    """One or two lines describing the design with sizes in mm."""
    mm = 1e3
    if isinstance(design, RPUDDesign):
        h, s, c, f = design.horn, design.stack, design.coupler, design.flange
        return (f"{design.name}: horn {h.profile} {h.length * mm:.1f} mm, D {h.back_diameter * mm:.1f}/"
                f"{h.tip_diameter * mm:.1f} mm; {s.n_rings} x {s.material} {s.outer_diameter * mm:.0f}/"
                f"{s.inner_diameter * mm:.0f} x {s.ring_thickness * mm:.1f} mm\n"
                f"flange D {f.outer_diameter * mm:.0f} x {f.thickness * mm:.1f} mm; coupler {c.length * mm:.1f} mm, "
                f"D {c.outer_diameter * mm:.0f}/{design.coupler_bore * mm:.0f} mm, {c.n_slots} {c.slot_profile}-slots "
                f"at {c.slot_angle_deg:g} deg, {c.n_teeth} teeth")
    if not hasattr(design, "segments"):       # a drawing: its STEP file and regions
        from pathlib import Path

        regions = ", ".join(f"{r} ({rule.material})" for r, rule in design.region_rules().items())
        return f"{design.name}: {Path(design.step).name}; {regions}"
    parts = []
    for seg in design.segments:
        if seg.kind == "box":
            size = f"{seg.thickness * mm:.1f} x {seg.width * mm:.1f}"
        elif seg.kind == "cone":
            size = f"D {seg.outer_diameter * mm:.1f}->{seg.end_diameter * mm:.1f}"
        else:
            size = f"D {seg.outer_diameter * mm:.1f}" + (f"/{seg.inner_diameter * mm:.1f}" if seg.inner_diameter else "")
        parts.append(f"{seg.name} {seg.material} {size} x {seg.length * mm:.1f} mm")
    return f"{design.name}: " + "; ".join(parts)


def offscreen_plotter(window_size: tuple[int, int]):
    """A ``pyvista.Plotter`` that renders off screen, made without touching global state.

    pyvista's ``OFF_SCREEN`` flag is left as the user set it (the plotter is made with
    ``off_screen=True``). Without a display VTK would try an X window first and print "bad X
    server connection" before falling back; while this plotter's window is created, VTK is asked
    for its EGL window instead (the same picture, quietly), and the environment is restored
    right after. A user's own ``VTK_DEFAULT_OPENGL_WINDOW`` is respected.
    """
    import os

    import pyvista as pv

    key = "VTK_DEFAULT_OPENGL_WINDOW"
    if os.environ.get("DISPLAY") or key in os.environ:
        return pv.Plotter(off_screen=True, window_size=list(window_size))
    os.environ[key] = "vtkEGLRenderWindow"
    try:
        return pv.Plotter(off_screen=True, window_size=list(window_size))
    finally:
        os.environ.pop(key, None)


def render_png(mesh: TaggedMesh, path: str | Path, title: str = "", size: tuple[int, int] = (1400, 700)) -> Path:
    """Render ``mesh`` off screen, one colour per part, and write a PNG atomically.

    Parameters
    ----------
    mesh : TaggedMesh
    path : str or Path
        Output ``.png``.
    title : str
        Text at the top (sizes in mm by convention).
    size : (int, int)
        Window size in pixels.
    """
    import pyvista as pv

    corners = mesh.cells[:, :4]
    cells = np.hstack([np.full((len(corners), 1), 4), corners]).ravel()
    grid = pv.UnstructuredGrid(cells, np.full(len(corners), pv.CellType.TETRA, dtype=np.uint8), mesh.points * 1e3)
    parts = list(mesh.parts)
    part_of_region = np.array([parts.index(r.part) for r in mesh.regions])
    grid.cell_data["part"] = part_of_region[mesh.cell_region]
    plotter = offscreen_plotter(size)
    plotter.set_background("white")
    for i, part in enumerate(parts):
        sub = grid.extract_cells(np.flatnonzero(grid.cell_data["part"] == i)).extract_surface(algorithm="dataset_surface")
        plotter.add_mesh(sub, color=_COLOURS[i % len(_COLOURS)], show_edges=True, edge_color="#303030",
                         line_width=0.3, label=part)
    plotter.add_legend(bcolor="white", face="rectangle", size=(0.1, 0.035 * len(parts)))
    if title:
        plotter.add_text(title, position="upper_left", font_size=9, color="black")
    lo, hi = grid.points.min(axis=0), grid.points.max(axis=0)
    centre = 0.5 * (lo + hi)
    span = float(np.max(hi - lo))
    plotter.camera.focal_point = centre
    plotter.camera.position = centre + span * np.array([0.55, -1.1, 0.25])
    plotter.camera.up = (1.0, 0.0, 0.0)
    plotter.reset_camera()
    plotter.camera.zoom(1.6)
    path = Path(path)
    with atomic_output(path) as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()
    log.info("wrote %s", path)
    return path

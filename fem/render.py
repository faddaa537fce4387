"""Mode-shape pictures (off-screen pyvista PNG) and a ParaView file with every mode (VTU).

Shapes are nodal displacements at the P2 nodes of the tagged mesh, ``(n_modes, n_nodes, 3)``
(see :mod:`fem.modeshape`). Pictures use the linear (corner) nodes, which come first in that
node order; the VTU keeps every P2 node (quadratic ``tetra10`` cells).

pyvista is imported on first use, so importing this module is cheap.
"""

from __future__ import annotations

import re
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rpud_common import ParameterError, atomic_output
from geometry.mesh import TaggedMesh
from geometry.render import offscreen_plotter

from .modeshape import mesh_context, axis_frame, check_shapes

__all__ = ["render_mode", "render_modes", "write_modes_vtu", "mode_names", "around", "add_triad",
           "DEFAULT_WINDOW", "check_window_size", "screenshot", "render_surface"]

DEFAULT_WINDOW = (1200, 800)
_SCALE_FRACTION = 0.09      # auto scale: peak displacement = 9 % of the largest bounding-box side


@dataclass
class _Surface:
    surf: object            # pyvista PolyData of the undeformed boundary (corner nodes)
    ids: np.ndarray         # surface point -> P2 node index (corner nodes come first)
    edges: object           # feature edges of the undeformed surface
    extent: float           # largest bounding-box side, m


_SURF: "weakref.WeakKeyDictionary[TaggedMesh, _Surface]" = weakref.WeakKeyDictionary()


def _pv():
    import pyvista as pv

    return pv


def render_surface(mesh: TaggedMesh) -> _Surface:
    """The outer surface of ``mesh`` for pyvista renders (built once per mesh, cached)."""
    cached = _SURF.get(mesh)
    if cached is not None:
        return cached
    pv = _pv()
    sk = mesh_context(mesh).sk
    grid = pv.UnstructuredGrid({pv.CellType.TETRA: np.asarray(sk.t.T, dtype=np.int64)},
                               np.asarray(sk.p.T, dtype=float))
    grid.point_data["node"] = np.arange(grid.n_points)
    try:
        surf = grid.extract_surface(algorithm="dataset_surface")
    except TypeError:  # pyvista < 0.47
        surf = grid.extract_surface()
    ids = np.asarray(surf.point_data["node"], dtype=np.int64)
    edges = surf.extract_feature_edges(feature_angle=60, boundary_edges=True, non_manifold_edges=False,
                                       manifold_edges=False)
    extent = float(np.ptp(sk.p, axis=1).max())
    out = _Surface(surf=surf, ids=ids, edges=edges, extent=extent)
    _SURF[mesh] = out
    return out


def check_window_size(window_size) -> tuple[int, int]:
    """``(width, height)`` of a render window, pixels, checked (16 to 8192 each)."""
    try:
        w, h = (int(v) for v in window_size)
    except (TypeError, ValueError):
        raise ParameterError("window_size", window_size, "must be two integers (width, height) in pixels") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise ParameterError("window_size", window_size, "must lie in [16, 8192] pixels each")
    return w, h


def _camera(axis_dir) -> tuple[np.ndarray, np.ndarray]:
    """View direction (from the focal point to the camera) and view-up for an oblique view with
    the drill axis horizontal on screen."""
    e1, e2, d = axis_frame(axis_dir)
    view = 0.75 * e1 + 0.55 * e2 + 0.45 * d       # oblique, a little along the axis
    view /= np.linalg.norm(view)
    up = np.cross(d, view)                         # perpendicular to the axis and the view
    up /= np.linalg.norm(up)
    return view, up


def render_mode(mesh: TaggedMesh, shape, path, *, title: str = "", scale: float | None = None,
                window_size=DEFAULT_WINDOW, axis_dir=(0.0, 0.0, 1.0), show_edges: bool = False) -> Path:
    """Render one mode shape to a PNG, off screen.

    Parameters
    ----------
    mesh : TaggedMesh
    shape : (n_nodes, 3) array
        Displacement at the P2 nodes (any normalisation, real).
    path : path-like
        Output ``.png``; written atomically (temporary file, then rename).
    title : str
        Text at the top left (the caller puts the frequency and label there).
    scale : float, optional
        Displacement magnification. Default: peak displacement drawn as 9 % of the largest
        side of the bounding box.
    window_size : (width, height)
        Picture size in pixels.
    axis_dir : 3 floats
        Drill axis; it is drawn horizontal, seen obliquely.
    show_edges : bool
        Draw the element edges of the deformed surface.

    The deformed boundary is coloured by the displacement magnitude over its maximum (a mode shape has no
    absolute amplitude, so the colour bar is dimensionless, 0 to 1); the undeformed shape is a translucent grey
    ghost with its feature edges (dihedral angle > 60 deg) drawn as grey lines. An x, y, z triad at the lower
    left gives the orientation (:func:`add_triad`).
    """
    u = check_shapes(mesh, shape, "shape", allow_complex=False)
    if u.shape[0] != 1:
        raise ParameterError("shape", np.shape(shape), "must be one mode, (n_nodes, 3)")
    u = u[0]
    w, h = check_window_size(window_size)
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ParameterError("path", str(path), "must end in .png")
    s = render_surface(mesh)
    us = u[s.ids]
    mag = np.linalg.norm(us, axis=1)
    peak = float(np.linalg.norm(u[: mesh_context(mesh).n_vertices], axis=1).max())
    if scale is None:
        scale = _SCALE_FRACTION * s.extent / peak if peak > 0 else 0.0
    elif not (np.isfinite(scale) and scale >= 0):
        raise ParameterError("scale", scale, "must be a finite number >= 0")
    deformed = s.surf.copy()
    deformed.points = s.surf.points + scale * us
    deformed.point_data["displacement"] = mag / peak if peak > 0 else mag

    pl = offscreen_plotter((w, h))
    try:
        pl.set_background("white")
        pl.add_mesh(s.surf, color="lightgray", opacity=0.18, lighting=False)
        if s.edges.n_points:
            pl.add_mesh(s.edges, color="gray", line_width=1.0, opacity=0.6)
        pl.add_mesh(deformed, scalars="displacement", cmap="turbo", clim=(0.0, 1.0),
                    show_edges=show_edges, edge_color="black", smooth_shading=False,
                    scalar_bar_args={"title": "displacement / max (-)", "color": "black", "vertical": True,
                                     "position_x": 0.84, "position_y": 0.2, "height": 0.6, "title_font_size": 14,
                                     "width": 0.05, "fmt": "%.1f"})
        if title:
            pl.add_text(title, position="upper_left", font_size=14, color="black")
        pl.add_text(f"displacement x {scale:.3g}", position="lower_left", font_size=9, color="dimgray")
        add_triad(pl)
        screenshot(pl, s, axis_dir, path)
    finally:
        pl.close()
    return path


def add_triad(pl, *, viewport=(0.0, 0.08, 0.16, 0.32)) -> None:
    """Draw the x, y, z orientation triad (model axes, red/green/blue) in a corner of ``pl``.

    A mode shape seen obliquely has no other cue to which way the drill axis and the bending
    planes lie. The triad follows the camera, so it is right for whatever view is shot.
    ``viewport``: (xmin, ymin, xmax, ymax) of the triad as fractions of the picture.
    """
    pl.add_axes(xlabel="x", ylabel="y", zlabel="z", line_width=3, color="black", viewport=viewport)


def screenshot(pl, s, axis_dir: str, path) -> None:
    """Aim the camera at the surface ``s`` along ``axis_dir`` and write the screenshot atomically."""
    view, up = _camera(axis_dir)
    center = np.asarray(s.surf.center)
    pl.camera.focal_point = center
    pl.camera.position = center + view * 10 * s.extent
    pl.camera.up = up
    pl.reset_camera()
    pl.camera.zoom(1.15)
    with atomic_output(path) as tmp:
        pl.screenshot(str(tmp))


def mode_names(n_modes: int, frequencies: Sequence[float] | None = None, prefix: str = "mode") -> list[str]:
    """Default names ``mode_01_19987Hz`` (or ``mode_01`` without frequencies)."""
    if frequencies is None:
        return [f"{prefix}_{i + 1:02d}" for i in range(n_modes)]
    f = np.asarray(frequencies, dtype=float).ravel()
    if len(f) != n_modes or not np.all(np.isfinite(f)):
        raise ParameterError("frequencies", f"{len(f)} values", f"must be {n_modes} finite values in Hz")
    return [f"{prefix}_{i + 1:02d}_{fi:.0f}Hz" for i, fi in enumerate(f)]


def around(index: int, n_modes: int, width: int = 2) -> list[int]:
    """The mode ``index`` and up to ``width`` neighbours on each side (valid indices only)."""
    if not (0 <= index < n_modes):
        raise ParameterError("mode", index, f"must lie in [0, {n_modes - 1}]")
    return list(range(max(0, index - width), min(n_modes, index + width + 1)))


def render_modes(mesh: TaggedMesh, shapes, directory, *, modes: Sequence[int] | None = None,
                 frequencies: Sequence[float] | None = None, labels: Sequence[str] | None = None,
                 prefix: str = "mode", scale: float | None = None, window_size=DEFAULT_WINDOW,
                 axis_dir=(0.0, 0.0, 1.0)) -> list[Path]:
    """Render several modes (e.g. ``around(working, n)``) to ``directory/<prefix>_NN_<f>Hz.png``.

    ``frequencies`` (Hz) and ``labels`` are per mode of ``shapes`` (all of them, not only the
    rendered ones); the title reads ``Mode 7 - 19.987 kHz - longitudinal``. Returns the paths in
    the order of ``modes`` (default: all).
    """
    u = check_shapes(mesh, shapes, allow_complex=False)
    n = len(u)
    names = mode_names(n, frequencies, prefix)
    if labels is not None and len(labels) != n:
        raise ParameterError("labels", f"{len(labels)} labels", f"must be one per mode ({n})")
    if modes is None:
        modes = range(n)
    modes = list(modes)
    for m in modes:
        if not isinstance(m, (int, np.integer)) or not 0 <= m < n:
            raise ParameterError("modes", m, f"must be mode indices in [0, {n - 1}]")
    directory = Path(directory)
    paths = []
    for m in modes:
        parts = [f"Mode {m + 1}"]
        if frequencies is not None:
            parts.append(f"{float(frequencies[m]) / 1e3:.3f} kHz")
        if labels is not None:
            parts.append(str(labels[m]))
        paths.append(render_mode(mesh, u[m], directory / f"{names[m]}.png", title="  -  ".join(parts),
                                 scale=scale, window_size=window_size, axis_dir=axis_dir))
    return paths


_NAME_RE = re.compile(r"^[A-Za-z0-9_.+\-]+$")


def write_modes_vtu(mesh: TaggedMesh, shapes, path, *, names: Sequence[str] | None = None,
                    frequencies: Sequence[float] | None = None) -> Path:
    """Write every mode as point data of one VTU file for ParaView (atomic write).

    Cells are quadratic tetrahedra (VTK ``tetra10``, meshio ``"tetra10"``) on all P2 nodes,
    so the file carries the full P2 field; ParaView draws them with non-linear subdivision
    and ``Warp By Vector`` works on each mode. Point data: one 3-vector per mode named
    ``names[i]`` (default ``mode_01_19987Hz`` from ``frequencies``, else ``mode_01``). Cell
    data: ``region`` (index into ``mesh.regions``) and ``part`` (index into ``mesh.parts``).
    """
    import meshio

    u = check_shapes(mesh, shapes, allow_complex=False)
    path = Path(path)
    if path.suffix.lower() != ".vtu":
        raise ParameterError("path", str(path), "must end in .vtu")
    n = len(u)
    if names is None:
        names = mode_names(n, frequencies)
    names = [str(x) for x in names]
    if len(names) != n:
        raise ParameterError("names", f"{len(names)} names", f"must be one per mode ({n})")
    if len(set(names)) != n or any(not _NAME_RE.match(x) for x in names):
        raise ParameterError("names", names, "must be unique and made of letters, digits, _ . + -")
    if {"region", "part"} & set(names):
        raise ParameterError("names", names, "'region' and 'part' are reserved")
    ctx = mesh_context(mesh)
    cells = np.asarray(ctx.basis.element_dofs.T, dtype=np.int64)   # skfem P2 local order == VTK
    part_of_region = np.array([mesh.parts.index(r.part) for r in mesh.regions], dtype=np.int64)
    out = meshio.Mesh(
        np.asarray(ctx.nodes, dtype=float), [("tetra10", cells)],
        point_data={name: np.ascontiguousarray(u[i]) for i, name in enumerate(names)},
        cell_data={"region": [mesh.cell_region.astype(np.int64)],
                   "part": [part_of_region[mesh.cell_region]]},
    )
    with atomic_output(path) as tmp:
        meshio.write(tmp, out, file_format="vtu")
    return path

"""fem.render: off-screen PNGs are real pictures; the VTU holds one displacement field per mode."""

import meshio
import numpy as np
import pytest

from rpud_common import ParameterError
from fem.modeshape import p2_nodes
from fem.render import around, mode_names, render_mode, render_modes, write_modes_vtu

from test_fem_modeshape import bar, fields


@pytest.fixture(scope="module")
def tm():
    return bar()


def _image(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


def test_render_mode_png_is_a_real_picture(tm, tmp_path):
    f = fields(tm)
    out = render_mode(tm, f["bending"], tmp_path / "bend.png", title="Mode 9 - 19.987 kHz - bending",
                      window_size=(640, 400))
    img = _image(out)
    assert img.shape == (400, 640, 3)
    assert img.std() > 20                                   # not blank
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 200  # a colour map, not a flat fill
    # coloured (non-grey) pixels: the deformed body covers a good part of the picture
    rgb = img.astype(int)
    coloured = (rgb.max(axis=2) - rgb.min(axis=2)) > 60
    assert coloured.mean() > 0.03
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bend.png"]   # no temporary left


def test_render_modes_names_titles_and_neighbours(tm, tmp_path):
    f = fields(tm)
    shapes = np.stack([f["axial"], f["torsion"], f["bending"]])
    freqs = [15000.2, 19987.0, 24000.0]
    idx = around(1, 3, width=1)
    assert idx == [0, 1, 2] and around(0, 3, width=1) == [0, 1]
    paths = render_modes(tm, shapes, tmp_path / "renders", modes=idx, frequencies=freqs,
                         labels=["longitudinal", "torsional", "bending"], window_size=(320, 240))
    assert [p.name for p in paths] == ["mode_01_15000Hz.png", "mode_02_19987Hz.png", "mode_03_24000Hz.png"]
    for p in paths:
        assert _image(p).shape == (240, 320, 3) and _image(p).std() > 10


def test_modes_vtu_reopens_with_one_field_per_mode(tm, tmp_path):
    f = fields(tm)
    shapes = np.stack([f["axial"], f["torsion"], f["bending"]])
    path = write_modes_vtu(tm, shapes, tmp_path / "modes.vtu", frequencies=[15000.2, 19987.0, 24000.0])
    back = meshio.read(path)
    names = mode_names(3, [15000.2, 19987.0, 24000.0])
    assert names == ["mode_01_15000Hz", "mode_02_19987Hz", "mode_03_24000Hz"]
    assert sorted(back.point_data) == names
    nodes = p2_nodes(tm)
    np.testing.assert_allclose(back.points, nodes)
    for name, u in zip(names, shapes):
        assert back.point_data[name].shape == (len(nodes), 3)
        np.testing.assert_allclose(back.point_data[name], u)
    cells = back.cells_dict["tetra10"]
    assert cells.shape == (tm.n_cells, 10)
    # VTK tetra10 order: the edge nodes are the midpoints of edges 01, 12, 02, 03, 13, 23
    pts = back.points[cells]
    for k, (a, b) in enumerate([(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]):
        np.testing.assert_allclose(pts[:, 4 + k], 0.5 * (pts[:, a] + pts[:, b]), atol=1e-15)
    np.testing.assert_array_equal(back.cell_data["region"][0], tm.cell_region)
    # also readable by VTK itself (what ParaView uses)
    import pyvista as pv

    grid = pv.read(path)
    assert grid.n_cells == tm.n_cells and set(names) <= set(grid.point_data)
    custom = write_modes_vtu(tm, shapes[:1], tmp_path / "one.vtu", names=["working"])
    assert list(meshio.read(custom).point_data) == ["working"]


def test_bad_input(tm, tmp_path):
    f = fields(tm)
    with pytest.raises(ParameterError, match="shape"):
        render_mode(tm, f["axial"][:, :2], tmp_path / "x.png")
    with pytest.raises(ParameterError, match="must end in .png"):
        render_mode(tm, f["axial"], tmp_path / "x.jpg")
    with pytest.raises(ParameterError, match="names"):
        write_modes_vtu(tm, np.stack([f["axial"]] * 2), tmp_path / "x.vtu", names=["a", "a"])
    with pytest.raises(ParameterError, match="names"):
        write_modes_vtu(tm, f["axial"], tmp_path / "x.vtu", names=["a", "b"])
    with pytest.raises(ParameterError, match="shapes"):
        write_modes_vtu(tm, f["axial"][None, ::2], tmp_path / "x.vtu")
    with pytest.raises(ParameterError, match="real"):
        write_modes_vtu(tm, f["axial"] * 1j, tmp_path / "x.vtu")
    with pytest.raises(ParameterError, match="modes"):
        render_modes(tm, f["axial"], tmp_path, modes=[3])
    assert not any(tmp_path.iterdir())


def test_rendering_leaves_no_global_state(tm, tmp_path, monkeypatch):
    # a notebook user's pyvista flag and environment must survive a render from the library
    import os

    import pyvista as pv

    monkeypatch.setattr(pv, "OFF_SCREEN", False)
    env = dict(os.environ)
    render_mode(tm, fields(tm)["bending"], tmp_path / "b.png", window_size=(160, 100))
    assert pv.OFF_SCREEN is False
    assert dict(os.environ) == env

"""CAD in: ``kind = "cad"`` designs (a STEP file and a rule table), the STEP export of
parametric designs, and the split of the design kinds into modules of their own.

Reference: the parametric design itself. Exported as STEP + rules and read back, the default
design must give the same regions, surfaces, electrodes, closed-form volumes and axial layout,
and -- meshed at the default refinement -- its working mode within 0.05 % (f_r and f_a). The
structural checks use coarse meshes (``refine`` 1.5, ~25k DOFs) to keep the file fast.
"""

from __future__ import annotations

import math
import numpy as np
import pytest

import fem
import geometry
from geometry.cad_export import export_cad
from geometry.design import load_design
from geometry.design_cad import CadDesign
from geometry.design_stack import ElectrodeSpec, Segment, StackDesign
from geometry.report import mesh_part_volumes
from rpud_common import ParameterError, run_cli
from reference_designs import reference_default

REFINE = 1.5
ROUND_TRIP_TOL = 5e-4        # the 0.05 % on f_r and f_a


def _default():
    """The default drill, with its 2 mm fillets: the horn's length stretches the two sections
    around the step fillet (one declared band spans both and the fillet between), and the flange
    fillet's metal is split between flange and horn along a slanted line (the flange part reaches
    above the flange's face, to the arc's mid point). Without the bolt part: the STEP export's
    parametric layout has no bolt region. At the lengths of tests/reference_designs.py, where the
    round trip's working mode was measured (two free meshes of the same solids differ by mesh
    noise of that size: +3.5e-4 / +5.1e-4 at horn 68.04 mm, coupler 49.714 mm)."""
    return reference_default().replace({"stack.bolt_diameter": 0.0})


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    # another STEP file written first: OpenCASCADE numbers the files a process writes, and the
    # export must label its solids whatever that number is
    from geometry.cad import gmsh_session, native_stdout_quiet

    with gmsh_session() as gmsh:
        gmsh.model.occ.addBox(0, 0, 0, 0.01, 0.01, 0.01)
        gmsh.model.occ.synchronize()
        with native_stdout_quiet():
            gmsh.write(str(tmp_path_factory.mktemp("cad") / "first.step"))
    folder = tmp_path_factory.mktemp("cad") / "export"
    step, toml = export_cad(_default(), folder)
    return folder, step, toml


@pytest.fixture(scope="module")
def meshes(exported):
    d0 = _default()
    d1 = load_design(exported[2])
    return d0, d1, geometry.build_mesh(d0, refine=REFINE), geometry.build_mesh(d1, refine=REFINE)


def _langevin_stack() -> StackDesign:
    """Steel back 10 mm / PZT-4 disc 2 mm / steel front 10 mm, D 10 mm: three solids."""
    return StackDesign(name="mini", target_frequency=60e3, segments=(
        Segment("back", 0.010, material="steel_45", outer_diameter=0.010),
        Segment("disc", 0.002, material="PZT-4", outer_diameter=0.010, poling="+z", part="stack"),
        Segment("front", 0.010, material="steel_45", outer_diameter=0.010)),
        electrodes=(ElectrodeSpec("electrode_0", "disc", "bottom", "ground"),
                    ElectrodeSpec("electrode_1", "disc", "top", "hot")))


@pytest.fixture(scope="module")
def mini_step(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mini")
    step, _toml = export_cad(_langevin_stack(), folder)
    return step


def _mini_toml(step, volumes: str, surfaces: str = "") -> str:
    return f'kind = "cad"\nname = "mini"\nstep = "{step.name}"\ntarget_frequency = 60000.0\n' + volumes + surfaces


_MINI_VOLUMES = '''
[[volumes]]
region = "back"
material = "steel_45"
select = {{ box = [-0.006, -0.006, -0.001, 0.006, 0.006, 0.0101] }}
[[volumes]]
region = "disc"
part = "stack"
material = "PZT-4"
poling = "+z"
select = {{ point = [0.001, 0.002, 0.011] }}
[[volumes]]
region = "front"
material = "steel_45"
select = {{ name = "{front}" }}
'''

_MINI_SURFACES = '''
[[surfaces]]
name = "electrode_0"
role = "ground"
select = { plane = { normal = [0, 0, -1], offset = -0.010 }, regions = ["disc"] }
[[surfaces]]
name = "electrode_1"
role = "hot"
select = { plane = { normal = [0, 0, 1], offset = 0.012 }, box = [-0.01, -0.01, 0.011, 0.01, 0.01, 0.013] }
[[surfaces]]
name = "top"
select = { point = [0.0, 0.001, 0.022] }
'''


# ---------------------------------------------------------------------------- layout


def test_design_kinds_in_modules_of_their_own_with_the_old_import_paths():
    import geometry.design as loader
    import geometry.design_rpud as rpud
    import geometry.design_stack as stack

    assert geometry.RPUDDesign is loader.RPUDDesign is rpud.RPUDDesign
    assert geometry.StackDesign is loader.StackDesign is stack.StackDesign
    assert geometry.CadDesign is loader.CadDesign is CadDesign
    assert geometry.default_design is loader.default_design is rpud.default_design
    assert set(loader.KINDS) == {"rpud", "stack", "cad"}
    assert loader.POLING_VECTORS["-z"] == (0.0, 0.0, -1.0)


# ---------------------------------------------------------------------------- round trip


def test_export_reads_back_with_the_parametric_layout(exported):
    folder, step, toml = exported
    assert sorted(p.name for p in folder.iterdir()) == ["design.step", "design.toml"]
    d0, d1 = _default(), load_design(toml)
    assert isinstance(d1, CadDesign) and d1.default_tuned == ("lengths.horn_length.value",
                                                              "lengths.coupler_length.value")
    # OpenCASCADE's volumes of the drawing = the closed forms (helical slots, tooth gaps included)
    v0 = {r: v for r, _p, _m, v in d0.region_table()}
    for region, part, material, vol in d1.region_table():
        assert vol == pytest.approx(v0[region], rel=1e-6), region
    # a drawing's part spans its solids (the flange's up to the fillet arc's mid point)
    a = d0.fillets()["flange"]
    for part, (z0, z1) in d0.part_extents().items():
        z1 = a.mid[1] if part == "flange" else z1
        assert d1.part_extents()[part] == pytest.approx((z0, z1), abs=1e-9), part
    p0, p1 = d0.electrode_planes(), d1.electrode_planes()
    assert set(p0) == set(p1)
    for name in p0:
        assert [a for a, _ in p1[name]] == [a for a, _ in p0[name]] == ["z"]
        assert [z for _, z in p1[name]] == pytest.approx([z for _, z in p0[name]], abs=1e-12), name
    # the solids are labelled in the STEP file and selected by label and point
    assert all(r.select.name == r.region and r.select.point is not None for r in d1.volumes)


def test_round_trip_mesh_structure(meshes):
    d0, d1, m0, m1 = meshes
    assert [(r.name, r.part, r.material, r.poling) for r in m0.regions] == \
        [(r.name, r.part, r.material, r.poling) for r in m1.regions]
    assert set(m0.facet_sets) == set(m1.facet_sets)
    assert m0.electrodes == m1.electrodes
    assert len(m1.facet_sets["teeth_tops"]) > 0 and len(m1.facet_sets["flange"]) > 0


def test_round_trip_working_mode_at_the_default_mesh(exported):
    """The issue's check: the default design re-imported from its STEP export, both meshed at the
    default refinement, has the same working mode within 0.05 % (measured on the filleted default:
    f_r +2.9e-4, f_a +4.4e-4; 15 565 vs 15 279 tetrahedra: two free meshes of the same solids)."""
    out = []
    for design in (_default(), load_design(exported[2])):
        res = fem.modal_analysis(fem.assemble(geometry.build_mesh(design)), near_hz=20000.0, n_modes=4)
        w = res.working
        assert res.labels[w] == "longitudinal"
        out.append((res.f_r_hz[w], res.f_a_hz[w]))
    (fr0, fa0), (fr1, fa1) = out
    assert abs(fr1 / fr0 - 1) < ROUND_TRIP_TOL and abs(fa1 / fa0 - 1) < ROUND_TRIP_TOL


def test_declared_lengths_morph_like_the_parametric_lengths(meshes):
    """A declared length stretches its band (nodes above shift). The coupler's band is its one
    zone: the same map as the parametric length change, up to a rigid shift, and the same
    volumes. The horn's band spans its back section, the step fillet and the tip section: the
    tip moves as the parametric one, and inside the band the uniform stretch differs from the
    parametric map (sections stretched, fillet zones kept) by at most dL c / B (c the fillet
    zones' length, B the band's), and the horn's volume by at most pi (R0^2 - Rt^2) dL c / B."""
    d0, d1, m0, m1 = meshes
    pts = m1.points
    for path0, path1, factor in (("horn.length", "lengths.horn_length.value", 1.03),
                                 ("coupler.length", "lengths.coupler_length.value", 1.05)):
        p0 = d0.replace({path0: d0.get(path0) * factor})
        dl = p0.get(path0) - d0.get(path0)
        p1 = d1.replace({path1: d1.get(path1) + dl})
        dz = d1.morph_points(pts, p1)[:, 2] - d0.morph_points(pts, p0)[:, 2]
        v0 = {r: v for r, _p, _m, v in p0.region_table()}
        if path0 == "coupler.length":
            assert np.ptp(dz) < 1e-12, path1
            for region, _part, _mat, vol in p1.region_table():
                assert vol == pytest.approx(v0[region], rel=1e-6), (path1, region)
            continue
        h, band = d0.horn, d1.lengths[0]
        c = h.flange_fillet + h.step_fillet
        top = pts[:, 2] > band.z1 - 1e-9
        assert np.abs(dz[top]).max() < 1e-12
        assert np.abs(dz).max() <= dl * c / band.drawn
        dv = math.pi * ((h.back_diameter / 2) ** 2 - (h.tip_diameter / 2) ** 2) * dl * c / band.drawn
        v1 = {r: v for r, _p, _m, v in p1.region_table()}
        assert abs(v1["horn"] - v0["horn"]) <= dv and v1["flange_disc"] == pytest.approx(v0["flange_disc"], rel=1e-6)
    # a built design with a declared length away from the drawing is the drawing's mesh, stretched
    longer = d1.replace({"lengths.horn_length.value": 0.070})
    m2 = geometry.build_mesh(longer, refine=REFINE)
    assert m2.n_points == m1.n_points and np.array_equal(m2.cells, m1.cells)       # deterministic Gmsh
    assert np.abs(m2.points - d1.morph_points(m1.points, longer)).max() < 1e-15
    assert m2.points[:, 2].max() == pytest.approx(longer.part_extents()["horn"][1], abs=1e-9)
    vols = mesh_part_volumes(m2)[0]
    # the band's and the fixed zones' mesh volumes carry their own discretisation errors (up to
    # 1.5e-4 of the closed form on curved faces, tests/test_fillets.py): the stretched ratio
    # (V_o + s V_b) / (V_o + V_b) of the mesh differs from the exact one by <= (s - 1) 3e-4 / 4
    s = longer.lengths[0].value / longer.lengths[0].drawn
    assert vols["horn"] / mesh_part_volumes(m1)[0]["horn"] == pytest.approx(
        longer.part_volumes()["horn"] / d1.part_volumes()["horn"], abs=(s - 1) * 3e-4 / 4)
    assert longer.electrode_planes() == d1.electrode_planes()      # the stack lies below the band


# ---------------------------------------------------------------------------- selectors


def test_selection_by_box_point_label_and_plane(mini_step, tmp_path):
    toml = mini_step.parent / "own.toml"
    toml.write_text(_mini_toml(mini_step, _MINI_VOLUMES.format(front="front"), _MINI_SURFACES))
    d = load_design(toml)
    assert [r for r, *_ in d.region_table()] == ["back", "disc", "front"]
    vols = {r: v for r, _p, _m, v in d.region_table()}
    assert vols["disc"] == pytest.approx(np.pi / 4 * 0.010 ** 2 * 0.002, rel=1e-9)
    assert d.electrode_planes() == {"electrode_0": [("z", 0.010)], "electrode_1": [("z", 0.012)]}
    mesh = geometry.build_mesh(d, order=1, mesh_size=0.003)
    assert {e.name: e.role for e in mesh.electrodes} == {"electrode_0": "ground", "electrode_1": "hot"}
    assert mesh.region("disc").poling == (0.0, 0.0, 1.0)
    for name, z in (("electrode_0", 0.010), ("electrode_1", 0.012), ("top", 0.022)):
        tri = mesh.facet_sets[name]
        assert len(tri) > 0 and np.allclose(mesh.points[tri, 2], z, atol=1e-9), name
    # the electrode is the whole disc face: straight triangles inside the circle, at least the
    # inscribed 12-gon (Gmsh's 12 elements per circle)
    p = mesh.points[mesh.facet_sets["electrode_1"]]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    assert 3 * 0.005 ** 2 * (1 - 1e-9) <= area <= np.pi * 0.005 ** 2
    # same rules, saved elsewhere: the STEP path stays right (relative to the new file)
    (tmp_path / "sub").mkdir()
    d.save(tmp_path / "sub" / "again.toml")
    assert load_design(tmp_path / "sub" / "again.toml").region_table() == d.region_table()


@pytest.mark.parametrize("volumes, surfaces, expected", [
    # a rule that matches nothing
    (_MINI_VOLUMES.format(front="nose"), "", ("volumes[2] (region front)", "name = 'nose'", "matches no solid")),
    # one rule, two solids
    (_MINI_VOLUMES.format(front="front").replace("0.006, 0.006, 0.0101]", "0.006, 0.006, 0.0121]"), "",
     ("volumes[0] (region back)", "matches 2 solids", "narrow the selection")),
    # a solid no rule claims
    (_MINI_VOLUMES.format(front="front").split('[[volumes]]\nregion = "front"')[0], "",
     ("volumes = ", "1 solid(s) match no [[volumes]] rule")),
    # a face rule that matches nothing
    (_MINI_VOLUMES.format(front="front"), '\n[[surfaces]]\nname = "tip"\nselect = { point = [0, 0, 0.05] }\n',
     ("surfaces[0] (tip)", "matches no face")),
], ids=["nothing", "two-solids", "unclaimed", "no-face"])
def test_bad_rules_are_one_clear_line(mini_step, volumes, surfaces, expected, capsys):
    toml = mini_step.parent / "bad.toml"
    toml.write_text(_mini_toml(mini_step, volumes, surfaces))
    with pytest.raises(ParameterError) as exc:
        load_design(toml)
    assert all(part in str(exc.value) for part in expected), str(exc.value)
    # the command line: one line on stderr, exit 2, no output written
    from geometry.__main__ import main

    out = mini_step.parent / "bad.json"
    assert run_cli(main, ["--design", str(toml), "--json", str(out)], prog="python -m geometry") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected[-1] in err and not out.exists()


def test_bad_step_path_and_options(mini_step, capsys):
    toml = mini_step.parent / "nofile.toml"
    toml.write_text(_mini_toml(mini_step, _MINI_VOLUMES.format(front="front")).replace(mini_step.name, "gone.step"))
    with pytest.raises(ParameterError, match="gone.step.*file does not exist"):
        load_design(toml)
    good = mini_step.parent / "good.toml"
    good.write_text(_mini_toml(mini_step, _MINI_VOLUMES.format(front="front"), _MINI_SURFACES))
    d = load_design(good)
    with pytest.raises(ParameterError, match="--grade"):
        geometry.build_mesh(d, grade=True)
    # no declared lengths: --match refuses before meshing, in one line
    from fem.matching import default_tune
    from fem.modal_cli import main

    with pytest.raises(ParameterError, match="no lengths to tune"):
        default_tune(d)
    assert run_cli(main, ["--design", str(good), "--match"], prog="python -m fem.modal") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "[[lengths]]" in err


def test_export_command_line(tmp_path, capsys):
    from geometry.__main__ import main

    examples = str(__import__("pathlib").Path(geometry.__file__).parent / "examples.toml")
    out = tmp_path / "k33"
    assert run_cli(main, ["--design", examples, "--select", "k33_rod", "--export-step", str(out)],
                   prog="python -m geometry") == 0
    assert sorted(p.name for p in out.iterdir()) == ["design.step", "design.toml"]
    stdout = capsys.readouterr().out
    assert "wrote" in stdout and "Statistics on Transfer" not in stdout
    d = load_design(out / "design.toml")
    assert {e.name for e in d.electrodes} == {e.name for e in load_design(examples, "k33_rod").electrodes}
    # a cad design is not exported again
    assert run_cli(main, ["--design", str(out / "design.toml"), "--export-step", str(tmp_path / "again")],
                   prog="python -m geometry") == 2
    assert "already a cad design" in capsys.readouterr().err and not (tmp_path / "again").exists()


def test_pipeline_and_library_do_not_grade_a_drawing_unasked(exported):
    """The whole-drill path grades a parametric drill toward its re-entrant edges by default, but
    a drawing's re-entrant edges are not known and its mesher refuses grading: the pipeline's
    resolved mesh options (and ``fem.default_system``) leave it ungraded unless asked, so
    ``python -m results --design drawing.toml`` runs; asking with ``--grade`` stays refused."""
    from fem.sector_system import whole_grade
    from results.pipeline import PipelineSettings

    drawing = load_design(exported[2])
    assert whole_grade(_default()) and not whole_grade(drawing)
    opt = PipelineSettings().mesh_options().resolved(drawing)
    assert opt.path == "whole" and opt.grade is False and "ungraded" in opt.label(drawing)
    assert PipelineSettings(path="whole").mesh_options().resolved(_default()).grade is True
    with pytest.raises(ParameterError, match="grade"):
        geometry.build_mesh(drawing, grade=True)

"""Hostile material records and CAD inputs: every one ends cleanly.

Material records (a ``--materials FILE`` or a design's ``[materials]`` table) must keep every
field inside its stated physical range (``geometry.materials.FIELD_RANGES``, ``POISSON_RANGE``,
``TABLE_RANGES``, ``SOUND_SPEED_RANGE``), and a record must suit the part's role (no ceramic
horn, no metal stack). CAD designs refuse unusable ``step`` paths and solids of no drill's size
(``geometry.cad.SOLID_SIZE_RANGE``) before meshing. ``python -m geometry`` runs every check,
the resource budget included, before it writes anything, and refuses options that do not apply
to the run. A refusal is exit code 2, one stderr line naming the field or option, no traceback
and no new file; the command lines run in-process (``run_cli``) in a fresh folder.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import tempfile
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geometry.materials import (FIELD_RANGES, POISSON_RANGE, TABLE_RANGES, builtin_library, load_library,
                                records_from_mapping)
from rpud_common import ParameterError, run_cli

ROOT = Path(__file__).resolve().parents[1]

_SETTINGS = dict(derandomize=True, deadline=None, database=None, suppress_health_check=list(HealthCheck))

TI = {"kind": "isotropic", "density": 4430.0, "youngs_modulus": 113.8e9, "poisson_ratio": 0.342, "q_mech": 1e4}
"""A valid metal record (the built-in Ti-6Al-4V's constants)."""


def _ceramic() -> dict:
    """A valid ceramic record (the built-in PZT-8, stress-charge form)."""
    return builtin_library()["PZT-8"].to_record()


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def run_refused(argv: list[str], files: dict[str, object] | None = None, setup=None) -> str:
    """Run ``python -m geometry argv`` in a fresh folder holding ``files`` (name -> text, bytes
    or a mapping written as TOML); assert exit 2, one stderr line, no traceback, no new file;
    return the line."""
    from geometry.__main__ import main

    old = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for name, content in (files or {}).items():
            data = tomli_w.dumps(content).encode() if isinstance(content, dict) else content
            (root / name).write_bytes(data if isinstance(data, bytes) else data.encode())
        if setup:
            setup(root)
        before = _files(root)
        err, out = io.StringIO(), io.StringIO()
        os.chdir(root)
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
                code = run_cli(main, argv + ["-q"], prog="python -m geometry")
        except SystemExit as exc:
            code = exc.code
        finally:
            os.chdir(old)
        after = _files(root)
    text = err.getvalue()
    assert code == 2, f"{argv}: exit {code}, stderr {text!r}"
    assert text.count("\n") == 1 and text.endswith("\n"), f"{argv}: stderr {text!r}"
    assert "Traceback" not in text and "internal error" not in text, text
    assert after == before, f"{argv}: new files {sorted(after - before)}"
    return text


# ----------------------------------------------------------------------------- material records

_SCALAR_CASES = [
    ("isotropic", "density", 1e300), ("isotropic", "density", 1e-300), ("isotropic", "density", 50.0),
    ("isotropic", "youngs_modulus", 1e300), ("isotropic", "youngs_modulus", 1e-300),
    ("isotropic", "youngs_modulus", 113.8),                        # GPa typed for Pa
    ("isotropic", "q_mech", 1e300), ("isotropic", "q_mech", 1e-300), ("isotropic", "q_mech", 2.0),
    ("isotropic", "poisson_ratio", 0.5), ("isotropic", "poisson_ratio", -1.0), ("isotropic", "poisson_ratio", 1e300),
    ("isotropic", "tan_delta", 0.5), ("isotropic", "tan_delta", 0.01),   # metals carry no field
    ("isotropic", "fatigue_strength", 1e300), ("isotropic", "fatigue_strength", 510.0),
    ("piezo", "density", 1e300), ("piezo", "density", 1e-300), ("piezo", "q_mech", 1e300),
    ("piezo", "q_mech", 1e-300), ("piezo", "tan_delta", 0.5), ("piezo", "tensile_strength", 1e-300),
    ("piezo", "compressive_strength", 1e300), ("piezo", "depolarisation_field", 1.5),
]


@pytest.mark.parametrize("kind, key, value", _SCALAR_CASES)
def test_material_file_out_of_range_field_is_one_line(kind, key, value):
    rec = {**(TI if kind == "isotropic" else _ceramic()), key: value}
    line = run_refused(["--materials", "m.toml", "--json", "o.json"],
                       {"m.toml": {"ti6al4v" if kind == "isotropic" else "PZT-8": rec}})
    assert f".{key} = " in line, line


@pytest.mark.parametrize("table, key, value", [
    ("c_E", "c33", 1e300), ("c_E", "c33", 1e-300), ("c_E", "c13", -1e300), ("e", "e33", 1e300),
    ("e", "e33", 150.0), ("eps_S", "eps33", 1e-300), ("eps_S", "eps33", 1e300), ("eps_S", "eps11", 0.5),
])
def test_material_file_out_of_range_constant_is_one_line(table, key, value):
    rec = _ceramic()
    rec[table] = {**rec[table], key: value}
    line = run_refused(["--materials", "m.toml", "--json", "o.json"], {"m.toml": {"PZT-8": rec}})
    assert f"materials.PZT-8.{table}.{key} = " in line, line


def test_design_materials_table_is_checked_like_a_file():
    line = run_refused(["--design", "d.toml", "--json", "o.json"],
                       {"d.toml": {"materials": {"ti6al4v": {**TI, "density": 1e300}}}})
    assert "materials.ti6al4v.density = 1e+300: must lie in [100, 25000] kg/m^3" in line


def test_pairs_of_fields_must_make_a_solid():
    """Each field in range, the pair not: a bar speed of 63 m/s, a bulk modulus of 3.5e12 Pa,
    an open-circuit stiffness of 1e15 Pa (e = 100 C/m^2 against eps = 1)."""
    with pytest.raises(ParameterError, match=r"materials\.x\.density .*wave speed"):
        records_from_mapping({"x": {**TI, "youngs_modulus": 1e8, "density": 25e3}}, "test")
    with pytest.raises(ParameterError, match=r"materials\.x\.poisson_ratio .*bulk modulus"):
        records_from_mapping({"x": {**TI, "youngs_modulus": 209e9, "poisson_ratio": 0.49}}, "test")
    rec = _ceramic()
    rec["e"] = {**rec["e"], "e33": 100.0}
    rec["eps_S"] = {**rec["eps_S"], "eps33": 1.0}
    with pytest.raises(ParameterError, match=r"materials\.x\.e .*open-circuit stiffness"):
        records_from_mapping({"x": rec}, "test")


def test_strain_charge_converting_out_of_range_names_the_given_table():
    """A nearly singular compliance converts to a stiffness above any solid's: the message names s_E."""
    rec = {"kind": "piezo", "density": 7600.0, "d": {"d31": -1e-15, "d33": 1e-15, "d15": 1e-15},
           "eps_T": {"eps11": 1290.0, "eps33": 1000.0},
           "s_E": {"s11": 1e-12, "s12": -0.4999e-12, "s13": -0.4999e-12, "s33": 1e-12, "s44": 3e-12, "s66": 3e-12}}
    with pytest.raises(ParameterError, match=r"materials\.x\.s_E = 'c_E\..*converts to a stress-charge"):
        records_from_mapping({"x": rec}, "test")


def _outside(lo: float, hi: float, open_: bool = False):
    """Numbers and non-numbers outside ``[lo, hi]`` (the bounds themselves with ``open_``)."""
    far = st.integers(1, 300).map(lambda k: 10.0 ** k)
    above = far.map(lambda f: hi * f if hi > 0 else hi + f)
    below = far.map(lambda f: lo / f if lo > 0 else lo - f)
    special = [math.nan, math.inf, -math.inf, "1e3", True, [1.0]] + ([lo, hi] if open_ else [])
    if lo >= 0:
        special += [-1e-300]
    if lo > 0:
        special += [0.0, 1e-300]
    return st.one_of(above, below, st.sampled_from(special))


_FIELDS = {**{k: (lo, hi, False) for k, (lo, hi, _u, _w) in FIELD_RANGES.items()},
           "poisson_ratio": (*POISSON_RANGE, True)}


@st.composite
def hostile_record(draw):
    """A valid record with one field or table constant outside its range: (record, field path)."""
    kind = draw(st.sampled_from(["isotropic", "piezo"]))
    rec = dict(TI) if kind == "isotropic" else _ceramic()
    fields = [k for k in _FIELDS if k != "depolarisation_field" or kind == "piezo"]
    if kind == "piezo":
        fields = [k for k in fields if k not in ("youngs_modulus", "poisson_ratio")]
        fields += [f"{t}.{k}" for t in ("c_E", "e", "eps_S") for k in rec[t]]
    path = draw(st.sampled_from(fields))
    if "." in path:
        table, key = path.split(".")
        pre = "eps" if table == "eps_S" else table.split("_")[0]
        lo, hi, _u, _w = TABLE_RANGES[pre]
        diagonal = pre in ("c", "eps") and key[-1] == key[-2]
        value = draw(_outside(lo, hi) if diagonal else _outside(-hi, hi))
        rec[table] = {**rec[table], key: value}
    else:
        lo, hi, open_ = _FIELDS[path]
        value = draw(_outside(lo, hi, open_))
        if path == "q_mech" and value == math.inf:
            value = -math.inf                     # inf is the documented lossless value
        rec[path] = value
    return rec, path


@settings(max_examples=1000, **_SETTINGS)
@given(hostile_record())
def test_fuzz_every_field_out_of_range_is_refused_naming_it(case):
    rec, path = case
    with pytest.raises(ParameterError) as info:
        records_from_mapping({"x": rec}, "test")
    assert info.value.name.startswith(f"materials.x.{path}"), (path, str(info.value))
    assert "\n" not in str(info.value)


@settings(max_examples=100, **_SETTINGS)
@given(hostile_record())
def test_fuzz_material_files_end_in_one_line(case):
    rec, _path = case
    run_refused(["--materials", "m.toml", "--json", "o.json"], {"m.toml": {"rec": rec}})


def test_every_shipped_material_and_example_still_loads():
    from geometry.design import load_design
    from rpud_common import load_toml

    lib = load_library(ROOT / "geometry" / "materials.toml")
    assert {"steel_45", "ti6al4v", "al7075", "copper", "epoxy", "PZT-4", "PZT-8", "PZT-5A"} <= set(lib)
    examples = ROOT / "geometry" / "examples.toml"
    for name in load_toml(examples):
        load_design(examples, name)
    for path in sorted((ROOT / "results" / "examples").glob("*.toml")):
        if "kind" in load_toml(path) or "segments" in load_toml(path):
            load_design(path)


# ----------------------------------------------------------------------------- roles

@pytest.mark.parametrize("design, words", [
    ({"horn": {"material": "PZT-8"}}, "horn.material = 'PZT-8': is a piezoceramic: the horn must be a passive"),
    ({"coupler": {"material": "PZT-4"}}, "coupler.material = 'PZT-4': is a piezoceramic"),
    ({"flange": {"material": "PZT-5A"}}, "flange.material = 'PZT-5A': is a piezoceramic"),
    ({"stack": {"electrode_shims": True, "shim_material": "PZT-4"}}, "stack.shim_material = 'PZT-4'"),
    ({"stack": {"material": "ti6al4v"}}, "stack.material = 'ti6al4v': must be a piezoceramic"),
    ({"horn": {"material": "myceramic"}, "materials": {"myceramic": _ceramic()}},
     "horn.material = 'myceramic': is a piezoceramic"),
])
def test_a_record_in_the_wrong_role_is_refused(design, words):
    line = run_refused(["--design", "d.toml", "--json", "o.json"], {"d.toml": design})
    assert words in line, line


# ----------------------------------------------------------------------------- CAD inputs

def _cad(step: str) -> bytes:
    return (f'kind = "cad"\nstep = "{step}"\n[[volumes]]\nregion = "a"\nmaterial = "steel_45"\n'
            'select = { box = [-5.0, -5.0, -5.0, 5.0, 5.0, 5.0] }\n').encode()


def _box_step(size: float):
    """A setup writing ``box.step``: one cube of side ``size`` m."""
    def setup(root: Path):
        from geometry.cad import gmsh_session, native_stdout_quiet

        with gmsh_session() as gmsh:
            gmsh.option.setString("Geometry.OCCTargetUnit", "M")
            gmsh.model.occ.addBox(0, 0, 0, size, size, size)
            gmsh.model.occ.synchronize()
            with native_stdout_quiet():
                gmsh.write(str(root / "box.step"))
    return setup


@pytest.mark.parametrize("step, words", [
    ("~nosuchuser_rpud/x.step", "step = '~nosuchuser_rpud/x.step': names the home folder of an unknown user"),
    ("a\\u0000b.step", "step = 'a\\x00b.step': must not contain NUL or control characters"),
    ("a\\tb.step", "must not contain NUL or control characters"),
    ("nofile.step", "file does not exist"),
    ("x" * 300 + ".step", "step = "),
])
def test_unusable_step_paths_are_one_line(step, words):
    line = run_refused(["--design", "d.toml", "--json", "o.json"], {"d.toml": _cad(step)})
    assert words in line, line


@pytest.mark.parametrize("size, words", [(1e-6, "measures 0.001"), (3.0, "measures 3000 mm across")])
def test_solids_of_no_drill_size_are_refused_before_meshing(size, words):
    line = run_refused(["--design", "d.toml", "--json", "o.json"], {"d.toml": _cad("box.step")},
                       setup=_box_step(size))
    assert words in line and "a drill part measures 1 mm to 2000 mm" in line, line


def test_a_centimetre_cube_is_accepted():
    from geometry.design import load_design

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _box_step(0.01)(root)
        (root / "d.toml").write_bytes(_cad("box.step"))
        d = load_design(root / "d.toml")
        assert d.region_table()[0][3] == pytest.approx(1e-6, rel=1e-6)


def test_step_path_helper():
    from geometry.design_cad import step_path

    assert step_path("x.step", "/base") == "/base/x.step"
    assert step_path("/abs/x.step", "/base") == "/abs/x.step"
    assert step_path(5, "/base") == 5                      # left for the design's own check
    for bad in ("~nosuchuser_rpud/x.step", "a\0b.step", ""):
        with pytest.raises(ParameterError, match=r"^step = "):
            step_path(bad, "/base")


# ----------------------------------------------------------------------------- options and order

@pytest.mark.parametrize("argv, words", [
    # the budget refuses the mesh: nothing exported first
    (["--export-step", "out", "--json", "o.json", "--mesh-size", "1e-4"], "--mesh-size = 0.0001"),
    (["--export-step", "adir", "--mesh", "o.msh", "--refine", "0.2"], "--refine = 0.2"),
    # --write-default takes no other option (it exits at once)
    (["--export-step", "out", "--write-default", "d.toml"],
     "--export-step = 'out': does not apply with --write-default"),
    (["--write-default", "d.toml", "--json", "o.json"], "--json = 'o.json': does not apply with --write-default"),
    (["--write-default", "d.toml", "--design", "afile"], "--design"),
    (["--write-default", "d.toml", "--mesh-size", "0.01"], "--mesh-size"),
    # meshing options without a mesh to build
    (["--export-step", "out", "--refine", "2"], "--refine = 2.0: acts on meshing only"),
    (["--export-step", "out", "--order", "1"], "--order = 1: acts on meshing only"),
    (["--export-step", "out", "--allow-large"], "--allow-large = True: acts on meshing only"),
    (["--export-step", "out", "--mesher", "free"], "--mesher = 'free'"),
])
def test_export_and_write_default_refuse_before_writing(argv, words):
    def setup(root):
        (root / "afile").write_text("x")
        (root / "adir").mkdir()
    line = run_refused(argv, setup=setup)
    assert words in line, line

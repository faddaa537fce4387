"""The validation layer: bounded design values, output paths, TOML files, dataclass mapping, the
atomic writers.

Every refusal is a :class:`ParameterError` whose message names the parameter, shows the value
and states what is allowed, with its unit; nothing is created on disk by a refused call.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import pytest

import geometry
from rpud_common import files as common
from rpud_common import (MAX_TOML_BYTES, MAX_TOML_DEPTH, NAME_MAX, PATH_MAX, ParameterError, atomic_folder,
                             check_output_paths, from_mapping, json_text, load_toml, toml_section, write_json)
from geometry.validate import (FREQUENCY_BAND, MAX_COUNT, MAX_LENGTH, MIN_FEATURE, check_bore, check_count,
                               check_frequency, check_length, check_material, check_name, design_table,
                               finite_or_none)

# ----------------------------------------------------------------------------- geometry.validate


@pytest.mark.parametrize("value", [MIN_FEATURE / 2, MAX_LENGTH * 1.01, 0.0, -0.01, math.nan, math.inf,
                                   -math.inf, 1e308, True, "0.1", None])
def test_length_bounds_name_the_range_and_unit(value):
    with pytest.raises(ParameterError) as exc:
        check_length("horn.length", value)
    text = str(exc.value)
    assert text.startswith("horn.length = ")
    assert f"[{MIN_FEATURE:g}, {MAX_LENGTH:g}] m" in text


@pytest.mark.parametrize("value", [MIN_FEATURE, 0.05, MAX_LENGTH, 1])
def test_lengths_inside_the_range_pass(value):
    check_length("horn.length", value)


def test_bore_is_zero_or_a_real_feature():
    check_bore("bore_diameter", 0.0)
    check_bore("bore_diameter", MIN_FEATURE)
    with pytest.raises(ParameterError, match=r"bore_diameter = 5e-05: must be 0 \(none\) or >= 0.0001 m"):
        check_bore("bore_diameter", 5e-5)
    with pytest.raises(ParameterError, match=r"bore_diameter = -0.001: must lie in \[0, 2\] m"):
        check_bore("bore_diameter", -1e-3)


@pytest.mark.parametrize("value", [FREQUENCY_BAND[0] * 0.99, FREQUENCY_BAND[1] * 1.01, 1e-320, math.nan, -2e4])
def test_frequency_band_in_hz(value):
    with pytest.raises(ParameterError, match=r"^target_frequency = .*: must lie in \[100, 1e\+06\] Hz$"):
        check_frequency("target_frequency", value)
    check_frequency("target_frequency", 20e3)


def test_counts_are_bounded_integers():
    check_count("coupler.n_slots", 0)
    check_count("stack.n_rings", 4, minimum=2, even=True)
    with pytest.raises(ParameterError, match=rf"stack.n_rings = 100000: must be an integer in \[2, {MAX_COUNT}\]"):
        check_count("stack.n_rings", 100000, minimum=2, even=True)
    with pytest.raises(ParameterError, match=r"stack.n_rings = 3: must be an even integer .*ground at both ends"):
        check_count("stack.n_rings", 3, minimum=2, even=True)
    for bad in (True, 2.0, "4", -1, None):
        with pytest.raises(ParameterError, match=r"^coupler.n_slots = "):
            check_count("coupler.n_slots", bad)


@pytest.mark.parametrize("value", ["../evil", "/abs/path", "", "a/b", "..", "a..b", "x" * 65, "a\nb", "a b",
                                   ".hidden", "-x", 5, None])
def test_names_that_would_leave_their_folder_are_refused(value):
    with pytest.raises(ParameterError, match=r"^name = .*: must be 1-64 letters.*becomes a file name"):
        check_name("name", value)


def test_names_and_segment_names():
    for ok in ("rpud-default", "k33_rod", "PZT+steel", "v1.2", "x" * 64):
        check_name("name", ok)
    with pytest.raises(ParameterError, match="no dots"):
        check_name("segments[0].name", "a.b", dots=False)


def test_material_must_be_known():
    check_material("horn.material", "ti6al4v")
    with pytest.raises(ParameterError, match=r"horn.material = 'unobtainium': unknown; known: .*ti6al4v"):
        check_material("horn.material", "unobtainium")
    with pytest.raises(ParameterError, match="must be a material name"):
        check_material("horn.material", 7)


def test_segment_start_is_finite_or_absent():
    finite_or_none("segments[0].start", None)
    finite_or_none("segments[0].start", -0.5)
    for bad in (math.nan, math.inf, 11.0, True, "0"):
        with pytest.raises(ParameterError, match=r"must be a finite number in \[-10, 10\] m or absent"):
            finite_or_none("segments[0].start", bad)


def test_design_table_shapes():
    single = {"kind": "rpud", "name": "x"}
    assert design_table(single, "d.toml", None, ("kind", "name")) == (single, "")
    several = {"a": {"kind": "stack"}, "b": {"kind": "stack"}}
    assert design_table(several, "d.toml", "b", ("kind",)) == ({"kind": "stack"}, "b")
    with pytest.raises(ParameterError, match=r"^design = 'd.toml': is empty"):
        design_table({}, "d.toml", None, ("kind",))
    with pytest.raises(ParameterError, match=r"^select = 'a': d.toml holds a single design"):
        design_table(single, "d.toml", "a", ("kind", "name"))
    with pytest.raises(ParameterError, match=r"^design = 'd.toml': holds several designs; select one of: a, b"):
        design_table(several, "d.toml", None, ("kind",))
    with pytest.raises(ParameterError, match=r"^select = 'c': unknown design; known: a, b"):
        design_table(several, "d.toml", "c", ("kind",))


@pytest.mark.parametrize("change, name, words", [
    ({"stack.ring_thickness": 1e-6}, "stack.ring_thickness", "[0.0001, 2] m"),
    ({"horn.length": math.inf}, "horn.length", "[0.0001, 2] m"),
    ({"target_frequency": 1e7}, "target_frequency", "[100, 1e+06] Hz"),
    ({"stack.n_rings": 100000}, "stack.n_rings", "integer in [2, 64]"),
    ({"name": "../evil"}, "name", "file name"),
])
def test_designs_use_the_layer(change, name, words):
    """A design refuses through the same checks: the dotted field name and the range."""
    with pytest.raises(ParameterError) as exc:
        geometry.default_design().replace(change)
    assert exc.value.name == name and words in str(exc.value)


# ----------------------------------------------------------------------------- output paths


def test_output_paths_accepted_and_named(tmp_path):
    got = check_output_paths(json=str(tmp_path / "o.json"), csv=None, plots=str(tmp_path / "plots"),
                             folders=("plots",))
    assert got == {"json": tmp_path / "o.json", "plots": tmp_path / "plots"}
    (tmp_path / "plots").mkdir()                     # an existing output folder is fine (replaced whole)
    check_output_paths(plots=str(tmp_path / "plots"), folders=("plots",))


@pytest.mark.parametrize("make, words", [
    (lambda r: "", "must be a path"),
    (lambda r: "   ", "must be a path"),
    (lambda r: str(r / "a\0b.json"), "must be a path"),
    (lambda r: str(r / ("n" * (NAME_MAX + 1) + ".json")), f"at most {NAME_MAX} are allowed"),
    (lambda r: str(r / "/".join(["d" * 200] * 25) / "o.json"), f"path longer than {PATH_MAX} bytes"),
    (lambda r: str(r / "nodir" / "o.json"), "does not exist"),
    (lambda r: str(r / "afile" / "o.json"), "is not a folder"),
    (lambda r: str(r / "adir"), "is a folder; give a file path"),
    (lambda r: str(r / ".."), "must end in a file or folder name"),
    (lambda r: 5, "must be a path"),
])
def test_unusable_output_paths(tmp_path, make, words):
    (tmp_path / "afile").write_text("x")
    (tmp_path / "adir").mkdir()
    before = sorted(tmp_path.iterdir())
    with pytest.raises(ParameterError) as exc:
        check_output_paths(json=make(tmp_path))
    assert exc.value.name == "--json" and words in str(exc.value)
    assert sorted(tmp_path.iterdir()) == before


def test_folder_output_on_a_file_and_shared_and_input_paths(tmp_path, monkeypatch):
    (tmp_path / "afile").write_text("x")
    design = tmp_path / "d.toml"
    design.write_text("kind = 'rpud'\n")
    with pytest.raises(ParameterError, match=r"^--plots = .*is an existing file; an output folder is expected"):
        check_output_paths(plots=str(tmp_path / "afile"), folders=("plots",))
    monkeypatch.chdir(tmp_path)
    # one file under two spellings
    with pytest.raises(ParameterError, match=r"^--csv = './o.json': is also the output of --json"):
        check_output_paths(json="o.json", csv="./o.json")
    with pytest.raises(ParameterError, match=r"^--out-design = .*would overwrite the input --design"):
        check_output_paths(inputs={"--design": str(design)}, out_design="d.toml")


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes anywhere")
def test_unwritable_parent(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        with pytest.raises(ParameterError, match="is not writable"):
            check_output_paths(json=str(locked / "o.json"))
    finally:
        locked.chmod(0o700)


# ----------------------------------------------------------------------------- load_toml


def test_load_toml_reads_utf8_and_a_bom(tmp_path):
    p = tmp_path / "c.toml"
    p.write_bytes("\ufeffname = 'caf\u00e9'\n[a]\nb = 1\n".encode())
    assert load_toml(p) == {"name": "caf\u00e9", "a": {"b": 1}}


def test_load_toml_refuses_non_utf8(tmp_path):
    p = tmp_path / "c.toml"
    p.write_bytes(b"m_free = 0.004\n# caf\xe9\n")
    with pytest.raises(ParameterError, match=r"^--config = .*c.toml': is not UTF-8 text \(byte 0xe9 at offset 20\)"):
        load_toml(p, "--config")


def test_load_toml_refuses_deep_nesting(tmp_path):
    p = tmp_path / "c.toml"
    ok = MAX_TOML_DEPTH - 1           # the key's table is one level, the arrays the others
    p.write_text("a = " + "[" * ok + "]" * ok + "\n")
    load_toml(p)
    for depth in (MAX_TOML_DEPTH + 1, 400, 5000):
        p.write_text("a = " + "[" * depth + "]" * depth + "\n")
        with pytest.raises(ParameterError, match=rf"nests deeper than {MAX_TOML_DEPTH} levels"):
            load_toml(p)
    p.write_text("\n".join(f"[{'.'.join('t' * 1 for _ in range(k))}]" for k in (1, MAX_TOML_DEPTH + 2)) + "\n")
    with pytest.raises(ParameterError, match="nests deeper"):
        load_toml(p)


def test_load_toml_refuses_a_large_file_before_reading_it(tmp_path):
    p = tmp_path / "c.toml"
    with p.open("wb") as f:
        f.truncate(MAX_TOML_BYTES + 1)    # sparse: a big file without writing it
    with pytest.raises(ParameterError, match=rf"is {MAX_TOML_BYTES + 1} bytes; at most {MAX_TOML_BYTES} are read"):
        load_toml(p, "--design")


@pytest.mark.parametrize("value, words", [("", "must name a TOML file"), ("  ", "must name a TOML file"),
                                          ("a\0b", "must name a TOML file"), (None, "must name a TOML file"),
                                          ("missing.toml", "file does not exist"),
                                          (".", "is not a regular file")])
def test_load_toml_refuses_bad_paths(tmp_path, monkeypatch, value, words):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ParameterError) as exc:
        load_toml(value, "--design")
    assert exc.value.name == "--design" and words in str(exc.value)


def test_load_toml_refuses_a_folder_and_bad_syntax(tmp_path):
    with pytest.raises(ParameterError, match="is not a regular file"):
        load_toml(tmp_path, "--design")
    p = tmp_path / "c.toml"
    p.write_text("[horn\nlength = 1\n")
    with pytest.raises(ParameterError, match=r"is not valid TOML \(.*line 1"):
        load_toml(p, "--design")


# ----------------------------------------------------------------------------- toml_section


def test_toml_section_top_level_or_one_table():
    assert toml_section({"m_free": 0.004}, "impact") == {"m_free": 0.004}
    assert toml_section({"impact": {"m_free": 0.004}}, "impact") == {"m_free": 0.004}
    with pytest.raises(ParameterError, match=r"^m_free = 0.004: top-level key next to the \[impact\] table in "
                                             r"c.toml: move it into \[impact\] or drop the table"):
        toml_section({"m_free": 0.004, "impact": {"A0": 1.5e-5}}, "impact", "c.toml")
    with pytest.raises(ParameterError, match=r"^impact = 3: must be a table \(\[impact\]\)"):
        toml_section({"impact": 3}, "impact")


# ----------------------------------------------------------------------------- from_mapping


@dataclass(frozen=True)
class _Inner:
    length: float
    count: int = 4


@dataclass(frozen=True)
class _Outer:
    inner: _Inner
    name: str = "x"
    sizes: tuple[float, ...] = (1.0,)
    pair: tuple[float, float] = (0.0, 1.0)
    mode: str = "a"
    extra: list = field(default_factory=list)


def test_from_mapping_missing_required_field_is_named():
    with pytest.raises(ParameterError, match=r"^inner = None: required field is missing"):
        from_mapping(_Outer, {"name": "y"})
    with pytest.raises(ParameterError, match=r"^inner.length = None: required field is missing"):
        from_mapping(_Outer, {"inner": {"count": 2}})


def test_from_mapping_unknown_key_lists_the_allowed_ones():
    with pytest.raises(ParameterError, match=r"^inner.lenght = 1.0: unknown key; allowed: length, count"):
        from_mapping(_Outer, {"inner": {"lenght": 1.0}})
    with pytest.raises(ParameterError, match=r"^nmae = 'y': unknown key; allowed: inner, name"):
        from_mapping(_Outer, {"inner": {"length": 1.0}, "nmae": "y"})


def test_from_mapping_types():
    got = from_mapping(_Outer, {"inner": {"length": 1, "count": 3.0}, "sizes": [1, 2.5], "pair": [1, 2]})
    assert got == _Outer(_Inner(1.0, 3), sizes=(1.0, 2.5), pair=(1.0, 2.0))
    for data, where, words in [
        ({"inner": {"length": "1"}}, "inner.length", "must be a number"),
        ({"inner": {"length": True}}, "inner.length", "must be a number"),
        ({"inner": {"length": 10 ** 400}}, "inner.length", "must be a finite number"),
        ({"inner": {"length": math.nan}}, "inner.length", "must be a finite number"),
        ({"inner": {"length": -math.inf}}, "inner.length", "must be a finite number"),
        ({"inner": {"length": 1.0, "count": 2.5}}, "inner.count", "must be an integer"),
        ({"inner": 3}, "inner", "must be a table of _Inner fields"),
        ({"inner": {"length": 1.0}, "sizes": 3}, "sizes", "must be a list"),
        ({"inner": {"length": 1.0}, "sizes": [1, "x"]}, "sizes[1]", "must be a number"),
        ({"inner": {"length": 1.0}, "pair": [1, 2, 3]}, "pair", "must be a list of 2 values"),
        ({"inner": {"length": 1.0}, "name": 5}, "name", "must be a string"),
    ]:
        with pytest.raises(ParameterError) as exc:
            from_mapping(_Outer, data)
        assert exc.value.name == where and words in str(exc.value), (data, str(exc.value))
    with pytest.raises(ParameterError, match="must be a table of _Outer fields"):
        from_mapping(_Outer, [1, 2])


def test_a_hostile_value_is_shortened_in_the_message():
    with pytest.raises(ParameterError) as exc:
        from_mapping(_Outer, {"inner": {"length": "x" * 10_000}})
    assert len(str(exc.value)) < 200 and "..." in str(exc.value)


# ----------------------------------------------------------------------------- JSON


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_write_json_refuses_nonfinite_before_any_file_exists(tmp_path, bad):
    target = tmp_path / "new" / "deeper" / "o.json"
    with pytest.raises(ParameterError, match=r"^json = .*result entry 'fit.points\[1\].slope' is not finite"):
        write_json(target, {"fit": {"points": [{"slope": 1.0}, {"slope": bad}]}})
    assert list(tmp_path.iterdir()) == []          # not even the parent folders


def test_json_nonfinite_as_null_and_numpy_values(tmp_path):
    import numpy as np

    text = json_text({"a": np.float64("nan"), "b": np.arange(2), "c": (np.int32(3), True)}, nonfinite="null",
                     provenance=False)
    assert text == '{\n  "a": null,\n  "b": [\n    0,\n    1\n  ],\n  "c": [\n    3,\n    true\n  ]\n}\n'
    with pytest.raises(ParameterError, match=r"^--json = nan: result entry 'a'"):
        json_text({"a": np.float32("nan")}, name="--json")


# ----------------------------------------------------------------------------- atomic_folder


def _siblings(root: Path) -> list[str]:
    return sorted(p.name for p in root.iterdir())


def _old_results(root: Path) -> Path:
    out = root / "res"
    out.mkdir()
    (out / "old.txt").write_text("previous run")
    (out / "sub").mkdir()
    (out / "sub" / "f.png").write_bytes(b"png")
    return out


def test_atomic_folder_creates_and_swaps(tmp_path):
    out = tmp_path / "res"
    with atomic_folder(out) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".res.part-")
        (tmp / "a.txt").write_text("first")
    assert _siblings(tmp_path) == ["res"] and _siblings(out) == ["a.txt"]
    with atomic_folder(out) as tmp:
        (tmp / "b.txt").write_text("second")
    assert _siblings(tmp_path) == ["res"] and _siblings(out) == ["b.txt"]


def test_atomic_folder_rolls_back_on_failure(tmp_path):
    out = _old_results(tmp_path)
    with pytest.raises(RuntimeError):
        with atomic_folder(out) as tmp:
            (tmp / "new.txt").write_text("half a run")
            raise RuntimeError("stage failed")
    assert _siblings(tmp_path) == ["res"]
    assert _siblings(out) == ["old.txt", "sub"] and (out / "sub" / "f.png").read_bytes() == b"png"


def test_atomic_folder_keeps_the_old_folder_when_the_swap_fails(tmp_path, monkeypatch):
    """The old folder is moved aside first; if the new one cannot take its place it goes back."""
    out = _old_results(tmp_path)
    real = os.replace

    def failing_replace(src, dst):
        if Path(src).name.startswith(".res.part-"):
            raise OSError(28, "No space left on device", str(dst))
        return real(src, dst)

    monkeypatch.setattr(common.os, "replace", failing_replace)
    with pytest.raises(OSError, match="No space left"):
        with atomic_folder(out) as tmp:
            (tmp / "new.txt").write_text("new run")
    monkeypatch.undo()
    assert _siblings(tmp_path) == ["res"]
    assert _siblings(out) == ["old.txt", "sub"] and (out / "old.txt").read_text() == "previous run"


def test_atomic_folder_needs_an_existing_parent(tmp_path):
    with pytest.raises(ParameterError, match="does not exist"):
        with atomic_folder(tmp_path / "nodir" / "res"):
            pass
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("field, value", [("band", 0.7), ("band", 0.0), ("band", math.nan), ("n_points", 2),
                                          ("n_points", 10.5), ("voltage", -1.0), ("handoff_digits", 13)])
def test_pipeline_settings_name_the_bad_field(field, value):
    from results.pipeline import PipelineSettings

    with pytest.raises(ParameterError, match=field):
        PipelineSettings(**{field: value})

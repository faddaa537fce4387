"""Property-based fuzzing of every CLI: hostile options, design/config files and output paths.

Every example is invalid on purpose, so every run must end the same clean way: exit code 2,
exactly one line on stderr, no traceback, no new file. The CLIs run in-process through
``run_cli(main, argv)`` (validation happens before any meshing or solving, so an example takes
milliseconds); examples are derandomized so the suite is reproducible. Counts: see ``EXAMPLES``.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import signal
import tempfile
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import geometry
from rpud_common import run_cli

EXAMPLES = {"geometry": 200, "design_toml": 300, "fem.modal": 200, "fem.harmonic": 200, "results": 150,
            "impact": 30, "impact sweep": 25, "impact article": 15, "impact config": 25}
"""Examples per property (about 1,150 in all; the impact counts are the impact package's)."""

_SETTINGS = dict(derandomize=True, deadline=None, database=None,
                 suppress_health_check=list(HealthCheck))

BAD_FLOAT = ["nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "-1", "abc", "", "1e400", "0x10", "--"]
"""Hostile values for a float option whose valid range excludes 0 and negatives."""

BAD_INT = ["0", "-1", "100000000", "1.5", "nan", "abc", "", "9" * 30]

LONG = "n" * 300


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout()


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def run_clean(main, argv: list[str], setup=None, prog: str = "cli", limit: float = 20.0):
    """Run ``main(argv)`` through ``run_cli`` in a fresh folder; assert the clean refusal."""
    old_cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "afile").write_text("x")
        (root / "adir").mkdir()
        if setup:
            setup(root)
        before = _files(root)
        err, out = io.StringIO(), io.StringIO()
        os.chdir(root)
        old = signal.signal(signal.SIGALRM, _alarm)
        signal.setitimer(signal.ITIMER_REAL, limit)
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
                code = run_cli(main, list(argv), prog=prog)
        except SystemExit as exc:       # argparse usage errors; __main__ passes the code on
            code = exc.code
        except _Timeout:
            code = "timeout"
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
            os.chdir(old_cwd)
        after = _files(root)
    text = err.getvalue()
    assert code == 2, f"{argv}: exit {code}, stderr {text!r}"
    assert text.count("\n") == 1 and text.endswith("\n"), f"{argv}: stderr {text!r}"
    assert "Traceback" not in text, argv
    assert after == before, f"{argv}: new files {sorted(after - before)}"
    return text


def _one(pool):
    return st.sampled_from(pool)


def _options(spec: dict[str, list[str]], k: int = 2):
    """1..k hostile (option, value) pairs from ``spec``, flattened to argv."""
    pairs = st.lists(st.sampled_from(sorted(spec)).flatmap(lambda o: st.tuples(st.just(o), _one(spec[o]))),
                     min_size=1, max_size=k, unique_by=lambda t: t[0])
    return pairs.map(lambda ps: [x for o, v in ps for x in ((o,) if v is None else (o, v))])


def _bad_outputs(opts: list[str], suffix: dict[str, str]):
    """Hostile output paths: through a file, missing parent, a folder, too long, shared by two."""
    def make(opt):
        s = suffix.get(opt, "")
        return st.sampled_from([f"afile/x{s}", f"nodir/x{s}", "adir" if s else "afile", f"{LONG}{s}",
                                "" if s else f"{LONG}"])
    single = st.sampled_from(opts).flatmap(lambda o: make(o).map(lambda v: [o, v]))
    if len(opts) < 2:
        return single
    pair = st.permutations(opts).map(lambda p: [p[0], "same" + suffix.get(p[0], ""), p[1],
                                                "same" + suffix.get(p[0], "")])
    return st.one_of(single, pair)


# ----------------------------------------------------------------------------- geometry

GEOMETRY_OPTS = {"--mesh-size": BAD_FLOAT, "--refine": BAD_FLOAT + ["0.1", "6"], "--epw": BAD_FLOAT + ["0.5", "201"], "--order": ["3", "0", "x"],
                 "--algorithm": ["nope", ""], "--gmsh-timeout": BAD_FLOAT + ["0", "0.05", "1e5"],
                 "--design": ["", "missing.toml", "adir", "afile"], "--select": ["k33_rod"],
                 "--json": ["x.txt"], "--png": ["x.jpg"], "--mesh": ["x.vtu"], "--vtu": ["x.msh"],
                 "--write-default": ["x.json"], "--bogus": [None, "1"]}


@settings(max_examples=EXAMPLES["geometry"], **_SETTINGS)
@given(st.one_of(_options(GEOMETRY_OPTS),
                 _bad_outputs(["--json", "--mesh", "--vtu", "--png"],
                              {"--json": ".json", "--mesh": ".msh", "--vtu": ".vtu", "--png": ".png"})))
def test_geometry_cli_refuses_cleanly(argv):
    from geometry.__main__ import main

    run_clean(main, argv + ["-q"])


# ----------------------------------------------------------------------------- design TOML

_HOSTILE = [math.nan, math.inf, -math.inf, 1e308, -1e308, 10 ** 30, [], {"x": 1}, 1e-9]


def _paths(obj, prefix=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list) and obj and isinstance(obj[0], dict):
        for i, v in enumerate(obj):
            yield from _paths(v, prefix + (i,))
    else:
        yield prefix


def _set(obj, path, value):
    for k in path[:-1]:
        obj = obj[k]
    obj[path[-1]] = value


def _designs():
    from geometry import examples
    from rpud_common import to_jsonable

    designs = {"rpud": geometry.default_design(), "stack": examples.langevin_sandwich(), "bar": examples.k31_bar()}
    return {k: to_jsonable(d.to_mapping(), drop_none=True) for k, d in designs.items()}


_SKIP = {("kind",), ("name",)}

_USED = {"cylinder": {"length", "start", "outer_diameter", "inner_diameter"},
         "cone": {"length", "start", "outer_diameter", "inner_diameter", "end_diameter"},
         "box": {"length", "start", "thickness", "width"}}
"""Numeric segment fields each kind uses."""


@st.composite
def hostile_design(draw):
    """Bytes of a design file with one hostile change."""
    base = _designs()[draw(st.sampled_from(["rpud", "stack", "bar"]))]
    how = draw(st.sampled_from(["value", "value", "value", "unknown", "missing", "encoding", "nesting",
                                "empty", "syntax", "name", "kind"]))
    if how == "value":
        paths = [p for p in _paths(base) if p not in _SKIP and p[-1] not in ("name", "part", "segment")]
        path = draw(st.sampled_from(paths))
        value = draw(st.sampled_from(_HOSTILE))
        if value == 1e-9 and path[-1] in ("start", "slot_offset", "inner_diameter", "bore_diameter",
                                           "slot_angle_deg"):
            value = math.nan   # 1e-9 is a legal offset/angle
        if path[0] == "segments" and path[-1] not in _USED[base["segments"][path[1]]["kind"]] \
                and isinstance(value, (int, float)):
            value = math.nan   # a finite size a segment's kind does not use is ignored (design.py)
        if path[-1] in ("end_diameter", "thickness", "width") and value in ([], {"x": 1}):
            value = "wide"
        _set(base, path, value)
    elif how == "unknown":
        paths = [p for p in _paths(base) if len(p) > 1] + [("x",)]
        path = draw(st.sampled_from(paths))
        _set(base, path[:-1] + (draw(st.sampled_from(["lenght", "n_ring", "ü", "a b"])),), 1.0)
    elif how == "missing":
        if "segments" in base:
            seg = base["segments"][draw(st.integers(0, len(base["segments"]) - 1))]
            del seg[draw(st.sampled_from(["name", "length"]))]
        else:
            base["stack"] = "PZT-8"
    elif how == "name":
        base["name"] = draw(st.sampled_from(["../evil", "/abs/path", "", "a/b", "..", "x" * 200, "a\nb", 5]))
    elif how == "kind":
        base["kind"] = draw(st.sampled_from(["rpd", 1, [], ""]))
    text = tomli_w.dumps(base).encode() if how in ("value", "unknown", "missing", "name", "kind") else b""
    if how == "encoding":
        raw = tomli_w.dumps(base).encode()
        at = draw(st.integers(0, len(raw)))
        text = raw[:at] + draw(st.sampled_from([b"\xff", b"\xc3(", b"\xe9", b"\x80\x80"])) + raw[at:]
    elif how == "nesting":
        depth = draw(st.integers(9, 400))
        text = b"a = " + b"[" * depth + b"]" * depth + b"\n"
    elif how == "syntax":
        text = draw(st.sampled_from([b"[horn\nlength = 1", b"= 1", b"horn.length = ", b"\x00", b"kind = 'rpud'\nkind = 'rpud'"]))
    return text


def _toml_writer(data: bytes, name="d.toml"):
    def setup(root):
        (root / name).write_bytes(data)
    return setup


def _tomli_ok(value) -> bool:
    return True


@settings(max_examples=EXAMPLES["design_toml"], **_SETTINGS)
@given(hostile_design(), st.sampled_from(["geometry", "modal", "harmonic", "results"]))
def test_design_files_are_refused_cleanly(data, cli):
    if cli == "geometry":
        from geometry.__main__ import main
        argv = ["--design", "d.toml", "--json", "o.json", "-q"]
    elif cli == "modal":
        from fem.modal_cli import main
        argv = ["--design", "d.toml", "--json", "o.json"]
    elif cli == "harmonic":
        from fem.harmonic_cli import main
        argv = ["--design", "d.toml", "--json", "o.json"]
    else:
        from results.__main__ import main
        argv = ["--design", "d.toml", "--out", "res", "-q"]
    run_clean(main, argv, setup=_toml_writer(data))


# ----------------------------------------------------------------------------- fem

MODAL_OPTS = {"--mesh-size": BAD_FLOAT, "--refine": BAD_FLOAT + ["0.1", "6"], "--converge": BAD_FLOAT + ["0", "0.5"], "--near": [v for v in BAD_FLOAT if v not in ("1e-320",)] + ["1e-3", "5e6"],
              "--modes": BAD_INT + ["201"], "--order": ["3"], "--solver": ["mkl"], "--target": BAD_FLOAT,
              "--tol": BAD_FLOAT + ["0", "0.5"], "--bracket": ["1,2", "0,2", "nan,2", "0.5,inf", "x", "0.5"],
              "--tune": ["horn.lenght"], "--design": ["", "missing.toml", "adir"], "--select": ["x"],
              "--json": ["x.txt"], "--vtu": ["x.json"], "--out-design": ["x.json"],
              "--clamp": ["nowhere"], "--sectors": ["x", "4", "2", "1e9", "-6", "nan", ""],
              "--harmonics": ["9", "x", "-1", "", "0,,1"]}


@settings(max_examples=EXAMPLES["fem.modal"], **_SETTINGS)
@given(st.one_of(_options(MODAL_OPTS),
                 _options(MODAL_OPTS).map(lambda a: ["--match"] + a),
                 _bad_outputs(["--json", "--vtu", "--render"], {"--json": ".json", "--vtu": ".vtu"})))
def test_modal_cli_refuses_cleanly(argv):
    from fem.modal_cli import main

    if argv in (["--match", "--tune", "horn.lenght"],) or argv[:1] == ["--clamp"] and len(argv) == 2:
        argv = argv + ["--modes", "0"]      # these two are refused only after meshing
    run_clean(main, argv)


HARMONIC_OPTS = {"--voltage": BAD_FLOAT + ["0", "1e5"], "--freq": BAD_FLOAT + ["0"],
                 "--band": ["1,2", "0,inf", "nan,5", "3e4,2e4", "x"], "--points": BAD_INT[1:] + ["2"],
                 "--q-mech": BAD_FLOAT + ["0"], "--tan-delta": BAD_FLOAT[:5] + ["2", "-0.1"],
                 "--mesh-size": BAD_FLOAT, "--refine": BAD_FLOAT + ["0.1", "6"], "--modes": BAD_INT, "--mode": BAD_INT + ["9"],
                 "--ring-up": BAD_FLOAT[:5] + ["-1", "5"], "--converge": BAD_FLOAT + ["0", "0.5"],
                 "--preload": BAD_FLOAT, "--stress-points": BAD_INT,
                 "--design": ["", "missing.toml", "adir"], "--json": ["x.txt"]}


@settings(max_examples=EXAMPLES["fem.harmonic"], **_SETTINGS)
@given(st.one_of(_options(HARMONIC_OPTS), _bad_outputs(["--json", "--plots"], {"--json": ".json"})))
def test_harmonic_cli_refuses_cleanly(argv):
    from fem.harmonic_cli import main

    run_clean(main, argv)


RESULTS_OPTS = {"--voltage": BAD_FLOAT + ["0"], "--q-mech": [v for v in BAD_FLOAT if v != "0"] + ["0.5"],
                "--mesh-size": BAD_FLOAT, "--refine": BAD_FLOAT + ["0.1", "6"], "--rel-tol": BAD_FLOAT + ["0", "2"],
                "--max-members": BAD_INT, "--seed": ["-1", "x", "1.5", "9" * 30],
                "--design": ["", "missing.toml", "adir", "afile"]}


@settings(max_examples=EXAMPLES["results"], **_SETTINGS)
@given(st.one_of(_options(RESULTS_OPTS),
                 st.sampled_from([["--out", "afile"], ["--out", "nodir/x"], ["--out", LONG],
                                  ["--out", f"adir/{LONG}"], ["--out", ""]])))
def test_results_cli_refuses_cleanly(argv):
    from results.__main__ import main

    run_clean(main, argv + ["-q"])


# ----------------------------------------------------------------------------- impact

IMPACT_FLOATS = ["nan", "inf", "-inf", "1e308", "1e-320", "-1", "abc", ""]
_IMPACT_FIELDS = ["--m-free", "--A0", "--freq", "--e1", "--e2", "--m-horn", "--m-tool", "--k0", "--c",
                  "--gap", "--v0", "--t-end", "--t-from", "--spring-force", "--rel-tol"]
IMPACT_OPTS = {**{o: IMPACT_FLOATS for o in _IMPACT_FIELDS},
               "--g": [v for v in IMPACT_FLOATS if v != "-1"],       # g < 0: a drill pointing up, valid
               "--horn-law": ["x"], "--scenario": ["lab"],
               "--members": BAD_INT[:2] + BAD_INT[3:], "--max-members": BAD_INT, "--threads": BAD_INT,
               "--seed": ["-1", "x", "1.5"], "--config": ["", "missing.toml", "adir", "afile"]}


@settings(max_examples=EXAMPLES["impact"], **_SETTINGS)
@given(st.one_of(_options(IMPACT_OPTS), _bad_outputs(["--json", "--plots"], {"--json": ".json"})))
def test_impact_cli_refuses_cleanly(argv):
    from impact.__main__ import main

    run_clean(main, argv + ["--t-end", "0.001"] if "--t-end" not in argv else argv)


@settings(max_examples=EXAMPLES["impact sweep"], **_SETTINGS)
@given(st.one_of(
    _options({o: v for o, v in IMPACT_OPTS.items() if o != "--m-free"}).map(lambda a: ["--m-free", "0.004"] + a),
    st.sampled_from([["--m-free", v] for v in ("nan", "1e308", "-0.001", "", "a,b", "0.004,inf")]),
    _bad_outputs(["--json", "--csv", "--plots"], {"--json": ".json", "--csv": ".csv"}).map(
        lambda a: ["--m-free", "0.004", "--t-end", "0.001"] + a)))
def test_impact_sweep_cli_refuses_cleanly(argv):
    from impact.__main__ import main

    run_clean(main, ["sweep", "--no-progress"] + argv)


@settings(max_examples=EXAMPLES["impact article"], **_SETTINGS)
@given(st.sampled_from([["--out", "afile"], ["--out", "nodir/x"], ["--out", LONG], ["--out", ""],
                        ["--out", "o", "--threads", "0"], ["--out", "o", "--threads", "x"],
                        ["--out", "o", "--seed", "-1"],
                        ["--out", "o", "--config", "missing.toml"], ["--out", "o", "--config", "afile"],
                        ["--out", "o", "--config", "adir"], ["--out", "o", "--config", ""]]))
def test_impact_article_cli_refuses_cleanly(argv):
    from impact.__main__ import main

    run_clean(main, ["article"] + argv)


@st.composite
def hostile_config(draw):
    fields = ["m_free", "A0", "freq", "e1", "e2", "k0", "gap", "t_end"]
    how = draw(st.sampled_from(["value", "unknown", "ambiguous", "encoding", "nesting", "type"]))
    if how == "value":
        return tomli_w.dumps({"impact": {draw(st.sampled_from(fields)):
                                         draw(st.sampled_from([math.nan, math.inf, -1.0, 1e308, 10 ** 30]))}}).encode()
    if how == "unknown":
        return tomli_w.dumps({draw(st.sampled_from(["mfree", "x", "impact.x"])): 1.0}).encode()
    if how == "ambiguous":
        return tomli_w.dumps({"m_free": 0.004, "impact": {"A0": 1.5e-5}}).encode()
    if how == "encoding":
        return b"m_free = 0.004\n# caf\xe9\n"
    if how == "nesting":
        return b"a = " + b"[" * 300 + b"]" * 300 + b"\n"
    return tomli_w.dumps({draw(st.sampled_from(fields)): draw(st.sampled_from(["x", [1.0], {"a": 1}, True]))}).encode()


@settings(max_examples=EXAMPLES["impact config"], **_SETTINGS)
@given(hostile_config(), st.sampled_from([[], ["sweep", "--m-free", "0.004", "--no-progress"],
                                          ["article", "--out", "o"]]))
def test_impact_config_files_are_refused_cleanly(data, head):
    from impact.__main__ import main

    run_clean(main, head + ["--config", "c.toml"], setup=_toml_writer(data, "c.toml"))

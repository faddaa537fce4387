"""Own materials: strain-charge records, validation, a design's [materials] table,
--materials FILE on the command lines, and the constants recorded by meshes, systems and results."""

from __future__ import annotations

import json
import logging
import math

import numpy as np
import pytest
import tomli_w

from geometry.materials import EPS0, Material, builtin_library, load_library, records_from_mapping
from rpud_common import ParameterError

# shared/references.md, strain-charge datasheet values (rounded to 3 digits): s 1e-12 m^2/N,
# d 1e-12 C/N, eps^T relative
DATASHEET = {
    "PZT-4": dict(s11=12.3, s12=-4.05, s13=-5.31, s33=15.5, s44=39.0, s66=32.7, d31=-123, d33=289, d15=496,
                  eps11=1475, eps33=1300),
    "PZT-8": dict(s11=11.5, s12=-3.7, s13=-4.8, s33=13.5, s44=31.9, s66=30.4, d31=-97, d33=225, d15=330,
                  eps11=1290, eps33=1000),
}


def _plain_numpy_strain_charge(name: str) -> dict:
    """Strain-charge tables of a built-in record, by plain numpy (no rpud conversion code):
    s^E = (c^E)^-1, d = e s^E, eps^T = eps^S + d e^T."""
    b = builtin_library()[name]
    c, e_, eps = b.c_E, b.e, b.eps_S
    C = np.array([[c["c11"], c["c12"], c["c13"], 0, 0, 0], [c["c12"], c["c11"], c["c13"], 0, 0, 0],
                  [c["c13"], c["c13"], c["c33"], 0, 0, 0], [0, 0, 0, c["c44"], 0, 0], [0, 0, 0, 0, c["c44"], 0],
                  [0, 0, 0, 0, 0, c["c66"]]])
    E = np.zeros((3, 6))
    E[2, 0] = E[2, 1] = e_["e31"]
    E[2, 2] = e_["e33"]
    E[0, 4] = E[1, 3] = e_["e15"]
    S = np.linalg.inv(C)
    D = E @ S
    epsT = np.diag([eps["eps11"], eps["eps11"], eps["eps33"]]) * EPS0 + D @ E.T
    return {"kind": "piezo", "density": b.density, "q_mech": b.q_mech, "tan_delta": b.tan_delta,
            "s_E": {"s11": S[0, 0], "s12": S[0, 1], "s13": S[0, 2], "s33": S[2, 2], "s44": S[3, 3], "s66": S[5, 5]},
            "d": {"d31": D[2, 0], "d33": D[2, 2], "d15": D[0, 4]},
            "eps_T": {"eps11": epsT[0, 0] / EPS0, "eps33": epsT[2, 2] / EPS0}}


def _close(got: Material, ref: Material, rel: float, tables=("c_E", "e", "eps_S")):
    for t in tables:
        a, b = getattr(got, t), getattr(ref, t)
        assert set(a) == set(b), t
        for k in b:
            assert a[k] == pytest.approx(b[k], rel=rel), f"{t}.{k}"


@pytest.mark.parametrize("name", ["PZT-4", "PZT-8"])
def test_strain_charge_input_converts_to_the_builtin_stress_charge_record(name, tmp_path):
    """Verification: the strain-charge form of a built-in ceramic, given as a user record,
    becomes its stress-charge record within 1e-6. The strain-charge values are made here by
    inverting the built-in record with plain numpy (references.md lists them only to 3 digits,
    see the next test), so this is a round trip through the library's conversion."""
    path = tmp_path / "m.toml"
    path.write_text(tomli_w.dumps({f"my-{name}": _plain_numpy_strain_charge(name)}))
    got = load_library(path)[f"my-{name}"]
    _close(got, builtin_library()[name], 1e-6)
    assert not got.s_E and not got.d and not got.eps_T       # the record holds the constants used
    assert got.to_record()["c_E"].keys() == {"c11", "c12", "c13", "c33", "c44", "c66"}


@pytest.mark.parametrize("name, eps_tol", [("PZT-4", 0.05), ("PZT-8", 0.005)])
def test_datasheet_strain_charge_values_give_the_builtin_constants(name, eps_tol):
    """Independent source: the rounded datasheet strain-charge values of references.md convert to the
    built-in stress-charge row within their rounding: c^E and e within 0.5 %; eps^S = eps^T - d e^T,
    a difference of large numbers, within 0.5 % (PZT-8) and 5 % (PZT-4: eps^S is 0.5 eps^T there)."""
    r = DATASHEET[name]
    rec = {"kind": "piezo", "density": 7500.0,
           "s_E": {k: v * 1e-12 for k, v in r.items() if k[0] == "s"},
           "d": {k: v * 1e-12 for k, v in r.items() if k[0] == "d"},
           "eps_T": {k: float(v) for k, v in r.items() if k.startswith("eps")}}
    got = records_from_mapping({"x": rec}, "test")["x"]
    _close(got, builtin_library()[name], 0.005, tables=("c_E", "e"))
    _close(got, builtin_library()[name], eps_tol, tables=("eps_S",))


def _piezo(**over):
    rec = _plain_numpy_strain_charge("PZT-8")
    for path, value in over.items():
        table, key = path.split("__")
        if value is None:
            del rec[table][key]
        else:
            rec[table][key] = value
    return rec


@pytest.mark.parametrize("change, field, words", [
    ({"s_E__s11": 11.5}, "materials.bad.s_E.s11", "1/Pa"),                   # unit slip: 11.5 for 11.5e-12
    ({"s_E__s12": -9e-12}, "materials.bad.s_E", "not positive definite"),     # unstable solid
    ({"d__d33": 900e-12}, "materials.bad.d", "coupling exceeds 1"),           # eps^S would be negative
    ({"eps_T__eps33": 1000 * EPS0}, "materials.bad.eps_T.eps33", "relative"),  # F/m instead of relative
    ({"d__d15": None}, "materials.bad.d", "missing d15"),
    ({"d__d99": 1e-12}, "materials.bad.d.d99", "unknown key"),
])
def test_bad_records_name_the_record_and_field(change, field, words):
    with pytest.raises(ParameterError) as info:
        records_from_mapping({"bad": _piezo(**change)}, "test")
    assert info.value.name == field
    assert words in str(info.value)


def test_both_forms_or_mixed_kinds_are_refused():
    rec = {**_piezo(), "c_E": dict(builtin_library()["PZT-8"].c_E)}
    with pytest.raises(ParameterError, match=r"materials.bad.s_E .*either the stress-charge"):
        records_from_mapping({"bad": rec}, "test")
    with pytest.raises(ParameterError, match=r"materials.bad.youngs_modulus .*'isotropic' only"):
        records_from_mapping({"bad": {**_piezo(), "youngs_modulus": 1e11}}, "test")


def test_full_anisotropy_is_allowed_and_a_non_transversely_isotropic_ceramic_warned(caplog):
    b = builtin_library()["PZT-8"].to_record()
    rec = {**b, "c_E": {**b["c_E"], "c66": 25e9, "c22": 150e9, "c55": 30e9}}
    with caplog.at_level(logging.WARNING, logger="geometry.materials"):
        m = records_from_mapping({"aniso": rec}, "test")["aniso"]
    assert "not transversely isotropic" in caplog.text and "materials.aniso" in caplog.text
    C = m.voigt_matrices()[0]
    assert (C[5, 5], C[1, 1], C[4, 4], C[3, 3]) == (25e9, 150e9, 30e9, b["c_E"]["c44"])   # used as given
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="geometry.materials"):
        records_from_mapping({"ok": b}, "test")
    assert "transversely" not in caplog.text


# ----------------------------------------------------------------------------- designs

ROD = """kind = "stack"
name = "own_rod"
target_frequency = 60000.0
electrodes = [
    {{ name = "eb", segment = "rod", face = "bottom", role = "ground" }},
    {{ name = "et", segment = "rod", face = "top", role = "hot" }},
]
[[segments]]
name = "rod"
length = 0.02
material = "{ceramic}"
outer_diameter = 0.004
poling = "+z"
[[segments]]
name = "cap"
length = 0.004
material = "{metal}"
outer_diameter = 0.004
"""


def _own_table():
    rec = _plain_numpy_strain_charge("PZT-4")
    rec["density"] = 7700.0
    return {"my_pzt": rec, "my_steel": {"kind": "isotropic", "density": 7000.0, "youngs_modulus": 190e9,
                                        "poisson_ratio": 0.28}}


def test_a_design_resolves_its_own_materials_and_round_trips(tmp_path):
    from geometry.design import load_design

    path = tmp_path / "d.toml"
    path.write_text(ROD.format(ceramic="my_pzt", metal="my_steel") + tomli_w.dumps({"materials": _own_table()}))
    d = load_design(path)
    assert sorted(d.materials) == ["my_pzt", "my_steel"]
    assert math.isinf(d.materials["my_steel"].q_mech)                   # no q_mech: lossless
    _close(d.materials["my_pzt"], builtin_library()["PZT-4"], 1e-6)
    vol = math.pi * 0.002 ** 2
    assert d.part_masses()["cap"] == pytest.approx(7000.0 * vol * 0.004, rel=1e-12)
    d.save(tmp_path / "back.toml")
    assert load_design(tmp_path / "back.toml") == d                     # the table travels with the design
    json.dumps(d.to_mapping(), allow_nan=False)                         # strict JSON (no inf q_mech)
    # unknown names list what is available, own records included
    (tmp_path / "u.toml").write_text(ROD.format(ceramic="my_pzt", metal="wood") + tomli_w.dumps({"materials": _own_table()}))
    with pytest.raises(ParameterError, match=r"segments.cap.material = 'wood': unknown; known: .*my_pzt.*my_steel"):
        load_design(tmp_path / "u.toml")
    # roles are checked in the design's library
    (tmp_path / "r.toml").write_text(ROD.format(ceramic="my_steel", metal="my_steel")
                                     + tomli_w.dumps({"materials": _own_table()}))
    with pytest.raises(ParameterError, match=r"segments.rod.poling = '\+z': must be 'none' for passive material my_steel"):
        load_design(tmp_path / "r.toml")
    # a bad own record names the design's table, record and field
    bad = _own_table()
    bad["my_pzt"]["s_E"]["s11"] = 12.3
    (tmp_path / "b.toml").write_text(ROD.format(ceramic="my_pzt", metal="my_steel") + tomli_w.dumps({"materials": bad}))
    with pytest.raises(ParameterError, match=r"materials.my_pzt.s_E.s11 = 12.3"):
        load_design(tmp_path / "b.toml")


def _geometry_cli(argv, capsys):
    from geometry.__main__ import main
    from rpud_common.cli import run_cli

    try:
        code = run_cli(main, argv)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_materials_file_on_the_command_line_and_the_recorded_constants(tmp_path, capsys):
    """--materials FILE resolves the design's names; the mesh, the system, the modal result and the
    geometry JSON carry exactly those constants; mode labels use the same densities."""
    import fem
    import geometry
    from fem.modeshape import mass_matrix

    lib = tmp_path / "lib.toml"
    lib.write_text(tomli_w.dumps(_own_table()))
    design = tmp_path / "d.toml"
    design.write_text(ROD.format(ceramic="my_pzt", metal="my_steel"))
    code, out, err = _geometry_cli(["--design", str(design), "--materials", str(lib), "--json",
                                    str(tmp_path / "g.json"), "--mesh-size", "0.002", "-q"], capsys)
    assert code == 0, err
    rep = json.loads((tmp_path / "g.json").read_text())
    assert rep["materials"]["my_steel"]["density"] == 7000.0
    assert rep["materials"]["my_pzt"]["c_E"]["c33"] == pytest.approx(115e9, rel=1e-6)
    assert sorted(rep["design"]["parameters"]["materials"]) == ["my_pzt", "my_steel"]
    # without the file: one line naming the field, exit 2, no output
    code, out, err = _geometry_cli(["--design", str(design), "--json", str(tmp_path / "h.json")], capsys)
    assert code == 2 and err.count("\n") == 1 and "segments.rod.material = 'my_pzt': unknown" in err
    assert not (tmp_path / "h.json").exists()
    # a bad record in the file: one line naming record and field
    bad = _own_table()
    bad["my_steel"]["poisson_ratio"] = 0.7
    lib.write_text(tomli_w.dumps(bad))
    code, out, err = _geometry_cli(["--design", str(design), "--materials", str(lib)], capsys)
    assert code == 2 and "materials.my_steel.poisson_ratio = 0.7" in err
    lib.write_text(tomli_w.dumps(_own_table()))

    from geometry.options import add_design_options, design_from_options
    from rpud_common import CliParser

    ns = add_design_options(CliParser(prog="t")).parse_args(["--design", str(design), "--materials", str(lib)])
    d = design_from_options(ns)
    mesh = geometry.build_mesh(d, mesh_size=0.002)
    assert set(mesh.materials) == {"my_pzt", "my_steel"}
    system = fem.assemble(mesh)                                # no library argument: the mesh's records
    assert system.materials_block()["my_steel"]["youngs_modulus"] == 190e9
    vol_rod, vol_cap = math.pi * 0.002 ** 2 * 0.02, math.pi * 0.002 ** 2 * 0.004
    # the mass of the mesh's own matrix (labels, shares) uses the design's densities (curved P2: ~1e-4)
    assert mass_matrix(mesh).sum() == pytest.approx(7700.0 * vol_rod + 7000.0 * vol_cap, rel=1e-3)
    res = fem.modal_analysis(system, 60e3, 6)
    assert fem.modeshape.classify(fem.modeshape.energy_shares(mesh, res.shapes)) == res.labels
    assert res.to_dict()["materials"]["my_pzt"]["density"] == 7700.0
    # a name defined differently in the design and in the file is refused
    design.write_text(ROD.format(ceramic="my_pzt", metal="my_steel")
                      + tomli_w.dumps({"materials": {"my_steel": {**_own_table()["my_steel"], "density": 7100.0}}}))
    with pytest.raises(ParameterError, match=r"materials.my_steel .*defined differently"):
        design_from_options(ns)


def test_materials_file_overrides_a_builtin_name_for_the_default_design(tmp_path):
    from geometry.options import add_design_options, design_from_options
    from rpud_common import CliParser

    b = builtin_library()["PZT-8"].to_record()
    lib = tmp_path / "lib.toml"
    lib.write_text(tomli_w.dumps({"PZT-8": {**b, "density": 7700.0}}))
    ns = add_design_options(CliParser(prog="t")).parse_args(["--materials", str(lib)])
    d = design_from_options(ns)
    assert d.used_materials()["PZT-8"].density == 7700.0
    assert d.stack.material == "PZT-8" and "PZT-8" in d.to_mapping()["materials"]


def test_the_worked_example_design_loads_with_its_own_materials():
    """results/examples/own_material.toml (README worked example): its datasheet PZT-8 is the
    built-in record within the datasheet's rounding, its aluminium is lossless (no q_mech)."""
    from pathlib import Path

    from geometry.design import load_design

    d = load_design(Path(__file__).parents[1] / "results" / "examples" / "own_material.toml")
    _close(d.materials["pzt8_datasheet"], builtin_library()["PZT-8"], 0.005)
    assert math.isinf(d.materials["al6061"].q_mech) and d.used_materials().keys() == {"al6061", "pzt8_datasheet"}

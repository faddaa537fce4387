"""The notebook user's view of the result objects and figures.

Every analysis result has a short ``repr`` that shows its headline numbers, a ``to_dict()`` that
is strict JSON (no NaN/inf) holding the same numbers as the object, and ``save(folder)`` whose
files read back to the same numbers. Every plot function draws on a caller's Axes and returns
it, and none touches pyplot's figure registry.
"""

import json

import matplotlib
import numpy as np
import pytest

import fem
import impact
from rpud_common.figures import subplots
from rpud_common.provenance import version
from test_fem_harmonic import TIP, _stack

FAST = impact.StatsSettings(rel_tol=0.2, n_start=8, n_max=16)


@pytest.fixture(scope="module")
def system():
    return fem.assemble(_stack())


@pytest.fixture(scope="module")
def modes(system):
    return fem.modal_analysis(system, 70e3, 6)


def _strict(d):
    return json.loads(json.dumps(d, allow_nan=False))


def _saved(result, folder):
    path = result.save(folder)
    assert path.suffix == ".json" and path.stat().st_mode & 0o777 == 0o666 & ~_umask()
    record = json.loads(path.read_text())
    # the saved file says which code wrote it; the rest is to_dict() unchanged
    assert record.pop("provenance")["rpud_version"] == version()
    return record, folder / f"{path.stem}.npz"


def _umask():
    import os

    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_modal_result(modes, tmp_path):
    i = modes.nearest
    text = repr(modes)
    assert text.startswith("ModalResult(6 modes") and len(text) < 300
    assert f"f_r {modes.f_r_hz[i]:.1f} Hz" in text and modes.labels[i] in text
    d = _strict(modes.to_dict())
    assert [m["f_r_hz"] for m in d["modes"]] == pytest.approx(modes.f_r_hz, rel=1e-15)
    back, npz = _saved(modes, tmp_path)
    assert back == d
    with np.load(npz) as z:
        assert np.array_equal(z["shapes_m"], modes.shapes) and np.array_equal(z["f_r_hz"], modes.f_r_hz)


def test_harmonic_results(system, modes, tmp_path):
    f0 = modes.f_r_hz[modes.nearest]
    sw = fem.harmonic_sweep(system, np.linspace(0.9 * f0, 1.1 * f0, 21), 2.0, surfaces=TIP)
    assert f"f_r {sw.f_r_hz:.1f} Hz" in repr(sw) and len(repr(sw)) < 300
    d = _strict(sw.to_dict())
    assert d["admittance_s"]["re"] == pytest.approx(sw.admittance.real, rel=1e-15)
    wp = fem.working_point(system, f0, 2.0, surfaces=TIP)
    assert f"{wp.tip_amplitude_m * 1e6:.3g} um" in repr(wp)
    assert _strict(wp.to_dict())["tip_amplitude_m"] == wp.tip_amplitude_m
    ring = fem.ring_up(system, f0, 2.0, 20 / f0, surfaces=TIP)
    assert "ring-up" in repr(ring)
    back, npz = _saved(ring, tmp_path)
    assert back["steady_amplitude_m"] == pytest.approx(ring.to_dict()["steady_amplitude_m"], rel=1e-15)
    with np.load(npz) as z:
        assert np.array_equal(z["t_s"], ring.t)


def test_impact_results(tmp_path):
    r = impact.simulate(impact.ImpactParams(m_free=0.008, t_end=0.01))
    text = repr(r)
    assert text.startswith("ImpactResult(one sample") and f"{r.tool_impacts} tool" in text
    back, npz = _saved(r, tmp_path / "run")
    assert back["tool_impacts"] == r.tool_impacts and len(back["events"]) == r.t.size
    with np.load(npz) as z:
        assert np.array_equal(z["t"], r.t) and np.array_equal(z["w"], r.w)

    st = impact.ensemble_statistics(impact.ImpactParams(m_free=0.008), "article", FAST)
    ke = st["mean_tool_ke_after_j"]
    assert f"{ke.scaled(1e3)} mJ" in repr(st) and "95 % CI" in repr(st)
    d = _strict(st.to_dict())
    assert d["mean_tool_ke_after_j"]["mean"] == ke.mean and d["members"] == st.members
    back, npz = _saved(st, tmp_path / "stats")
    assert back == d
    with np.load(npz) as z:
        assert z["members"].shape[0] == st.members

    sw = impact.sweep(impact.ImpactParams(), [0.004, 0.008], scenario="article", settings=FAST)
    assert "2 masses 4-8 g" in repr(sw) and f"{impact.Estimate(sw.fit.slope, sw.fit.slope_ci95, 2)}" in repr(sw)
    d = _strict(sw.to_dict())
    assert d["fit_ke_vs_mass"]["r2"] is None          # two points: no R² to report (NaN -> null)
    assert [row["m_free_kg"] for row in d["table"]] == [0.004, 0.008]


def test_plot_functions_draw_on_the_callers_axes(system, modes, tmp_path):
    import matplotlib.pyplot as plt

    before = plt.get_fignums()
    backend = matplotlib.get_backend()
    f0 = modes.f_r_hz[modes.nearest]
    sw = fem.harmonic_sweep(system, np.linspace(0.9 * f0, 1.1 * f0, 11), 1.0, surfaces=TIP)
    ring = fem.ring_up(system, f0, 1.0, 12 / f0, surfaces=TIP)
    fig, axes = subplots(2, 3)
    pair = fem.plot_admittance(sw, f0, modes.f_a_hz[modes.nearest], axes=axes[:, 0])
    assert pair == tuple(axes[:, 0]) and pair[0].lines
    assert fem.plot_ring_up(ring, axes=axes[:, 1]) == tuple(axes[:, 1])
    r = impact.simulate(impact.ImpactParams(m_free=0.008, t_end=0.01))
    assert impact.plot_history(r, ax=axes[0, 2]) is axes[0, 2] and len(axes[0, 2].lines) == 4
    swp = impact.sweep(impact.ImpactParams(), [0.004, 0.008], scenario="article", settings=FAST)
    assert impact.plot_ke_vs_mass(swp, ax=axes[1, 2]) is axes[1, 2]
    assert impact.plot_ke_vs_mass(swp, ax=axes[1, 2], label="again", fmt="s") is axes[1, 2]
    assert len(axes[1, 2].containers) == 2               # two error-bar series on one Axes
    from rpud_common import save_figure

    assert save_figure(pair, tmp_path / "all.png").stat().st_size > 10_000
    new = impact.plot_spectrum(r)                        # no Axes given: a new figure
    assert new.figure is not fig
    assert plt.get_fignums() == before and matplotlib.get_backend() == backend
    with pytest.raises(TypeError, match="Axes"):
        impact.plot_history(r, ax="not an axes")


def _result_classes():
    """Every subclass of rpud_common.Result defined in the four packages."""
    import importlib
    import inspect
    import pkgutil

    from rpud_common.result import Result

    found = []
    for pkg in ("geometry", "fem", "impact", "results"):
        for m in pkgutil.iter_modules(importlib.import_module(pkg).__path__):
            if m.name.startswith("__"):
                continue
            mod = importlib.import_module(f"{pkg}.{m.name}")
            found += [c for c in vars(mod).values()
                      if inspect.isclass(c) and issubclass(c, Result) and c.__module__ == mod.__name__]
    return found


def test_every_result_keeps_the_short_repr():
    """A dataclass generates a repr printing every field (the rows of a study, every array)
    unless declared ``repr=False``: every result class uses Result's headline repr instead."""
    from rpud_common.result import Result

    classes = _result_classes()
    assert len(classes) >= 10
    assert [c.__qualname__ for c in classes if c.__repr__ is not Result.__repr__] == []


def test_meshes_and_assembled_systems_have_short_reprs(system):
    mesh = system.mesh
    assert repr(mesh).startswith("TaggedMesh(") and len(repr(mesh)) < 300
    assert f"{len(mesh.cells)} " in repr(mesh) and f"{len(mesh.points)} nodes" in repr(mesh)
    assert repr(system).startswith("PiezoSystem(") and len(repr(system)) < 300
    assert f"{system.ndof} DOFs" in repr(system)
    split = system.split()
    assert repr(split).startswith("Split(") and len(repr(split)) < 300

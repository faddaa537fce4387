"""Design studies on Dask: every point of a :class:`results.study.Study` through its stages.

Tasks are per point and stage (mesh -> match -> harmonic -> impact). Points that share their
design values share the mesh and match tasks, and points that also share ``q_mech`` share the
harmonic task (drive voltage and impact parameters only enter later), so a study over free
mass and voltage on one design meshes and matches once. Heavy objects (meshes, FE systems,
modal bases) stay on the worker that made them; only small records travel. Each point ends in a
row task that also writes the row to the resume store, so an interrupted study (or a lost
worker) restarts with ``resume=True`` from the finished points.

A stage that fails records its error in the point's row (``status`` "failed", ``error``) and
the study goes on. Rows are deterministic: every FE task runs with one BLAS thread in its own
worker process (the same numbers on 1 or many workers, and in :func:`run_sequential`), the
impact ensembles are seeded with the study seed (the same members at every point: common random
numbers, so differences between points are not masked by member-to-member scatter), and the
amplitude handed to the impacts is rounded to 4 significant digits as in the pipeline.

Outputs (:func:`explore`): ``table.parquet`` and ``table.csv`` (one row per point: inputs,
outputs, impact outputs with their 95 % CI half-width ``<name>_ci95``, status, error),
``study.json`` (the study, counts, timings) and ``points/`` (one JSON per point), written into
the output folder as a whole.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import logging
import os
import re
import shutil
import signal
import stat
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from rpud_common import ParameterError, atomic_folder, is_finite_number, write_json
from rpud_common.result import Result

from .study import OUTPUTS, STAGES, Study

log = logging.getLogger(__name__)

__all__ = ["explore", "run_sequential", "StudyResult", "point_id", "WORKER_ENV", "estimate_cost",
           "CostEstimate", "check_scheduler_address", "MAX_HOURS"]

WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "NUMBA_NUM_THREADS": "1", "MKL_CBWR": "COMPATIBLE"}
"""Environment of every worker process: one thread each, so numbers do not depend on the layout."""

_HANDOFF_DIGITS = 4

WORKER_LOG_LEVEL = logging.CRITICAL
"""Log level of the worker processes, whose lines reach the terminal directly. A task's error
comes back to this process as its future's exception and a lost worker is logged by the
scheduler here; what workers log besides is the noise of a cluster shutting down (heartbeats
to a scheduler that already closed, with tracebacks)."""


@dataclass(frozen=True)
class _Failed:
    stage: str
    error: str


def _failed(stage: str, exc: BaseException) -> _Failed:
    text = " ".join(str(exc).split())
    return _Failed(stage, f"{type(exc).__name__}: {text}"[:500])


def _guard(stage: str, fn: Callable, *inputs, threads: int | None = 1):
    """Run ``fn`` unless an input already failed; a failure becomes a :class:`_Failed` value.

    ``threads``: BLAS threads of the stage (1 on workers: numbers independent of the cluster
    layout; None leaves the library default, for the sequential baseline)."""
    for x in inputs:
        if isinstance(x, _Failed):
            return x
    try:
        from contextlib import nullcontext

        from fem.solvers import blas_threads

        with blas_threads(threads) if threads else nullcontext():
            return fn(*inputs)
    except Exception as exc:  # a failed point is recorded, not fatal (the study goes on)
        log.info("stage %s failed: %s", stage, exc)
        return _failed(stage, exc)


# ------------------------------------------------------------------------------- stages


def _round_sig(x: float, digits: int) -> float:
    from .pipeline import round_sig

    return round_sig(x, digits)


def stage_mesh(study: Study, design_values: dict) -> dict:
    import geometry

    t0 = time.perf_counter()
    design = study.base_design().replace(design_values) if design_values else study.base_design()
    size = study.settings.mesh_size or None
    mesh = geometry.build_mesh(design, mesh_size=size)
    return {"design": design, "mesh": mesh,
            "rec": {"tetrahedra": mesh.n_cells, "nodes": mesh.n_points, "mesh_s": time.perf_counter() - t0}}


def stage_match(study: Study, prev: dict) -> dict:
    from fem.assembly import assemble
    from fem.matching import MatchSettings, default_tune, match, working_mode
    from fem.modal import modal_analysis

    t0 = time.perf_counter()
    design, mesh = prev["design"], prev["mesh"]
    target = float(design.target_frequency)
    rec: dict[str, Any] = {}
    if study.settings.match:
        m = match(design, MatchSettings(target_hz=target, mesh_size=study.settings.mesh_size or None,
                                        tune=default_tune(design)), mesh=mesh)
        design, mesh, system, modal, w = m.design, m.mesh, m.system, m.modal, m.working_index
        rec["matched"] = float(m.converged)
        rec.update({f"tuned.{k}": float(v) for k, v in m.tuned.items()})
    else:
        system = assemble(mesh)
        modal = modal_analysis(system, target, 4)
        w = working_mode(system, modal.f_r_hz, modal.vectors, target)
    rec.update({"f_r_hz": float(modal.f_r_hz[w]), "f_a_hz": float(modal.f_a_hz[w]), "k_eff": float(modal.k_eff[w]),
                "match_s": time.perf_counter() - t0})
    return {"design": design, "mesh": mesh, "system": system, "modal": modal, "w": w, "rec": rec}


def _tip_surfaces(study: Study, mesh) -> tuple[str, ...]:
    tip = study.settings.tip_surface or ("horn_tip" if "horn_tip" in mesh.facet_sets else "top")
    if tip not in mesh.facet_sets:
        from rpud_common import ParameterError

        raise ParameterError("settings.tip_surface", tip, f"no such surface; the mesh has {sorted(mesh.facet_sets)}")
    return (tip,) + (("teeth_tops",) if "teeth_tops" in mesh.facet_sets else ())


def stage_harmonic(study: Study, prev: dict, q_mech: float) -> dict:
    from fem.harmonic import LossModel, modal_basis, working_point
    from geometry.report import mesh_part_volumes

    t0 = time.perf_counter()
    system, modal, w, mesh = prev["system"], prev["modal"], prev["w"], prev["mesh"]
    f_w = float(modal.f_r_hz[w])
    loss = LossModel(q_mech=q_mech)
    surfaces = _tip_surfaces(study, mesh)
    basis = modal_basis(system, f_w, loss=loss, modes=modal)
    wp = working_point(system, f_w, 1.0, loss=loss, surfaces=surfaces, basis=basis)
    ratio = wp.teeth_ellipse_ratio if "teeth_tops" in surfaces else float("nan")
    horn_mass = mesh_part_volumes(mesh)[1].get("horn")
    rec = {"tip_per_volt_m": wp.tip_per_volt_m, "teeth_ellipse_ratio": ratio, "power_per_v2_w": wp.power_w,
           "harmonic_s": time.perf_counter() - t0}
    # the residual's factorisation (a solver handle, not picklable) is only needed to build the
    # basis; without it the basis can move to the worker that runs an impact task
    basis = dataclasses.replace(basis, factor=None)
    return {"system": system, "basis": basis, "loss": loss, "f_w": f_w, "surfaces": surfaces,
            "horn_mass": horn_mass, "rec": rec}


def stage_impact(study: Study, harm: dict, voltage: float, impact_values: dict) -> dict:
    import numpy as np

    from fem.harmonic import working_point
    from impact.params import ImpactParams
    from impact.stats import StatsSettings, ensemble_statistics

    from .pipeline import coupled_amplitudes

    t0 = time.perf_counter()
    st = study.settings
    f_w = harm["f_w"]
    stats_settings = StatsSettings(rel_tol=st.rel_tol, n_start=min(64, st.max_members), n_max=st.max_members,
                                   seed=study.seed)
    m_horn = harm["horn_mass"] if harm["horn_mass"] is not None else ImpactParams().m_horn
    base = ImpactParams(freq=_round_sig(f_w, _HANDOFF_DIGITS + 2), m_horn=_round_sig(m_horn, _HANDOFF_DIGITS))
    base = base.with_(**impact_values)

    def point(c):
        return working_point(harm["system"], f_w, voltage, loss=harm["loss"], surfaces=harm["surfaces"][:1],
                             basis=harm["basis"], tip_damping=c).tip_amplitude_m

    amp = coupled_amplitudes(point, base, [base.m_free], omega=2 * np.pi * f_w, scenario=st.scenario,
                             settings=stats_settings, digits=_HANDOFF_DIGITS)[base.m_free]
    est = ensemble_statistics(base.with_(A0=amp.A0), st.scenario, stats_settings)
    names = {"tool_ke_j": "mean_tool_ke_after_j", "ke_gain_j": "mean_ke_gain_j", "tool_power_w": "tool_power_w",
             "tool_rate_hz": "tool_impact_rate_hz", "horn_power_w": "horn_power_w"}
    rec: dict[str, Any] = {"A0_m": amp.A0, "members": est.members, "stats_converged": float(est.converged),
                           "impact_note": est.note or amp.note}
    for out, q in names.items():
        rec[out] = est[q].mean
        rec[f"{out}_ci95"] = est[q].half_width
    rec["impact_s"] = time.perf_counter() - t0
    return {"rec": rec}


def _record(x):
    return x if isinstance(x, _Failed) else x["rec"]


# ------------------------------------------------------------------------------- rows


def point_id(study: Study, index: int, point: dict, fingerprint: str | None = None) -> str:
    """``p<index>-<hash>``: the hash covers the point's values and the study's fingerprint, so a
    resumed study never picks up a record computed under other settings (``fingerprint``:
    :meth:`Study.fingerprint`, when already known)."""
    blob = json.dumps({"fp": fingerprint or study.fingerprint(), "point": point}, sort_keys=True)
    return f"p{index:05d}-{hashlib.sha256(blob.encode()).hexdigest()[:10]}"


def make_row(study: Study, index: int, point: dict, records: list, store: str | None = None) -> dict:
    """One table row from the stage records of a point (and write it to ``store`` if given)."""
    row: dict[str, Any] = {"point": index, "id": point_id(study, index, point)}
    row.update({f"in.{k}": v for k, v in point.items()})
    row["status"], row["error"], row["failed_stage"] = "ok", "", ""
    voltage = point.get("drive.voltage", study.settings.voltage)
    for rec in records:
        if isinstance(rec, _Failed):
            row["status"], row["error"], row["failed_stage"] = "failed", rec.error, rec.stage
            break
        row.update(rec)
    if "tip_per_volt_m" in row:
        row["A0_unloaded_m"] = row["tip_per_volt_m"] * voltage
        row["power_w"] = row.pop("power_per_v2_w") * voltage ** 2
    if store is not None:
        _write_record(Path(store), row)
    return row


def _write_record(store: Path, row: dict) -> None:
    if store.is_dir():
        write_json(store / f"{row['id']}.json", row, nonfinite="null", provenance=False)


# ------------------------------------------------------------------------------- resume store
#
# A resume record is trusted only if it is exactly what make_row writes: a regular file named
# after its point id, a JSON object of known fields with the right types, and (for a point of
# this study) the point's index and input values. Anything else ends the run before it starts:
# a hand-edited or foreign file must never become a row of the table.

MAX_RECORD_BYTES = 1_000_000
"""Largest resume record read, bytes (a real one is about 2 kB)."""

_ID = re.compile(r"p(\d{5,9})-[0-9a-f]{10}\Z")
_TEXT_FIELDS = {"error": 1000, "failed_stage": 20, "impact_note": 2000}
_NUMBER_FIELDS = (set(OUTPUTS) | {f"{o}_ci95" for o, v in OUTPUTS.items() if v[0] == "impact"}
                  | {f"{stage}_s" for stage in STAGES} | {"members", "stats_converged", "power_per_v2_w"})


def _bad_record(path: Path, value: Any, why: str) -> ParameterError:
    return ParameterError(f"resume record {path}", value, f"{why}; delete the file or run without --resume")


def _no_constant(name: str):
    raise ValueError(f"{name} is not written by a study (non-finite values are null)")


def _check_store(store: Path) -> bool:
    """Whether the resume store exists; anything but a plain folder in its place is refused."""
    try:
        mode = os.lstat(store).st_mode
    except FileNotFoundError:
        return False
    except OSError as exc:
        raise ParameterError("resume store", str(store), f"cannot be read ({exc.strerror})") from None
    if not stat.S_ISDIR(mode):
        raise ParameterError("resume store", str(store), f"is a {_kind(mode)}, not a folder of resume records: "
                                                         "move it away")
    return True


def _kind(mode: int) -> str:
    kinds = ((stat.S_ISLNK, "link"), (stat.S_ISFIFO, "FIFO"), (stat.S_ISSOCK, "socket"), (stat.S_ISCHR, "device"),
             (stat.S_ISBLK, "device"), (stat.S_ISDIR, "folder"), (stat.S_ISREG, "file"))
    return next((name for test, name in kinds if test(mode)), "special file")


def _load_record(path: Path) -> Any:
    """Parse one record; only a regular file of bounded size is ever opened (a FIFO would block)."""
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode):
            raise _bad_record(path, _kind(st.st_mode), "is not a regular file")
        if st.st_size > MAX_RECORD_BYTES:
            raise _bad_record(path, f"{st.st_size} bytes", f"is larger than {MAX_RECORD_BYTES} bytes")
        # O_NONBLOCK and the second check: a file swapped for a FIFO after lstat neither blocks nor is read
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        with os.fdopen(fd, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                raise _bad_record(path, "not a regular file", "is not a regular file")
            raw = f.read(MAX_RECORD_BYTES + 1)
    except OSError as exc:
        raise _bad_record(path, type(exc).__name__, f"cannot be read ({exc.strerror or exc})") from None
    try:
        return json.loads(raw.decode("utf-8"), parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        raise _bad_record(path, raw[:40].decode("utf-8", "replace"), f"is not a JSON record ({exc})") from None


def _check_field(path: Path, key: str, value: Any) -> None:
    if key in ("id", "point", "status"):
        return
    if key in _TEXT_FIELDS:
        if not isinstance(value, str) or len(value) > _TEXT_FIELDS[key]:
            raise _bad_record(path, value, f"field {key!r} must be text of at most {_TEXT_FIELDS[key]} characters")
    elif key.startswith("in."):
        if not is_finite_number(value):
            raise _bad_record(path, value, f"field {key!r} must be a finite number")
    elif key in _NUMBER_FIELDS or key.startswith("tuned."):
        if value is not None and not is_finite_number(value):
            raise _bad_record(path, value, f"field {key!r} must be a finite number or null")
    else:
        raise _bad_record(path, key, "has an unknown field")


def _check_record(path: Path, rec: Any, study: Study) -> dict:
    """The record's structure and field types, as :func:`make_row` writes them."""
    if not isinstance(rec, dict):
        raise _bad_record(path, rec, "must be a JSON object (one table row)")
    rid = rec.get("id")
    match = _ID.match(rid) if isinstance(rid, str) else None
    if match is None or path.name != f"{rid}.json":
        raise _bad_record(path, rid, "field 'id' must be the point id the file is named after")
    point = rec.get("point")
    if isinstance(point, bool) or not isinstance(point, int) or point != int(match.group(1)):
        raise _bad_record(path, point, f"field 'point' must be the index {int(match.group(1))} of its id")
    status = rec.get("status")
    if not isinstance(status, str) or status not in ("ok", "failed"):
        raise _bad_record(path, status, "field 'status' must be 'ok' or 'failed'")
    for key, value in rec.items():
        _check_field(path, key, value)
    error, stage = rec.get("error"), rec.get("failed_stage")
    if status == "ok" and (error or stage):
        raise _bad_record(path, error or stage, "a point with status 'ok' has no error")
    if status == "failed" and (not error or stage not in study.stages):
        raise _bad_record(path, stage, f"a failed point names its error and its stage ({', '.join(study.stages)})")
    return rec


def _check_point_record(path: Path, rec: dict, study: Study, point: dict) -> None:
    """A record of one of this study's points: its inputs and, if ok, every output of the stages."""
    inputs = {k[3:]: v for k, v in rec.items() if k.startswith("in.")}
    if inputs != point:
        raise _bad_record(path, inputs, f"inputs must be those of point {rec['point']}: {point}")
    if rec["status"] == "ok":
        for o, (stage, _, _) in OUTPUTS.items():
            if stage in study.stages and o not in rec and not (o == "matched" and not study.settings.match):
                raise _bad_record(path, o, "a point with status 'ok' has every output of its stages")


def _read_store(store: Path, study: Study, points: list[dict], ids: list[str]) -> dict[str, dict]:
    """The validated records of this study's points in the resume store, by point id.

    Records of other studies or settings (other ids) are checked, then left out; a record
    that is not what :func:`make_row` writes is a :class:`ParameterError` naming the file.
    """
    if not _check_store(store):
        return {}
    index = {pid: i for i, pid in enumerate(ids)}
    done = {}
    for path in sorted(store.glob("p*.json")):
        rec = _check_record(path, _load_record(path), study)
        i = index.get(rec["id"])
        if i is None:
            log.info("resume record %s is of other settings or another study: not used", path)
            continue
        _check_point_record(path, rec, study, points[i])
        done[rec["id"]] = rec
    return done


# ------------------------------------------------------------------------------- plan


@dataclass
class _Plan:
    """Task keys per point: the unique (design), (design, q_mech) and per-point chains."""

    points: list[dict]
    design_keys: list[str] = field(default_factory=list)
    harm_keys: list[str] = field(default_factory=list)


def _key(d: dict) -> str:
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]


def _split(study: Study, point: dict) -> tuple[dict, float, float, dict]:
    design = {k: v for k, v in point.items() if k.split(".", 1)[0] not in ("drive", "impact")}
    q_mech = point.get("drive.q_mech", study.settings.q_mech)
    voltage = point.get("drive.voltage", study.settings.voltage)
    impact = {k.split(".", 1)[1]: v for k, v in point.items() if k.startswith("impact.")}
    return design, q_mech, voltage, impact


def _submit(client, study: Study, todo: list[tuple[int, dict]], store: str | None):
    """Submit every stage task of the points in ``todo``; returns the row futures."""
    stages = set(study.stages)
    cache: dict[str, Any] = {}
    rows = []

    def once(key, fn, *args):
        if key not in cache:
            cache[key] = client.submit(_guard, key.split("-", 1)[0], fn, *args, key=key, pure=False)
        return cache[key]

    fp = study.fingerprint()
    for index, point in todo:
        design, q_mech, voltage, impact = _split(study, point)
        dk = f"mesh-{fp}-{_key(design)}"
        futs = [once(dk, lambda d=design: stage_mesh(study, d))]
        if "match" in stages:
            futs.append(once(dk.replace("mesh-", "match-", 1), lambda m: stage_match(study, m), futs[0]))
        if "harmonic" in stages:
            hk = f"harmonic-{fp}-{_key({'d': design, 'q': q_mech})}"
            futs.append(once(hk, lambda m, q=q_mech: stage_harmonic(study, m, q), futs[1]))
        if "impact" in stages:
            ik = f"impact-{fp}-{_key(point)}-{index}"
            futs.append(once(ik, lambda h, v=voltage, i=impact: stage_impact(study, h, v, i), futs[2]))
        recs = [once(f"rec-{f.key}", _record, f) for f in futs]
        rows.append(client.submit(make_row, study, index, point, recs, store, key=f"row-{fp}-{index}", pure=False))
    return rows


def run_sequential(study: Study, points: list[dict] | None = None, threads: int | None = 1) -> list[dict]:
    """The hand-scheduled loop: each unique mesh / match / harmonic computed once, in order.

    Same stage functions and reuse as the Dask path, in this process: the baseline of
    ``benchmarks/bench_explore.py`` (its impact numbers equal the Dask run's)."""
    points = study.points() if points is None else points
    cache: dict[str, Any] = {}

    def once(key, fn, *args):
        if key not in cache:
            cache[key] = _guard(key.split("-", 1)[0], fn, *args, threads=threads)
        return cache[key]

    rows = []
    for index, point in enumerate(points):
        design, q_mech, voltage, impact = _split(study, point)
        dk = _key(design)
        out = [once(f"mesh-{dk}", lambda d=design: stage_mesh(study, d))]
        if "match" in study.stages:
            out.append(once(f"match-{dk}", lambda m: stage_match(study, m), out[0]))
        if "harmonic" in study.stages:
            out.append(once(f"harmonic-{_key({'d': design, 'q': q_mech})}",
                            lambda m, q=q_mech: stage_harmonic(study, m, q), out[1]))
        if "impact" in study.stages:
            out.append(_guard("impact", lambda h, v=voltage, i=impact: stage_impact(study, h, v, i), out[2],
                              threads=threads))
        rows.append(make_row(study, index, point, [_record(x) for x in out]))
    return rows


# ------------------------------------------------------------------------------- result


@dataclass
class StudyResult(Result):
    """A finished study: its table and where it was written.

    Attributes
    ----------
    study : Study
    rows : list of dict
        One per point, in point order (see the module docstring for the columns).
    folder : Path or None
    computed, resumed : int
        Points computed in this run and taken from the resume store.
    seconds : float
        Wall time of the run, s.
    workers : int
    """

    study: Study
    rows: list
    folder: Path | None = None
    computed: int = 0
    resumed: int = 0
    seconds: float = 0.0
    workers: int = 0

    @property
    def failed(self) -> int:
        return sum(r["status"] != "ok" for r in self.rows)

    def _headline(self) -> str:
        return (f"study {self.study.name}: {len(self.rows)} points ({self.failed} failed), "
                f"{self.computed} computed + {self.resumed} resumed in {self.seconds:.1f} s on {self.workers} workers")

    def _record(self) -> dict:
        from rpud_common import to_jsonable

        from .explore_figures import tolerance_table

        extra = {"tolerance": tolerance_table(self)} if self.study.sampling == "tolerance" else {}
        return {**extra, "study": to_jsonable(self.study), "points": len(self.rows), "failed": self.failed,
                "computed": self.computed, "resumed": self.resumed, "seconds": self.seconds,
                "workers": self.workers, "stages": list(self.study.stages),
                "outputs": {k: {"stage": v[0], "unit": v[1], "description": v[2]} for k, v in OUTPUTS.items()
                            if v[0] in self.study.stages}}

    def frame(self):
        """The table as a pandas DataFrame (one row per point)."""
        import pandas as pd

        return pd.DataFrame(self.rows)


# ------------------------------------------------------------------------------- cost

# Stage times of the default design (as built, its own mesh rule: 12 925 tetrahedra, ~93 000
# estimated DOFs), measured on this project's 2-core reference machine with one BLAS thread, as
# a worker runs them: the stage functions called in turn on one point (see run_sequential).
MESH_SECONDS = 1.5
"""Gmsh meshing of the default design, s (measured 1.44 s)."""
MODAL_SECONDS = 4.5
"""The match stage without resonance matching (assembly + modal analysis), s (measured 4.5 s)."""
MATCHING_SECONDS = 16.5
"""The match stage with resonance matching (``settings.match``), s (measured 16.2 s)."""
HARMONIC_SECONDS = 4.5
"""Harmonic response and modal basis at the working mode, s (measured 4.2-4.5 s)."""
IMPACT_SECONDS = 0.5
"""Impact statistics: the fixed part (amplitude iteration, first batch), s (measured 0.45 s)."""
IMPACT_MEMBER_SECONDS = 1.2e-3
"""Impact statistics per ensemble member, s (256 members 0.73 s, 1024 members 1.59 s); the
estimate takes ``settings.max_members`` members, the most a point can take."""
REFERENCE_DOFS = 93_056
"""``geometry.guard.estimate`` of the default design at its own mesh rule: FE stage times scale
from it."""
FE_COST_EXPONENT = 1.3
"""FE stage time ~ estimated DOFs ** 1.3 (default design at mesh_size 2.5 and 2 mm: 2.7x and
5.1x the DOFs took 2.6-3.1x and 7.0-8.6x the modal and harmonic time)."""
STARTUP_SECONDS = 5.0
"""Starting a local cluster and writing the results folder, s."""
MAX_HOURS = 2.0
"""Budget of the command line: a study estimated longer is refused unless ``--allow-large``."""


@dataclass(frozen=True)
class CostEstimate:
    """Predicted cost of a study's points (see :func:`estimate_cost`).

    Attributes
    ----------
    seconds : float
        Wall time on ``workers`` workers, s.
    core_seconds : float
        Computing time summed over the tasks, s.
    points, meshes, harmonics, workers : int
        Points, unique designs (mesh and match tasks), unique harmonic tasks, workers.
    dofs : int
        Estimated FE degrees of freedom of the base design at the study's mesh size.
    """

    seconds: float
    core_seconds: float
    points: int
    meshes: int
    harmonics: int
    workers: int
    dofs: int

    def describe(self) -> str:
        return (f"{_duration(self.seconds)} on {self.workers} workers ({self.points} points: {self.meshes} meshes, "
                f"{self.harmonics} harmonic analyses of ~{self.dofs:,} DOFs, {self.core_seconds / 3600:.3g} "
                "core-hours)")


def estimate_cost(study: Study, points: list[dict], workers: int) -> CostEstimate:
    """Wall time of ``points`` of ``study`` on ``workers`` workers.

    Points that share their design share the mesh and match tasks and, with the same
    ``q_mech``, the harmonic task (as :func:`explore` schedules them); every point has its own
    impact task. Stage times are the constants above, scaled by the base design's estimated
    DOFs at the study's mesh size.
    """
    from geometry.guard import estimate

    dofs = estimate(study.base_design(), study.settings.mesh_size or None).dofs
    scale = (dofs / REFERENCE_DOFS) ** FE_COST_EXPONENT
    splits = [_split(study, p) for p in points]
    meshes = len({_key(d) for d, _, _, _ in splits})
    harmonics = len({_key({"d": d, "q": q}) for d, q, _, _ in splits}) if "harmonic" in study.stages else 0
    match_s = (MATCHING_SECONDS if study.settings.match else MODAL_SECONDS) if "match" in study.stages else 0.0
    core = (meshes * (MESH_SECONDS + match_s) + harmonics * HARMONIC_SECONDS) * scale
    if "impact" in study.stages:
        core += len(points) * (IMPACT_SECONDS + IMPACT_MEMBER_SECONDS * study.settings.max_members)
    workers = max(workers, 1)
    return CostEstimate(seconds=STARTUP_SECONDS + core / workers, core_seconds=core, points=len(points),
                        meshes=meshes, harmonics=harmonics, workers=workers, dofs=dofs)


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def check_cost(study: Study, points: list[dict], workers: int, max_hours: float | None) -> CostEstimate | None:
    """Refuse a study estimated longer than ``max_hours`` or above the FE size budget."""
    if not points:
        return None
    from geometry.guard import MAX_DOFS

    cost = estimate_cost(study, points, workers)
    log.info("study %s: estimated %s", study.name, cost.describe())
    if max_hours is None:
        return cost
    if cost.seconds > max_hours * 3600:
        raise ParameterError("study", f"{cost.points} points", f"estimated {cost.describe()}, above the budget of "
                                      f"{max_hours:g} h: pass --allow-large to run it anyway, or sample fewer points")
    if cost.dofs > MAX_DOFS:
        raise ParameterError("settings.mesh_size", study.settings.mesh_size,
                             f"gives ~{cost.dofs:,} DOFs per point, above the budget of {MAX_DOFS:,}: use a larger "
                             "mesh_size, or pass --allow-large")
    return cost


# ------------------------------------------------------------------------------- scheduler

SCHEDULER_TIMEOUT_S = 10.0
"""Bound of the whole connection to ``--scheduler``: TCP connect, handshake and first answer, s."""

_HOST = re.compile(r"[A-Za-z0-9]([A-Za-z0-9.-]{0,252})?\Z|\[[0-9A-Fa-f:.]{2,45}\]\Z")


def check_scheduler_address(address: Any) -> str:
    """``tcp://host:port`` (or ``host:port``): the one protocol a Client needs no setup for.

    ``tls://`` needs certificates (a ``Security`` object) and ``ucx://`` a UCX build, neither of
    which this command takes; ``inproc://`` only reaches a scheduler in the same process.
    """
    where = "--scheduler"
    if not isinstance(address, str) or not address.strip() or len(address) > 300 or not address.isprintable():
        raise ParameterError(where, address, "give the address of a running Dask scheduler, tcp://host:port")
    text = address.strip()
    scheme, sep, loc = text.partition("://")
    if not sep:
        scheme, loc = "tcp", text
    if scheme != "tcp":
        raise ParameterError(where, address, f"the {scheme!r} protocol is not supported here: give tcp://host:port")
    host, colon, port = loc.rpartition(":")
    if not colon or not _HOST.match(host) or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ParameterError(where, address, "give tcp://host:port, a host name or IP address and a port 1-65535")
    return f"tcp://{loc}"


def _probe(address: str, timeout_s: float) -> Any:
    """The scheduler's identity, asked with one deadline over connect, handshake and answer.

    Dask's own connect timeout ends with the TCP connection: a peer that accepts it and never
    answers the handshake would hold the Client forever.
    """
    import asyncio

    from distributed.comm import connect

    async def ask():
        comm = await connect(address, timeout=timeout_s)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    return asyncio.run(asyncio.wait_for(ask(), timeout_s))


def _connect(address: str, timeout_s: float | None = None):
    """A client of the scheduler at ``address`` with at least one worker, or a ParameterError."""
    from dask.distributed import Client

    timeout_s = SCHEDULER_TIMEOUT_S if timeout_s is None else timeout_s
    address = check_scheduler_address(address)
    why = f"no Dask scheduler answered there within {timeout_s:g} s"
    try:
        info = _probe(address, timeout_s)
    # whatever a peer sends back (garbage, a closed stream) means it is no usable scheduler
    except Exception as exc:  # noqa: BLE001
        raise ParameterError("--scheduler", address, f"{why} ({type(exc).__name__}); give the tcp://host:port "
                                                     "of a running scheduler") from None
    if not isinstance(info, dict) or info.get("type") != "Scheduler":
        raise ParameterError("--scheduler", address, "answers, but not as a Dask scheduler")
    if not info.get("workers"):
        raise ParameterError("--scheduler", address, "the scheduler has no workers: start some "
                                                     f"(dask worker {address}) first")
    try:
        return Client(address, timeout=timeout_s)
    except (ValueError, OSError, TimeoutError) as exc:
        raise ParameterError("--scheduler", address, f"{why} ({type(exc).__name__})") from None


# ------------------------------------------------------------------------------- driver


def _resume_store(out: Path) -> Path:
    return out.parent / f".{out.name}.resume"


@contextlib.contextmanager
def _signals_held_for_dask(insist: bool = True):
    """Start or stop a local cluster as a whole, and start its workers deaf to SIGINT.

    SIGINT/SIGTERM received meanwhile are recorded and re-delivered to the previous handlers
    when the block ends: raised inside Dask's start-up or shut-down they would leave a half
    started cluster, which Dask's exit hook then fails to close with a traceback. With
    ``insist``, a second signal is delivered at once, so a start-up that hangs can still be
    stopped (by a second SIGTERM: a SIGINT held by the mask below counts once).

    SIGINT is also blocked in the threads Dask starts meanwhile, and through them in the
    worker processes (threads and processes inherit the signal mask): a terminal's Ctrl-C
    reaches the whole process group, and only this process should answer it, by stopping the
    cluster and reporting one line, not every worker with a traceback.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from multiprocessing import resource_tracker

    # multiprocessing starts its resource tracker on the first spawn and then *unblocks* SIGINT
    # in the spawning thread (rather than restoring its mask): start it before the block
    resource_tracker.ensure_running()
    got: list[int] = []
    previous: dict[int, Any] = {}

    def restore() -> None:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        previous.clear()

    def hold(signum, frame):
        got.append(signum)
        if insist and len(got) > 1:
            handler = previous.get(signum)
            restore()
            _deliver(signum, handler)

    for sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(sig) not in (signal.SIG_IGN, None):
            previous[sig] = signal.signal(sig, hold)
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)     # a held SIGINT arrives here, in hold()
        handlers = dict(previous)
        restore()
        if got and handlers:
            _deliver(got[-1], handlers.get(got[-1]))


def _deliver(signum: int, handler) -> None:
    """Run a signal's handler as the signal would have (a default action through the kernel)."""
    if callable(handler):
        handler(signum, None)
    else:
        signal.raise_signal(signum)


def _local_cluster(n: int):
    from dask.distributed import Client, LocalCluster

    cluster = client = None
    try:
        with _signals_held_for_dask():
            # the scheduler's HTTP server on a free local port: two studies at once do not compete for 8787
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                   env=WORKER_ENV, silence_logs=WORKER_LOG_LEVEL,
                                   scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
            client = Client(cluster)
    except BaseException:
        _close(client, cluster)
        raise
    return cluster, client


def _close(client, cluster) -> None:
    with _signals_held_for_dask(insist=False):
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()


def _run(client, study: Study, todo: list[tuple[int, dict]], store: Path, progress: bool) -> list[dict]:
    from dask.distributed import progress as dask_progress
    from dask.distributed import wait

    futures = _submit(client, study, todo, str(store))
    if progress:
        dask_progress(futures)
    wait(futures)
    return client.gather(futures)


def _reset_store(store: Path, resume: bool) -> None:
    if not resume and _check_store(store):
        shutil.rmtree(store)
    store.mkdir(exist_ok=True)


def explore(study: Study, out: str | os.PathLike, *, workers: int | None = None, scheduler: str | None = None,
            resume: bool = False, progress: bool = False, figures: bool = True,
            max_hours: float | None = None) -> StudyResult:
    """Run ``study`` on Dask and write its folder ``out`` (whole or not at all).

    Everything is checked (resume records, scheduler, cost) before anything is written or a
    cluster starts; ``out``'s parent folder is created then if missing.

    Parameters
    ----------
    study : Study
    out : path
        Result folder (replaced as a whole when the study ends).
    workers : int, optional
        Worker processes of the local cluster (default: one per core). Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); its workers need rpud
        installed and the output folder's file system for the resume records.
    resume : bool
        Take finished points from the resume store of an earlier, interrupted run of the same
        study (same settings; a point computed under other settings is never reused). A record
        that is not what this module writes is refused (:class:`ParameterError`).
    progress : bool
        Show Dask's progress bar on the terminal.
    figures : bool
        Write ``figures/``.
    max_hours : float, optional
        Refuse a study whose estimated wall time (:func:`estimate_cost`) exceeds it, or
        whose base design exceeds the FE size budget; None runs any study.
    """
    out = Path(out)
    t0 = time.perf_counter()
    points = study.points()
    fp = study.fingerprint()
    ids = [point_id(study, i, p, fp) for i, p in enumerate(points)]
    store = _resume_store(out)
    done = _read_store(store, study, points, ids) if resume else {}
    if not resume:
        _check_store(store)
    todo = [(i, p) for i, p in enumerate(points) if ids[i] not in done]
    remote = _connect(scheduler) if scheduler else None
    with contextlib.closing(remote) if remote is not None else contextlib.nullcontext():
        n_workers = len(remote.scheduler_info()["workers"]) if remote else workers or os.cpu_count() or 1
        check_cost(study, [p for _, p in todo], n_workers, max_hours)
        out.parent.mkdir(exist_ok=True)
        _reset_store(store, resume)
        log.info("study %s: %d points, %d resumed from %s, %d to compute", study.name, len(points),
                 len(points) - len(todo), store, len(todo))
        rows_new = _compute(study, todo, store, remote, workers, progress)
    for row in rows_new:        # the client writes too: a remote worker may not see the store
        _write_record(store, row)
        log.info("point %s %s (computed)", row["id"], row["status"])
    for pid in ids:
        if pid in done:
            log.info("point %s %s (resumed)", pid, done[pid]["status"])
    by_id = {**done, **{r["id"]: r for r in rows_new}}
    result = StudyResult(study=study, rows=[by_id[i] for i in ids], computed=len(rows_new),
                         resumed=len(points) - len(todo), seconds=time.perf_counter() - t0,
                         workers=n_workers if todo else 0)
    _write_folder(result, out, figures)
    shutil.rmtree(store, ignore_errors=True)
    result.folder = out
    return result


def _compute(study: Study, todo, store: Path, remote, workers: int | None, progress: bool) -> list[dict]:
    """The rows of the points in ``todo``, on the remote client or a local cluster."""
    if not todo:
        return []
    cluster, client = (None, remote) if remote is not None else _local_cluster(workers or os.cpu_count() or 1)
    try:
        return _run(client, study, todo, store, progress)
    finally:
        _close(client, cluster)


def _write_folder(result: StudyResult, out: Path, figures: bool) -> None:
    with atomic_folder(out) as tmp:
        _write_table(result, tmp)
        if figures:
            from .explore_figures import study_figures

            study_figures(result, tmp / "figures")
        # only this study's rows: a foreign record left in the store is not part of the result
        for row in result.rows:
            write_json(tmp / "points" / f"{row['id']}.json", row, nonfinite="null", provenance=False)


def _write_table(result: StudyResult, folder: Path) -> None:
    from rpud_common import atomic_output

    df = result.frame()
    with atomic_output(folder / "table.parquet") as tmp:
        df.to_parquet(tmp, engine="pyarrow", index=False)
    with atomic_output(folder / "table.csv") as tmp:
        df.to_csv(tmp, index=False)
    write_json(folder / "study.json", result.to_dict(), nonfinite="null")

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

import dataclasses
import hashlib
import json
import logging
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from rpud_common import atomic_folder, write_json
from rpud_common.result import Result

from .study import OUTPUTS, STAGES, Study

log = logging.getLogger(__name__)

__all__ = ["explore", "run_sequential", "StudyResult", "point_id", "WORKER_ENV"]

WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "NUMBA_NUM_THREADS": "1", "MKL_CBWR": "COMPATIBLE"}
"""Environment of every worker process: one thread each, so numbers do not depend on the layout."""

_HANDOFF_DIGITS = 4


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


def point_id(study: Study, index: int, point: dict) -> str:
    """``p<index>-<hash>``: the hash covers the point's values and the study's fingerprint, so a
    resumed study never picks up a record computed under other settings."""
    blob = json.dumps({"fp": study.fingerprint(), "point": point}, sort_keys=True)
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
        write_json(store / f"{row['id']}.json", row, nonfinite="null")


def _read_store(store: Path) -> dict[str, dict]:
    done = {}
    if store.is_dir():
        for f in sorted(store.glob("p*.json")):
            try:
                row = json.loads(f.read_text())
            except (OSError, ValueError):
                log.warning("ignoring unreadable resume record %s", f)
                continue
            done[row.get("id", "")] = row
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


# ------------------------------------------------------------------------------- driver


def _resume_store(out: Path) -> Path:
    return out.parent / f".{out.name}.resume"


def explore(study: Study, out: str | os.PathLike, *, workers: int | None = None, scheduler: str | None = None,
            resume: bool = False, progress: bool = False, figures: bool = True) -> StudyResult:
    """Run ``study`` on Dask and write its folder ``out`` (whole or not at all).

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
        study (same settings; a point computed under other settings is never reused).
    progress : bool
        Show Dask's progress bar on the terminal.
    """
    from dask.distributed import Client, LocalCluster, wait
    from dask.distributed import progress as dask_progress

    out = Path(out)
    t0 = time.perf_counter()
    points = study.points()
    # a scheduler address is checked before anything is written or computed
    remote = _connect(Client, scheduler) if scheduler else None
    store = _resume_store(out)
    if not resume and store.exists():
        shutil.rmtree(store)
    store.mkdir(exist_ok=True)
    done = _read_store(store) if resume else {}
    ids = [point_id(study, i, p) for i, p in enumerate(points)]
    todo = [(i, p) for i, p in enumerate(points) if ids[i] not in done]
    log.info("study %s: %d points, %d resumed from %s, %d to compute", study.name, len(points),
             len(points) - len(todo), store, len(todo))
    rows_new: list[dict] = []
    n_workers = 0
    if not todo and remote is not None:
        remote.close()
    if todo:
        if remote is not None:
            cluster, client = None, remote
        else:
            n = workers or os.cpu_count() or 1
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                   env=WORKER_ENV, silence_logs=logging.ERROR)
            client = Client(cluster)
        try:
            n_workers = len(client.scheduler_info()["workers"])
            futures = _submit(client, study, todo, str(store))
            if progress:
                dask_progress(futures)
            wait(futures)
            rows_new = client.gather(futures)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        for row in rows_new:        # the client writes too: a remote worker may not see the store
            _write_record(store, row)
            log.info("point %s %s (computed)", row["id"], row["status"])
    for i in range(len(points)):
        if ids[i] in done:
            log.info("point %s %s (resumed)", ids[i], done[ids[i]]["status"])
    by_id = {**done, **{r["id"]: r for r in rows_new}}
    rows = [by_id[i] for i in ids]
    result = StudyResult(study=study, rows=rows, computed=len(rows_new), resumed=len(points) - len(todo),
                         seconds=time.perf_counter() - t0, workers=n_workers)
    with atomic_folder(out) as tmp:
        _write_table(result, tmp)
        if figures:
            from .explore_figures import study_figures

            study_figures(result, tmp / "figures")
        shutil.copytree(store, tmp / "points")
    shutil.rmtree(store, ignore_errors=True)
    result.folder = out
    return result


def _connect(client_cls, address: str, timeout_s: float = 10.0):
    """A client of the scheduler at ``address``, or a ParameterError saying why not."""
    from rpud_common import ParameterError

    try:
        return client_cls(address, timeout=timeout_s)
    except (ValueError, OSError, TimeoutError) as exc:
        raise ParameterError("scheduler", address, f"no Dask scheduler reachable there within {timeout_s:g} s "
                             f"({type(exc).__name__}); give the tcp://host:port of a running scheduler") from None


def _write_table(result: StudyResult, folder: Path) -> None:
    from rpud_common import atomic_output

    df = result.frame()
    with atomic_output(folder / "table.parquet") as tmp:
        df.to_parquet(tmp, engine="pyarrow", index=False)
    with atomic_output(folder / "table.csv") as tmp:
        df.to_csv(tmp, index=False)
    write_json(folder / "study.json", result.to_dict(), nonfinite="null")

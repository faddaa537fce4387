"""Design studies on Dask: every point of a :class:`results.study.Study` through the pipeline's stages.

Tasks are per point and stage (mesh -> match -> harmonic -> impact), each the stage function the
end-to-end run calls (:mod:`results.explore_tasks`), so a one-point study gives the numbers of
:func:`results.pipeline.run_pipeline` with the same settings. Points that share
their design values share the mesh and match tasks, and points that also share ``q_mech`` share
the harmonic task (drive voltage and impact parameters only enter later), so a study over free
mass and voltage on one design meshes and matches once. Heavy objects (meshes, FE systems, modal
bases) stay on the worker that made them; only small records travel. Each point ends in a row
task that also writes the row to the resume store (:mod:`results.explore_store`), so an
interrupted study (or a lost worker) restarts with ``resume=True`` from the finished points.

A stage that fails records its error in the point's row (``status`` "failed", ``error``) and
the study goes on. Rows are deterministic: every FE task runs with one BLAS thread in its own
worker process (the same numbers on 1 or many workers, and in :func:`run_sequential`), the
impact ensembles are seeded with the study seed (the same members at every point: common random
numbers, so differences between points are not masked by member-to-member scatter), and the
amplitude handed to the impacts is rounded to 4 significant digits as in the pipeline.

Outputs (:func:`explore`): ``table.parquet`` and ``table.csv`` (one row per point: inputs,
outputs, impact outputs with their 95 % CI half-width ``<name>_ci95``, rotor outputs with their
error ``<name>_error`` from the teeth motion's discretisation error, status, error),
``study.json`` (the study, counts, timings) and ``points/`` (one JSON per point), written into
the output folder as a whole.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rpud_common import atomic_folder, write_json
from rpud_common.result import Result

from .explore_cluster import (WORKER_ENV, SCHEDULER_TIMEOUT_S, check_scheduler_address, close_cluster, connect,
                              local_cluster)
from .explore_cost import MAX_HOURS, CostEstimate, check_cost, estimate_cost
from .explore_store import (MAX_RECORD_BYTES, check_store, make_row, point_id, read_store, reset_store, resume_store,
                            write_record)
from .explore_tasks import (guard, record, rotor_values, split_point, task_harmonic, task_impact, task_key,
                            task_match, task_mesh, task_rotor, task_teeth_error)
from .study import OUTPUTS, Study

log = logging.getLogger(__name__)

__all__ = ["explore", "run_sequential", "StudyResult", "point_id", "WORKER_ENV", "estimate_cost",
           "CostEstimate", "check_scheduler_address", "MAX_HOURS", "SCHEDULER_TIMEOUT_S", "MAX_RECORD_BYTES"]


def _submit(client, study: Study, todo: list[tuple[int, dict]], store: str | None):
    """Submit every stage task of the points in ``todo``; returns the row futures."""
    stages = set(study.stages)
    cache: dict[str, Any] = {}
    rows = []

    def once(key, fn, *args):
        if key not in cache:
            cache[key] = client.submit(guard, key.split("-", 1)[0], fn, *args, key=key, pure=False)
        return cache[key]

    fp = study.fingerprint()
    for index, point in todo:
        design, q_mech, voltage, impact = split_point(study, point)
        dk = f"mesh-{fp}-{task_key(design)}"
        futs = [once(dk, lambda d=design: task_mesh(study, d))]
        if "match" in stages:
            futs.append(once(dk.replace("mesh-", "match-", 1), lambda m: task_match(study, m), futs[0]))
        if "harmonic" in stages:
            hk = f"harmonic-{fp}-{task_key({'d': design, 'q': q_mech})}"
            futs.append(once(hk, lambda m, q=q_mech: task_harmonic(study, m, q), futs[1]))
        if "impact" in stages:
            ik = f"impact-{fp}-{task_key(point)}-{index}"
            futs.append(once(ik, lambda h, v=voltage, i=impact: task_impact(study, h, v, i), futs[2]))
        if "rotor" in stages:
            ek = f"rotor-{fp}-teeth-{task_key({'d': design, 'q': q_mech})}"     # a failure is the rotor stage's
            est = once(ek, lambda m, h: task_teeth_error(study, m, h), futs[1], futs[2])
            rk = f"rotor-{fp}-{task_key(point)}-{index}"
            futs.append(once(rk, lambda h, e, d=design, v=voltage, r=rotor_values(point):
                             task_rotor(study, h, d, v, r, e), futs[2], est))
        recs = [once(f"rec-{f.key}", record, f) for f in futs]
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
            cache[key] = guard(key.split("-", 1)[0], fn, *args, threads=threads)
        return cache[key]

    rows = []
    for index, point in enumerate(points):
        design, q_mech, voltage, impact = split_point(study, point)
        dk = task_key(design)
        out = [once(f"mesh-{dk}", lambda d=design: task_mesh(study, d))]
        if "match" in study.stages:
            out.append(once(f"match-{dk}", lambda m: task_match(study, m), out[0]))
        if "harmonic" in study.stages:
            out.append(once(f"harmonic-{task_key({'d': design, 'q': q_mech})}",
                            lambda m, q=q_mech: task_harmonic(study, m, q), out[1]))
        if "impact" in study.stages:
            out.append(guard("impact", lambda h, v=voltage, i=impact: task_impact(study, h, v, i), out[2],
                             threads=threads))
        if "rotor" in study.stages:
            rotor = rotor_values(point)
            est = once(f"rotor-teeth-{task_key({'d': design, 'q': q_mech})}", lambda m, h: task_teeth_error(study, m, h),
                       out[1], out[2])
            out.append(guard("rotor", lambda h, e, d=design, v=voltage, r=rotor: task_rotor(study, h, d, v, r, e),
                             out[2], est, threads=threads))
        rows.append(make_row(study, index, point, [record(x) for x in out]))
    return rows


@dataclass(repr=False)
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


def _run(client, study: Study, todo: list[tuple[int, dict]], store: Path, progress: bool) -> list[dict]:
    from dask.distributed import progress as dask_progress
    from dask.distributed import wait

    futures = _submit(client, study, todo, str(store))
    if progress:
        dask_progress(futures)
    wait(futures)
    return client.gather(futures)



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
    store = resume_store(out)
    done = read_store(store, study, points, ids) if resume else {}
    if not resume:
        check_store(store)
    todo = [(i, p) for i, p in enumerate(points) if ids[i] not in done]
    remote = connect(scheduler) if scheduler else None
    with contextlib.closing(remote) if remote is not None else contextlib.nullcontext():
        n_workers = len(remote.scheduler_info()["workers"]) if remote else workers or os.cpu_count() or 1
        check_cost(study, [p for _, p in todo], n_workers, max_hours)
        out.parent.mkdir(exist_ok=True)
        reset_store(store, resume)
        log.info("study %s: %d points, %d resumed from %s, %d to compute", study.name, len(points),
                 len(points) - len(todo), store, len(todo))
        rows_new = _compute(study, todo, store, remote, workers, progress)
    for row in rows_new:        # the client writes too: a remote worker may not see the store
        write_record(store, row)
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
    cluster, client = (None, remote) if remote is not None else local_cluster(workers or os.cpu_count() or 1)
    try:
        return _run(client, study, todo, store, progress)
    finally:
        close_cluster(client, cluster)


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

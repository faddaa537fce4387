"""``python -m results explore STUDY.toml``: a design study on Dask (see :mod:`results.explore`)."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

from rpud_common import CliParser, ParameterError, check_integer, check_output_paths, setup_logging

_CORES = os.cpu_count() or 1
MAX_WORKERS = 4 * _CORES
"""Most local worker processes: each holds an FE model (about 1 GB for the article's drill)."""


def build_parser() -> CliParser:
    from .explore import MAX_HOURS, SCHEDULER_TIMEOUT_S

    p = CliParser(prog="python -m results explore",
                  description="Run a design study: every point of STUDY.toml through its stages (mesh -> match -> "
                              "harmonic -> impact statistics) on a Dask cluster. Writes table.parquet, table.csv, "
                              "study.json, figures/ and points/ into the output folder. The study file, the "
                              "resume records, the scheduler and the estimated run time are checked before "
                              "anything is written or computed.")
    p.add_argument("study", metavar="STUDY.toml", help="study file (see results/examples/study_*.toml)")
    p.add_argument("--out", metavar="DIR", help="output folder (default results/study-<name>)")
    p.add_argument("--workers", type=int, metavar="N",
                   help=f"worker processes of the local Dask cluster, 1-{MAX_WORKERS} (default: one per core, "
                        f"{_CORES} here)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of a running Dask scheduler with workers (tcp://host:8786; no other protocol) "
                        "instead of a local cluster; its workers need rpud installed and the output folder's file "
                        f"system. Refused if it does not answer within {SCHEDULER_TIMEOUT_S:g} s")
    p.add_argument("--resume", action="store_true",
                   help="keep the points an interrupted run of the same study finished (a resume record that "
                        "is not one this command wrote is refused)")
    p.add_argument("--allow-large", action="store_true",
                   help=f"run even when the estimated time exceeds {MAX_HOURS:g} h or the base design exceeds the "
                        "FE size budget (the estimate: stage times of the article's drill measured on a 2-core "
                        "machine, scaled by the mesh size, over the workers)")
    p.add_argument("--no-figures", action="store_true", help="table and JSON only")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.add_argument("-v", "--verbose", action="count", default=0,
                   help="log each point and the run's estimate (-v; Dask's warnings too), and Dask's INFO lines (-vv)")
    return p


def quiet_dask(verbose: int) -> None:
    """Dask's loggers at ERROR (its warnings with -v, its INFO with -vv).

    ``distributed`` sets its loggers' levels when it is imported, so this imports it first.
    Worker processes are silenced by :func:`results.explore.explore` itself.
    """
    import distributed  # noqa: F401 - for its logging set-up, overridden below

    logging.getLogger("distributed").setLevel(logging.ERROR if verbose < 1 else logging.WARNING if verbose < 2
                                              else logging.INFO)
    for name in ("tornado", "asyncio", "bokeh"):
        logging.getLogger(name).setLevel(logging.ERROR)


def _output_folder(args, study) -> Path:
    """The output folder, checked; its default parent ``results/`` need not exist yet."""
    if args.out:
        check_output_paths(inputs={"STUDY.toml": args.study}, folders=("out",), out=args.out)
        return Path(args.out)
    out = Path("results") / f"study-{study.name}"
    target = out if out.parent.is_dir() else out.parent     # created by explore once all checks passed
    check_output_paths(inputs={"STUDY.toml": args.study}, folders=("out",), out=target)
    return out


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.verbose - 1)
    if args.workers is not None:
        check_integer("--workers", args.workers, 1, MAX_WORKERS)
    from .explore import MAX_HOURS, check_scheduler_address, explore

    if args.scheduler is not None:
        check_scheduler_address(args.scheduler)
    from .study import load_study

    path = Path(args.study)
    if not path.is_file():
        raise ParameterError("STUDY.toml", args.study, "is not a regular file" if path.exists() else "no such file")
    study = load_study(path)
    out = _output_folder(args, study)
    if not args.quiet:
        print(f"study {study.name}: {len(study.points())} points, stages {' -> '.join(study.stages)}", flush=True)
    quiet_dask(args.verbose)
    res = explore(study, out, workers=args.workers, scheduler=args.scheduler, resume=args.resume,
                  progress=not args.quiet, figures=not args.no_figures,
                  max_hours=None if args.allow_large else MAX_HOURS)
    logging.getLogger(__name__).info("%s", res)
    if not args.quiet:
        print(f"\n{len(res.rows)} points ({res.failed} failed; {res.computed} computed, {res.resumed} resumed) "
              f"in {res.seconds:.1f} s on {res.workers} workers", flush=True)
        print(f"results: {out}", flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover - python -m results explore is the entry point
    sys.exit(main())

"""``python -m results explore STUDY.toml``: a design study on Dask (see :mod:`results.explore`)."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

from rpud_common import CliParser, ParameterError, check_integer, check_output_paths, setup_logging


def build_parser() -> CliParser:
    p = CliParser(prog="python -m results explore",
                  description="Run a design study: every point of STUDY.toml through its stages (mesh -> match -> "
                              "harmonic -> impact statistics) on a Dask cluster. Writes table.parquet, table.csv, "
                              "study.json, figures/ and points/ into the output folder.")
    p.add_argument("study", metavar="STUDY.toml", help="study file (see results/examples/study_*.toml)")
    p.add_argument("--out", metavar="DIR", help="output folder (default results/study-<name>)")
    p.add_argument("--workers", type=int, metavar="N",
                   help=f"worker processes of the local Dask cluster (default: one per core, {os.cpu_count()} here)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of a running Dask scheduler (tcp://host:8786) instead of a local cluster; "
                        "its workers need rpud installed and the output folder's file system")
    p.add_argument("--resume", action="store_true",
                   help="keep the points an interrupted run of the same study finished")
    p.add_argument("--no-figures", action="store_true", help="table and JSON only")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.add_argument("-v", "--verbose", action="count", default=0, help="log each point (-v)")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.verbose - 1)
    if args.workers is not None:
        check_integer("--workers", args.workers, 1, 1024)
    if args.scheduler is not None and not args.scheduler.strip():
        raise ParameterError("--scheduler", args.scheduler, "give an address such as tcp://host:8786")
    from .study import load_study

    path = Path(args.study)
    if not path.is_file():
        raise ParameterError("STUDY.toml", args.study, "no such file")
    study = load_study(path)
    out = Path(args.out) if args.out else Path("results") / f"study-{study.name}"
    if args.out is None:
        out.parent.mkdir(exist_ok=True)
    check_output_paths(inputs={"STUDY.toml": args.study}, folders=("out",), out=out)
    n_points = len(study.points())
    if not args.quiet:
        print(f"study {study.name}: {n_points} points, stages {' -> '.join(study.stages)}", flush=True)
    from .explore import explore

    res = explore(study, out, workers=args.workers, scheduler=args.scheduler, resume=args.resume,
                  progress=not args.quiet, figures=not args.no_figures)
    logging.getLogger(__name__).info("%s", res)
    if not args.quiet:
        print(f"\n{len(res.rows)} points ({res.failed} failed; {res.computed} computed, {res.resumed} resumed) "
              f"in {res.seconds:.1f} s on {res.workers} workers", flush=True)
        print(f"results: {out}", flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover - python -m results explore is the entry point
    sys.exit(main())

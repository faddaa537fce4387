"""Shared by the benchmark scripts: Markdown tables (they paste into the README), timing, and the
same tables as JSON in benchmarks/results/ (the documentation's Benchmarks page reads them, so its
numbers are the scripts' own output, with the machine and date they were measured on)."""

import json
import math
import os
import platform
import sys
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"

# every table printed by this process, in order: a script may print several (its JSON holds all)
_TABLES: list[dict] = []


def best_of(fn, n: int) -> float:
    """Shortest of n timed calls, s (the least disturbed by other processes)."""
    best = math.inf
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _cpu_model() -> str:
    """The processor's name (Linux /proc/cpuinfo; platform.processor() elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_record() -> dict:
    """Where a benchmark ran: processor, cores visible to the process, OS and Python."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    # the 1-minute load average when the table was written: a loaded machine slows every timing
    return {"cpu": _cpu_model(), "cores": cores, "os": f"{platform.system()} {platform.release()}",
            "python": platform.python_version(), "load_average_1min": load}


def _script_name() -> str | None:
    """The running benchmark script's stem (``bench_impact``), or None outside a script run."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    return Path(path).stem if path else None


def write_json(name: str | None = None) -> Path | None:
    """Write every table printed so far to ``benchmarks/results/<name>.json``.

    Parameters
    ----------
    name : str, optional
        File stem; default the running script's name. Nothing is written when neither is known
        (the tables were printed from an import, e.g. a test).

    Returns
    -------
    pathlib.Path or None
        The file written.
    """
    name = name or _script_name()
    if not name or not _TABLES:
        return None
    try:
        from rpud_common.provenance import provenance_record
        prov = provenance_record()
    except ImportError:          # run without the package installed: the date alone
        prov = {"date_utc": time.strftime("%Y-%m-%dT%H:%M:%S+00:00", time.gmtime())}
    RESULTS.mkdir(exist_ok=True)
    out = RESULTS / f"{name}.json"
    out.write_text(json.dumps({"script": f"benchmarks/{name}.py", "provenance": prov,
                               "machine": machine_record(), "tables": _TABLES}, indent=1) + "\n")
    return out


def print_table(rows, headers=("benchmark", "time", "note")) -> None:
    """Print rows (tuples of strings) as a Markdown table, first column padded, and record it in
    the script's JSON (benchmarks/results/<script>.json, rewritten with every table so far)."""
    w = max(len(headers[0]), *(len(r[0]) for r in rows))
    print("| " + " | ".join([headers[0].ljust(w), *headers[1:]]) + " |")
    print(f"|{'-' * (w + 2)}|" + "---|" * (len(headers) - 1))
    for r in rows:
        print("| " + " | ".join([r[0].ljust(w), *r[1:]]) + " |")
    _TABLES.append({"headers": [str(h) for h in headers], "rows": [[str(c) for c in r] for r in rows]})
    write_json()

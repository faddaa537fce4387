"""The default end-to-end run (what `make run` does after the install), per stage.
Target: under 90 s on 2 cores. Writes into a temporary folder."""

import tempfile
import time

from _table import print_table

import geometry
from results.pipeline import PipelineSettings, run_pipeline


def main():
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        s = run_pipeline(geometry.default_design(), PipelineSettings(), tmp, progress=lambda msg: None).summary
        wall = time.perf_counter() - t0
    rows = [(k.removesuffix("_s"), f"{v:.1f} s") for k, v in s["timings"].items() if k != "total_s"]
    rows.append(("total (target < 90 s)", f"{wall:.1f} s"))
    print_table(rows, ("stage", "time"))


if __name__ == "__main__":
    main()

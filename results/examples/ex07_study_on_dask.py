"""A design study on a Dask cluster
==================================

Example 7: a small design study (free mass x drive voltage on the default drill) run by
``results.explore`` on a local Dask cluster, and how to run the same study on a batch cluster.

A study file names a base design, the parameters that vary, the sampling and the stages
(mesh -> match -> harmonic -> impact); ``results.explore`` turns every point into Dask tasks.
Points that share their design values share the mesh and the FE tasks, so this study of four
points meshes and solves the drill once and runs four impact ensembles. Every worker runs one
BLAS thread, so the table is the same on one worker or many. The folder it writes holds
``table.csv`` / ``table.parquet`` (one row per point, impact outputs with their 95 % CI
half-widths), ``study.json`` and ``figures/``.

The command line does the same: ``python -m results explore study.toml --workers 2`` (see
``results/examples/study_free_mass_voltage.toml`` for a larger study).

Dask starts its worker processes by *spawning* a fresh interpreter that imports this script
again, so a script that starts a local cluster keeps its work under
``if __name__ == "__main__":``.

Run it with ``python results/examples/ex07_study_on_dask.py`` (``--fast``: coarse mesh, every size
rule 2x coarser, 10 % interval target).
"""

import sys
from pathlib import Path

from results.explore import explore
from results.study import load_study

fast = "--fast" in sys.argv
out = Path("example_output")

STUDY = f"""
[study]
name = "free_mass_voltage_small"
design = "default"
stages = ["mesh", "match", "harmonic", "impact"]
sampling = "grid"
seed = 20260
outputs = ["A0_m", "tool_ke_j"]
pareto = ["tool_ke_j", "tool_rate_hz"]

[settings]
match = false              # the design as it is, no resonance matching
q_mech = 100.0             # assembled-transducer quality factor, as in the pipeline
mesh_size = {0.008 if fast else 0.0}        # m; 0: the design's own mesh rule
refine = {2.0 if fast else 1.0}             # every size rule scaled (mesh_size leaves the sector's layers)
rel_tol = {0.10 if fast else 0.05}          # 95 % CI half-width / mean of the impact outputs
max_members = 512

[parameters."impact.m_free"]
values = [0.004, 0.008]    # kg

[parameters."drive.voltage"]
values = [150.0, 225.0]    # V
"""

if __name__ == "__main__":
    out.mkdir(exist_ok=True)
    (out / "study_small.toml").write_text(STUDY)
    study = load_study(out / "study_small.toml")        # every key checked before anything runs
    print(f"{study.name}: {len(study.points())} points")

    # two worker processes on this machine (one per core of the reference machine)
    result = explore(study, out / "study_small", workers=2)
    print(f"{len(result.rows)} points, {result.failed} failed, {result.computed} computed in "
          f"{result.seconds:.1f} s on {result.workers} workers")

    # the table: one row per point; impact outputs carry their 95 % CI half-width
    table = result.frame()
    columns = ["in.impact.m_free", "in.drive.voltage", "status", "A0_m", "tool_ke_j", "tool_ke_j_ci95"]
    print(table[columns].to_string(index=False, float_format="{:.4g}".format))   # SI units: kg, V, m, J
    for row in result.rows:
        print(f"  {row['in.impact.m_free'] * 1e3:g} g at {row['in.drive.voltage']:g} V: A0 {row['A0_m'] * 1e6:.2f} um, "
              f"tool KE {row['tool_ke_j'] * 1e3:.3f} ± {row['tool_ke_j_ci95'] * 1e3:.3f} mJ")
    print(f"written: {sorted(p.name for p in (out / 'study_small').iterdir())}")

# %%
# On a batch cluster
# ------------------
#
# ``explore`` (and ``python -m results explore --scheduler``) also runs on the workers of any
# running Dask scheduler reachable at ``tcp://host:port``. On a SLURM machine,
# `dask-jobqueue <https://jobqueue.dask.org>`_ (not an rpud dependency: install it yourself)
# submits the workers as batch jobs. Each worker needs rpud installed (the same virtual
# environment), one thread, and the file system of the output folder (the resume records
# are written there). A sketch; add ``queue=`` and ``account=`` as your site requires and adapt the sizes:
#
# .. code-block:: python
#
#    from dask_jobqueue import SLURMCluster
#
#    from results.explore import WORKER_ENV, explore
#    from results.study import load_study
#
#    cluster = SLURMCluster(
#        cores=1, processes=1, memory="4GB", walltime="02:00:00",      # one worker per job
#        job_script_prologue=["source /path/to/rpud/.venv/bin/activate",
#                             *(f"export {k}={v}" for k, v in WORKER_ENV.items())],
#    )
#    cluster.scale(jobs=16)
#    result = explore(load_study("study.toml"), "/shared/results/study",
#                     scheduler=cluster.scheduler_address)             # tcp://host:port
#
# To use the command line instead, keep the cluster above alive in one session, print
# ``cluster.scheduler_address`` and, from another shell on the same network:
#
# .. code-block:: sh
#
#    python -m results explore study.toml --scheduler tcp://10.0.0.5:8786 --out /shared/results/study
#
# An interrupted study (a lost job, the wall time reached) continues with ``--resume``: the
# finished points are read back from the resume records instead of being computed again.

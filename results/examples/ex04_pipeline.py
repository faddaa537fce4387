"""The whole chain from Python
============================

Example 4: the whole chain from Python, geometry to drill-tool kinetic energy.

``results.run_pipeline`` does what ``python -m results`` (and ``make run``) does: mesh the
design, match horn and coupler to the target frequency, compute the horn-tip amplitude A0 at
the drive voltage, load it with the free-mass impacts until A0 and the impact power agree, and
sweep the free mass with converged statistics. Here with a lighter design study: one design
variant, a coarse mesh and a 5 % interval target (``--fast``: every mesh rule 2x coarser, no
matching, 10 %, no renders, no Q/2, 2Q range).

Run it with ``python results/examples/ex04_pipeline.py`` (about a minute; ``--fast``: also without the coupled model).
"""

import dataclasses
import sys
from pathlib import Path

import geometry
import results

fast = "--fast" in sys.argv
out = Path("example_output")

# A design variant: the default drill with a 2 mm longer coupler (frozen dataclasses: change
# a copy; the constructor validates it again).
base = geometry.default_design()
design = dataclasses.replace(base, name="longer_coupler",
                             coupler=dataclasses.replace(base.coupler, length=base.coupler.length + 0.002))

settings = results.PipelineSettings(
    mesh_size=0.008,                                 # coarse: a design study, not the final answer
    refine=2.0 if fast else 1.0,                     # mesh_size leaves the sector's layers and caps; refine scales all
    m_free_values=(0.004, 0.008) if fast else (0.002, 0.004, 0.008),    # kg
    impact_rel_tol=0.10 if fast else 0.05,           # 95 % CI half-width / mean
    match=not fast, render=not fast, n_points=40 if fast else 120,
    coupled_model=not fast,                          # the FE transducer inside the impacts (slow)
    compliant_members=0 if fast else 16,             # the compliant headline: 0 skips it (it costs ~1 min CPU)
    losses_bracket=not fast,                         # the headline again at Q/2 and 2Q (the losses' range)
)
res = results.run_pipeline(design, settings, out / "pipeline", progress=print)
print(res)                                           # headline numbers with their 95 % CIs

for row in res.summary["kinetic_energy_table"]:
    ke = row["device_fe"]["mean_tool_ke_after_j"]
    print(f"  {row['m_free_kg'] * 1e3:g} g: A0 {row['A0_fe_m'] * 1e6:.2f} um, tool KE "
          f"{ke['mean'] * 1e3:.2f} ± {ke['ci95_half_width'] * 1e3:.2f} mJ")

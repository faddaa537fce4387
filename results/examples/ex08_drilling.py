"""Drilling under load
====================

Example 8: the drill pressed on rock with a weight on bit, blows and predicted depth against
the free mass, and how much the answer depends on the rock law.

``impact.drilling`` extends the free-mass model to drilling (article section 5.2): the housing
that carries the horn is pushed toward the rock by the weight on bit (WOB, 7 N in the article),
the tool is a collar on a slender elastic rod, and the rod's far end meets the rock through a
bilinear force-penetration law with a crushing threshold (``impact.rock``). Every number is an
ensemble mean with its 95 % confidence interval, as for the no-load impacts.

.. warning::

   The rock law is **not calibrated**. Its three constants (loading and unloading stiffness,
   crushing threshold) come from handbook values of a medium sandstone, not from a bit-rock
   test on the article's rock with its bit, and every blow is assumed to meet fresh rock. The
   predicted depths are far larger than the article's 5-minute holes can have been: read the
   *trend* with the free mass (the article's finding: deeper with a heavier free mass), not the
   millimetres. The last step below doubles the crushing threshold to show how far the depth
   moves with one of these constants.

The command line runs the same model over 0-8 g: ``python -m impact --load rock --wob 7``.

Run it with ``python results/examples/ex08_drilling.py`` (a few seconds; ``--fast``: three
free masses, a 10 % interval target).
"""

import sys
from pathlib import Path

from impact.drilling import DrillParams, DrillSettings, DrillSweep, drilling_statistics, drilling_sweep
from impact.drilling_plots import plot_depth_vs_mass
from rpud_common import save_figure

fast = "--fast" in sys.argv
out = Path("example_output")
out.mkdir(exist_ok=True)

# The article's drilling experiment: 19.95 kHz, A0 = 15 um (Table 1), WOB 7 N, a 0.59 kg drill,
# the sandstone defaults of the rock law; statistics over 20-220 ms of each member, the depth
# after 300 s = rate x 300 s.
params = DrillParams(wob=7.0)
settings = DrillSettings(rel_tol=0.10 if fast else 0.05)
masses = (0.0, 0.002, 0.008) if fast else (0.0, 0.002, 0.004, 0.006, 0.008)      # kg
print(f"rock law: {params.rock}")

rows = drilling_sweep(params, masses, settings)
print(f"{'free mass':>9s}  {'blows (Hz)':>14s}  {'penetration/blow (um)':>22s}  {'rate (mm/min)':>14s}  "
      f"{'depth after 300 s (mm)':>22s}  members")
for r in rows:
    print(f"{r.m_free * 1e3:7g} g  {str(r['blow_rate_hz']):>14s}  {str(r['penetration_per_blow_m'].scaled(1e6)):>22s}  "
          f"{str(r['drilling_rate_m_s'].scaled(6e4)):>14s}  {str(r.depth_m.scaled(1e3)):>22s}  {r.members}")

# %%
# The depth against the free mass (95 % CI bars).
sweep = DrillSweep(rows=rows, params=params)
save_figure(plot_depth_vs_mass(sweep), out / "depth_vs_free_mass.png")

# %%
# How far one uncalibrated constant moves the answer: the crushing threshold doubled, 8 g.
hard = params.with_(rock=params.rock.with_(f_threshold=2 * params.rock.f_threshold))
harder = drilling_statistics(hard, settings, m_free=0.008)
print(f"8 g, F_th {params.rock.f_threshold:g} N: depth {rows[-1].depth_m.scaled(1e3)} mm; "
      f"F_th {hard.rock.f_threshold:g} N: depth {harder.depth_m.scaled(1e3)} mm")

"""Modes of the default drill
===========================

Example 1: the modes of the default drill, and a picture of its working mode.

The default design is the article's drill (Table 1): percussive horn, four PZT-8 rings and the
V-type coupler. Gmsh meshes it with tagged volumes and surfaces, ``fem.assemble`` builds the
coupled piezo-elastic system (P2 displacement, P2 potential), and ``fem.modal_analysis``
returns the short-circuit resonances f_r, the open-circuit anti-resonances f_a and the
effective coupling factor of every mode near the target frequency.

Run it with ``python results/examples/ex01_modal.py`` (about 15 s); ``--fast`` uses a coarse
mesh (the test suite runs every example that way).
"""

import sys
from pathlib import Path

import fem
import geometry

fast = "--fast" in sys.argv
out = Path("example_output")

design = geometry.default_design()                       # SI units: m, Hz
mesh = geometry.build_mesh(design, mesh_size=0.008 if fast else None)
system = fem.assemble(mesh)
modes = fem.modal_analysis(system, near_hz=design.target_frequency, n_modes=8 if fast else 12)
print(modes)                                             # band, nearest mode, DOF

# The working mode is the longitudinal one nearest the target (the largest axial
# kinetic-energy share), not simply the nearest frequency.
w = modes.working
print(f"working mode {w}: {modes.labels[w]}, f_r = {modes.f_r_hz[w]:.1f} Hz, "
      f"f_a = {modes.f_a_hz[w]:.1f} Hz, k_eff = {modes.k_eff[w]:.3f}")

# Off-screen picture of the mode (colour: displacement magnitude), the whole record as
# JSON + NPZ (frequencies and mode shapes), and every mode for ParaView.
fem.render_mode(mesh, modes.shapes[w], out / "working_mode.png",
                title=f"Mode {w} - {modes.f_r_hz[w] / 1e3:.3f} kHz - {modes.labels[w]}")
modes.save(out)
fem.write_modes_vtu(mesh, modes.shapes, out / "modes.vtu", frequencies=modes.f_r_hz)
print(f"written: {sorted(p.name for p in out.iterdir())}")

"""Your own transducer from a design file
=======================================

Example 2: your own transducer from a design file, its modes and its admittance.

A design is a TOML file (SI units: m, Hz; materials by name from the library in
``geometry/materials.toml``). Here a half-wave Langevin sandwich: two steel cylinders clamping
two PZT-8 rings poled against each other, the middle electrode hot, the outer ones grounded.
The same file works on the command line: ``python -m geometry --design langevin.toml --png l.png``
and ``python -m fem.modal --design langevin.toml``.

Run it with ``python results/examples/ex02_own_design.py`` (``--fast``: coarse mesh).
"""

import sys
from pathlib import Path

import numpy as np

import fem
import geometry
from rpud_common import save_figure

fast = "--fast" in sys.argv
out = Path("example_output")
out.mkdir(exist_ok=True)

DESIGN = """
kind = "stack"
name = "my_langevin"
target_frequency = 25000.0
electrodes = [
    { name = "electrode_0", segment = "ring_1", face = "bottom", role = "ground" },
    { name = "electrode_1", segment = "ring_1", face = "top", role = "hot" },
    { name = "electrode_2", segment = "ring_2", face = "top", role = "ground" },
]
segments = [
    { name = "back", length = 0.04, material = "steel_45", outer_diameter = 0.03 },
    { name = "ring_1", length = 0.005, material = "PZT-8", outer_diameter = 0.03, poling = "-z", part = "stack" },
    { name = "ring_2", length = 0.005, material = "PZT-8", outer_diameter = 0.03, poling = "+z", part = "stack" },
    { name = "front", length = 0.04, material = "steel_45", outer_diameter = 0.03 },
]
"""
(out / "langevin.toml").write_text(DESIGN)

# Loading validates every field: a bad value is a ParameterError that names the field, the
# value and what is allowed.
design = geometry.load_design(out / "langevin.toml")
print(f"{design.name}: {design.total_mass() * 1e3:.1f} g, parts {sorted(design.part_volumes())}")

mesh = geometry.build_mesh(design, mesh_size=0.006 if fast else None)
system = fem.assemble(mesh)
modes = fem.modal_analysis(system, near_hz=design.target_frequency, n_modes=6)
w = modes.working
print(modes)
print(f"longitudinal mode: f_r = {modes.f_r_hz[w]:.1f} Hz, f_a = {modes.f_a_hz[w]:.1f} Hz, "
      f"k_eff = {modes.k_eff[w]:.3f}")

# Admittance over the resonance / anti-resonance band by modal superposition (Q_m = 500 on
# every part), the tip amplitude at resonance per volt, and the figure.
f_r, f_a = modes.f_r_hz[w], modes.f_a_hz[w]
band = np.linspace(0.97 * f_r, 1.03 * f_a, 41 if fast else 301)
loss = fem.LossModel(q_mech=500.0)
sweep = fem.harmonic_sweep(system, band, voltage=1.0, loss=loss, surfaces=("top",))   # "top": the front face
print(sweep)
print(f"|Y| peak at {sweep.f_r_hz:.1f} Hz and dip at {sweep.f_a_hz:.1f} Hz "
      f"(modal: {f_r:.1f} / {f_a:.1f} Hz)")
save_figure(fem.plot_admittance(sweep, f_r, f_a), out / "langevin_admittance.png")

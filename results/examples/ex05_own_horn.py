"""Your own horn
=============

Example 5: the drill with a longer horn, written to a design file, meshed, and its working
resonance compared with the default drill's.

A ``kind = "rpud"`` design is the article's drill composition (coupler, piezo rings, flange,
horn); every field has a default, so a design file needs only what differs. Here the horn is
10 mm longer than the default one (the stepped profile keeps its step at half the length). A
longer horn lowers the working resonance: the default horn and coupler lengths are the ones
resonance matching (``fem.match``, ``python -m fem.modal --match``) tuned to the 20 kHz target,
and a changed horn is off that target until it is matched again.

The file written here works on the command line as well:
``python -m fem.modal --design example_output/longer_horn.toml``.

Run it with ``python results/examples/ex05_own_horn.py`` (about half a minute; ``--fast``: coarse
meshes).
"""

import dataclasses
import sys
from pathlib import Path

import fem
import geometry

fast = "--fast" in sys.argv
out = Path("example_output")
out.mkdir(exist_ok=True)

# %%
# The design: a copy of the default with another horn (frozen dataclasses; the constructor
# validates the new values), saved as TOML and read back as any design file is.
base = geometry.default_design()
LONGER = 0.010                                          # m
horn = dataclasses.replace(base.horn, length=base.horn.length + LONGER)
mine = dataclasses.replace(base, name="longer_horn", horn=horn)
mine.save(out / "longer_horn.toml")
design = geometry.load_design(out / "longer_horn.toml")
assert design == mine                                   # the file holds the whole design
toml = (out / "longer_horn.toml").read_text()
print(toml[toml.index("[horn]"):toml.index("[stack]")])

# %%
# Both drills on the same mesh rule, and the working (longitudinal) mode of each.
mesh_size = 0.008 if fast else None                     # m; None: the design's own rule
working = {}
for d in (base, design):
    mesh = geometry.build_mesh(d, mesh_size=mesh_size)
    modes = fem.modal_analysis(fem.assemble(mesh), near_hz=d.target_frequency, n_modes=8)
    w = modes.working
    working[d.name] = modes.f_r_hz[w]
    print(f"{d.name:14s} horn {d.horn.length * 1e3:.1f} mm: working mode {w} ({modes.labels[w]}), "
          f"f_r = {modes.f_r_hz[w]:.1f} Hz, k_eff = {modes.k_eff[w]:.3f}")

shift = working["longer_horn"] - working[base.name]
print(f"f_r shift from the {LONGER * 1e3:g} mm longer horn: {shift:.1f} Hz ({100 * shift / working[base.name]:.2f} %)")

# %%
# The working mode of the longer-horn drill (colour: displacement magnitude over its maximum).
fem.render_mode(mesh, modes.shapes[w], out / "longer_horn_mode.png",
                title=f"longer horn - {modes.f_r_hz[w] / 1e3:.3f} kHz - {modes.labels[w]}")

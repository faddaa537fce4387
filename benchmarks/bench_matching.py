"""Resonance matching of the default design (python -m fem.modal --match), side by side:

* from the default start (the default design is its own matched design: a check that the
  converged state is found again), and from a start 10 % off on both tuned lengths;
* per iteration: our morph-and-reassemble step against the baseline that re-meshes the design
  at every iteration (measured once, same design, same solver).

Target: under 60 s on 2 cores from the default start."""

import time

from _table import print_table

import geometry
from fem.assembly import assemble
from fem.matching import MatchSettings, _modes, match


def _iteration_remesh(design):
    t0 = time.perf_counter()
    mesh = geometry.build_mesh(design)
    sy = assemble(mesh)
    _modes(sy, sy.free_dofs("short"), 20e3, 4)
    return time.perf_counter() - t0


def main():
    d = geometry.default_design()
    rows = []
    for label, start in (("default start", d),
                         ("start 10 % long", d.replace({"horn.length": d.horn.length * 1.1,
                                                        "coupler.length": d.coupler.length * 1.1}))):
        t0 = time.perf_counter()
        r = match(start, MatchSettings())
        wall = time.perf_counter() - t0
        n = len(r.iterations)
        rows.append((f"match, {label}", f"{wall:.1f} s", f"{n} iterations, {r.matched_hz:.2f} Hz, "
                     f"horn {r.tuned['horn.length'] * 1e3:.3f} mm, coupler {r.tuned['coupler.length'] * 1e3:.3f} mm, "
                     f"{r.system.ndof} DOFs"))
        if label == "default start":
            per_it = (r.timings["horn_side_s"] + r.timings["whole_s"]) / max(n, 1)
    t_remesh = _iteration_remesh(d)
    rows.append(("one iteration: morph + assemble + 4 modes (mean)", f"{per_it:.2f} s", "this code (half model or whole)"))
    rows.append(("one iteration: re-mesh + assemble + 4 modes (whole)", f"{t_remesh:.2f} s", "baseline"))
    print_table(rows)


if __name__ == "__main__":
    main()

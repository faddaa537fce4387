"""The stress options of ``python -m fem.harmonic`` (``--stress DIR``, ``--preload N``,
``--stress-points N``): parsing checks, the run, printing and files. Physics in
:mod:`fem.stress`, :mod:`fem.stress_table`, :mod:`fem.preload`, :mod:`fem.stress_output`."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rpud_common import ParameterError, check_integer, check_range

__all__ = ["add_stress_options", "check_stress_options", "coarse_hook", "run_stress"]

MAX_PRELOAD = 1e6
"""Largest bolt preload accepted, N (a 100 t press: far beyond any transducer bolt)."""

STRESS_POINTS = 21
"""Default number of frequencies of the stress peaks along the band."""


def add_stress_options(p) -> None:
    p.add_argument("--stress", metavar="DIR",
                   help="stress and limits at the working point: print the utilisation table (peak von Mises per "
                        "metal region, largest tensile / compressive principal stress and peak |E| per ceramic "
                        "region, locations, limits from the material records) and write DIR/stress.png, "
                        "DIR/stress.vtu, DIR/stress.json and the peaks along the band (DIR/stress_sweep.png)")
    p.add_argument("--preload", type=float, default=None, metavar="N",
                   help="bolt preload on the stack, N (>= 0; default: the design's bolt, stack.bolt_prestress "
                        "times the ring area): its static stress is added to the dynamic one before the peaks are "
                        "taken, and the preload window of every ring is printed (needs --stress)")
    p.add_argument("--stress-points", type=int, default=None, metavar="N",
                   help=f"frequencies of the stress peaks along the band, plus the working frequency (default "
                        f"{STRESS_POINTS}; 0: working point only; needs --stress)")


def check_stress_options(args) -> None:
    """Before any meshing: finite, non-negative preload, options given only with ``--stress``;
    then the defaults of the options not given (``args.preload`` None: the design's bolt,
    ``args.stress_points`` :data:`STRESS_POINTS`)."""
    pre = args.preload
    if pre is not None:
        if not (isinstance(pre, (int, float)) and math.isfinite(pre)) or pre < 0:
            raise ParameterError("--preload", pre, "must be a finite force >= 0 N")
        check_range("--preload", pre, 0.0, MAX_PRELOAD, "N")
    if args.stress_points is not None:
        check_integer("--stress-points", args.stress_points, 0, 400)
    if args.stress is None:
        for opt, value in (("--preload", pre), ("--stress-points", args.stress_points)):
            if value is not None:
                raise ParameterError(opt, value, "needs --stress DIR")
    args.stress_points = STRESS_POINTS if args.stress_points is None else args.stress_points


def coarse_hook(args, design, wp):
    """Sets ``args.preload`` (None: the design's bolt) and returns the hook that gives the
    utilisation table its two-mesh estimate (:class:`fem.stress_converged.CoarseTable`, run by
    the discretisation-error estimate on its coarser mesh), or None where that estimate does not
    apply: a drive frequency or mode of the user's (the coarse mesh is compared at its own f_r)
    or ``--refine`` above 3.5 (no coarser mesh in range)."""
    from .preload import design_preload
    from .stress_converged import CoarseTable

    if args.preload is None:
        args.preload = design_preload(design)
    if args.freq is not None or args.mode is not None or args.refine * 1.4 > 5.0:
        return None
    return CoarseTable(float(wp.voltage), float(args.preload))


def run_stress(args, system, basis, wp, band, est=None, mesh: str | None = None) -> dict:
    """Compute, print and write the stress results; returns their JSON record. ``est``: the
    discretisation-error estimate run with :func:`coarse_hook` (its coarse table gives every
    row a two-mesh estimate; None: the single-mesh one, said in the note); ``mesh``: the mesh
    that ran, in words (printed and written). The table is :func:`fem.stress_state.working_point_stress`'s,
    the pipeline's; the files show the whole drill."""
    from rpud_common import atomic_write_text, json_text

    from .preload import preload_solve, preload_windows, window_lines
    from .stress_state import working_point_stress

    out = Path(args.stress)
    pre = preload_solve(system, args.preload) if args.preload > 0 else None
    res = working_point_stress(system, wp, pre, est, mesh)
    win = preload_windows(system, wp.x, wp.voltage, wp.tip_amplitude_m, args.preload, recovery=res.recovery,
                          unit_state=pre)
    table = res.table
    state = f"{wp.voltage:g} V at {wp.freq_hz:.1f} Hz" + (f" + bolt preload {args.preload:g} N on "
                                                           f"{pre.faces[0]}/{pre.faces[1]}" if pre else "")
    print(f"stress, peaks over one cycle ({state}; mesh: {res.mesh}) (rows marked * peak on a singular edge: "
          "their utilisation is the off-edge peak's)")
    print(table.text())
    print(table.note)
    print(f"preload window per ring at {wp.voltage:.4g} V amplitude (least preload keeping the ring's mean stress "
          "compressive over the cycle .. most within the rated compressive stress):")
    print("\n".join(window_lines(win)))
    sweep = _band_sweep(args, system, basis, wp, band, res) if args.stress_points else None
    out.mkdir(exist_ok=True)
    res.write_files(out / "stress.png", out / "stress.vtu", state)
    if sweep is not None:
        _sweep_figure(sweep, wp.voltage, out / "stress_sweep.png")
    w = table.worst()
    data = {"mesh": res.mesh, "working_point": table.to_dict(), "sweep": sweep.to_dict() if sweep is not None else None,
            "preload": None if pre is None else {"force_n": pre.force_n, "faces": list(pre.faces),
                                                 "areas_m2": list(pre.areas_m2)},
            "worst": None if w is None else w.record(), "preload_window": win.record()}
    atomic_write_text(out / "stress.json", json_text(data, nonfinite="null"))
    return data


def _band_sweep(args, system, basis, wp, band, res):
    """The table's headlines along the band's grid and the working frequency (a coarse grid
    may straddle the resonance), printed: their highest utilisation."""
    from .stress_table import stress_sweep

    freqs = np.union1d(np.linspace(band[0], band[1], args.stress_points), [wp.freq_hz])
    sweep = stress_sweep(system, basis, freqs, wp.voltage, static=res.static, preload_n=res.preload_n,
                         recovery=res.recovery)
    worst = sweep.worst_utilisation()
    if worst is not None:
        print(f"along the band ({len(freqs)} frequencies, {band[0]:.0f}-{band[1]:.0f} Hz): highest "
              f"utilisation {100 * worst[2]:.1f} % ({worst[0]}) at {worst[1]:.1f} Hz")
    return sweep


def _sweep_figure(sweep, voltage: float, path: Path) -> None:
    """Utilisation of each rated stress row along the band (PNG)."""
    from rpud_common import save_figure, subplots

    from .stress_table import QUANTITIES

    _fig, ax = subplots(1, 1, figsize=(7, 4))
    for (region, q), vals in sweep.peaks.items():
        lim = sweep.limits.get((region, q))
        if lim is None or q == "efield":
            continue
        v = -vals if q == "principal_min" else vals
        ax.plot(sweep.freqs_hz / 1e3, 100 * np.maximum(v, 0) / lim, label=f"{region} {QUANTITIES[q][0]}")
    ax.set_xlabel("frequency (kHz)")
    ax.set_ylabel("utilisation (%)")
    ax.set_title(f"stress peaks along the band at {voltage:g} V")
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    save_figure(ax, path)

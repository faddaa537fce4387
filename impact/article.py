"""Reproduce the article's section 4 figures: Fig. 6 (50 ms), Fig. 7 (20 ms), Fig. 8 (tool
kinetic energy against free-mass weight 2-8 g) and the free-mass spectrum (Fig. 12 analogue).

Figs. 6 and 7 show one trajectory: in a chaotic system that is one sample, and the figure says
so. Every number in the summary is an ensemble mean with its 95 % confidence interval in the
article scenario (first 50 ms, no restoring spring, see :mod:`impact.stats`). The spectrum
(Fig. 12) was measured on the running drill, so it comes from one long sample trajectory of the
device scenario (restoring spring, steady operation).
"""

from __future__ import annotations

import logging
from pathlib import Path

from rpud_common import save_figure, write_json
from rpud_common.figures import subplots

from .model import simulate
from .params import ImpactParams
from .plots import plot_history, plot_ke_vs_mass, plot_spectrum, plot_tool_ke_history
from .stats import SCENARIOS, StatsSettings, ensemble_statistics
from .sweeps import sweep

__all__ = ["reproduce", "MASSES"]

log = logging.getLogger(__name__)

MASSES = (0.002, 0.004, 0.006, 0.008)
"""Free masses of the article's Fig. 8, kg."""


def reproduce(out_dir, params: ImpactParams | None = None, *, settings: StatsSettings | None = None,
              spectrum_t_end: float = 1.0, progress=None) -> dict:
    """Make the article's figures and a JSON summary in ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Output folder (created).
    params : ImpactParams, optional
        Base case (Table 1 + calibrated defaults); ``A0``/``freq`` may come from the FE model.
    settings : StatsSettings, optional
        Ensemble rule (default: 95 % CIs within 3 %).
    spectrum_t_end : float
        Length of the device-scenario sample trajectory behind the spectrum, s.

    Returns
    -------
    dict
        The summary written to ``out_dir/impact_summary.json``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    p = params if params is not None else ImpactParams()
    art = SCENARIOS["article"]
    st8 = ensemble_statistics(p, art, settings, progress)
    sample = simulate(art.apply(p))
    note = "one sample trajectory (chaotic); statistics in impact_summary.json"
    save_figure(plot_history(sample, 0.05, title=f"First 50 ms: {note}"), out / "fig6_displacement_50ms.png")
    save_figure(plot_history(sample, 0.02, title=f"First 20 ms: {note}"), out / "fig7_displacement_20ms.png")
    dev = SCENARIOS["device"]
    long_run = simulate(dev.apply(p).with_(t_end=spectrum_t_end))
    save_figure(plot_spectrum(long_run), out / "fig12_free_mass_spectrum.png")
    sw = sweep(p, MASSES, scenario=art, settings=settings, progress=progress)
    hist = {m: simulate(art.apply(p).with_(m_free=m), series=False) for m in MASSES}
    fig, (left, right) = subplots(1, 2, figsize=(12, 4.5), dpi=120)
    plot_tool_ke_history(hist, ax=left)
    plot_ke_vs_mass(sw, ax=right)
    save_figure(fig, out / "fig8_tool_ke_vs_free_mass.png")
    f, amp = long_run.spectrum()
    band = (f > 0) & (f <= 2000)
    summary = {
        "params": p.to_dict(),
        "article_8g": st8.to_dict() | {"m_free_kg": p.m_free},
        "sample_50ms": {"note": note, **sample.summary()},
        "spectrum_device_sample": {"t_end_s": spectrum_t_end, "spring_force_n": dev.spring_force,
                                   "peak_hz": float(f[band][amp[band].argmax()]),
                                   "max_free_mass_displacement_m": float(long_run.w.max())},
        "fig8": sw.to_dict(),
        "figures": sorted(x.name for x in out.glob("fig*.png")),
    }
    write_json(out / "impact_summary.json", summary)
    log.info("article figures written to %s", out)
    return summary

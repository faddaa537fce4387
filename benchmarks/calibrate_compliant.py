"""Calibration of the gap L0 under the compliant-contact model, against the article's one dynamic
figure: "the average collision frequency of the free mass is about 520 Hz" (section 4, 8 g free
mass, first 50 ms), as benchmarks/calibrate_impact.py does for the kinematic horn.

The model is the compliant stage's (results.stage_compliant): the default drill's axial modes to
2 / t_c with the static residual, Hertz contacts at tip and tool. The article scenario assumes a
15 um horn amplitude: the drive voltage is scaled so that the FE horn's steady tip amplitude at the
working resonance is 15 um. The statistic is the ensemble mean tool-contact rate over the first
50 ms (no spring) with its 95 % CI. The kinematic calibration found the gap to set the rate and the
tool's f_n, zeta and v0 to move it by less than the CIs; they keep its values (k0 1.8e5 N/m, c 38
N s/m, v0 4 m/s). The gap is scanned on a 0.1 mm grid with 64 members per point, the rate
interpolated linearly to 520 Hz between the two points that bracket it, rounded to 0.01 mm and
confirmed with CIs within 3 %. When no gap of the scan brackets 520 Hz, the tool's natural
frequency (200-600 Hz, damping ratio kept) and the launch speed (4, 8 m/s) are scanned at the
kinematic gap instead, and nothing is chosen.

Measured on the default drill (modes to 122 kHz, 32 modes, 145.5 V for 15 um): the rate is
105-161 Hz over gaps 1.5-2.6 mm and 113-169 Hz over f_n 200-600 Hz and v0 4-8 m/s (64 members,
CIs about +-10 Hz): the compliant model does not reach 520 Hz with these unknowns. The likely
reason: the tip the free mass meets has an effective mass of 4 g at this cut-off, below the 8 g
free mass, and cannot throw it back as fast as the kinematic horn (an infinite mass) does; the
article's 520 Hz rests on its assumption 1. The compliant stage therefore inherits the kinematic calibration's
gap, k0, c and v0 and says so (results.stage_compliant).

    PYTHONPATH=. python benchmarks/calibrate_compliant.py      # ~50 s CPU (~4-8 min wall on a loaded machine)
"""

import time

import numpy as np


def main():
    import geometry
    from fem.matching import working_mode
    from fem.sector_system import axial_sector
    from impact.compliant_engine import compliant_batch
    from impact.params import ImpactParams
    from impact.stats import StatsSettings
    from results.coupled import wideband_horn, wideband_modes
    from results.stage_compliant import CompliantSettings, contact_laws, shortest_contact_time

    t0 = time.process_time()
    design = geometry.default_design()
    system = axial_sector(design)
    settings = CompliantSettings()
    base = ImpactParams()
    t_c = shortest_contact_time(design, [0.001, 0.008], base, settings)
    cut = round(settings.cutoff_factors[-1] / t_c, -2)
    modes = wideband_modes(system, cut)
    f = float(np.round(modes.f_r_hz[working_mode(system, modes.f_r_hz, modes.vectors,
                                                  float(design.target_frequency))], 1))
    horn, g, _ = wideband_horn(system, f, cut, 225.0, modes=modes)
    horn = horn.with_(voltage=225.0 * 15e-6 / abs(horn.steady_tip(f)))
    laws = contact_laws(design, 0.008, base.e2, base.e1, settings)[:2]
    print(f"FE: modes to {cut / 1e3:.0f} kHz ({horn.n_modes}), drive {f:.1f} Hz at {horn.voltage:.2f} V "
          f"(tip {abs(horn.steady_tip(f)) * 1e6:.3f} um); {time.process_time() - t0:.1f} s CPU")

    def rates(gaps, st):
        cases = [base.with_(gap=gp, freq=f) for gp in gaps]
        return compliant_batch(cases, horn, horn_law=laws[0], tool_law=laws[1], horn_residual=g,
                               scenario="article", settings=st)

    gaps = [round(1.5e-3 + 0.1e-3 * k, 6) for k in range(12)]
    scan = rates(gaps, StatsSettings(n_start=64, n_max=64))
    print("\n| gap (mm) | tool-contact rate, first 50 ms, 8 g (Hz, 95 % CI) |\n|---|---|")
    r = [s["tool_impact_rate_hz"].mean for s in scan]
    for gp, s in zip(gaps, scan):
        print(f"| {gp * 1e3:.1f} | {s['tool_impact_rate_hz']} |")
    i = next((k for k in range(len(gaps) - 1) if (r[k] - 520.0) * (r[k + 1] - 520.0) <= 0), None)
    if i is None:
        print("\n520 Hz not bracketed by the gap: the tool's f_n and the launch speed at the kinematic gap")
        pts = [(fn, v0) for fn in (200.0, 300.0, 600.0) for v0 in (4.0, 8.0)]
        def tool(fn):
            k0 = float(f"{base.m_tool * (2 * np.pi * fn) ** 2:.3g}")
            return {"k0": k0, "c": float(f"{2 * base.tool_zeta * np.sqrt(k0 * base.m_tool):.3g}")}

        cases = [base.with_(**tool(fn), v0=v0, freq=f) for fn, v0 in pts]
        other = compliant_batch(cases, horn, horn_law=laws[0], tool_law=laws[1], horn_residual=g, scenario="article",
                                settings=StatsSettings(n_start=64, n_max=64))
        print(f"\n| tool f_n (Hz), zeta {base.tool_zeta:.2f} kept | v0 (m/s) | rate (Hz, 95 % CI) |\n|---|---|---|")
        for (fn, v0), s in zip(pts, other):
            print(f"| {fn:g} | {v0:g} | {s['tool_impact_rate_hz']} |")
        print(f"total {time.process_time() - t0:.1f} s CPU")
        return
    gap = round(gaps[i] + (520.0 - r[i]) * (gaps[i + 1] - gaps[i]) / (r[i + 1] - r[i]), 5)
    final = rates([gap], StatsSettings())[0]
    print(f"\nchosen: gap {gap * 1e3:.2f} mm (k0 {base.k0:g} N/m, c {base.c:g} N s/m, v0 {base.v0:g} m/s kept)")
    print(f"confirmed: {final['tool_impact_rate_hz']} Hz ({final.members} members, converged {final.converged})")
    print(f"total {time.process_time() - t0:.1f} s CPU")


if __name__ == "__main__":
    main()

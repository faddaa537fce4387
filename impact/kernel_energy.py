"""Closed-form energy integrals of the coupled model's segments, compiled (numba).

Between events every modal coordinate is a damped oscillation under the harmonic drive, so the
window integrals of :func:`impact.kernel_modal.ensemble_coupled` (drive work, damping loss, the
tip's fundamental, electrical energy; with a series-resistance drive the source's work and loss)
are sums of exponential integrals ``int_0^S exp(lam s) ds`` over each segment: the compiled
counterparts of :func:`impact.horn.segment_integrals` and :mod:`impact.drive`.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit

from .columns import C_DAMP, C_DRIVE, C_ELEC, C_FUND_IM, C_FUND_RE, C_SOURCE_LOSS
from .horn import H_A, H_B, H_FC, H_FS, H_GIM, H_GRE, H_MASS, H_OMEGA, H_TIP, H_ZETA, X_QBI, X_QBR, X_SERIES, X_UC, X_US, X_V0, X_W

__all__ = ["expint", "segment_energy", "segment_energy_series", "window_integrals"]


@njit(cache=True)
def expint(lam, S):
    """int_0^S exp(lam s) ds (complex lam), as impact.horn._expint."""
    z = lam * S
    if abs(z) < 1e-6:
        return S * (1.0 + z / 2.0 + z * z / 6.0)
    x, y = z.real, z.imag
    em1 = complex(math.expm1(x) * math.cos(y) - 2.0 * math.sin(0.5 * y) ** 2, math.exp(x) * math.sin(y))
    return em1 / lam


@njit(cache=True)
def _expint_e(lam, S, e):
    """expint(lam, S) given e = exp(lam S): (e - 1) / lam when |lam S| >= 0.5 (no cancellation
    there), else the cancellation-free form."""
    if abs(lam * S) >= 0.5:
        return (e - 1.0) / lam
    return expint(lam, S)


@njit(cache=True)
def segment_energy(tab, xs, n, t0, q, qd, sa, sb):
    """(drive work, damping loss, fundamental, electrical energy) over [t0 + sa, t0 + sb] of a free
    segment: the integrals of impact.horn.segment_integrals, with the exponential integrals shared
    between the products (per mode E(jW + mu), E(mu - jW), E(2 mu), E(2 Re mu); E(jW + conj mu) =
    conj E(mu - jW) and E(conj mu - jW) = conj E(mu + jW))."""
    W = xs[X_W]
    jw = 1j * W
    S = sb - sa
    ta = t0 + sa
    ewa = cmath.exp(jw * ta)
    eW = cmath.exp(jw * S)
    E2w = _expint_e(2.0 * jw, S, eW * eW)
    drive = 0.0
    damp = 0.0
    U = complex(xs[X_UC], -xs[X_US])
    Uc = U * ewa
    fund = 0.5 * (Uc * S + Uc.conjugate() * E2w.conjugate())
    e0 = cmath.exp(jw * t0)
    V0 = xs[X_V0]
    Vc = -1j * V0 * ewa
    tb = ta + S
    elec = xs[X_QBR] * 0.5 * V0 * V0 * (math.sin(W * tb) ** 2 - math.sin(W * ta) ** 2)
    elec -= xs[X_QBI] * W * V0 * V0 * (0.5 * S - (math.sin(2.0 * W * tb) - math.sin(2.0 * W * ta)) / (4.0 * W))
    for i in range(n):
        om, ze, m = tab[i, H_OMEGA], tab[i, H_ZETA], tab[i, H_MASS]
        qs = complex(tab[i, H_A], -tab[i, H_B])
        mu = complex(-ze * om, om * math.sqrt(1.0 - ze * ze))
        h0 = q[i] - (qs * e0).real
        hd0 = qd[i] - (jw * qs * e0).real
        C = complex(h0, -(hd0 - h0 * mu.real) / mu.imag) * cmath.exp(mu * sa)
        eM = cmath.exp(mu * S)
        Ep = _expint_e(jw + mu, S, eM * eW)
        Em = _expint_e(mu - jw, S, eM * eW.conjugate())
        E2m = _expint_e(2.0 * mu, S, eM * eM)
        E2r = _expint_e(complex(2.0 * mu.real, 0.0), S, complex(abs(eM) ** 2, 0.0))
        cEm = Em.conjugate()
        G = jw * qs * ewa
        H = C * mu
        F = complex(tab[i, H_FC], -tab[i, H_FS]) * ewa
        # int Re(A e^{la s}) Re(B e^{lb s}) ds = Re(A B E(la + lb)) / 2 + Re(A conj(B) E(la + conj lb)) / 2
        drive += 0.5 * ((F * G * E2w).real + (F * G.conjugate()).real * S + (F * H * Ep).real
                        + (F * H.conjugate() * cEm).real)
        gg = 0.5 * ((G * G * E2w).real + (G * G.conjugate()).real * S)
        gh = 0.5 * ((G * H * Ep).real + (G * H.conjugate() * cEm).real)
        hh = 0.5 * ((H * H * E2m).real + (H * H.conjugate() * E2r).real)
        damp += 2.0 * ze * om * m * (gg + 2.0 * gh + hh)
        G2 = jw * G
        H2 = mu * H
        vq1 = 0.5 * ((Vc * G * E2w).real + (Vc * G.conjugate()).real * S + (Vc * H * Ep).real
                     + (Vc * H.conjugate() * cEm).real)
        vq2 = 0.5 * ((Vc * G2 * E2w).real + (Vc * G2.conjugate()).real * S + (Vc * H2 * Ep).real
                     + (Vc * H2.conjugate() * cEm).real)
        elec += tab[i, H_GRE] * vq1 + tab[i, H_GIM] / W * vq2
        Ct = C * tab[i, H_TIP]
        fund += 0.5 * (Ct * Em + Ct.conjugate() * Ep.conjugate())
    fund = fund * cmath.exp(-jw * ta)
    return drive, damp, fund, elec


@njit(cache=True)
def segment_energy_series(tab, xs, n, t0, q, qd, sa, sb, lam, G1, G2, cw):
    """(source work, resistor + dielectric loss, conversion to mechanics, modal damping, fundamental)
    over [t0 + sa, t0 + sb] of a free segment of a series-resistance drive (:mod:`impact.drive`).

    Over the segment the augmented state is ``Re(sum_j C_j w_j e^{lam_j s})`` (the pseudo-modes, then
    the steady state with ``lam = jW``), so ``int xt^T Q xt ds = sum_jl Re(C_j C_l G1_jl E(lam_j +
    lam_l)) / 2 + Re(C_j conj(C_l) G2_jl E(lam_j + conj lam_l)) / 2``; the (j, l) and (l, j) terms
    are equal, so only l >= j is summed. ``cw`` is work space (n + 1,) complex."""
    W = xs[X_W]
    jw = 1j * W
    S = sb - sa
    ta = t0 + sa
    e0 = cmath.exp(jw * t0)
    for k in range(n):
        P = complex(tab[k, H_A], -tab[k, H_B])
        h0 = q[k] - (P * e0).real
        hd0 = qd[k] - (jw * P * e0).real
        lk = lam[k]
        if lk.imag != 0.0:
            C = complex(h0, -(hd0 - h0 * lk.real) / lk.imag)
        else:
            C = complex(h0, 0.0)
        cw[k] = C * cmath.exp(lk * sa)
    ewa = cmath.exp(jw * ta)
    cw[n] = ewa
    acc = np.zeros(4)
    for j in range(n + 1):
        for l in range(j, n + 1):
            f = 0.5 if l == j else 1.0
            x1 = cw[j] * cw[l] * expint(lam[j] + lam[l], S)
            x2 = cw[j] * cw[l].conjugate() * expint(lam[j] + lam[l].conjugate(), S)
            for a in range(4):
                acc[a] += f * ((G1[a, j, l] * x1).real + (G2[a, j, l] * x2).real)
    U = complex(xs[X_UC], -xs[X_US]) * ewa
    fund = 0.5 * (U * S + U.conjugate() * expint(2.0 * jw, S).conjugate())
    for k in range(n):
        Ct = cw[k] * tab[k, H_TIP]
        fund += 0.5 * (Ct * expint(lam[k] - jw, S) + Ct.conjugate() * expint(lam[k].conjugate() - jw, S))
    fund = fund * cmath.exp(-jw * ta)
    return acc[0], acc[1], acc[2], acc[3], fund


@njit(cache=True)
def window_integrals(tab, xs, n, t0, t1, q, qd, t_from, t_end, stats, lam, G1, G2, cw):
    """Add the part of the segment [t0, t1] (s) inside the window [t_from, t_end] to the ``C_*``
    columns of ``stats``: the segment starts from the modal state (q, qd) at t0."""
    lo = max(t0, t_from)
    hi = min(t1, t_end)
    if hi > lo:
        if xs[X_SERIES] == 1.0:
            src, loss, conv, dm, f = segment_energy_series(tab, xs, n, t0, q, qd, lo - t0, hi - t0, lam, G1, G2, cw)
            stats[C_ELEC] += src
            stats[C_SOURCE_LOSS] += loss
            stats[C_DRIVE] += conv
            stats[C_DAMP] += dm
        else:
            d, dm, f, el = segment_energy(tab, xs, n, t0, q, qd, lo - t0, hi - t0)
            stats[C_ELEC] += el
            stats[C_DRIVE] += d
            stats[C_DAMP] += dm
        stats[C_FUND_RE] += f.real
        stats[C_FUND_IM] += f.imag


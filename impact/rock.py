"""Bit-rock contact law of percussive drilling, at the bit end of an elastic rod (SI units).

Law (bilinear force-penetration with a crushing threshold)
----------------------------------------------------------
The form is Lundberg's bit-rock model of percussive drilling (B. Lundberg, "Microcomputer
simulation of stress wave energy transfer to rock in percussive drilling", Int. J. Rock Mech.
Min. Sci. 19 (1982) 229-239; also Lundberg & Okrouhlik, same journal 43 (2006)): the force
grows with the penetration along a *loading* slope ``k_load`` and falls back along a steeper
*unloading* slope ``k_unload``, so each blow leaves a permanent penetration. The JPL USDC model
(Bao et al., IEEE UFFC 50 (2003) 1147-1160) adds that no crater forms below a *threshold*
force. Here, with ``e = d - p`` the elastic penetration (d: bit penetration below the original
surface, p: permanent penetration, the crater floor):

* ``e <= 0``: no contact, F = 0;
* ``0 < e <= e_th = F_th / k_load``: elastic, ``F = k_load e`` (reversible, no crater);
* above the threshold, while the force exceeds the largest force the current crater has borne
  (``F_max``), the rock crushes: ``dF = k_load dd`` and the crater deepens by
  ``dp = dd (1 - k_load / k_unload)``;
* unloading and reloading below ``F_max``: ``F = F_th + k_unload (e - e_th)`` down to F_th,
  then ``k_load e``.

A blow that peaks at ``F_peak > F_th`` on fresh rock leaves
``p_blow = (F_peak - F_th)(1/k_load - 1/k_unload)`` (0 below the threshold), continuously.
The reflections of one blow (the stress wave rings in the rod) reload its own crater and crush
further only beyond that blow's largest force. When a new blow starts (the free mass strikes the
tool) the crater's memory is cleared, ``F_max = max(F_th, F)`` (:func:`rock_new_blow`): each blow
meets fresh rock. That is an assumption: the bit indexes between blows (rotary-percussive mode)
and the chips of the last blow are cleared; re-crushing of chips is not modelled. With a weight
on bit above F_th the rock crushes under the static load until ``F_max`` reaches it.

Rod coupling
------------
At the bit end of a uniform rod of impedance ``Z = rho c A`` the incident (right-going) wave
velocity ``a`` and the force ``F`` give the bit velocity ``d' = 2 a - F / Z`` and the reflected
wave ``b = a - F / Z``. With ``a`` constant over a time step, each branch of the law is linear,
so ``d`` relaxes exponentially with rate ``k / Z`` toward the penetration where ``F = 2 a Z``:
:func:`rock_step` integrates it exactly, splitting the step where a branch ends.

Sandstone values (defaults; 3 mm bit)
-------------------------------------
``k_load = 4.8e7 N/m``: the elastic stiffness of a rigid flat punch of radius a = 1.5 mm on a
half-space, ``2 E a / (1 - nu^2)``, with E = 15 GPa and nu = 0.25 (typical of a medium sandstone,
e.g. Berea). ``f_threshold = 350 N``: the uniaxial compressive strength of a medium sandstone,
50 MPa, over the bit face (7.07 mm^2). ``k_unload = 5 k_load``: assumed (Lundberg's unloading
slope is several times the loading one). None of the three was measured on the article's rock
or bit: all three are assumptions, the threshold and the unloading ratio the least known (the
README gives the sensitivity of the predicted depth to them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from rpud_common import ParameterError, check_range

__all__ = ["RockLaw", "rock_step", "rock_new_blow", "rock_response", "R_E", "R_P", "R_FMAX", "R_N"]

# rock state vector: elastic penetration e = d - p, permanent penetration p (the crater floor
# below the original surface), the crater's largest force F_max
R_E, R_P, R_FMAX = 0, 1, 2
R_N = 3
# accumulators: work on the rock, reflected wave energy (exact integral; tests)
A_WORK, A_REFL = 0, 1


@dataclass(frozen=True)
class RockLaw:
    """Bit-rock contact law (see the module docstring), SI units.

    Parameters
    ----------
    k_load : float
        Loading stiffness, N/m, in (0, 1e12] (default 4.8e7: flat punch r = 1.5 mm on sandstone).
    k_unload : float
        Unloading stiffness, N/m, >= k_load (equal: no crater, purely elastic), <= 1e13
        (default 2.4e8 = 5 k_load, assumed).
    f_threshold : float
        Force above which the rock crushes, N, in [0, 1e7] (default 350: 50 MPa over 7.07 mm^2).
    """

    k_load: float = 4.8e7
    k_unload: float = 2.4e8
    f_threshold: float = 350.0

    def __post_init__(self):
        check_range("k_load", self.k_load, 0.0, 1e12, "N/m", lo_open=True)
        check_range("k_unload", self.k_unload, 0.0, 1e13, "N/m", lo_open=True)
        if self.k_unload < self.k_load:
            raise ParameterError("k_unload", self.k_unload, f"must be >= k_load = {self.k_load:g} N/m")
        check_range("f_threshold", self.f_threshold, 0.0, 1e7, "N")

    def with_(self, **changes) -> "RockLaw":
        return replace(self, **changes)

    def penetration_per_blow(self, f_peak: float) -> float:
        """Permanent penetration left by one blow on fresh rock peaking at ``f_peak`` N, m."""
        if f_peak <= self.f_threshold:
            return 0.0
        return (f_peak - self.f_threshold) * (1.0 / self.k_load - 1.0 / self.k_unload)

    def static_state(self, force: float) -> np.ndarray:
        """Rock state (e, p, F_max) at rest under a constant force (the weight on bit), N.

        Below the threshold the penetration is elastic; above it the rock has crushed until
        F_max = force."""
        st = np.empty(R_N)
        if force <= self.f_threshold:
            st[R_E] = force / self.k_load
            st[R_P] = 0.0
            st[R_FMAX] = self.f_threshold
        else:
            st[R_P] = self.penetration_per_blow(force)
            st[R_E] = self.f_threshold / self.k_load + (force - self.f_threshold) / self.k_unload
            st[R_FMAX] = force
        return st

    def to_dict(self) -> dict:
        return {"k_load_n_per_m": self.k_load, "k_unload_n_per_m": self.k_unload,
                "f_threshold_n": self.f_threshold}


# ----------------------------------------------------------------------------- compiled step


@njit(cache=True)
def _force(e, kl, ku, fth, fmax):
    """Force of the elastic curve at elastic penetration e (no crushing)."""
    if e <= 0.0:
        return 0.0
    eth = fth / kl
    if e <= eth:
        return kl * e
    return fth + ku * (e - eth)


@njit(cache=True)
def _relax(x0, xinf, kap, s):
    """x(s) of x' = -kap (x - xinf)."""
    return xinf + (x0 - xinf) * math.exp(-kap * s)


@njit(cache=True)
def _t_reach(x0, xinf, kap, x):
    """Time for the relaxation from x0 toward xinf to reach x (inf if it never does)."""
    if (x - x0) * (xinf - x0) <= 0.0 or abs(x - x0) >= abs(xinf - x0):
        return math.inf
    return -math.log((xinf - x) / (xinf - x0)) / kap


@njit(cache=True)
def _refl_energy(a, F0, kap, Z, s):
    """Exact integral of Z b^2 over s for b = a - F/Z, F relaxing from F0 to 2 a Z at rate kap."""
    g = F0 / Z - 2.0 * a
    if kap == 0.0:
        bb = a - F0 / Z
        return Z * bb * bb * s
    e1 = -math.expm1(-kap * s) / kap
    e2 = -math.expm1(-2.0 * kap * s) / (2.0 * kap)
    return Z * (a * a * s + 2.0 * a * g * e1 + g * g * e2)


@njit(cache=True)
def rock_step(a, Z, kl, ku, fth, st, dt, acc):
    """Advance the bit penetration over one step with the incident wave ``a`` (m/s) constant
    (:func:`rock_step_fast` with the reflected energy integrated and no precomputed exponentials)."""
    return rock_step_fast(a, Z, kl, ku, fth, st, dt, acc, -math.expm1(-kl / Z * dt), -math.expm1(-ku / Z * dt), True)


@njit(cache=True)
def rock_step_fast(a, Z, kl, ku, fth, st, dt, acc, em_l, em_u, refl):
    """Advance the bit penetration over one step with the incident wave ``a`` (m/s) constant.

    Parameters
    ----------
    a : float
        Incident wave velocity at the bit, m/s (positive toward the rock).
    Z : float
        Rod impedance at the bit, N s/m.
    kl, ku, fth : float
        Loading and unloading stiffness (N/m), threshold (N).
    st : ndarray (R_N,)
        Rock state (e, p, F_max), updated in place (penetration d = e + p).
    dt : float
        Step, s.
    acc : ndarray (2,)
        ``acc[0]`` += work done on the rock (J), ``acc[1]`` += energy of the reflected wave (J,
        exact integral; used by the tests to close the energy balance; only with ``refl``).
    em_l, em_u : float
        ``1 - exp(-k dt / Z)`` for k_load and k_unload: a whole step on one branch (the common
        case) needs no exponential.
    refl : bool
        Integrate the reflected energy.

    Returns
    -------
    float
        Change of the penetration d over the step, m (the bit's mean velocity is that / dt).
    """
    d_start = st[R_E] + st[R_P]
    s = 0.0
    eth = fth / kl
    for _ in range(32):
        h = dt - s
        if h <= 0.0:
            break
        e, p, fmax = st[R_E], st[R_P], st[R_FMAX]
        if e < 0.0 or (e == 0.0 and a <= 0.0):
            # no contact: the bit end is free, d' = 2 a, until e reaches 0 from below
            if a > 0.0 and -e < 2.0 * a * h:
                tc = -e / (2.0 * a)
                st[R_E] = 0.0
                if refl:
                    acc[A_REFL] += Z * a * a * tc
                s += tc
                continue
            st[R_E] = e + 2.0 * a * h
            if refl:
                acc[A_REFL] += Z * a * a * h
            break
        etop = eth + (fmax - fth) / ku
        F0 = _force(e, kl, ku, fth, fmax)
        v0 = 2.0 * a - F0 / Z
        # branch: slope k between the elastic penetrations lo and hi
        crush = False
        if e < eth or (e == eth and v0 <= 0.0):
            k, lo, hi = kl, 0.0, eth
        elif e < etop or (e == etop and v0 <= 0.0):
            k, lo, hi = ku, eth, etop
        else:
            k, lo, hi, crush = kl, e, math.inf, True
        kap = k / Z
        # d relaxes toward the penetration where F = 2 a Z; while crushing, e moves by kl/ku of d
        ddinf = (2.0 * a * Z - F0) / k
        frac = kl / ku if crush else 1.0
        t_hi = _t_reach(e, e + ddinf * frac, kap, hi) if hi < math.inf else math.inf
        t_lo = _t_reach(e, e + ddinf * frac, kap, lo) if not crush else math.inf
        tb = min(t_hi, t_lo, h)
        if tb == dt:
            dd = ddinf * (em_l if k == kl else em_u)
        else:
            dd = ddinf * -math.expm1(-kap * tb)
        if tb == t_hi:
            e1 = hi
        elif tb == t_lo:
            e1 = lo
        else:
            e1 = e + dd * frac
        acc[A_WORK] += F0 * dd + 0.5 * k * dd * dd
        if refl:
            acc[A_REFL] += _refl_energy(a, F0, kap, Z, tb)
        st[R_E] = e1
        if crush:
            st[R_P] = p + dd * (1.0 - frac)
            st[R_FMAX] = F0 + kl * dd
        s += tb
        if tb == h:
            break
    return st[R_E] + st[R_P] - d_start


@njit(cache=True)
def rock_new_blow(st, kl, ku, fth):
    """A new blow starts: clear the crater's memory, F_max = max(F_th, current force)."""
    f = _force(st[R_E], kl, ku, fth, st[R_FMAX])
    st[R_FMAX] = max(fth, f)
    if f > fth:
        st[R_E] = fth / kl + (f - fth) / ku        # the same force, now at the top of the elastic curve


@njit(cache=True)
def rock_response(incident, Z, kl, ku, fth, state0, dt):
    """Drive the bit with a sampled incident wave (one value per step): force (N, at each step
    end), penetration (m), permanent penetration (m), and the accumulated work on the rock and
    reflected wave energy (J). A test harness around :func:`rock_step`, the same code the drill
    kernel runs."""
    n = incident.shape[0]
    force = np.empty(n)
    pen = np.empty(n)
    perm = np.empty(n)
    st = state0.copy()
    acc = np.zeros(2)
    for i in range(n):
        rock_step(incident[i], Z, kl, ku, fth, st, dt, acc)
        force[i] = _force(st[R_E], kl, ku, fth, st[R_FMAX])
        pen[i] = st[R_E] + st[R_P]
        perm[i] = st[R_P]
    return force, pen, perm, acc[A_WORK], acc[A_REFL]

"""Free motion of a damped oscillator in closed form (plain Python, scalars and arrays).

The tool between events (and each mode of a modal horn in the reference engines) moves as
:class:`Oscillator`; the compiled engines keep the same closed form in a float record
(:func:`impact.kernel_blocks.osc_make`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Oscillator"]


class Oscillator:
    """Free motion of a damped oscillator ``m y'' + c y' + k y = 0``, position ``delta + y(s)``.

    Every derivative ``z = y^(n)`` solves the same equation, with initial values
    ``y^(n)(0), y^(n+1)(0)`` from the recursion ``y'' = -2 al y' - wn^2 y``
    (``al = c / 2m``, ``wn^2 = k / m``). Closed forms, with ``P = z(0)``:

    * underdamped (al < wn, ``be = sqrt(wn^2 - al^2)``):
      ``z = exp(-al s) (P cos(be s) + Q sin(be s))``, ``Q = (z'(0) + al P) / be``;
    * critically (al = wn) and over-damped (``gm = sqrt(al^2 - wn^2)``, slow root
      ``l1 = -al + gm``): ``z = exp(l1 s) (P + Q phi(s))``, ``Q = z'(0) - l1 P``,
      ``phi = (1 - exp(-2 gm s)) / (2 gm)`` (``= s`` at critical damping): the sum of the two
      real exponentials written without their cancellation near critical damping.

    ``b0``, ``b2``, ``b4`` bound ``|y|``, ``|y''|``, ``|y''''|`` over all s >= 0 (m, m/s^2,
    m/s^4); the event search relies on them.
    """

    __slots__ = ("delta", "kind", "al", "be", "gm", "l1", "P", "Q", "b0", "b2", "b4")

    def __init__(self, mass: float, k: float, c: float, delta: float, x0: float, xd0: float):
        wn2 = k / mass
        wn = math.sqrt(wn2)
        al = c / (2.0 * mass)
        y = [x0 - delta, xd0]
        for _ in range(4):
            y.append(-2.0 * al * y[-1] - wn2 * y[-2])
        self.delta, self.al = delta, al
        P, Q, bnd = [0.0] * 5, [0.0] * 5, [0.0] * 5
        if al < wn:
            self.kind = 0
            be = math.sqrt((wn - al) * (wn + al))
            self.be, self.gm, self.l1 = be, 0.0, 0.0
            # exp(-al s)|sin(be s)| <= min(1, be s exp(-al s)) <= min(1, be / (e al)): finite
            # near critical damping, where |Q| alone grows like 1 / be
            ks = min(1.0, be / (math.e * al)) if al > 0.0 else 1.0
            for n in range(5):
                P[n] = y[n]
                Q[n] = (y[n + 1] + al * y[n]) / be
                bnd[n] = min(math.sqrt(P[n] * P[n] + Q[n] * Q[n]), abs(P[n]) + abs(Q[n]) * ks)
        else:
            self.kind = 1
            gm = math.sqrt((al - wn) * (al + wn))
            l1 = -wn2 / (al + gm)          # = -al + gm, without the cancellation
            self.be, self.gm, self.l1 = 0.0, gm, l1
            # exp(l1 s) phi(s) <= min(s exp(l1 s), 1 / (2 gm)) <= min(1 / (e |l1|), 1 / (2 gm))
            kp = 1.0 / (math.e * -l1)
            if gm > 0.0:
                kp = min(kp, 0.5 / gm)
            for n in range(5):
                P[n] = y[n]
                Q[n] = y[n + 1] - l1 * y[n]
                b = abs(P[n]) + abs(Q[n]) * kp
                if gm > 0.0:
                    # two-exponential form (P + Q/2gm) e^{l1 s} - (Q/2gm) e^{(l1 - 2gm) s}
                    r = Q[n] * (0.5 / gm)
                    b = min(b, abs(P[n] + r) + abs(r))
                bnd[n] = b
        self.P, self.Q = P, Q
        self.b0, self.b2, self.b4 = bnd[0], bnd[2], bnd[4]

    # scalar ---------------------------------------------------------------
    def _basis(self, s: float) -> tuple[float, float, float]:
        if self.kind == 0:
            return math.exp(-self.al * s), math.cos(self.be * s), math.sin(self.be * s)
        ph = -math.expm1(-2.0 * self.gm * s) / (2.0 * self.gm) if self.gm > 0.0 else s
        return math.exp(self.l1 * s), 1.0, ph

    def pos(self, s: float) -> float:
        ex, cs, sn = self._basis(s)
        return self.delta + ex * (self.P[0] * cs + self.Q[0] * sn)

    def pv(self, s: float) -> tuple[float, float]:
        ex, cs, sn = self._basis(s)
        P, Q = self.P, self.Q
        return self.delta + ex * (P[0] * cs + Q[0] * sn), ex * (P[1] * cs + Q[1] * sn)

    def acc_jerk(self, s: float) -> tuple[float, float]:
        ex, cs, sn = self._basis(s)
        P, Q = self.P, self.Q
        return ex * (P[2] * cs + Q[2] * sn), ex * (P[3] * cs + Q[3] * sn)

    # vector ---------------------------------------------------------------
    def _basis_vec(self, s: np.ndarray):
        if self.kind == 0:
            return np.exp(-self.al * s), np.cos(self.be * s), np.sin(self.be * s)
        ph = -np.expm1(-2.0 * self.gm * s) / (2.0 * self.gm) if self.gm > 0.0 else s
        return np.exp(self.l1 * s), 1.0, ph

    def pv_vec(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ex, cs, sn = self._basis_vec(s)
        P, Q = self.P, self.Q
        return self.delta + ex * (P[0] * cs + Q[0] * sn), ex * (P[1] * cs + Q[1] * sn)

    def acc_jerk_vec(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ex, cs, sn = self._basis_vec(s)
        P, Q = self.P, self.Q
        return ex * (P[2] * cs + Q[2] * sn), ex * (P[3] * cs + Q[3] * sn)

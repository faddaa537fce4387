"""Reduced transducer: the FE modes that carry tip motion as damped oscillators, as plain data.

The impact model (``impact``) cannot import ``fem``; it consumes a horn described by arrays.
This module turns a :class:`fem.harmonic.ModalBasis` into such arrays, a
:class:`ReducedTransducer` (numpy arrays and floats only, ``to_dict``/``from_dict``), which
``results`` converts into ``impact.horn.ModalHorn``.

Model
-----
Short-circuit modes ``phi_i`` of the driven free set, mass-normalised (``phi^T M phi = 1``, so
every modal mass is 1 and the modal stiffness is ``lambda_i = omega_i^2``). Under the hot-electrode
voltage ``V(t) = V0 sin(W t)`` each kept modal coordinate obeys::

    q_i'' + 2 zeta_i omega_i q_i' + omega_i^2 q_i = Re(gamma_i) V(t) + Im(gamma_i) V'(t) / W

* ``gamma_i = phi_i^T b1`` (N/V per unit modal mass): the modal force per volt, the projection of
  the hot-electrode column of the coupled stiffness (with its loss), i.e. the hot electrode's
  charge row (reciprocity: the same ``gamma_i`` is the charge per unit modal coordinate);
* losses: the harmonic analysis' :class:`fem.harmonic.LossModel`, modal loss factor
  ``eta_i = phi_i^T L phi_i / lambda_i``, turned into the viscous damping that gives the same
  response at the drive, ``2 zeta_i omega_i = eta_i omega_i^2 / W`` (as :func:`fem.transient.ring_up`);
* tip participation ``s_i = a^T phi_i`` (m per unit modal coordinate), ``a`` the area-mean axial
  displacement row of the tip surface (:func:`fem.harmonic.surface_functional`), so that a tip
  impulse ``J`` (N s, along +z on the horn) changes ``q_i'`` by ``s_i J`` (modal mass 1); each mode's
  sign is chosen so that ``s_i >= 0`` (the same numbers in every run, whichever sign the
  eigen-solver returned).

Residual (static correction). The modes left out (other basis modes and the truncated space of
the basis' residual) respond to the drive quasi-statically; at the drive frequency their tip
displacement per volt is the complex number ``r = x_tip(W) - sum_kept s_i gamma_i / (lambda_i (1 + j
eta_i) - W^2)``, ``x_tip(W)`` the modal-basis solution (modes + second-order residual) of the
harmonic analysis. In the time domain it is ``Re(r) V(t) + Im(r) V'(t) / W``: a driven
displacement of the tip that an impulse does not change. ``blocked_charge`` is the same for the
electrode charge (C/V): the clamped capacitance, the dielectric loss and the truncated modes.

Mode selection (``n_modes=None``): the working mode plus every basis mode whose tip
participation satisfies ``s_i^2 >= tip_share * s_w^2`` (default ``tip_share`` = 1 %: the mode's
effective mass at the tip is at most 100 times that of the working mode). ``n_modes=k`` keeps
the working mode and the ``k - 1`` other basis modes with the largest ``s_i^2``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, fields

import numpy as np

from rpud_common import ParameterError, check_integer, check_positive, check_range

from .assembly import PiezoSystem
from .harmonic import ModalBasis, charge_row, loss_matrix, surface_functional

__all__ = ["ReducedTransducer", "reduce_transducer", "DEFAULT_TIP_SHARE"]

log = logging.getLogger(__name__)

DEFAULT_TIP_SHARE = 0.01
"""Default selection rule: keep a mode if s_i^2 >= 1 % of the working mode's s_w^2."""

_ARRAYS = ("omega", "modal_mass", "stiffness", "eta", "zeta", "coupling_re", "coupling_im", "tip",
           "mode_index")


@dataclass(frozen=True, eq=False)
class ReducedTransducer:
    """The transducer reduced to ``n`` modal oscillators, as plain data (SI units).

    Attributes
    ----------
    freq_hz : float
        Drive frequency W / 2 pi at which the losses were made viscous and the residual taken, Hz.
    omega : ndarray (n,)
        Natural angular frequencies, rad/s.
    modal_mass : ndarray (n,)
        Modal masses (mass-normalised modes: 1), kg m^2 per (unit coordinate)^2.
    stiffness : ndarray (n,)
        Modal stiffnesses ``omega^2 * modal_mass``.
    eta : ndarray (n,)
        Modal loss factors of the LossModel (hysteretic).
    zeta : ndarray (n,)
        Viscous damping ratios equivalent at the drive: ``eta omega / (2 W)``.
    coupling_re, coupling_im : ndarray (n,)
        Modal force per volt ``gamma_i``, N/V per unit modal coordinate (real and imaginary part;
        the imaginary part is the loss of the coupling).
    tip : ndarray (n,)
        Area-mean axial tip displacement per unit modal coordinate, m.
    mode_index : ndarray (n,) of int
        Index of each kept mode in the modal basis.
    working : int
        Position of the working mode in the kept arrays.
    residual_re, residual_im : float
        Tip displacement per volt of everything not kept, at the drive, m/V.
    blocked_charge_re, blocked_charge_im : float
        Electrode charge per volt of everything not kept (clamped capacitance, dielectric loss,
        truncated modes), at the drive, C/V.
    tip_surface : str
        Facet set of the tip.
    rule : str
        How the modes were chosen.
    """

    freq_hz: float
    omega: np.ndarray
    modal_mass: np.ndarray
    stiffness: np.ndarray
    eta: np.ndarray
    zeta: np.ndarray
    coupling_re: np.ndarray
    coupling_im: np.ndarray
    tip: np.ndarray
    mode_index: np.ndarray
    working: int
    residual_re: float
    residual_im: float
    blocked_charge_re: float
    blocked_charge_im: float
    tip_surface: str = "horn_tip"
    rule: str = ""

    @property
    def n_modes(self) -> int:
        return int(self.omega.size)

    @property
    def coupling(self) -> np.ndarray:
        """Complex modal force per volt, N/V."""
        return self.coupling_re + 1j * self.coupling_im

    @property
    def residual(self) -> complex:
        return complex(self.residual_re, self.residual_im)

    @property
    def blocked_charge(self) -> complex:
        return complex(self.blocked_charge_re, self.blocked_charge_im)

    def modal_amplitudes(self, voltage: float = 1.0) -> np.ndarray:
        """Steady complex modal coordinates at the drive (phasor of ``V0 e^{jWt}``), viscous model."""
        W = 2 * np.pi * self.freq_hz
        den = self.modal_mass * (self.omega ** 2 - W ** 2 + 2j * self.zeta * self.omega * W)
        return self.coupling * voltage / den

    def tip_phasor(self, voltage: float = 1.0) -> complex:
        """Steady complex tip displacement at the drive, m (kept modes + residual)."""
        return complex(self.tip @ self.modal_amplitudes(voltage) + self.residual * voltage)

    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = v.tolist() if isinstance(v, np.ndarray) else v
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "ReducedTransducer":
        kw = dict(data)
        for name in _ARRAYS:
            kw[name] = np.asarray(kw[name], dtype=int if name == "mode_index" else float)
        return cls(**kw)


def reduce_transducer(system: PiezoSystem, basis: ModalBasis, freq_hz: float, *, tip_surface: str = "horn_tip",
                      n_modes: int | None = None, tip_share: float = DEFAULT_TIP_SHARE,
                      working: int | None = None) -> ReducedTransducer:
    """Reduce the transducer to the modes that carry tip motion (see the module docstring).

    Parameters
    ----------
    system : PiezoSystem
    basis : ModalBasis
        Modes, losses and residual of the harmonic analysis (its LossModel is used).
    freq_hz : float
        Drive frequency, Hz.
    tip_surface : str
        Facet set whose area-mean axial displacement is the tip.
    n_modes : int, optional
        Number of modes kept (working mode first in importance); ``None``: the tip-share rule.
    tip_share : float
        Rule threshold: keep modes with ``s_i^2 >= tip_share * s_w^2`` (``n_modes=None`` only).
    working : int, optional
        Index of the working mode in the basis; default: the basis mode with the largest steady
        tip response at ``freq_hz``.

    Returns
    -------
    ReducedTransducer
    """
    check_positive("freq", freq_hz, "Hz")
    check_range("tip_share", tip_share, 0.0, 1.0)
    nb = len(basis.lam)
    if nb == 0:
        raise ParameterError("basis", "0 modes", "needs at least one mode")
    if n_modes is not None:
        check_integer("n_modes", n_modes, 1, nb)
    W = 2 * np.pi * float(freq_hz)
    func = surface_functional(system, tip_surface)
    a = np.asarray(func.rows[0][:, basis.free].toarray()).ravel()
    s_all = basis.Phi.T @ a
    q_all = basis.gamma / (basis.lam * (1 + 1j * basis.eta) - W ** 2)
    if working is None:
        working = int(np.argmax(np.abs(s_all * q_all)))
    check_integer("working", working, 0, nb - 1)
    s2 = s_all ** 2
    order = [working] + [int(i) for i in np.argsort(-s2, kind="stable") if i != working]
    if n_modes is None:
        keep = [i for i in order if i == working or s2[i] >= tip_share * s2[working]]
        rule = f"working mode + modes with s_i^2 >= {tip_share:g} s_w^2 ({len(keep)} of {nb})"
    else:
        keep = order[:n_modes]
        rule = f"working mode + the {n_modes - 1} other modes of largest s_i^2 (of {nb})"
    keep = sorted(keep)
    idx = np.array(keep, dtype=int)
    # the whole basis at the drive: modes, loss coupling and second-order residual
    x_f = basis.solution_free(float(freq_hz), 1.0)
    tip_full = complex(a @ x_f)
    lam, eta, gam = basis.lam[idx], basis.eta[idx], basis.gamma[idx]
    omega = np.sqrt(lam)
    zeta = eta * omega / (2 * W)
    q_keep = gam / (lam - W ** 2 + 2j * zeta * omega * W)
    residual = tip_full - complex(s_all[idx] @ q_keep)
    L = basis.L if basis.L is not None else loss_matrix(system, basis.loss)
    x = system.expand(x_f, basis.free, 1.0)
    charge_full = complex(charge_row(system, L) @ x)
    blocked = charge_full - complex(gam @ q_keep)
    w_pos = int(np.flatnonzero(idx == working)[0])
    # a mode's sign is arbitrary (eigen-solvers may return either from run to run); the sign with a
    # positive tip participation makes the reduced transducer the same numbers in every run
    sign = np.where(s_all[idx] < 0, -1.0, 1.0)
    gam = sign * gam
    log.info("reduced transducer: %d modes (%s), residual %.3g of the tip response", len(idx), rule,
             abs(residual) / abs(tip_full) if tip_full else 0.0)
    return ReducedTransducer(
        freq_hz=float(freq_hz), omega=omega, modal_mass=np.ones(len(idx)), stiffness=lam.copy(), eta=eta.copy(),
        zeta=zeta, coupling_re=gam.real.copy(), coupling_im=gam.imag.copy(), tip=sign * s_all[idx],
        mode_index=idx, working=w_pos, residual_re=residual.real, residual_im=residual.imag,
        blocked_charge_re=blocked.real, blocked_charge_im=blocked.imag, tip_surface=tip_surface, rule=rule)

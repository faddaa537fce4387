"""Wiring of the coupled model: the FE reduced transducer (``fem.reduced``) as the impact model's
modal horn (``impact.horn.ModalHorn``), and the coupled ensemble statistics.

``fem`` and ``impact`` do not know each other; this module (allowed to import both) converts
one into the other.
"""

from __future__ import annotations

import logging

from impact.horn import ModalHorn

log = logging.getLogger(__name__)

__all__ = ["horn_from_reduced"]


def horn_from_reduced(reduced, voltage: float, start: str = "rest") -> ModalHorn:
    """The impact model's modal horn from a :class:`fem.reduced.ReducedTransducer`.

    Parameters
    ----------
    reduced : fem.reduced.ReducedTransducer
        Modes kept, losses (viscous at the drive), couplings, tip participations, residual.
    voltage : float
        Drive amplitude, V.
    start : {"rest", "steady"}
        Modal state at t = 0.

    Returns
    -------
    ModalHorn
        Its drive frequency is ``reduced.freq_hz`` (pass it as ``ImpactParams.freq``).
    """
    return ModalHorn(omega=reduced.omega, zeta=reduced.zeta, modal_mass=reduced.modal_mass, tip=reduced.tip,
                     coupling_re=reduced.coupling_re, coupling_im=reduced.coupling_im, voltage=float(voltage),
                     residual_re=float(reduced.residual_re), residual_im=float(reduced.residual_im),
                     blocked_charge_re=float(reduced.blocked_charge_re),
                     blocked_charge_im=float(reduced.blocked_charge_im), start=start)

"""Results of the compliant impact model (:mod:`impact.compliant_loop`), from either engine."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CompliantRun", "Contact"]


@dataclass(frozen=True)
class Contact:
    """One finished contact: ``body`` ("horn" or "tool"), start and end (s), approach and separation
    speeds (relative, m/s, both > 0), largest Hertz approach (m), peak force (N), energy lost (J),
    free-mass and tool velocities at separation (m/s)."""

    body: str
    t_start: float
    t_end: float
    v_in: float
    v_out: float
    d_max: float
    peak_force: float
    loss: float
    free_mass_after: float
    tool_after: float


@dataclass
class CompliantRun:
    """One run of :func:`simulate_compliant`.

    Attributes
    ----------
    contacts : list of Contact
        The finished contacts in order of their start.
    t_end : float
        End of the run, s.
    state : ndarray
        ``[w, w', x, x', q..., q'...]`` at ``t_end``.
    ledger : dict
        Energies over the run, J: ``drive_j`` (modes + residual through the contact),
        ``gravity_j`` (the constant force on the free mass), ``modal_damping_j``,
        ``tool_damping_j``, ``contact_loss_j`` (finished contacts), ``stored_change_j`` (bodies +
        open contacts' absorbed energy), ``residual_j`` (the balance; 0 up to the integration error).
    """

    contacts: list
    t_end: float
    state: np.ndarray
    ledger: dict

    def tool_contacts(self) -> list:
        return [c for c in self.contacts if c.body == "tool"]

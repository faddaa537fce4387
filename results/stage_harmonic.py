"""The harmonic stages: the working point at the drive, and (for the report) the band around it.

:func:`harmonic_stage` is what every run needs: the modal basis at the working mode (modes +
residual, one real factorisation) with the assembled-transducer losses, the working point at the
drive voltage and the horn mass the impacts see. :func:`response_stage` adds what the report
draws: the admittance sweep over the resonance/anti-resonance band, the working point with
datasheet losses and the ring-up at the drive.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from rpud_common import ParameterError

log = logging.getLogger(__name__)

__all__ = ["Harmonic", "harmonic_stage", "tip_surfaces", "Response", "response_stage"]


def tip_surfaces(mesh, tip: str | None = None) -> tuple[str, ...]:
    """The surfaces a working point reads: the tip first (``tip``, else ``horn_tip``, else
    ``top``), then ``teeth_tops`` when the mesh has teeth."""
    tip = tip or ("horn_tip" if "horn_tip" in mesh.facet_sets else "top")
    if tip not in mesh.facet_sets:
        raise ParameterError("tip_surface", tip, f"no such surface; the mesh has {sorted(mesh.facet_sets)}")
    return (tip,) + (("teeth_tops",) if "teeth_tops" in mesh.facet_sets and tip != "teeth_tops" else ())


@dataclass(frozen=True)
class Harmonic:
    """The working point of a matched design (:func:`harmonic_stage`).

    Attributes
    ----------
    system, modal, w
        As in :class:`results.stage_fe.Matched`.
    f_w : float
        Working frequency (the working mode's short-circuit resonance), Hz.
    loss : fem.harmonic.LossModel
    basis : fem.harmonic.ModalBasis
    surfaces : tuple of str
        Tip surface first (:func:`tip_surfaces`).
    wp : fem.harmonic.WorkingPoint
        At ``f_w`` and the stage's voltage.
    horn_mass : float or None
        Mass of the horn region, kg (None: the mesh has no horn).
    seconds : float
    """

    system: Any
    modal: Any
    w: int
    f_w: float
    loss: Any
    basis: Any
    surfaces: tuple[str, ...]
    wp: Any
    horn_mass: float | None
    seconds: float

    @property
    def eta(self) -> float:
        """Modal loss factor of the working mode."""
        return float(self.basis.eta[self.w])

    def tip_amplitude(self, voltage: float) -> Callable[[float], float]:
        """``c -> tip amplitude`` (m) at ``voltage`` with a viscous damper ``c`` (N s/m) on the tip."""
        from fem.harmonic import working_point

        def amplitude(c: float) -> float:
            return working_point(self.system, self.f_w, voltage, loss=self.loss, surfaces=self.surfaces[:1],
                                 basis=self.basis, tip_damping=c).tip_amplitude_m

        return amplitude

    def portable(self) -> "Harmonic":
        """This stage without the residual's factorisation (a solver handle: not picklable, and only
        needed to build the basis), so it can move to another worker."""
        return dataclasses.replace(self, basis=dataclasses.replace(self.basis, factor=None))

    def record(self) -> dict:
        """Per-volt figures (a study's table columns: the drive voltage enters later)."""
        wp = self.wp
        ratio = wp.teeth_ellipse_ratio if "teeth_tops" in self.surfaces else float("nan")
        return {"tip_per_volt_m": wp.tip_per_volt_m, "teeth_ellipse_ratio": ratio,
                "power_per_v2_w": wp.power_w / wp.voltage ** 2, "harmonic_s": self.seconds}


def harmonic_stage(matched, *, loss, voltage: float, tip: str | None = None) -> Harmonic:
    """The modal basis at the working mode of ``matched`` (:class:`results.stage_fe.Matched`)
    with the losses ``loss`` (:class:`fem.harmonic.LossModel`) and the working point at
    ``voltage`` (V, amplitude) on :func:`tip_surfaces` (``tip``: the tip surface's name)."""
    from fem.harmonic import modal_basis, working_point
    from geometry.report import mesh_part_volumes

    t0 = time.perf_counter()
    system, modal, w = matched.system, matched.modal, matched.w
    f_w = float(modal.f_r_hz[w])
    surfaces = tip_surfaces(matched.mesh, tip)
    basis = modal_basis(system, f_w, loss=loss, modes=modal)
    wp = working_point(system, f_w, voltage, loss=loss, surfaces=surfaces, basis=basis)
    horn_mass = mesh_part_volumes(matched.mesh)[1].get("horn")
    return Harmonic(system, modal, w, f_w, loss, basis, surfaces, wp, horn_mass, time.perf_counter() - t0)


@dataclass(frozen=True)
class Response:
    """What the report draws around the working point (:func:`response_stage`).

    Attributes
    ----------
    sweep : fem.harmonic.HarmonicResult
        Admittance and surface motion over the band.
    wp_datasheet : fem.harmonic.WorkingPoint
        The working point with datasheet losses (the unloaded resonator).
    ring : fem.transient.TransientResult
        Ring-up at the drive, from rest.
    tau : float
        Amplitude time constant of the working mode, s.
    seconds : float
    """

    sweep: Any
    wp_datasheet: Any
    ring: Any
    tau: float
    seconds: float


def response_stage(harm: Harmonic, f_a: float, *, voltage: float, band: float, n_points: int) -> Response:
    """The admittance sweep over ``[f_r (1 - band), f_a (1 + band)]`` (``n_points`` frequencies), the
    datasheet-loss working point and the ring-up over six time constants (at most 50 ms)."""
    from fem.harmonic import LossModel, harmonic_sweep, modal_basis, working_point
    from fem.transient import ring_up

    t0 = time.perf_counter()
    system, f_w, surfaces = harm.system, harm.f_w, harm.surfaces
    hi = (f_a if np.isfinite(f_a) else f_w) * (1 + band)
    freqs = np.linspace(f_w * (1 - band), hi, n_points)
    sweep = harmonic_sweep(system, freqs, voltage, loss=harm.loss, basis=harm.basis, surfaces=surfaces)
    basis_ds = modal_basis(system, f_w, loss=LossModel(), modes=harm.modal, reuse=harm.basis)
    wp_ds = working_point(system, f_w, voltage, loss=LossModel(), surfaces=surfaces, basis=basis_ds)
    tau = 2.0 / (harm.eta * 2 * np.pi * f_w)
    ring = ring_up(system, f_w, voltage, min(6 * tau, 0.05), loss=harm.loss, basis=harm.basis,
                   surfaces=surfaces[:1])
    return Response(sweep, wp_ds, ring, tau, time.perf_counter() - t0)

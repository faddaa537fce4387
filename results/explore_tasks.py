"""The tasks of a design study: the pipeline's stage functions on one point.

A point's chain is mesh -> match -> harmonic -> impact (and rotor after harmonic), each task the stage function the
end-to-end run calls (:mod:`results.stage_fe`, :mod:`results.stage_harmonic`,
:mod:`results.stage_impacts`), with the mesh options, losses and impact rule of the study's settings
(:class:`results.study.StudySettings`). The harmonic task works per volt (the drive voltage
enters at the impact task), so points that differ only in voltage or impact parameters share
every FE task. A task whose input failed, or that fails, returns a :class:`Failed` value, which
the point's row records; the study goes on.
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any, Callable

from .study import GROUPS, Study

log = logging.getLogger(__name__)

__all__ = ["Failed", "guard", "split_point", "task_key", "task_mesh", "task_match", "task_harmonic", "task_impact",
           "task_teeth_error", "task_rotor", "rotor_values", "record", "HANDOFF_DIGITS"]

HANDOFF_DIGITS = 4
"""Significant digits of the amplitude handed to the impacts (the pipeline's default)."""


@dataclass(frozen=True)
class Failed:
    """A stage that failed: its name and the error, one line."""

    stage: str
    error: str


def _failed(stage: str, exc: BaseException) -> Failed:
    text = " ".join(str(exc).split())
    return Failed(stage, f"{type(exc).__name__}: {text}"[:500])


def guard(stage: str, fn: Callable, *inputs, threads: int | None = 1):
    """Run ``fn`` unless an input already failed; a failure becomes a :class:`Failed` value.

    ``threads``: BLAS threads of the stage (1 on workers: numbers independent of the cluster
    layout; None leaves the library default, for the sequential baseline)."""
    for x in inputs:
        if isinstance(x, Failed):
            return x
    try:
        from fem.solvers import blas_threads

        with blas_threads(threads) if threads else nullcontext():
            return fn(*inputs)
    except Exception as exc:  # a failed point is recorded, not fatal (the study goes on)
        log.info("stage %s failed: %s", stage, exc)
        return _failed(stage, exc)


def split_point(study: Study, point: dict) -> tuple[dict, float, float, dict]:
    """A point's design values, ``q_mech``, drive voltage (V) and impact parameters."""
    design = {k: v for k, v in point.items() if k.split(".", 1)[0] not in GROUPS}
    q_mech = point.get("drive.q_mech", study.settings.q_mech)
    voltage = point.get("drive.voltage", study.settings.voltage)
    impact = {k.split(".", 1)[1]: v for k, v in point.items() if k.startswith("impact.")}
    return design, q_mech, voltage, impact


def task_key(d: Any) -> str:
    """Short hash of a JSON-able value: the key of a task shared by the points that give it."""
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]


def task_mesh(study: Study, design_values: dict):
    """The point's design meshed (:func:`results.stage_fe.mesh_stage`)."""
    from .stage_fe import mesh_stage

    design = study.base_design().replace(design_values) if design_values else study.base_design()
    return mesh_stage(design, study.settings.mesh_options())


def task_match(study: Study, meshed):
    """The working mode, matched if the study matches (:func:`results.stage_fe.match_stage`)."""
    from .stage_fe import match_stage

    return match_stage(meshed, match=study.settings.match)


def task_harmonic(study: Study, matched, q_mech: float):
    """The working point per volt (:func:`results.stage_harmonic.harmonic_stage` at 1 V), without
    the solver handle, so an impact task on another worker can take it."""
    from fem.harmonic import LossModel

    from .stage_harmonic import harmonic_stage

    return harmonic_stage(matched, loss=LossModel(q_mech=q_mech), voltage=1.0,
                          tip=study.settings.tip_surface or None).portable()


_IMPACT_COLUMNS = {"tool_ke_j": "mean_tool_ke_after_j", "ke_gain_j": "mean_ke_gain_j",
                   "tool_power_w": "tool_power_w", "tool_rate_hz": "tool_impact_rate_hz",
                   "horn_power_w": "horn_power_w"}


def task_impact(study: Study, harm, voltage: float, impact_values: dict) -> dict:
    """The loaded amplitude and the impact statistics of one point
    (:func:`results.stage_impacts.amplitude_stage`, :func:`~results.stage_impacts.impact_stage`)."""
    from .stage_impacts import amplitude_stage, handoff, impact_stage, stats_settings

    t0 = time.perf_counter()
    st = study.settings
    rule = stats_settings(st.rel_tol, st.max_members, study.seed)
    base = handoff(harm, HANDOFF_DIGITS).with_(**impact_values)
    amps = amplitude_stage(harm, base, [base.m_free], voltage=voltage, settings=rule, scenario=st.scenario,
                           digits=HANDOFF_DIGITS)
    est = impact_stage(base, [base.m_free], amps, scenario=st.scenario, settings=rule).rows[0]
    amp = amps[base.m_free]
    rec: dict[str, Any] = {"A0_m": amp.A0, "members": est.members, "stats_converged": float(est.converged),
                           "impact_note": est.note or amp.note}
    for out, q in _IMPACT_COLUMNS.items():
        rec[out] = est[q].mean
        rec[f"{out}_ci95"] = est[q].half_width
    rec["impact_s"] = time.perf_counter() - t0
    return rec


def rotor_values(point: dict) -> dict:
    """A point's :class:`impact.rotor.RotorParams` fields (``rotor.<field>`` parameters)."""
    return {k.split(".", 1)[1]: v for k, v in point.items() if k.startswith("rotor.")}


def task_teeth_error(study: Study, matched, harm):
    """The discretisation error of the teeth motion the rotor uses: the pipeline's estimate
    (:func:`results.errors.estimate_stage`, one solve on a 1.4x coarser mesh) of the point's
    working mode with the harmonic task's losses; None when the study's ``refine`` leaves no
    coarser mesh. Shared, like the harmonic task, by the points of one design and ``q_mech``."""
    from .errors import estimate_stage

    m = matched
    return estimate_stage(m.design, m.options, None, m.system, m.modal, m.w, harm.wp, harm.surfaces,
                          float(m.design.target_frequency), loss=harm.loss)


def task_rotor(study: Study, harm, design_values: dict, voltage: float, values: dict, est=None) -> dict:
    """The rotor's speed and torque of one point, each with its error
    (:func:`results.rotor_stage.study_rotor`): the per-volt teeth motion at the point's voltage,
    its errors from ``est`` (:func:`task_teeth_error`), the load the pipeline's default weight on
    bit gives."""
    from .pipeline import PipelineSettings
    from .rotor_stage import study_rotor

    t0 = time.perf_counter()
    design = study.base_design().replace(design_values) if design_values else study.base_design()
    rec = study_rotor(design, harm.wp, harm.f_w, voltage, values, PipelineSettings().wob, est=est)
    rec["rotor_s"] = time.perf_counter() - t0
    return rec


def record(x) -> Any:
    """The table columns of a task's outcome (a :class:`Failed` value stays as it is)."""
    return x if isinstance(x, (Failed, dict)) else x.record()

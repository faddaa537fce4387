"""What a design study will cost, estimated before it runs (and refused above a budget).

Points that share their design share the mesh and match tasks and, with the same ``q_mech``,
the harmonic task (as :mod:`results.explore` schedules them); every point has its own impact
task.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass

from rpud_common import ParameterError

from .explore_tasks import split_point
from .study import Study

log = logging.getLogger(__name__)

__all__ = ["estimate_cost", "check_cost", "CostEstimate", "MAX_HOURS", "MESH_SECONDS", "MODAL_SECONDS",
           "MATCHING_SECONDS", "HARMONIC_SECONDS", "IMPACT_SECONDS", "IMPACT_MEMBER_SECONDS"]


# Stage times of the article's drill (as built, its own mesh rule: 12 925 tetrahedra, ~93 000
# estimated DOFs), measured on this project's 2-core reference machine with one BLAS thread, as
# a worker runs them: the stage functions called in turn on one point (see run_sequential).
MESH_SECONDS = 1.5
"""Gmsh meshing of the article's drill, s (measured 1.44 s)."""
MODAL_SECONDS = 4.5
"""The match stage without resonance matching (assembly + modal analysis), s (measured 4.5 s)."""
MATCHING_SECONDS = 16.5
"""The match stage with resonance matching (``settings.match``), s (measured 16.2 s)."""
HARMONIC_SECONDS = 4.5
"""Harmonic response and modal basis at the working mode, s (measured 4.2-4.5 s)."""
IMPACT_SECONDS = 0.5
"""Impact statistics: the fixed part (amplitude iteration, first batch), s (measured 0.45 s)."""
IMPACT_MEMBER_SECONDS = 1.2e-3
"""Impact statistics per ensemble member, s (256 members 0.73 s, 1024 members 1.59 s); the
estimate takes ``settings.max_members`` members, the most a point can take."""
REFERENCE_DOFS = 93_056
"""``geometry.guard.estimate`` of the article's drill at its own mesh rule: FE stage times scale
from it."""
FE_COST_EXPONENT = 1.3
"""FE stage time ~ estimated DOFs ** 1.3 (the article's drill at mesh_size 2.5 and 2 mm: 2.7x and
5.1x the DOFs took 2.6-3.1x and 7.0-8.6x the modal and harmonic time)."""
ROTOR_SECONDS = 0.25
"""The rotor stage of one point (torque-speed curve and hovering check at the teeth motion, the
curve at the eight corners of its error box), s (measured 0.19-0.20 s CPU warm)."""
TEETH_ERROR_SECONDS = 4.5
"""The discretisation-error estimate of a harmonic task's teeth motion (one solve on a 1.4x
coarser mesh), s (the pipeline's ``discretisation_error_s`` of the article's drill: 4.3 s)."""
STARTUP_SECONDS = 5.0
"""Starting a local cluster and writing the results folder, s."""
MAX_HOURS = 2.0
"""Budget of the command line: a study estimated longer is refused unless ``--allow-large``."""


@dataclass(frozen=True)
class CostEstimate:
    """Predicted cost of a study's points (see :func:`estimate_cost`).

    Attributes
    ----------
    seconds : float
        Wall time on ``workers`` workers, s.
    core_seconds : float
        Computing time summed over the tasks, s.
    points, meshes, harmonics, workers : int
        Points, unique designs (mesh and match tasks), unique harmonic tasks, workers.
    dofs : int
        Estimated FE degrees of freedom of the base design at the study's mesh size.
    """

    seconds: float
    core_seconds: float
    points: int
    meshes: int
    harmonics: int
    workers: int
    dofs: int

    def describe(self) -> str:
        return (f"{_duration(self.seconds)} on {self.workers} workers ({self.points} points: {self.meshes} meshes, "
                f"{self.harmonics} harmonic analyses of ~{self.dofs:,} DOFs, {self.core_seconds / 3600:.3g} "
                "core-hours)")


def estimate_cost(study: Study, points: list[dict], workers: int) -> CostEstimate:
    """Wall time of ``points`` of ``study`` on ``workers`` workers.

    Points that share their design share the mesh and match tasks and, with the same
    ``q_mech``, the harmonic task (as :func:`explore` schedules them); every point has its own
    impact task. Stage times are the constants above, scaled by the base design's estimated
    DOFs as the study meshes it (the sector on the sector path).
    """
    from geometry.guard import estimate, sector_estimate

    design = study.base_design()
    opt = study.settings.mesh_options().budget(design)
    size = study.settings.mesh_size or None
    dofs = (sector_estimate(design, opt["sectors"], size, opt["refine"]) if "sectors" in opt
            else estimate(design, size, **opt)).dofs
    scale = (dofs / REFERENCE_DOFS) ** FE_COST_EXPONENT
    splits = [split_point(study, p) for p in points]
    meshes = len({json.dumps(d, sort_keys=True) for d, _, _, _ in splits})
    harmonics = (len({json.dumps([d, q], sort_keys=True) for d, q, _, _ in splits})
                 if "harmonic" in study.stages else 0)
    match_s = (MATCHING_SECONDS if study.settings.match else MODAL_SECONDS) if "match" in study.stages else 0.0
    core = (meshes * (MESH_SECONDS + match_s) + harmonics * HARMONIC_SECONDS) * scale
    if "impact" in study.stages:
        core += len(points) * (IMPACT_SECONDS + IMPACT_MEMBER_SECONDS * study.settings.max_members)
    if "rotor" in study.stages:
        core += len(points) * ROTOR_SECONDS + harmonics * TEETH_ERROR_SECONDS * scale
    workers = max(workers, 1)
    return CostEstimate(seconds=STARTUP_SECONDS + core / workers, core_seconds=core, points=len(points),
                        meshes=meshes, harmonics=harmonics, workers=workers, dofs=dofs)


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def check_cost(study: Study, points: list[dict], workers: int, max_hours: float | None) -> CostEstimate | None:
    """Refuse a study estimated longer than ``max_hours`` or above the FE size budget."""
    if not points:
        return None
    from geometry.guard import MAX_DOFS

    cost = estimate_cost(study, points, workers)
    log.info("study %s: estimated %s", study.name, cost.describe())
    if max_hours is None:
        return cost
    if cost.seconds > max_hours * 3600:
        raise ParameterError("study", f"{cost.points} points", f"estimated {cost.describe()}, above the budget of "
                                      f"{max_hours:g} h: pass --allow-large to run it anyway, or sample fewer points")
    if cost.dofs > MAX_DOFS:
        raise ParameterError("settings.mesh_size", study.settings.mesh_size,
                             f"gives ~{cost.dofs:,} DOFs per point, above the budget of {MAX_DOFS:,}: use a larger "
                             "mesh_size, or pass --allow-large")
    return cost



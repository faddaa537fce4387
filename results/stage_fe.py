"""The finite-element stages: mesh the design, then match it (or take it as it is) to its working mode.

Both the end-to-end run (:func:`results.pipeline.run_pipeline`) and the design studies
(:mod:`results.explore`) call these functions with the same :class:`MeshOptions`, so a mesh rule
or a matching fix reaches both at once.

Two paths (:mod:`fem.sector_system`): a design that can be swept as a sector is solved on the
``k = 0`` swept sector, which holds every response the axisymmetric stack drives (the working
mode, its anti-resonance, the torsion, the harmonic response, the ring-up) on about a sixth of
the unknowns, converged within ~0.03 % on the article's drill; any other design on the whole
drill (swept where it can be, graded). :func:`fem.sector_system.default_path` picks, as every
command and the library do, so one design gives one answer.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass
from typing import Any, Callable

log = logging.getLogger(__name__)

__all__ = ["MeshOptions", "Meshed", "mesh_stage", "Matched", "match_stage"]


@dataclass(frozen=True)
class MeshOptions:
    """How a design is meshed (SI units).

    Attributes
    ----------
    mesh_size : float or None
        Mesh size override, m (None: the design's elements-per-wavelength rule).
    refine : float
        Factor scaling every size rule (:mod:`geometry.sizing`; < 1 refines).
    grade : bool or None
        Grade the mesh toward the re-entrant edges (None: the path's own rule: the sector's notch
        grading on the sector path, graded on the whole drill).
    mesher : str
        Whole-drill path: ``"free"``, ``"revolve"`` or ``"auto"`` (swept where it can be,
        :mod:`geometry.revolve`).
    path : str or None
        ``"sector"``, ``"whole"`` or None (:func:`fem.sector_system.default_path`).
    """

    mesh_size: float | None = None
    refine: float = 1.0
    grade: bool | None = None
    mesher: str = "auto"
    path: str | None = None

    def __post_init__(self):
        from fem.sector_system import PATHS
        from geometry.revolve import MESHERS
        from geometry.sizing import check_refine
        from rpud_common import ParameterError, check_choice, check_positive

        if self.mesh_size is not None:
            check_positive("mesh_size", self.mesh_size, "m")
        check_refine(self.refine)
        check_choice("mesher", self.mesher, MESHERS)
        if self.path is not None:
            check_choice("path", self.path, ("auto",) + PATHS)
        if self.path == "sector" and self.mesher != "auto":
            raise ParameterError("mesher", self.mesher, "applies to the whole drill; the sector path has its own "
                                 "swept mesh (leave the mesher on auto)")

    def resolved(self, design) -> "MeshOptions":
        """These options for ``design``: its path (a ParameterError if it cannot take the one asked,
        refused before any meshing), the mesher and the grading of that path."""
        from fem.sector_system import check_path, whole_grade
        from geometry.revolve import resolve_mesher

        asked = self.path if self.path not in (None, "auto") else ("whole" if self.mesher != "auto" else None)
        path = check_path(design, asked)          # a mesher asked for is a whole-drill mesh
        if path == "sector":
            return dataclasses.replace(self, path=path, grade=bool(self.grade))
        return dataclasses.replace(self, path=path, grade=whole_grade(design) if self.grade is None else self.grade,
                                   mesher=resolve_mesher(design, self.mesher))

    def budget(self, design) -> dict:
        """The keyword arguments of :func:`geometry.guard.check_budget` that size the mesh these
        options run for ``design`` (the sector on the sector path)."""
        from geometry.sector import symmetry_order

        opt = self.resolved(design)
        if opt.path == "sector":
            return {"refine": opt.refine, "grade": opt.grade, "mesher": "revolve",
                    "sectors": symmetry_order(design) or 6}
        return {"refine": opt.refine, "grade": opt.grade, "mesher": opt.mesher}

    def label(self, design) -> str:
        """The mesh these (resolved) options run, in words (:func:`fem.sector_system.path_label`)."""
        from fem.sector_system import path_label

        if self.path == "whole" and self.mesher == "free":
            text = path_label(design, "whole", refine=self.refine, grade=self.grade, mesh_size=self.mesh_size)
            return text.replace("swept (r, z) section, coupler free", "free")
        return path_label(design, self.path, refine=self.refine, grade=self.grade, mesh_size=self.mesh_size)


@dataclass(frozen=True)
class Meshed:
    """A design and its mesh (:func:`mesh_stage`), not assembled: the matching assembles morphed
    copies of the mesh only, so an assembly of this one would go unused.

    Attributes
    ----------
    design, mesh, options, seconds
        The design, its mesh, the resolved :class:`MeshOptions` and the meshing's wall time, s.
    sectors : int
        ``N`` of the swept ``k = 0`` sector mesh on the sector path, 0 on the whole drill.
    """

    design: Any
    mesh: Any
    options: MeshOptions
    seconds: float
    sectors: int = 0

    def record(self) -> dict:
        """Mesh size figures (a study's table columns)."""
        return {"tetrahedra": self.mesh.n_cells, "nodes": self.mesh.n_points, "mesh_s": self.seconds}

    def system_of(self, mesh=None):
        """The system ``mesh`` (default this mesh; a morphed copy of it in the matching) is solved
        as: the ``k = 0`` restriction of its assembly on the sector path
        (:func:`fem.sector_system.sector_system`), else its assembly."""
        from fem.assembly import assemble
        from fem.sector_system import sector_system

        mesh = self.mesh if mesh is None else mesh
        if not self.sectors:
            return assemble(mesh)
        return sector_system(assemble(mesh, order=2), self.sectors, label=self.options.label(self.design))


def mesh_stage(design, options: MeshOptions) -> Meshed:
    """Mesh ``design`` (Gmsh, second-order tetrahedra) as ``options`` say."""
    import geometry

    t0 = time.perf_counter()
    options = options.resolved(design)
    if options.path == "sector":
        mesh, sectors = _sector_mesh(design, options)
        return Meshed(design, mesh, options, time.perf_counter() - t0, sectors)
    mesh = geometry.build_mesh(design, mesh_size=options.mesh_size, refine=options.refine, grade=options.grade,
                               mesher=options.mesher)
    return Meshed(design, mesh, options, time.perf_counter() - t0)


def _sector_mesh(design, options: MeshOptions):
    from fem.sector_system import sector_mesh

    return sector_mesh(design, refine=options.refine, grade=options.grade, mesh_size=options.mesh_size)


@dataclass(frozen=True)
class Matched:
    """The working mode of a (matched) design (:func:`match_stage`).

    Attributes
    ----------
    design, mesh, system, modal
        The tuned design (the input design without matching), its mesh, the assembled
        :class:`fem.assembly.PiezoSystem` and the :class:`fem.modal.ModalResult` around the target.
    w : int
        Index of the working mode in ``modal``.
    matching : fem.matching.MatchResult or None
        The matching run (None: the design analysed as it is).
    options : MeshOptions
    seconds : float
    """

    design: Any
    mesh: Any
    system: Any
    modal: Any
    w: int
    matching: Any
    options: MeshOptions
    seconds: float

    @property
    def f_r_hz(self) -> float:
        return float(self.modal.f_r_hz[self.w])

    @property
    def f_a_hz(self) -> float:
        return float(self.modal.f_a_hz[self.w])

    @property
    def k_eff(self) -> float:
        return float(self.modal.k_eff[self.w])

    def record(self) -> dict:
        """The working mode's figures and the tuned lengths (a study's table columns)."""
        rec: dict[str, float] = {}
        if self.matching is not None:
            rec["matched"] = float(self.matching.converged)
            rec.update({f"tuned.{k}": float(v) for k, v in self.matching.tuned.items()})
        rec.update({"f_r_hz": self.f_r_hz, "f_a_hz": self.f_a_hz, "k_eff": self.k_eff, "match_s": self.seconds})
        return rec


def match_stage(meshed: Meshed, *, match: bool = True, tune: tuple[str, ...] | None = None,
                progress: Callable[[dict], None] | None = None) -> Matched:
    """Tune the design to its target frequency (:func:`fem.matching.match`) on ``meshed``'s mesh, or
    (``match`` False) assemble it and find its working mode as it is.

    ``tune``: the lengths matched (default :func:`fem.matching.default_tune`); ``progress`` is
    called after every matching iteration (:func:`fem.matching.match`).
    """
    from fem.matching import MatchSettings, default_tune
    from fem.matching import match as run_match

    t0 = time.perf_counter()
    design, mesh, opt = meshed.design, meshed.mesh, meshed.options
    target = float(design.target_frequency)
    if not match:
        system, modal, w = _as_it_is(meshed, target)
        return Matched(design, mesh, system, modal, w, None, opt, time.perf_counter() - t0)
    settings = MatchSettings(target_hz=target, mesh_size=opt.mesh_size, refine=opt.refine, grade=opt.grade,
                             mesher=opt.mesher, tune=tune or default_tune(design))
    hooks = {}
    if opt.path == "sector":
        hooks = {"system_of": meshed.system_of, "remesh": lambda d: _sector_mesh(d, opt)[0]}
    m = run_match(design, settings, mesh=mesh, progress=progress, **hooks)
    return Matched(m.design, m.mesh, m.system, m.modal, m.working_index, m, opt, time.perf_counter() - t0)


def _as_it_is(meshed: Meshed, target: float):
    from fem.matching import working_mode
    from fem.modal import modal_analysis

    system = meshed.system_of()
    modal = modal_analysis(system, target, 4)
    return system, modal, working_mode(system, modal.f_r_hz, modal.vectors, target)

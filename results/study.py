"""A design study: which parameters vary, how they are sampled, which stages run.

A study file (TOML) names a base design, the parameters and their ranges, the sampling and the
stages; :func:`load_study` validates it and :meth:`Study.points` expands it into the list of
points that :mod:`results.explore` runs::

    [study]
    name = "slot_angle"
    design = "default"            # or a design TOML, relative to the study file
    select = ""                   # the design's name in a file of several designs
    stages = ["mesh", "match", "harmonic"]   # a prefix of mesh -> match -> harmonic -> impact, + "rotor"
    sampling = "grid"             # grid | lhs | list | tolerance
    samples = 8                   # lhs / tolerance: number of points
    seed = 1                      # lhs / tolerance sampling and the impact ensembles
    outputs = ["f_r_hz", "teeth_ellipse_ratio"]   # plotted (the table has every output)
    pareto = ["teeth_ellipse_ratio", "tip_per_volt_m"]

    [settings]                    # fixed for every point (SI units)
    voltage = 225.0
    q_mech = 100.0
    mesh_size = 0.0               # 0: the design's own rule
    refine = 1.0                  # mesh refinement factor (< 1 refines), as python -m results --refine
    path = "auto"                 # auto (the sector where the design can be swept) | sector | whole
    # grade = true / false: the mesh graded or not (absent: the path's own rule, as python -m results)

    [parameters."coupler.slot_angle_deg"]
    values = [20.0, 30.0, 40.0]   # grid levels
    [parameters."impact.m_free"]
    range = [0.002, 0.008]        # grid (with n) or lhs
    n = 3
    [parameters."horn.length"]
    tolerance = 0.02              # tolerance sampling: +-2 % around the base value

Parameter names: a dotted design path (``horn.length``), ``drive.voltage`` (V) or
``drive.q_mech``, ``impact.<field>`` of :class:`impact.params.ImpactParams` (``m_free`` kg,
``e1``, ``gap`` m...), or ``rotor.<field>`` of :class:`impact.rotor.RotorParams` (``preload`` N,
``mu``, ``rotor_mass`` kg...; the ``rotor`` stage, which needs ``harmonic``, turns the teeth
motion into the rotor's speed and torque, :func:`results.rotor_stage.study_rotor`). The coupler's
dimensions reach the rotor through the design (contact radius, teeth, tooth area). Sampling
``list`` takes ``[[points]]`` tables instead of ranges.

Every key is checked by type and range on loading, before anything runs; a key the sampling
does not read (a tolerance under grid sampling, ``[parameters]`` tables under list sampling) is
refused rather than ignored, as is a varied design field that is not a number.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from rpud_common import ParameterError, check_choice, check_finite, check_integer, check_range, load_toml
from fem.losses import ASSEMBLED_Q_MECH

__all__ = ["Study", "StudyParameter", "StudySettings", "load_study", "STAGES", "SAMPLINGS", "OUTPUTS"]

CHAIN = ("mesh", "match", "harmonic", "impact")
STAGES = CHAIN + ("rotor",)
"""Every stage name: a prefix of :data:`CHAIN`, plus ``rotor`` (after ``harmonic``) if named."""
SAMPLINGS = ("grid", "lhs", "list", "tolerance")
MAX_POINTS = 100_000

#: output -> (stage that produces it, unit, description); impact outputs carry a 95 % CI column
#: (``<name>_ci95``), the rotor's speeds and torque an error column (``<name>_error``)
OUTPUTS = {
    "tetrahedra": ("mesh", "-", "tetrahedra of the mesh"),
    "nodes": ("mesh", "-", "mesh nodes"),
    "f_r_hz": ("match", "Hz", "working mode resonance (short circuit)"),
    "f_a_hz": ("match", "Hz", "working mode anti-resonance (open circuit)"),
    "k_eff": ("match", "-", "effective electromechanical coupling of the working mode"),
    "matched": ("match", "-", "resonance matching converged (1) or not (0)"),
    "tip_per_volt_m": ("harmonic", "m/V", "horn-tip amplitude per volt at f_r"),
    "A0_unloaded_m": ("harmonic", "m", "horn-tip amplitude at the drive voltage, no impacts"),
    "teeth_ellipse_ratio": ("harmonic", "-", "torsional / axial motion of the coupler teeth"),
    "power_w": ("harmonic", "W", "electrical power at the drive voltage, no impacts"),
    "A0_m": ("impact", "m", "horn-tip amplitude loaded by the impacts"),
    "tool_ke_j": ("impact", "J", "drill-tool kinetic energy after a tool impact (95 % CI)"),
    "ke_gain_j": ("impact", "J", "tool kinetic energy gained per tool impact (95 % CI)"),
    "tool_power_w": ("impact", "W", "kinetic energy delivered to the tool per second (95 % CI)"),
    "tool_rate_hz": ("impact", "Hz", "free-mass/tool impacts per second (95 % CI)"),
    "horn_power_w": ("impact", "W", "work of the horn on the free mass per second (95 % CI)"),
    "rotor_no_load_rpm": ("rotor", "rpm", "rotor speed without load (hovering model)"),
    "rotor_stall_torque_n_m": ("rotor", "N m", "rotor's mean driving torque at rest"),
    "rotor_load_rpm": ("rotor", "rpm", "rotor speed under the bit's friction torque"),
    "rotor_hovers": ("rotor", "-", "direct integration keeps the rotor on the teeth (1) or it bounces (0)"),
}
ROTOR_ERRORS = ("rotor_no_load_rpm", "rotor_stall_torque_n_m", "rotor_load_rpm")
"""Rotor outputs with an ``<name>_error`` column: their largest departure over the corners of the
teeth motion's error box (:func:`results.rotor_stage.study_rotor`)."""
IMPACT_FIELDS = ("m_free", "e1", "e2", "m_tool", "k0", "c", "gap", "v0", "spring_force")
DRIVE_FIELDS = ("voltage", "q_mech")
ROTOR_FIELDS = ("preload", "spring_stiffness", "mu", "rotor_mass", "rotor_inertia", "k_normal", "k_tangential")
GROUPS = ("drive", "impact", "rotor")
"""Parameter groups that are not design paths."""


@dataclass(frozen=True)
class StudyParameter:
    """One varied parameter.

    Attributes
    ----------
    name : str
        Dotted design path, ``drive.<voltage|q_mech>``, ``impact.<field>`` or ``rotor.<field>``.
    values : tuple of float
        Explicit levels (grid sampling).
    low, high : float or None
        Range (grid with ``n`` levels, or Latin hypercube).
    n : int
        Levels of a grid range.
    tolerance : float or None
        Relative half-width around the base value (tolerance sampling).
    """

    name: str
    values: tuple[float, ...] = ()
    low: float | None = None
    high: float | None = None
    n: int = 0
    tolerance: float | None = None

    @property
    def group(self) -> str:
        """``design``, ``drive``, ``impact`` or ``rotor``: which stage the parameter first reaches."""
        head = self.name.split(".", 1)[0]
        return head if head in GROUPS else "design"

    def levels(self) -> list[float]:
        if self.values:
            return list(self.values)
        return list(np.linspace(self.low, self.high, self.n)) if self.n > 1 else [self.low]


@dataclass(frozen=True)
class StudySettings:
    """Fixed settings of every point (SI units; see :class:`results.pipeline.PipelineSettings`)."""

    voltage: float = 225.0
    q_mech: float = ASSEMBLED_Q_MECH
    mesh_size: float = 0.0
    refine: float = 1.0
    grade: bool | None = None
    mesher: str = "auto"
    path: str = "auto"
    match: bool = True
    scenario: str = "device"
    rel_tol: float = 0.05
    max_members: int = 1024
    tip_surface: str = ""

    def __post_init__(self):
        check_range("settings.voltage", self.voltage, 1e-3, 1e4, "V")
        check_range("settings.q_mech", self.q_mech, 1.0, 1e6)
        if self.mesh_size != 0:
            check_range("settings.mesh_size", self.mesh_size, 1e-5, 1.0, "m (0: the design's rule)")
        from geometry.sizing import check_refine

        check_refine(self.refine, "settings.refine")
        from geometry.revolve import MESHERS

        check_choice("settings.mesher", self.mesher, MESHERS)
        check_choice("settings.path", self.path, ("auto", "sector", "whole"))
        check_choice("settings.scenario", self.scenario, ("device", "article"))
        check_range("settings.rel_tol", self.rel_tol, 0.0, 1.0, lo_open=True)
        check_integer("settings.max_members", self.max_members, 2, 1_000_000)

    def mesh_options(self):
        """How every point's design is meshed (:class:`results.stage_fe.MeshOptions`), as the
        end-to-end run meshes it with the same settings."""
        from .stage_fe import MeshOptions

        return MeshOptions(mesh_size=self.mesh_size or None, refine=self.refine, grade=self.grade,
                           mesher=self.mesher, path=self.path)


@dataclass(frozen=True)
class Study:
    """A validated study (see the module docstring for the file layout)."""

    name: str
    design: str
    stages: tuple[str, ...]
    sampling: str
    parameters: tuple[StudyParameter, ...]
    settings: StudySettings = StudySettings()
    samples: int = 0
    seed: int = 1
    outputs: tuple[str, ...] = ()
    pareto: tuple[str, ...] = ()
    listed: tuple[dict, ...] = field(default=(), repr=False)
    base_dir: str = "."
    select: str = ""

    def base_design(self):
        """The base design object (geometry is imported here, not at module import)."""
        if self.design == "default":
            from geometry.design_rpud import default_design

            return default_design()
        from geometry.design import load_design

        return load_design(self.design_path, self.select or None)

    @property
    def design_path(self) -> Path:
        p = Path(self.design)
        return p if p.is_absolute() else Path(self.base_dir) / p

    def base_value(self, p: StudyParameter, design=None) -> float:
        """The value of ``p`` in the base design / settings / impact defaults."""
        group, _, rest = p.name.partition(".")
        if p.group == "drive":
            return float(getattr(self.settings, rest))
        if p.group in ("impact", "rotor"):
            return _base_of(p, self.settings)
        return float((design or self.base_design()).get(p.name))

    def points(self, design=None) -> list[dict[str, float]]:
        """Every point: ``{parameter name: value}``, in a fixed order."""
        names = [p.name for p in self.parameters]
        if self.sampling == "grid":
            pts = [dict(zip(names, combo)) for combo in itertools.product(*(p.levels() for p in self.parameters))]
        elif self.sampling == "list":
            pts = [dict(d) for d in self.listed]
        else:
            from scipy.stats import qmc

            u = qmc.LatinHypercube(d=len(names), seed=self.seed).random(self.samples)
            if self.sampling == "lhs":
                lo = np.array([p.low for p in self.parameters])
                hi = np.array([p.high for p in self.parameters])
                pts = [dict(zip(names, map(float, lo + row * (hi - lo)))) for row in u]
            else:
                base = np.array([self.base_value(p, design) for p in self.parameters])
                tol = np.array([p.tolerance for p in self.parameters])
                nominal = dict(zip(names, map(float, base)))
                pts = [nominal] + [dict(zip(names, map(float, base * (1 + tol * (2 * row - 1))))) for row in u]
        return [{k: float(v) for k, v in p.items()} for p in pts]

    def fingerprint(self) -> str:
        """Hash of everything that changes a point's numbers (not its name or outputs)."""
        design = (self.design if self.design == "default"
                  else hashlib.sha256(self.design_path.read_bytes()).hexdigest())
        blob = json.dumps({"design": design, "select": self.select, "stages": self.stages, "seed": self.seed,
                           "settings": {f.name: getattr(self.settings, f.name) for f in fields(self.settings)}},
                          sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


# ------------------------------------------------------------------------------ loading

MAX_PARAMETERS = 32
"""Most varied parameters of a study (a hypercube's memory grows with points x parameters)."""

MAX_LEVELS = 1000
"""Most levels of one grid parameter."""

_NAME_PART = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_STUDY_KEYS = ("name", "design", "select", "stages", "sampling", "samples", "seed", "outputs", "pareto")
_PARAMETER_KEYS = ("values", "range", "n", "tolerance")


def _number(where: str, v: Any) -> float:
    check_finite(where, v)
    x = float(v)
    if x != 0 and not 1e-12 <= abs(x) <= 1e12:
        raise ParameterError(where, v, "must be 0 or of magnitude 1e-12 to 1e12 (SI units)")
    return x


def _text(where: str, v: Any, allowed: str, limit: int = 200) -> str:
    if not isinstance(v, str) or len(v) > limit or not v.isprintable():
        raise ParameterError(where, v, allowed)
    return v


def _unknown_keys(where: str, table: Mapping, allowed: tuple[str, ...], hint: str = "") -> None:
    for key in table:
        if key not in allowed:
            raise ParameterError(f"{where}.{key}", table[key], f"unknown key: use {', '.join(allowed)}{hint}")


def _names(where: str, v: Any, choices: tuple[str, ...]) -> tuple[str, ...]:
    """A list of distinct names out of ``choices``; a ParameterError names the first bad one."""
    if not isinstance(v, list):
        raise ParameterError(where, v, f"must be a list of names out of {', '.join(choices)}")
    seen: set[str] = set()
    for item in v:
        if not isinstance(item, str) or item not in choices:
            raise ParameterError(where, item, f"unknown name: use {', '.join(choices)}")
        if item in seen:
            raise ParameterError(where, item, "is named twice")
        seen.add(item)
    return tuple(v)


def _study_table(data: Mapping[str, Any]) -> dict[str, Any]:
    """The checked ``[study]`` table: every key by type and range, with the defaults filled in."""
    s = data.get("study")
    if not isinstance(s, Mapping):
        raise ParameterError("study", s, "a [study] table is required")
    _unknown_keys("study", s, _STUDY_KEYS)
    name = s.get("name", "study")
    if not isinstance(name, str) or not name or len(name) > 80 or not all(c.isalnum() or c in "-_." for c in name):
        raise ParameterError("study.name", name, "must be 1-80 characters of letters, digits, - _ .")
    design = _text("study.design", s.get("design", "default"), "must be 'default' or the path of a design TOML",
                   limit=4096)
    select = _text("study.select", s.get("select", ""), "must be the name of a design in the design file")
    if not design.strip():
        raise ParameterError("study.design", design, "must be 'default' or the path of a design TOML")
    if select and design == "default":
        raise ParameterError("study.select", select, "picks a design out of a design file; the default design has "
                                                     "no choice (remove select or name a file in design)")
    stages = _names("study.stages", s.get("stages", list(CHAIN)), STAGES)
    chain = tuple(x for x in stages if x != "rotor")
    if not chain or chain != CHAIN[:len(chain)] or ("rotor" in stages and "harmonic" not in chain):
        raise ParameterError("study.stages", list(stages), f"must be a prefix of {list(CHAIN)}, plus 'rotor' if "
                                                           "'harmonic' is in it")
    sampling = s.get("sampling", "grid")
    check_choice("study.sampling", sampling, SAMPLINGS)
    seed = s.get("seed", 1)
    check_integer("study.seed", seed, 0, 2 ** 32 - 1)
    samples = s.get("samples", 0)
    if sampling in ("lhs", "tolerance"):
        check_integer("study.samples", samples, 1, MAX_POINTS - (sampling == "tolerance"))
    else:
        check_integer("study.samples", samples, 0, MAX_POINTS)
    outputs = _names("study.outputs", s.get("outputs", []), tuple(OUTPUTS))
    pareto = _names("study.pareto", s.get("pareto", []), tuple(OUTPUTS))
    if pareto and len(pareto) != 2:
        raise ParameterError("study.pareto", list(pareto), "must name two different outputs (both maximised)")
    for where, names in (("study.outputs", outputs), ("study.pareto", pareto)):
        for o in names:
            if OUTPUTS[o][0] not in stages:
                raise ParameterError(where, o, f"needs the {OUTPUTS[o][0]!r} stage in study.stages")
    return dict(name=name, design=design, select=select, stages=stages, sampling=sampling, seed=int(seed),
                samples=int(samples), outputs=outputs, pareto=pareto)


def _settings(raw: Any) -> StudySettings:
    """The ``[settings]`` table, each key checked by type before its range."""
    if not isinstance(raw, Mapping):
        raise ParameterError("settings", raw, "must be a table")
    known = tuple(f.name for f in fields(StudySettings))
    _unknown_keys("settings", raw, known)
    kw = {}
    for key, v in raw.items():
        where = f"settings.{key}"
        if key in ("match", "grade"):
            if not isinstance(v, bool):
                raise ParameterError(where, v, "must be true or false")
        elif key == "scenario":
            v = _text(where, v, "must be 'device' or 'article'")
        elif key == "mesher":
            v = _text(where, v, "must be 'free', 'revolve' or 'auto'")
        elif key == "path":
            v = _text(where, v, "must be 'auto', 'sector' or 'whole'")
        elif key == "tip_surface":
            if not isinstance(v, str) or (v and not _NAME_PART.match(v)) or len(v) > 64:
                raise ParameterError(where, v, "must be the name of a surface of the mesh ('' picks horn_tip)")
        elif key == "max_members":
            check_integer(where, v, 2, 1_000_000)
        else:
            v = _number(where, v)
        kw[key] = v
    return StudySettings(**kw)


def _parameter_name(where: str, name: Any) -> str:
    """A dotted design path, ``drive.<field>``, ``impact.<field>`` or ``rotor.<field>``."""
    parts = name.split(".") if isinstance(name, str) and len(name) <= 200 else [""]
    if not all(_NAME_PART.match(part) for part in parts):
        raise ParameterError(where, name, "must be a dotted design path such as horn.length, drive.voltage or "
                                          "impact.m_free (quote it: [parameters.\"horn.length\"])")
    group, _, rest = name.partition(".")
    if group == "drive" and rest not in DRIVE_FIELDS:
        raise ParameterError(where, name, f"drive parameters are {', '.join('drive.' + f for f in DRIVE_FIELDS)}")
    if group == "impact" and rest not in IMPACT_FIELDS:
        raise ParameterError(where, name, f"impact parameters are {', '.join('impact.' + f for f in IMPACT_FIELDS)}")
    if group == "rotor" and rest not in ROTOR_FIELDS:
        raise ParameterError(where, name, f"rotor parameters are {', '.join('rotor.' + f for f in ROTOR_FIELDS)}")
    return name


def _values(where: str, v: Any) -> tuple[float, ...]:
    if not isinstance(v, list) or not 1 <= len(v) <= MAX_LEVELS:
        raise ParameterError(where, v, f"must be a list of 1 to {MAX_LEVELS} numbers")
    values = tuple(_number(where, x) for x in v)
    if len(set(values)) != len(values):
        twice = next(x for x in values if values.count(x) > 1)
        raise ParameterError(where, twice, "is listed twice: every level must differ")
    return values


def _range(where: str, r: Any) -> tuple[float, float]:
    if not isinstance(r, list) or len(r) != 2:
        raise ParameterError(where, r, "must be [low, high]")
    low, high = _number(where, r[0]), _number(where, r[1])
    if not low < high:
        raise ParameterError(where, r, "must have low < high")
    return low, high


def _parameter(name: str, table: Any, sampling: str) -> StudyParameter:
    where = f"parameters.{name}"
    _parameter_name(where, name)
    if sampling == "list":
        raise ParameterError(where, table, "list sampling takes every value from the [[points]] tables: remove "
                                           "the [parameters] tables")
    if not isinstance(table, Mapping):
        raise ParameterError(where, table, "must be a table with values, range (+ n) or tolerance")
    _unknown_keys(where, table, _PARAMETER_KEYS, " (quote a dotted name: [parameters.\"horn.length\"])")
    values = _values(f"{where}.values", table["values"]) if "values" in table else ()
    low, high = _range(f"{where}.range", table["range"]) if "range" in table else (None, None)
    n, tol = table.get("n", 0), table.get("tolerance")
    if sampling == "grid":
        if bool(values) == (low is not None):
            raise ParameterError(where, table, "grid sampling: give either values or range with n")
        if low is not None:
            check_integer(f"{where}.n", n, 2, MAX_LEVELS)
        used = ("values",) if values else ("range", "n")
    elif sampling == "lhs":
        if low is None:
            raise ParameterError(where, table, "lhs sampling: give range = [low, high]")
        used = ("range",)
    else:
        if tol is None:
            raise ParameterError(where, table, "tolerance sampling: give tolerance (relative, e.g. 0.02)")
        tol = _number(f"{where}.tolerance", tol)
        check_range(f"{where}.tolerance", tol, 0.0, 0.5, lo_open=True)
        used = ("tolerance",)
    for key in table:
        if key not in used:
            raise ParameterError(f"{where}.{key}", table[key], f"is not used by {sampling} sampling (it takes "
                                                               f"{' and '.join(used)})")
    return StudyParameter(name=name, values=values, low=low, high=high, n=int(n),
                          tolerance=None if tol is None else float(tol))


def _parameters(raw: Any, sampling: str) -> tuple[StudyParameter, ...]:
    if not isinstance(raw, Mapping):
        raise ParameterError("parameters", raw, "must be tables [parameters.\"<name>\"]")
    if not raw and sampling != "list":
        raise ParameterError("parameters", raw, "name at least one [parameters.\"<name>\"] table")
    if len(raw) > MAX_PARAMETERS:
        raise ParameterError("parameters", f"{len(raw)} tables", f"at most {MAX_PARAMETERS} parameters per study")
    return tuple(_parameter(k, v, sampling) for k, v in raw.items())


def _listed(pts: Any) -> tuple[tuple[StudyParameter, ...], tuple[dict, ...]]:
    """The ``[[points]]`` of list sampling: the same parameters in each, every point different."""
    if not isinstance(pts, list) or not pts or not isinstance(pts[0], Mapping) or not pts[0]:
        raise ParameterError("points", pts, "list sampling needs [[points]] tables, each setting the same parameters")
    if len(pts) > MAX_POINTS:
        raise ParameterError("points", f"{len(pts)} tables", f"at most {MAX_POINTS} points per study")
    names = sorted(pts[0], key=str)
    if len(names) > MAX_PARAMETERS:
        raise ParameterError("points[0]", f"{len(names)} parameters", f"at most {MAX_PARAMETERS} per study")
    for k in names:
        _parameter_name(f"points[0].{k}", k)
    listed, seen = [], set()
    for i, p in enumerate(pts):
        if not isinstance(p, Mapping) or sorted(p, key=str) != names:
            raise ParameterError(f"points[{i}]", p, f"every point must set the same parameters {names}")
        point = {k: _number(f"points[{i}].{k}", p[k]) for k in names}
        values = tuple(point.values())
        if values in seen:
            raise ParameterError(f"points[{i}]", p, "repeats an earlier point: every point must differ")
        seen.add(values)
        listed.append(point)
    return tuple(StudyParameter(name=k) for k in names), tuple(listed)


def _base_of(p: StudyParameter, settings: StudySettings) -> float | None:
    """The base value of a drive, impact or rotor parameter (None for a design one: known on loading)."""
    group, _, rest = p.name.partition(".")
    if group == "drive":
        return float(getattr(settings, rest))
    if group == "impact":
        from impact.params import ImpactParams

        return float(getattr(ImpactParams(), rest))
    if group == "rotor":
        from impact.rotor import RotorParams

        return float(getattr(RotorParams(), rest))
    return None


def _extremes(p: StudyParameter, listed: tuple[dict, ...], base: float | None) -> list[float]:
    """The smallest and largest value a parameter takes in the study."""
    if p.values:
        return [min(p.values), max(p.values)]
    if p.low is not None:
        return [p.low, p.high]
    if p.tolerance is not None:
        return [] if base is None else [base * (1 - p.tolerance), base * (1 + p.tolerance)]
    return [min(pt[p.name] for pt in listed), max(pt[p.name] for pt in listed)]


def _check_physical(p: StudyParameter, values: list[float]) -> None:
    """Drive and impact levels within the ranges their stage accepts (one point's failure is
    recorded, but a study whose every point fails is refused before it starts)."""
    where = f"parameters.{p.name}"
    group, _, rest = p.name.partition(".")
    if group == "drive":
        lo, hi, unit = (1e-3, 1e4, "V") if rest == "voltage" else (1.0, 1e6, "")
        for v in values:
            check_range(where, v, lo, hi, unit)
    elif group == "impact":
        from impact.params import ImpactParams

        for v in values:
            try:
                ImpactParams(A0=0.0).with_(**{rest: v})
            except ParameterError as exc:
                raise ParameterError(where, v, exc.allowed) from None
    elif group == "rotor":
        from impact.rotor import RotorParams

        for v in values:
            try:
                RotorParams().with_(**{rest: v})
            except ParameterError as exc:
                raise ParameterError(where, v, exc.allowed) from None


def _check_reach(params, stages: tuple[str, ...]) -> None:
    needed = {"design": "mesh", "drive": "harmonic", "impact": "impact", "rotor": "rotor"}
    for p in params:
        if needed[p.group] not in stages:
            raise ParameterError(f"parameters.{p.name}", p.name, f"needs the {needed[p.group]!r} stage in study.stages")


def _count_points(sampling: str, params, samples: int, listed) -> int:
    """Points a study expands to, counted without expanding it (a grid's count is a product)."""
    if sampling == "grid":
        return math.prod(len(p.values) or max(p.n, 1) for p in params)
    if sampling == "list":
        return len(listed)
    return samples + (sampling == "tolerance")


def study_from_mapping(data: Mapping[str, Any], base_dir: str | os.PathLike = ".") -> Study:
    """Validate a parsed study file; errors name the table and key.

    Every key is checked by type and range here, before anything is computed; the design's
    own fields are checked by :func:`load_study`, which reads the design.
    """
    if not isinstance(data, Mapping):
        raise ParameterError("study file", data, "must be TOML tables [study], [settings], [parameters.*]")
    for key in data:
        if key not in ("study", "settings", "parameters", "points"):
            raise ParameterError(str(key), data[key], "unknown table: use [study], [settings], [parameters.*], "
                                                      "[[points]]")
    head = _study_table(data)
    sampling = head["sampling"]
    settings = _settings(data.get("settings", {}))
    params = _parameters(data.get("parameters", {}), sampling)
    listed: tuple[dict, ...] = ()
    if sampling == "list":
        params, listed = _listed(data.get("points"))
    elif "points" in data:
        raise ParameterError("points", data["points"], f"[[points]] tables are read by list sampling only, not "
                                                       f"{sampling}")
    _check_reach(params, head["stages"])
    if not settings.match and "matched" in head["outputs"] + head["pareto"]:
        raise ParameterError("study.outputs", "matched", "needs settings.match = true (no matching, no flag)")
    for p in params:
        base = _base_of(p, settings)
        if p.tolerance is not None and base == 0:
            raise ParameterError(f"parameters.{p.name}", p.name, "has the base value 0: a relative tolerance "
                                                                 "around it is empty")
        _check_physical(p, _extremes(p, listed, base))
    n = _count_points(sampling, params, head["samples"], listed)
    if n > MAX_POINTS:
        raise ParameterError("parameters", f"{n} points", f"at most {MAX_POINTS} points per study")
    return Study(parameters=params, settings=settings, listed=listed, base_dir=str(base_dir), **head)


def _check_design_parameter(study: Study, p: StudyParameter, base) -> None:
    """A varied design field exists, is a number (an integer field takes whole numbers only) and,
    under tolerance sampling, has a nonzero base value."""
    where = f"parameters.{p.name}"
    try:
        value = base.get(p.name)
    except (KeyError, AttributeError, TypeError, ValueError):  # ParameterError is a ValueError
        raise ParameterError(where, p.name, "not a field of the design") from None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(where, p.name, f"is a {type(value).__name__} field of the design: only numeric "
                                            "fields can vary")
    if not math.isfinite(value):
        raise ParameterError(where, p.name, f"has the base value {value}: only finite fields can vary")
    if isinstance(value, (int, np.integer)):
        if study.sampling in ("lhs", "tolerance"):
            raise ParameterError(where, p.name, f"is an integer field: vary it by grid values or [[points]], not "
                                                f"{study.sampling} sampling")
        levels = p.levels() if study.sampling == "grid" else [pt[p.name] for pt in study.listed]
        for v in levels:
            if not float(v).is_integer():
                raise ParameterError(where, float(v), "is a level of an integer field: give whole numbers")
    if study.sampling == "tolerance" and value == 0:
        raise ParameterError(where, p.name, "has the base value 0: a relative tolerance around it is empty")


def _is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except OSError:     # a name too long for the file system, a loop of links
        return False


def load_study(path: str | os.PathLike) -> Study:
    """Read and validate a study TOML (see the module docstring)."""
    path = Path(path)
    try:
        data = load_toml(path, "study")
    except ParameterError:
        raise
    except ValueError as exc:   # tomllib's own limits, e.g. an integer of more than 4300 digits
        raise ParameterError("study", str(path), f"is not a usable TOML file ({exc})") from None
    study = study_from_mapping(data, base_dir=path.parent)
    if study.design != "default" and not _is_file(study.design_path):
        raise ParameterError("study.design", study.design, f"no design file at {str(study.design_path)!r}")
    base = study.base_design()
    for p in study.parameters:
        if p.group == "design":
            _check_design_parameter(study, p, base)
    return study

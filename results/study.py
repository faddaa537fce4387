"""A design study: which parameters vary, how they are sampled, which stages run.

A study file (TOML) names a base design, the parameters and their ranges, the sampling and the
stages; :func:`load_study` validates it and :meth:`Study.points` expands it into the list of
points that :mod:`results.explore` runs::

    [study]
    name = "slot_angle"
    design = "default"            # or a design TOML, relative to the study file
    select = ""                   # the design's name in a file of several designs
    stages = ["mesh", "match", "harmonic"]   # a prefix of mesh -> match -> harmonic -> impact
    sampling = "grid"             # grid | lhs | list | tolerance
    samples = 8                   # lhs / tolerance: number of points
    seed = 1                      # lhs / tolerance sampling and the impact ensembles
    outputs = ["f_r_hz", "teeth_ellipse_ratio"]   # plotted (the table has every output)
    pareto = ["teeth_ellipse_ratio", "tip_per_volt_m"]

    [settings]                    # fixed for every point (SI units)
    voltage = 225.0
    q_mech = 100.0
    mesh_size = 0.0               # 0: the design's own rule

    [parameters."coupler.slot_angle_deg"]
    values = [20.0, 30.0, 40.0]   # grid / list levels
    [parameters."impact.m_free"]
    range = [0.002, 0.008]        # grid (with n) or lhs
    n = 3
    [parameters."horn.length"]
    tolerance = 0.02              # tolerance sampling: +-2 % around the base value

Parameter names: a dotted design path (``horn.length``), ``drive.voltage`` (V) or
``drive.q_mech``, or ``impact.<field>`` of :class:`impact.params.ImpactParams` (``m_free`` kg,
``e1``, ``gap`` m...). Sampling ``list`` takes ``[[points]]`` tables instead of ranges.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from rpud_common import ParameterError, check_choice, check_integer, check_range, load_toml

__all__ = ["Study", "StudyParameter", "StudySettings", "load_study", "STAGES", "SAMPLINGS", "OUTPUTS"]

STAGES = ("mesh", "match", "harmonic", "impact")
SAMPLINGS = ("grid", "lhs", "list", "tolerance")
MAX_POINTS = 100_000

#: output -> (stage that produces it, unit, description); impact outputs carry a 95 % CI column
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
}
IMPACT_FIELDS = ("m_free", "e1", "e2", "m_tool", "k0", "c", "gap", "v0", "spring_force")
DRIVE_FIELDS = ("voltage", "q_mech")


@dataclass(frozen=True)
class StudyParameter:
    """One varied parameter.

    Attributes
    ----------
    name : str
        Dotted design path, ``drive.<voltage|q_mech>`` or ``impact.<field>``.
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
        """``design``, ``drive`` or ``impact``: which stage the parameter first reaches."""
        head = self.name.split(".", 1)[0]
        return head if head in ("drive", "impact") else "design"

    def levels(self) -> list[float]:
        if self.values:
            return list(self.values)
        return list(np.linspace(self.low, self.high, self.n)) if self.n > 1 else [self.low]


@dataclass(frozen=True)
class StudySettings:
    """Fixed settings of every point (SI units; see :class:`results.pipeline.PipelineSettings`)."""

    voltage: float = 225.0
    q_mech: float = 100.0
    mesh_size: float = 0.0
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
        check_choice("settings.scenario", self.scenario, ("device", "article"))
        check_range("settings.rel_tol", self.rel_tol, 0.0, 1.0, lo_open=True)
        check_integer("settings.max_members", self.max_members, 2, 1_000_000)


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
        if p.group == "impact":
            from impact.params import ImpactParams

            return float(getattr(ImpactParams(), rest))
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


def _number(where: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ParameterError(where, v, "must be a finite number")
    if v != 0 and not 1e-12 <= abs(v) <= 1e12:
        raise ParameterError(where, v, "must be 0 or of magnitude 1e-12 to 1e12 (SI units)")
    return float(v)


def _parameter(name: str, table: Any, sampling: str) -> StudyParameter:
    where = f"parameters.{name}"
    if not isinstance(table, Mapping):
        raise ParameterError(where, table, "must be a table with values, range (+ n) or tolerance")
    unknown = set(table) - {"values", "range", "n", "tolerance"}
    if unknown:
        raise ParameterError(f"{where}.{sorted(unknown)[0]}", table[sorted(unknown)[0]],
                             "unknown key: use values, range, n or tolerance")
    group, _, rest = name.partition(".")
    if group == "drive" and rest not in DRIVE_FIELDS:
        raise ParameterError(where, name, f"drive parameters are {', '.join('drive.' + f for f in DRIVE_FIELDS)}")
    if group == "impact" and rest not in IMPACT_FIELDS:
        raise ParameterError(where, name, f"impact parameters are {', '.join('impact.' + f for f in IMPACT_FIELDS)}")
    values = tuple(_number(f"{where}.values", v) for v in table.get("values", ()))
    low = high = None
    if "range" in table:
        r = table["range"]
        if not isinstance(r, list) or len(r) != 2:
            raise ParameterError(f"{where}.range", r, "must be [low, high]")
        low, high = _number(f"{where}.range", r[0]), _number(f"{where}.range", r[1])
        if not low < high:
            raise ParameterError(f"{where}.range", r, "must have low < high")
    n = table.get("n", 0)
    tol = table.get("tolerance")
    if sampling == "grid":
        if bool(values) == (low is not None):
            raise ParameterError(where, table, "grid sampling: give either values or range with n")
        if low is not None:
            check_integer(f"{where}.n", n, 2, 1000)
    elif sampling == "lhs" and low is None:
        raise ParameterError(where, table, "lhs sampling: give range = [low, high]")
    elif sampling == "tolerance":
        if tol is None:
            raise ParameterError(where, table, "tolerance sampling: give tolerance (relative, e.g. 0.02)")
        check_range(f"{where}.tolerance", tol, 0.0, 0.5, lo_open=True)
    return StudyParameter(name=name, values=values, low=low, high=high, n=int(n),
                          tolerance=None if tol is None else float(tol))


def study_from_mapping(data: Mapping[str, Any], base_dir: str | os.PathLike = ".") -> Study:
    """Validate a parsed study file; errors name the table and key."""
    for key in data:
        if key not in ("study", "settings", "parameters", "points"):
            raise ParameterError(key, "...", "unknown table: use [study], [settings], [parameters.*], [[points]]")
    s = data.get("study")
    if not isinstance(s, Mapping):
        raise ParameterError("study", s, "a [study] table is required")
    allowed = {"name", "design", "select", "stages", "sampling", "samples", "seed", "outputs", "pareto"}
    for key in s:
        if key not in allowed:
            raise ParameterError(f"study.{key}", s[key], f"unknown key: use {', '.join(sorted(allowed))}")
    name = s.get("name", "study")
    if not isinstance(name, str) or not name or len(name) > 80 or not all(c.isalnum() or c in "-_." for c in name):
        raise ParameterError("study.name", name, "must be 1-80 characters of letters, digits, - _ .")
    design = s.get("design", "default")
    if not isinstance(design, str) or not design:
        raise ParameterError("study.design", design, "must be 'default' or the path of a design TOML")
    select = s.get("select", "")
    if not isinstance(select, str):
        raise ParameterError("study.select", select, "must be the name of a design in the design file")
    stages = tuple(s.get("stages", STAGES))
    if not stages or stages != STAGES[:len(stages)]:
        raise ParameterError("study.stages", list(stages), f"must be a prefix of {list(STAGES)}")
    sampling = s.get("sampling", "grid")
    check_choice("study.sampling", sampling, SAMPLINGS)
    seed = s.get("seed", 1)
    check_integer("study.seed", seed, 0, 2 ** 32 - 1)
    samples = s.get("samples", 0)
    if sampling in ("lhs", "tolerance"):
        check_integer("study.samples", samples, 1, MAX_POINTS)
    raw_settings = data.get("settings", {})
    if not isinstance(raw_settings, Mapping):
        raise ParameterError("settings", raw_settings, "must be a table")
    known = {f.name: f for f in fields(StudySettings)}
    kw = {}
    for key, v in raw_settings.items():
        if key not in known:
            raise ParameterError(f"settings.{key}", v, f"unknown key: use {', '.join(known)}")
        if key in ("match",):
            if not isinstance(v, bool):
                raise ParameterError(f"settings.{key}", v, "must be true or false")
        elif key in ("scenario", "tip_surface"):
            if not isinstance(v, str):
                raise ParameterError(f"settings.{key}", v, "must be a string")
        elif key == "max_members":
            check_integer("settings.max_members", v, 2, 1_000_000)
        else:
            v = _number(f"settings.{key}", v)
        kw[key] = v
    settings = StudySettings(**kw)
    raw_params = data.get("parameters", {})
    if not isinstance(raw_params, Mapping) or (not raw_params and sampling != "list"):
        raise ParameterError("parameters", raw_params, "name at least one [parameters.\"<name>\"] table")
    params = tuple(_parameter(k, v, sampling) for k, v in raw_params.items())
    listed: tuple[dict, ...] = ()
    if sampling == "list":
        pts = data.get("points")
        if not isinstance(pts, list) or not pts:
            raise ParameterError("points", pts, "list sampling needs [[points]] tables")
        names = sorted({k for p in pts if isinstance(p, Mapping) for k in p})
        for i, p in enumerate(pts):
            if not isinstance(p, Mapping) or sorted(p) != names:
                raise ParameterError(f"points[{i}]", p, f"every point must set the same parameters {names}")
        listed = tuple({k: _number(f"points[{i}].{k}", v) for k, v in p.items()} for i, p in enumerate(pts))
        params = tuple(StudyParameter(name=k) for k in names)
        for p in params:
            _parameter(p.name, {}, "list")
    needed = {"design": "mesh", "drive": "harmonic", "impact": "impact"}
    for p in params:
        if needed[p.group] not in stages:
            raise ParameterError(f"parameters.{p.name}", p.name, f"needs the {needed[p.group]!r} stage in study.stages")
    outputs = tuple(s.get("outputs", ()))
    for o in outputs + tuple(s.get("pareto", ())):
        if o not in OUTPUTS:
            raise ParameterError("study.outputs", o, f"unknown output: use {', '.join(OUTPUTS)}")
        if OUTPUTS[o][0] not in stages:
            raise ParameterError("study.outputs", o, f"needs the {OUTPUTS[o][0]!r} stage in study.stages")
    pareto = tuple(s.get("pareto", ()))
    if pareto and len(pareto) != 2:
        raise ParameterError("study.pareto", list(pareto), "must name two outputs (both maximised)")
    study = Study(name=name, design=design, stages=stages, sampling=sampling, parameters=params,
                  settings=settings, samples=int(samples), seed=int(seed), outputs=outputs, pareto=pareto,
                  listed=listed, base_dir=str(base_dir), select=select)
    n = len(study.points()) if sampling != "tolerance" else samples + 1
    if n > MAX_POINTS:
        raise ParameterError("parameters", f"{n} points", f"at most {MAX_POINTS} points per study")
    return study


def load_study(path: str | os.PathLike) -> Study:
    """Read and validate a study TOML (see the module docstring)."""
    path = Path(path)
    data = load_toml(path, "study")
    study = study_from_mapping(data, base_dir=path.parent)
    if study.design != "default" and not study.design_path.is_file():
        raise ParameterError("study.design", study.design, f"no design file at {str(study.design_path)!r}")
    base = study.base_design()
    for p in study.parameters:
        if p.group == "design":
            try:
                base.get(p.name)
            except (KeyError, AttributeError, ParameterError):
                raise ParameterError(f"parameters.{p.name}", p.name, "not a field of the design") from None
    return study

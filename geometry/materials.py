"""The material library: named records of raw constants (SI units).

The records are design data: a design names its materials, geometry validates the names and
computes masses from ``density``; ``fem.materials`` turns a record into constitutive matrices.
Built-in records come from ``materials.toml`` beside this file; users add or override records
with their own TOML file of the same layout (``load_library(extra=...)``).
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Literal, Mapping

import numpy as np

from rpud_common import ParameterError, check_positive, check_range, load_toml

from .piezo_forms import (EPS0, FORMS, REQUIRED, allowed_keys, check_positive_definite, matrices,
                          stress_charge, tables, transverse_isotropy_defect)

__all__ = ["Material", "load_library", "get_material", "builtin_library", "records_from_mapping", "EPS0",
           "LIMIT_FIELDS", "FIELD_RANGES", "POISSON_RANGE", "TABLE_RANGES", "SOUND_SPEED_RANGE"]

log = logging.getLogger(__name__)

LIMIT_FIELDS = ("fatigue_strength", "tensile_strength", "compressive_strength", "depolarisation_field")
"""Optional strength limits of a record (used by :mod:`fem.stress` for the utilisation table)."""

FIELD_RANGES: dict[str, tuple[float, float, str, str]] = {
    "density": (100.0, 25e3, "kg/m^3", "rigid foams and light polymers (~100) to osmium (22 590)"),
    "youngs_modulus": (1e8, 1.2e12, "Pa", "soft engineering polymers (PTFE, LDPE: 0.2-0.5 GPa) to diamond "
                       "(1.05-1.2 TPa); rubbers below carry no ultrasound through a drill"),
    "q_mech": (10.0, 1e6, "", "loss factor 1/Q <= 0.1 (bond epoxies 0.02-0.05, soft PZT Q ~ 60-80) up to "
               "single-crystal quartz (~1e6, also the largest --q-mech); inf or omitted: lossless"),
    "tan_delta": (0.0, 0.1, "", "dielectric loss of a piezoceramic: hard PZT 0.002-0.004, soft PZT ~0.02; "
                  "above 0.1 a driven ceramic heats up at once. Isotropic (passive) records: 0 only"),
    "fatigue_strength": (1e5, 1e10, "Pa", "weakest foams (0.1 MPa) to above any bulk material (10 GPa)"),
    "tensile_strength": (1e5, 1e10, "Pa", "as fatigue_strength"),
    "compressive_strength": (1e5, 1e10, "Pa", "as fatigue_strength"),
    "depolarisation_field": (1e4, 1e8, "V/m", "single crystals' ~0.1 MV/m to PVDF's coercive ~50 MV/m"),
}
"""Accepted range of every scalar field of a record: ``(lo, hi, unit, reason)``, bounds
included. A value outside is a unit slip (510 for 510e6 Pa), a typing error, or a number that
makes later arithmetic overflow or divide by zero (1e300, 1e-300)."""

POISSON_RANGE = (-1.0, 0.5)
"""Poisson's ratio of an isotropic record, bounds excluded: outside, the solid is not stable
(its bulk or shear modulus would be negative or infinite)."""

TABLE_RANGES: dict[str, tuple[float, float, str, str]] = {
    "c": (1e8, 1.2e12, "Pa", "stiffness constants: as youngs_modulus; off-diagonal |c_ij| <= hi"),
    "s": (8e-13, 1e-8, "1/Pa", "compliances: s_ii >= 1/c_ii, so the inverse bounds of c; |s_ij| <= hi"),
    "e": (-100.0, 100.0, "C/m^2", "PZT |e| <= 30, relaxor single crystals <= ~40"),
    "d": (-1e-8, 1e-8, "C/N", "PZT |d| <= 1e-9, relaxor single crystals (PMN-PT) <= ~5e-9"),
    "eps": (1.0, 1e5, "(relative to eps0 = 8.854e-12 F/m)", "vacuum (1) to relaxor ceramics (~2e4); "
            "off-diagonal |eps_ij| <= hi"),
}
"""Accepted ranges of the piezoelectric tables by prefix: diagonal entries of ``c``, ``s`` and
``eps`` lie in ``[lo, hi]``, every other entry in ``[-hi, hi]``; ``(lo, hi, unit, reason)``.
A strain-charge record's converted stress-charge tables must lie in these ranges too."""

SOUND_SPEED_RANGE = (200.0, 20e3)
"""Wave speeds of a record, m/s: the bar speed sqrt(E/rho) of an isotropic record and every
sqrt(c_ii/rho) of a ceramic. Soft polymers' shear waves (~250) to diamond (~18 000): a density
and a modulus each in range may still pair into no solid (1e8 Pa with 25 000 kg/m^3)."""

_STIFFEST = TABLE_RANGES["c"][1]
"""Upper bound of every derived modulus (bulk, shear, open-circuit stiffness), Pa."""

_TRANSVERSE_TOL = 1e-3
"""Departure from transverse isotropy (of the largest entry) above which a ceramic is warned about."""


@dataclass(frozen=True)
class Material:
    """A material record.

    A piezoceramic is given in one of two forms: stress-charge (``c_E``, ``e``, ``eps_S``) or
    strain-charge (``s_E``, ``d``, ``eps_T``, converted on construction: afterwards the record
    holds the stress-charge constants, the ones every computation uses, and empty strain-charge
    tables). Keys: the 6mm constants of a poled ceramic are required; other components
    (full anisotropy) are optional, see :mod:`geometry.piezo_forms`.

    Attributes
    ----------
    name : str
        Record name, the key a design's ``material`` fields use.
    kind : {"isotropic", "piezo"}
        Isotropic elastic solid, or piezoceramic (poled along its part's poling direction).
    density : float
        kg/m^3.
    youngs_modulus, poisson_ratio : float
        Pa and -, isotropic materials only.
    c_E : mapping
        Stiffness at constant field, Pa (keys c11 c12 c13 c33 c44 c66, optional others).
    e : mapping
        Piezoelectric stress constants, C/m^2 (keys e31 e33 e15, optional others).
    eps_S : mapping
        Clamped relative permittivity, dimensionless (keys eps11 eps33, optional eps22 eps12...).
    s_E, d, eps_T : mapping
        Strain-charge input instead: compliance 1/Pa (s11 s12 s13 s33 s44 s66), d C/N (d31 d33
        d15), free relative permittivity (eps11 eps33).
    q_mech : float
        Mechanical quality factor, dimensionless (loss factor 1/Q); omitted or inf: lossless.
    tan_delta : float
        Dielectric loss tangent, dimensionless (piezo only; 0 for passive records).

    Every number must lie in its stated range (:data:`FIELD_RANGES`, :data:`POISSON_RANGE`,
    :data:`TABLE_RANGES`), and the pairs of them a solid (:data:`SOUND_SPEED_RANGE`; derived
    bulk, shear and open-circuit moduli at most those of the stiffest solid).
    description : str
        Free text: grade, source of the constants.
    fatigue_strength : float, optional
        Metals: fully reversed fatigue strength (stress amplitude, Pa) at a stated number of
        cycles (the record's source says which); compared with the peak von Mises stress.
    tensile_strength : float, optional
        Ceramics: rated dynamic (peak) tensile strength, Pa; compared with the largest
        principal stress over a cycle.
    compressive_strength : float, optional
        Ceramics: rated static compressive stress parallel to the polar axis, Pa; compared with
        the most negative principal stress.
    depolarisation_field : float, optional
        Ceramics: field at which an AC drive starts to depole, V/m (amplitude); compared with
        the peak |E|. Omitted limits are reported as "n/a", never guessed.
    """

    name: str
    kind: Literal["isotropic", "piezo"]
    density: float
    youngs_modulus: float | None = None
    poisson_ratio: float | None = None
    c_E: Mapping[str, float] = field(default_factory=dict)
    e: Mapping[str, float] = field(default_factory=dict)
    eps_S: Mapping[str, float] = field(default_factory=dict)
    q_mech: float = math.inf
    tan_delta: float = 0.0
    description: str = ""
    s_E: Mapping[str, float] = field(default_factory=dict)
    d: Mapping[str, float] = field(default_factory=dict)
    eps_T: Mapping[str, float] = field(default_factory=dict)
    fatigue_strength: float | None = None
    tensile_strength: float | None = None
    compressive_strength: float | None = None
    depolarisation_field: float | None = None

    def __post_init__(self):
        where = f"materials.{self.name}"
        if self.kind not in ("isotropic", "piezo"):
            raise ParameterError(f"{where}.kind", self.kind, "must be 'isotropic' or 'piezo'")
        self._check_limits(where)
        self._check_common(where)
        if not isinstance(self.description, str):
            raise ParameterError(f"{where}.description", self.description, "must be a string")
        if self.kind == "isotropic":
            self._check_isotropic(where)
            return
        for key in ("youngs_modulus", "poisson_ratio"):
            if getattr(self, key) is not None:
                raise ParameterError(f"{where}.{key}", getattr(self, key),
                                     "applies to kind = 'isotropic' only (a piezo record gives c_E or s_E)")
        form = self._form(where)
        for group in FORMS[form]:
            self._check_table(where, group, getattr(self, group))
        if form == "strain-charge":
            self._convert_strain_charge(where)
        else:
            A, _B, eps = matrices({g: getattr(self, g) for g in FORMS[form]}, form)
            check_positive_definite(f"{where}.c_E", A, "not a stable solid (check signs and units, Pa)")
            check_positive_definite(f"{where}.eps_S", eps, "a permittivity must be (relative values, e.g. 600)")
            for g in FORMS["stress-charge"]:
                object.__setattr__(self, g, {k: float(v) for k, v in getattr(self, g).items()})
        self._check_piezo_derived(where)
        defect, comp = transverse_isotropy_defect(*self.voigt_matrices())
        if defect > _TRANSVERSE_TOL:
            log.warning("%s: not transversely isotropic about the poling axis (%s departs by %.2g of the "
                        "largest constant; a poled ceramic has c66 = (c11 - c12)/2, c22 = c11, ...): "
                        "used as given", where, comp, defect)

    def _check_common(self, where: str) -> None:
        """Density, Q and loss tangent: in their :data:`FIELD_RANGES` (q_mech may be inf)."""
        _check_field(where, "density", self.density)
        q = self.q_mech
        if not (isinstance(q, float) and q == math.inf):       # inf (the default) is lossless
            lo, hi, _unit, _why = FIELD_RANGES["q_mech"]
            try:
                check_range(f"{where}.q_mech", q, lo, hi)
            except ParameterError as exc:
                raise ParameterError(exc.name, exc.value, f"{exc.allowed} (inf or omitted: lossless)") from None
        if self.kind == "isotropic" and (isinstance(self.tan_delta, bool) or self.tan_delta != 0):
            raise ParameterError(f"{where}.tan_delta", self.tan_delta, "applies to kind = 'piezo' only (0 or "
                                 "omitted here: a passive part carries no field; its damping is q_mech)")
        _check_field(where, "tan_delta", self.tan_delta)

    def _check_isotropic(self, where: str) -> None:
        """E and nu in range, the bulk and shear moduli they imply and the bar speed those of a
        solid, and no piezoelectric table."""
        _check_field(where, "youngs_modulus", self.youngs_modulus)
        check_range(f"{where}.poisson_ratio", self.poisson_ratio, *POISSON_RANGE, lo_open=True, hi_open=True)
        E, nu = float(self.youngs_modulus), float(self.poisson_ratio)
        for label, modulus in (("bulk", E / (3 * (1 - 2 * nu))), ("shear", E / (2 * (1 + nu)))):
            if modulus > _STIFFEST:
                raise ParameterError(f"{where}.poisson_ratio", self.poisson_ratio,
                                     f"with youngs_modulus {E:g} Pa gives a {label} modulus of {modulus:.3g} Pa, "
                                     f"above any solid's ({_STIFFEST:g} Pa): nu this close to "
                                     f"{0.5 if label == 'bulk' else -1:g} is not a solid")
        _check_speed(f"{where}.density", self.density, E, "youngs_modulus")
        for group in ("c_E", "e", "eps_S", "s_E", "d", "eps_T"):
            if getattr(self, group):
                raise ParameterError(f"{where}.{group}", dict(getattr(self, group)),
                                     "applies to kind = 'piezo' only")

    def _convert_strain_charge(self, where: str) -> None:
        """Check the strain-charge tables as matrices, then hold their stress-charge form."""
        A, B, eps = matrices({g: getattr(self, g) for g in FORMS["strain-charge"]}, "strain-charge")
        check_positive_definite(f"{where}.s_E", A, "not a stable solid (check signs and units, 1/Pa)")
        check_positive_definite(f"{where}.eps_T", eps, "a permittivity must be (relative values, e.g. 1300)")
        c_E, e, eps_S = stress_charge(A, B, eps)
        check_positive_definite(f"{where}.d", eps_S, "eps^S = eps^T - d c^E d^T is not: the coupling "
                                "exceeds 1 (check d in C/N and eps_T relative)")
        converted = tables(c_E, e, eps_S, "stress-charge")
        source = {"c_E": "s_E", "e": "d", "eps_S": "d"}   # eps^S is eps^T less the coupling through d
        for group in FORMS["stress-charge"]:
            try:
                self._check_table(where, group, converted[group])
            except ParameterError as exc:
                shown = f"{group}.{exc.name.rsplit('.', 1)[-1]} = {exc.value:.4g}"
                raise ParameterError(f"{where}.{source[group]}", shown, f"converts to a stress-charge constant "
                                     f"that {exc.allowed} (check the strain-charge signs and units)") from None
        for g in FORMS["stress-charge"]:
            object.__setattr__(self, g, converted[g])
        for g in FORMS["strain-charge"]:
            object.__setattr__(self, g, {})

    def _check_piezo_derived(self, where: str) -> None:
        """Wave speeds sqrt(c_ii/rho) of a solid, and an open-circuit stiffness
        c^D = c^E + e^T (eps^S)^-1 e no stiffer than any solid (a larger one means a coupling no
        ceramic has: e too large for eps_S, usually a unit slip)."""
        c_E, e, eps_S = self.voigt_matrices()
        for i in range(6):
            _check_speed(f"{where}.density", self.density, float(c_E[i, i]), f"c_E.c{i + 1}{i + 1}")
        c_D = c_E + e.T @ np.linalg.solve(eps_S, e)
        worst = int(np.argmax(np.diag(c_D)))
        if not c_D[worst, worst] <= _STIFFEST:
            raise ParameterError(f"{where}.e", dict(self.e), f"with eps_S gives an open-circuit stiffness c^D_"
                                 f"{worst + 1}{worst + 1} = {c_D[worst, worst]:.3g} Pa, above any solid's "
                                 f"({_STIFFEST:g} Pa): a coupling no ceramic has (check e in C/m^2, eps_S relative)")

    def _check_limits(self, where: str) -> None:
        """Optional strength limits: in their :data:`FIELD_RANGES` (a value outside is a unit
        slip: 510 for 510e6 Pa, 1.5 for 1.5e6 V/m)."""
        for key in LIMIT_FIELDS:
            value = getattr(self, key)
            if value is None:
                continue
            check_positive(f"{where}.{key}", value, FIELD_RANGES[key][2])
            _check_field(where, key, value)
            object.__setattr__(self, key, float(value))
        if self.depolarisation_field is not None and self.kind != "piezo":
            raise ParameterError(f"{where}.depolarisation_field", self.depolarisation_field,
                                 "applies to kind = 'piezo' only")

    def limits(self) -> dict[str, float | None]:
        """The strength limits of the record (SI; None where the record gives none)."""
        return {k: getattr(self, k) for k in LIMIT_FIELDS}

    def _form(self, where: str) -> str:
        given = {f: [g for g in groups if getattr(self, g)] for f, groups in FORMS.items()}
        if given["stress-charge"] and given["strain-charge"]:
            raise ParameterError(f"{where}.{given['strain-charge'][0]}", dict(getattr(self, given['strain-charge'][0])),
                                 "give either the stress-charge tables (c_E, e, eps_S) or the strain-charge "
                                 "tables (s_E, d, eps_T), not both")
        form = "strain-charge" if given["strain-charge"] else "stress-charge"
        for g in FORMS[form]:
            if not getattr(self, g):
                raise ParameterError(f"{where}.{g}", {}, f"missing ({form} form: {', '.join(FORMS[form])}; "
                                     f"keys {', '.join(REQUIRED[g])} at least)")
        return form

    @staticmethod
    def _check_table(where: str, group: str, table) -> None:
        if not isinstance(table, Mapping):
            raise ParameterError(f"{where}.{group}", table, "must be a table of constants")
        missing = [k for k in REQUIRED[group] if k not in table]
        if missing:
            raise ParameterError(f"{where}.{group}", dict(table), f"missing {', '.join(missing)}")
        allowed = allowed_keys(group)
        extra = sorted(set(table) - set(allowed))
        if extra:
            raise ParameterError(f"{where}.{group}.{extra[0]}", table[extra[0]],
                                 f"unknown key; allowed: {', '.join(allowed)}")
        pre = group.split("_")[0] if group != "eps_S" and group != "eps_T" else "eps"
        lo, hi, unit, _why = TABLE_RANGES[pre]
        for key, value in table.items():
            name = f"{where}.{group}.{key}"
            sub = key[len(pre):]
            diagonal = sub[0] == sub[1] if pre in ("c", "s", "eps") else False
            if diagonal:
                check_range(name, value, lo, hi, unit)
            else:
                check_range(name, value, -hi, hi, unit)

    @property
    def is_piezo(self) -> bool:
        return self.kind == "piezo"

    def voigt_matrices(self):
        """Stress-charge constants in the material frame (poling along +z), Voigt order
        xx yy zz yz xz xy: ``(c_E (6, 6) Pa, e (3, 6) C/m^2, eps_S (3, 3) F/m)``."""
        if not self.is_piezo:
            raise ParameterError(f"materials.{self.name}.kind", self.kind, "is not a piezoceramic")
        return matrices({"c_E": self.c_E, "e": self.e, "eps_S": self.eps_S}, "stress-charge")

    def to_record(self) -> dict:
        """The record in the layout of ``materials.toml`` (stress-charge form for ceramics; the
        constants every computation uses), without its name; TOML and strict-JSON friendly
        (a lossless ``q_mech`` is left out)."""
        rec: dict = {"kind": self.kind}
        if self.description:
            rec["description"] = self.description
        rec["density"] = float(self.density)
        if self.kind == "isotropic":
            rec["youngs_modulus"] = float(self.youngs_modulus)
            rec["poisson_ratio"] = float(self.poisson_ratio)
        if math.isfinite(self.q_mech):
            rec["q_mech"] = float(self.q_mech)
        if self.is_piezo:
            rec["tan_delta"] = float(self.tan_delta)
            for g in FORMS["stress-charge"]:
                rec[g] = dict(getattr(self, g))
        for key in LIMIT_FIELDS:
            if getattr(self, key) is not None:
                rec[key] = float(getattr(self, key))
        return rec


def _check_field(where: str, key: str, value) -> None:
    """``value`` of the scalar field ``key`` in its :data:`FIELD_RANGES` entry."""
    lo, hi, unit, _why = FIELD_RANGES[key]
    check_range(f"{where}.{key}", value, lo, hi, unit)


def _check_speed(name: str, density: float, modulus: float, what: str) -> None:
    """The wave speed sqrt(modulus / density) in :data:`SOUND_SPEED_RANGE` (``name``: the
    density's field, ``what``: the modulus' field, for the message)."""
    lo, hi = SOUND_SPEED_RANGE
    speed = math.sqrt(modulus / density)
    if not lo <= speed <= hi:
        raise ParameterError(name, density, f"with {what} {modulus:g} Pa gives a wave speed sqrt({what}/density) "
                             f"of {speed:.4g} m/s, outside the [{lo:g}, {hi:g}] m/s of solids (check the units)")


def records_from_mapping(data: Mapping, source: str, prefix: str = "materials") -> dict[str, Material]:
    """Material records from a mapping ``name -> table`` (a ``materials.toml``-layout file or a
    design's ``[materials]`` table); errors name ``<prefix>.<name>.<field>``."""
    if not isinstance(data, Mapping):
        raise ParameterError(prefix, data, f"must be a table of material records (in {source})")
    out = {}
    allowed = set(Material.__dataclass_fields__) - {"name"}
    for name, rec in data.items():
        where = f"{prefix}.{name}"
        if isinstance(rec, Material):
            if rec.name != name:
                raise ParameterError(f"{where}.name", rec.name, f"must equal its key '{name}'")
            out[name] = rec
            continue
        if not isinstance(rec, Mapping):
            raise ParameterError(where, rec, f"must be a table (in {source})")
        unknown = sorted(set(rec) - allowed)
        if unknown:
            raise ParameterError(f"{where}.{unknown[0]}", rec[unknown[0]],
                                 f"unknown key; allowed: {', '.join(sorted(allowed))}")
        if "kind" not in rec or "density" not in rec:
            raise ParameterError(where, dict(rec), "needs at least 'kind' and 'density'")
        try:
            out[name] = Material(name=name, **rec)
        except ParameterError as exc:
            if prefix != "materials" and exc.name.startswith(f"materials.{name}"):
                raise ParameterError(prefix + exc.name[len("materials"):], exc.value, exc.allowed) from None
            raise
    return out


_records = records_from_mapping


@lru_cache(maxsize=1)
def _builtin() -> dict[str, Material]:
    return _records(load_toml(Path(__file__).with_name("materials.toml")), "materials.toml")


def builtin_library() -> dict[str, Material]:
    """A copy of the built-in library (``materials.toml`` beside this module)."""
    return dict(_builtin())


def load_library(extra: str | os.PathLike | None = None) -> dict[str, Material]:
    """The built-in library, optionally extended/overridden by a user TOML file."""
    lib = dict(_builtin())
    if extra is not None:
        lib.update(_records(load_toml(extra, "--materials"), str(extra)))
    return lib


def get_material(name: str, library: Mapping[str, Material] | None = None) -> Material:
    """Look up a material by name; unknown names are a :class:`ParameterError` listing the known ones."""
    lib = _builtin() if library is None else library
    try:
        return lib[name]
    except (KeyError, TypeError):
        raise ParameterError("material", name, "unknown; known: " + ", ".join(sorted(lib))) from None

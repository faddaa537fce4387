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

from rpud_common import ParameterError, check_positive, check_range, load_toml

from .piezo_forms import (EPS0, FORMS, REQUIRED, allowed_keys, check_positive_definite, matrices,
                          stress_charge, tables, transverse_isotropy_defect)

__all__ = ["Material", "load_library", "get_material", "builtin_library", "records_from_mapping", "EPS0",
           "LIMIT_FIELDS"]

log = logging.getLogger(__name__)

# plausible magnitudes: a value outside is a unit slip (12.3 for 12.3e-12 m^2/N, 1300 F/m for 1300)
_RANGES = {"c": (1e8, 1e13, "Pa"), "s": (1e-13, 1e-8, "1/Pa"), "e": (-1e3, 1e3, "C/m^2"),
           "d": (-1e-7, 1e-7, "C/N"), "eps": (1.0, 1e6, "(relative to eps0 = 8.854e-12 F/m)")}

LIMIT_FIELDS = ("fatigue_strength", "tensile_strength", "compressive_strength", "depolarisation_field")
"""Optional strength limits of a record (used by :mod:`fem.stress` for the utilisation table)."""

_LIMIT_RANGES = {"fatigue_strength": (1e5, 1e11, "Pa"), "tensile_strength": (1e5, 1e11, "Pa"),
                 "compressive_strength": (1e5, 1e11, "Pa"), "depolarisation_field": (1e3, 1e9, "V/m")}

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
    kind : {"isotropic", "piezo"}
    density : float
        kg/m^3.
    youngs_modulus, poisson_ratio : float
        Pa and -, isotropic materials only.
    c_E : mapping
        Stiffness at constant field, Pa (keys c11 c12 c13 c33 c44 c66, optional others).
    e : mapping
        Piezoelectric stress constants, C/m^2 (keys e31 e33 e15, optional others).
    eps_S : mapping
        Clamped relative permittivity (keys eps11 eps33, optional eps22 eps12...).
    s_E, d, eps_T : mapping
        Strain-charge input instead: compliance 1/Pa (s11 s12 s13 s33 s44 s66), d C/N (d31 d33
        d15), free relative permittivity (eps11 eps33).
    q_mech : float
        Mechanical quality factor (loss factor 1/Q); omitted or inf: lossless.
    tan_delta : float
        Dielectric loss tangent (piezo only; 0 for metals).
    description : str
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
        self._check_limits(where)
        if self.kind not in ("isotropic", "piezo"):
            raise ParameterError(f"{where}.kind", self.kind, "must be 'isotropic' or 'piezo'")
        check_positive(f"{where}.density", self.density, "kg/m^3")
        q = self.q_mech
        if isinstance(q, bool) or not isinstance(q, (int, float)) or not q > 0:
            # inf (the default) is lossless, as documented
            raise ParameterError(f"{where}.q_mech", self.q_mech, "must be a number > 0 (inf or omitted: lossless)")
        check_range(f"{where}.tan_delta", self.tan_delta, 0.0, 1.0)
        if not isinstance(self.description, str):
            raise ParameterError(f"{where}.description", self.description, "must be a string")
        if self.kind == "isotropic":
            check_positive(f"{where}.youngs_modulus", self.youngs_modulus, "Pa")
            check_range(f"{where}.poisson_ratio", self.poisson_ratio, -1.0, 0.5, lo_open=True, hi_open=True)
            for group in ("c_E", "e", "eps_S", "s_E", "d", "eps_T"):
                if getattr(self, group):
                    raise ParameterError(f"{where}.{group}", dict(getattr(self, group)),
                                         "applies to kind = 'piezo' only")
            return
        for key in ("youngs_modulus", "poisson_ratio"):
            if getattr(self, key) is not None:
                raise ParameterError(f"{where}.{key}", getattr(self, key),
                                     "applies to kind = 'isotropic' only (a piezo record gives c_E or s_E)")
        form = self._form(where)
        for group in FORMS[form]:
            self._check_table(where, group, getattr(self, group))
        A, B, eps = matrices({g: getattr(self, g) for g in FORMS[form]}, form)
        if form == "strain-charge":
            check_positive_definite(f"{where}.s_E", A, "not a stable solid (check signs and units, 1/Pa)")
            check_positive_definite(f"{where}.eps_T", eps, "a permittivity must be (relative values, e.g. 1300)")
            c_E, e, eps_S = stress_charge(A, B, eps)
            check_positive_definite(f"{where}.d", eps_S, "eps^S = eps^T - d c^E d^T is not: the coupling "
                                    "exceeds 1 (check d in C/N and eps_T relative)")
            converted = tables(c_E, e, eps_S, "stress-charge")
            for g in FORMS["stress-charge"]:
                object.__setattr__(self, g, converted[g])
            for g in FORMS["strain-charge"]:
                object.__setattr__(self, g, {})
        else:
            check_positive_definite(f"{where}.c_E", A, "not a stable solid (check signs and units, Pa)")
            check_positive_definite(f"{where}.eps_S", eps, "a permittivity must be (relative values, e.g. 600)")
            for g in FORMS["stress-charge"]:
                object.__setattr__(self, g, {k: float(v) for k, v in getattr(self, g).items()})
        defect, comp = transverse_isotropy_defect(*self.voigt_matrices())
        if defect > _TRANSVERSE_TOL:
            log.warning("%s: not transversely isotropic about the poling axis (%s departs by %.2g of the "
                        "largest constant; a poled ceramic has c66 = (c11 - c12)/2, c22 = c11, ...): "
                        "used as given", where, comp, defect)

    def _check_limits(self, where: str) -> None:
        """Optional strength limits: positive, finite, of a plausible magnitude (a value outside
        is a unit slip: 510 for 510e6 Pa, 1.5 for 1.5e6 V/m)."""
        for key in LIMIT_FIELDS:
            value = getattr(self, key)
            if value is None:
                continue
            lo, hi, unit = _LIMIT_RANGES[key]
            check_positive(f"{where}.{key}", value, unit)
            check_range(f"{where}.{key}", value, lo, hi, unit)
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
        lo, hi, unit = _RANGES[pre]
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

"""The material library: named records of raw constants (SI units).

The records are design data: a design names its materials, geometry validates the names and
computes masses from ``density``; ``fem.materials`` turns a record into constitutive matrices.
Built-in records come from ``materials.toml`` beside this file; users add or override records
with their own TOML file of the same layout (``load_library(extra=...)``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Literal, Mapping

from rpud_common import ParameterError, check_positive, check_range, load_toml

__all__ = ["Material", "load_library", "get_material", "EPS0"]

EPS0 = 8.854e-12
"""Vacuum permittivity in F/m, as used by the reference data."""

_PIEZO_KEYS = {
    "c_E": ("c11", "c12", "c13", "c33", "c44", "c66"),
    "e": ("e31", "e33", "e15"),
    "eps_S": ("eps11", "eps33"),
}


@dataclass(frozen=True)
class Material:
    """A material record.

    Attributes
    ----------
    name : str
    kind : {"isotropic", "piezo"}
    density : float
        kg/m^3.
    youngs_modulus, poisson_ratio : float
        Pa and -, isotropic materials only.
    c_E : mapping
        Stiffness at constant field, Pa (keys c11 c12 c13 c33 c44 c66), piezo only.
    e : mapping
        Piezoelectric stress constants, C/m^2 (keys e31 e33 e15), piezo only.
    eps_S : mapping
        Clamped relative permittivity (keys eps11 eps33), piezo only.
    q_mech : float
        Mechanical quality factor (loss factor 1/Q).
    tan_delta : float
        Dielectric loss tangent (piezo only; 0 for metals).
    description : str
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

    def __post_init__(self):
        where = f"materials.{self.name}"
        if self.kind not in ("isotropic", "piezo"):
            raise ParameterError(f"{where}.kind", self.kind, "must be 'isotropic' or 'piezo'")
        check_positive(f"{where}.density", self.density, "kg/m^3")
        q = self.q_mech
        if isinstance(q, bool) or not isinstance(q, (int, float)) or not q > 0:
            # inf (the default) is lossless, as documented
            raise ParameterError(f"{where}.q_mech", self.q_mech, "must be a number > 0 (inf or omitted: lossless)")
        check_range(f"{where}.tan_delta", self.tan_delta, 0.0, 1.0)
        if self.kind == "isotropic":
            check_positive(f"{where}.youngs_modulus", self.youngs_modulus, "Pa")
            check_range(f"{where}.poisson_ratio", self.poisson_ratio, -1.0, 0.5, lo_open=True, hi_open=True)
        else:
            for group, keys in _PIEZO_KEYS.items():
                table = getattr(self, group)
                missing = [k for k in keys if k not in table]
                if missing:
                    raise ParameterError(f"{where}.{group}", dict(table), f"missing {', '.join(missing)}")
                extra = sorted(set(table) - set(keys))
                if extra:
                    raise ParameterError(f"{where}.{group}.{extra[0]}", table[extra[0]],
                                         f"unknown key; allowed: {', '.join(keys)}")
            for k in ("c11", "c33", "c44", "c66"):
                check_positive(f"{where}.c_E.{k}", self.c_E[k], "Pa")
            for k in ("eps11", "eps33"):
                check_positive(f"{where}.eps_S.{k}", self.eps_S[k])
            object.__setattr__(self, "c_E", {k: float(self.c_E[k]) for k in _PIEZO_KEYS["c_E"]})
            object.__setattr__(self, "e", {k: float(self.e[k]) for k in _PIEZO_KEYS["e"]})
            object.__setattr__(self, "eps_S", {k: float(self.eps_S[k]) for k in _PIEZO_KEYS["eps_S"]})

    @property
    def is_piezo(self) -> bool:
        return self.kind == "piezo"

    def voigt_matrices(self):
        """Stress-charge constants in the material frame (poling along +z), Voigt order
        xx yy zz yz xz xy: ``(c_E (6, 6) Pa, e (3, 6) C/m^2, eps_S (3, 3) F/m)``."""
        import numpy as np

        if not self.is_piezo:
            raise ParameterError(f"materials.{self.name}.kind", self.kind, "is not a piezoceramic")
        c = self.c_E
        C = np.zeros((6, 6))
        C[0, 0] = C[1, 1] = c["c11"]
        C[0, 1] = C[1, 0] = c["c12"]
        C[0, 2] = C[2, 0] = C[1, 2] = C[2, 1] = c["c13"]
        C[2, 2] = c["c33"]
        C[3, 3] = C[4, 4] = c["c44"]
        C[5, 5] = c["c66"]
        e = np.zeros((3, 6))
        e[2, 0] = e[2, 1] = self.e["e31"]
        e[2, 2] = self.e["e33"]
        e[1, 3] = e[0, 4] = self.e["e15"]
        eps = np.diag([self.eps_S["eps11"], self.eps_S["eps11"], self.eps_S["eps33"]]) * EPS0
        return C, e, eps


def _records(data: Mapping, source: str) -> dict[str, Material]:
    out = {}
    allowed = set(Material.__dataclass_fields__) - {"name"}
    for name, rec in data.items():
        if not isinstance(rec, Mapping):
            raise ParameterError(f"materials.{name}", rec, f"must be a table (in {source})")
        unknown = sorted(set(rec) - allowed)
        if unknown:
            raise ParameterError(f"materials.{name}.{unknown[0]}", rec[unknown[0]],
                                 f"unknown key; allowed: {', '.join(sorted(allowed))}")
        if "kind" not in rec or "density" not in rec:
            raise ParameterError(f"materials.{name}", dict(rec), "needs at least 'kind' and 'density'")
        out[name] = Material(name=name, **rec)
    return out


@lru_cache(maxsize=1)
def _builtin() -> dict[str, Material]:
    return _records(load_toml(Path(__file__).with_name("materials.toml")), "materials.toml")


def load_library(extra: str | os.PathLike | None = None) -> dict[str, Material]:
    """The built-in library, optionally extended/overridden by a user TOML file."""
    lib = dict(_builtin())
    if extra is not None:
        lib.update(_records(load_toml(extra), str(extra)))
    return lib


def get_material(name: str, library: Mapping[str, Material] | None = None) -> Material:
    """Look up a material by name; unknown names are a :class:`ParameterError` listing the known ones."""
    lib = _builtin() if library is None else library
    try:
        return lib[name]
    except KeyError:
        raise ParameterError("material", name, "unknown; known: " + ", ".join(sorted(lib))) from None

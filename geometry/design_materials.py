"""A design's own material library: its ``[materials]`` table, resolution of the names its parts
use, and records added from a user's material file (``--materials FILE``).

A design resolves material names in its *library*: the built-in records
(``geometry/materials.toml``) overlaid with the design's own records (``design.materials``, the
``[materials]`` table of its TOML, same layout as ``materials.toml``). Parts only name their
material; the design checks every name (unknown names list what is available) and the roles the
names play (a ring must be a piezoceramic, a horn, flange, coupler or shim must not be, a
segment or CAD region is poled iff its material is).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from typing import Any

from rpud_common import ParameterError

from .materials import Material, builtin_library, records_from_mapping

__all__ = ["own_records", "check_material_name", "resolve_uses", "with_records", "materials_block"]

log = logging.getLogger(__name__)


def check_material_name(name: str, value: Any) -> None:
    """A material name: a non-empty string (the design resolves it in its library)."""
    if not isinstance(value, str) or not value:
        raise ParameterError(name, value, "must be a material name (string)")


def own_records(value: Any) -> dict[str, Material]:
    """The design field ``materials``: a mapping name -> record (a :class:`Material` or a table
    in the layout of ``materials.toml``), validated; errors name ``materials.<name>.<field>``."""
    if value is None:
        return {}
    records = records_from_mapping(value, "the design's [materials] table")
    for name, rec in records.items():
        if name in builtin_library() and rec != builtin_library()[name]:
            log.warning("materials.%s overrides the built-in record of that name", name)
    return records


def resolve_uses(uses, library: Mapping[str, Material]) -> None:
    """Check every material a design uses, and that it suits the part's role.

    Parameters
    ----------
    uses : iterable of (dotted path, name, role)
        ``role``: ``"piezo"`` (must be a piezoceramic), ``("poling", path, value)`` (a segment
        or a CAD region: poled iff piezo, so the design says explicitly where a ceramic goes) or
        ``"passive"``/``None`` (a metal part: horn, flange, coupler, electrode shim). The kinds
        have no flag for an active horn or coupler, so a piezoceramic there is refused: it is a
        mistyped name, and the part would be meshed and solved as unpoled ceramic.
    library : mapping name -> Material
    """
    for path, name, role in uses:
        if name not in library:
            raise ParameterError(path, name, "unknown; known: " + ", ".join(sorted(library))
                                 + " (or add it to the design's [materials] table, or give --materials FILE)")
        piezo = library[name].is_piezo
        if role == "piezo" and not piezo:
            raise ParameterError(path, name, "must be a piezoceramic (kind = 'piezo'): "
                                 f"{_part(path)} is the design's active ceramic")
        if role in ("passive", None) and piezo:
            raise ParameterError(path, name, f"is a piezoceramic: the {_part(path)} must be a passive material "
                                 "(kind = 'isotropic', e.g. ti6al4v, steel_45); the ceramic rings take stack.material")
        if isinstance(role, tuple) and role[0] == "poling":
            _, ppath, poling = role
            if piezo and poling == "none":
                raise ParameterError(ppath, poling, f"a piezoceramic ({name}) needs a poling direction")
            if not piezo and poling != "none":
                raise ParameterError(ppath, poling, f"must be 'none' for passive material {name}")


def _part(path: str) -> str:
    """The part a material path belongs to, for messages (``horn.material`` -> ``horn``,
    ``stack.shim_material`` -> ``stack's electrode shim``)."""
    head, _, field = path.rpartition(".")
    return f"{head}'s electrode shim" if field == "shim_material" else head


def with_records(design, records: Mapping[str, Material], source: str):
    """``design`` with the records of ``records`` (a user's material file) that it uses added to
    its own table, so that it carries every constant it needs.

    A name defined both in the design's table and in ``records`` with different constants is an
    error (which one was meant?); equal definitions are fine.
    """
    own = dict(design.materials)
    for name in sorted({name for _p, name, _r in design.material_uses()}):
        if name not in records:
            continue
        if name in own and own[name] != records[name]:
            raise ParameterError(f"materials.{name}", source, "is defined differently in the design's [materials] "
                                 "table and in this file: rename one of them")
        own[name] = records[name]
    return dataclasses.replace(design, materials=own) if own != dict(design.materials) else design


def materials_block(library: Mapping[str, Material], names) -> dict[str, dict]:
    """``{name: record}`` (layout of ``materials.toml``, stress-charge form) of ``names``: the
    constants actually used, for JSON results."""
    return {n: library[n].to_record() for n in sorted(set(names))}

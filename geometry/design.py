"""Loading designs: the design kinds by their ``kind`` key, from a mapping or a TOML file.

The kinds live in modules of their own, on the shared base :class:`~geometry.design_base.DesignBase`:

- ``kind = "rpud"`` -- :class:`~geometry.design_rpud.RPUDDesign`, the rotary-percussive
  composition of the article (coupler, rings, flange, horn; :mod:`geometry.design_rpud`);
- ``kind = "stack"`` -- :class:`~geometry.design_stack.StackDesign`, coaxial segments along z
  (:mod:`geometry.design_stack`);
- ``kind = "cad"`` -- :class:`~geometry.design_cad.CadDesign`, a STEP file with a rule table that
  names its volumes and faces (:mod:`geometry.design_cad`).

Every name these modules export is also importable from here (``from geometry.design import
RPUDDesign`` keeps working).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rpud_common import ParameterError, check_choice, from_mapping, load_toml
from .design_base import MIN_WALL, POLING_VECTORS, DesignBase
from .design_cad import CadDesign, LengthRule, SizeRule, SurfaceRule, VolumeRule, step_path
from .design_materials import own_records
from .design_rpud import CouplerDesign, FlangeDesign, HornDesign, RPUDDesign, StackRings, default_design
from .design_stack import ElectrodeSpec, Segment, StackDesign
from .materials import Material
from .validate import design_table

__all__ = [
    "HornDesign", "StackRings", "FlangeDesign", "CouplerDesign", "RPUDDesign",
    "Segment", "ElectrodeSpec", "StackDesign", "DesignBase",
    "CadDesign", "VolumeRule", "SurfaceRule", "SizeRule", "LengthRule",
    "load_design", "design_from_mapping", "default_design", "POLING_VECTORS", "MIN_WALL", "KINDS",
]

KINDS: dict[str, type[DesignBase]] = {"rpud": RPUDDesign, "stack": StackDesign, "cad": CadDesign}
"""The design kinds by their ``kind`` key."""


def design_from_mapping(data: Mapping[str, Any], where: str = "",
                        materials: Mapping[str, Material] | None = None,
                        base_dir: str | os.PathLike | None = None) -> DesignBase:
    """Build a design from a mapping with a ``kind`` key ("rpud", "stack" or "cad").

    ``materials``: extra records (a user's material file) the design's names may resolve in;
    those it uses are added to its own table (see :mod:`geometry.design_materials`).
    ``base_dir``: folder a CAD design's relative ``step`` path is taken from (the TOML file's
    folder when loaded from a file; default the working directory).
    """
    if not isinstance(data, Mapping):
        raise ParameterError(where or "design", data, "must be a table")
    kind = data.get("kind", "rpud")
    check_choice(f"{where}.kind" if where else "kind", kind, tuple(KINDS))
    try:
        own = own_records(data.get("materials"))
        if materials:
            for name, rec in materials.items():
                if name in own and own[name] != rec:
                    raise ParameterError(f"materials.{name}", name, "is defined differently in the design's "
                                         "[materials] table and in the --materials file: rename one of them")
            data = {**data, "materials": {**materials, **own}}
        if kind == "cad" and base_dir is not None and isinstance(data.get("step"), str):
            data = {**data, "step": step_path(data["step"], base_dir)}
        design = from_mapping(KINDS[kind], data)
    except ParameterError as exc:
        if where:
            raise ParameterError(f"{where}: {exc.name}", exc.value, exc.allowed) from None
        raise
    if materials:
        keep = set(own) | {name for _p, name, _r in design.material_uses()}
        design = dataclasses.replace(design, materials={k: v for k, v in design.materials.items() if k in keep})
    if isinstance(design, CadDesign):
        try:
            design.resolve()            # the rules against the drawing: one line now, not after meshing
        except ParameterError as exc:
            if where:
                raise ParameterError(f"{where}: {exc.name}", exc.value, exc.allowed) from None
            raise
    return design


def load_design(path: str | os.PathLike, select: str | None = None,
                materials: Mapping[str, Material] | None = None) -> DesignBase:
    """Load a design from TOML.

    A file is either one design (top-level ``kind`` key, or RPUD tables ``[horn]``...) or a
    collection of designs, one table each (``[k33_rod]``, ``[k31_bar]``...) from which
    ``select`` picks one. A design may carry its own ``[materials]`` table; ``materials`` adds
    the records of a user's material file (``geometry.materials.load_library``). A CAD design's
    ``step`` path is relative to the TOML file's folder.

    Parameters
    ----------
    path : str or os.PathLike
        The TOML file.
    select : str, optional
        The design to take from a collection (its table name).
    materials : mapping of str to Material, optional
        Extra material records, by name.

    Returns
    -------
    DesignBase
        An :class:`RPUDDesign`, :class:`StackDesign` or :class:`CadDesign`, validated.

    Examples
    --------
    A design written by :meth:`DesignBase.save` reads back equal:

    >>> import os, tempfile
    >>> from geometry.examples import k33_rod
    >>> path = os.path.join(tempfile.mkdtemp(), "rod.toml")
    >>> k33_rod().save(path)
    >>> load_design(path) == k33_rod()
    True
    >>> load_design("geometry/examples.toml", select="k31_bar").name
    'k31_bar'
    """
    data = load_toml(path, "design")
    known = {f.name for cls in KINDS.values() for f in dataclasses.fields(cls)}
    table, where = design_table(data, str(path), select, known)
    return design_from_mapping(table, where=where, materials=materials, base_dir=Path(path).parent)

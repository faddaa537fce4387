"""Build a design and summarise it: parts (volume from the mesh, closed form, mass), groups,
counts, quality, timings, 1-D reference frequency (a JSON-friendly dict)."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from .builder import build
from .design_base import DesignBase
from .mesh import TaggedMesh

__all__ = ["build_report", "mesh_part_volumes"]

log = logging.getLogger(__name__)


def mesh_part_volumes(mesh: TaggedMesh) -> tuple[dict[str, float], dict[str, float]]:
    """Volume (m^3) and mass (kg) of every part, integrated over the mesh cells."""
    vol = mesh.cell_volumes()
    volumes: dict[str, float] = {}
    masses: dict[str, float] = {}
    for i, r in enumerate(mesh.regions):
        v = float(vol[mesh.cell_region == i].sum())
        volumes[r.part] = volumes.get(r.part, 0.0) + v
        masses[r.part] = masses.get(r.part, 0.0) + v * mesh.material(r.material).density
    return volumes, masses


def build_report(design: DesignBase, **build_kw: Any) -> tuple[TaggedMesh, dict]:
    """Mesh ``design`` (keywords as :func:`geometry.builder.build`) and report on it."""
    from .onedim import design_modes
    from .onedim_check import check_1d

    tm, rep = build(design, **build_kw)
    volumes, masses = mesh_part_volumes(tm)
    closed = design.part_volumes()
    extents = design.part_extents()
    parts = {}
    for part in tm.parts:
        parts[part] = {
            "materials": sorted({r.material for r in tm.regions if r.part == part}),
            "regions": [r.name for r in tm.regions if r.part == part],
            "z0_m": extents[part][0], "z1_m": extents[part][1],
            "volume_m3": volumes[part], "volume_closed_form_m3": closed[part],
            "volume_error": volumes[part] / closed[part] - 1.0,
            "mass_kg": masses[part],
        }
    onedim, f1, nodes = None, None, []
    if hasattr(design, "sections_1d"):    # a drawing (kind "cad") has no 1-D bar chain
        try:
            modes = design_modes(design)
            f1 = modes[0].frequency if modes else None
            nodes = list(modes[0].nodes) if modes else []
            if modes:
                onedim = {"f1_hz": f1, **check_1d(design, modes[0]).as_dict()}
                if not onedim["valid"]:
                    f1, nodes = None, []     # not a reference for this design: said why in "onedim"
        except Exception as exc:  # the 1-D reference is informative only
            log.warning("1-D reference failed: %s", exc)
            f1, nodes = None, []
    d = rep.as_dict()
    report = {
        "design": {"name": design.name, "kind": design.kind, "parameters": design.to_mapping()},
        "parts": parts,
        "total_mass_kg": float(sum(masses.values())),
        "regions": [{"name": r.name, "part": r.part, "material": r.material, "poling": r.poling,
                     "elements": int(np.sum(tm.cell_region == i))} for i, r in enumerate(tm.regions)],
        "electrodes": [{"name": e.name, "role": e.role, "triangles": int(len(tm.facet_sets[e.name]))}
                       for e in tm.electrodes],
        "physical_groups": d["physical_groups"],
        "mesh": {"order": rep.order, "algorithm": rep.algorithm, "mesher": rep.mesher, "n_nodes": rep.n_nodes,
                 "n_elements": rep.n_elements, "size_m": d["mesh_size_m"]},
        "quality": d["quality"],
        "timings_s": d["timings_s"],
        "f1_1d_hz": f1,
        "nodal_planes_1d_m": nodes,
        "onedim": onedim,
        "materials": {n: tm.material(n).to_record() for n in sorted({r.material for r in tm.regions})},
    }
    return tm, report

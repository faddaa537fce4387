"""Export a parametric design as a STEP file plus the rule table of a ``kind = "cad"`` design.

:func:`export_cad` builds the design's solids as the builder does (:mod:`geometry.solids`,
fragmented into one conformal model), writes them as STEP (lengths in mm in the file, as CAD
tools expect; every solid labelled with its region name) and writes ``design.toml``: a
:class:`~geometry.design_cad.CadDesign` whose rules give back the parametric design's regions
(by label and a point inside each solid), facet sets and electrodes (by plane and region, plus a
point on the face where the plane alone would take too much), its feature size caps
(:func:`geometry.sizing.feature_caps`) and its tuned lengths as declared length bands (so
resonance matching runs on the drawing too). Before anything is committed the STEP file is
read back and the rules applied to it: every region and facet set must come back with the
same solids and the same number of faces. Both files are written atomically.
"""

from __future__ import annotations

import json
import logging
import re
from pathlib import Path

from rpud_common import ParameterError, atomic_output, dump_toml
from .cad import apply_rules, face_point, gmsh_session, import_step, native_stdout_quiet, volume_point
from .design_base import POLING_VECTORS, DesignBase
from .design_cad import CadDesign, LengthRule
from .design_rpud import RPUDDesign
from .sizing import feature_caps

__all__ = ["export_cad", "cad_rules", "rules_toml", "STEP_NAME", "TOML_NAME"]

log = logging.getLogger(__name__)

STEP_NAME = "design.step"
TOML_NAME = "design.toml"

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def _poling_word(vector) -> str:
    for word, v in POLING_VECTORS.items():
        if v == (None if vector is None else tuple(float(x) for x in vector)):
            return word
    raise ParameterError("poling", vector, "has no keyword (only +-x, +-y, +-z polings export)")


def _roles(design: DesignBase) -> dict[str, str]:
    if isinstance(design, RPUDDesign):
        return design.electrode_roles()
    return {e.name: e.role for e in design.electrodes}


def _length_rules(design: DesignBase) -> tuple[list[LengthRule], tuple[str, ...]]:
    """The design's default tuned lengths as declared bands: the axial zones each changes, and
    the fixed zones of the same part between them (a stepped horn's length stretches the sections
    on both sides of its step fillet: one band spans the three). A band that spans a fillet
    stretches its arc with the band when the length changes (an ellipse's quarter, by the band's
    stretch: about 1 % in matching), where the parametric design keeps the radius; at the drawn
    length the two are the same solid. A length whose zones belong to other parts too is not
    declared."""
    zones = design._zones()
    rules, tuned = [], []
    for path in design.default_tuned:
        v = float(design.get(path))
        new = design.replace({path: v * 1.01})
        changed = [i for i, (z, n) in enumerate(zip(zones, new._zones()))
                   if abs((n[3] - n[2]) - (z[3] - z[2])) > 1e-12]
        span = zones[changed[0]:changed[-1] + 1] if changed else []
        if not span or len({z[1] for z in span}) != 1:
            log.info("%s changes %d axial zones of %d parts: not declared as a length", path, len(changed),
                     len({z[1] for z in span}))
            continue
        part, z0, z1 = span[0][1], span[0][2], span[-1][3]
        name = re.sub(r"[^A-Za-z0-9_]", "_", path.removeprefix("segments."))
        rules.append(LengthRule(name=name, z0=z0, z1=z1, part=part or design.length_part(path)))
        tuned.append(f"lengths.{name}.value")
    return rules, tuple(tuned)


def cad_rules(gmsh, design: DesignBase, region_vols, region_meta, facet_surfs, *, labels: dict[int, str]) -> dict:
    """The rule tables (TOML layout) that select the built model's solids and faces."""
    from .tagging import surface_rules

    bb = gmsh.model.getBoundingBox(-1, -1)
    tol = 1e-6 + 1e-6 * max(abs(x) for x in bb)
    volumes = []
    for region, vols in region_vols.items():
        part, material, poling = region_meta[region]
        for v in vols:
            point = volume_point(gmsh, v, margin=1e-5)
            if point is None:
                raise ParameterError("design", design.name, f"found no point inside region {region} to select it by")
            sel = {"point": list(point)}
            if labels.get(v):
                sel = {"name": labels[v], **sel}
            volumes.append({"region": region, "part": part, "material": material,
                            "poling": _poling_word(poling), "select": sel})
    roles = _roles(design)
    surfaces = []
    by_name: dict[str, list] = {}
    for name, region, axis, value, rmin in surface_rules(design):
        by_name.setdefault(name, []).append((region, axis, value, rmin))
    for name, faces in facet_surfs.items():
        role = roles.get(name, "none")
        for region, axis, value, rmin in by_name[name]:
            plane = {"normal": list(_AXES[axis]), "offset": float(value)}
            if rmin <= 0:
                surfaces.append({"name": name, "role": role, "select": {"plane": plane, "regions": [region]}})
                continue
            # only the faces outside a radius (the flange's clamping faces): one rule per face
            on_plane = [f for f in faces if abs(gmsh.model.getBoundingBox(2, f)["xyz".index(axis)] - value) < tol * 10]
            for f in on_plane:
                point = face_point(gmsh, f, tol)
                if point is None:
                    raise ParameterError("design", design.name, f"found no point on a face of {name} to select it by")
                surfaces.append({"name": name, "role": role,
                                 "select": {"plane": plane, "regions": [region], "point": list(point)}})
    for s in surfaces:
        if s["role"] == "none":
            del s["role"]
    caps, boxes = feature_caps(design)
    sizes = [{"region": r, "size": float(c)} for r, c in caps.items()]
    sizes += [{"box": [float(x) for x in box], "size": float(c)} for c, box, _r in boxes.values()]
    return {"volumes": volumes, "surfaces": surfaces, "sizes": sizes}


def _inline(value) -> str:
    """A TOML inline value (strings, numbers, lists, tables on one line)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, float):
        return repr(round(value, 12) + 0.0)          # 1e-12 m: far below any feature; no -0.0
    if isinstance(value, int):
        return str(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_inline(v) for v in value) + "]"
    return "{ " + ", ".join(f"{k} = {_inline(v)}" for k, v in value.items()) + " }"


def rules_toml(data: dict) -> str:
    """A CAD design mapping as TOML, one line per rule field (the rule tables stay readable)."""
    lines = []
    for key, value in data.items():
        if key not in ("volumes", "surfaces", "sizes", "lengths", "materials"):
            lines.append(f"{key} = {_inline(value)}")
    for key in ("lengths", "volumes", "surfaces", "sizes"):
        for rule in data.get(key, ()):
            lines.append(f"\n[[{key}]]")
            lines += [f"{k} = {_inline(v)}" for k, v in rule.items()]
    text = "\n".join(lines) + "\n"
    if data.get("materials"):
        text += "\n" + dump_toml({"materials": data["materials"]})
    return text


def _rename_products(step: Path, names: list[str]) -> None:
    """Label the k-th solid of an OCC-written STEP file with ``names[k]`` (OCC writes
    ``PRODUCT('<translator> n.k', ...)`` for the k-th solid of the compound, n counting the files
    this process has written)."""
    text = step.read_text(encoding="utf-8")

    def repl(m):
        k = int(m.group(2)) - 1
        return f"'{names[k]}'" if 0 <= k < len(names) else m.group(0)

    text = re.sub(r"'(Open CASCADE STEP translator [0-9.]+ \d+)\.(\d+)'", repl, text)
    step.write_text(text, encoding="utf-8")


def export_cad(design: DesignBase, folder: str | Path, name: str | None = None) -> tuple[Path, Path]:
    """Write ``folder/design.step`` and ``folder/design.toml`` (a ``kind = "cad"`` design).

    Parameters
    ----------
    design : RPUDDesign or StackDesign
    folder : path
        Created if missing; other files in it are left alone.
    name : str, optional
        Name of the CAD design (default: the design's name + ``"-cad"``).

    Returns
    -------
    (STEP path, TOML path)
    """
    from .tagging import parametric_model

    if isinstance(design, CadDesign):
        raise ParameterError("--export-step", design.name, "is already a cad design (copy its STEP file)")
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ParameterError("--export-step", str(folder), "is a file, not a folder")
    step_out, toml_out = folder / STEP_NAME, folder / TOML_NAME
    with atomic_output(step_out) as tmp_step, atomic_output(toml_out) as tmp_toml:
        with gmsh_session() as gmsh:
            gmsh.option.setString("Geometry.OCCTargetUnit", "M")     # file in mm, model in m
            region_vols, region_meta, facet_surfs = parametric_model(gmsh, design, {})
            order = [t for _d, t in gmsh.model.getEntities(3)]
            label = {}
            for region, vols in region_vols.items():
                for k, v in enumerate(vols):
                    label[v] = region if len(vols) == 1 else f"{region}_{k + 1}"
            rules = cad_rules(gmsh, design, region_vols, region_meta, facet_surfs, labels=label)
            with native_stdout_quiet():
                gmsh.write(str(tmp_step))
        _rename_products(tmp_step, [label[v] for v in order])
        lengths, tuned = _length_rules(design)
        data = {"kind": "cad", "name": name or f"{design.name}-cad", "step": STEP_NAME,
                "target_frequency": design.target_frequency,
                "elements_per_wavelength": design.elements_per_wavelength,
                "default_tuned": list(tuned), **rules,
                "lengths": [{"name": x.name, "z0": x.z0, "z1": x.z1, "part": x.part} for x in lengths]}
        if design.materials:
            data["materials"] = {n: m.to_record() for n, m in design.materials.items()}
        try:
            cad = _verify(design, data, tmp_step, region_vols, facet_surfs)
        except ParameterError as exc:
            # the labels did not survive the STEP writer: select by the points alone
            log.warning("solid labels not read back (%s); selecting solids by points only", exc)
            for rule in data["volumes"]:
                rule["select"].pop("name", None)
            cad = _verify(design, data, tmp_step, region_vols, facet_surfs)
        tmp_toml.write_text(f"# {cad.name}: {design.kind} design {design.name!r} exported as STEP + rules "
                            "(python -m geometry --export-step); SI units (m, Hz)\n" + rules_toml(data),
                            encoding="utf-8")
    return step_out, toml_out


def _verify(design, data, step: Path, region_vols, facet_surfs) -> CadDesign:
    """Read the written STEP file back and apply the rules: same regions, solids and faces."""
    from .design import design_from_mapping

    cad = design_from_mapping({**data, "step": str(step)})
    with gmsh_session() as gmsh:
        vols, labels = import_step(gmsh, str(step))
        got_vols, _meta, got_surfs = apply_rules(gmsh, cad, vols, labels)
    for region, vols_ in region_vols.items():
        if len(got_vols.get(region, ())) != len(vols_):
            raise ParameterError("--export-step", design.name, f"region {region} does not come back from the STEP "
                                 "file (internal error of the export)")
    for name, faces in facet_surfs.items():
        if len(got_surfs.get(name, ())) != len(faces):
            raise ParameterError("--export-step", design.name, f"facet set {name}: {len(faces)} faces exported, "
                                 f"{len(got_surfs.get(name, ()))} read back (internal error of the export)")
    log.info("export verified: %d solids, %d facet sets", len(vols), len(facet_surfs))
    return cad


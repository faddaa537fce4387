"""``TaggedMesh``: the tetrahedral mesh that ``geometry`` hands to ``fem``.

A tagged mesh is plain data: points, tetrahedra (linear or quadratic), one region index per
element (each region knowing its part, material and poling), and named triangle sets
(electrodes, ``horn_tip``, ``teeth_tops``, ``flange``...). It converts to a scikit-fem mesh with
``subdomains``/``boundaries`` and to meshio for ``.msh``/``.vtu`` files. It does not import gmsh.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from rpud_common import ParameterError, atomic_output

if TYPE_CHECKING:
    from .materials import Material

__all__ = ["Region", "Electrode", "TaggedMesh", "match_rows"]


@dataclass(frozen=True)
class Region:
    """One volume region of the mesh.

    Attributes
    ----------
    name : str
        Unique region name, e.g. ``"ring_1"``, ``"horn"``.
    part : str
        The part it belongs to, e.g. ``"stack"``, ``"horn"``, ``"coupler"``.
    material : str
        Material key in the material library (``geometry.materials``).
    poling : tuple of 3 floats or None
        Unit poling direction for piezoceramic regions (``(0, 0, 1)`` or ``(0, 0, -1)`` in a
        stack); ``None`` for passive material.
    """

    name: str
    part: str
    material: str
    poling: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Electrode:
    """An electrode surface: the facet set ``name``, wired as ``"hot"`` or ``"ground"``."""

    name: str
    role: Literal["hot", "ground"]


def match_rows(table: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Index into ``table`` of each row of ``rows``, comparing rows as unordered integer sets.

    Parameters
    ----------
    table, rows : (n, k) and (m, k) int arrays

    Returns
    -------
    (m,) int array; raises ``KeyError`` if a row is not found.
    """
    a = np.sort(np.asarray(table, dtype=np.int64), axis=1)
    b = np.sort(np.asarray(rows, dtype=np.int64), axis=1)
    if len(b) == 0:
        return np.zeros(0, dtype=np.int64)
    base = int(max(a.max(initial=0), b.max(initial=0))) + 1
    # Encode each sorted row as one integer; fine for meshes below ~2e6 points (k = 3).
    weights = base ** np.arange(a.shape[1] - 1, -1, -1, dtype=np.int64)
    ka, kb = a @ weights, b @ weights
    order = np.argsort(ka)
    pos = np.searchsorted(ka, kb, sorter=order)
    pos = np.clip(pos, 0, len(ka) - 1)
    found = order[pos]
    if not np.all(ka[found] == kb):
        raise KeyError(f"{int(np.sum(ka[found] != kb))} rows not found")
    return found


@dataclass(frozen=True, eq=False, repr=False)
class TaggedMesh:
    """A tetrahedral mesh with named regions and facet sets (SI units: metres).

    Attributes
    ----------
    points : (n, 3) float array
        Node coordinates in m. The drill axis is z.
    cells : (m, 4) or (m, 10) int array
        Tetrahedra in meshio/VTK node order (corner nodes first, then edge nodes
        01, 12, 02, 03, 13, 23 for quadratic geometry).
    cell_region : (m,) int array
        Index into ``regions`` for every cell.
    regions : tuple of Region
    facet_sets : mapping of str to (k, 3) int array
        Named surfaces as triangles of corner-node indices.
    electrodes : tuple of Electrode
        Electrode surfaces (each is also a key of ``facet_sets``).
    materials : mapping of str to Material
        The records of the regions' materials as the design resolved them (its own library:
        built-in records, its ``[materials]`` table, a ``--materials`` file). ``fem`` assembles,
        sizes and labels with exactly these; a name missing here resolves in the built-in
        library (:attr:`library`).
    """

    points: np.ndarray
    cells: np.ndarray
    cell_region: np.ndarray
    regions: tuple[Region, ...]
    facet_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    electrodes: tuple[Electrode, ...] = ()
    materials: Mapping[str, "Material"] = field(default_factory=dict)

    def __repr__(self) -> str:
        # counts and names: the generated repr would print every node and cell
        names = [r.name for r in self.regions]
        regions = ", ".join(names[:6]) + (f", ... ({len(names)} in all)" if len(names) > 6 else "")
        kind = "quadratic" if self.cells.shape[1] == 10 else "linear"
        return (f"TaggedMesh({len(self.points)} nodes, {len(self.cells)} {kind} tetrahedra; regions {regions}; "
                f"{len(self.facet_sets)} surfaces, {len(self.electrodes)} electrodes)")

    def __post_init__(self):
        object.__setattr__(self, "points", np.ascontiguousarray(self.points, dtype=np.float64))
        object.__setattr__(self, "cells", np.ascontiguousarray(self.cells, dtype=np.int64))
        object.__setattr__(self, "cell_region", np.ascontiguousarray(self.cell_region, dtype=np.int64))
        object.__setattr__(self, "regions", tuple(self.regions))
        object.__setattr__(self, "electrodes", tuple(self.electrodes))
        object.__setattr__(self, "facet_sets", {k: np.asarray(v, dtype=np.int64).reshape(-1, 3)
                                                for k, v in self.facet_sets.items()})
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise ParameterError("points", self.points.shape, "must have shape (n, 3)")
        if self.cells.ndim != 2 or self.cells.shape[1] not in (4, 10):
            raise ParameterError("cells", self.cells.shape, "must have shape (m, 4) or (m, 10)")
        if self.cell_region.shape != (len(self.cells),):
            raise ParameterError("cell_region", self.cell_region.shape, f"must have shape ({len(self.cells)},)")
        names = [r.name for r in self.regions]
        if len(set(names)) != len(names):
            raise ParameterError("regions", names, "region names must be unique")
        if len(self.cell_region) and (self.cell_region.min() < 0 or self.cell_region.max() >= len(self.regions)):
            raise ParameterError("cell_region", "out of range", f"indices must lie in [0, {len(self.regions) - 1}]")
        for e in self.electrodes:
            if e.name not in self.facet_sets:
                raise ParameterError("electrodes", e.name, "has no facet set of that name")
            if e.role not in ("hot", "ground"):
                raise ParameterError(f"electrodes.{e.name}.role", e.role, "must be 'hot' or 'ground'")

        for name, rec in self.materials.items():
            if getattr(rec, "name", None) != name:
                raise ParameterError(f"materials.{name}", rec, "must be the Material record of that name")

    # ------------------------------------------------------------------ queries
    @property
    def library(self) -> dict:
        """Where region material names resolve: the built-in records overlaid with :attr:`materials`."""
        from .materials import builtin_library

        return {**builtin_library(), **self.materials}

    def material(self, name: str) -> "Material":
        """The record of material ``name`` (:attr:`library`; unknown names list the known ones)."""
        from .materials import get_material

        return get_material(name, self.library)

    @property
    def order(self) -> int:
        """Geometric order: 1 (straight tetrahedra) or 2 (curved, 10 nodes)."""
        return 1 if self.cells.shape[1] == 4 else 2

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    def region(self, name: str) -> Region:
        """The region called ``name``."""
        for r in self.regions:
            if r.name == name:
                return r
        raise ParameterError("region", name, "unknown; known: " + ", ".join(r.name for r in self.regions))

    def cells_in(self, *, region: str | None = None, part: str | None = None,
                 material: str | None = None) -> np.ndarray:
        """Indices of the cells of a region, a part or a material (exactly one selector)."""
        if sum(x is not None for x in (region, part, material)) != 1:
            raise TypeError("give exactly one of region=, part=, material=")
        if region is not None:
            self.region(region)
            wanted = [i for i, r in enumerate(self.regions) if r.name == region]
        elif part is not None:
            wanted = [i for i, r in enumerate(self.regions) if r.part == part]
            if not wanted:
                raise ParameterError("part", part, "unknown; known: " + ", ".join(sorted(self.parts)))
        else:
            wanted = [i for i, r in enumerate(self.regions) if r.material == material]
        return np.flatnonzero(np.isin(self.cell_region, wanted))

    @property
    def parts(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.part for r in self.regions))

    def facets(self, name: str) -> np.ndarray:
        """The (k, 3) corner-node triangles of the facet set ``name``."""
        if name not in self.facet_sets:
            raise ParameterError("surface", name, "unknown; known: " + ", ".join(sorted(self.facet_sets)))
        return self.facet_sets[name]

    def cell_volumes(self) -> np.ndarray:
        """Volume of every cell in m^3 (exact for curved cells: 4-point rule on the P2 map)."""
        from skfem import CellBasis, ElementTetP0

        m = self.to_skfem(with_tags=False)
        basis = CellBasis(m, ElementTetP0(), intorder=2 if self.order == 2 else 0)
        return np.asarray(basis.dx.sum(axis=1))

    def replace(self, **changes) -> "TaggedMesh":
        """A copy with some fields replaced (e.g. morphed ``points``)."""
        return dataclasses.replace(self, **changes)

    def boundary_triangles(self) -> np.ndarray:
        """(k, 3) corner-node triangles on the boundary of the mesh (faces of one cell only)."""
        local = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
        faces = np.sort(self.cells[:, :4][:, local].reshape(-1, 3), axis=1)
        uniq, counts = np.unique(faces, axis=0, return_counts=True)
        return uniq[counts == 1]

    def submesh(self, cell_mask: np.ndarray) -> "TaggedMesh":
        """The mesh of the selected cells: nodes renumbered, unused regions dropped, facet sets
        kept where their triangles are faces of kept cells, electrodes kept while non-empty."""
        keep = np.flatnonzero(np.asarray(cell_mask, dtype=bool))
        if keep.size == 0:
            raise ParameterError("cell_mask", "empty", "select at least one cell")
        cells = self.cells[keep]
        used = np.unique(cells)
        new_index = np.full(self.n_points, -1, dtype=np.int64)
        new_index[used] = np.arange(len(used))
        regions_used = np.unique(self.cell_region[keep])
        region_index = np.full(len(self.regions), -1, dtype=np.int64)
        region_index[regions_used] = np.arange(len(regions_used))
        local = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
        faces = np.unique(np.sort(cells[:, :4][:, local].reshape(-1, 3), axis=1), axis=0)
        facet_sets = {}
        for name, tri in self.facet_sets.items():
            if len(tri) == 0 or np.any(new_index[tri] < 0):
                tri = tri[np.all(new_index[tri] >= 0, axis=1)]
            if len(tri) == 0:
                continue
            try:
                match_rows(faces, tri)
            except KeyError:
                continue                  # e.g. an interface whose other side was cut away
            facet_sets[name] = new_index[tri]
        electrodes = tuple(e for e in self.electrodes if e.name in facet_sets)
        regions = tuple(self.regions[i] for i in regions_used)
        names = {r.material for r in regions}
        return TaggedMesh(self.points[used], new_index[cells], region_index[self.cell_region[keep]],
                          regions, facet_sets, electrodes,
                          {k: v for k, v in self.materials.items() if k in names})

    # ------------------------------------------------------------------ conversions
    def _corner_renumbering(self) -> tuple[np.ndarray, np.ndarray]:
        """Corner nodes used by cells and old->new index map (skfem numbers corners first)."""
        corners = np.unique(self.cells[:, :4])
        old_to_new = np.full(self.n_points, -1, dtype=np.int64)
        old_to_new[corners] = np.arange(len(corners))
        return corners, old_to_new

    def to_skfem(self, with_tags: bool = True):
        """A scikit-fem ``MeshTet1``/``MeshTet2`` with ``subdomains`` (one per region name)
        and ``boundaries`` (one per facet set).

        For quadratic geometry skfem renumbers nodes (corners first); the returned mesh's
        ``p`` holds the corner nodes and ``doflocs`` all P2 nodes.
        """
        from skfem import MeshTet1, MeshTet2

        if self.order == 1:
            corners, old_to_new = self._corner_renumbering()
            mesh = MeshTet1(self.points[corners].T, old_to_new[self.cells].T)
        else:
            mesh = MeshTet2(self.points.T, self.cells.T)
            # skfem's reordering maps corner k of the input to index rank(k) among corners
            corners, old_to_new = self._corner_renumbering()
        if not with_tags:
            return mesh
        subdomains = {r.name: np.flatnonzero(self.cell_region == i).astype(np.int32)
                      for i, r in enumerate(self.regions)}
        boundaries = {}
        facets_table = mesh.facets.T
        for name, tri in self.facet_sets.items():
            new_tri = old_to_new[tri]
            if np.any(new_tri < 0):
                raise ParameterError(f"facet_sets.{name}", "node", "refers to a node that no cell uses")
            boundaries[name] = match_rows(facets_table, new_tri).astype(np.int32)
        # The tags are set on the mesh built here rather than through with_boundaries() /
        # with_subdomains(): those return copies that rebuild facets, edges and DOFs (~0.4 s at
        # 40k nodes); the tags are plain dataclass fields and nothing else refers to this mesh.
        mesh._subdomains = subdomains
        mesh._boundaries = boundaries
        return mesh

    def to_meshio(self):
        """A ``meshio.Mesh``: volume cells with ``region``/``material``/``poling`` cell data,
        plus one triangle block per facet set, with ``cell_sets`` naming everything."""
        import meshio

        vol_type = "tetra" if self.order == 1 else "tetra10"
        blocks = [(vol_type, self.cells)]
        region_id = [self.cell_region]
        materials = sorted({r.material for r in self.regions})
        mat_of_region = np.array([materials.index(r.material) for r in self.regions], dtype=np.int64)
        pol_of_region = np.array([0 if r.poling is None else int(np.sign(r.poling[2]) or 2)
                                  for r in self.regions], dtype=np.int64)
        material_id = [mat_of_region[self.cell_region]]
        poling = [pol_of_region[self.cell_region]]
        cell_sets = {r.name: [np.flatnonzero(self.cell_region == i)] for i, r in enumerate(self.regions)}
        for name in self.facet_sets:
            cell_sets[name] = [np.zeros(0, dtype=np.int64)]
        for k, (name, tri) in enumerate(self.facet_sets.items()):
            blocks.append(("triangle", tri))
            region_id.append(np.full(len(tri), -1, dtype=np.int64))
            material_id.append(np.full(len(tri), -1, dtype=np.int64))
            poling.append(np.zeros(len(tri), dtype=np.int64))
            for other in cell_sets:
                cell_sets[other].append(np.arange(len(tri)) if other == name else np.zeros(0, dtype=np.int64))
        # physical tags for the gmsh writer: regions 1..R, facet sets R+1..
        phys = [self.cell_region + 1] + [np.full(len(t), len(self.regions) + 1 + k, dtype=np.int64)
                                         for k, t in enumerate(self.facet_sets.values())]
        field_data = {r.name: np.array([i + 1, 3]) for i, r in enumerate(self.regions)}
        field_data.update({n: np.array([len(self.regions) + 1 + k, 2]) for k, n in enumerate(self.facet_sets)})
        return meshio.Mesh(
            self.points, blocks,
            cell_data={"region": region_id, "material": material_id, "poling": poling,
                       "gmsh:physical": phys, "gmsh:geometrical": phys},
            cell_sets=cell_sets, field_data=field_data,
        )

    def write(self, path: str | Path) -> Path:
        """Write ``.vtu`` (ParaView) or ``.msh`` (Gmsh 2.2, physical tags named) atomically;
        the format comes from the suffix."""
        import meshio

        path = Path(path)
        fmt = {".vtu": "vtu", ".msh": "gmsh22"}.get(path.suffix.lower())
        if fmt is None:
            raise ParameterError("output", str(path), "must end in .vtu or .msh")
        mesh = self.to_meshio()
        # Sets live in the gmsh physical tags (.msh) or the region/material data (.vtu).
        mesh.cell_sets = {}
        drop = ("gmsh:physical", "gmsh:geometrical") if fmt == "vtu" else ("region", "material", "poling")
        for key in drop:
            mesh.cell_data.pop(key)
        if fmt == "vtu":
            mesh.field_data = {}
        with atomic_output(path) as tmp:
            meshio.write(tmp, mesh, file_format=fmt)
        return path

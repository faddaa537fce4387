"""Layout: the import graph is one-way (rpud_common -> geometry -> fem -> results, impact apart
from geometry and fem) and acyclic, and ``import impact`` loads no mesh, FE or rendering package.

The graph is read from the source (every ``import`` statement, also those inside functions),
so a lazy import counts as an arrow too."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("rpud_common", "geometry", "fem", "impact", "results")
#: which packages each package may import (besides itself)
ALLOWED = {
    "rpud_common": set(),
    "geometry": {"rpud_common"},
    "fem": {"rpud_common", "geometry"},
    "impact": {"rpud_common"},
    "results": {"rpud_common", "geometry", "fem", "impact"},
}


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            mods[name] = path
    return mods


def _resolve(name: str, mods) -> str | None:
    """The project module ``name`` refers to (the longest existing prefix), or None."""
    parts = name.split(".")
    while parts:
        cand = ".".join(parts)
        if cand in mods:
            return cand
        parts.pop()
    return None


def import_graph() -> dict[str, set[str]]:
    """Project module -> the project modules it imports anywhere in its source."""
    mods = _modules()
    graph = {}
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"
        here = name if is_pkg else name.rpartition(".")[0]
        out = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here.split(".")
                    base = base[: len(base) - (node.level - 1)]
                    stem = ".".join(base + ([node.module] if node.module else []))
                else:
                    stem = node.module or ""
                targets = [f"{stem}.{a.name}" for a in node.names] + [stem]
            for t in targets:
                r = _resolve(t, mods)
                if r is not None and r != name:
                    out.add(r)
        graph[name] = out
    return graph


def _cycles(graph) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _package_of(module: str) -> str:
    return module.split(".")[0]


def problems(graph) -> list[str]:
    """Upward or sideways arrows between packages, and import cycles between modules."""
    bad = []
    for src, dsts in sorted(graph.items()):
        p = _package_of(src)
        for dst in sorted(dsts):
            q = _package_of(dst)
            if q != p and q not in ALLOWED[p]:
                bad.append(f"{src} imports {dst}: {p} may import only {sorted(ALLOWED[p]) or 'nothing of ours'}")
    # a package's __init__ re-exporting its modules is not a cycle with the modules importing
    # the package's siblings; leave __init__ -> submodule arrows out of the cycle search
    inner = {s: {d for d in ds if not (s in PACKAGES and _package_of(d) == s)} for s, ds in graph.items()}
    bad += [f"import cycle: {' <-> '.join(c)}" for c in _cycles(inner)]
    return bad


def test_import_graph_is_one_way_and_acyclic():
    assert problems(import_graph()) == []


def test_the_check_catches_an_upward_import_and_a_cycle():
    """The same check on the real graph plus one deliberately added upward import and one cycle."""
    g = import_graph()
    g["geometry.design"] = g["geometry.design"] | {"results.pipeline"}          # upward
    g["impact.model"] = g["impact.model"] | {"fem.modal"}                        # sideways
    g["rpud_common.errors"] = g["rpud_common.errors"] | {"rpud_common.cli"}     # closes a cycle
    found = problems(g)
    assert any(p.startswith("geometry.design imports results.pipeline") for p in found)
    assert any(p.startswith("impact.model imports fem.modal") for p in found)
    assert any("import cycle" in p and "rpud_common.errors" in p for p in found)


@pytest.mark.parametrize("code", [
    "import impact",
    "import impact; impact.simulate; impact.ensemble_statistics; impact.sweep",
    "from impact.stats import ensemble_statistics; from impact.cli import main",
])
def test_import_impact_loads_no_mesh_fe_or_rendering_package(code):
    probe = (f"{code}; import sys; "
             "print(sorted({m.split('.')[0] for m in sys.modules} & "
             "{'gmsh', 'skfem', 'pyvista', 'vtk', 'meshio', 'geometry', 'fem', 'results', 'matplotlib'}))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("package", ["rpud_common", "geometry", "fem", "impact"])
def test_every_public_name_resolves(package):
    """A lazy package API must not name something its modules no longer define."""
    import importlib

    mod = importlib.import_module(package)
    for name in mod.__all__:
        assert getattr(mod, name) is not None, name
    assert set(mod.__all__) <= set(dir(mod))


@pytest.mark.parametrize("package", ["rpud_common", "geometry", "fem", "impact", "results"])
def test_no_public_name_is_shadowed_by_a_submodule(package):
    """Importing a submodule binds its name on the package: a public function named like a
    submodule (``impact.sweep`` when the module was ``impact/sweep.py``) would turn into that
    module as soon as anything imported it."""
    import importlib
    import pkgutil
    import types

    mod = importlib.import_module(package)
    subs = {m.name for m in pkgutil.iter_modules(mod.__path__)}
    clash = sorted(n for n in mod.__all__ if n in subs)
    assert not clash, f"{package}: public names that are also submodules: {clash}"
    for name in mod.__all__:
        assert not isinstance(getattr(mod, name), types.ModuleType), name

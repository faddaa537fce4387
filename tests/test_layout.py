"""Layout: the import graph is one-way (rpud_common -> geometry -> fem -> results, impact apart
from geometry and fem) and acyclic, commands sit on top of it, and ``import impact`` loads no
mesh, FE or rendering package.

The graph is read from the source (every ``import`` statement, also those inside functions, and
every import by a constant string: ``importlib.import_module("x")``, ``__import__("x")``,
``launch("x")``), so a lazy import counts as an arrow too.

Commands are the top layer: a package's ``__main__`` module, its ``*_cli`` modules, the code under
an ``if __name__ == "__main__":`` guard and the console scripts (``rpud_common.entry``). A
command may import any package; a library module may import no command."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("rpud_common", "geometry", "fem", "impact", "results")
#: which packages each package's library may import (besides itself)
ALLOWED = {
    "rpud_common": set(),
    "geometry": {"rpud_common"},
    "fem": {"rpud_common", "geometry"},
    "impact": {"rpud_common"},
    "results": {"rpud_common", "geometry", "fem", "impact"},
}
CONSOLE_SCRIPTS = "rpud_common.entry"
#: the part of a module that runs only as a program (its ``if __name__ == "__main__":`` block)
GUARD = ":__main__"
#: calls whose constant first argument names a module they import
STRING_IMPORTERS = ("import_module", "__import__", "launch")


def is_command(module: str) -> bool:
    """True for a module (or guard block) of the command layer."""
    last = module.rpartition(".")[2]
    return (module.endswith(GUARD) or last == "__main__" or last.endswith("_cli")
            or module == CONSOLE_SCRIPTS)


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


def _is_main_guard(node) -> bool:
    """``if __name__ == "__main__":``"""
    t = getattr(node, "test", None)
    return (isinstance(node, ast.If) and isinstance(t, ast.Compare) and isinstance(t.left, ast.Name)
            and t.left.id == "__name__" and len(t.comparators) == 1
            and getattr(t.comparators[0], "value", None) == "__main__")


def _string_import(node) -> str | None:
    """The module a call imports by a constant string, or None."""
    if not (isinstance(node, ast.Call) and node.args):
        return None
    f = node.func
    name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
    arg = node.args[0]
    if name in STRING_IMPORTERS and isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value
    return None


def _imported_names(node, here: str) -> tuple[str, list[str]]:
    """(module, names) of an ``import`` or ``from ... import`` statement; module absolute."""
    if isinstance(node, ast.Import):
        return "", [a.name for a in node.names]
    base = here.split(".")
    stem = node.module or ""
    if node.level:
        base = base[: len(base) - (node.level - 1)]
        stem = ".".join(base + ([node.module] if node.module else []))
    return stem, [a.name for a in node.names]


def module_imports(name: str, source: str, mods) -> dict[str, dict[str, set[str]]]:
    """What module ``name`` imports: ``{part: {"code": modules, "string": modules}}``.

    ``part`` is ``name``, or ``name + GUARD`` for the imports under its ``__main__`` guard."""
    tree = ast.parse(source)
    here = name if mods.get(name, Path()).name == "__init__.py" else name.rpartition(".")[0]
    guarded = {id(n) for g in tree.body if _is_main_guard(g) for stmt in g.body for n in ast.walk(stmt)}
    out = {name: {"code": set(), "string": set()}, name + GUARD: {"code": set(), "string": set()}}
    for node in ast.walk(tree):
        part = out[name + GUARD if id(node) in guarded else name]
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            stem, names = _imported_names(node, here)
            targets = names if isinstance(node, ast.Import) else [f"{stem}.{n}" for n in names] + [stem]
            kind = "code"
        elif (target := _string_import(node)) is not None:
            targets, kind = [target], "string"
        else:
            continue
        for t in targets:
            r = _resolve(t, mods)
            if r is not None and r != name:
                part[kind].add(r)
    return {k: v for k, v in out.items() if k == name or v["code"] or v["string"]}


def private_imports(name: str, source: str, mods) -> list[str]:
    """The names with a leading underscore that module ``name`` takes from another project module:
    ``from other import _name``, or ``other._name`` on a module it imported. What more than one
    module uses is public (named without the underscore, in ``__all__``)."""
    tree = ast.parse(source)
    here = name if mods.get(name, Path()).name == "__init__.py" else name.rpartition(".")[0]
    out, aliases = [], {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if (r := _resolve(a.name, mods)) is not None:
                    aliases[a.asname or a.name.split(".")[0]] = r if a.asname else _resolve(a.name.split(".")[0], mods)
        elif isinstance(node, ast.ImportFrom):
            stem, names = _imported_names(node, here)
            src = _resolve(stem, mods)
            if src is None:
                continue
            for a in node.names:
                if f"{stem}.{a.name}" in mods:
                    aliases[a.asname or a.name] = f"{stem}.{a.name}"
                elif _is_private(a.name) and src != name:
                    out.append(f"{name} imports {a.name} from {src}")
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and _is_private(node.attr) and isinstance(node.value, ast.Name)
                and aliases.get(node.value.id) not in (None, name)):
            out.append(f"{name} uses {aliases[node.value.id]}.{node.attr}")
    return sorted(set(out))


def _is_private(attr: str) -> bool:
    return attr.startswith("_") and not attr.startswith("__")


def _all_imports() -> dict[str, dict[str, set[str]]]:
    mods = _modules()
    out = {}
    for name, path in mods.items():
        out.update(module_imports(name, path.read_text(encoding="utf-8"), mods))
    return out


def import_graph() -> dict[str, set[str]]:
    """Project module (or guard block) -> the project modules it imports anywhere in its source."""
    return {m: kinds["code"] | kinds["string"] for m, kinds in _all_imports().items()}


def string_imports_between_packages(imports=None) -> list[str]:
    """Imports by a string that cross a package boundary: a dispatch no reader of the imports sees."""
    imports = _all_imports() if imports is None else imports
    return [f"{src} imports {dst} by a string" for src, kinds in sorted(imports.items())
            for dst in sorted(kinds["string"]) if _package_of(dst) != _package_of(src)]


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
    return module.split(".")[0].split(":")[0]


def problems(graph) -> list[str]:
    """Upward or sideways arrows between packages, libraries importing commands, and import cycles."""
    bad = []
    for src, dsts in sorted(graph.items()):
        p = _package_of(src)
        for dst in sorted(dsts):
            q = _package_of(dst)
            if is_command(src):
                continue
            if is_command(dst):
                bad.append(f"{src} imports {dst}: a library module may import no command")
            elif q != p and q not in ALLOWED[p]:
                bad.append(f"{src} imports {dst}: {p} may import only {sorted(ALLOWED[p]) or 'nothing of ours'}")
    # a package's __init__ re-exporting its modules is not a cycle with the modules importing
    # the package's siblings; leave __init__ -> submodule arrows out of the cycle search
    inner = {s: {d for d in ds if not (s in PACKAGES and _package_of(d) == s)} for s, ds in graph.items()}
    bad += [f"import cycle: {' <-> '.join(c)}" for c in _cycles(inner)]
    return bad


def test_import_graph_is_one_way_and_acyclic():
    assert problems(import_graph()) == []


def test_no_string_import_between_packages():
    assert string_imports_between_packages() == []


def test_the_check_catches_an_upward_import_and_a_cycle():
    """The same check on the real graph plus one deliberately added upward import and one cycle."""
    g = import_graph()
    g["geometry.design"] = g["geometry.design"] | {"results.pipeline"}          # upward
    g["impact.model"] = g["impact.model"] | {"fem.modal"}                        # sideways
    g["rpud_common.errors"] = g["rpud_common.errors"] | {"rpud_common.cli"}     # closes a cycle
    g["fem.modal"] = g["fem.modal"] | {"fem.modal_cli"}                          # library -> command
    found = problems(g)
    assert any(p.startswith("geometry.design imports results.pipeline") for p in found)
    assert any(p.startswith("impact.model imports fem.modal:") for p in found)
    assert any("import cycle" in p and "rpud_common.errors" in p for p in found)
    assert any(p.startswith("fem.modal imports fem.modal_cli: a library") for p in found)


def test_commands_may_import_any_package_but_not_in_a_cycle():
    g = import_graph()
    g["impact.__main__"] = g["impact.__main__"] | {"results.pipeline"}            # a command: allowed
    assert problems(g) == []
    g["results.coupled_cli"] = g["results.coupled_cli"] | {"impact.__main__"}      # closes a cycle
    assert any("import cycle" in p and "impact.__main__" in p for p in problems(g))


def test_no_private_name_crosses_modules():
    """What another module uses is public: named without the underscore, in ``__all__``."""
    mods = _modules()
    found = [line for name, path in mods.items()
             for line in private_imports(name, path.read_text(encoding="utf-8"), mods)]
    assert found == []


def test_the_private_import_check_catches_both_forms():
    mods = _modules()
    src = ("from .kernel import _grid_step, plan\n"
           "from impact import stats\n"
           "import impact.model as model\n"
           "from . import params\n"
           "x = stats._estimates(model._series, params.ImpactParams)\n"
           "from ._private_helpers import thing\n")
    assert private_imports("impact.coupled", src, mods) == [
        "impact.coupled imports _grid_step from impact.kernel",
        "impact.coupled uses impact.model._series",
        "impact.coupled uses impact.stats._estimates",
    ]


def test_the_check_reads_string_imports_and_main_guards():
    """Imports by a constant string are arrows, and a cross-package one is reported; the imports
    under a ``__main__`` guard belong to the command layer."""
    mods = _modules()
    src = (
        "import importlib\n"
        "def f():\n"
        "    return importlib.import_module('results.coupled_cli').main\n"
        "if __name__ == '__main__':\n"
        "    from rpud_common.launch import launch\n"
        "    launch('impact.drilling_cli', prog='x')\n"
    )
    found = module_imports("impact.model", src, mods)
    assert found["impact.model"]["string"] == {"results.coupled_cli"}
    assert found["impact.model" + GUARD] == {"code": {"rpud_common.launch"}, "string": {"impact.drilling_cli"}}
    assert string_imports_between_packages(found) == ["impact.model imports results.coupled_cli by a string"]
    g = {m: k["code"] | k["string"] for m, k in found.items()}
    assert problems(g) == ["impact.model imports results.coupled_cli: a library module may import no command"]


@pytest.mark.parametrize("code", [
    "import impact",
    "import impact; impact.simulate; impact.ensemble_statistics; impact.sweep",
    "from impact.stats import ensemble_statistics; from impact.__main__ import main",
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

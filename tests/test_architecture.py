"""Static checks over every module of urident/ (AST walks, nothing imported): no import cycles
(module-level imports; and none either when the imports deferred into functions are counted), no
private names imported across modules, and the 78-parameter layout written only in
``urident.model.parameters``."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYOUT_MODULE = "urident.model.parameters"


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules(root: Path, package: str = "urident") -> dict[str, Path]:
    return {_module_name(p, root): p for p in sorted((root / package).rglob("*.py"))}


def _is_submodule(modules: dict[str, Path], package: str, name: str) -> bool:
    """``package.name`` is a module: a .py file or package, or a compiled extension (``_kernel.*.so``)."""
    if f"{package}.{name}" in modules:
        return True
    pkg = modules.get(package)
    return pkg is not None and pkg.name == "__init__.py" and any(
        p.name.split(".")[0] == name for p in pkg.parent.iterdir() if p.is_file())


def _target(modules: dict[str, Path], module: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")
    if modules[module].name != "__init__.py":
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _module_level_imports(tree: ast.Module) -> list[ast.stmt]:
    """Import statements that run when the module is imported (``if``/``try``/``with`` blocks
    included, ``if TYPE_CHECKING:`` too); not those inside functions or classes."""
    out: list[ast.stmt] = []

    def visit(stmts):
        for s in stmts:
            if isinstance(s, (ast.Import, ast.ImportFrom)):
                out.append(s)
            elif isinstance(s, (ast.If, ast.Try, ast.With)):
                for name in ("body", "orelse", "finalbody"):
                    visit(getattr(s, name, []))
                for handler in getattr(s, "handlers", []):
                    visit(handler.body)
    visit(tree.body)
    return out


def _edges(modules: dict[str, Path], module: str, nodes) -> set[str]:
    """Modules of the package that ``nodes`` import (``from pkg import sub`` is the submodule)."""
    out = set()
    for n in nodes:
        if isinstance(n, ast.Import):
            out.update(a.name for a in n.names)
        else:
            target = _target(modules, module, n)
            for a in n.names:
                out.add(f"{target}.{a.name}" if _is_submodule(modules, target, a.name) else target)
    return {m for m in out if m in modules and m != module}


def import_graph(root: Path, package: str = "urident", deferred: bool = False) -> dict[str, set[str]]:
    """Module → the package's modules it imports at module level (``deferred``: also inside
    functions and classes)."""
    modules = _modules(root, package)
    out = {}
    for m, p in modules.items():
        tree = ast.parse(p.read_text(encoding="utf-8"))
        nodes = ([n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))] if deferred
                 else _module_level_imports(tree))
        out[m] = _edges(modules, m, nodes)
    return out


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle (as a path a → … → a) per strongly connected component with more than one module
    (or a module importing itself), by Tarjan's algorithm without recursion."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1 or v in graph[v]:
                        components.append(sorted(comp))
    return [_cycle_path(graph, set(c)) for c in components]


def _cycle_path(graph: dict[str, set[str]], comp: set[str]) -> list[str]:
    start = min(comp)
    paths = {start: [start]}
    frontier = [start]
    while frontier:      # breadth-first inside the component back to the start
        nxt = []
        for v in frontier:
            for w in sorted(graph[v]):
                if w == start:
                    return paths[v] + [start]
                if w in comp and w not in paths:
                    paths[w] = paths[v] + [w]
                    nxt.append(w)
        frontier = nxt
    return sorted(comp)


def private_imports(root: Path, package: str = "urident") -> list[str]:
    """``from M import _name`` (anywhere in a module, function bodies included) of a private name
    of another module; a package's own private submodule (a compiled ``_kernel``) is allowed to
    the modules of that package."""
    modules = _modules(root, package)
    out = []
    for m, path in modules.items():
        own_package = m if path.name == "__init__.py" else m.rpartition(".")[0]
        for n in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(n, ast.ImportFrom):
                target = _target(modules, m, n)
                if not target.split(".")[0] == package:
                    continue
                for a in n.names:
                    if not a.name.startswith("_") or a.name.startswith("__"):
                        continue
                    if target == own_package and _is_submodule(modules, target, a.name):
                        continue
                    out.append(f"{m}: from {target} import {a.name}")
            elif isinstance(n, ast.Import):
                for a in n.names:
                    parts = a.name.split(".")
                    if parts[0] == package and any(x.startswith("_") and not x.startswith("__") for x in parts):
                        out.append(f"{m}: import {a.name}")
    return out


def test_no_import_cycles_in_urident():
    cycles = import_cycles(import_graph(ROOT))
    assert not cycles, "module-level import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_no_import_cycles_in_urident_counting_deferred_imports():
    # a cycle closed by an import inside a function (gap.diagnose <-> gap.report once) still ties
    # the two modules together: each needs the other to be understood or changed
    cycles = import_cycles(import_graph(ROOT, deferred=True))
    assert not cycles, "import cycles (deferred imports counted): " + "; ".join(" -> ".join(c) for c in cycles)


def symmetric_3x3_literals(root: Path, package: str = "urident") -> list[str]:
    """Places that write a symmetric 3×3 matrix out of six numbers by hand (a nested list literal
    whose off-diagonal entries repeat): the inertia conversions, which have one place."""
    out = []
    for m, path in _modules(root, package).items():
        for n in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(n, ast.List) and len(n.elts) == 3
                    and all(isinstance(r, ast.List) and len(r.elts) == 3 for r in n.elts)):
                continue
            e = [[ast.dump(x) for x in r.elts] for r in n.elts]
            if e[0][1] == e[1][0] and e[0][2] == e[2][0] and e[1][2] == e[2][1]:
                out.append(f"{m}:{n.lineno}")
    return out


def test_the_inertia_conversions_have_one_place():
    """Six numbers ↔ a 3×3 inertia only through urident.model.parameters (inertia_matrix,
    inertia_vector, inertia_tensor): robot files, payloads, URScript, φ_F and MJCF/URDF agree."""
    found = [p for p in symmetric_3x3_literals(ROOT) if not p.startswith("urident.model.parameters:")]
    assert not found, "a 3×3 inertia built by hand: " + "; ".join(found)


def test_nothing_below_the_command_line_imports_it():
    """The CLI is the top layer: it parses, calls the library and prints. No library module imports
    it (deferred imports counted); only entry points (``__main__`` modules) may."""
    graph = import_graph(ROOT, deferred=True)
    upward = sorted(f"{m} -> {t}" for m, targets in graph.items() for t in targets
                    if (t == "urident.cli" or t.startswith("urident.cli."))
                    and not (m == "urident.cli" or m.startswith("urident.cli.") or m.endswith("__main__")))
    assert not upward, "modules below urident.cli import it: " + "; ".join(upward)


def test_no_private_names_imported_across_modules():
    found = private_imports(ROOT)
    assert not found, "private names imported across modules: " + "; ".join(found)


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)


def test_the_checks_catch_a_cycle_through_a_third_module_and_a_private_import(tmp_path):
    _write(tmp_path, {
        "urident/__init__.py": "",
        "urident/a.py": "from urident import b\n",
        "urident/b.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from urident.c import X\n",
        "urident/c.py": "import urident.a\n\ndef f():\n    from urident.b import _hidden\n",
        "urident/d.py": "def g():\n    from urident.a import x   # inside a function: not a cycle\n",
        "urident/sub/__init__.py": "from urident.sub import _kernel\n",
        "urident/sub/_kernel.c": "",
    })
    cycles = import_cycles(import_graph(tmp_path))
    assert cycles == [["urident.a", "urident.b", "urident.c", "urident.a"]]
    assert import_cycles(import_graph(tmp_path, deferred=True)) == [
        ["urident.a", "urident.b", "urident.c", "urident.a"]]
    (tmp_path / "urident/b.py").write_text("def h():\n    from urident import d\n")
    assert import_cycles(import_graph(tmp_path)) == []
    assert import_cycles(import_graph(tmp_path, deferred=True)) == [["urident.a", "urident.b", "urident.d", "urident.a"]]
    assert private_imports(tmp_path) == ["urident.c: from urident.b import _hidden"]


# ------------------------------------------------------------------ the 78-vector layout
_LAYOUT_NUMBERS = {50, 60, 66, 72, 78}


def _layout_literals(text: str, where: str) -> list[str]:
    """Integer literals of the layout (offsets 50/60/66/72, length 78) used to index or size an
    array: in a subscript, in np.zeros/empty/ones/full/arange(...) or a comparison with 78."""
    tree = ast.parse(text)
    hits = []

    def consts(node):
        return [c for c in ast.walk(node) if isinstance(c, ast.Constant) and type(c.value) is int
                and c.value in _LAYOUT_NUMBERS]

    for n in ast.walk(tree):
        found = []
        if isinstance(n, ast.Subscript):
            found = consts(n.slice)
        elif isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and \
                n.func.attr in ("zeros", "empty", "ones", "full", "arange", "Variable") and n.args:
            found = consts(n.args[0])
        elif isinstance(n, ast.Compare):
            found = [c for c in consts(n) if c.value == 78]
        hits += [f"{where}:{c.lineno}: {c.value}" for c in found]
    return hits


def test_the_parameter_layout_is_written_only_in_urident_model_parameters():
    modules = _modules(ROOT)
    hits = [h for m, p in modules.items() if m != LAYOUT_MODULE
            for h in _layout_literals(p.read_text(encoding="utf-8"), str(p.relative_to(ROOT)))]
    assert not hits, "layout literals outside urident.model.parameters: " + "; ".join(hits)


@pytest.mark.parametrize("text", ["p[50:60] = x\n", "p = np.zeros(78)\n", "ok = p.shape != (78,)\n",
                                  "v = params[66 + i]\n"])
def test_the_layout_check_catches_a_literal(text):
    assert _layout_literals(text, "probe.py")


# ------------------------------------------------------------------ results as types, not dicts
#: A function may return a dict to another package when the dict *is* the product: a file's or a
#: report's JSON/YAML document (``*_dict``, ``*_document``, ``to_dict``/``as_dict``).
_DOCUMENT_SUFFIXES = ("_dict", "_document")


def _returns_bare_dict(fn: ast.FunctionDef) -> bool:
    """Annotated ``-> dict``/``dict[...]`` (alone or ``| None``), or, unannotated, returning a dict
    display, comprehension or ``dict(...)`` call."""
    if fn.returns is not None:
        parts = [p.strip() for p in ast.unparse(fn.returns).split("|")]
        return any(p == "dict" or p.startswith(("dict[", "Dict")) for p in parts)
    for node in ast.walk(fn):
        if isinstance(node, ast.Return) and node.value is not None:
            v = node.value
            if isinstance(v, (ast.Dict, ast.DictComp)) or (
                    isinstance(v, ast.Call) and isinstance(v.func, ast.Name) and v.func.id == "dict"):
                return True
    return False


def bare_dict_crossings(root: Path) -> list[str]:
    """``module.function <- user`` for every public module-level function that returns a bare dict
    and is imported (``from m import f``, or called as ``m.f`` after ``from pkg import m``) by a
    module of another subpackage of urident (``urident.gap`` and ``urident.cli`` are two)."""
    modules = _modules(root)
    trees = {m: ast.parse(p.read_text(encoding="utf-8")) for m, p in modules.items()}
    dicts = {(m, n.name) for m, tree in trees.items() for n in tree.body
             if isinstance(n, ast.FunctionDef) and not n.name.startswith("_")
             and not n.name.endswith(_DOCUMENT_SUFFIXES) and _returns_bare_dict(n)}

    def package(m: str) -> str:
        return m.split(".")[1] if m.count(".") else m

    found = set()
    for m, tree in trees.items():
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = _target(modules, m, node)
                for a in node.names:
                    if (target, a.name) in dicts and package(target) != package(m):
                        found.add(f"{target}.{a.name} <- {m}")
                    if f"{target}.{a.name}" in modules:
                        aliases[a.asname or a.name] = f"{target}.{a.name}"
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
                target = aliases[node.value.id]
                if (target, node.attr) in dicts and package(target) != package(m):
                    found.add(f"{target}.{node.attr} <- {m}")
    return sorted(found)


def test_no_result_crosses_a_package_boundary_as_a_bare_dict():
    """Results travel between urident's subpackages as typed (frozen) dataclasses: a reader sees
    the fields, units and shapes in one place, and a misspelt key fails where it is written."""
    found = bare_dict_crossings(ROOT)
    assert not found, "bare dicts returned across packages (make them dataclasses): " + "; ".join(found)


def test_the_bare_dict_check_catches_both_import_forms(tmp_path):
    _write(tmp_path, {
        "urident/__init__.py": "",
        "urident/gap/__init__.py": "",
        "urident/gap/fit.py": ("def shrink(x) -> dict[str, float]:\n    return {'a': x}\n\n"
                               "def plain(x):\n    return dict(a=x)\n\n"
                               "def report_dict(x) -> dict:\n    return {'a': x}\n\n"
                               "def inside(x) -> dict:\n    return {}\n"),
        "urident/gap/use.py": "from urident.gap.fit import inside\n",
        "urident/cli/__init__.py": "",
        "urident/cli/cmd.py": ("from urident.gap.fit import shrink, report_dict\nfrom urident.gap import fit\n\n"
                               "def run():\n    return fit.plain(1), shrink(2), report_dict(3)\n"),
    })
    assert bare_dict_crossings(tmp_path) == ["urident.gap.fit.plain <- urident.cli.cmd",
                                             "urident.gap.fit.shrink <- urident.cli.cmd"]

"""The packages' layers: bench uses datasets_gen, which uses algos; algos imports neither,
and no modules import each other in a circle.

Two checks of the same rules, written differently: ``lint-imports`` with the contracts in
pyproject.toml (import-linter, skipped when it is not installed), and a plain reading of
every module's imports with :mod:`ast` (every ``import`` and ``from ... import``, those
inside functions too), whose graph must have no cycle and whose every project import
must name a module that exists in the tree.
"""
from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PACKAGES = ("algos", "datasets_gen", "bench")
#: The layers, top first: a package may import only from the packages after it.
LAYERS = ("bench", "datasets_gen", "algos")
#: Known exceptions, (importer, imported), each with the change that removes it; the same
#: as the ``ignore_imports`` of pyproject.toml's contracts.
KNOWN_IMPORTS = {
    ("algos.plugins", "algos"): "plugin loading",
}
#: Largest module, in lines.
MAX_LINES = 800


def _modules(packages=PACKAGES):
    """{dotted name: path} of every .py module of ``packages`` (a package by its name)."""
    out = {}
    for package in packages:
        for folder, dirs, files in os.walk(os.path.join(ROOT, package)):
            dirs[:] = sorted(d for d in dirs if not d.startswith((".", "__")))
            for name in sorted(files):
                if name.endswith(".py"):
                    path = os.path.join(folder, name)
                    dotted = os.path.relpath(path, ROOT)[:-3].replace(os.sep, ".")
                    out[dotted.removesuffix(".__init__")] = path
    return out


def _extensions():
    """The compiled extension modules setup.py builds (``algos._kernels`` ...): they
    import nothing from the project."""
    with open(os.path.join(ROOT, "setup.py")) as f:
        return set(re.findall(r'Extension\(\s*"([\w.]+)"', f.read()))


def _imports(name, path):
    """(line, imported name, names taken from it) of every import in a module; relative
    imports resolved against the module's package."""
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    package = name if path.endswith("__init__.py") else name.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = parts[:len(parts) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            yield node.lineno, target, tuple(a.name for a in node.names)


def _imported(name, path, modules, extensions):
    """(line, project module) of every import of a module: ``from p import n`` imports
    the module ``p.n`` when there is one, else ``p``; a compiled extension is left out
    (it imports nothing from the project)."""
    for line, target, names in _imports(name, path):
        if target.split(".")[0] not in PACKAGES or target in extensions:
            continue
        for taken in names or (None,):
            sub = f"{target}.{taken}" if taken else None
            if sub in modules:
                yield line, sub
            elif sub not in extensions and target in modules:
                yield line, target


def _graph(modules):
    """{module: {project module it imports}} (:func:`_imported`)."""
    extensions = _extensions()
    return {name: {m for _, m in _imported(name, path, modules, extensions)}
            for name, path in modules.items()}


def _top_level_names(path):
    """The names a module binds at its top level (definitions, assignments, imports,
    inside top-level if/try/with blocks too)."""
    with open(path) as f:
        body = list(ast.parse(f.read(), path).body)
    names = set()
    while body:
        node = body.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                names.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
        elif isinstance(node, (ast.If, ast.Try, ast.With)):
            for field in ("body", "orelse", "finalbody", "handlers"):
                for child in getattr(node, field, []):
                    body.extend(child.body if isinstance(child, ast.ExceptHandler) else [child])
    return names


def _cycles(edges):
    """The strongly connected components of more than one module (Tarjan), sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(edges)))
    try:
        for v in sorted(edges):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return sorted(found)


def _without_known(edges):
    return {a: {b for b in bs if (a, b) not in KNOWN_IMPORTS} for a, bs in edges.items()}


def test_cycle_finder_finds_a_circle_and_nothing_else():
    """The finder itself, on a small graph: a -> b -> c -> a is one circle, d -> a none."""
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _cycles(edges) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles():
    """No module imports itself through others, besides the known exceptions."""
    cycles = _cycles(_without_known(_graph(_modules())))
    assert cycles == [], "import circles (each a set of modules that import each other): " \
        + "; ".join(" <-> ".join(c) for c in cycles)


def test_no_upward_import():
    """algos imports nothing from datasets_gen or bench, datasets_gen nothing from bench."""
    modules, extensions = _modules(), _extensions()
    bad = []
    for name, path in modules.items():
        rank = LAYERS.index(name.split(".")[0])
        for line, imported in _imported(name, path, modules, extensions):
            if LAYERS.index(imported.split(".")[0]) < rank and (name, imported) not in KNOWN_IMPORTS:
                bad.append(f"{os.path.relpath(path, ROOT)}:{line} imports {imported}")
    assert bad == [], "imports up the layers " + " > ".join(LAYERS) + ": " + "; ".join(bad)


def test_every_project_import_names_something_that_exists():
    """A moved module or name leaves no import of its old home behind (an installed copy
    of the project could otherwise answer it): ``import p`` names a module of the tree,
    and ``from p import n`` a module ``p.n`` or a name ``p`` binds at its top level."""
    modules, extensions = _modules(), _extensions()
    bound = {}
    bad = []
    for name, path in {**modules, **_modules(("tests",))}.items():
        for line, target, names in _imports(name, path):
            if target.split(".")[0] not in PACKAGES or target in extensions:
                continue
            where = f"{os.path.relpath(path, ROOT)}:{line}"
            if target not in modules:
                bad.append(f"{where} imports {target}")
                continue
            if target not in bound:
                bound[target] = _top_level_names(modules[target])
            for taken in names:
                sub = f"{target}.{taken}"
                if taken != "*" and sub not in modules and sub not in extensions \
                        and taken not in bound[target]:
                    bad.append(f"{where} imports {taken} from {target}")
    assert bad == [], "imports of modules or names that do not exist: " + "; ".join(bad)


def test_known_exceptions_are_the_contracts_ignores():
    """The exceptions here and pyproject.toml's ignored imports are the same list."""
    with open(os.path.join(ROOT, "pyproject.toml")) as f:
        text = f.read()
    ignored = set(re.findall(r'"([\w.]+) -> ([\w.]+)"', text))
    # the plugins' import of the package root is not a sibling import: no contract sees it
    assert ignored == set(KNOWN_IMPORTS) - {("algos.plugins", "algos")}


def test_no_module_over_the_size_limit():
    """One module per idea: none of algos, datasets_gen and bench over 800 lines."""
    big = []
    for name, path in _modules().items():
        with open(path) as f:
            lines = sum(1 for _ in f)
        if lines > MAX_LINES:
            big.append(f"{os.path.relpath(path, ROOT)} ({lines} lines)")
    assert big == [], f"modules over {MAX_LINES} lines: " + ", ".join(big)


def _lint_imports():
    """The ``lint-imports`` command next to this Python, or on PATH; None when missing."""
    here = os.path.dirname(sys.executable)
    return shutil.which("lint-imports", path=os.pathsep.join([here, os.environ.get("PATH", "")]))


def test_import_linter_contracts_hold():
    """``lint-imports`` keeps every contract of pyproject.toml."""
    command = _lint_imports()
    if command is None:
        pytest.skip("import-linter is not installed (the test extra installs it)")
    done = subprocess.run([command, "--config", os.path.join(ROOT, "pyproject.toml")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": ROOT + os.pathsep
                               + os.environ.get("PYTHONPATH", "")})
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "broken" in done.stdout and "0 broken" in done.stdout, done.stdout[-2000:]

"""The C kernels' layers (cext/): one folder per idea, and no circle among the files.

Each C file's functions (the ones it defines, ``static inline`` ones of headers included)
and the functions it uses (calls, or names as a pointer) are read from the source by a
small parser; a use of a function defined in another file, and an ``#include``, are an
edge from the user to that file. The graph must have no cycle, and every edge between two
folders must point down the layer order below. Where the object files of a build are in
build/, their symbol tables (``nm``) are checked too: what the linker sees must point
down as well.
"""
from __future__ import annotations

import glob
import os
import re
import shutil
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CEXT = os.path.join(ROOT, "cext")

#: The folders of cext/, lowest first: a file may use and include only its own folder and
#: the folders before it. "." is cext/ itself (the plugin ABI header); peers/ stand apart
#: (each peer is its own extension and uses none of the kernels).
LAYERS = (".", "core", "surfaces", "walks", "hierarchies", "dispatch", "terrain", "raster",
          "binding", "peers")

#: The longest C file allowed, in lines.
MAX_LINES = 800

_KEYWORDS = {"if", "for", "while", "switch", "return", "sizeof", "do", "else", "case",
             "defined", "__attribute__", "__builtin_expect", "_Pragma"}


def _c_files(root: str = CEXT) -> list[str]:
    """Every .c and .h file under root (cext/), as paths relative to it."""
    paths = glob.glob(os.path.join(root, "**", "*.[ch]"), recursive=True)
    return sorted(os.path.relpath(p, root) for p in paths)


def _folder(rel: str) -> str:
    return os.path.dirname(rel) or "."


def _strip(text: str) -> str:
    """The code without comments, string and character literals (kept as empty quotes)."""
    pattern = re.compile(r'//[^\n]*|/\*.*?\*/|"(?:\\.|[^"\\])*"|\'(?:\\.|[^\'\\])*\'', re.S)

    def blank(m):
        s = m.group(0)
        return ('""' if s[0] == '"' else "''" if s[0] == "'" else " ") + "\n" * s.count("\n")

    return pattern.sub(blank, text)


class Source:
    """One C file: what it includes, defines, declares and uses."""

    def __init__(self, rel: str, macros: dict | None = None, root: str = CEXT):
        self.rel = rel
        with open(os.path.join(root, rel), encoding="utf-8") as f:
            raw = f.read()
        self.lines = raw.count("\n") + 1
        self.includes = re.findall(r'^\s*#\s*include\s+"([^"]+)"', raw, re.M)
        code = _strip(raw.replace("\\\n", " "))
        directives = re.findall(r"^\s*#.*$", code, re.M)
        self.macros = {}  # name -> (params, body) of the function-like macros
        for line in directives:
            m = re.match(r"\s*#\s*define\s+(\w+)\(([^)]*)\)(.*)", line)
            if m:
                params = [p.strip() for p in m.group(2).split(",") if p.strip()]
                self.macros[m.group(1)] = (params, m.group(3))
        self.code = re.sub(r"^\s*#.*$", " ", code, flags=re.M)
        self.macro_text = " ".join(body for _, body in self.macros.values())
        #: the function-defining macros this file may invoke (every file's, when given)
        self.known_macros = dict(self.macros, **(macros or {}))
        self.defined, self.static, self.declared = set(), set(), set()
        self.bodies = []  # code whose identifiers are uses (bodies, initialisers, macros)
        self._scan()

    def _scan(self):
        """Split the code at depth 0 into declarations, definitions and initialisers."""
        code, depth, start = self.code, 0, 0
        head = ""
        body_start = 0
        for pos, ch in enumerate(code):
            if ch == "{":
                if depth == 0:
                    head, body_start = code[start:pos], pos
                depth += 1
            elif ch == "}":
                depth -= 1
                if depth == 0:
                    self._definition(head, code[body_start:pos + 1])
                    start = pos + 1
            elif ch == ";" and depth == 0:
                self._declaration(code[start:pos])
                start = pos + 1
        if code[start:].strip():
            self._declaration(code[start:])  # trailing macro invocations

    def _definition(self, head: str, body: str):
        m = re.search(r"(\w+)\s*\((?:[^()]|\([^()]*\))*\)\s*(?:__attribute__\s*\(\(.*?\)\)\s*)?$",
                      head.strip(), re.S)
        if m and not re.search(r"\b(struct|enum|union|typedef)\b|=", head[:m.start(1)]):
            name = m.group(1)
            self.defined.add(name)
            if re.search(r"\bstatic\b|\bHF_(INLINE|COLD|HOT)\b", head):
                self.static.add(name)
            self.bodies.append(body)
        else:
            self.bodies.append(head + body)  # an initialiser or a type
        self._expand_macro_calls(head)

    def _declaration(self, text: str):
        text = text.strip()
        m = re.match(r"(?:[\w\s\*]+?)\b(\w+)\s*\((?:[^()]|\([^()]*\))*\)$", text, re.S)
        if m and not re.search(r"=|\btypedef\b", text):
            self.declared.add(m.group(1))
        else:
            self.bodies.append(text)
        self._expand_macro_calls(text)

    def _expand_macro_calls(self, text: str):
        """Top-level invocations of this file's function-defining macros (a batch driver
        such as HF_DEFINE_BATCH(name, walk)): the functions they define, and their
        arguments as uses."""
        for name in self.known_macros:
            for m in re.finditer(rf"\b{name}\s*\(([^()]*)\)", text):
                args = [a.strip() for a in m.group(1).split(",")]
                self._macro_defines(name, args)
                self.bodies.append(" ".join(args))

    def _macro_defines(self, name: str, args: list, depth: int = 0):
        """The functions macro ``name`` defines with ``args``, through the function-
        defining macros its body invokes in turn (HF_DEFINE_BATCH invokes
        HF_DEFINE_BATCH_MODES)."""
        params, body = self.known_macros[name]
        for param, arg in zip(params, args):
            for suffix in re.findall(rf"\b{param}\s*##\s*(\w+)\s*\(", body):
                self.defined.add(arg + suffix)
            if re.search(rf"\bint\s+{param}\s*\(", body):
                self.defined.add(arg)
        if depth >= 4:
            return
        for inner in self.known_macros:
            for m in re.finditer(rf"\b{inner}\s*\(([^()]*)\)", body):
                value = dict(zip(params, args))
                inner_args = [value.get(a.strip(), a.strip()) for a in m.group(1).split(",")]
                self._macro_defines(inner, inner_args, depth + 1)

    def used(self) -> set[str]:
        """Identifiers named in bodies, initialisers and macro bodies."""
        words = set()
        for text in self.bodies + [self.macro_text]:
            words.update(re.findall(r"\b[A-Za-z_]\w*\b", text))
        return words - _KEYWORDS


def _graph(sources: dict[str, Source]) -> dict[str, set[str]]:
    """file -> the files it includes or uses a function of (its own functions aside)."""
    visible = {}  # function name -> the files whose definition other files can reach
    for rel, s in sources.items():
        for name in s.defined:
            if rel.endswith(".h") or name not in s.static:
                visible.setdefault(name, set()).add(rel)
    edges = {}
    for rel, s in sources.items():
        out = set()
        # (a header's inline code calling a function the header itself declares uses its
        # own interface, implemented by its .c file: no edge)
        for inc in s.includes:
            if inc in sources:
                out.add(inc)
        own = s.declared if rel.endswith(".h") else set()
        for name in s.used() - s.defined - own:
            out.update(visible.get(name, ()))
        out.discard(rel)
        edges[rel] = out
    return edges


def _modules(edges: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph with each header and the source of the same name in its folder (hit.h and
    hit.c) as one node: a module, which must not be in a circle either."""
    def module(rel):
        return rel[:-2]

    merged = {}
    for src, targets in edges.items():
        merged.setdefault(module(src), set()).update(module(t) for t in targets)
    for node, targets in merged.items():
        targets.discard(node)
    return merged


def _read(root: str = CEXT) -> dict[str, Source]:
    """Every C file under root, parsed with every file's function-defining macros known."""
    macros = {}
    for rel in _c_files(root):
        macros.update(Source(rel, root=root).macros)
    return {rel: Source(rel, macros, root) for rel in _c_files(root)}


def _cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph as a list of nodes, or None (depth-first search)."""
    state, stack = {}, []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        state[node] = 2
        stack.pop()
        return None

    for node in sorted(edges):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def _layer_violations(edges: dict[str, set[str]]) -> list[str]:
    bad = []
    for src, targets in sorted(edges.items()):
        for dst in sorted(targets):
            a, b = _folder(src), _folder(dst)
            if a not in LAYERS or b not in LAYERS or LAYERS.index(b) > LAYERS.index(a):
                bad.append(f"{src} -> {dst}")
    return bad


@pytest.fixture(scope="module")
def sources() -> dict[str, Source]:
    return _read()


def test_parser_sees_the_known_edges(sources):
    """The parser finds what a reader finds: the dispatcher uses the walks and the
    hierarchies, a walk uses the cell tests through the sink, the batch driver's macro
    defines each walk's entry points."""
    edges = _graph(sources)
    assert "walks/dda.c" in edges["dispatch/intersect.c"]
    assert "hierarchies/cone.c" in edges["dispatch/intersect.c"]
    assert "surfaces/cell_test.h" in edges["walks/walk.h"]
    assert {"hf_batch_dda", "hf_batch_dda_hit"} <= sources["walks/dda.c"].defined
    assert "hf_surface_test" in sources["surfaces/cell_test.h"].defined


def test_no_cycle_among_files(sources):
    edges = _graph(sources)
    cycle = _cycle(edges)
    assert cycle is None, "C files in a circle (uses and includes): " + " -> ".join(cycle)


def test_no_cycle_among_modules(sources):
    cycle = _cycle(_modules(_graph(sources)))
    assert cycle is None, "C modules (a .h with its .c) in a circle: " + " -> ".join(cycle)


def test_finds_the_dispatcher_circle(tmp_path):
    """The circle this layout removed, in miniature: the dispatcher (hit.c) calls a walk,
    whose sink (internal.h) calls back into the cell test of hit.h."""
    files = {
        "hit.h": "static inline int hf_hit_cell(int i) { return i > 0; }\n",
        "internal.h": '#include "hit.h"\n'
                      "static inline int hf_emit_cell(int i) { return hf_hit_cell(i); }\n",
        "dda.c": '#include "internal.h"\nint hf_batch_dda_hit(int i) { return hf_emit_cell(i); }\n',
        "hit.c": '#include "hit.h"\nint hf_batch_dda_hit(int i);\n'
                 "int hf_intersect_batch(int i) { return hf_batch_dda_hit(i); }\n",
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    edges = _graph(_read(str(tmp_path)))
    assert _cycle(edges) is None  # file by file the graph is a tree ...
    assert _cycle(_modules(edges)) == ["dda", "internal", "hit", "dda"]  # ... but not by module


def test_no_cycle_among_folders(sources):
    edges = _graph(sources)
    folders = {}
    for src, targets in edges.items():
        folders.setdefault(_folder(src), set()).update(
            _folder(t) for t in targets if _folder(t) != _folder(src))
    cycle = _cycle(folders)
    assert cycle is None, "cext/ folders in a circle: " + " -> ".join(cycle)


def test_every_edge_points_down(sources):
    """A file uses and includes only its own folder and the folders below it (LAYERS)."""
    assert _layer_violations(_graph(sources)) == []


def test_every_file_in_a_layer(sources):
    assert sorted({_folder(rel) for rel in sources} - set(LAYERS)) == []


def test_no_file_over_the_limit(sources):
    long_files = {rel: s.lines for rel, s in sources.items() if s.lines > MAX_LINES}
    assert long_files == {}, f"C files over {MAX_LINES} lines: {long_files}"


def test_linked_symbols_point_down():
    """The object files of the latest build (build/temp*/cext/...): each file's undefined
    symbols resolve to files of its own folder or below."""
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (binutils) is not on PATH")
    objects = {}
    for path in glob.glob(os.path.join(ROOT, "build", "temp*", "cext", "**", "*.o"), recursive=True):
        rel = os.path.relpath(path, os.path.join(path.split(os.sep + "cext" + os.sep)[0], "cext"))
        source = rel[:-2] + ".c"
        if os.path.exists(os.path.join(CEXT, source)):  # a stale object of a moved file: ignored
            objects[source] = path
    if not objects:
        pytest.skip("no object files in build/ (build the extension with setup.py first)")
    defined, undefined = {}, {}
    for source, path in objects.items():
        out = subprocess.run([nm, path], capture_output=True, text=True, check=True).stdout
        for line in out.splitlines():
            parts = line.split()
            if len(parts) == 3 and parts[1] == "T":
                defined[parts[2]] = source
            elif len(parts) == 2 and parts[0] == "U":
                undefined.setdefault(source, set()).add(parts[1])
    edges = {s: {defined[u] for u in undefined.get(s, ()) if u in defined} - {s} for s in objects}
    assert _cycle(edges) is None
    assert _layer_violations(edges) == []


def test_kernel_ids_come_from_c():
    """The extension names every kernel id once; the registry's ids are those."""
    from algos import _kernels
    from algos.registry import INTERSECTOR_REGISTRY, TRAVERSAL_REGISTRY

    ids = _kernels.KERNEL_IDS
    assert sorted(ids.values()) == list(range(len(ids)))
    for registry in (TRAVERSAL_REGISTRY, INTERSECTOR_REGISTRY):
        for name, entry in registry.items():
            if entry.kernel_id is not None and entry.plugin is None:
                assert entry.kernel_id == ids[name], name

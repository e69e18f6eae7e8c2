"""The package's shape (issue 23): the folder layout reads like the pipeline, and stays so.

Walks ``mtanno/`` with :mod:`ast` (nothing is imported): every import, also those inside
functions, is an edge from the importing module to the module that defines the name (a
name a package's ``__init__`` re-exports counts as its defining module); imports under
``if TYPE_CHECKING:`` are type hints only and do not count. Then:

* no import cycle between modules, and no module imports a package it is part of (an
  upward import: ``from mtanno import __version__`` inside ``mtanno.templates.learn``);
* at most 10 modules at the top level of ``mtanno/``, none of them over 700 lines, no
  function over 100 lines (a numba kernel may be longer where a comment beginning
  ``# one kernel:`` says why splitting it would cost speed);
* every subpackage's ``__init__.py`` has a docstring naming each of its modules and an
  ``__all__``;
* docs/architecture.md names every file of the package.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "mtanno"
MAX_TOP_LEVEL = 10
MAX_MODULE_LINES = 700
MAX_FUNCTION_LINES = 100
KERNEL_NOTE = "# one kernel:"


def _modules() -> dict[str, Path]:
    out = {}
    for p in sorted(PACKAGE.rglob("*.py")):
        parts = list(p.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


MODULES = _modules()


def _imports(tree: ast.AST):
    """Every Import/ImportFrom node, skipping ``if TYPE_CHECKING:`` bodies."""
    stack = [tree]
    while stack:
        node = stack.pop()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                stack.extend(child.orelse)
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                yield child
            stack.append(child)


def _absolute(module: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")
    if MODULES[module].name != "__init__.py":
        base = base[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _owner(name: str) -> str:
    """The longest prefix of a dotted name that is a module of the package."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name


def _reexports() -> dict[tuple[str, str], str]:
    """(package, name) → the module a package's ``__init__`` takes ``name`` from."""
    out = {}
    for mod, path in MODULES.items():
        if path.name != "__init__.py":
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ImportFrom):
                src = _absolute(mod, node)
                if src in MODULES:
                    for a in node.names:
                        out[(mod, a.asname or a.name)] = src
            elif (isinstance(node, ast.Assign) and isinstance(node.value, ast.Call)
                  and getattr(node.value.func, "id", "") == "lazy_exports"):
                # names attached on first use: lazy_exports(__name__, {module: names})
                for module, names in ast.literal_eval(node.value.args[1]).items():
                    out.update({(mod, name): f"{mod}.{module}" for name in names})
    return out


def import_graph() -> dict[str, set[str]]:
    """Module → the modules of the package it imports (see the module docstring)."""
    reexports = _reexports()
    graph: dict[str, set[str]] = {}
    for mod, path in MODULES.items():
        deps: set[str] = set()
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                deps.update(_owner(a.name) for a in node.names if a.name.startswith("mtanno"))
                continue
            src = _absolute(mod, node)
            if not src.startswith("mtanno"):
                continue
            for a in node.names:
                full = f"{src}.{a.name}"
                if full in MODULES:
                    deps.add(full)
                else:
                    owner = _owner(src)
                    deps.add(reexports.get((owner, a.name), owner))
        deps.discard(mod)
        deps.discard("")
        graph[mod] = deps
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in graph:
                    continue
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
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    found = cycles(import_graph())
    assert not found, f"import cycles: {found}"


def test_no_upward_import():
    up = sorted((m, d) for m, deps in import_graph().items() for d in deps
                if m.startswith(d + "."))
    assert not up, f"modules importing a package they are part of: {up}"


#: The layers, bottom to top: a module may import only from its own package and from the
#: packages ranked below it (imports under ``if TYPE_CHECKING:`` excepted). Top-level
#: modules (``mtanno/retrieve.py``) rank as packages of their own; ``mtanno`` (the
#: package's ``__init__``, the lazy facade) is the top.
RANKS = ["_version", "errors", "util", "io", "features", "labels", "info", "synthetic",
         "templates", "retrieve", "index", "keyframes", "confidence", "align", "annotate", "plot",
         "evaluation", "tuning", "api", "commands", "cli", "__main__", "mtanno"]


def layer(module: str) -> str:
    """The package (or top-level module) of the rank table a module belongs to."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "mtanno"


def upward_edges(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(module, import) pairs where the import's layer ranks above the module's."""
    rank = {name: i for i, name in enumerate(RANKS)}
    return sorted((m, d) for m, deps in graph.items() for d in deps
                  if layer(d) != layer(m) and rank[layer(d)] > rank[layer(m)])


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for m, deps in graph.items():
        out.setdefault(layer(m), set()).update(layer(d) for d in deps if layer(d) != layer(m))
    return out


def test_every_layer_has_a_rank():
    layers = {layer(m) for m in MODULES}
    assert layers <= set(RANKS), f"packages without a rank: {sorted(layers - set(RANKS))}"


def test_imports_point_down_the_layers():
    up = upward_edges(import_graph())
    assert not up, f"imports of a higher layer: {up}"


def test_no_package_cycle():
    found = cycles(package_graph(import_graph()))
    assert not found, f"package cycles: {found}"


def test_the_layer_checks_catch_what_they_forbid():
    graph = {"mtanno.util.store": {"mtanno.features.table"},
             "mtanno.features.table": {"mtanno.util.output"}, "mtanno.util.output": set()}
    assert upward_edges(graph) == [("mtanno.util.store", "mtanno.features.table")]
    assert cycles(package_graph(graph)) == [["features", "util"]]
    assert not upward_edges({"mtanno.annotate.run": {"mtanno.templates.match"}})


def test_top_level_modules():
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= MAX_TOP_LEVEL, top


@pytest.mark.parametrize("module", sorted(MODULES))
def test_module_and_function_length(module):
    path = MODULES[module]
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    assert len(lines) <= MAX_MODULE_LINES, f"{path}: {len(lines)} lines"
    for node in ast.walk(ast.parse(text)):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        n = node.end_lineno - node.lineno + 1
        if n <= MAX_FUNCTION_LINES:
            continue
        kernel = any("njit" in ast.unparse(d) for d in node.decorator_list)
        noted = any(KERNEL_NOTE in line for line in lines[node.lineno - 1:node.end_lineno])
        assert kernel and noted, f"{path}:{node.lineno}: {node.name} has {n} lines"


@pytest.mark.parametrize("package", sorted(m for m, p in MODULES.items()
                                           if p.name == "__init__.py" and m != "mtanno"))
def test_package_docstring_lists_its_modules(package):
    path = MODULES[package]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    doc = ast.get_docstring(tree) or ""
    assert doc, f"{path}: no docstring"
    names = sorted(p.stem for p in path.parent.glob("*.py") if p.name != "__init__.py")
    names += sorted(p.name for p in path.parent.iterdir()
                    if p.is_dir() and (p / "__init__.py").exists())
    missing = [n for n in names if n not in doc]
    assert not missing, f"{path}: the docstring does not name {missing}"
    targets = [t for n in tree.body if isinstance(n, ast.Assign) for t in n.targets]
    targets += [e for t in targets if isinstance(t, ast.Tuple) for e in t.elts]
    assert any(getattr(t, "id", None) == "__all__" for t in targets), \
        f"{path}: no __all__"


def test_architecture_doc_names_every_file_of_the_package():
    """docs/architecture.md draws the tree `ls -R mtanno` shows: every file is named there
    (a module added without a line in the drawing fails here)."""
    doc = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    missing = [str(p.relative_to(PACKAGE.parent)) for p in sorted(PACKAGE.rglob("*"))
               if p.is_file() and "__pycache__" not in p.parts and p.name not in doc]
    assert not missing, f"not in docs/architecture.md: {missing}"

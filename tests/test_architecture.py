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


# --------------------------------------------------------------- one API call per command

#: Modules a command may call as often as it likes: the commands' own helpers, the one
#: exception type, and the plumbing every stage shares (locks, outputs, tables).
COMMAND_PLUMBING = ("mtanno.commands._common", "mtanno.errors", "mtanno.util", "mtanno._version")


def _is_class(module: str, name: str, reexports: dict[tuple[str, str], str]) -> bool:
    """Whether ``name`` imported from ``module`` is a class (its defining module holds a
    top-level ``class name``): building a value (an options dataclass) is no API call."""
    owner = _owner(module)
    src = reexports.get((owner, name), owner)
    if src not in MODULES:
        return False
    tree = ast.parse(MODULES[src].read_text(encoding="utf-8"))
    return any(isinstance(n, ast.ClassDef) and n.name == name for n in tree.body)


def _is_command(fn: ast.FunctionDef) -> bool:
    """A Click command or group: a decorator ``@….command(…)``, ``@….group(…)`` or a
    helper ending so (``@_update_command(…)``)."""
    for d in fn.decorator_list:
        f = d.func if isinstance(d, ast.Call) else d
        name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
        if name.endswith(("command", "group")):
            return True
    return False


def command_api_calls(source: str, module: str = "mtanno.commands.x",
                      reexports: dict[tuple[str, str], str] | None = None,
                      ) -> dict[str, set[str]]:
    """Command function → the stage-API functions it calls (``module.name``).

    The rule: a call counts when its callee is a name imported from a module of the
    package — at the module's top or inside the function — other than
    :data:`COMMAND_PLUMBING`, and that name is not a class (building an options value is
    no call). Attribute calls on an imported module (``index.search(…)``) count the same
    way; method calls on values (``report.table()``) do not. Calls inside the function's
    nested functions (callbacks) count, and so do those of the functions of the same
    module that it calls (``_write_hits``), followed transitively. Each API function
    counts once however often it is called."""
    reexports = _reexports() if reexports is None else reexports
    tree = ast.parse(source)
    local_defs = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}

    def imports_of(node: ast.AST) -> dict[str, str]:
        """Bound name → dotted origin (``mtanno.index.search`` or a module ``mtanno.index``)."""
        out = {}
        for imp in _imports(node) if not isinstance(node, ast.ImportFrom) else [node]:
            if isinstance(imp, ast.Import):
                out.update({(a.asname or a.name): a.name for a in imp.names})
                continue
            src = imp.module or "" if not imp.level else \
                ".".join(module.split(".")[:-imp.level] + ([imp.module] if imp.module else []))
            out.update({(a.asname or a.name): f"{src}.{a.name}" for a in imp.names})
        return out

    top = {}
    for n in tree.body:
        if isinstance(n, (ast.Import, ast.ImportFrom)):
            top.update(imports_of(n))

    def api_calls(fn: ast.FunctionDef, seen: set[str]) -> set[str]:
        bound = {**top, **imports_of(fn)}
        found: set[str] = set()
        for node in ast.walk(fn):
            if not isinstance(node, ast.Call):
                continue
            f = node.func
            if isinstance(f, ast.Name) and f.id in local_defs and f.id not in bound:
                if f.id not in seen:
                    seen.add(f.id)
                    found |= api_calls(local_defs[f.id], seen)
                continue
            if isinstance(f, ast.Name) and f.id in bound:
                origin = bound[f.id]
            elif (isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name)
                  and f.value.id in bound and bound[f.value.id] in MODULES):
                origin = f"{bound[f.value.id]}.{f.attr}"
            else:
                continue
            src, _, name = origin.rpartition(".")
            if not src.startswith("mtanno") or src.startswith(COMMAND_PLUMBING):
                continue
            if origin in MODULES or _is_class(src, name, reexports):
                continue  # a module bound by name, or a value built
            found.add(origin)
        return found

    return {fn.name: api_calls(fn, {fn.name}) for fn in tree.body
            if isinstance(fn, ast.FunctionDef) and _is_command(fn)}


def test_command_api_call_rule_catches_a_second_call():
    """A hand-made command module: one API call passes; a second one, made directly, in a
    callback, in a helper of the module or through an imported module, is caught; building
    an options dataclass and the plumbing do not count."""
    head = ("import click\n"
            "from mtanno.commands._common import user_errors\n"
            "from mtanno.util.preflight import check_outputs\n"
            "from mtanno.keyframes.run import KeyframeOptions, learn_keyframes_to\n")
    one = head + (
        "@click.command('x')\n@user_errors(2)\ndef x_cmd(a):\n"
        "    check_outputs([a], [])\n    check_outputs([a], [])\n"
        "    learn_keyframes_to([a], a, a, options=KeyframeOptions(method='hard'))\n"
        "    learn_keyframes_to([a], a, a)\n")
    assert command_api_calls(one) == {"x_cmd": {"mtanno.keyframes.run.learn_keyframes_to"}}
    direct = one + "    from mtanno.keyframes import load_keyframes\n    load_keyframes(a)\n"
    callback = one + ("    def note(m):\n        from mtanno.index import search\n"
                      "        search(m)\n")
    helper = (one + "    _helper(a)\n\n"
              "def _helper(a):\n    from mtanno.retrieve import retrieve_files\n"
              "    return retrieve_files(a)\n")
    module = one + "    from mtanno import index\n    index.open_index(a)\n"
    group = head + ("@_update_command('add')\ndef add_cmd(a):\n"
                    "    from mtanno.index import add_documents, open_index\n"
                    "    open_index(a)\n    add_documents(a)\n")
    for case in (direct, callback, helper, module, group):
        (calls,) = command_api_calls(case).values()
        assert len(calls) == 2, (case, calls)


#: Commands that still call more than one API function, each with the reason; an entry
#: that no longer does fails the test below until it is removed.
SEVERAL_CALLS = {
    # --classes CONFIG: the configuration's [inputs] (annotate, a layer above features)
    # choose the options of extract_to
    "mtanno.commands.features.features_cmd",
}


def test_one_api_call_per_command():
    """Each command parses, makes one call of the stage API, prints one summary line
    (docs/architecture.md): no command function calls two API functions
    (:func:`command_api_calls` states the rule), except those of :data:`SEVERAL_CALLS`."""
    reexports = _reexports()
    many = {}
    for mod, path in MODULES.items():
        if mod.startswith("mtanno.commands."):
            calls = command_api_calls(path.read_text(encoding="utf-8"), mod, reexports)
            many.update({f"{mod}.{c}": sorted(v) for c, v in calls.items() if len(v) > 1})
    extra = {c: v for c, v in many.items() if c not in SEVERAL_CALLS}
    assert not extra, f"commands calling more than one API function: {extra}"
    done = sorted(SEVERAL_CALLS - set(many))
    assert not done, f"make one call now; remove from SEVERAL_CALLS: {done}"


# ------------------------------------------------------------- options and module sizes

#: At most this many keyword options (keyword-only or defaulted parameters) on a public
#: function; longer lists become a frozen options dataclass (``LearnOptions``,
#: ``KeyframeOptions``, ``QueryOptions``). A ``**options`` parameter hides options and counts
#: as too many.
MAX_OPTIONS = 10

#: Public functions with more options for now, each with why.
MANY_OPTIONS: set[str] = set()  # none now: every run function has its options dataclass


def keyword_options(source: str, module: str = "mtanno.x") -> dict[str, int]:
    """Public function or method (``module.Class.name``; ``__init__`` included) → its
    keyword options: keyword-only parameters plus positional ones with a default; a
    ``**options`` parameter (any ``**`` but those of a few plumbing helpers, which pass
    fields on: ``**items``, ``**changes``, ``**params``, ``**record``, ``**kwargs``) counts as
    ``MAX_OPTIONS + 1``. Functions and classes whose name starts with ``_`` are private."""
    out = {}

    def visit(body, prefix):
        for n in body:
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if n.name.startswith("_") and n.name != "__init__":
                    continue
                a = n.args
                count = len(a.kwonlyargs) + len(a.defaults)
                if a.kwarg is not None and a.kwarg.arg in ("options", "opts"):
                    count = max(count, MAX_OPTIONS + 1)
                out[f"{prefix}{n.name}"] = count
            elif isinstance(n, ast.ClassDef) and not n.name.startswith("_"):
                visit(n.body, f"{prefix}{n.name}.")

    visit(ast.parse(source).body, f"{module}.")
    return out


def test_the_options_count_is_right():
    src = ("def f(a, b=1, *, c, d=2, **options): pass\n"
           "def g(a, *args, b=1, **record): pass\n"
           "def _h(*, a=1, b=2): pass\n"
           "class C:\n    def __init__(self, x, y=1, *, z=2): pass\n"
           "    def _p(self, q=1): pass\n")
    assert keyword_options(src, "m") == {"m.f": MAX_OPTIONS + 1, "m.g": 1, "m.C.__init__": 2}
    assert keyword_options("def f(a, b, *, " + ", ".join(f"k{i}=0" for i in range(11))
                           + "): pass\n", "m") == {"m.f": 11}


def test_no_public_function_with_more_than_ten_keyword_options():
    found = {}
    for mod, path in MODULES.items():
        counts = keyword_options(path.read_text(encoding="utf-8"), mod)
        found.update({f: n for f, n in counts.items() if n > MAX_OPTIONS})
    extra = {f: n for f, n in found.items() if f not in MANY_OPTIONS}
    assert not extra, f"more than {MAX_OPTIONS} keyword options (an options dataclass): {extra}"
    done = sorted(MANY_OPTIONS - set(found))
    assert not done, f"remove from MANY_OPTIONS, they have {MAX_OPTIONS} or fewer now: {done}"


#: A module of more lines than this holds one job that is long, listed in LONG_MODULES,
#: or more than one, and is split along its seams.
MAX_JOB_LINES = 500

#: The modules over MAX_JOB_LINES lines, each with its one job (reviewed). Those marked
#: "two jobs" are to be split when their owners are free (see each note).
LONG_MODULES = {
    "mtanno.annotate.label": "one document's labels and segments (MBS09 §4; docs/method.md "
                             "§7 steps 3-4): class models, Δ̄ labels and runs or the decoder, "
                             "single-label resolution",
    "mtanno.confidence.calibration": "calibrating the evidence of segments: logistic (Platt) "
                                     "and isotonic models, fitted out of fold, read and written",
    "mtanno.evaluation.report": "the HTML report of annotations and its tables and figures",
    "mtanno.features.store": "the feature file (Parquet): its one validating reader, writer, "
                             "layout and compatibility check",
    "mtanno.io.bvh": "reading BVH files (hierarchy and motion), bounded and checked",
    "mtanno.io.markerset": "marker sets: their TOML files (built-in and the user's), checked, "
                           "chosen for a file's labels, and guessed from them",
    "mtanno.io.guess": "skeleton maps made from a BVH rig's joint names and tree "
                       "(and the skeleton guess run that writes one)",
    "mtanno.keyframes.search": "searching keyframe queries (through an index or a scan) and "
                               "their candidate windows",
    "mtanno.templates.match": "streaming masked subsequence DTW of a template over documents",
    "mtanno.tuning.run": "the tune run, in named steps (inputs, folds, search, further "
                         "templates, confidence) and their worker tasks; the configuration "
                         "it writes is tuning/write.py's",
    "mtanno.tuning.search": "the per-fold, per-class search of tune: templates, Δ on held-out "
                            "documents, objective, coordinate search",
}


def test_long_modules_are_listed_with_their_job():
    """A module over MAX_JOB_LINES lines is listed in LONG_MODULES with its one job (a module
    with several is split instead); an entry for a module that is shorter now is removed."""
    lines = {m: len(p.read_text(encoding="utf-8").splitlines()) for m, p in MODULES.items()}
    long = {m for m, n in lines.items() if n > MAX_JOB_LINES}
    unlisted = sorted(long - set(LONG_MODULES))
    assert not unlisted, (f"modules over {MAX_JOB_LINES} lines: split them along their "
                          f"seams, or list their one job in LONG_MODULES: {unlisted}")
    stale = sorted(set(LONG_MODULES) - long)
    assert not stale, f"remove from LONG_MODULES (now {MAX_JOB_LINES} lines or fewer): {stale}"


def test_the_scripts_import_what_exists():
    """Every ``from mtanno.X import Y`` and ``import mtanno.X`` in ``scripts/`` names a
    module and a name that exist: a rename in the package that missed a benchmark script
    (which no other test runs) fails here, not in the next person's benchmark."""
    import importlib

    missing = []
    for path in sorted((PACKAGE.parent / "scripts").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("mtanno"):
                try:
                    module = importlib.import_module(node.module)
                except ImportError as exc:
                    missing.append(f"{path.name}:{node.lineno}: {exc}")
                    continue
                for alias in node.names:
                    if not hasattr(module, alias.name):
                        try:
                            importlib.import_module(f"{node.module}.{alias.name}")
                        except ImportError:
                            missing.append(f"{path.name}:{node.lineno}: "
                                           f"{node.module}.{alias.name}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("mtanno"):
                        try:
                            importlib.import_module(alias.name)
                        except ImportError as exc:
                            missing.append(f"{path.name}:{node.lineno}: {exc}")
    assert not missing, missing

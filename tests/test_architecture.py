"""The architecture's import rules (docs/architecture.md), checked on the source: data flows one
way, and no layer reaches into another's private names."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "pbrbench"
STDLIB_OK = set(sys.stdlib_module_names)


def imports(path: Path) -> list[tuple[str, bool, list[str]]]:
    """(module, at top level?, imported names) of every import of a source file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    top = {id(n) for n in tree.body}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                out.append((a.name, id(node) in top, []))
        elif isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if node.level:  # relative: resolve against the file's package
                parts = path.relative_to(PKG.parent).with_suffix("").parts[:-node.level]
                mod = ".".join(parts + ((mod,) if mod else ()))
            out.append((mod, id(node) in top, [a.name for a in node.names]))
    return out


def files(sub: str) -> list[Path]:
    return sorted((PKG / sub).rglob("*.py")) if (PKG / sub).is_dir() else [PKG / f"{sub}.py"]


def test_infer_imports_only_numpy_scipy_and_checks_at_import_time():
    bad = []
    for f in files("infer"):
        for mod, top, _ in imports(f):
            root = mod.split(".")[0]
            if not top:
                continue
            ok = root in ("numpy", "scipy") or root in STDLIB_OK or mod.startswith("pbrbench.infer") \
                or mod == "pbrbench.checks"
            if not ok:
                bad.append(f"{f.relative_to(PKG)}: {mod}")
    assert not bad, bad


# The layers, lowest first.  A module may import modules of its own layer or of a lower one,
# never of a higher one; these rules are the data flow of docs/architecture.md.
LAYERS = (
    ("__init__", "errors"),                 # the version; one-line user errors
    ("checks",),                            # input checks and the methods dispatcher
    ("settings", "quality", "scratch", "progress", "lock", "uncertainty", "io", "camera", "text", "memo", "versions"),   # leaves
    ("infer", "shading"),                   # NumPy inference; NumPy forward models and closed forms
    ("metrics", "datasets"),                # scores of inferred quantities; real data on disk
    ("scene",),                             # scene files, specs, their data files
    ("radiosity",),                         # patches of a scene spec, form factors, the solve
    ("render",),                            # Mitsuba: ground truths, their cache and proofs
    ("inverse",),                           # inverse rendering (renders when called)
    ("isolation",),                         # an algorithm call in a child process
    ("registry",),                          # algorithm entries
    ("tasks",),                             # inputs, conditions and scores of each problem
    ("plugins",),                           # the run's registry: built-ins, plugins loaded in children
    ("report",),                            # reads a store it is handed
    ("bench",),                             # plan, run, store, baselines
    ("perf",),                              # speed benchmarks
    ("cli", "__main__"),                    # the command line
)
RANK = {name: i for i, names in enumerate(LAYERS) for name in names}
# modules that import code by a computed name (plugins are user code, loaded by their path or name)
DYNAMIC_IMPORT_OK = {"pbrbench.registry", "pbrbench.plugins", "pbrbench.isolation"}


def module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(root: Path) -> tuple[dict[str, set[str]], list[str]]:
    """``({module: {imported module of the package}}, [computed imports])`` of the package at
    ``root``: every import statement (top level or inside a function), every
    ``importlib.import_module`` / ``__import__`` of a literal name, and of an f-string (its literal
    prefix stands for every module it can name).  ``from pkg import name`` is an edge to
    ``pkg.name`` when that is a module, else to ``pkg``."""
    pkg = root.name
    mods = {module_name(f, root): f for f in root.rglob("*.py")}

    def resolve(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    computed: list[str] = []
    for m, f in mods.items():
        targets: list[str] = []
        for node in ast.walk(ast.parse(f.read_text(), filename=str(f))):
            if isinstance(node, ast.Import):
                targets += [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    here = m.split(".") if f.name == "__init__.py" else m.split(".")[:-1]
                    here = here[:len(here) - (node.level - 1)]
                    base = ".".join(here + ([base] if base else []))
                targets += [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
            elif isinstance(node, ast.Call) and node.args and (
                    getattr(node.func, "attr", None) == "import_module" or getattr(node.func, "id", None) in ("import_module", "__import__")):
                arg = node.args[0]
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                    targets.append(arg.value)
                elif isinstance(arg, ast.JoinedStr) and arg.values and isinstance(arg.values[0], ast.Constant) \
                        and str(arg.values[0].value).startswith(pkg + "."):
                    targets += [x for x in mods if x.startswith(arg.values[0].value)]
                elif m not in DYNAMIC_IMPORT_OK:
                    computed.append(f"{m}: {ast.unparse(arg)}")
        graph[m] = {r for t in targets if (t == pkg or t.startswith(pkg + ".")) and (r := resolve(t)) and r != m}
    return graph, computed


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
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

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def layer_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def climbing(graph: dict[str, set[str]]) -> list[str]:
    """Every import from a layer to a higher one, and every module of a layer :data:`LAYERS` lacks."""
    bad = []
    for a, targets in graph.items():
        la = layer_of(a)
        if la not in RANK:
            bad.append(f"{a}: layer {la!r} is not in LAYERS")
            continue
        bad += [f"{a} -> {b}" for b in sorted(targets) if RANK.get(layer_of(b), -1) > RANK[la]]
    return sorted(bad)


def test_the_package_has_no_import_cycle():
    graph, computed = import_graph(PKG)
    assert not cycles(graph), cycles(graph)
    assert not computed, f"imports by a computed name the guard cannot follow: {computed}"


def test_no_import_climbs_the_layers():
    graph, _ = import_graph(PKG)
    bad = climbing(graph)
    assert not bad, bad


def test_the_guard_finds_a_planted_cycle_and_a_climbing_import(tmp_path):
    root = tmp_path / "pbrbench"
    (root / "tasks").mkdir(parents=True)
    (root / "scene").mkdir()
    (root / "__init__.py").write_text("")
    (root / "tasks" / "__init__.py").write_text("")
    (root / "scene" / "__init__.py").write_text("")
    (root / "tasks" / "a.py").write_text("def f():\n    from pbrbench.tasks.b import g\n")
    (root / "tasks" / "b.py").write_text("import importlib\n\ndef g():\n    return importlib.import_module('pbrbench.tasks.a')\n")
    (root / "scene" / "c.py").write_text("from pbrbench.tasks import a\n")
    (root / "scene" / "d.py").write_text("import importlib\nm = importlib.import_module(f'pbrbench.tasks.{1}')\n")
    graph, computed = import_graph(root)
    assert cycles(graph) == [["pbrbench.tasks.a", "pbrbench.tasks.b"]]
    assert climbing(graph) == ["pbrbench.scene.c -> pbrbench.tasks.a", "pbrbench.scene.d -> pbrbench.tasks.a",
                               "pbrbench.scene.d -> pbrbench.tasks.b"]
    (root / "scene" / "e.py").write_text("import importlib\nname = 'x'\nimportlib.import_module(name)\n")
    assert import_graph(root)[1] == ["pbrbench.scene.e: name"]


def test_no_layer_imports_private_names_of_another():
    bad = []
    for f in PKG.rglob("*.py"):
        own = ".".join(f.relative_to(PKG.parent).with_suffix("").parts[:2])  # pbrbench.<layer>
        for mod, _, names in imports(f):
            if not mod.startswith("pbrbench.") or mod.startswith(own):
                continue
            private_mod = any(p.startswith("_") and p != "__init__" for p in mod.split("."))
            private_names = [n for n in names if n.startswith("_")]
            if private_mod or private_names:
                bad.append(f"{f.relative_to(PKG)}: {mod} {private_names}")
    assert not bad, bad


def test_docstrings_cite_only_files_of_the_repository():
    pattern = re.compile(r"SCIENCE\.md|notes/mitsuba|DESIGN\.md|issue \d")
    bad = [str(f.relative_to(PKG)) for f in PKG.rglob("*.py") if pattern.search(f.read_text())]
    assert not bad, bad


def test_no_code_compares_a_quality_name():
    pattern = re.compile(r"""quality\s*[!=]=\s*["'](draft|standard|high)["']|["'](draft|standard|high)["']\s*[!=]=\s*quality""")
    bad = [str(f.relative_to(PKG)) for f in PKG.rglob("*.py") if pattern.search(f.read_text())]
    assert not bad, bad


def test_only_settings_reads_pbrbench_environment_variables():
    pattern = re.compile(r"""environ(?:\.get)?\s*[\[(]\s*["']PBRBENCH_""")
    bad = [str(f.relative_to(PKG)) for f in PKG.rglob("*.py") if f.name != "settings.py" and pattern.search(f.read_text())]
    assert not bad, bad


def test_no_method_module_is_a_big_room():
    big = {str(f.relative_to(PKG)): n for f in files("infer") if (n := len(f.read_text().splitlines())) > 420}
    assert not big, big


def test_infer_never_imports_inverse_rendering():
    """``pbrbench.inverse`` renders (Mitsuba); the NumPy-only inference package must not reach it."""
    bad = [f"{f.relative_to(PKG)}: {mod}" for f in files("infer") for mod, _, _ in imports(f)
           if mod.startswith("pbrbench.inverse")]
    assert not bad, bad

"""The architecture's import rules (docs/architecture.md), checked on the source: data flows one
way, and no layer reaches into another's private names."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

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


@pytest.mark.parametrize("layer, forbidden", [
    ("report", r"^pbrbench\.bench"),
    ("render", r"^pbrbench\.(infer|tasks|bench|report)"),
    ("shading", r"^pbrbench\.(infer|render|tasks|bench|report)"),
    ("scene", r"^pbrbench\.(infer|tasks|bench|report)"),
    ("metrics", r"^pbrbench\.(render|tasks|bench|report)"),
    ("tasks", r"^pbrbench\.(bench|report)"),
    ("inverse", r"^pbrbench\.(tasks|bench|report)"),
    ("infer", r"^pbrbench\.(?!infer|checks)"),
    ("checks", r"^pbrbench\.(?!errors)"),
    ("datasets", r"^pbrbench\.(infer|render|scene|tasks|bench|report|registry)"),
    ("io", r"^pbrbench\.(?!checks)"),
])
def test_no_import_runs_against_the_data_flow(layer, forbidden):
    bad = [f"{f.relative_to(PKG)}: {mod}" for f in files(layer) for mod, _, _ in imports(f) if re.match(forbidden, mod)]
    assert not bad, bad


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

"""The house's rules, checked: import-linter's contracts (pipeline layers, no cycles; pyproject.toml),
modules and functions of a readable size, and tests that mirror the source."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "nerfkit"
MAX_LINES = 400  # "no module over ~400 lines"; the largest today is viewer/server.py (389)

MAX_FUNCTION_LINES = 60  # "no function over ~60 lines": from `def` to the end of the body, docstring included
# Functions allowed to be longer, each with its reason ("path:Class.function", relative to src/nerfkit).
LONG_FUNCTIONS: set[str] = set()  # "package/module.py:function" for a justified exception, with its reason

pytestmark = pytest.mark.smoke


def function_lengths(root: Path) -> dict[str, int]:
    """{"path:Class.function": lines from `def` to the end of its body} of every function and method (nested
    ones too, named after their parents) in the modules under root."""
    lengths = {}

    def walk(node, path: str, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lengths[f"{path}:{prefix}{child.name}"] = child.end_lineno - child.lineno + 1
                walk(child, path, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                walk(child, path, f"{prefix}{child.name}.")
            else:
                walk(child, path, prefix)

    for p in sorted(root.rglob("*.py")):
        walk(ast.parse(p.read_text()), p.relative_to(root).as_posix(), "")
    return lengths


def test_layers_and_no_cycles():
    lint = Path(sys.executable).with_name("lint-imports")
    r = subprocess.run([str(lint)], cwd=ROOT, capture_output=True, text=True, timeout=300,
                       env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert "2 kept, 0 broken" in r.stdout


def test_no_module_is_long():
    sizes = {p.relative_to(SRC): len(p.read_text().splitlines()) for p in SRC.rglob("*.py")}
    assert max(sizes.values()) > 100  # the walk found the modules
    assert {str(p): n for p, n in sizes.items() if n > MAX_LINES} == {}


def test_no_function_is_long():
    lengths = function_lengths(SRC)
    assert len(lengths) > 500  # the walk found the functions
    long = {name for name, n in lengths.items() if n > MAX_FUNCTION_LINES}
    assert {name: lengths[name] for name in sorted(long - LONG_FUNCTIONS)} == {}
    assert sorted(LONG_FUNCTIONS - long) == []  # an exemption whose function is now short (or gone) is dropped


def test_each_package_has_its_tests_folder():
    packages = {p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    missing = sorted(p for p in packages if not (ROOT / "tests" / p).is_dir())
    assert missing == []


# Where a method may be named: its own package, and the presets that pick one.
METHOD_NAMES_ALLOWED = ("models/", "core/presets.py")


def method_name_comparisons(root: Path, names: set[str]) -> list[str]:
    """["path:line"] of every comparison that tests a method's kind against its name: a Compare with a
    `kind` (a name or an attribute) on one side and a string of `names` (alone or in a tuple, list or set)
    on another, in the modules under root outside METHOD_NAMES_ALLOWED."""

    def mentions_kind(node) -> bool:
        return any(isinstance(n, ast.Name) and n.id == "kind" or isinstance(n, ast.Attribute) and n.attr == "kind"
                   for n in ast.walk(node))

    def method_strings(node) -> bool:
        elts = node.elts if isinstance(node, (ast.Tuple, ast.List, ast.Set)) else [node]
        return any(isinstance(e, ast.Constant) and e.value in names for e in elts)

    found = []
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root).as_posix()
        if rel.startswith(METHOD_NAMES_ALLOWED):
            continue
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.Compare):
                sides = [node.left, *node.comparators]
                if any(mentions_kind(a) for a in sides) and any(method_strings(b) for b in sides):
                    found.append(f"{rel}:{node.lineno}")
    return found


def test_callers_ask_what_a_model_supports_not_which_method_it_is(tmp_path):
    from nerfkit.models.registry import METHODS

    names = set(METHODS)
    assert {"mlp", "ngp", "splat"} <= names
    # The check finds what it looks for: a planted comparison, in each of its forms, is reported.
    planted = tmp_path / "pkg" / "mod.py"
    planted.parent.mkdir()
    planted.write_text('if cfg.field.kind == "splat": pass\nif kind in ("mlp", "mip"): pass\nif x == "ngp": pass\n')
    assert method_name_comparisons(tmp_path, names) == ["pkg/mod.py:1", "pkg/mod.py:2"]
    assert method_name_comparisons(SRC, names) == []

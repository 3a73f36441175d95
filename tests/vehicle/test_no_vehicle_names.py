"""No shipped vehicle is named in dynid's code: a car is data (a vehicle file), and where code needs a default
vehicle it takes the one `dynid.shipped.DEMO_VEHICLE` names. Comments and docstrings may quote a vehicle (a
measurement, an example); string literals and identifiers may not, outside dynid/shipped.py.

Oracle: the names read from the shipped vehicle files themselves (their stems and their `name` keys)."""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

import dynid

SRC = Path(dynid.__file__).parent
EXEMPT = {SRC / "shipped.py"}


def _norm(text: str) -> str:
    return re.sub(r"[^0-9a-z]", "", text.lower())


def shipped_names() -> set[str]:
    """Each shipped vehicle's stem, its name and its name's first two words (the make and model), normalised."""
    out = set()
    for p in sorted((SRC / "vehicle" / "vehicles").glob("*.toml")):
        name = tomllib.loads(p.read_text(encoding="utf-8"))["name"]
        out |= {_norm(p.stem), _norm(name), _norm(" ".join(name.split()[:2]))}
    return out


def _docstrings(tree: ast.AST) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def _words(tree: ast.AST):
    """(line, text) of every string literal that is not a docstring and of every identifier."""
    skip = _docstrings(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in skip:
            yield node.lineno, node.value
        elif isinstance(node, ast.Name):
            yield node.lineno, node.id
        elif isinstance(node, ast.Attribute):
            yield node.lineno, node.attr
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            yield node.lineno, node.name
        elif isinstance(node, ast.arg):
            yield node.lineno, node.arg
        elif isinstance(node, ast.alias):
            yield node.lineno, node.asname or node.name


def test_the_names_are_read_from_the_shipped_files():
    names = shipped_names()
    assert {"peugeot406", "compactsuv"} <= names  # the oracle reads what ships


def test_no_shipped_vehicle_is_named_in_code():
    names = shipped_names()
    found = []
    for path in sorted(SRC.rglob("*.py")):
        if path in EXEMPT:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for line, text in _words(tree):
            hits = [n for n in names if n in _norm(text)]
            if hits:
                found.append(f"{path.relative_to(SRC.parent)}:{line}: {text[:70]!r}")
    assert not found, "a shipped vehicle named in code (take it from dynid.shipped.DEMO_VEHICLE):\n" + "\n".join(found)

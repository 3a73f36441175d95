"""Python source parsed and compiled one call at a time in this process.

CPython before 3.11.8 keeps the AST builder's recursion depth in per-interpreter state: two threads parsing or
compiling at once can fail with SystemError "AST constructor recursion depth mismatch" (gh-106905; seen here in
the full test run, a generated kernel parsed while another thread parsed an expression). dynid parses the source it
generates, and reads numbers written as expressions, from the scheduler's threads: every such call goes through
here, under one lock (they are rare and short: the lock costs nothing measurable).
"""

from __future__ import annotations

import ast
import threading
from types import CodeType

_LOCK = threading.RLock()


def parse(source: str, mode: str = "exec") -> ast.AST:
    """`ast.parse(source, mode=mode)`, one thread at a time."""
    with _LOCK:
        return ast.parse(source, mode=mode)


def compile_source(source: str, filename: str, mode: str = "exec") -> CodeType:
    """`compile(source, filename, mode)`, one thread at a time."""
    with _LOCK:
        return compile(source, filename, mode)

"""The disk cache of generated code (`DYNID_CACHE`, default ~/.cache/dynid): `load_entry`, the one loader of its
entries, written atomically and read back under a key that hashes the model description, the options and the
generator's own source; through it `load_module`, of every generated module (NumPy, Numba per-sample and block
kernels, the simulator's), imported by path, and numba_backend.native_functions, of the compiled libraries
(object code); `numpy_module`, the generated NumPy module of a model.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import json
import linecache
import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import TypeVar

from ..atomic import write_atomic as _write_atomic
from ..dynamics import trig
from ..model.files import tree_to_toml
from ..model.tree import Tree
from ..pysource import compile_source
from .codegen import GENERATOR_VERSION
from .expr import SymbolicError
from .models import build
from .numpy_code import to_numpy

T = TypeVar("T")


# ----- hashing, caching, importing ----------------------------------------------------------------
@functools.cache
def generator_fingerprint() -> str:
    """Hash of the generator's own source (this package's modules and dynamics.trig): a cached module generated
    by another version of dynid is never reused, without anyone having to remember to bump GENERATOR_VERSION."""
    return fingerprint([*sorted(Path(__file__).parent.glob("*.py")), Path(trig.__file__)])  # trig: every target's sine


def fingerprint(files: list[Path]) -> str:
    """Hash of GENERATOR_VERSION and of the files' names and bytes, in order (generator_fingerprint's)."""
    h = hashlib.sha256(GENERATOR_VERSION.encode())
    for f in files:
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:20]


def model_hash(tree: Tree, model: str, options: dict) -> str:
    """Hash of everything the generated code depends on: the model, the options and the generator."""
    opts = {k: (list(map(repr, v)) if k == "wrenches" else v) for k, v in sorted(options.items())}
    # a model file holds no load terms (model.tree): they go in beside its text (a parameter column's name moves)
    text = tree_to_toml(dataclasses.replace(tree, load_terms={}))
    payload = json.dumps({"v": generator_fingerprint(), "tree": text, "load_terms": sorted(tree.load_terms.items()),
                          "gravity": list(tree.gravity), "model": model, "options": opts}, sort_keys=True, default=repr)
    return hashlib.sha256(payload.encode()).hexdigest()[:20]


def cache_dir() -> Path:
    """DYNID_CACHE if set, else the user cache (XDG_CACHE_HOME or ~/.cache)/dynid."""
    env = os.environ.get("DYNID_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "dynid"


def write_atomic(path: Path, text: str | bytes) -> None:
    """Write (text or bytes) then rename (dynid.atomic), so that a reader never sees half a file; creates the folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    _write_atomic(path, text)


def module_path(folder: str, name: str) -> Path:
    """Where load_module keeps the generated module `name` of a kind (numpy, numba)."""
    return cache_dir() / folder / f"{name}.py"


def import_file(path: Path, name: str) -> ModuleType:
    """Import the Python file `path` as the module `name` (in sys.modules while it runs, as an import does)."""
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise SymbolicError(f"cannot import the generated module {path}")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    try:
        spec.loader.exec_module(mod)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return mod


_LOADED: dict[str, object] = {}
_LOAD_LOCK = threading.Lock()


def cache_lock() -> threading.Lock:
    """The loader's lock (held briefly by load_entry): a fork of this process holds it, so that the child's copy
    is never left locked by another thread (vehicle.sim.car's kernel prebuild)."""
    return _LOAD_LOCK


def load_entry(path: Path, name: str, read: Callable[[Path], T | None],
               build: Callable[[], tuple[str | bytes, T | None]] | None,
               in_memory: Callable[[str | bytes], T] | None = None) -> T | None:
    """The one loader of the disk cache's entries (generated modules: load_module; compiled libraries:
    numba_backend.native_functions): the entry `name` (naming its key) from memory, else from the file `path`,
    else built and written there atomically (a reader never sees half a file: two processes writing the same
    entry leave one whole file).

    read(path): the file's value, None when it is another key's (or was made for another CPU); a file it cannot
    read (truncated, damaged: it raises) is built again, never trusted. build(): (the file's content, holding the
    key; its value, or None to read the written file back, as an import must). in_memory(content): the value when
    the cache cannot be written (read-only); without it the value is built again at the next run. build None:
    from the cache only, None when it is not there."""
    with _LOAD_LOCK:
        if name in _LOADED:
            return _LOADED[name]  # type: ignore[return-value]
    value = None
    if path.exists():
        try:
            value = read(path)
        except Exception:  # a damaged cache file is built again
            value = None
    if value is None:
        if build is None:
            return None
        content, value = build()
        try:
            write_atomic(path, content)
            if value is None:
                value = read(path)
                if value is None:
                    raise SymbolicError(f"the cache entry {path}, just written, reads as another key's")
        except OSError:  # read-only cache
            if value is None:
                if in_memory is None:
                    raise
                value = in_memory(content)
    with _LOAD_LOCK:
        return _LOADED.setdefault(name, value)  # type: ignore[return-value]


def load_module(folder: str, name: str, key: str, source: Callable[[], str] | None) -> ModuleType | None:
    """The generated module `name` (a Python identifier naming its key: its folder, its file, its entry in
    sys.modules), through load_entry from `module_path(folder, name)` when the file's KEY is `key`, or else
    `source()` with a `KEY = key` line written there and imported by path (Numba's cache=True keeps machine code
    beside a file); source None: from the cache only, None when it is not there.

    key: a hash of everything the text depends on, the generator's fingerprint included, so that a file of
    another version is never reused. A read-only cache gives an in-memory module (its source registered for
    inspect.getsource, which llvm_code reads)."""

    def read(path: Path) -> ModuleType | None:
        mod = import_file(path, name)
        return mod if getattr(mod, "KEY", None) == key else None

    def build() -> tuple[str, None]:
        assert source is not None
        return source() + f"\nKEY = {key!r}  # the cache key (dynid.symbolic.cache.load_module)\n", None

    def in_memory(text: str | bytes) -> ModuleType:  # Numba then compiles every run: it caches beside a file
        assert isinstance(text, str)
        mod = ModuleType(name)
        fname = f"<dynid generated {name}>"
        linecache.cache[fname] = (len(text), None, text.splitlines(True), fname)
        sys.modules[name] = mod
        exec(compile_source(text, fname), mod.__dict__)
        return mod

    mod = load_entry(module_path(folder, name), name, read, None if source is None else build, in_memory)
    if mod is not None:
        with _LOAD_LOCK:
            sys.modules[name] = mod
    return mod


def numpy_module(tree: Tree, model: str, **options) -> ModuleType:
    """The generated NumPy module of a model, from memory, the disk cache, or generated now.

    Its `evaluate` function (also named after the model) is batched over samples.
    """

    h = model_hash(tree, model, options)

    def source() -> str:
        prog = build(tree, model, **options)
        prog.meta["n"] = tree.n
        return to_numpy(prog, tree, h)

    mod = load_module("numpy", f"dynid_gen_{model}_{h}", h, source)
    assert mod is not None
    return mod


__all__ = ["cache_dir", "cache_lock", "fingerprint", "generator_fingerprint", "import_file", "load_entry",
           "load_module", "model_hash", "module_path", "numpy_module", "write_atomic"]

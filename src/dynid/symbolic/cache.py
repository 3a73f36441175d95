"""The generated NumPy modules, cached on disk under a hash of the model description, the options and
the generator's own source (`DYNID_CACHE`, default ~/.cache/dynid), written atomically and imported
from there.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import json
import os
import sys
from pathlib import Path
from types import ModuleType

from ..atomic import write_atomic as _write_atomic
from ..dynamics import trig
from ..model.files import tree_to_toml
from ..model.tree import Tree
from ..pysource import compile_source
from .codegen import GENERATOR_VERSION
from .expr import SymbolicError
from .models import build
from .numpy_code import to_numpy


# ----- hashing, caching, importing ----------------------------------------------------------------
@functools.cache
def generator_fingerprint() -> str:
    """Hash of the generator's own source (this package's modules and dynamics.trig): a cached module generated
    by another version of dynid is never reused, without anyone having to remember to bump GENERATOR_VERSION."""
    h = hashlib.sha256(GENERATOR_VERSION.encode())
    for f in [*sorted(Path(__file__).parent.glob("*.py")), Path(trig.__file__)]:  # trig: the sine in every target
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


def write_atomic(path: Path, text: str) -> None:
    """Write then rename (dynid.atomic), so that a reader never sees half a file; creates the folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    _write_atomic(path, text)


def import_file(path: Path, name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise SymbolicError(f"cannot import the generated module {path}")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


_LOADED: dict[str, ModuleType] = {}


def numpy_module(tree: Tree, model: str, **options) -> ModuleType:
    """The generated NumPy module of a model, from memory, the disk cache, or generated now.

    Its `evaluate` function (also named after the model) is batched over samples.
    """

    h = model_hash(tree, model, options)
    if h in _LOADED:
        return _LOADED[h]
    name = f"dynid_gen_{model}_{h}"
    path = cache_dir() / "numpy" / f"{name}.py"
    mod = None
    if path.exists():
        try:
            mod = import_file(path, name)
            if getattr(mod, "HASH", None) != h:
                mod = None
        except Exception:  # a damaged cache file is regenerated, never trusted
            mod = None
    if mod is None:
        prog = build(tree, model, **options)
        prog.meta["n"] = tree.n
        src = to_numpy(prog, tree, h)
        try:
            write_atomic(path, src)
            mod = import_file(path, name)
        except OSError:  # read-only cache: fall back to an in-memory module
            mod = ModuleType(name)
            exec(compile_source(src, f"<dynid generated {model}>"), mod.__dict__)
    sys.modules.setdefault(name, mod)
    _LOADED[h] = mod
    return mod


__all__ = ["cache_dir", "generator_fingerprint", "import_file", "model_hash", "numpy_module", "write_atomic"]

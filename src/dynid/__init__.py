"""dynid: dynamic identification of vehicles and robots with the robotics formalism."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__

if TYPE_CHECKING:
    from .dynamics import BaseParameters, Model, Wrench, load_model
    from .model import EXAMPLES, ModelError, Tree, example_path, load_tree, save_tree

# each public name and the sub-package it comes from, imported on first use: `import dynid` (and so
# `dynid --version`, `dynid --help`) loads no NumPy, SciPy or Numba
_LAZY = {
    "BaseParameters": "dynamics", "Model": "dynamics", "Wrench": "dynamics", "load_model": "dynamics",
    "EXAMPLES": "model", "ModelError": "model", "Tree": "model", "example_path": "model", "load_tree": "model",
    "save_tree": "model",
}


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'dynid' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    globals()[name] = value  # later look-ups find it directly
    return value


def identify(config, progress=None, scheduler=None):
    """Run the identification a config describes, as `dynid identify` does (without writing the output folder).

    config: the config file's path (str or path-like), or an `IdentifyConfig` from
    `dynid.pipeline.config.load_config`. progress: a callable taking each progress message; scheduler: where the
    segments run (default: the config's [compute], else this machine's threads). Returns the
    `IdentificationRun` (its `result`, `errors`, `summary()`). The pipeline is imported here, on first use:
    `import dynid` stays light."""
    from .pipeline.run import identify as run  # start-up: import dynid stays light (the pipeline 1-5 s)

    return run(config, progress=progress, scheduler=scheduler)


__all__ = [
    "EXAMPLES",
    "BaseParameters",
    "Model",
    "ModelError",
    "Tree",
    "Wrench",
    "__version__",
    "example_path",
    "identify",
    "load_model",
    "load_tree",
    "save_tree",
]

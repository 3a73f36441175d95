"""dynid: dynamic identification of vehicles and robots with the robotics formalism."""

from __future__ import annotations

import os
from pathlib import Path

from .dynamics import BaseParameters, Model, Wrench
from .model import EXAMPLES, ModelError, Tree, example_path, load_tree, save_tree

__version__ = "0.1.0"


def load_model(path: str | os.PathLike[str]) -> Model:
    """Load a model file (TOML), or a shipped example by name (puma560, tx40, floating_tree)."""
    if isinstance(path, str) and path in EXAMPLES and not Path(path).exists():
        path = example_path(path)
    return Model(load_tree(path))


def identify(config, progress=None, scheduler=None):
    """Run the identification a config describes, as `dynid identify` does (without writing the output folder).

    config: the config file's path (str or path-like), or an `IdentifyConfig` from
    `dynid.pipeline.config.load_config`. progress: a callable taking each progress message; scheduler: where the
    segments run (default: the config's [compute], else this machine's threads). Returns the
    `IdentificationRun` (its `result`, `errors`, `summary()`)."""
    from .pipeline.run import identify as run

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
    "save_tree",
]

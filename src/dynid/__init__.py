"""dynid: dynamic identification of vehicles and robots with the robotics formalism."""

from __future__ import annotations

from ._version import __version__
from .dynamics import BaseParameters, Model, Wrench, load_model
from .model import EXAMPLES, ModelError, Tree, example_path, load_tree, save_tree


def identify(config, progress=None, scheduler=None):
    """Run the identification a config describes, as `dynid identify` does (without writing the output folder).

    config: the config file's path (str or path-like), or an `IdentifyConfig` from
    `dynid.pipeline.config.load_config`. progress: a callable taking each progress message; scheduler: where the
    segments run (default: the config's [compute], else this machine's threads). Returns the
    `IdentificationRun` (its `result`, `errors`, `summary()`). The pipeline is imported here, on first use:
    `import dynid` stays light."""
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
    "load_tree",
    "save_tree",
]

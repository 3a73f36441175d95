"""Model description: MDH frames, parameters, couplings, and model files."""

from importlib import resources
from pathlib import Path

from .consistency import Violation, check_physical
from .files import load_tree, save_tree, tree_from_dict, tree_to_toml
from .tree import (
    COUPLING_KINDS,
    FIXED,
    FRICTION_SHAPES,
    INERTIAL,
    JOINT_TERMS,
    PRISMATIC,
    REVOLUTE,
    Coupling,
    Frame,
    Mimic,
    ModelError,
    Tree,
)
from .urdf import UrdfError, export_urdf, import_urdf, read_urdf

EXAMPLES = ("puma560", "tx40", "floating_tree")


def example_path(name: str) -> Path:
    """Path of a shipped example model file (puma560, tx40, floating_tree)."""
    if name not in EXAMPLES:
        raise ModelError(f"no shipped example {name!r}; examples: {', '.join(EXAMPLES)}")
    return Path(str(resources.files(__package__) / "examples" / f"{name}.toml"))


__all__ = [
    "COUPLING_KINDS", "EXAMPLES", "FIXED", "FRICTION_SHAPES", "INERTIAL", "JOINT_TERMS", "PRISMATIC", "REVOLUTE",
    "Coupling", "Frame", "Mimic", "ModelError", "Tree", "UrdfError", "Violation", "check_physical", "example_path",
    "export_urdf", "import_urdf", "load_tree", "read_urdf", "save_tree", "tree_from_dict", "tree_to_toml",
]

"""Optional dependencies of the file formats, imported on first use with a clear error if absent."""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import MissingDependencyError

# module -> (pip package, dynid extra that installs it)
PACKAGES = {
    "pyarrow": ("pyarrow", "parquet"),
    "pyarrow.parquet": ("pyarrow", "parquet"),
    "asammdf": ("asammdf", "mdf"),
    "h5py": ("h5py", "mat73"),
}


def require(module: str, what: str) -> ModuleType:
    """Import `module` or raise `MissingDependencyError` saying what needs it and what to install."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        package, extra = PACKAGES.get(module, (module.split(".")[0], None))
        # the package itself: dynid is not on the package index, so 'dynid[extra]' is no install line
        how = f"pip install {package} (dynid's {extra!r} extra)" if extra else f"pip install {package}"
        raise MissingDependencyError(f"{what} needs the optional package {package!r}, not installed: {how}") from exc


def available(module: str) -> bool:
    """True if `module` can be imported."""
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True

"""The package version (one place: the package, its outputs' provenance and `dynid --version` read it)."""

__version__ = "0.1.0"

"""Symbolic models (SYMORO-style) and code generation.

    prog = dynid.symbolic.idm(tree)          # or dgm, regressor(tree, rows, cols), inertia
    prog.ops()                               # multiplications, additions, functions
    to_text(prog); to_numpy(prog, tree); to_c(prog)
    numpy_module(tree, "regressor").evaluate(q, qd, qdd)   # generated, cached on disk
    base_parameters(tree, geometry="symbolic")             # Khalil's regrouping rules
"""

from .cache import cache_dir, model_hash, numpy_module
from .codegen import to_c, to_text
from .expr import OpCount, Program, SymbolicError
from .models import MODELS, WrenchSite, build, dgm, idm, inertia, regressor
from .numpy_code import to_numpy
from .regroup import SymbolicBaseParameters, base_parameters

__all__ = [
    "MODELS", "OpCount", "Program", "SymbolicBaseParameters", "SymbolicError", "WrenchSite", "base_parameters",
    "build", "cache_dir", "dgm", "idm", "inertia", "model_hash", "numpy_module", "regressor", "to_c", "to_numpy",
    "to_text",
]

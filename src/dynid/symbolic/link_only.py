"""Numba compiles of functions that only jitted callers call, kept as LLVM IR for those callers to link.

Numba gives each compiled function its own code library and finalises it at once: it links the callees'
modules in, optimises the whole module (its inliner, then LLVM's -O3 passes) and emits machine code. A
function called only from jitted code (numba_backend.compile_source's `internal`: no Python or C entry
point) never runs that machine code: each caller links the function's IR into its own library, optimises
it again there and emits it again. For the simulator's kernel (simulate -> derivative -> driver, the
tables, the tires, the LU solve) that is every function but `simulate`, whose library runs everything once
more. `LinkOnlyCompiler` (a Numba `pipeline_class`) gives such a function a `LinkOnlyLibrary`: its functions
optimised one by one as before (Numba does that when they are added), the callees linked, and nothing else:
the module's optimisation and the machine code are left to the caller that runs it.

The numbers do not change: no fast-math flag anywhere, so LLVM's passes keep every IEEE operation, in
order, whichever library inlines it; tests/vehicle/test_kernel_compile.py checks a simulation's bits against
the kernel compiled the usual way. Measured (a first run's kernel build after a trivial compile, 2-core
Xeon, load 1.3-5, alternated): 5.4 and 6.1 s of CPU against 4.4 and 4.4; a 40 s sine simulated in the
same CPU time (0.60-0.65 s either way). A link-only function is not cached (there is no object code to keep):
its code is cached in its callers'.
"""

from __future__ import annotations

from numba.core import codegen, compiler
from numba.core.compiler_lock import require_global_compiler_lock


class _NoEnvironment:
    """The codegen, but for setting a function's environment (Numba's `set_env` writes it where the machine code
    holds it, and a link-only library has none: the caller's library sets it in its own)."""

    def __init__(self, owner) -> None:
        self._owner = owner

    def set_env(self, env_name, env) -> None:
        pass

    def __getattr__(self, name):
        return getattr(self._owner, name)


class LinkOnlyLibrary(codegen.JITCodeLibrary):
    """A code library finalised without module optimisation or machine code (module doc)."""

    def finalize(self) -> None:
        require_global_compiler_lock()
        self._raise_if_finalized()
        seen = set()
        for library in self._linking_libraries:  # as JITCodeLibrary.finalize: the callees linked for the callers
            if library not in seen:
                seen.add(library)
                self._reload_init.update(library._reload_init)
                self._final_module.link_in(library._get_module_for_linking(), preserve=True)
        self._final_module.verify()
        self._finalize_dynamic_globals()
        self._finalized = True

    def get_pointer_to_function(self, name: str) -> int:
        return 0  # no machine code: as for an entry point a function compiled without one does not have

    @property
    def codegen(self):
        return _NoEnvironment(self._codegen)


class LinkOnlyCompiler(compiler.Compiler):
    """Numba's nopython pipeline, compiling into a LinkOnlyLibrary (`njit(pipeline_class=LinkOnlyCompiler,
    no_cpython_wrapper=True, no_cfunc_wrapper=True)`, without cache=True)."""

    def compile_extra(self, func):
        if self.state.library is None and _fits(self.state.targetctx.codegen()):
            self.state.library = LinkOnlyLibrary(self.state.targetctx.codegen(), func.__qualname__)
        return super().compile_extra(func)


# what LinkOnlyLibrary.finalize uses of Numba's private JITCodeLibrary (as of Numba 0.60-0.68)
_USED = ("_linking_libraries", "_final_module", "_reload_init", "_get_module_for_linking",
         "_finalize_dynamic_globals", "_raise_if_finalized", "_codegen")
_FITS: list[bool] = []


def _fits(cg) -> bool:
    """Whether this Numba's code library has what LinkOnlyLibrary uses; if not (another version), the functions
    compile the usual way: a first run a second slower, nothing else."""
    if not _FITS:
        probe = cg.create_library("dynid_link_only_probe")
        _FITS.append(isinstance(probe, codegen.JITCodeLibrary) and all(hasattr(probe, a) for a in _USED))
    return _FITS[0]

"""The simulator's kernel compiled with its helpers kept as LLVM IR for simulate to link (symbolic.link_only: a first
run's kernel build about 1 s of CPU shorter): the same simulation, to the bit.

Oracle: the same kernel source compiled the usual way (every helper optimised and emitted in its own library, the
code before link_only), run on the same car and manoeuvres in this process.
"""

import numpy as np
import pytest

from dynid.symbolic import numba_backend as nb
from dynid.vehicle.sim import car, kernel

pytest.importorskip("numba")


@pytest.mark.slow
def test_the_linked_kernel_simulates_the_bits_of_the_kernel_emitted_as_usual(tmp_path, monkeypatch):
    from dynid.symbolic.link_only import LinkOnlyCompiler

    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    sim = car.CarSimulator()
    shipped = sim.module
    assert all(getattr(shipped, n)._compiler.pipeline_class is LinkOnlyCompiler for n in kernel.INTERNAL)
    usual = nb.compile_source(car._kernel_body(), list(kernel.JITTED), nb.source_key("usual", car._kernel_key()),
                              prefix="dynid_test_simk", error_model=car.KERNEL_ERROR_MODEL)
    assert usual.derivative._compiler.pipeline_class is not LinkOnlyCompiler
    # the driver's branches, the tires in and out of their linear range, the tables, the aero, the LU solve
    for name in ("sine", "braking", "lane", "fishhook"):
        runs = []
        for module in (shipped, usual):
            sim.module = module
            r = sim.run(name, duration=3.0, start=0.2)
            runs.append(np.concatenate([a.ravel() for a in (r.q, r.qd, r.qdd, r.wheel_wrenches, r.record)]))
        assert runs[0].view(np.int64).tolist() == runs[1].view(np.int64).tolist(), name  # the bits, NaN or not

"""The simulated car: its tree, its generated and compiled models, and the run loop.

`CarSimulator(parameters, geometry, tables, aero, tires, settings)` builds the tree of the
car template with the true parameters plus a small tire damping declared as FV on the
tire joints (`sim_tree`: car_identification moves it to Y as a known term, so the tire
equations stay exact), generates three per-sample models with numeric parameters
(numba_backend): the kinematics of the tire frames and of frame 6, the inverse dynamics
with the four tire wrench sites and the aerodynamic site, and the free joints' rows of
the inertia matrix M(q) (composite bodies: one pass, where NF products M v would cost
eight times as much); compiles them from their LLVM IR into machine code (numba_backend.
native_functions: no Numba typing, cached as object code), and hands their addresses to the
kernel (kernel.py: one compiled module for every vehicle, cached once per dynid version).
`run(manoeuvre)` integrates with RK4 on the 625 Hz acquisition clock (substeps optional) and
returns a SimulationResult.

First run: `prebuild_kernel()` (called by pipeline.demo.simulated_car before the vehicle is
loaded) compiles the kernel in a forked process while this one loads the vehicle (its rest
state compiles the engine) and generates its models; a new vehicle then costs only its models.

Step: one RK4 step per 1.6 ms sample by default. The fastest dynamics are the wheel hop
(about 13 Hz) and the tire-slip/spin loop through the relaxation lengths (about 30 Hz):
omega dt <= 0.3, well inside RK4's stability and accuracy range; `test_simulator`
halves the step and bounds the change of the lateral acceleration and the wheel loads.

Dry friction of the dampers: fs tanh(qd / v_s) (v_s = `SimSettings.friction_speed`, 2 mm/s),
applied by the kernel, not the tree's fs sign(qd): a well-posed force at reversal, whose
slope fs / v_s (at most 18 kN.s/m on a 35 kg wheel: 510 1/s, lambda dt = 0.8) RK4
integrates stably. Past a few v_s it is the identification model's fs sign(qd); the sidecar
states the law.
"""

from __future__ import annotations

import atexit
import contextlib
import dataclasses
import hashlib
import inspect
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...dynamics import Model
from ...model.files import tree_to_toml
from ...model.tree import CURVE_TERMS, PRISMATIC, Tree
from ...resources import memory_budget
from ...symbolic import numba_backend as nb
from ...symbolic.cache import cache_lock
from ...symbolic.expr import ZERO, add, cross
from ...symbolic.models import Builder, WrenchSite, add3, finish, idm, inertia
from ..aero import Aerodynamics, aero_wrench, reference_point
from ..car_model import car_template
from ..equations import car_identification
from ..geometry import CarGeometry, demo_geometry
from ..parameters import ParameterSet, truth
from ..sensors import ideal_channels, mounted
from ..statics import REST_ENGINE, rest_state
from ..tables import STEERING_RATIO, KinematicTables, default_tables
from ..template import CHASSIS, DAMPERS, TIRES, WHEELS, tabulated
from . import kernel as K  # noqa: N812 - the kernel layout constants read as K.NY, K.FREE
from .bicycle import Bicycle, Car, bicycle, cornering_bicycle
from .interp import pack_aero, pack_tables
from .manoeuvres import Manoeuvre, ManoeuvreError, manoeuvre, pack
from .tires import MagicFormula

SAMPLE_TIME = 1.6e-3


class SimulationError(RuntimeError):
    """The integration left the model's domain (a table's range, a non-finite state)."""


@dataclass(frozen=True)
class SimSettings:
    """dt: sample time (s); substeps: RK4 steps per sample; switches for the energy tests:
    aero, tire_horizontal (Fx, Fy, Mz), rolling_resistance; tire_damping: c_t (N.s/m, FV on
    the tire joints); friction_speed: v_s (m/s) of the dampers' dry friction law fs tanh(qd / v_s);
    steering robot natural frequency (Hz) and damping; speed controller
    gains kp (1/s), ki (1/s^2) on the speed error, drive torque limits (N.m, total)."""

    dt: float = SAMPLE_TIME
    substeps: int = 1
    aero: bool = True
    tire_horizontal: bool = True
    rolling_resistance: bool = True
    tire_damping: float = 100.0
    friction_speed: float = 0.002
    steering_frequency: float = 8.0
    steering_damping: float = 0.8
    kp: float = 1.0
    ki: float = 0.3
    drive_max: float = 3000.0
    drive_min: float = -600.0

    def __post_init__(self) -> None:
        if not (self.dt > 0 and self.substeps >= 1 and self.tire_damping >= 0 and self.friction_speed > 0):
            raise ValueError("simulator settings: need dt > 0, substeps >= 1, tire_damping >= 0, friction_speed > 0; "
                             f"got {self}")


def sim_tree(parameters: ParameterSet | dict | None = None, geometry: CarGeometry | None = None,
             tire_damping: float = 100.0, damper_knees: Mapping[int, tuple[float, float]] | None = None,
             name: str = "car") -> Tree:
    """The car template with the parameter set and FV (tire damping) on the tire joints; a damper whose curve
    slopes the set gives (hbl9 ...) drives with that curve about its damper_knees (car_template), the generated
    inverse dynamics applying it like any joint term. name: the car's (the vehicle file's), which the tree and the
    recordings' sidecars carry."""
    if parameters is None:
        parameters = truth(geometry)
    values = dict(parameters if isinstance(parameters, dict) else parameters.values)
    curved = {d for d in DAMPERS if any(f"{t}{d}" in values for t in CURVE_TERMS)}
    missing = sorted(curved - set(damper_knees or {}))
    if missing:
        raise ValueError(f"the parameter set gives a curve for dampers {missing}: damper_knees needs their knees")
    tree = car_template(geometry, values, name=f"{name} (simulated truth)",
                        damper_knees={d: damper_knees[d] for d in curved} if damper_knees else None)
    terms = dict(tree.joint_terms)
    for t in TIRES:
        terms[t] = ("FV", "K")
    tree = dataclasses.replace(tree, joint_terms=terms)
    return tree.with_values({**values, **{f"FV{t}": float(tire_damping) for t in TIRES}})


def kinematics_program(tree: Tree):
    """Poses and twists the kernel needs: per tire frame (R 9, P 3 in frame 0; w, v 3+3 in its own
    frame), then frame 6 (v, w in frame 6): K.NKIN outputs (see kernel.py)."""
    b = Builder(tree, "kin", (K.NKIN,), "numeric", "numeric")
    out = b.prog.outputs
    vel: dict[int, list] = {0: [ZERO] * 3}

    def velocity(k: int) -> list:
        """Velocity of O_k in frame k, recursively (one rotation per frame, not one Jacobian column per
        ancestor: half the operations of the kinematics and of its compile time)."""
        if k not in vel:
            i = tree.frames[k - 1].ant
            v = b.geo.down(k, add3(velocity(i), cross(b.w(i), b.geo.pos(k))))
            if tree.frames[k - 1].sigma == PRISMATIC:
                v[2] = add(v[2], b.geo.qd(k))
            vel[k] = b.geo.name3("V", k, v)
        return vel[k]

    for i, t in enumerate(TIRES):
        R, P = b.geo.abs_rot(t), b.geo.abs_pos(t)
        o = K.KIN_CORNER * i
        for r in range(3):
            for c in range(3):
                out.append(((o + 3 * r + c,), R[r][c]))
            out.append(((o + 9 + r,), P[r]))
        w, v = b.w(t), velocity(t)
        for c in range(3):
            out.append(((o + 12 + c,), w[c]))
            out.append(((o + 15 + c,), v[c]))
    v6, w6 = velocity(CHASSIS), b.w(CHASSIS)
    for c in range(3):
        out.append(((K.KIN_6 + c,), v6[c]))
        out.append(((K.KIN_6 + 3 + c,), w6[c]))
    return finish(b)


def free_rows_inertia(inert: Tree):
    """The inertia matrix's rows of the free joints (K.FREE), columns of the free and tabulated joints
    (the rest left zero), shape (K.NF, K.NF_ROW): composite bodies, numeric parameters."""
    prog = inertia(inert, "numeric", "numeric")
    rows = {j - 1: i for i, j in enumerate(K.FREE)}
    cols = set(rows) | {j - 1 for k in range(4) for j in tabulated(k)}
    prog.outputs = [((rows[i], j), v) for (i, j), v in prog.outputs if i in rows and j in cols]
    prog.shape = (K.NF, K.NF_ROW)
    return prog.prune()


KERNEL_SOURCES = ("kernel.py", "tires.py", "interp.py", "../table_poly.py")  # what the compiled kernel depends on


def _models_key(tree: Tree, aero_point) -> str:
    """Hash of what the vehicle's generated models depend on: the tree, the functions here that generate them,
    the aero point (and the generator: source_key)."""
    srcs = "".join(inspect.getsource(f) for f in (kinematics_program, free_rows_inertia, _models_source))
    return nb.source_key(tree_to_toml(tree), repr(list(tree.gravity)), srcs, repr([float(x) for x in aero_point]))


def _models_source(tree: Tree, aero_point) -> dict[str, str]:
    """K.MODELS -> the source of the vehicle's generated straight-line function (numba_backend.scalar_source)."""
    sites = [WrenchSite(t) for t in TIRES] + [WrenchSite(CHASSIS, tuple(float(x) for x in aero_point), CHASSIS)]
    inertial = {n: v for n, v in tree.values.items() if n[:2] in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ")
                or (n.startswith("M") and n[1:].isdigit())}
    inert = dataclasses.replace(tree, joint_terms={}, couplings=(), gravity=(0.0, 0.0, 0.0), values=inertial,
                                known=frozenset(), labels={})
    # the dampers' dry friction is the kernel's smooth law (P_FS), not the tree's sign(qd)
    no_dry = dataclasses.replace(tree, values={**tree.values, **{f"FS{d}": 0.0 for d in DAMPERS}})
    progs = (kinematics_program(tree), idm(no_dry, parameters="numeric", wrenches=sites), free_rows_inertia(inert))
    out = {}
    for name, prog, args in zip(K.MODELS, progs, _MODEL_ARGS, strict=True):
        if nb.arguments(prog) != list(args):  # the kernel calls each with these arrays, by position
            raise AssertionError(f"{name}: generated with arguments {nb.arguments(prog)}, the kernel passes {args}")
        out[name] = nb.scalar_source(prog, name)
    return out


_MODEL_ARGS = (("q", "qd"), ("q", "qd", "qdd", "wrench"), ("q",))


# Numba's error model for the kernel: "numpy" lowers no zero-division check and raise per division (a 20 s sine
# 0.35 -> 0.32 s of CPU, the same bits; its compile measured unchanged, ~9-10 s either way); a division by zero
# gives inf or NaN, which the non-finite state check (S_NONFINITE) turns into a SimulationError
KERNEL_ERROR_MODEL = "numpy"


def _kernel_key() -> str:
    here = Path(__file__).parent
    return nb.source_key(*((here / f).read_text(encoding="utf-8") for f in KERNEL_SOURCES),
                         f"error_model={KERNEL_ERROR_MODEL}")


def _kernel_body() -> str:
    kernel_src = inspect.getsource(K).replace("from __future__ import annotations\n", "")
    here = Path(__file__).parent
    deps = hashlib.sha256(b"".join((here / f).read_bytes() for f in KERNEL_SOURCES[1:])).hexdigest()[:16]
    # compiled: the models are called through their addresses (llvm_code.address_call), not as Python functions
    return "\n".join([f"# kernel dependencies: tires.py + interp.py + table_poly.py {deps}", kernel_src,
                      "try:", "    from dynid.symbolic.llvm_code import address_call",
                      "    call_model = address_call()  # noqa: F811 - replaces the Python version",
                      "except ImportError:  # no numba: the Python version", "    pass"])


def kernel_module():
    """The compiled kernel (kernel.py, one module for every vehicle), from the cache or written now; waits for
    a kernel build prebuild_kernel started (so that its compiled code is loaded, not compiled twice)."""
    key = _kernel_key()
    module = nb.compile_source(None, [], key, prefix="dynid_simk")
    if module is None:
        module = nb.compile_source(_kernel_body(), list(K.JITTED), key, prefix="dynid_simk",
                                   error_model=KERNEL_ERROR_MODEL, internal=K.INTERNAL)
    build = _PREBUILD.get(key)
    if build is not None:
        _run_meanwhile()
        build.wait()  # kept listed until it ends: an interrupt meanwhile leaves it to _stop_prebuilds at exit
        _PREBUILD.pop(key, None)
    return module


_MEANWHILE: list[Callable[[], object]] = []


def while_kernel_builds(task: Callable[[], object]) -> None:
    """Run `task` in this process while it waits for the kernel's build (prebuild_kernel) at the next
    kernel_module(): a first run's idle core then compiles what the run needs later (pipeline.first_run: or lets
    the child that compiles it start). Call it before prebuild_kernel, which drops it when the kernel is cached (no
    wait), or after one that returned True. Its errors are dropped: it may only save time, never fail the run."""
    _MEANWHILE.append(task)


def _run_meanwhile() -> None:
    while _MEANWHILE:
        task = _MEANWHILE.pop(0)
        with contextlib.suppress(Exception):  # a head start only: what it did not compile compiles when used
            task()


def compile_lock():
    """Numba's global compiler lock (its compiles, in any thread, hold it)."""
    from numba.core.compiler_lock import global_compiler_lock  # start-up: numba 0.5 s (called only where it is)

    return global_compiler_lock


# the longest a first run waits for the kernel's build in another process (measured: ~10 s of CPU on an idle
# core, 20-30 s on a loaded one) before it is taken for stuck and compiled here
WAIT_S = 300.0


def _start_numba() -> None:
    """Compile a trivial function first (0.2-0.3 s of CPU) in the kernel's build process: Numba installs its typing
    registries lazily, during a process's first compile, and that compile then types each operation through many
    more of its overload templates: the kernel's compile as a process's first resolves 19,013 overload
    implementations, after a trivial one 995, and takes ~1 s more CPU than the two together."""
    from numba import njit  # start-up: numba 0.5 s (imported already where a kernel is prebuilt)

    njit(lambda x: x + 1.0)(1.0)


class _Build:
    """A kernel compile running in another process: a fork of this one where there is fork (Linux: numba and
    dynid already imported, about 2 s of CPU a fresh interpreter would spend again), else a new interpreter."""

    def __init__(self, key: str) -> None:
        self.pid = self.proc = None
        # fork only a process of one thread: another thread's locks (logging, a library's) would stay held in the
        # child's copy, where nothing frees them (a library embedding dynid in a threaded worker gets a new interpreter)
        if sys.platform.startswith("linux") and threading.active_count() == 1:
            # forked while holding the locks the child takes (Numba's compiler lock, the generated modules' loader),
            # so that no other thread of this process holds one in the child's copy, where it would never be freed
            with compile_lock(), cache_lock():
                pid = os.fork()
            if pid == 0:  # the child: compile, then leave at once (no atexit, no buffered output flushed twice)
                code = 1
                try:
                    _compile_kernel(key)
                    code = 0
                finally:
                    os._exit(code)
            self.pid = pid
        else:  # its output is of no use to the user; a failure costs only the wait
            self.proc = subprocess.Popen(
                [sys.executable, "-c", f"from dynid.vehicle.sim.car import _compile_kernel; _compile_kernel({key!r})"],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def wait(self, timeout: float = WAIT_S) -> None:
        """Until the build ends; one stuck beyond `timeout` is killed (the kernel then compiles in this process:
        the user loses the time, never the run)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self.proc is not None and self.proc.poll() is not None:
                return
            if self.pid is not None and os.waitpid(self.pid, os.WNOHANG)[0] != 0:
                self.pid = None
                return
            if self.proc is None and self.pid is None:
                return
            time.sleep(0.02)
        self.kill()

    def kill(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
        elif self.pid is not None:
            pid, self.pid = self.pid, None
            # (none left when an interrupt cut short the wait that had reaped it)
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            with contextlib.suppress(ChildProcessError):
                os.waitpid(pid, 0)


_PREBUILD: dict[str, _Build] = {}


@atexit.register
def _stop_prebuilds() -> None:
    """A run that ends before its simulator is built (a vehicle file's error) leaves no compile running."""
    for build in _PREBUILD.values():
        build.kill()


def prebuild_kernel() -> bool:
    """Start compiling the simulator's kernel in another process when its compiled code is not cached yet (a
    first run): Numba's typing of it is most of a first simulation, and the vehicle's loading (its rest state,
    its generated models) runs meanwhile on the other core. The next kernel_module() waits for it. Returns
    whether a build was started."""
    if not nb.have_numba():
        _MEANWHILE.clear()  # no wait to fill (while_kernel_builds)
        return False
    key = _kernel_key()
    if key in _PREBUILD:
        return True
    module = kernel_module()
    if kernel_cached(module) is not False:
        _MEANWHILE.clear()
        return False
    _PREBUILD[key] = _Build(key)
    return True


def kernel_cached(module) -> bool | None:
    """Whether Numba has the kernel's compiled code on disk (None: cannot tell, numba absent or changed)."""
    try:
        return Path(module.simulate._cache._cache_file._index_path).exists()
    except Exception:  # a guess for a message or a prebuild: never a reason to fail
        return None


def _kernel_arguments(module, models: np.ndarray, n: int = 1) -> tuple:
    """simulate's arguments for n samples of zeros, of the types run() passes (the compile is per type)."""
    packed = pack_tables(default_tables())
    return (np.zeros(K.NY), 0.0, SAMPLE_TIME, 0, 1, np.zeros(K.NPAR), np.zeros((4, 27)), np.zeros(K.MAN_TABLE),
            *packed, *pack_aero(Aerodynamics()), models, np.zeros((n, 42)), np.zeros((n, 42)), np.zeros((n, 42)),
            np.zeros((n, 4, 6)), np.zeros((n, K.NREC)), np.zeros(2, dtype=np.int64))


def _compile_kernel(key: str) -> None:
    """In prebuild_kernel's process: compile simulate (and so everything it calls) into Numba's disk cache, with
    no step taken (nsteps 0)."""
    module = nb.compile_source(None, [], key, prefix="dynid_simk")
    if module is not None:
        _start_numba()
        module.simulate(*_kernel_arguments(module, np.zeros(len(K.MODELS), dtype=np.int64)))


@dataclass
class CompileInfo:
    """generate_s: the vehicle's models generated and compiled (or loaded); import_s: the kernel loaded, with the
    wait for a prebuild_kernel process; first_call_s: the first simulate call (Numba's compile when not cached)."""

    generate_s: float = 0.0
    import_s: float = 0.0
    first_call_s: float = 0.0
    module: str = ""


class CarSimulator:
    """A car to drive: tree, tables, tires, aerodynamics and the compiled kernel (see module doc)."""

    def __init__(
        self,
        parameters: ParameterSet | dict | None = None,
        geometry: CarGeometry | None = None,
        tables: KinematicTables | None = None,
        aero: Aerodynamics | None = None,
        tires: MagicFormula | tuple[MagicFormula, ...] | None = None,
        settings: SimSettings | None = None,
        steering_ratio: float = STEERING_RATIO,
        damper_knees: Mapping[int, tuple[float, float]] | None = None,
        name: str = "car",
    ) -> None:
        # a first run (empty caches): the kernel compiles in another process while this one solves the rest state
        # (the engine's compile) and generates the models, as simulated_car does (a no-op when it already started one
        # or the kernel is cached); bench_simulator's first run measured the two one after the other
        prebuild_kernel()
        self.geometry = demo_geometry() if geometry is None else geometry
        self.steering_ratio = float(steering_ratio)  # the driver robot's: steering-wheel angle per wheel angle
        self.tables = default_tables(self.geometry, self.steering_ratio) if tables is None else tables
        self.aero = Aerodynamics() if aero is None else aero
        tires = MagicFormula() if tires is None else tires
        self.tires = tuple(tires) if isinstance(tires, tuple) else (tires,) * 4
        self.settings = SimSettings() if settings is None else settings
        self.parameters = truth(self.geometry, self.tables) if parameters is None else parameters
        self.tree = sim_tree(self.parameters, self.geometry, self.settings.tire_damping, damper_knees, name)
        self.rest = rest_state(self.tree, self.tables)
        self.mass = sum(self.tree.values.get(f"M{j}", 0.0) for j in range(1, 43))
        self.radius = self.geometry.wheel_radius

        g = -self.tree.gravity[2]
        b_rear = self.geometry.wheelbase * (self.rest.loads[2] + self.rest.loads[3]) / (self.mass * g)
        # one posture: the reference engine, as the rest state (statics.REST_ENGINE: no engine compile on a first run)
        iz = float(Model(self.tree).inertia_matrix(self.rest.q, backend=REST_ENGINE)[3, 3]) - self.mass * b_rear**2
        self.bicycle = bicycle(self.rest.loads, self.tires, self.geometry.wheelbase, g, iz)
        self.mu = min(min(t.peak_friction(float(f))) for t, f in zip(self.tires, self.rest.loads, strict=True))
        self.aero_point = reference_point(self.geometry) if self.aero.point is None else np.asarray(self.aero.point)
        self.compile_info = CompileInfo()
        t0 = time.perf_counter()
        key = _models_key(self.tree, self.aero_point)
        # the vehicle's models: straight-line code through LLVM IR into machine code, cached as object code
        self.models = nb.native_functions(key, lambda: _models_source(self.tree, self.aero_point), prefix="dynid_car")
        self._addresses = np.array([self.models.address[n] for n in K.MODELS], dtype=np.int64)
        self.compile_info.generate_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        self.module = kernel_module()
        if not self.models.native:
            self.module._PYTHON_MODELS.update({self.models.address[n]: f for n, f in self.models.python.items()})
        self.compile_info.import_s = time.perf_counter() - t0
        self.compile_info.module = self.module.__name__
        self._packed_tables = pack_tables(self.tables)
        self._packed_aero = pack_aero(self.aero)

    def cornering_model(self, speed: float) -> Bicycle:
        """The extended linear bicycle model at `speed` m/s (bicycle.py: loads at speed, trail, roll steer,
        toe x load transfer, the tires' longitudinal forces, drive, aerodynamics) of this car; the
        manoeuvres use the classic `self.bicycle`. Assumes the tire forces and rolling resistance on."""
        aero = self.aero if self.settings.aero else None
        car = Car(self.tree, self.tables, self.rest, self.tires, self.geometry, aero)
        return cornering_bicycle(self.bicycle, car, speed)

    # ----- packing ------------------------------------------------------------------------
    def car_constants(self) -> dict[str, float]:
        return {"mass": self.mass, "radius": self.radius, "ratio": self.steering_ratio,
                "wheelbase": self.geometry.wheelbase, "understeer": self.bicycle.understeer, "mu": self.mu,
                "bicycle": self.bicycle, "front_share": self._front_share()}

    def _front_share(self) -> float:
        """The front axle's static share of the sprung weight (its CoG ahead of the rear axle, z6, over the
        wheelbase): what a front-wheel drive can pull with."""
        v = self.tree.values
        return float(np.clip(v.get("MZ6", 0.0) / v["M6"] / self.geometry.wheelbase, 0.0, 1.0))

    def _par(self) -> np.ndarray:
        s, a = self.settings, self.aero
        p = np.zeros(K.NPAR)
        p[K.P_R0], p[K.P_G], p[K.P_MASS] = self.radius, -self.tree.gravity[2], self.mass
        p[K.P_RATIO], p[K.P_WB], p[K.P_US] = self.steering_ratio, self.geometry.wheelbase, self.bicycle.understeer
        p[K.P_KP], p[K.P_KI], p[K.P_TDMAX], p[K.P_TDMIN] = s.kp, s.ki, s.drive_max, s.drive_min
        p[K.P_WS], p[K.P_ZS] = 2 * np.pi * s.steering_frequency, s.steering_damping
        p[K.P_RHO], p[K.P_AREA], p[K.P_LEN], p[K.P_VMIN] = a.rho, a.area, a.length, a.min_speed
        p[K.P_AREF:K.P_AREF + 3] = self.aero_point
        p[K.P_AERO_ON] = float(s.aero)
        p[K.P_HORIZ] = float(s.tire_horizontal)
        p[K.P_ROLL] = float(s.rolling_resistance)
        p[K.P_VLOW] = 1.0
        p[K.P_FS:K.P_FS + 4] = [self.tree.values.get(f"FS{d}", 0.0) for d in DAMPERS]
        p[K.P_FVS] = s.friction_speed
        return p

    def _tire(self) -> np.ndarray:
        out = np.zeros((4, 27))
        for k, t in enumerate(TIRES):
            out[k, :25] = self.tires[k].pack()
            out[k, 25] = self.tree.values[f"K{t}"]
            out[k, 26] = self.tree.values.get(f"FV{t}", 0.0)
        return out

    def initial_state(self, speed: float, q: np.ndarray | None = None) -> np.ndarray:
        """Rest attitude (or q), rolling straight ahead at `speed` m/s with the wheels turning freely."""
        q = self.rest.q if q is None else np.asarray(q, dtype=float)
        y = np.zeros(K.NY)
        for i, j in enumerate(K.FREE):
            y[i] = q[j - 1]
        y[K.NF + 1] = speed  # qd2: forward along y0 at zero yaw
        for k, t in enumerate(TIRES):
            re = self.radius - q[t - 1] / 3.0
            y[K.NF + 10 + k] = speed / re
        return y

    # ----- running --------------------------------------------------------------------------
    def run(self, m: Manoeuvre | str, duration: float | None = None, y0: np.ndarray | None = None,
            progress: Callable[[float], None] | None = None, **params) -> SimulationResult:
        """Drive a manoeuvre (a Manoeuvre, or a name with parameters) and record every 1.6 ms sample."""
        if isinstance(m, str):
            m = manoeuvre(m, **params)
        elif params:
            raise ManoeuvreError("pass parameters with a manoeuvre name, or build the Manoeuvre with them")
        dur = m.duration if duration is None else float(duration)
        man = pack(m, self.car_constants())
        s = self.settings
        N = round(dur / s.dt) + 1
        need = 3 * N * (3 * 42 + 4 * 6 + K.NREC) * 8  # the record, then the sensor channels and the file's copy
        if need > memory_budget():
            raise SimulationError(f"{m.name}: {dur:g} s at {1 / s.dt:g} Hz needs {need / 2**30:.1f} GiB, more than "
                                  f"half this machine's memory; simulate at most "
                                  f"{dur * memory_budget() / need:.0f} s per file")
        y = self.initial_state(m.speed) if y0 is None else np.array(y0, dtype=float)
        RQ, RQD, RQDD = np.zeros((N, 42)), np.zeros((N, 42)), np.zeros((N, 42))
        RW, RR = np.zeros((N, 4, 6)), np.zeros((N, K.NREC))
        status = np.zeros(2, dtype=np.int64)
        XB, YB, NX, NY, C = self._packed_tables
        ax, aC = self._packed_aero
        par, tire = self._par(), self._tire()
        chunk = max(1, round(1.0 / s.dt))  # one second of driving per call: progress and interrupts
        done = 0
        t_first = time.perf_counter()
        while done < N:
            n = min(chunk, N - done)
            rows = n if done + n == N else n + 1  # records `rows` samples, advances rows - 1 steps
            sl = slice(done, done + rows)
            self.module.simulate(y, done * s.dt, s.dt, rows, s.substeps, par, tire, man, XB, YB, NX, NY, C, ax, aC,
                                 self._addresses, RQ[sl], RQD[sl], RQDD[sl], RW[sl], RR[sl], status)
            if self.compile_info.first_call_s == 0.0:
                self.compile_info.first_call_s = time.perf_counter() - t_first
            if status[0] != K.S_OK:
                k = done + int(status[1])
                what = ("a damper travel or the steering-wheel angle left the kinematic tables' range"
                        if status[0] == K.S_TABLE else "the state became non-finite (the car left the model)")
                raise SimulationError(f"{m.name} at t = {k * s.dt:.4f} s (sample {k}): {what}; "
                                      f"reduce the speed or the steering of the manoeuvre")
            done += n
            if progress is not None:
                progress(min(done, N) * s.dt)
        return SimulationResult(self, m, np.arange(N) * s.dt, RQ, RQD, RQDD, RW, RR)


@dataclass
class SimulationResult:
    """The recorded samples of one run (625 Hz): q, qd, qdd (N, 42), wheel wrenches (N, 4, 6) at the
    wheel centres in the non-spinning wheel frames, steering wheel h, h', h'' (rad), spin torques (N, 4),
    contact flags (N, 4), slips kappa and alpha (N, 4)."""

    sim: CarSimulator
    manoeuvre: Manoeuvre
    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    wheel_wrenches: np.ndarray
    record: np.ndarray
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        # the massless tire links' accelerations are not used by any equation; give their derivative
        cols = np.array(TIRES) - 1
        if self.time.size > 2:
            self.qdd[:, cols] = np.gradient(self.qd[:, cols], self.time, axis=0)

    @property
    def steering_wheel(self) -> np.ndarray:
        return self.record[:, 0:3]

    @property
    def spin_torques(self) -> np.ndarray:
        return self.record[:, 3:7]

    @property
    def contact(self) -> np.ndarray:
        return self.record[:, 7:11] > 0.5

    @property
    def slips(self) -> tuple[np.ndarray, np.ndarray]:
        return self.record[:, 11:15], self.record[:, 15:19]

    @property
    def tree(self) -> Tree:
        return self.sim.tree

    def aero_wrench(self):

        if not self.sim.settings.aero:
            return None
        return aero_wrench(Model(self.tree), self.q, self.qd, self.sim.aero, self.sim.geometry)

    def identification(self, base: str = "generic", spin: bool = True, model=None):
        """car_identification on the true trajectories (the simulator's own tree; spin rows with the torques)."""

        model = Model(self.tree) if model is None else model
        spin_torques = {w: self.spin_torques[:, k] for k, w in enumerate(WHEELS)} if spin else None
        return car_identification(model, self.q, self.qd, self.qdd, self.wheel_wrenches, self.aero_wrench(),
                                  spin_torques, base=base)

    def ideal_channels(self, suite=None) -> dict[str, np.ndarray]:
        """The noise-free value of every channel, at the suite's mounting points (default: the car's)."""

        g = self.sim.geometry if suite is None else mounted(self.sim.geometry, suite)
        return ideal_channels(Model(self.tree), self.q, self.qd, self.qdd, self.wheel_wrenches,
                              self.steering_wheel[:, 0], self.spin_torques, g)

    @property
    def dampers(self) -> np.ndarray:
        return self.q[:, np.array(DAMPERS) - 1]

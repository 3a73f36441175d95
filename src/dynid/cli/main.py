"""`dynid`: command-line entry point. Errors are printed as one clear line, never a traceback."""

from __future__ import annotations

import argparse
import atexit
import contextlib
import errno
import gc
import os
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from .._version import __version__
from ..atomic import OutputError, Terminated, final_text, interrupts, staged_folder, write_atomic
from ..progress import Count
from ..shipped import CAR_TEMPLATE, DEMO_VEHICLE
from ..textfiles import TextEncodingError
from . import excite_cmds, model_io_cmds, plan_cmds, simulate_cmds, symbolic_cmds, vehicle_cmds
from .model_table import format_table
from .progress import report
from .simulate_cmds import progress_bar
from .usage import UsageError, check_options, command, overview
from .vehicle_cmds import show_template

if TYPE_CHECKING:  # the model layer (NumPy) is imported by the commands that use it: --help and --version stay quick
    from ..model import Tree

DESCRIPTION = """\
dynid identifies the dynamic parameters of robots and cars (masses, inertias, friction,
springs) from measurements with the inverse dynamic identification model and least squares,
and reports them with their uncertainty, validation and physical consistency."""


def format_parameters(tree: Tree) -> str:
    rows, line = [], []
    for name, value in zip(tree.parameter_names, tree.parameters, strict=True):
        tag = "*" if name in tree.known else ""
        line.append(f"{tree.label(name) + tag:>8} = {value:<11.6g}")
        if len(line) == 4:
            rows.append("  ".join(line))
            line = []
    if line:
        rows.append("  ".join(line))
    return "\n".join(rows)


def cmd_model_show(args: argparse.Namespace) -> int:
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..dynamics import load_model
    from ..model import ModelError

    if args.template:
        print(show_template(args.template))
        return 0
    if not args.file:
        raise ModelError("give a model file (or a shipped example: puma560, tx40, floating_tree) or --template NAME")
    model = load_model(args.file)
    tree = model.tree
    try:  # first: a tree too large to analyse is refused before anything is printed
        base = model.base_parameters()
    except ModelError as exc:
        raise ModelError(f"model show {args.file}: {exc}") from None
    print(f"{tree.name}: {tree.n} frames, {tree.p} parameters, gravity {list(tree.gravity)} m/s²\n")
    table = format_table(tree)
    if tree.joint_names:  # a model imported from a URDF: each moving frame's joint
        lines = table.splitlines()
        table = "\n".join([f"{lines[0]}  joint"] + [f"{line}  {tree.joint_names.get(f.j, '')}".rstrip()
                                                    for f, line in zip(tree.frames, lines[1:], strict=True)])
    print(table)
    print(f"\nParameters ({'* = known' if tree.known else 'values from the file'}):")
    print(format_parameters(tree))
    if tree.couplings:
        print("\nCouplings:")
        for c in tree.couplings:
            combo = " + ".join(f"{v:g}·q{j}" for j, v in c.coeffs.items())
            print(f"  {c.name}: {c.kind} on {combo}")
    print()
    print(base)
    return 0


def _say(msg: str) -> None:
    # the output folder's name, never its staging folder's; a count (segments) is drawn as a bar on a terminal
    report(msg if isinstance(msg, Count) else final_text(msg))


def _print_run(run, validation_title: str) -> None:
    """The tables of an identification, the published comparison if any, and the validation errors."""
    from ..report import validation_table  # start-up: the library, 1-5 s (--help 0.1 s)

    print(run.summary())
    if run.reference:
        print("\nComparison with the published identification:")
        print(run.reference_table())
    print(f"\n{validation_title}")
    print(validation_table(run.errors, run.not_excited, getattr(getattr(run, "config", None), "kind", None)))
    if run.delays is not None:
        print(f"\n{run.delays.text()}")
    if getattr(run, "tires", None) is not None:
        print(f"\n{run.tires.text()}")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give a whole number >= 1")
    return value


def cmd_identify(args: argparse.Namespace) -> int:
    from ..pipeline.campaign import (  # start-up: the library, 1-5 s (--help 0.1 s)
        SUMMARY_FILE,
        campaign_names,
        identify_campaign,
        summary,
        summary_csv,
        summary_text,
    )

    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..pipeline.config import ConfigError, load_config
    from ..pipeline.run import write_outputs
    from ..pipeline.schedulers import address_problem, scheduler_for
    from ..report.build import input_files

    if args.scheduler is not None:  # checked before any config is read or any work starts
        problem = address_problem(args.scheduler)
        if problem is not None:
            raise ConfigError(f"--scheduler {problem}")
        args.scheduler = args.scheduler.strip()
    cfgs = [load_config(c) for c in args.config]
    out = Path(args.out)
    computes = {(c.scheduler, c.workers) for c in cfgs}
    if len(computes) > 1 and args.scheduler is None:
        raise ConfigError("the configs' [compute] sections differ (" + "; ".join(
            f"{c.path}: scheduler = {c.scheduler!r}, workers = {c.workers!r}" for c in cfgs) + "): a campaign runs "
            "on one scheduler; give --scheduler (and --workers), or the same [compute] in every config")
    address = args.scheduler or cfgs[0].scheduler
    workers = args.workers or cfgs[0].workers
    inputs = [p for cfg in cfgs for _, p in input_files(cfg)]
    # the folder is checked and locked before computing; the results replace it as a whole at the end
    with staged_folder(out, inputs=inputs) as stage:
        scheduler = scheduler_for(address, workers)
        try:
            runs = identify_campaign(cfgs, scheduler, progress=_say, errors=_user_errors() if len(cfgs) > 1 else ())
        finally:
            getattr(scheduler, "close", lambda: None)()
        names = campaign_names([c.path for c in cfgs])
        files = []
        for name, run in zip(names, runs, strict=True):
            if isinstance(run, Exception):
                continue
            if len(runs) > 1:
                print(f"\n=== {name} ({run.config.path}) ===")
            _print_run(run, "Validation, relative error ||Y - W X|| / ||Y||:")
            folder = stage if len(runs) == 1 else stage / name
            files += write_outputs(run, folder, f"Identification of {run.model.name}", progress=_say)
        if len(runs) > 1:
            head, rows = summary(names, runs)
            print(f"\nThe campaign ({len(runs)} identifications):\n{summary_text(head, rows)}")
            files.append(write_atomic(stage / SUMMARY_FILE, summary_csv(head, rows)))
    print(f"\nwrote {', '.join(str(out / f.relative_to(stage)) for f in files)}")
    failed = [(n, r) for n, r in zip(names, runs, strict=True) if isinstance(r, Exception)]
    for name, exc in failed:  # the others' results are written: a campaign is not lost to one broken file
        print(f"dynid: error: {name}: {final_text(str(exc))}", file=sys.stderr)
    return 2 if failed else 0


def cmd_demo(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    out = Path(args.out)
    _say(f"the demo: simulate the tests, write their files, identify, report into {out}")
    # the simulator first: a first run's kernel build, the critical path (pipeline.demo), forks before the rest of
    # the library is imported (0.24 s of CPU), which this process then imports beside it
    from ..vehicle.sim.car import prebuild_kernel  # start-up: the simulator, ~0.8 s (--help 0.1 s)

    first = prebuild_kernel()  # a first run: the simulator's kernel compiles on the other core while the vehicle loads
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..pipeline.demo import FIRST_RUN, run_demo
    from ..pipeline.run import write_outputs
    from ..vehicle import WHEELS

    # the library's objects, imported now, live as long as the run: out of the collector's full scans (a warm demo's
    # 0.11 s -> 0.02 s of CPU, 185k objects frozen; the forks of report.apart freeze the rest as they go); a caller's
    # process (main(argv) in tests) gets them back at the end, unless it had frozen objects itself
    ours = gc.get_freeze_count() == 0
    gc.freeze()
    try:
        if first:
            _say(FIRST_RUN)  # the vehicle's loading compiles too, silent otherwise
        if args.vehicle:  # a bad vehicle file is refused before the output folder is made
            from ..vehicle.description import load_vehicle  # start-up: the library, 1-5 s (--help 0.1 s)

            load_vehicle(args.vehicle)
        # everything (the logger files, the config, the results) is written into a staging folder swapped in at the end
        with staged_folder(out) as stage:
            run = run_demo(stage, quick=args.quick, seed=args.seed, progress=_say, simulation_progress=progress_bar,
                           vehicle=args.vehicle)
            _print_run(run, "Validation, relative error ||Y - W X|| / ||Y|| "
                            "(direct: sine, spiral, braking, lane change; cross: step steer, gentler braking):")
            r, tree = run.result, run.model.tree
            wheels = sum(tree.values.get(f"M{w}", 0.0) for w in WHEELS)
            m6, true_m6 = r.value("M6"), r.truth.get("M6")
            if true_m6:
                err = 100 * (m6 - true_m6) / (true_m6 + wheels)
                print(f"\nTotal mass: {m6 + wheels:.1f} kg estimated, {true_m6 + wheels:.1f} kg true ({err:+.2f} %)")
            write_outputs(run, stage, f"dynid demo: the simulated {tree.name}", progress=_say)
        print(f"\nwrote {out / 'report.html'}, {out / 'results.json'}, the figures, and the test files and "
              f"config in {out} (dynid identify {out / 'identify.toml'} reruns it) in {time.perf_counter() - t0:.1f} s")
        return 0
    finally:
        if ours:
            gc.unfreeze()


class _Parser(argparse.ArgumentParser):
    """argparse with its usage errors as every other error: one line, naming the option and where the help is
    (the sub-commands' parsers are of this class too: add_subparsers makes them of the parent's type)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"dynid: error: {self.prog}: {message}; `{self.prog} --help` lists the options\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="dynid", description=DESCRIPTION,
                                     usage="dynid [-h] [--version] [--debug] COMMAND ...",
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"dynid {__version__}",
                        help="print dynid's version and exit")
    parser.add_argument("--debug", action="store_true", help="on an unexpected error, show the whole traceback")
    # the commands are listed by the epilog (purpose and example side by side), not by argparse
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", help=argparse.SUPPRESS,
                                prog="dynid")
    model = command(
        sub, "model", help="robot models: show one, count or generate its symbolic models, import/export a URDF",
        description="A robot is a model file (TOML: the modified Denavit-Hartenberg table, the parameters and "
                    "the known values) or a shipped example: puma560, tx40, floating_tree. These commands print "
                    "it, count or generate its symbolic models, and read or write a URDF.",
        examples=["dynid model show tx40", "dynid model codegen tx40 --lang c --model idm --out gen",
                  "dynid model import panda.urdf --out panda.toml"])
    msub = model.add_subparsers(dest="model_command", required=True, metavar="SUBCOMMAND")
    show = command(
        msub, "show", help="print the MDH table, the parameters and the base parameters",
        description="Print a model's geometric table (MDH), its parameters (the file's values; * marks the known "
                    "ones) and its base parameters: the combinations an identification can estimate. With "
                    "--template, a vehicle template's instead.",
        examples=["dynid model show tx40", "dynid model show robot.toml",
                  f"dynid model show --template {CAR_TEMPLATE}"])
    show.add_argument("file", nargs="?", help="model file (TOML) or a shipped example: puma560, tx40, floating_tree")
    show.add_argument("--template", help=f"a vehicle template instead of a file: {CAR_TEMPLATE}")
    show.set_defaults(func=cmd_model_show)
    demo = command(
        sub, "demo", help=f"the paper's experiment on a simulated car ({DEMO_VEHICLE} by default), end to end",
        description="Simulate the paper's tests with a vehicle's sensor suite (seeded noise), write the logger "
                    "files and the identification config, identify the parameters and write the report, "
                    "results.json, the figures and CSV files. The output folder is replaced as a whole when the "
                    "run ends: an interrupted or failed run leaves the previous results as they were.",
        examples=["dynid demo --quick --out demo", "dynid demo --out demo --seed 7",
                  "dynid identify demo/identify.toml --out demo-rerun"],
        notes="The first run compiles the simulator's kernel (on the second core, while the car loads) and "
              "generates and compiles the car's and the identification's models: about 8 s more than a later run "
              "(measured on a loaded 2-core Xeon: 25.0 s of CPU against 11.6 s, the kernel's build on the other "
              "core, pipeline.demo.FIRST_RUN_S); later runs load them "
              "from the cache (DYNID_CACHE, default ~/.cache/dynid).")
    demo.add_argument("--out", default="dynid-demo", help="output folder, replaced as a whole at the end "
                                                          "(default: dynid-demo)")
    demo.add_argument("--quick", action="store_true", help="shorter tests (about half the driving)")
    demo.add_argument("--seed", type=int, default=406, help="seed of the sensor noise (default 406)")
    demo.add_argument("--vehicle", default=DEMO_VEHICLE,
                      help="a shipped vehicle (dynid vehicle list) or a vehicle file with a [truth] set "
                           f"(default: {DEMO_VEHICLE})")
    demo.set_defaults(func=cmd_demo)
    ident = command(
        sub, "identify", help="identify a model's parameters from measurement files, as a config describes them",
        description="Identify the parameters of a robot or a car from measurement files. The config (TOML) "
                    "names the model or vehicle, the tests (to identify on, or to validate with), the channels, "
                    "the conditioning and the method. Prints the estimates with their %σ and the validation "
                    "errors, and writes results.json, report.html, the figures and CSV files into the output "
                    "folder, which is replaced as a whole when the run ends: an interrupted or failed run leaves "
                    "the previous results as they were, and a second run into the same folder is refused.",
        examples=["dynid identify demo/identify.toml --out results", "dynid identify robot.toml --out robot-out",
                  "dynid identify empty.toml laden.toml --out campaign --scheduler local",
                  "dynid identify fleet/*.toml --out fleet-out --scheduler tcp://10.0.0.5:8786"],
        notes="docs/tutorial.md describes the config; `dynid demo` writes one to start from. docs/cluster.md: "
              "running on a laptop, a workstation's cores or a Dask cluster.")
    ident.add_argument("config", nargs="+", help="identification config (TOML); several make a campaign: one "
                                                 "output folder each inside --out, and campaign.csv across them")
    ident.add_argument("--out", default="dynid-out", help="output folder, replaced as a whole at the end "
                                                          "(default: dynid-out)")
    ident.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="where the segments run: \"local\" (a Dask LocalCluster on this machine) or a Dask "
                            "scheduler's address (tcp://host:8786; needs pip install distributed); default: the "
                            "config's [compute] scheduler, else this machine's threads")
    ident.add_argument("--workers", type=_positive_int, default=None, metavar="N",
                       help="threads, or a LocalCluster's worker processes (default: the config's, else 2); a remote "
                            "cluster has the workers it was started with")
    ident.set_defaults(func=cmd_identify)
    symbolic_cmds.register(msub)
    model_io_cmds.register(msub)
    simulate_cmds.register(sub)
    excite_cmds.register(sub)
    vehicle_cmds.register(sub)
    plan_cmds.register(sub)
    parser.epilog = overview(sub, order=("demo", "identify", "plan", "simulate", "excite", "model", "vehicle"))
    return parser


def _user_errors() -> tuple[type[Exception], ...]:
    """The errors that report bad input (files, configs, data) rather than a bug: one line, no traceback."""
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..estimation.errors import IdentificationError
    from ..io.errors import DataError, MissingDependencyError
    from ..model import ModelError
    from ..signals.errors import SignalError
    from ..symbolic.expr import SymbolicError
    from ..vehicle.sensors import SensorError
    from ..vehicle.sim.car import SimulationError
    from ..vehicle.sim.manoeuvres import ManoeuvreError

    return (ModelError, DataError, SignalError, IdentificationError, SymbolicError, OutputError, SimulationError,
            ManoeuvreError, SensorError, TextEncodingError, MissingDependencyError, UsageError)


# a write the file system refused for want of room: the fix, and the output named when the error names no file
_NO_ROOM = {errno.ENOSPC: "free space on that disk, or write elsewhere (--out)",
            errno.EDQUOT: "your disk quota is used up: free space, or write elsewhere (--out)",
            errno.EFBIG: "a file outgrew the largest size allowed there (the file system's limit, or the shell's "
                         "ulimit -f): write elsewhere (--out), or write shorter files"}


def _os_error_text(exc: OSError, out: object) -> str:
    """One line for a file system refusal: the file (or, for a write refused for want of room that names none, the
    output being written), what the system said, and the fix where there is one."""

    what = " ".join(str(exc.strerror or exc).split())
    fix = _NO_ROOM.get(exc.errno)
    name = exc.filename if exc.filename else (out if fix and out else None)
    where = f"{final_text(str(name))}: " if name else ""
    if fix:
        return f"{where}{what} while writing{'' if exc.filename or not out else ' the output'}; {fix}"
    return f"{where}{what}"


def _end_bars() -> None:
    report.close()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command `argv` (default: the process's arguments) and return its exit status. Without argv (the
    `dynid` command itself), a command that ends normally ends the process (`_leave`)."""
    code = _main(argv)
    if argv is None:
        _leave(code)
    return code


def _leave(code: int) -> None:
    """End the process now with `code`: the output flushed and the atexit handlers run, but not Python's teardown of
    every module and object, which the operating system's reclaiming of the memory makes pointless and which costs
    a warm `dynid demo` 0.3-0.4 s of CPU (1 core, 29 Nov: 4-5 % of the run). Only this process's thread left: another
    would be joined by the teardown."""
    if threading.active_count() != 1:
        return
    atexit._run_exitfuncs()
    try:
        if sys.stdout is not None and not sys.stdout.closed:  # None: started with its descriptor closed
            sys.stdout.flush()
    except BrokenPipeError:  # a pipe closed by its reader (`| head`): not an error, as in _main
        pass
    except OSError as exc:  # the last of the output lost (a full disk): said, as Python's teardown did
        what = " ".join(str(getattr(exc, "strerror", None) or exc).split())
        with contextlib.suppress(Exception):
            print(f"dynid: error: the command's output (stdout) could not be written: {what}", file=sys.stderr)
        code = code or 2
    with contextlib.suppress(Exception):  # closed, or gone: nothing more to show
        sys.stderr.flush()
    os._exit(code)


class _ReaderMayLeave:
    """stdout, but once its pipe's reader has gone (`dynid demo | head -1`: BrokenPipeError) the rest of the output
    goes to /dev/null and the command runs on: its files are its result. Before, the first print after the reader
    left stopped the run, its output folder removed, with exit status 0."""

    def __init__(self, stream) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._gone()
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._gone()

    def _gone(self) -> None:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, self._stream.fileno())  # what the stream still holds is written there
        finally:
            os.close(devnull)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


@contextlib.contextmanager
def _reader_may_leave():
    """sys.stdout as `_ReaderMayLeave` inside, where it is a stream on a file descriptor."""
    stream = sys.stdout
    try:
        usable = stream is not None and stream.fileno() >= 0
    except (AttributeError, OSError, ValueError):  # captured (no descriptor), or closed
        usable = False
    if not usable:
        yield
        return
    sys.stdout = _ReaderMayLeave(stream)
    try:
        yield
    finally:
        sys.stdout = stream


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        check_options(args)
        try:
            # a Ctrl-C while Numba compiles is not lost in LLVM's callbacks; a reader that leaves (`| head`) does
            # not stop the run
            with interrupts(), _reader_may_leave():
                return int(args.func(args) or 0)
        finally:  # a bar an error interrupted is ended (its line finished) before the error's line
            _end_bars()
    except _user_errors() as exc:
        print(f"dynid: error: {final_text(str(exc))}", file=sys.stderr)
        return 2
    except Terminated as exc:  # SIGTERM: the output folder kept its previous results, the temporaries removed
        print(f"dynid: {exc}", file=sys.stderr)
        return 128 + exc.signum
    except BrokenPipeError:  # output piped into `head` and closed early: not an error
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print("dynid: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        if args.debug:
            raise
        print("dynid: error: out of memory; shorten the test (start, end), decimate more, or use a machine with more "
              "memory (--debug shows where)", file=sys.stderr)
        return 2
    except OSError as exc:  # a file system refusal (full disk, read-only, a folder where a file is wanted)
        if args.debug:
            raise
        print(f"dynid: error: {_os_error_text(exc, getattr(args, 'out', None))} (--debug shows where)",
              file=sys.stderr)
        return 2
    except Exception as exc:  # a bug of dynid's: one line and the way to the traceback, never a raw one
        if args.debug:
            raise
        print(f"dynid: internal error: {type(exc).__name__}: {final_text(str(exc))[:300]}; rerun with --debug for the "
              "traceback and report it with the command you ran", file=sys.stderr)
        return 3


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

"""`dynid`: command-line entry point. Errors are printed as one clear line, never a traceback."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from .. import __version__
from ..model import ModelError, Tree

SIGMA = {0: "R", 1: "P", 2: "F"}


def format_table(tree: Tree) -> str:
    """The geometric table in SYMORO's layout (angles in degrees where that reads better)."""
    head = f"{'j':>3} {'a(j)':>4} {'sigma':>5} {'gamma':>9} {'b':>8} {'alpha':>9} {'d':>8} {'theta':>9} {'r':>8}"
    lines = [head]
    for f in tree.frames:
        th = f"q{f.j}" + (f"{np.degrees(f.theta):+.4g}°" if f.theta else "") if f.sigma == 0 else _deg(f.theta)
        r = f"q{f.j}" + (f"{f.r:+.4g}" if f.r else "") if f.sigma == 1 else f"{f.r:.4g}"
        lines.append(
            f"{f.j:>3} {f.ant:>4} {SIGMA[f.sigma]:>5} {_deg(f.gamma):>9} {f.b:>8.4g} {_deg(f.alpha):>9} "
            f"{f.d:>8.4g} {th:>9} {r:>8}"
        )
    return "\n".join(lines)


def _deg(a: float) -> str:
    return f"{np.degrees(a):.4g}°" if a else "0"


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
    from .. import load_model

    if args.template:
        from .vehicle_cmds import show_template

        print(show_template(args.template))
        return 0
    if not args.file:
        raise ModelError("give a model file (or a shipped example: puma560, tx40, floating_tree) or --template NAME")
    model = load_model(args.file)
    tree = model.tree
    print(f"{tree.name}: {tree.n} frames, {tree.p} parameters, gravity {list(tree.gravity)} m/s²\n")
    print(format_table(tree))
    print(f"\nParameters ({'* = known' if tree.known else 'values from the file'}):")
    print(format_parameters(tree))
    if tree.couplings:
        print("\nCouplings:")
        for c in tree.couplings:
            combo = " + ".join(f"{v:g}·q{j}" for j, v in c.coeffs.items())
            print(f"  {c.name}: {c.kind} on {combo}")
    print()
    print(model.base_parameters())
    return 0


def _say(msg: str) -> None:
    print(f"· {msg}", file=sys.stderr)


def _print_run(run, validation_title: str) -> None:
    """The tables of an identification, the published comparison if any, and the validation errors."""
    from ..report import validation_table

    print(run.summary())
    if run.reference:
        print("\nComparison with the published identification:")
        print(run.reference_table())
    print(f"\n{validation_title}")
    print(validation_table(run.errors, run.not_excited))


def cmd_identify(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..atomic import output_folder
    from ..pipeline.config import load_config
    from ..pipeline.run import identify, write_outputs

    cfg = load_config(args.config)
    output_folder(args.out)
    run = identify(cfg, progress=_say)
    _print_run(run, "Validation, relative error ||Y - W X|| / ||Y||:")
    files = write_outputs(run, Path(args.out), f"Identification of {run.model.name}", progress=_say)
    print(f"\nwrote {', '.join(str(f) for f in files)}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    from ..atomic import output_folder
    from ..pipeline.demo import run_demo
    from ..pipeline.run import write_outputs
    from ..vehicle import WHEELS
    from .simulate_cmds import progress_bar

    t0 = time.perf_counter()
    out = Path(args.out)
    if args.vehicle:  # a bad vehicle file is refused before the output folder is made
        from ..vehicle.description import load_vehicle

        load_vehicle(args.vehicle)
    output_folder(out)
    run = run_demo(out, quick=args.quick, seed=args.seed, progress=_say, simulation_progress=progress_bar,
                   vehicle=args.vehicle)
    _print_run(run, "Validation, relative error ||Y - W X|| / ||Y|| "
                    "(direct: sine, spiral, braking, lane change; cross: step steer, gentler braking):")
    r, tree = run.result, run.model.tree
    wheels = sum(tree.values.get(f"M{w}", 0.0) for w in WHEELS)
    m6, true_m6 = r.value("M6"), r.truth.get("M6")
    if true_m6:
        err = 100 * (m6 - true_m6) / (true_m6 + wheels)
        print(f"\nTotal mass: {m6 + wheels:.1f} kg estimated, {true_m6 + wheels:.1f} kg true ({err:+.2f} %)")
    write_outputs(run, out, f"dynid demo: the simulated {tree.name}", progress=_say)
    print(f"\nwrote {out / 'report.html'}, {out / 'results.json'}, the figures, and the test files and "
          f"config in {out} (dynid identify {out / 'identify.toml'} reruns it) in {time.perf_counter() - t0:.1f} s")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dynid", description=__doc__)
    parser.add_argument("--version", action="version", version=f"dynid {__version__}")
    parser.add_argument("--debug", action="store_true", help="on an unexpected error, show the whole traceback")
    sub = parser.add_subparsers(dest="command", required=True)
    model = sub.add_parser("model", help="describe and generate models of a tree")
    msub = model.add_subparsers(dest="model_command", required=True)
    show = msub.add_parser("show", help="print the MDH table, the parameters and the base parameters")
    show.add_argument("file", nargs="?", help="model file (TOML) or a shipped example: puma560, tx40, floating_tree")
    show.add_argument("--template", help="a vehicle template instead of a file: peugeot406")
    show.set_defaults(func=cmd_model_show)
    demo = sub.add_parser("demo", help="the paper's experiment on the simulated Peugeot 406, end to end",
                          description="Simulate the paper's tests with a vehicle's sensor suite, write the files "
                                      "and the config, identify and report. Example: dynid demo --out demo")
    demo.add_argument("--out", default="dynid-demo", help="output folder (default: dynid-demo)")
    demo.add_argument("--quick", action="store_true", help="shorter tests (about half the driving)")
    demo.add_argument("--seed", type=int, default=406, help="seed of the sensor noise (default 406)")
    demo.add_argument("--vehicle", default="peugeot406",
                      help="a shipped vehicle (dynid vehicle list) or a vehicle file with a [truth] set "
                           "(default: peugeot406)")
    demo.set_defaults(func=cmd_demo)
    ident = sub.add_parser("identify", help="identify the parameters of a model from measurement files")
    ident.add_argument("config", help="identification config (TOML)")
    ident.add_argument("--out", default="dynid-out", help="output folder (default: dynid-out)")
    ident.set_defaults(func=cmd_identify)
    from . import excite_cmds, model_io_cmds, simulate_cmds, symbolic_cmds, vehicle_cmds

    symbolic_cmds.register(msub)
    model_io_cmds.register(msub)
    simulate_cmds.register(sub)
    excite_cmds.register(sub)
    vehicle_cmds.register(sub)
    return parser


def _user_errors() -> tuple[type[Exception], ...]:
    """The errors that report bad input (files, configs, data) rather than a bug: one line, no traceback."""
    from ..atomic import OutputError
    from ..estimation.errors import IdentificationError
    from ..io.errors import DataError
    from ..signals.errors import SignalError
    from ..symbolic.expr import SymbolicError
    from ..vehicle.sim.recording import OutputError as SimulationOutputError

    return ModelError, DataError, SignalError, IdentificationError, SymbolicError, OutputError, SimulationOutputError


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except _user_errors() as exc:
        print(f"dynid: error: {exc}", file=sys.stderr)
        return 2
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
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"dynid: error: {where}{exc.strerror or exc} (--debug shows where)", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug of dynid's: one line and the way to the traceback, never a raw one
        if args.debug:
            raise
        print(f"dynid: internal error: {type(exc).__name__}: {str(exc)[:300]}; rerun with --debug for the "
              "traceback and report it with the command you ran", file=sys.stderr)
        return 3


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

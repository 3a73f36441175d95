"""`dynid model ops` and `dynid model codegen`: the symbolic layer on the command line."""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

from ..atomic import OutputError, add_force, refuse_overwrite
from .usage import UsageError, command

HELP_FILE = "model file (TOML) or a shipped example: puma560, tx40, floating_tree"


def register(model_subparsers: argparse._SubParsersAction) -> None:
    """Add `ops` and `codegen` to the `dynid model ...` sub-commands."""

    ops = command(model_subparsers, "ops", help="operation counts of the symbolic models (mult, add, functions)",
                  description="Build the symbolic models of a tree (geometric dgm, inverse dynamic idm, "
                              "identification regressor, inertia matrix) and print their operation counts "
                              "(multiplications, additions, functions), equations and build times.",
                  examples=["dynid model ops tx40", "dynid model ops robot.toml --geometry symbolic"])
    ops.add_argument("file", help=HELP_FILE)
    _common(ops)
    ops.set_defaults(func=cmd_ops)
    gen = command(model_subparsers, "codegen", help="generate a model as NumPy, C or readable equations",
                  description="Generate one symbolic model of a tree as code: a NumPy module, C (a header and a "
                              "source file) or readable equations, written into a folder.",
                  examples=["dynid model codegen tx40 --lang c --model idm --out gen",
                            "dynid model codegen robot.toml --lang numpy --model regressor --out gen"])
    gen.add_argument("file", help=HELP_FILE)
    gen.add_argument("--lang", choices=("numpy", "c", "text"), required=True,
                     help="numpy (a Python module), c (a .h and a .c file) or text (readable equations)")
    gen.add_argument("--model", choices=("idm", "regressor", "inertia", "dgm"), required=True,
                     help="idm (inverse dynamics: joint torques), regressor (the identification model: torques "
                          "linear in the parameters), inertia (the inertia matrix) or dgm (the geometric model: "
                          "frame poses)")
    gen.add_argument("--out", required=True, help="output directory (created if missing)")
    add_force(gen)
    gen.add_argument("--prefix", default=None, help="C function prefix / file stem (default: from the model name)")
    gen.add_argument("--block", action="store_true",
                     help="C: also <prefix>_<model>_block, the batch function with 8 samples side by side, "
                          "vectorised by the compiler (for models of a few thousand operations: a compiler takes "
                          "minutes on the full regressor of a 42-frame tree)")
    _common(gen)
    gen.set_defaults(func=cmd_codegen)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--geometry", choices=("numeric", "symbolic"), default="numeric",
                   help="geometric constants as numbers or as symbols (D3, RL4, ...)")
    p.add_argument("--rows", default=None, help="identification model rows: frame numbers, e.g. 1,2,3,9")
    p.add_argument("--cols", default=None, help="identification model columns: parameter names, e.g. XX6,M6,K9")


# frame-ancestor pairs the symbolic models are built for: their inertia matrix and regressor hold an entry per pair
# (a chain of n frames has n (n + 1) / 2: the time grows with its square; a star's n). A chain of 300 frames (45,150
# pairs) took 29 s of CPU for `model ops` on a loaded 2-core machine, of 1000 a RecursionError; a star of 1000
# frames, 2.5 s. A robot or the car has a few hundred pairs.
MAX_PAIRS = 20_000
# cells of the symbolic regressor (its rows x columns, before the zeros are dropped): a star of 1000 frames
# (1000 x 10,000) took 1.4 s of CPU, of 2000 frames 13 s (its time grows faster than its cells), of 10,000 more
# than 300 s of wall time; `model ops` builds it, `model codegen --model regressor` too (--rows, --cols cut it)
MAX_CELLS = 12_000_000


def _load(args: argparse.Namespace, command: str = ""):
    """The model's tree; with command (ops, codegen), refused with one line when its symbolic models would be too
    large (`MAX_PAIRS`)."""
    from ..dynamics import load_model  # start-up: the library, 1-5 s (--help 0.1 s)

    tree = load_model(args.file).tree
    if command:
        ant = [int(a) for a in tree.ant]
        depth = [0] * (tree.n + 1)
        for j in range(1, tree.n + 1):  # a frame's antecedent comes before it: one pass (no ancestor lists)
            depth[j] = depth[ant[j]] + 1
        pairs = sum(depth)
        if pairs > MAX_PAIRS:
            raise UsageError(
                f"model {command} {args.file}: {tree.name!r} has {tree.n} frames, {pairs:,} frame-ancestor pairs "
                f"(the inertia matrix and the regressor have an entry per pair: time and memory grow with them); the "
                f"symbolic models are built for up to {MAX_PAIRS:,} (a chain of 200 frames, about 15 s); describe a "
                "smaller tree, or use the numeric models (dynid.Model), which grow with the frames alone")
        if command == "ops" or args.model == "regressor":
            chosen = _rows_cols(args, tree)
            rows = len(chosen.get("rows", tree.equations))
            cols = len(chosen.get("cols", tree.parameter_names))
            if rows * cols > MAX_CELLS:
                raise UsageError(
                    f"model {command} {args.file}: the symbolic regressor of {tree.name!r} has {rows:,} rows x "
                    f"{cols:,} columns ({rows * cols:,} cells; time grows faster than them); it is built for up to "
                    f"{MAX_CELLS:,} (a star of 1000 frames, about 1.5 s): choose its rows and columns with --rows "
                    "and --cols, describe a smaller tree, or use the numeric models (dynid.Model)")
    return tree


def _is_column(tree, name: str) -> bool:
    from ..model import ModelError  # start-up: the library, 1-5 s (--help 0.1 s)

    try:
        tree.column(name)
    except ModelError:
        return False
    return True


def _rows_cols(args: argparse.Namespace, tree=None) -> dict:
    out: dict = {}
    if args.rows:
        try:
            out["rows"] = [int(x) for x in args.rows.split(",") if x.strip()]
        except ValueError:
            raise UsageError(f"--rows {args.rows}: give frame numbers separated by commas, like --rows 1,2,3") from None
        bad = [r for r in out["rows"] if tree is not None and not 1 <= r <= tree.n]
        if bad:
            raise UsageError(f"--rows {args.rows}: frame {bad[0]} is not in model {tree.name!r} (frames 1..{tree.n}); "
                             "give its frame numbers, like --rows 1,2,3")
    if args.cols:
        out["cols"] = [x.strip() for x in args.cols.split(",") if x.strip()]
        bad = [c for c in out["cols"] if tree is not None and not _is_column(tree, c)]
        if bad:
            raise UsageError(f"--cols {args.cols}: model {tree.name!r} has no parameter {bad[0]!r}; give "
                             f"parameter names, like --cols {','.join(tree.parameter_names[:3])}")
    return out


def cmd_ops(args: argparse.Namespace) -> int:
    from ..symbolic import SymbolicError, build  # start-up: the library, 1-5 s (--help 0.1 s)

    tree = _load(args, "ops")
    print(f"{tree.name}: {tree.n} frames, {tree.p} parameters; geometry {args.geometry}")
    print(f"{'model':<10} {'mult':>8} {'add':>8} {'functions':>10} {'equations':>10} {'time':>9}")
    try:
        for model in ("dgm", "idm", "regressor", "inertia"):
            opts = {"geometry": args.geometry}
            if model == "regressor":
                opts.update(_rows_cols(args, tree))
            t0 = time.perf_counter()
            prog = build(tree, model, **opts)
            dt = time.perf_counter() - t0
            c = prog.ops()
            print(f"{model:<10} {c.mult:>8} {c.add:>8} {c.func:>10} {len(prog.equations):>10} {dt * 1e3:>7.0f}ms")
    except SymbolicError as exc:
        print(f"dynid: error: {exc}", file=sys.stderr)
        return 2
    return 0


def cmd_codegen(args: argparse.Namespace) -> int:
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..symbolic import SymbolicError, build, model_hash, to_c, to_numpy, to_text
    from ..symbolic.cache import write_atomic  # start-up: the library, 1-5 s (--help 0.1 s)

    tree = _load(args, "codegen")
    opts = {"geometry": args.geometry}
    if args.model == "regressor":
        opts.update(_rows_cols(args, tree))
    stem = args.prefix or re.sub(r"[^0-9a-zA-Z]+", "_", tree.name).strip("_").lower() or "model"
    if not stem[0].isalpha():
        stem = "m_" + stem
    out = Path(args.out)
    try:
        prog = build(tree, args.model, **opts)
        if args.lang == "numpy":
            files = {f"{stem}_{args.model}.py": to_numpy(prog, tree, model_hash(tree, args.model, opts))}
        elif args.lang == "c":
            h, c = to_c(prog, prefix=stem, block=args.block)
            files = {f"{stem}_{args.model}.h": h, f"{stem}_{args.model}.c": c}
        else:
            files = {f"{stem}_{args.model}.txt": to_text(prog)}
        if out.exists() and not out.is_dir():
            raise OutputError(f"{out}: is a file, not a folder; give --out a folder (created if missing)")
        if out.is_dir():  # a new folder holds nothing to replace
            refuse_overwrite([out / name for name in files], args.force)
        for name, text in files.items():
            write_atomic(out / name, text)
    except SymbolicError as exc:
        print(f"dynid: error: {exc}", file=sys.stderr)
        return 2
    except OutputError as exc:
        print(f"dynid: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"dynid: error: cannot write to {out}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    for name in files:
        print(out / name)
    print(f"{args.model} of {tree.name}: {prog.ops()}")
    return 0

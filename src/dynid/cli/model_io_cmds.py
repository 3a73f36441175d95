"""`dynid model import` and `dynid model export`: a URDF into a model file, identified inertias back into the URDF."""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ..atomic import add_force, refuse_overwrite
from .usage import UsageError, command

if TYPE_CHECKING:  # the model layer (NumPy) is imported where used: `dynid --help` stays quick
    from ..model import Tree

_STANDARD = re.compile(r"^(XX|XY|XZ|YY|YZ|ZZ|MX|MY|MZ|M|IA|FV|FS|OFF|K)(\d+)$")


def register(model_subparsers: argparse._SubParsersAction) -> None:
    """Add `import` and `export` to the `dynid model ...` sub-commands."""

    imp = command(
        model_subparsers, "import", help="read a URDF into a model file (one MDH frame per moving joint)",
        description="Read a URDF (revolute, continuous, prismatic and fixed joints) into a model file: one MDH "
                    "frame per moving joint, named after it in [joints]; fixed joints' links are merged into "
                    "the body they are fixed to. Meshes are not read.",
        examples="dynid model import panda.urdf --out panda.toml")
    imp.add_argument("urdf", help="the URDF file (expanded, not .xacro), e.g. robot.urdf")
    imp.add_argument("--out", required=True, help="model file to write (TOML), e.g. --out robot.toml")
    imp.add_argument("--name", default=None, help="model name (default: the URDF's robot name), e.g. --name panda")
    imp.add_argument("--joints", default=None,
                     help="the identified chain: the moving joints to keep, comma-separated; every other one is "
                          "frozen (held still, at its --freeze value or 0) with the joints that mimic it, e.g. "
                          "--joints panda_joint1,panda_joint2,panda_joint3,panda_joint4,panda_joint5,panda_joint6,"
                          "panda_joint7")
    imp.add_argument("--freeze", default=None,
                     help="moving joints to hold still, comma-separated NAME or NAME=VALUE (rad or m, default 0), "
                          "merged into the body they hang from; a joint that mimics a frozen one follows it, e.g. "
                          "--freeze panda_finger_joint1=0.04")
    add_force(imp)
    imp.set_defaults(func=cmd_import)
    exp = command(
        model_subparsers, "export", help="write a parameter set into a URDF's inertials (mass, CoM, inertia)",
        description="Write the standard inertial parameters of a model (or of an identification) into a copy of "
                    "the URDF it was imported from; only <inertial> elements change. A set that no real body has "
                    "(mass <= 0, inertia at the CoM not positive definite, triangle inequality broken) is refused.",
        examples="dynid model export robot.toml --params out/results.json --urdf robot.urdf "
                 "--out robot_identified.urdf")
    exp.add_argument("model", help="the model file made by `dynid model import`, e.g. robot.toml")
    exp.add_argument("--params", default=None,
                     help="parameters to write (default: the model file's): an identification's results.json "
                          "(base parameters: each kept standard parameter takes the identified value less the "
                          "regrouped ones at the model's values), or a TOML with [parameters.N] tables or "
                          "NAME = value lines, e.g. --params out/results.json or --params params.toml")
    exp.add_argument("--urdf", required=True, help="the URDF the model was imported from, e.g. --urdf robot.urdf")
    exp.add_argument("--out", required=True, help="URDF to write (atomically), e.g. --out robot_identified.urdf")
    add_force(exp)
    exp.set_defaults(func=cmd_export)


def cmd_import(args: argparse.Namespace) -> int:
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..model import save_tree
    from ..model.urdf import import_urdf

    if args.name is not None and not args.name.strip():
        raise UsageError(f"--name {args.name!r}: give the model's name (text), or leave --name out to keep the URDF's")
    refuse_overwrite([args.out], args.force)
    freeze = _freeze_option(args.freeze, args.urdf)
    joints = None if args.joints is None else [j.strip() for j in args.joints.split(",") if j.strip()]
    imp = import_urdf(args.urdf, name=args.name, freeze=freeze, joints=joints)
    tree = imp.tree
    _write(lambda: save_tree(tree, args.out), args.out)
    moving = len(tree.joint_names)
    helpers = tree.n - moving
    merged = sum(len(v) for v in imp.merged.values())
    print(f"{args.urdf}: {tree.name}, {moving} moving joints"
          + (f", {helpers} fixed frame(s) inserted for nearly parallel offset axes" if helpers else "")
          + (f", {merged} link(s) merged through fixed joints" if merged else "")
          + (f", {len(tree.mimic)} mimic joint(s) following their master ("
             + ", ".join(f"{tree.joint_names[j]} = {m.ratio:g} {tree.joint_names[m.master]} + {m.offset:g}"
                         for j, m in sorted(tree.mimic.items())) + ")" if tree.mimic else "")
          + (f", frozen: {', '.join(f'{k} = {v:g}' for k, v in tree.frozen.items())}" if tree.frozen else ""))
    print(f"wrote {args.out} ({tree.n} frames, {tree.p} parameters)")
    for note in imp.notes:  # imported as given (published URDFs have them); the a priori values, not a result
        print(f"dynid: warning: {note}; imported as given: fix it in the URDF if it is to be trusted", file=sys.stderr)
    return 0


def _freeze_option(text: str | None, where: str) -> dict[str, float] | None:
    """--freeze a,b=0.01 -> {a: 0.0, b: 0.01}."""
    from ..model import ModelError  # start-up: the library, 1-5 s (--help 0.1 s)

    if text is None:
        return None
    out = {}
    for item in (x.strip() for x in text.split(",")):
        if not item:
            continue
        name, _, value = item.partition("=")
        try:
            out[name.strip()] = float(value) if value.strip() else 0.0
        except ValueError:
            raise ModelError(f"{where}: --freeze {item!r}: the value after = must be a number (rad or m), like "
                             f"--freeze {name.strip()}=0.04") from None
    return out


def cmd_export(args: argparse.Namespace) -> int:
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..dynamics import load_model
    from ..model import ModelError
    from ..model.urdf import export_urdf

    refuse_overwrite([args.out], args.force)
    tree = load_model(args.model).tree
    if not tree.joint_names:
        raise ModelError(f"{args.model}: has no [joints] table, so its frames cannot be matched to URDF joints; "
                         f"make it with dynid model import")
    plausible = _plausible(args.params, tree) if args.params else None
    if plausible is not None:
        values = plausible.values
    else:
        values = None if args.params is None else read_parameters(args.params, tree)
    what = args.params or args.model
    notes: list[str] = []
    _write(lambda: notes.extend(export_urdf(tree, args.urdf, args.out, values, what=what)), args.out)
    for note in notes:
        print(f"note: {note}")
    if plausible is not None:
        name, z = plausible.worst
        print(f"the standard set closest to {args.model} in each link's units that is physically plausible "
              f"(pseudo-inertia positive definite with a margin, centre of mass inside the link) reproduces the "
              f"estimate to chi-square {plausible.chi2:.3g} (σ² units; the base parameter moved most: {name}, "
              f"{z:+.2f} σ). How far each link moved from {args.model}:")
        for line in plausible.moves:
            print(f"  {line}")
        for line in plausible.warnings:
            print(f"warning: {line}: more than the file's 10 % prior; the data moved it there (weigh the link, or "
                  "excite it)")
    print(f"wrote {args.out} (inertials of {len(tree.joint_names)} links from {what})")
    return 0


def _plausible(params: str, tree: Tree):
    """For an identification's results.json (base parameters with their σ) and the pc extra installed: the
    physically plausible standard set closest to the model file (pipeline.run.plausible_export); else None."""
    p = Path(params)
    if p.suffix.lower() != ".json":
        return None
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
        import cvxpy  # noqa: F401  optional: cvxpy (the pc extra)
    except (OSError, json.JSONDecodeError, ImportError):
        return None  # read_parameters says what is wrong with the file; without cvxpy the exact regrouping
    if not isinstance(data, dict) or "base_parameters" not in data or not isinstance(data.get("parameters"), list):
        return None
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..dynamics import Model
    from ..estimation.errors import IdentificationError
    from ..model import ModelError
    from ..pipeline.run import plausible_export

    rows = [r for r in data["parameters"] if isinstance(r, dict) and "name" in r]
    values = {str(r["name"]): float(r["value"]) for r in rows}
    std = {str(r["name"]): float(r.get("std") or 0.0) for r in rows}
    base = Model(tree).base_parameters()
    if set(values) != set(base.names):
        return None  # read_parameters names the mismatch
    try:
        return plausible_export(tree, base, values, std)
    except IdentificationError as exc:
        raise ModelError(f"{params}: {exc}") from None


def _write(action, out: str) -> None:
    from ..model import ModelError  # start-up: the library, 1-5 s (--help 0.1 s)

    try:
        action()
    except OSError as exc:
        raise ModelError(f"{out}: cannot write ({exc.strerror})") from None


def read_parameters(path: str, tree: Tree) -> dict[str, float]:
    """Standard parameter values from a results.json (base parameters) or a TOML parameter file."""
    from ..model import ModelError  # start-up: the library, 1-5 s (--help 0.1 s)

    p = Path(path)
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except OSError as exc:
            raise ModelError(f"{p}: cannot read the parameters ({exc.strerror})") from None
        except json.JSONDecodeError as exc:
            raise ModelError(f"{p}: not valid JSON: {exc}") from None
        consistent = data.get("consistency", {}).get("wls_pc", {}) if isinstance(data, dict) else {}
        if isinstance(consistent, dict) and isinstance(consistent.get("standard_parameters"), dict):
            # a wls-pc run: the physically consistent standard set it found (its base values are the estimate)
            return _standard(consistent["standard_parameters"], tree, str(p))
        table = _json_table(data, p)
        if isinstance(data, dict) and "base_parameters" in data:
            return standard_from_base(tree, table, str(p))
        return _standard(table, tree, str(p))
    from ..model.files import parse_number, read_toml  # start-up: the library, 1-5 s (--help 0.1 s)

    data = read_toml(p, "parameter file", ModelError)
    if "frames" in data:  # a whole model file: its values
        from ..model.files import tree_from_dict  # start-up: the library, 1-5 s (--help 0.1 s)

        return dict(tree_from_dict(data, source=str(p)).values)
    table: dict[str, float] = {}
    for key, v in data.items():
        if key == "parameters" and isinstance(v, dict):
            for j, sect in v.items():
                if not isinstance(sect, dict) or not j.isdigit():
                    raise ModelError(f"{p}: [parameters.{j}]: sections are per frame number, like [parameters.3]")
                for k, x in sect.items():
                    table[f"{k}{j}"] = parse_number(x, f"{p}: [parameters.{j}] {k}")
        else:
            table[key] = parse_number(v, f"{p}: {key}")
    return _standard(table, tree, str(p))


def _json_table(data: object, p: Path) -> dict[str, float]:
    from ..model import ModelError  # start-up: the library, 1-5 s (--help 0.1 s)

    params = data.get("parameters") if isinstance(data, dict) else None
    if isinstance(params, list):
        out = {}
        for i, r in enumerate(params, start=1):
            if not isinstance(r, dict) or "name" not in r or not isinstance(r.get("value"), int | float):
                raise ModelError(f"{p}: parameters[{i}] needs a \"name\" and a numeric \"value\"")
            out[str(r["name"])] = float(r["value"])
        return out
    if isinstance(params, dict) and all(isinstance(v, int | float) for v in params.values()):
        return {str(k): float(v) for k, v in params.items()}
    raise ModelError(f"{p}: no \"parameters\" list of {{\"name\", \"value\"}} (as results.json has)")


def _standard(table: dict[str, float], tree: Tree, where: str) -> dict[str, float]:
    from ..model import ModelError  # start-up: the library, 1-5 s (--help 0.1 s)

    out = {}
    for k, v in table.items():
        try:
            out[tree.parameter_names[tree.column(k)]] = v
        except ModelError:
            raise ModelError(f"{where}: {k!r} is not a parameter of {tree.name!r} (names like XX1, MX3, M7)") from None
    return out


def standard_from_base(tree: Tree, base_values: dict[str, float], where: str) -> dict[str, float]:
    """A standard set that reproduces identified base parameters: X_B = X_1 + beta X_2, so each kept
    standard parameter X_1 takes X_B - beta X_2 with the regrouped X_2 at the model's (a priori) values.
    Only the inertial parameters are returned (a URDF has no joint terms)."""
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..dynamics import Model
    from ..model import ModelError

    base = Model(tree).base_parameters()  # as the identification computed it (deterministic samples)
    unknown = [k for k in base_values if k not in base.names]
    if unknown:
        raise ModelError(f"{where}: {unknown[0]!r} is not a base parameter of {tree.name!r}; this result was "
                         f"identified on another model (base parameters: {', '.join(base.names[:8])}, ...)")
    X = tree.parameters.copy()
    XB = base.values(X)
    for i, name in enumerate(base.names):
        XB[i] = base_values.get(name, XB[i])
    X2 = X[list(base.regrouped_columns)]
    X[list(base.columns)] = XB - base.beta @ X2
    names = tree.parameter_names
    return {names[i]: float(X[i]) for i in range(tree.p) if _is_inertial(names[i])}


def _is_inertial(name: str) -> bool:
    from ..model import INERTIAL  # start-up: the library, 1-5 s (--help 0.1 s)

    m = _STANDARD.match(name)
    return bool(m) and m.group(1) in INERTIAL


__all__ = ["read_parameters", "register", "standard_from_base"]

"""Model files: a TOML whose frame table reads like SYMORO's geometric table.

    name = "PUMA 560"
    gravity = [0.0, 0.0, -9.81]
    known = ["IA1"]                 # parameters taken as known, not identified

    #          j ant sigma gamma  b   alpha     d      theta  r
    frames = [[1, 0,  0,    0,    0,  0,        0,     0,     0],
              [2, 1,  0,    0,    0,  "-pi/2",  0,     0,     0]]

    [parameters.1]                  # per frame, by name; a joint term listed here
    ZZ = 0.35                       # (IA FV FS OFF K) is declared for that joint
    IA = 0.0

    [[couplings]]
    name = "karf"
    kind = "K"                      # K, IA, FV or FS
    coeffs = { 27 = 1.0, 36 = -1.0 }
    value = 19780.0

    [labels]
    K9 = "ks9"

    [joints]                        # frame number -> joint name (a URDF's), for data and exports
    1 = "shoulder_pan_joint"

    [mimic]                         # optional: frame number -> the joint it follows (a URDF <mimic>):
    9 = { follows = 8, ratio = 1.0, offset = 0.0 }   # q9 = ratio q8 + offset; no data column or equation

    [frozen]                        # URDF joints the import held still (merged, no frame): name = value
    panda_finger_joint1 = 0.0

    [friction]                      # optional: joint terms on every joint, and the Coulomb law
    all = ["FV", "FS"]              # among IA FV FS OFF, declared on every moving joint (value 0
                                    # unless [parameters.j] gives one; merged with its terms)
    shape = "tanh"                  # law of every FS term: "sign" (default), "tanh", "sigmoid"
    vs = 0.01                       # velocity scale (rad/s or m/s), > 0; tanh and sigmoid only
    joints = { 6 = { vs = 0.02 }, 1 = { shape = "sign" } }   # per frame: shape and/or vs

    [knees]                         # optional: the knees (v-, v+) of a joint's viscous curve
    9 = [-0.1, 0.1]                 # (FVPL FVPH FVNL FVNH in [parameters.9]; v- < 0 < v+, inf allowed)

(or on one line: friction = { all = ["FV", "FS"], shape = "tanh", vs = 0.01 }). The laws:
sign: FS sign(qd); tanh: FS tanh(qd / vs); sigmoid: FS (2 / (1 + exp(-qd / vs)) - 1), which
equals FS tanh(qd / (2 vs)): choose by the convention of the vs you have. A per-joint entry
takes the top-level shape when it names none, and the top-level vs when it names none and
its shape is not sign; a shape other than sign applies only to joints with an FS term.

Angles and lengths may be numbers or strings of arithmetic on numbers and `pi`. Lengths are in m
(each under 100 m: mm written for m is refused), gravity in m/s² (at most 50), parameters SI.
"""

from __future__ import annotations

import ast
import difflib
import math
import operator
import os
from collections.abc import Sequence
from pathlib import Path

from ..atomic import write_atomic
from ..pysource import parse
from ..textfiles import read_toml
from .tree import (
    COUPLING_KINDS,
    FIXED,
    FRICTION_SHAPES,
    INERTIAL,
    JOINT_TERMS,
    SIGN_LAW,
    Coupling,
    Frame,
    Mimic,
    ModelError,
    Tree,
)

COLUMNS = ("j", "ant", "sigma", "gamma", "b", "alpha", "d", "theta", "r")
_TOP_KEYS = {"name", "gravity", "known", "frames", "parameters", "couplings", "labels", "joints", "friction",
             "knees", "mimic", "frozen"}
_MIMIC_KEYS = ("follows", "ratio", "offset")
_FRICTION_KEYS = ("all", "shape", "vs", "joints")
_FRICTION_ALL = ("IA", "FV", "FS", "OFF")  # K (stiffness) on every joint is rare: per joint only
_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv}


def did_you_mean(name: object, valid: Sequence[str]) -> str:
    """The hint " did you mean 'x'?" for the nearest of `valid` (difflib), or "" when none is close."""
    close = difflib.get_close_matches(str(name), list(valid), n=1)
    return f" did you mean {close[0]!r}?" if close else ""


def unknown_keys(keys: Sequence[object], valid: Sequence[str], what: str = "key",
                 notes: dict[str, str] | None = None) -> str:
    """The message for keys that are not among `valid`: "unknown key 'know'; did you mean 'known'? valid keys:
    ...". `notes` explain keys valid elsewhere (a robot's key in a car's section) instead of a guess."""
    notes = notes or {}
    whats = {"quantity": "quantities"}.get(what, what + "s")
    listing = f"valid {whats}: {', '.join(sorted(valid))}"
    hints = [(k, f" ({notes[k]})" if k in notes else did_you_mean(k, valid)) for k in keys]
    if len(hints) == 1:
        k, hint = hints[0]
        return f"unknown {what} {k!r}{';' + hint if hint.startswith(' did') else hint + ';'} {listing}"
    items = ", ".join(f"{k!r}{' (' + hint.strip() + ')' if hint.startswith(' did') else hint}" for k, hint in hints)
    return f"unknown {whats} {items}; {listing}"


def load_tree(path: str | os.PathLike[str]) -> Tree:
    """Read a model file; errors name the file, the frame and the field."""
    return tree_from_dict(read_toml(path, "model file", ModelError), source=str(path))


# a priori values that no physical body or joint can have below zero (moments of inertia about any axis,
# mass, rotor inertia, friction); products of inertia, first moments and offsets take either sign
_NONNEGATIVE = {"XX": "a moment of inertia", "YY": "a moment of inertia", "ZZ": "a moment of inertia",
                "M": "a mass", "IA": "a rotor inertia", "FV": "viscous friction", "FS": "Coulomb friction"}
# lengths beyond this are a unit slip (mm written for m: d = 300), and they wreck the base-parameter analysis's
# precision (1e8 m once gave 4 base parameters instead of 17); no robot arm or car spans 100 m
MAX_LENGTH_M = 100.0
MAX_PARAMETER = 1e9  # the same bound as a config's known values
# m/s^2: gravity beyond this is a unit slip (mm/s^2: -9810, or -9.81e6); the Earth's is 9.81, Jupiter's 24.8
MAX_GRAVITY = 50.0


def tree_from_dict(data: dict, source: str = "<dict>") -> Tree:
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise ModelError(f"{source}: unknown top-level key(s) {sorted(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    if "frames" not in data:
        raise ModelError(f"{source}: no 'frames' table (rows [j, ant, sigma, gamma, b, alpha, d, theta, r])")
    for key, kind, example in (("frames", list, "frames = [[1, 0, 0, 0, 0, 0, 0, 0, 0]]"),
                               ("parameters", dict, "[parameters.1] with ZZ = 0.3"),
                               ("couplings", list, "[[couplings]] tables"), ("labels", dict, "[labels] K9 = \"ks9\""),
                               ("known", list, "known = [\"IA1\"]"), ("gravity", list, "gravity = [0, 0, -9.81]"),
                               ("name", str, "name = \"my robot\"")):
        if key in data and not isinstance(data[key], kind):
            raise ModelError(f"{source}: {key} = {_short(data[key])}; expected {example}")
    if not all(isinstance(c, dict) for c in data.get("couplings", [])):
        raise ModelError(f"{source}: couplings: each is a [[couplings]] table with name, kind, coeffs")
    if not all(isinstance(k, str) for k in data.get("known", [])):
        raise ModelError(f"{source}: known = {_short(data['known'])}; expected names: known = [\"IA1\"]")
    if not all(isinstance(v, str) for v in data.get("labels", {}).values()):
        raise ModelError(f"{source}: [labels] values are names, like K9 = \"ks9\"")
    if not data["frames"]:
        raise ModelError(f"{source}: frames = []: give one row [j, ant, sigma, gamma, b, alpha, d, theta, r] per "
                         "frame, like frames = [[1, 0, 0, 0, 0, 0, 0, 0, 0]]")
    frames = []
    for i, row in enumerate(data["frames"], start=1):
        if not isinstance(row, list) or len(row) != len(COLUMNS):
            raise ModelError(
                f"{source}: frames row {i} must list the {len(COLUMNS)} columns {', '.join(COLUMNS)}; got {row!r}"
            )
        vals = {}
        for col, v in zip(COLUMNS, row, strict=True):
            where = f"{source}: frame {row[0]}, column {col}"
            if col in ("j", "ant", "sigma"):
                if not isinstance(v, int) or isinstance(v, bool):
                    raise ModelError(f"{where}: expected an integer, got {v!r}")
                vals[col] = v
            else:
                vals[col] = parse_number(v, where)
                if col in ("b", "d", "r") and abs(vals[col]) > MAX_LENGTH_M:
                    raise ModelError(f"{where}: {vals[col]:g} m; lengths are in metres and a link is shorter than "
                                     f"{MAX_LENGTH_M:g} m (a unit slip? {vals[col]:g} mm is "
                                     f"{vals[col] / 1000:g} m)")
        frames.append(Frame(**vals))

    joint_terms: dict[int, tuple[str, ...]] = {}
    values: dict[str, float] = {}
    for key, table in data.get("parameters", {}).items():
        where = f"{source}: [parameters.{key}]"
        if not key.isdigit() or not isinstance(table, dict):
            raise ModelError(f"{where}: sections are per frame number, like [parameters.3]")
        j = int(key)
        if not 1 <= j <= len(frames):
            raise ModelError(f"{where}: frame {j} does not exist (the table has frames 1..{len(frames)})")
        bad = [k for k in table if k not in INERTIAL and k not in JOINT_TERMS]
        if bad:
            raise ModelError(
                f"{where}: unknown parameter(s) {bad}; per frame: {' '.join(INERTIAL)} {' '.join(JOINT_TERMS)}"
            )
        terms = tuple(t for t in JOINT_TERMS if t in table)
        if terms:
            joint_terms[j] = terms
        for k, v in table.items():
            values[f"{k}{j}"] = parse_number(v, f"{where} {k}")
            if abs(values[f"{k}{j}"]) > MAX_PARAMETER:  # no arm or car has these: a unit or exponent slip
                raise ModelError(f"{where}: {k} = {values[f'{k}{j}']:g}; parameters are in SI units (kg, kg.m², "
                                 f"N.m.s/rad, ...) and within ±{MAX_PARAMETER:g}")
            if k in _NONNEGATIVE and values[f"{k}{j}"] < 0:  # no body or joint has these below zero
                raise ModelError(f"{where}: {k} = {values[f'{k}{j}']:g} < 0; {_NONNEGATIVE[k]} cannot be negative "
                                 "(a sign or unit slip?)")

    couplings = []
    for i, c in enumerate(data.get("couplings", []), start=1):
        where = f"{source}: coupling {i}"
        missing = {"name", "kind", "coeffs"} - set(c)
        if missing:
            raise ModelError(f"{where}: missing {sorted(missing)}")
        extra = set(c) - {"name", "kind", "coeffs", "value"}
        if extra:
            raise ModelError(f"{where}: unknown key(s) {sorted(extra)}")
        if c["kind"] not in COUPLING_KINDS:
            raise ModelError(f"{where}: kind {c['kind']!r} must be one of {COUPLING_KINDS}")
        if not isinstance(c["coeffs"], dict) or not isinstance(c["name"], str):
            raise ModelError(f"{where}: name is a string and coeffs a table of joint = coefficient, like "
                             "coeffs = { 27 = 1.0, 36 = -1.0 }")
        if not c["coeffs"]:
            raise ModelError(f"{where}: coeffs = {{}}: give the joints it combines, like coeffs = {{ 27 = 1.0, "
                             "36 = -1.0 }")
        coeffs = {}
        for k, v in c["coeffs"].items():
            if not k.isdigit():
                raise ModelError(f"{where}: coeffs keys are joint numbers, got {k!r}")
            coeffs[int(k)] = parse_number(v, f"{where} coeff {k}")
        couplings.append(Coupling(c["name"], c["kind"], coeffs))
        if "value" in c:
            values[c["name"]] = parse_number(c["value"], f"{where} value")

    friction = data.get("friction", {})
    if not isinstance(friction, dict):
        raise ModelError(f"{source}: friction = {_short(friction)}; expected a table, like "
                         "friction = { all = [\"FV\", \"FS\"], shape = \"tanh\", vs = 0.01 }")
    everywhere = _friction_all(friction, source)
    for j in (f.j for f in frames if f.sigma != FIXED):  # `all`: the same terms on every moving joint
        merged = set(joint_terms.get(j, ())) | set(everywhere)
        if merged:
            joint_terms[j] = tuple(t for t in JOINT_TERMS if t in merged)
    friction_shape = _friction_shapes(friction, joint_terms, frames, source)

    joint_names = _joint_names(data.get("joints", {}), len(frames), source)
    knees = _knees(data.get("knees", {}), source)
    mimic = _mimic(data.get("mimic", {}), len(frames), source)
    frozen = data.get("frozen", {})
    if not isinstance(frozen, dict):
        raise ModelError(f"{source}: [frozen] must be a table of joint name = value (rad or m)")
    frozen = {str(k): parse_number(v, f"{source}: [frozen] {k}") for k, v in frozen.items()}
    gravity = data.get("gravity", [0.0, 0.0, -9.81])
    if not isinstance(gravity, list) or len(gravity) != 3:
        raise ModelError(f"{source}: gravity must be a list of 3 numbers")
    g = [parse_number(x, f"{source}: gravity") for x in gravity]
    if math.hypot(*g) > MAX_GRAVITY:
        raise ModelError(f"{source}: gravity = {_short(gravity)} is {math.hypot(*g):g} m/s²; give it in m/s², at most "
                         f"{MAX_GRAVITY:g} (the Earth's: [0, 0, -9.81] with z up)")
    try:
        return Tree(
            name=str(data.get("name", Path(source).stem)),
            frames=tuple(frames),
            joint_terms=joint_terms,
            couplings=tuple(couplings),
            values=values,
            known=frozenset(data.get("known", [])),
            labels=dict(data.get("labels", {})),
            gravity=tuple(g),
            joint_names=joint_names,
            friction_shape=friction_shape,
            knees=knees,
            mimic=mimic,
            frozen=frozen,
        )
    except ModelError as exc:
        raise ModelError(f"{source}: {exc}") from None


def _friction_all(friction: dict, source: str) -> tuple[str, ...]:
    """The terms of friction.all, checked."""
    unknown = [k for k in friction if k not in _FRICTION_KEYS]
    if unknown:
        raise ModelError(f"{source}: friction: {unknown_keys(unknown, _FRICTION_KEYS)}")
    terms = friction.get("all", [])
    if not isinstance(terms, list) or not all(isinstance(t, str) for t in terms):
        raise ModelError(f"{source}: friction.all = {_short(terms)}; expected term names, like all = [\"FV\", \"FS\"]")
    for t in terms:
        if t not in _FRICTION_ALL:
            note = {"K": "a stiffness: declare it per joint in [parameters.j]"}
            if t.upper() in _FRICTION_ALL:  # difflib finds no match for a case slip of two letters
                note[t] = f"did you mean {t.upper()!r}?"
            raise ModelError(f"{source}: friction.all: {unknown_keys([t], _FRICTION_ALL, 'term', note)}")
    return tuple(terms)


def _friction_law(table: dict, default: tuple[str, object], where: str) -> tuple[str, float]:
    """(shape, vs) from a table with optional shape and vs. `default`: the (shape, vs) that what the table
    leaves out is taken from (vs None: none given); the sign law takes no vs."""
    shape = table.get("shape", default[0])
    if not isinstance(shape, str) or shape not in FRICTION_SHAPES:
        hint = did_you_mean(shape, FRICTION_SHAPES)
        raise ModelError(f"{where}: shape = {_short(shape)} is not a friction law;{hint} "
                         f"use one of {', '.join(FRICTION_SHAPES)}")
    if "vs" in table:
        if shape == "sign":
            raise ModelError(f"{where}: vs = {_short(table['vs'])} given for shape \"sign\", which has no velocity "
                             "scale (remove vs, or choose shape = \"tanh\" or \"sigmoid\")")
        vs = parse_number(table["vs"], f"{where}: vs")
    elif shape == "sign":
        return SIGN_LAW
    elif default[1] is None:
        raise ModelError(f"{where}: shape = \"{shape}\" needs vs, its velocity scale (> 0, rad/s or m/s), "
                         "like vs = 0.01")
    else:
        vs = float(default[1])  # type: ignore[arg-type]
    if not vs > 0.0:
        raise ModelError(f"{where}: vs = {vs:g}; the velocity scale of a {shape} law must be > 0 (rad/s or m/s)")
    return shape, vs


def _friction_shapes(friction: dict, joint_terms: dict[int, tuple[str, ...]], frames: list[Frame],
                     source: str) -> dict[int, tuple[str, float]]:
    """Frame -> (shape, vs) for the FS terms whose law is not sign."""
    where = f"{source}: friction"
    top = _friction_law({k: v for k, v in friction.items() if k in ("shape", "vs")}, ("sign", None), where)
    default = (top[0], top[1] if top[0] != "sign" else None)
    laws = {j: top for j, terms in joint_terms.items() if "FS" in terms}
    overrides = friction.get("joints", {})
    if not isinstance(overrides, dict) or not all(isinstance(v, dict) for v in overrides.values()):
        raise ModelError(f"{where}.joints must be a table of frame number = {{ shape, vs }}, like "
                         "joints = { 6 = { shape = \"tanh\", vs = 0.02 } }")
    for key, table in overrides.items():
        w = f"{where}.joints.{key}"
        if not key.strip().isdigit():
            raise ModelError(f"{w}: keys are frame numbers (1..{len(frames)}), like 6 = {{ vs = 0.02 }}")
        j = int(key)
        if not 1 <= j <= len(frames):
            raise ModelError(f"{w}: frame {j} does not exist (the table has frames 1..{len(frames)})")
        unknown = [k for k in table if k not in ("shape", "vs")]
        if unknown:
            raise ModelError(f"{w}: {unknown_keys(unknown, ('shape', 'vs'))}")
        if "FS" not in joint_terms.get(j, ()):
            raise ModelError(f"{w}: frame {j} has no Coulomb term FS for the law to apply to (declare FS in "
                             f"friction.all or [parameters.{j}])")
        laws[j] = _friction_law(table, default, w)
    return {j: law for j, law in sorted(laws.items()) if law[0] != "sign"}


def _knees(table: object, source: str) -> dict[int, tuple[float, float]]:
    """The [knees] table: frame number -> [v-, v+] (Tree.knees checks the values against the joint terms)."""
    where = f"{source}: [knees]"
    if not isinstance(table, dict):
        raise ModelError(f"{where} must be a table of frame number = [v-, v+], like 9 = [-0.1, 0.1]")
    out: dict[int, tuple[float, float]] = {}
    for key, v in table.items():
        if not key.strip().isdigit():
            raise ModelError(f"{where}: keys are frame numbers, like 9 = [-0.1, 0.1]; got {key!r}")
        if not isinstance(v, list) or len(v) != 2 or any(isinstance(x, bool) or not isinstance(x, int | float)
                                                         for x in v):
            raise ModelError(f"{where}: {key} = {_short(v)}; give [v-, v+], two numbers with v- < 0 < v+ (m/s or "
                             "rad/s; inf for no knee), like [-0.1, 0.1]")
        out[int(key)] = (float(v[0]), float(v[1]))
    return out


def _joint_names(table: object, n: int, source: str) -> dict[int, str]:
    """The [joints] table: frame number -> joint name, each frame and each name at most once."""
    if not isinstance(table, dict):
        raise ModelError(f"{source}: [joints] must be a table of frame number = \"joint name\", like 1 = \"joint1\"")
    out: dict[int, str] = {}
    seen: dict[str, int] = {}
    for key, name in table.items():
        where = f"{source}: [joints] {key}"
        if not key.strip().isdigit():
            raise ModelError(f"{where}: keys are frame numbers (1..{n}), like 1 = \"joint1\"")
        j = int(key)
        if not 1 <= j <= n:
            raise ModelError(f"{where}: frame {j} does not exist (the table has frames 1..{n})")
        if not isinstance(name, str) or not name:
            raise ModelError(f"{where}: the joint name must be a non-empty string, got {name!r}")
        if name in seen:
            raise ModelError(f"{where}: {name!r} already names frame {seen[name]}")
        if j in out:
            raise ModelError(f"{where}: frame {j} is named twice")
        out[j], seen[name] = name, j
    return out


def _mimic(table: object, n: int, source: str) -> dict[int, Mimic]:
    """The [mimic] table: frame number -> { follows = master frame, ratio = 1.0, offset = 0.0 }."""
    example = "9 = { follows = 8, ratio = 1.0, offset = 0.0 }"
    if not isinstance(table, dict):
        raise ModelError(f"{source}: [mimic] must be a table of frame number = {{ follows, ratio, offset }}, like "
                         f"{example}")
    out: dict[int, Mimic] = {}
    for key, entry in table.items():
        where = f"{source}: [mimic] {key}"
        if not key.strip().isdigit() or not 1 <= int(key) <= n:
            raise ModelError(f"{where}: keys are frame numbers (1..{n}), like {example}")
        if not isinstance(entry, dict) or "follows" not in entry:
            raise ModelError(f"{where}: expected {{ follows = frame number, ratio, offset }}, like {example}")
        unknown = [k for k in entry if k not in _MIMIC_KEYS]
        if unknown:
            raise ModelError(f"{where}: {unknown_keys(unknown, _MIMIC_KEYS)}")
        master = entry["follows"]
        if isinstance(master, bool) or not isinstance(master, int):
            raise ModelError(f"{where}: follows = {_short(master)}; give the frame number of the joint it follows")
        out[int(key)] = Mimic(master, parse_number(entry.get("ratio", 1.0), f"{where} ratio"),
                              parse_number(entry.get("offset", 0.0), f"{where} offset"))
    return out


def save_tree(tree: Tree, path: str | os.PathLike[str]) -> None:
    """Write a model file atomically (a crash never leaves half a file)."""
    write_atomic(path, tree_to_toml(tree))


def tree_to_toml(tree: Tree) -> str:
    if tree.load_terms:  # a load term's column is an application's (model.tree): a model file cannot say which wrench
        raise ModelError(f"model {tree.name!r} has load terms on frames {sorted(tree.load_terms)} (a car's "
                         "tire_lateral_force): a model file holds none; save the tree without them")
    lines = [f"name = {_q(tree.name)}", f"gravity = [{', '.join(_fmt(g) for g in tree.gravity)}]"]
    if tree.known:
        lines.append("known = [" + ", ".join(_q(k) for k in tree.parameter_names if k in tree.known) + "]")
    lines += ["", "#  j, ant, sigma, gamma, b, alpha, d, theta, r", "frames = ["]
    for f in tree.frames:
        cells = [str(f.j), str(f.ant), str(f.sigma)] + [_fmt(getattr(f, c)) for c in COLUMNS[3:]]
        lines.append("  [" + ", ".join(cells) + "],")
    lines.append("]")
    lines += _friction_lines(tree)
    for f in tree.frames:
        entries = [(k, tree.values.get(f"{k}{f.j}", 0.0)) for k in INERTIAL]
        entries = [(k, v) for k, v in entries if v != 0.0]
        entries += [(t, tree.values.get(f"{t}{f.j}", 0.0)) for t in tree.joint_terms.get(f.j, ())]
        if entries:
            lines += ["", f"[parameters.{f.j}]"] + [f"{k} = {_fmt(v)}" for k, v in entries]
    for c in tree.couplings:
        coeffs = ", ".join(f"{j} = {_fmt(v)}" for j, v in c.coeffs.items())
        lines += ["", "[[couplings]]", f"name = {_q(c.name)}", f"kind = {_q(c.kind)}",
                  f"coeffs = {{ {coeffs} }}", f"value = {_fmt(tree.values.get(c.name, 0.0))}"]
    if tree.labels:
        lines += ["", "[labels]"] + [f"{k} = {_q(v)}" for k, v in tree.labels.items()]
    if tree.joint_names:
        lines += ["", "[joints]"] + [f"{j} = {_q(v)}" for j, v in sorted(tree.joint_names.items())]
    if tree.knees:
        lines += ["", "[knees]"] + [f"{j} = [{lo!r}, {hi!r}]" for j, (lo, hi) in sorted(tree.knees.items())]
    if tree.mimic:
        lines += ["", "[mimic]"] + [f"{j} = {{ follows = {m.master}, ratio = {m.ratio!r}, offset = {m.offset!r} }}"
                                    for j, m in sorted(tree.mimic.items())]
    if tree.frozen:
        lines += ["", "[frozen]"] + [f"{_q(k)} = {v!r}" for k, v in tree.frozen.items()]
    return "\n".join(lines) + "\n"


def _friction_lines(tree: Tree) -> list[str]:
    """The [friction] section of the laws that are not sign: one shape and vs when every FS term shares
    them, else one entry per joint (the terms themselves are written in [parameters.j])."""
    fs = [j for j, terms in sorted(tree.joint_terms.items()) if "FS" in terms]
    laws = {j: tree.friction_law(j) for j in fs}
    shared = set(laws.values())
    if not tree.friction_shape:
        return []
    if len(shared) == 1:
        shape, vs = shared.pop()
        return ["", "[friction]", f"shape = {_q(shape)}", f"vs = {vs!r}"]
    entries = [f"{j} = {{ shape = {_q(s)}, vs = {vs!r} }}" for j, (s, vs) in sorted(tree.friction_shape.items())]
    return ["", "[friction.joints]", *entries]


def _q(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _fmt(v: float) -> str:
    """A float as TOML, as a multiple of pi where that is exact."""
    if v != 0.0:
        for m in (1, 2, 3, 4, 6, 12):
            k = round(v * m / math.pi)
            if k != 0 and abs(k) <= 4 * m:
                s = ("-" if k < 0 else "") + (f"{abs(k)}*pi" if abs(k) != 1 else "pi") + (f"/{m}" if m > 1 else "")
                if parse_number(s, "") == v:
                    return _q(s)
    return repr(float(v))


def parse_number(v: object, where: str) -> float:
    if isinstance(v, bool):
        raise ModelError(f"{where}: expected a number, got {v!r}")
    x = None
    try:
        if isinstance(v, int | float):
            x = float(v)
        elif isinstance(v, str) and len(v) <= _MAX_EXPRESSION:  # a bound: ast recursion and huge literals
            x = float(_eval(parse(v.strip(), mode="eval").body))
    except (SyntaxError, ValueError, ZeroDivisionError, KeyError, TypeError, OverflowError, RecursionError,
            MemoryError):
        x = None
    if x is not None and not math.isfinite(x):
        raise ModelError(f"{where}: {_short(v)} is not a finite number")
    if x is None:
        raise ModelError(f"{where}: expected a number or arithmetic on numbers and pi (at most {_MAX_EXPRESSION} "
                         f"characters), got {_short(v)}")
    return x


_MAX_EXPRESSION = 200


def _short(v: object) -> str:
    text = repr(v)
    return text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"


def _eval(node: ast.AST) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        return node.value
    if isinstance(node, ast.Name) and node.id == "pi":
        return math.pi
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        x = _eval(node.operand)
        return -x if isinstance(node.op, ast.USub) else x
    if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
        return _OPS[type(node.op)](_eval(node.left), _eval(node.right))
    raise ValueError("not arithmetic")

"""Physical consistency of inertial parameters: can a real body have them?

A set XX XY XZ YY YZ ZZ MX MY MZ M (about the origin of frame j, in frame j, Khalil's
order; XY etc. are entries of the inertia matrix, i.e. minus the products of inertia)
belongs to a physical body if and only if

  1. the mass is positive, M > 0;
  2. the inertia matrix at the centre of mass, J_G = J_O - M (|c|^2 I - c c^T) with
     c = (MX, MY, MZ) / M, is positive definite;
  3. its principal moments satisfy the triangle inequalities I_a <= I_b + I_c: a mass
     distribution has I_a = int(r_b^2 + r_c^2) dm, and int r_a^2 dm >= 0 for every axis.

(1)-(3) together are equivalent to a positive definite pseudo-inertia matrix. The
estimation layer uses this check on identified values, the vehicle layer on its sets.

A robot's joint terms add: rotor inertia IA, viscous FV and Coulomb FS friction are >= 0
(`check_joint_terms`; couplings of those kinds too). On a regrouped (base) set only some
conditions can be read directly (`check_base_singletons`): those on a base parameter that is a
standard one alone; the rest needs a standard set reproducing the base values
(`estimation.physical.feasible_standard`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .tree import INERTIAL, Tree

_AXES = ("x", "y", "z")
_NAME = re.compile(r"^(XX|XY|XZ|YY|YZ|ZZ|MX|MY|MZ|M)(\d+)$")


@dataclass(frozen=True)
class Violation:
    """One failed condition: the body (frame number), which condition, a readable message, the numbers."""

    body: int
    condition: str  # "mass", "positive definite" or "triangle"
    message: str
    numbers: dict[str, float] = field(default_factory=dict)

    def __str__(self) -> str:
        return self.message


def inertia_at_com(p: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(J_G (3, 3), c (3,)) from the 10 parameters of one body (mass must be nonzero)."""
    XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M = (float(v) for v in p)
    J = np.array([[XX, XY, XZ], [XY, YY, YZ], [XZ, YZ, ZZ]])
    c = np.array([MX, MY, MZ]) / M
    return J - M * (c @ c * np.eye(3) - np.outer(c, c)), c


def check_body(p: Sequence[float], body: int, rtol: float = 1e-9) -> list[Violation]:
    """Violations of one body's 10 parameters (XX XY XZ YY YZ ZZ MX MY MZ M), empty if realisable.

    rtol: tolerance relative to the largest principal moment, so that round-off on a body
    that is exactly on the boundary (a thin rod, a flat plate) is not reported.
    """
    p = np.asarray(p, dtype=float)
    if p.shape != (10,):
        raise ValueError(f"body {body}: expected 10 inertial parameters {INERTIAL}, got shape {p.shape}")
    M = p[9]
    if not M > 0.0:
        return [Violation(body, "mass", f"body {body}: mass M{body} = {M:.6g} kg is not positive", {"M": M})]
    JG, c = inertia_at_com(p)
    lam, vec = np.linalg.eigh(JG)
    scale = max(float(np.abs(lam).max()), np.finfo(float).tiny)
    tol = rtol * scale
    out: list[Violation] = []
    at = f"at the centre of mass ({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g}) m in frame {body}"
    moments = ", ".join(f"{v:.6g}" for v in lam)
    if lam[0] <= tol:
        out.append(Violation(
            body, "positive definite",
            f"body {body}: inertia {at} is not positive definite: principal moments ({moments}) kg·m²",
            {"min_principal_moment": float(lam[0])},
        ))
    for a in range(3):
        others = lam.sum() - lam[a]
        if lam[a] > others + tol:
            axis = int(np.argmax(np.abs(vec[:, a])))
            name = f"{_AXES[axis].upper() * 2}{body}"
            out.append(Violation(
                body, "triangle",
                f"body {body}: triangle inequality violated: the principal moment {lam[a]:.6g} kg·m² "
                f"about the axis nearest {_AXES[axis]}{body} ({name} moved to the centre of mass, "
                f"{JG[axis, axis]:.6g}) exceeds the sum of the other two, {others:.6g} kg·m² ({at})",
                {"principal_moment": float(lam[a]), "sum_of_others": float(others), name + "_G": float(JG[axis, axis])},
            ))
    return out


def check_physical(
    tree_or_values: Tree | Mapping[str, float],
    frames: Sequence[int] | None = None,
    rtol: float = 1e-9,
) -> list[Violation]:
    """Physical-consistency violations of the bodies of a tree or of a set of named values.

    tree_or_values: a Tree (its values) or a mapping parameter name -> value using the
    standard names XXj ... Mj (missing = 0). frames: the bodies to check; default every
    body with a nonzero inertial parameter (massless virtual links are skipped).
    Returns [] when every body checked is realisable.
    """
    if isinstance(tree_or_values, Tree):
        tree = tree_or_values
        block = tree.inertial_block()
        bodies = {f.j: block[f.j] for f in tree.frames}
    else:
        bodies = {}
        for key, v in tree_or_values.items():
            m = _NAME.match(key)
            if m:
                bodies.setdefault(int(m.group(2)), np.zeros(10))[INERTIAL.index(m.group(1))] = float(v)
    if frames is None:
        frames = sorted(j for j, p in bodies.items() if np.any(p != 0.0))
    out: list[Violation] = []
    for j in frames:
        out += check_body(bodies.get(j, np.zeros(10)), j, rtol)
    return out


NONNEGATIVE_TERMS = {"IA": "rotor inertia", "FV": "viscous friction", "FS": "Coulomb friction"}
"""Joint terms that a real drive cannot have negative (OFF and K may take either sign)."""

_TERM = re.compile(r"^(IA|FV|FS)(\d+)$")


def check_joint_terms(values: Mapping[str, float], couplings: Mapping[str, str] | None = None) -> list[Violation]:
    """Violations of IAj, FVj, FSj >= 0 in a set of named values, and of the couplings named in
    ``couplings`` ({name: kind}, kind IA, FV or FS; e.g. a motor's rotor inertia on two joints).
    A coupling's body is reported as 0 (it belongs to no single body)."""
    out = []
    kinds = {n: k for n, k in (couplings or {}).items() if k in NONNEGATIVE_TERMS}
    for name, v in values.items():
        m = _TERM.match(name)
        kind, body = (m.group(1), int(m.group(2))) if m else (kinds.get(name), 0)
        if kind is None or float(v) >= 0.0:
            continue
        what = NONNEGATIVE_TERMS[kind]
        out.append(Violation(body, what, f"{what} {name} = {float(v):.6g} is negative (a drive's {what} is >= 0)",
                             {name: float(v)}))
    return out


def check_base_singletons(values: Mapping[str, float], couplings: Mapping[str, str] | None = None) -> list[Violation]:
    """The necessary conditions readable on base parameters that are one standard parameter each (no
    regrouping): Mj > 0; XXj, YYj, ZZj (moments about the axes of frame j, ∫(y²+z²)dm...) >= 0; the joint
    terms of `check_joint_terms`. ``values``: only such base parameters."""
    out = []
    for name, v in values.items():
        m = _NAME.match(name)
        if m is None:
            continue
        kind, body = m.group(1), int(m.group(2))
        if kind == "M" and not float(v) > 0.0:
            out.append(Violation(body, "mass", f"body {body}: mass {name} = {float(v):.6g} kg is not positive",
                                 {"M": float(v)}))
        elif kind in ("XX", "YY", "ZZ") and float(v) < 0.0:
            axis = kind[0].lower()
            out.append(Violation(body, "positive definite",
                                 f"body {body}: moment of inertia {name} = {float(v):.6g} kg·m² about the {axis} axis "
                                 f"of frame {body} is negative (a moment about any axis is ∫ r² dm >= 0)",
                                 {name: float(v)}))
    return out + check_joint_terms(values, couplings)


__all__ = ["NONNEGATIVE_TERMS", "Violation", "check_base_singletons", "check_body", "check_joint_terms",
           "check_physical", "inertia_at_com"]

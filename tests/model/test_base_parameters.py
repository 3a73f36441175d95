"""Base parameters (numeric QR method) against published results and invariances."""

import csv
import re

import numpy as np
import pytest
from oracles import random_states, random_tree

from dynid import Model, load_model

_PUBLISHED_NAMES = {"Ixx": "XX", "Ixy": "XY", "Ixz": "XZ", "Iyy": "YY", "Iyz": "YZ", "Izz": "ZZ",
                    "mx": "MX", "my": "MY", "mz": "MZ", "m": "M", "Ia": "IA", "fv": "FV", "fs": "FS", "off": "OFF"}


def parse_combination(expr: str) -> dict[str, float]:
    """'Izz1 + 1.0*Ia1 - 0.05*m3' -> {'ZZ1': 1.0, 'IA1': 1.0, 'M3': -0.05} in dynid's names."""
    out = {}
    for sign, coef, name in re.findall(r"([+-]?)\s*(?:([\d.]+)\*)?([A-Za-z]+\d)", expr.replace(" ", "")):
        kind, j = name[:-1], name[-1]
        key = name if name in ("Iam6", "fvm6", "fsm6") else _PUBLISHED_NAMES.get(kind, kind) + j
        out[key] = (-1.0 if sign == "-" else 1.0) * float(coef or 1.0)
    return out


def test_tx40_regrouping_has_the_published_structure(tx40_data):
    """Same 60 base parameters and the same regrouping coefficients as the published TX40 table."""
    with open(tx40_data / "TX40_bp_5.csv") as fh:
        published = [parse_combination(row[0]) for row in csv.reader(fh)]
    ours = load_model("tx40").base_parameters()
    assert ours.rank == len(published) == 60
    for expr, pub in zip(ours.expressions, published, strict=True):
        mine = {}
        for k, v in parse_combination(expr).items():
            mine[k] = v
        assert mine.keys() == pub.keys(), (expr, pub)
        for k in pub:
            assert abs(mine[k] - pub[k]) <= 5e-6 * max(1, abs(pub[k])), (k, mine[k], pub[k])


@pytest.mark.slow
def test_rank_and_base_set_do_not_depend_on_the_samples():
    for m in (load_model("puma560"), load_model("floating_tree"), Model(random_tree(seed=41, n=18))):
        sets = {m.base_parameters(seed=s).names for s in (0, 1, 2)}
        assert len(sets) == 1


def test_regrouped_model_reproduces_the_full_model():
    """W_base X_B = W X for every X: the base set loses nothing."""
    for m in (load_model("tx40"), load_model("floating_tree"), Model(random_tree(seed=42, n=20, floating=True))):
        b = m.base_parameters()
        rng = np.random.default_rng(0)
        X = rng.normal(size=m.tree.p)
        q, qd, qdd = random_states(m.tree, 30, 7)
        W = m.regressor(q, qd, qdd)
        assert np.allclose(W[:, :, list(b.columns)] @ b.values(X), W @ X, rtol=1e-9, atol=1e-9 * np.abs(W @ X).max())
        # and the base columns are independent: full column rank on fresh samples
        assert np.linalg.matrix_rank(np.asarray(W[:, :, list(b.columns)]).reshape(-1, b.rank)) == b.rank


def test_base_parameters_of_chosen_rows_and_columns():
    """Joint 1's equation alone: joint 2's friction has no effect on it, and fewer parameters are identifiable."""
    m = load_model("puma560")
    b = m.base_parameters(rows=[1])
    assert {"ZZ1", "FV1", "FS1"} <= set(b.names)
    assert {"FV2", "FS2", "IA2", "FV6"} <= set(b.eliminated)
    assert b.rank < m.base_parameters().rank
    b = m.base_parameters(cols=["ZZ1", "IA1", "FV1"])
    assert b.names == ("ZZ1", "FV1") and b.regrouped == ("IA1",) and b.expressions[0] == "ZZ1 + IA1"

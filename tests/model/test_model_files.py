"""Model files: round trips and clear errors on bad input."""

import numpy as np
import pytest

from dynid import EXAMPLES, ModelError, load_model, save_tree
from dynid.model import example_path, load_tree

GOOD = """
name = "two links"
frames = [
  [1, 0, 0, 0, 0, 0, 0, 0, 0],
  [2, 1, 0, 0, 0, "-pi/2", 0.3, 0, 0],
]
[parameters.2]
M = 2.0
"""


@pytest.mark.parametrize("name", EXAMPLES)
def test_round_trip(name, tmp_path):
    tree = load_tree(example_path(name))
    save_tree(tree, tmp_path / "m.toml")
    again = load_tree(tmp_path / "m.toml")
    assert again == tree
    assert again.parameter_names == tree.parameter_names
    assert np.array_equal(again.parameters, tree.parameters)


def write(tmp_path, text):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "text, words",
    [
        (GOOD.replace("frames = [", "frames = [[["), ["bad.toml", "not valid TOML", "line"]),
        ("colour = 'red'\n" + GOOD, ["bad.toml", "unknown top-level key", "colour"]),
        (GOOD.replace("M = 2.0", "MASS = 2.0"), ["parameters.2", "MASS"]),
        (GOOD.replace("[2, 1, 0,", "[2, 2, 0,"), ["frame 2", "a(2) = 2"]),
        (GOOD.replace("[2, 1, 0,", "[2, 1, 5,"), ["frame 2", "sigma = 5"]),
        (GOOD.replace('"-pi/2"', '"-pi/two"'), ["frame 2", "alpha", "-pi/two"]),
        (GOOD.replace("0.3, 0, 0]", "0.3, 0]"), ["frames row 2", "9 columns"]),
        (GOOD.replace("[parameters.2]", "[parameters.7]"), ["frame 7", "does not exist"]),
    ],
)
def test_bad_files_say_what_and_where(tmp_path, text, words):
    with pytest.raises(ModelError) as err:
        load_tree(write(tmp_path, text))
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_missing_file(tmp_path):
    with pytest.raises(ModelError, match="cannot read"):
        load_tree(tmp_path / "nope.toml")


def test_bad_arrays_name_the_sample_and_frame():
    m = load_model("puma560")
    q = np.zeros((4, 6))
    with pytest.raises(ModelError, match=r"shape \(N, 6\)"):
        m.inverse_dynamics(np.zeros((4, 5)), q, q)
    bad = q.copy()
    bad[2, 3] = np.nan
    with pytest.raises(ModelError, match=r"qd has a non-finite value.*sample 2, frame 4"):
        m.inverse_dynamics(q, bad, q)
    with pytest.raises(ModelError, match="same shape"):
        m.inverse_dynamics(q, q[:3], q)
    with pytest.raises(ModelError, match="no parameter 'ZZ9'"):
        m.regressor(q, q, q, cols=["ZZ9"])
    with pytest.raises(ModelError, match="row 0 is not a joint"):
        m.regressor(q, q, q, rows=[0])
    with pytest.raises(ModelError, match="78 values"):
        m.inverse_dynamics(q, q, q, X=np.ones(3))

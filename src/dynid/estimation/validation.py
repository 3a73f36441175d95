"""Validation errors of an estimate on rows (paper §7.2): the pipeline's, from the rows' per-group factors.

Each function adds the rows to a `StreamingLS` as one block and asks it, so a batch of rows and a stream of them
(the pipeline's direct and cross validation) are one computation: ``||Y_g - W_g X|| = ||R_g [X; -1]||`` with
``[W_g | Y_g] = Q_g R_g``, to round-off of the rows' residual.

Cost: a QR of the rows, O(m p^2), where the residual alone is a product, O(m p) (200,000 x 60 rows: 0.57 s against
0.03 s of CPU); these functions are the batch face of the pipeline's validation, so that there is one definition
of each error, not a faster second one to keep in step.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from numpy.typing import ArrayLike

from ._checks import as_matrix
from .errors import IdentificationError
from .streaming import StreamingLS, one_block


def relative_errors(W: ArrayLike, Y: ArrayLike, X: ArrayLike | Mapping[str, float], groups: ArrayLike,
                    names: Sequence[str] | None = None) -> dict[str, float]:
    """Relative error ``||Y_g - W_g X|| / ||Y_g||`` per equation group, plus ``"overall"``.

    W : (m, p); Y : (m,); X : (p,) values in W's column order, or ``{name: value}`` with ``names``
    giving W's column order (every name must be present); groups : (m,) group label of each row.
    A group with ``||Y_g|| = 0`` gets 0 if its residual is 0 too, else inf. Direct validation passes
    the identification data, cross validation data from a test not used for estimation (paper §7.2).
    `StreamingLS.relative_errors` on the rows as one block.
    """
    ls, x = _block(W, Y, X, groups, names)
    return ls.relative_errors(x)


def nrmse(W: ArrayLike, Y: ArrayLike, X: ArrayLike | Mapping[str, float], groups: ArrayLike,
          names: Sequence[str] | None = None) -> dict[str, float]:
    """Normalised RMS error ``RMS(Y_g - W_g X) / std(Y_g)`` per equation group, plus ``"overall"`` (the
    residuals' and the spreads' sums of squares pooled over groups). Unlike the relative error it does not
    count the part of Y that never changes (a robot's static gravity load): 1 is no better than predicting
    each group's mean. Arguments as for `relative_errors`; `StreamingLS.nrmse` on the rows as one block.

    The spread is the factors' ``||Y_g||^2 - (sum Y_g)^2 / n_g``, as the pipeline's: it loses about
    ``2 log10(|mean| / std)`` of its digits (a group whose mean is 1e4 times its spread: ~1e-9 relative), and a
    constant group reads a round-off spread, so a large finite NRMSE, where the rows' two-pass spread gives inf."""
    ls, x = _block(W, Y, X, groups, names)
    return ls.nrmse(x)


def residual_rms(W: ArrayLike, Y: ArrayLike, X: ArrayLike | Mapping[str, float], groups: ArrayLike,
                 names: Sequence[str] | None = None) -> dict[str, float]:
    """RMS of the residual ``Y_g - W_g X`` per equation group (no "overall"): on the identification rows, the
    noise floor `not_excited` compares a test's signal with. Arguments as for `relative_errors`;
    `StreamingLS.group_rms` on the rows as one block."""
    ls, x = _block(W, Y, X, groups, names)
    return ls.group_rms(x)


def _block(W: ArrayLike, Y: ArrayLike, X: ArrayLike | Mapping[str, float], groups: ArrayLike,
           names: Sequence[str] | None) -> tuple[StreamingLS, ArrayLike | Mapping[str, float]]:
    """The rows as one block (columns named x1..xp without names) and X, the arguments checked."""
    if isinstance(X, Mapping) and names is None:
        raise IdentificationError("X given as {name: value} needs names (the parameter of each column of W)")
    A = as_matrix(W, names)
    ls = one_block(A, Y, [f"x{k + 1}" for k in range(A.shape[1])] if names is None else names, groups)
    if "overall" in ls.group_rows:  # before any answer: StreamingLS.group_rms has no "overall" to clash with
        raise IdentificationError('"overall" is reserved for the whole system; rename that equation group')
    return ls, X

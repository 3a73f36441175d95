"""Errors and warnings of the estimation layer."""

from __future__ import annotations

from collections.abc import Mapping, Sequence


class IdentificationError(ValueError):
    """The data cannot identify what was asked, with what to do about it.

    Attributes
    ----------
    parameters : tuple of str
        The parameters the problem is about (e.g. the unidentifiable ones), possibly empty.
    group : str or None
        The equation group the problem is about, if any.
    relations : dict
        For rank deficiency: ``{name: {other_name: coefficient}}`` meaning that the column of
        ``name`` in W equals ``sum(coefficient * column of other_name)`` (an empty dict for a
        zero column).
    """

    def __init__(
        self,
        message: str,
        *,
        parameters: Sequence[str] = (),
        group: str | None = None,
        relations: Mapping[str, Mapping[str, float]] | None = None,
    ) -> None:
        super().__init__(message)
        self.parameters = tuple(parameters)
        self.group = group
        self.relations = {k: dict(v) for k, v in (relations or {}).items()}


class EstimationWarning(UserWarning):
    """Something in the estimation was patched up (e.g. a zero noise level) and should be looked at."""

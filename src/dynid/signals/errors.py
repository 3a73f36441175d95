"""The one exception of the signal layer."""

from __future__ import annotations


class SignalError(ValueError):
    """A signal or a signal-processing setting that cannot be used.

    The message says what was wrong, where (sample index, column, stage) and, when
    there is one, what to do about it.
    """

"""Errors and warnings of the measurement-file layer.

Every error is a `DataError` (a `ValueError`) whose message says what was wrong, where
(file, line, channel, sample index, time) and what to do. The attributes repeat the
"where" for programs: `source` (file), `channel`, `sample`, `line`, each None when it
does not apply.
"""

from __future__ import annotations

from collections.abc import Sequence


class DataError(ValueError):
    """A measurement file, channel or mapping that cannot be used as it is."""

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        channel: str | None = None,
        sample: int | None = None,
        line: int | None = None,
    ) -> None:
        super().__init__(message)
        self.source = source
        self.channel = channel
        self.sample = sample
        self.line = line


class FileFormatError(DataError):
    """A file that cannot be parsed: unknown format, bad cell, ragged row, unreadable layout."""


class MissingChannelError(DataError):
    """Channels that are needed and not in the file.

    Attributes `needed` (the missing names) and `available` (what the file has).
    """

    def __init__(self, message: str, *, needed: Sequence[str] = (), available: Sequence[str] = (), **where) -> None:
        super().__init__(message, **where)
        self.needed = tuple(needed)
        self.available = tuple(available)


class UnknownUnitError(DataError):
    """A unit string that is not in the unit table, or a channel with no unit where one is needed."""

    def __init__(self, message: str, *, unit: str | None = None, **where) -> None:
        super().__init__(message, **where)
        self.unit = unit


class GapError(DataError):
    """A hole in a channel: a NaN (or infinite) value, or a step in its time stamps far above the usual one."""


class TimeBaseError(DataError):
    """Time stamps that are not finite or not strictly increasing (going backwards or duplicated)."""


class RecordTooShortError(DataError):
    """A record with too few samples for the filter asked for (its transients would eat it all)."""


class MappingError(DataError):
    """A channel-mapping entry that cannot be used (unknown key, bad sign or scale, ...)."""


class MissingDependencyError(ImportError):
    """An optional package that a file format needs is not installed; the message names the extra."""


class DataWarning(UserWarning):
    """Something in the data looks wrong but can still be used; look at it."""


class SaturationWarning(DataWarning):
    """A channel stuck at a range limit for a while (a saturated or clipped sensor)."""


class UnitOverrideWarning(DataWarning):
    """A channel map gives a unit different from the one the file declares; the map's unit is used."""

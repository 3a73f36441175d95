"""Atomic file writes: a crash or an error never leaves a half-written result.

The data go to a temporary file beside the target (same file system, so the final
`os.replace` is an atomic rename), flushed to disk, given the mode a new file would have
(or the mode of the file it replaces), then renamed over the target.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def _new_file_mode(target: Path) -> int:
    if target.exists():
        return target.stat().st_mode & 0o7777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside `path` for a writer that needs a path; on success it replaces `path`,
    on any error it is removed. Named ``.<name>.<random>.tmp<suffix>`` so writers see the right extension."""
    target = Path(path)
    fd, tmp_name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp" + target.suffix)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, _new_file_mode(target))
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: str | os.PathLike[str], data: str | bytes) -> Path:
    """Write text (UTF-8) or bytes to `path` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
    return Path(path)


class OutputError(OSError):
    """An output that cannot be written where asked (the message says where and why)."""


def output_folder(path: str | os.PathLike[str]) -> Path:
    """The output folder, created if needed and checked writable BEFORE a run computes anything: a folder
    that cannot take the results must not cost the user the whole run first."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out}: exists and is not a folder; give --out a folder (new or existing)")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise OutputError(f"{out}: cannot write there ({exc.strerror or exc}); give --out a folder you can "
                          "write") from None
    return out

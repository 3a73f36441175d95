"""Atomic writes for writers that need a path (pyarrow, scipy, asammdf): temp file, then rename."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success it replaces `path`, on any error it is removed.

    The temporary file lives in the same directory (so `os.replace` is an atomic rename
    on the same file system), is named ``.<name>.<random>.tmp<suffix>`` (writers that
    look at the extension see the right one) and is flushed to disk before the rename.
    A crash or an exception never leaves a partial file at `path`: either the old file
    (if any) or the complete new one.
    """
    target = Path(path)
    fd, tmp_name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp" + target.suffix)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise

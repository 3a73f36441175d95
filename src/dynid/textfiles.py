"""Text files (configs, model and vehicle files, CSV): UTF-8, with a byte-order mark accepted; any other
encoding is named in a one-line error with the line and the fix, never a UnicodeDecodeError from inside."""

from __future__ import annotations

import csv
import io
import os
import stat
import tomllib
from pathlib import Path

_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")


MAX_TEXT_BYTES = 64 * 2**20  # a config, model or vehicle file, a table: kilobytes; more is the wrong file


class TextEncodingError(ValueError):
    """A text file that is not UTF-8: the message says where and what to do (the caller adds the file)."""


class NotAFileError(OSError):
    """A path that is not a regular file (a pipe, a device, a folder): reading it could hang or never end."""


def regular_file(path: str | os.PathLike[str], limit: int | None = None) -> os.stat_result:
    """stat of `path` (symlinks followed) if it is a regular file of at most `limit` bytes, else NotAFileError
    naming it: a named pipe blocks its reader for ever and /dev/zero never ends, so neither is opened."""
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        kind = ("a folder" if stat.S_ISDIR(st.st_mode) else "a named pipe" if stat.S_ISFIFO(st.st_mode)
                else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "a socket"
                if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise NotAFileError(f"{path}: is {kind}, not a file; give the file itself (a copy of the stream, if it "
                            "is one)")
    if limit is not None and st.st_size > limit:
        raise NotAFileError(f"{path}: {st.st_size / 2**20:.0f} MiB, more than any text file of this kind "
                            f"({limit / 2**20:.0f} MiB at most): is it the right file?")
    return st


def read_utf8(path: str | os.PathLike[str]) -> str:
    """The text of a small file (a config, a model, a table). OSError passes through; a file that is not
    UTF-8 raises TextEncodingError; a path that is not a regular file, or one over MAX_TEXT_BYTES, raises
    NotAFileError (an OSError) before anything is read."""
    regular_file(path, MAX_TEXT_BYTES)
    raw = Path(path).read_bytes()
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise TextEncodingError(encoding_problem(path)) from None


def encoding_problem(path: str | os.PathLike[str]) -> str:
    """Why a file failed to decode as UTF-8, and the fix (read again in binary: only on the error path)."""
    with open(path, "rb") as fh:
        head = fh.read(4096)
        if head.startswith(_UTF16_BOMS):
            return "UTF-16 text (it starts with a UTF-16 byte-order mark); save it as UTF-8"
        if b"\x00" in head:
            return "binary data, not text (a NUL byte in its first 4 kB); is it the right file, or another format?"
        fh.seek(0)
        for number, line in enumerate(fh, start=1):
            try:
                line.decode("utf-8")
            except UnicodeDecodeError as exc:
                byte = line[exc.start]
                return (f"line {number}: byte 0x{byte:02x} is not UTF-8 (Latin-1 or Windows-1252 text, e.g. a '°' "
                        "or 'µ'?); save the file as UTF-8 (iconv -f latin1 -t utf-8 IN > OUT)")
    return "not UTF-8 text; save it as UTF-8"


def _other_format(text: str, what: str) -> str:
    """What a file that is not TOML looks like instead, and the fix (a URDF given for a model file, JSON, CSV)."""
    head = text.lstrip()[:2000]
    first = head.splitlines()[0] if head else ""
    if head.startswith("<"):
        fix = ("; import it first: dynid model import FILE.urdf --out FILE.toml" if "<robot" in head else "")
        return f"; this file is XML{' (a URDF)' if '<robot' in head else ''}, and the {what} is TOML{fix}"
    if head.startswith(("{", "[{")) and '":' in head:
        return f"; this file is JSON, and the {what} is TOML (key = value lines)"
    if first.count(",") >= 2 and "=" not in first:
        return f"; this file is a CSV table, and the {what} is TOML (key = value lines)"
    return ""


def read_toml(path: str | os.PathLike[str], what: str, error: type[Exception]) -> dict:
    """The table of a TOML file; a missing file or bad TOML raises `error` naming the file (and the line)."""
    path = Path(path)
    text = ""
    try:
        text = read_utf8(path)
        return tomllib.loads(text)
    except NotAFileError as exc:
        raise error(f"{exc} (the {what})") from None
    except OSError as exc:
        raise error(f"{path}: cannot read the {what} ({exc.strerror})") from None
    except TextEncodingError as exc:
        raise error(f"{path}: the {what} is {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {exc}{_other_format(text, what)}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise error(f"{path}: the {what} nests arrays or tables hundreds deep, beyond what can be read; no dynid "
                    "file nests more than a few levels: is it the right file? look for a run of '[' or '{'") from None


def read_csv_rows(path: str | os.PathLike[str]) -> list[list[str]]:
    """The non-blank rows of a small CSV (a table, a coefficient file), cells as text. OSError passes through;
    a file that is not UTF-8 raises TextEncodingError."""
    return [r for r in csv.reader(io.StringIO(read_utf8(path), newline="")) if r and any(c.strip() for c in r)]

"""Atomic writes: a crash or an error never leaves a half-written result.

A file: the data go to a temporary file beside the target (same file system, so the final
`os.replace` is an atomic rename), flushed to disk, given the mode a new file would have
(or the mode of the file it replaces), then renamed over the target.

An output folder (`staged_folder`): the run writes into a hidden sibling `.NAME.partial-<random>`
which is swapped in as a whole at the end, under a lock `.NAME.lock`, so the folder is always
either the complete old set of results or the complete new one, whatever stops the run.
"""

from __future__ import annotations

import _thread
import ctypes
import errno
import hashlib
import itertools
import json
import os
import re
import shutil
import signal
import stat
import sys
import tempfile
import threading
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

from ._version import __version__

try:
    import fcntl
except ImportError:  # Windows: lock files created with O_EXCL instead
    fcntl = None  # type: ignore[assignment]


def _umask() -> int:
    """The process's umask, read now (a program may change it); os.umask can only be read by setting it, so
    it is set to the strictest value for that instant: a file another thread creates then is private, never
    world-writable."""
    umask = os.umask(0o077)
    os.umask(umask)
    return umask


def _new_file_mode(target: Path) -> int:
    if target.exists():
        return target.stat().st_mode & 0o7777
    return 0o666 & ~_umask()


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


def refuse_overwrite(paths: Iterable[str | os.PathLike[str]], force: bool = False) -> None:
    """Before a command computes anything: none of `paths` (the files it is about to write) exists, unless the
    user said --force. dynid cannot prove it wrote a lone file (an output folder has its marker), so an
    existing one is the user's until they say otherwise. Raises OutputError (one line)."""
    for p in map(Path, paths):
        parent = p.parent
        if not parent.is_dir():  # found before computing, and named as the user gave it (not a temporary's name)
            what = "is a file, not a folder" if parent.exists() else "does not exist"
            raise OutputError(f"{p}: the folder {parent} {what}; create the folder first (mkdir -p {parent}), or give "
                              "--out a file in an existing folder")
        if force:
            continue
        if os.path.lexists(p):
            what = "a folder" if p.is_dir() else "a link" if p.is_symlink() else "a file"
            raise OutputError(f"{p}: exists ({what}) and dynid does not replace what it cannot prove it wrote; "
                              "give another --out, or add --force to replace it")


def add_force(parser) -> None:
    """The --force flag of a command that writes files (`refuse_overwrite`)."""
    parser.add_argument("--force", action="store_true",
                        help="replace files the command would write that exist already (default: refuse)")


# ------------------------------------------------------------------ a whole output folder

MARKER = ".dynid-output.json"  # written last in every output folder: run id and the files with their SHA-256
_JUNK = {".DS_Store", "Thumbs.db", "desktop.ini"}  # written by file browsers, not by a user: replaced freely
_TMP = re.compile(r"^\..+\.tmp(\.[^.]*)?$")  # atomic_path's temporaries, left by a killed pre-staging run


class Terminated(BaseException):
    """SIGTERM or SIGHUP during a staged run, raised so that `finally` blocks clean up; a BaseException, like
    KeyboardInterrupt, so that no `except Exception` swallows it."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"terminated by {signal.Signals(signum).name}")
        self.signum = signum


class _Signals:
    """SIGTERM/SIGHUP raise Terminated, SIGINT KeyboardInterrupt, while installed; inside `deferred()` (lock,
    swap, cleanup) a signal is held and raised when the guard is left. Signals that were ignored (nohup) or
    given a handler by someone else are left alone; outside the main thread nothing is installed."""

    def __init__(self) -> None:
        self.saved: dict[int, object] = {}
        self.critical = 0
        self.pending: int | None = None

    def __enter__(self) -> _Signals:
        if threading.current_thread() is not threading.main_thread():
            return self
        wanted = {signal.SIGINT: (signal.default_int_handler, interrupt), signal.SIGTERM: (signal.SIG_DFL,)}
        if hasattr(signal, "SIGHUP"):
            wanted[signal.SIGHUP] = (signal.SIG_DFL,)
        for sig, defaults in wanted.items():
            if signal.getsignal(sig) in defaults:
                self.saved[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, kind, exc, tb) -> None:
        for sig, old in self.saved.items():
            signal.signal(sig, old)  # type: ignore[arg-type]
        if self.pending is not None and kind is None:
            _raise_for(self.pending)

    def _handle(self, signum: int, frame) -> None:
        if self.critical:
            self.pending = signum
            return
        if unraisable(frame):
            _again(signum)
            return
        _raise_for(signum)

    @contextmanager
    def deferred(self) -> Iterator[None]:
        self.critical += 1
        try:
            yield
        finally:
            self.critical -= 1

    def raise_pending(self) -> None:
        """Raise a signal held by `deferred()` now (the run must not go on computing until its end)."""
        if self.pending is not None and not self.critical:
            signum, self.pending = self.pending, None
            _raise_for(signum)


def _raise_for(signum: int) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated(signum)


# ctypes callbacks through which LLVM calls Numba's object cache back while it compiles (llvmlite's executionengine)
_LLVM_CALLBACKS = frozenset({"_raw_object_cache_notify", "_raw_object_cache_getbuffer"})


def unraisable(frame) -> bool:
    """Whether an exception raised in `frame` would be printed and dropped instead of reaching the caller: inside a
    ctypes callback (LLVM calls llvmlite back each time Numba compiles a function: much of a first run's time) or
    an object's __del__. A Ctrl-C raised there was lost: the run went on, or failed later ("no compiled object
    yet")."""
    while frame is not None:
        code = frame.f_code
        if code.co_name == "__del__" or (code.co_name in _LLVM_CALLBACKS and "llvmlite" in code.co_filename):
            return True
        frame = frame.f_back
    return False


def interrupt(signum: int, frame) -> None:
    """SIGINT's handler for a whole command (`interrupts`): KeyboardInterrupt, but where Python would drop it
    (`unraisable`) the signal is raised again a moment later (`_again`)."""
    if unraisable(frame):
        _again(signum)
        return
    raise KeyboardInterrupt


def _again(signum: int) -> None:
    """The signal raised again in 5 ms, from another thread: this thread handles it at its first instruction then,
    normally out of the callback (if not, it goes round again). Raised from this thread, it would be handled at
    once, inside the callback still."""
    timer = threading.Timer(0.005, _thread.interrupt_main, (signum,))
    timer.daemon = True  # never what keeps a process from ending
    timer.start()


@contextmanager
def interrupts() -> Iterator[None]:
    """SIGINT handled by `interrupt` inside (a command's run, cli.main), where Python's default handler is set and
    this is the main thread; the handler before restored after."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    before = signal.signal(signal.SIGINT, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


# staging folder -> the output folder it becomes: kept after the run, so that an error raised inside it can
# still be shown with the final names
_SEEN: dict[str, str] = {}


def final_path(path: str | os.PathLike[str]) -> Path:
    """`path` with a staging folder (`staged_folder`) replaced by the output folder it becomes: what a report,
    results.json or a message should name, since the staging folder is gone after the swap."""
    return Path(final_text(os.fspath(path)))


def final_text(text: str) -> str:
    """`text` with every staging folder's path replaced by its output folder's."""
    for stage, final in _SEEN.items():
        if stage in text:
            text = text.replace(stage, final)
    return text


def _names(folder: Path) -> Iterator[str]:
    """Files (and symlinks) under `folder`, as POSIX paths relative to it."""
    for root, dirs, files in os.walk(folder):
        dirs.sort()
        for name in sorted(files) + sorted(d for d in dirs if os.path.islink(os.path.join(root, d))):
            yield Path(root, name).relative_to(folder).as_posix()


def remove_temporaries(folder: str | os.PathLike[str]) -> None:
    """Delete the temporaries a killed writer left in `folder` (`atomic_path`'s names); call it only when no writer
    is left there."""
    for p in Path(folder).iterdir():
        if _TMP.match(p.name):
            p.unlink(missing_ok=True)


def _ours(rel: str) -> bool:
    """Left by file browsers or by a killed atomic write: not a user's file."""
    name = rel.rsplit("/", 1)[-1]
    return name in _JUNK or bool(_TMP.match(name))


def _check_replaceable(real: Path, shown: Path) -> None:
    """Refuse to replace a folder that holds anything dynid did not write: the user's files are never deleted."""
    if not real.exists():
        return
    if not real.is_dir():
        raise OutputError(f"{shown}: exists and is not a folder; give --out a folder (new or existing)")
    if os.path.ismount(real):
        raise OutputError(f"{shown}: is a mount point, and an output folder is replaced as a whole; give --out "
                          "a folder inside it")
    if not os.access(real, os.W_OK | os.X_OK):
        raise OutputError(f"{shown}: cannot write there (permission denied); give --out a folder you can write")
    written = _written(real)
    extra = list(itertools.islice((r for r in _names(real) if not _ours(r) and not _replaceable(real, r, written)),
                                  4))
    if extra:
        listed = ", ".join(extra[:3]) + (", ..." if len(extra) > 3 else "")
        raise OutputError(f"{shown}: holds files dynid did not write, or not as they are now ({listed}: its "
                          f"{MARKER} does not list them with these bytes); an output folder is replaced as a whole, "
                          "so give --out a new or empty folder, or move those files out")


def _written(real: Path) -> dict[str, str] | None:
    """The files the marker of the run that wrote `real` lists, with their SHA-256 (None without a readable one)."""
    try:
        files = json.loads((real / MARKER).read_text(encoding="utf-8"))["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return files if isinstance(files, dict) and all(isinstance(v, str) for v in files.values()) else None


def _replaceable(real: Path, rel: str, written: dict[str, str] | None) -> bool:
    """Whether dynid may delete `rel` in `real`: the marker itself, or a file the marker lists (`written`) with
    these bytes, still a regular file (not a link put in its place) that the user has not made read-only."""
    if written is None:
        return False  # no readable marker: nothing is proven dynid's, the marker's remains included
    if rel == MARKER:
        return True
    p = real / rel
    try:
        st = p.lstat()
    except OSError:
        return True  # gone meanwhile: nothing to keep
    return (rel in written and stat.S_ISREG(st.st_mode) and bool(st.st_mode & stat.S_IWUSR)
            and file_sha256(p) == written[rel])


def _check_inputs(real: Path, shown: Path, inputs: Iterable[str | os.PathLike[str]]) -> None:
    try:
        cwd: Path | None = Path.cwd().resolve()
    except OSError:  # the current folder was deleted: it cannot be the output folder
        cwd = None
    if cwd is not None and (cwd == real or real in cwd.parents):
        raise OutputError(f"{shown}: is the current folder or holds it, and an output folder is replaced as a "
                          "whole; give --out another folder")
    for p in inputs:
        q = Path(p).resolve()
        if real in q.parents:
            raise OutputError(f"{shown}: holds this run's input {p}, and an output folder is replaced as a whole; "
                              f"give --out another folder (e.g. --out {shown.name}-2)")


def _pid_alive(pid: int) -> bool:
    if os.name == "nt":  # os.kill(pid, 0) would send CTRL_C_EVENT there
        k32 = ctypes.windll.kernel32  # type: ignore[attr-defined]
        handle = k32.OpenProcess(0x1000, False, pid)  # PROCESS_QUERY_LIMITED_INFORMATION
        if not handle:
            return False
        code = ctypes.c_ulong()
        ok = k32.GetExitCodeProcess(handle, ctypes.byref(code))
        k32.CloseHandle(handle)
        return bool(ok) and code.value == 259  # STILL_ACTIVE
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    return True


def _holder(lock: Path) -> str:
    try:
        return lock.read_text().strip() or "?"
    except OSError:
        return "?"


def _busy(shown: Path, pid: str) -> OutputError:
    return OutputError(f"{shown}: another dynid run (pid {pid}) is writing this folder; wait for it to end, or "
                       "give another --out")


def _lock(lock: Path, shown: Path):
    """Take the folder's lock (non-blocking); returns its release. flock where there is one: the kernel drops it
    when its holder dies, however it dies; elsewhere an O_EXCL file with the holder's pid, taken over when that
    process is gone."""
    if fcntl is not None:
        while True:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise _busy(shown, _holder(lock)) from None
            try:  # the holder before us may have unlinked the file we opened: lock the one on disk
                same = os.path.samestat(os.fstat(fd), os.stat(lock))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
        except OSError:  # a full disk: the lock is held all the same, the pid is only for messages
            pass

        def release() -> None:
            lock.unlink(missing_ok=True)  # while still held: a waiter then sees a new file, not ours
            os.close(fd)
        return release
    for _ in range(3):
        try:
            fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            pid = _holder(lock)
            if pid.isdigit() and _pid_alive(int(pid)):
                raise _busy(shown, pid) from None
            lock.unlink(missing_ok=True)  # its run was killed: stale
            continue
        os.write(fd, f"{os.getpid()}\n".encode())
        os.close(fd)
        return lambda: lock.unlink(missing_ok=True)
    raise _busy(shown, _holder(lock))


def _siblings(real: Path, kind: str) -> list[Path]:
    prefix = f".{real.name}.{kind}-"
    return sorted((p for p in real.parent.iterdir() if p.name.startswith(prefix)), key=lambda p: p.stat().st_mtime)


def _recover(real: Path) -> None:
    """Under the lock, what killed runs left: an old set moved aside by a run killed between its two renames
    goes back in place; staging folders and moved-aside old sets are removed."""
    olds = _siblings(real, "old")
    if olds and not os.path.lexists(real):
        os.rename(olds.pop(), real)
    for p in _siblings(real, "partial") + olds:
        shutil.rmtree(p, ignore_errors=True)


def _folder_mode(real: Path) -> int:
    if real.is_dir():
        return real.stat().st_mode & 0o7777
    return 0o777 & ~_umask()


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux renameat2 RENAME_EXCHANGE, glibc >= 2.28); False where that is not
    available (another system, an older libc, a file system without it)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    at_fdcwd, rename_exchange = -100, 2
    if fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), os.fspath(b))


def _swap_in(stage: Path, real: Path) -> Path | None:
    """Put `stage` at `real`; returns where the old set now is (to delete), None if there was none."""
    if not os.path.lexists(real):
        os.rename(stage, real)
        return None
    if _exchange(stage, real):
        return stage  # at every instant `real` was the old set or the new one
    old = real.with_name(f".{real.name}.old-{uuid.uuid4().hex[:8]}")
    os.rename(real, old)  # from here to the next rename `real` is absent; a kill here is undone by _recover
    try:
        os.rename(stage, real)
    except BaseException:
        os.rename(old, real)
        raise
    return old


def _fsync_dir(path: Path) -> None:
    if os.name != "posix":
        return
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:  # some file systems refuse fsync on a folder: durability is best effort there
        pass
    finally:
        os.close(fd)


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _write_marker(stage: Path) -> None:
    files = {}
    for rel in _names(stage):
        if rel != MARKER and (stage / rel).is_file():
            files[rel] = file_sha256(stage / rel)
    for root, _dirs, _files in os.walk(stage):
        _fsync_dir(Path(root))
    marker = {"dynid": __version__, "run_id": uuid.uuid4().hex[:16],
              "written_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"), "files": files}
    write_atomic(stage / MARKER, json.dumps(marker, indent=1) + "\n")


@contextmanager
def staged_folder(path: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str]] = ()) -> Iterator[Path]:
    """An output folder replaced as a whole: yields a hidden staging folder beside `path` to write the results
    in; on success it is swapped in (the old set deleted after), on any error, Ctrl-C or SIGTERM it is removed
    and `path` keeps the old set. Checked before the caller computes anything: `path` is not a file, is not
    locked by another run, holds only a previous run's outputs (or nothing) and none of `inputs`, and its
    parent can be written. Leftovers of a killed run are cleaned up first. Raises OutputError (one line)."""
    shown = Path(path)
    real = shown.resolve()
    if real.parent == real:
        raise OutputError(f"{shown}: is the root of the file system; give --out a folder below it")
    guard = _Signals()
    with guard:
        if real.exists() and not real.is_dir():
            raise OutputError(f"{shown}: exists and is not a folder; give --out a folder (new or existing)")
        above = next((p for p in real.parents if p.exists()), None)
        if above is not None and not above.is_dir():  # --out log.csv/out: a folder cannot be made in a file
            raise OutputError(f"{shown}: {above} is a file, not a folder; give --out a folder (new or existing) "
                              "outside it")
        try:
            real.parent.mkdir(parents=True, exist_ok=True)
            with guard.deferred():
                release = _lock(real.with_name(f".{real.name}.lock"), shown)
        except OSError as exc:
            if isinstance(exc, OutputError):
                raise
            raise OutputError(f"{shown}: cannot write there ({exc.strerror or exc}: the results are written "
                              "beside the folder, then swapped in); give --out a folder you can write") from None
        trash: Path | None = None
        try:
            _recover(real)
            _check_replaceable(real, shown)
            _check_inputs(real, shown, inputs)
            with guard.deferred():
                trash = Path(tempfile.mkdtemp(prefix=f".{real.name}.partial-", dir=real.parent))
            guard.raise_pending()  # a Ctrl-C held while locking or making the folder stops the run before it computes
            os.chmod(trash, _folder_mode(real))
            stage = trash
            _SEEN[os.fspath(stage)] = os.path.abspath(shown)  # as the user named it (a symlink stays one)
            yield stage
            with guard.deferred():
                _write_marker(stage)
                trash = _swap_in(stage, real)
                _fsync_dir(real.parent)
        finally:
            with guard.deferred():
                if trash is not None:
                    shutil.rmtree(trash, ignore_errors=True)
                release()

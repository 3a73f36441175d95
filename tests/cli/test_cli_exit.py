"""The `dynid` command ends its process once a command is done (cli.main._leave): its output flushed, the atexit
handlers run, its exit status kept, Python's teardown of the modules skipped; main(argv) called in a process returns.
`dynid demo` runs with the library's objects frozen out of the collector's full scans, and gives them back.

Oracle: what a fresh interpreter running the entry point prints (an object's __del__ writes only if the teardown
runs; an atexit handler; the command's own last line, printed by the in-process call) and its exit status; gc's
count of frozen objects.
"""

import os
import subprocess
import sys

import pytest

# the entry point as the `dynid` script runs it, with an object that says when the teardown deletes it
PROBE = """
import atexit, os, runpy, sys


class Watch:
    def __del__(self, write=os.write):  # the teardown clears this module's names: write bound now
        write(1, b"TEARDOWN\\n")


watch = Watch()
atexit.register(lambda: print("ATEXIT"))
sys.argv = ["dynid", *sys.argv[1:]]
runpy.run_module("dynid.cli.main", run_name="__main__")
print("AFTER")  # reached only if main() returned
"""


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, timeout=120)


def test_a_command_ends_the_process_with_its_output_and_atexit_handlers_but_no_teardown(capsys):
    from dynid.cli.main import main

    assert main(["model", "show", "tx40"]) == 0  # in a process: main returns
    last = capsys.readouterr().out.rstrip().splitlines()[-1]
    proc = _run("model", "show", "tx40")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.rstrip().splitlines()
    assert lines[-2:] == [last, "ATEXIT"]  # the whole output (a pipe: buffered), then the handlers
    assert "AFTER" not in lines and "TEARDOWN" not in lines


def test_a_failed_command_keeps_its_exit_status_and_message():
    proc = _run("model", "show", "no-such-model.toml")
    assert proc.returncode == 2
    assert proc.stderr.startswith("dynid: error: no-such-model.toml")
    assert proc.stdout.splitlines() == ["ATEXIT"]


def test_the_demo_runs_with_the_library_frozen_out_of_the_collector_and_gives_it_back(tmp_path, monkeypatch, capsys):
    """cmd_demo freezes the objects alive once the library is imported (gc.freeze: the collector's full scans skip
    them) and unfreezes them when it ends, here on an error (the caller's process, as it was)."""
    import gc

    import dynid.pipeline.demo as demo
    from dynid.cli.main import main
    from dynid.pipeline.config import ConfigError

    seen = []

    def run_demo(*_a, **_k):
        seen.append(gc.get_freeze_count())
        raise ConfigError("stopped here")

    monkeypatch.setattr(demo, "run_demo", run_demo)
    assert gc.get_freeze_count() == 0
    assert main(["demo", "--quick", "--out", str(tmp_path / "out")]) == 2
    assert "stopped here" in capsys.readouterr().err
    assert seen and seen[0] > 10_000  # the library's objects (numpy, scipy, numba, dynid: ~185k)
    assert gc.get_freeze_count() == 0


# the command's last output still in stdout's buffer when the process ends, and the disk full for it
FULL = """
import errno, io, sys
from dynid.cli.main import _leave


class Full(io.RawIOBase):
    def writable(self):
        return True

    def write(self, b):
        raise OSError(errno.ENOSPC, "No space left on device")


sys.stdout = io.TextIOWrapper(io.BufferedWriter(Full()))
print("the command's last line")  # buffered: refused only when flushed
_leave(0)
"""


def test_output_lost_at_the_end_is_an_error_not_a_silent_success():
    """A write of the output refused as the process ends (a full disk) is said and fails the command, as Python's own
    teardown did (its exit status 120 and the error) before the command ended by _leave; a reader gone (`| head`)
    is no error. Old code: exit status 0, nothing said."""
    proc = subprocess.run([sys.executable, "-c", FULL], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr == "dynid: error: the command's output (stdout) could not be written: No space left on device\n"
    gone = subprocess.run([sys.executable, "-c", FULL.replace("errno.ENOSPC, ", "errno.EPIPE, ")],
                          capture_output=True, text=True, timeout=60)
    assert (gone.returncode, gone.stderr) == (0, "")


@pytest.mark.slow
def test_a_reader_that_leaves_does_not_stop_the_run(tmp_path):
    """`dynid demo ... | head -1`: once the pipe's reader has gone, the rest of the output goes nowhere and the run
    ends with its folder written, status 0. Oracle: the folder's report and results after the reader closed the
    pipe at the first line (unbuffered output: every print meets the closed pipe; before, the first one stopped the
    run and its folder was removed, with status 0)."""
    out = tmp_path / "demo"
    proc = subprocess.Popen([sys.executable, "-m", "dynid", "demo", "--quick", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.stdout.readline()
    proc.stdout.close()  # the reader leaves, as head -1 does
    assert proc.wait(timeout=600) == 0
    assert (out / "report.html").is_file() and (out / "results.json").is_file()

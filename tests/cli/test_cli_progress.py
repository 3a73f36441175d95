"""Progress a person trusts (issue 27, item 5): one bar with its time left on a terminal, occasional plain lines
without carriage returns when the output is a file or a pipe.

Oracles: the text a `Reporter` writes for a known sequence of counts (a fake clock makes the plain lines' times
exact), and the stderr of real `dynid` commands run with their output captured (not a terminal).
"""

from __future__ import annotations

import io
import subprocess
import sys

import pytest

from dynid.cli import progress as cli_progress
from dynid.cli.progress import Reporter
from dynid.progress import Count


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def clock(monkeypatch) -> Clock:
    c = Clock()
    monkeypatch.setattr(cli_progress.time, "perf_counter", c)
    return c


def _segments(rep: Reporter, clock: Clock, n: int = 60, seconds_each: float = 5.0) -> None:
    """An hour of data in 60 s segments, each taking `seconds_each`, with a message before and after."""
    rep("joints and equations on 2 local thread(s)")
    for k in range(1, n + 1):
        clock.t += seconds_each
        rep(Count("segments", k, n, f"segments done {k}/{n}", unit="segment"))
    rep("estimating 32 parameters")


def test_plain_output_is_occasional_lines_with_the_time_left(clock):
    out = io.StringIO()
    _segments(Reporter(out, tty=False), clock)
    text = out.getvalue()
    assert "\r" not in text
    counted = [line for line in text.splitlines() if "segments done" in line]
    # the first line once 10 s have passed, then one every tenth of the way, not one per segment
    assert [line.split()[3] for line in counted] == ["3/60"] + [f"{k}/60" for k in range(6, 61, 6)]
    # 5 s a segment: after 3 of them, 57 remain, 285 s; after 6, 270 s
    assert counted[0] == "· segments done 3/60 (5 %, about 4 min 45 s left)"
    assert counted[1] == "· segments done 6/60 (10 %, about 4 min 30 s left)"
    assert counted[-1] == "· segments done 60/60 (100 %, 5 min 00 s)"
    assert text.splitlines()[0] == "· joints and equations on 2 local thread(s)"
    assert text.splitlines()[-1] == "· estimating 32 parameters"


def test_a_quick_step_prints_only_its_last_line(clock):
    out = io.StringIO()
    rep = Reporter(out, tty=False)
    for t in range(1, 13):  # twelve simulated seconds in a fraction of a second each
        clock.t += 0.05
        rep(Count("simulating", t, 12, f"simulated {t} / 12 s", unit="s"))
    rep(Count("simulating", 12, 12, "simulated 12 / 12 s", unit="s"))  # the last, reported twice
    assert out.getvalue() == "· simulated 12 / 12 s (100 %, 1 s)\n"


def test_a_terminal_gets_one_bar_with_messages_above_it(clock):
    out = io.StringIO()
    _segments(Reporter(out, tty=True), clock)
    text = out.getvalue()
    assert "segments done" not in text  # no line per segment: the bar counts them
    assert text.count("\n") == 3  # the message before, the finished bar's line, the message after
    assert "60/60" in text.split("\n")[1].split("\r")[-1]  # the bar's final state, its own line


def _run(*args: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dynid.cli.main", *args], capture_output=True, text=True,
                          timeout=600, cwd=cwd)


def test_excite_output_in_a_file_has_no_carriage_return(tmp_path):
    # 3 SLSQP iterations a start are enough for the progress lines this checks (15: 2 s more of CPU, same lines)
    proc = _run("excite", "tx40", "--out", "traj.csv", "--starts", "3", "--refine", "2", "--maxiter", "3",
                cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr
    assert "start 2/2: condition number" in proc.stderr and "(100 %" in proc.stderr


def test_simulate_output_in_a_file_has_no_carriage_return(tmp_path):
    proc = _run("simulate", "sine", "--duration", "3", "--out", "sine.csv", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr
    assert proc.stderr.count("simulated 3 / 3 s") == 1  # its last line, once

"""An output folder is replaced as a whole (issue 18, item 3).

The oracle: after anything that stops a run (an error, a full disk, Ctrl-C, SIGTERM, SIGKILL), the output
folder is EITHER the complete old set OR the complete new one: its files are exactly those listed, with
their SHA-256, by the marker the run that wrote it left (`.dynid-output.json`), and its run id and hashes
are the old run's or a new one's, never a mixture. After an error, Ctrl-C or SIGTERM nothing temporary is
left beside or inside it; after SIGKILL the next run cleans up. A second run into a locked folder, and a
folder holding a user's own files, are refused with one line and touch nothing.

Most cases drive `staged_folder` directly with a few small files; the kill cases run the small robot
identification of test_bad_input (a few seconds) in a child process, stopped at a chosen point of its
writing phase (before the k-th file, or just before the swap) or at a delay after the writing began.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_bad_input import CONFIG, _robot_log

import dynid.atomic as atomic
from dynid.atomic import MARKER, OutputError, Terminated, final_path, final_text, staged_folder
from dynid.cli.main import main

posix_only = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")


# ------------------------------------------------------------------ the oracle


def snapshot(folder: Path) -> dict[str, str]:
    """Every file under `folder` (hidden ones too) -> its SHA-256."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def complete(folder: Path) -> str:
    """Assert `folder` holds exactly the files its marker lists, with those hashes; returns the run id."""
    marker = json.loads((folder / MARKER).read_text())
    files = {k: v for k, v in snapshot(folder).items() if k != MARKER}
    assert files == marker["files"], f"{folder} is not one run's complete set"
    return marker["run_id"]


def leftovers(folder: Path) -> list[str]:
    """Temporaries of the folder's runs: beside it (.NAME.*) and hidden ones inside it."""
    beside = [p.name for p in folder.parent.iterdir() if p.name.startswith(f".{folder.name}.")]
    inside = [p.name for p in folder.rglob(".*") if p.name != MARKER] if folder.is_dir() else []
    return beside + inside


def one_line(err: str, *words: str) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("dynid: error:"), err
    for w in words:
        assert w in lines[0], (w, err)


def write_set(stage: Path, tag: str) -> None:
    """A small stand-in for a run's outputs, nested like a demo's."""
    (stage / "results.json").write_text(json.dumps({"run": tag}))
    (stage / "report.html").write_text(f"<p>{tag}</p>")
    (stage / "data").mkdir()
    (stage / "data" / "a.csv").write_text(f"t,{tag}\n")


@pytest.fixture
def old(tmp_path) -> tuple[Path, dict[str, str]]:
    """An output folder holding a complete old set, and its snapshot."""
    out = tmp_path / "out"
    with staged_folder(out) as stage:
        write_set(stage, "old")
    complete(out)
    return out, snapshot(out)


# ------------------------------------------------------------------ staged_folder on its own


def test_a_new_folder_appears_complete_with_the_usual_mode(tmp_path):
    out = tmp_path / "sub" / "out"
    old_umask = os.umask(0o022)
    try:
        with staged_folder(out) as stage:
            assert stage.parent == out.parent.resolve() and stage.name.startswith(".out.partial-")
            assert not out.exists()  # nothing at the final path until the end
            write_set(stage, "new")
    finally:
        os.umask(old_umask)
    complete(out)
    assert stat.S_IMODE(out.stat().st_mode) == 0o755  # not the 0700 of a temporary folder
    assert json.loads((out / "results.json").read_text()) == {"run": "new"}
    assert leftovers(out) == []


def test_success_replaces_the_old_set_whole(old):
    out, _ = old
    old_id = complete(out)
    os.chmod(out, 0o750)
    with staged_folder(out) as stage:
        (stage / "results.json").write_text("{}")
    assert sorted(snapshot(out)) == [MARKER, "results.json"]  # the old report and data/ are gone
    assert complete(out) != old_id
    assert stat.S_IMODE(out.stat().st_mode) == 0o750  # the replaced folder's mode kept
    assert leftovers(out) == []


@pytest.mark.parametrize("stop", [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt(),
                                  ValueError("a bug")], ids=["disk full", "Ctrl-C", "bug"])
def test_an_error_keeps_the_old_set_and_removes_the_staging_folder(old, stop):
    out, before = old
    with pytest.raises(type(stop)), staged_folder(out) as stage:
        write_set(stage, "new")
        raise stop
    assert snapshot(out) == before and leftovers(out) == []


@posix_only
@pytest.mark.parametrize("sig, raised", [(signal.SIGTERM, Terminated), (signal.SIGINT, KeyboardInterrupt)])
def test_a_signal_while_writing_keeps_the_old_set(old, sig, raised):
    out, before = old
    ignored = signal.getsignal(sig) == signal.SIG_IGN
    if ignored:  # a shell's background job (CI started with &) ignores Ctrl-C: make it live, as at a terminal
        signal.signal(sig, signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL)
    handler = signal.getsignal(sig)
    with pytest.raises(raised), staged_folder(out) as stage:
        (stage / "results.json").write_text("{}")
        os.kill(os.getpid(), sig)
        time.sleep(5)  # interrupted by the handler
    assert snapshot(out) == before and leftovers(out) == []
    assert signal.getsignal(sig) is handler  # the handler lives only as long as the staging
    if ignored:
        signal.signal(sig, signal.SIG_IGN)


@posix_only
def test_ctrl_c_while_locking_stops_the_run_before_it_computes(old, monkeypatch):
    """A signal held while the folder is locked (a critical section) is raised as soon as that ends, before the
    body runs: the user's Ctrl-C must not wait for the whole computation."""
    out, before = old
    ignored = signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    if ignored:  # a shell's background job ignores Ctrl-C: make it live, as at a terminal
        signal.signal(signal.SIGINT, signal.default_int_handler)
    real_lock = atomic._lock

    def lock_then_ctrl_c(*args):
        release = real_lock(*args)
        os.kill(os.getpid(), signal.SIGINT)  # arrives while the lock's section holds signals
        return release

    monkeypatch.setattr(atomic, "_lock", lock_then_ctrl_c)
    ran = []
    try:
        with pytest.raises(KeyboardInterrupt), staged_folder(out):
            ran.append(True)
    finally:
        if ignored:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
    assert not ran and snapshot(out) == before and leftovers(out) == []
    monkeypatch.undo()
    with staged_folder(out) as stage:  # and the lock was released
        write_set(stage, "new")


@posix_only
def test_sigterm_during_the_swap_lets_it_finish_then_stops(old, monkeypatch):
    out, _ = old
    old_id = complete(out)
    swap = atomic._swap_in

    def swap_after_a_signal(stage, real):
        os.kill(os.getpid(), signal.SIGTERM)
        return swap(stage, real)

    monkeypatch.setattr(atomic, "_swap_in", swap_after_a_signal)
    with pytest.raises(Terminated), staged_folder(out) as stage:
        write_set(stage, "new")
    assert complete(out) != old_id
    assert json.loads((out / "results.json").read_text()) == {"run": "new"} and leftovers(out) == []


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="renameat2 is Linux's")
def test_linux_swaps_in_one_step(old, monkeypatch):
    out, _ = old
    calls = []
    exchange = atomic._exchange
    monkeypatch.setattr(atomic, "_exchange", lambda a, b: calls.append((a, b)) or exchange(a, b))
    monkeypatch.setattr(atomic.os, "rename", lambda *a: pytest.fail("renamed instead of exchanged"))
    with staged_folder(out) as stage:
        write_set(stage, "new")
    assert len(calls) == 1 and json.loads((out / "results.json").read_text()) == {"run": "new"}
    complete(out)
    assert leftovers(out) == []


def test_without_renameat2_two_renames_and_a_failed_one_is_undone(old, monkeypatch):
    out, before = old
    monkeypatch.setattr(atomic, "_exchange", lambda a, b: False)
    rename = os.rename

    def failing(src, dst):
        if Path(src).name.startswith(".out.partial-"):
            raise OSError(errno.EIO, "I/O error")
        rename(src, dst)

    monkeypatch.setattr(atomic.os, "rename", failing)
    with pytest.raises(OSError, match="I/O error"), staged_folder(out) as stage:
        write_set(stage, "new")
    assert snapshot(out) == before and leftovers(out) == []
    monkeypatch.setattr(atomic.os, "rename", rename)
    with staged_folder(out) as stage:
        write_set(stage, "new")
    assert json.loads((out / "results.json").read_text()) == {"run": "new"} and leftovers(out) == []


def test_what_a_killed_run_left_is_cleaned_by_the_next(old):
    """SIGKILL between the fallback's two renames: the old set aside, no folder, a complete staging folder,
    the lock file. The next run puts the old set back before anything else, and removes the rest."""
    out, before = old
    aside = out.with_name(".out.old-1234abcd")
    os.rename(out, aside)
    (out.parent / ".out.partial-zzzz").mkdir()
    (out.parent / ".out.partial-zzzz" / "results.json").write_text("{}")
    (out.parent / ".out.lock").write_text("999999\n")
    with pytest.raises(RuntimeError), staged_folder(out):
        assert snapshot(out) == before  # restored before the run computes
        raise RuntimeError("stop")
    assert snapshot(out) == before and leftovers(out) == []


def test_a_folder_with_a_users_files_is_refused_and_kept(tmp_path, old):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    with pytest.raises(OutputError, match=r"thesis\.tex") as err, staged_folder(mine):
        pytest.fail("a folder of the user's files was accepted")
    assert "dynid did not write" in str(err.value) and "--out" in str(err.value) and "\n" not in str(err.value)
    assert (mine / "thesis.tex").read_text() == "years of work" and leftovers(mine) == []
    out, _before = old  # an output folder the user added a file to
    (out / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match=r"notes\.txt"), staged_folder(out):
        pass
    assert (out / "notes.txt").read_text() == "mine"


def test_an_empty_folder_is_replaced(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / ".DS_Store").write_bytes(b"\0")  # a file browser's, not the user's
    with staged_folder(empty) as stage:
        write_set(stage, "new")
    complete(empty)
    assert leftovers(empty) == []


def _refused_and_kept(folder: Path, *named: str) -> None:
    """staged_folder(folder) refuses with one line naming `named`, and every file (the symlinks' targets too)
    keeps its bytes, hidden ones and the marker included."""
    before = snapshot(folder)
    links = {p: os.readlink(p) for p in folder.rglob("*") if p.is_symlink()}
    with pytest.raises(OutputError) as err, staged_folder(folder):
        pytest.fail(f"{folder} was accepted")
    text = str(err.value)
    assert "\n" not in text and "--out" in text and all(n in text for n in named), text
    assert snapshot(folder) == before and {p: os.readlink(p) for p in links} == links
    assert not [p for p in folder.parent.iterdir() if p.name.startswith(f".{folder.name}.partial")]


def test_a_folder_dynid_cannot_prove_it_wrote_is_refused_and_kept(tmp_path):
    """Without a marker (another tool's results.json, an older dynid's run, a marker deleted) nothing is proven
    dynid's: refused, every file kept byte for byte (the rule before guessed by file type and deleted them)."""
    legacy = tmp_path / "legacy"
    (legacy / "data").mkdir(parents=True)
    for name in ("results.json", "report.html", "parameters.csv", "figure_parameters.png", "identify.toml",
                 "data/sine.csv", "data/sine.json"):
        (legacy / name).write_text(f"old {name}")
    _refused_and_kept(legacy, "figure_parameters.png")
    (legacy / MARKER).write_text("{not json")  # a damaged marker proves nothing either
    _refused_and_kept(legacy, MARKER)


def test_an_output_edited_since_dynid_wrote_it_is_refused_and_kept(old):
    out, _ = old
    (out / "data" / "a.csv").write_text("t,old\nmy note\n")  # the user's notes in an output
    _refused_and_kept(out, "data/a.csv")


def test_an_output_made_read_only_is_refused_and_kept(old):
    out, _ = old
    os.chmod(out / "report.html", 0o444)  # the user's way of saying "keep this one"
    try:
        _refused_and_kept(out, "report.html")
    finally:
        os.chmod(out / "report.html", 0o644)


def test_an_output_replaced_by_a_link_is_refused_and_its_target_kept(tmp_path, old):
    out, _ = old
    mine = tmp_path / "mine.json"
    mine.write_text(json.dumps({"run": "old"}))  # the same bytes as the output it stands for
    (out / "results.json").unlink()
    (out / "results.json").symlink_to(mine)
    _refused_and_kept(out, "results.json")
    assert mine.read_text() == json.dumps({"run": "old"})


def test_a_folder_holding_the_runs_input_is_refused(tmp_path, monkeypatch):
    out = tmp_path / "demo"
    out.mkdir()
    with pytest.raises(OutputError, match="holds this run's input"), staged_folder(out, inputs=[out / "x.toml"]):
        pass
    monkeypatch.chdir(out)
    with pytest.raises(OutputError, match="current folder"), staged_folder("."):
        pass


def test_a_second_run_is_refused_naming_the_holder(old):
    out, _before = old
    with staged_folder(out) as stage:
        with pytest.raises(OutputError) as err, staged_folder(out):
            pass
        msg = str(err.value)
        assert str(out) in msg and f"pid {os.getpid()}" in msg and "\n" not in msg
        write_set(stage, "first")
    assert json.loads((out / "results.json").read_text()) == {"run": "first"} and leftovers(out) == []


def test_without_flock_a_lock_file_with_a_pid(old, monkeypatch):
    out, _ = old
    monkeypatch.setattr(atomic, "fcntl", None)
    with staged_folder(out):
        assert (out.parent / ".out.lock").read_text().strip() == str(os.getpid())
        with pytest.raises(OutputError, match=f"pid {os.getpid()}"), staged_folder(out):
            pass
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (out.parent / ".out.lock").write_text(dead.stdout)  # its run was killed: stale
    with staged_folder(out) as stage:
        write_set(stage, "after a stale lock")
    assert leftovers(out) == []


def test_paths_inside_the_staging_folder_are_named_as_they_will_be(tmp_path):
    out = tmp_path / "out"
    with staged_folder(out) as stage:
        assert final_path(stage / "data" / "a.csv") == out / "data" / "a.csv"
        assert final_text(f"reading {stage}/data/a.csv") == f"reading {out}/data/a.csv"
        assert final_path(tmp_path / "elsewhere.csv") == tmp_path / "elsewhere.csv"


# ------------------------------------------------------------------ the command line, killed


CHILD = r"""
import sys

import dynid.atomic as atomic
import dynid.pipeline.run as run
from dynid.cli.main import main

point = sys.argv[1]


def pause():
    print("READY", flush=True)
    sys.stdin.readline()


if point == "swap":  # all written and the marker too: just before the swap
    swap = atomic._swap_in

    def hooked_swap(stage, real):
        pause()
        return swap(stage, real)

    atomic._swap_in = hooked_swap
elif point.isdigit():  # before writing the k-th output file
    k, n, write = int(point), [0], run.write_atomic

    def hooked(path, data):
        if n[0] == k:
            pause()
        n[0] += 1
        return write(path, data)

    run.write_atomic = hooked
sys.exit(main(sys.argv[2:]))
"""


@pytest.fixture(scope="module")
def robot_done(tmp_path_factory) -> Path:
    """The small robot's files and a completed output folder `out` (the old set)."""
    work = tmp_path_factory.mktemp("robot")
    _robot_log(work)
    (work / "robot.toml").write_text(CONFIG)
    assert main(["identify", str(work / "robot.toml"), "--out", str(work / "out")]) == 0
    return work


@pytest.fixture
def work(robot_done, tmp_path) -> Path:
    w = tmp_path / "w"
    shutil.copytree(robot_done, w)
    return w


def start(work: Path, point: str) -> subprocess.Popen:
    # Ctrl-C live in the child, as at a terminal: a shell's background job (CI started with &) inherits it ignored
    return subprocess.Popen([sys.executable, "-u", "-c", CHILD, point, "identify", "robot.toml", "--out", "out"],
                            cwd=work, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_for(proc: subprocess.Popen, text: str) -> None:
    seen = []
    for line in proc.stdout:
        seen.append(line)
        if text in line:
            return
    proc.wait()
    pytest.fail(f"the run ended (exit {proc.returncode}) before {text!r}:\n{''.join(seen)}")


def stop(proc: subprocess.Popen, sig: int) -> tuple[int, str]:
    """Send `sig`, then let a paused child go on (a signal held during the swap needs it to); exit status, output."""
    proc.send_signal(sig)
    try:
        proc.stdin.write("go\n")
        proc.stdin.close()
    except OSError:  # already gone
        pass
    out = proc.stdout.read()
    return proc.wait(timeout=120), out


def identify_again(work: Path, capsys) -> str:
    assert main(["identify", str(work / "robot.toml"), "--out", str(work / "out")]) == 0, capsys.readouterr().err
    return complete(work / "out")


@posix_only
@pytest.mark.parametrize("sig, point", [
    (signal.SIGTERM, "3"), (signal.SIGINT, "0"), (signal.SIGTERM, "swap"), (signal.SIGKILL, "2"),
    (signal.SIGKILL, "swap"), (signal.SIGTERM, "+0.3 s"), (signal.SIGKILL, "+0.6 s"),
], ids=["TERM before the 4th file", "Ctrl-C before the first file", "TERM at the swap", "KILL before the 3rd file",
        "KILL at the swap", "TERM 0.3 s into writing", "KILL 0.6 s into writing"])
@pytest.mark.slow
@pytest.mark.e2e
def test_a_killed_run_leaves_the_old_set_or_the_new_one(work, capsys, sig, point):
    out = work / "out"
    before = snapshot(out)
    old_id = complete(out)
    proc = start(work, "none" if point.startswith("+") else point)
    if point.startswith("+"):  # a delay after the writing phase began, wherever that falls
        wait_for(proc, "drawing figures and writing the report")
        time.sleep(float(point.split()[0]))
    else:
        wait_for(proc, "READY")
    code, output = stop(proc, sig)
    if sig == signal.SIGKILL:
        assert code == -signal.SIGKILL
        complete(out)  # the old set or the new one, whole
        if point != "+0.6 s":  # stopped before the swap: the old set, exactly
            assert snapshot(out) == before
        if point == "swap":  # the next run cleans up what the kill left, and replaces the set
            assert identify_again(work, capsys) != old_id
        else:  # the next run cleans up first, even if it then fails
            now = snapshot(out)
            with pytest.raises(RuntimeError), staged_folder(out):
                raise RuntimeError("stop")
            assert snapshot(out) == now
        assert leftovers(out) == []
        return
    assert code == (130 if sig == signal.SIGINT else 143) or (point.startswith("+") and code == 0), output
    assert "Traceback" not in output
    new_id = complete(out)
    if point == "swap":  # a signal during the swap is held until it is done: the new set
        assert new_id != old_id
    elif code != 0:
        assert snapshot(out) == before
    assert leftovers(out) == [], output


@posix_only
@pytest.mark.slow
@pytest.mark.e2e
def test_a_second_run_into_a_busy_folder_is_refused(work, capsys):
    out = work / "out"
    before = snapshot(out)
    proc = start(work, "1")
    try:
        wait_for(proc, "READY")
        assert main(["identify", str(work / "robot.toml"), "--out", str(out)]) == 2
        one_line(capsys.readouterr().err, str(out), f"pid {proc.pid}", "another dynid run")
    finally:
        code, output = stop(proc, signal.SIGTERM)
    assert code == 143 and snapshot(out) == before and leftovers(out) == [], output


@pytest.mark.slow
@pytest.mark.e2e
def test_a_full_disk_while_writing_keeps_the_old_set(work, capsys, monkeypatch):
    import dynid.pipeline.run as run

    out = work / "out"
    before = snapshot(out)
    write, n = run.write_atomic, [0]

    def full_after_three(path, data):
        n[0] += 1
        if n[0] > 3:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return write(path, data)

    monkeypatch.setattr(run, "write_atomic", full_after_three)
    assert main(["identify", str(work / "robot.toml"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "No space left on device" in err.splitlines()[-1] and "partial" not in err
    assert snapshot(out) == before and leftovers(out) == []


@pytest.mark.slow
@pytest.mark.e2e
def test_users_files_stop_identify_before_computing(work, capsys):
    (work / "out" / "my notes.txt").write_text("mine")
    assert main(["identify", str(work / "robot.toml"), "--out", str(work / "out")]) == 2
    err = capsys.readouterr().err
    one_line(err, "my notes.txt", "dynid did not write")
    assert "reading" not in err and (work / "out" / "my notes.txt").read_text() == "mine"
    assert main(["identify", str(work / "robot.toml"), "--out", str(work)]) == 2  # the config's own folder
    one_line(capsys.readouterr().err, "dynid did not write")


# ------------------------------------------------------------------ the demo: everything staged


@pytest.mark.slow
@pytest.mark.e2e
def test_the_demo_is_staged_and_names_its_final_folder(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    complete(out)
    assert leftovers(out) == [] and (out / "identify.toml").is_file() and (out / "data" / "sine.csv").is_file()
    assert "partial" not in err and "partial" not in (out / "report.html").read_text()
    results = (out / "results.json").read_text()
    assert "partial" not in results
    inside = [f for f in json.loads(results)["provenance"]["files"] if f["path"].startswith(str(out))]
    assert len(inside) >= 7  # the config and the tests' files: named where they are now, hashed as read
    for f in inside:
        assert hashlib.sha256(Path(f["path"]).read_bytes()).hexdigest() == f["sha256"]
    assert "s of driving)" in err


# ------------------------------------------------------------------ commands that write one file


def _a_urdf(tmp_path: Path) -> Path:
    from test_urdf import SMALL

    src = tmp_path / "robot.urdf"
    src.write_text(SMALL["fixed_inertial_child"])
    return src


@pytest.mark.parametrize("command", ["model import", "model export", "model codegen", "vehicle new", "simulate",
                                     "excite"])
def test_a_command_does_not_replace_a_file_it_did_not_write(tmp_path, capsys, command):
    """Every command that writes files refuses, before it computes, to replace one that exists (dynid cannot prove
    it wrote a lone file): one line naming it and --force, the file byte for byte as it was."""
    src = _a_urdf(tmp_path)
    assert main(["model", "import", str(src), "--out", str(tmp_path / "robot.toml")]) == 0
    mine = tmp_path / "mine"
    mine.mkdir()
    argv, victim = {
        "model import": (["model", "import", str(src)], mine / "m.toml"),
        "model export": (["model", "export", str(tmp_path / "robot.toml"), "--urdf", str(src)], mine / "r.urdf"),
        "model codegen": (["model", "codegen", str(tmp_path / "robot.toml"), "--lang", "numpy", "--model", "idm",
                           "--prefix", "arm"], mine / "arm_idm.py"),
        "vehicle new": (["vehicle", "new", "mycar"], mine / "car.toml"),
        "simulate": (["simulate", "sine"], mine / "sine.json"),  # the sidecar of sine.csv
        "excite": (["excite", "tx40"], mine / "traj.toml"),  # the coefficients beside traj.csv
    }[command]
    out = {"model codegen": mine, "simulate": mine / "sine.csv", "excite": mine / "traj.csv"}.get(command, victim)
    victim.write_bytes(b"the user's own \x00 bytes")
    capsys.readouterr()
    assert main([*argv, "--out", str(out)]) == 2
    one_line(capsys.readouterr().err, str(victim), "--force")
    assert victim.read_bytes() == b"the user's own \x00 bytes"
    assert sorted(p.name for p in mine.iterdir()) == [victim.name]


def test_force_replaces_the_file(tmp_path, capsys):
    src = _a_urdf(tmp_path)
    out = tmp_path / "m.toml"
    out.write_text("old")
    assert main(["model", "import", str(src), "--out", str(out), "--force"]) == 0
    assert "[joints]" in out.read_text()

"""The quick commands stay quick: `dynid --version`, `--help` and `vehicle list` import no heavy library.

Oracle: `sys.modules` of a fresh interpreter that ran the command (deterministic, unlike a timing; the timing is
benchmarks/bench_cli_start.py); the shipped vehicles as `load_vehicle` reads them.
"""

import subprocess
import sys

import pytest

HEAVY = ("numpy", "scipy", "numba", "matplotlib", "sympy")

# the command as the `dynid` script runs it, then the heavy libraries that were imported
PROBE = f"""
import atexit, runpy, sys
# at exit: a command that ends normally ends the process in the entry point (cli.main._leave), atexit handlers run
atexit.register(lambda: print("HEAVY:", *[m for m in {HEAVY!r} if m in sys.modules]))
sys.argv = ["dynid", *sys.argv[1:]]
runpy.run_module("dynid.cli.main", run_name="__main__")
"""


@pytest.mark.parametrize("args", [["--version"], ["--help"], ["vehicle", "list"], ["identify", "--help"],
                                  ["simulate", "--help"], ["model", "export", "--help"]])
def test_quick_commands_import_no_heavy_library(args):
    proc = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[-1] == "HEAVY:", f"dynid {' '.join(args)} imported {lines[-1].split()[1:]}"
    assert len(lines) > 1  # it printed its answer before


def test_import_dynid_is_light_and_its_names_still_resolve():
    code = ("import sys, dynid; light = not any(m in sys.modules for m in ('numpy', 'scipy', 'numba')); "
            "from dynid import Model, load_model, example_path; print(light, Model.__name__, "
            "callable(load_model), example_path('tx40').name)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.stdout.split() == ["True", "Model", "True", "tx40.toml"], proc.stderr


def test_vehicle_list_reads_what_load_vehicle_reads(capsys):
    from dynid.cli.main import main
    from dynid.vehicle.description import load_vehicle, shipped_vehicles

    assert main(["vehicle", "list"]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert [r.split()[0] for r in rows] == shipped_vehicles()
    for name, row in zip(shipped_vehicles(), rows, strict=True):
        v = load_vehicle(name)
        g = v.geometry
        assert row == (f"{name:<14} {v.name}: wheelbase {g.wheelbase:.3g} m, tracks {2 * g.front.half_track:.3g} / "
                       f"{2 * g.rear.half_track:.3g} m, {'with' if v.truth else 'no'} simulation truth")


def test_simulate_lists_the_simulators_manoeuvres():
    from dynid.cli.simulate_cmds import MANOEUVRES
    from dynid.vehicle.sim.manoeuvres import DEFAULTS

    assert tuple(DEFAULTS) == MANOEUVRES


class _StopError(Exception):
    pass


@pytest.mark.parametrize("first", [True, False])
def test_a_first_demo_says_how_long_its_compiles_take(first, monkeypatch, capsys, tmp_path):
    """The demo's first run (a kernel build started) tells the user, before the silent loading, how much longer it
    takes (pipeline.demo.FIRST_RUN, measured there); a later run (kernel cached) says nothing of it."""
    import dynid.pipeline.demo as demo
    import dynid.vehicle.sim.car as car
    from dynid.cli.main import main

    monkeypatch.setattr(car, "prebuild_kernel", lambda: first)

    def stop(*_a, **_k):
        raise _StopError

    monkeypatch.setattr(demo, "run_demo", stop)
    with pytest.raises(_StopError):
        main(["--debug", "demo", "--out", str(tmp_path / "out")])
    said = capsys.readouterr()
    assert (f"about {demo.FIRST_RUN_S} s more than a later run" in said.out + said.err) is first


def test_python_m_dynid_is_the_command_line():
    from dynid import __version__

    proc = subprocess.run([sys.executable, "-m", "dynid", "--version"], capture_output=True, text=True, timeout=60)
    assert (proc.returncode, proc.stdout.strip()) == (0, f"dynid {__version__}"), proc.stderr
    proc = subprocess.run([sys.executable, "-m", "dynid", "vehicle", "nosuchcommand"], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2 and proc.stderr.startswith("dynid: error:"), proc.stderr  # the same errors

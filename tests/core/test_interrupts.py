"""A Ctrl-C while Numba compiles ends the run.

LLVM calls Numba's object cache back through a ctypes callback each time it emits a function's machine code;
Python prints and drops an exception raised inside such a callback, so a SIGINT that landed there was lost (a
cold demo ran on to the end, or failed later with "no compiled object yet"). The oracle is Python's own
behaviour: the script below raises SIGINT from inside that callback, in a fresh process with an empty cache, and
the run must end in KeyboardInterrupt, under a command's handler (`interrupts`) and under a staged output
folder's (`staged_folder`), whose partial folder must then be gone."""

import signal
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import os, signal, sys, tempfile
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp()  # a first compile: its object passes through the callback
    import numba
    from numba.core import codegen
    from dynid.atomic import interrupts, staged_folder

    notify = codegen.CPUCodeLibrary._object_compiled_hook.__func__
    landed = []

    def hook(cls, ll_module, buf):  # called by llvmlite's ctypes callback: the user's Ctrl-C lands here
        if not landed:
            frame = sys._getframe()
            while frame.f_code.co_name != "_raw_object_cache_notify":  # llvmlite's callback is up the stack
                frame = frame.f_back
            landed.append(frame.f_code.co_name)
            signal.raise_signal(signal.SIGINT)
        return notify(cls, ll_module, buf)

    codegen.CPUCodeLibrary._object_compiled_hook = classmethod(hook)

    @numba.njit(cache=True)
    def f(x):
        return 2.0 * x

    out = os.path.join(tempfile.mkdtemp(), "out")
    guard = interrupts() if sys.argv[1] == "command" else staged_folder(out)
    try:
        with guard:
            f(1.0)
        print("not interrupted", landed)
    except KeyboardInterrupt:
        left = os.listdir(os.path.dirname(out))
        print("interrupted", landed, left)
""")


@pytest.mark.parametrize("where", ["command", "staged"])
def test_a_ctrl_c_inside_llvms_callback_interrupts_the_run(where, tmp_path):
    script = tmp_path / "compile.py"  # a file: Numba caches a function of a file, not of `python -c`
    script.write_text(SCRIPT)
    run = subprocess.run([sys.executable, str(script), where], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    words = run.stdout.strip().split(maxsplit=1)
    assert words[0] == "interrupted", run.stdout + run.stderr
    assert "_raw_object_cache_notify" in words[1]  # the signal did land inside the callback
    assert words[1].endswith("[]"), words[1]  # a staged run's partial folder (and lock) removed: nothing left


def test_a_command_restores_the_interrupt_handler():
    from dynid.cli.main import main

    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert main(["vehicle", "list"]) == 0
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler

"""The `dynid` command, run as a user runs it."""

import subprocess
import sys

from dynid.cli.main import main


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dynid.cli.main", *args], capture_output=True, text=True, timeout=120)


def test_model_show_prints_table_parameters_and_base_set():
    out = run("model", "show", "tx40")
    assert out.returncode == 0, out.stderr
    assert "Staubli TX40: 6 frames, 86 parameters" in out.stdout
    assert "60 base parameters" in out.stdout
    assert "ZZ1 = ZZ1 + IA1 + YY2 + YY3 + 0.07*MZ3" in out.stdout
    assert "Iam6: IA on 32·q5 + 32·q6" in out.stdout


def test_bad_file_is_one_clear_line(tmp_path, capsys):
    bad = tmp_path / "m.toml"
    bad.write_text("frames = [[1, 0, 0, 0, 0, 0, 0, 0]]\n")
    assert main(["model", "show", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dynid: error:") and "m.toml" in err and "9 columns" in err
    assert "Traceback" not in err


def test_model_show_template_prints_the_paper_car():
    out = run("model", "show", "--template", "peugeot406")
    assert out.returncode == 0, out.stderr
    assert "42 frames" in out.stdout and "paper estimates: NOT realisable" in out.stdout
    assert "YY6" in out.stdout.split("NOT realisable")[1].splitlines()[1]
    assert "48 of 48" in out.stdout


def _commands(parser, path=("dynid",)):
    """(command path, its parser) for every command and sub-command, depth first."""
    import argparse

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*path, name), sub
                yield from _commands(sub, (*path, name))


def test_every_command_says_what_it_is_for_with_an_example_and_every_option_has_help():
    import argparse

    from dynid.cli.main import build_parser

    parser = build_parser()
    commands = dict(_commands(parser))
    assert {"demo", "identify", "simulate", "excite", "model", "vehicle"} <= {p[1] for p in commands}
    assert ("dynid", "model", "codegen") in commands and ("dynid", "vehicle", "new") in commands
    for path, p in [(("dynid",), parser), *commands.items()]:
        name = " ".join(path)
        assert p.description and len(p.description) > 40, f"{name}: no description"
        if len(path) > 1:  # an example that runs this very command, in the epilog, kept as written
            assert p.formatter_class is argparse.RawDescriptionHelpFormatter, name
            examples = [ln.strip() for ln in p.epilog.split("example")[1].splitlines()[1:] if ln.strip()]
            assert any(e.startswith(name + " ") or e == name for e in examples), f"{name}: no example"
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for c in a._choices_actions:
                    assert c.help, f"{name} {c.dest}: no help line"
            elif not isinstance(a, argparse._HelpAction):
                assert a.help and a.help != argparse.SUPPRESS, f"{name} {'/'.join(a.option_strings) or a.dest}: no help"


def test_top_level_help_lists_each_command_with_its_purpose_and_an_example():
    out = run("--help")
    assert out.returncode == 0
    for command in ("demo", "identify", "simulate", "excite", "model", "vehicle"):
        line = next(ln for ln in out.stdout.splitlines() if ln.strip().startswith(command + " "))
        assert len(line.split()) > 3, line  # the command and what it is for
        assert f"e.g. dynid {command} " in out.stdout
    assert "Traceback" not in out.stderr

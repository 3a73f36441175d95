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

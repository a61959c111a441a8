"""The command line: --version, exit codes (2 + one line for every user
error in every subcommand), `simulate` outputs, progress without a terminal."""

from __future__ import annotations

import io
import os
import subprocess
import sys

import pandas as pd
import pytest

from dampertwin import __version__
from dampertwin.cli import main
from dampertwin.io import read_meta
from dampertwin.progress import LineProgress, progress

from conftest import ROOT

BASE = str(ROOT / "conf" / "design" / "baseline.yaml")


def run(argv, capsys):
    """main(argv) in process -> (exit code, stdout, stderr); argparse's exits included."""
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


def test_version(capsys):
    code, out, _ = run(["--version"], capsys)
    assert code == 0 and out.strip() == f"dampertwin {__version__}"
    r = subprocess.run([sys.executable, "-m", "dampertwin.cli", "--version"], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.strip() == f"dampertwin {__version__}"


USER_ERRORS = {
    "no subcommand": [],
    "unknown option": ["design", "show", BASE, "--bogus"],
    "design show, missing file": ["design", "show", "{tmp}/nope.yaml"],
    "design show, bad design": ["design", "show", "{tmp}/bad.yaml"],
    "design check, missing file": ["design", "check", "{tmp}/nope.yaml"],
    "simulate, unknown test": ["simulate", BASE, "--test", "nope", "--out", "{tmp}/o"],
    "simulate, no such run": ["simulate", BASE, "--test", "monosine", "--case", "I9", "--out", "{tmp}/o"],
    "simulate, no such current": ["simulate", BASE, "--test", "monosine", "--current", "0.5", "--out", "{tmp}/o"],
    "simulate, missing design": ["simulate", "{tmp}/nope.yaml", "--test", "monosine", "--out", "{tmp}/o"],
    "simulate, bad current": ["simulate", BASE, "--test", "monosine", "--current", "x", "--out", "{tmp}/o"],
    "plot, unknown case": ["plot", "nocase", "--conf", str(ROOT / "conf"), "--out", "{tmp}/p"],
    "import, missing mapping": ["import", "{tmp}/rig.csv", "--map", "{tmp}/nope.yaml", "--out", "{tmp}/x.parquet"],
    "fit, missing record": ["fit", "friction", "--data", "{tmp}/nope.parquet", "--out", "{tmp}/f"],
    "fit, valve without --valve": ["fit", "valve", "--data", "{tmp}/rig.csv", "--out", "{tmp}/f"],
    "lab, missing sample": ["lab", "--sample", "{tmp}/nope.yaml", "--out", "{tmp}/l"],
    "lab, bad seed": ["lab", "--sample", "conf/lab/sample.yaml", "--out", "{tmp}/l", "--seed", "x"],
    "discrepancy, missing design": ["discrepancy", "--design", "{tmp}/nope.yaml", "--measured", "{tmp}",
                                    "--out", "{tmp}/d"],
    "sweep, not a project": ["sweep", "--root", "{tmp}", "variant=baseline_1.6"],
    "sweep, --root without folder": ["sweep", "--root"],
    "sweep, unknown override (Hydra)": ["sweep", "--root", str(ROOT), "nokey=1", "results_dir={tmp}/s"],
}


@pytest.mark.parametrize("case", USER_ERRORS)
def test_every_user_error_exits_2_with_one_line(case, tmp_path, capsys):
    (tmp_path / "bad.yaml").write_text(open(BASE).read().replace("unit: kg\n", "unit: g\n", 1))
    (tmp_path / "rig.csv").write_text("t,x\n0,1\n")
    argv = [a.format(tmp=tmp_path) for a in USER_ERRORS[case]]
    code, out, err = run(argv, capsys)
    lines = err.strip().splitlines()
    assert code == 2, (case, code, err)
    assert len(lines) == 1 and "error" in lines[0], (case, err)


def test_design_check_exit_1_is_for_problems_found(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(open(BASE).read().replace("unit: kg\n", "unit: g\n", 1))
    code, _, err = run(["design", "check", str(bad)], capsys)
    assert code == 1 and "geometry.M_rod" in err
    assert run(["design", "check", BASE], capsys)[0] == 0


def test_simulate_writes_parquet_and_png(tmp_path, capsys):
    out = tmp_path / "sim"
    code, stdout, err = run(["simulate", BASE, "--test", "monosine", "--current", "1.6", "--out", str(out)], capsys)
    assert code == 0, err
    pq, png = out / "monosine.parquet", out / "monosine.png"
    assert stdout.split() == [str(pq), str(png)]
    df = pd.read_parquet(pq)
    assert set(df["run"]) == {"I1.6"} and len(df) > 1000
    assert df["rod acceleration [m/s^2]"].abs().max() > 10.0  # a damper that moves, not zeros
    meta = read_meta(pq)
    assert meta["test"] == "monosine" and meta["synthetic"] and meta["design_hash"]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    first = pq.read_bytes()
    assert run(["simulate", BASE, "--test", "monosine", "--case", "I1.6", "--out", str(out)], capsys)[0] == 0
    assert pq.read_bytes() == first  # --case I1.6 is the same run; same input, same bytes


def test_simulate_current_selects_runs(tmp_path, capsys):
    code, _, err = run(["simulate", BASE, "--test", "flowbench", "--case", "piston_rebound", "--out",
                        str(tmp_path)], capsys)
    assert code == 0, err
    df = pd.read_parquet(tmp_path / "flowbench.parquet")
    assert set(df["run"]) == {"piston_rebound"} and df["dp [Pa]"].max() > 1e5


def test_progress_without_a_terminal_is_one_line_per_step():
    buf = io.StringIO()  # not a terminal
    bar = progress(total=3, desc="fits", file=buf)
    assert isinstance(bar, LineProgress)
    for k in range(3):
        bar.set_postfix(best=f"{k}.0")
        bar.update()
    bar.close()
    text = buf.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    assert len(lines) == 3 and lines[-1].startswith("fits: 3/3") and lines[-1].endswith("best=2.0")
    assert list(progress(range(4), desc="it", file=buf)) == [0, 1, 2, 3]
    silent = io.StringIO()
    progress(total=2, file=silent, disable=True).update()
    assert silent.getvalue() == ""


def test_progress_on_a_terminal_is_a_tqdm_bar():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    buf = Tty()
    bar = progress(total=3, desc="fits", file=buf)
    bar.update(3)
    bar.close()
    assert "\r" in buf.getvalue()  # tqdm redraws in place


def test_lab_progress_in_a_log_file_has_no_carriage_returns(tmp_path):
    r = subprocess.run([sys.executable, "-m", "dampertwin.cli", "lab", "--sample", "conf/lab/sample.yaml",
                        "--tests", "compliance", "--workers", "1", "--out", str(tmp_path / "lab")],
                       cwd=ROOT, capture_output=True, text=True, env=dict(os.environ, MPLBACKEND="Agg"))
    assert r.returncode == 0, r.stderr[-2000:]
    assert "\r" not in r.stderr and "lab: 1/1" in r.stderr


def test_sweep_results_dir_hydra_cannot_create_is_the_exception_line(tmp_path, capsys):
    (tmp_path / "afile").write_text("not a folder")
    code, _, err = run(["sweep", "--root", str(ROOT), "variant=baseline_1.6", f"results_dir={tmp_path}/afile/x"],
                       capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err and 'File "' not in err, err   # not Hydra's traceback flattened into one line
    assert "NotADirectoryError" in err and "under results_dir" in err, err


def test_sweep_hydra_exception_keeps_its_message_lines(tmp_path, capsys):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the summary callback does not stumble over the same error first
        code, _, err = run(["sweep", "--root", str(ROOT), "variant=baseline_1.6", "results_dir=${oops}"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "InterpolationKeyError: Interpolation key 'oops' not found" in err and "Traceback" not in err, err
    assert "results_dir)" not in err                          # no output-folder hint for an error that is not one

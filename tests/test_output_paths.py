"""Output paths and inputs checked before any work: a folder where a command writes a file is exit 2 naming it
(nothing written, no temporary file left); implausible protocol values (a mm / m mix-up, a sampling rate too
coarse for the excitation) are refused by the loader naming file and key; a simulation that stopped early is
never written as a result with NaN rows."""

from __future__ import annotations

import dataclasses
import shutil

import pandas as pd
import pytest
import yaml

from dampertwin.errors import UserError
from dampertwin.io import atomic_files, check_targets, write_frame
from dampertwin.io.outdir import OutputError
from dampertwin.protocols import ProtocolError, load_protocol

from conftest import BASELINE, ROOT
from test_cli import run  # main(argv) in process -> (exit code, stdout, stderr)

CONF = ROOT / "conf"
FOLDER = "is a folder; expected a file path or nothing"


def one_line_error(code, err, *needles):
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


def listing(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))


# ------------------------------------------------------------ a folder where an output file goes
@pytest.mark.parametrize("name", ["monosine.png", "monosine.parquet"])
def test_simulate_refuses_a_folder_at_an_output_file(tmp_path, capsys, name):
    out = tmp_path / "o"
    (out / name).mkdir(parents=True)
    code, _, err = run(["simulate", str(BASELINE), "--test", "monosine", "--case", "I1.6", "--out", str(out)], capsys)
    one_line_error(code, err, str(out / name), FOLDER)
    assert listing(out) == [name]  # no parquet without its PNG, no temporary file


def test_plot_refuses_a_folder_at_an_output_file(tmp_path, capsys):
    (tmp_path / "baseline_1.6" / "pq.png").mkdir(parents=True)
    code, _, err = run(["plot", "baseline_1.6", "--out", str(tmp_path), "--conf", str(CONF)], capsys)
    one_line_error(code, err, str(tmp_path / "baseline_1.6" / "pq.png"), FOLDER)
    assert listing(tmp_path) == ["baseline_1.6", "baseline_1.6/pq.png"]
    other = tmp_path / "other"
    other.mkdir()
    (other / "baseline_1.6").write_text("")  # OUT/CASE a file: named, not a FileExistsError traceback
    code, _, err = run(["plot", "baseline_1.6", "--out", str(other), "--conf", str(CONF)], capsys)
    one_line_error(code, err, str(other / "baseline_1.6"), "is a file; expected a folder")


@pytest.mark.parametrize("name", ["fit.json", "friction_0_friction.png"])
def test_fit_refuses_a_folder_at_an_output_file(tmp_path, capsys, name):
    (tmp_path / name).mkdir()
    code, _, err = run(["fit", "friction", "--data", str(ROOT / "examples" / "friction.parquet"),
                        "--design", str(BASELINE), "--out", str(tmp_path)], capsys)
    one_line_error(code, err, str(tmp_path / name), FOLDER)
    assert listing(tmp_path) == [name]


def test_atomic_files_refuse_a_folder_first_and_always_remove_their_temporaries(tmp_path):
    (tmp_path / "b.png").mkdir()
    with pytest.raises(OutputError, match="b.png: is a folder"):
        with atomic_files([tmp_path / "a.png", tmp_path / "b.png"]):
            raise AssertionError("the block must not run")
    (tmp_path / "x.parquet").mkdir()
    with pytest.raises(OutputError, match="x.parquet: is a folder"):
        write_frame(tmp_path / "x.parquet", pd.DataFrame({"time [s]": [0.0, 1.0]}), {})
    with pytest.raises(KeyboardInterrupt):
        with atomic_files([tmp_path / "c.png", tmp_path / "d.png"], ".png") as tmps:
            for t in tmps:
                t.write_text("half")
            raise KeyboardInterrupt
    assert listing(tmp_path) == ["b.png", "x.parquet"]  # nothing replaced, no temporary left
    (tmp_path / "f").write_text("")
    with pytest.raises(OutputError, match="is a file; expected a folder"):
        check_targets([tmp_path / "f" / "g.png"])


# ------------------------------------------------------------ implausible protocol values
def _conf_with(tmp_path, test, **changes):
    """A copy of conf/test/ with ``changes`` in ``test``.yaml; returns (conf folder, protocol file)."""
    conf = tmp_path / "conf"
    shutil.copytree(CONF / "test", conf / "test")
    p = conf / "test" / f"{test}.yaml"
    p.write_text(yaml.safe_dump({**yaml.safe_load(p.read_text()), **changes}))
    return conf, p


@pytest.mark.parametrize("changes, key", [({"amplitude": 5.0}, "monosine.amplitude = 5 m"),
                                          ({"rate": 1.0}, "monosine.rate = 1 Hz")])
def test_simulate_refuses_an_implausible_protocol(tmp_path, capsys, changes, key):
    conf, p = _conf_with(tmp_path, "monosine", **changes)
    out = tmp_path / "o"
    code, _, err = run(["simulate", str(BASELINE), "--test", "monosine", "--case", "I1.6", "--out", str(out),
                        "--conf", str(conf)], capsys)
    one_line_error(code, err, str(p), key)
    assert not out.exists()


@pytest.mark.parametrize("test, changes, key", [
    ("curving", {"amplitude": 25.0}, "curving.amplitude"),
    ("training", {"strokes": [50.0, 0.03]}, "training.strokes"),
    ("curving", {"velocities": [50.0, 100.0]}, "curving.velocities"),  # mm/s written as m/s
    ("friction", {"velocity": 50.0}, "friction.velocity"),
    ("verification", {"bands": [{"band": [0.5, 6.0], "rms": 8.0}]}, "verification.bands"),
    ("random", {"rate": 1000.0}, "random.rate = 1000 Hz"),  # bands to 500 Hz
    ("compliance", {"rate": 1000.0}, "compliance.rate = 1000 Hz"),  # 2 m/s at 5 mm: 64 Hz
    ("dyno", {"rate": 50.0}, "dyno.rate = 50 Hz"),
    ("thermal", {"frequency": 800.0}, "thermal.frequency x amplitude"),
    ("topmount", {"static": {"amplitude": 1.5, "period": 40.0, "cycles": 1, "rate": 200.0}},
     "topmount.static.amplitude"),
])
def test_loader_refuses_implausible_values_naming_file_and_key(tmp_path, test, changes, key):
    _, p = _conf_with(tmp_path, test, **changes)
    with pytest.raises(ProtocolError) as ei:
        load_protocol(p)
    assert str(p) in str(ei.value) and key in str(ei.value)


def test_simulate_refuses_a_stroke_beyond_the_designs_travel(tmp_path, capsys):
    """0.15 m passes the loader's generic bound but the baseline has 0.11 m of rebound travel."""
    conf, p = _conf_with(tmp_path, "monosine", amplitude=0.15, frequency=2.0)
    out = tmp_path / "o"
    code, _, err = run(["simulate", str(BASELINE), "--test", "monosine", "--case", "I1.6", "--out", str(out),
                        "--conf", str(conf)], capsys)
    one_line_error(code, err, str(p), "monosine.amplitude", "geometry.l_r0", str(BASELINE))
    assert not out.exists()


# ------------------------------------------------------------ a run that stopped early
def _stopped(real):
    """``real`` (a simulate) whose result reports a step-size underflow and NaN rows from a third on."""
    import numpy as np

    from dampertwin.solver import STATUS_TEXT, STEP_UNDERFLOW

    def stopped(*a, **k):
        r = real(*a, **k)
        r.stats = dataclasses.replace(r.stats, status=STEP_UNDERFLOW, message=STATUS_TEXT[STEP_UNDERFLOW])
        for v in r.channels.values():
            v[len(v) // 3:] = np.nan
        return r

    return stopped


def test_simulate_writes_nothing_when_a_run_stopped_early(tmp_path, capsys, monkeypatch):
    from dampertwin import simulate_test as st

    monkeypatch.setattr(st, "simulate", _stopped(st.simulate))
    out = tmp_path / "o"
    code, _, err = run(["simulate", str(BASELINE), "--test", "monosine", "--case", "I1.6", "--out", str(out)], capsys)
    one_line_error(code, err, "run I1.6", "stopped early (step size underflow)", "nothing written")
    assert not out.exists()
    with pytest.raises(UserError, match="stopped early"):
        st.simulate_test(BASELINE, "monosine", out, case="I1.6", conf=CONF)
    assert not out.exists()


def test_simulate_writes_both_files_or_neither(tmp_path, monkeypatch):
    """A failure while drawing the PNG leaves no Parquet (and no temporary file) behind."""
    from dampertwin import simulate_test as st

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(st, "_plot", boom)
    out = tmp_path / "o"
    with pytest.raises(RuntimeError, match="disk full"):
        st.simulate_test(BASELINE, "monosine", out, case="I1.6", conf=CONF)
    assert listing(out) == []


def test_plot_refuses_a_stroke_beyond_the_travel_and_draws_nothing_from_a_stopped_run(tmp_path, capsys,
                                                                                       monkeypatch):
    """plot checks the curving / monosine / random strokes against the design's travel as simulate does (0.115 m
    passes the loader, the baseline has 0.11 m), and refuses a run that stopped early instead of drawing its
    NaN rows; nothing is written either way."""
    from dampertwin import report

    conf = tmp_path / "conf"
    shutil.copytree(CONF, conf, ignore=shutil.ignore_patterns("lab", "sweep*"))
    p = conf / "test" / "monosine.yaml"
    p.write_text(yaml.safe_dump({**yaml.safe_load(p.read_text()), "amplitude": 0.115, "frequency": 1.0}))
    out = tmp_path / "o"
    code, _, err = run(["plot", "baseline_1.6", "--out", str(out), "--conf", str(conf)], capsys)
    one_line_error(code, err, str(p), "monosine.amplitude", "geometry.l_r0")
    assert not out.exists()

    monkeypatch.setattr(report, "simulate", _stopped(report.simulate))
    code, _, err = run(["plot", "baseline_1.6", "--out", str(out), "--conf", str(CONF)], capsys)
    one_line_error(code, err, "flowbench run", "stopped early (step size underflow); nothing drawn")
    assert not out.exists()

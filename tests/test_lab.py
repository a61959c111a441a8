"""The virtual laboratory: it measures the hidden sample (not the nominal
design) through benches that are not what the fits assume, reproducibly,
and refuses bad sample files with the file and key named."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import signal

from dampertwin import cli
from dampertwin import lab as labmod
from dampertwin.design import load
from dampertwin.excitation import Excitation
from dampertwin.io import read_frame, read_meta
from dampertwin.lab import actuate, check_sample, load_sample, run_lab, sample_design
from dampertwin.protocols import load_protocol
from dampertwin.report import simulate_from_record
from dampertwin.sensors import quantise, sensor_lowpass, transducer

from conftest import ROOT

CONF = ROOT / "conf"
SAMPLE = CONF / "lab" / "lab2" / "sample.yaml"
NOMINAL = CONF / "lab" / "nominal.yaml"
SUBSET = [("monosine", "baseline_1.6"), ("flowbench", "piston_intake"), ("topmount", "alternative")]


def test_lab_is_deterministic_labelled_synthetic_and_carries_the_sample_hash(tmp_path):
    a = run_lab(SAMPLE, tmp_path / "a", seed=9, only=SUBSET, progress=False, conf=CONF, workers=1)
    b = run_lab(SAMPLE, tmp_path / "b", seed=9, only=SUBSET, progress=False, conf=CONF, workers=2)
    c = run_lab(SAMPLE, tmp_path / "c", seed=10, only=SUBSET[:1], progress=False, conf=CONF, workers=1)
    for pa_, pb in zip(a, b):  # bit for bit, whatever the number of workers
        assert pa_.read_bytes() == pb.read_bytes()
    assert a[0].read_bytes() != c[0].read_bytes()
    for p, (proto, case) in zip(a, SUBSET):
        assert p == tmp_path / "a" / proto / f"{case}.parquet"
        meta = read_meta(p)
        assert meta["synthetic"] is True and meta["generator"] == labmod.LAB_VERSION
        assert meta["sample_hash"] == load_sample(SAMPLE)["_hash"] and len(meta["sample_hash"]) == 16
        assert meta["truth_rtol"] <= 1e-8 and meta["case"] == case
        read_frame(p, proto)  # passes the same checks as real data


def test_truth_absolute_floor_keeps_the_record_far_below_noise_and_resolution():
    """TRUTH_ATOL (1e-6 state scales) against the tight floor 1e-8 on 2 s of
    the module random test: the recorded channels move by far less than the
    shipped sensors' noise and resolution (< 1/20 of a converter step),
    while a loose floor would not."""
    from dampertwin.protocols import build_runs, load_all
    from dampertwin.simulation import simulate

    sample = load_sample(SAMPLE)
    part = sample_design(load(NOMINAL), sample)
    run = next(r for r in build_runs(load_all(CONF / "test")["random"], 0) if math.isclose(r.current, 1.6))
    a = sample["benches"]["actuator"]
    ex = actuate(run.excitation, a["gain"], a["delay"], a.get("natural_frequency"), a.get("damping"))

    def rec(atol):
        r = simulate(part, ex, "module", current=1.6, rate=run.rate, duration=2.0, rtol=labmod.TRUTH_RTOL, atol=atol)
        assert r.ok
        return r["rod force [N]"], r["rod acceleration [m/s^2]"], r.stats.accepted

    F0, A0, n0 = rec(1e-8)
    F1, A1, n1 = rec(labmod.TRUTH_ATOL)
    sens = sample["benches"]["sensors"]
    for d, ch in ((np.abs(F1 - F0).max(), "force [N]"), (np.abs(A1 - A0).max(), "rod acceleration [m/s^2]")):
        floor = min(sample["benches"]["noise"][ch], sens[ch].get("resolution", np.inf))
        assert d < 0.05 * floor, (ch, d, floor)  # < 1/20 of a converter step
    assert n1 < 0.7 * n0  # the reason for the floor: fewer steps
    F2, A2, _ = rec(1e-3)  # a loose floor is seen by the same check
    assert np.abs(F2 - F0).max() > 0.05 * min(sample["benches"]["noise"]["force [N]"],
                                              sens["force [N]"].get("resolution", np.inf))


def _force_rms_residual(df, design, current):
    """RMS of measured - simulated force, the simulation driven by the
    recorded displacement and seen through the DOCUMENTED load cell."""
    fs = 1.0 / float(np.mean(np.diff(df["time [s]"])))
    r = simulate_from_record(design, df, "module", current)
    documented = load_protocol(CONF / "test" / "monosine.yaml")["sensors"]["force"]
    sim = sensor_lowpass(r["top mount force [N]"], documented, fs)
    meas = df["force [N]"].to_numpy()
    n = len(meas) // 4  # skip the first cycle (start transient)
    return float(np.sqrt(np.mean((meas[n:] - sim[n:]) ** 2)))


@pytest.mark.parametrize("simulate_nominal", [False, True])
def test_lab_measures_the_hidden_sample_not_the_nominal_design(tmp_path, monkeypatch, simulate_nominal):
    """The record is much closer to a simulation of the sample's real part
    than to one of the nominal design. Negative control: a lab that
    simulates the nominal design (sample deviations dropped) fails it."""
    if simulate_nominal:
        monkeypatch.setattr("dampertwin.lab_record.sample_design", lambda d, s: d)  # where a run looks it up
    (p,) = run_lab(SAMPLE, tmp_path, seed=3, only=[("monosine", "baseline_1.6")], progress=False, conf=CONF, workers=1)
    df, _ = read_frame(p, "monosine")
    nominal = load(NOMINAL)
    real = sample_design(nominal, load_sample(SAMPLE))
    e_real = _force_rms_residual(df, real, 1.6)
    e_nom = _force_rms_residual(df, nominal, 1.6)
    closer_to_sample = e_real < 0.5 * e_nom
    assert closer_to_sample is (not simulate_nominal), (e_real, e_nom)


def test_shipped_benches_differ_from_what_the_fits_assume():
    """The documented transducers (conf/test sensors:, 2nd-order Butterworth)
    are not the lab's: another filter kind or order AND another corner."""
    b = load_sample(SAMPLE)["benches"]
    documented = load_protocol(CONF / "test" / "monosine.yaml")["sensors"]
    for ch, key in (("force [N]", "force"), ("rod acceleration [m/s^2]", "acceleration")):
        s = b["sensors"][ch]
        assert (s["filter"], s["order"]) != ("butter", 2) and s["corner"] != documented[key]
        assert s["gain"] != 1.0 and s["offset"] != 0.0 and s["resolution"] > 0
    assert "natural_frequency" in b["actuator"] and b["temperature"]["drift"] > 0
    assert b["scatter"]["actuator_gain"] > 0


def test_actuator_is_a_second_order_loop():
    """At its natural frequency a 2nd-order loop lags 90 deg with gain 1/(2 zeta)."""
    fn, zeta = 50.0, 0.4
    ex = Excitation.sine(1e-3, fn, 40 / fn, ramp=0.0)
    real = actuate(ex, 1.0, 0.0, fn, zeta)
    t = ex.t0 + ex.dt * np.arange(len(ex.value))
    tail = t > 20 / fn
    z = np.exp(-2j * math.pi * fn * t[tail])
    h = np.sum(real.value[tail] * z) / np.sum(ex.value[tail] * z)
    assert abs(h) == pytest.approx(1 / (2 * zeta), rel=0.02)
    assert np.degrees(np.angle(h)) == pytest.approx(-90.0, abs=1.5)
    assert np.allclose(np.gradient(real.value, ex.dt)[tail][:-2], real.rate[tail][:-2], rtol=0, atol=2e-3 * np.abs(real.rate).max())
    plain = actuate(ex, 0.98, 0.001)  # without dynamics: gain and delay only
    assert np.max(plain.value) == pytest.approx(0.98e-3, rel=1e-3)


def test_transducer_chain_filter_gain_offset_and_quantisation():
    fs = 20_000.0
    x = np.ones(4000)
    x[:100] = 0.0
    y = transducer(x, fs, filter="bessel", order=4, corner=1300.0, gain=1.01, offset=0.5)
    assert y[-1] == pytest.approx(1.01 + 0.5, rel=1e-9)  # DC: gain and offset
    f, h = signal.freqz(*signal.bessel(4, 1300.0, norm="mag", fs=fs), worN=[1300.0], fs=fs)
    assert abs(h[0]) == pytest.approx(1 / math.sqrt(2), rel=1e-6)  # -3 dB at the corner
    q = quantise(np.array([0.12, -0.37, 0.5049]), 0.25)
    assert np.allclose(q, [0.0, -0.25, 0.5])


def test_oil_temperature_drifts_along_a_sequence(tmp_path):
    runs = [type("R", (), {"excitation": Excitation.sine(1e-3, 10.0, 1.0)})() for _ in range(4)]
    tc = {**labmod.TEMPERATURE_DEFAULTS, "drift": 0.6}
    dT = labmod._sequence_temperatures(runs, tc, np.random.default_rng(0))
    step = (1.0 + labmod.REST_S) / 60.0 * 0.6
    assert np.allclose(np.diff(dT), step)
    (p,) = run_lab(SAMPLE, tmp_path, seed=1, only=[("curving", "baseline")], progress=False, conf=CONF, workers=1)
    temps = list(read_meta(p)["oil_temperature_K"].values())
    assert len(temps) == 27 and temps[-1] > temps[0]  # 27 runs, ~10 min of sequence


def _write_sample(tmp_path, edit):
    doc = yaml.safe_load(SAMPLE.read_text())
    edit(doc)
    p = tmp_path / "bad_sample.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


@pytest.mark.parametrize("edit, key", [
    (lambda d: d.update(colour="red"), "colour"),
    (lambda d: d["effects"].update(warp_drive=True), "effects.warp_drive"),
    (lambda d: d["factors"].update({"piston_rebound.a": -1.0}), "factors.piston_rebound.a"),
    (lambda d: d["factors"].update({"piston_rebound.zz": 1.1}), "factors.piston_rebound.zz"),
    (lambda d: d["values"].update({"oil.chi": "lots"}), "values.oil.chi"),
    (lambda d: d["benches"]["sensors"]["force [N]"].update(filter="kalman"), "benches.sensors.force [N].filter"),
    (lambda d: d["benches"].update(wind={"speed": 3.0}), "benches.wind"),
    (lambda d: d["benches"].update(precharge={"scatter": -0.01}), "benches.precharge"),
    (lambda d: d["benches"].update(precharge={"gauge": 1.0}), "benches.precharge.gauge"),
    (lambda d: d.pop("benches"), "benches"),
])
def test_bad_sample_exits_2_naming_file_and_key(tmp_path, capsys, edit, key):
    p = _write_sample(tmp_path, edit)
    rc = cli.main(["lab", "--sample", str(p), "--out", str(tmp_path / "out"), "--tests", "monosine"])
    err = capsys.readouterr().err
    assert rc == 2 and str(p) in err and key in err, err
    assert not (tmp_path / "out").exists()


def test_unknown_test_and_missing_sample_exit_2(tmp_path, capsys):
    assert cli.main(["lab", "--sample", str(SAMPLE), "--out", str(tmp_path), "--tests", "wind_tunnel"]) == 2
    assert "wind_tunnel" in capsys.readouterr().err
    assert cli.main(["lab", "--sample", str(tmp_path / "none.yaml"), "--out", str(tmp_path)]) == 2
    assert "none.yaml" in capsys.readouterr().err


def test_cli_writes_the_standard_layout(tmp_path, capsys):
    rc = cli.main(["lab", "--sample", str(SAMPLE), "--out", str(tmp_path), "--tests", "flowbench", "--seed", "4",
                   "--workers", "1"])
    assert rc == 0
    files = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*.parquet"))
    assert files == sorted(f"flowbench/{v}.parquet" for v in labmod.VALVE_DESIGNS)
    assert read_meta(tmp_path / files[0])["synthetic"] is True


def test_check_sample_accepts_the_shipped_samples():
    nominal = load(NOMINAL)
    for name in ("sample.yaml", "sample2.yaml", "lab2/sample.yaml", "lab2/sample2.yaml"):
        s = load_sample(CONF / "lab" / name)
        check_sample(s, nominal)
        assert Path(s["_path"]).name == Path(name).name


def test_warm_up_test_records_the_oil_temperature(tmp_path):
    """The thermal test's records carry a thermocouple channel (the protocol declares one): flat within
    noise and the converter step on a part that does not heat, rising by the dissipated heat / C_th with
    oil_thermal hidden (~2-3 K over 10 s at 1.6 A with 1200 J/K); records of tests without a temperature
    sensor have no such column."""
    base = {k: v for k, v in load_sample(SAMPLE).items() if not k.startswith("_")}
    rise = {}
    for name, eff in (("cold", False), ("hot", True)):
        s = {**base, "effects": {**base["effects"], "oil_thermal": eff}, "nominal": str(NOMINAL)}
        p = tmp_path / f"{name}.yaml"
        p.write_text(yaml.safe_dump(s))
        run_lab(p, tmp_path / name, seed=4, only=[("thermal", "baseline"), ("compliance", "baseline")],
                progress=False, workers=1)
        df, _ = read_frame(tmp_path / name / "thermal" / "baseline.parquet", "thermal")
        g = df[df["run"] == "I1.6"]
        t, T = g["time [s]"].to_numpy(), g["oil temperature [K]"].to_numpy()
        rise[name] = T[t > t[-1] - 1.0].mean() - T[t < t[0] + 1.0].mean()
        assert np.all(np.abs(T / 0.1 - np.round(T / 0.1)) < 1e-6)  # the converter's 0.1 K step
        comp, _ = read_frame(tmp_path / name / "compliance" / "baseline.parquet", "compliance")
        assert "oil temperature [K]" not in comp
    assert abs(rise["cold"]) < 0.05, rise
    assert 1.5 < rise["hot"] < 4.0, rise


def test_friction_test_refills_the_gas_to_each_precharge(tmp_path):
    """The friction test's runs record their precharge and are measured on the part with oil.P_0 set to it:
    the gas force on the rod, (P_0 - P_atm) x rod area, shifts the mean force by ~ -(14 - 4) bar x rod area
    between the runs; the seal term (seal_friction_pressure, hidden) widens the hysteresis (twice the friction)
    at 14 bar by ~2 x 1 N per bar more than at 4 bar, with no change of the mean."""
    base = {k: v for k, v in load_sample(SAMPLE).items() if not k.startswith("_")}
    nominal = load(NOMINAL)
    A_r = math.pi / 4 * nominal["geometry.D_R"] ** 2   # rod cross-section [m^2]
    width, mean = {}, {}
    for name, eff in (("plain", False), ("seal", True)):
        s = {**base, "effects": {**base["effects"], "seal_friction_pressure": eff},
             "values": {**base.get("values", {}), "seal_friction_pressure.k_p": 1e-5}, "nominal": str(NOMINAL)}
        p = tmp_path / f"{name}.yaml"
        p.write_text(yaml.safe_dump(s))
        run_lab(p, tmp_path / name, seed=4, only=[("friction", "baseline")], progress=False, workers=1)
        df, _ = read_frame(tmp_path / name / "friction" / "baseline.parquet", "friction")
        for run, g in df.groupby("run", sort=False):
            P = g["precharge [Pa]"].to_numpy()
            assert np.all(P == P[0]) and run.startswith(f"P{P[0] / 1e5:.3g}bar_I")
            if not run.endswith("_I0.32"):
                continue
            t, x, F = (g[c].to_numpy() for c in ("time [s]", "displacement [m]", "force [N]"))
            v = np.gradient(x, t)
            steady = t > t[0] + (t[-1] - t[0]) / 3   # after the first of three cycles
            mid = steady & (np.abs(x) < 0.5 * np.abs(x).max())   # mid-stroke, both directions
            width[name, P[0]] = F[mid & (v > 0)].mean() - F[mid & (v < 0)].mean()
            mean[name, P[0]] = F[steady].mean()
    lo, hi = 401325.0, 1.4e6
    shift = mean["plain", hi] - mean["plain", lo]
    assert shift == pytest.approx(-(hi - lo) * A_r, rel=0.15), (shift, A_r)   # the precharge reached the part
    grow = (width["seal", hi] - width["seal", lo]) - (width["plain", hi] - width["plain", lo])
    assert 2 * 0.6 * 1e-5 * (hi - lo) < grow < 2 * 1.4 * 1e-5 * (hi - lo), width


def test_the_rig_refuses_a_stroke_beyond_the_parts_travel(tmp_path, capsys):
    """A protocol under --conf whose monosine amplitude (0.115 m) passes the loader's bound but exceeds the
    nominal design's 0.11 m of rebound travel: the lab names the protocol file, the key and the design's
    geometry instead of recording a rod beyond its chamber (the lab-3 truth recorded it silently); nothing is
    written."""
    import shutil

    import yaml

    conf = tmp_path / "conf"
    shutil.copytree(CONF, conf)
    p = conf / "test" / "monosine.yaml"
    p.write_text(yaml.safe_dump({**yaml.safe_load(p.read_text()), "amplitude": 0.115, "frequency": 1.0}))
    out = tmp_path / "out"
    rc = cli.main(["lab", "--sample", str(conf / "lab" / "sample.yaml"), "--out", str(out), "--tests", "monosine",
                   "--conf", str(conf), "--workers", "1"])
    err = capsys.readouterr().err
    assert rc == 2 and str(p) in err and "monosine.amplitude" in err and "geometry.l_r0" in err, err
    assert not out.exists() or not list(out.rglob("*.parquet"))

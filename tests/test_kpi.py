"""KPIs on analytic signals and the thesis table builders."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from dampertwin import kpi

G = kpi.G


def mono_frame(f=13.0, fs=50_000.0, cycles=4, spikes=(), noise=0.0, seed=0):
    t = np.arange(0, cycles / f, 1 / fs)
    x = 0.005 * np.sin(2 * math.pi * f * t)
    a = 2.0 * G * np.sin(2 * math.pi * f * t + 0.3)
    for tc, amp in spikes:
        a += amp * G * np.exp(-(((t - tc) / 2e-4) ** 2))
    a += noise * np.random.default_rng(seed).standard_normal(len(t))
    return pd.DataFrame({"time [s]": t, "displacement [m]": x, "rod acceleration [m/s^2]": a})


def test_rod_acceleration_peaks_find_known_spikes():
    f = 13.0
    T = 1 / f
    t_reb = 3 * T + 0.10 * T  # rebound half: displacement rising (0 .. T/4, 3T/4 .. T)
    t_comp = 3 * T + 0.45 * T  # compression half: T/4 .. 3T/4
    df = mono_frame(spikes=[(t_reb, 9.0), (t_comp, -14.0), (1.2 * T, 30.0)])  # the earlier spike is not in the last cycle
    pk = kpi.rod_acceleration_peaks(df, f)
    base_r = 2.0 * math.sin(2 * math.pi * 0.10 + 0.3)
    base_c = 2.0 * math.sin(2 * math.pi * 0.45 + 0.3)
    assert pk["rebound"] == pytest.approx(9.0 + base_r, abs=0.02)
    assert pk["compression"] == pytest.approx(-14.0 + base_c, abs=0.02)


def test_rod_acceleration_peaks_robust_to_displacement_noise():
    df = mono_frame(spikes=[(3.3 / 13, 9.0)])
    noisy = df.copy()
    noisy["displacement [m]"] += 2e-5 * np.random.default_rng(1).standard_normal(len(df))
    assert kpi.rod_acceleration_peaks(noisy, 13.0) == kpi.rod_acceleration_peaks(df, 13.0)


def _reb_comp_frame(spike_g, f=13.0, cycles=4, fs=50_000.0):
    """Rod acceleration +3.5 g in the middle of each rebound half and -9 g in
    each compression half (smooth), with a negative spike of ``spike_g`` [g]
    early in every rebound half (as a valve opening would give)."""
    t = np.arange(0, cycles / f, 1 / fs)
    ph = (f * t) % 1.0
    x = 0.005 * np.sin(2 * math.pi * f * t)  # rebound (rising x): ph in [0, .25) U [.75, 1)
    a = np.where(np.cos(2 * math.pi * ph) >= 0, 3.5, 9.0) * np.cos(2 * math.pi * ph)
    a += spike_g * np.exp(-(((ph - 0.05) / 0.004) ** 2))
    return pd.DataFrame({"time [s]": t, "displacement [m]": x, "rod acceleration [m/s^2]": a * G})


@pytest.mark.parametrize("spike_to", [-3.3, -3.7])
def test_extremes_do_not_flip_where_the_thesis_peak_does(spike_to):
    """A spike taking the rebound-half acceleration to -3.3 g vs -3.7 g (the
    smooth rebound peak is +3.5 g): the thesis' signed max |a| jumps from
    +3.5 g to -3.7 g (the issue-14 +210 % row); the positive extreme stays
    at +3.5 g and the negative one moves with the spike by 0.4 g only."""
    base = 3.5 * math.cos(2 * math.pi * 0.05)
    df = _reb_comp_frame(spike_to - base)
    old = kpi.rod_acceleration_peaks(df, 13.0)["rebound"]
    new = kpi.rod_acceleration_extremes(df, 13.0)
    assert old == pytest.approx(3.5 if spike_to > -3.5 else spike_to, abs=0.01)
    assert new["rebound max"] == pytest.approx(3.5, abs=0.01)
    assert new["rebound min"] == pytest.approx(spike_to, abs=0.01)
    assert new["compression min"] == pytest.approx(-9.0, abs=0.01)
    assert new["compression max"] == pytest.approx(0.0, abs=0.01)


def test_extremes_average_the_steady_cycles_not_the_last():
    """One spike per cycle, heights 1, 2, 3, 6 g: with the first cycle left
    out as transient the rebound max is the mean of 2, 3, 6 g with their std."""
    f = 13.0
    df = mono_frame(f=f, cycles=4)
    df["rod acceleration [m/s^2]"] = 0.0
    t = df["time [s]"].to_numpy()
    for k, h in enumerate((1.0, 2.0, 3.0, 6.0)):
        df.loc[np.argmin(np.abs(t - (k + 0.1) / f)), "rod acceleration [m/s^2]"] = h * G
    ex = kpi.rod_acceleration_extremes(df, f, transient_cycles=1)
    assert ex["cycles"] == 3
    assert ex["rebound max"] == pytest.approx(np.mean([2, 3, 6]))
    assert ex["rebound max std"] == pytest.approx(np.std([2, 3, 6], ddof=1))
    assert kpi.rod_acceleration_extremes(df, f, transient_cycles=3)["rebound max"] == pytest.approx(6.0)
    with pytest.raises(ValueError, match="none steady"):
        kpi.rod_acceleration_extremes(df, f, transient_cycles=4)


def _extreme_rows(sim_reb_max, meas_reb_max=3.5, std=0.05):
    r = dict(no=8, case="Lower piston rebound stack stiff.", current=1.6)
    for h in kpi.HALVES:
        for e in kpi.EXTREMES:
            r[f"sim_{h}_{e}"] = r[f"meas_{h}_{e}"] = {"max": 3.5, "min": -9.0}[e]
            r[f"sim_{h}_{e}_std"] = r[f"meas_{h}_{e}_std"] = std
    r["sim_rebound_max"], r["meas_rebound_max"] = sim_reb_max, meas_reb_max
    return [r]


@pytest.mark.parametrize("sim, flagged", [(3.5 * 0.8, False), (3.5 * 0.7, True), (3.5 * 1.3, True)])
def test_flag_appears_above_threshold_only(sim, flagged):
    rows = _extreme_rows(sim)
    tab = kpi.table_6_5(rows)
    assert tab["Rebound max diff [%]"].iloc[0] == pytest.approx(kpi.percent_diff(3.5, sim))
    flags = kpi.flag_table_6_5(tab, rows, threshold_pct=25.0, near_zero_g=1.0)
    assert [f["column"] for f in flags] == (["Rebound max diff [%]"] if flagged else [])
    md = kpi.flagged_markdown(tab, flags)
    assert ("[!1]" in md) == flagged
    if flagged:
        assert "likely cause: model or calibration difference" in md
        assert md.count("[!1]") == 2  # the cell's marker and its footnote


def test_flag_causes_are_derived_from_the_data():
    causes = {}
    for label, sim, meas, std in (("near zero", 0.1, 0.5, 0.01), ("sign", -3.8, 3.4, 0.01),
                                  ("scatter", 2.0, 3.0, 1.0)):
        rows = _extreme_rows(sim, meas, std)
        flags = kpi.flag_table_6_5(kpi.table_6_5(rows), rows, threshold_pct=25.0, near_zero_g=1.0)
        assert len(flags) == 1
        causes[label] = flags[0]["cause"]
    assert causes["near zero"].startswith("measured extreme near zero")
    assert causes["sign"].startswith("simulated and measured extremes have opposite signs")
    assert "cycle-to-cycle scatter" in causes["scatter"]


def test_flag_table_6_6_threshold():
    tab = kpi.table_6_6([dict(no=1, case="Baseline", current=1.6, sim_200=-4.6, meas_200=-7.6, sim_300=-6.0,
                              meas_300=-5.2)])
    assert [f["column"] for f in kpi.flag_table_6_6(tab, 1.5)] == ["200 Hz diff [dB]"]
    assert [f["column"] for f in kpi.flag_table_6_6(tab, 0.5)] == ["200 Hz diff [dB]", "300 Hz diff [dB]"]


@pytest.mark.parametrize("sigma_g", [0.05, 0.3])
def test_white_noise_psd_level(sigma_g):
    """White noise of variance s^2 sampled at fs has the one-sided PSD
    2 s^2 / fs everywhere: the KPI recovers it within 0.5 dB."""
    fs = 5000.0
    t = np.arange(0, 60.0, 1 / fs)
    a = sigma_g * G * np.random.default_rng(7).standard_normal(len(t))
    levels = kpi.psd_levels(pd.DataFrame({"time [s]": t, "rod acceleration [m/s^2]": a}))
    expected = 10 * math.log10(2 * sigma_g**2 / fs)
    assert levels["resolution [Hz]"] == pytest.approx(2.0)
    for fc in (200, 300):
        assert levels[f"{fc} Hz [dB]"] == pytest.approx(expected, abs=0.5)


def test_psd_sees_a_tone_at_its_frequency():
    fs = 5000.0
    t = np.arange(0, 10.0, 1 / fs)
    a = G * np.sin(2 * math.pi * 300 * t)
    lv = kpi.psd_levels(pd.DataFrame({"time [s]": t, "rod acceleration [m/s^2]": a}))
    assert lv["300 Hz [dB]"] > lv["200 Hz [dB]"] + 60


def test_curving_points_and_hysteresis_of_a_viscous_damper():
    """F = c v on a sine: peak force c*v_peak both ways; loop area pi c w A^2."""
    c, A, f, fs = 2000.0, 0.025, 3.0, 5000.0
    t = np.arange(0, 2 / f, 1 / fs)
    x = A * np.sin(2 * math.pi * f * t)
    v = A * 2 * math.pi * f * np.cos(2 * math.pi * f * t)
    df = pd.DataFrame({"run": "r", "time [s]": t, "displacement [m]": x, "force [N]": c * v, "current [A]": 1.6})
    pts = kpi.curving_points(df)
    vp = A * 2 * math.pi * f
    assert pts["velocity [m/s]"].iloc[0] == pytest.approx(vp, rel=1e-4)
    assert pts.set_index("direction")["force [N]"]["rebound"] == pytest.approx(c * vp, rel=1e-3)
    assert pts.set_index("direction")["force [N]"]["compression"] == pytest.approx(-c * vp, rel=1e-3)
    assert kpi.hysteresis_area(df, f) == pytest.approx(math.pi * c * 2 * math.pi * f * A**2, rel=1e-3)


def test_dynamic_stiffness_of_kelvin_voigt():
    k, c, A, fs = 1.5e6, 300.0, 1e-4, 20_000.0
    rows = []
    for f in (5.0, 50.0):
        t = np.arange(0, 6 / f, 1 / fs)
        x = A * np.sin(2 * math.pi * f * t)
        F = k * x + c * A * 2 * math.pi * f * np.cos(2 * math.pi * f * t)
        rows.append(pd.DataFrame({"run": f"sweep_f{f:g}", "time [s]": t, "displacement [m]": x, "force [N]": F}))
    ds = kpi.dynamic_stiffness(pd.concat(rows))
    for f, (_, r) in zip((5.0, 50.0), ds.iterrows()):
        w = 2 * math.pi * f
        assert r["stiffness [N/m]"] == pytest.approx(math.hypot(k, c * w), rel=1e-4)
        assert r["loss angle [deg]"] == pytest.approx(math.degrees(math.atan2(c * w, k)), abs=1e-3)


def test_pq_curve_branches():
    fs, ramp = 1000.0, 2.0
    t = np.arange(0, 4 * ramp, 1 / fs)
    q = 1e-3 * np.where(np.mod(t, 2 * ramp) < ramp, np.mod(t, 2 * ramp) / ramp, 2 - np.mod(t, 2 * ramp) / ramp)
    rising = np.gradient(q) > 0
    dp = 4e9 * q + np.where(rising, 2e5, 0.0)  # friction hysteresis: opening branch 2 bar higher
    pq_ = kpi.pq_curve(pd.DataFrame({"time [s]": t, "flow [m^3/s]": q, "dp [Pa]": dp}), bins=10)
    op = pq_[pq_.branch == "opening"].set_index("flow [m^3/s]")["dp [Pa]"]
    cl = pq_[pq_.branch == "closing"].set_index("flow [m^3/s]")["dp [Pa]"]
    assert np.median(op.values - 4e9 * op.index.values) == pytest.approx(2e5, rel=0.05)
    assert np.median(cl.values - 4e9 * cl.index.values) == pytest.approx(0.0, abs=1e4)


# Thesis table 6.5 / 6.6 rows 1-3 as printed (inputs rounded to 0.1).
T65 = [  # no, current, sim_reb, meas_reb, diff_reb, sim_comp, meas_comp, diff_comp
    (1, 1.6, 8.1, 10.7, 23.7, -16.9, -9.2, -83.1),
    (2, 0.9, -4.7, -1.3, -247.4, -12.6, -6.1, -105.0),
    (3, 0.32, 2.4, 4.5, 45.6, -2.3, -2.7, -15.5),
]
T66 = [  # no, current, sim200, meas200, diff200, sim300, meas300, diff300
    (1, 1.6, -4.6, -7.6, 3.0, -6.0, -5.2, 0.9),
    (2, 0.9, -5.4, -12.5, 7.0, -8.8, -14.4, 5.5),
    (3, 0.32, -15.1, -16.2, 1.1, -16.1, -19.3, 3.2),
]


def _range_of(fn, sim, meas, h=0.05):
    """Range of fn(meas, sim) over the rounding interval of printed inputs."""
    vals = [fn(m, s) for s in (sim - h, sim + h) for m in (meas - h, meas + h)]
    return min(vals), max(vals)


# Row 3's compression diff is printed -15.5 although (meas - sim)/meas with
# sim -2.3, meas -2.7 is +14.8: the thesis flips the sign in that one cell
# (rows 1-2 and every rebound cell follow the formula). Its magnitude agrees.
SIGN_FLIPPED_IN_THESIS = {(3, "Compression diff [%]")}


@pytest.mark.parametrize("row", T65)
def test_table_6_5_reproduces_thesis_diff_columns(row):
    no, cur, sr, mr, dr, sc, mc, dc = row
    tab = kpi.table_6_5([dict(no=no, case="Baseline", current=cur, sim_rebound=sr, meas_rebound=mr,
                              sim_compression=sc, meas_compression=mc)], extremes=False)
    assert list(tab.columns)[:3] == ["no.", "Design case", "Active valve current [A]"]
    for col, sim, meas, printed in (("Rebound diff [%]", sr, mr, dr), ("Compression diff [%]", sc, mc, dc)):
        ours = tab[col].iloc[0]
        assert ours == pytest.approx(kpi.percent_diff(meas, sim))
        if (no, col) in SIGN_FLIPPED_IN_THESIS:
            printed = -printed
        # the printed value lies in the range the formula gives over the rounding of its inputs
        lo, hi = _range_of(kpi.percent_diff, sim, meas)
        assert lo - 0.05 <= printed <= hi + 0.05, (col, printed, lo, hi)
        assert lo <= ours <= hi


@pytest.mark.parametrize("row", T66)
def test_table_6_6_reproduces_thesis_diff_columns(row):
    no, cur, s2, m2, d2, s3, m3, d3 = row
    tab = kpi.table_6_6([dict(no=no, case="Baseline", current=cur, sim_200=s2, meas_200=m2, sim_300=s3, meas_300=m3)])
    assert tab["200 Hz diff [dB]"].iloc[0] == pytest.approx(d2, abs=0.1 + 1e-9)
    # the thesis prints |sim - meas| in its 300 Hz column (row 1: -6.0 vs -5.2 printed 0.9)
    assert abs(tab["300 Hz diff [dB]"].iloc[0]) == pytest.approx(d3, abs=0.1 + 1e-9)


def test_markdown_table():
    tab = kpi.table_6_6([dict(no=1, case="Baseline", current=1.6, sim_200=-4.6, meas_200=-7.6, sim_300=-6.0, meas_300=-5.2)])
    md = kpi.to_markdown(tab)
    assert md.splitlines()[0].startswith("| no. | Design case |") and "| 3.0 |" in md


def test_sensor_lowpass_gain_matches_butterworth():
    """2nd-order Butterworth designed by the bilinear transform with its
    cutoff prewarped: |H(f)| = 1/sqrt(1 + (w/wc)^4), w = tan(pi f / fs),
    wc = tan(pi fc / fs); measured as the steady-state gain of a sine."""
    from dampertwin.sensors import sensor_lowpass

    fs, fc = 50_000.0, 1000.0
    t = np.arange(0, 0.2, 1 / fs)
    for f in (100.0, 1000.0, 3000.0):
        y = sensor_lowpass(np.sin(2 * math.pi * f * t), fc, fs)
        late = t > 0.1
        gain = np.sqrt(2 * np.mean(y[late] ** 2))
        r = math.tan(math.pi * f / fs) / math.tan(math.pi * fc / fs)
        assert gain == pytest.approx(1 / math.sqrt(1 + r**4), rel=2e-3)
    x = np.ones(100)
    assert np.array_equal(sensor_lowpass(x, None, fs), x)


def test_flag_table_7_marks_only_cells_above_the_thresholds():
    """Tables 7.1 / 7.2 flag like 6.5 / 6.6 (the ci approach-2 table printed
    +32.5 % / -33.7 % rows with no warning)."""
    t71 = kpi.table_7_1([
        {"no": 1, "current": 1.6, "sim_rebound": 8.6, "meas_rebound": 8.4, "sim_compression": -11.2, "meas_compression": -13.1},
        {"no": 2, "current": 0.32, "sim_rebound": 3.2, "meas_rebound": 4.8, "sim_compression": -4.3, "meas_compression": -6.4}])
    flags = kpi.flag_table_7(t71, "7.1", 25.0, 1.5, "; note")
    assert [(f["no."], f["column"]) for f in flags] == [(2, "Rebound difference [%]"), (2, "Compression difference [%]")]
    assert flags[0]["diff"] == pytest.approx(100 * (4.8 - 3.2) / 4.8) and flags[0]["cause"].endswith("; note")
    md = kpi.flagged_markdown(t71, flags)
    assert md.count("[!1]") == 2 and "[!2]" in md and "[!3]" not in md
    t72 = kpi.table_7_2([{"no": 1, "current": 1.6, "sim_200": -21.4, "meas_200": -21.3, "sim_300": -17.6,
                          "meas_300": -15.0}])
    assert [f["column"] for f in kpi.flag_table_7(t72, "7.2", 25.0, 1.5)] == ["300 Hz difference [dB]"]

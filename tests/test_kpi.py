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
                              sim_compression=sc, meas_compression=mc)])
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

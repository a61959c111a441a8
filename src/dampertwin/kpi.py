"""KPIs the thesis reports, each a function of a tidy frame (unit-suffixed
columns, SI), and the table builders of thesis tables 6.5 and 6.6.

Sign conventions: tube displacement positive in rebound (extension); rod
acceleration positive up (THESIS-ERRATA 5); force positive in tension.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import signal

G = 9.80665  # [m/s^2] per g
T, X, F, A, I = "time [s]", "displacement [m]", "force [N]", "rod acceleration [m/s^2]", "current [A]"


def _fs(t: np.ndarray) -> float:
    return 1.0 / float(np.mean(np.diff(t)))


def dominant_frequency(t: np.ndarray, x: np.ndarray) -> float:
    """Frequency [Hz] of the largest spectral line of x: a zero-padded FFT
    peak, refined by the best least-squares sine fit around it (exact for a
    clean sine even over few cycles)."""
    from scipy.optimize import minimize_scalar

    f0 = _fft_peak(t, x)

    def resid(f):
        w = 2 * math.pi * f
        M = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])
        r = x - M @ np.linalg.lstsq(M, x, rcond=None)[0]
        return float(r @ r)

    res = minimize_scalar(resid, bounds=(0.9 * f0, 1.1 * f0), method="bounded", options={"xatol": 1e-9 * f0})
    return float(res.x)


def _fft_peak(t: np.ndarray, x: np.ndarray) -> float:
    """Parabolic-interpolated peak of a Hann-windowed, zero-padded FFT [Hz]."""
    n = len(x)
    nf = 1 << int(math.ceil(math.log2(8 * n)))
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(n), nf))
    k = int(np.argmax(spec[1:])) + 1
    if 1 <= k < len(spec) - 1:
        a, b, c = np.log(spec[k - 1:k + 2] + 1e-300)
        k = k + 0.5 * (a - c) / (a - 2 * b + c)
    return k * _fs(t) / nf


def harmonic(t: np.ndarray, x: np.ndarray, f: float) -> complex:
    """Complex amplitude of x at frequency f by least squares
    (x ~ Re(c e^{i 2 pi f t}) + offset)."""
    w = 2 * math.pi * f
    M = np.column_stack([np.cos(w * t), -np.sin(w * t), np.ones_like(t)])
    (a, b, _), *_ = np.linalg.lstsq(M, x, rcond=None)
    return complex(a, b)


def last_cycle(df: pd.DataFrame, f: float | None = None) -> pd.DataFrame:
    """Rows of the last full period of the (dominant) excitation frequency."""
    t = df[T].to_numpy()
    f = dominant_frequency(t, df[X].to_numpy()) if f is None else f
    return df[t >= t[-1] - 1.0 / f + 0.5 / _fs(t)]


def tube_velocity_sign(df: pd.DataFrame, f: float) -> np.ndarray:
    """+1 in rebound (extension), -1 in compression, from a sine fit of the
    displacement at f (robust to sensor noise)."""
    t = df[T].to_numpy()
    c = harmonic(t, df[X].to_numpy(), f)
    v = np.real(1j * 2 * math.pi * f * c * np.exp(1j * 2 * math.pi * f * t))
    return np.where(v >= 0, 1, -1)


def rod_acceleration_peaks(df: pd.DataFrame, frequency: float) -> dict[str, float]:
    """The thesis' literal table-6.5 KPI (THESIS-ERRATA 38): signed value of
    max |a| of the rod acceleration [g] in the rebound and in the compression
    half of the last cycle. Kept to document (and test) why it is not used:
    a small spike of the other sign flips it (issue 14); tables use
    :func:`rod_acceleration_extremes`."""
    cyc = last_cycle(df, frequency)
    a = cyc[A].to_numpy() / G
    s = tube_velocity_sign(cyc, frequency)
    out = {}
    for name, sgn in (("rebound", 1), ("compression", -1)):
        m = s == sgn
        if not m.any():
            raise ValueError(f"no {name} half-cycle in the last cycle")
        i = np.argmax(np.abs(np.where(m, a, 0.0)))
        out[name] = float(a[i])
    return out


HALVES = ("rebound", "compression")
EXTREMES = ("max", "min")


def rod_acceleration_extremes(df: pd.DataFrame, frequency: float, transient_cycles: int = 1) -> dict[str, float]:
    """Table 6.5 KPI as used here (issue 14; thesis 6.5 layout): the positive
    (``max``) and the negative (``min``) extreme of the rod acceleration [g]
    in the rebound and in the compression half of each steady cycle, averaged
    over the steady cycles (all full cycles of the record at ``frequency``
    [Hz], counted back from its end, except the first ``transient_cycles``).
    Both extremes are reported, so no KPI can change sign because a spike of
    the other sign grows slightly. Returns ``<half> <max|min>`` (mean [g]),
    ``<half> <max|min> std`` (cycle-to-cycle std [g]) and ``cycles``."""
    t = df[T].to_numpy()
    period = 1.0 / frequency
    n_full = int(np.floor((t[-1] - t[0] + 1.0 / _fs(t)) * frequency + 1e-6))  # the record spans n samples * dt
    n = n_full - transient_cycles
    if n < 1:
        raise ValueError(f"record of {t[-1] - t[0]:.4g} s holds {n_full} full cycles at {frequency:g} Hz; "
                         f"{transient_cycles} transient cycle(s) leave none steady")
    s = tube_velocity_sign(df, frequency)
    a = df[A].to_numpy() / G
    vals: dict[str, list[float]] = {f"{h} {e}": [] for h in HALVES for e in EXTREMES}
    half_dt = 0.5 / _fs(t)
    for k in range(n):  # cycle k ends k periods before the record's end
        hi = t[-1] - k * period + half_dt
        cyc = (t >= hi - period) & (t < hi)
        for h, sgn in zip(HALVES, (1, -1)):
            m = cyc & (s == sgn)
            if not m.any():
                raise ValueError(f"no {h} half-cycle in steady cycle {k}")
            vals[f"{h} max"].append(float(a[m].max()))
            vals[f"{h} min"].append(float(a[m].min()))
    out: dict[str, float] = {"cycles": n}
    for key, v in vals.items():
        out[key] = float(np.mean(v))
        out[f"{key} std"] = float(np.std(v, ddof=1)) if len(v) > 1 else float("nan")
    return out


def psd(df: pd.DataFrame, resolution: float = 2.0, column: str = A) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Welch PSD of rod acceleration in g^2/Hz (Hann, 50 % overlap,
    segment length fs/resolution). Returns (f [Hz], P [g^2/Hz])."""
    t = df[T].to_numpy()
    fs = _fs(t)
    nper = int(round(fs / resolution))
    x = df[column].to_numpy() / (G if column == A else 1.0)
    if len(x) < nper:
        raise ValueError(f"record of {len(x)} samples is shorter than one Welch segment ({nper}) at {resolution} Hz")
    return signal.welch(x, fs=fs, nperseg=nper, noverlap=nper // 2, window="hann", detrend="constant")


def psd_levels(df: pd.DataFrame, freqs=(200.0, 300.0), resolution: float = 2.0, band: float = 10.0) -> dict:
    """Table 6.6 KPI: rod-acceleration PSD in dB re 1 g^2/Hz at each frequency,
    the mean over a ``band`` [Hz] wide window centred on it (Welch resolution
    ``resolution`` [Hz]); both stated in the result."""
    f, P = psd(df, resolution)
    out = {"resolution [Hz]": float(f[1] - f[0]), "band [Hz]": band}
    for fc in freqs:
        m = (f >= fc - band / 2) & (f <= fc + band / 2)
        out[f"{fc:g} Hz [dB]"] = float(10 * np.log10(np.mean(P[m])))
    return out


def curving_points(df: pd.DataFrame) -> pd.DataFrame:
    """Curving test: for each run, the peak velocity [m/s] (from a sine fit of
    the displacement) and the peak force in rebound and compression [N] of the
    last cycle. One row per run and direction."""
    from .io import runs

    rows = []
    for name, g in runs(df):
        t, x = g[T].to_numpy(), g[X].to_numpy()
        f = dominant_frequency(t, x)
        cyc = last_cycle(g, f)
        v = abs(harmonic(cyc[T].to_numpy(), cyc[X].to_numpy(), f)) * 2 * math.pi * f
        cur = float(g[I].iloc[0]) if I in g else float("nan")
        Fc = cyc[F].to_numpy()
        rows.append({"run": name, "current [A]": cur, "velocity [m/s]": v, "direction": "rebound",
                     "force [N]": float(Fc.max())})
        rows.append({"run": name, "current [A]": cur, "velocity [m/s]": v, "direction": "compression",
                     "force [N]": float(Fc.min())})
    return pd.DataFrame(rows)


def hysteresis_area(df: pd.DataFrame, f: float | None = None) -> float:
    """Area of the force-displacement loop of the last cycle, the energy the
    damper dissipates per cycle [J] (positive for a damper)."""
    cyc = last_cycle(df, f)
    x, Fv = cyc[X].to_numpy(), cyc[F].to_numpy()
    return float(np.trapezoid(np.append(Fv, Fv[0]), np.append(x, x[0])))


def pq_curve(df: pd.DataFrame, bins: int = 40) -> pd.DataFrame:
    """Flow-bench P-Q curve: mean dp [Pa] per flow bin [m^3/s], separately for
    the opening (rising flow) and closing (falling flow) branches."""
    q = df["flow [m^3/s]"].to_numpy()
    dp = df["dp [Pa]"].to_numpy()
    t = df[T].to_numpy()
    qs = signal.savgol_filter(q, max(5, (int(0.05 * _fs(t)) // 2) * 2 + 1), 2)
    dq = np.gradient(qs, t)
    edges = np.linspace(0, np.percentile(q, 99.5), bins + 1)
    rows = []
    for branch, m in (("opening", dq > 0), ("closing", dq < 0)):
        idx = np.digitize(q[m], edges) - 1
        for b in range(bins):
            sel = idx == b
            if sel.sum() >= 3:
                rows.append({"branch": branch, "flow [m^3/s]": float(q[m][sel].mean()),
                             "dp [Pa]": float(dp[m][sel].mean())})
    return pd.DataFrame(rows)


def dynamic_stiffness(df: pd.DataFrame) -> pd.DataFrame:
    """Top-mount sweeps: |K*| = |F^|/|X^| [N/m] and loss angle [deg] per run
    from harmonic fits over all but the first cycle."""
    from .io import runs

    rows = []
    for name, g in runs(df):
        if not str(name).startswith("sweep"):
            continue
        t, x, Fv = g[T].to_numpy(), g[X].to_numpy(), g[F].to_numpy()
        f = dominant_frequency(t, x)
        m = t >= t[0] + 1.0 / f
        cx, cf = harmonic(t[m], x[m], f), harmonic(t[m], Fv[m], f)
        k = cf / cx
        rows.append({"run": name, "frequency [Hz]": f, "amplitude [m]": abs(cx), "stiffness [N/m]": abs(k),
                     "loss angle [deg]": math.degrees(math.atan2(k.imag, k.real))})
    return pd.DataFrame(rows)


# ------------------------------------------------------------ thesis tables
def table_6_5(rows: list[dict], extremes: bool = True) -> pd.DataFrame:
    """Thesis table 6.5 layout: no, case, current, then per half-cycle
    (rebound, compression) simulated / measured rod acceleration [g] and
    Diff [%] = (measured - simulated) / measured * 100. With ``extremes``
    each half-cycle has a ``max`` and a ``min`` group (row keys
    ``sim_<half>_<max|min>``, ``meas_<half>_<max|min>``; see
    :func:`rod_acceleration_extremes`); without, the thesis' single signed
    peak per half (row keys ``sim_<half>``, ``meas_<half>``)."""
    groups = [(h, e) for h in HALVES for e in EXTREMES] if extremes else [(h, None) for h in HALVES]
    out = []
    for r in rows:
        row = {"no.": r["no"], "Design case": r["case"], "Active valve current [A]": r["current"]}
        for h, e in groups:
            key, label = (f"{h}_{e}", f"{h.capitalize()} {e}") if e else (h, h.capitalize())
            row[f"{label} simulated [g]"] = r[f"sim_{key}"]
            row[f"{label} measured [g]"] = r[f"meas_{key}"]
            row[f"{label} diff [%]"] = percent_diff(r[f"meas_{key}"], r[f"sim_{key}"])
        out.append(row)
    return pd.DataFrame(out)


TABLE_6_5_DEFINITION = (
    "Rod acceleration [g], + up. For each half-cycle of the tube motion (rebound: extension; compression) "
    "`max` is the most positive and `min` the most negative value of the rod acceleration in that half, "
    "averaged over the steady cycles of the 13 Hz record ({cycles} of {total}; the first {transient} "
    "left out as transient). Diff [%] = (measured - simulated) / measured x 100 (thesis table 6.5). "
    "The thesis reports one signed peak per half; reporting both extremes keeps a KPI from changing sign "
    "when a short spike of the other sign grows slightly (issue 14).")


def flag_table_6_5(tab: pd.DataFrame, rows: list[dict], threshold_pct: float, near_zero_g: float,
                   scatter_sigmas: float = 2.0) -> list[dict]:
    """Cells of an extremes table 6.5 with |diff| > ``threshold_pct`` [%],
    each with the likely cause derived from the data (first that applies):
    a measured extreme near zero (|m| < ``near_zero_g`` [g]); simulated and
    measured extremes of opposite sign; a difference within
    ``scatter_sigmas`` cycle-to-cycle standard deviations (row keys
    ``*_std``); otherwise an unexplained model / calibration difference."""
    flags = []
    for (_, t), r in zip(tab.iterrows(), rows):
        for h in HALVES:
            for e in EXTREMES:
                col = f"{h.capitalize()} {e} diff [%]"
                d = float(t[col])
                if not abs(d) > threshold_pct:
                    continue
                sim, meas = r[f"sim_{h}_{e}"], r[f"meas_{h}_{e}"]
                sd = math.hypot(r.get(f"sim_{h}_{e}_std", 0.0) or 0.0, r.get(f"meas_{h}_{e}_std", 0.0) or 0.0)
                if abs(meas) < near_zero_g:
                    cause = (f"measured extreme near zero (|{meas:.2f}| g < {near_zero_g:g} g): "
                             "a small absolute difference is a large percentage")
                elif np.sign(sim) != np.sign(meas):
                    cause = ("simulated and measured extremes have opposite signs: the extreme is a short feature "
                             "(e.g. a valve-opening spike) that the model places or sizes differently")
                elif abs(sim - meas) <= scatter_sigmas * sd:
                    cause = (f"difference {sim - meas:+.2f} g within {scatter_sigmas:g} sigma of the "
                             f"cycle-to-cycle scatter ({sd:.2f} g)")
                else:
                    cause = "model or calibration difference (unexplained by the checks above)"
                flags.append({"table": "6.5", "no.": int(t["no."]), "case": str(t["Design case"]),
                              "current [A]": float(t["Active valve current [A]"]), "column": col, "diff": d,
                              "threshold": threshold_pct, "cause": cause})
    return flags


def flag_table_6_6(tab: pd.DataFrame, threshold_db: float) -> list[dict]:
    """Cells of table 6.6 with |diff| > ``threshold_db`` [dB]. No cause can
    be derived from the PSD levels alone: stated as unexplained."""
    flags = []
    for _, t in tab.iterrows():
        for col in ("200 Hz diff [dB]", "300 Hz diff [dB]"):
            d = float(t[col])
            if abs(d) > threshold_db:
                flags.append({"table": "6.6", "no.": int(t["no."]), "case": str(t["Design case"]),
                              "current [A]": float(t["Active valve current [A]"]), "column": col, "diff": d,
                              "threshold": threshold_db,
                              "cause": "model or calibration difference (unexplained from the PSD levels)"})
    return flags


def flag_table_7(tab: pd.DataFrame, table: str, threshold_pct: float, threshold_db: float,
                 note: str = "") -> list[dict]:
    """Cells of a table 7.1 (``Difference [%]`` columns, |diff| >
    ``threshold_pct``) or 7.2 (``Difference [dB]``, > ``threshold_db``), in
    the record format of :func:`flag_table_6_5` (case ``baseline``). Only the
    peaks and levels are at hand here, so the cause is stated as unexplained,
    followed by ``note`` (e.g. the GA budget of the profile)."""
    flags = []
    for _, t in tab.iterrows():
        for col in tab.columns:
            low = col.lower()
            if low.endswith("difference [%]"):
                thr = threshold_pct
            elif low.endswith("difference [db]"):
                thr = threshold_db
            else:
                continue
            d = float(t[col])
            if abs(d) > thr:
                flags.append({"table": table, "no.": int(t["no."]), "case": "baseline",
                              "current [A]": float(t["Active valve current [A]"]), "column": col, "diff": d,
                              "threshold": thr,
                              "cause": "model or calibration difference (unexplained from the peaks / levels)" + note})
    return flags


def flagged_markdown(tab: pd.DataFrame, flags: list[dict], digits: int = 1) -> str:
    """:func:`to_markdown` with each flagged cell marked ``[!n]`` and a
    numbered footnote per flag (threshold, likely cause)."""
    marks = {(f["no."], f["column"]): i + 1 for i, f in enumerate(flags)}
    cells = tab.astype(object).copy()
    for (no, col), n in marks.items():
        i = int(np.flatnonzero(tab["no."].to_numpy() == no)[0])
        cells.iat[i, tab.columns.get_loc(col)] = f"{tab[col].iloc[i]:+.{digits}f} [!{n}]"
    md = to_markdown(cells, digits)
    if flags:
        md += "\nFlagged cells (|diff| above the threshold of conf/compare.yaml):\n\n"
        md += "".join(f"- [!{i + 1}] row {f['no.']} ({f['case']}, {f['current [A]']:g} A), {f['column']} = "
                      f"{f['diff']:+.{digits}f} (threshold {f['threshold']:g}): likely cause: {f['cause']}\n"
                      for i, f in enumerate(flags))
    else:
        md += "\nNo cell above the flag threshold of conf/compare.yaml.\n"
    return md


def table_6_6(rows: list[dict]) -> pd.DataFrame:
    """Thesis table 6.6 layout: PSD of rod acceleration at 200 and 300 Hz
    [dB re 1 g^2/Hz], Diff [dB] = simulated - measured."""
    out = []
    for r in rows:
        out.append({
            "no.": r["no"], "Design case": r["case"], "Active valve current [A]": r["current"],
            "200 Hz simulated [dB]": r["sim_200"], "200 Hz measured [dB]": r["meas_200"],
            "200 Hz diff [dB]": r["sim_200"] - r["meas_200"],
            "300 Hz simulated [dB]": r["sim_300"], "300 Hz measured [dB]": r["meas_300"],
            "300 Hz diff [dB]": r["sim_300"] - r["meas_300"],
        })
    return pd.DataFrame(out)


def percent_diff(measured: float, simulated: float) -> float:
    """(measured - simulated) / measured * 100 (thesis tables 6.5)."""
    return (measured - simulated) / measured * 100.0


def to_markdown(df: pd.DataFrame, digits: int = 1) -> str:
    """A Markdown table (no extra dependency)."""
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.{digits}f}"
        return str(v)

    head = "| " + " | ".join(df.columns) + " |"
    sep = "|" + "|".join("---" for _ in df.columns) + "|"
    body = ["| " + " | ".join(fmt(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([head, sep, *body]) + "\n"


# ------------------------------------------------------------ thesis tables 7.1 / 7.2 (approach 2)
def table_7_1(rows: list[dict]) -> pd.DataFrame:
    """Thesis table 7.1 layout: no, current, rod acceleration peak at the
    rebound / compression stroke [g], simulated / measured and Difference
    [%] = (measured - simulated) / |measured| x 100 (the sign convention the
    thesis' rows follow, checked row by row: 1.6 A compression -9.1 / -9.9 g
    -> negative). Row keys ``sim_<half>`` / ``meas_<half>``."""
    out = []
    for r in rows:
        row = {"no.": r["no"], "Active valve current [A]": r["current"]}
        for h in HALVES:
            s, m = r[f"sim_{h}"], r[f"meas_{h}"]
            row[f"{h.capitalize()} simulated [g]"] = s
            row[f"{h.capitalize()} measured [g]"] = m
            row[f"{h.capitalize()} difference [%]"] = (m - s) / abs(m) * 100.0
        out.append(row)
    return pd.DataFrame(out)


def table_7_2(rows: list[dict]) -> pd.DataFrame:
    """Thesis table 7.2 layout: PSD of rod acceleration at 200 / 300 Hz [dB
    re 1 g^2/Hz], simulated / measured and Difference [dB] =
    |simulated - measured| (as the thesis' rows and table 6.6 print it)."""
    out = []
    for r in rows:
        row = {"no.": r["no"], "Active valve current [A]": r["current"]}
        for f in ("200", "300"):
            s, m = r[f"sim_{f}"], r[f"meas_{f}"]
            row[f"{f} Hz simulated [dB]"] = s
            row[f"{f} Hz measured [dB]"] = m
            row[f"{f} Hz difference [dB]"] = abs(s - m)
        out.append(row)
    return pd.DataFrame(out)

"""KPIs of a damper-dyno record (protocol ``dyno``, conf/test/dyno.yaml):
the F-v curve (force at the peak velocity of each speed step, per
direction), the loop area (energy dissipated per cycle) of each step and
the oil temperature at the start and the end. Pure functions of a tidy
frame (SI, unit-suffixed columns: ``time [s]``, ``displacement [m]``,
``force [N]``, optional ``oil temperature [K]``); no I/O.

Sign convention (the project's, kpi.py): displacement and velocity positive
in extension = rebound, force positive in tension; so the rebound branch has
v > 0, F > 0 and the compression branch v < 0, F < 0 for a damper, and a
damper's loop area int F dx over a cycle is positive.

Method (dyno exports rarely carry a velocity channel, so every record is
treated alike):

1. stroke reversals: turning points of the displacement, confirmed once it
   has turned back by REVERSAL of its peak-to-peak range (a zig-zag with
   hysteresis, immune to sensor noise); a half-stroke runs from one reversal
   to the next, rebound if the displacement rises;
2. velocity: Savitzky-Golay derivative of the displacement (cubic, window
   about 1/8 of the half-stroke's duration, >= 5 samples; Savitzky & Golay,
   Anal. Chem. 36 (1964) 1627), so the dyno's own rate is used as recorded;
3. speed steps: consecutive half-strokes whose speed (step 4) stays within
   STEP_TOL of the step's median (a new speed starts a new step); the first
   half-stroke of each direction of a step is its run-in and left out
   (``cycles``: use only the last N of each direction instead);
4. force at peak velocity: in each half-stroke the samples around
   mid-stroke, |x - x_mid| <= MID_BAND x half its stroke, where a sine's
   velocity peaks (|v| >= cos(asin(MID_BAND)) = 98 % of the peak) and a
   triangle's is constant, away from the reversals (no corner of a triangle
   or overshoot of the derivative there); their mean velocity and mean force
   are one F-v point (exact for a linear damper: mean(c v) = c mean(v)); a
   step's point per direction is the mean over its half-strokes;
5. loop area: int F dx over each full cycle (a rebound and the adjacent
   compression half-stroke of the step, closed; trapezoidal rule), mean over
   the step's cycles [J]; a viscous damper c at amplitude X and angular
   frequency w dissipates pi c w X^2 per cycle (Den Hartog, Mechanical
   Vibrations, 4th ed., 1956, section 2.8);
6. oil temperature at start / end: its mean over the first / last TEMP_WINDOW.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.signal import savgol_filter

from .errors import UserError

T, X, F, TEMP = "time [s]", "displacement [m]", "force [N]", "oil temperature [K]"
REVERSAL = 0.05   # a reversal: the displacement turned back by this fraction of its peak-to-peak range
STEP_TOL = 0.1    # a half-stroke whose speed differs from its step's median by more starts a new step
MID_BAND = 0.2    # F-v point: samples within this fraction of half the stroke around the half-stroke's middle
SMOOTH = 8        # velocity window: the half-stroke's duration / SMOOTH (odd, >= 5 samples; cubic)
TEMP_WINDOW = 1.0  # [s] oil temperature at start / end: mean over this long (the whole record if shorter)
DIRECTIONS = {1: "rebound", -1: "compression"}


def reversals(x: np.ndarray, hysteresis: float) -> np.ndarray:
    """Indices of the stroke reversals of ``x``: a running extreme becomes a
    reversal when ``x`` has moved back from it by more than ``hysteresis``."""
    hi = lo = 0
    d = 0
    turns = []
    for i in range(len(x)):
        xi = x[i]
        if d >= 0 and xi > x[hi]:
            hi = i
        if d <= 0 and xi < x[lo]:
            lo = i
        if d >= 0 and x[hi] - xi > hysteresis:
            turns.append(hi)
            d, lo = -1, i
        elif d <= 0 and xi - x[lo] > hysteresis:
            turns.append(lo)
            d, hi = 1, i
    return np.asarray(turns, int)


def _window(n: float) -> int:
    """An odd Savitzky-Golay window of about ``n`` samples on a ladder (shared between half-strokes), >= 5."""
    w = 5
    while w * 1.5 <= n:
        w = int(w * 1.5) | 1
    return w


def half_strokes(t: np.ndarray, x: np.ndarray, Fv: np.ndarray) -> pd.DataFrame:
    """One row per half-stroke between two reversals: start / end index,
    direction (+1 rebound, -1 compression), speed |v| [m/s] and the F-v point
    (mean velocity [m/s], mean force [N] of the samples around mid-stroke)."""
    span = float(np.ptp(x))
    if span <= 0:
        raise ValueError("the displacement is constant: no stroke")
    turns = reversals(x, REVERSAL * span)
    fs = (len(t) - 1) / (t[-1] - t[0])
    cache: dict[int, np.ndarray] = {}
    rows = []
    for a, b in zip(turns[:-1], turns[1:]):
        s = 1 if x[b] > x[a] else -1
        w = min(_window((t[b] - t[a]) * fs / SMOOTH), len(x) - (1 - len(x) % 2))
        if w not in cache:
            cache[w] = savgol_filter(x, w, 3, deriv=1, delta=1.0 / fs)
        v, xs = cache[w][a:b + 1], x[a:b + 1]
        m = np.abs(xs - 0.5 * (x[a] + x[b])) <= MID_BAND * 0.5 * abs(x[b] - x[a])
        speed = float(np.mean(s * v[m]))
        if speed <= 0:
            continue
        rows.append({"start": int(a), "end": int(b), "direction": s, "speed [m/s]": speed,
                     "velocity [m/s]": float(np.mean(v[m])), "force [N]": float(np.mean(Fv[a:b + 1][m]))})
    return pd.DataFrame(rows, columns=["start", "end", "direction", "speed [m/s]", "velocity [m/s]", "force [N]"])


def speed_steps(hs: pd.DataFrame) -> np.ndarray:
    """Step number (0, 1, ...) of each half-stroke: a new step where its
    speed leaves the current step's median by more than STEP_TOL."""
    step = np.zeros(len(hs), int)
    k, members = 0, []
    for i, p in enumerate(hs["speed [m/s]"].to_numpy()):
        if members and abs(p - float(np.median(members))) > STEP_TOL * float(np.median(members)):
            k, members = k + 1, []
        members.append(p)
        step[i] = k
    return step


def _used(g: pd.DataFrame, cycles: int | None) -> pd.DataFrame | None:
    """The half-strokes of one step the KPIs average (run-in left out), or
    None when a direction has fewer than 2 half-strokes."""
    keep = []
    for s in DIRECTIONS:
        d = g[g["direction"] == s]
        if len(d) < 2:
            return None
        if cycles is not None and cycles > len(d):
            raise UserError(f"cycles {cycles}: the speed step at {float(d['velocity [m/s]'].abs().mean()):.3g} m/s "
                            f"has only {len(d)} {DIRECTIONS[s]} half-strokes; expected at most the fewest half-strokes "
                            f"per direction of any step (or no cycles: all but the run-in one)")
        keep.append(d.iloc[1:] if cycles is None else d.iloc[-cycles:])
    return pd.concat(keep).sort_index()


def _loop_energy(x: np.ndarray, Fv: np.ndarray, used: pd.DataFrame) -> tuple[float, int]:
    """Mean int F dx [J] over the full cycles (two adjacent used half-strokes) and their number."""
    E = []
    idx = used.index.to_numpy()
    i = 0
    while i + 1 < len(idx):
        if idx[i + 1] == idx[i] + 1:
            a, b = int(used["start"].loc[idx[i]]), int(used["end"].loc[idx[i + 1]])
            xs, Fs = x[a:b + 1], Fv[a:b + 1]
            E.append(float(np.trapezoid(np.append(Fs, Fs[0]), np.append(xs, xs[0]))))
            i += 2
        else:
            i += 1
    return (float(np.mean(E)) if E else float("nan")), len(E)


def fv_steps(df: pd.DataFrame, cycles: int | None = None) -> pd.DataFrame:
    """The F-v curve and loop area of one dyno record: one row per speed step
    (in the order run) with, per direction, the mean velocity [m/s] and force
    [N] at peak speed, the loop area ``hysteresis [J]`` (energy per cycle),
    the number of half-strokes and cycles used and, with an oil-temperature
    column, the step's mean oil temperature [K]. Steps with fewer than two
    half-strokes in a direction are left out. See the module docstring."""
    t, x, Fv = (df[c].to_numpy(float) for c in (T, X, F))
    hs = half_strokes(t, x, Fv)
    hs["step"] = speed_steps(hs)
    rows = []
    for _, g in hs.groupby("step", sort=True):
        used = _used(g, cycles)
        if used is None:
            continue
        row = {"step": len(rows) + 1, "start [s]": float(t[int(used["start"].iloc[0])]),
               "end [s]": float(t[int(used["end"].iloc[-1])])}
        for s, name in DIRECTIONS.items():
            d = used[used["direction"] == s]
            row[f"{name} velocity [m/s]"] = float(d["velocity [m/s]"].mean())
            row[f"{name} force [N]"] = float(d["force [N]"].mean())
            row[f"{name} half-strokes"] = len(d)
        row["hysteresis [J]"], row["cycles"] = _loop_energy(x, Fv, used)
        if TEMP in df:
            a, b = int(used["start"].iloc[0]), int(used["end"].iloc[-1])
            row["oil temperature [K]"] = float(df[TEMP].to_numpy(float)[a:b + 1].mean())
        rows.append(row)
    return pd.DataFrame(rows)


def force_at(steps: pd.DataFrame, velocities) -> dict:
    """Force [N] at reference peak speeds ``velocities`` [m/s] (positive
    numbers) per direction, linearly interpolated along the measured F-v
    points of :func:`fv_steps`; NaN outside the measured speeds (no
    extrapolation)."""
    out = {"velocities [m/s]": [float(v) for v in velocities]}
    for name in DIRECTIONS.values():
        sp = np.abs(steps[f"{name} velocity [m/s]"].to_numpy(float))
        fo = steps[f"{name} force [N]"].to_numpy(float)
        o = np.argsort(sp)
        out[f"{name} force [N]"] = [float(np.interp(v, sp[o], fo[o], left=np.nan, right=np.nan)) if len(sp)
                                    else float("nan") for v in velocities]
    return out


def temperatures(df: pd.DataFrame, window: float = TEMP_WINDOW) -> dict:
    """Oil temperature [K] at the start and the end of the record: the mean
    over its first and last ``window`` seconds; {} without the column."""
    if TEMP not in df:
        return {}
    t, T_oil = df[T].to_numpy(float), df[TEMP].to_numpy(float)
    return {"oil temperature start [K]": float(T_oil[t <= t[0] + window].mean()),
            "oil temperature end [K]": float(T_oil[t >= t[-1] - window].mean())}


def dyno_kpis(df: pd.DataFrame, reference=None, cycles: int | None = None) -> dict:
    """Every KPI of one dyno record (one run): measured sampling rate [Hz],
    ``steps`` (rows of :func:`fv_steps`), the force at the ``reference``
    peak speeds [m/s] (if given) and the oil temperature at start and end."""
    t = df[T].to_numpy(float)
    steps = fv_steps(df, cycles)
    if not len(steps):
        raise ValueError("no speed step with >= 2 half-strokes in each direction (a record of the dyno test?)")
    out = {"rate [Hz]": (len(t) - 1) / (t[-1] - t[0]), "duration [s]": float(t[-1] - t[0]),
           "steps": [{k: _plain(v) for k, v in r.items()} for r in steps.to_dict("records")]}
    if reference is not None and len(steps):
        out["force at reference velocities"] = {k: [_plain(x) for x in v] for k, v in force_at(steps, reference).items()}
    out.update(temperatures(df))
    return out


def _plain(v):
    """A JSON-safe number (NaN -> None)."""
    if isinstance(v, (np.integer, int)):
        return int(v)
    v = float(v)
    return None if math.isnan(v) else v


__all__ = ["reversals", "half_strokes", "speed_steps", "fv_steps", "force_at", "temperatures", "dyno_kpis"]

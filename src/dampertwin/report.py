"""Plots an engineer would rather look at than read: P-Q curves, F-V and
F-x loops, mono-sine rod acceleration with valve openings, random-test PSD.
Functions take frames / designs and return matplotlib Figures (callers save).
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from . import kpi  # noqa: E402
from .design import Design  # noqa: E402
from .excitation import Excitation  # noqa: E402
from .simulation import simulate  # noqa: E402

VALVE_LABELS = {"piston_rebound": "piston rebound (shim)", "piston_intake": "piston intake",
                "base_compression": "base compression (shim)", "base_intake": "base intake"}
VALVE_COLOURS = {"piston_rebound": "tab:red", "piston_intake": "tab:orange", "base_compression": "tab:blue",
                 "base_intake": "tab:cyan"}
LPM = 60000.0  # m^3/s -> l/min


def fit_title(text: str, width_in: float, fontsize: float = 10.0) -> str:
    """``text`` wrapped so that each line fits ``width_in`` inches at ``fontsize`` points
    (an average glyph about 0.6 em wide, 10 % margin), existing line breaks kept."""
    import textwrap

    chars = max(20, int(0.9 * width_in * 72 / (0.6 * fontsize)))
    return "\n".join(textwrap.fill(line, chars) for line in text.split("\n"))


def _legend(ax, **kw) -> None:
    """A legend only when something is labelled (no empty legend boxes)."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(**kw)


def pq_figure(measured: dict[str, pd.DataFrame], simulated: dict[str, pd.DataFrame], title: str):
    """P-Q curves, one panel per valve with data: measured (opening / closing) and simulated."""
    valves = [v for v in VALVE_LABELS if v in measured or v in simulated]
    if not valves:
        raise ValueError("pq_figure: no valve has measured or simulated data")
    ncol = 1 if len(valves) == 1 else 2
    nrow = (len(valves) + ncol - 1) // ncol
    width = 6.5 if ncol == 1 else 10
    fig, axes = plt.subplots(nrow, ncol, figsize=(width, 3.8 * nrow + 0.6), constrained_layout=True, squeeze=False)
    for ax in axes.flat[len(valves):]:
        ax.remove()
    for ax, valve in zip(axes.flat, valves):
        for src, frames, style in (("measured", measured, "-"), ("simulated", simulated, "--")):
            if valve not in frames:
                continue
            pq_ = kpi.pq_curve(frames[valve])
            for branch, alpha in (("opening", 1.0), ("closing", 0.55)):
                b = pq_[pq_.branch == branch]
                ax.plot(b["flow [m^3/s]"] * LPM, b["dp [Pa]"] / 1e5, style, color=VALVE_COLOURS[valve], alpha=alpha,
                        label=f"{src}, {branch}")
        ax.set(title=VALVE_LABELS[valve], xlabel="flow [l/min]", ylabel="pressure drop [bar]")
        ax.grid(alpha=0.3)
        _legend(ax, fontsize=7)
    fig.suptitle(fit_title(title, width, 11), fontsize=11)
    return fig


def active_valve_map_figure(measured: pd.DataFrame, built, datasheet, title: str):
    """The active valve on its bench, one panel per current [A]: the record (flow against the pressure drop),
    the map built from it and the datasheet map (both on the map's grid)."""
    n = len(built.currents)
    ncol = min(n, 3)
    nrow = (n + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.6 * nrow + 0.6), constrained_layout=True,
                             squeeze=False)
    for ax in axes.flat[n:]:
        ax.remove()
    runs = {str(k): g for k, g in measured.groupby("run", sort=False)}
    for i, (ax, c) in enumerate(zip(axes.flat, built.currents)):
        g = min(runs.values(), key=lambda g: abs(float(g["current [A]"].mean()) - c))
        ax.plot(g["flow [m^3/s]"] * LPM, g["dp [Pa]"] / 1e5, ",", color="0.6", label="record")
        ax.plot(built.flow[i] * LPM, built.dps / 1e5, "o-", ms=3, color="tab:red", label="map from the record")
        ax.plot(datasheet.flow[i] * LPM, datasheet.dps / 1e5, "s--", ms=3, color="tab:blue", label="datasheet map")
        ax.set(title=f"{c:g} A", xlabel="flow [l/min]", ylabel="pressure drop [bar]")
        ax.grid(alpha=0.3)
        _legend(ax, fontsize=7)
    fig.suptitle(fit_title(title, 4.2 * ncol, 11), fontsize=11)
    return fig


def curving_figure(results: dict[float, list[tuple[str, pd.DataFrame]]], measured: pd.DataFrame | None, title: str):
    """Force-velocity (peak points) and force-displacement loops at each current."""
    fig, (ax_v, ax_x) = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    colours = {0.32: "tab:green", 0.9: "tab:orange", 1.6: "tab:red"}
    for cur, runs in sorted(results.items()):
        c = colours.get(cur, None)
        sim = pd.concat([g.assign(run=n) for n, g in runs])
        pts = kpi.curving_points(sim).sort_values("velocity [m/s]")
        for d in ("rebound", "compression"):
            p = pts[pts.direction == d]
            ax_v.plot(p["velocity [m/s]"] * (1 if d == "rebound" else -1), p["force [N]"], "--o", color=c, ms=3,
                      label=f"simulated {cur:g} A" if d == "rebound" else None)
        name, g = runs[-1]
        cyc = kpi.last_cycle(g)
        xs, fs_ = cyc["displacement [m]"].to_numpy(), cyc["force [N]"].to_numpy()
        ax_x.plot(np.append(xs, xs[0]) * 1e3, np.append(fs_, fs_[0]), "--", color=c, label=f"simulated {cur:g} A, {name}")
    if measured is not None:
        mp = kpi.curving_points(measured)
        for cur, grp in mp.groupby("current [A]"):
            for d in ("rebound", "compression"):
                p = grp[grp.direction == d].sort_values("velocity [m/s]")
                ax_v.plot(p["velocity [m/s]"] * (1 if d == "rebound" else -1), p["force [N]"], "-s",
                          color=colours.get(cur), ms=3, label=f"measured {cur:g} A" if d == "rebound" else None)
    ax_v.set(xlabel="velocity [m/s] (+ rebound)", ylabel="force [N] (+ tension)", title="force-velocity")
    ax_x.set(xlabel="displacement [mm]", ylabel="force [N]", title="force-displacement (fastest run)")
    for ax in (ax_v, ax_x):
        ax.grid(alpha=0.3)
        _legend(ax, fontsize=7)
    fig.suptitle(fit_title(title, 12, 11), fontsize=11)
    return fig


def monosine_figure(sim: pd.DataFrame, measured: pd.DataFrame | None, frequency: float, title: str):
    """Rod acceleration of the last 1.5 cycles with each valve's open
    intervals marked (simulated lifts), measured overlaid. ``sim`` is a
    simulated frame with time, rod acceleration, displacement and lifts."""
    fig, (ax, axv) = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True, height_ratios=[3, 1], constrained_layout=True)
    t = sim["time [s]"].to_numpy()
    m = t >= t[-1] - 1.5 / frequency
    ax.plot(t[m], sim["rod acceleration [m/s^2]"].to_numpy()[m] / kpi.G, color="k", lw=0.8, label="simulated")
    if measured is not None:
        tm = measured["time [s]"].to_numpy()
        mm = tm >= tm[-1] - 1.5 / frequency
        ax.plot(tm[mm], measured["rod acceleration [m/s^2]"].to_numpy()[mm] / kpi.G, color="tab:purple", lw=0.8,
                alpha=0.7, label="measured")
    _mark_kpi_peaks(ax, sim, measured, frequency)
    for k, (valve, lab) in enumerate(VALVE_LABELS.items()):
        if f"lift {valve} [m]" not in sim:
            continue
        lift = sim[f"lift {valve} [m]"].to_numpy()[m]
        axv.fill_between(t[m], k, k + 0.8 * (lift > 0), color=VALVE_COLOURS[valve], step="mid", label=lab)
        opens = t[m][1:][(lift[1:] > 0) & (lift[:-1] <= 0)]
        for to in opens:
            ax.axvline(to, color=VALVE_COLOURS[valve], ls=":", lw=1)
    ax.set(ylabel="rod acceleration [g] (+ up)")
    ax.set_title(fit_title(title, 11, 10), fontsize=10)
    ax.grid(alpha=0.3)
    _legend(ax, fontsize=8)
    axv.set(yticks=[0.4, 1.4, 2.4, 3.4], yticklabels=[v.replace("_", " ") for v in VALVE_LABELS], xlabel="time [s]")
    axv2 = axv.twinx()
    vel = np.gradient(sim["displacement [m]"].to_numpy(), t)
    axv2.plot(t[m], vel[m], color="0.5", lw=0.8)
    axv2.set_ylabel("tube velocity [m/s]")
    return fig


def kpi_peak_points(df: pd.DataFrame, frequency: float) -> tuple[float, float, dict[str, tuple[float, float]]]:
    """The table-6.5 KPI window (the last cycle, kpi.last_cycle) and the
    chosen peak of each half cycle, as kpi.rod_acceleration_peaks picks it.
    Returns (window start [s], window end [s], {half: (time [s], value [g])})."""
    cyc = kpi.last_cycle(df, frequency)
    t = cyc["time [s]"].to_numpy()
    a = cyc["rod acceleration [m/s^2]"].to_numpy() / kpi.G
    s = kpi.tube_velocity_sign(cyc, frequency)
    out = {}
    for name, sgn in (("rebound", 1), ("compression", -1)):
        if np.any(s == sgn):
            i = int(np.argmax(np.abs(np.where(s == sgn, a, 0.0))))
            out[name] = (float(t[i]), float(a[i]))
    return float(t[0]), float(t[-1]), out


def _mark_kpi_peaks(ax, sim: pd.DataFrame, measured: pd.DataFrame | None, frequency: float) -> None:
    """Shade the KPI window and mark the chosen rebound / compression peaks."""
    for label, df, colour in (("simulated", sim, "k"), ("measured", measured, "tab:purple")):
        if df is None:
            continue
        t0, t1, peaks = kpi_peak_points(df, frequency)
        if label == "simulated":
            ax.axvspan(t0, t1, color="tab:green", alpha=0.08, label="KPI window (last cycle)")
        for half, (tp, ap) in peaks.items():
            ax.plot(tp, ap, "v" if ap < 0 else "^", color=colour, ms=8, mfc="none", mew=1.5)
            ax.annotate(f"{half} {ap:+.2f} g", (tp, ap), textcoords="offset points", xytext=(6, 6 if ap > 0 else -12),
                        fontsize=7, color=colour)


def psd_figure(sim_df: pd.DataFrame, measured: pd.DataFrame | None, title: str):
    fig, ax = plt.subplots(figsize=(9, 5), constrained_layout=True)
    for label, df, c in (("simulated", sim_df, "k"), ("measured", measured, "tab:purple")):
        if df is None:
            continue
        f, P = kpi.psd(df)
        ax.semilogx(f[1:], 10 * np.log10(P[1:]), color=c, lw=0.9, label=label)
    for fc in (200, 300):
        ax.axvline(fc, color="tab:red", ls=":", lw=1)
    ax.set(xlim=(5, 1000), xlabel="frequency [Hz]", ylabel="PSD of rod acceleration [dB re 1 g^2/Hz]")
    ax.set_title(fit_title(title, 9, 10), fontsize=10)
    ax.grid(alpha=0.3, which="both")
    _legend(ax)
    return fig


RECORD_CUTOFF = 1000.0  # [Hz] low-pass of recorded displacements used as inputs


def simulate_from_record(design: Design, df: pd.DataFrame, configuration: str, current: float,
                         cutoff: float = RECORD_CUTOFF, **kw):
    """Simulate a test driven by the recorded displacement of a measurement
    (thesis 6.5), low-passed at ``cutoff`` [Hz], on the record's time grid."""
    t = df["time [s]"].to_numpy()
    ex = Excitation.from_samples(t, df["displacement [m]"].to_numpy(), cutoff=cutoff)
    return simulate(design, ex, configuration, current=current, rate=1.0 / float(np.mean(np.diff(t))), **kw)


def frame(result) -> pd.DataFrame:
    f = result.to_frame()
    if "top mount force [N]" in f:
        f["force [N]"] = f["top mount force [N]"]
    elif "rod force [N]" in f:
        f["force [N]"] = f["rod force [N]"]
    return f


__all__ = ["fit_title", "pq_figure", "curving_figure", "monosine_figure", "kpi_peak_points", "psd_figure", "simulate_from_record", "frame"]

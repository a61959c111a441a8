"""``dampertwin simulate DESIGN --test NAME [--case C] [--current I] --out DIR``:
simulate the runs of one standard test (``conf/test/NAME.yaml``) on a design
and write ``OUT/NAME.parquet`` (one row per sample, a ``run`` column, the
layout of a measured file) and ``OUT/NAME.png`` (the main output of each run
against time). The runs come from :func:`dampertwin.protocols.build_runs`
exactly as the virtual laboratory plans them, without its bench errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from . import __version__
from .design import load as load_design
from .errors import UserError
from .io import atomic_files, check_targets, write_frame
from .protocols import build_runs, flow_bench, load_protocol, passive_runs
from .simulation import simulate

# the channel drawn per configuration, with its unit label
MAIN_CHANNEL = {"valve": ("dp [Pa]", 1e-5, "pressure drop [bar]"), "damper": ("rod force [N]", 1.0, "force [N]"),
                "module": ("rod acceleration [m/s^2]", 1.0 / 9.80665, "rod acceleration [g]"),
                "topmount": ("top mount force [N]", 1.0, "top-mount force [N]")}
CURRENT_MATCH = 1e-9  # [A] a run's current equals --current within this


def select_runs(protocol: dict, test: str, case: str | None, current: float | None, seed: int = 0) -> list:
    """The runs of ``protocol`` named ``case`` and/or at ``current`` (all when
    neither is given); UserError naming the known runs when none matches."""
    runs = build_runs(protocol, seed)
    chosen = [r for r in runs if (case is None or r.name == case)
              and (current is None or abs(r.current - current) <= CURRENT_MATCH)]
    if not chosen:
        names = ", ".join(f"{r.name} ({r.current:g} A)" for r in runs)
        want = " and ".join(x for x in (f"--case {case}" if case else "",
                                         f"--current {current:g}" if current is not None else "") if x)
        raise UserError(f"test {test!r}: no run matches {want}; expected one of: {names}")
    return chosen


def runs_for_design(design, runs: list, test: str) -> list:
    """The runs a design's architecture can run: no flow-bench run of a valve it lacks; a passive damper (no
    active valve) runs each input once, at the protocol's first current (protocols.passive_runs; the current
    is not read)."""
    from .calibration.damper_fit import present_valves

    if design.pq_map is not None:
        return runs
    have = present_valves(design)
    kept = passive_runs([r for r in runs if r.configuration != "valve" or r.bench_valve in have])
    if not kept:
        raise UserError(f"test {test!r}: no run a {design.architecture} damper can run (no active valve"
                        + (", no such valve" if runs and runs[0].configuration == "valve" else "") + ")")
    return kept


# the protocol key that sets a run's displacement, named when a run's stroke exceeds the design's travel
STROKE_KEY = {"training": "strokes", "random": "bands", "verification": "bands"}


def check_travel(design, design_path: Path, runs: list, proto_path: Path, protocol: str) -> None:
    """Each damper / module run's peak displacement from mid-stroke within the design's travel: below the
    rebound chamber's length geometry.l_r0 and the compression chamber's geometry.l_c0 at mid-stroke (the
    chamber volumes A (l - |s|) reach zero there: the piston would hit an end). UserError naming both files."""
    travel = {k: float(design[k]) for k in ("geometry.l_r0", "geometry.l_c0")}
    key, limit = min(travel.items(), key=lambda kv: kv[1])
    for r in runs:
        if r.configuration not in ("damper", "module") or r.excitation.kind != "displacement":
            continue
        peak = float(np.max(np.abs(r.excitation.value)))
        if not peak < limit:
            raise UserError(f"{proto_path}: {protocol}.{STROKE_KEY.get(protocol, 'amplitude')}: run {r.name} "
                            f"moves the rod {peak:.4g} m from mid-stroke; design {design_path} has {limit:.4g} m of "
                            f"travel ({key}); expected metres within the damper's stroke (mm written as m?)")


def _run_frame(design, run, protocol: dict, where: str) -> pd.DataFrame:
    kw = {}
    if run.configuration == "valve":
        kw = {"bench_valve": run.bench_valve, "bench": flow_bench(protocol)}
    d = design
    if "precharge [Pa]" in run.meta:  # friction test: the run's gas fill is the design's oil.P_0
        d = design.with_overrides({"oil.P_0": run.meta["precharge [Pa]"]}, source=f"run {run.name}")
    try:
        r = simulate(d, run.excitation, run.configuration, current=run.current, rate=run.rate, **kw)
    except ValueError as e:  # unusable parameters for this configuration
        raise UserError(str(e)) from None
    bad = ~np.all([np.isfinite(np.asarray(v, float)) for v in r.channels.values()], axis=0)
    if not r.ok or bad.any():  # never a result with NaN rows (as the lab: a stopped run is an error)
        t = r.time[bad][0] if bad.any() else r.time[-1]
        why = f"stopped early ({r.stats.message})" if not r.ok else "gave non-finite outputs"
        raise UserError(f"{where}: run {run.name}: the simulation {why} at t = {t:.4g} s of {r.time[-1]:.4g} s; "
                        f"nothing written (a protocol value or design parameter outside what the model can run?)")
    df = r.to_frame()
    df.insert(0, "run", run.name)
    return df


def simulate_test(design_path: str | Path, test: str, out: str | Path, *, case: str | None = None,
                  current: float | None = None, conf: str | Path = "conf") -> list[Path]:
    """Simulate the chosen runs of a standard test; returns [parquet, png]."""
    design_path, conf, out = Path(design_path), Path(conf), Path(out)
    if not design_path.is_file():
        raise UserError(f"{design_path}: {'a folder' if design_path.is_dir() else 'design file not found'}; expected a design YAML "
                        "(e.g. conf/design/baseline.yaml)")
    proto_path = conf / "test" / f"{test}.yaml"
    if proto_path.is_dir():
        raise UserError(f"--test {test}: {proto_path} is a folder; expected the test's protocol YAML file")
    if not proto_path.is_file():
        known = ", ".join(sorted(p.stem for p in (conf / "test").glob("*.yaml") if p.is_file())) or "none"
        raise UserError(f"--test {test}: {proto_path} not found; expected one of: {known}")
    if current is not None and not np.isfinite(current):
        raise UserError(f"--current {current}: expected a finite current in A")
    if test == "activevalve":
        raise UserError(f"--test {test}: the model's active valve is its P/Q map (design no. 52), not a valve to "
                        f"put on a bench; a record of the test builds the part's map (stage activevalve_map)")
    targets = check_targets([out / f"{test}.parquet", out / f"{test}.png"], "--out")  # before any work
    design = load_design(design_path)
    protocol = load_protocol(proto_path)
    runs = runs_for_design(design, select_runs(protocol, test, case, current), test)
    check_travel(design, design_path, runs, proto_path, protocol["protocol"])
    where = f"design {design_path}, test {test} ({proto_path})"
    frames = [_run_frame(design, r, protocol, where) for r in runs]
    df = pd.concat(frames, ignore_index=True)
    meta = {"synthetic": True, "simulated": True, "design": str(design_path), "design_hash": design.hash(),
            "test": test, "runs": [f["run"].iloc[0] for f in frames], "dampertwin": __version__,
            **({"setting": design.setting} if design.adjusters else {}),  # the record names its clicks
            **({"architecture": design.architecture, "current_read": False} if design.pq_map is None else {})}
    out.mkdir(parents=True, exist_ok=True)
    with atomic_files(targets[:1]) as (tmp_pq,), atomic_files(targets[1:], ".png") as (tmp_png,):
        write_frame(tmp_pq, df, meta)  # both files written before either replaces an earlier one
        _plot(frames, test, design_path, design.hash(), tmp_png)
    return targets


def _plot(frames: list[pd.DataFrame], test: str, design_path: Path, design_hash: str, path: Path) -> None:
    """The main channel of each run against time, as a PNG at ``path`` (a temporary file of the caller's)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfg = frames[0].attrs.get("configuration", "damper")
    col, scale, label = MAIN_CHANNEL.get(cfg, MAIN_CHANNEL["damper"])
    fig, ax = plt.subplots(figsize=(9, 4.5), constrained_layout=True)
    for f in frames:
        c = col if col in f else "rod force [N]"
        ax.plot(f["time [s]"], f[c] * scale, lw=0.8, label=str(f["run"].iloc[0]))
    ax.set(xlabel="time [s]", ylabel=label)
    ax.set_title(f"simulated {test} test: {design_path.name} ({design_hash[:8]})", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(title="run", fontsize=7, ncol=max(1, len(frames) // 10))
    try:
        fig.savefig(path, dpi=100, format="png", metadata={"Software": None})
    finally:
        plt.close(fig)


__all__ = ["simulate_test", "select_runs"]

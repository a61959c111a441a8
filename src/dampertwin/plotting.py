"""``dampertwin plot CASE``: the standard plots of one design case, simulated
with the nominal design of the case (baseline + the case's variant) or a
given design file (e.g. a calibrated one, results/approach1/designs/CASE.yaml),
overlaid on measurements when a measured folder is given. Every title names
the design drawn and the measurement source."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib.pyplot as plt

from . import report
from .design import load as load_design
from .io import atomic_files, check_targets, read_record, runs
from .errors import UserError
from .protocols import build_runs, flow_bench, load_all
from .simulate_test import check_travel
from .variants import VALVE_DESIGNS, load_variant

CURVING_VELOCITIES = (0.1, 0.3, 0.5, 1.0, 1.5)  # subset of the protocol, for speed
PLOTS = ("pq", "curving", "monosine", "psd")  # the files OUT/CASE/NAME.png of a case (_draw's names)


def _maybe(path: Path | None, protocol: str):
    """A measured record to overlay, through the one measurement reader (same checks as fit and the stages)."""
    return read_record(path, protocol)[0] if path is not None and path.is_file() else None


def _p(data: Path | None, *parts: str) -> Path | None:
    return None if data is None else data.joinpath(*parts)


def _source_label(data: Path | None) -> str:
    """'measured: DIR (SYNTHETIC)' / 'measured: DIR' / 'no measured data'."""
    if data is None or not Path(data).is_dir():
        return "no measured data"
    from .io import read_meta

    files = sorted(Path(data).glob("*/*.parquet"))
    synthetic = any(read_meta(f).get("synthetic") for f in files[:3])
    return f"measured: {data}" + (" (SYNTHETIC lab data)" if synthetic else "")


def plot_case(case: str, conf: Path, data: Path | None, out: Path, design_path: Path | None = None) -> list[Path]:
    """PNG plots of one design case; ``design_path`` draws that design file
    instead of the nominal baseline + variant; ``data`` (a measured folder,
    <test>/<file>.parquet) is overlaid when given."""
    vpath = conf / "variant" / f"{case}.yaml"
    known = ", ".join(sorted(p.stem for p in (conf / "variant").glob("*.yaml")))
    if not re.fullmatch(r"\w[\w.-]*", case):  # a file name, never a path out of --out
        raise FileNotFoundError(f"design case {case!r}: expected the name of a file of {conf / 'variant'}; known: {known}")
    if not vpath.is_file():
        raise FileNotFoundError(f"no design case {case!r} ({vpath} missing); known: {known}")
    variant = load_variant(vpath)
    if design_path is not None:
        design = load_design(design_path)
        dlabel = f"design {design_path} ({design.hash()[:8]})"
    else:
        design = variant.apply(load_design(conf / "design" / "baseline.yaml"))
        dlabel = f"nominal design: {conf / 'design' / 'baseline.yaml'} + variant {case} ({design.hash()[:8]})"
    data = Path(data) if data is not None else None
    out = out / case
    check_targets([out / f"{name}.png" for name in PLOTS], "--out")  # before any work
    tag = f"\n{dlabel}; {_source_label(data)}"
    protocols = load_all(conf / "test")
    for name in ("curving", "monosine", "random"):  # a stroke beyond the design's travel, named before any work
        check_travel(design, design_path or conf / "design" / "baseline.yaml", build_runs(protocols[name], 0),
                     conf / "test" / f"{name}.yaml", name)
    figures: list = []  # every figure drawn first, written at the end: a bad record leaves the old set whole

    def save(fig, name):
        figures.append((fig, name))

    try:
        _draw(case, design, variant, data, tag, protocols, save)
        out.mkdir(parents=True, exist_ok=True)
        paths = [out / f"{name}.png" for _, name in figures]
        with atomic_files(paths, option="--out") as tmps:  # every file written before any replaces the old one
            for (fig, _), tmp in zip(figures, tmps):
                fig.savefig(tmp, dpi=110, format="png")
        return paths
    finally:
        for fig, _ in figures:
            plt.close(fig)


def _ok(result, what: str):
    """A simulation that ran to its end; else a UserError (nothing is drawn from a stopped run's NaN rows)."""
    if not result.ok:
        raise UserError(f"{what}: the simulation stopped early ({result.stats.message}); nothing drawn (a protocol "
                        f"value or design parameter outside what the model can run?)")
    return result


def _draw(case: str, design, variant, data: Path | None, tag: str, protocols: dict, save) -> None:
    """The case's figures (P-Q, curving, mono-sine, PSD), each handed to ``save(fig, name)``."""

    # P-Q curves: the valves of this case (alternative valves where the case changes them)
    fb = protocols["flowbench"]
    meas, sim = {}, {}
    for run in build_runs(fb):
        valve = run.bench_valve
        vd = next((n for n, (v, c) in VALVE_DESIGNS.items() if v == valve and c == case), valve)
        meas_df = _maybe(_p(data, "flowbench", f"{vd}.parquet"), "flowbench")
        if meas_df is not None:
            meas[valve] = meas_df
        r = _ok(report.simulate(design, run.excitation, "valve", bench_valve=valve, rate=run.rate,
                                bench=flow_bench(fb)), f"flowbench run {run.name}")
        sim[valve] = r.to_frame()
    save(report.pq_figure(meas, sim, f"{case}: flow-bench P-Q (solid measured, dashed simulated)" + tag), "pq")

    # F-V and F-x at the three currents
    res = {}
    for run in build_runs(protocols["curving"]):
        if run.meta["velocity [m/s]"] in CURVING_VELOCITIES:
            r = _ok(report.simulate(design, run.excitation, "damper", current=run.current, rate=run.rate),
                    f"curving run {run.name}")
            res.setdefault(run.current, []).append((run.name, report.frame(r)))
    base_curving = _maybe(_p(data, "curving", "baseline.parquet"), "curving")
    save(report.curving_figure(res, base_curving, f"{case}: curving test (solid: measured baseline)" + tag), "curving")

    # mono-sine, driven by the recorded displacement when a measurement exists
    ms = _maybe(_p(data, "monosine", f"{case}.parquet"), "monosine")
    f = protocols["monosine"]["frequency"]
    if ms is not None:
        sim_ms = _ok(report.simulate_from_record(design, runs(ms)[0][1], "module", variant.current),
                     "monosine, driven by the measured record")
    else:
        run = next(r for r in build_runs(protocols["monosine"]) if abs(r.current - variant.current) < 1e-9)
        sim_ms = _ok(report.simulate(design, run.excitation, "module", current=run.current, rate=run.rate),
                     f"monosine run {run.name}")
    save(report.monosine_figure(sim_ms.to_frame(), ms, f, f"{case}: {f:g} Hz mono-sine at {variant.current:g} A" + tag),
         "monosine")

    # random road noise PSD
    rnd = _maybe(_p(data, "random", f"{case}.parquet"), "random")
    if rnd is not None:
        sim_r = report.frame(_ok(report.simulate_from_record(design, runs(rnd)[0][1], "module", variant.current),
                                 "random, driven by the measured record"))
    else:
        run = next(r for r in build_runs(protocols["random"], 0) if abs(r.current - variant.current) < 1e-9)
        sim_r = report.frame(_ok(report.simulate(design, run.excitation, "module", current=run.current,
                                                 rate=run.rate), f"random run {run.name}"))
    save(report.psd_figure(sim_r, rnd, f"{case}: random road noise at {variant.current:g} A" + tag), "psd")

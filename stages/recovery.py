"""DVC stage `recovery`: how close the calibrated model's parameters come to
the lab's truth (issue 32, acceptance 5), only where a truth quantity has a
model counterpart: free gas at rest, oil bulk modulus, each valve's
lift-force curve over the lift range of the flow bench, the top mount's
dynamic stiffness. Reads the lab's hidden sample (conf/lab, the truth of
other physics) and the fitted overlays of approach 1 and approach 2; writes
results/recovery/ (recovery.md, recovery.json, valves.png, topmount.png,
metrics.json). SYNTHETIC: the truth is a simulation.

    python stages/recovery.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from _common import CONF, ROOT, read_overlay, stage, write_json, write_text
import _recovery as rc
from dampertwin import kpi, lab
from dampertwin.calibration.identifiability import sweep_points
from dampertwin.design import load
from dampertwin.errors import UserError
from dampertwin.io import json_safe
from dampertwin.protocols import build_runs, flow_bench, load_protocol
from dampertwin.truth import TRUTH_VERSION
from dampertwin.truth.part import build
from dampertwin.variants import TOP_MOUNTS, VALVE_DESIGNS, load_variant

VALVES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")  # fitted by approach 2
SYNTHETIC = ("SYNTHETIC: the 'truth' is the virtual lab's reference damper (a simulation of other physics than "
             "the model), not a physical part.")


def inputs(conf: Path, results: Path) -> dict:
    """The fitted overlays the stage reads (dvc.yaml deps), by role."""
    a1 = results / "approach1"
    return {**{f"valve/{n}": a1 / "valves" / n / "overlay.yaml" for n in VALVE_DESIGNS},
            "compliance": a1 / "compliance" / "overlay.yaml",
            **{f"topmount/{n}": a1 / "topmount" / n / "overlay.yaml" for n in TOP_MOUNTS},
            "approach2": results / "approach2" / "fit" / "overlay.yaml",
            "approach2_topmount": results / "approach2" / "topmount" / "overlay.yaml"}


def _variant(conf: Path, d, case: str | None):
    return load_variant(conf / "variant" / f"{case}.yaml").apply(d) if case else d


def _truth_sample(conf: Path, path: Path | None = None):
    """(sample, lab nominal design) of the lab stage's hidden sample (or of ``path``)."""
    path = conf / "lab" / lab.STAGE_SAMPLE if path is None else Path(path)
    sample = lab.load_sample(path)
    if not lab.is_truth_sample(sample):
        raise UserError(f"{path}: generator {sample.get('generator')!r}; the recovery compares against the truth "
                        f"of a '{lab.LAB3_VERSION}' sample")
    nominal = path.parent / sample["nominal"] if "nominal" in sample else conf / "lab" / "nominal.yaml"
    return sample, lab.load_design(nominal)


def gas_and_oil(base, a1, a2, p, rest) -> list[dict]:
    """Rows: free gas at rest and the oil's tangent modulus at P_ref and P0,
    truth against the nominal, approach-1 and approach-2 designs."""
    P0, P_ref = float(rest["P0"]), float(base["constants.P_ref"])
    rows = [("free gas at rest [%]", "undissolved gas volume / liquid volume at the rest state (P0 = "
             f"{P0 / 1e5:.2f} bar abs, T = {rest['T']:.2f} K); model eq. 4.14-4.15 from oil.chi, truth the Henry "
             "equilibrium of its entrained gas (isothermal bubbles)",
             lambda d: 100 * rc.model_free_gas(d), 100 * rc.truth_free_gas(p, P0))]
    for P, where in ((P_ref, "P_ref"), (P0, "P0")):
        rows.append((f"oil bulk modulus at {where} [MPa]",
                     f"tangent modulus rho dP/drho of the gas-free oil at {P / 1e5:.2f} bar abs and the design's oil "
                     "temperature; model oil.K_oil (pressure-independent), truth Murnaghan K0 + K1 (P - P_ref)",
                     lambda d: rc.model_oil_modulus(d) / 1e6, rc.truth_oil_modulus(p, P) / 1e6))
    out = []
    for name, definition, model, truth in rows:
        r = {"quantity": name, "truth": truth}
        for label, d in (("nominal", base), ("approach 1", a1), ("approach 2", a2)):
            r[label] = model(d)
        for label in ("nominal", "approach 1", "approach 2"):
            r[f"{label} error [%]"] = 100 * rc.rel_error(r[label], truth)
        r["definition"] = definition
        out.append(r)
    return out


def valve_curves(conf: Path, base, sample, lab_nominal, a1_overlays: dict, a2) -> list[dict]:
    """Per valve design: the truth's largest flow-bench lift, the truth's
    elastic force and the nominal / approach-1 / approach-2 model forces at
    CURVE_POINTS lifts up to it, and each model curve's largest relative
    error."""
    fb = load_protocol(conf / "test" / "flowbench.yaml")
    bench, runs = flow_bench(fb), build_runs(fb)
    out = []
    for name, (valve, case) in VALVE_DESIGNS.items():
        p, rest = lab.truth_part(_variant(conf, lab_nominal, case), lab_nominal, sample)
        run = next(r for r in runs if r.bench_valve == valve)
        x_max = rc.truth_bench_lift(p, rest, valve, run, bench)
        lifts = np.linspace(0.0, x_max, rc.CURVE_POINTS)
        nominal = _variant(conf, base, case)
        models = {"nominal": nominal, "approach 1": nominal.with_overrides(a1_overlays[name])}
        if case is None:
            models["approach 2"] = a2
        truth = rc.truth_lift_force(p, valve, lifts)
        curves = {k: rc.model_lift_force(d, valve, lifts) for k, d in models.items()}
        out.append({"valve design": name, "valve": valve, "model area [m^2]": rc.model_pressure_area(nominal, valve),
                    "truth area [m^2]": rc.truth_pressure_area(p, valve), "lift [m]": lifts.tolist(),
                    "truth [N]": truth.tolist(),
                    **{f"{k} [N]": v.tolist() for k, v in curves.items()},
                    **{f"{k} max error [%]": 100 * rc.curve_error(v, truth) for k, v in curves.items()}})
    return out


A2_TOP_MOUNT = "baseline, approach 2"  # the baseline top mount as approach 2 fits it (module test)


def top_mounts(conf: Path, base, sample, lab_nominal, tm_overlays: dict) -> tuple[list[dict], float]:
    """Per top mount and sweep frequency: |K*| and loss angle of the truth, the
    nominal and the fitted top mount (approach 1: component test, per top
    mount; ``baseline, approach 2``: the module-level test's fit), at the
    sweep's middle amplitude [m] (returned)."""
    freqs, amp = sweep_points(load_protocol(conf / "test" / "topmount.yaml"))
    out = []
    mounts = {**TOP_MOUNTS, A2_TOP_MOUNT: TOP_MOUNTS["baseline"]}
    for name, case in mounts.items():
        p, rest = lab.truth_part(_variant(conf, lab_nominal, case), lab_nominal, sample)
        nominal = _variant(conf, base, case)
        sides = {"truth": rc.truth_dynamic_stiffness(p, rest, freqs, amp),
                 "nominal": rc.model_dynamic_stiffness(nominal, freqs, amp),
                 "fitted": rc.model_dynamic_stiffness(nominal.with_overrides(tm_overlays[name]), freqs, amp)}
        for i, f in enumerate(freqs):
            r = {"top mount": name, "frequency [Hz]": f}
            for k, rows in sides.items():
                r[f"{k} |K*| [N/mm]"] = rows[i]["stiffness [N/m]"] / 1e3
                r[f"{k} loss angle [deg]"] = rows[i]["loss angle [deg]"]
            for k in ("nominal", "fitted"):
                r[f"{k} |K*| error [%]"] = 100 * rc.rel_error(r[f"{k} |K*| [N/mm]"], r["truth |K*| [N/mm]"])
                r[f"{k} loss angle diff [deg]"] = r[f"{k} loss angle [deg]"] - r["truth loss angle [deg]"]
            out.append(r)
    return out, amp


def valve_table(curves: list[dict]) -> pd.DataFrame:
    rows = []
    for c in curves:
        rows.append({"valve design": c["valve design"], "truth lift range [mm]": 1e3 * c["lift [m]"][-1],
                     "truth F(0) [N]": c["truth [N]"][0], "truth F(x_max) [N]": c["truth [N]"][-1],
                     "model area [mm^2]": 1e6 * c["model area [m^2]"], "truth area [mm^2]": 1e6 * c["truth area [m^2]"],
                     **{f"{k} max error [%]": c.get(f"{k} max error [%]", "not fitted")
                        for k in ("nominal", "approach 1", "approach 2")}})
    return pd.DataFrame(rows)


def markdown(gas: list[dict], curves: list[dict], tm: list[dict], amp: float, sample: dict, raw: dict) -> str:
    """The recovery tables with their definitions; ``raw``: the gas-content
    parameters behind the free-gas row."""
    g = pd.DataFrame(gas)
    gas_note = ("- The parameters behind the free gas differ in definition and are not compared 1:1: the model's "
                "oil.chi (gas volume fraction of the emulsion at P_ref, of which the share theta(P0) is "
                f"undissolved at rest, eq. 4.14) nominal {raw['oil.chi nominal']:.5g}, approach 1 "
                f"{raw['oil.chi approach 1']:.5g}, approach 2 {raw['oil.chi approach 2']:.5g}; the truth's "
                f"alpha_free (free gas at P0 in m^3 at P_ref per m^3 of liquid) {raw['truth alpha_free']:.5g}.")
    defs = "\n".join(f"- {r['quantity']}: {r['definition']}." for r in gas)
    return (
        f"# Recovery of the lab's truth by the calibrated model (issue 32, acceptance 5)\n\n{SYNTHETIC}\n\n"
        f"Truth: {TRUTH_VERSION}, sample conf/lab/{Path(sample.get('_path', 'sample.yaml')).name} "
        f"(hash {sample.get('_hash', '')}), as built, ideal sensors. Nominal: conf/design/baseline.yaml (and the "
        "design variants), the fits' starting point. Approach 1: the flow-bench, compliance and top-mount overlays "
        "(results/approach1); approach 2: results/approach2/fit/overlay.yaml and results/approach2/topmount/overlay.yaml. "
        "Error = (model - truth) / |truth|. Only quantities with a counterpart on both sides are compared.\n\n"
        "## Gas content and oil bulk modulus\n\n"
        + kpi.to_markdown(g.drop(columns="definition"), 4) + "\n\n" + defs + "\n" + gas_note + "\n\n"
        "## Valve lift-force curves over the flow bench's lift range\n\n"
        "Force holding the valve at lift x, for x from 0 to the largest lift of the truth's valve on its "
        f"flow-bench run (conf/test/flowbench.yaml, the test's flow ramp; {rc.CURVE_POINTS} lifts). Model: "
        "F_pre + a(e^(bx) - 1) + c(e^(dx) - 1) (eq. 4.19, THESIS-ERRATA 17) with the nominal or fitted "
        "coefficients. Truth: shim stacks truth.shims.elastic_force (plate bending, preload, backing set; "
        "without the shim-to-shim friction hysteresis around it), intake valves the coil spring F_S + K_S x, "
        "of the part as built. Max error = max over the lifts of |F_model - F_truth| / |F_truth|. Approach 2 "
        "fits the four baseline valves only. The areas the pressure drop acts on (model: eq. 4.21 / 4.22 on the "
        "drawings; truth: plate-bending equivalent area or seat land, as built) differ, so equal forces need not "
        "mean equal opening pressures.\n\n"
        + kpi.to_markdown(valve_table(curves), 2) + "\n\n"
        "## Top mount: dynamic stiffness and loss angle\n\n"
        f"Sines of {amp * 1e3:g} mm (the middle amplitude of the sweep) at the sweep's frequencies, "
        f"{rc.SINE_CYCLES} cycles at {rc.SINE_RATE:g} Hz, first harmonic over all but the first cycle. Truth: its "
        "`topmount` configuration (generalised Maxwell rubber with the Payne effect); model: AutoBushFD with the "
        "nominal or the fitted parameters: approach 1 on the component test (per top mount), approach 2 on the "
        "module-level test (`baseline, approach 2`, stage approach2_topmount).\n\n"
        + kpi.to_markdown(pd.DataFrame(tm), 3) + "\n")


def figures(curves: list[dict], tm: list[dict], out: Path) -> None:
    """valves.png (lift-force curves) and topmount.png (|K*|, loss angle)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {"truth": "-", "nominal": ":", "approach 1": "--", "approach 2": "-."}
    fig, axes = plt.subplots(2, 4, figsize=(16, 7.5), constrained_layout=True)
    for ax, c in zip(axes.T.ravel(), curves):
        x = 1e3 * np.asarray(c["lift [m]"])
        for k, st in styles.items():
            if f"{k} [N]" in c:
                ax.plot(x, c[f"{k} [N]"], st, label=k)
        ax.set(title=c["valve design"], xlabel="lift [mm]", ylabel="force [N]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend()
    fig.suptitle("Valve lift-force curves over the flow bench's lift range: truth vs model (SYNTHETIC lab)")
    fig.savefig(out / "valves.png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    t = pd.DataFrame(tm)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
    for (name, g), col in zip(t.groupby("top mount", sort=False), ("C0", "C1", "C2")):
        for k, st in (("truth", "-o"), ("nominal", ":"), ("fitted", "--s")):
            axes[0].semilogx(g["frequency [Hz]"], g[f"{k} |K*| [N/mm]"], st, color=col, label=f"{name} {k}")
            axes[1].semilogx(g["frequency [Hz]"], g[f"{k} loss angle [deg]"], st, color=col, label=f"{name} {k}")
    axes[0].set(xlabel="frequency [Hz]", ylabel="|K*| [N/mm]", title="top mount dynamic stiffness")
    axes[1].set(xlabel="frequency [Hz]", ylabel="loss angle [deg]", title="loss angle")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Top mount: truth vs nominal vs fitted (SYNTHETIC lab)")
    fig.savefig(out / "topmount.png", dpi=90, metadata={"Software": None})
    plt.close(fig)


def metrics(gas, curves, tm, sample) -> dict:
    """Summary for `dvc metrics` (errors in %, loss-angle differences in deg)."""
    t = pd.DataFrame(tm)
    m = {"synthetic": True, "truth": TRUTH_VERSION, "sample_hash": sample.get("_hash", ""),
         "free_gas_error_pct": {k: gas[0][f"{k} error [%]"] for k in ("nominal", "approach 1", "approach 2")},
         "oil_modulus_P_ref_error_pct": {k: gas[1][f"{k} error [%]"] for k in ("nominal", "approach 1", "approach 2")},
         "valve_curve_max_error_pct": {k: {c["valve design"]: c[f"{k} max error [%]"] for c in curves
                                           if f"{k} max error [%]" in c} for k in ("nominal", "approach 1", "approach 2")}}
    for k in ("nominal", "fitted"):
        m[f"topmount_{k}_stiffness_max_abs_error_pct"] = {n: float(g[f"{k} |K*| error [%]"].abs().max())
                                                          for n, g in t.groupby("top mount", sort=False)}
        m[f"topmount_{k}_loss_angle_max_abs_diff_deg"] = {n: float(g[f"{k} loss angle diff [deg]"].abs().max())
                                                          for n, g in t.groupby("top mount", sort=False)}
    return m


def run(conf: Path, results: Path, out: Path, sample_path: Path | None = None) -> dict:
    """Compute the recovery from ``conf`` and the fitted overlays under
    ``results`` and write it to ``out``; returns the metrics."""
    paths = inputs(conf, results)
    overlays = {k: read_overlay(p) for k, p in paths.items()}
    base = load(conf / "design" / "baseline.yaml")
    a1 = base.with_overrides(overlays["compliance"])
    a2 = base.with_overrides(overlays["approach2"])
    sample, lab_nominal = _truth_sample(conf, sample_path)
    p, rest = lab.truth_part(lab_nominal, lab_nominal, sample)
    truth_inputs = build(lab_nominal, lab_nominal, sample["truth"])[2]  # the sample's values (not as built)
    gas = gas_and_oil(base, a1, a2, p, rest)
    a1_valves = {n: overlays[f"valve/{n}"] for n in VALVE_DESIGNS}
    curves = valve_curves(conf, base, sample, lab_nominal, a1_valves, a2)
    tm, amp = top_mounts(conf, base, sample, lab_nominal, {**{n: overlays[f"topmount/{n}"] for n in TOP_MOUNTS},
                                                           A2_TOP_MOUNT: overlays["approach2_topmount"]})
    m = metrics(gas, curves, tm, sample)
    out.mkdir(parents=True, exist_ok=True)
    raw = {**{f"oil.chi {k}": float(d["oil.chi"]) for k, d in (("nominal", base), ("approach 1", a1),
                                                                 ("approach 2", a2))},
           "truth alpha_free": float(truth_inputs["alpha_free"])}
    write_text(out / "recovery.md", markdown(gas, curves, tm, amp, sample, raw))
    doc = {"note": SYNTHETIC, "synthetic": True, "truth": TRUTH_VERSION, "sample_hash": sample.get("_hash", ""),
           "gas_and_oil": gas, "gas_parameters": raw, "valves": curves, "topmount": {"amplitude [m]": amp, "rows": tm},
           "inputs": {k: str(v.relative_to(results.parent)) for k, v in paths.items()}}
    write_text(out / "recovery.json", json.dumps(json_safe(doc), indent=1, sort_keys=True, allow_nan=False) + "\n")
    figures(curves, tm, out)
    write_json(out / "metrics.json", m)
    return m


def main(*argv: str) -> None:
    """``python stages/recovery.py`` (the DVC stage: the lab stage's sample, results/recovery), or, for
    another lab sample whose records the study was run on (`dvc exp run -S measured=...`),
    ``python stages/recovery.py --sample conf/lab/sample2.yaml --out results/recovery_sample2``."""
    import argparse

    ap = argparse.ArgumentParser(prog="stages/recovery.py")
    ap.add_argument("--sample", default=None, help="lab-3 sample YAML (default: the lab stage's)")
    ap.add_argument("--out", default=None, help="output folder (default results/recovery)")
    a = ap.parse_args(list(argv))
    sample = Path(a.sample) if a.sample else None
    if sample is not None and not sample.is_file():
        raise UserError(f"--sample {sample}: file not found; expected a lab-3 sample YAML (conf/lab/*.yaml)")
    run(CONF, ROOT / "results", Path(a.out) if a.out else ROOT / "results" / "recovery", sample)


if __name__ == "__main__":
    stage(main, "recovery")

"""Damper-level fit of the valves' and the gas's parameters on dyno records
(displacement in, force out), without a flow bench: approach 2's idea
(thesis ch. 7: calibrate at damper level on the damper's own records) with
the fitting core's GA and the residual-Jacobian intervals of
:mod:`.component_fits`. No file I/O (``dampertwin fit damper`` reads and
writes: :mod:`dampertwin.cli_fit_files`).

Every record is simulated with the design at the record's own clicker
setting (``design.adjusters``, the record's ``setting`` metadata), so one fit
on one setting predicts the others. The fitted files' records together make
the objective (eq. 6.2's int |F_meas - F_sim| dt summed over them); the
other files are predicted and their force NRMSE reported per file.
"""

from __future__ import annotations

import numpy as np

from ..design import Design
from ..design.adjusters import design_for_record
from ..design.architecture import UNUSED_NUMBERS
from ..design.schema import BY_NUMBER, VALVES
from ..io import runs
from .approach1 import Channel, force_chain_nominal, record_input, through_sensor
from .component_fits import RecordProblem, _fit_model, search_specs
from .ga import FitError, GASettings

# default search space: per valve of the architecture its preload and spring coefficient a (eq. 4.19), the
# emulsion's gas content (windows: factors on the design's value, clipped to its calibration bounds) and the
# load cell's zero (OFFSET)
VALVE_WINDOWS = {"F_preload": ([0.5, 2.0], "lin"), "a": ([0.3, 3.0], "log")}
BLEED_WINDOW = ([0.2, 5.0], "log")  # a shim stack's bleed area (eq. 4.21), unless a clicker moves it
GAS_ITEMS = ({"key": "oil.chi", "window": [0.2, 5.0], "scale": "log"},)
FORCE_COLUMN = "rod force [N]"
FORCE = Channel((FORCE_COLUMN,), lambda c, nuis: c[FORCE_COLUMN])  # (plots, reports: the problem's channel)
OFFSET = "sensor.force_offset"  # the load cell's zero [N]: a dyno tares it, often with the gas force included


def present_valves(design: Design) -> tuple[str, ...]:
    """The valve blocks the design's architecture has."""
    absent = {BY_NUMBER[n].group for n in UNUSED_NUMBERS[design.architecture]}
    return tuple(v for v in VALVES if v not in absent)


def default_items(design: Design) -> list[dict]:
    """The default search space of a damper fit (module docstring), without the parameters a clicker moves
    (their values are the records' settings)."""
    moved = {a.key for a in design.adjusters.values()}
    windows = dict(VALVE_WINDOWS, A_bleed=BLEED_WINDOW)
    items = [{"key": f"{v}.{n}", "window": w, "scale": s} for v in present_valves(design)
             for n, (w, s) in windows.items() if f"{v}.{n}" not in moved
             and (n != "A_bleed" or design.group(v).get("A_bleed", 0.0) > 0)]  # intake discs have no bleed
    return items + [dict(i) for i in GAS_ITEMS] + [{"key": OFFSET, "bounds": [-offset_range(design),
                                                                           offset_range(design)]}]


def offset_range(design: Design) -> float:
    """Half-width [N] of the load cell's zero searched: three times the static gas force (P_0 - P_atm) A_rod,
    at least 100 N (a dyno that tared the load cell on the mounted damper took the gas force out)."""
    a_rod = np.pi * design["geometry.D_R"] ** 2 / 4.0
    return max(100.0, 3.0 * (design["oil.P_0"] - design.constant("P_atm")) * a_rod)


class DamperProblem(RecordProblem):
    """Dyno records -> simulations of a design population, each record at its own setting (``extra['design']``)
    and through the load cell's zero (``sensor.force_offset``); file 0 holds every fitted record (the base
    class's objective sums over them), the others are predicted files."""

    def simulate(self, rows: list[dict], which=None):
        from ..simulation import simulate_batch

        out = {}
        nuis = {k: np.array([r[k] for r in rows], float) for k in (rows[0] if rows else {}) if k.startswith("sensor.")}
        for fi, (_, cases) in enumerate(self.files):
            if which is not None and fi not in which:
                continue
            out[fi] = []
            for t, meas, ex, extra in cases:
                designs = [extra["design"].with_overrides({k: v for k, v in r.items() if not k.startswith("sensor.")})
                           for r in rows]
                fs = 1.0 / (t[1] - t[0])
                _, ch, status = simulate_batch(designs, ex, "damper", rate=fs, duration=t[-1] - t[0],
                                               channels=[FORCE_COLUMN], current=extra["current"], **self.sim_kw)
                sim = np.asarray(through_sensor(FORCE_COLUMN, None, fs)(ch, nuis), float)[:, : len(t)]
                sim[status != 0] = np.nan
                out[fi].append(sim)
        return out


def _current(design: Design, g, name: str) -> float:
    """The active-valve current of a record [A]: its column for the thesis' damper, 0 (not read) for a passive one."""
    if design.pq_map is None:
        return 0.0
    if "current [A]" not in g:
        raise FitError(f"{name}: the design {design.name!r} is semi-active; its records need a 'current [A]' column")
    return float(g["current [A]"].iloc[0])


def _cases(design: Design, name: str, frame, meta: dict, cutoff: float) -> list:
    """[(t, force, excitation, {design, current}) per run] of one record file at its setting."""
    d = design_for_record(design, meta, where=name)
    cases = []
    for _, g in runs(frame):
        t = g["time [s]"].to_numpy()
        fs = 1.0 / float(np.mean(np.diff(t)))
        _, ex = record_input(g, "displacement [m]", "displacement", min(cutoff, 0.4 * fs))
        cases.append((t - t[0], g["force [N]"].to_numpy(), ex, {"design": d, "current": _current(design, g, name)}))
    return cases


def fit_damper_records(design: Design, fitted: list, predicted: list, items=None, *, settings: GASettings, seed: int,
                       cutoff: float = 1000.0, where: str = "damper search space", scheduler=None):
    """Fit on ``fitted`` = [(name, frame, metadata), ...], predict ``predicted`` (same form). Returns the
    fit.json dict (parameters, intervals, NRMSE per file with its role and setting), the problem and its
    simulations at the optimum (component_fits.report)."""
    if not fitted:
        raise FitError("a damper fit needs at least one record to fit")
    items = items or default_items(design)
    specs = search_specs(design, items, "", where, force_chain_nominal(None))
    moved = {a.key for a in design.adjusters.values()} & {s.key for s in specs}
    if moved:
        raise FitError(f"{where}: {', '.join(sorted(moved))} is moved by a clicker (adjusters:); its values are the "
                       f"records' settings, not a fitted parameter")
    per_file = [(str(name), _cases(design, name, f, meta, cutoff), meta) for name, f, meta in fitted]
    files = [(" + ".join(n for n, _, _ in per_file), [c for _, cases, _ in per_file for c in cases])]
    files += [(str(name), _cases(design, name, f, meta, cutoff)) for name, f, meta in predicted]
    problem = DamperProblem(design, "damper", FORCE, files, {}, force_chain_nominal(None))
    result, problem, sims = _fit_model(problem, specs, "damper", "damper", settings, seed,
                                       {"objective_name": "eq. 6.2 int |F_meas - F_sim| dt [N*s], summed over the "
                                                          "fitted records", "architecture": design.architecture})
    result["files"] = _per_file(per_file, predicted, problem, sims)
    if design.adjusters:
        result["flags"] += [f"{name}: the record names no clicker setting; simulated at the design's "
                            f"{design.setting}" for name, _, meta in [*fitted, *predicted] if not meta.get("setting")]
    return result, problem, sims


def _per_file(per_file, predicted, problem, sims) -> dict:
    """NRMSE per record file (fitted ones split out of the joint file 0), with its role and clicker setting."""
    from .friction_fit import nrmse

    out, k = {}, 0
    for name, cases, meta in per_file:
        sim = np.concatenate([s[0] for s in sims[0][k:k + len(cases)]])
        meas = np.concatenate([c[1] for c in cases])
        out[name] = {"role": "fitted", "nrmse": nrmse(meas, sim), "records": len(cases), "samples": len(meas),
                     "setting": dict(meta.get("setting") or {})}
        k += len(cases)
    for fi, (name, _, meta) in enumerate(predicted, start=1):
        cases = problem.files[fi][1]
        meas = np.concatenate([c[1] for c in cases])
        sim = np.concatenate([s[0] for s in sims[fi]])
        out[str(name)] = {"role": "predicted", "nrmse": nrmse(meas, sim), "records": len(cases),
                          "samples": len(meas), "setting": dict(meta.get("setting") or {})}
    return out


__all__ = ["DamperProblem", "default_items", "fit_damper_records", "present_valves"]

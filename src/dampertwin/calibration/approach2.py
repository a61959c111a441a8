"""Calibration approach 2 (thesis chapter 7): the valves and the compliance
fitted together at damper level on one training signal (L1485-1490,
fig. 7.1; damper rigidly mounted, fig. 7.3a; recorded actuator position as
the input, L1430), with sensitivity-based concurrent GAs.

1. Sensitivity (L1434-1436, L1527-1536): the simulated damper force of the
   training signal at every instant; parameters grouped by valve (4 groups);
   SALib's grouped Saltelli design (thesis: 32 x (2 x 4 + 2) = 320 runs);
   gas content and oil bulk modulus left out (L1530: "uniform impact with
   respect to time"). Index curves -> weights (:mod:`.sensitivity`).
2. Concurrent GAs (Algorithm 1, L1452-1479, :mod:`.concurrent`): one GA per
   valve scored by eq. 7.1, J_i = int I_i(t) |F_test - F_sim| dt, plus one
   unweighted GA for gas content and oil bulk modulus (L1511); best solution
   by the unweighted residual int |F_test - F_sim| dt.

Problem / cost / optimiser as in approach 1 (:mod:`.approach1`): the same
batched record evaluation (``approach1._records``: measured - simulated
force through the documented load-cell bandwidth, failed members with their
reason), only the costs (eq. 7.1 weights) and the optimiser differ. The top
mount is fitted on the module-level test (:mod:`.module_topmount`, thesis
7.2; issue 37). No file I/O here;
calibration never reads the lab's hidden sample.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..design import Design
from ..errors import UserError
from ..io import runs
from ..parallel import DaskMap
from . import sensitivity as sens
from .approach1 import _Channel, _context, _need, _record_input, _records, specs_from_config, trapezoid_weights
from .concurrent import ConcurrentSettings, GAGroup
from .ga import FitResult, GASettings
from .optimisers import run
from .problem import GroupedAbs, Problem
from ..sensors import sensor_lowpass

WHERE = "conf/calibration/approach2.yaml"
VALVES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")
COMPLIANCE = "compliance"
DAMPER_COLUMNS = ("time [s]", "displacement [m]", "force [N]", "current [A]")


@dataclass(frozen=True)
class SensitivitySettings:
    """Named settings of the sensitivity stage (profile: n_base, n_max; the
    rest from conf/calibration/approach2.yaml ``sensitivity``). The base
    sample is doubled from ``n_base`` up to ``n_max`` (None: n_base, no
    convergence check) until the weight curves change by less than ``tol``
    (:func:`.sensitivity.run_converged`)."""

    n_base: int = 32
    second_order: bool = True
    num_resamples: int = 100
    conf_level: float = 0.95
    mask_rel_std: float = 1e-6
    n_max: int | None = None
    tol: float = 0.1

    @classmethod
    def from_config(cls, c, n_base: int | None = None, where: str = WHERE + ": sensitivity") -> "SensitivitySettings":
        if not hasattr(c, "get"):
            raise UserError(f"{where}: expected a mapping")
        known = {"n_base", "second_order", "num_resamples", "conf_level", "mask_rel_std", "n_max", "tol"}
        unknown = set(c) - known
        if unknown:
            raise UserError(f"{where}: unknown key(s) {sorted(unknown)}; expected {sorted(known)}")
        n = int(n_base if n_base is not None else c.get("n_base", 32))
        n_max = c.get("n_max")
        n_max = n if n_max is None else int(n_max)
        if n_max < n or n_max & (n_max - 1):
            raise UserError(f"{where}: n_max = {n_max}; expected a power of 2 >= n_base = {n} "
                            "(conf/profile/*.yaml approach2.sensitivity)")
        tol = c.get("tol", 0.1)
        if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not tol > 0:
            raise UserError(f"{where}: tol = {tol!r}; expected a share of the weight that moves between "
                            "instants, in (0, 1]")
        return cls(n, bool(c.get("second_order", True)), int(c.get("num_resamples", 100)),
                   float(c.get("conf_level", 0.95)), float(c.get("mask_rel_std", 1e-6)), n_max, float(tol))


def groups_from_config(design: Design, cal: dict) -> tuple[list[GAGroup], GAGroup]:
    """(valve groups, compliance group) from conf/calibration/approach2.yaml:
    ``valves: {valve: shim|intake}``, ``parameters: {shim: [...], intake:
    [...]}`` (items as in approach 1: name + bounds or window) and
    ``compliance: [...]`` (items with key)."""
    valves = _need(cal, "valves", WHERE)
    params = _need(cal, "parameters", WHERE)
    if not isinstance(valves, dict) or not valves:
        raise UserError(f"{WHERE}: valves must map each valve to its kind (shim | intake)")
    groups = []
    for v, kind in valves.items():
        if v not in VALVES:
            raise UserError(f"{WHERE}: valves.{v}: unknown valve; expected {', '.join(VALVES)}")
        if kind not in params:
            raise UserError(f"{WHERE}: valves.{v} = {kind!r}: no parameters.{kind} list")
        groups.append(GAGroup(v, tuple(specs_from_config(design, params[kind], prefix=f"{v}.",
                                                         where=f"{WHERE}: parameters.{kind}"))))
    comp = GAGroup(COMPLIANCE, tuple(specs_from_config(design, _need(cal, "compliance", WHERE),
                                                       where=f"{WHERE}: compliance")))
    return groups, comp


INPUT_CUTOFF_MIN_RATIO = 4.0  # input low-pass corner / highest fundamental of the protocol's motion, at least


def excitation_fundamental(protocol: dict) -> float:
    """Highest fundamental frequency [Hz] of a damper-level protocol's
    motion: sine bursts (``strokes`` peak-to-peak [m], ``velocities`` peak
    [m/s]; x = s/2 sin(2 pi f t) -> f = v / (pi s)) or band-limited noise
    (``bands``: the highest band edge)."""
    if "bands" in protocol:
        return float(max(b["band"][1] for b in protocol["bands"]))
    if "strokes" in protocol and "velocities" in protocol:
        return float(max(protocol["velocities"]) / (np.pi * min(protocol["strokes"])))
    if "frequency" in protocol:
        return float(protocol["frequency"])
    raise UserError(f"protocol {protocol.get('protocol')!r}: no strokes / velocities, bands or frequency to bound "
                    "its motion's bandwidth")


def input_cutoff(cal: dict, protocols: dict) -> float:
    """``input_cutoff`` [Hz] of conf/calibration/approach2.yaml, checked
    against the motion of the damper-level protocols it filters ({name:
    protocol}): the zero-phase low-pass of the recorded displacement must
    keep the motion (corner >= INPUT_CUTOFF_MIN_RATIO x its highest
    fundamental) and stay below 0.45 x the sampling rate (above it
    ``Excitation.from_samples`` does not filter at all). A corner far above
    the motion passes the displacement transducer's noise, differentiated
    into velocity noise that drives the valves (issue 12, the lab's
    training record, nominal design, three currents: 1 kHz -> 200 Hz cut
    the residual int |F_meas - F_sim| dt by 25 % and the solver steps 5x)."""
    c = _need(cal, "input_cutoff", WHERE)
    if isinstance(c, bool) or not isinstance(c, (int, float)) or not np.isfinite(c) or c <= 0:
        raise UserError(f"{WHERE}: input_cutoff = {c!r}; expected a positive frequency [Hz]")
    for name, proto in protocols.items():
        f = excitation_fundamental(proto)
        if c < INPUT_CUTOFF_MIN_RATIO * f:
            raise UserError(f"{WHERE}: input_cutoff = {c:g} Hz would filter the {name} motion itself (highest "
                            f"fundamental {f:.1f} Hz); expected >= {INPUT_CUTOFF_MIN_RATIO:g} x that, "
                            f"{INPUT_CUTOFF_MIN_RATIO * f:.0f} Hz")
        rate = proto.get("rate")
        if rate is not None and c >= 0.45 * float(rate):
            raise UserError(f"{WHERE}: input_cutoff = {c:g} Hz is not below 0.45 x the {name} sampling rate "
                            f"({float(rate):g} Hz): the recorded displacement would not be filtered")
    return float(c)


def check_damper_record(df: pd.DataFrame, where: str, runs_wanted=None, tail_s: float | None = None) -> pd.DataFrame:
    """A damper-level record (training / verification): the columns it needs
    and the runs asked for (``runs_wanted``: labels, None = all); with
    ``tail_s`` [s] only the last ``tail_s`` seconds of each run (the ci
    profile: 1.95 s = the 10 mm-stroke bursts of the training signal, which
    start in a rest, so the model starts from rest)."""
    miss = [c for c in DAMPER_COLUMNS if c not in df]
    if miss:
        raise UserError(f"{where}: missing column(s) {miss}; a damper-level record needs {list(DAMPER_COLUMNS)}")
    if runs_wanted:
        have = [n for n, _ in runs(df)]
        bad = [r for r in runs_wanted if r not in have]
        if bad:
            raise UserError(f"{where}: no run(s) {bad}; runs present: {', '.join(map(str, have))} "
                            f"(conf/profile/*.yaml approach2.runs)")
        df = df[df["run"].astype(str).isin([str(r) for r in runs_wanted])]
    if tail_s is not None:
        if not tail_s > 0:
            raise UserError(f"{where}: tail_s = {tail_s!r}; expected a positive duration [s] (conf/profile/*.yaml "
                            "approach2.tail_s)")
        parts = []
        for _, g in runs(df):
            t = g["time [s]"].to_numpy()
            parts.append(g[t >= t[-1] - tail_s])
        df = pd.concat(parts, ignore_index=True)
    return df


def damper_cases(measured: pd.DataFrame, cutoff: float):
    """(t, force, excitation, {'current'}) per run, driven by the recorded displacement."""
    cases = []
    for _, g in runs(measured):
        t, ex = _record_input(g, "displacement [m]", "displacement", cutoff)
        cases.append((t, g["force [N]"].to_numpy(), ex, {"current": float(g["current [A]"].iloc[0])}))
    return cases


def force_channel(bandwidth: float | None, fs: float) -> _Channel:
    """Simulated rod force through the documented load-cell bandwidth."""
    def fn(c, nuis):
        X = c["rod force [N]"]
        return np.array([sensor_lowpass(r, bandwidth, fs) if np.all(np.isfinite(r)) else r for r in X])

    return _Channel(("rod force [N]",), fn)


class TrainingProblem(Problem):
    """Design + training records + free parameters: residual force of a
    batch of parameter rows (one simulate_batch per record), the simulated
    force (sensitivity output) and, once weighted (:meth:`weighted`), the
    concurrent GAs' scores (cost :class:`~.problem.GroupedAbs`)."""

    def __init__(self, design: Design, measured: pd.DataFrame, specs, cutoff: float, bandwidth: float | None,
                 max_wall_s: float | None):
        self.design, self.specs = design, list(specs)
        self.cases = damper_cases(measured, cutoff)
        fs = 1.0 / (self.cases[0][0][1] - self.cases[0][0][0])
        self.records = _records(design, self.specs, self.cases, "damper", force_channel(bandwidth, fs), max_wall_s)
        self.measured = np.concatenate([c[1] for c in self.cases])
        self.time = np.concatenate([c[0] + sum(cc[0][-1] + (cc[0][1] - cc[0][0]) for cc in self.cases[:i])
                                    for i, c in enumerate(self.cases)])  # runs laid end to end [s]
        self.run = np.concatenate([np.full(len(c[0]), n) for n, c in enumerate(self.cases)])
        self.quad = trapezoid_weights_per_case(self.cases)
        self.context = _context(design, measured)
        self.cost = self.records.cost  # unweighted until weighted()

    def evaluate(self, X: np.ndarray) -> tuple[np.ndarray, list]:
        """Measured - simulated (sensor-filtered) force [N], (m, T), and the failure reasons."""
        return self.records.evaluate(X)

    def simulated(self, X: np.ndarray) -> np.ndarray:
        """Simulated (sensor-filtered) force [N], (m, T); NaN rows for failures."""
        R, _ = self.evaluate(X)
        return self.measured[None, :] - R

    def weighted(self, W: np.ndarray) -> "TrainingProblem":
        """Score eq. 7.1 for the valve groups (rows of ``W``), the unweighted
        integral for the compliance group (L1511) and, last, the unweighted
        integral (best-solution tracker of Algorithm 1)."""
        self.cost = GroupedAbs(self.quad, W, n_unweighted=1)
        return self

    def scores(self, X: np.ndarray) -> tuple[np.ndarray, list]:
        """(m, G + 1) scores and the failure reasons: a failed row's NaN
        residuals give NaN scores, which the concurrent GAs count with its
        reason."""
        R, why = self.evaluate(X)
        return self.cost(R), why


def trapezoid_weights_per_case(cases) -> np.ndarray:
    return np.concatenate([trapezoid_weights(c[0]) for c in cases])


def sensitivity(design: Design, measured: pd.DataFrame, cal: dict, settings: SensitivitySettings, seed: int, *,
                bandwidth: float | None, max_wall_s: float | None, batch: int = 16, progress: bool = True,
                scheduler: str | None = None, weights: "sens.WeightSettings | None" = None):
    """Time-resolved grouped Sobol indices of the simulated training force
    (valve groups only), the runs simulated ``batch`` at a time, locally or
    (a Dask ``scheduler`` address) one batch per task on the cluster: the
    same batches, the same numbers. N doubled up to ``settings.n_max`` until
    the eq.-7.1 weight curves (``weights``) change by less than
    ``settings.tol`` (``result.meta["convergence"]``). Returns (problem,
    SobolResult, Y)."""
    from ..progress import progress as tqdm

    groups, _ = groups_from_config(design, cal)
    sg = [sens.Group(g.name, g.specs) for g in groups]
    specs = [s for g in groups for s in g.specs]
    prob = TrainingProblem(design, measured, specs, float(_need(cal, "input_cutoff", WHERE)), bandwidth, max_wall_s)

    def output(X):
        if scheduler:
            cluster = DaskMap(scheduler)
            try:
                return np.vstack([y for y, _ in cluster(prob.simulated, [X[lo:lo + batch]
                                                                          for lo in range(0, len(X), batch)])])
            finally:
                cluster.close()
        parts = []
        for lo in tqdm(range(0, len(X), batch), desc="sensitivity runs", disable=not progress, leave=False):
            parts.append(prob.simulated(X[lo:lo + batch]))
        return np.vstack(parts)

    wset = weights or sens.WeightSettings()
    res, Y, conv = sens.run_converged(sg, output, settings.n_base, settings.n_max or settings.n_base, settings.tol,
                                      seed, lambda r: sens.result_weights(r, prob.time, wset),
                                      second_order=settings.second_order, num_resamples=settings.num_resamples,
                                      conf_level=settings.conf_level, mask_rel_std=settings.mask_rel_std)
    res.meta["convergence"] = conv
    return prob, res, Y


def nominal_channels(design: Design, prob: TrainingProblem, channels, max_wall_s: float | None = None) -> dict:
    """Simulated ``channels`` (e.g. the valve lifts, ``lift <valve> [m]``)
    of ``design`` on the training problem's runs, laid end to end like
    ``prob.time``: {channel: (T,)}; NaN where a run failed."""
    from ..simulation import simulate_batch

    out = {c: [] for c in channels}
    for t, _, ex, extra in prob.cases:
        _, ch, _ = simulate_batch([design], ex, "damper", rate=1.0 / (t[1] - t[0]), duration=t[-1] - t[0],
                                  channels=list(channels), max_wall_s=max_wall_s, **extra)
        for c in channels:
            y = np.full(len(t), np.nan)
            v = np.asarray(ch[c][0], float)[:len(t)]
            y[:len(v)] = v
            out[c].append(y)
    return {c: np.concatenate(v) for c, v in out.items()}


def fit(design: Design, measured: pd.DataFrame, cal: dict, W: np.ndarray, group_names: list[str],
        settings: GASettings, seed: int, *, bandwidth: float | None, checkpoint=None, scheduler=None,
        progress: bool = True, free=None) -> tuple[FitResult, TrainingProblem]:
    """Algorithm 1 on the training record: the valve groups weighted by
    ``W`` (rows in ``group_names`` order, from the sensitivity stage), the
    compliance unweighted. ``free``: the valve parameter keys the record
    determines (the identifiability stage's decision; None: all of
    ``parameters``); the others stay at the drawings' values and a group
    with none left has no GA."""
    groups, comp = groups_from_config(design, cal)
    if [g.name for g in groups] != list(group_names):
        raise UserError(f"{WHERE}: valve groups {[g.name for g in groups]} differ from those of the sensitivity "
                        f"weights {list(group_names)}; rerun the sensitivity stage")
    if free is not None:
        groups, W = free_groups(groups, W, free)
    specs = [s for g in groups + [comp] for s in g.specs]
    prob = TrainingProblem(design, measured, specs, float(_need(cal, "input_cutoff", WHERE)), bandwidth,
                           settings.max_wall_s)
    if W.shape != (len(groups), len(prob.measured)):
        raise UserError(f"sensitivity weights have shape {W.shape}; the training record needs "
                        f"({len(groups)}, {len(prob.measured)}): rerun the sensitivity stage on the same record")
    x0 = {s.key: design[s.key] for s in specs}
    res = run(prob.weighted(W), groups + [comp], ConcurrentSettings(settings), seed=seed, x0=x0,
              checkpoint=checkpoint, scheduler=scheduler, label="approach 2 (concurrent GAs)", progress=progress,
              context=prob.context)
    return res, prob


def identifiability(design: Design, measured: pd.DataFrame, cal: dict, W: np.ndarray, group_names: list[str], *,
                    bandwidth: float | None, max_wall_s: float | None) -> tuple[dict, TrainingProblem]:
    """Which of each valve group's ``parameters`` the training record
    determines at the drawings' values, each group on its eq.-7.1-weighted
    residual (``W`` rows in ``group_names`` order; :mod:`.determined`, rule
    from ``identifiability`` of conf/calibration/approach2.yaml). Returns
    ({group: decision}, problem)."""
    from .determined import Rule, decide

    rule = Rule.from_config(_need(cal, "identifiability", WHERE))
    groups, _ = groups_from_config(design, cal)
    if [g.name for g in groups] != list(group_names):
        raise UserError(f"{WHERE}: valve groups {[g.name for g in groups]} differ from those of the sensitivity "
                        f"weights {list(group_names)}; rerun the sensitivity stage")
    specs = [s for g in groups for s in g.specs]
    prob = TrainingProblem(design, measured, specs, float(_need(cal, "input_cutoff", WHERE)), bandwidth, max_wall_s)
    return decide(prob.records, groups, W, {s.key: design[s.key] for s in specs}, rule), prob


def free_groups(groups: list[GAGroup], W: np.ndarray, free) -> tuple[list[GAGroup], np.ndarray]:
    """The valve groups reduced to the ``free`` keys (rows of ``W`` of
    groups left with none dropped); a key no group has is an error."""
    free = set(free)
    known = {s.key for g in groups for s in g.specs}
    if free - known:
        raise UserError(f"identifiability decision names {sorted(free - known)}, not in {WHERE} parameters "
                        f"({sorted(known)}); rerun the approach2_identifiability stage")
    kept = [(i, GAGroup(g.name, tuple(s for s in g.specs if s.key in free))) for i, g in enumerate(groups)]
    kept = [(i, g) for i, g in kept if g.specs]
    return [g for _, g in kept], W[[i for i, _ in kept]]


# ------------------------------------------------------------ verification metrics
def force_agreement(t: np.ndarray, measured: np.ndarray, simulated: np.ndarray) -> dict:
    """Damper-force agreement of a record: int |F_meas - F_sim| dt [N s],
    RMS error [N] and NRMSE (RMS error / RMS of the measurement) [-]."""
    e = measured - simulated
    return {"iae [N*s]": float(np.trapezoid(np.abs(e), t)), "rmse [N]": float(np.sqrt(np.mean(e**2))),
            "nrmse [-]": float(np.sqrt(np.mean(e**2)) / np.sqrt(np.mean(measured**2)))}


__all__ = ["SensitivitySettings", "TrainingProblem", "groups_from_config", "free_groups", "identifiability", "check_damper_record", "damper_cases",
           "excitation_fundamental", "input_cutoff",
           "sensitivity", "nominal_channels", "fit", "force_agreement", "VALVES", "COMPLIANCE"]

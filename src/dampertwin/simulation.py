"""``simulate``: run one test on a design and return a tidy Result."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .design import Design
from .excitation import Excitation
from .model import layout as L
from .model.active_valve import pack_map
from .model.damper import RHS_BY_CFG
from .model.layout import N_OUT, O, initial_state, state_scales
from .model.params import pack, parameter_problems
from .model.sparsity import sparsity
from .solver import STATUS_TEXT, RunStats, integrate, integrate_batch

DEFAULT_RATE = 10_000.0  # [Hz] output sampling
# Integrator by tolerance (bench/README.md "Speed levers"): at the fits' tolerances the Rosenbrock-W method
# ROS34PW2 (order 3, Jacobian kept over steps) is the cheaper one; at tight tolerances (the lab's truth, 1e-8)
# the order-4 Rodas4 takes far fewer steps. ``method=None`` picks by rtol.
TIGHT_RTOL = 1e-6  # rtol at or below this: "rodas4", above: "ros34pw2"


def default_method(rtol: float) -> str:
    """The integrator ``simulate`` uses when none is named: "rodas4" at rtol <= TIGHT_RTOL, else "ros34pw2"."""
    return "rodas4" if rtol <= TIGHT_RTOL else "ros34pw2"
CHUNK_S = 0.25  # [s] simulated time between wall-time checks
DEFAULT_RTOL = 1e-4  # KPIs within 0.01 % of rtol 1e-8 on the 13 Hz mono-sine (bench/solver.py)


@dataclass
class Result:
    """Simulated channels on a uniform time grid (SI), plus solver statistics."""

    configuration: str
    time: np.ndarray
    channels: dict[str, np.ndarray]
    stats: RunStats
    design_hash: str
    current: float
    meta: dict = field(default_factory=dict)

    def __getitem__(self, column: str) -> np.ndarray:
        return self.channels[column]

    @property
    def ok(self) -> bool:
        return self.stats.ok

    def to_frame(self) -> pd.DataFrame:
        """Tidy frame, one row per sample, unit-suffixed columns. Warns when the
        run did not finish (rows after the stop are NaN)."""
        if not self.ok:
            warnings.warn(f"simulation of design {self.design_hash[:12]} stopped early ({self.stats.message}); "
                          "rows after the stop are NaN", RuntimeWarning, stacklevel=2)
        df = pd.DataFrame({"time [s]": self.time, **self.channels})
        df.attrs.update({"configuration": self.configuration, "design_hash": self.design_hash,
                         "current [A]": self.current, "solver": self.stats.message, **self.meta})
        return df


_BENCH_COLUMNS = {"flow [m^3/s]": O.U, "p upstream [Pa]": O.P_R, "p downstream [Pa]": O.P_C,
                  "lift [m]": O.X0, "valve flow [m^3/s]": O.Q0}
_TOPMOUNT_COLUMNS = {"displacement [m]": O.U, "velocity [m/s]": O.V, "top mount force [N]": O.F_TM}


def _channels(cfg: int, out: np.ndarray) -> dict[str, np.ndarray]:
    if cfg == L.CFG_VALVE:
        ch = {k: out[:, i] for k, i in _BENCH_COLUMNS.items()}
        ch["dp [Pa]"] = ch["p upstream [Pa]"] - ch["p downstream [Pa]"]
        return ch
    if cfg == L.CFG_TOPMOUNT:
        return {k: out[:, i] for k, i in _TOPMOUNT_COLUMNS.items()}
    skip = {O.F_TM, O.A_ROD} if L.base_configuration(cfg) == L.CFG_DAMPER else set()
    return {name: out[:, i] for i, (name, _) in enumerate(L.OUTPUTS) if i not in skip}


def _setup(design, excitation, configuration, current, effects, bench_valve, bench=None, step=None):
    if configuration not in L.CONFIGURATIONS:
        raise ValueError(f"configuration must be one of {list(L.CONFIGURATIONS)}, got {configuration!r}")
    cfg = L.CONFIGURATIONS[configuration]
    want = "flow" if cfg == L.CFG_VALVE else "displacement"
    if excitation.kind != want:
        raise ValueError(f"the {configuration!r} configuration takes a {want} excitation, got {excitation.kind!r}")
    if cfg == L.CFG_VALVE and bench_valve not in L.VALVE_NAMES:
        raise ValueError(f"the valve configuration needs bench_valve in {L.VALVE_NAMES}, got {bench_valve!r}")
    if not (isinstance(current, (int, float, np.floating)) and np.isfinite(current)):
        raise ValueError(f"current must be a finite number [A], got {current!r}")
    if cfg in (L.CFG_DAMPER, L.CFG_MODULE) and design.pq_map is not None:  # a passive design has no map
        lo, hi = float(np.min(design.pq_map.currents)), float(np.max(design.pq_map.currents))
        if not lo - 1e-9 <= current <= hi + 1e-9:
            raise ValueError(f"current {current!r} A is outside the active-valve map of design {design.name!r} "
                             f"({lo:g}-{hi:g} A); the map is not extrapolated")
    for name, v in (step or {}).items():
        if v is not None and not (isinstance(v, (int, float, np.floating)) and np.isfinite(v)):
            raise ValueError(f"{name} must be a finite number, got {v!r}")
    p = pack(design, current=current, effects=effects, bench_valve=bench_valve, **(bench or {}), **(step or {}))
    p[L.P.EX_T0] = excitation.t0
    p[L.P.EX_DT] = excitation.dt
    return L.variant(cfg, p), p  # the extended configuration when an effect with states is on


_SPARSITY_CACHE: dict = {}


def _problem(configuration, cfg, P, ex, aux, t_out):
    """Compiled RHS, state scales and probed sparsity of a configuration.
    The probe is cached per configuration, pattern of zero parameters (a
    zero removes a dependency) and value of the selector parameters (the
    flow bench's valve selects which valve's equations, hence states, run; the
    architecture which chambers and valves are coupled)."""
    rhs = RHS_BY_CFG[cfg]
    rows = np.asarray(P)[:8]
    key = (configuration, cfg, np.packbits(rows != 0.0).tobytes(), rows.shape, rows[:, L.P.BENCH_VALVE].tobytes(),
           rows[:, L.P.ARCH].tobytes())
    sp = _SPARSITY_CACHE.get(key)
    if sp is None:
        sp = sparsity(rhs, cfg, rows, ex, aux, (float(t_out[0]), float(t_out[-1])))
        _SPARSITY_CACHE[key] = sp
    return dict(scales=state_scales(cfg), n_rhs_out=N_OUT, sparsity=sp, chunk_s=CHUNK_S), rhs


def _time_grid(excitation, duration, rate):
    t_end = excitation.t_end if duration is None else excitation.t0 + duration
    n = int(round((t_end - excitation.t0) * rate)) + 1
    return excitation.t0 + np.arange(n) / rate


def simulate(design: Design, excitation: Excitation, configuration: str = "module", *,
             current: float = 1.6, effects: dict | None = None, bench_valve: str | None = None,
             rate: float = DEFAULT_RATE, duration: float | None = None, rtol: float = DEFAULT_RTOL,
             atol: float | None = None, max_steps: int = 2_000_000, max_wall_s: float | None = 600.0,
             h_max: float = 1e-3, bench: dict | None = None, method: str | None = None,
             current_before: float | None = None, current_step_time: float | None = None) -> Result:
    """Simulate one test. ``configuration`` is "valve" (flow bench; needs
    ``bench_valve``), "damper" (rod fixed), "module" (rod on the top mount) or
    "topmount" (the top mount alone, deflection prescribed).
    Outputs are sampled at ``rate`` [Hz]; ``method`` is the integrator
    ("ros34pw2" or "rodas4"; default: by rtol, :func:`default_method`). A run that hits the step or
    wall-time cap returns with ``result.ok`` False and NaN after the stop.
    ``bench`` sets the flow bench (``bench_volume`` [m^3], ``bench_back_pressure`` [Pa]).
    ``current_before`` [A]: the current commanded until ``current_step_time`` [s] (default the
    record's start), ``current`` after it: a current step, which only the effect
    active_valve_driver sees (default: no step)."""
    step = {"current_before": current_before,
            "current_step_time": excitation.t0 if current_step_time is None else current_step_time}
    cfg, p = _setup(design, excitation, configuration, current, effects, bench_valve, bench, step)
    bad = parameter_problems(p, configuration)
    if bad:
        raise ValueError(f"design {design.name!r} cannot be simulated in the {configuration!r} configuration: "
                         + "; ".join(bad))
    t_out = _time_grid(excitation, duration, rate)
    y0 = initial_state(p, cfg)
    aux = model_map(design.pq_map)
    ex = excitation.array()
    kw, rhs = _problem(configuration, cfg, p[None, :], ex, aux, t_out)
    out, _, stats = integrate(rhs, p, ex, aux, y0, t_out, rtol=rtol, atol=atol, max_steps=max_steps,
                              max_wall_s=max_wall_s, h_max=h_max, method=method or default_method(rtol), **kw)
    return Result(configuration, t_out, _channels(cfg, out), stats, design.hash(), current)


def model_map(pq_map) -> np.ndarray:
    """The active-valve map as the model's ``aux`` vector (active_valve.pack_map); for a design without an
    active valve (pq_map None, a passive architecture) a zero map the model never reads."""
    if pq_map is None:
        return pack_map([0.0, 1.0], [0.0, 1.0], np.zeros((2, 2)))
    return pack_map(pq_map.currents, pq_map.dps, pq_map.flow)


def simulate_batch(designs: list[Design], excitation: Excitation, configuration: str = "module", *,
                   current: float = 1.6, effects: dict | None = None, bench_valve: str | None = None,
                   rate: float = DEFAULT_RATE, duration: float | None = None, rtol: float = DEFAULT_RTOL,
                   atol: float | None = None, max_steps: int = 2_000_000, max_wall_s: float | None = None,
                   h_max: float = 1e-3, channels: list[str] | None = None, bench: dict | None = None,
                   method: str | None = None):
    """Run many designs (a GA population) through one test in parallel
    threads. All designs must share one active-valve map. Returns
    (time, {column: array[m, n_t]}, statuses[m]) — status 0 is ok."""
    if not designs:
        raise ValueError("simulate_batch needs at least one design")
    pqm = designs[0].pq_map
    if any(d.pq_map != pqm for d in designs[1:]):
        raise ValueError("simulate_batch: all designs must share one active-valve map")
    setups = [_setup(d, excitation, configuration, current, effects, bench_valve, bench) for d in designs]
    cfg = setups[0][0]
    if any(s[0] != cfg for s in setups):
        raise ValueError("simulate_batch: all designs must switch the effects with states (layout.STATE_EFFECTS: "
                         "active_valve_lag, valve_friction_current, oil_thermal, aeration, fixture_resonance, "
                         "active_valve_driver, gas_release) alike")
    P = np.vstack([s[1] for s in setups])
    problems = [parameter_problems(p, configuration) for p in P]
    invalid = np.array([bool(b) for b in problems])
    Y0 = np.vstack([initial_state(p, cfg) if not bad else np.zeros(L.N_STATES[cfg]) for p, bad in zip(P, invalid)])
    t_out = _time_grid(excitation, duration, rate)
    names = {name: i for i, (name, _) in enumerate(L.OUTPUTS)}
    if cfg == L.CFG_VALVE:
        names = dict(_BENCH_COLUMNS)
    elif cfg == L.CFG_TOPMOUNT:
        names = dict(_TOPMOUNT_COLUMNS)
    cols = list(names) if channels is None else channels
    unknown = [c for c in cols if c not in names]
    if unknown:
        raise ValueError(f"unknown output channel(s) {unknown}; expected some of {list(names)}")
    idx = np.array([names[c] for c in cols], np.int64)
    aux = model_map(pqm)
    ex = excitation.array()
    valid = P[~invalid] if np.any(~invalid) else P[:1]
    kw, rhs = _problem(configuration, cfg, valid, ex, aux, t_out)
    OUT, status, _ = integrate_batch(rhs, P, ex, aux, Y0, t_out, rtol=rtol, atol=atol, max_steps=max_steps,
                                     max_wall_s=max_wall_s, h_max=h_max, channels=idx, skip=invalid, method=method or default_method(rtol),
                                     **kw)
    return t_out, {c: OUT[:, :, k] for k, c in enumerate(cols)}, status


def batch_status_text(status: np.ndarray) -> list[str]:
    """Readable reason per member of a ``simulate_batch`` status array."""
    return [STATUS_TEXT.get(int(s), f"status {int(s)}") for s in status]

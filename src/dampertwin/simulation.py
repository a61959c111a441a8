"""``simulate``: run one test on a design and return a tidy Result."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .design import Design
from .excitation import Excitation
from .model import layout as L
from .model.params import initial_state, pack
from .solver import RunStats, integrate, integrate_batch

DEFAULT_RATE = 10_000.0  # [Hz] output sampling
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
        """Tidy frame, one row per sample, unit-suffixed columns."""
        df = pd.DataFrame({"time [s]": self.time, **self.channels})
        df.attrs.update({"configuration": self.configuration, "design_hash": self.design_hash,
                         "current [A]": self.current, "solver": self.stats.message, **self.meta})
        return df


_BENCH_COLUMNS = {"flow [m^3/s]": L.O_U, "p upstream [Pa]": L.O_P_R, "p downstream [Pa]": L.O_P_C,
                  "lift [m]": L.O_X0, "valve flow [m^3/s]": L.O_Q0}


def _channels(cfg: int, out: np.ndarray) -> dict[str, np.ndarray]:
    if cfg == L.CFG_VALVE:
        ch = {k: out[:, i] for k, i in _BENCH_COLUMNS.items()}
        ch["dp [Pa]"] = ch["p upstream [Pa]"] - ch["p downstream [Pa]"]
        return ch
    if cfg == L.CFG_TOPMOUNT:
        return {"displacement [m]": out[:, L.O_U], "velocity [m/s]": out[:, L.O_V],
                "top mount force [N]": out[:, L.O_F_TM]}
    skip = {L.O_F_TM, L.O_A_ROD} if cfg == L.CFG_DAMPER else set()
    return {name: out[:, i] for i, (name, _) in enumerate(L.OUTPUTS) if i not in skip}


def _setup(design, excitation, configuration, current, effects, bench_valve, bench=None):
    if configuration not in L.CONFIGURATIONS:
        raise ValueError(f"configuration must be one of {list(L.CONFIGURATIONS)}, got {configuration!r}")
    cfg = L.CONFIGURATIONS[configuration]
    want = "flow" if cfg == L.CFG_VALVE else "displacement"
    if excitation.kind != want:
        raise ValueError(f"the {configuration!r} configuration takes a {want} excitation, got {excitation.kind!r}")
    if cfg == L.CFG_VALVE and bench_valve not in L.VALVE_NAMES:
        raise ValueError(f"the valve configuration needs bench_valve in {L.VALVE_NAMES}, got {bench_valve!r}")
    p = pack(design, current=current, effects=effects, bench_valve=bench_valve, **(bench or {}))
    p[L.P_EX_T0] = excitation.t0
    p[L.P_EX_DT] = excitation.dt
    return cfg, p


def _time_grid(excitation, duration, rate):
    t_end = excitation.t_end if duration is None else excitation.t0 + duration
    n = int(round((t_end - excitation.t0) * rate)) + 1
    return excitation.t0 + np.arange(n) / rate


def simulate(design: Design, excitation: Excitation, configuration: str = "module", *,
             current: float = 1.6, effects: dict | None = None, bench_valve: str | None = None,
             rate: float = DEFAULT_RATE, duration: float | None = None, rtol: float = DEFAULT_RTOL,
             atol: float | None = None, max_steps: int = 2_000_000, max_wall_s: float | None = 600.0,
             h_max: float = 1e-3, bench: dict | None = None) -> Result:
    """Simulate one test. ``configuration`` is "valve" (flow bench; needs
    ``bench_valve``), "damper" (rod fixed), "module" (rod on the top mount) or
    "topmount" (the top mount alone, deflection prescribed).
    Outputs are sampled at ``rate`` [Hz]. A run that hits the step or
    wall-time cap returns with ``result.ok`` False and NaN after the stop.
    ``bench`` sets the flow bench (``bench_volume`` [m^3], ``bench_back_pressure`` [Pa])."""
    cfg, p = _setup(design, excitation, configuration, current, effects, bench_valve, bench)
    t_out = _time_grid(excitation, duration, rate)
    y0 = initial_state(p, cfg)
    pq = (design.pq_map.currents, design.pq_map.dps, design.pq_map.flow)
    out, _, stats = integrate(p, excitation.array(), pq, cfg, y0, t_out, rtol=rtol, atol=atol,
                              max_steps=max_steps, max_wall_s=max_wall_s, h_max=h_max)
    return Result(configuration, t_out, _channels(cfg, out), stats, design.hash(), current)


def simulate_batch(designs: list[Design], excitation: Excitation, configuration: str = "module", *,
                   current: float = 1.6, effects: dict | None = None, bench_valve: str | None = None,
                   rate: float = DEFAULT_RATE, duration: float | None = None, rtol: float = DEFAULT_RTOL,
                   atol: float | None = None, max_steps: int = 2_000_000, max_wall_s: float | None = None,
                   h_max: float = 1e-3, channels: list[str] | None = None, bench: dict | None = None):
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
    P = np.vstack([s[1] for s in setups])
    Y0 = np.vstack([initial_state(s[1], cfg) for s in setups])
    t_out = _time_grid(excitation, duration, rate)
    names = {name: i for i, (name, _) in enumerate(L.OUTPUTS)}
    if cfg == L.CFG_VALVE:
        names = dict(_BENCH_COLUMNS)
    elif cfg == L.CFG_TOPMOUNT:
        names = {"displacement [m]": L.O_U, "velocity [m/s]": L.O_V, "top mount force [N]": L.O_F_TM}
    cols = list(names) if channels is None else channels
    unknown = [c for c in cols if c not in names]
    if unknown:
        raise ValueError(f"unknown output channel(s) {unknown}; expected some of {list(names)}")
    idx = np.array([names[c] for c in cols], np.int64)
    OUT, status, _ = integrate_batch(P, excitation.array(), (pqm.currents, pqm.dps, pqm.flow), cfg, Y0, t_out,
                                     rtol=rtol, atol=atol, max_steps=max_steps, max_wall_s=max_wall_s,
                                     h_max=h_max, channels=idx)
    return t_out, {c: OUT[:, :, k] for k, c in enumerate(cols)}, status

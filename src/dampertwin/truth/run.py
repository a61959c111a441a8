"""Run the truth through one test: initial rest state, a settling pause at
the first input value, then the record, integrated by the generic solver
(compiled Rodas4, dense Jacobian). No Python per time step."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..excitation import Excitation
from ..solver import RunStats, integrate
from . import chambers as ch
from . import aeration as ae
from . import fixture as fx
from . import fluid
from . import passive as pv
from . import freeplay as fpl
from . import gas as gs
from . import mount as mt
from . import solenoid as sv
from . import thermal as th
from .damper import RHS
from .fluid import density, ramp
from .layout import (BENCH_BLOCK, BENCH_KIND, BENCH_P, BENCH_V, CURRENT, E_TW, E_VS, E_XS, EX_DT, EX_T0, EXT_AT,
                     N_OUT, OUTPUTS, PO, SO, scales, state_names)
from .params import INTAKES, SHIMS

SETTLE_S = 0.3  # [s] rest before the record: valves, driver, fixture and rubber find their rest state
# The truth's tolerances on the states scaled by layout's declared scales. 1e-5 against 1e-6 on 2 s of the
# module random test: rod acceleration within 0.09 m/s^2 (sensor noise 0.5 m/s^2), top-mount force within
# 0.05 N (noise 3 N), at 0.6x the CPU time.
RTOL = 1e-5
ATOL = 1e-5
VALVE_KIND = {**{v: 0 for v in SHIMS}, **{v: 1 for v in INTAKES}}
CHANNELS = {
    "valve": ("flow [m^3/s]", "dp [Pa]", "lift [m]", "dissipated power [W]"),
    "topmount": ("displacement [m]", "velocity [m/s]", "top mount force [N]", "dissipated power [W]"),
    "active_valve": ("dp [Pa]", "flow [m^3/s]", "p control [Pa]", "lift main stage [m]"),
}


@dataclass
class TruthResult:
    """Channels of a truth run on a uniform grid (SI) and solver statistics."""

    configuration: str
    time: np.ndarray
    channels: dict
    stats: RunStats
    meta: dict = field(default_factory=dict)

    def __getitem__(self, column: str) -> np.ndarray:
        return self.channels[column]

    @property
    def ok(self) -> bool:
        return self.stats.ok


def _rest_damper(p, configuration, u0, oil_T, P0, V_gas0):
    """Rough rest state of the damper / module (pressures at the precharge,
    valves on their seats, gas in equilibrium; :func:`simulate` lets it settle)."""
    n = len(state_names(configuration))
    y = np.zeros(n)
    oo, co, go = PO["oil"], PO["chambers"], PO["gas"]
    P_ref = p[oo + fluid.P_REF]
    s0 = u0
    A_r, A_b = p[co + ch.A_R], p[co + ch.A_B]
    vols = (A_r * (p[co + ch.L_R0] - s0), A_b * (p[co + ch.L_C0] + s0), p[co + ch.V_B])
    kap = (p[co + ch.KAPPA_PT], p[co + ch.KAPPA_PT], p[co + ch.KAPPA_TT])
    triple = architecture(p) == pv.TRIPLE
    for k, (V0, kk) in enumerate(zip(vols, kap)):
        e = p[go + gs.ALPHA_N] + ramp(p[go + gs.ALPHA_TOT] - p[go + gs.S_H] * P0 / P_ref, gs.ALPHA_EPS)
        V = V0 * (1 + kk * (P0 - p[oo + fluid.P_ATM]))
        y[SO["chambers"] + k] = P0
        y[SO["chambers"] + 3 + k] = e * V / (1 + e * P_ref / P0) if triple or k < 2 else 0.0  # no third tube
    y[SO["chambers"] + ch.T_OIL] = oil_T
    rho_ref = float(density(P_ref, oil_T, p, oo))
    V_oil = p[go + gs.V_TOT] - V_gas0
    V_fill = V_gas0
    if architecture(p) == pv.MONO:  # the gas chamber alone behind the floating piston, filled to P0 as built
        V_oil, V_fill = 0.0, p[go + gs.V_TOT]
    y[SO["gas"] + gs.M_RES] = rho_ref * V_oil
    y[SO["gas"] + gs.M_G] = P0 * V_fill / (p[go + gs.R_S] * oil_T)
    y[SO["gas"] + gs.T_G] = oil_T
    y[SO["gas"] + gs.C] = p[go + gs.K_H] * P0 * V_oil
    av, ao = SO["active_valve"], PO["active_valve"]
    i = p[PO["run"] + CURRENT]
    if triple:  # a passive damper has no coil: its states rest at 0
        y[av + sv.I] = i
        y[av + sv.E] = p[ao + sv.R] * i / p[ao + sv.KI]
    y[av + sv.PK] = P0
    F0 = -(P0 - p[oo + fluid.P_ATM]) * (A_b - A_r)
    fo, mo = PO["fixture"], PO["mount"]
    if configuration == "module":
        X = mt.static_deflection(F0, p[mo + mt.K_E], p[mo + mt.K_E3])
        xf = F0 / p[fo + fx.K_F] if p[fo + fx.ON] > 0.5 else 0.0
        y[SO["rod"]] = X + xf
        y[SO["mount"] + mt.X_MEAN] = X
        y[SO["fixture"] + fx.XF] = xf
    elif p[fo + fx.ON] > 0.5:
        y[SO["fixture"] + fx.XF] = F0 / p[fo + fx.K_F]
    return y


def architecture(p) -> int:
    """The architecture's code of the truth ``p`` (passive.CODES)."""
    return int(round(p[PO["chambers"] + ch.ARCH]))


def extended(p, configuration: str) -> bool:
    """A damper / module run with a hidden effect that has states of its own
    (two_node_thermal, air_entrainment; top_mount_free_play in the module):
    it runs on configuration "damper+" / "module+"."""
    on = lambda block, flag: p[PO[block] + flag] > 0.5  # noqa: E731
    return configuration in ("damper", "module") and (
        on("thermal", th.ON) or on("aeration", ae.ON) or (configuration == "module" and on("free_play", fpl.ON)))


def _extend(y, p, configuration, oil_T, P0, cfg=None):
    """The rest state of the extended configuration ``cfg`` (default
    configuration + "+"): the steel at the oil's temperature, no entrained
    gas, the top-mount sleeve where the rod was and the rod against the
    play's side the gas force presses it to; a mono tube's floating piston
    at rest at its origin (its friction element relaxed)."""
    cfg = cfg or configuration + "+"
    z = np.zeros(len(state_names(cfg)))
    z[: len(y)] = y
    e = EXT_AT[cfg]
    z[e + E_TW] = oil_T
    if configuration == "module":
        fo, co = PO["free_play"], PO["chambers"]
        z[e + E_XS] = y[SO["rod"]]
        z[e + E_VS] = 0.0
        if p[fo + fpl.ON] > 0.5:
            F0 = -(P0 - p[PO["oil"] + fluid.P_ATM]) * (p[co + ch.A_B] - p[co + ch.A_R])
            z[SO["rod"]] = y[SO["rod"]] + fpl.rest_offset(F0, p[fo + fpl.GAP], p[fo + fpl.K])
    return z


def simulate(p: np.ndarray, excitation: Excitation, configuration: str, *, current: float = 0.0,
             bench_valve: str | None = None, bench: dict | None = None, rate: float = 10_000.0,
             oil_T: float | None = None, rest: dict | None = None, rtol: float = RTOL, atol: float = ATOL,
             settle: float = SETTLE_S, max_wall_s: float | None = 900.0,
             start_current: float | None = None) -> TruthResult:
    """One test on the truth ``p`` (params.derive): ``configuration`` valve /
    damper / module / topmount; ``rest`` gives P0 [Pa], V_gas0 [m^3] (the
    gas fill) and T [K]; ``oil_T`` the oil temperature at the start
    (default rest["T"]); ``start_current`` the coil current at the start
    (default: the command, the driver's steady state). A passive truth
    (twin / mono tube) has no coil: ``current`` does not act on it; a mono
    tube runs on configuration "damper_fp" / "module_fp"."""
    p = np.array(p, float)
    run = PO["run"]
    p[run + CURRENT] = current
    p[run + EX_T0] = excitation.t0
    p[run + EX_DT] = excitation.dt
    oil_T = rest["T"] if oil_T is None else oil_T
    if configuration == "valve":
        p[run + BENCH_BLOCK] = PO[bench_valve]
        p[run + BENCH_KIND] = VALVE_KIND[bench_valve]
        p[run + BENCH_V] = bench["bench_volume"]
        p[run + BENCH_P] = bench["bench_back_pressure"]
        p[PO["chambers"] + ch.T_AMB] = oil_T
        y0 = np.zeros(4)
        y0[0] = p[run + BENCH_P]
    elif configuration == "topmount":
        y0 = np.zeros(len(state_names("topmount")))
    elif configuration == "active_valve":  # pressure bench: dp prescribed, outlet at the back pressure
        p[run + BENCH_P] = bench["bench_back_pressure"]
        p[PO["chambers"] + ch.T_AMB] = oil_T
        y0 = np.zeros(len(state_names("active_valve")))
        y0[sv.I] = current
        y0[sv.E] = p[PO["active_valve"] + sv.R] * current / p[PO["active_valve"] + sv.KI]
        y0[sv.PK] = p[run + BENCH_P]
    else:
        p[PO["chambers"] + ch.T_AMB] = oil_T
        y0 = _rest_damper(p, configuration, float(excitation.value[0]), oil_T, rest["P0"], rest["V_gas0"])
        if start_current is not None and architecture(p) == pv.TRIPLE:
            y0[SO["active_valve"] + sv.I] = start_current
            y0[SO["active_valve"] + sv.E] = 0.0
    cfg = configuration
    if configuration in ("damper", "module") and architecture(p) == pv.MONO:  # the floating piston's states
        if start_current:
            raise ValueError("start_current: a mono_tube damper has no coil; expected None or 0")
        cfg = configuration + "_fp"
        y0 = _extend(y0, p, configuration, oil_T, rest["P0"], cfg)
    elif extended(p, configuration):
        y0 = _extend(y0, p, configuration, oil_T, rest["P0"])
        cfg = configuration + "+"
    rhs = RHS[cfg]
    sc = scales(cfg)
    ex = excitation.array()
    t0 = float(excitation.t0)
    if settle > 0:
        _, y0, st = integrate(rhs, p, ex, np.zeros(1), y0, np.array([t0 - settle, t0]), scales=sc, n_rhs_out=N_OUT,
                              rtol=rtol, atol=atol, method="rodas4", h_max=1e-3, max_wall_s=max_wall_s)
        if not st.ok:
            return TruthResult(configuration, np.array([t0]), {}, st)
    n = int(round((excitation.t_end - t0) * rate)) + 1
    t_out = t0 + np.arange(n) / rate
    out, _, stats = integrate(rhs, p, ex, np.zeros(1), y0, t_out, scales=sc, n_rhs_out=N_OUT, rtol=rtol, atol=atol,
                              method="rodas4", h_max=1e-3, max_wall_s=max_wall_s)
    chans = CHANNELS.get(configuration, OUTPUTS)
    return TruthResult(configuration, t_out, {c: out[:, OUTPUTS.index(c)] for c in chans}, stats)

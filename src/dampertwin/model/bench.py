"""Flow bench (thesis 2.7.2, 6.2.1): a prescribed flow Q_in into an upstream
volume of gas-free oil, one valve to a constant back pressure."""

from __future__ import annotations

from numba import njit

from .declarations import Parameter, State
from .valves import V_SIZE, seated_lift

# Flow-bench defaults (THESIS-ERRATA 37): 0.2 L upstream, 2 bar back pressure (gauge)
BENCH_VOLUME = 2.0e-4  # [m^3]
BENCH_BACK_PRESSURE = 2.0e5 + 101325.0  # [Pa abs]

PARAMETERS = (
    Parameter("BENCH_V", "m^3", None, "upstream oil volume"),
    Parameter("BENCH_P_DOWN", "Pa", None, "back pressure (absolute)"),
    Parameter("BENCH_VALVE", "-", None, "index of the valve on the bench (valves.VALVE_NAMES)"),
)

STATES = (
    State("P_up", "Pa", 1e5, lambda q: q["BENCH_P_DOWN"], "upstream pressure"),
    State("x", "m", 1e-4, lambda q: seated_lift(q.block("VALVES", int(q["BENCH_VALVE"]), V_SIZE), q["K_C"]),
          "valve lift (seated at rest)"),
    State("v", "m/s", 1e-1, 0.0, "valve velocity"),
    State("F_dahl", "N", 1.0, 0.0, "Dahl force (shim stacks)"),
)


@njit(cache=True, error_model="numpy")
def upstream_pressure_rate(K, V, Q_valve, Q_in):
    """dP/dt of the upstream volume, eq. 4.9 with rigid walls [Pa/s]."""
    return -K / V * (Q_valve - Q_in)

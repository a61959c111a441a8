"""Flow bench (thesis 2.7.2, 6.2.1): a prescribed flow Q_in into an upstream
volume of gas-free oil, one valve to a constant back pressure."""

from __future__ import annotations

from numba import njit

from .chambers import cavitation_factor
from .declarations import Parameter, State
from .valves import valve_states

# Flow-bench defaults (THESIS-ERRATA 37): 0.2 L upstream, 2 bar back pressure (gauge)
BENCH_VOLUME = 2.0e-4  # [m^3]
BENCH_BACK_PRESSURE = 2.0e5 + 101325.0  # [Pa abs]

PARAMETERS = (
    Parameter("BENCH_V", "m^3", None, "upstream oil volume"),
    Parameter("BENCH_P_DOWN", "Pa", None, "back pressure (absolute)"),
    Parameter("BENCH_VALVE", "-", None, "index of the valve on the bench (valves.VALVE_NAMES)"),
)

STATES = (State("P_up", "Pa", 1e5, lambda q: q["BENCH_P_DOWN"], "upstream pressure"),)
VALVE_STATES = valve_states("bench", None, dahl=True)  # the valve under test (its Dahl slot unused for intakes)


@njit(cache=True, error_model="numpy")
def upstream_pressure_rate(K, V, Q_valve, Q_in):
    """dP/dt of the upstream volume, eq. 4.9 with rigid walls [Pa/s]."""
    return -K / V * (Q_valve - Q_in)


@njit(cache=True, error_model="numpy", inline="always")
def upstream_modulus(p, P_up):
    """Modulus of the bench's degassed oil (THESIS-ERRATA 37), with the
    cavitation factor when that effect is on [Pa]."""
    K = p[_L.P.K_OIL]
    if p[_L.P.E_CAV] > 0.5:
        K *= cavitation_factor(P_up, p[_L.P.P_VAP])
    return K


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)

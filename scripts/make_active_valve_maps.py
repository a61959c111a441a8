"""Generate the SYNTHETIC active-valve P/Q maps (design parameter no. 52).

The thesis uses the supplier's map (fig. 6.2), which is not published as
numbers. These maps are plausible stand-ins (THESIS-ERRATA.md item 30): a
pilot orifice in parallel with a main stage that opens at a current-dependent
pressure, from 1.5 bar at 0.32 A to 25 bar at 1.6 A (baseline). Higher
current means more restriction, so flow never rises with current at a fixed
pressure drop. Run from the repository root:

    python scripts/make_active_valve_maps.py
"""

from pathlib import Path

import numpy as np

from dampertwin.design import PQMap, write_map

RHO = 850.0  # oil density [kg/m^3], design no. 8
CURRENTS = np.array([0.32, 0.6, 0.9, 1.2, 1.6])  # [A]
DPS = 1e5 * np.array(
    [0, 0.25, 0.5, 1, 1.5, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 35, 40, 50, 60, 80, 100, 150]
)  # [Pa]


def pq_map(dp_open_lo, dp_open_hi, a_pilot, gain, cq=0.7):
    """Q [m^3/s] = pilot orifice + linear main stage above dp_open(I)."""
    dp_open = dp_open_lo + (CURRENTS - CURRENTS[0]) / (CURRENTS[-1] - CURRENTS[0]) * (dp_open_hi - dp_open_lo)
    pilot = cq * a_pilot * np.sqrt(2.0 * DPS / RHO)
    main = gain * np.maximum(DPS[None, :] - dp_open[:, None], 0.0)
    return PQMap(CURRENTS.copy(), DPS.copy(), np.round(pilot[None, :] + main, 12))


if __name__ == "__main__":
    out = Path("conf/design")
    write_map(out / "active_valve_baseline.csv", pq_map(1.5e5, 25e5, 0.6e-6, 6.5e-10))
    write_map(out / "active_valve_alternative.csv", pq_map(3.0e5, 32e5, 0.9e-6, 4.5e-10))
    print("wrote", out / "active_valve_baseline.csv", out / "active_valve_alternative.csv")

"""The active valve's own P/Q map (no. 52) from an active-valve bench record
(conf/test/activevalve.yaml), in place of the supplier's datasheet map.

The thesis takes the map from the supplier (fig. 6.2): a measurement of *a*
valve of the type, not of the part in the damper. A record of the part's
valve on a pressure bench gives, per current, the flow at each pressure drop;
the map is that characteristic on the design map's grid (its currents and
pressure drops), so the model's bilinear interpolation (errata 30) is
unchanged. Non-parametric: no valve model is assumed between the grid points.

Per current run: the flow against the pressure drop, up and down ramps
together (their spool lag and the transducers' phase average out), as the
monotone least-squares fit (isotonic regression, scipy) of the flow rising
with the pressure drop, read at the grid's pressure drops. Then the two
orderings the map reader requires (pqmap._read_map), by alternating
projections until both hold: at each pressure drop the flow does not rise
with the current (more current, more restriction; the monotone least-squares
fit across the currents, which pools crossing curves symmetrically), and at
each current it rises strictly with the pressure drop (``MIN_STEP`` between
grid points where noise leaves a plateau). How far this moved each current's
curve is returned with the map (stage activevalve_map writes it).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.optimize import isotonic_regression

from ..design.pqmap import PQMap
from ..errors import UserError

CURRENT_TOL = 0.05   # [A] a run's current against the map's grid current it stands for
MIN_STEP = 1.0e-12   # [m^3/s] (6e-8 l/min) least flow step between two grid pressure drops: far below any sensor
MIN_SAMPLES = 50     # samples per run at and above the grid's smallest nonzero pressure drop
MAX_PASSES = 100     # alternating projections onto the two orderings before the record is refused
ORDER_FLAG = 0.02    # a curve the orderings moved by more than this share of its top flow is flagged


class MapRecordError(UserError):
    """An active-valve bench record cannot give the map (names the record and run)."""


def _run_curve(dp: np.ndarray, q: np.ndarray, grid_dp: np.ndarray, label: str) -> np.ndarray:
    """Flow [m^3/s] at ``grid_dp`` [Pa] from one run's samples (monotone fit, see the module)."""
    ok = dp >= 0.0
    if np.count_nonzero(dp < -grid_dp[1]) > np.count_nonzero(dp > grid_dp[1]):
        raise MapRecordError(f"{label}: the pressure drop is mostly negative (flow with it); expected dp >= 0 "
                             f"across the valve in its flow direction (both signs flipped: dp measured the other way?)")
    if np.count_nonzero(ok & (dp >= grid_dp[1])) < MIN_SAMPLES:
        raise MapRecordError(f"{label}: fewer than {MIN_SAMPLES} samples at or above the map's smallest pressure "
                             f"drop {grid_dp[1]:.4g} Pa; expected a ramp over the whole map")
    step = float(np.median(np.abs(np.diff(dp))))
    if step > np.min(np.diff(grid_dp)):
        raise MapRecordError(f"{label}: the pressure drop moves {step:.4g} Pa between samples (median), more than "
                             f"the map grid's smallest step {np.min(np.diff(grid_dp)):.4g} Pa; expected a slower "
                             f"ramp or a faster sampling rate")
    top = float(np.max(dp[ok]))
    if top < grid_dp[-1]:
        raise MapRecordError(f"{label}: the pressure drop reaches {top / 1e5:.4g} bar; the design's map grid goes to "
                             f"{grid_dp[-1] / 1e5:.4g} bar: measure up to at least that (no extrapolation)")
    order = np.argsort(dp[ok], kind="stable")
    x, y = dp[ok][order], q[ok][order]
    fit = isotonic_regression(y, increasing=True).x
    out = np.interp(grid_dp, x, fit)
    out[0] = 0.0  # no flow without a pressure drop (the map's odd extension)
    return out


def _orderings(flow: np.ndarray, where: str) -> np.ndarray:
    """``flow`` [current, dp] [m^3/s] moved onto the map's orderings (see the module)."""
    f = flow.copy()
    for _ in range(MAX_PASSES):
        for j in range(1, f.shape[1]):  # not rising with the current
            f[:, j] = isotonic_regression(f[:, j], increasing=False).x
        for j in range(1, f.shape[1]):  # strictly rising with the pressure drop
            f[:, j] = np.maximum(f[:, j], f[:, j - 1] + MIN_STEP)
        if np.all(np.diff(f, axis=0) <= 0):
            return f
    raise MapRecordError(f"{where}: the runs' curves cannot be ordered (flow falling with the current, rising with "
                         f"the pressure drop) in {MAX_PASSES} passes; expected a valve whose flow the current lowers")


def map_from_record(record: pd.DataFrame, grid: PQMap, where: str) -> tuple[PQMap, np.ndarray]:
    """The part's P/Q map on ``grid``'s currents [A] and pressure drops [Pa]
    from an active-valve bench ``record`` (run, dp [Pa], flow [m^3/s],
    current [A]; io.read_record checked it), and per current the largest
    flow change [m^3/s] the orderings made to its fitted curve. Every grid
    current needs a run within CURRENT_TOL. ``where`` names the record in errors."""
    runs = {str(k): g for k, g in record.groupby("run", sort=False)}
    mean_i = {k: float(g["current [A]"].mean()) for k, g in runs.items()}
    rows = []
    for c in grid.currents:
        near = [k for k, i in mean_i.items() if abs(i - c) <= CURRENT_TOL]
        if not near:
            have = ", ".join(f"{k} ({i:.3g} A)" for k, i in mean_i.items())
            raise MapRecordError(f"{where}: no run at the map's current {c:g} A (within {CURRENT_TOL} A); the "
                                 f"record has {have}; expected one run per current of the design's map")
        g = runs[min(near, key=lambda k: abs(mean_i[k] - c))]
        rows.append(_run_curve(g["dp [Pa]"].to_numpy(float), g["flow [m^3/s]"].to_numpy(float), grid.dps,
                               f"{where} run {g['run'].iloc[0]!r}"))
    fitted = np.array(rows)
    flow = _orderings(fitted, where)
    return PQMap(grid.currents, grid.dps, flow), np.max(np.abs(flow - fitted), axis=1)


def ordering_flags(pq: PQMap, moved: np.ndarray) -> list[str]:
    """A warning per current whose curve the orderings moved by more than ORDER_FLAG of its top flow
    (``moved``: map_from_record's second result [m^3/s]): crossing curves, a run at another current?"""
    return [f"the {c:g} A curve crosses its neighbours: the map's orderings moved it by {m * 6e4:.3g} l/min "
            f"({m / t:.1%} of its top flow); check the run's current"
            for c, m, t in zip(pq.currents, moved, pq.flow.max(axis=1)) if m > ORDER_FLAG * t]


def map_change(fitted: PQMap, datasheet: PQMap, ordered: np.ndarray | None = None) -> dict:
    """How far the part's map lies from the datasheet's: per current [A], the
    largest flow difference [m^3/s] over the grid, the pressure drop [Pa]
    where it is and the difference relative to the datasheet's flow there;
    with ``ordered`` (map_from_record's second result), how far the
    orderings moved the current's curve [m^3/s]."""
    out = {}
    for i, c in enumerate(fitted.currents):
        diff = fitted.flow[i] - datasheet.flow[i]
        j = int(np.argmax(np.abs(diff)))
        out[f"{c:g}"] = {"largest_change [m^3/s]": float(diff[j]), "at_dp [Pa]": float(fitted.dps[j]),
                         "relative": float(diff[j] / datasheet.flow[i, j]) if datasheet.flow[i, j] > 0 else None}
        if ordered is not None:
            out[f"{c:g}"]["moved_by_orderings [m^3/s]"] = float(ordered[i])
    return out

"""The active-valve P/Q map (no. 52): the grid, its CSV reader and writer."""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .schema import MAP_COLUMNS

# the largest value of each map column (SI) in a damper valve's map: a current of at most a few A, a map over
# 1-1000 bar, a largest flow of 0.06-6000 l/min; outside, a unit was mixed up (mA, bar, l/min)
MAP_RANGE = {"current": (0.01, 10.0), "dp": (1.0e5, 1.0e8), "flow": (1.0e-6, 0.1)}
from .yaml_io import ConfigTextError, read_config_text


@dataclass(frozen=True)
class PQMap:
    """Active-valve characteristic (no. 52): Q [m^3/s] on a current x dp grid.

    ``flow[i, j]`` is the flow at ``currents[i]`` [A] and ``dps[j]`` [Pa].
    """

    currents: np.ndarray
    dps: np.ndarray
    flow: np.ndarray

    def __post_init__(self):
        # read-only copies: a Design caches what it derives from the map (its hash), so the map cannot change
        for name in ("currents", "dps", "flow"):
            a = np.array(getattr(self, name), float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def __reduce__(self):
        return (PQMap, (self.currents, self.dps, self.flow))

    def __eq__(self, other):
        return (
            isinstance(other, PQMap)
            and np.array_equal(self.currents, other.currents)
            and np.array_equal(self.dps, other.dps)
            and np.array_equal(self.flow, other.flow)
        )

    __hash__ = None  # type: ignore[assignment]


def _inside(path: Path, folders) -> bool:
    """True if ``path`` (symlinks resolved) lies in one of ``folders``."""
    try:
        rp = path.resolve()
    except (OSError, RuntimeError):
        return False
    for f in folders:
        try:
            rp.relative_to(Path(f).resolve())
            return True
        except (ValueError, OSError, RuntimeError):
            continue
    return False


def _find_map(name: str, base_dir: Path, folders) -> Path:
    """A relative P/Q map file name: the design's folder first, then the
    other allowed folders in order (``map_dirs``, DAMPERTWIN_MAP_DIRS), e.g.
    a calibrated design whose case names the nominal design's alternative
    map. The design's folder when no folder has it (the error names it)."""
    for f in (base_dir, *folders):
        if (Path(f) / name).is_file():
            return Path(f) / name
    return base_dir / name


def _read_map(path: Path, label: str, errors: list[str]) -> PQMap | None:
    """Read and check the active-valve P/Q map CSV (tidy: current, dp, flow)."""
    if not path.is_file():
        errors.append(f"{label}: P/Q map file {str(path)!r} " + ("is a folder; expected a CSV file" if path.is_dir()
                                                                 else "not found"))
        return None
    n0 = len(errors)
    # never echo the file's content: a wrong path may point at anything
    try:
        text = read_config_text(path).removeprefix("\ufeff")  # a UTF-8 byte-order mark (spreadsheet export)
        rows = list(csv.reader(io.StringIO(text)))
    except (ConfigTextError, csv.Error) as e:
        msg = str(e).split(": ", 1)[-1] if isinstance(e, ConfigTextError) else "not a CSV file"
        errors.append(f"{label}: cannot read P/Q map {str(path)!r}: {msg}")
        return None
    if not rows or tuple(c.strip() for c in rows[0]) != MAP_COLUMNS:
        errors.append(f"{label}: P/Q map {str(path)!r}: first line is not the expected header; "
                      f"expected columns {list(MAP_COLUMNS)}")
        return None
    data = []
    for i, r in enumerate(rows[1:], start=2):
        try:
            vals = [float(x) for x in r]
        except ValueError:
            errors.append(f"{label}: P/Q map {str(path)!r} line {i}: non-numeric entry; expected 3 numbers")
            continue
        if len(vals) != 3 or not all(math.isfinite(x) for x in vals):
            errors.append(f"{label}: P/Q map {str(path)!r} line {i}: expected 3 finite numbers, got {len(vals)} "
                          f"value(s)" + (" with NaN/inf" if len(vals) == 3 else ""))
            continue
        data.append(vals)
    if len(errors) > n0:
        return None
    return map_from_rows(np.array(data, dtype=float).reshape(-1, 3), label, str(path), errors)


def map_from_rows(arr: np.ndarray, label: str, path: str, errors: list[str]) -> PQMap | None:
    """The P/Q map of tidy rows (current [A], dp [Pa], flow [m^3/s]) after the map reader's checks
    (full grid, flow 0 at dp 0, SI ranges, orderings); None with ``errors`` appended otherwise."""
    n0 = len(errors)
    currents = np.unique(arr[:, 0])
    dps = np.unique(arr[:, 1])
    if len(currents) < 2 or len(dps) < 2 or len(arr) != len(currents) * len(dps):
        errors.append(f"{label}: P/Q map {str(path)!r} must be a full grid of >= 2 currents x >= 2 dp values, each pair once")
        return None
    if currents[0] < 0 or dps[0] != 0.0:
        errors.append(f"{label}: P/Q map {str(path)!r}: currents must be >= 0 A and dp must start at 0 Pa (negative dp is the odd extension)")
        return None
    flow = np.full((len(currents), len(dps)), np.nan)
    ci = np.searchsorted(currents, arr[:, 0])
    di = np.searchsorted(dps, arr[:, 1])
    flow[ci, di] = arr[:, 2]
    if np.isnan(flow).any():
        errors.append(f"{label}: P/Q map {str(path)!r}: grid has duplicated (current, dp) pairs")
        return None
    if np.any(flow[:, 0] != 0.0):
        errors.append(f"{label}: P/Q map {str(path)!r}: flow at dp = 0 must be 0")
    top_flow = float(np.max(flow))
    flow_hint = "values in l/min?" if top_flow > 0 else "the flow must be positive for dp > 0 (sign flipped?)"
    top_flow = top_flow if top_flow > 0 else float(np.min(flow))  # a flipped column: name its largest magnitude
    for col, top, (lo, hi), hint in (("current [A]", currents[-1], MAP_RANGE["current"], "values in mA?"),
                                     ("dp [Pa]", dps[-1], MAP_RANGE["dp"], "values in bar (or MPa)?"),
                                     ("flow [m^3/s]", top_flow, MAP_RANGE["flow"], flow_hint)):
        if not lo <= top <= hi:
            errors.append(f"{label}: P/Q map {str(path)!r}: column {col!r} reaches {top:.4g}, outside the "
                          f"{lo:g} .. {hi:g} of a passenger-car damper valve's map: {hint}")
    if len(errors) > n0:
        return None
    if np.any(np.diff(flow, axis=1) <= 0):
        i = int(np.argwhere(np.diff(flow, axis=1) <= 0)[0, 0])
        errors.append(f"{label}: P/Q map {str(path)!r} is not monotone: flow must rise with dp (current {currents[i]} A)")
    if np.any(np.diff(flow, axis=0) > 0):
        errors.append(f"{label}: P/Q map {str(path)!r} is not monotone: flow must not rise with current at fixed dp (higher current = more restriction)")
    if len(errors) > n0:
        return None
    return PQMap(currents, dps, flow)


def write_map(path: str | os.PathLike, pq: PQMap) -> None:
    """Write a P/Q map in the tidy CSV layout read by :func:`load`."""
    lines = [",".join(MAP_COLUMNS)]
    for i, c in enumerate(pq.currents):
        for j, dp in enumerate(pq.dps):
            lines.append(f"{float(c)!r},{float(dp)!r},{float(pq.flow[i, j])!r}")
    Path(path).write_text("\n".join(lines) + "\n")

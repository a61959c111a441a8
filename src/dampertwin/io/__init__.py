"""Measured / simulated frames on disk: Parquet (or CSV for real
measurements), unit-suffixed columns (``force [N]``), schema checks and atomic
writes. Metadata (synthetic flag, seed, design hash, ...) rides in the
Parquet schema under the key ``dampertwin``.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ..design.schema import SI_UNITS
from ..errors import UserError

META_KEY = b"dampertwin"

# quantity -> SI unit accepted in column names
UNITS = {
    "time": "s", "displacement": "m", "velocity": "m/s", "force": "N", "rod acceleration": "m/s^2",
    "current": "A", "flow": "m^3/s", "dp": "Pa", "velocity setpoint": "m/s", "frequency": "Hz",
    "amplitude": "m", "lift": "m", "oil temperature": "K",
    "precharge": "Pa",
}
REQUIRED = {
    "flowbench": ("time", "flow", "dp"),
    "activevalve": ("time", "flow", "dp", "current"),
    "compliance": ("time", "displacement", "force", "current"),
    "curving": ("time", "displacement", "force", "current"),
    "monosine": ("time", "displacement", "force", "rod acceleration", "current"),
    "random": ("time", "displacement", "force", "rod acceleration", "current"),
    "training": ("time", "displacement", "force", "current"),  # damper or module (then rod acceleration too,
    "verification": ("time", "displacement", "force", "current"),  # required by io.read_record)
    "topmount": ("time", "displacement", "force"),
    "thermal": ("time", "displacement", "force", "current", "oil temperature"),
    "friction": ("time", "displacement", "force", "current", "precharge"),
    "dyno": ("time", "displacement", "force"),  # a passive damper's dyno export (current, oil temperature optional)
}
# shortest usable record per protocol [s] (per run where a file holds several)
MIN_DURATION = {"flowbench": 2.0, "activevalve": 2.0, "compliance": 0.05, "curving": 0.2, "monosine": 2.0 / 13.0, "random": 8.0,
                "topmount": 0.02, "training": 1.0, "verification": 1.0, "thermal": 2.0,
                "friction": 0.5, "dyno": 1.0}
from ..excitation import UNIFORM_TOL, grid_deviation  # noqa: E402  (time stamps within UNIFORM_TOL intervals of a grid)
T_OIL_RANGE = (233.15, 423.15)  # [K] an oil temperature a damper test can have (-40 .. 150 degC)
PRECHARGE_RANGE = (1.5e5, 5.0e6)  # [Pa] absolute gas precharge of a damper (0.5 .. 49 bar gauge)
MAX_FILE_MB = 64.0  # [MB] largest measurement file read (DAMPERTWIN_MAX_FILE_MB raises it): a junk file is refused, not parsed
RATE_TOL = 0.01  # relative deviation of the sampling rate from the protocol's still accepted
# protocols whose records may have any sampling rate at or above this [Hz] (measured from the time column),
# instead of the protocol's own rate: a dyno export is logged at whatever rate the dyno's software was set to; a
# pressure bench's quasi-static ramps likewise (the map builder also refuses a record whose pressure drop moves
# more between samples than the map grid's smallest step: calibration.active_valve_map)
MIN_RATE = {"dyno": 100.0, "activevalve": 100.0}
# channels that must vary in a record of the protocol (a constant one is a dead sensor or an empty file)
EXCITED = {"flowbench": ("flow", "dp"), "activevalve": ("flow", "dp"),
           **{p: ("displacement", "force") for p in ("compliance", "curving", "topmount", "thermal",
                                                           "friction", "dyno")},
           **{p: ("displacement", "force", "rod acceleration") for p in ("monosine", "random", "training",
                                                                       "verification")}}
# every unit a column may carry (SI); anything else (bar, mm, kN, l/min, g, degC, ...) is rejected
SI_COLUMN_UNITS = frozenset(UNITS.values()) | SI_UNITS | {"m/s^2", "N*s", "Pa*s", "W", "J"}

_COL = re.compile(r"^(?P<q>[^\[\]]+?)\s*\[(?P<u>[^\[\]]*)\]$")


class DataError(UserError):
    """A data file is invalid; ``errors`` lists every problem (file and column named)."""

    def __init__(self, errors: list[str]):
        self.errors = list(errors)
        ValueError.__init__(self, "invalid data file:\n  - " + "\n  - ".join(self.errors))


def column(quantity: str) -> str:
    """Column name with its SI unit, e.g. column('force') -> 'force [N]'."""
    return f"{quantity} [{UNITS[quantity]}]"


def write_frame(path: str | os.PathLike, df: pd.DataFrame, meta: dict) -> Path:
    """Write a frame as Parquet atomically (temp file + rename) with ``meta``
    as JSON in the schema metadata. Deterministic bytes for equal input."""
    path = Path(path)
    check_targets([path])
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    md = dict(table.schema.metadata or {})
    md.pop(b"pandas", None)
    md[META_KEY] = json.dumps(json_safe(meta), sort_keys=True, allow_nan=False).encode()
    table = table.replace_schema_metadata(md)
    with atomic_files([path]) as (tmp,):  # a folder at ``path``: OutputError, nothing written
        pq.write_table(table, tmp, compression="zstd")
    return path


def json_safe(o):
    """``o`` as standard JSON values (RFC 8259 has no Infinity or NaN): numpy scalars / arrays as numbers /
    lists, a non-finite number (an unbounded interval end, an undefined ratio) as null. Every JSON file the
    stages and the CLI write, and a record's Parquet metadata, goes through it, with ``allow_nan=False``."""
    if isinstance(o, dict):
        return {k: json_safe(v) for k, v in o.items()}
    if isinstance(o, np.ndarray) and o.ndim == 0:
        return json_safe(o.item())
    if isinstance(o, (list, tuple, np.ndarray)):
        return [json_safe(v) for v in (o.tolist() if isinstance(o, np.ndarray) else o)]
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.integer):
        return int(o)
    return json_safe(o.item()) if isinstance(o, np.generic) else o


def json_number(v, null: float = math.nan) -> float:
    """A number read back from standard JSON (:func:`json_safe`): null, written for a non-finite value,
    as ``null`` (e.g. -inf / +inf for the ends of an unbounded interval)."""
    return null if v is None else v


def read_meta(path: str | os.PathLike) -> dict:
    """A record's dampertwin metadata (a JSON object in the Parquet schema; {} when it has none);
    metadata that is no JSON object is a DataError naming the file."""
    try:
        md = pq.read_schema(path).metadata or {}
    except (OSError, ValueError) as e:  # missing, a folder, not Parquet (pyarrow's ArrowInvalid is a ValueError)
        raise DataError([f"{path}: cannot read: {' '.join(str(e).split())[:300]}"]) from None
    if META_KEY not in md:
        return {}
    try:
        doc = json.loads(md[META_KEY])
    except ValueError as e:  # JSONDecodeError and UnicodeDecodeError
        raise DataError([f"{path}: metadata {META_KEY.decode()!r} is not JSON ({e}); expected a JSON object"]) from None
    if not isinstance(doc, dict):
        raise DataError([f"{path}: metadata {META_KEY.decode()!r} is a JSON {type(doc).__name__}; expected a JSON object"])
    return doc


def read_frame(path: str | os.PathLike, protocol: str | None = None, *,
               current_range: tuple[float, float] | None = None,
               rate: float | dict[str, float] | None = None) -> tuple[pd.DataFrame, dict]:
    """Read and check a measured (or simulated) frame. ``protocol`` names the
    test whose columns, minimum duration and excited (non-constant) channels
    are required; ``rate`` [Hz] (one value, or per run label, see
    ``protocols.recording_rates``) the sampling rate it must be recorded at.
    Every column needs an SI unit, one column per quantity. Raises DataError
    naming the file and the column for every problem found."""
    path = Path(path)
    where = str(path)
    if protocol is not None and protocol not in REQUIRED:
        raise DataError([f"{where}: unknown protocol {protocol!r}; expected one of {', '.join(REQUIRED)}"])
    df, meta = read_table(path)
    return check_frame(df, meta, where, protocol, current_range=current_range, rate=rate), meta


def max_file_bytes() -> int:
    """The size limit of a measurement file [bytes] (MAX_FILE_MB, or $DAMPERTWIN_MAX_FILE_MB)."""
    env = os.environ.get("DAMPERTWIN_MAX_FILE_MB", "").strip()
    try:
        mb = float(env) if env else MAX_FILE_MB
    except ValueError:
        mb = MAX_FILE_MB
    return int(mb * 1024 * 1024)


CSV_COMPRESSIONS = (".gz", ".bz2", ".xz", ".zip")  # pandas reads these CSVs directly


def file_kind(path: Path) -> str:
    """The file's table type: '.parquet', '.csv' (compressed CSVs included) or its suffix."""
    if path.suffix in CSV_COMPRESSIONS and Path(path.stem).suffix == ".csv":
        return ".csv"
    return path.suffix


def check_file(path: str | os.PathLike, suffixes: tuple[str, ...] = (".parquet", ".csv")) -> Path:
    """A measurement file that exists, has one of ``suffixes``, is not empty
    and is below the size limit; a DataError naming it otherwise."""
    path = Path(path)
    where = str(path)
    if path.is_dir():
        raise DataError([f"{where}: is a folder; expected a {' or '.join(suffixes)} file"])
    if not path.is_file():
        raise DataError([f"{where}: file not found"])
    if file_kind(path) not in suffixes:
        raise DataError([f"{where}: unsupported file type {path.suffix!r}; expected {' or '.join(suffixes)}"
                         + (" (a .csv may be compressed: .csv.gz, .csv.bz2, .csv.xz, .csv.zip)"
                            if ".csv" in suffixes else "")])
    size, limit = path.stat().st_size, max_file_bytes()
    if size > limit:
        raise DataError([f"{where}: file is {size / 2**20:.1f} MB, larger than the {limit / 2**20:g} MB limit of a "
                         f"measurement file (not read; split the record, or raise DAMPERTWIN_MAX_FILE_MB)"])
    if size == 0:
        raise DataError([f"{where}: empty file (0 bytes); expected a record"])
    return path


def read_table(path: str | os.PathLike, csv_kw: dict | None = None) -> tuple[pd.DataFrame, dict]:
    """The raw table of a .parquet or .csv file (and its metadata), before
    any schema check: a missing, oversized, unreadable or empty (header
    only) file is a DataError naming it. Used by :func:`read_frame` and the
    importer (a source in the user's own columns)."""
    path = check_file(path)
    where = str(path)
    try:
        if path.suffix == ".parquet":
            df = pq.read_table(path).to_pandas()
            meta = read_meta(path)
        else:
            kw = dict(csv_kw or {})
            if kw.get("engine", "c") == "c":  # whole-file type inference: no DtypeWarning beside our own error
                kw.setdefault("low_memory", False)
            df = pd.read_csv(path, **kw)
            meta = {}
    except DataError:
        raise
    except Exception as e:  # unreadable file: report it, never a raw traceback
        raise DataError([f"{where}: cannot read: {' '.join(str(e).split())[:300]}"]) from None
    if len(df) == 0:
        raise DataError([f"{where}: empty record: no rows (a header of {len(df.columns)} columns only); expected a record"])
    if path.suffix != ".parquet":
        _check_csv_header(path, df, csv_kw or {})
    return df, meta


_MANGLED = re.compile(r"^(?P<base>.*)\.(?P<k>[1-9][0-9]*)$")  # pandas' name for a repeated header name: 'x.1'


def _check_csv_header(path: Path, df: pd.DataFrame, csv_kw: dict) -> None:
    """A CSV header naming a column twice is a DataError: pandas names the second 'x.1' and a reader would take
    the first. Suspects are read from pandas' own parse (so ``header``, ``usecols`` and the like apply); a
    suspect is cleared only when the header line itself, read again as data, holds the name 'x.1'."""
    names = [str(c) for c in df.columns]
    suspects = [(c, m.group("base")) for c in names if (m := _MANGLED.match(c)) and m.group("base") in names]
    if not suspects:
        return
    raw = None
    header = csv_kw.get("header", "infer")
    h = 0 if header == "infer" else header
    if isinstance(h, int) and not isinstance(h, bool) and "names" not in csv_kw:
        kw = {k: v for k, v in csv_kw.items() if k not in ("header", "nrows", "skipfooter", "usecols", "index_col",
                                                             "dtype", "keep_default_na", "na_values", "parse_dates",
                                                             "converters", "names")}
        try:
            raw = pd.read_csv(path, header=None, nrows=h + 1, dtype=str, keep_default_na=False, **kw).iloc[h].tolist()
        except Exception:  # noqa: BLE001 - a preamble the re-read cannot parse: pandas' renaming stands
            raw = None
    for c, base in suspects:
        if raw is not None and raw.count(c) >= 1 and raw.count(base) == 1:
            continue  # the file really names a column 'x.1'
        raise DataError([f"{path}: the header names column {base!r} more than once (pandas called a repeat {c!r}); "
                         f"expected each column name once"])


def check_frame(df: pd.DataFrame, meta: dict, where: str, protocol: str | None = None, *,
                current_range: tuple[float, float] | None = None,
                rate: float | dict[str, float] | None = None) -> pd.DataFrame:
    """The schema checks of :func:`read_frame` on a frame in memory
    (``where`` names it in the errors). Returns the frame."""
    if protocol is not None and protocol not in REQUIRED:
        raise DataError([f"{where}: unknown protocol {protocol!r}; expected one of {', '.join(REQUIRED)}"])
    if len(df) == 0:
        raise DataError([f"{where}: empty record: no rows (a header of {len(df.columns)} columns only); expected a record"])
    qty, numeric = _check_columns(df, where, protocol)
    labels = df["run"].to_numpy() if "run" in df else np.zeros(len(df), int)
    order = list(dict.fromkeys(labels.tolist()))
    errors = [] if order else [f"{where}: no rows; expected a record"]
    for run in order:
        sel = labels == run
        label = f"{where}" + (f" run {run!r}" if "run" in df else "")
        want = rate.get(str(run)) if isinstance(rate, dict) else rate
        errors += _check_run(numeric, qty, sel, label, protocol, want)
    errors += _check_ranges(numeric, qty, where, current_range)
    if errors:
        raise DataError(errors)
    return df


def _check_columns(df: pd.DataFrame, where: str, protocol: str | None) -> tuple[dict[str, str], dict[str, np.ndarray]]:
    """The run labels and the 'quantity [unit]' columns: SI units, one column per quantity, the protocol's
    required quantities, finite numbers. Returns (quantity -> column, quantity -> values); a DataError
    listing every problem otherwise."""
    errors: list[str] = []
    qty: dict[str, str] = {}
    if "run" in df:
        r = df["run"]
        ok_type = r.map(lambda x: isinstance(x, (str, int, np.integer)) and not isinstance(x, bool))
        if r.isna().any():
            errors.append(f"{where}: column 'run' has {int(r.isna().sum())} missing (NaN) labels; expected a label "
                          f"on every row")
        elif not ok_type.all():
            errors.append(f"{where}: column 'run' holds {type(r[~ok_type].iloc[0]).__name__} labels; expected strings")
    for c in df.columns:
        if c == "run":
            continue
        m = _COL.match(str(c))
        if not m:
            errors.append(f"{where}: column {c!r} has no unit; expected 'quantity [unit]' (SI)")
            continue
        q, u = m.group("q").strip(), m.group("u").strip()
        if q in UNITS and u != UNITS[q]:
            errors.append(f"{where}: column {c!r}: unit {u!r}; expected {UNITS[q]!r}")
            continue
        if u not in SI_COLUMN_UNITS:
            errors.append(f"{where}: column {c!r}: unit {u!r} is not SI; expected one of "
                          f"{', '.join(sorted(SI_COLUMN_UNITS))} (convert before loading)")
            continue
        if q in qty:
            errors.append(f"{where}: columns {qty[q]!r} and {c!r} hold the same quantity {q!r}; expected one column")
            continue
        qty[q] = c
    for q in REQUIRED.get(protocol, ("time",)):
        if q not in qty:
            errors.append(f"{where}: missing column {column(q)!r} (protocol {protocol})")
    numeric = {}
    for q, c in qty.items():
        col = df.loc[:, c]
        if isinstance(col, pd.DataFrame):  # duplicated column name
            errors.append(f"{where}: column {c!r} appears {col.shape[1]} times; expected once")
            continue
        if not pd.api.types.is_numeric_dtype(col) or pd.api.types.is_bool_dtype(col):
            errors.append(f"{where}: column {c!r} is not numeric (dtype {col.dtype}); expected numbers in {q!r}")
            continue
        x = col.to_numpy(float)
        if not np.all(np.isfinite(x)):
            errors.append(f"{where}: column {c!r} has {int(np.sum(~np.isfinite(x)))} NaN/inf values")
            continue
        numeric[q] = x
    if errors:
        raise DataError(errors)
    return qty, numeric


def _check_run(numeric: dict, qty: dict, sel: np.ndarray, label: str, protocol: str | None,
               want: float | None) -> list[str]:
    """One run's time axis (increasing, uniform, its protocol's rate and duration) and its excited
    quantities (not constant: a dead sensor). Returns the problems found."""
    errors: list[str] = []
    tcol = qty["time"]
    t = numeric["time"][sel]
    dt = np.diff(t)
    if len(t) < 2:
        return [f"{label}: column {tcol!r}: fewer than 2 samples"]
    if np.any(dt == 0):
        errors.append(f"{label}: column {tcol!r}: duplicated time at {float(t[1:][dt == 0][0])!r} s")
    elif np.all(dt < 0):
        return [f"{label}: column {tcol!r}: reversed time axis (time decreases from {float(t[0])!r} to "
                f"{float(t[-1])!r} s); expected increasing time"]
    elif np.any(dt < 0):
        return [f"{label}: column {tcol!r}: time not increasing at {float(t[1:][dt < 0][0])!r} s"]
    elif grid_deviation(t) > UNIFORM_TOL:
        errors.append(f"{label}: column {tcol!r}: non-uniform sampling (interval {dt.min():.6g} .. {dt.max():.6g} s; "
                      f"a time stamp {grid_deviation(t):.2g} intervals off the uniform grid, at most {UNIFORM_TOL:g}); "
                      f"a uniform grid is required")
    else:
        fs = 1.0 / float(np.mean(dt))
        if protocol in MIN_RATE and fs < MIN_RATE[protocol]:
            errors.append(f"{label}: column {tcol!r}: sampling rate {fs:.6g} Hz (measured from the time stamps); "
                          f"{'an' if protocol[0] in 'aeiou' else 'a'} {protocol} record needs >= "
                          f"{MIN_RATE[protocol]:g} Hz")
        if want is not None and abs(fs - want) > RATE_TOL * want:
            errors.append(f"{label}: column {tcol!r}: sampling rate {fs:.6g} Hz; protocol {protocol} records at "
                          f"{want:g} Hz ({_rate_hint(fs, want)})")
    if protocol is not None and t[-1] - t[0] < MIN_DURATION[protocol] * (1 - 1e-9):
        errors.append(f"{label}: record lasts {t[-1] - t[0]:.4g} s; protocol {protocol} needs >= "
                      f"{MIN_DURATION[protocol]:.4g} s")
    for q in EXCITED.get(protocol, ()):
        if q in numeric and np.ptp(numeric[q][sel]) == 0:
            errors.append(f"{label}: column {qty[q]!r} is constant ({float(numeric[q][sel][0])!r}); expected a record "
                          f"of the excited test (sensor disconnected?)")
    return errors


def _check_ranges(numeric: dict, qty: dict, where: str, current_range: tuple[float, float] | None) -> list[str]:
    """Physical ranges that catch a wrong unit under an SI header (degrees Celsius as kelvin, bar or gauge
    pressure as absolute pascal) and a current outside the active-valve map. Returns the problems found."""
    errors: list[str] = []
    if "oil temperature" in numeric:
        T = numeric["oil temperature"]
        bad = T[(T < T_OIL_RANGE[0]) | (T > T_OIL_RANGE[1])]
        if len(bad):
            errors.append(f"{where}: column {qty['oil temperature']!r}: {float(bad[0])!r} K outside "
                          f"{T_OIL_RANGE[0]:g}..{T_OIL_RANGE[1]:g} K (degrees Celsius in a kelvin column?)")
    if "precharge" in numeric:
        P = numeric["precharge"]
        bad = P[(P < PRECHARGE_RANGE[0]) | (P > PRECHARGE_RANGE[1])]
        if len(bad):
            errors.append(f"{where}: column {qty['precharge']!r}: {float(bad[0])!r} Pa outside "
                          f"{PRECHARGE_RANGE[0]:g}..{PRECHARGE_RANGE[1]:g} Pa absolute (bar in a pascal column? "
                          f"gauge instead of absolute?)")
    if current_range is not None and "current" in qty:
        cur = numeric["current"]
        lo, hi = current_range
        out = cur[(cur < lo - 1e-12) | (cur > hi + 1e-12)]
        if len(out):
            errors.append(f"{where}: column {qty['current']!r}: current {float(out[0])!r} A outside the active-valve map "
                          f"[{lo}, {hi}] A")
    return errors


def _rate_hint(fs: float, want: float) -> str:
    """The likely cause of a sampling rate ``fs`` off the protocol's ``want`` [Hz]."""
    for k, unit in ((1e3, "ms"), (1e6, "us"), (1 / 60.0, "min")):
        if abs(fs * k - want) <= RATE_TOL * want:
            return f"time in {unit} under a [s] header?"
    return "decimated or time-scaled record?"


def runs(df: pd.DataFrame) -> list[tuple[str | None, pd.DataFrame]]:
    """The records of a frame, split by its 'run' column (if any)."""
    if "run" not in df:
        return [(None, df)]
    return [(str(k), g.reset_index(drop=True)) for k, g in df.groupby("run", sort=False)]


from .record import read_record, check_record  # noqa: E402  (the one reader of measurement files)
from .outdir import atomic_files, check_out_dir, check_targets, out_lock  # noqa: E402

__all__ = ["DataError", "UNITS", "REQUIRED", "column", "write_frame", "read_frame", "read_meta", "runs",
           "read_table", "check_frame", "read_record", "check_record", "check_out_dir", "check_targets", "atomic_files",
           "out_lock"]

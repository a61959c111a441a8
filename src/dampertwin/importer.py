"""Import a user's own measurement (CSV / Parquet, any common units) into the
project's schema: SI, unit-suffixed columns (``force [N]``), Parquet with
metadata saying the file is imported, from which source (SHA-256) and how.

A mapping (YAML) names, for each source column, the quantity it holds and
its unit::

    protocol: monosine            # optional: validate against this test's schema
    columns:
      Zeit:  {quantity: time, unit: ms}
      Weg:   {quantity: displacement, unit: mm}
      Kraft: {quantity: force, unit: kN}
      Acc:   {quantity: rod acceleration, unit: g}
      Lauf:  {quantity: run}      # optional: the record name column
    constants:                    # optional: quantities the file lacks
      current: {value: 1600, unit: mA}
    csv: {sep: ";", decimal: ","} # optional: pandas.read_csv keywords
    time_offset: true             # optional: shift time to start at 0

A dyno export's date-time stamps (ISO 8601 ``2024-05-13 14:02:11.250``,
``13.05.2024 14:02:11,250``, a time of day ``14:02:11.250``; or any strptime
``format:``) become seconds from the first sample::

      Datum: {quantity: time, unit: datetime}            # or {..., format: "%d/%m/%Y %H:%M:%S.%f"}

The stamps must increase; they may lie off a uniform clock by half their
resolution (their rounding, e.g. 0.5 ms for stamps in ms) plus STAMP_JITTER
sampling intervals; the time written is that uniform clock (least-squares
fit through the stamps: the rate is measured, never assumed), the stamps'
resolution, deviation and rate go to the metadata (``time stamps``).
``synthetic: true`` labels a made-up record (the example files) as such.

A JSON source holding a matrix (one row per sample) names its columns::

    json: {matrix: data, columns: [Zeit, Weg, Kraft]}   # key of the matrix, its column names

    dampertwin import --map mapping.yaml rig.csv --out data/own/monosine/baseline_1.6.parquet
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from . import io
from .errors import UserError

G0 = 9.80665  # [m/s^2] standard gravity (same as kpi.G)

# unit -> (SI unit, factor, offset): value_SI = value * factor + offset
UNIT_TABLE: dict[str, tuple[str, float, float]] = {
    # time
    "s": ("s", 1.0, 0.0), "ms": ("s", 1e-3, 0.0), "us": ("s", 1e-6, 0.0), "min": ("s", 60.0, 0.0),
    # length
    "m": ("m", 1.0, 0.0), "cm": ("m", 1e-2, 0.0), "mm": ("m", 1e-3, 0.0), "um": ("m", 1e-6, 0.0),
    "in": ("m", 0.0254, 0.0),
    # velocity
    "m/s": ("m/s", 1.0, 0.0), "mm/s": ("m/s", 1e-3, 0.0), "cm/s": ("m/s", 1e-2, 0.0), "km/h": ("m/s", 1 / 3.6, 0.0),
    # acceleration
    "m/s^2": ("m/s^2", 1.0, 0.0), "m/s2": ("m/s^2", 1.0, 0.0), "mm/s^2": ("m/s^2", 1e-3, 0.0), "g": ("m/s^2", G0, 0.0),
    # force
    "in/s": ("m/s", 0.0254, 0.0),
    "N": ("N", 1.0, 0.0), "kN": ("N", 1e3, 0.0), "daN": ("N", 10.0, 0.0), "lbf": ("N", 4.4482216152605, 0.0),
    "kip": ("N", 4448.2216152605, 0.0),
    # pressure (absolute unless the mapping says gauge: true)
    "Pa": ("Pa", 1.0, 0.0), "kPa": ("Pa", 1e3, 0.0), "MPa": ("Pa", 1e6, 0.0), "bar": ("Pa", 1e5, 0.0),
    "mbar": ("Pa", 100.0, 0.0), "psi": ("Pa", 6894.757293168, 0.0),
    # volume flow
    "m^3/s": ("m^3/s", 1.0, 0.0), "l/min": ("m^3/s", 1e-3 / 60.0, 0.0), "l/s": ("m^3/s", 1e-3, 0.0),
    "cm^3/s": ("m^3/s", 1e-6, 0.0), "ml/s": ("m^3/s", 1e-6, 0.0), "m^3/h": ("m^3/s", 1 / 3600.0, 0.0),
    # current, temperature, frequency, dimensionless
    "A": ("A", 1.0, 0.0), "mA": ("A", 1e-3, 0.0),
    "K": ("K", 1.0, 0.0), "degC": ("K", 1.0, 273.15), "degF": ("K", 5.0 / 9.0, 273.15 - 32.0 * 5.0 / 9.0),
    "Hz": ("Hz", 1.0, 0.0), "kHz": ("Hz", 1e3, 0.0), "-": ("-", 1.0, 0.0),
}
ALIASES = {"µm": "um", "μm": "um", "µs": "us", "m/s²": "m/s^2", "°C": "degC", "C": "degC", "°F": "degF",
           "L/min": "l/min", "lb": "lbf", "kips": "kip", "ips": "in/s", "lpm": "l/min", "L/s": "l/s", "ccm/s": "cm^3/s", "G": "g"}
P_ATM = 101325.0  # [Pa] added to gauge pressures
# a number written with a decimal comma (1,5 / -0,25 / 1.234,5 / 1,5e-3): the hint of a non-numeric cell
_DECIMAL_COMMA = re.compile(r"^[+-]?(\d{1,3}(\.\d{3})+|\d+)?,\d+([eE][+-]?\d+)?$")
# a number with a thousands separator (1 234,5 / 1,234.5 / 1 234 with a (no-break) space): its own hint
_THOUSANDS = re.compile(r"^[+-]?\d{1,3}([ \u00a0\u202f]\d{3})+([.,]\d+)?$|^[+-]?\d{1,3}(,\d{3})+\.\d+$")

# date-time formats tried in turn (after a decimal comma becomes a point) when the mapping gives no format:
DATETIME_FORMATS = ("ISO8601", "%d.%m.%Y %H:%M:%S.%f", "%d.%m.%Y %H:%M:%S", "%H:%M:%S.%f", "%H:%M:%S")
STAMP_JITTER = 0.1  # [sampling intervals] clock jitter of date-time stamps tolerated on top of half their resolution


class MappingError(UserError):
    """A mapping or source problem; the message names the file and column."""


def to_si(values, unit: str, *, where: str = "value", gauge: bool = False) -> tuple[np.ndarray, str]:
    """Convert ``values`` in ``unit`` to SI. Returns (array, SI unit).
    Raises MappingError naming ``where`` for an unknown unit."""
    u = ALIASES.get(str(unit).strip(), str(unit).strip())
    if u not in UNIT_TABLE:
        raise MappingError(f"{where}: unknown unit {unit!r}; known: {', '.join(UNIT_TABLE)}")
    si, factor, offset = UNIT_TABLE[u]
    x = np.asarray(values, dtype=float) * factor + offset
    if gauge:
        if si != "Pa":
            raise MappingError(f"{where}: gauge: true only applies to pressures, unit is {unit!r}")
        x = x + P_ATM
    return x, si


def file_sha256(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _read_json_matrix(src: Path, spec) -> pd.DataFrame:
    """A JSON object holding a matrix (list of rows) under ``spec['matrix']``,
    columns named by ``spec['columns']``."""
    import json

    if not isinstance(spec, dict) or "matrix" not in spec or not isinstance(spec.get("columns"), list):
        raise MappingError(f"{src}: a JSON source needs 'json: {{matrix: KEY, columns: [NAME, ...]}}' in the mapping")
    try:
        doc = json.loads(src.read_text(encoding="utf-8"))
    except ValueError as e:  # JSONDecodeError and UnicodeDecodeError
        raise MappingError(f"{src}: not a UTF-8 JSON file ({' '.join(str(e).split())[:200]}); expected a JSON object "
                           f"holding the matrix") from None
    key, names = spec["matrix"], [str(c) for c in spec["columns"]]
    if not isinstance(doc, dict) or key not in doc:
        raise MappingError(f"{src}: no key {key!r} (keys: {', '.join(map(str, doc)) if isinstance(doc, dict) else '-'})")
    try:
        a = np.asarray(doc[key], dtype=float)
    except (TypeError, ValueError):
        raise MappingError(f"{src}: {key!r} is not a numeric matrix (one row per sample)") from None
    if a.ndim != 2 or a.shape[1] != len(names):
        raise MappingError(f"{src}: {key!r} has shape {a.shape}; the mapping names {len(names)} columns")
    return pd.DataFrame(a, columns=names)


def _read_source(src: Path, csv_kw: dict, json_spec=None) -> pd.DataFrame:
    """The source table through the measurement reader's file checks (size limit, readable, not empty);
    a JSON matrix (``json:`` in the mapping) after the same file checks."""
    if src.suffix == ".json":
        io.check_file(src, (".json",))
        df = _read_json_matrix(src, json_spec)
        if len(df) == 0:
            raise MappingError(f"{src}: the matrix has no rows; expected a record")
        return df
    return io.read_table(src, csv_kw)[0]


def _plain(o):
    """A YAML value as JSON-safe data (keys as strings, dates and the like as text)."""
    if isinstance(o, dict):
        return {str(k): _plain(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_plain(v) for v in o]
    return o if isinstance(o, (str, int, float, bool, type(None))) else str(o)


def _number(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise MappingError(f"{where}: {v!r}; expected a finite number")
    return float(v)


def _numeric(col: pd.Series, csv_kw) -> pd.Series:
    """A column as numbers (NaN where a cell is not one). A text cell keeps pandas from applying the
    mapping's csv ``decimal`` / ``thousands`` to its column: they are applied here, so the cell named
    is the text cell, not the column's first number."""
    raw = pd.to_numeric(col, errors="coerce")
    kw = csv_kw if isinstance(csv_kw, dict) else {}
    if raw.isna().any() and not pd.api.types.is_numeric_dtype(col) and (kw.get("decimal") or kw.get("thousands")):
        text = col.astype(str).str.strip()
        if kw.get("thousands"):
            text = text.str.replace(str(kw["thousands"]), "", regex=False)
        if kw.get("decimal"):
            text = text.str.replace(str(kw["decimal"]), ".", regex=False)
        raw = pd.to_numeric(text.where(col.notna()), errors="coerce")
    return raw


def convert(df: pd.DataFrame, mapping: dict, *, where: str = "source") -> pd.DataFrame:
    """Apply a column mapping (see module docstring) to a frame: the result
    has only the mapped columns, in SI, named ``quantity [SI unit]``."""
    cols = mapping.get("columns")
    if not isinstance(cols, dict) or not cols:
        raise MappingError(f"{where}: mapping needs a non-empty 'columns:' section")
    out, stamps = {}, None
    for name, spec in cols.items():
        label = f"{where}: column {name!r}"
        if name not in df.columns:
            raise MappingError(f"{label}: not in the file (columns: {', '.join(map(str, df.columns))})")
        if not isinstance(spec, dict) or "quantity" not in spec:
            raise MappingError(f"{label}: mapping entry needs 'quantity' (and 'unit')")
        q = str(spec["quantity"]).strip()
        if q != "run" and q not in io.UNITS:
            raise MappingError(f"{label}: unknown quantity {q!r}; expected one of run, {', '.join(io.UNITS)}")
        if q == "run":
            out["run"] = df[name].astype(str).to_numpy()
            continue
        if "unit" not in spec:
            raise MappingError(f"{label}: mapping entry needs 'unit'")
        if spec["unit"] == "datetime" or "format" in spec:
            if q != "time" or spec["unit"] != "datetime":
                raise MappingError(f"{label}: unit 'datetime' (and format:) only applies to quantity time, with "
                                   f"unit: datetime; got quantity {q!r}, unit {spec['unit']!r}")
            if "time [s]" in out:
                raise MappingError(f"{label}: quantity 'time' mapped twice")
            out["time [s]"], stamps = parse_stamps(df[name], label, spec.get("format"))
            stamp_label = label
            continue
        raw = _numeric(df[name], mapping.get("csv"))
        if raw.isna().any():
            i = int(np.argmax(raw.isna().to_numpy()))
            bad = df[name].iloc[i]
            empty = pd.isna(bad) or str(bad).strip() == ""
            cell = "" if empty else str(bad).strip()
            hint = ("a thousands separator needs csv: {thousands: ...} (and decimal:)" if _THOUSANDS.match(cell)
                    else "a decimal comma needs csv: {decimal: ','}" if _DECIMAL_COMMA.match(cell)
                    else "a text line in the data (a footer, a second header) needs csv: {skipfooter: N, "
                         "engine: python} or {comment: '#'}; a missing value cannot be imported")
            raise MappingError(f"{label}: {int(raw.isna().sum())} non-numeric values (the first, data row {i + 1}: "
                               f"{'an empty cell' if empty else repr(str(bad))}; {hint})")
        vals = raw.to_numpy()
        if q == "time" and mapping.get("time_offset") is True:  # in the file's own units and dtype first: exact
            vals = vals - vals[0]  # for integer epoch stamps (1.7e15 us; float64 seconds resolve only ~0.2 us)
        x, si = to_si(vals, spec["unit"], where=label, gauge=bool(spec.get("gauge", False)))
        if q in io.UNITS and io.UNITS[q] != si:
            raise MappingError(f"{label}: unit {spec['unit']!r} is a {si} unit but {q!r} needs {io.UNITS[q]!r}")
        col = f"{q} [{si}]"
        if col in out:
            raise MappingError(f"{label}: quantity {q!r} mapped twice")
        out[col] = x * _number(spec.get("scale", 1.0), f"{label}: scale")
    n = len(df)
    consts = mapping.get("constants") or {}
    if not isinstance(consts, dict):
        raise MappingError(f"{where}: 'constants:' must map a quantity to {{value, unit}}")
    for q, spec in consts.items():
        label = f"{where}: constant {q!r}"
        if not isinstance(spec, dict) or "value" not in spec or "unit" not in spec:
            raise MappingError(f"{label}: needs 'value' and 'unit'")
        if q not in io.UNITS:
            raise MappingError(f"{label}: unknown quantity {q!r}; expected one of {', '.join(io.UNITS)}")
        x, si = to_si([_number(spec["value"], f"{label}: value")], spec["unit"], where=label)
        if q in io.UNITS and io.UNITS[q] != si:
            raise MappingError(f"{label}: unit {spec['unit']!r} is a {si} unit but {q!r} needs {io.UNITS[q]!r}")
        if f"{q} [{si}]" in out:  # a constant is for a quantity the file lacks, never in place of a measured one
            src = next(str(c) for c, sp in cols.items() if isinstance(sp, dict) and str(sp.get("quantity")).strip() == q)
            raise MappingError(f"{label}: quantity {q!r} is already mapped from column {src!r}; 'constants:' is for "
                               f"quantities the file lacks (drop the constant or the column's entry)")
        out[f"{q} [{si}]"] = np.full(n, x[0])
    res = pd.DataFrame(out)
    if mapping.get("run") is not None and "run" not in res:  # one label for the whole file
        if not isinstance(mapping["run"], str) or not mapping["run"]:
            raise MappingError(f"{where}: run: {mapping['run']!r}; expected the record's run label (e.g. I1.6)")
        res["run"] = mapping["run"]
    if stamps is not None:  # the uniform clock through the stamps, per record
        res["time [s]"], stamp_info = regrid_stamps(res["time [s]"].to_numpy(), stamps,
                                                    res["run"].to_numpy() if "run" in res else None, stamp_label)
    if mapping.get("time_offset") and "time [s]" in res:
        if "run" in res:
            res["time [s]"] = res["time [s]"] - res.groupby("run")["time [s]"].transform("first")
        else:
            res["time [s]"] = res["time [s]"] - res["time [s]"].iloc[0]
    if "run" in res:  # the project's files carry 'run' last
        res = res[[c for c in res.columns if c != "run"] + ["run"]]
    if stamps is not None:
        res.attrs["time stamps"] = stamp_info
    return res


def parse_stamps(values: pd.Series, label: str, fmt: str | None = None) -> tuple[np.ndarray, dict]:
    """Date-time stamps -> seconds from the first one [s] (float) and
    ``{strings, resolution [s], format}``: the resolution is the largest
    power of ten of seconds (1 s .. 1 ns) every stamp is a multiple of.
    Tries ``fmt`` (strptime, on the stamps as written) or DATETIME_FORMATS;
    MappingError naming ``label`` when no format reads every stamp."""
    raw = values.astype(str).str.strip()
    if fmt is not None and not isinstance(fmt, str):
        raise MappingError(f"{label}: format: {fmt!r}; expected a strptime format such as '%d.%m.%Y %H:%M:%S,%f'")
    tries = [(fmt, raw)] if fmt is not None else [(f, raw.str.replace(",", ".", regex=False)) for f in DATETIME_FORMATS]
    best = None
    for f, ss in tries:
        try:
            ts = pd.to_datetime(ss, format=f, utc=True, errors="coerce")
        except (ValueError, TypeError):  # a format pandas cannot use at all
            continue
        bad = int(ts.isna().sum())
        if bad == 0:
            d = ts - ts.iloc[0]
            ns = d.dt.as_unit("ns").astype("int64").to_numpy()
            k = next(k for k in range(9, -1, -1) if np.all(ns % 10**k == 0))
            return d.dt.total_seconds().to_numpy(float), {"strings": raw.to_numpy(), "resolution [s]": 10.0**(k - 9),
                                                          "format": f}
        if best is None or bad < best[0]:
            best = (bad, raw[ts.isna()].iloc[0])
    n_bad, first = best if best is not None else (len(raw), raw.iloc[0])
    want = repr(fmt) if fmt is not None else ("ISO 8601 (2024-05-13 14:02:11.250), DD.MM.YYYY hh:mm:ss,fff or "
                                             "hh:mm:ss.fff; or give format: (strptime) in the mapping")
    raise MappingError(f"{label}: {n_bad} of {len(raw)} date-time stamps unreadable (first {first!r}); expected {want}")


def regrid_stamps(t: np.ndarray, stamps: dict, runs: np.ndarray | None, label: str) -> tuple[np.ndarray, dict]:
    """The uniform clock through date-time stamps ``t`` [s] (each run on its
    own): a least-squares line t_k = t_0 + k dt, kept when every stamp lies
    within half the stamps' resolution plus STAMP_JITTER intervals of it.
    Returns (time from the file's first sample [s], metadata: resolution,
    largest deviation [s], measured rate [Hz] per run). MappingError naming
    ``label`` for a repeated, decreasing or irregular stamp."""
    res, s = stamps["resolution [s]"], stamps["strings"]
    labels = runs if runs is not None else np.zeros(len(t), int)
    out = np.empty_like(t)
    rates, devs = {}, []
    for run in dict.fromkeys(labels.tolist()):
        idx = np.flatnonzero(labels == run)
        where = label + (f" run {run!r}" if runs is not None else "")
        tg = t[idx]
        if len(tg) < 2:
            raise MappingError(f"{where}: fewer than 2 date-time stamps; expected a record")
        dt = np.diff(tg)
        for cond, what in ((dt == 0, "repeats"), (dt < 0, "is earlier than")):
            if np.any(cond):
                i = int(np.argmax(cond))
                raise MappingError(f"{where}: stamp {s[idx[i + 1]]!r} (data row {idx[i + 1] + 1}) {what} the one "
                                   f"before it ({s[idx[i]]!r}); expected increasing stamps"
                                   + (f" (stamps resolving {res:g} s cannot hold a record sampled faster than "
                                      f"{1 / res:g} Hz)" if what == "repeats" and np.median(dt) < 2 * res else ""))
        k = np.arange(len(tg), dtype=float)
        slope, icept = np.polyfit(k, tg, 1)
        dev = np.abs(tg - (icept + slope * k))
        tol = 0.5 * res + STAMP_JITTER * slope
        if dev.max() > tol:
            i = int(np.argmax(dev))
            raise MappingError(f"{where}: irregular sampling: stamp {s[idx[i]]!r} (data row {idx[i] + 1}) lies "
                               f"{dev.max():.3g} s off the uniform {1 / slope:.6g} Hz clock through the stamps; at "
                               f"most {tol:.3g} s (half the stamps' {res:g} s resolution + {STAMP_JITTER:g} "
                               f"sampling interval) is accepted")
        out[idx] = icept + slope * k
        rates[str(run)] = 1.0 / slope
        devs.append(float(dev.max()))
    out -= out[0]
    info = {"format": stamps["format"], "resolution [s]": res, "max deviation [s]": max(devs),
            "rate [Hz]": rates if runs is not None else rates["0"]}
    return out, info


def _setting_meta(mapping: dict, where: str) -> dict:
    """``{"setting": {adjuster: click}}`` for the record's metadata from the mapping's optional
    ``setting: {rebound: R, compression: C}`` (clicks counted out from fully closed,
    design/adjusters.py); {} when the mapping names none."""
    from .design.adjusters import ADJUSTER_NAMES

    s = mapping.get("setting")
    if s is None:
        return {}
    if not (isinstance(s, dict) and s and all(n in ADJUSTER_NAMES and isinstance(k, int) and not isinstance(k, bool)
                                              and k >= 0 for n, k in s.items())):
        raise MappingError(f"{where}: setting: {s!r}; expected {{rebound: R, compression: C}} (either or both): "
                           f"click numbers >= 0, counted out from fully closed")
    return {"setting": dict(s)}


MAPPING_KEYS = {"columns", "constants", "run", "time_offset", "protocol", "csv", "json", "synthetic", "setting"}
COLUMN_KEYS = {"quantity", "unit", "scale", "gauge", "format"}


def _check_mapping_keys(mapping: dict, where: str) -> None:
    """A mapping's keys and its columns' keys are the documented ones (a typo would drop a setting or a
    scale without a word); time_offset and gauge are true / false."""
    extra = sorted(map(str, set(mapping) - MAPPING_KEYS))
    if extra:
        raise MappingError(f"{where}: unknown key(s) {', '.join(extra)}; expected {', '.join(sorted(MAPPING_KEYS))}")
    if not isinstance(mapping.get("time_offset", False), bool):
        raise MappingError(f"{where}: time_offset: {mapping['time_offset']!r}; expected true or false")
    for name, spec in (mapping.get("columns") or {}).items() if isinstance(mapping.get("columns"), dict) else ():
        if isinstance(spec, dict):
            extra = sorted(map(str, set(spec) - COLUMN_KEYS))
            if extra:
                raise MappingError(f"{where}: column {name!r}: unknown key(s) {', '.join(extra)}; expected "
                                   f"{', '.join(sorted(COLUMN_KEYS))}")
            if not isinstance(spec.get("gauge", False), bool):
                raise MappingError(f"{where}: column {name!r}: gauge: {spec['gauge']!r}; expected true or false")


def import_measurement(src: str | os.PathLike, mapping: dict | str | os.PathLike, out: str | os.PathLike, *,
                       protocol: str | None = None) -> Path:
    """Convert ``src`` (CSV / Parquet / JSON matrix) with ``mapping`` (dict or YAML path) and
    write ``out`` (Parquet, project schema). ``protocol`` (default: the
    mapping's ``protocol`` or the parent folder name of ``out`` when it is a
    known test) selects the checks of ``io.read_record`` (rate, duration,
    labels, magnitudes, sign) the record must pass before it is written."""
    from .design import ConfigTextError, yaml_load_file
    from .io.record import default_conf

    src, out = Path(src), Path(out)
    map_where = "mapping"
    if not isinstance(mapping, dict):
        map_where = str(mapping)
        if not Path(mapping).is_file():
            raise MappingError(f"{map_where}: " + ("is a folder; expected a mapping YAML file" if Path(mapping).is_dir()
                                                   else "file not found"))
        try:
            mapping = yaml_load_file(mapping)  # duplicate keys, bad YAML: one line naming file and line
        except ConfigTextError as e:
            raise MappingError(str(e)) from None
        if not isinstance(mapping, dict):
            raise MappingError(f"{map_where}: expected a mapping with a 'columns:' section")
    if out.suffix != ".parquet":
        raise MappingError(f"{out}: output must be a .parquet file")
    _check_mapping_keys(mapping, map_where)
    for key in ("protocol", "csv", "json"):
        if mapping.get(key) is not None and not isinstance(mapping[key], str if key == "protocol" else dict):
            raise MappingError(f"{map_where}: {key}: {mapping[key]!r}; expected "
                               + {"protocol": "a test name (conf/test/<test>.yaml)",
                                  "csv": "a mapping of pandas.read_csv keywords",
                                  "json": "a mapping {matrix: KEY, columns: [NAME, ...]}"}[key])
    named = out.parent.name if (default_conf() / "test" / f"{out.parent.name}.yaml").is_file() else None
    protocol = protocol or mapping.get("protocol") or named
    df = _read_source(src, dict(mapping.get("csv") or {}), mapping.get("json"))
    res = convert(df, mapping, where=f"{src} (mapping {map_where})")
    if not isinstance(mapping.get("synthetic", False), bool):
        raise MappingError(f"{map_where}: synthetic: {mapping['synthetic']!r}; expected true or false")
    meta = {"imported": True, "synthetic": mapping.get("synthetic", False), "source": src.name,
            "source_sha256": file_sha256(src), "mapping": _plain(mapping), "protocol": protocol,
            "units": {str(k): v.get("unit") for k, v in mapping["columns"].items() if isinstance(v, dict)},
            **_setting_meta(mapping, map_where)}
    if "time stamps" in res.attrs:
        meta["time stamps"] = res.attrs["time stamps"]
    # the record passes the measurement reader's checks before anything is written (an earlier file stays)
    io.check_record(res, meta, f"{out} (imported from {src})", protocol)
    io.write_frame(out, res, meta)
    return out


__all__ = ["UNIT_TABLE", "MappingError", "to_si", "convert", "import_measurement", "file_sha256", "parse_stamps",
           "regrid_stamps", "DATETIME_FORMATS", "STAMP_JITTER"]

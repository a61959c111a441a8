"""The keys of ``conf/discrepancy.yaml`` the workflow reads from its
``decision`` block and its ``profiles``, with their types and ranges: a
misspelt key or a value out of range is an error naming the key, never a
silent default (no I/O here: the entry reads the file)."""

from __future__ import annotations

import difflib
import math

# key -> (kind, low, high, required); kind: "num" (low < x <= high), "prob" (low <= x < high: a test's
# size, 0 switches the test off), "int" (low <= x), "bool", or a tuple of allowed words. Shares in (0, 1]
DECISION = {
    "step": ("num", 0.0, 1.0, True),               # finite-difference step, normalised coordinates
    "disagree_mean_z2": ("num", 0.0, math.inf, True),
    "ok_mean_z2": ("num", 0.0, math.inf, True),
    "record_alpha": ("prob", 0.0, 1.0, False),     # 0: no per-record gate
    "min_closed": ("num", 0.0, 1.0, True),
    "closed_on": (("heldout", "reached"), None, None, False),
    "bootstrap_over": (("eligible", "viable"), None, None, False),
    "partner_alpha": ("prob", 0.0, 1.0, False),
    "partner_resolvable": ("bool", None, None, False),
    "lead_resolvable": ("bool", None, None, False),
    "prior_sigma": ("num", 0.0, math.inf, False),
    "stable": ("num", 0.0, 1.0, True),
    "group_share": ("num", 0.0, 1.0, True),
    "resolvability": ("bool", None, None, False),
    "where_z": ("num", 0.0, math.inf, True),
    "where_max": ("int", 0, None, True),
}
PROFILE = {"tests", "max_duration", "run_filter", "calibration", "candidates", "bootstrap"}
PROFILE_BLOCKS = {"calibration": {"max_params": 1, "iterations": 0},      # key -> smallest value (integers)
                  "candidates": {"refit_top": 1, "iterations": 0, "pairs": 0}}
RUN_FILTER = {"min_peak_velocity", "max_peak_velocity", "currents"}


def _unknown(where: str, key, known) -> str:
    near = difflib.get_close_matches(str(key), list(known), n=1)
    return (f"{where}.{key}: unknown key" + (f" (did you mean {near[0]!r}?)" if near else "")
            + f"; expected {', '.join(sorted(known))}")


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(float(x))


def _value(where: str, x, kind, lo, hi) -> str | None:
    """The error of one value, or None."""
    if isinstance(kind, tuple):
        return None if x in kind else f"{where}: {x!r}; expected one of {', '.join(kind)}"
    if kind == "bool":
        return None if isinstance(x, bool) else f"{where}: {x!r}; expected true or false"
    if kind == "int":
        ok = isinstance(x, int) and not isinstance(x, bool) and x >= lo
        return None if ok else f"{where}: {x!r}; expected an integer >= {lo}"
    if kind == "prob":  # [0, 1)
        return None if _number(x) and lo <= x < hi else f"{where}: {x!r}; expected a number in [{lo:g}, {hi:g})"
    return None if _number(x) and lo < x <= hi else f"{where}: {x!r}; expected a number in ({lo:g}, {hi:g}]"


def decision_errors(dec) -> list[str]:
    """Errors of the ``decision`` block (unknown keys, missing required ones, types, ranges)."""
    if not isinstance(dec, dict):
        return [f"decision: {dec!r}; expected a mapping of {', '.join(DECISION)}"]
    bad = [_unknown("decision", k, DECISION) for k in dec if k not in DECISION]
    for k, (kind, lo, hi, required) in DECISION.items():
        if k not in dec:
            bad += [f"decision.{k}: missing"] if required else []
        elif (e := _value(f"decision.{k}", dec[k], kind, lo, hi)) is not None:
            bad.append(e)
    return bad


def _run_filter_errors(where: str, rf) -> list[str]:
    if rf is None:
        return []
    if not isinstance(rf, dict):
        return [f"{where}: {rf!r}; expected a mapping test -> {{{', '.join(sorted(RUN_FILTER))}}}"]
    bad = []
    for test, spec in rf.items():
        w = f"{where}.{test}"
        if not isinstance(spec, dict):
            bad.append(f"{w}: {spec!r}; expected a mapping of {', '.join(sorted(RUN_FILTER))}")
            continue
        bad += [_unknown(w, k, RUN_FILTER) for k in spec if k not in RUN_FILTER]
        for k in ("min_peak_velocity", "max_peak_velocity"):  # [m/s]
            if k in spec and not (_number(spec[k]) and spec[k] >= 0):
                bad.append(f"{w}.{k}: {spec[k]!r}; expected a velocity >= 0 [m/s]")
        cur = spec.get("currents")
        if cur is not None and not (isinstance(cur, list) and cur and all(_number(c) and c >= 0 for c in cur)):
            bad.append(f"{w}.currents: {cur!r}; expected a list of currents >= 0 [A]")
    return bad


def profile_errors(name: str, prof) -> list[str]:
    """Errors of one budget profile (keys, the integer budgets, run filters, record durations)."""
    where = f"profiles.{name}"
    if not isinstance(prof, dict):
        return [f"{where}: {prof!r}; expected a mapping of {', '.join(sorted(PROFILE))}"]
    bad = [_unknown(where, k, PROFILE) for k in prof if k not in PROFILE]
    bad += [f"{where}.{k}: missing" for k in ("tests", "calibration", "candidates", "bootstrap") if k not in prof]
    if "tests" in prof and not isinstance(prof["tests"], dict):
        bad.append(f"{where}.tests: {prof['tests']!r}; expected a mapping test -> cases (a list, or all)")
    for block, keys in PROFILE_BLOCKS.items():
        b = prof.get(block)
        if block not in prof:
            continue
        if not isinstance(b, dict):
            bad.append(f"{where}.{block}: {b!r}; expected a mapping of {', '.join(keys)}")
            continue
        bad += [_unknown(f"{where}.{block}", k, keys) for k in b if k not in keys]
        bad += [e for k, lo in keys.items() if k in b
                and (e := _value(f"{where}.{block}.{k}", b[k], "int", lo, None)) is not None]
        bad += [f"{where}.{block}.{k}: missing" for k in keys if k not in b and k != "pairs"]
    if "bootstrap" in prof and (e := _value(f"{where}.bootstrap", prof["bootstrap"], "int", 1, None)):
        bad.append(e)
    md = prof.get("max_duration")
    if md is not None and not (isinstance(md, dict) and all(_number(v) and v > 0 for v in md.values())):
        bad.append(f"{where}.max_duration: {md!r}; expected a mapping test -> seconds > 0")
    return bad + _run_filter_errors(f"{where}.run_filter", prof.get("run_filter"))

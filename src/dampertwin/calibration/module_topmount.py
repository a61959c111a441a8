"""Approach 2's top mount (thesis 7.2, fig. 7.2 / 7.4): fitted on the
module-level test instead of a top-mount bench.

The damper module is driven at its lower mount by the training signal; an
LVDT on the rod records the rod's displacement relative to the top-mount
housing (the mount's deflection X [m]) and the load cell above the housing
the force [N]. With X as the input, the mount alone is a regular fit
(thesis L1499): the static curve F_LD(X) a 5th-order polynomial by least
squares on the force-deflection characteristic, then the AutoBushFD
parameters by the GA of approach 1 with the table 6.4 limits (eq. 6.3,
int |F_test - F_sim| dt). The fitting core is approach 1's
(:func:`approach1.fit_top_mount`); this module turns the module record into
its input. No file I/O here.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..design import Design
from ..errors import UserError
from ..io import runs
from .approach1 import fit_top_mount
from .ga import FitResult, GASettings

DEFLECTION = "top mount deflection [m]"  # the LVDT channel of the module record (dampertwin.lab)
KEYS = ("run", "input_cutoff", "static")


def deflection_record(measured: pd.DataFrame, run: str, where: str = "module record") -> pd.DataFrame:
    """One run of a module-level record as a top-mount record: time [s],
    displacement [m] = the LVDT's deflection, force [N] = the load cell,
    run. UserError naming ``where`` when the run or a channel is missing."""
    rs = dict(runs(measured))
    if run not in rs:
        raise UserError(f"{where}: no run {run!r}; runs present: {', '.join(map(str, rs))}")
    g = rs[run]
    missing = [c for c in ("time [s]", DEFLECTION, "force [N]") if c not in g]
    if missing:
        raise UserError(f"{where}: run {run!r} lacks the column(s) {', '.join(missing)}; expected the module-level "
                        "top-mount test (conf/test/module_topmount.yaml: the LVDT on the rod, the load cell)")
    X = g[DEFLECTION].to_numpy(float)
    if not np.all(np.isfinite(X)) or np.ptp(X) <= 0:
        raise UserError(f"{where}: run {run!r}: column {DEFLECTION!r} is not a finite, moving deflection")
    return pd.DataFrame({"run": run, "time [s]": g["time [s]"].to_numpy(float), "displacement [m]": X,
                         "force [N]": g["force [N]"].to_numpy(float)})


def calibration(module_cal: dict, parameters: list, where: str) -> dict:
    """approach1.fit_top_mount's configuration for the module record:
    the run, the input low-pass [Hz], the static curve's order and input
    low-pass, approach 1's parameter list (table 6.4 limits).
    UserError naming ``where`` and the key."""
    if not isinstance(module_cal, dict):
        raise UserError(f"{where}: expected a mapping with the keys {', '.join(KEYS)}")
    bad = [f"{k}: missing" for k in KEYS if k not in module_cal]
    bad += [f"{k}: unknown key; expected {', '.join(KEYS)}" for k in module_cal if k not in KEYS]
    st = module_cal.get("static", {})
    if not isinstance(st, dict) or set(st) != {"order", "input_cutoff"}:
        bad.append(f"static: {st!r}; expected {{order: 5, input_cutoff: Hz}}")
    elif not (isinstance(st["order"], int) and 1 <= st["order"] <= 5):
        bad.append(f"static.order: {st['order']!r}; expected an integer 1..5 (thesis 7.2: 5)")
    if bad:
        raise UserError(f"{where}: " + "; ".join(bad))
    run = str(module_cal["run"])
    return {"input_cutoff": float(module_cal["input_cutoff"]), "dynamic_run": run, "parameters": parameters,
            "static": {"run": run, "order": int(st["order"]), "input_cutoff": float(st["input_cutoff"])}}


def fit_module_top_mount(design: Design, measured: pd.DataFrame, cal: dict, settings: GASettings, seed: int,
                         **kw) -> tuple[FitResult, list[float], str, pd.DataFrame]:
    """Fit the top mount on one run of the module-level record (``cal`` from
    :func:`calibration`): approach1.fit_top_mount on the LVDT deflection and
    the load-cell force. Returns (result, static curve coefficients [N/m^k],
    which curve was kept, the deflection record fitted)."""
    rec = deflection_record(measured, cal["dynamic_run"])
    res, coef, kept = fit_top_mount(design, rec, cal, settings, seed, **kw)
    return res, coef, kept, rec

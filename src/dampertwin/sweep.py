"""One-factor-at-a-time design sweeps with Hydra multirun (thesis table 6.5
design cases, or any parameter at chosen levels).

    dampertwin sweep 'variant=glob(*)'                 # the 10 design cases
    dampertwin sweep +ofat=c_params                    # every C parameter at -20 % / +20 %
    dampertwin sweep factor=piston_intake.a,base_intake.a level=-0.2,0.2
    dampertwin sweep 'variant=glob(*)' hydra/launcher=slurm   # same sweep on SLURM (submitit)
    dampertwin sweep --scheduler tcp://HOST:8786 'variant=glob(*)'   # same sweep on a Dask cluster

Each job writes results/sweeps/<sweep>/<name>/ (time series and KPIs as
Parquet with the resolved config and design hash in the metadata); a job
whose artifacts are complete is skipped (resume); a failing job is recorded
and does not stop the others; the summary (one row per variant, every KPI
and its change vs the baseline) is written when the multirun ends.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import re
import sys
import traceback
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from . import kpi
from .config import repo_root
from .design import Design, load
from .errors import UserError, one_line
from .io import write_frame
from .protocols import build_runs, load_protocol
from .simulation import simulate
from .variants import check_current

log = logging.getLogger("dampertwin.sweep")
ROOT_ENV = "DAMPERTWIN_ROOT"
COMPLETE, FAILED = "_COMPLETE.json", "_FAILED.json"
# "rebound peak" is the positive extreme of the rebound half-cycle, "compression
# peak" the negative extreme of the compression half, each averaged over the
# steady cycles (kpi.rod_acceleration_extremes): the directions of the thesis'
# table-6.5 peaks, without their sign flips (issue 14)
KPIS = ("rebound peak [g]", "compression peak [g]", "PSD 200 Hz [dB]", "PSD 300 Hz [dB]", "peak rod force [N]")
# thesis table 6.5, measured column (rebound, compression peaks [g]) for the trend check
THESIS_MEASURED = {
    "baseline_1.6": (10.7, -9.2), "baseline_0.9": (-1.3, -6.1), "baseline_0.32": (4.5, -2.7),
    "alternative_top_mount": (8.3, -10.9), "increased_precharge": (10.2, -9.5),
    "different_active_valve": (9.1, -8.9), "lower_piston_intake": (10.9, -12.3),
    "lower_piston_rebound": (10.7, -9.6), "lower_base_intake": (15.7, -8.4), "lower_base_compression": (5.1, -8.6),
}
BASELINE_CASE = "baseline_1.6"


def project_root(root: str | Path | None = None) -> Path:
    """The project whose conf/ and results/ a sweep uses: ``root`` if given,
    else $DAMPERTWIN_ROOT, else the repository around the working directory
    (as DVC and Hydra do) — never the installed package's location."""
    root = root or os.environ.get(ROOT_ENV)
    if root:
        r = Path(root).resolve()
        if not (r / "conf").is_dir():
            raise UserError(f"{r}: no conf/ folder; expected a dampertwin project root")
        return r
    try:
        return repo_root(Path.cwd())
    except FileNotFoundError as e:
        raise UserError(f"{e}; run from inside the project, or give --root DIR or ${ROOT_ENV}") from None


def _root(cfg: DictConfig, root: Path | None) -> Path:
    return Path(root) if root is not None else project_root(cfg.get("root"))


def _level(cfg: DictConfig) -> float:
    """The OFAT level of ``factor`` as a finite number (UserError otherwise)."""
    lv = cfg.get("level")
    if isinstance(lv, bool) or not isinstance(lv, (int, float)) or not math.isfinite(lv):
        raise UserError(f"factor={cfg.factor}: level {lv!r}; expected a finite number (e.g. level=-0.2,0.2)")
    return float(lv)


def job_name(cfg: DictConfig) -> str:
    v = cfg.get("variant")
    case = v.get("case") if isinstance(v, DictConfig) else None
    name = str(case) if isinstance(case, str) and case else "invalid_variant"
    if cfg.get("factor"):
        try:
            name += f"__{cfg.factor}@{100 * _level(cfg):+.10g}%"  # 10 digits: distinct levels, distinct folders
        except UserError:
            name += f"__{cfg.factor}@invalid-level"
    return re.sub(r"[^\w.@+%=-]", "_", name)  # one folder, never a path


RUN_CONTROL = ("hydra", "fail_on", "results_dir", "sweep", "root")  # keys that do not change a variant's results


def config_hash(cfg: DictConfig) -> str:
    """Hash of what determines a variant's results (not where or how it runs)."""
    c = OmegaConf.to_container(cfg, resolve=True)
    for k in RUN_CONTROL:
        c.pop(k, None)
    return hashlib.sha256(json.dumps(c, sort_keys=True, default=str).encode()).hexdigest()[:16]


def design_for(cfg: DictConfig, root: Path | None = None) -> Design:
    """The calibrated design of the case when the approach-1 study produced
    one, else the nominal baseline with the case's overrides; then the OFAT
    factor, if any. Errors name the variant file or the factor."""
    root = _root(cfg, root)
    case = cfg.variant.case
    cal = root / cfg.calibrated / f"{case}.yaml"
    if cfg.use_calibrated and cal.is_file():
        d = load(cal, map_dirs=[(root / cfg.design).parent])  # a variant may name a map of conf/design
    else:
        d = load(root / cfg.design)
        if cfg.variant.overrides:
            d = d.with_overrides(OmegaConf.to_container(cfg.variant.overrides, resolve=True),
                                 source=root / "conf" / "variant" / f"{case}.yaml")
    if cfg.get("factor"):
        level = _level(cfg)
        try:
            nominal = d[cfg.factor]
        except KeyError as e:
            raise UserError(f"factor={cfg.factor}: {e.args[0]}") from None
        if not isinstance(nominal, float):
            raise UserError(f"factor={cfg.factor}: not a scalar parameter; expected a key like piston_intake.a")
        d = d.with_overrides({cfg.factor: nominal * (1.0 + level)}, source=f"factor={cfg.factor} level={level}")
    return d


def variant_file(cfg: DictConfig, root: Path) -> Path:
    """The conf/variant file Hydra composed ``cfg.variant`` from (its choice), for error messages."""
    try:
        from hydra.core.hydra_config import HydraConfig

        choice = HydraConfig.get().runtime.choices.get("variant")
    except (ImportError, ValueError):
        choice = None
    v = cfg.get("variant")
    choice = choice or (v.get("case") if isinstance(v, DictConfig) else None) or "?"
    return root / "conf" / "variant" / f"{choice}.yaml"


def check_job(cfg: DictConfig, root: Path) -> None:
    """The composed variant (keys, row, current) and the seed, before any work:
    a UserError naming the variant file and key, never a raw omegaconf message."""
    from .variants import variant_errors

    path = variant_file(cfg, root)
    v = cfg.get("variant")
    errors = variant_errors(OmegaConf.to_container(v, resolve=True) if isinstance(v, DictConfig) else v, path)
    seed = cfg.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32:
        errors.append(f"seed={seed!r}: expected an integer 0 .. {2**32 - 1}")
    tests, known = cfg.get("tests"), sorted(p.stem for p in (root / "conf" / "test").glob("*.yaml"))
    if not OmegaConf.is_list(tests) or not tests or any(not isinstance(t, str) or t not in known for t in tests):
        errors.append(f"tests={tests!r}: expected a list of tests of conf/test/ (e.g. 'tests=[monosine,random]'; "
                      f"known: {', '.join(known)})")
    if cfg.get("level") is not None and not cfg.get("factor"):
        errors.append(f"level={cfg.get('level')!r} without factor=: a level scales a design key; give factor=GROUP.NAME")
    if errors:
        raise UserError(errors)


def sweep_dir(cfg: DictConfig, root: Path | None = None) -> Path:
    """results_dir/<sweep> (results_dir relative to the project root unless absolute)."""
    return _root(cfg, root) / cfg.results_dir / cfg.sweep


def run_variant(cfg: DictConfig, root: Path | None = None) -> Path:
    """Run the standard tests for one variant; write artifacts atomically;
    skip if complete; record (not raise) a failure."""
    root = _root(cfg, root)
    name = job_name(cfg)
    out = sweep_dir(cfg, root) / name
    h = config_hash(cfg)
    done = out / COMPLETE
    if done.is_file() and json.loads(done.read_text()).get("config_hash") == h:
        log.info("%s: complete, skipped", name)
        return out
    out.mkdir(parents=True, exist_ok=True)
    # this run's attempt: one past the earlier run's, failed or complete (a count that a success does not reset)
    attempt = max(_attempt(out / FAILED), _attempt(out / COMPLETE)) + 1
    (out / FAILED).unlink(missing_ok=True)
    try:
        if cfg.get("fail_on") and cfg.fail_on == name:  # deliberate failure, for tests of the sweep machinery
            raise RuntimeError(f"deliberate failure of {name} (fail_on)")
        check_job(cfg, root)
        d = design_for(cfg, root)
        check_current(cfg.variant.current, d, str(root / "conf" / "variant" / f"{cfg.variant.case}.yaml"))
        resolved = OmegaConf.to_container(cfg, resolve=True)
        resolved.pop("hydra", None)
        meta = {"config": resolved, "config_hash": h, "design_hash": d.hash(), "variant": name,
                "sweep": cfg.sweep, "current [A]": float(cfg.variant.current)}
        row = {"variant": name, "case": cfg.variant.case, "factor": cfg.get("factor") or "",
               "level": float(cfg.level) if cfg.get("factor") else 0.0, "current [A]": float(cfg.variant.current)}
        for test in cfg.tests:
            proto = load_protocol(root / "conf" / "test" / f"{test}.yaml")
            runs = [r for r in build_runs(proto, int(cfg.seed)) if abs(r.current - cfg.variant.current) < 1e-9]
            if not runs:
                raise ValueError(f"protocol {test} has no run at {cfg.variant.current} A")
            r = simulate(d, runs[0].excitation, runs[0].configuration, current=runs[0].current, rate=runs[0].rate)
            if not r.ok:
                raise RuntimeError(f"{test}: simulation stopped: {r.stats.message}")
            f = r.to_frame()
            f["force [N]"] = f["top mount force [N]"]
            f["current [A]"] = runs[0].current
            write_frame(out / f"{test}.parquet", f, {**meta, "protocol": test})
            if test == "monosine":
                pk = kpi.rod_acceleration_extremes(f, proto["frequency"])  # steady cycles, both extremes
                row["rebound peak [g]"], row["compression peak [g]"] = pk["rebound max"], pk["compression min"]
                row["peak rod force [N]"] = float(np.max(np.abs(kpi.last_cycle(f, proto["frequency"])["rod force [N]"])))
            if test == "random":
                lv = kpi.psd_levels(f)
                row["PSD 200 Hz [dB]"], row["PSD 300 Hz [dB]"] = lv["200 Hz [dB]"], lv["300 Hz [dB]"]
        write_frame(out / "kpis.parquet", pd.DataFrame([row]), meta)
        (out / COMPLETE).write_text(json.dumps({"config_hash": h, "design_hash": d.hash(), "attempt": attempt}))
        log.info("%s: done", name)
    except Exception as e:  # a failed variant is reported and does not stop the sweep
        (out / COMPLETE).unlink(missing_ok=True)
        msg = one_line(e) if isinstance(e, UserError) else f"{type(e).__name__}: {one_line(e)}"
        (out / FAILED).write_text(json.dumps({"error": msg, "traceback": traceback.format_exc(), "config_hash": h,
                                              "attempt": attempt}))
        log.error("%s: FAILED: %s", name, msg)
    return out


def _attempt(path: Path) -> int:
    """The attempt number of a failure or completion record (0: none, unreadable, or without a number)."""
    try:
        n = json.loads(path.read_text()).get("attempt") if path.is_file() else 0
    except (OSError, ValueError, AttributeError):
        return 0
    return n if isinstance(n, int) and not isinstance(n, bool) and n > 0 else 0


def failure_attempts(sweep_dir: Path) -> dict[str, int | None]:
    """variant -> attempt number of each failure record in a sweep folder (None: a record without one). A
    multirun notes them at its start: a variant it runs writes a record one attempt later (failed or
    complete: a success in between does not restart the count). The number counts (no random id, no
    clock), so the same failures give the same bytes."""
    out = {}
    for f in sorted(sweep_dir.glob(f"*/{FAILED}")) if sweep_dir.is_dir() else []:
        out[f.parent.name] = _attempt(f) or None
    return out


def summarize(sweep_dir: Path, before: dict[str, int | None] | None = None) -> pd.DataFrame:
    """One row per variant with every KPI and its change vs the baseline
    (the unperturbed baseline_1.6 case); failed variants listed with their
    error. With ``before`` (:func:`failure_attempts` at the multirun's start)
    a failure record still the same attempt belongs to a variant this run did
    not run again (a run retries its variants' failures): it is left out of
    the table and named in a note. Writes summary.parquet and summary.md into
    the sweep folder (an empty table too)."""
    rows, stale = [], []
    for v in sorted(p for p in sweep_dir.iterdir() if p.is_dir() and not p.name.startswith(".")):
        if (v / COMPLETE).is_file():
            df = pd.read_parquet(v / "kpis.parquet")  # a KPI table, not a time series
            rows.append({**df.iloc[0].to_dict(), "status": "ok"})
        elif (v / FAILED).is_file():
            rec = json.loads((v / FAILED).read_text())
            if before is not None and v.name in before and (_attempt(v / FAILED) or None) == before[v.name]:
                stale.append(v.name)
                continue
            rows.append({"variant": v.name, "status": "failed: " + _cell(rec.get("error", "unknown error"))})
    if stale:
        log.warning("left out of the summary: %d failed variant(s) of an earlier run, not run again: %s "
                    "(delete their folders to clean up)", len(stale), ", ".join(stale))
    tab = pd.DataFrame(rows)
    note = ("" if not stale else f"Left out: {len(stale)} failed variant(s) of an earlier run, not run again here: "
            f"{_cell(', '.join(stale))}.\n\n")
    if tab.empty:
        write_frame(sweep_dir / "summary.parquet", pd.DataFrame({"variant": pd.Series(dtype=str)}),
                    {"sweep": sweep_dir.name, "rows": 0, "failed": 0, "left out (earlier runs' failures)": stale})
        (sweep_dir / "summary.md").write_text(f"# Sweep {sweep_dir.name}\n\n{note}No variant results.\n")
        return tab
    base = tab[(tab.get("case") == BASELINE_CASE) & (tab.get("factor", "") == "") & (tab.status == "ok")]
    for k in KPIS:
        if k not in tab:
            continue
        ref = base[k].iloc[0] if len(base) else np.nan
        tab[f"change {k}"] = tab[k] - ref
    if "rebound peak [g]" in tab and len(base):
        tb = THESIS_MEASURED[BASELINE_CASE]
        for i, (kk, j) in enumerate((("rebound", 0), ("compression", 1))):
            col = f"{kk} peak [g]"
            ours = np.sign(np.abs(tab[col]) - abs(base[col].iloc[0]))
            thesis = [np.sign(abs(THESIS_MEASURED[c][j]) - abs(tb[j])) if c in THESIS_MEASURED and not f else np.nan
                      for c, f in zip(tab["case"], tab["factor"])]
            tab[f"|{kk}| trend"] = ours
            tab[f"|{kk}| trend thesis"] = thesis
    meta = {"sweep": sweep_dir.name, "rows": len(tab), "failed": int((tab.status != "ok").sum()),
            "left out (earlier runs' failures)": stale}
    write_frame(sweep_dir / "summary.parquet", tab.fillna({"factor": ""}), meta)
    (sweep_dir / "summary.md").write_text(f"# Sweep {sweep_dir.name}\n\n" + note + kpi.to_markdown(tab, digits=2))
    return tab


_EXC_LINE = re.compile(r"[A-Za-z_][\w.]*(Error|Exception|Exit|Interrupt)\b:?")  # a traceback's exception line
_OS_ERROR = re.compile(r"(OSError|FileNotFoundError|NotADirectoryError|FileExistsError|PermissionError)\b")


def _hydra_error(text: str, code, results_dir: str | None = None) -> str:
    """Hydra's error report on one line: its own lines, or of a Python traceback (an error Hydra did not
    expect, e.g. a results_dir it cannot create) the last exception with its message lines and notes;
    an OS error naming ``results_dir`` gets a hint."""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip() and "HYDRA_FULL_ERROR" not in ln]
    if not any(ln.startswith("Traceback (most recent call last)") for ln in lines):
        return "; ".join(lines) or f"Hydra exited with {code}"
    start = max((i for i, ln in enumerate(lines) if _EXC_LINE.match(ln)), default=len(lines) - 1)
    block = lines[start:]
    hint = (" (Hydra could not create its output folder under results_dir)"
            if results_dir and _OS_ERROR.match(block[0]) and results_dir in " ".join(block) else "")
    return "; ".join(block) + hint


def _cell(text: str) -> str:
    """Text safe in one markdown table cell: one line, no column separator."""
    return " ".join(str(text).split()).replace("|", "/")


def trend_agreement(tab: pd.DataFrame) -> tuple[int, int]:
    """(agreeing, compared) directions of |peak| change vs thesis table 6.5."""
    agree = total = 0
    for kk in ("rebound", "compression"):
        a, b = tab.get(f"|{kk}| trend"), tab.get(f"|{kk}| trend thesis")
        if a is None or b is None:
            continue
        m = b.notna() & (tab.case != BASELINE_CASE) & (b != 0)
        agree += int((a[m] == b[m]).sum())
        total += int(m.sum())
    return agree, total


TREND_RESOLUTION = 0.1  # [g] the thesis prints table 6.5 to 0.1 g: smaller changes have no direction


def lab_peaks(measured_dir: Path, frequency: float) -> dict[str, tuple[float, float]]:
    """(rebound, compression) peaks [g] of each case's measured mono-sine
    record (``<measured_dir>/<case>.parquet``), same definition as the sweep."""
    from .io import read_frame

    out = {}
    for p in sorted(Path(measured_dir).glob("*.parquet")):
        pk = kpi.rod_acceleration_extremes(read_frame(p, "monosine")[0], frequency)
        out[p.stem] = (pk["rebound max"], pk["compression min"])
    return out


def _peak_changes(tab: pd.DataFrame, thesis: dict[str, tuple[float, float]], resolution: float):
    """Per table-6.5 case (the ``factor``-less ok rows of ``tab``) and
    half-cycle: (case, j, half, change of |peak| vs the baseline here [g],
    the same change in the thesis column ``thesis`` [g]); rows whose thesis
    change is below ``resolution`` (no direction) left out."""
    ok = tab[(tab.get("factor", "") == "") & (tab.status == "ok")].set_index("case")
    if BASELINE_CASE not in ok.index or BASELINE_CASE not in thesis:
        return
    for case in ok.index:
        if case == BASELINE_CASE or case not in thesis:
            continue
        for j, half in enumerate(("rebound", "compression")):
            col = f"{half} peak [g]"
            d_sim = abs(ok.loc[case, col]) - abs(ok.loc[BASELINE_CASE, col])
            d_th = abs(thesis[case][j]) - abs(thesis[BASELINE_CASE][j])
            if abs(d_th) >= resolution:
                yield case, j, half, d_sim, d_th


def trend_table(tab: pd.DataFrame, lab: dict[str, tuple[float, float]] | None = None,
                resolution: float = TREND_RESOLUTION) -> pd.DataFrame:
    """Per table-6.5 case and half-cycle: the change of |peak| vs the
    baseline [g] simulated, in the thesis' measured column and (if given)
    on the lab sample's measurements, whether the simulated direction agrees
    with the thesis, and a reason derived from the numbers when it does not:
    a change below ``resolution`` [g] has no direction; a simulated direction
    the lab sample shares points to the lab sample's physics differing from
    the thesis' part; one the lab sample contradicts points to the model or
    its calibration; otherwise "unexplained"."""
    rows = []
    for case, j, half, d_sim, d_th in _peak_changes(tab, THESIS_MEASURED, resolution):
        d_lab = (abs(lab[case][j]) - abs(lab[BASELINE_CASE][j])
                 if lab and case in lab and BASELINE_CASE in lab else np.nan)
        agree = bool(np.sign(d_sim) == np.sign(d_th)) and abs(d_sim) >= resolution
        if agree:
            reason = ""
        elif abs(d_sim) < resolution:
            reason = f"simulated change {d_sim:+.2f} g below the {resolution:g} g resolution: no direction"
        elif np.isfinite(d_lab) and abs(d_lab) >= resolution and np.sign(d_lab) == np.sign(d_sim):
            reason = ("lab sample physics vs thesis part: the lab measurement moves the same way as the "
                      f"model ({d_lab:+.2f} g)")
        elif np.isfinite(d_lab) and abs(d_lab) >= resolution and np.sign(d_lab) == np.sign(d_th):
            reason = f"model defect or calibration: the lab measurement moves as the thesis ({d_lab:+.2f} g)"
        else:
            reason = "unexplained"
        rows.append({"case": case, "half-cycle": half, "change simulated [g]": float(d_sim),
                     "change thesis measured [g]": float(d_th), "change lab measured [g]": float(d_lab),
                     "agrees": agree, "reason": reason})
    return pd.DataFrame(rows)


def simulated_trend_table(tab: pd.DataFrame, thesis_simulated: dict[str, tuple[float, float]],
                          resolution: float = TREND_RESOLUTION) -> pd.DataFrame:
    """Per table-6.5 case and half-cycle: the change of |peak| vs the baseline
    [g] simulated here and in the thesis' SIMULATED column (its chapter-6
    model, ``thesis_simulated``: case -> (rebound, compression) [g]; issue 40
    item 4), and whether the directions agree. A thesis change below
    ``resolution`` has no direction (row left out); a change here below it
    disagrees, with that reason."""
    rows = []
    for case, _, half, d_sim, d_ts in _peak_changes(tab, thesis_simulated, resolution):
        agree = bool(np.sign(d_sim) == np.sign(d_ts)) and abs(d_sim) >= resolution
        reason = ("" if agree else f"simulated change {d_sim:+.2f} g below the {resolution:g} g resolution: "
                  "no direction" if abs(d_sim) < resolution else
                  f"opposite direction: {d_sim:+.2f} g here, {d_ts:+.2f} g in the thesis' model")
        rows.append({"case": case, "half-cycle": half, "change simulated [g]": float(d_sim),
                     "change thesis simulated [g]": float(d_ts), "agrees": agree, "reason": reason})
    return pd.DataFrame(rows)


def trend_metrics(trend: pd.DataFrame) -> dict:
    """metrics.json entry: agreeing / compared directions, and the cases that
    disagree with their reason."""
    if trend.empty:
        return {"agree": 0, "compared": 0, "disagreeing": []}
    bad = trend[~trend.agrees]
    return {"agree": int(trend.agrees.sum()), "compared": int(len(trend)),
            "disagreeing": [{"case": r["case"], "half-cycle": r["half-cycle"], "reason": r["reason"]}
                            for _, r in bad.iterrows()]}


try:  # the Hydra callback that writes the summary when a multirun ends
    from hydra.experimental.callback import Callback

    class SummaryCallback(Callback):
        def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
            try:
                self.before = failure_attempts(sweep_dir(config))
            except (OmegaConfBaseException, OSError):  # a results_dir Hydra reports itself, in a moment
                self.before = None

        def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
            d = sweep_dir(config)
            if d.is_dir():
                tab = summarize(d, before=getattr(self, "before", None))
                failed = int((tab.status != "ok").sum()) if len(tab) else 0
                log.info("summary: %s (%d variants, %d failed)", d / "summary.md", len(tab), failed)
                _OUTCOME["all_failed"] = len(tab) > 0 and failed == len(tab)
except ImportError:  # pragma: no cover
    pass


_OUTCOME = {"all_failed": False}


def multirun(overrides: list[str], root: str | Path | None = None, scheduler: str | None = None) -> int:
    """Run the Hydra multirun of ``conf/sweep.yaml`` with ``overrides``
    (``-m`` is added when missing). The project root is ``root``,
    $DAMPERTWIN_ROOT or the repository around the working directory. With a
    Dask ``scheduler`` address the variants run on that cluster (the ``dask``
    launcher, conf/hydra/launcher/dask.yaml). Returns 0, or 1 if every
    variant failed; a bad root is a UserError. The command line is
    ``dampertwin sweep`` (cli.py)."""
    import hydra

    root = project_root(root)
    if scheduler:
        if "'" in scheduler or '"' in scheduler:
            raise UserError(f"sweep: --scheduler {scheduler!r}: expected an address like tcp://HOST:PORT")
        overrides = [*overrides, "hydra/launcher=dask", f"hydra.launcher.scheduler='{scheduler}'"]
    # Hydra takes its options before the overrides: -m first, then the overrides in the user's order
    info = any(a in ("-h", "--help", "--hydra-help", "--info", "--cfg", "-c") for a in overrides)
    argv = [a for a in overrides if a not in ("-m", "--multirun")]
    if not info:
        argv.insert(0, "-m")
    if not any(a.startswith("root=") for a in argv):
        argv.append(f"root='{root}'" if "'" not in str(root) else f'root="{root}"')
    saved = sys.argv
    sys.argv = [saved[0] if saved else "dampertwin", *argv]
    _OUTCOME["all_failed"] = False

    @hydra.main(config_path=str(root / "conf"), config_name="sweep", version_base="1.3")
    def app(cfg: DictConfig) -> None:
        run_variant(cfg)

    # Hydra reports a bad override itself (several lines, exit 1): its stderr is held back and a
    # failure before any job becomes one UserError line (exit 2); otherwise it is passed on unchanged
    import contextlib
    import io

    held = io.StringIO()
    try:
        with contextlib.redirect_stderr(held):
            app()
    except SystemExit as e:
        if e.code in (0, None):
            raise
        rd = next((a.split("=", 1)[1].strip("'\"") for a in reversed(argv) if a.startswith("results_dir=")), None)
        raise UserError("sweep: " + _hydra_error(held.getvalue(), e.code, rd)) from None
    finally:
        sys.argv = saved
        sys.stderr.write(held.getvalue() if not sys.exc_info()[0] else "")
    from dampertwin import sweep as this  # the callback's module (this file may run as __main__)

    if this._OUTCOME["all_failed"]:
        log.error("every variant of the sweep failed")
        return 1
    return 0


if __name__ == "__main__":  # compatible path: `python -m dampertwin.sweep ARGS` = `dampertwin sweep ARGS`
    from dampertwin.cli import main as _cli_main

    sys.exit(_cli_main(["sweep", *sys.argv[1:]]))

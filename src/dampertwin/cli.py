"""Command line: ``dampertwin design show|check``, ``simulate``, ``plot``, ``import``, ``kpi``, ``fit``, ``lab``,
``discrepancy``, ``cluster``, ``sweep`` and ``--version``."""

from __future__ import annotations

import argparse
import sys
import traceback
from pathlib import Path

from .design import TYPES, DesignError, load
from .design.adjusters import format_adjusters
from .design.schema import TYPE_MEANING
from . import __version__
from .errors import USER_ERROR_EXIT, UserError, debug_enabled, one_line, user_error_types

DEFAULT_DESIGN = Path("conf/design/baseline.yaml")


def _fmt_value(v) -> str:
    if isinstance(v, tuple):
        return "[" + ", ".join(f"{x:.6g}" for x in v) + "]"
    if isinstance(v, str):
        return v
    return f"{v:.6g}"


def format_table(design, ptype: str | None = None) -> str:
    """A readable table: number, name, type, value, unit (and bounds)."""
    rows = [p for p in design.parameters.values() if ptype is None or p.type == ptype]
    head = ("no", "name", "type", "value", "unit", "bounds")
    body = [
        (
            str(p.no), p.key, p.type, _fmt_value(p.value), p.unit,
            "" if p.bounds is None else f"[{_fmt_value(p.bounds[0])}, {_fmt_value(p.bounds[1])}]",
        )
        for p in rows
    ]
    widths = [max(len(r[i]) for r in [head, *body]) for i in range(len(head))]
    lines = [
        f"design {design.name!r}  hash {design.hash()}  ({len(rows)} of {len(design.parameters)} parameters"
        + (f", type {ptype} = {TYPE_MEANING[ptype]})" if ptype else ")"),
        "  ".join(h.ljust(w) for h, w in zip(head, widths)),
        "  ".join("-" * w for w in widths),
    ]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in body]
    if ptype is None:
        on = [k for k, v in design.effects.items() if v]
        off = [k for k, v in design.effects.items() if not v]
        lines.append(f"effects on: {', '.join(on) or '-'}; off: {', '.join(off) or '-'}")
        lines.append(f"constants: {len(design.constants)} (see the YAML 'constants:' section)")
        lines += format_adjusters(design)
    return "\n".join(lines)


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line usage error (``prog: error: message``, exit 2)."""

    def error(self, message: str):
        self.exit(USER_ERROR_EXIT, f"{self.prog}: error: {' '.join(message.split())}\n")


def _cli_user_errors() -> tuple[type, ...]:
    """Every exception type that means bad input to some subcommand."""
    from .calibration.ga import FitError as SubmodelFitError
    from .importer import MappingError

    return (*user_error_types(), SubmodelFitError, MappingError)


def main(argv: list[str] | None = None) -> int:
    """Entry point. Exit 0 on success; 2 with one line on stderr for a user
    error (bad file, key, column, option) in any subcommand; 1 only where a
    subcommand documents it (``design check`` found problems; a sweep whose
    every variant failed). ``--debug`` or DAMPERTWIN_DEBUG=1 adds the traceback."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = debug_enabled(argv)
    try:
        return _main([a for a in argv if a != "--debug"])
    except _cli_user_errors() as e:
        if debug:
            traceback.print_exc()
        print(f"dampertwin: error: {one_line(e)}", file=sys.stderr)
        return USER_ERROR_EXIT
    except KeyboardInterrupt:  # Ctrl-C: the outputs' cleanups have run while the exception unwound
        if debug:
            traceback.print_exc()
        print("dampertwin: interrupted", file=sys.stderr)
        return 130


def build_parser() -> argparse.ArgumentParser:
    """The whole command line (also read by the documentation's CLI reference)."""
    ap = _Parser(prog="dampertwin", description="Semi-active damper digital twin. Exit codes: 0 success, "
                 "2 user error (one line on stderr; --debug adds the traceback), 1 only where a command says so.")
    ap.add_argument("--version", action="version", version=f"dampertwin {__version__}")
    sub = ap.add_subparsers(dest="cmd", required=True, parser_class=_Parser)
    dsg = sub.add_parser("design", help="inspect and validate design descriptions")
    dsub = dsg.add_subparsers(dest="action", required=True, parser_class=_Parser)
    show = dsub.add_parser("show", help="print the parameter table of a design")
    show.add_argument("path", nargs="?", default=str(DEFAULT_DESIGN))
    show.add_argument("--type", choices=TYPES, help="only parameters of this type")
    chk = dsub.add_parser("check", help="validate a design file; exit 1 listing every problem it finds "
                                        "(exit 2 if the file does not exist)")
    chk.add_argument("path")
    _add_simulate(sub)
    plot = sub.add_parser("plot", help="PNG plots of one design case: P-Q, F-V / F-x, mono-sine, PSD")
    plot.add_argument("case", help="design case, a file name of conf/variant/ (e.g. baseline_1.6)")
    plot.add_argument("--measured", "--data", dest="data", default=None,
                      help="measured data folder to overlay (e.g. data/measured or data/own); default none")
    plot.add_argument("--design", dest="design_path", default=None,
                      help="design file to draw (e.g. results/approach1/designs/CASE.yaml, a calibrated one); "
                           "default: conf/design/baseline.yaml + the case's variant")
    plot.add_argument("--out", default="results/plots", help="output folder (PNG files go to OUT/CASE/)")
    plot.add_argument("--conf", default="conf", help="configuration folder")
    _add_import_fit(sub)
    _add_kpi(sub)
    lab = sub.add_parser("lab", help="virtual laboratory: run a hidden-sample file through the standard tests "
                         "(SYNTHETIC data)")
    lab.add_argument("--sample", required=True, help="hidden-sample YAML (see the virtual laboratory in the docs)")
    lab.add_argument("--out", required=True, help="output folder: OUT/<test>/<case>.parquet")
    lab.add_argument("--tests", default=None, help="comma-separated tests (default all), e.g. monosine,random")
    lab.add_argument("--seed", type=int, default=0, help="noise / scatter seed")
    lab.add_argument("--conf", default=None, help="configuration folder with test/ and variant/ (default the project's)")
    lab.add_argument("--workers", type=int, default=None, help="parallel processes (default: all cores)")
    _add_discrepancy(sub)
    clu = sub.add_parser("cluster", help="start a Dask cluster of SLURM jobs (dask-jobqueue) and print its "
                         "scheduler address, for --scheduler / the profile's scheduler: (Ctrl-C stops it)")
    clu.add_argument("--config", default="conf/cluster/slurm.yaml", help="cluster description YAML "
                     "(cores, memory, walltime, queue, account, processes, jobs, job_extra_directives)")
    clu.add_argument("--check", action="store_true", help="only check the description and print the SLURM job "
                     "script (no job submitted)")
    swp = sub.add_parser("sweep", help="one-factor-at-a-time design sweep (Hydra multirun of conf/sweep.yaml); "
                         "exit 1 if every variant failed", add_help=False)
    swp.add_argument("--root", default=None, help="project root (default $DAMPERTWIN_ROOT or the repository "
                     "around the working directory)")
    swp.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="Dask scheduler address (tcp://HOST:PORT): the variants run as tasks on that cluster "
                          "(Hydra launcher `dask`; same results)")
    swp.add_argument("overrides", nargs="*", metavar="OVERRIDE",
                     help="Hydra overrides, e.g. +ofat=table65 or factor=piston_intake.a level=-0.3,0.3 "
                          "(-m is implied); --help shows Hydra's help")
    return ap


def _main(argv: list[str]) -> int:
    ap = build_parser()
    if argv and argv[0] == "sweep":  # Hydra parses its own options (-m, --cfg, --help, ...), in order
        rest = list(argv[1:])
        root, scheduler = _take_option(rest, "--root", "a project folder"), _take_option(rest, "--scheduler",
                                                                                        "a Dask scheduler address")
        from .sweep import multirun

        return multirun(rest, root=root, scheduler=scheduler)
    args = ap.parse_args(argv)
    from .cli_checks import check_args, output_lock

    check_args(args)  # every option in range, every output writable, before any work
    with output_lock(args):  # a second run on the same output is refused while this one runs
        if args.cmd == "discrepancy":
            return _run_discrepancy(args)
        if args.cmd == "lab":
            return _run_lab(args)
        if args.cmd == "simulate":
            return _run_simulate(args)
        if args.cmd in ("import", "fit"):
            return _run_import_fit(args)
    if args.cmd == "kpi":
        return _run_kpi(args)
    if args.cmd == "cluster":
        return _run_cluster(args)
    if args.cmd == "plot":
        from .plotting import plot_case

        try:
            paths = plot_case(args.case, Path(args.conf), Path(args.data) if args.data else None, Path(args.out),
                              Path(args.design_path) if args.design_path else None)
        except ValueError as e:  # a design the plots cannot simulate
            raise UserError(f"plot {args.case}: {one_line(e)}") from None
        for p in paths:
            print(p)
        return 0
    return _run_design(args)


def _run_cluster(args) -> int:
    """Check conf/cluster/*.yaml; start the SLURM jobs and serve until Ctrl-C (``--check``: print the job script)."""
    import time

    from .design import yaml_load_file
    from .parallel import slurm_cluster

    path = Path(args.config)
    if not path.is_file():
        raise UserError(f"{path}: cluster description not found (e.g. conf/cluster/slurm.yaml)")
    doc = yaml_load_file(path)  # bad YAML: a ConfigTextError naming the file
    cluster = slurm_cluster(doc, str(path))
    try:
        if args.check:
            print(cluster.job_script())
            return 0
        cluster.scale(jobs=doc["jobs"])
        print(f"scheduler: {cluster.scheduler_address}  (--scheduler {cluster.scheduler_address}; Ctrl-C stops "
              f"the {doc['jobs']} SLURM jobs)", flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        return 0
    finally:
        cluster.close()


def _take_option(rest: list[str], name: str, what: str) -> str | None:
    """Remove ``name VALUE`` from ``rest`` (the sweep's own options, before Hydra's); its value or None."""
    if name not in rest:
        return None
    i = rest.index(name)
    if i + 1 >= len(rest):
        raise UserError(f"sweep: argument {name}: expected one argument ({what})")
    value = rest[i + 1]
    del rest[i:i + 2]
    return value


def _run_design(args) -> int:
    if not Path(args.path).is_file():
        raise FileNotFoundError(f"{args.path}: " + ("a folder; expected a design YAML file" if Path(args.path).is_dir()
                                                    else "design file not found"))
    if args.action == "show":
        print(format_table(load(args.path), args.type))  # a bad design: DesignError, exit 2
        return 0
    try:
        design = load(args.path)
    except DesignError as e:  # the documented exit 1: every problem the check found
        print(str(e), file=sys.stderr)
        return 1
    from .design.architecture import DESCRIPTION, is_placeholder

    held = sum(is_placeholder(p.source, design.architecture) for p in design.parameters.values())
    arch = f"architecture {design.architecture}: {DESCRIPTION[design.architecture]}"
    adj = "".join(f", adjuster {n}: {a.key} {len(a.clicks)} clicks at {design.setting[n]}"
                  for n, a in design.adjusters.items())
    print(f"{args.path}: OK ({arch}; {len(design.parameters) - held} parameters"
          + (f", {held} of parts it lacks filled with placeholders" if held else "") + f", hash {design.hash()}{adj})")
    return 0


def _add_simulate(sub) -> None:
    sim = sub.add_parser("simulate", help="simulate the runs of one standard test on a design: "
                                          "OUT/TEST.parquet and OUT/TEST.png")
    sim.add_argument("design", help="design YAML, e.g. conf/design/baseline.yaml")
    sim.add_argument("--test", required=True, help="a test of conf/test/ (monosine, curving, flowbench, ...)")
    sim.add_argument("--case", default=None, help="one run of the test by name (e.g. I1.6, v0.1_I1.6, "
                                                  "piston_rebound); default all")
    sim.add_argument("--current", type=float, default=None, help="only the runs at this active-valve current [A]")
    sim.add_argument("--out", required=True, help="output folder")
    sim.add_argument("--conf", default="conf", help="configuration folder with test/ (default conf)")


def _run_simulate(args) -> int:
    from .simulate_test import simulate_test

    for p in simulate_test(args.design, args.test, args.out, case=args.case, current=args.current,
                           conf=args.conf):
        print(p)
    return 0


def _run_lab(args) -> int:
    # the lab's entry point: the only CLI path that reads a hidden sample
    from .lab import run_lab

    tests = [t.strip() for t in args.tests.split(",") if t.strip()] if args.tests else None
    if args.tests is not None and not tests:
        from .lab import LabError

        raise LabError("--tests: expected a comma-separated list of test names")
    for p in run_lab(args.sample, args.out, tests=tests, seed=args.seed, conf=args.conf, workers=args.workers):
        print(p)
    return 0


def _add_import_fit(sub) -> None:
    imp = sub.add_parser("import", help="convert your own measurement (any common units) into the project schema")
    imp.add_argument("src", help="source file (.csv or .parquet)")
    imp.add_argument("--map", required=True, dest="mapping", help="column mapping YAML (quantity + unit per column)")
    imp.add_argument("--out", required=True, help="output Parquet, e.g. data/own/monosine/baseline_1.6.parquet")
    imp.add_argument("--protocol", help="test schema to check (default: the mapping's or the output folder name)")
    fit = sub.add_parser("fit", help="fit one submodel on a bench record: valve | compliance | topmount | friction | "
                                     "active-valve (the part's P/Q map); or the whole damper on dyno records: damper")
    fit.add_argument("submodel", choices=("valve", "compliance", "topmount", "friction", "damper", "active-valve"))
    fit.add_argument("--data", required=True, help="the record to fit (Parquet or CSV, project schema); damper: "
                                                   "a comma-separated list a.parquet,b.parquet (each at the clicker "
                                                   "setting its metadata names)")
    fit.add_argument("--design", default=str(DEFAULT_DESIGN), help="design YAML (start values, constants)")
    fit.add_argument("--out", required=True, help="output folder: fit.json and PNG plots")
    fit.add_argument("--predict", nargs="*", default=[], help="records only predicted (NRMSE reported)")
    fit.add_argument("--bounds", help="search-space YAML (parameters: [{name, bounds | window, scale}])")
    fit.add_argument("--param", action="append", default=[], metavar="NAME=LO:HI",
                     help="search bounds on the command line (repeatable; overrides --bounds)")
    fit.add_argument("--valve", help="valve of a 'valve' fit (piston_rebound, piston_intake, ...)")
    fit.add_argument("--current", type=float, help="active-valve current [A] (compliance; default from the record)")
    fit.add_argument("--population", type=int, default=None, help="GA population (default 20)")
    fit.add_argument("--generations", type=int, default=None, help="GA generations (default 15)")
    fit.add_argument("--seed", type=int, default=0)
    fit.add_argument("--profile", choices=("ci", "full", "thesis"), default=None,
                     help="GA and polish budgets of the study profile conf/profile/PROFILE.yaml (valve, compliance, "
                          "topmount; --population / --generations still override)")
    fit.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="Dask scheduler address (tcp://HOST:PORT): the GA's populations are evaluated on that "
                          "cluster (valve, compliance, topmount; same results)")
    fit.add_argument("--effect", action="append", default=[], choices=("asymmetric", "free_play"),
                     help="friction: add a library effect to the law (repeatable); the report says whether the "
                          "held-out cycles support it")
    fit.add_argument("--holdout-cycles", type=int, default=None, metavar="N",
                     help="friction: the last N cycles of the record are not fitted, only predicted "
                          "(default: a third of the cycles)")


def _run_import_fit(args) -> int:
    """Bad input (mapping, data, design, bounds) raises; main() makes it exit 2."""
    if args.cmd == "import":
        from .importer import import_measurement

        print(import_measurement(args.src, args.mapping, args.out, protocol=args.protocol))
        return 0
    from .cli_fit import run_fit_cli

    path, flags = run_fit_cli(args)
    for f in flags:
        print(f"dampertwin fit: warning: {f}", file=sys.stderr)
    print(path)
    return 0


def _add_kpi(sub) -> None:
    kpi = sub.add_parser("kpi", help="KPIs of a measured record as JSON on stdout (dyno: F-v points per speed step "
                                     "and direction, loop area, oil temperature at start and end)")
    kpi.add_argument("kind", choices=("dyno",), help="the record's test type")
    kpi.add_argument("file", help="the record (Parquet or CSV, project schema; e.g. written by dampertwin import)")
    kpi.add_argument("--test", default=None, help="the test whose checks the record must pass (default: the test "
                                                  "its metadata names, else dyno)")
    kpi.add_argument("--velocities", default=None, metavar="V1,V2,...",
                     help="reference peak speeds [m/s]: the force at each per direction, interpolated along the "
                          "measured F-v points (null outside them)")
    kpi.add_argument("--cycles", type=int, default=None, metavar="N",
                     help="average the last N half-strokes of each direction per step (default: all but the first)")


def _run_kpi(args) -> int:
    """``dampertwin kpi dyno FILE``: one JSON document {file, test, setting (the record's clicker setting, or
    null), runs: {label: KPIs}} (dampertwin.dyno.dyno_kpis)."""
    import json

    from .dyno import dyno_kpis
    from .io import read_meta, read_record, runs

    ref = None
    if args.velocities is not None:
        try:
            ref = [float(v) for v in args.velocities.split(",")]
        except ValueError:
            raise UserError(f"--velocities {args.velocities!r}: expected comma-separated speeds in m/s") from None
        if not ref or not all(v > 0 and v < float("inf") for v in ref):
            raise UserError(f"--velocities {args.velocities!r}: expected positive finite speeds in m/s")
    if args.cycles is not None and args.cycles < 1:
        raise UserError(f"--cycles {args.cycles}: expected an integer >= 1")
    path = Path(args.file)
    try:
        meta = read_meta(path) if path.suffix == ".parquet" and path.is_file() else {}
    except Exception:  # unreadable: read_record names the file
        meta = {}
    test = args.test or (meta.get("protocol") if isinstance(meta.get("protocol"), str) else None) or "dyno"
    df, _ = read_record(path, test)
    lacking = [c for c in ("displacement [m]", "force [N]") if c not in df.columns]
    if lacking:  # a flow-bench or active-valve record: no stroke to cut into half-strokes
        raise UserError(f"{path}: a {test} record without {' and '.join(repr(c) for c in lacking)}; kpi dyno reads "
                        f"damper records with the rod's displacement and force (a dyno export, dampertwin import)")
    out = {"file": str(path), "test": test, "setting": meta.get("setting"), "runs": {}}
    for name, g in runs(df):
        try:
            out["runs"][name or "record"] = dyno_kpis(g, ref, args.cycles)
        except ValueError as e:
            raise UserError(f"{path}" + (f" run {name!r}" if name else "") + f": {e}") from None
    print(json.dumps(out, indent=1))
    return 0


def _add_discrepancy(sub) -> None:
    dis = sub.add_parser("discrepancy", help="find where simulation and measurement disagree, name the missing "
                                             "effect, add it (OUT/verdict.json, design.yaml, report.md, plots/)")
    dis.add_argument("--design", required=True, help="design YAML to examine (nominal or calibrated)")
    dis.add_argument("--measured", required=True, help="measured folder DIR/<test>/<case>.parquet")
    dis.add_argument("--out", required=True, help="output folder")
    dis.add_argument("--profile", choices=("ci", "full"), default="ci", help="budget (conf/discrepancy.yaml)")
    dis.add_argument("--seed", type=int, default=0, help="seed of every random draw (bootstrap)")
    dis.add_argument("--valve-map", choices=("record", "design"), default="record",
                     help="the active valve's P/Q map: 'record' builds the part's own from MEASURED/activevalve/"
                          "baseline.parquet when present (the design's map otherwise); 'design' keeps the design's")
    dis.add_argument("--workers", type=int, default=None,
                     help="processes simulating the records in parallel (default: all cores; same results)")
    dis.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="Dask scheduler address (tcp://HOST:PORT): the records run as tasks on that cluster "
                          "(same results; see docs/how-to/cluster.md)")


def _run_discrepancy(args) -> int:
    """Exit 0 for every verdict; bad input raises a UserError (exit 2, file named)."""
    import signal

    from .discrepancy.entry import main as run_discrepancy

    # SIGTERM (a killed job) unwinds like Ctrl-C: the temporary output folder is removed and the record
    # workers are stopped by the entry's cleanup, instead of being left behind
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    doc = run_discrepancy(args.design, args.measured, args.out, profile=args.profile, seed=args.seed,
                          workers=args.workers, scheduler=args.scheduler, valve_map=args.valve_map)
    print(f"verdict: {doc['verdict']}" + (f" ({', '.join(doc['effects'])})" if doc["effects"] else "")
          + f"; held-out gap {doc['gap']['before']:.3g} -> {doc['gap']['after']:.3g} "
          f"(closed {100 * doc['gap']['closed_fraction']:.0f} %); {Path(args.out) / 'verdict.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

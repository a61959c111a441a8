"""Command line: ``dampertwin design show|check``, ``plot``, ``import``, ``fit``, ``lab``."""

from __future__ import annotations

import argparse
import sys
import traceback
from pathlib import Path

from .design import TYPES, DesignError, load
from .design.schema import TYPE_MEANING
from .errors import USER_ERROR_EXIT, debug_enabled, one_line, user_error_types

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
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Entry point: a user error (bad file, key, column) is one line on
    stderr and exit 2; ``--debug`` or DAMPERTWIN_DEBUG=1 adds the traceback."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = debug_enabled(argv)
    try:
        return _main([a for a in argv if a != "--debug"])
    except user_error_types() as e:
        if debug:
            traceback.print_exc()
        print(f"dampertwin: error: {one_line(e)}", file=sys.stderr)
        return USER_ERROR_EXIT


def _main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="dampertwin", description="Semi-active damper digital twin "
                                 "(--debug: tracebacks for errors)")
    sub = ap.add_subparsers(dest="cmd", required=True)
    dsg = sub.add_parser("design", help="inspect and validate design descriptions")
    dsub = dsg.add_subparsers(dest="action", required=True)
    show = dsub.add_parser("show", help="print the parameter table of a design")
    show.add_argument("path", nargs="?", default=str(DEFAULT_DESIGN))
    show.add_argument("--type", choices=TYPES, help="only parameters of this type")
    chk = dsub.add_parser("check", help="validate a design file; exit 1 listing every problem")
    chk.add_argument("path")
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
    lab = sub.add_parser("lab", help="virtual laboratory: run a hidden-sample file through the standard tests "
                         "(SYNTHETIC data)")
    lab.add_argument("--sample", required=True, help="hidden-sample YAML (README: the virtual laboratory)")
    lab.add_argument("--out", required=True, help="output folder: OUT/<test>/<case>.parquet")
    lab.add_argument("--tests", default=None, help="comma-separated tests (default all), e.g. monosine,random")
    lab.add_argument("--seed", type=int, default=0, help="noise / scatter seed")
    lab.add_argument("--conf", default=None, help="configuration folder with test/ and variant/ (default the project's)")
    lab.add_argument("--workers", type=int, default=None, help="parallel processes (default: all cores)")
    _add_discrepancy(sub)
    args = ap.parse_args(argv)
    if args.cmd == "discrepancy":
        return _run_discrepancy(args)
    if args.cmd == "lab":
        return _run_lab(args)
    if args.cmd in ("import", "fit"):
        return _run_import_fit(args)
    if args.cmd == "plot":
        from .plotting import plot_case

        try:
            for p in plot_case(args.case, Path(args.conf), Path(args.data) if args.data else None, Path(args.out),
                               Path(args.design_path) if args.design_path else None):
                print(p)
        except (FileNotFoundError, ValueError, DesignError) as e:
            print(f"dampertwin plot: {e}", file=sys.stderr)
            return 1
        return 0

    try:
        design = load(args.path)
    except DesignError as e:
        print(str(e), file=sys.stderr)
        return 1
    if args.action == "show":
        print(format_table(design, args.type))
    else:
        print(f"{args.path}: OK ({len(design.parameters)} parameters, hash {design.hash()})")
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
    fit = sub.add_parser("fit", help="fit one submodel on a bench record: valve | compliance | topmount | friction")
    fit.add_argument("submodel", choices=("valve", "compliance", "topmount", "friction"))
    fit.add_argument("--data", required=True, help="the record to fit (Parquet or CSV, project schema)")
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
    fit.add_argument("--profile", choices=("ci", "full"), default=None,
                     help="GA and polish budgets of the study profile conf/profile/PROFILE.yaml (valve, compliance, "
                          "topmount; --population / --generations still override)")
    fit.add_argument("--effect", action="append", default=[], choices=("asymmetric", "free_play"),
                     help="friction: add a library effect to the law (repeatable); the report says whether the "
                          "held-out cycles support it")
    fit.add_argument("--holdout-cycles", type=int, default=None, metavar="N",
                     help="friction: the last N cycles of the record are not fitted, only predicted "
                          "(default: a third of the cycles)")


def _run_import_fit(args) -> int:
    from .io import DataError

    if args.cmd == "import":
        from .importer import MappingError, import_measurement

        try:
            print(import_measurement(args.src, args.mapping, args.out, protocol=args.protocol))
        except (MappingError, DataError) as e:
            print(f"dampertwin import: {e}", file=sys.stderr)
            return 1
        return 0
    from .cli_fit import FitError, run_fit_cli

    try:
        path, flags = run_fit_cli(args)
    except (FitError, DataError, DesignError) as e:
        print(f"dampertwin fit: {e}", file=sys.stderr)
        return 1
    for f in flags:
        print(f"dampertwin fit: warning: {f}", file=sys.stderr)
    print(path)
    return 0


def _add_discrepancy(sub) -> None:
    dis = sub.add_parser("discrepancy", help="find where simulation and measurement disagree, name the missing "
                                             "effect, add it (OUT/verdict.json, design.yaml, report.md, plots/)")
    dis.add_argument("--design", required=True, help="design YAML to examine (nominal or calibrated)")
    dis.add_argument("--measured", required=True, help="measured folder DIR/<test>/<case>.parquet")
    dis.add_argument("--out", required=True, help="output folder")
    dis.add_argument("--profile", choices=("ci", "full"), default="ci", help="budget (conf/discrepancy.yaml)")
    dis.add_argument("--seed", type=int, default=0, help="seed of every random draw (bootstrap)")
    dis.add_argument("--workers", type=int, default=None,
                     help="processes simulating the records in parallel (default: all cores; same results)")


def _run_discrepancy(args) -> int:
    """Exit 0 for every verdict; bad input raises a UserError (exit 2, file named)."""
    import signal

    from .discrepancy.entry import main as run_discrepancy

    # SIGTERM (a killed job) unwinds like Ctrl-C: the temporary output folder is removed and the record
    # workers are stopped by the entry's cleanup, instead of being left behind
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    doc = run_discrepancy(args.design, args.measured, args.out, profile=args.profile, seed=args.seed,
                          workers=args.workers)
    print(f"verdict: {doc['verdict']}" + (f" ({', '.join(doc['effects'])})" if doc["effects"] else "")
          + f"; held-out gap {doc['gap']['before']:.3g} -> {doc['gap']['after']:.3g} "
          f"(closed {100 * doc['gap']['closed_fraction']:.0f} %); {Path(args.out) / 'verdict.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Command-line arguments checked before any work: every numeric option in
its range, every output path writable and of the right kind. A violation
is an ArgumentError naming the option (one line, exit 2 via cli.main);
``output_lock`` holds the output's lock while the command runs."""

from __future__ import annotations

import contextlib
import math
from pathlib import Path

from .errors import UserError

SEED_MAX = 2**32 - 1  # numpy's legacy seeding and the lab's per-case seeds are 32-bit
# option -> (smallest allowed, what it means); checked when the option is given
INT_RANGES = {
    "population": (2, "GA population: an integer >= 2 (pairs of parents)"),
    "generations": (1, "GA generations: an integer >= 1"),
    "workers": (1, "parallel processes: an integer >= 1"),
    "seed": (0, f"seed: an integer 0 .. {SEED_MAX}"),
}
FILE_OUTPUT = ("import",)  # commands whose --out is a file; every other command's --out is a folder
NO_LOCK = ("plot", "design")  # commands whose outputs are not locked (plots are rewritten file by file)


class ArgumentError(UserError):
    """A command-line option outside its range (the message names the option)."""


def check_int(name: str, value) -> None:
    lo, what = INT_RANGES[name]
    bad = isinstance(value, bool) or not isinstance(value, int) or value < lo
    if name == "seed" and not bad:
        bad = value > SEED_MAX
    if bad:
        raise ArgumentError(f"--{name} {value!r}: expected {what}")


def check_current(value, design_path) -> None:
    """--current: finite and inside the active-valve P/Q map of the design."""
    if not (isinstance(value, (int, float)) and math.isfinite(value)):
        raise ArgumentError(f"--current {value!r}: expected a finite current in A")
    from .design import load

    d = load(design_path)
    if d.pq_map is None:  # a passive architecture: no active valve, the current is not read
        return
    lo, hi = float(d.pq_map.currents[0]), float(d.pq_map.currents[-1])
    if not lo - 1e-12 <= value <= hi + 1e-12:
        raise ArgumentError(f"--current {value!r}: outside the active-valve map [{lo:g}, {hi:g}] A of {design_path}")


# the test whose records each `fit` submodel reads (friction: also a device record without protocol)
FIT_PROTOCOLS = {"valve": ("flowbench",), "compliance": ("compliance",), "topmount": ("topmount",),
                 "friction": ("friction", None), "active-valve": ("activevalve",),
                 "damper": ("dyno", "curving", "compliance", "thermal", None)}  # damper-level: displacement in, force out


def check_fit_records(submodel: str, paths) -> None:
    """A record whose metadata names another test than the submodel's is refused
    (a compliance or friction record given to a top-mount fit, ...)."""
    from .io import read_meta

    want = FIT_PROTOCOLS.get(submodel)
    for p in paths:
        if want is None or not str(p).endswith(".parquet") or not Path(p).is_file():
            continue  # the reader names a missing or unreadable file
        try:
            proto = read_meta(p).get("protocol")
        except Exception:  # unreadable: the reader reports it
            continue
        if isinstance(proto, str) and proto not in want:
            article = "an" if submodel[0] in "aeiou" else "a"
            raise ArgumentError(f"{p}: a {proto} record (its metadata); {article} {submodel} fit reads "
                                f"{' or '.join(w for w in want if w)} records")


def check_args(args) -> None:
    """Range-check the parsed arguments of any subcommand (absent options pass)."""
    from .io import check_out_dir

    for name in INT_RANGES:
        v = getattr(args, name, None)
        if v is not None:
            check_int(name, v)
    if getattr(args, "current", None) is not None:
        check_current(args.current, getattr(args, "design", None) or "conf/design/baseline.yaml")
    cmd = getattr(args, "cmd", None)
    if cmd == "fit":
        from .design.schema import VALVES

        if getattr(args, "valve", None) is not None and args.valve not in VALVES:
            raise ArgumentError(f"--valve {args.valve!r}: expected one of {', '.join(VALVES)}")
        data = args.data.split(",") if args.submodel == "damper" else [args.data]
        check_fit_records(args.submodel, [*data, *(args.predict or [])])
        if getattr(args, "out", None) is not None:  # the fit replaces the files it writes in OUT (fit.json,
            o = Path(args.out).resolve()             # plots, design.yaml, map.csv): never an input of its own
            for opt, f in [*(("--data", f) for f in data), *(("--predict", f) for f in args.predict or []),
                           ("--design", getattr(args, "design", None)), ("--bounds", getattr(args, "bounds", None))]:
                if f and o in (Path(f).resolve(), Path(f).resolve().parent):
                    raise ArgumentError(f"--out {args.out}: holds the {opt} file {f}; the fit writes its outputs "
                                        f"there, choose another folder (inputs are kept)")
        if getattr(args, "bounds", None):  # readable YAML without duplicate keys, a mapping
            from .design import yaml_load_file

            if not isinstance(yaml_load_file(args.bounds), dict):
                raise ArgumentError(f"--bounds {args.bounds}: expected a mapping with a 'parameters:' list")
    if cmd == "plot":  # its outputs are not locked, but checked like every other command's
        check_out_dir(args.out, "--out")
        if args.data is not None and not Path(args.data).is_dir():
            raise ArgumentError(f"--measured {args.data}: not a folder (expected a measured data folder)")
    if cmd not in NO_LOCK and getattr(args, "out", None) is not None:
        check_out_dir(args.out, "--out", file=cmd in FILE_OUTPUT)
        if cmd in FILE_OUTPUT and Path(args.out).suffix != ".parquet":
            raise ArgumentError(f"--out {args.out}: expected a .parquet file")
        if cmd == "import" and Path(args.out).resolve() == Path(args.src).resolve():
            raise ArgumentError(f"--out {args.out}: is the source file; choose another path (the source is kept)")


@contextlib.contextmanager
def output_lock(args):
    """The lock of the command's output (fit, import, discrepancy, the laboratory) while it runs."""
    if getattr(args, "cmd", None) in NO_LOCK or getattr(args, "out", None) is None:
        yield None
        return
    from .io import out_lock

    with out_lock(args.out) as lock:
        yield lock


__all__ = ["ArgumentError", "check_args", "check_int", "check_current", "output_lock"]

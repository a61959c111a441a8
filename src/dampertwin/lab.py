"""The virtual laboratory: SYNTHETIC reference "measurements".

No public measurements of this damper type exist, so a hidden physical
sample (a YAML like ``conf/lab/sample.yaml``: each design case's nominal
values with the deviations of a real part, hidden effects switched on, and
the imperfections of the benches) is run through the standard tests. Every
file says ``synthetic: true`` in its metadata, with the sample file's hash.

The lab is not the fitted model's path (no inverse crime):

- the truth is integrated at ``TRUTH_RTOL`` = 1e-8 (the fits run at
  simulation.DEFAULT_RTOL = 1e-4), with an absolute floor ``TRUTH_ATOL``
  of 1e-6 state scales (see there);
- the real part may carry effects the model under test lacks (``effects:``);
- the benches are not what the fits assume: the transducers have their own
  filters (e.g. 4th-order Bessel at 1.3 kHz where ``conf/test`` documents a
  2nd-order Butterworth at 1 kHz), gain and offset errors, noise and the
  converter's quantisation; the servo-hydraulic actuator has its own
  closed-loop dynamics (2nd order + delay), and the recorded displacement is
  the real motion; the oil temperature drifts slowly along a test sequence
  and scatters between runs (viscosity and bulk modulus follow it), as does
  the actuator gain.

A ``dampertwin-lab 3`` sample (``generator: dampertwin-lab 3``, a ``truth:``
section instead of ``factors`` / ``values`` / ``effects``) is measured on the
reference damper of :mod:`dampertwin.truth`, written from other physics than
the model (issue 32); its records name the truth's version. Lab-2 samples
(``conf/lab/lab2/``) keep the path above: the committed data/measured.

Only this module (with lab_sample, lab_record and lab_passive), the
``dampertwin lab`` command and the tests read ``conf/lab/``; calibration
never does. The shipped samples were built from ``conf/lab/nominal.yaml``, a
frozen copy of the baseline drawings: editing ``conf/design/baseline.yaml``
changes the model, not the parts on the shelf.

A lab-3 sample of a passive damper (its nominal design's ``architecture:``
twin_tube or mono_tube, e.g. ``conf/lab/twin_tube_sample.yaml``) runs the
tests a passive damper can run (lab_passive.PASSIVE_TESTS: the damper-level
sine tests at current 0, the flow bench of the valves it has);
lab_passive.measure_excitation records the truth for any displacement
excitation (a dyno run).

This module plans the tests and runs them; lab_sample reads and checks a
sample, lab_record measures one run (actuator, truth, transducers).
"""

from __future__ import annotations

import math
import os
import zlib
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd

from . import __version__
from .design import Design, DesignError
from .design import load as load_design
from .io import write_frame
from .lab_passive import DEFAULT_ARCHITECTURE, PASSIVE_VALVES
from .lab_record import TRUTH_ATOL, TRUTH_RTOL, actuate, record
from .lab_sample import (LAB3_VERSION, LAB_VERSION, TEMPERATURE_DEFAULTS, LabError, _sensor_specs, check_corners,
                         check_sample, is_truth_sample, load_sample, sample_design, truth_part)
from .protocols import Run, build_runs, flow_bench, load_all, passive_runs
from .variants import TOP_MOUNTS, VALVE_DESIGNS, Variant, load_variants

# The sample the DVC lab stage measures: the lab-3 sample, measured on the truth of other physics
# (dampertwin.truth). "lab2/sample.yaml" (the model's own equations, the lab of rounds 1-2) stays for the tests
# that need a truth with a model counterpart for every parameter.
STAGE_SAMPLE = "sample.yaml"
REST_S = 20.0            # [s] pause between two runs of a test sequence (temperature drift clock)
# recorded on the baseline when declared; module_topmount: the module-level top-mount test (thesis 7.2, fig. 7.2)
APPROACH2_TESTS = ("training", "verification", "monosine16", "module_topmount")
EXTRA_TESTS = ("thermal", "friction")
  # recorded on the baseline when conf/test declares them (issue 11)


def _seed(root: int, sample: dict, *names: str) -> int:
    return int(root + sample["seed_offset"] + zlib.crc32("/".join(names).encode())) % (2**32)


def plan(conf: Path, protocols: dict | None = None,
         architecture: str = DEFAULT_ARCHITECTURE) -> list[tuple[str, str]]:
    """(test, case) of every file the lab writes: the standard tests of
    approach 1 and, when ``conf/test`` declares them, the approach-2 tests
    the warm-up test ``thermal`` and the friction test ``friction`` (all their
    runs in one file, case ``baseline``). A passive ``architecture``: the
    flow bench of its valves, the compliance and curving tests and, when
    ``conf/test`` declares it, the dyno test (at 0 A)."""
    if architecture != DEFAULT_ARCHITECTURE:
        protocols = load_all(conf / "test") if protocols is None else protocols
        return ([("flowbench", v) for v in PASSIVE_VALVES[architecture]]
                + [(t, "baseline") for t in ("compliance", "curving", "dyno") if t in protocols])
    variants = load_variants(conf / "variant")
    protocols = load_all(conf / "test") if protocols is None else protocols
    items = [("flowbench", v) for v in VALVE_DESIGNS] + [("compliance", "baseline")]
    items += [("activevalve", "baseline")] if "activevalve" in protocols else []
    items += [("topmount", t) for t in TOP_MOUNTS] + [("curving", "baseline")]
    items += [("monosine", v.case) for v in variants] + [("random", v.case) for v in variants]
    items += [(t, "baseline") for t in APPROACH2_TESTS + EXTRA_TESTS if t in protocols]
    return items


def _sequence_temperatures(runs: list[Run], tc: dict, rng: np.random.Generator) -> list[float]:
    """Oil temperature rise [K] of each run of a test sequence: a start offset
    (another day, another oil state), a slow drift with test time (``drift``
    K/min, runs separated by REST_S) and a run-to-run scatter."""
    t0 = tc["start"] + tc["start_scatter"] * rng.standard_normal()
    out, clock = [], 0.0
    for r in runs:
        out.append(float(t0 + tc["drift"] * clock / 60.0 + tc["scatter"] * rng.standard_normal()))
        clock += r.excitation.t_end - r.excitation.t0 + REST_S
    return out


def measure_case(conf: Path, sample: dict, nominal: Design, protocol: str, case: str, seed: int,
                 protocols: dict | None = None, variants: dict | None = None) -> tuple[pd.DataFrame, dict]:
    """One (test, case) of the plan on the hidden sample: the frame and its
    metadata (without writing)."""
    protocols = load_all(conf / "test") if protocols is None else protocols
    variants = {v.case: v for v in load_variants(conf / "variant")} if variants is None else variants
    arch = getattr(nominal, "architecture", DEFAULT_ARCHITECTURE)
    if arch != DEFAULT_ARCHITECTURE and (protocol, case) not in plan(conf, protocols, arch):
        raise LabError(f"{sample.get('_path', '<sample>')}: test {protocol}/{case} is not one a {arch} damper can "
                       f"run; expected one of {', '.join('/'.join(i) for i in plan(conf, protocols, arch))}")
    s = _seed(seed, sample, protocol, case)
    rng = np.random.default_rng(s)
    pc = protocols[protocol]
    runs = build_runs(pc, seed)
    bench = None
    extra = {}
    if protocol == "flowbench":
        valve, vcase = VALVE_DESIGNS[case]
        d = variants[vcase].apply(nominal) if vcase else nominal
        runs = [next(r for r in runs if r.bench_valve == valve)]
        bench = flow_bench(pc)
        extra = {"valve": valve, "valve_design": case}
    elif protocol == "topmount":
        vcase = TOP_MOUNTS[case]
        d = variants[vcase].apply(nominal) if vcase else nominal
    elif protocol == "activevalve":
        if not is_truth_sample(sample):
            raise LabError(f"{sample.get('_path', '<sample>')}: the active-valve bench runs on a lab-3 sample (the "
                           f"reference damper's solenoid valve); a lab-2 sample has no valve of its own")
        d = nominal
        bench = flow_bench(pc)
    elif protocol in ("compliance", "curving", "dyno") or protocol in APPROACH2_TESTS + EXTRA_TESTS:
        d = nominal
    else:
        v: Variant = variants[case]
        d = v.apply(nominal)
        runs = [r for r in runs if math.isclose(r.current, v.current)]
        if not runs:
            raise LabError(f"protocol {protocol} has no run at {v.current} A for case {case}")
    if arch != DEFAULT_ARCHITECTURE and protocol != "flowbench":
        runs = passive_runs(runs, at_zero=True)
        extra = {**extra, "architecture": arch}
    from .simulate_test import check_travel  # the rig cannot stroke the part beyond its travel

    check_travel(d, nominal.path or "<nominal design>", runs, conf / "test" / f"{protocol}.yaml", protocol)
    b = sample["benches"]
    tc = {**TEMPERATURE_DEFAULTS, **b.get("temperature", {})}
    temps = _sequence_temperatures(runs, tc, rng) if protocol != "topmount" else [0.0] * len(runs)
    sg = b.get("scatter", {}).get("actuator_gain", 0.0)
    gains = [1.0 + sg * rng.standard_normal() for _ in runs]
    thermo = "temperature" in pc.get("sensors", {})
    lvdt = "deflection" in pc.get("sensors", {})
    frames = [record(r, d, sample, rng, bench, oil_dT=dT, gain_scatter=g, temperature=thermo, nominal=nominal,
                     deflection=lvdt) for r, dT, g in zip(runs, temps, gains)]
    truth = {}
    if is_truth_sample(sample):
        from .truth import TRUTH_VERSION
        from .truth.run import ATOL, RTOL

        truth = {"truth": TRUTH_VERSION, "truth_rtol": RTOL, "truth_atol": ATOL,
                 "note": "SYNTHETIC measurement from the dampertwin virtual laboratory: hidden sample on the "
                         f"reference damper {TRUTH_VERSION} (other physics than the model)"}
    meta = {"synthetic": True, "generator": LAB3_VERSION if truth else LAB_VERSION, "dampertwin": __version__,
            "seed": s,
            "design_hash": d.hash(), "protocol": protocol, "case": case,
            "sample": Path(sample.get("_path", "sample.yaml")).name, "sample_hash": sample.get("_hash", ""),
            "truth_rtol": TRUTH_RTOL, "truth_atol": TRUTH_ATOL,
            "oil_temperature_K": {r.name: round(d["oil.T"] + dT, 3) for r, dT in zip(runs, temps)},
            "note": "SYNTHETIC measurement from the dampertwin virtual laboratory (hidden sample)", **extra, **truth}
    return pd.concat(frames, ignore_index=True), meta


def _measure_and_write(conf: str, sample: dict, nominal_path: str, protocol: str, case: str, seed: int,
                       out: str) -> str:
    nominal = load_design(nominal_path)
    df, meta = measure_case(Path(conf), sample, nominal, protocol, case, seed)
    return str(write_frame(Path(out) / protocol / f"{case}.parquet", df, meta))


def _nominal_path(conf: Path, sample: dict) -> Path:
    if "nominal" in sample:
        return (Path(sample["_path"]).parent / sample["nominal"]).resolve()
    return conf / "lab" / "nominal.yaml"


INCOMPLETE = ".incomplete"  # the marker file of a lab folder being written (see run_lab)


def _check_other_sample(out: Path, sample_doc: dict) -> None:
    """OUT may hold records of this sample (a rerun, or other tests of it), nothing else: another
    sample's records would mix two parts in one folder without a word, and a record the lab did not
    write (an imported measurement, a file it cannot read) could be overwritten by synthetic data."""
    from .io import read_meta

    for f in sorted(out.glob("*/*.parquet")) if out.is_dir() else []:
        try:
            meta = read_meta(f)
        except Exception as e:  # not a readable record: never the lab's to overwrite
            why = str(e).splitlines()[-1].strip().lstrip("- ").replace(f"{f}: ", "")  # the reader's line, once
            raise LabError(f"--out {out}: holds {f}, which is not a readable record ({why}); write the lab into "
                           f"an empty folder or one of this sample's") from None
        h = meta.get("sample_hash") if isinstance(meta, dict) else None
        if not h:
            what = "an imported measurement" if isinstance(meta, dict) and meta.get("imported") else "a record"
            raise LabError(f"--out {out}: holds {f}, {what} the lab did not write (no sample hash); write the lab "
                           f"into an empty folder or one of this sample's ({sample_doc.get('_path')})")
        if h != sample_doc.get("_hash"):
            raise LabError(f"--out {out}: holds records of another sample ({f}, sample hash {h}); write this "
                           f"sample ({sample_doc.get('_path')}) into an empty folder")


def run_lab(sample: str | Path, out: str | Path, tests: list[str] | None = None, seed: int = 0,
            progress: bool = True, conf: str | Path | None = None, only: list[tuple[str, str]] | None = None,
            workers: int | None = None) -> list[Path]:
    """Run a hidden-sample file through the standard tests (all, or the
    ``tests`` named) and write ``out/<test>/<case>.parquet``, labelled
    synthetic. ``conf`` is the configuration folder (protocols, variants;
    default the project's); ``workers`` processes run the cases in parallel
    (default: the machine's cores). Same sample, seed and conf: same bytes."""
    from .progress import progress as tqdm

    from .config import repo_root

    conf = Path(conf) if conf is not None else repo_root(Path(__file__).parent) / "conf"
    sample_doc = load_sample(sample)
    nominal_path = _nominal_path(conf, sample_doc)
    try:
        nominal = load_design(nominal_path)
    except (DesignError, FileNotFoundError) as e:
        raise LabError(f"{sample}: nominal design {nominal_path}: {e}") from None
    check_sample(sample_doc, nominal)
    protocols = load_all(conf / "test")
    check_corners(sample_doc, protocols)
    items = plan(conf, protocols, getattr(nominal, "architecture", DEFAULT_ARCHITECTURE)) if only is None else list(only)
    if only is None and not is_truth_sample(sample_doc):  # a lab-2 part has no solenoid valve of its own
        items = [it for it in items if it[0] != "activevalve"]
    if tests is not None and "activevalve" in tests and not is_truth_sample(sample_doc):
        raise LabError(f"--tests activevalve: {sample} is a lab-2 sample, whose part has no solenoid valve of its "
                       f"own (the model's P/Q map); the active-valve bench runs on a lab-3 sample")
    if tests is not None:
        known = sorted({t for t, _ in items})
        unknown = [t for t in tests if t not in known]
        if unknown:
            raise LabError(f"--tests: unknown test(s) {', '.join(unknown)}; expected some of {', '.join(known)}")
        items = [it for it in items if it[0] in tests]
    out = Path(out)
    _check_other_sample(out, sample_doc)
    out.mkdir(parents=True, exist_ok=True)
    marker = out / INCOMPLETE  # removed once every record is written: a killed run leaves it (readers refuse)
    # the records a stopped earlier run of this sample left unwritten stay pending until a run writes them
    header = [f"a dampertwin lab run of {sample} is writing this folder, or was stopped before it finished: "
              f"its records may be partial or mixed with an earlier run's; run it again. Records not written yet:",
              f"sample {sample_doc['_hash']}"]
    old = marker.read_text().splitlines() if marker.is_file() else []
    earlier = old[2:] if old[1:2] == header[1:] else []  # another sample's list: none of its records is here
    for stale in out.glob(f"{INCOMPLETE}.tmp*"):  # a list a killed run was writing
        stale.unlink()
    pending = dict.fromkeys([*earlier, *(f"{t}/{c}" for t, c in items)])

    def note() -> None:  # atomic: a kill while it is written leaves the previous list
        tmp = out / f"{INCOMPLETE}.tmp{os.getpid()}"
        tmp.write_text("\n".join([*header, *pending]) + "\n")
        os.replace(tmp, marker)

    note()
    # longest first (module random tests), so the workers finish together
    order = sorted(range(len(items)), key=lambda i: items[i][0] not in ("random", "verification", "training"))
    workers = min(len(items), workers or os.cpu_count() or 1)
    args = [(str(conf), sample_doc, str(nominal_path), *items[i], seed, str(out)) for i in order]
    paths: dict[int, str] = {}
    bar = tqdm(total=len(items), desc="lab", disable=not progress)

    def done(i: int, path: str) -> None:
        paths[i] = path
        pending.pop(f"{items[i][0]}/{items[i][1]}", None)
        if pending:
            note()
        bar.update()

    if workers <= 1:
        for i, a in zip(order, args):
            done(i, _measure_and_write(*a))
    else:
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
            futs = {pool.submit(_measure_and_write, *a): i for i, a in zip(order, args)}
            for f in as_completed(futs):
                done(futs[f], f.result())
    bar.close()
    if not pending:  # else an earlier stopped run's records this run did not write: still incomplete
        marker.unlink()
    return [Path(paths[i]) for i in range(len(items))]


def generate(conf: str | Path, out: str | Path, seed: int, only: list[tuple[str, str]] | None = None,
             progress: bool = True, sample: str | Path | None = None, workers: int | None = None) -> list[Path]:
    """The DVC lab stage: ``conf/lab/<STAGE_SAMPLE>`` (or ``sample``) through
    every test of the plan into ``out`` (data/measured)."""
    conf = Path(conf)
    return run_lab(sample or conf / "lab" / STAGE_SAMPLE, out, seed=seed, progress=progress, conf=conf,
                   only=only, workers=workers)


# the lab's API (the sample's and the run's parts live in lab_sample and lab_record)
__all__ = ["APPROACH2_TESTS", "EXTRA_TESTS", "LAB3_VERSION", "LAB_VERSION", "LabError", "REST_S", "STAGE_SAMPLE",
           "TEMPERATURE_DEFAULTS", "TRUTH_ATOL", "TRUTH_RTOL", "_sensor_specs", "actuate", "check_corners",
           "check_sample", "generate", "is_truth_sample", "load_sample", "measure_case", "plan", "record", "run_lab",
           "sample_design", "truth_part"]

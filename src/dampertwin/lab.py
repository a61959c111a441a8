"""The virtual laboratory: SYNTHETIC reference "measurements".

No public measurements of this damper type exist, so a hidden physical
sample (``conf/lab/sample.yaml``: each design case's nominal values with the
deviations of a real part) is run through every standard test with the
imperfections of real benches: actuator tracking error (the recorded
displacement is the real motion, not the target, as in thesis 6.5), force
transducer and accelerometer bandwidth, sensor noise, and the flow bench's
isolated conditions (degassed oil, low flow acceleration). Every file says
``synthetic: true`` in its metadata.

Only this module and the tests read ``conf/lab/``; calibration never does.
The samples were built from ``conf/lab/nominal.yaml``, a frozen copy of the
baseline drawings: editing ``conf/design/baseline.yaml`` changes the model,
not the parts on the lab's shelf.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from . import __version__
from .design import Design
from .design import load as load_design
from .design import ConfigTextError, yaml_load_file
from .errors import UserError
from .excitation import Excitation
from .io import write_frame
from .protocols import Run, build_runs, load_all
from .sensors import sensor_lowpass
from .simulation import simulate
from .variants import TOP_MOUNTS, VALVE_DESIGNS, Variant, load_variants

LAB_VERSION = "dampertwin-lab 1"
SAMPLE_KEYS = ("generator", "seed_offset", "factors", "values", "effects", "benches")


class LabError(UserError):
    """A lab description (hidden sample) is invalid, or a lab run failed."""


def load_sample(path: str | Path) -> dict:
    """Read and check the hidden-sample description."""
    path = Path(path)
    try:
        doc = yaml_load_file(path)
    except ConfigTextError as e:
        raise LabError(str(e)) from None
    if not isinstance(doc, dict) or set(doc) != set(SAMPLE_KEYS):
        raise LabError(f"{path}: expected exactly the keys {', '.join(SAMPLE_KEYS)}")
    b = doc["benches"]
    for k in ("actuator", "noise", "bandwidth"):
        if k not in b:
            raise LabError(f"{path}: benches.{k} missing")
    return doc


def sample_design(nominal: Design, sample: dict) -> Design:
    """The real part behind a nominal design: factors and absolute values."""
    ov = {k: nominal[k] * f for k, f in sample["factors"].items()}
    ov.update(sample["values"])
    ov.update({f"effects.{k}": bool(v) for k, v in sample["effects"].items()})
    return nominal.with_overrides(ov)


def _seed(root: int, sample: dict, *names: str) -> int:
    return int(root + sample["seed_offset"] + zlib.crc32("/".join(names).encode())) % (2**32)


def _track(ex: Excitation, gain: float, delay: float) -> Excitation:
    """Actuator tracking error: the real motion lags the target and falls
    short of it. Recorded displacement = this real motion."""
    t = ex.t0 + ex.dt * np.arange(len(ex.value))
    v = gain * np.interp(t - delay, t, ex.value, left=ex.value[0])
    r = gain * np.interp(t - delay, t, ex.rate, left=0.0)
    return replace(ex, value=v, rate=r)


def record(run: Run, design: Design, sample: dict, rng: np.random.Generator, bench: dict | None = None) -> pd.DataFrame:
    """Measure one run on the hidden sample behind ``design``."""
    b = sample["benches"]
    real = _track(run.excitation, b["actuator"]["gain"], b["actuator"]["delay"])
    r = simulate(sample_design(design, sample), real, run.configuration, current=run.current,
                 bench_valve=run.bench_valve, rate=run.rate, bench=bench)
    if not r.ok:
        raise LabError(f"lab simulation of {run.test}/{run.name} failed: {r.stats.message}")
    fs = run.rate
    noise, bw = b["noise"], b["bandwidth"]

    def meas(name: str, x: np.ndarray) -> np.ndarray:
        if name in bw:
            x = sensor_lowpass(x, bw[name], fs)
        return x + noise.get(name, 0.0) * rng.standard_normal(len(x))

    cols = {"time [s]": r.time}
    if run.configuration == "valve":
        cols["flow [m^3/s]"] = meas("flow [m^3/s]", r["flow [m^3/s]"])
        cols["dp [Pa]"] = meas("dp [Pa]", r["dp [Pa]"])
    else:
        cols["displacement [m]"] = meas("displacement [m]", r["displacement [m]"])
        if run.configuration == "damper":
            cols["force [N]"] = meas("force [N]", r["rod force [N]"])
        else:  # load cell above the top mount
            cols["force [N]"] = meas("force [N]", r["top mount force [N]"])
        if run.configuration == "module":
            cols["rod acceleration [m/s^2]"] = meas("rod acceleration [m/s^2]", r["rod acceleration [m/s^2]"])
        if run.configuration in ("damper", "module"):
            cols["current [A]"] = np.full(len(r.time), run.current)
    df = pd.DataFrame(cols)
    df.insert(0, "run", run.name)
    return df


def _write(out: Path, protocol: str, case: str, frames: list[pd.DataFrame], design: Design, seed: int,
           extra: dict | None = None) -> Path:
    meta = {"synthetic": True, "generator": LAB_VERSION, "dampertwin": __version__, "seed": seed,
            "design_hash": design.hash(), "protocol": protocol, "case": case,
            "note": "SYNTHETIC measurement from the dampertwin virtual laboratory (hidden sample)", **(extra or {})}
    return write_frame(out / protocol / f"{case}.parquet", pd.concat(frames, ignore_index=True), meta)


def plan(conf: Path) -> list[tuple[str, str]]:
    """(protocol, case) of every file the lab writes."""
    variants = load_variants(conf / "variant")
    items = [("flowbench", v) for v in VALVE_DESIGNS] + [("compliance", "baseline")]
    items += [("topmount", t) for t in TOP_MOUNTS] + [("curving", "baseline")]
    items += [("monosine", v.case) for v in variants] + [("random", v.case) for v in variants]
    return items


def generate(conf: str | Path, out: str | Path, seed: int, only: list[tuple[str, str]] | None = None,
             progress: bool = True) -> list[Path]:
    """Run the hidden sample through every protocol and write data/measured."""
    from tqdm import tqdm

    conf, out = Path(conf), Path(out)
    sample = load_sample(conf / "lab" / "sample.yaml")
    baseline = load_design(conf / "lab" / "nominal.yaml")  # the drawings the samples were built from
    variants = {v.case: v for v in load_variants(conf / "variant")}
    protocols = load_all(conf / "test")
    items = plan(conf) if only is None else only
    written = []
    for protocol, case in tqdm(items, desc="lab", disable=not progress):
        s = _seed(seed, sample, protocol, case)
        rng = np.random.default_rng(s)
        pc = protocols[protocol]
        runs = build_runs(pc, seed)
        if protocol == "flowbench":
            valve, vcase = VALVE_DESIGNS[case]
            d = variants[vcase].apply(baseline) if vcase else baseline
            run = next(r for r in runs if r.bench_valve == valve)
            bench = {"bench_volume": pc["volume"], "bench_back_pressure": pc["back_pressure"]}
            frames = [record(run, d, sample, rng, bench)]
            written.append(_write(out, protocol, case, frames, d, s, {"valve": valve, "valve_design": case}))
            continue
        if protocol == "topmount":
            vcase = TOP_MOUNTS[case]
            d = variants[vcase].apply(baseline) if vcase else baseline
        elif protocol in ("compliance", "curving"):
            d = baseline
        else:
            v: Variant = variants[case]
            d = v.apply(baseline)
            runs = [r for r in runs if math.isclose(r.current, v.current)]
            if not runs:
                raise LabError(f"protocol {protocol} has no run at {v.current} A for case {case}")
        frames = [record(r, d, sample, rng) for r in runs]
        written.append(_write(out, protocol, case, frames, d, s))
    return written


"""The virtual laboratory's passive samples (a nominal design of
architecture twin_tube or mono_tube): the tests a passive damper can run,
and one record of any lab-3 sample's truth for any displacement excitation
(e.g. a dyno run). Records say ``synthetic: true`` like the lab's others."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .excitation import Excitation

DEFAULT_ARCHITECTURE = "triple_tube_semi_active"
# the tests of a passive damper's sample (no active valve: each input once, at 0 A: protocols.passive_runs)
PASSIVE_TESTS = ("flowbench", "compliance", "curving", "dyno")
PASSIVE_VALVES = {"twin_tube": ("piston_rebound", "piston_intake", "base_compression", "base_intake"),
                  "mono_tube": ("piston_rebound", "piston_intake")}


def measure_excitation(sample: str | Path | dict, excitation: Excitation, *, name: str = "run",
                       test: str = "excitation", configuration: str = "damper", current: float = 0.0,
                       rate: float = 1000.0, seed: int = 0, oil_dT: float = 0.0,
                       conf: str | Path | None = None) -> tuple[pd.DataFrame, dict]:
    """One record of a lab-3 sample's truth for any displacement
    ``excitation`` (e.g. a dyno run): the actuator, the truth, the benches'
    transducers, as the standard tests. Returns the frame and its metadata
    (``synthetic: true``). A passive sample runs at 0 A whatever ``current``."""
    from . import __version__
    from .config import repo_root
    from .design import load as load_design
    from .lab import LAB3_VERSION, LabError, _nominal_path, _seed, check_sample, is_truth_sample, load_sample, record
    from .protocols import Run
    from .truth import TRUTH_VERSION
    from .truth.run import ATOL, RTOL

    conf = Path(conf) if conf is not None else repo_root(Path(__file__).parent) / "conf"
    doc = sample if isinstance(sample, dict) else load_sample(sample)
    if not is_truth_sample(doc):
        raise LabError(f"{doc.get('_path', '<sample>')}: generator: expected {LAB3_VERSION!r} (a truth sample)")
    if excitation.kind != "displacement" or configuration not in ("damper", "module"):
        raise LabError(f"excitation: a displacement on configuration damper or module expected, got "
                       f"{excitation.kind} on {configuration!r}")
    nominal_path = _nominal_path(conf, doc)
    nominal = load_design(nominal_path)
    check_sample(doc, nominal)
    arch = getattr(nominal, "architecture", DEFAULT_ARCHITECTURE)
    if arch != DEFAULT_ARCHITECTURE:
        current = 0.0
    s = _seed(seed, doc, test, name)
    rng = np.random.default_rng(s)
    run = Run(test, name, configuration, excitation, float(current), float(rate))
    df = record(run, nominal, doc, rng, oil_dT=oil_dT, nominal=nominal)
    meta = {"synthetic": True, "generator": LAB3_VERSION, "dampertwin": __version__, "seed": s,
            "design_hash": nominal.hash(), "protocol": test, "case": name, "architecture": arch,
            "sample": Path(doc.get("_path", "sample.yaml")).name, "sample_hash": doc.get("_hash", ""),
            "truth": TRUTH_VERSION, "truth_rtol": RTOL, "truth_atol": ATOL,
            "oil_temperature_K": {name: round(nominal["oil.T"] + oil_dT, 3)},
            "note": "SYNTHETIC measurement from the dampertwin virtual laboratory: hidden sample on the "
                    f"reference damper {TRUTH_VERSION} (other physics than the model)"}
    return df, meta

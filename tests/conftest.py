import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BASELINE = ROOT / "conf" / "design" / "baseline.yaml"
sys.path.insert(0, str(Path(__file__).parent))

# pytest-xdist workers for `-n auto` (pyproject's addopts): one per core, at most 4. Each worker compiles
# the numba kernels its tests call on a cold cache and holds ~1.2 GB, so more workers gain little and cost
# memory. `-n 0` runs serially (a debugger, `-x` on the first failure in order).
XDIST_MAX_WORKERS = 4


def pytest_xdist_auto_num_workers(config):
    import os

    return max(1, min(XDIST_MAX_WORKERS, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                      else os.cpu_count() or 1))


# Session-scoped data shared by several test modules: one copy per run of the suite (a fixture
# imported from another test module is a second fixture with its own module-scoped copy). Pure
# data: no test writes into them.


@pytest.fixture(scope="session")
def short_training():
    """Damper-level training record: one stroke, two velocities, one
    current (the shipped protocol's structure, shortened for CI)."""
    import numpy as np
    import pandas as pd

    from dampertwin import lab
    from dampertwin.protocols import build_runs, load_protocol

    conf = ROOT / "conf"
    proto = dict(load_protocol(conf / "test" / "training.yaml"))
    assert proto["configuration"] == "damper"
    proto.update(strokes=[0.01], velocities=[0.5, 1.0], cycles=2, currents=[1.6], rate=2000.0)
    sample = lab.load_sample(conf / "lab" / "lab2" / "sample.yaml")
    nominal = lab.load_design(conf / "lab" / "nominal.yaml")
    rng = np.random.default_rng(1)
    frames = [lab.record(r, nominal, sample, rng) for r in build_runs(proto, 0)]
    return pd.concat(frames, ignore_index=True)


@pytest.fixture(scope="session")
def control(tmp_path_factory) -> Path:
    """The nominal part (no deviations, no hidden effect) on the shipped lab's benches
    (compliance + two mono-sine currents: tests/test_discrepancy.py ONLY)."""
    from test_discrepancy import _lab

    return _lab(tmp_path_factory.mktemp("lab"), "control", 11)


@pytest.fixture(scope="session")
def control_serial_run(control, tmp_path_factory):
    """The discrepancy workflow on ``control`` (ci profile, seed 0, the records simulated in this
    process): (OUT, verdict). The reference that the 2-process pool and the Dask cluster runs are
    compared with byte for byte."""
    from test_discrepancy import _run

    out = tmp_path_factory.mktemp("control_serial") / "out"
    return out, _run(control, out, workers=1)

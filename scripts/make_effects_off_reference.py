"""Regenerate tests/reference/effects_off_reference.npz (the change detector of
tests/test_effects.py::test_off_equals_the_model_without_the_library) and print
how far the new run is from the stored one. Run it only when a change of the
solver's or the model's arithmetic is intended, and name the change and the
printed deviation in the commit message.

    python scripts/make_effects_off_reference.py [--check]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from dampertwin import Excitation, simulate
from dampertwin.design import load

ROOT = Path(__file__).resolve().parents[1]
REF = ROOT / "tests" / "reference" / "effects_off_reference.npz"
CHANNELS = ("rod force [N]", "p compression [Pa]", "p third tube [Pa]", "friction force [N]")


def runs() -> dict[str, np.ndarray]:
    base = load(ROOT / "conf" / "design" / "baseline.yaml")
    ex = Excitation.sine(duration=2 / 13.0, amplitude=0.005, frequency=13.0)
    out = {}
    for cfg in ("damper", "module"):
        r = simulate(base, ex, cfg)
        out.update({f"{cfg}|{k}": r[k] for k in CHANNELS})
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--check", action="store_true", help="only print the deviation from the stored run")
    a = ap.parse_args()
    new = runs()
    old = np.load(REF)
    dev = {k: float(np.max(np.abs(new[k] - old[k])) / np.max(np.abs(old[k]))) for k in new}
    print(json.dumps({"max_abs_deviation_rel_to_channel_max": dev}))
    if not a.check:
        np.savez(REF, **new)


if __name__ == "__main__":
    main()

"""The friction fit with the library's effects: the friction-only model's
free play and asymmetry (limits, passivity), parameter recovery on a
SYNTHETIC record of known parameters, bound hits reported and data-derived
bounds widened, and the real BRFD record (CC BY-SA 4.0, the worked example's
copy) fitted to force NRMSE <= 0.08 on fitted and held-out cycles."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dampertwin.calibration import friction_fit as ff
from dampertwin.calibration.ga import ParamSpec
from dampertwin.cli import main
from dampertwin.cli_fit_files import fit_friction
from dampertwin.io import write_frame
from dampertwin.model.friction_only import simulate_friction

LAW = dict(F_c=20.0, F_s=35.0, k_b=4e5, s2=150.0, c_comp=500.0, vd=0.001, a_s=0.01, alpha_s=2.0)
FIXED = dict(c_comp=500.0, vd=0.001, a_s=0.01, alpha_s=2.0, v_reg=1e-3)
EFFECTS = dict(a=-0.2, delta=5e-4)
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "friction-brfd"
BRFD = EXAMPLE / "brfd_0.25Hz_36lb_1in.csv.gz"  # real record, CC BY-SA 4.0 (examples/friction-brfd/README.md)
MAPPING = EXAMPLE / "mapping.yaml"


def _motion(cycles=6, f=0.5, fs=1000.0, amp=0.005):
    t = np.arange(0, cycles / f, 1 / fs)
    x = amp * np.sin(2 * np.pi * f * t) * np.minimum(t * f, 1.0)
    return t, x, np.gradient(x, t)


def synthetic(path, noise=0.5, seed=3, **effects):
    """A friction-device record from known parameters (SYNTHETIC)."""
    t, x, v = _motion()
    F = simulate_friction(t, v, **LAW, **effects) + np.random.default_rng(seed).normal(0, noise, len(t))
    return write_frame(path, pd.DataFrame({"time [s]": t, "displacement [m]": x, "force [N]": F}),
                       {"synthetic": True, "truth": {**LAW, **effects}, "noise [N]": noise})


def test_free_play_carries_no_force_and_the_law_stays_passive():
    t, x, v = _motion(cycles=3)
    F0 = simulate_friction(t, v, **LAW)
    F = simulate_friction(t, v, **LAW, **EFFECTS)
    # the plain law is the limit of vanishing effects
    assert np.max(np.abs(simulate_friction(t, v, **LAW, delta=1e-15) - F0)) < 1e-6
    assert np.max(np.abs(simulate_friction(t, v, **LAW, a=1e-12) - F0)) < 1e-6
    # after a reversal, once the bristles have unloaded (a travel of ~F_s / k_b), the elastic force is
    # zero over the play (a travel of 2 delta): the force is the damping terms only
    i = int(np.argmax(x[len(x) // 2:])) + len(x) // 2  # a displacement maximum
    back = x[i] - x[i:]
    inside = slice(i + int(np.argmax(back > 2 * LAW["F_s"] / LAW["k_b"])),
                   i + int(np.argmax(back > 1.9 * EFFECTS["delta"])))
    assert inside.stop - inside.start > 20
    damping = 500.0 * np.exp(-(v[inside] / 1e-3) ** 2) * v[inside] + LAW["s2"] * v[inside]
    assert np.max(np.abs(F[inside] - damping)) < 1e-6 * LAW["F_c"] + 1e-9
    assert np.max(np.abs(F0[inside])) > 10.0  # the plain law carries its friction there
    # asymmetry: sliding levels (1 + a) and (1 - a) of F_c
    assert np.max(F[len(F) // 2:]) < np.max(-F[len(F) // 2:])
    # passivity: over whole cycles the device absorbs work
    per = int(round(1000.0 / 0.5))
    for k in range(1, 3):
        s = slice(k * per, (k + 1) * per)
        assert np.sum(F[s] * v[s]) * 1e-3 > 0


def test_fit_recovers_known_parameters_and_effects(tmp_path):
    rec = synthetic(tmp_path / "rec.parquet", **EFFECTS)
    r = fit_friction(rec, fixed=FIXED, effects=("asymmetric", "free_play"), out=tmp_path / "out", starts=4)
    truth = {**LAW, **EFFECTS}
    for k in ("F_c", "F_s", "k_b", "s2", "a", "delta"):
        assert r["parameters"][k] == pytest.approx(truth[k], rel=0.05), k
    assert r["cycles"]["held_out"] and r["nrmse"] < 0.02 and r["nrmse_held_out"] < 0.02
    assert r["bound_hits"] == [] and r["flags"] == []
    assert r["effects"]["without asymmetric"]["supported"] and r["effects"]["without free_play"]["supported"]
    assert json.loads((tmp_path / "out" / "fit.json").read_text())["parameters"] == pytest.approx(r["parameters"])


def test_effects_absent_from_the_data_are_not_supported(tmp_path):
    rec = synthetic(tmp_path / "rec.parquet")  # plain law: no play
    r = fit_friction(rec, fixed=FIXED, effects=("free_play",), starts=3)
    assert not r["effects"]["without free_play"]["supported"]
    assert any("free_play not supported" in f for f in r["flags"])


def test_a_bound_the_optimum_lies_beyond_is_reported(tmp_path, capsys):
    rec = synthetic(tmp_path / "rec.parquet")
    out = tmp_path / "o"
    assert main(["fit", "friction", "--data", str(rec), "--out", str(out), "--param", "F_c=0:100",
                 "--param", "F_s=0:100", "--param", "s2=0:1000", "--param", "k_b=1e4:1e5:log"]) == 0
    doc = json.loads((out / "fit.json").read_text())
    hit = [h for h in doc["bound_hits"] if h["parameter"] == "k_b"]
    assert hit and hit[0]["bound"] == "upper" and hit[0]["kind"] == "user"
    assert "k_b" in capsys.readouterr().err


SHAPE = "expected [low, high], two finite numbers, low < high"


@pytest.mark.parametrize("item, param, needle", [
    ("{name: F_c, bounds: [0, abc]}", None, f"item 0 (F_c): bad interval [0, 'abc']; {SHAPE}"),
    ("{name: F_c, bounds: [0, 1, 2]}", None, f"item 0 (F_c): bad interval [0, 1, 2]; {SHAPE}"),
    ("{name: F_c, bounds: 5}", None, f"item 0 (F_c): bad interval 5; {SHAPE}"),
    ("{name: F_c, bounds: [0, .inf]}", None, SHAPE),
    ("{name: F_c, bounds: [-100, -1]}", "F_c=-100:-1",
     "item 0 (F_c): bounds [-100, -1] outside the physical range of F_c, the Coulomb friction force [N]: "
     "expected within [0, inf)"),
    ("{name: F_s, bounds: [-5, 50]}", "F_s=-5:50", "physical range of F_s, the static friction force [N]"),
    ("{name: k_b, bounds: [0, 1.0e6]}", "k_b=0:1e6", "physical range of k_b, the bristle stiffness [N/m]: "
                                                     "expected within (0, inf)"),
    ("{name: s2, bounds: [-10, 100]}", "s2=-10:100", "physical range of s2"),
    ("{name: a_s, bounds: [0, 0.1]}", "a_s=0:0.1", "physical range of a_s"),
    ("{name: a, bounds: [-1, 0.5]}", "a=-1:0.5", "physical range of a, the direction factor [-]: expected within "
                                                 "(-1, 1)"),
], ids=["abc", "three", "scalar", "inf", "negative F_c", "negative F_s", "zero k_b", "negative s2", "zero a_s",
        "a -1"])
def test_bad_or_unphysical_bounds_are_one_line_naming_source_and_item(tmp_path, capsys, item, param, needle):
    """A --bounds item (and the same bounds by --param) that is not [low, high] or leaves the parameter's
    physical range: exit 2, one line naming the file / option, the item and what was expected; no fit."""
    rec = synthetic(tmp_path / "rec.parquet")
    b = tmp_path / "b.yaml"
    b.write_text(f"parameters:\n  - {item}\n")
    out = tmp_path / "o"
    for src, argv in ((str(b), ["--bounds", str(b)]), ("--param", ["--param", param] if param else None)):
        if argv is None:
            continue
        assert main(["fit", "friction", "--data", str(rec), "--out", str(out), *argv]) == 2
        err = capsys.readouterr().err
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        assert f"{src}: " in err and needle in err, err
    assert not out.exists()


def test_a_data_derived_bound_is_widened_until_it_holds_the_optimum():
    t, x, v = _motion(cycles=3)
    F = simulate_friction(t, v, **LAW)
    specs = [ParamSpec("F_c", 0, 100), ParamSpec("F_s", 0, 100), ParamSpec("k_b", 1e3, 4e4, "log")]
    base = {**LAW, "a": 0.0, "delta": 0.0, "v_reg": 1e-3}
    fit = ff.fit_model(t, v, F, np.ones(len(t), bool), base, specs, ["data"] * 3, starts=3)
    assert fit["widening_rounds"] >= 1 and fit["bound_hits"] == []
    assert fit["values"]["k_b"] == pytest.approx(LAW["k_b"], rel=1e-3)


def test_real_brfd_record_fitted_and_held_out_within_8_percent(tmp_path):
    """The real friction record (kN forces, asymmetric, free play), imported
    with the worked example's mapping, fitted on its first cycles with both
    effects: force NRMSE <= 0.08 on fitted and held-out cycles, no
    parameter on a bound, and both effects supported by the held-out cycles
    (the plain law misses 0.08 there)."""
    rec = tmp_path / "brfd.parquet"
    assert main(["import", str(BRFD), "--map", str(MAPPING), "--out", str(rec)]) == 0
    r = fit_friction(rec, effects=("asymmetric", "free_play"), starts=4, out=tmp_path / "fit")
    assert r["cycles"]["held_out"], r["cycles"]
    assert r["nrmse"] <= 0.08 and r["nrmse_held_out"] <= 0.08, (r["nrmse"], r["nrmse_held_out"])
    assert r["bound_hits"] == []
    assert r["effects"]["without asymmetric"]["supported"] and r["effects"]["without free_play"]["supported"]
    assert r["effects"]["without any effect"]["nrmse_held_out_without"] > 0.08


def test_a_law_that_cannot_run_at_the_start_is_a_fit_error_not_a_traceback(tmp_path):
    """Through the API (the command line refuses a fixed F_s = 0 before): LuGre's steady bristle state
    divides by g(0) = F_s, so no start gives a finite force; the fit stops with a FitError naming the
    bounds, the fixed values and what the law needs, not scipy's ValueError."""
    from dampertwin.calibration.ga import FitError

    rec = synthetic(tmp_path / "rec.parquet")
    with pytest.raises(FitError, match=r"no finite force at a start inside the bounds .*'F_s': 0\.0.*F_s > 0"):
        fit_friction(rec, fixed={"F_s": 0.0}, bounds=[{"name": "F_c", "bounds": [0.0, 200.0]}], starts=2)

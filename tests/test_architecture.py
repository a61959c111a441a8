"""Damper architectures (design key ``architecture:``): the thesis' triple tube unchanged, passive twin-tube and
mono-tube dampers from the same submodels, each checked on a property that fails if its physics were wrong."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from dampertwin.design import DesignError, load, loads
from dampertwin.design.architecture import PLACEHOLDER, UNUSED_NUMBERS
from dampertwin.excitation import Excitation
from dampertwin.model.params import pack
from dampertwin.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]
DESIGNS = ROOT / "conf" / "design"


@pytest.fixture(scope="module")
def designs():
    return {n: load(DESIGNS / f"{n}.yaml") for n in ("baseline", "twin_tube", "mono_tube")}


def _doc(name: str) -> dict:
    return yaml.safe_load((DESIGNS / f"{name}.yaml").read_text())


def _loads(doc: dict, where: str = "probe.yaml"):
    return loads(yaml.safe_dump(doc, sort_keys=False), base_dir=DESIGNS, where=where)


def _sine(design, amplitude=0.02, frequency=2.0, cycles=3, current=0.0, configuration="damper", effects=None):
    ex = Excitation.sine(amplitude=amplitude, frequency=frequency, duration=cycles / frequency)
    return simulate(design, ex, configuration, current=current, effects=effects)


def test_the_thesis_damper_is_the_default_and_naming_it_changes_nothing(designs):
    base = designs["baseline"]
    assert base.architecture == "triple_tube_semi_active"
    named = _loads({**_doc("baseline"), "architecture": "triple_tube_semi_active"})
    assert named.hash() == base.hash()
    assert np.array_equal(pack(named), pack(base))
    assert "architecture" not in base.dumps()  # the default is not written: old files round-trip byte for byte


@pytest.mark.parametrize("name", ["twin_tube", "mono_tube"])
def test_a_passive_design_round_trips_without_its_placeholders(designs, name, tmp_path):
    d = designs[name]
    assert d.architecture == name and d.pq_map is None
    left_out = [n for n in UNUSED_NUMBERS[name] if d.parameters.get(n) and d.parameters[n].source
                == PLACEHOLDER.format(arch=name)]
    assert left_out, "the example leaves the parts it lacks out of the file"
    text = d.dumps()
    assert f"architecture: {name}" in text and "placeholder" not in text
    again = load(d.dump(tmp_path / f"{name}.yaml"))
    assert again == d and again.hash() == d.hash()


def test_unknown_architecture_and_missing_parts_are_named():
    with pytest.raises(DesignError, match=r"probe.yaml: architecture: 'quad_tube'; expected one of"):
        _loads({**_doc("baseline"), "architecture": "quad_tube"})
    doc = _doc("twin_tube")  # the thesis' damper needs its third tube: leaving it out is an error there
    doc["architecture"] = "triple_tube_semi_active"
    with pytest.raises(DesignError) as e:
        _loads(doc)
    assert "no. 4 (geometry.V_b): missing number" in str(e.value)
    assert "no. 52 (active_valve.pq_map): missing number" in str(e.value)


@pytest.mark.parametrize("name,effect", [("twin_tube", "active_valve_lag"), ("mono_tube", "active_valve_driver"),
                                         ("mono_tube", "valve_friction_current")])
def test_effects_a_passive_damper_has_no_part_for_are_refused(name, effect):
    doc = _doc(name)
    doc["effects"][effect] = True
    with pytest.raises(DesignError, match=rf"probe.yaml: effects.{effect}: true"):
        _loads(doc)


def test_the_gas_must_take_the_rod_volume():
    doc = _doc("mono_tube")
    for c in doc["constants"]:
        if c["name"] == "V_gas0":
            c["value"] = 1e-6
    with pytest.raises(DesignError, match=r"constant 'V_gas0': value 1e-06; expected > the rod's swept volume"):
        _loads(doc)


def _gas_volume(r, design):
    """Gas volume [m^3] from the gas pressure (polytropic, THESIS-ERRATA 8)."""
    P0, V0, g = design["oil.P_0"], design.constant("V_gas0"), design["oil.Gamma"]
    return V0 * (P0 / r.channels["p reserve [Pa]"]) ** (1.0 / g)


@pytest.mark.parametrize("name", ["twin_tube", "mono_tube"])
def test_the_gas_takes_the_rod_volume_and_no_third_tube_or_active_valve_acts(designs, name):
    """Volume balance of the oil (eq. 4.9-4.12): the gas volume changes by the rod's swept volume A_rod s plus
    the oil volume the chambers' pressures store (the time integral of the storage channels V / K dP/dt);
    the passive damper's third tube and active valve carry nothing."""
    from scipy.integrate import cumulative_trapezoid

    d = designs[name]
    r = _sine(d, amplitude=0.02, frequency=2.0, cycles=2)
    c = r.channels
    a_rod = math.pi * d["geometry.D_R"] ** 2 / 4.0
    dv = _gas_volume(r, d) - d.constant("V_gas0")
    stored = cumulative_trapezoid(c["storage rebound [m^3/s]"] + c["storage compression [m^3/s]"], r.time,
                                  initial=0.0)
    assert np.max(np.abs(stored)) > 0.01 * a_rod * 0.02  # the storage term matters at this speed
    assert np.max(np.abs(dv - (a_rod * c["stroke [m]"] + stored))) < 0.005 * a_rod * 0.02
    np.testing.assert_allclose(c["p third tube [Pa]"], d["oil.P_0"], rtol=1e-9)
    assert np.all(c["flow active valve [m^3/s]"] == 0.0)
    assert np.all(c["flow bypass [m^3/s]"] == 0.0)


def test_mono_tube_floating_piston_keeps_the_compression_chamber_at_the_gas_pressure(designs):
    d = designs["mono_tube"]
    r = _sine(d, amplitude=0.02, frequency=5.0, cycles=2)
    pc, pg = r.channels["p compression [Pa]"], r.channels["p reserve [Pa]"]
    assert np.max(np.abs(pc - pg)) < 1e-6 * np.max(pg)
    assert np.all(r.channels["flow base_compression [m^3/s]"] == 0.0)
    assert np.all(r.channels["flow base_intake [m^3/s]"] == 0.0)
    # at rest the gas pushes the rod out with (P_0 - P_atm) A_rod (a compressive rod force)
    a_rod = math.pi * d["geometry.D_R"] ** 2 / 4.0
    assert r.channels["rod force [N]"][0] == pytest.approx(-(d["oil.P_0"] - d.constant("P_atm")) * a_rod, rel=1e-6)


@pytest.mark.parametrize("name", ["twin_tube", "mono_tube"])
def test_passive_dampers_dissipate_and_ignore_the_current(designs, name):
    """Passivity: the work of the rod force over a steady cycle is dissipated (loop area > 0), rebound force
    above compression force at the velocity peaks; the current is not read (no active valve)."""
    d = designs[name]
    r = _sine(d, amplitude=0.01, frequency=8.0, cycles=3)
    t, F, u = r.time, r.channels["rod force [N]"], r.channels["stroke [m]"]
    last = t >= t[-1] - 1.0 / 8.0
    work = np.trapezoid(F[last], u[last])  # energy into the damper over one cycle [J] (F > 0 resists extension)
    assert work > 0.0
    v = r.channels["velocity [m/s]"]
    assert F[last][np.argmax(v[last])] > 0.0 > F[last][np.argmin(v[last])]
    other = _sine(d, amplitude=0.01, frequency=8.0, cycles=3, current=1.6)
    assert np.array_equal(other.channels["rod force [N]"], F)


def test_the_mono_tube_compression_chamber_is_stiffer_with_less_gas(designs):
    """Limit case: the floating piston puts the gas in series with the oil; with a smaller gas chamber the
    pressure rise per rod volume (gamma P / V_g) grows, so the compression force at a fast stroke grows."""
    d = designs["mono_tube"]
    small = d.with_overrides({"constants.V_gas0": 3.5e-5})
    big = _sine(d, amplitude=0.02, frequency=2.0, cycles=1)
    sm = _sine(small, amplitude=0.02, frequency=2.0, cycles=1)
    assert sm.channels["p reserve [Pa]"].max() > big.channels["p reserve [Pa]"].max()


@pytest.mark.parametrize("name", ["twin_tube", "mono_tube"])
def test_probed_sparsity_covers_each_architecture(designs, name):
    """Full finite-difference Jacobians of a passive damper at random states never show a dependency outside the
    probed pattern (the floating piston couples the compression chamber to the gas volume)."""
    from dampertwin.model import layout as L
    from dampertwin.model.damper import RHS
    from dampertwin.model.sparsity import pattern, probe_states
    from dampertwin.simulation import model_map
    from dampertwin.solver import Sparsity, fd_jacobian

    d = designs[name]
    cfg = L.CONFIGURATIONS["damper"]
    p = pack(d, 0.0)
    ex = Excitation.sine(0.005, 13.0, 0.2)
    p[L.P.EX_T0], p[L.P.EX_DT] = ex.t0, ex.dt
    aux = model_map(d.pq_map)
    J = pattern(RHS["damper"], cfg, p[None], ex.array(), aux, (0.0, 0.2))
    rng = np.random.default_rng(4321)
    Y = probe_states(p, cfg, 100, rng)
    n, sc = Y.shape[1], L.state_scales(cfg)
    dense = Sparsity.dense(n)
    for y in Y:
        jac, ft = np.zeros((n, n)), np.zeros(n)
        fd_jacobian(RHS["damper"], rng.uniform(0, 0.2), y / sc, sc, p, ex.array(), aux, *dense.args(), jac, ft, L.N_OUT)
        nz = np.isfinite(jac) & (jac != 0)
        assert not np.any(nz & ~J)
    if name == "mono_tube":
        assert J[L.S.P_c, L.S.V_g] and J[L.S.V_g, L.S.P_r]


def test_the_sparsity_cache_tells_the_architectures_apart(designs):
    """A probe cached for a twin tube must not serve a mono tube: same bytes fresh and after the other's run."""
    from dampertwin import simulation

    simulation._SPARSITY_CACHE.clear()
    fresh = _sine(designs["mono_tube"], cycles=1)
    simulation._SPARSITY_CACHE.clear()
    _sine(designs["twin_tube"], cycles=1)
    after = _sine(designs["mono_tube"], cycles=1)
    for k, v in fresh.channels.items():
        assert np.array_equal(v, after.channels[k]), k


def test_an_adjuster_on_a_valve_the_architecture_lacks_is_refused():
    doc = _doc("mono_tube")
    doc["adjusters"] = {"compression": {"valve": "base_compression", "parameter": "F_preload", "unit": "N",
                                        "clicks": [300.0, 200.0, 100.0], "source": "probe"}}
    with pytest.raises(DesignError, match=r"adjusters.compression.valve: 'base_compression', but a mono_tube damper "
                                          r"has no base valves"):
        _loads(doc)
    doc["adjusters"]["compression"]["valve"] = "piston_intake"  # the piston's compression valve
    pre = next(p["value"] for p in doc["parameters"] if p["no"] == 63)
    doc["adjusters"]["compression"]["clicks"] = [pre * 1.5, pre, pre * 0.5]
    d = _loads(doc)
    assert d.at_setting({"compression": 2})["piston_intake.F_preload"] == pre * 0.5


def test_simulate_runs_only_what_the_architecture_has(designs, tmp_path):
    """`dampertwin simulate` on a mono tube: no flow-bench run of its absent base valves; a passive damper runs
    each input once (the current is not read) and its record says so."""
    import pandas as pd

    from dampertwin import cli
    from dampertwin.io import read_meta

    assert cli.main(["simulate", str(DESIGNS / "mono_tube.yaml"), "--test", "flowbench", "--out", str(tmp_path)]) == 0
    df = pd.read_parquet(tmp_path / "flowbench.parquet")
    assert sorted(df["run"].unique()) == ["piston_intake", "piston_rebound"]
    assert read_meta(tmp_path / "flowbench.parquet")["current_read"] is False
    from dampertwin.protocols import build_runs, load_protocol
    from dampertwin.simulate_test import runs_for_design

    runs = build_runs(load_protocol(ROOT / "conf" / "test" / "curving.yaml"))
    kept = runs_for_design(designs["twin_tube"], runs, "curving")
    assert len(kept) == len({r.excitation.array().tobytes() for r in runs}) < len(runs)
    assert runs_for_design(designs["baseline"], runs, "curving") == runs


def test_a_passive_damper_runs_each_input_once_whatever_the_protocol():
    """protocols.passive_runs, which `dampertwin simulate` and the lab both use: runs that differ only by the
    current are one run for a passive damper (the first current's); other inputs stay apart; the lab's records
    of it are at 0 A, labelled I0."""
    from dampertwin.protocols import build_runs, load_protocol, passive_runs

    curving = build_runs(load_protocol(ROOT / "conf" / "test" / "curving.yaml"))
    first = [r for r in curving if r.current == curving[0].current]
    assert passive_runs(curving) == first and len(first) < len(curving)
    recs = passive_runs(curving, at_zero=True)
    assert [(r.name, r.current) for r in recs] == [(r.name.replace(f"_I{r.current:g}", "_I0"), 0.0) for r in first]
    dyno = load_protocol(ROOT / "conf" / "test" / "dyno.yaml")
    (alone,) = build_runs(dyno)
    assert passive_runs([alone], at_zero=True) == [alone]  # the current-free dyno run: label passive, 0 A
    active = build_runs({**dyno, "currents": [0.32, 1.6]})
    assert passive_runs(active) == active[:1]
    fast = build_runs({**dyno, "currents": [0.32], "amplitude": dyno["amplitude"] / 2})  # another input
    assert passive_runs(active + fast) == [active[0], fast[0]]


def test_mono_tube_gas_heating_moves_the_compression_chamber_with_the_gas_law(designs):
    """oil_thermal in a mono tube: at rest with the oil 20 K above the ambient (cooling), the compression
    chamber's pressure rate equals the gas law's total derivative, d/dt [P0 (V0/V_g)^gamma T/T0] =
    -gamma P / V_g dV_g/dt + P dT/dt / T; without the heating term the chamber would not follow its gas."""
    from dampertwin.model import layout as L
    from dampertwin.model.damper import RHS_BY_CFG
    from dampertwin.simulation import model_map

    doc = _doc("mono_tube")
    doc["effects"]["oil_thermal"] = True
    d = _loads(doc)
    p = pack(d, 0.0)
    ex = Excitation.sine(0.0, 1.0, 0.1)  # no motion
    p[L.P.EX_T0], p[L.P.EX_DT] = ex.t0, ex.dt
    cfg = L.variant(L.CFG_DAMPER, p)
    assert cfg == L.CFG_DAMPER_X
    y = L.initial_state(p, cfg)
    T = y[L.EB_DAMPER + L.EX.T_oil] = d["oil.T"] + 20.0
    dy, out = np.zeros_like(y), np.zeros(L.N_OUT)
    RHS_BY_CFG[cfg](0.05, y, p, ex.array(), model_map(None), dy, out)
    dT, Vg, dVg = dy[L.EB_DAMPER + L.EX.T_oil], y[L.S.V_g], dy[L.S.V_g]
    P = out[L.O.P_RES]
    assert dT < 0 and P == pytest.approx(d["oil.P_0"] * T / d["oil.T"])
    assert out[L.O.P_C] == P
    law = -d["oil.Gamma"] * P / Vg * dVg + P * dT / T
    assert dy[L.S.P_c] == pytest.approx(law, rel=1e-9, abs=1e-6)
    assert abs(dy[L.S.P_c]) > 1.0  # the cooling gas does move the chamber [Pa/s]


def test_the_discrepancy_candidates_of_a_passive_damper_leave_out_the_active_valve(designs):
    from dampertwin.design.architecture import ACTIVE_VALVE_EFFECTS
    from dampertwin.discrepancy.entry import load_config
    from dampertwin.discrepancy.workflow import catalogue

    cfg = load_config(ROOT / "conf")
    base = {c.name for c in catalogue(designs["baseline"], cfg)}
    twin = {c.name for c in catalogue(designs["twin_tube"], cfg)}
    assert set(ACTIVE_VALVE_EFFECTS) & base and not set(ACTIVE_VALVE_EFFECTS) & twin
    assert "oil_thermal" in twin and "oil_thermal" in {c.name for c in catalogue(designs["mono_tube"], cfg)}


@pytest.mark.slow
def test_the_discrepancy_workflow_runs_on_a_twin_tube(designs, tmp_path):
    """A twin tube's own simulated records (compliance, curving) through `dampertwin discrepancy`: verdict none
    (the records are the model's: nothing is missing), the augmented design loads without a P/Q map."""
    import pandas as pd

    from dampertwin import cli
    from dampertwin.io import write_frame

    meas = tmp_path / "measured"
    for test in ("compliance", "curving"):
        assert cli.main(["simulate", str(DESIGNS / "twin_tube.yaml"), "--test", test, "--out", str(tmp_path / test)]) == 0
        df = pd.read_parquet(tmp_path / test / f"{test}.parquet")
        rec = pd.DataFrame({"time [s]": df["time [s]"], "displacement [m]": df["displacement [m]"],
                            "force [N]": df["rod force [N]"], "current [A]": 0.0, "run": df["run"]})
        write_frame(meas / test / "baseline.parquet", rec, {"synthetic": True, "protocol": test})
    out = tmp_path / "out"
    assert cli.main(["discrepancy", "--design", str(DESIGNS / "twin_tube.yaml"), "--measured", str(meas), "--out",
                     str(out), "--profile", "ci", "--workers", "1"]) == 0
    import json

    v = json.loads((out / "verdict.json").read_text())
    assert v["verdict"] == "none"
    assert load(out / "design.yaml").architecture == "twin_tube"


@pytest.mark.parametrize("name", ["twin_tube", "mono_tube"])
@pytest.mark.parametrize("effect", ["oil_thermal", "gas_release"])
def test_a_passive_damper_writes_every_state_rate_with_an_effect_on(designs, name, effect):
    """An effect with states runs the extended model; the active valve's effect states (lag, spool,
    coil) have no valve on a passive damper and must still get a rate (0): the solver's rate vector is
    not cleared between calls, so an unwritten entry is whatever was in memory (NaN here)."""
    from dampertwin.model import layout as L
    from dampertwin.model.damper import RHS_BY_CFG
    from dampertwin.simulation import model_map

    d = designs[name]
    p = pack(d, 0.0, effects={effect: True})
    cfg = L.variant(L.CONFIGURATIONS["damper"], p)
    assert cfg == L.CFG_DAMPER_X
    ex = Excitation.sine(0.005, 13.0, 0.2)
    p[L.P.EX_T0], p[L.P.EX_DT] = ex.t0, ex.dt
    y = L.initial_state(p, cfg)
    dy, out = np.full(L.N_STATES[cfg], np.nan), np.zeros(L.N_OUT)
    RHS_BY_CFG[cfg](0.01, y, p, ex.array(), model_map(d.pq_map), dy, out)
    names = L.state_names(cfg)
    assert np.all(np.isfinite(dy)), [names[i] for i in range(len(dy)) if not np.isfinite(dy[i])]
    oe = L.N_STATES[L.CFG_DAMPER]
    assert all(dy[oe + k] == 0.0 for k in (L.EX.i_coil, L.EX.i_eff, L.EX.p_spool, L.EX.p_open))

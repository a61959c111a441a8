"""The truth's passive architectures (twin tube, mono tube with a floating
piston of mass and O-ring friction): volume balance, passivity, the mono
tube's rest force and floating-piston pressure, the twin tube without third
tube and active valve."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import ROOT
from dampertwin.design import load
from dampertwin.excitation import Excitation
from dampertwin.truth import fluid
from dampertwin.truth.part import build
from dampertwin.truth.run import simulate

DESIGNS = {a: ROOT / "conf" / "design" / f"{a}.yaml" for a in ("twin_tube", "mono_tube")}
AMP, FREQ = 0.015, 0.5  # [m], [Hz]: a slow stroke, peak 0.047 m/s


def _truth(arch, **effects):
    d = load(DESIGNS[arch])
    assert d.architecture == arch
    return build(d, d, {"effects": effects})


_RUNS: dict = {}


def _slow(arch):
    """A slow sine stroke (two cycles after a half-cycle ramp) with the gas
    dissolution and the oil's heating off: the oil's volume changes only by
    its compressibility."""
    if arch not in _RUNS:
        p, rest, v = _truth(arch, gas_dissolution=False, oil_thermal=False)
        ex = Excitation.sine(AMP, FREQ, 3.0 / FREQ, ramp=0.5 / FREQ)
        r = simulate(p, ex, "damper", rest=rest, rate=1000.0)
        assert r.ok, r.stats.message
        _RUNS[arch] = (p, rest, v, r)
    return _RUNS[arch]


@pytest.mark.parametrize("arch", DESIGNS)
def test_gas_takes_the_rods_volume_within_the_oils_compressibility(arch):
    """dV_gas = A_rod ds: the rod leaving the tube (s grows) makes room the
    gas fills; what the oil, its bubbles and the pressure tube's wall take by
    their compliance bounds the difference (Murnaghan tangent modulus, free
    gas g P_ref / P^2, Lame's wall)."""
    p, rest, v, r = _slow(arch)
    s, Vg = r["stroke [m]"], r["gas volume [m^3]"]
    A_rod = math.pi / 4 * v["D_R"] ** 2
    err = np.abs((Vg - Vg[0]) - A_rod * (s - s[0]))
    A_b = math.pi / 4 * v["chambers.D_PT"] ** 2
    kappa = fluid.lame_compliance(v["pt_r_i"], v["pt_r_o"], v["E"], v["nu_p"])
    bound = np.zeros_like(s)
    for key, V in (("p rebound [Pa]", (A_b - A_rod) * v["chambers.L_R0"]), ("p compression [Pa]",
                                                                              A_b * v["chambers.L_C0"])):
        P = r[key]
        K = v["oil.K0"] + v["oil.K1"] * (P.min() - v["oil.P_REF"])
        c = 1.0 / K + kappa + v["alpha_free"] * v["oil.P_REF"] / P.min() ** 2
        bound += 1.15 * V * c * np.abs(P - P[0])  # 1.15: the chambers' volume over the stroke, rounding
    assert bound.max() < 0.25 * A_rod * AMP  # tight enough to see a part sweeping the wrong area
    assert np.all(err <= bound + 0.01 * A_rod * AMP)
    assert np.ptp(Vg) > 1.8 * A_rod * AMP * 0.95


@pytest.mark.parametrize("arch", DESIGNS)
def test_energy_into_the_damper_over_a_steady_cycle_is_positive_and_dissipated(arch):
    """Passivity: the work F ds into the damper over the last full cycle is
    > 0 and equals the dissipated power's integral (valves, seal, band,
    floating piston, gas heat exchange) within 0.1 %."""
    p, rest, v, r = _slow(arch)
    t = r.time
    last = t >= t[-1] - 1.0 / FREQ
    W = np.trapezoid(r["rod force [N]"][last], r["stroke [m]"][last])
    D = np.trapezoid(r["dissipated power [W]"][last], t[last])
    assert W > 0
    assert W == pytest.approx(D, rel=1e-3)  # balanced to ~3e-4 (the floating piston O-ring: ~1.3e-3)


def test_mono_tube_at_rest_the_gas_pushes_the_rod_out():
    """At rest the rod force is -(P_gas0 - P_atm) A_rod (tension positive:
    the gas pushes the rod out), the compression chamber at the gas pressure."""
    p, rest, v = _truth("mono_tube")
    ex = Excitation(0.0, 1e-3, np.zeros(201), np.zeros(201))
    r = simulate(p, ex, "damper", rest=rest, rate=1000.0)
    assert r.ok
    A_rod = math.pi / 4 * v["D_R"] ** 2
    F0 = -(rest["P0"] - v["oil.P_ATM"]) * A_rod
    assert r["rod force [N]"][-1] == pytest.approx(F0, rel=2e-3)
    assert r["p compression [Pa]"][-1] == pytest.approx(r["p reserve [Pa]"][-1], abs=v["floating.F0"] / (
        math.pi / 4 * v["chambers.D_PT"] ** 2))


def test_mono_tube_gas_is_alone_behind_the_floating_piston_as_built():
    """As built (the gas chamber's volume off its drawing) the mono tube's gas
    fills its whole chamber at the precharge: no reserve oil, nothing dissolved."""
    from dampertwin.truth import gas as gs
    from dampertwin.truth import params as tp
    from dampertwin.truth.layout import SO
    from dampertwin.truth.run import _rest_damper

    d = load(DESIGNS["mono_tube"])
    p, rest, v = build(d, d, {}, as_built_seed=tp.as_built_seed(5))
    V = p[tp.index("gas.V_TOT")]
    assert V != rest["V_gas0"]
    y = _rest_damper(p, "damper", 0.0, rest["T"], rest["P0"], rest["V_gas0"])
    g = SO["gas"]
    assert y[g + gs.M_RES] == 0.0 and y[g + gs.C] == 0.0
    assert y[g + gs.M_G] * v["gas.R_S"] * rest["T"] / V == pytest.approx(rest["P0"], rel=1e-12)


def test_mono_tube_compression_pressure_follows_the_gas_within_the_floating_pistons_friction():
    """The floating piston (mass M, O-ring slip force F0 and film C_V) holds
    P_c - P_g within (F0 + C_V |v| + M |a|) / A; sliding, the difference
    reaches the friction's level (the model's piston is frictionless)."""
    p, rest, v, r = _slow("mono_tube")
    A = math.pi / 4 * v["chambers.D_PT"] ** 2
    x = r["floating piston position [m]"]
    t = r.time
    vel = np.gradient(x, t)
    acc = np.gradient(vel, t)
    dp = r["p compression [Pa]"] - r["p reserve [Pa]"]
    lim = (v["floating.F0"] + v["floating.C_V"] * np.abs(vel) + v["floating.M"] * np.abs(acc)) / A
    assert np.all(np.abs(dp) <= 1.02 * lim + 100.0)
    sliding = np.abs(vel) > 1e-3
    assert sliding.any() and np.abs(dp[sliding]).max() > 0.8 * v["floating.F0"] / A
    A_rod = math.pi / 4 * v["D_R"] ** 2
    s = r["stroke [m]"]
    assert np.abs((x - x[0]) + A_rod / A * (s - s[0])).max() < 0.2 * A_rod / A * AMP  # it moves with the rod


def test_twin_tube_has_no_third_tube_and_no_active_valve():
    """No flow through a bypass or an active valve, no third-tube or control
    chamber: every output finite with those parts' parameters NaN (not built),
    and the coil current changes nothing (bit for bit)."""
    p, rest, v = _truth("twin_tube")
    from dampertwin.truth import params as tp
    assert math.isnan(p[tp.index("active_valve.K_M")]) and math.isnan(p[tp.index("chambers.V_B")])
    ex = Excitation.sine(0.01, 3.0, 0.7, ramp=0.3)
    runs = [simulate(p, ex, "damper", current=i, rest=rest, rate=2000.0) for i in (0.0, 1.5)]
    for r in runs:
        assert r.ok
        for k, x in r.channels.items():
            assert np.all(np.isfinite(x)), k
        assert not np.any(r["flow bypass [m^3/s]"]) and not np.any(r["flow active valve [m^3/s]"])
        assert not np.any(r["p third tube [Pa]"])
        assert np.abs(r["flow base [m^3/s]"]).max() > 1e-6  # the base valves work
    assert np.array_equal(runs[0]["rod force [N]"], runs[1]["rod force [N]"])


def test_mono_tube_has_no_base_valves():
    p, rest, v = _truth("mono_tube")
    ex = Excitation.sine(0.01, 3.0, 0.7, ramp=0.3)
    r = simulate(p, ex, "damper", rest=rest, rate=2000.0)
    assert r.ok
    assert not np.any(r["flow base [m^3/s]"]) and not np.any(r["lift base_compression [m]"])
    assert np.abs(r["floating piston position [m]"]).max() > 1e-4


# --- the lab's passive samples ----------------------------------------------------------------------------

SAMPLES = {a: ROOT / "conf" / "lab" / f"{a}_sample.yaml" for a in DESIGNS}


@pytest.mark.parametrize("arch", DESIGNS)
def test_passive_samples_plan_only_what_a_passive_damper_can_run(arch):
    from dampertwin import lab

    s = lab.load_sample(SAMPLES[arch])
    nominal = load(lab._nominal_path(ROOT / "conf", s))
    assert nominal.architecture == arch
    lab.check_sample(s, nominal)
    items = lab.plan(ROOT / "conf", architecture=arch)
    assert {t for t, _ in items} == {"flowbench", "compliance", "curving", "dyno"}
    assert ("flowbench", "base_intake") in items if arch == "twin_tube" else ("flowbench", "base_intake") not in items
    with pytest.raises(lab.LabError, match="monosine"):
        lab.measure_case(ROOT / "conf", s, nominal, "monosine", "baseline_1.6", 0)


def test_mono_sample_records_are_synthetic_at_zero_current(tmp_path):
    from dampertwin.io import read_meta
    from dampertwin.lab import run_lab
    from dampertwin.lab_passive import measure_excitation

    (path,) = run_lab(SAMPLES["mono_tube"], tmp_path, seed=1, only=[("compliance", "baseline")], progress=False,
                      conf=ROOT / "conf", workers=1)
    meta = read_meta(path)
    assert meta["synthetic"] is True and meta["architecture"] == "mono_tube" and "SYNTHETIC" in meta["note"]
    import pandas as pd

    df = pd.read_parquet(path)
    assert set(df["run"]) == {"v0.4_I0", "v0.8_I0", "v1.2_I0", "v1.6_I0", "v2_I0"}
    assert not df["current [A]"].any()
    ex = Excitation.sine(0.01, 2.0, 0.6, ramp=0.25)
    a, ma = measure_excitation(SAMPLES["mono_tube"], ex, name="dyno_2Hz", rate=1000.0, seed=4, current=1.2)
    b, _ = measure_excitation(SAMPLES["mono_tube"], ex, name="dyno_2Hz", rate=1000.0, seed=4)
    assert ma["synthetic"] is True and ma["architecture"] == "mono_tube"
    pd.testing.assert_frame_equal(a, b)  # reproducible; no coil: the current does not act
    assert {"displacement [m]", "force [N]"} <= set(a.columns)
    assert a["force [N]"].min() < -200.0  # the gas pushes the rod out (~ -300 N at rest)

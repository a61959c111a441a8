"""The model core: declarations -> layout, probed sparsity, compile cache,
a hand-derived steady state, and parameter checks that name the design key."""

from __future__ import annotations

import faulthandler
import inspect
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from numba.core.registry import CPUDispatcher
from scipy.optimize import brentq

from dampertwin import Excitation, simulate, simulate_batch
from dampertwin.design import load
from dampertwin.jit import LazyDispatcher
from dampertwin.model import cache_sources, layout as L
from dampertwin.model.active_valve import pack_map
from dampertwin.model.damper import RHS
from dampertwin.model.params import pack
from dampertwin.model.sparsity import pattern, probe_states
from dampertwin.model.valves import V, V_SIZE, shim_pressure_force, stiffness_force
from dampertwin.solver import OK, Sparsity, fd_jacobian

from conftest import BASELINE, ROOT

MODEL = ROOT / "src" / "dampertwin" / "model"


@pytest.fixture(scope="module")
def base():
    return load(BASELINE)


def test_layout_is_derived_from_the_submodel_declarations():
    from dampertwin.model import chambers, rod, rod_friction, top_mount, valves
    assert L.N_DAMPER == len(chambers.STATES) + 10 + len(rod_friction.STATES)  # 4 valves x (x, v) + 2 Dahl
    assert L.N_MODULE == L.N_DAMPER + len(rod.STATES) + len(top_mount.STATES)
    assert [s.name for s in L.STATES[L.CFG_MODULE]] == list(L.S.__members__)
    np.testing.assert_array_equal(L.state_scales(L.CFG_MODULE), [s.scale for s in L.STATES[L.CFG_MODULE]])
    assert L.N_PARAMS == len(L.PARAMETERS) + 4 * len(valves.VALVE_PARAMETERS)
    assert int(L.P.VALVES) == len(L.PARAMETERS)


def test_no_globals_made_constants_in_the_model():
    for f in MODEL.glob("*.py"):
        assert "globals()" not in f.read_text(), f


def test_initial_state_is_the_declared_rest_state(base):
    p = pack(base, 1.6)
    y0 = L.initial_state(p, L.CFG_MODULE)
    assert y0[L.S.P_r] == y0[L.S.P_c] == y0[L.S.P_b] == base["oil.P_0"]
    assert y0[L.S.V_g] == base.constant("V_gas0")
    for valve in ("piston_rebound", "piston_intake", "base_compression", "base_intake"):
        x = y0[L.S[f"x_{valve}"]]
        assert x < 0  # seated: the seat contact holds the preload
        blk = p[L.P.VALVES + ("piston_rebound", "piston_intake", "base_compression", "base_intake").index(valve) * V_SIZE:][:V_SIZE]
        assert p[L.P.K_C] * (-x) == pytest.approx(stiffness_force(x, blk[V.PRE], blk[V.A], blk[V.B], blk[V.CC], blk[V.D]),
                                                   rel=1e-9)


@pytest.mark.parametrize("configuration", ["valve", "damper", "module", "topmount"])
def test_probed_sparsity_is_a_superset_of_the_true_pattern(base, configuration):
    """Full finite-difference Jacobians at random states (another seed than the
    probe's, wider spread) and along a simulated trajectory never show a
    dependency outside the probed pattern."""
    cfg = L.CONFIGURATIONS[configuration]
    rhs = RHS[configuration]
    kw = {"bench_valve": "piston_rebound"} if configuration == "valve" else {}
    p = pack(base, 1.6, **kw)
    ex = (Excitation.constant_rate(2e-4, 0.2, kind="flow") if configuration == "valve"
          else Excitation.sine(0.005, 13.0, 0.2))
    p[L.P.EX_T0], p[L.P.EX_DT] = ex.t0, ex.dt
    aux = pack_map(base.pq_map.currents, base.pq_map.dps, base.pq_map.flow)
    J = pattern(rhs, cfg, p[None], ex.array(), aux, (0.0, 0.2))
    rng = np.random.default_rng(12345)
    Y = probe_states(p, cfg, 150, rng)
    if configuration in ("damper", "module"):
        r = simulate(base, ex, configuration)
        assert r.ok
    n = Y.shape[1]
    sc = L.state_scales(cfg)
    dense = Sparsity.dense(n)
    for y in Y:
        jac, ft = np.zeros((n, n)), np.zeros(n)
        fd_jacobian(rhs, rng.uniform(0, 0.2), y / sc, sc, p, ex.array(), aux, *dense.args(), jac, ft, L.N_OUT)
        nz = np.isfinite(jac) & (jac != 0)
        assert not np.any(nz & ~J), [(L.state_names(cfg)[i], L.state_names(cfg)[j]) for i, j in zip(*np.nonzero(nz & ~J))]
    assert J.sum() < n * n or n <= 4  # the damper's pattern is sparse


def _reachable_files(fn, seen):
    """Source files of every compiled function reachable from dispatcher fn."""
    if id(fn) in seen:
        return set()
    seen.add(id(fn))
    py = fn.py_func
    files = {Path(inspect.getsourcefile(py)).resolve()}
    for name in py.__code__.co_names:
        g = py.__globals__.get(name)
        if isinstance(g, (CPUDispatcher, LazyDispatcher)):
            files |= _reachable_files(g, seen)
    return files


def test_compile_cache_key_covers_every_file_the_compiled_code_uses():
    from dampertwin import solver
    files = set()
    for fn in list(RHS.values()) + [solver.rodas4, solver.ros34pw2, solver.step_chunk, solver._batch_chunk]:
        files |= _reachable_files(fn, set())
    covered = {f.resolve() for f in cache_sources()}
    assert files <= covered, files - covered
    assert len(files) >= 8  # the walk really followed calls into the submodels


def test_flow_bench_steady_state_matches_the_hand_force_balance(base):
    """Piston rebound valve on the flow bench at a constant 20 l/min, slot and
    Cq(lambda) off: at steady state the lift x solves the force balance
    F_k(x) = pi/12 (D_d - D_i)(2 D_d + D_i) dp with dp from the orifice law
    Q = (Cq pi D_d x + Cq_b A_b) sqrt(2 dp / rho) (eq. 4.19, 4.21, 4.27, 4.29),
    solved here by brentq."""
    Q = 20.0 / 60000.0
    eff = {"jet_force": False, "shim_friction": False, "flow_number_cq": False, "slot_restriction": False,
           "cavitation": False}
    r = simulate(base, Excitation.constant_rate(Q, 0.5, kind="flow"), "valve", bench_valve="piston_rebound",
                 effects=eff, h_max=0.01)
    assert r.ok
    g = base.group("piston_rebound")
    rho = base["oil.rho_oil"]
    p_tr = base.constant("p_transition")

    def dp_of(x):  # invert Q = G sqrt(2/rho) dp / (dp^2 + p_tr^2)^(1/4)
        G = g["Cq_max"] * math.pi * g["D_d"] * x + g["Cq_bleed"] * g["A_bleed"]
        return brentq(lambda dp: G * math.sqrt(2 / rho) * dp / (dp * dp + p_tr * p_tr) ** 0.25 - Q, 1.0, 1e9)

    def balance(x):
        return shim_pressure_force(dp_of(x), g["D_d"], g["D_i"]) - stiffness_force(
            x, g["F_preload"], g["a"], g["b"], g["c"], g["d"])

    x_hand = brentq(balance, 1e-9, base.constant("x_max_piston_rebound"))
    x_sim = r["lift [m]"][-1]
    dp_sim = r["dp [Pa]"][-1]
    assert x_sim == pytest.approx(x_hand, rel=2e-3)
    assert dp_sim == pytest.approx(dp_of(x_hand), rel=2e-3)


_SLOTS = {"piston_rebound.m_v": lambda: L.P.VALVES + V.M, "base_intake.m_v": lambda: L.P.VALVES + 3 * V_SIZE + V.M,
          "geometry.M_rod": lambda: L.P.M_ROD, "oil.rho_oil": lambda: L.P.RHO, "D_R": lambda: L.P.A_R}


def _poison(monkeypatch, which, key, value):
    """Make pack() return ``value`` in the slot of ``key`` for the designs in
    ``which``: the solver-side safety net, whatever the design loader accepts."""
    import dampertwin.simulation as sim
    real = sim.pack

    def fake(design, *a, **k):
        p = real(design, *a, **k)
        if any(design is w for w in which):
            p[_SLOTS[key]()] = value
        return p

    monkeypatch.setattr(sim, "pack", fake)


@pytest.mark.parametrize("key,value,configuration", [
    ("piston_rebound.m_v", 0.0, "valve"),
    ("base_intake.m_v", 0.0, "module"),
    ("geometry.M_rod", 0.0, "module"),
    ("geometry.M_rod", -1.0, "module"),
    ("oil.rho_oil", -850.0, "damper"),
    ("D_R", -1e-4, "damper"),
    ("oil.rho_oil", float("nan"), "module"),
])
def test_unusable_parameters_are_named_not_divided_by(base, monkeypatch, key, value, configuration):
    _poison(monkeypatch, [base], key, value)
    ex = (Excitation.constant_rate(1e-4, 0.05, kind="flow") if configuration == "valve"
          else Excitation.sine(0.005, 13.0, 0.05))
    kw = {"bench_valve": "piston_rebound"} if configuration == "valve" else {}
    with pytest.raises(ValueError, match=re.escape(key)):
        simulate(base, ex, configuration, **kw)


@pytest.mark.parametrize("configuration", ["valve", "module"])
def test_batch_with_an_invalid_member_scores_the_rest(base, monkeypatch, configuration):
    """A member with a zero valve mass is marked invalid; the others run as
    alone. Hang guard: the process dumps its stack after 300 s."""
    faulthandler.dump_traceback_later(300, exit=True)
    try:
        bad = base.with_overrides({"piston_rebound.c_v": base["piston_rebound.c_v"] * 1.01})
        _poison(monkeypatch, [bad], "piston_rebound.m_v", 0.0)
        ex = (Excitation.constant_rate(1e-4, 0.05, kind="flow") if configuration == "valve"
              else Excitation.sine(0.005, 13.0, 0.05))
        kw = {"bench_valve": "piston_rebound"} if configuration == "valve" else {}
        t, ch, status = simulate_batch([base, bad, base], ex, configuration, **kw)
        assert status[0] == OK and status[2] == OK and status[1] != OK
        col = next(iter(ch))
        assert np.isnan(ch[col][1]).all()
        single = simulate(base, ex, configuration, **kw)
        np.testing.assert_array_equal(ch[col][0], single[col])
    finally:
        faulthandler.cancel_dump_traceback_later()


def test_a_failed_run_warns_when_framed(base):
    r = simulate(base, Excitation.sine(0.005, 13.0, 0.2), "module", max_steps=20)
    assert not r.ok
    with pytest.warns(RuntimeWarning, match="step cap"):
        r.to_frame()


def test_the_hub_reads_only_the_chamber_states_and_parameters():
    """damper.py (the volume balances) names only the chambers' / fluid's /
    inputs' / bench's own parameters and the chambers' states: every other
    submodel reads its own parameters and states, so adding one to it touches
    its file and the design description only."""
    from dampertwin.model import bench, chambers, fluid, inputs
    src = (MODEL / "damper.py").read_text()
    own_params = {d.name for m in (chambers, fluid, inputs, bench) for d in m.PARAMETERS}
    used_params = set(re.findall(r"\bP\.(\w+)", src))
    assert used_params and used_params <= own_params, used_params - own_params
    used_states = set(re.findall(r"\bS\.(\w+)", src))
    assert used_states <= {s.name for s in chambers.STATES}, used_states


def test_sparsity_cache_tells_the_flow_bench_valves_apart(base):
    """The flow bench's valve selector changes the equations (intake valves
    and shim valves have other states): a probe cached for one valve must not
    serve another. Same result with a fresh cache as after another valve's run."""
    from dampertwin import simulation
    from dampertwin.protocols import build_runs, load_protocol

    fb = load_protocol(ROOT / "conf" / "test" / "flowbench.yaml")
    bench = {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}
    runs = {r.bench_valve: r for r in build_runs(fb)}

    def run(valve):
        r = runs[valve]
        return simulate(base, r.excitation, "valve", bench_valve=valve, rate=r.rate, bench=bench, rtol=1e-6,
                        duration=0.5)

    simulation._SPARSITY_CACHE.clear()
    fresh = run("base_compression")
    simulation._SPARSITY_CACHE.clear()
    run("piston_intake")
    after = run("base_compression")
    assert fresh.ok and after.ok
    assert np.array_equal(fresh["dp [Pa]"], after["dp [Pa]"])


@pytest.mark.parametrize("module", ["dampertwin.solver", "dampertwin.truth", "dampertwin.model"])
def test_every_compiled_package_uses_the_hashed_cache_folder(module):
    """Importing only the solver (or only the truth) must still put numba's cache in the folder named
    after the hash of every compiled source: numba's own per-file cache keeps the machine code of a
    caller when a callee in another file changes (a stale step loop after a solver_*.py edit)."""
    import subprocess
    import sys

    from dampertwin.numba_cache import cache_dir

    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    code = f"import {module}, numba; print(numba.config.CACHE_DIR)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert r.stdout.strip() == cache_dir()

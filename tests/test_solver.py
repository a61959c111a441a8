"""The compiled integrator: order, caps, batch, Jacobian sparsity."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dampertwin import Excitation
from dampertwin.design import load
from dampertwin.model import layout as L
from dampertwin.model.damper import evaluate
from dampertwin.model.params import initial_state, pack
from dampertwin.model.sparsity import colouring, pattern
from dampertwin.solver import MAX_STEPS, OK, WALL_TIME, integrate, integrate_batch

from conftest import BASELINE

NO_MAP = (np.zeros(2), np.array([0.0, 1.0]), np.zeros((2, 2)))


def _test_problem(lam, w, rtol, t_end=1.0):
    p = np.zeros(L.N_PARAMS)
    p[0], p[1] = lam, w
    t_out = np.linspace(0.0, t_end, 201)
    out, _, st = integrate(p, np.zeros((2, 2)), NO_MAP, L.CFG_SOLVER_TEST, np.array([0.0, 1.0, 0.0]), t_out,
                           rtol=rtol, h_max=1.0)
    err_pr = np.max(np.abs(out[:, 0] - np.sin(t_out)))
    err_osc = np.max(np.abs(out[:, 1] - np.cos(w * t_out)))
    return err_pr, err_osc, st


def test_fourth_order_convergence_on_oscillator():
    """Rodas4 is order 4: at fixed tolerance per step the step count grows
    like tol^(-1/4); global error tracks the tolerance."""
    w = 2 * math.pi * 5
    steps, errs = [], []
    for tol in (1e-4, 1e-6, 1e-8):
        _, e, st = _test_problem(1.0, w, tol)
        assert st.ok
        steps.append(st.steps)
        errs.append(e)
    slope = math.log(steps[2] / steps[0]) / math.log(1e4)  # steps ~ tol^-slope
    assert 0.18 < slope < 0.35, (steps, slope)
    assert errs[0] > 30 * errs[2]  # error falls with the tolerance


def test_stiff_prothero_robinson_is_stable_and_accurate():
    """Stiffness up to 1e9 neither forces tiny steps (L-stability) nor spoils
    the answer; the error bound allows the known order reduction of
    Rosenbrock methods on this problem (Hairer & Wanner IV.15)."""
    for lam in (1e2, 1e6, 1e9):
        e, _, st = _test_problem(lam, 1.0, 1e-6)
        assert st.ok and e < 1e-4, (lam, e)
        assert st.steps < 400


def _mono_args(duration):
    """integrate() arguments of the baseline module on a 13 Hz mono-sine."""
    d = load(BASELINE)
    p = pack(d, 1.6)
    ex = Excitation.sine(0.005, 13.0, duration)
    p[L.P_EX_T0], p[L.P_EX_DT] = ex.t0, ex.dt
    t_out = np.arange(0, duration + 1e-9, 1e-4)
    return (p, ex.array(), (d.pq_map.currents, d.pq_map.dps, d.pq_map.flow), L.CFG_MODULE,
            initial_state(p, L.CFG_MODULE), t_out)


def test_step_cap_ends_run_with_status_and_nan_tail():
    out, _, st = integrate(*_mono_args(0.2), max_steps=50)
    assert st.status == MAX_STEPS and not st.ok
    assert np.isnan(out[-1]).all() and np.isfinite(out[0]).all()


def test_wall_cap_ends_run_with_status():
    out, _, st = integrate(*_mono_args(0.5), max_wall_s=0.0, chunk_s=0.01)
    assert st.status == WALL_TIME
    assert np.isnan(out[-1]).all()


def test_pausing_does_not_change_results():
    args = _mono_args(0.15)
    a, _, _ = integrate(*args)
    b, _, _ = integrate(*args, max_wall_s=1e6, chunk_s=0.007)
    np.testing.assert_array_equal(a, b)


def test_batch_equals_single_runs_and_isolates_failures():
    d = load(BASELINE)
    ex = Excitation.sine(0.005, 13.0, 0.1)
    pq = (d.pq_map.currents, d.pq_map.dps, d.pq_map.flow)
    ps = []
    for a in (200.0, 300.0, 600.0):
        p = pack(d.with_overrides({"piston_rebound.a": a}), 1.6)
        p[L.P_EX_T0], p[L.P_EX_DT] = ex.t0, ex.dt
        ps.append(p)
    bad = ps[1].copy()
    bad[L.P_M_ROD] = -1.0  # negative rod mass: the run blows up
    P = np.vstack(ps + [bad])
    Y0 = np.vstack([initial_state(p, L.CFG_MODULE) for p in P])
    t_out = np.arange(0, 0.1 + 1e-9, 1e-4)
    OUT, status, _ = integrate_batch(P, ex.array(), pq, L.CFG_MODULE, Y0, t_out, max_steps=20000)
    assert list(status[:3]) == [OK, OK, OK] and status[3] != OK
    for b in range(3):
        single, _, _ = integrate(P[b], ex.array(), pq, L.CFG_MODULE, Y0[b], t_out)
        np.testing.assert_array_equal(OUT[b], single)


@pytest.mark.parametrize("cfg", [L.CFG_DAMPER, L.CFG_MODULE])
def test_declared_sparsity_covers_the_jacobian(cfg):
    """Finite-difference Jacobians probed along a mono-sine trajectory have no
    non-zero outside the declared pattern (else the coloured Jacobian would
    be wrong)."""
    d = load(BASELINE)
    p = pack(d, 1.6)
    ex = Excitation.sine(0.005, 13.0, 0.2)
    p[L.P_EX_T0], p[L.P_EX_DT] = ex.t0, ex.dt
    pq = (d.pq_map.currents, d.pq_map.dps, d.pq_map.flow)
    J = pattern(cfg)
    n = L.N_STATES[cfg]
    rng = np.random.default_rng(1)
    y0 = initial_state(p, cfg)
    out = np.empty(L.N_OUT)
    for _ in range(40):
        # states near rest and with valves open / pressures spread
        y = y0.copy()
        y[:4] *= 1 + 0.5 * rng.standard_normal(4) * (np.arange(4) < 3)
        for k in range(4):
            y[L.S_X0 + 2 * k] = rng.uniform(-5e-6, 2e-4)
            y[L.S_X0 + 2 * k + 1] = rng.normal(0, 0.1)
        y[L.S_DAHL_PR:L.S_Z + 1] = rng.normal(0, [5.0, 5.0, 1e-5])
        if cfg == L.CFG_MODULE:
            y[L.S_VROD] = rng.normal(0, 0.1)
            y[L.S_TMX:] = rng.normal(0, 1e-4, 3)
        t = rng.uniform(0.02, 0.2)
        f0 = np.empty(n)
        evaluate(t, y, p, ex.array(), *pq, cfg, f0, out)
        for j in range(n):
            yj = y.copy()
            yj[j] += 1e-7 * max(abs(y[j]), 1e-6)
            f1 = np.empty(n)
            evaluate(t, yj, p, ex.array(), *pq, cfg, f1, out)
            nz = np.flatnonzero(f1 != f0)
            assert J[nz, j].all(), (j, [i for i in nz if not J[i, j]])
    colour, nc, _, _ = colouring(J)
    assert nc < n  # the colouring saves evaluations
    for c in range(nc):
        cols = np.flatnonzero(colour == c)
        assert (J[:, cols].sum(axis=1) <= 1).all()  # no two columns of a colour share a row

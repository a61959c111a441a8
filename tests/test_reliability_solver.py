"""Issue 13, solver side: bad members of a batch must not hang or take the
population down, and degenerate designs must fail with a named parameter.
The designs bypass the loader's range checks (which now reject them) to
reach the solver directly. Each case runs in a subprocess with a timeout, so
a hang can never stall CI."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from conftest import BASELINE, ROOT

TIMEOUT_S = 240  # generous: includes numba compilation on a cold cache

PRELUDE = f"""
import dataclasses, math, sys
from types import MappingProxyType
import numpy as np
from dampertwin.design import load
from dampertwin.excitation import Excitation
from dampertwin.simulation import simulate, simulate_batch

BASE = load({str(BASELINE)!r})

def raw(d, **values):
    '''The design with values set WITHOUT validation (as a solver input).'''
    params = dict(d.parameters)
    for key, v in values.items():
        p = d.param(key.replace('__', '.'))
        params[p.no] = dataclasses.replace(p, value=v)
    return dataclasses.replace(d, parameters=MappingProxyType(params))
"""

def run(body: str) -> subprocess.CompletedProcess:
    code = PRELUDE + textwrap.dedent(body)
    try:
        return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                              timeout=TIMEOUT_S, env=dict(os.environ, MPLBACKEND="Agg"))
    except subprocess.TimeoutExpired:
        pytest.fail(f"hung for more than {TIMEOUT_S} s")


def test_valve_batch_with_a_zero_mass_member_does_not_hang():
    r = run("""
        ex = Excitation.constant_rate(2e-4, 0.5, kind="flow")
        ds = [BASE, raw(BASE, piston_rebound__m_v=0.0), BASE]
        _, _, status = simulate_batch(ds, ex, "valve", bench_valve="piston_rebound", rate=1000.0, max_wall_s=60)
        assert status[0] == 0 and status[2] == 0 and status[1] != 0, status
    """)
    assert r.returncode == 0, r.stderr[-3000:]


def test_module_batch_with_a_zero_mass_member_scores_the_others():
    r = run("""
        ex = Excitation.sine(amplitude=0.005, frequency=13.0, duration=0.1)
        ds = [BASE, raw(BASE, piston_rebound__m_v=0.0)]
        _, _, status = simulate_batch(ds, ex, "module", current=1.6, rate=5000.0, max_wall_s=120)
        assert status[0] == 0 and status[1] != 0, status
    """)
    assert r.returncode == 0, r.stderr[-3000:]


@pytest.mark.parametrize("values, name", [
    ("geometry__M_rod=0.0", "M_rod"),
    ("piston_rebound__m_v=0.0", "m_v"),
    ("geometry__D_R=0.032", "D_R"),
])
def test_degenerate_design_fails_naming_the_parameter(values, name):
    r = run(f"""
        ex = Excitation.sine(amplitude=0.005, frequency=13.0, duration=0.05)
        try:
            res = simulate(raw(BASE, {values}), ex, "module", current=1.6, rate=5000.0, max_wall_s=60)
        except ZeroDivisionError as e:
            sys.exit("bare ZeroDivisionError: " + str(e))
        except Exception as e:
            assert {name!r} in str(e), str(e)
        else:
            assert not res.ok and {name!r} in res.stats.message, res.stats.message
    """)
    assert r.returncode == 0, r.stderr[-3000:]


@pytest.mark.parametrize("values", ["geometry__M_rod=-0.85", "oil__rho_oil=-850.0"])
def test_nan_result_is_never_silent(values):
    r = run(f"""
        import warnings
        ex = Excitation.sine(amplitude=0.005, frequency=13.0, duration=0.05)
        try:
            res = simulate(raw(BASE, {values}), ex, "module", current=1.6, rate=5000.0, max_wall_s=60)
        except Exception:
            sys.exit(0)  # refused: fine
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            df = res.to_frame()
        nan = df.isna().any().any()
        assert not nan or (not res.ok and w), "NaN result without a warning"
    """)
    assert r.returncode == 0, r.stderr[-3000:]

"""Reference path: the *same* model equations (the same source code, run as
plain Python with numba disabled) under another integrator,
``scipy.integrate.solve_ivp(method="BDF")``.

What it checks: the compiled Rodas4 integrator, its coloured Jacobian, dense
output and step control, and the numba compilation itself. What it cannot
check: the equations, since both paths run them (the submodel tests against
analytic cases and hand-derived balances do that). It is also the naive
baseline of the solver benchmark. Numba cannot be switched off inside a
process that has compiled the model, so unless ``NUMBA_DISABLE_JIT=1`` is
already set, the run happens in a child process that has it set.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .design import Design
from .excitation import Excitation
from .simulation import Result, _channels, _setup, _time_grid
from .solver import OK, STATUS_TEXT, RunStats


def _solve(p, ex, aux, configuration, y0, t_out, rtol, atol_scale):
    """Integrate with scipy BDF; returns (outputs[n_t, N_OUT], nfev, status)."""
    from scipy.integrate import solve_ivp

    from .model.damper import RHS_BY_CFG
    from .model.layout import CONFIGURATIONS, N_OUT, variant

    evaluate = RHS_BY_CFG[variant(CONFIGURATIONS[str(configuration)], p)]  # extended when an effect with states is on
    n = len(y0)
    dy = np.empty(n)
    scratch = np.empty(N_OUT)

    def rhs(t, y):
        d = np.empty(n)
        evaluate(t, np.ascontiguousarray(y), p, ex, aux, d, scratch)
        return d

    sol = solve_ivp(rhs, (t_out[0], t_out[-1]), y0, method="BDF", t_eval=t_out, rtol=rtol,
                    atol=rtol * atol_scale, max_step=1e-3)
    out = np.full((len(t_out), N_OUT), np.nan)
    for i in range(sol.y.shape[1]):
        evaluate(sol.t[i], np.ascontiguousarray(sol.y[:, i]), p, ex, aux, dy, out[i])
    return out, sol.nfev, sol.status


def _child(inp: str, outp: str) -> None:
    a = np.load(inp)
    t0 = time.perf_counter()
    out, nfev, status = _solve(a["p"], a["ex"], a["aux"], str(a["configuration"]), a["y0"], a["t_out"],
                               float(a["rtol"]), a["atol_scale"])
    wall = time.perf_counter() - t0
    tmp = outp + ".tmp.npz"
    np.savez(tmp, out=out, nfev=nfev, status=status, wall=wall)
    os.replace(tmp, outp)


def simulate_reference(design: Design, excitation: Excitation, configuration: str = "module", *,
                       current: float = 1.6, effects: dict | None = None, bench_valve: str | None = None,
                       rate: float = 10_000.0, duration: float | None = None, rtol: float = 1e-6,
                       timeout_s: float = 3600.0) -> Result:
    """Same interface as :func:`dampertwin.simulate`, reference integrator.
    ``result.stats.wall_s`` is the integration time inside the child process."""
    from .model.layout import initial_state, state_scales
    from .simulation import model_map

    cfg, p = _setup(design, excitation, configuration, current, effects, bench_valve)
    t_out = _time_grid(excitation, duration, rate)
    y0 = initial_state(p, cfg)
    arrays = dict(p=p, ex=excitation.array(), aux=model_map(design.pq_map), configuration=configuration,
                  y0=y0, t_out=t_out, rtol=rtol, atol_scale=state_scales(cfg))
    from numba import config as nb_config

    if nb_config.DISABLE_JIT:
        t0 = time.perf_counter()
        out, nfev, status = _solve(**arrays)
        wall = time.perf_counter() - t0
    else:
        with tempfile.TemporaryDirectory() as td:
            inp, outp = str(Path(td) / "in.npz"), str(Path(td) / "out.npz")
            np.savez(inp, **arrays)
            env = dict(os.environ, NUMBA_DISABLE_JIT="1")
            r = subprocess.run([sys.executable, "-m", "dampertwin.reference", inp, outp], env=env,
                               capture_output=True, text=True, timeout=timeout_s)
            if r.returncode != 0:
                raise RuntimeError(f"reference solver failed:\n{r.stderr[-3000:]}")
            res = np.load(outp)
            out, nfev, status, wall = res["out"], int(res["nfev"]), int(res["status"]), float(res["wall"])
    ok = status == 0
    stats = RunStats(OK if ok else -1, STATUS_TEXT[OK] if ok else "scipy BDF failed", 0, 0, 0, int(nfev), 0, wall)
    return Result(configuration, t_out, _channels(cfg, out), stats, design.hash(), current,
                  meta={"integrator": "scipy solve_ivp BDF, Python RHS"})


if __name__ == "__main__":
    _child(sys.argv[1], sys.argv[2])

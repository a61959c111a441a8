"""The inverse problem of issue 40 item 2, its pieces: factor parameters
applied to the nominal design, its cases and the random test; the thesis'
simulated cells as data; the sensitivity Jacobian in log-parameter space and
its singular value decomposition (what the cells determine); the
calibration core's Gauss-Newton (:mod:`dampertwin.calibration.optimisers`)
on the whitened residuals. Used by scripts/thesis_inverse.py and its test;
the simulations reuse scripts/thesis_comparison.py's KPI extraction
(``project_values``).

Scaled residual of a cell (so that |z| <= 1 is issue 40's target):
    peaks: z = (thesis - project) / (0.15 |thesis|)      (15 %)
    PSD:   z = (thesis - project) / 2 dB
Sensitivity of cell i to parameter j (factor theta_j, log range
[ln lo_j, ln hi_j]): S_ij = dz_i / d ln theta_j by forward differences;
range-scaled S~_ij = S_ij * (ln hi_j - ln lo_j) / 2, the change of z_i in
tolerance units when theta_j moves over half its plausible log range. The
SVD S~ = U diag(s) V^T (Golub & Van Loan, Matrix Computations, 4th ed.,
2013, 2.4) gives the parameter directions V_k the cells determine (s_k >
threshold: moving along V_k over the ranges changes the cells by more than
the tolerance) and those they do not; Fisher information in tolerance
units F = S^T S (Bard, Nonlinear Parameter Estimation, 1974, 7.5). The
subset fitted is picked by QR with column pivoting of S~ (Golub, Klema &
Stewart, Stanford TR STAN-CS-76-559, 1976), as many parameters as
determined directions.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "scripts") not in sys.path:
    sys.path.insert(0, str(ROOT / "scripts"))

import thesis_comparison as tc  # noqa: E402

TABLE_KEYS = {"6.5": "table_6_5", "6.6": "table_6_6", "7.1": "table_7_1", "7.2": "table_7_2"}
PEAK_TABLES = ("6.5", "7.1")
MAP_KEYS = ("dp_open_lo", "dp_open_hi", "a_pilot", "gain")


# ------------------------------------------------------------------ parameters
@dataclass(frozen=True)
class FactorParam:
    """A factor theta [-] on nominal values: design keys, ``map.<coef>`` or
    ``random.bands.<i>.rms``; searched on a log scale in [lo, hi]."""

    name: str
    keys: tuple
    lo: float
    hi: float
    offset: float = 0.0
    scale_variants: bool = True
    range: str = ""
    note: str = ""

    @property
    def half_log_range(self) -> float:
        return 0.5 * math.log(self.hi / self.lo)


def load_params(doc: dict, where: str) -> list[FactorParam]:
    """The ``parameters`` list of conf/thesis/inverse.yaml; errors name the file and entry."""
    out = []
    for i, p in enumerate(doc.get("parameters") or []):
        try:
            fp = FactorParam(str(p["name"]), tuple(p["keys"]), float(p["lo"]), float(p["hi"]),
                             float(p.get("offset", 0.0)), bool(p.get("scale_variants", True)),
                             str(p.get("range", "")), str(p.get("note", "")))
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"{where}: parameters[{i}]: {e!r}; expected name, keys, lo, hi") from e
        if not 0 < fp.lo < 1 < fp.hi:
            raise ValueError(f"{where}: parameters[{i}] ({fp.name}): bounds [{fp.lo}, {fp.hi}]; "
                             f"expected 0 < lo < 1 < hi (factors on the nominal value)")
        out.append(fp)
    if not out:
        raise ValueError(f"{where}: parameters: empty or missing; expected a list of name, keys, lo, hi entries")
    if len({p.name for p in out}) != len(out):
        raise ValueError(f"{where}: duplicated parameter names")
    return out


def _scale(v, theta: float, offset: float):
    if isinstance(v, (list, tuple)):
        return [offset + theta * (float(x) - offset) for x in v]
    return offset + theta * (float(v) - offset)


def case_overrides(base, variant_overrides: dict, params: list[FactorParam], theta: dict) -> dict:
    """Design overrides of one case at factors ``theta`` (name -> factor):
    each design key of a parameter scaled from the baseline's value, or
    from the case's own value when the case sets the key and the parameter
    scales variants (else the case's value is kept)."""
    out = {k: v for k, v in variant_overrides.items() if k != "active_valve.pq_map"}
    for p in params:
        t = float(theta.get(p.name, 1.0))
        for k in p.keys:
            if k.startswith(("map.", "random.")):
                continue
            if k in variant_overrides:
                out[k] = _scale(variant_overrides[k], t, p.offset) if p.scale_variants else variant_overrides[k]
            elif t != 1.0:
                out[k] = _scale(base[k], t, p.offset)
    return out


def map_coefficients(nominal: dict, params: list[FactorParam], theta: dict) -> dict:
    """The map generator's coefficients at factors ``theta`` (every map scaled alike)."""
    c = dict(nominal)
    for p in params:
        for k in p.keys:
            if k.startswith("map."):
                name = k.split(".", 1)[1]
                if name not in MAP_KEYS:
                    raise ValueError(f"parameter {p.name}: unknown map coefficient {name!r}; expected {MAP_KEYS}")
                c[name] = c[name] * float(theta.get(p.name, 1.0))
    return c


def random_protocol(proto: dict, params: list[FactorParam], theta: dict) -> dict:
    """The random test with its band levels scaled by the ``random.bands.<i>.rms`` factors."""
    bands = [dict(b) for b in proto["bands"]]
    for p in params:
        for k in p.keys:
            if k.startswith("random."):
                _, _, i, what = k.split(".")
                if what != "rms" or not 0 <= int(i) < len(bands):
                    raise ValueError(f"parameter {p.name}: key {k!r}; expected random.bands.<0..{len(bands) - 1}>.rms")
                bands[int(i)]["rms"] = bands[int(i)]["rms"] * float(theta.get(p.name, 1.0))
    return {**proto, "bands": bands}


# ------------------------------------------------------------------ cells
@dataclass(frozen=True)
class Cell:
    """One published simulated value: table ('6.5', ...), row no., column."""

    table: str
    no: int
    case: str
    column: str
    thesis: float

    @property
    def unit(self) -> str:
        return "%" if self.table in PEAK_TABLES else "dB"

    @property
    def sigma(self) -> float:
        """Tolerance of the cell in its own unit [g or dB]."""
        return tc.PCT_AGREE / 100.0 * abs(self.thesis) if self.unit == "%" else tc.DB_AGREE

    @property
    def label(self) -> str:
        return f"{self.table}/{self.no}/{self.column}"


def cells_of(pub: dict, tables=("6.5", "6.6", "7.1", "7.2"), cases=None) -> list[Cell]:
    """Every simulated cell of the tables (optionally only the ``cases``)."""
    out = []
    for t in tables:
        tab = pub[TABLE_KEYS[t]]
        cols = tc.HALVES if t in PEAK_TABLES else tc.FREQS
        for row in tab["rows"]:
            if cases is None or row["case"] in cases:
                out.extend(Cell(t, int(row["no"]), row["case"], c, float(row[c]["s"])) for c in cols)
    return out


def scaled_residual(cells: list[Cell], values: np.ndarray) -> np.ndarray:
    """z = (thesis - project) / tolerance per cell (|z| <= 1: within target)."""
    th = np.array([c.thesis for c in cells])
    return (th - np.asarray(values, float)) / np.array([c.sigma for c in cells])


def diffs(cells: list[Cell], values) -> list[float]:
    """The comparison page's differences: % of |thesis| for peaks, dB for PSD."""
    return [tc.pct_diff(v, c.thesis) if c.unit == "%" else tc.db_diff(v, c.thesis) for c, v in zip(cells, values)]


# ------------------------------------------------------------------ simulation
@dataclass
class Simulator:
    """Nominal design, cases, tests and map coefficients; ``values(theta,
    cells)`` simulates what the cells need (thesis_comparison's KPIs)."""

    pub: dict
    params: list
    maps: dict  # map file name -> generator coefficients
    count: int = 0  # simulation sets run
    _ctx: dict = field(default_factory=dict)

    def __post_init__(self):
        from dampertwin.design import load, yaml_load_file
        from dampertwin.protocols import load_protocol
        from dampertwin.variants import load_variant

        self._ctx["base"] = load(ROOT / "conf" / "design" / "baseline.yaml")
        self._ctx["seed"] = int(yaml_load_file(ROOT / "conf" / "config.yaml")["seed"])
        self._ctx["variant"] = lambda case: load_variant(ROOT / "conf" / "variant" / f"{case}.yaml")
        self._ctx["proto"] = {t: load_protocol(ROOT / "conf" / "test" / f"{t}.yaml")
                              for t in ("monosine", "monosine16", "random")}
        check_maps(self._ctx["base"], self.maps)

    def frames(self, theta: dict):
        """A ``frames(case, test)`` closure as scripts/thesis_comparison.py's, at factors ``theta``."""
        from dampertwin.protocols import build_runs
        from thesis_comparison import simulate_runs
        import make_active_valve_maps as mk

        base, cache = self._ctx["base"], {}

        def frames(case: str, test: str):
            if (case, test) in cache:
                return cache[(case, test)]
            v = self._ctx["variant"](case)
            d = base.with_overrides(case_overrides(base, v.overrides, self.params, theta), source=f"case {case}")
            mfile = str(v.overrides.get("active_valve.pq_map", "active_valve_baseline.csv"))
            d = dataclasses.replace(d, pq_map=mk.pq_map(**map_coefficients(self.maps[mfile], self.params, theta)))
            proto = self._ctx["proto"][test]
            if test == "random":
                proto = random_protocol(proto, self.params, theta)
            runs = [r for r in build_runs(proto, self._ctx["seed"]) if abs(r.current - v.current) < 1e-9]
            cache[(case, test)] = (d, proto, simulate_runs(d, runs, f"{case}/{test}"))
            return cache[(case, test)]

        return frames

    def values(self, theta: dict, cells: list[Cell]) -> np.ndarray:
        """The project's value of every cell at factors ``theta`` [g or dB]."""
        need = {t: {c.case for c in cells if c.table == t} for t in TABLE_KEYS}
        need["6.6"] |= need.pop("7.2")
        sub = dict(self.pub)
        for t in ("6.5", "6.6", "7.1"):
            k = TABLE_KEYS[t]
            sub[k] = {**self.pub[k], "rows": [r for r in self.pub[k]["rows"] if r["case"] in need[t]]}
        v = tc.project_values(sub, self.frames(theta))
        self.count += 1
        src = {"6.5": "6.5", "7.1": "7.1", "6.6": "6.6", "7.2": "6.6"}
        return np.array([v[src[c.table]][(c.case, c.column)] for c in cells], float)


def check_maps(base, maps: dict) -> None:
    """The generator coefficients reproduce the design's committed map CSVs."""
    import make_active_valve_maps as mk

    for fname, coef in maps.items():
        ref = base.pq_map if fname == "active_valve_baseline.csv" else \
            base.with_overrides({"active_valve.pq_map": fname}).pq_map
        if not np.allclose(mk.pq_map(**coef).flow, ref.flow, rtol=1e-9, atol=1e-15):
            raise ValueError(f"conf/thesis/inverse.yaml maps: the coefficients of {fname} do not reproduce "
                             f"conf/design/{fname} (scripts/make_active_valve_maps.py changed?)")


# ------------------------------------------------------------------ problem, Jacobian, SVD
def make_problem(sim: Simulator, cells: list[Cell], fit_mask: np.ndarray, fixed: dict | None = None):
    """A calibration-core Problem: parameter rows (factors of the fitted
    names, in ``specs`` order, set by ``names``) -> scaled residual rows z,
    a reason per failed row, the cell values per row; cost: whitened chi^2
    over ``fit_mask``."""
    from dampertwin.calibration.problem import Problem, WhitenedChi2

    class InverseProblem(Problem):
        names: list = []

        def evaluate(self, X):
            Z, why, outs = [], [], []
            for x in np.atleast_2d(X):
                th = {**(fixed or {}), **dict(zip(self.names, map(float, x)))}
                try:
                    v = sim.values(th, cells)
                    Z.append(scaled_residual(cells, v))
                    why.append(None)
                    outs.append(v)
                except (RuntimeError, ValueError) as e:
                    Z.append(np.full(len(cells), np.nan))
                    why.append(str(e))
                    outs.append(None)
            return np.array(Z), why, outs

    pr = InverseProblem()
    pr.cost = WhitenedChi2(np.asarray(fit_mask, bool))
    return pr


def jacobian(f, params: list[FactorParam], theta0: dict, step: float, z0: np.ndarray | None = None):
    """Forward differences S_ij = dz_i / d ln theta_j at ``theta0``; ``f``
    maps a theta dict to z. A step past the upper bound goes the other way.
    Returns (z0, S)."""
    z0 = f(theta0) if z0 is None else z0
    S = np.zeros((len(z0), len(params)))
    for j, p in enumerate(params):
        t0 = float(theta0.get(p.name, 1.0))
        h = float(fd_steps([p], theta0, step)[0])
        z = f({**theta0, p.name: t0 * math.exp(h)})
        S[:, j] = (z - z0) / h
    return z0, S


def fd_steps(params: list[FactorParam], theta: dict, step: float) -> np.ndarray:
    """The signed step in ln theta that :func:`jacobian` takes per parameter."""
    return np.array([step if math.log(float(theta.get(p.name, 1.0))) + step <= math.log(p.hi) + 1e-12 else -step
                     for p in params])


def kpi_jumps(cells: list[Cell], values, S: np.ndarray, params: list[FactorParam], theta: dict,
              step: float) -> np.ndarray:
    """(cells, params) True where a finite-difference step flipped the sign of
    a peak cell: the thesis' literal KPI (THESIS-ERRATA 38) jumped between
    the half-cycle's positive and negative extreme. Such an entry is a
    discontinuity, not a slope: it is left out of the SVD and the fit."""
    v = np.asarray(values, float)[:, None]
    sig = np.array([c.sigma for c in cells])[:, None]
    pert = v - sig * np.nan_to_num(S) * fd_steps(params, theta, step)[None, :]  # z = (thesis - v) / sigma
    peak = np.array([c.unit == "%" for c in cells])[:, None]
    return peak & (np.sign(pert) != np.sign(v))


def identifiability(S: np.ndarray, params: list[FactorParam], threshold: float) -> dict:
    """SVD of the range-scaled sensitivity S~ = S diag(half log ranges):
    singular values, the determined directions (s > ``threshold``), per
    parameter its column norm (largest effect over the range, tolerance
    units), its share in the determined subspace (sum of V_jk^2 over the
    determined k, 0..1), the pivoted-QR order and the selected subset."""
    from scipy.linalg import qr

    w = np.array([p.half_log_range for p in params])
    St = np.nan_to_num(S, nan=0.0) * w[None, :]
    U, s, Vt = np.linalg.svd(St, full_matrices=False)
    r = int(np.sum(s > threshold))
    share = np.sum(Vt[:r, :] ** 2, axis=0) if r else np.zeros(len(params))
    _, R, piv = qr(St, pivoting=True, mode="economic")
    sel = [params[i].name for i in piv[:r]] if r else []
    F = S.T @ S
    rows = []
    for j, p in enumerate(params):
        rows.append({"parameter": p.name, "column norm": float(np.linalg.norm(St[:, j])),
                     "determined share": float(share[j]), "pivot rank": int(np.flatnonzero(piv == j)[0]) + 1,
                     "selected": p.name in sel})
    dirs = []
    for k in range(len(s)):
        comp = sorted(((float(Vt[k, j]), params[j].name) for j in range(len(params))), key=lambda c: -abs(c[0]))
        dirs.append({"singular value": float(s[k]), "determined": bool(s[k] > threshold),
                     "leading": [{"parameter": n, "weight": c} for c, n in comp[:4]]})
    return {"threshold": threshold, "rank": r, "singular values": [float(x) for x in s], "parameters": rows,
            "directions": dirs, "selected": sel, "fisher_diag": [float(x) for x in np.diag(F)]}


def fit(problem, params: list[FactorParam], names: list[str], theta0: dict, J_u: dict | None, start,
        iterations: int, step_u: float, tol: float):
    """The calibration core's Gauss-Newton (``optimisers.run``) over the
    factors ``names`` from ``theta0``; ``J_u``: known columns dz/du,
    ``start``: (z, values) known at ``theta0``."""
    from dampertwin.calibration.ga import ParamSpec
    from dampertwin.calibration.gauss_newton import GaussNewtonSettings
    from dampertwin.calibration.optimisers import run

    by = {p.name: p for p in params}
    specs = [ParamSpec(n, by[n].lo, by[n].hi, "log", float(theta0.get(n, 1.0))) for n in names]
    problem.names = list(names)
    return run(problem, specs, GaussNewtonSettings(iterations=iterations, step=step_u, tol=tol),
               start=start, jacobian=J_u)


def to_u_columns(S: np.ndarray, params: list[FactorParam], names: list[str]) -> dict:
    """dz/d ln theta columns -> dz/du columns of the log-scale specs (u = ln(theta/lo) / ln(hi/lo))."""
    idx = {p.name: j for j, p in enumerate(params)}
    return {n: S[:, idx[n]] * 2.0 * params[idx[n]].half_log_range for n in names}


__all__ = ["Cell", "FactorParam", "Simulator", "case_overrides", "cells_of", "diffs", "fd_steps", "fit",
           "identifiability", "jacobian", "kpi_jumps", "load_params", "make_problem", "map_coefficients",
           "random_protocol", "scaled_residual", "to_u_columns"]

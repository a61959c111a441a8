"""Which of a valve group's table-6.1 parameters the damper-level training
record determines (thesis ch. 7, issue 37).

The valve stiffness law F_k(x) = F_pre + a(e^{bx} - 1) + c(e^{dx} - 1)
(eq. 4.19) has coefficients that trade off pairwise near |corr| = 1 even on
the flow bench (approach 1's fits, ``results/approach1/fits.json``): the
curve is determined, not every coefficient. Approach 2 calibrates each
valve's group on one damper-level record, where a valve's lift is seen only
through the damper force. Fitting a coefficient the record cannot
determine lets it wander within its window and drag the curve with it.

The decision, at the drawings' values (the GA's start):

1. Jacobian of the residual F_meas - F_sim [N] with respect to every
   table-6.1 parameter of every valve (gene coordinates of the search
   windows), central differences at the tight tolerance
   (:func:`.polish.uncertainty_at`'s Jacobian).
2. Per valve, its rows weighted by its eq.-7.1 weight I_i(t) (the GA of that
   group sees exactly this residual) and analysed by
   :func:`.uncertainty.analyse`: intervals, correlations, singular
   directions of all its parameters together (the figure's first row).
3. The determined subset by forward selection in the order of the
   orthogonal method (Yao et al. 2003, Polym. React. Eng. 11:563-588;
   Brun, Reichert & Kuensch 2001, Water Resour. Res. 37:1015-1030): next
   is the parameter whose sensitivity column is largest after projecting
   out those already chosen; it joins if the analysis of the chosen set
   with it meets the rule (:class:`Rule`), else it is fixed at the
   drawings' value. The group's other parameters are held at the drawings'
   values in each analysis, as they are in the fit.

No file I/O here; the stage ``approach2_identifiability`` writes the figure
and the decision, the fit stage reads it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from .polish import UNCERTAINTY_STEP, values
from .uncertainty import analyse, central_jacobian

WHERE = "conf/calibration/approach2.yaml: identifiability"


@dataclass(frozen=True)
class Rule:
    """A parameter is determined when its 95 % interval half-width is below
    ``rel_ci_max`` of its value, its |correlation| with every other chosen
    parameter below ``corr_max`` and it loads no unresolved direction."""

    rel_ci_max: float = 1.0
    corr_max: float = 0.99

    @classmethod
    def from_config(cls, c, where: str = WHERE) -> "Rule":
        if not hasattr(c, "get"):
            raise UserError(f"{where}: expected a mapping with rel_ci_max and corr_max")
        unknown = set(c) - {"rel_ci_max", "corr_max", "reason"}
        if unknown:
            raise UserError(f"{where}: unknown key(s) {sorted(unknown)}; expected rel_ci_max, corr_max, reason")
        out = []
        for k, ok in (("rel_ci_max", lambda v: v > 0), ("corr_max", lambda v: 0 < v < 1)):
            v = c.get(k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not ok(float(v)):
                raise UserError(f"{where}: {k} = {v!r}; expected a number "
                                + ("> 0 (fraction of the value)" if k == "rel_ci_max" else "in (0, 1)"))
            out.append(float(v))
        return cls(*out)


def _analysis(J, r, names, g, specs, E, blocks, rule):
    to_value = lambda j, u: values([specs[j]], np.atleast_1d(u)[:, None])[0, 0]  # noqa: E731
    return analyse(J, r, names, g, to_value=to_value, blocks=blocks, jac_error=E,
                   rel_ci_max=rule.rel_ci_max, corr_max=rule.corr_max)


def select(J: np.ndarray, r: np.ndarray, E: np.ndarray, g: np.ndarray, specs, rule: Rule,
           blocks=None) -> dict:
    """Determined subset of one group: ``J`` / ``E`` (n, p) Jacobian and its
    error estimate (gene coordinates), ``r`` (n,) residual [N], ``g`` (p,)
    genes of the drawings' values, ``specs`` the group's ParamSpecs. Returns
    {"all": analysis of all p together (Uncertainty.to_dict), "order": the
    orthogonal-method order tried, "determined" / "fixed": keys, "subset":
    analysis of the determined set, "steps": why each joined or not}."""
    names = [s.key for s in specs]
    p = len(names)
    full = _analysis(J, r, names, g, specs, E, blocks, rule)
    chosen, steps, left = [], [], list(range(p))
    while left:
        if chosen:
            Q, _ = np.linalg.qr(J[:, chosen])
            norms = np.linalg.norm(J[:, left] - Q @ (Q.T @ J[:, left]), axis=0)
        else:
            norms = np.linalg.norm(J[:, left], axis=0)
        j = left[int(np.argmax(norms))]
        left.remove(j)
        trial = chosen + [j]
        u = _analysis(J[:, trial], r, [names[k] for k in trial], g[trial], [specs[k] for k in trial], E[:, trial],
                      blocks, rule)
        ok = bool(u.table["determined"].all()) and float(np.max(norms)) > 0
        why = "; ".join(f"{w['parameter']}: {w['why']}" for _, w in u.table.iterrows() if w["why"])
        row = u.table.iloc[-1]
        steps.append({"parameter": names[j], "orthogonal sensitivity": float(np.max(norms)), "joins": ok,
                      "rel_halfwidth": float(row["rel. half-width [%]"]) / 100.0,
                      "max_abs_corr": float(row["max |corr|"]), "with": str(row["with"]),
                      "why not": "" if ok else (why or "no sensitivity")})
        if ok:
            chosen = trial
    sub = (_analysis(J[:, chosen], r, [names[k] for k in chosen], g[chosen], [specs[k] for k in chosen],
                     E[:, chosen], blocks, rule).to_dict() if chosen else None)
    return {"all": full.to_dict(), "order": [s["parameter"] for s in steps], "steps": steps,
            "determined": [names[k] for k in sorted(chosen)], "fixed": [names[k] for k in range(p) if k not in chosen],
            "subset": sub}


def decide(records, groups, W: np.ndarray, x0: dict, rule: Rule, step: float = UNCERTAINTY_STEP) -> dict:
    """The decision for every valve group: ``records`` (the training
    problem's :class:`.polish.Records` over all groups' specs, in order),
    ``groups`` (GAGroup list), ``W`` (G, n) eq.-7.1 weights, ``x0`` the
    drawings' values. One batch of 4p + 1 precise simulations. Returns
    {group: :func:`select` result}."""
    specs = [s for gr in groups for s in gr.specs]
    g0 = np.array([s.to_gene(x0[s.key]) for s in specs])
    e0, J, E = central_jacobian(lambda G: records.precise_residuals(values(specs, G)), g0, step,
                                np.zeros_like(g0), np.ones_like(g0))
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(e0))):
        raise UserError("approach-2 identifiability: a simulation failed at or next to the drawings' values; "
                        "no Jacobian (check the training record and conf/calibration/approach2.yaml windows)")
    if W.shape != (len(groups), len(e0)):
        raise UserError(f"sensitivity weights have shape {W.shape}; the training record needs "
                        f"({len(groups)}, {len(e0)}): rerun the sensitivity stage on the same record")
    out, lo = {}, 0
    for gi, gr in enumerate(groups):
        cols = slice(lo, lo + len(gr.specs))
        lo += len(gr.specs)
        w = np.nan_to_num(np.asarray(W[gi], float))
        out[gr.name] = select(J[:, cols] * w[:, None], e0 * w, E[:, cols] * w[:, None], g0[cols], list(gr.specs),
                              rule, blocks=records.blocks)
    return out


def figure(decision: dict, rule: Rule, title: str):
    """Per group: relative 95 % half-width of each parameter analysed all
    together and in the determined subset (log scale, the rule's line), and
    the correlation matrix of all together; determined ones in bold."""
    import matplotlib.pyplot as plt

    G = len(decision)
    fig, axes = plt.subplots(2, G, figsize=(4.2 * G, 8), constrained_layout=True, squeeze=False)
    for k, (name, d) in enumerate(decision.items()):
        rows = d["all"]["parameters"]
        keys = [r["parameter"] for r in rows]
        short = [x.split(".")[-1] for x in keys]
        sub = {r["parameter"]: r["rel. half-width [%]"] for r in (d["subset"] or {}).get("parameters", [])}
        tried = {st["parameter"]: 100 * st["rel_halfwidth"] for st in d["steps"]}
        cap = 1e5
        allw = [min(r["rel. half-width [%]"], cap) for r in rows]
        fitw = [min(sub.get(x, np.nan), cap) for x in keys]
        fixw = [np.nan if x in sub else min(tried.get(x, np.nan), cap) for x in keys]
        y = np.arange(len(keys))
        ax = axes[0, k]
        ax.barh(y + 0.2, allw, 0.4, color="0.7", label="all together")
        ax.barh(y - 0.2, fitw, 0.4, color="C0", label="determined subset (fitted)")
        ax.barh(y - 0.2, fixw, 0.4, color="C1", label="tried with the chosen ones (fixed)")
        ax.axvline(100 * rule.rel_ci_max, color="C3", ls="--", lw=1, label=f"rule {rule.rel_ci_max:.0%}")
        ax.set_yticks(y, [f"{s} (fit)" if x in d["determined"] else f"{s} (fixed)" for s, x in zip(short, keys)])
        for t, x in zip(ax.get_yticklabels(), keys):
            t.set_fontweight("bold" if x in d["determined"] else "normal")
        ax.set(xscale="log", xlabel="95 % half-width / value [%] (capped at 1e5)", title=name)
        ax.invert_yaxis()
        ax.grid(alpha=0.3, axis="x")
        if k == 0:
            ax.legend(fontsize=7, loc="best", framealpha=0.9)
        C = np.array([[d["all"]["correlation"][a][b] for b in keys] for a in keys])
        ax = axes[1, k]
        im = ax.imshow(np.abs(C), vmin=0, vmax=1, cmap="viridis")
        ax.set_xticks(y, short)
        ax.set_yticks(y, short)
        for i in range(len(keys)):
            for j in range(len(keys)):
                ax.text(j, i, f"{C[i, j]:.2f}", ha="center", va="center", fontsize=6,
                        color="w" if abs(C[i, j]) < 0.6 else "k")
        ax.set_title(f"correlation, all together (|corr| > {rule.corr_max:g}: not separable)", fontsize=8)
    fig.colorbar(im, ax=axes[1, :].tolist(), shrink=0.6, label="|corr|")
    fig.suptitle(title)
    return fig


def summary(decision: dict, rule: Rule) -> dict:
    """The JSON form of :func:`decide` (keys per group: determined, fixed,
    steps, the relative half-widths and max |corr| of all together and of
    the subset) with the rule."""
    out = {"rule": {"rel_ci_max": rule.rel_ci_max, "corr_max": rule.corr_max}, "groups": {}}
    for name, d in decision.items():
        def table(u):
            return {r["parameter"]: {"value": r["value"], "rel_halfwidth": r["rel. half-width [%]"] / 100.0,
                                     "max_abs_corr": r["max |corr|"], "with": r["with"],
                                     "determined": bool(r["determined"]), "why": r["why"]}
                    for r in u["parameters"]} if u else {}
        out["groups"][name] = {"determined": d["determined"], "fixed": d["fixed"], "steps": d["steps"],
                               "all_together": table(d["all"]), "subset": table(d["subset"]),
                               "n_samples": d["all"]["n_samples"], "n_eff": d["all"]["n_eff"]}
    return out


__all__ = ["Rule", "select", "decide", "figure", "summary"]

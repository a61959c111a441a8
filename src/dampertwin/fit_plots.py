"""PNG plots of ``dampertwin fit``: measured vs fitted per record (friction:
time series with the held-out cycles shaded, force-displacement and
force-velocity loops; GA fits: one panel per record)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .calibration import friction_fit as _ff
from .calibration.friction_fit import nrmse
from .io import atomic_files


def _save(fig, path: Path) -> None:
    """The PNG written beside itself and renamed: a killed run leaves the old file or the new one (a folder at
    ``path``: OutputError, nothing written)."""
    with atomic_files([path], ".png") as (tmp,):
        fig.savefig(tmp, dpi=100)


def friction_plots(out: Path, paths, recs, sims, result) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = [sims["fitted"]] + [q["_sim"] for q in sims["predicted"]]
    for i, (path, r, sim) in enumerate(zip(paths, recs, models)):
        t, v, F = r["t"], r["v"], r["F"]
        cv = sims["coulomb_viscous"] if i == 0 else _ff.coulomb_viscous(v, {"F_c": result["baseline"]["F_c [N]"],
                                                                            "c": result["baseline"]["c [N*s/m]"]})
        held = ~sims["mask"] if i == 0 else np.zeros(len(t), bool)
        fig, axes = plt.subplots(1, 3, figsize=(16, 4.8), constrained_layout=True)
        lab = (f"fitted cycles NRMSE {result['nrmse']:.3f}" + (f", held-out {result['nrmse_held_out']:.3f}"
               if result["nrmse_held_out"] is not None else "")) if i == 0 else \
            f"NRMSE {result['files'][str(path)]['nrmse']:.3f}"
        axes[0].plot(t, F, lw=0.7, label="measured")
        axes[0].plot(t, sim, "--", lw=0.9, label=f"model ({lab})")
        axes[0].plot(t, cv, ":", lw=0.8, label=f"Coulomb + viscous (NRMSE {_ff.nrmse(F, cv):.3f})")
        if held.any():
            axes[0].axvspan(t[held][0], t[-1], color="0.9", zorder=0, label="held-out cycles")
        axes[0].set(xlabel="time [s]", ylabel="force [N]")
        if r["x"] is not None:
            xm = r["x"] * 1e3
            axes[1].plot(np.where(held, np.nan, xm), F, lw=0.6, color="C0", label="measured, fitted cycles")
            if held.any():
                axes[1].plot(np.where(held, xm, np.nan), F, lw=0.6, color="C2", label="measured, held-out cycles")
            axes[1].plot(r["x"] * 1e3, sim, "--", lw=0.8, color="C1", label="model")
        axes[1].set(xlabel="displacement [mm]", ylabel="force [N]")
        axes[2].plot(v, F, ".", ms=1.2, label="measured")
        axes[2].plot(v, sim, ".", ms=1.2, label="model")
        axes[2].set(xlabel="velocity [m/s]", ylabel="force [N]")
        for ax in axes:
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        flags = "; ".join(h["parameter"] + " on " + h["bound"] + " bound" for h in result["bound_hits"]) \
            if i == 0 else ""
        fig.suptitle(f"friction fit: {path.name} ({'fitted' if i == 0 else 'predicted'}); {result['model']}"
                     + (f"\nFLAG: {flags}" if flags else ""), fontsize=9)
        _save(fig, out / f"friction_{i}_{path.stem}.png")
        plt.close(fig)


def series_plots(out: Path, problem, sims, ylabel: str, name: str, x_of=None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for fi, (path, cases) in enumerate(problem.files):
        k = len(cases)
        fig, axes = plt.subplots(k, 1, figsize=(11, 3.2 * k), squeeze=False, constrained_layout=True)
        for ax, (t, meas, ex, extra), s in zip(axes[:, 0], cases, sims[fi]):
            if x_of is None:
                ax.plot(t, meas, lw=0.8, label="measured")
                ax.plot(t, s[0], "--", lw=0.9, label=f"fitted (NRMSE {nrmse(meas, s[0]):.3f})")
                ax.set(xlabel="time [s]", ylabel=ylabel)
            else:
                x, xl = x_of(t, ex, extra)
                ax.plot(x, meas, lw=0.8, label="measured")
                ax.plot(x, s[0], "--", lw=0.9, label=f"fitted (NRMSE {nrmse(meas, s[0]):.3f})")
                ax.set(xlabel=xl, ylabel=ylabel)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        fig.suptitle(f"{name} fit: {Path(path).name} ({'fitted' if fi == 0 else 'predicted'})")
        _save(fig, out / f"{name}_{fi}_{Path(path).stem}.png")
        plt.close(fig)


__all__ = ["friction_plots", "series_plots"]

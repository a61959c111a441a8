"""Plots that read: no empty panel or legend, titles inside the figure,
measured data visible on the discrepancy overlays."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from dampertwin import report  # noqa: E402


def _pq_frame(scale: float = 1.0) -> pd.DataFrame:
    t = np.linspace(0, 2, 400)
    q = 1e-3 * np.concatenate([np.linspace(0, 1, 200), np.linspace(1, 0, 200)])
    return pd.DataFrame({"time [s]": t, "flow [m^3/s]": q, "dp [Pa]": scale * 4e6 * np.sqrt(q / 1e-3)})


def _inside(fig, artist) -> bool:
    fig.canvas.draw()
    box, page = artist.get_window_extent(), fig.bbox
    return box.x0 >= page.x0 - 1 and box.x1 <= page.x1 + 1 and box.y1 <= page.y1 + 1


def test_pq_figure_of_one_valve_has_one_panel_and_no_empty_legend():
    fig = report.pq_figure({"piston_rebound": _pq_frame()}, {"piston_rebound": _pq_frame(1.05)}, "one valve " * 12)
    axes = fig.get_axes()
    assert len(axes) == 1 and len(axes[0].lines) == 4
    assert _inside(fig, fig._suptitle)
    plt.close(fig)
    fig = report.pq_figure({}, {v: _pq_frame() for v in ("piston_rebound", "base_intake")}, "two")
    assert len(fig.get_axes()) == 2 and all(ax.lines and ax.get_legend() for ax in fig.get_axes())
    plt.close(fig)


def test_psd_title_fits_the_figure():
    rng = np.random.default_rng(0)
    df = pd.DataFrame({"time [s]": np.arange(4000) / 2000.0, "rod acceleration [m/s^2]": rng.normal(size=4000)})
    long = ("baseline_1.6: random road noise at 1.6 A\nnominal design: conf/design/baseline.yaml + variant "
            "baseline_1.6 (ce926ce5); measured: data/measured (SYNTHETIC lab data)")
    fig = report.psd_figure(df, None, long)
    assert _inside(fig, fig.get_axes()[0].title)
    plt.close(fig)


def test_discrepancy_overlay_draws_the_measured_curve_on_top(tmp_path, monkeypatch):
    from dampertwin.discrepancy import report as drep

    captured = []
    monkeypatch.setattr(drep.plt, "close", lambda fig: captured.append(fig))
    t = np.linspace(0, 0.2, 400)
    x = 0.005 * np.sin(2 * np.pi * 10 * t)
    f = 300 * np.cos(2 * np.pi * 10 * t)
    u = SimpleNamespace(kind="sine", channels=["force [N]"], t=t, frequency=10.0, drive="displacement [m]",
                        measured={"displacement [m]": x, "force [N]": f}, key="monosine/baseline_1.6/I1.6",
                        test="monosine", case="baseline_1.6", run="I1.6", thermal=False)
    signals = [({"force [N]": 0.9 * f}, {"force [N]": f})]  # "after" equals the measurement
    paths = drep.overlays(SimpleNamespace(units=[u]), signals, tmp_path)
    assert paths and paths[0].is_file()
    ax = captured[0].get_axes()[0]
    by_label = {ln.get_label(): ln for ln in ax.lines}
    assert by_label["measured"].get_zorder() > max(by_label["after"].get_zorder(), by_label["before"].get_zorder())
    meas, after = by_label["measured"], by_label["after"]
    assert meas.get_color() != after.get_color() and meas.get_linewidth() < after.get_linewidth()

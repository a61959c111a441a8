"""Localised features of one measured record (a "unit": test / case / run)
and of the simulations of the same record, plus the noise level of every
feature estimated from the measurement itself.

* Sine tests (compliance, curving, mono-sine): the cycle is cut into phase
  bins of the fitted stroke sine (stroke position x velocity sign); per
  steady cycle the bin mean of the force (and the bin mean and RMS of the rod
  acceleration) is a feature row. Noise = cycle-to-cycle scatter of the
  measured bin values / sqrt(cycles), plus a bench allowance.
* Flow bench (one valve alone, triangular flow ramps): the ramp cycle is cut
  into phase bins of the recorded flow (flow level x rising / falling); per
  cycle the bin mean of the pressure drop. These records pin the valves'
  own parameters, so a damper-level disagreement cannot be absorbed by
  distorting a valve (e.g. piston band leakage, which the flow bench does not
  see).
* Random test: band levels [dB] of the force and rod-acceleration PSD per
  Welch segment (segments are the bootstrap units); the measured high-band
  floor (sensor noise) is added to the simulated PSD before comparing.
* Friction test (slow sines at two gas precharges): sine features like the
  other damper tests; each run is simulated with the precharge it records
  (``Unit.overrides``: oil.P_0), so a friction that grows with the chamber
  pressure shows as a hysteresis that differs between the runs.
* Oil temperature (records with a thermocouple channel, the warm-up test
  ``thermal``): the rise of the block means over the record's first
  ``thermal.reference`` seconds, in ``thermal.blocks`` blocks (record-level
  features, the same in every cycle row); the absolute reading (offset of
  the thermocouple, the oil temperature on the day) is not compared. The
  simulated temperature passes the documented first-order thermocouple lag.

Everything here is pure: frames / arrays in, arrays out (no files).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import kpi
from ..excitation import Excitation
from ..report import RECORD_CUTOFF
from ..sensors import sensor_lowpass, transducer

FORCE, ACC = "force [N]", "rod acceleration [m/s^2]"
TEMP = "oil temperature [K]"                          # measured and simulated channel (thermocouple)
TEMP_FEATURE = "temperature rise"
PRECHARGE = "precharge [Pa]"                          # friction test: the run's gas precharge (a design value)
DP, FLOW, DISPLACEMENT = "dp [Pa]", "flow [m^3/s]", "displacement [m]"
SIM_FORCE = {"damper": "rod force [N]", "module": "top mount force [N]"}
SIM_DP = ("p upstream [Pa]", "p downstream [Pa]")   # valve configuration (flow bench)
SINE_TESTS = ("compliance", "curving", "monosine", "training", "flowbench", "friction")
NAMES = {FORCE: "force", DP: "dp"}                   # feature name of a channel's bin mean
PSD_TESTS = ("random", "verification")


@dataclass
class Unit:
    """One measured record prepared for comparison."""

    test: str
    case: str
    run: str
    configuration: str
    current: float
    t: np.ndarray
    excitation: Excitation
    measured: dict            # channel -> array (measured, on t)
    sensors: dict             # documented transducer bandwidths [Hz]
    kind: str                 # "sine" | "psd"
    labels: list = field(default_factory=list)      # (channel, phase_or_band) per feature
    per_cycle: np.ndarray | None = None             # measured features per cycle / segment [n_cyc, n_feat]
    sigma: np.ndarray | None = None                 # noise level per feature (diagonal)
    white: np.ndarray | None = None                 # whitening matrix of the unit's features
    fold: str = "train"
    frequency: float | None = None
    _bins: tuple | None = None                      # (cycle index, bin index, valid mask) for sine units
    _floor: dict | None = None                      # measured PSD floor per channel
    _slope: dict | None = None                      # bin mean of d(signal)/dt per channel (sine units)
    _within: np.ndarray | None = None               # within-cycle standard error (single steady cycle)
    drive: str = DISPLACEMENT                       # recorded input channel (the phase reference)
    sim_kw: dict = field(default_factory=dict)      # extra simulate_batch arguments (flow bench: valve, bench)
    overrides: dict = field(default_factory=dict)   # design values the record sets (friction test: oil.P_0)

    @property
    def key(self) -> str:
        return f"{self.test}/{self.case}/{self.run}"

    @property
    def n_cycles(self) -> int:
        return 0 if self.per_cycle is None else int(self.per_cycle.shape[0])

    @property
    def thermal(self) -> bool:
        """Whether the record has an oil temperature channel (compared as its rise)."""
        return TEMP in self.measured

    @property
    def channels(self) -> list[str]:
        if self.configuration == "valve":
            return [DP]
        return [FORCE] + ([ACC] if self.configuration == "module" and ACC in self.measured else [])

    def measured_features(self, idx: np.ndarray | None = None) -> np.ndarray:
        """Measured features: mean over cycles (or over resampled cycles ``idx``)."""
        pc = self.per_cycle if idx is None else self.per_cycle[idx]
        return pc.mean(axis=0)


def make_unit(test: str, case: str, run: str, configuration: str, current: float, frame, sensors: dict,
              max_duration: float | None = None, bench: dict | None = None, flow_cutoff: float | None = None) -> Unit:
    """A unit from one run's measured frame (``frame``: time, displacement, force[, rod acceleration];
    flow bench: time, flow, dp with ``run`` the valve, ``bench`` its volume / back pressure and
    ``flow_cutoff`` [Hz] the low-pass of the recorded flow used as input, as in the valve fits)."""
    t = frame["time [s]"].to_numpy(float)
    if max_duration is not None and t[-1] - t[0] > max_duration:
        keep = t <= t[0] + max_duration
        frame = frame[keep]
        t = t[keep]
    if configuration == "valve":
        if flow_cutoff is None:
            raise ValueError("a flow-bench unit needs flow_cutoff (the valve fits' input_cutoff)")
        q = frame[FLOW].to_numpy(float)
        ex = Excitation.from_samples(t - t[0], q, kind="flow", cutoff=flow_cutoff)
        meas = {FLOW: q, DP: frame[DP].to_numpy(float)}
        kw = {"bench_valve": run, "bench": dict(bench or {})}
        return Unit(test, case, run, configuration, float(current), t, ex, meas, dict(sensors or {}), "sine",
                    drive=FLOW, sim_kw=kw)
    x = frame["displacement [m]"].to_numpy(float)
    ex = Excitation.from_samples(t, x, cutoff=RECORD_CUTOFF)
    meas = {"displacement [m]": x, FORCE: frame[FORCE].to_numpy(float)}
    if ACC in frame:
        meas[ACC] = frame[ACC].to_numpy(float)
    if TEMP in frame:
        meas[TEMP] = frame[TEMP].to_numpy(float)
    kind = "psd" if test in PSD_TESTS else "sine"
    over = {}
    if PRECHARGE in frame:  # the friction test's gas precharge of this run [Pa abs]: the fill, one value
        P = frame[PRECHARGE].to_numpy(float)
        if np.ptp(P) > 1e-3 * abs(float(P[0])):
            raise ValueError(f"run {run}: column {PRECHARGE!r} varies ({P.min():.6g}..{P.max():.6g} Pa); expected "
                             f"the run's gas fill pressure, one value per run (a chamber pressure trace?)")
        over["oil.P_0"] = float(P[0])
    return Unit(test, case, run, configuration, float(current), t, ex, meas, dict(sensors or {}), kind,
                overrides=over)


# ------------------------------------------------------------------ sine units
def _phase_bins(u: Unit, n_bins: int, transient: int):
    t, x = u.t, u.measured[u.drive]
    f = kpi.dominant_frequency(t, x)
    c = kpi.harmonic(t, x, f)  # x ~ Re(c e^{i w t})
    theta = 2 * math.pi * f * t + math.atan2(c.imag, c.real)
    # x = |c| cos(theta): phase in (0, pi) = compression (x falling), (pi, 2 pi) = rebound
    rel = (theta - theta[0]) / (2 * math.pi)
    cyc = np.floor(rel + 1e-9).astype(int)  # cycles counted from the record start
    ph = np.mod(theta, 2 * math.pi)
    b = np.minimum((ph / (2 * math.pi) * n_bins).astype(int), n_bins - 1)
    n_full = int(np.floor(rel[-1] + f * float(np.mean(np.diff(t))) + 1e-6))
    valid = (cyc >= transient) & (cyc < n_full)
    return f, cyc, b, valid


def bin_label(k: int, n_bins: int, drive: str = DISPLACEMENT) -> str:
    """Phase bin k as stroke position (fraction of the amplitude) and direction
    (flow bench: flow level about the mean and rising / falling)."""
    centre = (k + 0.5) / n_bins * 2 * math.pi
    if drive == FLOW:
        return f"flow {'falling' if centre < math.pi else 'rising'} q=mean{math.cos(centre):+.2f}A"
    direction = "compression" if centre < math.pi else "rebound"
    return f"{direction} x={math.cos(centre):+.2f}A"


def _sine_matrix(u: Unit, signals: dict, n_bins: int) -> np.ndarray:
    """Per-cycle feature rows [n_cyc, n_feat] of ``signals`` (channel -> array or [m, n] arrays)."""
    _, cyc, b, valid = u._bins
    cycles = np.unique(cyc[valid])
    ci = np.searchsorted(cycles, cyc[valid])
    idx = ci * n_bins + b[valid]
    nc = len(cycles)
    cnt = np.bincount(idx, minlength=nc * n_bins).reshape(nc, n_bins)
    cnt = np.maximum(cnt, 1)
    cols = []
    for ch in u.channels:
        s = signals[ch][valid]
        mean = np.bincount(idx, weights=s, minlength=nc * n_bins).reshape(nc, n_bins) / cnt
        cols.append(mean)
        if ch == ACC:
            ms = np.bincount(idx, weights=s * s, minlength=nc * n_bins).reshape(nc, n_bins) / cnt
            cols.append(np.sqrt(np.maximum(ms, 0.0)))
    return np.hstack(cols)


def _within_cycle_se(u: Unit, signals: dict, n_bins: int, m: int, deg: int) -> np.ndarray:
    """Standard error of the bin features of a single steady cycle (curving
    runs: one steady cycle), by batch means: each bin's samples in ``m``
    consecutive blocks, a polynomial of degree ``deg`` in time removed from the
    block means (the force changes along a bin), their scatter / sqrt(m).
    Covers sensor noise and its autocorrelation up to a block; what remains of
    the within-bin shape counts as noise (conservative)."""
    _, cyc, b, valid = u._bins
    out = []
    for ch in u.channels:
        s = signals[ch][valid]
        kinds = [s] + ([s * s] if ch == ACC else [])
        for q, sig in enumerate(kinds):
            se = np.zeros(n_bins)
            for k in range(n_bins):
                v = sig[b[valid] == k]
                if len(v) < 2 * m:
                    se[k] = np.nan
                    continue
                blocks = np.array([blk.mean() for blk in np.array_split(v, m)])
                tt = np.arange(m, dtype=float)
                res = blocks - np.polyval(np.polyfit(tt, blocks, deg), tt)
                sd = math.sqrt(float(np.sum(res ** 2)) / max(m - deg - 1, 1))
                se[k] = sd / math.sqrt(m)
                if q == 1:  # rms = sqrt(mean square): d rms = d ms / (2 rms)
                    se[k] /= max(2 * math.sqrt(max(blocks.mean(), 0.0)), 1e-300)
            out.append(se)
    se = np.concatenate(out)
    return np.where(np.isfinite(se), se, np.nanmedian(se) if np.isfinite(se).any() else 0.0)


def _sine_labels(u: Unit, n_bins: int) -> list:
    out = []
    for ch in u.channels:
        name = NAMES.get(ch, "acceleration mean")
        out += [(name, bin_label(k, n_bins, u.drive)) for k in range(n_bins)]
        if ch == ACC:
            out += [("acceleration rms", bin_label(k, n_bins, u.drive)) for k in range(n_bins)]
    return out


# ------------------------------------------------------------------ temperature
def _blocks(t: np.ndarray, cfg: dict):
    """(reference mask, [block masks], block labels) of the thermal features."""
    th = cfg.get("thermal") or {}
    ref_s, nb = float(th.get("reference", 1.0)), int(th.get("blocks", 4))
    t0, t1 = float(t[0]), float(t[-1])
    if t1 - t0 < 2 * ref_s:
        raise ValueError(f"record of {t1 - t0:.3g} s too short for the temperature rise (reference {ref_s:g} s)")
    ref = t < t0 + ref_s
    edges = np.linspace(t0 + ref_s, t1 + 1e-12, nb + 1)
    masks = [(t >= a) & (t < b) for a, b in zip(edges[:-1], edges[1:])]
    labels = [f"{a - t0:.1f}-{b - t0:.1f} s" for a, b in zip(edges[:-1], edges[1:])]
    return ref, masks, labels


def temperature_rise(t: np.ndarray, T: np.ndarray, cfg: dict) -> np.ndarray:
    """Block means of the temperature [K] minus the mean of the reference window."""
    ref, masks, _ = _blocks(t, cfg)
    T0 = float(np.mean(T[ref]))
    return np.array([float(np.mean(T[m])) - T0 for m in masks])


def _temperature_noise(t: np.ndarray, T: np.ndarray, cfg: dict):
    """Standard error [K] of each rise from the thermocouple's white noise
    (the scatter of successive differences / sqrt 2: the slow signal cancels),
    and d(rise)/d(lag) [K/s]: the rise moves by -(slope in the block - slope in
    the reference window) x a lag other than documented."""
    ref, masks, _ = _blocks(t, cfg)
    sw = float(np.std(np.diff(T))) / math.sqrt(2.0)
    se = np.array([sw * math.sqrt(1.0 / m.sum() + 1.0 / ref.sum()) for m in masks])

    def slope(m):
        tt = t[m]
        return float(np.polyfit(tt - tt.mean(), T[m], 1)[0]) if m.sum() > 2 else 0.0

    s0 = slope(ref)
    return se, np.array([slope(m) - s0 for m in masks])


def _temperature_labels(u: Unit, cfg: dict) -> list:
    return [(TEMP_FEATURE, lab) for lab in _blocks(u.t, cfg)[2]]


def _with_temperature(u: Unit, pc: np.ndarray, T: np.ndarray, cfg: dict) -> np.ndarray:
    """Feature rows with the temperature rise appended (the same in every row)."""
    if not u.thermal:
        return pc
    rise = temperature_rise(u.t, T, cfg)
    return np.hstack([pc, np.tile(rise, (pc.shape[0], 1))])


# ------------------------------------------------------------------ PSD units
def _segments(u: Unit, seg_s: float):
    fs = 1.0 / float(np.mean(np.diff(u.t)))
    n = int(round(seg_s * fs))
    m = len(u.t) // n
    return fs, n, m


def _band_levels(x: np.ndarray, fs: float, n: int, m: int, bands, floor: float | None = None,
                 floor_band=None, return_floor: bool = False):
    """Per-segment band PSD levels [dB] of x (Hann periodogram, segments of n samples)."""
    seg = x[: n * m].reshape(m, n)
    seg = seg - seg.mean(axis=1, keepdims=True)
    w = np.hanning(n)
    P = np.abs(np.fft.rfft(seg * w, axis=1)) ** 2 / (fs * np.sum(w * w))
    P[:, 1:-1] *= 2
    f = np.fft.rfftfreq(n, 1.0 / fs)
    fl = None
    if floor_band is not None and floor_band[1] < fs / 2:
        fm = (f >= floor_band[0]) & (f <= floor_band[1])
        fl = float(np.mean(P[:, fm])) if fm.any() else None
    if return_floor:
        return fl
    add = floor or 0.0
    cols = []
    for lo, hi in bands:
        bm = (f >= lo) & (f < hi)
        if not bm.any():
            cols.append(np.full(m, np.nan))
        else:
            cols.append(10 * np.log10(np.mean(P[:, bm], axis=1) + add + 1e-300))
    return np.column_stack(cols)


def _psd_bands(u: Unit, bands):
    fs = 1.0 / float(np.mean(np.diff(u.t)))
    return [b for b in bands if b[1] <= 0.45 * fs]


def _psd_matrix(u: Unit, signals: dict, cfg: dict, simulated: bool) -> np.ndarray:
    fs, n, m = _segments(u, cfg["psd_segment"])
    bands = _psd_bands(u, cfg["psd_bands"])
    cols = []
    for ch in u.channels:
        floor = u._floor.get(ch) if simulated else None
        cols.append(_band_levels(signals[ch], fs, n, m, bands, floor=floor))
    return np.hstack(cols)


# ------------------------------------------------------------------ preparation
def peak_velocity(t: np.ndarray, x: np.ndarray) -> float:
    """Peak velocity [m/s] of the fitted stroke sine of a displacement record."""
    f = kpi.dominant_frequency(t, x)
    return float(2 * math.pi * f * abs(kpi.harmonic(t, x, f)))


DYNO_MIN_HALF_STROKES = 4  # a dyno speed step: at least two cycles


def dyno_segments(run: str, frame) -> list:
    """A dyno run cut into its speed steps (dampertwin.dyno: reversals and steps found from the displacement),
    each from its first to its last reversal: [(label, frame slice)], the run itself when it has one step (a
    warm-up run keeps its whole temperature history). Each step is a sine unit of its own, simulated from rest,
    so a cut step leaves its oil temperature out (its history before the step is not simulated)."""
    from ..dyno import F as DF, T as DT, X as DX, half_strokes, speed_steps

    hs = half_strokes(frame[DT].to_numpy(float), frame[DX].to_numpy(float), frame[DF].to_numpy(float))
    if len(hs) == 0:
        raise ValueError(f"run {run}: no full stroke in the record")
    steps = speed_steps(hs)
    # a step of fewer half-strokes is a transition (a fade-in / fade-out of the stroke), not a speed step
    kept = [k for k in range(int(steps.max()) + 1) if np.sum(steps == k) >= DYNO_MIN_HALF_STROKES]
    if len(kept) <= 1:
        return [(run, frame)]
    out = []
    for k in kept:
        g = hs[steps == k]
        a, b = int(g["start"].min()), int(g["end"].max())
        seg = frame.iloc[a:b + 1].drop(columns=[TEMP], errors="ignore").reset_index(drop=True)
        out.append((f"{run}@{float(g['speed [m/s]'].median()):.3g}m/s", seg))
    return out


def keep_run(test: str, current: float, t: np.ndarray, x: np.ndarray, run_filter: dict | None) -> bool:
    """Whether a run passes the profile's ``run_filter`` of its test
    (``min_peak_velocity`` / ``max_peak_velocity`` [m/s] of the fitted stroke sine,
    ``currents`` [A] within 0.02 A)."""
    rf = (run_filter or {}).get(test)
    if not rf:
        return True
    cur = rf.get("currents")
    if cur is not None and not any(abs(float(current) - float(c)) <= 0.02 for c in cur):
        return False
    vmin, vmax = rf.get("min_peak_velocity"), rf.get("max_peak_velocity")
    if vmin is None and vmax is None:
        return True
    v = peak_velocity(t, x)
    return (vmin is None or v >= float(vmin)) and (vmax is None or v <= float(vmax))


def prepare(u: Unit, cfg: dict) -> Unit:
    """Measured features per cycle / segment, labels and noise levels."""
    if u.kind == "sine":
        nb = int(cfg["phase_bins"])
        transient = (cfg.get("transient_cycles_by_test") or {}).get(u.test, cfg["transient_cycles"])
        u._bins = _phase_bins(u, nb, int(transient))
        u.frequency = u._bins[0]
        cmp_ = _compare(u, u.measured, cfg)
        u.per_cycle = _sine_matrix(u, cmp_, nb)
        dt = float(np.mean(np.diff(u.t)))
        slopes = _sine_matrix(u, {ch: np.gradient(cmp_[ch], dt) for ch in u.channels}, nb).mean(axis=0)
        u._slope, k = {}, 0
        for ch in u.channels:
            u._slope[ch] = slopes[k:k + nb]
            k += nb * (2 if ch == ACC else 1)
        u.labels = _sine_labels(u, nb)
        if u.per_cycle.shape[0] < 1:
            raise ValueError(f"{u.key}: no steady cycle after the {transient} transient cycle(s)")
        if u.per_cycle.shape[0] == 1:
            u._within = _within_cycle_se(u, cmp_, nb, int(cfg.get("within_cycle_blocks", 10)),
                                         int(cfg.get("within_cycle_degree", 2)))
            if u.thermal:
                u._within = np.concatenate([u._within, np.zeros(len(_temperature_labels(u, cfg)))])
    else:
        fs, n, m = _segments(u, cfg["psd_segment"])
        if m < 3:
            raise ValueError(f"{u.key}: record shorter than 3 PSD segments of {cfg['psd_segment']} s")
        u._floor = {ch: _band_levels(u.measured[ch], fs, n, m, [], floor_band=cfg["psd_floor_band"], return_floor=True)
                    for ch in u.channels}
        u.per_cycle = _psd_matrix(u, u.measured, cfg, simulated=False)
        bands = _psd_bands(u, cfg["psd_bands"])
        u.labels = [("force PSD" if ch == FORCE else "acceleration PSD", f"{lo:g}-{hi:g} Hz")
                    for ch in u.channels for lo, hi in bands]
    if u.thermal:
        u.per_cycle = _with_temperature(u, u.per_cycle, u.measured[TEMP], cfg)
        u.labels = u.labels + _temperature_labels(u, cfg)
        u._tsig, u._tlag = _temperature_noise(u.t, u.measured[TEMP], cfg)
    u.sigma, u.white = noise(u, cfg)
    return u


def noise(u: Unit, cfg: dict, sim_pc: np.ndarray | None = None):
    """Noise model of the unit's features, from the data: the cycle-to-cycle
    (segment-to-segment) scatter of the residual measured - simulated
    (``sim_pc``: simulated features per cycle of the design under test; the
    measured scatter alone without it) / sqrt(n), pooled with the median of
    the same channel (few cycles), plus a small floor; and the bench
    nuisances as covariance: a transducer gain error (proportional to the
    feature) and an offset per channel. Returns (sigma diagonal, whitening
    matrix of the unit's block).

    A channel whose ``bench_floor`` entry sets ``shared_gain: true`` is
    recorded by ONE transducer chain on every damper-level test (one load
    cell, one accelerometer, one dp transducer on the flow bench): its gain
    error is common to all records. The unit's own covariance then carries
    only the run-to-run part (``record_gain``) and the common part is left
    in ``u._shared`` (channel -> gain x feature vector) for
    ``shared_covariance``, which couples the records (the whitening returned
    here is the unit's block alone, for the first look before the records
    are coupled)."""
    pc = u.per_cycle
    n = pc.shape[0]
    r = pc - sim_pc if sim_pc is not None and np.all(np.isfinite(sim_pc)) else pc
    # one steady cycle (curving): batch-means standard error inside the cycle (n = 1)
    sd = np.std(r, axis=0, ddof=1) if n >= 2 else np.asarray(u._within, float)
    mean = pc.mean(axis=0)
    sig = np.zeros_like(mean)
    fl = cfg["bench_floor"]
    names = [lab[0] for lab in u.labels]
    nf = len(names)
    C = np.zeros((nf, nf))
    u._shared = {}
    for name in dict.fromkeys(names):
        m = np.array([x == name for x in names])
        pooled = np.sqrt(0.5 * sd[m] ** 2 + 0.5 * np.median(sd[m] ** 2))
        scatter = pooled / math.sqrt(n)
        idx = np.flatnonzero(m)
        if name == TEMP_FEATURE:
            # thermocouple: white noise of the block means, an absolute floor (cold-junction drift,
            # converter step), a sensitivity error (proportional to the rise) and a lag other than
            # documented (proportional to the change of slope); no offset (the rise is offset-free)
            b = fl["oil temperature"]
            sig[m] = np.sqrt(u._tsig ** 2 + float(b["floor"]) ** 2)
            gain = float(b["gain"]) * mean[m]
            off = np.zeros(len(idx))
            C[np.ix_(idx, idx)] += np.outer(*(2 * [float(b["lag"]) * u._tlag]))
        elif u.kind == "psd":
            sig[m] = np.sqrt(scatter ** 2 + float(fl["psd_db"]) ** 2)
            gain = np.full(len(idx), float(fl["psd_offset_db"]))
            off = np.zeros(len(idx))
        else:
            ch = {"force": FORCE, "dp": DP}.get(name, ACC)
            rms = float(np.sqrt(np.mean(u.measured[ch] ** 2)))
            b = fl[{FORCE: "force", DP: "dp", ACC: "rod acceleration"}[ch]]
            sig[m] = np.sqrt(scatter ** 2 + (float(b["floor"]) * rms) ** 2)
            gain = float(b["gain"]) * mean[m]
            if b.get("shared_gain", False):
                # common chain gain (set aside for shared_covariance) + run-to-run part of this record
                key = {FORCE: "force", DP: "dp", ACC: "rod acceleration"}[ch]
                shared = u._shared.setdefault(key, np.zeros(nf))
                shared[idx] = gain
                gain = float(b.get("record_gain", 0.0)) * mean[m]
            off = np.full(len(idx), float(b["offset"]) * rms if name != "acceleration rms" else 0.0)
            # transducer delay other than documented (filter kind / order / corner): bin means shift
            # along the signal's slope
            if name != "acceleration rms" and u._slope is not None:
                C[np.ix_(idx, idx)] += np.outer(*(2 * [float(cfg.get("delay_sigma", 0.0)) * u._slope[ch]]))
        C[np.ix_(idx, idx)] += np.outer(gain, gain) + np.outer(off, off)
    sig = np.maximum(sig, 1e-12)
    C += np.diag(sig ** 2)
    u._C = C
    L = np.linalg.cholesky(C)
    return sig, np.linalg.inv(L)


def shared_covariance(units: list) -> np.ndarray:
    """Covariance of the concatenated features of ``units`` (after ``noise``):
    each unit's own block plus, per transducer chain with a shared gain, the
    outer product of its gain vectors over every unit that records it (one
    gain error, common to the records). The records' chains: flow-bench
    records share the flow bench's dp chain, damper / module records the
    load cell and the accelerometer."""
    sizes = [len(u.labels) for u in units]
    C = np.zeros((sum(sizes), sum(sizes)))
    vecs: dict = {}
    o = 0
    for u, n in zip(units, sizes):
        C[o:o + n, o:o + n] = u._C
        for key, g in getattr(u, "_shared", {}).items():
            v = vecs.setdefault(("valve" if u.configuration == "valve" else "damper", key), np.zeros(len(C)))
            v[o:o + n] = g
        o += n
    for v in vecs.values():
        C += np.outer(v, v)
    return C


def sim_signals(u: Unit, channels: dict, row: int) -> dict:
    """Simulated channels of one batch row, through the documented transducer bandwidths."""
    fs = 1.0 / float(np.mean(np.diff(u.t)))
    n = len(u.t)
    out = {}
    if u.configuration == "valve":
        return {DP: channels[SIM_DP[0]][row][:n] - channels[SIM_DP[1]][row][:n]}
    f = channels[SIM_FORCE[u.configuration]][row][:n]
    out[FORCE] = sensor_lowpass(f, u.sensors.get("force"), fs)
    if ACC in u.channels:
        out[ACC] = sensor_lowpass(channels[ACC][row][:n], u.sensors.get("acceleration"), fs)
    if u.thermal:
        out[TEMP] = thermocouple(channels[TEMP][row][:n], u.sensors.get("temperature"), fs)
    return out


def thermocouple(T: np.ndarray, fc: float | None, fs: float) -> np.ndarray:
    """The documented thermocouple: first-order lag with corner ``fc`` [Hz]
    (time constant 1 / (2 pi fc)), started at rest on the first sample."""
    if fc is None:
        return T
    return transducer(T, fs, filter="butter", order=1, corner=fc)


def sim_features(u: Unit, signals: dict, cfg: dict) -> np.ndarray:
    """Simulated features per cycle / segment [n_cyc, n_feat] (the same cycles as the measurement)."""
    if any(len(s) < len(u.t) or not np.all(np.isfinite(s)) for s in signals.values()):
        return np.full(u.per_cycle.shape, np.nan)
    if u.kind == "sine":
        pc = _sine_matrix(u, _compare(u, signals, cfg), int(cfg["phase_bins"]))
    else:
        pc = _psd_matrix(u, signals, cfg, simulated=True)
    return _with_temperature(u, pc, signals.get(TEMP), cfg)


def _compare(u: Unit, signals: dict, cfg: dict) -> dict:
    """Both sides through the same zero-phase comparison low-pass (robust to
    transducer bandwidths other than documented)."""
    from scipy.signal import butter, sosfiltfilt

    fs = 1.0 / float(np.mean(np.diff(u.t)))
    out = dict(signals)
    for ch, fc in (cfg.get("compare_lowpass") or {}).items():
        if ch in out and fc < 0.45 * fs:
            out[ch] = sosfiltfilt(butter(2, fc, fs=fs, output="sos"), out[ch])
    return out


def sim_channels(u: Unit) -> list[str]:
    if u.configuration == "valve":
        return list(SIM_DP)
    return [SIM_FORCE[u.configuration]] + ([ACC] if ACC in u.channels else []) + ([TEMP] if u.thermal else [])

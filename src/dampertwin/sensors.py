"""Measurement-chain models: what a transducer does to a signal. Used by the
virtual laboratory (its hidden bench) and by calibration and comparison (the
bench's documented bandwidth applied to simulated signals, so model and
measurement are compared through the same chain)."""

from __future__ import annotations

import numpy as np
from scipy import signal

ORDER = 2  # Butterworth order of a transducer's bandwidth


def sensor_lowpass(x: np.ndarray, fc: float | None, fs: float) -> np.ndarray:
    """Causal Butterworth low-pass at ``fc`` [Hz] (a transducer's bandwidth),
    started at rest on the first sample; no filter when ``fc`` is None or
    beyond 0.45 fs (the recording's Nyquist limit dominates)."""
    if fc is None or fc >= 0.45 * fs:
        return x
    sos = signal.butter(ORDER, fc, fs=fs, output="sos")
    zi = signal.sosfilt_zi(sos) * x[0]
    return signal.sosfilt(sos, x, zi=zi)[0]


def sensor_delay(x: np.ndarray, delay: float, fs: float) -> np.ndarray:
    """The signal ``delay`` [s] later (negative: earlier), by cubic-spline
    interpolation between samples (amplitude error < 0.1 % below 0.1 fs),
    held at its first / last value outside the record. A transducer chain
    whose filter differs from its datasheet is, below its corner, the
    documented filter plus a pure delay (issue 14)."""
    if delay == 0.0:
        return x
    from scipy.interpolate import CubicSpline

    i = np.arange(len(x), dtype=float)
    return CubicSpline(i, x)(np.clip(i - delay * fs, 0.0, len(x) - 1.0))


FILTERS = ("butter", "bessel", "none")


def transducer(x: np.ndarray, fs: float, *, filter: str = "none", order: int = 2, corner: float | None = None,
               gain: float = 1.0, offset: float = 0.0) -> np.ndarray:
    """A real transducer's chain: low-pass dynamics of its own kind
    (``butter`` Butterworth, ``bessel`` Bessel with -3 dB at ``corner`` [Hz],
    ``none``), then gain and offset errors. Causal, started at rest on the
    first sample. Noise and the converter's quantisation are added by the
    caller (they depend on its random stream and resolution)."""
    if filter not in FILTERS:
        raise ValueError(f"unknown filter {filter!r}; expected one of {', '.join(FILTERS)}")
    if filter != "none" and corner is not None and corner < 0.45 * fs:
        if filter == "butter":
            sos = signal.butter(order, corner, fs=fs, output="sos")
        else:
            sos = signal.bessel(order, corner, norm="mag", fs=fs, output="sos")
        zi = signal.sosfilt_zi(sos) * x[0]
        x = signal.sosfilt(sos, x, zi=zi)[0]
    return gain * x + offset


def quantise(x: np.ndarray, resolution: float) -> np.ndarray:
    """Analogue-to-digital conversion with step ``resolution`` (0: none)."""
    if resolution <= 0:
        return x
    return np.round(x / resolution) * resolution

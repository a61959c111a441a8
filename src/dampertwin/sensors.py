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

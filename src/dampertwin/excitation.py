"""Prescribed inputs: tube displacement [m] (damper / module) or flow into
the flow bench [m^3/s] (valve), sampled with their rates on a uniform grid
and interpolated by cubic Hermite polynomials inside the compiled model."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

EXCITATION_RATE = 20_000.0  # [Hz] sampling of analytic excitations
UNIFORM_TOL = 1e-3  # [sampling intervals] largest deviation of a time stamp from the uniform grid still called uniform


def grid_deviation(t: np.ndarray) -> float:
    """Largest deviation of the time stamps t from the uniform grid through
    their ends, in sampling intervals (0 for an exact grid)."""
    t = np.asarray(t, float)
    dt = (t[-1] - t[0]) / (len(t) - 1)
    return float(np.max(np.abs(t - (t[0] + dt * np.arange(len(t)))))) / dt


KINDS = ("displacement", "flow", "pressure")


@dataclass(frozen=True)
class Excitation:
    """Samples ``value`` and ``rate`` at t0 + k*dt. ``kind`` is
    "displacement" [m], "flow" [m^3/s] or "pressure" [Pa] (the pressure drop
    of the active-valve bench)."""

    t0: float
    dt: float
    value: np.ndarray
    rate: np.ndarray
    kind: str = "displacement"

    def __post_init__(self):
        v, r = np.asarray(self.value, float), np.asarray(self.rate, float)
        if v.ndim != 1 or v.shape != r.shape or len(v) < 2:
            raise ValueError("excitation value and rate must be 1-D arrays of equal length >= 2")
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(r))):
            raise ValueError("excitation contains non-finite samples")
        if not self.dt > 0:
            raise ValueError(f"excitation dt must be > 0, got {self.dt}")
        if self.kind not in KINDS:
            raise ValueError(f"excitation kind must be one of {', '.join(KINDS)}, got {self.kind!r}")

    @property
    def t_end(self) -> float:
        return self.t0 + self.dt * (len(self.value) - 1)

    def array(self) -> np.ndarray:
        return np.ascontiguousarray(np.vstack([self.value, self.rate]))

    @classmethod
    def sine(cls, amplitude: float, frequency: float, duration: float, ramp: float | None = None,
             sample_rate: float = EXCITATION_RATE) -> "Excitation":
        """u = A w(t) sin(2 pi f t) with a raised-cosine ramp w over ``ramp``
        seconds (default one period) so the run starts from rest."""
        ramp = 1.0 / frequency if ramp is None else ramp
        t = np.arange(0.0, duration + 0.5 / sample_rate, 1.0 / sample_rate)
        om = 2 * math.pi * frequency
        w = np.ones_like(t)
        dw = np.zeros_like(t)
        if ramp > 0:
            m = t < ramp
            w[m] = 0.5 * (1 - np.cos(math.pi * t[m] / ramp))
            dw[m] = 0.5 * math.pi / ramp * np.sin(math.pi * t[m] / ramp)
        u = amplitude * w * np.sin(om * t)
        du = amplitude * (dw * np.sin(om * t) + w * om * np.cos(om * t))
        return cls(0.0, 1.0 / sample_rate, u, du)

    @classmethod
    def from_samples(cls, t, x, kind: str = "displacement", cutoff: float | None = None) -> "Excitation":
        """From a recorded signal on a uniform time grid (e.g. the measured
        actuator displacement); the rate is the cubic-spline derivative.
        ``cutoff`` [Hz] applies a zero-phase 4th-order Butterworth low-pass
        first, so sensor noise is not differentiated into the input."""
        from scipy.interpolate import CubicSpline
        from scipy.signal import butter, sosfiltfilt

        t = np.asarray(t, float)
        x = np.asarray(x, float)
        if t.ndim != 1 or t.shape != x.shape or len(t) < 4:
            raise ValueError("time and signal must be 1-D, equal length >= 4")
        dt = np.diff(t)
        if not np.all(dt > 0) or grid_deviation(t) > UNIFORM_TOL:
            raise ValueError(f"time must be strictly increasing on a uniform grid (time stamps within {UNIFORM_TOL:g} "
                             "of an interval of it)")
        fs = 1.0 / dt.mean()
        if cutoff is not None and cutoff < 0.45 * fs:
            pad = min(len(x) - 1, int(10 * fs / cutoff))  # odd extension long enough for the edge transient
            x = sosfiltfilt(butter(4, cutoff, fs=fs, output="sos"), x, padlen=pad)
        return cls(float(t[0]), float(dt.mean()), x, CubicSpline(t, x)(t, 1), kind)

    @classmethod
    def constant_rate(cls, rate: float, duration: float, kind: str = "displacement",
                      sample_rate: float = 1000.0) -> "Excitation":
        """A constant-velocity (or constant-flow) input with a 5 ms smooth
        start; ``rate`` is m/s or m^3/s."""
        t = np.arange(0.0, duration + 0.5 / sample_rate, 1.0 / sample_rate)
        tr = 0.005
        w = np.where(t < tr, 0.5 * (1 - np.cos(math.pi * np.minimum(t, tr) / tr)), 1.0)
        r = rate * w
        x = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(t))])
        if kind == "flow":
            return cls(0.0, 1.0 / sample_rate, r, np.gradient(r, t), kind)
        return cls(0.0, 1.0 / sample_rate, x, r, kind)

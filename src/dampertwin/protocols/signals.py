"""Excitation signals of the standard tests (pure functions, seeded)."""

from __future__ import annotations

import math

import numpy as np

from ..excitation import Excitation

FADE = 0.5  # [s] raised-cosine fade-in/out of random records (start and end at rest)


def triangle_ramps(q_max: float, ramp_time: float, cycles: int, sample_rate: float = 1000.0) -> Excitation:
    """Flow-bench input [m^3/s]: ``cycles`` triangles 0 -> q_max -> 0, each
    ramp lasting ``ramp_time`` (constant, low flow acceleration)."""
    T = 2 * ramp_time * cycles
    t = np.arange(0.0, T + 0.5 / sample_rate, 1.0 / sample_rate)
    ph = np.mod(t, 2 * ramp_time) / ramp_time  # 0..2
    q = q_max * np.where(ph <= 1.0, ph, 2.0 - ph)
    rate = q_max / ramp_time * np.where(ph < 1.0, 1.0, -1.0)
    apex = np.isclose(ph, 1.0) | np.isclose(ph, 0.0) | np.isclose(ph, 2.0)
    rate[apex] = 0.0  # corners: zero slope sample, rounded by the Hermite interpolation
    return Excitation(0.0, 1.0 / sample_rate, q, rate, "flow")


def triangle_wave(amplitude: float, period: float, cycles: int, sample_rate: float = 1000.0) -> Excitation:
    """Quasi-static displacement [m]: 0 -> +A -> -A -> 0 at constant speed,
    ``cycles`` times (static load-deflection measurement)."""
    t = np.arange(0.0, period * cycles + 0.5 / sample_rate, 1.0 / sample_rate)
    ph = np.mod(t / period + 0.25, 1.0)  # 0.25 at t = 0: start at zero going up
    tri = np.where(ph < 0.5, 4 * ph - 1, 3 - 4 * ph)
    rate = np.where(ph < 0.5, 4.0, -4.0) * amplitude / period
    corner = np.isclose(np.mod(ph, 0.5), 0.0)
    rate[corner] = 0.0
    return Excitation(0.0, 1.0 / sample_rate, amplitude * tri, rate)


def band_noise(bands: list[dict], duration: float, seed: int, sample_rate: float) -> Excitation:
    """Gaussian displacement [m] whose spectrum is flat inside each band
    (``{band: [f_lo, f_hi], rms: m}``) with that band's rms, built in the
    frequency domain (velocity exact from the same spectrum), faded in and out
    over FADE seconds. Deterministic for a seed."""
    rng = np.random.default_rng(seed)
    n = int(round(duration * sample_rate)) + 1
    f = np.fft.rfftfreq(n, 1.0 / sample_rate)
    spec = np.zeros(len(f), complex)
    for b in bands:
        lo, hi = b["band"]
        m = (f >= lo) & (f <= hi)
        if not m.any():
            raise ValueError(f"band {lo}-{hi} Hz holds no frequency line at {duration} s / {sample_rate} Hz")
        z = rng.standard_normal(m.sum()) + 1j * rng.standard_normal(m.sum())
        part = np.zeros(len(f), complex)
        part[m] = z
        x = np.fft.irfft(part, n)
        part *= b["rms"] / np.sqrt(np.mean(x**2))
        spec += part
    x = np.fft.irfft(spec, n)
    v = np.fft.irfft(spec * 2j * math.pi * f, n)
    t = np.arange(n) / sample_rate
    w, dw = _fade(t, duration)
    return Excitation(0.0, 1.0 / sample_rate, x * w, v * w + x * dw)


def _fade(t, duration):
    w = np.ones_like(t)
    dw = np.zeros_like(t)
    for mask, s, sign in ((t < FADE, t, 1.0), (t > duration - FADE, duration - t, -1.0)):
        w[mask] = 0.5 * (1 - np.cos(math.pi * s[mask] / FADE))
        dw[mask] = sign * 0.5 * math.pi / FADE * np.sin(math.pi * s[mask] / FADE)
    return w, dw


def sine_burst_train(segments: list[tuple[float, float]], cycles: int, rest: float = 0.2,
                     sample_rate: float = 20_000.0) -> Excitation:
    """Approach-2 training signal (thesis 7.2): for each (amplitude [m], peak
    velocity [m/s]) a burst of ``cycles`` sine periods with raised-cosine
    envelope on the first and last period, separated by ``rest`` seconds."""
    xs, vs = [], []
    for A, vpk in segments:
        f = vpk / (2 * math.pi * A)
        T = cycles / f
        t = np.arange(0.0, T, 1.0 / sample_rate)
        om = 2 * math.pi * f
        P = 1.0 / f
        w = np.ones_like(t)
        dw = np.zeros_like(t)
        m1 = t < P
        m2 = t > T - P
        w[m1] = 0.5 * (1 - np.cos(math.pi * t[m1] / P))
        dw[m1] = 0.5 * math.pi / P * np.sin(math.pi * t[m1] / P)
        w[m2] = 0.5 * (1 - np.cos(math.pi * (T - t[m2]) / P))
        dw[m2] = -0.5 * math.pi / P * np.sin(math.pi * (T - t[m2]) / P)
        xs += [A * w * np.sin(om * t), np.zeros(int(rest * sample_rate))]
        vs += [A * (dw * np.sin(om * t) + w * om * np.cos(om * t)), np.zeros(int(rest * sample_rate))]
    return Excitation(0.0, 1.0 / sample_rate, np.concatenate(xs), np.concatenate(vs))


DYNO_REST = 0.5  # [s] damper at rest (mid-stroke) between the speed steps of a dyno test


def velocity_steps(amplitude: float, velocities: list[float], cycles: int, waveform: str = "sine",
                   rest: float = DYNO_REST, sample_rate: float = 2000.0) -> Excitation:
    """Dyno test displacement [m]: for each peak velocity [m/s] in turn
    ``cycles`` cycles of stroke amplitude ``amplitude`` [m], ``rest`` seconds
    at mid-stroke between the steps. ``sine``: bursts of
    :func:`sine_burst_train` (f = v / (2 pi A), raised-cosine run-in and
    run-out periods); ``triangle``: constant speed v, period 4 A / v (the
    constant-velocity dyno program; corners rounded by the model's Hermite
    interpolation). Starts and ends at rest at mid-stroke."""
    if waveform == "sine":
        return sine_burst_train([(amplitude, v) for v in velocities], cycles, rest, sample_rate)
    if waveform != "triangle":
        raise ValueError(f"waveform {waveform!r}; expected 'sine' or 'triangle'")
    xs, vs = [np.zeros(int(rest * sample_rate))], [np.zeros(int(rest * sample_rate))]
    for v in velocities:
        tri = triangle_wave(amplitude, 4.0 * amplitude / v, cycles, sample_rate)
        xs += [tri.value[:-1], np.zeros(int(rest * sample_rate))]  # the last sample (0) is the rest's first
        vs += [tri.rate[:-1], np.zeros(int(rest * sample_rate))]
    return Excitation(0.0, 1.0 / sample_rate, np.concatenate(xs), np.concatenate(vs))

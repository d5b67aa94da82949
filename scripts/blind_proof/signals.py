"""Excitation family for the blind proof: continuous command signals u(t) (V).

Each family draws its settings from an RNG and returns (settings, f) where f
maps a time array to the raw signal; `make_command` adds a small fast band,
maps the signal onto the drive range and evaluates it on the fine grid.
"""
from __future__ import annotations

import numpy as np

FAMILIES = ["multisine", "triangle-chirp", "log-sweep", "smoothed-steps", "damped-bursts"]
RANGES = {"unipolar": (0.05, 4.65), "bipolar": (-2.3, 2.3)}


def _multisine(rng, T, fs):
    k = int(rng.integers(5, 13))
    fmax = rng.uniform(1.5, 3.0)
    f = np.sort(rng.uniform(0.2, fmax, k))
    ph = rng.uniform(0, 2 * np.pi, k)
    a = rng.uniform(0.5, 1.0, k)
    st = {"slow_freqs_hz": f.tolist(), "slow_amps": a.tolist(), "slow_phases": ph.tolist()}

    def fn(t):
        return np.sum(a[:, None] * np.sin(2 * np.pi * f[:, None] * t[None, :] + ph[:, None]), axis=0)
    return st, fn


def _triangle_chirp(rng, T, fs):
    f0 = rng.uniform(0.3, 2.0)
    c = rng.uniform(-0.3, 0.3)  # relative frequency change over the record
    ph0 = rng.uniform(0, 1)
    st = {"f0_hz": f0, "chirp": c, "phase0": ph0}

    def fn(t):
        phase = ph0 + f0 * (t + 0.5 * c * t * t / T)
        return 2 * np.abs(2 * (phase % 1.0) - 1) - 1
    return st, fn


def _log_sweep(rng, T, fs):
    f1 = rng.uniform(0.2, 0.5)
    f2 = rng.uniform(5.0, min(60.0, 0.1 * fs))
    st = {"f1_hz": f1, "f2_hz": f2}
    k = np.log(f2 / f1) / T

    def fn(t):
        return np.sin(2 * np.pi * f1 * (np.exp(k * t) - 1) / k - np.pi / 2)
    return st, fn


def _smoothed_steps(rng, T, fs):
    times = [0.0]
    while times[-1] < T:
        times.append(times[-1] + rng.uniform(0.2, 1.5))
    times = np.asarray(times[1:])
    levels = rng.uniform(-1, 1, times.shape[0] + 1)
    width = rng.uniform(0.02, 0.2)
    st = {"dwell_s": [0.2, 1.5], "transition_s": width, "levels": levels.tolist(), "step_times": times.tolist()}

    def fn(t):
        y = np.full(t.shape, levels[0])
        for j, tj in enumerate(times):
            x = np.clip((t - tj) / width, 0.0, 1.0)
            y += (levels[j + 1] - levels[j]) * (0.5 - 0.5 * np.cos(np.pi * x))
        return y
    return st, fn


def _damped_bursts(rng, T, fs):
    starts, freqs, taus, amps = [], [], [], []
    t0 = rng.uniform(0.0, 0.5)
    while t0 < T:
        starts.append(t0)
        freqs.append(rng.uniform(0.5, 10.0))
        taus.append(rng.uniform(0.3, 1.5))
        amps.append(rng.uniform(0.4, 1.0) * rng.choice([-1, 1]))
        t0 += rng.uniform(1.0, 4.0)
    st = {"starts_s": starts, "freqs_hz": freqs, "taus_s": taus, "amps": amps}

    def fn(t):
        y = np.zeros(t.shape)
        for s0, f, tau, a in zip(starts, freqs, taus, amps):
            x = t - s0
            m = x > 0
            y[m] += a * np.sin(2 * np.pi * f * x[m]) * np.exp(-x[m] / tau)
        return y
    return st, fn


_MAKERS = {"multisine": _multisine, "triangle-chirp": _triangle_chirp, "log-sweep": _log_sweep,
           "smoothed-steps": _smoothed_steps, "damped-bursts": _damped_bursts}


def make_command(rng, family, N, fs, M, polarity):
    """Draw an excitation of `family`; return (settings, fine command, sample values).

    The fine command is the continuous signal on (N-1)*M+1 points; the
    samples are every M-th point."""
    T = (N - 1) / fs
    st, fn = _MAKERS[family](rng, T, fs)
    # small fast band so that lags, modes and delays are observable
    ftop = min(rng.uniform(50.0, 200.0), 0.35 * fs)
    k = int(rng.integers(5, 11))
    ff = np.sort(rng.uniform(min(20.0, 0.5 * ftop), ftop, k))
    fph = rng.uniform(0, 2 * np.pi, k)
    frac = rng.uniform(0.01, 0.03)
    t = np.arange((N - 1) * M + 1) / (fs * M)
    slow = fn(t)
    slow = (slow - slow.min()) / max(slow.max() - slow.min(), 1e-12)
    fast = np.sum(np.sin(2 * np.pi * ff[:, None] * t[None, :] + fph[:, None]), axis=0)
    fast = fast / max(np.max(np.abs(fast)), 1e-12)
    x = slow + frac * fast
    lo, hi = RANGES[polarity]
    x = lo + (hi - lo) * (x - x.min()) / (x.max() - x.min())
    st = dict(st)
    st.update({"family": family, "fast_band_hz": [float(ff[0]), float(ff[-1])], "fast_lines": k,
               "fast_fraction": frac, "range_v": [lo, hi]})
    return st, x, x[::M].copy()

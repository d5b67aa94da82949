"""Independent piezo-actuator simulator for the blind proof of `optbench diagnose`.

Own code path (nothing from the Rust tool): every stage runs on a fine grid
(the record's sample interval divided by the oversampling factor M >= 8):

  command u -> drive v = 15 u -> [input-lag] -> [delay] -> [saturation]
  -> [even asymmetry] -> Bouc-Wen n = 1 (exact per fine step in the drive
  variable, with optional direction / rate modifiers) -> [creep] -> [dynamics]

Linear stages use exact discretisations (matrix exponential; first-order hold
for continuous inputs, zero-order hold for a D/A staircase).  The sensor part
(offset, drift, noise, quantisation) is added by generate.py.

Every effect has a scalar `size`; size 0 (or a missing effect) skips the stage,
so the output is then bit-identical to the plain model.

Out of vocabulary (generate.py --oov; physics none of the eight names describes):
[dead-zone] acts on the amplifier's output (before input-lag); after the dynamics
come [thermal] (self-heating expansion) -> [backlash] (play) -> [sensor-nonlinearity]
-> [feed-through] (the drive coupled into the sensor); mains pick-up is the
sensor's, added by generate.py like the drift.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.linalg import expm

GAIN = 15.0  # amplifier: drive volts per command volt


# ---------------------------------------------------------------- linear blocks
def discretise(A, B, h, zoh=False):
    """Exact discretisation of dx/dt = A x + B u over a step h.

    Returns (Ad, B0, B1) with x[i] = Ad x[i-1] + B0 u[i-1] + B1 u[i]:
    first-order hold (u linear between grid points) or, with zoh, u held at
    u[i-1] over the step (a staircase that jumps at the grid points)."""
    A = np.atleast_2d(np.asarray(A, float))
    B = np.asarray(B, float).reshape(-1, 1)
    n = A.shape[0]
    M = np.zeros((n + 2, n + 2))
    M[:n, :n] = A * h
    M[:n, n:n + 1] = B * h
    M[n, n + 1] = 1.0
    E = expm(M)
    Ad = E[:n, :n]
    G1 = E[:n, n]  # integral of e^{A s} B ds: a held input
    G2 = E[:n, n + 1]  # the ramp part
    if zoh:
        return Ad.copy(), G1.copy(), np.zeros(n)
    return Ad.copy(), (G1 - G2).copy(), G2.copy()


@njit(cache=False)
def _lsim(Ad, B0, B1, C, Dff, u, x0):
    n = Ad.shape[0]
    N = u.shape[0]
    y = np.empty(N)
    x = x0.copy()
    xn = np.empty(n)
    acc = 0.0
    for c in range(n):
        acc += C[c] * x[c]
    y[0] = acc + Dff * u[0]
    for i in range(1, N):
        u0 = u[i - 1]
        u1 = u[i]
        for r in range(n):
            s = B0[r] * u0 + B1[r] * u1
            for c in range(n):
                s += Ad[r, c] * x[c]
            xn[r] = s
        acc = 0.0
        for r in range(n):
            x[r] = xn[r]
            acc += C[r] * xn[r]
        y[i] = acc + Dff * u1
    return y


def lti(A, B, C, Dff, u, h, zoh=False):
    """Simulate an LTI block from equilibrium at u[0]."""
    A = np.atleast_2d(np.asarray(A, float))
    B = np.asarray(B, float).reshape(-1)
    C = np.asarray(C, float).reshape(-1)
    Ad, B0, B1 = discretise(A, B, h, zoh)
    x0 = -np.linalg.solve(A, B) * u[0]
    return _lsim(Ad, B0, B1, C, float(Dff), np.ascontiguousarray(u, dtype=float), x0)


# ------------------------------------------------------------------ Bouc-Wen
@njit(cache=False)
def bw_step(h, dv, a, beta, gamma):
    """Exact Bouc-Wen (n = 1) update of h for a monotone drive change dv.

    dh/dv = a - beta*s*h - gamma*|h| (s = sign dv) is linear in h while the
    sign of h is fixed; a zero crossing of h splits the step."""
    s = 1.0 if dv > 0.0 else -1.0
    rem = dv
    for _ in range(3):
        if h > 0.0:
            sh = 1.0
        elif h < 0.0:
            sh = -1.0
        else:
            sh = s  # from h = 0, h moves with a*dv (a > 0)
        c = beta * s + gamma * sh
        if abs(c * rem) < 1e-12:
            hn = h + (a - c * h) * rem
            if hn * sh >= 0.0 or h == 0.0:
                return hn
            r0 = -h / (a - c * h)
        else:
            hs = a / c
            hn = hs + (h - hs) * math.exp(-c * rem)
            if hn * sh >= 0.0 or h == 0.0:
                return hn
            r0 = -math.log(hs / (hs - h)) / c
        rem -= r0
        h = 0.0
    return h


@njit(cache=False)
def _bw_pass(v, de, d0, alpha, beta, gamma, asym_dir, rate, rho_h, rho_g):
    N = v.shape[0]
    D = np.empty(N)
    h = 0.0
    for i in range(N):
        if i > 0:
            dv = v[i] - v[i - 1]
            if dv != 0.0:
                s = 1.0 if dv > 0.0 else -1.0
                a = alpha * (1.0 + asym_dir * s) * (1.0 + rho_h * rate[i])
                h = bw_step(h, dv, a, beta, gamma)
        D[i] = de * (1.0 + rho_g * rate[i]) * v[i] + d0 - h
    return D


@njit(cache=False)
def _frac_delay(x, d):
    """x delayed by d fine steps (fractional, linear interpolation; held before start)."""
    N = x.shape[0]
    y = np.empty(N)
    for i in range(N):
        t = i - d
        if t <= 0.0:
            y[i] = x[0]
        else:
            k = int(math.floor(t))
            f = t - k
            if k + 1 < N:
                y[i] = (1.0 - f) * x[k] + f * x[k + 1]
            else:
                y[i] = x[N - 1]
    return y


# ------------------------------------------------------------------ fine grid
def fine_command(samples, M, hold, continuous=None):
    """The command on the fine grid (N-1)*M+1 points for a hold convention."""
    samples = np.asarray(samples, float)
    N = samples.shape[0]
    if hold == "zoh":
        out = np.repeat(samples, M)[: (N - 1) * M + 1]
    elif hold == "linear":
        out = np.interp(np.arange((N - 1) * M + 1) / M, np.arange(N), samples)
    elif hold == "bandlimited":
        out = np.asarray(continuous, float)
        assert out.shape[0] == (N - 1) * M + 1
    else:
        raise ValueError(hold)
    return out


def rate_signal(v, dtf, tau):
    """|dv/dt| low-passed (first order, time constant tau)."""
    raw = np.empty_like(v)
    raw[1:] = np.abs(np.diff(v)) / dtf
    raw[0] = raw[1] if v.shape[0] > 1 else 0.0
    return lti([[-1.0 / tau]], [1.0 / tau], [1.0], 0.0, raw, dtf, zoh=True)


def creep_taus_gains(e):
    """(taus, gains) of the creep chain for an effect dict; gains scale with size."""
    s = e["size"]
    if e["form"] == "kelvin-voigt":
        taus = np.asarray(e["taus"], float)
        w = np.asarray(e["weights"], float)
    else:  # logarithmic: equal gain per decade, 2 elements per decade 10 ms .. 100 s
        taus = np.logspace(-2, 2, 9)
        w = np.full(taus.shape[0], 1.0 / taus.shape[0])
    return taus, s * w


def simulate_fine(cmd_fine, dtf, M, plain, effects, consts, zoh=False):
    """Noise-free displacement (mm) on the fine grid.

    plain: dict de, d0, alpha, beta, gamma.
    effects: dict name -> dict(form=..., size=..., <form settings>).
    consts: dict vref (drive scale, V), rate_norm (RMS low-passed rate of the
    plain training drive, V/s; only for rate-dependence)."""
    eff = {k: e for k, e in effects.items() if e.get("size", 0.0) != 0.0}
    v = GAIN * np.asarray(cmd_fine, float)
    staircase = zoh
    if "dead-zone" in eff:  # out of vocabulary: the amplifier's dead band about its mid level
        v = dead_zone(v, consts["v_mid"], eff["dead-zone"]["size"] * consts["v_half"])
    v_amp = v  # the amplifier's output (what heats the stack, what couples into the sensor)
    if "input-lag" in eff:
        e = eff["input-lag"]
        w = 1.0 / e["size"]  # size = time constant 1/omega (s)
        if e["form"] == "first-order":
            v = lti([[-w]], [w], [1.0], 0.0, v, dtf, zoh=staircase)
        else:
            z = e["damping"]
            v = lti([[0.0, 1.0], [-w * w, -2 * z * w]], [0.0, w * w], [1.0, 0.0], 0.0, v, dtf, zoh=staircase)
        staircase = False
    if "delay" in eff:
        v = _frac_delay(v, eff["delay"]["size"] * M)
        staircase = False
    vref = consts["vref"]
    if "saturation" in eff:
        e = eff["saturation"]
        s = e["size"]
        if e["form"] == "hard-clip":
            L = vref * (1.0 - s)
            v = np.clip(v, -L, L)
        elif e["form"] == "tanh":
            L = vref / s
            v = L * np.tanh(v / L)
        else:  # cubic compression
            v = v - s * v ** 3 / vref ** 2
    asym_dir = 0.0
    if "asymmetry" in eff:
        e = eff["asymmetry"]
        if e["form"] == "even":
            v = v + e["size"] * v * v / vref
        else:
            asym_dir = e["size"]
    rate = np.zeros_like(v)
    rho_h = rho_g = 0.0
    if "rate-dependence" in eff:
        e = eff["rate-dependence"]
        rate = rate_signal(v, dtf, e["tau"]) / consts["rate_norm"]
        if e["form"] == "loop-width":
            rho_h = e["size"]
        else:
            rho_g = e["size"]
    p = plain
    D = _bw_pass(np.ascontiguousarray(v), p["de"], p["d0"], p["alpha"], p["beta"], p["gamma"],
                 asym_dir, np.ascontiguousarray(rate), rho_h, rho_g)
    if "creep" in eff:
        taus, g = creep_taus_gains(eff["creep"])
        n = taus.shape[0]
        A = np.diag(-1.0 / taus)
        B = g / taus
        D = p["d0"] + lti(A, B, np.ones(n), 1.0, D - p["d0"], dtf, zoh=staircase)
    if "dynamics" in eff:
        e = eff["dynamics"]
        w1 = 1.0 / e["size"]
        z1 = e["zeta"]
        if e["form"] == "one-mode":
            A = [[0.0, 1.0], [-w1 * w1, -2 * z1 * w1]]
            B = [0.0, w1 * w1]
            C = [1.0, 0.0]
        else:
            w2 = w1 * e["ratio"]
            z2 = e["zeta2"]
            sh = e["share"]
            A = np.zeros((4, 4))
            A[0, 1] = A[2, 3] = 1.0
            A[1, 0], A[1, 1] = -w1 * w1, -2 * z1 * w1
            A[3, 2], A[3, 3] = -w2 * w2, -2 * z2 * w2
            B = [0.0, (1 - sh) * w1 * w1, 0.0, sh * w2 * w2]
            C = [1.0, 0.0, 1.0, 0.0]
        D = lti(A, B, C, 0.0, D, dtf, zoh=staircase)
    if OOV_STAGES & eff.keys():
        D = oov_stages(D, v_amp, dtf, eff, consts, zoh)
    return D


# ------------------------------------------------------------ out of vocabulary
# Physics outside the eight names `optbench diagnose` knows (generate.py's --oov cases).
# Each is skipped when absent or of size 0, so the cases of the eight are unchanged.
OOV_STAGES = {"thermal", "backlash", "sensor-nonlinearity", "feed-through"}


def dead_zone(v, v_mid, half_width):
    """An amplifier with no output change while |v - v_mid| < half_width (crossover dead band)."""
    x = v - v_mid
    return v_mid + np.sign(x) * np.maximum(np.abs(x) - half_width, 0.0)


@njit(cache=False)
def play(x, r):
    """Mechanical play (backlash) of half-width r: the follower moves only when the driver
    pushes it at one edge of the gap; starts centred on x[0]."""
    N = x.shape[0]
    y = np.empty(N)
    p = x[0]
    for i in range(N):
        if x[i] - r > p:
            p = x[i] - r
        elif x[i] + r < p:
            p = x[i] + r
        y[i] = p
    return y


def drive_power(v, dtf, form):
    """Heating power (up to a constant) of the drive: `joule` v^2 (leakage / ohmic losses),
    `dielectric` |v dv/dt| (the loss of charging the stack's capacitance, ~ C v dv/dt tan delta).
    Even in v: the drive's sign does not matter."""
    if form == "joule":
        return v * v
    p = np.empty_like(v)
    p[1:] = np.abs(0.5 * (v[1:] + v[:-1]) * np.diff(v)) / dtf
    p[0] = p[1] if v.shape[0] > 1 else 0.0
    return p


def thermal_term(v, dtf, e, p_ref):
    """Unit thermal expansion: the drive's power low-passed (first order, tau_s), over the plain
    training drive's mean power; starts at `start` times the record's mean power."""
    p = drive_power(v, dtf, e["form"]) / p_ref
    tau = e["tau_s"]
    Ad = math.exp(-dtf / tau)
    x0 = e.get("start", 0.0) * float(np.mean(p))
    out = lti([[-1.0 / tau]], [1.0 / tau], [1.0], 0.0, p, dtf, zoh=True)
    # lti starts at equilibrium with p[0]; shift to the drawn start state (the record's history)
    n = np.arange(p.shape[0], dtype=float)
    return out + (x0 - p[0]) * Ad ** n


def high_pass(v, dtf, tau, zoh=False):
    """First-order high-pass tau s / (1 + tau s) of v (from rest at v[0])."""
    return v - lti([[-1.0 / tau]], [1.0 / tau], [1.0], 0.0, v, dtf, zoh=zoh)


def sensor_nonlinearity(y, e, y_mid, stroke):
    """The sensor's reading of displacement y (c = sign * size): `quadratic` y + c (y - y_mid)^2 / stroke
    (a capacitive gauge's gap non-linearity), `periodic` y + c stroke sin(2 pi (y - y_mid) / period + phase)
    (an interferometer's or encoder's cyclic error, period a fraction of the stroke)."""
    c = e["size"] * e.get("sign", 1.0)
    if e["form"] == "quadratic":
        return y + c * (y - y_mid) ** 2 / stroke
    period = stroke / e["periods_per_stroke"]
    return y + c * stroke * np.sin(2 * np.pi * (y - y_mid) / period + e["phase"])


def oov_stages(D, v_amp, dtf, eff, consts, zoh):
    """Displacement-side and sensor-side stages outside the vocabulary, after the dynamics:
    self-heating expansion -> play between actuator and sensor target -> sensor
    non-linearity -> capacitive feed-through of the drive into the sensor."""
    stroke = consts["stroke"]
    if "thermal" in eff:
        e = eff["thermal"]
        D = D + e["size"] * e["sign"] * stroke * thermal_term(v_amp, dtf, e, consts["p_ref"])
    if "backlash" in eff:
        D = play(np.ascontiguousarray(D), 0.5 * eff["backlash"]["size"] * stroke)
    if "sensor-nonlinearity" in eff:
        D = sensor_nonlinearity(D, eff["sensor-nonlinearity"], consts["y_mid"], stroke)
    if "feed-through" in eff:
        e = eff["feed-through"]
        D = D + e["size"] * e["sign"] * stroke * high_pass(v_amp, dtf, e["tau_s"], zoh) / consts["hp_ref"]
    return D


def simulate_record(cmd_fine, dt, M, plain, effects, consts, hold):
    """Noise-free displacement at the record's samples."""
    D = simulate_fine(cmd_fine, dt / M, M, plain, effects, consts, zoh=(hold == "zoh"))
    return D[::M].copy()


def plain_drive_rate_rms(cmd_fine, dt, M, tau):
    r = rate_signal(GAIN * np.asarray(cmd_fine, float), dt / M, tau)
    return float(np.sqrt(np.mean(r * r)))

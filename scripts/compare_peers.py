"""optbench against peer libraries at equal evaluation budgets (run by scripts/compare-peers).

Problems and methods (every method gets exactly the same number of evaluations):

1. 30-D Griewank in [-600, 600], 40,000 evaluations (the budget of suites/functions.toml):
   - PSO, 200 particles x 200 iterations, constant inertia 0.7298, c1 = c2 = 1.49618,
     velocity clamp 20 % of the domain, positions clipped to the box: pyswarms
     GlobalBestPSO against optbench's `pso` with the same settings;
   - DE/rand/1/bin, population 100, F 0.5, CR 0.9, generational updates:
     scipy.optimize.differential_evolution (updating="deferred", polish off, no early
     stop) against optbench's `de`.
2. The Bouc-Wen fit of suites/hysteresis.toml's bw-1hz (twin recording, 1 Hz sine, 1 s at
   1 ms, parameters d_e, alpha, beta, gamma, n in [0, 1.5], cost J = sum e^2 / 2 of the
   free-run simulation), 30,000 evaluations, same two method pairs. The numpy objective is
   vectorised over the population and follows optbench's recurrence (src/physics/bouc_wen.rs):
   input linear between samples, the rate-independent ODE dg/dv = alpha - c(g)|g|^n in
   the input, solved in closed form for n = 1 and by RK4 with equal sub-steps otherwise
   (optbench grades its steps near the cusp at g = 0; the difference is reported as the
   largest relative difference between the two costs at optbench's final points), the same
   instability bound and penalty, and the same cost cap.

3. Evaluation speed of the dissertation's Bouc-Wen recurrence (optbench's `scheme = "explicit"`,
   src/physics/bouc_wen_fast.rs: one clamped Euler step per sample, one |h|^n) over the
   record and population of `optbench bench` (200 individuals x 10,000 samples): a numpy
   port as fast as numpy allows (vectorised over the population, a loop over time doing
   only the recurrence with preallocated arrays and in-place ufuncs with `out=`, then the
   cost and the instability check vectorised over the stored states, with a re-run of the
   rare lanes that exceed the bound) against optbench's batched path
   on one core, read from `optbench bench --json` (run here, or given with --bench-json).
   The port is first checked against optbench's costs on the same record.

Times are wall-clock seconds per trial on one thread (optbench `--threads 1`; numpy may use
its BLAS threads, which these element-wise loops hardly touch), medians over the trials.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import pyswarms
import scipy
from pyswarms.single import GlobalBestPSO
from scipy.optimize import differential_evolution

W, C1, C2 = 0.7298, 1.49618, 1.49618  # Clerc's constriction coefficients, both sides
SINE_1HZ = "sine:freq=1,amp=2.3,offset=2.35,phase=-1.5707963267948966"


# --- objectives -------------------------------------------------------------------------


def griewank(x):
    """Griewank on rows of x (dissertation eq. 2.12); minimum 0 at 0."""
    x = np.atleast_2d(x)
    i = np.sqrt(np.arange(1, x.shape[1] + 1))
    return 1.0 + (x * x).sum(axis=1) / 4000.0 - np.prod(np.cos(x / i), axis=1)


def expm1_ratio(x):
    """(1 - exp(-x)) / x, 1 - x/2 near 0 (as optbench)."""
    small = np.abs(x) < 1e-8
    safe = np.where(small, 1.0, x)
    return np.where(small, 1.0 - 0.5 * x, -np.expm1(-safe) / safe)


def ln1p_ratio(x):
    """ln(1 + x) / x, 1 - x/2 near 0 (as optbench)."""
    small = np.abs(x) < 1e-8
    safe = np.where(small, 1.0, x)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(small, 1.0 - 0.5 * x, np.log1p(safe) / safe)


class BoucWenCost:
    """J = sum e^2 / 2 of the Bouc-Wen free run, for a whole population at once."""

    def __init__(self, u, y, substeps=4):
        self.u = np.asarray(u, float)
        self.y = np.asarray(y, float)
        self.m = substeps
        s = float(np.sum(self.y[np.isfinite(self.y)] ** 2))
        self.cap = min(1e12 * (1.0 + 0.5 * s), sys.float_info.max / 4.0)
        self.umax = float(np.max(np.abs(self.u)))
        self.calls = 0

    def __call__(self, p):
        p = np.atleast_2d(np.asarray(p, float))
        self.calls += p.shape[0]
        d_e, a, b, c, n = (p[:, k] for k in range(5))
        cp, cm = b + c, c - b  # coefficient of |g|^n for g >= 0 and g < 0
        exact = n == 1.0
        bound = 1e6 * (1.0 + np.abs(a)) * self.umax
        h = np.zeros(len(p))
        j = np.zeros(len(p))
        blown = np.full(len(p), -1)
        alive = np.ones(len(p), bool)
        u, y, N = self.u, self.y, len(self.u)
        with np.errstate(all="ignore"):
            for i in range(N):
                if i > 0:
                    du = u[i] - u[i - 1]
                    if du != 0.0:
                        s = 1.0 if du > 0 else -1.0
                        v = abs(du)
                        g = s * h
                        g_new = np.where(exact, self._exact(g, v, a, cp, cm), g)
                        if not exact.all():
                            g_new = np.where(exact, g_new, self._rk4(g, v, a, cp, cm, n))
                        h = s * g_new
                d = d_e * u[i] - h
                bad = alive & (~np.isfinite(h) | (np.abs(h) > bound))
                blown[bad] = i
                alive &= ~bad
                e = y[i] - d
                j = np.where(alive, j + 0.5 * e * e, j)
        out = np.where(j <= 1e12, j, np.minimum(j, self.cap))
        return np.where(alive, out, self.cap * (2.0 - blown / N))

    @staticmethod
    def _exact(g0, v, a, cp, cm):
        """n = 1: optbench's advance_exact in the one-directional frame."""
        cn = -cm
        c0 = np.where((g0 > 0) | ((g0 == 0) & (a >= 0)), cp, cn)
        toward = g0 * a < 0
        x = np.where(toward, -c0 * g0 / np.where(a == 0, 1.0, a), 0.0)
        v0 = np.where(toward & (x > -1), (-g0 / np.where(a == 0, 1.0, a)) * ln1p_ratio(x), np.inf)
        cross = toward & (x > -1) & (v0 < v)
        c1 = np.where(a > 0, cp, cn)
        rest = v - np.where(cross, v0, 0.0)
        crossed = a * rest * expm1_ratio(c1 * rest)
        slope = a - c0 * g0
        plain = np.where(slope == 0, g0, g0 + slope * v * expm1_ratio(c0 * v))
        return np.where(cross, crossed, plain)

    def _rk4(self, g, v, a, cp, cm, n):
        """Other n: RK4 in the input with m equal sub-steps."""

        def rate(g):
            return a - np.where(g >= 0, cp, cm) * np.abs(g) ** n

        ell = v / self.m
        for _ in range(self.m):
            k1 = rate(g)
            k2 = rate(g + 0.5 * ell * k1)
            k3 = rate(g + 0.5 * ell * k2)
            k4 = rate(g + ell * k3)
            g = g + ell / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        return g


# --- peers ------------------------------------------------------------------------------


def explicit_costs(P, u, y):
    """Costs J = sum e^2 / 2 of the explicit recurrence for the rows [d_e, alpha, beta, gamma,
    n, d0] of P on (u, y): optbench's bouc_wen_fast::run_explicit, vectorised over P."""
    P = np.asarray(P, dtype=float)
    k = len(P)
    d_e, alpha, beta, gamma, n, d0 = (np.ascontiguousarray(P[:, i]) for i in range(6))
    c_pos, c_neg = beta + gamma, gamma - beta

    def equilibrium(c):
        with np.errstate(all="ignore"):
            r = alpha / c
            e = r ** (1.0 / n)
        return np.where((r > 0) & np.isfinite(e), e, 1e300)

    eq_lo, eq_hi = -equilibrium(c_neg), equilibrium(c_pos)
    umax = float(np.max(np.abs(u)))
    bound = 1e6 * (1.0 + np.abs(alpha)) * umax
    du = np.diff(u, prepend=u[0])
    sign = np.where(du < 0, -1.0, 1.0)
    ell = np.abs(du)
    ell[0] = 0.0
    # The states of every sample are kept (T x k, preallocated), so that the cost and the
    # instability check run vectorised over time after the loop: the loop does the
    # recurrence only.
    H = np.zeros((len(u), k))
    g, a, c0, lo, hi = (np.empty(k) for _ in range(5))
    pos = np.empty(k, dtype=bool)
    h = H[0]
    with np.errstate(all="ignore"):
        for t, (s, l) in enumerate(zip(sign.tolist(), ell.tolist())):
            if l > 0.0:
                np.multiply(h, s, out=g)
                np.abs(g, out=a)
                np.fmax(a, TINY, out=a)
                np.power(a, n, out=a)  # |g|^n
                np.greater_equal(g, 0.0, out=pos)
                np.copyto(c0, c_neg)
                np.copyto(c0, c_pos, where=pos)
                np.multiply(c0, a, out=a)
                np.subtract(alpha, a, out=a)  # the rate
                np.multiply(a, l, out=a)
                np.add(a, g, out=a)  # the Euler step
                np.minimum(g, eq_lo, out=lo)
                np.maximum(g, eq_hi, out=hi)
                np.clip(a, lo, hi, out=a)  # the monotone path to the equilibrium
                np.multiply(a, s, out=H[t])
            elif t > 0:
                H[t] = h
            h = H[t]
        E = (y[:, None] - (u[:, None] * d_e + d0)) + H
        j = np.einsum("ij,ij->j", E, E)
        peak = np.max(np.abs(H), axis=0)  # NaN stays NaN
    cap = min(1e12 * (1.0 + 0.5 * float(np.sum(y[np.isfinite(y * y)] ** 2))), sys.float_info.max / 4)
    j *= 0.5
    out = np.where(j <= 1e12, j, np.minimum(j, cap))
    bad = np.flatnonzero(~(peak <= bound))
    for i in bad:  # rare: find the first unstable sample of each such lane
        hi_, n_ = 0.0, P[i, 4]
        at = len(u)
        for t in range(len(u)):
            if ell[t] > 0.0:
                gi = sign[t] * hi_
                pn = max(abs(gi), TINY) ** n_ if abs(gi) > TINY else TINY ** n_
                ci = c_pos[i] if gi >= 0 else c_neg[i]
                gh = gi + ell[t] * (alpha[i] - ci * pn)
                gh = min(max(gh, min(gi, eq_lo[i])), max(gi, eq_hi[i]))
                hi_ = sign[t] * gh
            if not abs(hi_) <= bound[i]:
                at = t
                break
        out[i] = cap * (2.0 - at / len(u))
    return out


TINY = 1e-300


def explicit_speed(binary, bench_json, work):
    """numpy's M samples/s on optbench bench's record and population, and optbench's."""
    if bench_json is None:
        bench_json = os.path.join(work, "bench.json")
        subprocess.run([binary, "bench", "--json", bench_json], check=True, stdout=subprocess.DEVNULL)
    with open(bench_json) as f:
        bench = json.load(f)
    check = bench["explicit_check"]
    u, y = np.array(check["u"]), np.array(check["y"])
    mine = explicit_costs(check["params"], u, y)
    ref = np.array(check["reference"])
    agree = float(np.max(np.abs(mine - ref) / np.abs(ref)))
    agree_batched = float(np.max(np.abs(mine - np.array(check["batched"])) / np.abs(ref)))
    # A population like the benchmark's (the JSON holds only the check rows): each parameter
    # within +-50 % of the first row's, n from 0.5 to 1.5; numpy's time per sample does not
    # depend on the values (no lane blows up here, so no re-runs).
    rng = np.random.default_rng(7)
    truth = np.array(check["params"][0])
    pop = np.abs(truth) * rng.uniform(0.5, 1.5, size=(bench["population"], 6))
    pop[:, 4] = rng.uniform(0.5, 1.5, size=bench["population"])
    pop[:, 5] = 0.0
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        explicit_costs(pop, u, y)
        times.append(time.perf_counter() - t0)
    rate = bench["population"] * len(u) / min(times) / 1e6
    row = next(r for r in bench["rows"] if r["name"] == "bouc-wen (explicit recurrence)")
    return {
        "numpy": rate,
        "optbench": row["batched"],
        "optbench_threads": row["threads"],
        "agree_reference": agree,
        "agree_batched": agree_batched,
        "check": list(zip(mine.tolist(), ref.tolist())),
        "threads": bench["threads"],
        "accelerated": bench["accelerated"],
        "population": bench["population"],
        "samples": len(u),
    }


def run_pyswarms(f, lo, hi, particles, iters, seed):
    np.random.seed(seed)
    dim = len(lo)
    vmax = 0.2 * (hi - lo)
    opt = GlobalBestPSO(
        n_particles=particles,
        dimensions=dim,
        options={"c1": C1, "c2": C2, "w": W},
        bounds=(lo, hi),
        bh_strategy="nearest",
        velocity_clamp=(-float(vmax.max()), float(vmax.max())),
    )
    t = time.perf_counter()
    best, _ = opt.optimize(f, iters=iters, verbose=False)
    return best, time.perf_counter() - t


def run_scipy_de(f, lo, hi, population, budget, seed):
    rng = np.random.default_rng(seed)
    dim = len(lo)
    init = lo + rng.random((population, dim)) * (hi - lo)
    maxiter = budget // population - 1  # the initial population is one generation
    calls = [0]

    def vf(x):  # scipy passes (dim, S) to vectorised objectives
        calls[0] += x.shape[1]
        return f(x.T)

    t = time.perf_counter()
    r = differential_evolution(
        vf,
        list(zip(lo, hi)),
        strategy="rand1bin",
        mutation=0.5,
        recombination=0.9,
        maxiter=maxiter,
        init=init,
        tol=0,
        atol=0,
        polish=False,
        updating="deferred",
        vectorized=True,
        rng=rng,
    )
    elapsed = time.perf_counter() - t
    assert calls[0] == budget, f"scipy DE spent {calls[0]} evaluations, not {budget}"
    return r.fun, elapsed


# --- optbench ---------------------------------------------------------------------------


def optbench_suite(path, objective, budget, trials):
    with open(path, "w") as fh:
        fh.write(
            f"""name = "peers"
seed = 2013
trials = {trials}
budget = {budget}

{objective}

[[optimizer]]
kind = "pso"
id = "PSO"
population = 200
w_start = {W}
w_end = {W}
c1 = {C1}
c2 = {C2}
vmax = 0.2

[[optimizer]]
kind = "de"
id = "DE"
population = 100
f = 0.5
cr = 0.9
"""
        )


def run_optbench(binary, suite, out):
    subprocess.run(
        [binary, "run", suite, "--out", out, "--threads", "1", "-q"], check=True
    )
    rows = {}
    with open(os.path.join(out, "traces.jsonl")) as fh:
        for line in fh:
            r = json.loads(line)
            rows.setdefault(r["optimizer"], []).append(r)
    return rows


def median(v):
    return float(np.median(v))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--binary", required=True)
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--work", default=None, help="folder for suites and results (default: temporary)")
    ap.add_argument("--bench-json", default=None, help="an `optbench bench --json` file to use (default: run it)")
    ap.add_argument("--speed-only", action="store_true", help="only part 3, the recurrence's speed")
    args = ap.parse_args()
    work = args.work or tempfile.mkdtemp(prefix="optbench-peers-")
    os.makedirs(work, exist_ok=True)
    print(
        f"numpy {np.__version__}, scipy {scipy.__version__}, pyswarms {pyswarms.__version__}; "
        f"{args.trials} trials per method; work folder {work}\n"
    )
    rows = []
    if args.speed_only:
        print_speed(explicit_speed(args.binary, args.bench_json, work))
        return

    # 1. Griewank 30-D.
    lo, hi = np.full(30, -600.0), np.full(30, 600.0)
    suite = os.path.join(work, "griewank.toml")
    optbench_suite(
        suite,
        '[[objective]]\nkind = "griewank"\nid = "griewank-30d"\ndim = 30\nlower = -600\nupper = 600',
        40000,
        args.trials,
    )
    ob = run_optbench(args.binary, suite, os.path.join(work, "griewank"))
    peer_pso = [run_pyswarms(griewank, lo, hi, 200, 200, s) for s in range(args.trials)]
    peer_de = [run_scipy_de(griewank, lo, hi, 100, 40000, s) for s in range(args.trials)]
    rows.append(("griewank-30d, 40k evals", "PSO", "pyswarms", ob["PSO"], peer_pso, lambda v: v))
    rows.append(("griewank-30d, 40k evals", "DE", "scipy", ob["DE"], peer_de, lambda v: v))

    # 2. Bouc-Wen fit at 1 Hz.
    rec_dir = os.path.join(work, "twin-1hz")
    subprocess.run(
        [args.binary, "simulate", "--signal", SINE_1HZ, "--duration", "1",
         "--columns", "t_s,u_V,y_mm", "--out", rec_dir],
        check=True, stdout=subprocess.DEVNULL,
    )
    csv = os.path.join(rec_dir, "twin.csv")
    data = np.genfromtxt(csv, delimiter=",", names=True)
    cost = BoucWenCost(data["u_V"], data["y_mm"])
    n_samples = len(data)
    rmse = lambda j: math.sqrt(2.0 * max(j, 0.0) / n_samples)  # noqa: E731 (mm)
    suite = os.path.join(work, "boucwen.toml")
    optbench_suite(
        suite,
        f'[[objective]]\nkind = "bouc-wen"\nid = "bw-1hz"\nrecording = "{csv}"\n'
        'columns = "t_s,u_V,y_mm"\nnormalize = false\nlower = 0\nupper = 1.5',
        30000,
        args.trials,
    )
    ob = run_optbench(args.binary, suite, os.path.join(work, "boucwen"))
    lo, hi = np.zeros(5), np.full(5, 1.5)
    peer_pso = [run_pyswarms(cost, lo, hi, 200, 150, s) for s in range(args.trials)]
    peer_de = [run_scipy_de(cost, lo, hi, 100, 30000, s) for s in range(args.trials)]
    rows.append(("Bouc-Wen fit 1 Hz, 30k evals (RMSE mm)", "PSO", "pyswarms", ob["PSO"], peer_pso, rmse))
    rows.append(("Bouc-Wen fit 1 Hz, 30k evals (RMSE mm)", "DE", "scipy", ob["DE"], peer_de, rmse))

    # The numpy objective against optbench's at optbench's final points.
    finals = [r for rs in ob.values() for r in rs]
    mine = cost(np.array([r["best_x"] for r in finals]))
    rel = max(abs(m - r["best"]) / abs(r["best"]) for m, r in zip(mine, finals))
    n_ones = sum(1 for r in finals if r["best_x"][4] == 1.0)

    print("| problem | method | optbench median final | peer | peer median final | optbench s/trial | peer s/trial | peer / optbench time |")
    print("|---|---|---:|---|---:|---:|---:|---:|")
    for problem, method, peer, ours, theirs, show in rows:
        ours_final = median([show(r["best"]) for r in ours])
        ours_time = median([r["wall_s"] for r in ours])
        assert all(r["evaluations"] == r["budget"] for r in ours)
        their_final = median([show(v) for v, _ in theirs])
        their_time = median([t for _, t in theirs])
        print(
            f"| {problem} | {method} | {ours_final:.4g} | {peer} | {their_final:.4g} "
            f"| {ours_time:.3f} | {their_time:.3f} | {their_time / ours_time:.1f}x |"
        )
    print(
        f"\nnumpy Bouc-Wen cost vs optbench's at optbench's {len(finals)} final points: "
        f"largest relative difference {rel:.2e} ({n_ones} of them at n = 1 exactly, the closed form; "
        f"the others RK4 with {cost.m} equal sub-steps against optbench's graded steps)"
    )
    print()
    print_speed(explicit_speed(args.binary, args.bench_json, work))


def print_speed(sp):
    print(
        f"The dissertation's Bouc-Wen recurrence (optbench scheme = \"explicit\"), "
        f"{sp['population']} individuals x {sp['samples']} samples:"
    )
    for mine, ref in sp["check"]:
        print(f"  cost check: numpy {mine!r}  optbench reference {ref!r}")
    print(
        f"  numpy port vs optbench: largest relative difference {sp['agree_reference']:.1e} against its "
        f"powf reference path, {sp['agree_batched']:.1e} against its batched path"
    )
    path = "AVX2+FMA" if sp["accelerated"] else "portable"
    print(f"  numpy, one thread:                {sp['numpy']:8.1f} M samples/s")
    print(f"  optbench batched ({path}), per core: {sp['optbench']:8.1f} M samples/s "
          f"({sp['optbench_threads']:.1f} per core on {sp['threads']} threads)")
    print(f"optbench / numpy = {sp['optbench'] / sp['numpy']:.1f}x")


if __name__ == "__main__":
    main()

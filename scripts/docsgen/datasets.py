"""Chapter 16's table of the data folder and chapter 9's facts about the Bouc-Wen benchmark
record, read from the files themselves (no optbench run): sampling rates from the time
columns, records and samples counted, the benchmark training record's periods (its input
repeats exactly) and its measurement noise (the spread of the output between periods, the
first period left out as it carries the start-up transient). Needs the data folder."""

import csv
import math
import re

from docsgen._util import count_words, sig, thousands

FRAGMENTS = ["data-folders", "data-boucwen-record", "data-boucwen-rate"]
FOLDERS = ["boucwen-benchmark", "mr-damper-labcontrol", "pea_p885_dbo", "fsm_cubespec_piezo"]
BENCH_TRAIN = "train_multisine_forgione.csv"
BENCH_PERIOD = "test_multisine.csv"   # one steady-state period of the multisine (README.txt)


def read(path):
    with open(path, newline="") as f:
        rows = csv.reader(f)
        header = next(rows)
        return header, [[float(x) for x in r] for r in rows if r]


def rate(t):
    """Samples per second from a time column (uniform to 0.1 % of a step: stamps are rounded)."""
    dt = (t[-1] - t[0]) / (len(t) - 1)
    if any(abs((b - a) - dt) > 1e-3 * dt for a, b in zip(t, t[1:])):
        raise RuntimeError("the time column is not uniform")
    return 1 / dt


def describe(path):
    header, rows = read(path)
    t = [r[header.index("t_s")] for r in rows]
    return {"columns": header, "samples": len(rows), "rate_hz": rate(t),
            "duration_s": t[-1] - t[0] + (t[1] - t[0])}


def bench_record(folder):
    """Periods and period-to-period noise of the benchmark's training record."""
    header, rows = read(folder / BENCH_TRAIN)
    period = len(read(folder / BENCH_PERIOD)[1])
    ui, yi = header.index("u_N"), header.index("y_m")
    u, y = [r[ui] for r in rows], [r[yi] for r in rows]
    if len(u) % period or any(u[i] != u[i + period] for i in range(len(u) - period)):
        raise RuntimeError(f"{BENCH_TRAIN}'s input does not repeat every {period} samples")
    periods = [y[k * period:(k + 1) * period] for k in range(1, len(y) // period)]
    m, ss = len(periods), 0.0
    for i in range(period):
        mean = sum(p[i] for p in periods) / m
        ss += sum((p[i] - mean) ** 2 for p in periods)
    return {"samples": len(u), "period": period, "periods": len(u) // period,
            "noise_rms_m": math.sqrt(ss / (period * (m - 1)))}


def collect(ctx):
    folders = {}
    for name in FOLDERS:
        base = ctx.need_data(name)
        folders[name] = {p.name: describe(p) for p in sorted(base.glob("*.csv"))}
    return {"folders": folders,
            "bench": bench_record(ctx.need_data("boucwen-benchmark"))}


def render(d):
    fo = d["folders"]

    def hz(name):
        rates = {round(f["rate_hz"], 3) for f in fo[name].values()}
        if len(rates) != 1:
            raise RuntimeError(f"{name}: files at different rates {rates}")
        r = rates.pop()
        return f"{r:.0f} Hz" if r == round(r) else f"{sig(r)} Hz"

    def samples(name, pattern):
        return [f["samples"] for n, f in fo[name].items() if re.fullmatch(pattern, n)]

    def counted(ns):
        return (f"{len(ns)} x {thousands(ns[0])}" if len(set(ns)) == 1
                else " + ".join(thousands(n) for n in ns))

    bw, mr, pea, fsm = FOLDERS
    b = d["bench"]
    runs, vali = samples(mr, r"ensaio_A_\d+\.csv"), samples(mr, r"ensaio_vali_A_\d+\.csv")
    test = fo[pea]["dbo_test_ramped_sine_with_holds.csv"]
    cols = next(iter(fo[fsm].values()))["columns"]
    ins = sum(1 for c in cols if re.fullmatch(r"u\d+_V", c))
    outs = sum(1 for c in cols if re.fullmatch(r"y\d+_um", c))
    levels = {re.match(r"fsm_(\d+)mV_", n).group(1) for n in fo[fsm]}
    link6, link9 = "06-hysteresis-claims.md", "09-diagnosis-real-data.md"
    rows = [
        (bw, "the nonlinear system identification benchmark \"hysteretic system with a dynamic "
             "nonlinearity\" (official test sets, a training set from the official simulator; "
             "published results in its `RESULTS.md`)",
         f"force N -> displacement m, {hz(bw)}",
         f"training {thousands(fo[bw][BENCH_TRAIN]['samples'])}; tests "
         f"{thousands(fo[bw]['test_multisine.csv']['samples'])} (multisine), "
         f"{thousands(fo[bw]['test_sinesweep.csv']['samples'])} (sine sweep)",
         f"[6]({link6}#benchmark-and-measured-data), [9]({link9}#bouc-wen-benchmark)"),
        (mr, f"a magnetorheological damper on a shaking table, {len(runs)} sinusoidal runs and "
             f"{len(vali)} validation runs",
         f"position mm / velocity mm/s -> force N, {hz(mr)}",
         counted(runs + vali),
         f"[6]({link6}#benchmark-and-measured-data), [9]({link9}#mr-damper)"),
        (pea, f"a PI P-885.91 piezo stack: a 1 Hz identification run and a "
              f"{test['duration_s']:.0f} s test with amplitude ramps and holds",
         f"command V -> displacement um, {hz(pea)}",
         counted([fo[pea]["dbo_identification_1Hz_sine.csv"]["samples"], test["samples"]]),
         f"[9]({link9}#a-real-piezo-stack-end-to-end)"),
        (fsm, f"the CubeSpec fine steering mirror, {ins} piezo inputs and {outs} outputs, "
              f"multisines at {count_words(len(levels))} levels",
         f"u1-u{ins} V -> y1-y{outs} um, {hz(fsm)}",
         counted([f["samples"] for f in fo[fsm].values()]),
         f"[9]({link9}#a-real-piezo-stack-end-to-end)"),
    ]
    table = ["| folder | what | input -> output | samples per record | used in |",
             "|---|---|---|---|---|"]
    table += [f"| `{r[0]}` | " + " | ".join(r[1:]) + " |" for r in rows]
    return {
        "data-folders": "\n".join(table),
        "data-boucwen-record": (
            f"{hz(bw)}; the training file holds {thousands(b['samples'])} samples "
            f"({count_words(b['periods'])} periods of a multisine) with the benchmark's "
            f"measurement noise ({sig(b['noise_rms_m'], 2)} m RMS, from the spread between "
            "its periods)"),
        "data-boucwen-rate": hz(bw),
    }

"""Experiments: Python optimizers run a suite's trials through the harness evaluator; the
folders they write go through `optbench report` and `optbench merge` beside MSGA."""

import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

import optbench
from conftest import HERE, ROOT

SUITE = HERE / "small.toml"
PLAN = [(o, t) for o in ("sphere-3d", "bbob-f15-d2") for t in range(3)]


def one_plus_one_es(problem, rng):
    """(1+1)-ES with the 1/5th success rule, until the budget is spent."""
    lo, hi = problem.lower_bounds, problem.upper_bounds
    x = rng.uniform(lo, hi)
    fx = problem(x)
    sigma = 0.2 * (hi - lo)
    while True:
        y = np.clip(x + sigma * rng.standard_normal(problem.dimension), lo, hi)
        fy = problem(y)
        if fy <= fx:
            x, fx = y, fy
            sigma *= 1.5
        else:
            sigma *= 1.5**-0.25


def scipy_de(problem, budget, rng):
    """scipy's differential_evolution with as many generations as fit in the budget, its
    populations evaluated as batches (vectorized: scipy hands in points as columns)."""
    from scipy.optimize import differential_evolution

    popsize = 10  # scipy's population is popsize x dimension
    generations = budget // (popsize * problem.dimension)
    return differential_evolution(
        lambda xs: problem(xs.T),
        bounds=list(zip(problem.lower_bounds, problem.upper_bounds)),
        popsize=popsize,
        maxiter=generations - 1,  # plus the initial population
        polish=False,
        tol=0,
        vectorized=True,
        updating="deferred",
        rng=rng,
    )


def traces(folder):
    return [json.loads(line) for line in (folder / "traces.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def runs(tmp_path_factory, cli):
    """MSGA (the CLI), scipy's DE and the (1+1)-ES (Experiments) on the small suite."""
    pytest.importorskip("scipy", reason="scipy missing (pip install scipy)")
    d = tmp_path_factory.mktemp("runs")
    cli("run", SUITE, "--out", d / "msga", "-q")
    de = []
    with optbench.Experiment(
        SUITE, optimizer="scipy-de", out=d / "de", description="scipy differential_evolution"
    ) as exp:
        assert len(exp) == exp.planned == 6
        for trial in exp:
            p = trial.problem
            result = scipy_de(p, trial.budget, np.random.default_rng(trial.seed))
            # Vectorized, scipy counts calls (generations) in nfev; points are what count.
            points = (result.nit + 1) * 10 * p.dimension
            de.append((trial.objective, trial.number, trial.seed, points, p.evaluations))
            assert p.best_value == result.fun
    es = []
    with optbench.Experiment(SUITE, optimizer="one-plus-one", out=d / "es") as exp:
        for trial in exp:
            try:
                one_plus_one_es(trial.problem, np.random.default_rng(trial.seed))
            except optbench.BudgetExhausted:
                pass
            es.append((trial.objective, trial.number, trial.seed, trial.problem.evaluations))
    return {"dir": d, "de": de, "es": es}


def test_trials_follow_the_suite_plan_with_seeds_fixed_by_it(runs):
    assert [(o, t) for o, t, *_ in runs["de"]] == PLAN
    assert [(o, t) for o, t, *_ in runs["es"]] == PLAN
    de_seeds = [s for _, _, s, *_ in runs["de"]]
    es_seeds = [s for _, _, s, *_ in runs["es"]]
    assert len(set(de_seeds)) == 6 and set(de_seeds).isdisjoint(es_seeds)
    # The same optimizer id on the same suite is handed the same seeds (a new folder).
    again = optbench.Experiment(SUITE, optimizer="scipy-de", out=runs["dir"] / "de-seeds")
    seeds = []
    for trial in again:
        seeds.append(trial.seed)
        assert trial.budget == 600 and trial.stop_value is None
        assert trial.params["dim"] == str(trial.problem.dimension)
        trial.problem(trial.problem.lower_bounds)
    again.close()
    assert seeds == de_seeds


def test_evaluations_are_counted_exactly(runs):
    for objective, number, _, points, counted in runs["de"]:
        assert counted == points <= 600, (objective, number)
    assert all(counted == 600 for *_, counted in runs["es"])
    records = {(r["objective"], r["trial"]): r for r in traces(runs["dir"] / "de")}
    for objective, number, _, points, _ in runs["de"]:
        assert records[(objective, number)]["evaluations"] == points
    records = traces(runs["dir"] / "es")
    assert len(records) == 6 and all(r["optimizer"] == "one-plus-one" for r in records)
    assert all(r["evaluations"] == 600 for r in records)


def test_scipys_own_count_agrees_point_by_point():
    """Not vectorized, scipy calls once per point and counts each: so does optbench."""
    pytest.importorskip("scipy", reason="scipy missing (pip install scipy)")
    from scipy.optimize import differential_evolution

    p = optbench.problem("rastrigin", dim=2, budget=1000)
    result = differential_evolution(
        p, bounds=list(zip(p.lower_bounds, p.upper_bounds)), maxiter=20, popsize=8,
        polish=False, tol=0, rng=np.random.default_rng(3),
    )
    assert p.evaluations == result.nfev == 21 * 8 * 2
    assert p.best_value == result.fun and p.best_x.tolist() == result.x.tolist()


def test_an_experiment_is_reproducible(runs, tmp_path):
    with optbench.Experiment(SUITE, optimizer="one-plus-one", out=tmp_path / "es") as exp:
        for trial in exp:
            with pytest.raises(optbench.BudgetExhausted):
                one_plus_one_es(trial.problem, np.random.default_rng(trial.seed))
    strip = lambda r: {k: v for k, v in r.items() if k != "wall_s"}  # noqa: E731
    assert [strip(r) for r in traces(tmp_path / "es")] == [
        strip(r) for r in traces(runs["dir"] / "es")
    ]


def test_report_and_merge_set_the_python_optimizers_beside_msga(runs, cli):
    d = runs["dir"]
    cli("report", d / "de", "-q")
    assert "scipy-de" in (d / "de" / "report.md").read_text()
    cli("merge", d / "msga", d / "de", d / "es", "--out", d / "merged", "-q")
    report = (d / "merged" / "report.md").read_text()
    for optimizer in ("MSGA", "scipy-de", "one-plus-one"):
        assert re.search(rf"\b{re.escape(optimizer)}\b", report), optimizer
    optimizers = {r["optimizer"] for r in traces(d / "merged")}
    assert optimizers == {"MSGA", "scipy-de", "one-plus-one"}
    assert len(traces(d / "merged")) == 18


def test_trials_and_experiments_refuse_misuse(tmp_path):
    exp = optbench.Experiment(SUITE, optimizer="careless", out=tmp_path / "x")
    first = next(exp)
    with pytest.raises(ValueError, match="has no evaluation"):
        first.finish()
    first.problem(np.zeros(3))
    first.finish()
    assert first.finished
    with pytest.raises(ValueError, match="finished already"):
        first.finish()
    with pytest.raises(ValueError, match="its trial is finished"):
        first.problem(np.zeros(3))
    assert first.problem.evaluations == 1 and first.problem.best_value == 0.0
    second = next(exp)
    with pytest.raises(optbench.BudgetExhausted) as e:
        second.problem(np.zeros((601, 3)))
    assert e.value.evaluated == 600 and second.problem.evaluations == 600
    with pytest.raises(ValueError, match="4 of 6 trials are unfinished"):
        exp.close()
    exp.close(partial=True)
    assert exp.closed
    with pytest.raises(ValueError, match="closed"):
        next(exp)
    resumed = optbench.Experiment(SUITE, optimizer="careless", out=tmp_path / "x", resume=True)
    assert len(resumed) == 4
    assert [t.index for t in resumed if t.problem(t.problem.upper_bounds) is not None] == [
        2, 3, 4, 5
    ]
    resumed.close()
    assert len(traces(tmp_path / "x")) == 6


def test_an_exception_in_the_block_keeps_the_finished_trials(tmp_path):
    with pytest.raises(RuntimeError, match="optimizer broke"):
        with optbench.Experiment(SUITE, optimizer="fragile", out=tmp_path / "f") as exp:
            for trial in exp:
                trial.problem(trial.problem.lower_bounds)
                if trial.index == 2:
                    raise RuntimeError("optimizer broke")
    assert exp.closed
    assert [(r["objective"], r["trial"]) for r in traces(tmp_path / "f")] == PLAN[:2]


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"suite": HERE / "missing.toml", "optimizer": "x"}, "missing.toml"),
        ({"suite": SUITE, "optimizer": "a b"}, "optimizer id"),
        ({"suite": SUITE, "optimizer": "x", "trials": 0}, "trials = 0: expected 1 to"),
        ({"suite": SUITE, "optimizer": "x", "budget": 0}, "budget = 0"),
    ],
)
def test_bad_experiments_are_value_errors(kwargs, message, tmp_path):
    with pytest.raises((ValueError, OSError)) as e:
        optbench.Experiment(out=tmp_path / "bad", **kwargs)
    assert message in str(e.value)


def test_the_books_example_runs(tmp_path, cli):
    """The complete example of docs/17-python.md, as written, from a scratch folder."""
    text = (ROOT / "docs" / "17-python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    example = next(b for b in blocks if "optbench.Experiment(" in b)
    (tmp_path / "python" / "tests").mkdir(parents=True)
    shutil.copy(SUITE, tmp_path / "python" / "tests" / "small.toml")
    p = subprocess.run(
        [sys.executable, "-c", example], cwd=tmp_path, capture_output=True, text=True
    )
    assert p.returncode == 0, p.stderr
    folder = tmp_path / "results" / "pysmall-one-plus-one"
    assert "results in results/pysmall-one-plus-one" in p.stdout
    assert len(traces(folder)) == 6
    cli("report", folder, "-q")


def test_a_trial_that_reaches_stop_at_raises_target_reached(tmp_path):
    suite = tmp_path / "stop.toml"
    suite.write_text(
        'name = "stop"\nseed = 1\ntrials = 1\nbudget = 100\nstop_at = 1e-8\n'
        '[[objective]]\nkind = "sphere"\ndim = 2\n[[optimizer]]\nkind = "random"\n'
    )
    with optbench.Experiment(suite, optimizer="lucky", out=tmp_path / "out") as exp:
        for trial in exp:
            p = trial.problem
            assert trial.stop_value == 1e-8
            with pytest.raises(optbench.TargetReached) as e:
                p(np.array([[1.0, 1.0], [0.0, 0.0], [2.0, 2.0]]))
            assert isinstance(e.value, optbench.BudgetExhausted)
            assert e.value.evaluated == 2 and p.evaluations == 2
            assert "reached its stop value; 2 of the 3 points" in str(e.value)
    (record,) = traces(tmp_path / "out")
    assert record["stopped_at_target"] and record["evaluations"] == 2

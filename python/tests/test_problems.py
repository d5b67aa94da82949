"""Problems: BBOB against COCO's own cocoex, batches, exact counting, budgets, bad input."""

import math
import os
import pathlib
import tempfile

import numpy as np
import pytest

import optbench

# Dimensions and instances compared with cocoex for each of the 24 functions.
DIMENSIONS = (2, 3, 5, 10, 20, 40)
INSTANCES = (1, 2, 7, 15)


def cocoex_problem(cocoex, f, d, i):
    suite = cocoex.Suite("bbob", f"instances: {i}", f"function_indices: {f} dimensions: {d}")
    return suite.get_problem_by_function_dimension_instance(f, d, i)


def cocoex_optimum_location(problem):
    """Where cocoex puts the optimum (it only prints it, to a file in the working folder)."""
    old = os.getcwd()
    with tempfile.TemporaryDirectory() as d:
        os.chdir(d)
        try:
            problem._best_parameter("print")
            text = pathlib.Path("._bbob_problem_best_parameter.txt").read_text()
        finally:
            os.chdir(old)
    return np.array([float(v) for v in text.split()])


def close(got, expected):
    return np.abs(got - expected) / np.maximum(1.0, np.abs(expected))


@pytest.mark.parametrize("function", range(1, 25))
def test_bbob_matches_cocoex(function):
    cocoex = pytest.importorskip("cocoex", reason="cocoex (pip coco-experiment) missing")
    rng = np.random.default_rng(function)
    for d in DIMENSIONS:
        for i in INSTANCES:
            ours = optbench.bbob(function, d, i)
            theirs = cocoex_problem(cocoex, function, d, i)
            assert ours.dimension == theirs.dimension == d
            assert np.array_equal(ours.lower_bounds, theirs.lower_bounds)
            assert np.array_equal(ours.upper_bounds, theirs.upper_bounds)
            # f_opt: cocoex's value at its optimum, and ours there.
            xopt = cocoex_optimum_location(theirs)
            assert close(ours.optimum, theirs(xopt)) <= 1e-12
            assert close(ours(xopt), ours.optimum) <= 1e-12
            # Inside the box, beyond it (penalties of f20-f24 etc.) and at the centre.
            points = np.vstack([
                rng.uniform(-5, 5, size=(12, d)),
                rng.uniform(-8, 8, size=(4, d)),
                np.zeros((1, d)),
            ])
            expected = np.array([theirs(x) for x in points])
            got = ours(points)
            rel = close(got, expected)
            assert rel.max() <= 1e-12, (function, d, i, rel.max())
            theirs.free()


def test_one_point_gives_a_float_a_batch_an_array_equal_to_the_loop():
    problems = (optbench.bbob(7, 5, 3), optbench.problem("rastrigin", dim=5),
                optbench.problem("griewank", dim=4))
    for p in problems:
        rng = np.random.default_rng(1)
        xs = rng.uniform(p.lower_bounds, p.upper_bounds, size=(9, p.dimension))
        loop = [p(x) for x in xs]
        assert all(type(v) is float for v in loop)
        batch = p(xs)
        assert isinstance(batch, np.ndarray) and batch.shape == (9,)
        assert batch.tolist() == loop
        # Lists and integer arrays are numbers too.
        assert p(xs[0].tolist()) == loop[0]
        assert p(np.zeros(p.dimension, dtype=np.int32)) == p(np.zeros(p.dimension))
        # An empty batch is no evaluation.
        before = p.evaluations
        assert p(np.empty((0, p.dimension))).shape == (0,)
        assert p.evaluations == before


def test_every_point_is_counted_and_the_best_kept():
    p = optbench.problem("sphere", dim=3)
    assert (p.evaluations, p.best_value, p.best_x) == (0, None, None)
    assert p.budget is None and p.optimum == 0.0
    assert p.name == "sphere" and p.id == "sphere-d3"
    p(np.array([1.0, 1.0, 1.0]))
    p(np.array([[2.0, 0.0, 0.0], [0.5, 0.0, 0.0], [3.0, 3.0, 3.0]]))
    assert p.evaluations == 4
    assert p.best_value == 0.25
    assert p.best_x.tolist() == [0.5, 0.0, 0.0]


def test_the_budget_is_exact_and_a_crossing_batch_evaluates_what_fits():
    p = optbench.problem("rosenbrock", dim=2, budget=5)
    assert p.budget == 5 and p.remaining == 5
    first = p(np.zeros((3, 2)))
    assert p.evaluations == 3
    xs = np.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [4.0, 4.0]])
    with pytest.raises(optbench.BudgetExhausted) as e:
        p(xs)
    # The two points within the budget were evaluated, counted and handed back.
    assert e.value.evaluated == 2
    assert e.value.values.tolist() == optbench.problem("rosenbrock", dim=2)(xs[:2]).tolist()
    assert "budget of 5 evaluations is spent; 2 of the 4 points were evaluated" in str(e.value)
    assert p.evaluations == 5 and p.remaining == 0
    assert p.best_value == min(first.min(), e.value.values.min())
    with pytest.raises(optbench.BudgetExhausted):
        p(np.zeros(2))
    assert p.evaluations == 5


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: optbench.problem("nope", dim=2), "unknown objective kind `nope`"),
        (lambda: optbench.problem("griewank"), "missing parameter `dim`"),
        (lambda: optbench.problem("griewank", dim=2, dims=3), "unknown parameter `dims`"),
        (lambda: optbench.problem("griewank", dim=0), "`dim`"),
        (lambda: optbench.problem("griewank", dim=[2]), "expected a number, a bool or a string"),
        (lambda: optbench.problem("griewank", dim=2, budget=0), "expected a positive number"),
        (lambda: optbench.bbob(25, 2, 1), "optbench.bbob: objective kind `bbob`: `function`"),
        (lambda: optbench.bbob(1, 2, 0), "optbench.bbob: objective kind `bbob`: `instance`"),
    ],
)
def test_bad_problems_are_value_errors_with_the_crates_message(make, message):
    with pytest.raises(ValueError) as e:
        make()
    assert message in str(e.value)


@pytest.mark.parametrize(
    "x, message",
    [
        (np.zeros(3), "a point has 2 coordinates, got 3"),
        (np.zeros((4, 3)), "a batch has shape (n, 2), got (4, 3)"),
        (np.zeros((2, 2, 2)), "got a 3-D array"),
        (np.float64(1.0), "got a 0-D array"),
        (np.array([0.0, math.nan]), "coordinate 1 of point 0 is NaN"),
        (np.array([[0.0, 0.0], [math.inf, 0.0]]), "coordinate 0 of point 1 is inf"),
        (np.array([1j, 0]), "expected real numbers"),
        (np.array(["a", "b"]), "expected real numbers"),
    ],
)
def test_bad_points_are_value_errors_and_never_counted(x, message):
    p = optbench.problem("ackley", dim=2)
    with pytest.raises(ValueError) as e:
        p(x)
    assert message in str(e.value)
    assert p.evaluations == 0


def test_a_fit_on_a_twin_signal_is_a_problem_too():
    p = optbench.problem(
        "bouc-wen",
        recording="twin:sine:freq=1,amp=2.3,offset=2.35,phase=-1.5707963267948966",
        duration=0.2,
        normalize=False,
        budget=20,
    )
    assert p.optimum is None and p.budget == 20
    rng = np.random.default_rng(0)
    xs = rng.uniform(p.lower_bounds, p.upper_bounds, size=(20, p.dimension))
    values = p(xs)
    assert np.all(np.isfinite(values)) and p.evaluations == 20
    assert p.best_value == values.min()

"""optbench for optimizers written in Python.

Problems (`bbob`, `problem`) evaluate through optbench's own evaluator, which counts every
point exactly and enforces the budget; `Experiment` runs a suite's trials with your
optimizer and writes a results folder that `optbench report` and `optbench merge` read.
"""

from ._optbench import (
    BudgetExhausted,
    Experiment,
    Problem,
    TargetReached,
    Trial,
    bbob,
    kinds,
    problem,
)

__all__ = [
    "BudgetExhausted",
    "Experiment",
    "Problem",
    "TargetReached",
    "Trial",
    "bbob",
    "kinds",
    "problem",
]

"""Shared by the Python package's tests: the optbench CLI (report, merge, run)."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
HERE = pathlib.Path(__file__).resolve().parent


def optbench_bin():
    """$OPTBENCH_BIN, else the release binary of the repository (`cargo build --release`)."""
    path = pathlib.Path(os.environ.get("OPTBENCH_BIN", ROOT / "target" / "release" / "optbench"))
    if not path.is_file():
        pytest.fail(
            f"the optbench CLI is missing at {path}: run `cargo build --release` in {ROOT} "
            "or set OPTBENCH_BIN"
        )
    return path


@pytest.fixture(scope="session")
def cli():
    """Runs `optbench ARGS...`; returns its stdout, failing the test with its stderr."""

    def run(*args):
        p = subprocess.run(
            [str(optbench_bin()), *map(str, args)], capture_output=True, text=True
        )
        assert p.returncode == 0, f"optbench {' '.join(map(str, args))}: {p.stderr}"
        return p.stdout

    return run

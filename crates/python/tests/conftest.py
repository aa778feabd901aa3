"""Shared fixtures: a short simulated data set, and the `pdcal` binary to compare with.

The binary is `$PDCAL_BIN`, else the workspace's `target/release/pdcal`
(`cargo build --release -p pdcal`); the comparisons fail, not skip, without it.
"""

import os
import pathlib
import subprocess

import pytest

import pdcal

ROOT = pathlib.Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def pdcal_bin():
    path = pathlib.Path(os.environ.get("PDCAL_BIN", ROOT / "target" / "release" / "pdcal"))
    assert path.is_file(), f"{path}: build it with cargo build --release -p pdcal"
    return path


@pytest.fixture(scope="session")
def short_set():
    """50 minutes of the RAX-2-like scenario: 24 in eclipse, then 26 sunlit."""
    scenario = pdcal.scenario("rax2-like")
    scenario["duration_s"] = 3000.0
    return pdcal.simulate(scenario, seed=3)


@pytest.fixture(scope="session")
def short_dir(short_set, tmp_path_factory):
    path = tmp_path_factory.mktemp("short") / "dataset"
    short_set.write(path)
    return path


def cli(pdcal_bin, *args):
    """Runs the binary; its exit status and stderr."""
    done = subprocess.run([str(pdcal_bin), *map(str, args)], capture_output=True, text=True)
    return done.returncode, done.stderr


def cli_error(pdcal_bin, *args):
    """The message of a failing CLI run, without `pdcal: error: `."""
    status, stderr = cli(pdcal_bin, *args)
    assert status != 0, f"pdcal {args} succeeded"
    lines = [l for l in stderr.splitlines() if l.startswith("pdcal: error: ")]
    assert len(lines) == 1, stderr
    return lines[0][len("pdcal: error: "):]


@pytest.fixture(scope="session")
def long_set():
    """The 2-hour RAX-2-like set (`pdcal simulate` default): a calibration of about a
    second, long enough to watch from another thread."""
    return pdcal.simulate()

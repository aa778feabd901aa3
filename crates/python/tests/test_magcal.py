"""pdcal.magcal: the attitude-independent magnetometer calibration from Python, against the
simulator's truth and against the CLI's `pdcal magcal` on the same data."""

import json
import math

import numpy as np
import pytest

import pdcal
from conftest import ROOT, cli

SCENARIO = ROOT / "fixtures" / "scenarios" / "magcal" / "rax2-like-magcal.ron"


@pytest.fixture(scope="module")
def magcal_set():
    """An hour of rax2-like with hard iron, soft iron and panel-current biases."""
    scenario = pdcal.scenario(str(SCENARIO))
    scenario["duration_s"] = 3600.0
    return pdcal.simulate(scenario, seed=2)


def test_magcal_estimates_the_truth_within_its_sigmas(magcal_set):
    cal = pdcal.magcal(magcal_set)
    truth = magcal_set.truth["magnetometer"]
    bias_z = (cal.bias_nT - np.asarray(truth["bias_nT"])) / cal.bias_sigma_nT
    assert np.all(np.abs(bias_z) < 4.0), bias_z
    assert cal.matrix.shape == (3, 3)
    assert np.allclose(cal.matrix, cal.matrix.T)
    n = len(cal.parameters)
    assert cal.covariance.shape == (n, n)
    assert np.all(np.linalg.eigvalsh(cal.covariance) > 0.0)
    # The panel currents that drive a bias are kept, the one that drives none is not.
    assert "cur_my_A" not in cal.current_bias_nT_per_A
    for name, c in cal.current_bias_nT_per_A.items():
        assert c.shape == (3,), name
    before = cal.summary["residual_rms_nT"]["before"]
    after = cal.summary["residual_rms_nT"]["after"]
    assert before > 2000.0 and after < 1.1 * 320.0, (before, after)


def test_magcal_matches_the_cli_and_applies_as_it_writes(magcal_set, pdcal_bin, tmp_path):
    data = tmp_path / "data"
    magcal_set.write(data)
    status, stderr = cli(pdcal_bin, "magcal", data, "--out", tmp_path / "cli")
    assert status == 0, stderr
    cli_json = json.loads((tmp_path / "cli" / "magcal.json").read_text())
    cal = pdcal.magcal(pdcal.Dataset.read(data))
    assert np.allclose(cal.bias_nT, cli_json["bias_nT"], rtol=0, atol=1e-6)
    assert np.allclose(cal.matrix, np.asarray(cli_json["matrix"]), rtol=0, atol=1e-12)
    cal.write(tmp_path / "py")
    for name in ["magcal.ron", "magcal.json", "rejected_rows.csv", "index.html"]:
        assert (tmp_path / "py" / name).is_file(), name
    corrected = cal.apply(magcal_set)
    written = pdcal.Dataset.read(tmp_path / "py" / "dataset")
    assert np.allclose(corrected.mag_nT, written.mag_nT, rtol=0, atol=1e-6, equal_nan=True)
    assert not np.allclose(corrected.mag_nT, magcal_set.mag_nT, equal_nan=True)
    assert math.isfinite(cal.summary["noise_sigma_nT"])

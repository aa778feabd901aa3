"""export_onboard and sun_vector from Python: the CLI's outputs, from a pdcal.Calibration
or its directory."""

import numpy as np
import pytest

import pdcal
from conftest import cli, cli_error


def without_provenance(text):
    """The header without its first comment block (paths and the export's date)."""
    return text.split("*/", 1)[1]


@pytest.fixture(scope="module")
def calibrated(short_dir, tmp_path_factory):
    dataset = pdcal.Dataset.read(short_dir)
    calibration = pdcal.calibrate(dataset)
    cal_dir = tmp_path_factory.mktemp("onboard") / "cal"
    calibration.write(cal_dir)
    return dataset, calibration, cal_dir


def test_export_onboard_is_the_clis(calibrated, short_dir, pdcal_bin, tmp_path):
    dataset, calibration, cal_dir = calibrated
    export = pdcal.export_onboard(calibration, dataset, tmp_path / "py", grid_deg=10.0)
    status, stderr = cli(
        pdcal_bin, "export-onboard", cal_dir, "--dataset", short_dir,
        "--out", tmp_path / "cli", "--grid-deg", "10",
    )
    assert status == 0, stderr
    header = "pdcal_calibration.h"
    assert without_provenance((tmp_path / "py" / header).read_text()) == without_provenance(
        (tmp_path / "cli" / header).read_text()
    )
    assert (export["grid"]["n_lat"], export["grid"]["n_lon"]) == (18, 36)
    assert len(export["grid"]["cells"]) == 18 * 36
    assert len(export["photodiodes"]) == 17
    summary = calibration.summary
    for pd, s in zip(export["photodiodes"], summary["photodiodes"]):
        statuses = {p["parameter"]: p for p in pd["status"]}
        if statuses["scale"]["status"] == "calibrated":
            assert pd["scale_v"] == s["scale_V"]
        else:
            assert statuses["scale"]["nominal"]
            assert pd["scale_v"] == s["initial"]["scale_V"]


def test_sun_vector_is_the_clis(calibrated, short_dir, pdcal_bin, tmp_path):
    dataset, calibration, cal_dir = calibrated
    columns = pdcal.sun_vector(dataset, calibration, out=tmp_path / "py.csv")
    status, stderr = cli(
        pdcal_bin, "sun-vector", short_dir, "--calibration", cal_dir, "--out", tmp_path / "cli.csv"
    )
    assert status == 0, stderr
    assert (tmp_path / "py.csv").read_bytes() == (tmp_path / "cli.csv").read_bytes()
    n = len(dataset.t_s)
    assert len(columns["t_s"]) == n
    valid = columns["valid"] == 1
    assert valid.sum() > 1000
    sun = np.stack([columns["sun_x"], columns["sun_y"], columns["sun_z"]], axis=1)[valid]
    np.testing.assert_allclose(np.linalg.norm(sun, axis=1), 1.0, atol=1e-6)
    assert set(columns["validity"][valid]) == {"valid"}
    # From the directory too.
    again = pdcal.sun_vector(dataset, cal_dir)
    np.testing.assert_array_equal(again["sun_x"], columns["sun_x"])


def test_a_missing_calibration_names_the_file(calibrated, short_dir, pdcal_bin, tmp_path):
    dataset, _, _ = calibrated
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(OSError) as raised:
        pdcal.sun_vector(dataset, empty)
    message = str(raised.value)
    assert str(empty / "calibration.ron") in message
    assert message == cli_error(
        pdcal_bin, "sun-vector", short_dir, "--calibration", empty, "--out", tmp_path / "x.csv"
    )

"""Every dataset field through numpy: constructor -> properties -> write -> read."""

import math

import numpy as np
import pytest

import pdcal
from conftest import cli


def same(a, b):
    """Equal arrays, NaN equal to NaN, bit for bit otherwise."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape
    assert np.array_equal(a, b, equal_nan=True), (a, b)


def rich_arrays(base):
    """The short set's arrays with every optional field in use: blank cells in each sensor,
    fields of view, panels, temperature columns of both kinds, noise hints, the truth."""
    n, m = base.rows, base.photodiodes_V.shape[1]
    gyro = base.gyro_rad_s.copy()
    gyro[5] = np.nan
    mag = base.mag_nT.copy()
    mag[1::2] = np.nan
    pd = base.photodiodes_V.copy()
    pd[7, 2] = np.nan
    fov = np.full(m, np.nan)
    fov[0], fov[3] = 70.0, 89.5
    panel = [None] * m
    panel[1], panel[2] = "xplus", "xplus"
    temp_pd = np.where(np.arange(n) % 10 == 0, 20.0 + np.arange(n) / 1000.0, np.nan)
    temp_panel = np.full(n, np.nan)
    temp_panel[::30] = -12.5
    return dict(
        name="rich set",
        epoch_utc=base.epoch_utc,
        t_s=base.t_s,
        gyro_rad_s=gyro,
        mag_nT=mag,
        photodiodes_V=pd,
        nominal_az_el_deg=base.nominal_az_el_deg,
        tle=base.tle,
        fov_deg=fov,
        panel=panel,
        temperatures_C={"temp_pd01_C": temp_pd, "temp_xplus_C": temp_panel},
        noise={"gyro_rad_s": 0.0008, "mag_nT": 320.0, "photodiode_V": None},
        truth=base.truth,
    )


def check_fields(ds, a):
    assert ds.name == a["name"]
    assert ds.epoch_utc == a["epoch_utc"]
    assert ds.tle == a["tle"]
    assert ds.positions_gcrf_km is None
    assert ds.rows == len(a["t_s"])
    for key in ["t_s", "gyro_rad_s", "mag_nT", "photodiodes_V", "nominal_az_el_deg", "fov_deg"]:
        same(getattr(ds, key), a[key])
    assert ds.panel == a["panel"]
    assert list(ds.temperatures_C) == list(a["temperatures_C"])
    for key, values in a["temperatures_C"].items():
        same(ds.temperatures_C[key], values)
    assert ds.noise == a["noise"]
    truth = ds.truth
    assert list(truth) == list(a["truth"])
    for key, values in a["truth"].items():
        if key == "effects":
            assert truth[key] == values
        else:
            same(truth[key], values)


def test_every_field_round_trips_through_numpy_and_files(short_set, tmp_path):
    a = rich_arrays(short_set)
    ds = pdcal.Dataset(**a)
    check_fields(ds, a)
    ds.write(tmp_path / "rich")
    back = pdcal.Dataset.read(tmp_path / "rich")
    check_fields(back, a)
    assert back == ds
    # The blank cells are blank in the file, not NaN text.
    text = (tmp_path / "rich" / "telemetry.csv").read_text()
    assert "NaN" not in text and "nan" not in text
    assert text.splitlines()[0].endswith("temp_pd01_C,temp_xplus_C")
    assert 'panel: "xplus"' in (tmp_path / "rich" / "dataset.ron").read_text()


def test_position_columns_instead_of_a_tle(short_set, tmp_path):
    r = short_set.truth["r_gcrf_km"]
    ds = pdcal.Dataset(
        epoch_utc=short_set.epoch_utc,
        t_s=short_set.t_s,
        gyro_rad_s=short_set.gyro_rad_s,
        photodiodes_V=short_set.photodiodes_V,
        nominal_az_el_deg=short_set.nominal_az_el_deg,
        positions_gcrf_km=r,
    )
    assert ds.tle is None and ds.mag_nT is None and ds.truth is None and ds.noise is None
    same(ds.positions_gcrf_km, r)
    same(ds.fov_deg, np.full(ds.nominal_az_el_deg.shape[0], np.nan))
    ds.write(tmp_path / "pos")
    back = pdcal.Dataset.read(tmp_path / "pos")
    assert back == ds
    assert "PositionColumns" in (tmp_path / "pos" / "dataset.ron").read_text()


def test_a_simulated_set_has_its_truth_and_writes_like_the_reader_reads(short_set, tmp_path):
    truth = short_set.truth
    assert truth["q_xyzw"].shape == (short_set.rows, 4)
    assert truth["scale_V"].shape == (short_set.photodiodes_V.shape[1],)
    assert any(e.startswith("Albedo(") for e in truth["effects"])
    short_set.write(tmp_path / "sim")
    assert pdcal.Dataset.read(tmp_path / "sim") == short_set


def test_shapes_are_checked_before_anything_else(short_set):
    a = rich_arrays(short_set)
    a["gyro_rad_s"] = a["gyro_rad_s"][:, :2]
    with pytest.raises(ValueError, match=r"gyro_rad_s: expected an array of shape \(N, 3\)"):
        pdcal.Dataset(**a)
    a = rich_arrays(short_set)
    a["noise"] = {"gyro": 1.0}
    with pytest.raises(ValueError, match="noise: unknown key 'gyro'|noise: unknown key \"gyro\""):
        pdcal.Dataset(**a)


def test_rows_of_unequal_length_name_the_column(short_set):
    a = rich_arrays(short_set)
    a["photodiodes_V"] = a["photodiodes_V"][:-1]
    with pytest.raises(ValueError) as e:
        pdcal.Dataset(**a)
    assert "pd01_V" in str(e.value) and str(short_set.rows) in str(e.value)
    assert not math.isnan(short_set.t_s[0])


def test_downlinks_of_a_seed_share_the_hardware_and_not_the_noise(pdcal_bin, tmp_path):
    scenario = pdcal.scenario("rax2-like")
    scenario["duration_s"] = 120.0
    first = pdcal.simulate(scenario, seed=4)
    later = pdcal.simulate(scenario, seed=4, downlink=2)
    np.testing.assert_array_equal(first.truth["scale_V"], later.truth["scale_V"])
    np.testing.assert_array_equal(first.truth["azimuth_deg"], later.truth["azimuth_deg"])
    assert not np.array_equal(first.gyro_rad_s, later.gyro_rad_s)
    assert pdcal.simulate(scenario, seed=4, downlink=0) == first
    # The CLI's --downlink is the same data set.
    out = tmp_path / "downlink2"
    status, stderr = cli(pdcal_bin, "simulate", "--seed", "4", "--downlink", "2", "--out", out)
    assert status == 0, stderr
    assert pdcal.Dataset.read(out) == pdcal.simulate("rax2-like", seed=4, downlink=2)

"""Bad input gives the CLI's message: `Dataset.read` of a bad directory raises what
`pdcal calibrate` prints after `pdcal: error: `, and the constructor, given the arrays of
that bad file, raises the same message with the file named without its directory."""

import re
import shutil

import numpy as np
import pytest

import pdcal
from conftest import cli_error


def edit_ron(path, pattern, replacement):
    text = path.read_text()
    new, count = re.subn(pattern, replacement, text, count=1)
    assert count == 1, pattern
    path.write_text(new)


def edit_csv(path, edit):
    rows = [line.split(",") for line in path.read_text().splitlines()]
    edit(rows)
    path.write_text("".join(",".join(r) + "\n" for r in rows))


def set_cell(row, column, value):
    def edit(rows):
        rows[row][rows[0].index(column)] = value

    return edit


def swap_cells(row_a, row_b, column):
    def edit(rows):
        j = rows[0].index(column)
        rows[row_a][j], rows[row_b][j] = rows[row_b][j], rows[row_a][j]

    return edit


def rename_header(old, new):
    def edit(rows):
        rows[0][rows[0].index(old)] = new

    return edit


def drop_column(column):
    def edit(rows):
        j = rows[0].index(column)
        for r in rows:
            del r[j]

    return edit


def add_column(name, value):
    def edit(rows):
        rows[0].append(name)
        for r in rows[1:]:
            r.append(value)

    return edit


TLE_LINE1 = r'line1: "(1 [^"]{66})(\d)"'


def bump_checksum(m):
    return f'line1: "{m.group(1)}{(int(m.group(2)) + 1) % 10}"'


# (id, file, edit): a dozen and more kinds of bad input, each in the file it lives in.
CASES = [
    ("elevation out of range", "dataset.ron", (r"elevation_deg: -?[0-9.]+", "elevation_deg: 1000.0")),
    ("azimuth out of range", "dataset.ron", (r"azimuth_deg: -?[0-9.]+", "azimuth_deg: -400.0")),
    ("unknown field", "dataset.ron", (r"name:", "colour: 1,\n    name:")),
    ("bad epoch", "dataset.ron", (r'epoch_utc: "[^"]*"', 'epoch_utc: "2011-13-04T18:29:45Z"')),
    ("format version", "dataset.ron", (r"format_version: 1", "format_version: 2")),
    ("tle checksum", "dataset.ron", (TLE_LINE1, bump_checksum)),
    ("negative noise", "dataset.ron", (r"gyro_rad_s: [0-9.e-]+", "gyro_rad_s: -0.001")),
    ("text in a cell", "telemetry.csv", set_cell(4, "pd03_V", "abc")),
    ("infinite cell", "telemetry.csv", set_cell(9, "pd02_V", "inf")),
    ("time not increasing", "telemetry.csv", swap_cells(6, 7, "t_s")),
    ("partly blank gyro", "telemetry.csv", set_cell(3, "gyro_y_rad_s", "")),
    ("unknown column", "telemetry.csv", rename_header("mag_z_nT", "mag_w_nT")),
    ("missing photodiode column", "telemetry.csv", drop_column("pd17_V")),
    ("unreferenced panel", "telemetry.csv", add_column("temp_zz_C", "")),
    ("temperature out of range", "telemetry.csv", add_column("temp_pd01_C", "300")),
    ("empty telemetry", "telemetry.csv", lambda rows: rows.clear()),
]


def bad_dir(good, tmp_path, name, edit):
    bad = tmp_path / "bad"
    shutil.copytree(good, bad)
    path = bad / name
    if name.endswith(".ron"):
        edit_ron(path, *edit)
    elif name.endswith(".csv"):
        edit_csv(path, edit)
    return bad


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_reading_a_bad_dataset_raises_the_cli_message(case, short_dir, pdcal_bin, tmp_path):
    _, name, edit = case
    bad = bad_dir(short_dir, tmp_path, name, edit)
    expected = cli_error(pdcal_bin, "calibrate", bad, "--out", tmp_path / "out")
    with pytest.raises(ValueError) as e:
        pdcal.Dataset.read(bad)
    assert str(e.value) == expected
    assert not (tmp_path / "out").exists()


def test_a_missing_file_is_an_os_error_with_the_cli_message(short_dir, pdcal_bin, tmp_path):
    bad = tmp_path / "bad"
    shutil.copytree(short_dir, bad)
    (bad / "dataset.ron").unlink()
    expected = cli_error(pdcal_bin, "calibrate", bad, "--out", tmp_path / "out")
    with pytest.raises(OSError) as e:
        pdcal.Dataset.read(bad)
    assert str(e.value) == expected


def arrays(ds):
    return dict(
        name=ds.name,
        epoch_utc=ds.epoch_utc,
        t_s=ds.t_s.copy(),
        gyro_rad_s=ds.gyro_rad_s.copy(),
        mag_nT=ds.mag_nT.copy(),
        photodiodes_V=ds.photodiodes_V.copy(),
        nominal_az_el_deg=ds.nominal_az_el_deg.copy(),
        tle=ds.tle,
        noise=ds.noise,
    )


def swapped_t(a):
    a["t_s"][[5, 6]] = a["t_s"][[6, 5]]


def bumped_tle(a):
    l1, l2 = a["tle"]
    a["tle"] = (l1[:68] + str((int(l1[68]) + 1) % 10), l2)


def set_item(key, index, value):
    def edit(a):
        a[key][index] = value

    return edit


def set_key(key, value):
    def edit(a):
        a[key] = value

    return edit


# The same bad input as arrays: (id of the file case above, edit of the arrays).
ARRAY_CASES = [
    ("elevation out of range", set_item("nominal_az_el_deg", (0, 1), 1000.0)),
    ("azimuth out of range", set_item("nominal_az_el_deg", (0, 0), -400.0)),
    ("bad epoch", set_key("epoch_utc", "2011-13-04T18:29:45Z")),
    ("tle checksum", bumped_tle),
    ("infinite cell", set_item("photodiodes_V", (8, 1), np.inf)),
    ("time not increasing", swapped_t),
    ("partly blank gyro", set_item("gyro_rad_s", (2, 1), np.nan)),
]


@pytest.mark.parametrize("case", ARRAY_CASES, ids=[c[0] for c in ARRAY_CASES])
def test_the_constructor_raises_the_cli_message_for_the_same_values(
    case, short_set, short_dir, pdcal_bin, tmp_path
):
    file_case = next(c for c in CASES if c[0] == case[0])
    bad = bad_dir(short_dir, tmp_path, file_case[1], file_case[2])
    expected = cli_error(pdcal_bin, "calibrate", bad, "--out", tmp_path / "out")
    a = arrays(short_set)
    case[1](a)
    with pytest.raises(ValueError) as e:
        pdcal.Dataset(**a)
    assert str(e.value) == expected.replace(f"{bad}/", "")


def test_a_bad_scenario_raises_the_cli_message(pdcal_bin, tmp_path):
    expected = cli_error(pdcal_bin, "simulate", "--scenario", "no-such", "--out", tmp_path / "x")
    with pytest.raises(ValueError) as e:
        pdcal.simulate("no-such")
    assert str(e.value) == expected
    bad = tmp_path / "bad.ron"
    bad.write_text("(name: 1)\n")
    expected = cli_error(pdcal_bin, "simulate", "--scenario", bad, "--out", tmp_path / "x")
    with pytest.raises(ValueError) as e:
        pdcal.simulate(bad)
    assert str(e.value) == expected
    scenario = pdcal.scenario()
    scenario["duration_s"] = -1.0
    with pytest.raises(ValueError, match="duration_s"):
        pdcal.simulate(scenario)

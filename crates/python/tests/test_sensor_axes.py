"""The sensor-axes findings from Python: none on the simulated set, the gyro's reversed
y axis found (with the matrix the CLI writes) when its column is negated."""

import csv

import pdcal


def test_clean_set_has_no_sensor_axes_finding(short_dir):
    cal = pdcal.calibrate(pdcal.Dataset.read(short_dir))
    assert cal.sensor_axes == []


def test_a_reversed_gyro_axis_is_found_and_applied(short_dir, tmp_path):
    ds = pdcal.Dataset.read(short_dir)
    ds.write(tmp_path / "reversed")
    path = tmp_path / "reversed" / "telemetry.csv"
    rows = list(csv.reader(path.open()))
    k = rows[0].index("gyro_y_rad_s")
    for row in rows[1:]:
        if row[k]:
            row[k] = repr(-float(row[k]))
    with path.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)
    cal = pdcal.calibrate(pdcal.Dataset.read(tmp_path / "reversed"))
    [finding] = cal.sensor_axes
    assert finding["sensor"] == "gyro"
    assert finding["body_from_sensor"] == [[1, 0, 0], [0, -1, 0], [0, 0, 1]]
    assert finding["applied"] is True
    assert finding["evidence"]["log_odds_nats"] > 100

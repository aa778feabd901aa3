"""pdcal.campaign on a real Dask LocalCluster of two worker processes: the same numbers as
`cargo xtask sim-calibrate`, a worker killed mid-campaign, an interrupted campaign resumed,
failing runs recorded, dispersions applied to the scenario as documented.

The xtask binary is `$XTASK_BIN`, else the workspace's `target/release/xtask`
(`cargo build --release -p xtask`); the comparison fails, not skips, without it.
"""

import json
import math
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pandas as pd
import pytest
from distributed import Client, LocalCluster

import pdcal
import pdcal.campaign as campaign

ROOT = pathlib.Path(__file__).resolve().parents[3]

# 50 minutes of the RAX-2-like scenario (24 in eclipse, 26 sunlit): about a second a run.
SHORT = {"duration_s": 3000.0}
# Columns that differ between two runs of the same campaign: where and how long it ran.
VARYING = ["wall_s", "worker", "runtime_s"]


@pytest.fixture(scope="module")
def client():
    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def six_seeds(tmp_path_factory):
    spec = {
        "name": "six",
        "scenario": "rax2-like",
        "overrides": SHORT,
        "dispersions": {"tumble_rate_deg_s": {"uniform": [2.0, 6.0]}},
        "seeds": 6,
    }
    path = tmp_path_factory.mktemp("spec") / "six.json"
    path.write_text(json.dumps(spec))
    return path


@pytest.fixture(scope="module")
def undisturbed(client, six_seeds, tmp_path_factory):
    out = tmp_path_factory.mktemp("undisturbed")
    return campaign.run(six_seeds, out, client=client)


def same(a, b):
    a = a.drop(columns=[c for c in VARYING if c in a]).reset_index(drop=True)
    b = b.drop(columns=[c for c in VARYING if c in b]).reset_index(drop=True)
    pd.testing.assert_frame_equal(a, b, check_exact=True)


def test_equals_xtask_sim_calibrate(client, tmp_path):
    xtask = pathlib.Path(os.environ.get("XTASK_BIN", ROOT / "target" / "release" / "xtask"))
    assert xtask.is_file(), f"{xtask}: build it with cargo build --release -p xtask"
    text = (ROOT / "fixtures" / "scenarios" / "rax2-like.ron").read_text()
    assert "duration_s: 7200.0," in text
    (tmp_path / "short.ron").write_text(text.replace("duration_s: 7200.0,", "duration_s: 3000.0,"))
    done = subprocess.run(
        [str(xtask), "sim-calibrate", "--seeds", "2", "--scenario", "short.ron"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    expected = json.loads(
        (tmp_path / "out" / "sim-calibrate" / "rax2-like-full" / "results.json").read_text()
    )

    # The built-in scenario with its duration overridden, not the RON file.
    spec = {"scenario": "rax2-like", "overrides": SHORT, "seeds": [1, 2]}
    table = campaign.run(spec, tmp_path / "campaign", client=client)
    assert list(table["status"]) == ["ok", "ok"]
    assert len(expected) == 2
    for want, row in zip(expected, table.to_dict("records")):
        assert row["seed"] == want["seed"]
        got = {
            "worst_normal_deg": row["worst_normal_deg"],
            "worst_scale_percent": row["worst_scale_percent"],
            "attitude_rms_deg": row["attitude_rms_deg"],
            "attitude_settled_rms_deg": row["attitude_settled_rms_deg"],
            "segments": [row["segments"], row["segments_lost"]],
            "first_lost": None
            if row["first_lost"] is None
            else [row["first_lost_row"], row["first_lost"]],
            "best_single": None,
            "final_inside": [row["final_inside"], row["final_states"]],
            "residual_inside": row["residual_inside"],
            "magnitude": [row["magnitude_mean"], row["magnitude_std"]],
            "converged": row["converged"],
            "verdict": row["verdict"],
            "by_status": {
                "calibrated": row["calibrated_states"],
                "calibrated_outside_3sigma": row["calibrated_outside_3sigma"],
                "weakly_determined": row["weakly_determined_states"],
                "weakly_determined_outside_3sigma": row["weakly_determined_outside_3sigma"],
                "not_determined": row["not_determined_states"],
                "not_determined_outside_3sigma": row["not_determined_outside_3sigma"],
            },
            "attitude_about_sun_inside": row["attitude_about_sun_inside"],
            "attitude_across_sun_inside": row["attitude_across_sun_inside"],
            "smoothed_attitude_sun_inside": [
                row["smoothed_attitude_about_sun_inside"],
                row["smoothed_attitude_across_sun_inside"],
            ],
            "gyro_bias_inside": row["gyro_bias_inside"],
            "repeatability": row["repeatability"],
            "differing": [d for d in row["repeat_differing"].split(";") if d],
            "bias_change_warnings": row["bias_change_warnings"],
            "repeat_tests_beyond_3": [
                row["repeat_tests_beyond_3"],
                row["repeat_tests"],
                row["repeat_rms_z"],
            ],
            "about_sun_probes": [
                row["about_sun_probes"],
                row["about_sun_turned"],
                row["about_sun_undecided"],
            ],
            "dynamics": [row["dynamics"], row["gyro_rate_chi_square_per_dof"]],
            "sigma_factor": row["sigma_factor"],
            "mounting_warning": row["mounting_warning"],
        }
        rotation = want["normals_rotation"]
        assert [
            row["normals_rotation_deg"],
            row["normals_rotation_chi_square"],
            row["normals_rotation_explained"],
            row["normals_turned"],
        ] == (
            [None] * 4
            if rotation is None
            else [
                rotation["angle_deg"],
                rotation["chi_square"],
                rotation["explained"],
                rotation["finding"],
            ]
        ), row["run_id"]
        skipped = ("seed", "runtime_s", "normals_rotation")
        want = {k: v for k, v in want.items() if k not in skipped}
        assert got == want, row["run_id"]
        # The worst photodiode of the per-photodiode errors is the worst of the table.
        lit = [
            i
            for i in range(1, 18)
            if row[f"pd{i:02d}_lit_minutes"] >= 5.0
        ]
        assert max(row[f"pd{i:02d}_normal_error_deg"] for i in lit) == row["worst_normal_deg"]
    # The summary beside the table.
    assert (tmp_path / "campaign" / "index.html").is_file()
    assert (tmp_path / "campaign" / "results.csv").is_file()

    # The options of a run: photodiode-only, passes, two downlinks calibrated jointly (and
    # each alone: best_single).
    done = subprocess.run(
        [
            str(xtask), "sim-calibrate", "--seeds", "1", "--scenario", "short.ron",
            "--photodiode-only", "--cut", "passes:600/900", "--sets", "2",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    (want,) = json.loads(
        (
            tmp_path / "out" / "sim-calibrate"
            / "rax2-like-photodiode-only-passes-600-900-2-sets" / "results.json"
        ).read_text()
    )
    spec = {
        "scenario": str(tmp_path / "short.ron"),
        "seeds": [1],
        "photodiode_only": True,
        "cut": "passes:600/900",
        "sets": 2,
    }
    (row,) = campaign.run(spec, tmp_path / "options", client=client).to_dict("records")
    assert row["status"] == "ok", row["error"]
    assert [row["best_single_normal_deg"], row["best_single_scale_percent"]] == want["best_single"]
    for key in [
        "worst_normal_deg",
        "worst_scale_percent",
        "attitude_rms_deg",
        "attitude_settled_rms_deg",
        "residual_inside",
        "converged",
    ]:
        assert row[key] == want[key], key
    assert [row["final_inside"], row["final_states"]] == want["final_inside"]
    assert [row["magnitude_mean"], row["magnitude_std"]] == want["magnitude"]


def test_killed_worker_reschedules(client, six_seeds, undisturbed, tmp_path):
    pids = client.run(os.getpid)
    result = {}

    def go():
        try:
            result["table"] = campaign.run(six_seeds, tmp_path, client=client)
        except BaseException as e:  # pragma: no cover - reported below
            result["error"] = e

    thread = threading.Thread(target=go)
    thread.start()
    # Kill a worker while it runs a task (its process, as the OOM killer or a node would).
    victim, in_flight = None, []
    deadline = time.time() + 60
    while victim is None and time.time() < deadline:
        busy = {w: t for w, t in client.processing().items() if t}
        if busy:
            victim = sorted(busy)[0]
            in_flight = [str(k).split("-", 2)[2] for k in busy[victim]]
        else:
            time.sleep(0.02)
    assert victim is not None, "no worker became busy"
    os.kill(pids[victim], signal.SIGKILL)
    thread.join(timeout=300)
    assert not thread.is_alive()
    assert "error" not in result, result.get("error")
    table = result["table"]
    assert list(table["status"]) == ["ok"] * 6
    same(table, undisturbed)
    # The written table is the returned one.
    same(campaign.read_table(tmp_path), undisturbed)
    # The runs the killed worker held finished on another worker (its restarted process
    # has a new address).
    assert in_flight and set(in_flight) <= set(table["run_id"]), in_flight
    assert victim not in set(table.set_index("run_id").loc[in_flight, "worker"])
    assert pids[victim] not in client.run(os.getpid).values()


def test_interrupted_campaign_resumes(client, six_seeds, undisturbed, tmp_path):
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "pdcal.campaign", str(six_seeds), "--out", str(out), "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    table = out / campaign.TABLE
    deadline = time.time() + 120
    while not table.exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.02)
    assert table.exists(), proc.communicate()[1] if proc.poll() is not None else "no table"
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "interrupted; run again to resume" in stderr
    partial = campaign.read_table(out)
    assert 1 <= len(partial) < 6, len(partial)

    resumed = campaign.run(six_seeds, out, client=client)
    same(resumed, undisturbed)
    # The rows present before were kept, not run again.
    kept = resumed.set_index("run_id").loc[partial["run_id"]]
    assert list(kept["wall_s"]) == list(partial["wall_s"])
    # A finished campaign resumed runs nothing and gives the same table.
    same(campaign.run(six_seeds, out, client=client), undisturbed)


def test_failing_run_is_recorded(client, tmp_path):
    spec = {
        "scenario": "rax2-like",
        "overrides": SHORT,
        "dispersions": {"scenario.gyro.noise_rad_s": {"choice": [0.00087, -1.0]}},
        "seeds": [],
    }
    # Seeds whose draw is the invalid noise and the valid one.
    draws = {s: campaign.draw({**spec, "draw_seed": 0}, s) for s in range(1, 20)}
    bad = next(s for s, d in draws.items() if d["scenario.gyro.noise_rad_s"] < 0)
    good = next(s for s, d in draws.items() if d["scenario.gyro.noise_rad_s"] > 0)
    spec["seeds"] = [good, bad]
    table = campaign.run(spec, tmp_path, client=client).set_index("seed")
    assert table.loc[good, "status"] == "ok"
    assert table.loc[bad, "status"] == "failed"
    assert "noise_rad_s" in table.loc[bad, "error"], table.loc[bad, "error"]
    assert table.loc[bad, "param_scenario.gyro.noise_rad_s"] == -1.0
    assert "Failed runs" in (tmp_path / "index.html").read_text()
    # A run that cannot calibrate (24 min of eclipse: nothing lit) fails with the library's
    # message and the campaign goes on.
    spec = {"scenario": "rax2-like", "overrides": {"duration_s": 600.0}, "seeds": [1]}
    table = campaign.run(spec, tmp_path / "eclipse", client=client)
    assert list(table["status"]) == ["failed"]
    assert "nothing to calibrate" in table["error"][0]


def test_dispersions_reach_the_scenario():
    spec = campaign.load(
        {
            "scenario": "rax2-like",
            "dispersions": {
                "altitude_km": {"uniform": [500.0, 600.0]},
                "inclination_deg": {"uniform": [45.0, 98.0]},
                "local_time_h": {"uniform": [6.0, 18.0]},
                "tumble_rate_deg_s": {"log_uniform": [1.0, 10.0]},
                "albedo_map": {"choice": ["ceres-5x5", "none"]},
                "mounting_error_max_deg": {"uniform": [0.0, 10.0]},
            },
            "seeds": 3,
        }
    )
    for seed in spec["seeds"]:
        p = campaign.draw(spec, seed)
        assert p == campaign.draw(spec, seed)
        assert 500 <= p["altitude_km"] <= 600 and 1 <= p["tumble_rate_deg_s"] <= 10
        s = campaign.scenario_for(spec, p)
        line2 = s["orbit"]["Tle"]["line2"]
        assert float(line2[8:16]) == pytest.approx(p["inclination_deg"], abs=1e-4)
        ecc = float("0." + line2[26:33])
        n_rev_day = float(line2[52:63])
        a_km = (398600.4418 / (n_rev_day * 2 * math.pi / 86400) ** 2) ** (1 / 3)
        assert a_km - 6378.137 == pytest.approx(p["altitude_km"], abs=0.01)
        assert s["spacecraft"]["initial_rate"]["RandomTumble"]["magnitude_rad_s"] == pytest.approx(
            math.radians(p["tumble_rate_deg_s"])
        )
        albedo = [e for e in s["effects"] if isinstance(e, dict) and "Albedo" in e]
        assert albedo == ([] if p["albedo_map"] == "none" else [{"Albedo": {"map": p["albedo_map"]}}])
        assert s["photodiodes"]["mounting_error_deg"]["Uniform"]["max"] == p["mounting_error_max_deg"]
        # The simulator accepts the orbit (the TLE checksum, the elements) and flies it: the
        # node is where the local time puts it.
        s["duration_s"] = 10.0
        truth = pdcal.simulate(s, seed=seed).truth
        r = truth["r_gcrf_km"][0]
        assert np.linalg.norm(r) - 6378.137 == pytest.approx(
            p["altitude_km"], abs=6378.137 * ecc + 30
        )
        raan = float(line2[17:25])
        ra_sun = campaign._sun_right_ascension_deg(s["epoch_utc"])
        offset = (raan - ra_sun - 15 * (p["local_time_h"] - 12) + 180) % 360 - 180
        assert offset == pytest.approx(0, abs=1e-3)
        # The almanac's Sun against the simulator's ephemeris: the Sun in GCRF from the
        # truth (v_B = A(q) v_I, scalar last).
        x, y, z, w = truth["q_xyzw"][0]
        v = np.array([x, y, z])
        cross = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
        a = (w * w - v @ v) * np.eye(3) + 2 * np.outer(v, v) - 2 * w * cross
        sun_gcrf = a.T @ truth["sun_body"][0]
        # From the Earth's centre (the spacecraft's parallax is up to 0.15 deg).
        sun_gcrf = sun_gcrf / np.linalg.norm(sun_gcrf) * 1.496e8 + r
        ra_truth = math.degrees(math.atan2(sun_gcrf[1], sun_gcrf[0])) % 360
        # The almanac's right ascension is of the equinox of date; GCRF's is J2000's
        # (0.014 deg a year of precession apart, 0.15 deg in 2011).
        assert (ra_truth - ra_sun + 180) % 360 - 180 == pytest.approx(0, abs=0.25)


def test_description_errors():
    with pytest.raises(ValueError, match="unknown key 'seed'"):
        campaign.load({"seed": [1]})
    with pytest.raises(ValueError, match="dispersion 'tumble'"):
        campaign.load({"dispersions": {"tumble": {"uniform": [1, 2]}}})
    with pytest.raises(ValueError, match="uniform needs lo <= hi"):
        campaign.load({"dispersions": {"altitude_km": {"uniform": [600, 500]}}})
    with pytest.raises(ValueError, match="perigee below 150 km"):
        campaign.load({"overrides": {"altitude_km": 100.0}})


def test_ron_description(tmp_path):
    (tmp_path / "study.ron").write_text(
        """// A design study.
(
    name: "study",
    scenario: "rax2-like",
    overrides: {"duration_s": 600.0},
    dispersions: {
        "gyro_bias_max_deg_s": {"uniform": (0.1, 0.5)},
        "albedo_map": {"choice": ["toms-mean-1p25x1", "ceres-1x1"]},
    },
    seeds: (first: 10, count: 3),
    cut: "passes:300/600",
)
"""
    )
    spec = campaign.load(tmp_path / "study.ron")
    assert spec["seeds"] == [10, 11, 12]
    assert spec["dispersions"]["gyro_bias_max_deg_s"] == {"uniform": [0.1, 0.5]}
    assert spec["cut"] == "passes:300/600"
    (tmp_path / "bad.ron").write_text("(name: \"x\",\n seeds: [1,, 2])")
    with pytest.raises(ValueError, match="bad.ron"):
        campaign.load(tmp_path / "bad.ron")


def test_fleet_calibrates_each_dataset_alone(client, short_set, tmp_path):
    # Two downlinks of one simulated spacecraft, each a dataset directory.
    short_set.write(tmp_path / "sat-a" / "d1")
    scenario = pdcal.scenario("rax2-like")
    scenario["duration_s"] = 3000.0
    other = pdcal.simulate(scenario, seed=3, downlink=1)
    other.write(tmp_path / "sat-a" / "d2")
    table = campaign.run({"fleet": str(tmp_path / "sat-a" / "d*")}, tmp_path / "out", client=client)
    assert list(table["run_id"]) == ["d1", "d2"]
    assert list(table["status"]) == ["ok", "ok"], list(table["error"])
    for row, ds in zip(table.to_dict("records"), [short_set, other]):
        cal = pdcal.calibrate(ds)
        assert [row[f"pd{i:02d}_scale_V"] for i in range(1, 18)] == list(cal.scale_V)
        assert row["worst_normal_deg"] == pdcal.evaluate(ds, cal)["worst_normal_error_deg"]
        # Each run's output is pdcal calibrate's.
        written = tmp_path / "out" / "runs" / row["run_id"]
        assert (written / "summary.json").is_file() and (written / "calibration.ron").is_file()

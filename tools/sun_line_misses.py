#!/usr/bin/env python3
"""Where a Sun-only run's attitude errors across the Sun line leave their 3 sigma.

For each seed: three downlinks of a scenario made as `cargo xtask sim-calibrate --sets 3`
makes them (the epoch moved 30 days per downlink), the magnetometer columns dropped,
calibrated jointly by `pdcal calibrate`; then every sunlit row of `estimates.csv` against
the simulator's `truth.csv`:

- the evaluator's test across the Sun line (`pdcal_evaluate::sun_line_inside`: the error of
  the Sun direction along each principal axis of the across-line covariance);
- the largest across-line sigma of the row;
- the error of the attitude relative to the photodiodes: the estimated Sun direction turned
  by the rotation that best carries the row's estimated normals onto the true ones, and
  that rotation's angle.

Needs numpy and a release build (`cargo build --release -p pdcal`):

    python tools/sun_line_misses.py --scenario fixtures/scenarios/weak/pyramid-head.ron \
        --seeds 9 11 13 14 15 16 17 19 --work out/sun-line-misses

docs/validation.md ("Where the across-line misses are") holds what it printed.
"""

import argparse
import csv
import datetime
import json
import math
import os
import re
import statistics
import subprocess
import sys

import numpy as np

SET_SHIFT_DAYS = 30
SET_SHIFT_S = SET_SHIFT_DAYS * 86400.0
SIGMA_BINS_DEG = [(0, 10), (10, 20), (20, 30), (30, 45), (45, math.inf)]


def attitude_matrix(x, y, z, w):
    """`A(q)`, scalar last, `v_B = A v_I` (docs/dataset-format.md)."""
    v = np.array([x, y, z])
    cross = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return (w * w - v @ v) * np.eye(3) + 2 * np.outer(v, v) - 2 * w * cross


def normal(az_deg, el_deg):
    a, e = math.radians(az_deg), math.radians(el_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def shifted_scenario(text, k):
    """The scenario of downlink `k`: epoch moved `k * 30` days, name suffixed."""
    if k == 0:
        return text
    m = re.search(r'epoch_utc: "(\d{4})-(\d{2})-(\d{2})T([^"]*)"', text)
    day = datetime.date(int(m[1]), int(m[2]), int(m[3])) + datetime.timedelta(
        days=SET_SHIFT_DAYS * k
    )
    text = text.replace(m[0], f'epoch_utc: "{day.isoformat()}T{m[4]}"')
    return re.sub(r'name: "([^"]*)"', lambda n: f'name: "{n[1]}-set{k + 1}"', text, count=1)


def drop_magnetometer(path):
    rows = list(csv.reader(open(path)))
    keep = [i for i, h in enumerate(rows[0]) if not h.startswith("mag_")]
    with open(path + ".tmp", "w", newline="") as f:
        w = csv.writer(f)
        for r in rows:
            w.writerow([r[i] for i in keep])
    os.replace(path + ".tmp", path)


def run_seed(pdcal, scenario_text, seed, work):
    sets = []
    for k in range(3):
        scen = os.path.join(work, f"scenario-{k}.ron")
        with open(scen, "w") as f:
            f.write(shifted_scenario(scenario_text, k))
        out = os.path.join(work, f"s{seed}d{k}")
        if not os.path.isdir(out):
            subprocess.run(
                [pdcal, "simulate", "--scenario", scen, "--seed", str(seed),
                 "--downlink", str(k), "--out", out],
                check=True, capture_output=True,
            )
            drop_magnetometer(os.path.join(out, "telemetry.csv"))
        sets.append(out)
    cal = os.path.join(work, f"o{seed}")
    subprocess.run([pdcal, "calibrate", *sets, "--out", cal], check=True, capture_output=True)
    return sets, cal


def true_normals(truth_ron):
    text = open(truth_ron).read()
    found = re.findall(
        r"scale_V: ([-\d.e]+), azimuth_deg: ([-\d.e]+), elevation_deg: ([-\d.e]+)", text
    )
    return [normal(float(az), float(el)) for _, az, el in found]


def about_inside(a_true, a_est, s_true, p_deg2):
    """`pdcal_evaluate::sun_line_inside`'s test about the Sun line."""
    turn = a_true @ a_est.T  # body vectors of the estimate to the truth's
    angle = math.acos(max(-1.0, min(1.0, (np.trace(turn) - 1) / 2)))
    axis = np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]])
    n = np.linalg.norm(axis)
    err = axis / n * math.degrees(angle) if n > 1e-12 else 0 * axis
    return abs(err @ s_true) <= 3 * math.sqrt(max(s_true @ p_deg2 @ s_true, 0.0))


def across_inside(s_true, s_est, p_deg2):
    """`pdcal_evaluate::sun_line_inside`'s across-line test."""
    cross = np.cross(s_est, s_true)
    angle = math.degrees(math.atan2(np.linalg.norm(cross), s_est @ s_true))
    err = cross / np.linalg.norm(cross) * angle if np.linalg.norm(cross) > 1e-15 else 0 * cross
    e1 = np.cross(s_true, [1.0, 0.0, 0.0])
    if np.linalg.norm(e1) < 1e-6:
        e1 = np.cross(s_true, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    basis = np.stack([e1, np.cross(s_true, e1)], 1)
    w, v = np.linalg.eigh(basis.T @ p_deg2 @ basis)
    return all(abs(err @ (basis @ v[:, k])) <= 3 * math.sqrt(max(w[k], 0)) for k in range(2))


def attitude_cov_deg2(r):
    p = np.diag([float(r[f"att_sigma_{c}_deg"]) ** 2 for c in "xyz"])
    for (i, j), name in {(0, 1): "xy", (0, 2): "xz", (1, 2): "yz"}.items():
        p[i, j] = p[j, i] = float(r[f"att_cov_{name}_deg2"])
    return p


def angle_deg(a, b):
    return math.degrees(math.acos(max(-1.0, min(1.0, a @ b))))


def rows_of(sets, cal):
    truth = []
    for d in sets:
        truth.append({round(float(r["t_s"]), 3): r for r in csv.DictReader(open(d + "/truth.csv"))})
    n_true = true_normals(os.path.join(sets[0], "truth.ron"))
    photodiodes = len(n_true)
    out = []
    for r in csv.DictReader(open(cal + "/estimates.csv")):
        t = float(r["t_s"])
        k = min(len(sets) - 1, int(t // SET_SHIFT_S))
        tr = truth[k].get(round(t - k * SET_SHIFT_S, 3))
        if tr is None or float(tr["eclipse"]) < 0.999:
            continue
        s_true = np.array([float(tr[c]) for c in ("sun_x", "sun_y", "sun_z")])
        s_true /= np.linalg.norm(s_true)
        a_true = attitude_matrix(*(float(tr[c]) for c in ("q_x", "q_y", "q_z", "q_w")))
        a_est = attitude_matrix(*(float(r[c]) for c in ("q_x", "q_y", "q_z", "q_w")))
        s_est = a_est @ (a_true.T @ s_true)
        n_est = [
            normal(float(r[f"pd{i:02d}_azimuth_deg"]), float(r[f"pd{i:02d}_elevation_deg"]))
            for i in range(1, photodiodes + 1)
        ]
        u, _, vt = np.linalg.svd(sum(np.outer(t_, e) for t_, e in zip(n_true, n_est)))
        turn = u @ np.diag([1, 1, np.linalg.det(u @ vt)]) @ vt
        p = attitude_cov_deg2(r)
        along = s_est / np.linalg.norm(s_est)
        proj = np.eye(3) - np.outer(along, along)
        sigma = math.sqrt(max(np.linalg.eigvalsh(proj @ p @ proj).max(), 0.0))
        out.append(
            dict(
                error=angle_deg(s_true, s_est),
                relative=angle_deg(s_true, turn @ s_est),
                common=math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(turn) - 1) / 2)))),
                sigma=sigma,
                inside=across_inside(s_true, s_est, p),
                about=about_inside(a_true, a_est, s_true, p),
                segment=int(r["segment"]),
            )
        )
    return out


def about_by_probe(cal, rows):
    """About-line misses in segments whose half-turn probe was decided / not decided."""
    segments = json.load(open(cal + "/summary.json"))["segments"]
    decided = {
        i: (s.get("about_sun_line") or {}).get("decided")
        for i, s in enumerate(segments)
    }
    out = {}
    for label, want in (("decided", True), ("not decided", False), ("not probed", None)):
        sel = [x for x in rows if decided.get(x["segment"]) is want]
        out[label] = (sum(not x["about"] for x in sel), len(sel))
    return out


def report(seed, rows):
    misses = [x for x in rows if not x["inside"]]
    bins = []
    for lo, hi in SIGMA_BINS_DEG:
        sel = [x for x in rows if lo <= x["sigma"] < hi]
        bins.append(f"{lo}-{hi}: {sum(not x['inside'] for x in sel)}/{len(sel)}")
    line = f"seed {seed}: {len(misses)} of {len(rows)} sunlit rows outside; by sigma (deg) " + ", ".join(bins)
    if misses:
        med = {k: statistics.median(x[k] for x in misses) for k in ("error", "relative", "common", "sigma")}
        line += (
            f"; misses' median error {med['error']:.1f} deg, relative to the photodiodes"
            f" {med['relative']:.1f}, normals' common rotation {med['common']:.1f},"
            f" sigma {med['sigma']:.1f}"
        )
    print(line)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--seeds", type=int, nargs="+", required=True)
    ap.add_argument("--work", default="out/sun-line-misses")
    ap.add_argument("--pdcal", default="target/release/pdcal")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    text = open(args.scenario).read()
    for seed in args.seeds:
        try:
            sets, cal = run_seed(args.pdcal, text, seed, args.work)
        except subprocess.CalledProcessError as e:
            print(f"seed {seed}: {' '.join(e.cmd[:2])} failed: {e.stderr.decode().strip()}")
            continue
        rows = rows_of(sets, cal)
        report(seed, rows)
        print("  about the Sun line outside, by the segment's half-turn probe:", about_by_probe(cal, rows))


if __name__ == "__main__":
    sys.exit(main())

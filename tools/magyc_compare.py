#!/usr/bin/env python3
"""An independent check of `pdcal magcal` against TWOSTEP as the `magyc` package implements it.

Outside CI (magyc pulls in gtsam and jax). The data come from the simulator through

    cargo xtask magcal-validate --seeds 20 --export out/magyc/main
    cargo xtask magcal-validate --seeds 20 \
        --scenario fixtures/scenarios/magcal/rax2-like-magcal-control.ron \
        --export out/magyc/control

which write, per seed, the samples the fit used (`seed-N.csv`: raw magnetometer, the IGRF-14
magnitude along the orbit, the current columns) and the truth with pdcal's estimate
(`seed-N.json`). Then, in a virtual environment with magyc (`pip install magyc`):

    python tools/magyc_compare.py out/magyc/control out/magyc/main

Both estimates are scored by the same code against the truth: the hard-iron error, the error
of the symmetric matrix `S = (T T^T)^(1/2)` (the part of `T` the field magnitude determines,
docs/magcal.md), and the field-magnitude residual RMS against what the noise alone gives.

magyc's TWOSTEP (Alonso & Shuster 2002, `magyc.benchmark_methods.twostep_hsi`) is written for
one place on Earth: one reference vector for every row. In orbit the field magnitude changes
from row to row (20-50 uT), and TWOSTEP's scalar measurement `|m_k|^2 - |H_k|^2` needs each
row's own `|H_k|`. magyc uses the reference only through that per-row norm
(`np.ones(shape) * reference`), so the rows' references are passed as an (N, 3) array whose
shape check is satisfied by `PerRowReference`; with all rows equal it gives magyc's result
for one reference to the last bit (checked below at every run). TWOSTEP has no current
regressors: on the main scenario the currents' bias is left in its data, as it would be in
any user's who had only TWOSTEP.
"""

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np
from magyc.benchmark_methods import twostep_hsi


class PerRowReference(np.ndarray):
    """Rows of reference vectors, reported as one-dimensional to pass magyc's shape check."""

    @property
    def ndim(self):
        return 1


def twostep(mag_ut, field_ut, noise_ut):
    """magyc's TWOSTEP with each row's reference magnitude: returns (b, S) in the model
    m = S B + b (magyc's `hard_iron`, `soft_iron`)."""
    reference = np.zeros((len(field_ut), 3))
    reference[:, 2] = field_ut
    hard, soft, _ = twostep_hsi(mag_ut, reference.view(PerRowReference), measurement_noise_std=noise_ut)
    return np.asarray(hard, dtype=float), np.asarray(soft, dtype=float)


def per_row_reference_is_magyc(mag_ut, noise_ut):
    """With one magnitude on every row the per-row call is magyc's own call."""
    field = 45.0
    b1, s1 = twostep(mag_ut, np.full(len(mag_ut), field), noise_ut)
    b2, s2, _ = twostep_hsi(mag_ut, np.array([0.0, 0.0, field]), measurement_noise_std=noise_ut)
    return np.array_equal(b1, b2) and np.array_equal(s1, s2)


def load(path_csv):
    with open(path_csv, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        data = np.array([[float(x) for x in row] for row in reader])
    columns = {name: data[:, i] for i, name in enumerate(header)}
    mag = np.column_stack([columns["mag_x_nT"], columns["mag_y_nT"], columns["mag_z_nT"]])
    currents = {name: columns[name] for name in header if name.startswith("cur_")}
    return mag, columns["field_nT"], currents


def debiased(mag, currents, bias, coeffs):
    out = mag - bias
    for name, c in coeffs.items():
        out = out - np.outer(currents[name], c)
    return out


def residual_rms(mag, field, currents, s, bias, coeffs):
    corrected = debiased(mag, currents, bias, coeffs) @ np.linalg.inv(s).T
    r = np.linalg.norm(corrected, axis=1) - field
    return math.sqrt(np.mean(r * r))


def noise_alone(mag, currents, truth, noise):
    """sigma sqrt(mean g^T P P g), P = S^-1, g the corrected field's direction."""
    p = np.linalg.inv(np.array(truth["symmetric_matrix"]))
    coeffs = {k: np.array(v) for k, v in truth["current_bias_nT_per_A"].items()}
    g = debiased(mag, currents, np.array(truth["bias_nT"]), coeffs) @ p.T
    g /= np.linalg.norm(g, axis=1, keepdims=True)
    return noise * math.sqrt(np.mean(np.sum((g @ p) ** 2, axis=1)))


def score(estimate, truth, mag, field, currents):
    s = np.array(estimate["matrix"])
    bias = np.array(estimate["bias_nT"])
    coeffs = {k: np.array(v) for k, v in estimate["current_bias_nT_per_A"].items()}
    return {
        "bias": float(np.linalg.norm(bias - np.array(truth["bias_nT"]))),
        "matrix": float(np.max(np.abs(s - np.array(truth["symmetric_matrix"])))),
        "rms": residual_rms(mag, field, currents, s, bias, coeffs),
    }


def compare(directory):
    rows = []
    for path in sorted(Path(directory).glob("seed-*.json"), key=lambda p: int(p.stem.split("-")[1])):
        meta = json.loads(path.read_text())
        mag, field, currents = load(path.with_suffix(".csv"))
        truth, noise = meta["truth"], meta["noise_nT"]
        if not rows and not per_row_reference_is_magyc(mag / 1000.0, noise / 1000.0):
            sys.exit("the per-row reference does not reproduce magyc's own call")
        b_ut, s = twostep(mag / 1000.0, field / 1000.0, noise / 1000.0)
        magyc_estimate = {"matrix": s, "bias_nT": 1000.0 * b_ut, "current_bias_nT_per_A": {}}
        rows.append(
            {
                "seed": meta["seed"],
                "rows": len(field),
                "noise": noise_alone(mag, currents, truth, noise),
                "pdcal": score(meta["pdcal"], truth, mag, field, currents),
                "magyc": score(magyc_estimate, truth, mag, field, currents),
                "kept": sorted(meta["pdcal"]["current_bias_nT_per_A"]),
            }
        )
    return rows


def table(directory, rows):
    out = [f"#### {directory}: pdcal magcal against magyc 1.0.0 TWOSTEP (twostep_hsi), seeds "
           f"{rows[0]['seed']}..={rows[-1]['seed']}", ""]
    out.append("| seed | hard iron error, nT (pdcal / TWOSTEP) | max error of S, 1e-3 (pdcal / TWOSTEP) "
               "| residual RMS, nT (pdcal / TWOSTEP) | noise alone, nT | pdcal's regressors |")
    out.append("|---|---|---|---|---|---|")
    for r in rows:
        p, m = r["pdcal"], r["magyc"]
        kept = " ".join(k[4:-2] for k in r["kept"]) or "-"
        out.append(
            f"| {r['seed']} | {p['bias']:.1f} / {m['bias']:.1f} | {1e3 * p['matrix']:.2f} / {1e3 * m['matrix']:.2f} "
            f"| {p['rms']:.1f} / {m['rms']:.1f} | {r['noise']:.1f} | {kept} |"
        )
    out.append("")
    for key, label, scale, fmt in [("bias", "hard iron error, nT", 1.0, "{:.1f}"),
                                   ("matrix", "max error of S, 1e-3", 1e3, "{:.2f}"),
                                   ("rms", "residual RMS / noise alone", None, "{:.3f}")]:
        def values(method):
            if scale is None:
                return [r[method][key] / r["noise"] for r in rows]
            return [scale * r[method][key] for r in rows]
        cells = []
        for method in ("pdcal", "magyc"):
            v = values(method)
            cells.append(f"{fmt.format(np.mean(v))} mean, {fmt.format(np.max(v))} worst")
        out.append(f"- {label}: pdcal {cells[0]}; TWOSTEP {cells[1]}")
    return "\n".join(out) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dirs", nargs="+", help="directories written by magcal-validate --export")
    args = parser.parse_args()
    for d in args.dirs:
        print(table(d, compare(d)))


if __name__ == "__main__":
    main()

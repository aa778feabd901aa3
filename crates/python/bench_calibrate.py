"""Python `calibrate` against `pdcal calibrate` on one data set, runs interleaved so that
both see the same machine load (docs/performance.md).

    python crates/python/bench_calibrate.py DATASET_DIR PDCAL_BIN [RUNS]

Times, per run: the CLI process (read, calibrate, write the files); in Python the same
three steps (`Dataset.read`, `calibrate`, `Calibration.write`), and `calibrate` alone; and
both runs' filter time (`runtime_s` of summary.json).
"""

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import pdcal


def main():
    dataset, binary = sys.argv[1], sys.argv[2]
    runs = int(sys.argv[3]) if len(sys.argv) > 3 else 10
    cli, py_all, py_cal, cli_filter, py_filter = [], [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(runs):
            out = os.path.join(tmp, f"cli{i}")
            start = time.perf_counter()
            subprocess.run([binary, "calibrate", dataset, "--out", out], check=True,
                           capture_output=True)
            cli.append(time.perf_counter() - start)
            with open(os.path.join(out, "summary.json")) as f:
                cli_filter.append(json.load(f)["runtime_s"])
            start = time.perf_counter()
            ds = pdcal.Dataset.read(dataset)
            t_cal = time.perf_counter()
            cal = pdcal.calibrate(ds)
            py_cal.append(time.perf_counter() - t_cal)
            py_filter.append(cal.summary["runtime_s"])
            cal.write(os.path.join(tmp, f"py{i}"))
            py_all.append(time.perf_counter() - start)
    for name, xs in [("cli process", cli), ("python read+calibrate+write", py_all),
                     ("python calibrate", py_cal), ("cli filter (runtime_s)", cli_filter),
                     ("python filter (runtime_s)", py_filter)]:
        print(f"{name:30s} median {statistics.median(xs):.3f} s  min {min(xs):.3f} s"
              f"  max {max(xs):.3f} s  (n={len(xs)})")
    ratio = statistics.median(py_all) / statistics.median(cli)
    print(f"python/cli (read+calibrate+write, medians): {ratio:.3f}")
    print(f"python calibrate alone / cli process (medians): "
          f"{statistics.median(py_cal) / statistics.median(cli):.3f}")


if __name__ == "__main__":
    main()

"""Throughput of `pdcal.campaign` on this machine, and the per-run cost of Dask and of the
table (docs/performance.md).

    python crates/python/bench_campaign.py [RUNS] [WORKERS ...]

For each worker count: a LocalCluster of that many single-threaded worker processes; a
warm-up campaign of one run per worker (each process loads the albedo model once); then
a timed campaign of RUNS runs (rax2-like, 50 min, no dispersions, seeds from 1001), with
the table rewritten after every run as in any campaign. Printed: runs per minute, the mean
time inside a run (`wall_s`), and the overhead per run: the workers' time not spent in a
run, `(elapsed * workers - sum(wall_s)) / runs`. Then, with one worker, 500 empty Dask
tasks (submit, run, gather through as_completed): Dask's own cost per task; and the time
to write a 1000-row results table (Parquet and CSV).
"""

import os
import pathlib
import sys
import tempfile
import time

import pandas as pd
from distributed import Client, LocalCluster, as_completed

import pdcal.campaign as campaign


def spec(first, count):
    return {
        "name": "throughput",
        "scenario": "rax2-like",
        "overrides": {"duration_s": 3000.0},
        "seeds": {"first": first, "count": count},
    }


def noop(i):
    return {"run_id": i}


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    worker_counts = [int(w) for w in sys.argv[2:]] or [1, 2]
    print(f"load average at start: {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in worker_counts:
            with LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster, Client(cluster) as client:
                campaign.run(spec(1, n), f"{tmp}/warm{n}", client=client)
                start = time.perf_counter()
                table = campaign.run(spec(1001, runs), f"{tmp}/runs{n}", client=client)
                elapsed = time.perf_counter() - start
                inside = table["wall_s"].sum()
                print(
                    f"{n} worker(s): {runs} runs in {elapsed:.1f} s = "
                    f"{60 * runs / elapsed:.1f} runs/min; mean run {table['wall_s'].mean():.2f} s "
                    f"(filter {table['runtime_s'].mean():.2f} s); overhead per run "
                    f"{1000 * (elapsed * n - inside) / runs:.0f} ms; load {os.getloadavg()[0]:.1f}"
                )
        with LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster, Client(cluster) as client:
            client.gather(client.map(noop, range(10), pure=False))
            start = time.perf_counter()
            futures = [client.submit(noop, i, pure=False) for i in range(500)]
            for f in as_completed(futures):
                f.result()
            per_task = (time.perf_counter() - start) / 500
            print(f"empty Dask task, submit to result, 1 worker: {1000 * per_task:.2f} ms")
        row = campaign.read_table(f"{tmp}/runs{worker_counts[-1]}").iloc[0].to_dict()
        big = pd.DataFrame([{**row, "run_id": f"r{i}", "seed": i} for i in range(1000)])
        start = time.perf_counter()
        for _ in range(5):
            campaign.write_table(big, pathlib.Path(tmp))
        print(f"table write, 1000 rows x {big.shape[1]} columns: {1000 * (time.perf_counter() - start) / 5:.0f} ms")


if __name__ == "__main__":
    main()

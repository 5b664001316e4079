"""The README's sweep figure: a 100-run sweep (centre height × feed, 10 × 10) of
examples/sphere_centre_height.toml on a 2-worker LocalCluster, against the same runs in
series in one process.  python python/bench_sweep.py"""

import tempfile
import time
from pathlib import Path

import toolmark
from toolmark.dask_sweep import apply, expand, load_job_dict

ROOT = Path(__file__).resolve().parents[1]
JOB = ROOT / "examples/sphere_centre_height.toml"
GRID = {
    "effects.centre_height.height_mm": [round(-0.005 + 0.001 * i, 4) for i in range(10)],
    "process.feed_per_rev_mm": [round(0.003 + 0.001 * i, 4) for i in range(10)],
}

if __name__ == "__main__":
    job, base = load_job_dict(JOB)
    started = time.perf_counter()
    for point in expand(GRID):
        toolmark.run(apply(job, point), base_dir=base)
    series = time.perf_counter() - started
    from dask.distributed import Client, LocalCluster

    started = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                           env={"RAYON_NUM_THREADS": "1"})
    client = Client(cluster)
    start_s = time.perf_counter() - started
    with tempfile.TemporaryDirectory() as tmp:
        started = time.perf_counter()
        frame = toolmark.sweep(JOB, GRID, table=Path(tmp) / "sweep.csv", client=client, progress=False)
        dask = time.perf_counter() - started
    client.close()
    cluster.close()
    ok = int((frame.status == "ok").sum())
    print(f"100 runs: series {series:.1f} s (one process, the CPU engine on both cores); "
          f"2-worker LocalCluster {dask:.1f} s (+ {start_s:.1f} s to start it); {ok} ok; "
          f"speed-up {series / dask:.2f}x")

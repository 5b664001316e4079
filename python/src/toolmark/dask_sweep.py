"""Parameter sweeps on Dask: a job × a grid of parameters → one run per grid point on a
Dask cluster (a ``distributed.LocalCluster`` by default, any cluster by its scheduler
address — Slurm or PBS through ``dask-jobqueue``), gathered into a table.

A grid maps dotted job paths to lists of values; the runs are their Cartesian product:

* ``"process.feed_per_rev_mm": [0.005, 0.01]`` sets a job field;
* ``"effects.centre_height.height_mm": [0.001, 0.003]`` sets a parameter of the job's
  ``[[effects]]`` table of that kind (added when the job has none);
* ``"tool.nose_radius_mm": [...]``, ``"grid.azimuths": [...]`` and so on.

Every run becomes one row: its parameters, a run id (a hash of them), ``status``
(``ok`` or ``failed``), ``error`` (the message, with the job field it names), and the
summary's figures (deviation PV/RMS, scallop, central feature, ISO texture). A failed
run is recorded, never fatal. The table (CSV, or Parquet when the name ends in
``.parquet``) is rewritten as results arrive, so an interrupted sweep keeps what it
finished, and re-running the same sweep skips the run ids already in it (resume).

``toolmark sweep JOB --grid GRID.toml`` (the CLI) and ``python -m toolmark.dask_sweep``
take a grid file::

    [parameters]
    "process.feed_per_rev_mm" = [0.004, 0.006, 0.008]
    "effects.centre_height.height_mm" = [0.0, 0.002]

    [cluster]            # optional
    workers = 2          # LocalCluster size, or
    # address = "tcp://scheduler:8786"

    [output]             # optional
    table = "sweep.csv"
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import itertools
import json
import os
import sys
import time
import tomllib
from pathlib import Path
from typing import Any, Mapping, Optional

# The summary figures every row carries: column name → path in summary.json.
FIGURES = {
    "deviation_pv_nm": ("deviation", "pv_nm"),
    "deviation_rms_nm": ("deviation", "rms_nm"),
    "scallop_max_nm": ("scallop", "max_nm"),
    "scallop_mean_nm": ("scallop", "mean_nm"),
    "protrusion_shape": ("protrusion", "shape"),
    "protrusion_height_nm": ("protrusion", "height_nm"),
    "protrusion_radius_um": ("protrusion", "radius_um"),
    "sa_nm": ("texture", "areal", "sa_nm"),
    "sq_nm": ("texture", "areal", "sq_nm"),
    "sz_nm": ("texture", "areal", "sz_nm"),
    "removal_s": ("timings_s", "removal"),
}


def load_job_dict(job) -> tuple[dict, str]:
    """A job as a dict (parsed from a TOML path or text) and the folder its file names
    resolve against."""
    if isinstance(job, Mapping):
        return copy.deepcopy(dict(job)), os.getcwd()
    path = Path(job)
    if path.suffix == ".toml" and path.exists():
        with path.open("rb") as handle:
            return tomllib.load(handle), str(path.resolve().parent)
    return tomllib.loads(str(job)), os.getcwd()


def expand(grid: Mapping[str, list]) -> list[dict]:
    """The Cartesian product of the grid, as a list of {path: value}."""
    keys = list(grid)
    for key in keys:
        if not isinstance(grid[key], (list, tuple)) or not grid[key]:
            raise ValueError(f"grid {key!r}: give a non-empty list of values")
    return [dict(zip(keys, values)) for values in itertools.product(*(grid[k] for k in keys))]


def apply(job: dict, parameters: Mapping[str, Any]) -> dict:
    """A copy of ``job`` with each dotted path set (see the module docs)."""
    job = copy.deepcopy(job)
    for path, value in parameters.items():
        parts = path.split(".")
        if parts[0] == "effects" and len(parts) == 3:
            effects = job.setdefault("effects", [])
            table = next((e for e in effects if e.get("kind") == parts[1]), None)
            if table is None:
                table = {"kind": parts[1]}
                effects.append(table)
            table[parts[2]] = value
            continue
        node = job
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return job


def run_id(parameters: Mapping[str, Any]) -> str:
    text = json.dumps(parameters, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _figure(summary: dict, path: tuple) -> Any:
    node = summary
    for key in path:
        if not isinstance(node, dict):
            return None
        node = node.get(key)
    return node


def run_one(job: dict, base_dir: str, parameters: dict, engine: str = "cpu") -> dict:
    """One grid point: the job with its parameters, run; a row for the table. Never
    raises: a failure is a row with status "failed" and the error."""
    import toolmark

    row = {"run_id": run_id(parameters), **parameters}
    started = time.perf_counter()
    try:
        result = toolmark.run(apply(job, parameters), engine=engine, base_dir=base_dir)
        row.update(status="ok", error="")
        for column, path in FIGURES.items():
            row[column] = _figure(result.summary, path)
    except toolmark.JobError as err:
        row.update(status="failed", error=f"{err.field}: {err.message}")
    except Exception as err:  # a failed run is recorded, never fatal
        row.update(status="failed", error=f"{type(err).__name__}: {err}")
    row["wall_s"] = time.perf_counter() - started
    return row


def _read_table(path: Path):
    import pandas as pd

    if not path.exists():
        return pd.DataFrame()
    if path.suffix == ".parquet":
        return pd.read_parquet(path)
    return pd.read_csv(path)


def _write_table(frame, path: Path) -> None:
    """Temp file, then rename: an interrupted sweep never leaves half a table."""
    temp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    if path.suffix == ".parquet":
        frame.to_parquet(temp, index=False)
    else:
        frame.to_csv(temp, index=False)
    os.replace(temp, path)


def sweep(job, grid: Mapping[str, list], *, table: Optional[os.PathLike] = "sweep.csv",
          address: Optional[str] = None, client=None, workers: int = 2, threads_per_worker: int = 1,
          engine: str = "cpu", resume: bool = True, progress: Optional[bool] = None):
    """Runs ``job`` at every point of ``grid`` on Dask and returns the table (a pandas
    DataFrame, also written to ``table``). The cluster: ``client`` if given, else the
    scheduler at ``address``, else a new ``LocalCluster`` of ``workers`` processes.
    ``resume``: skip the run ids already in ``table``. ``progress``: a progress bar
    (default: only on a terminal)."""
    import pandas as pd
    from dask.distributed import Client, LocalCluster, as_completed

    job_dict, base_dir = load_job_dict(job)
    points = expand(grid)
    path = Path(table) if table is not None else None
    done = _read_table(path) if (path is not None and resume) else pd.DataFrame()
    finished = set(done["run_id"]) if "run_id" in done else set()
    todo = [p for p in points if run_id(p) not in finished]
    rows = done.to_dict("records") if len(done) else []

    own_cluster = None
    if client is None:
        if address is not None:
            client = Client(address)
        else:
            # One core per worker: the CPU engine's own threads (rayon) follow the
            # worker's thread count instead of each taking every core.
            own_cluster = LocalCluster(n_workers=workers, threads_per_worker=threads_per_worker,
                                       processes=True, dashboard_address=None,
                                       env={"RAYON_NUM_THREADS": str(threads_per_worker)})
            client = Client(own_cluster)
    bar = None
    if progress is None:
        progress = sys.stderr.isatty()
    try:
        futures = [client.submit(run_one, job_dict, base_dir, p, engine, pure=False) for p in todo]
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(points), initial=len(points) - len(todo), unit="run", desc="sweep")
        last_write = time.monotonic()
        for future in as_completed(futures):
            rows.append(future.result())
            if bar is not None:
                bar.update(1)
            if path is not None and time.monotonic() - last_write > 5.0:
                _write_table(pd.DataFrame(rows), path)
                last_write = time.monotonic()
    finally:
        if bar is not None:
            bar.close()
        frame = pd.DataFrame(rows)
        if path is not None and len(frame):
            _write_table(frame, path)
        if own_cluster is not None:
            client.close()
            own_cluster.close()
    return frame


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="toolmark sweep", description="Run a job over a parameter grid on Dask.")
    parser.add_argument("job", help="job file (TOML)")
    parser.add_argument("--grid", required=True, help="grid file (TOML, see the module docs)")
    parser.add_argument("--table", help="output table (.csv or .parquet; default from the grid file or sweep.csv)")
    parser.add_argument("--address", help="a Dask scheduler's address (default: a LocalCluster)")
    parser.add_argument("--workers", type=int, help="LocalCluster workers (default 2)")
    parser.add_argument("--engine", default="cpu", choices=["cpu", "gpu", "auto"])
    parser.add_argument("--no-resume", action="store_true", help="run every point again")
    args = parser.parse_args(argv)
    with open(args.grid, "rb") as handle:
        spec = tomllib.load(handle)
    parameters = spec.get("parameters")
    if not parameters:
        print(f"error: {args.grid}: a [parameters] table of lists is required", file=sys.stderr)
        return 2
    cluster = spec.get("cluster", {})
    table = args.table or spec.get("output", {}).get("table", "sweep.csv")
    started = time.perf_counter()
    frame = sweep(args.job, parameters, table=table, address=args.address or cluster.get("address"),
                  workers=args.workers or cluster.get("workers", 2), engine=args.engine,
                  resume=not args.no_resume)
    failed = int((frame["status"] == "failed").sum()) if len(frame) else 0
    print(f"{len(frame)} runs ({failed} failed) in {time.perf_counter() - started:.1f} s; table: {table}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

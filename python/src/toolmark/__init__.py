"""toolmark from Python: simulate a machined surface, diagnose a measurement, sweep
parameter grids on Dask.

>>> import toolmark
>>> r = toolmark.run("examples/flat_facing.toml")
>>> r.summary["scallop"]["max_nm"]          # the closed form R − √(R² − f²/4) = 25.0 nm
>>> r.maps["deviation_nm"].shape            # (512, 512) NumPy array, row 0 = +Y

A job is a path to a TOML file, TOML text, or a dict with the job file's tables (as
``tomllib`` reads one). Bad input raises :class:`JobError` whose ``field`` names the
job field (``"process.feed_per_rev_mm"``) and whose message says what is allowed.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Optional, Union

import numpy as np

from . import _toolmark

__all__ = ["run", "check", "diagnose", "sweep", "Result", "Diagnosis", "JobError"]
__version__ = _toolmark.__version__

Job = Union[str, os.PathLike, Mapping[str, Any]]


class JobError(ValueError):
    """A job, effects file, measured file or option that is refused; ``field`` names it."""

    def __init__(self, message: str, field: str):
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def _job_source(job: Job, base_dir=None) -> tuple[str, bool, str, str]:
    """(text, is_json, default name, base folder for the files it names)."""
    if isinstance(job, Mapping):
        base = os.fspath(base_dir) if base_dir is not None else os.getcwd()
        return json.dumps(job), True, str(job.get("name", "job")), base
    if isinstance(job, os.PathLike) or (isinstance(job, str) and "\n" not in job and job.endswith(".toml")):
        path = Path(job)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as err:
            raise JobError(f"cannot read {path}: {err}", "job") from None
        return text, False, path.stem, str(path.resolve().parent)
    return str(job), False, "job", os.getcwd()


def _call(function, *args, **kwargs):
    try:
        return function(*args, **kwargs)
    except _toolmark.JobError as err:
        message, field_name = err.args
        raise JobError(message, field_name) from None


@dataclass
class Result:
    """A simulated part: ``summary`` is ``summary.json`` as a dict; ``maps`` are top
    views from +Z (float32, NaN outside the part, row 0 = +Y, ``pixel_mm`` apart);
    ``polar`` is the deviation per sample in nm (azimuth rows × rings); ``profile`` the
    radial profile's columns."""

    summary: dict
    maps: dict = field(repr=False)
    pixel_mm: float = 0.0
    polar: np.ndarray = field(default=None, repr=False)
    profile: dict = field(default_factory=dict, repr=False)
    written: list = field(default_factory=list)


def run(job: Job, *, effects: Optional[Union[str, os.PathLike]] = None, engine: str = "cpu",
        out: Optional[Union[str, os.PathLike]] = None, base_dir=None) -> Result:
    """Simulate ``job`` (path, TOML text or dict). ``effects``: an effects file (TOML
    with ``[[effects]]`` tables, path or text) added to the job's own. ``engine``:
    ``"cpu"`` (default, f64), ``"gpu"`` or ``"auto"``. ``out``: also write the usual
    output folder (maps, summary.json, report.html). ``base_dir``: where the files a
    dict job names are (default: the current folder)."""
    text, is_json, name, base = _job_source(job, base_dir)
    effects_text = None
    if effects is not None:
        effects_path = Path(effects)
        effects_text = effects_path.read_text(encoding="utf-8") if effects_path.exists() else str(effects)
    raw = _call(_toolmark.run_job, text, is_json, name, base, effects_text, engine,
                None if out is None else os.fspath(out))
    n = raw["pixels"]
    valid = np.frombuffer(raw["valid"], dtype=np.uint8).reshape(n, n).astype(bool)
    maps = {}
    for key, data in raw["maps"].items():
        values = np.frombuffer(data, dtype="<f4").reshape(n, n).copy()
        values[~valid] = np.nan
        maps[key] = values
    polar = np.frombuffer(raw["polar"], dtype="<f8").reshape(raw["azimuths"], raw["rings"])
    profile = {k: np.frombuffer(v, dtype="<f8") for k, v in raw["profile"].items()}
    return Result(summary=json.loads(raw["summary"]), maps=maps, pixel_mm=raw["pixel_mm"],
                  polar=polar, profile=profile, written=raw.get("written", []))


def check(job: Job) -> dict:
    """Validate ``job``: ``{"resolved": dict, "warnings": [...], "hash": str}``."""
    text, is_json, name, base = _job_source(job)
    resolved, warnings, digest = _call(_toolmark.check_job, text, is_json, name, base)
    return {"resolved": json.loads(resolved), "warnings": list(warnings), "hash": digest}


class Diagnosis(dict):
    """``diagnosis.json`` (schema ``toolmark.diagnosis/1``) as a dict, with shortcuts."""

    @property
    def verdict(self) -> str:
        return self.get("verdict", {}).get("sentence", "")

    @property
    def status(self) -> str:
        return self.get("verdict", {}).get("status", "")

    @property
    def accepted(self) -> list:
        return self.get("accepted", [])


def diagnose(job: Job, measured: Union[str, os.PathLike], **options) -> Diagnosis:
    """Diagnose the gap between ``job`` and the measured file with the library's
    diagnosis. Options as the CLI's flags: ``lateral_unit``, ``height_unit`` ("nm",
    "um", "mm"), ``pixel_um``, ``azimuth_deg``, ``axis_at_mm``, ``stylus_tip_um``,
    ``pixel_averaging``, ``remove_power``, ``fixed_axis``, ``fixed_scale``,
    ``compare_only``, ``calibrate_on=(from_mm,
    to_mm)``, ``only=[kinds]``, ``max_effects``, ``min_evidence``, ``engine``, ``out``
    (write diagnosis.json, the images and report.html there)."""
    text, is_json, name, base = _job_source(job)
    if "out" in options and options["out"] is not None:
        options["out"] = os.fspath(options["out"])
    doc = _call(_toolmark.diagnose_job, text, is_json, name, base, Path(measured),
                json.dumps(options))
    return Diagnosis(json.loads(doc))


def sweep(job: Job, grid: Mapping[str, Any], **kwargs):
    """Run ``job`` over a parameter grid on Dask; see :func:`toolmark.dask_sweep.sweep`."""
    from .dask_sweep import sweep as _sweep

    return _sweep(job, grid, **kwargs)

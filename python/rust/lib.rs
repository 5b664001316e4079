//! `toolmark._toolmark`: the native half of the Python package. It takes jobs as TOML
//! text or JSON (a dict from Python), runs them on the library's engines and hands back
//! the summary as JSON text and the maps as little-endian f32/f64 bytes, which the
//! Python half (`toolmark/__init__.py`) turns into NumPy arrays. Bad input raises
//! `JobError(message, field)`; the Python half exposes `.field`.

use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use std::path::{Path, PathBuf};
use toolmark::diagnose::files::{Placement, load_measurement, merge_source};
use toolmark::diagnose::measurement::Instrument;
use toolmark::diagnose::register::Terms;
use toolmark::diagnose::{DiagnoseError, Options};
use toolmark::engine::RemovalEngine;
use toolmark::engine::cpu::CpuEngine;
use toolmark::engine::gpu::GpuEngine;
use toolmark::formats::measured::{LengthUnit, ReadOptions};
use toolmark::model::{EffectsFragment, Job, JobError as LibJobError, JobFile};
use toolmark::output::run_files::{summary, write_outputs};
use toolmark::pipeline::products;

create_exception!(_toolmark, JobError, PyValueError);

fn job_error(field: &str, message: impl std::fmt::Display) -> PyErr {
    JobError::new_err((message.to_string(), field.to_string()))
}

fn from_lib(err: LibJobError) -> PyErr {
    job_error(&err.field, err.message)
}

/// A job from TOML text or JSON (a dict), its file names resolved against `base_dir`,
/// with an optional effects fragment (TOML text) appended.
fn build_job(
    text: &str,
    is_json: bool,
    name: &str,
    base_dir: &str,
    effects: Option<&str>,
) -> PyResult<Job> {
    let mut file: JobFile = if is_json {
        serde_json::from_str(text).map_err(|e| job_error("job", e))?
    } else {
        toml_job(text)?
    };
    if let Some(fragment) = effects {
        let fragment = EffectsFragment::from_toml_str(fragment).map_err(from_lib)?;
        file.effects.extend(fragment.effects);
    }
    Job::from_file(file, name, Path::new(base_dir)).map_err(from_lib)
}

fn toml_job(text: &str) -> PyResult<JobFile> {
    JobFile::from_toml_str(text).map_err(from_lib)
}

fn open_engine(name: &str, _job: &Job) -> PyResult<Box<dyn RemovalEngine>> {
    match name {
        "cpu" => Ok(Box::new(CpuEngine)),
        "gpu" => GpuEngine::new()
            .map(|e| Box::new(e) as Box<dyn RemovalEngine>)
            .map_err(|e| PyRuntimeError::new_err(format!("engine=\"gpu\": {e}"))),
        // As the CLI's `--engine auto`: a hardware adapter, else the CPU engine (a
        // software rasteriser runs the kernels on the same cores, slower).
        "auto" => Ok(match GpuEngine::new() {
            Ok(e) if !e.is_software() => Box::new(e) as Box<dyn RemovalEngine>,
            _ => Box::new(CpuEngine),
        }),
        other => Err(job_error(
            "engine",
            format!("\"{other}\"; allowed: \"cpu\", \"gpu\" or \"auto\""),
        )),
    }
}

fn f32_bytes<'py>(py: Python<'py>, values: &[f32]) -> Bound<'py, PyBytes> {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    PyBytes::new(py, &bytes)
}

fn f64_bytes<'py>(py: Python<'py>, values: impl Iterator<Item = f64>) -> Bound<'py, PyBytes> {
    let bytes: Vec<u8> = values.flat_map(|v| v.to_le_bytes()).collect();
    PyBytes::new(py, &bytes)
}

/// Runs a job; returns a dict: `summary` (JSON text), `pixels`, `pixel_mm`, `maps`
/// (name → f32 bytes, row 0 = +Y), `valid` (u8 bytes), `polar` (f64 bytes, azimuth rows ×
/// rings), `rings`, `azimuths`, `profile` (column → f64 bytes), `written` (paths).
#[pyfunction]
#[pyo3(signature = (text, is_json, name, base_dir, effects=None, engine="cpu", out=None))]
#[allow(clippy::too_many_arguments)]
fn run_job<'py>(
    py: Python<'py>,
    text: &str,
    is_json: bool,
    name: &str,
    base_dir: &str,
    effects: Option<&str>,
    engine: &str,
    out: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let job = build_job(text, is_json, name, base_dir, effects)?;
    let result = py.detach(|| {
        let mut engine = open_engine(engine, &job)?;
        toolmark::pipeline::simulate(job, engine.as_mut(), &|_, _| {})
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))
    })?;
    let made = py.detach(|| products(&result));
    let views = &made.maps;
    let dict = PyDict::new(py);
    let summary_json = summary(&result, &made);
    dict.set_item("summary", summary_json.to_string())?;
    dict.set_item("pixels", views.deviation_nm.pixels)?;
    dict.set_item("pixel_mm", views.deviation_nm.pitch_mm)?;
    let maps = PyDict::new(py);
    maps.set_item("deviation_nm", f32_bytes(py, &views.deviation_nm.values))?;
    maps.set_item("scallop_nm", f32_bytes(py, &views.scallop_nm.values))?;
    maps.set_item("height_mm", f32_bytes(py, &views.height_mm.values))?;
    maps.set_item("protrusion_nm", f32_bytes(py, &views.protrusion_nm.values))?;
    if let Some(d) = &views.cutting_diameter_mm {
        maps.set_item("cutting_diameter_mm", f32_bytes(py, &d.values))?;
    }
    dict.set_item("maps", maps)?;
    let valid: Vec<u8> = views
        .deviation_nm
        .valid
        .iter()
        .map(|v| u8::from(*v))
        .collect();
    dict.set_item("valid", PyBytes::new(py, &valid))?;
    let grid = result.grid();
    dict.set_item("rings", grid.ring_count())?;
    dict.set_item("azimuths", grid.azimuths)?;
    dict.set_item(
        "polar",
        f64_bytes(py, result.field.depth_mm.iter().map(|d| d * 1e6)),
    )?;
    let profile = PyDict::new(py);
    let p = &result.profile;
    for (column, pick) in [
        (
            "radius_mm",
            (|q| q.radius_mm) as fn(&toolmark::analysis::ProfilePoint) -> f64,
        ),
        ("arc_length_mm", |q| q.arc_length_mm),
        ("height_mm", |q| q.height_mm),
        ("deviation_nm", |q| q.deviation_nm),
        ("mean_deviation_nm", |q| q.mean_nm),
        ("min_deviation_nm", |q| q.min_nm),
        ("max_deviation_nm", |q| q.max_nm),
        ("scallop_nm", |q| q.scallop_nm),
    ] {
        profile.set_item(column, f64_bytes(py, p.iter().map(pick)))?;
    }
    dict.set_item("profile", profile)?;
    if let Some(out) = out {
        let written = py
            .detach(|| {
                toolmark::output::run_files::prepare_output_dir(&out)?;
                write_outputs(&out, &result, &made)
            })
            .map_err(|e| PyRuntimeError::new_err(format!("writing {}: {e}", out.display())))?;
        let paths: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
        dict.set_item("written", paths)?;
    }
    Ok(dict)
}

/// Checks a job; returns the resolved job as JSON text, its warnings and hash.
#[pyfunction]
fn check_job(
    text: &str,
    is_json: bool,
    name: &str,
    base_dir: &str,
) -> PyResult<(String, Vec<String>, String)> {
    let job = build_job(text, is_json, name, base_dir, None)?;
    let resolved = serde_json::to_string(&job.resolved).map_err(|e| job_error("job", e))?;
    Ok((resolved, job.warnings.clone(), job.hash()))
}

fn unit(field: &str, value: Option<&str>) -> PyResult<Option<LengthUnit>> {
    match value {
        None => Ok(None),
        Some(text) => LengthUnit::parse(text).map(Some).ok_or_else(|| {
            job_error(
                field,
                format!("\"{text}\"; allowed: \"nm\", \"um\", \"mm\" or \"m\""),
            )
        }),
    }
}

/// Diagnoses a measured file against a job with the library's diagnosis; `options` is
/// JSON (see `toolmark.diagnose`). Returns `diagnosis.json` as text.
#[pyfunction]
#[pyo3(signature = (text, is_json, name, base_dir, measured, options))]
fn diagnose_job(
    py: Python<'_>,
    text: &str,
    is_json: bool,
    name: &str,
    base_dir: &str,
    measured: PathBuf,
    options: &str,
) -> PyResult<String> {
    let job = build_job(text, is_json, name, base_dir, None)?;
    let o: serde_json::Value =
        serde_json::from_str(options).map_err(|e| job_error("options", e))?;
    const KNOWN: [&str; 17] = [
        "lateral_unit",
        "height_unit",
        "pixel_um",
        "azimuth_deg",
        "axis_at_mm",
        "stylus_tip_um",
        "pixel_averaging",
        "remove_power",
        "fixed_axis",
        "fixed_scale",
        "compare_only",
        "calibrate_on",
        "only",
        "max_effects",
        "min_evidence",
        "engine",
        "out",
    ];
    if let Some(bad) = o
        .as_object()
        .and_then(|m| m.keys().find(|k| !KNOWN.contains(&k.as_str())))
    {
        return Err(job_error(
            bad,
            format!("unknown option; allowed: {}", KNOWN.join(", ")),
        ));
    }
    let f = |k: &str| o.get(k).and_then(serde_json::Value::as_f64);
    let b = |k: &str| {
        o.get(k)
            .and_then(serde_json::Value::as_bool)
            .unwrap_or(false)
    };
    let s = |k: &str| o.get(k).and_then(serde_json::Value::as_str);
    let pair = |k: &str| -> Option<Vec<f64>> {
        match o.get(k)? {
            serde_json::Value::Array(a) => {
                Some(a.iter().filter_map(serde_json::Value::as_f64).collect())
            }
            v => v.as_f64().map(|x| vec![x]),
        }
    };
    let read = ReadOptions {
        lateral_unit: unit("lateral_unit", s("lateral_unit"))?,
        height_unit: unit("height_unit", s("height_unit"))?,
        pixel_mm: pair("pixel_um").map(|v| (v[0] * 1e-3, v.get(1).unwrap_or(&v[0]) * 1e-3)),
    };
    let placement = Placement {
        azimuth_deg: f("azimuth_deg"),
        axis_at_mm: pair("axis_at_mm").map(|v| [v[0], v.get(1).copied().unwrap_or(0.0)]),
    };
    let instrument = Instrument {
        stylus_tip_mm: f("stylus_tip_um").map(|t| t * 1e-3),
        pixel_averaging: b("pixel_averaging"),
        line_bin_mm: None,
    };
    let calibrate_on_mm = match pair("calibrate_on") {
        Some(v) if v.len() == 2 && v[0] < v[1] => Some((v[0], v[1])),
        Some(_) => {
            return Err(job_error(
                "calibrate_on",
                "allowed: (from_mm, to_mm) with from < to",
            ));
        }
        None => None,
    };
    let options = Options {
        terms: Terms {
            power: b("remove_power"),
            shift: !b("fixed_axis"),
        },
        max_effects: o
            .get("max_effects")
            .and_then(serde_json::Value::as_u64)
            .unwrap_or(3) as usize,
        min_evidence: f("min_evidence").unwrap_or(10.0),
        only: o
            .get("only")
            .and_then(serde_json::Value::as_array)
            .map(|a| {
                a.iter()
                    .filter_map(|v| v.as_str().map(String::from))
                    .collect()
            })
            .unwrap_or_default(),
        calibrate_on_mm,
        lateral_scale: !b("fixed_scale"),
        compare_only: b("compare_only"),
    };
    let (measurement, source) = load_measurement(&measured, &read, &placement, instrument)
        .map_err(|e| job_error("measured", e))?;
    let engine_name = s("engine").unwrap_or("cpu");
    let outcome = py.detach(|| {
        let mut engine = open_engine(engine_name, &job)?;
        Ok::<_, PyErr>(toolmark::diagnose::diagnose(
            &job,
            &measurement,
            engine.as_mut(),
            &options,
            &|_| {},
        ))
    })?;
    let mut outcome = match outcome {
        Ok(outcome) => outcome,
        Err(DiagnoseError::DoesNotFit(why)) => {
            return Err(job_error(
                "measured",
                format!("the measurement does not fit the job: {why}"),
            ));
        }
        Err(err) => return Err(PyRuntimeError::new_err(err.to_string())),
    };
    merge_source(&mut outcome.diagnosis.measurement, &source);
    if let Some(out) = s("out") {
        let out = PathBuf::from(out);
        toolmark::diagnose::report::write_outputs(&out, &outcome)
            .map_err(|e| PyRuntimeError::new_err(format!("writing {}: {e}", out.display())))?;
        let doc = serde_json::to_value(&outcome.diagnosis)
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
        toolmark::output::html::write_diagnosis_html(&out, &doc)
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    }
    serde_json::to_string(&outcome.diagnosis).map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

#[pymodule]
fn _toolmark(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_job, m)?)?;
    m.add_function(wrap_pyfunction!(check_job, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose_job, m)?)?;
    m.add("JobError", m.py().get_type::<JobError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

//! `toolmark run` and `toolmark check`.

use super::{EngineChoice, Failure, load_job, load_job_with_effects, open_engine, slug};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;
use toolmark::engine::RemovalEngine;
use toolmark::model::resources;
use toolmark::output::run_files::{prepare_output_dir, write_outputs};
use toolmark::pipeline::{Products, RunResult, products, simulate};
use toolmark::process::Process;

#[derive(clap::Args, Default)]
pub struct RunArgs {
    /// Job file (TOML); omit to run the built-in default job.
    pub job: Option<PathBuf>,
    /// Which removal engine to use.
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    pub engine: EngineChoice,
    /// Output folder (default: toolmark-out/<job name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// An effects file (TOML with only [[effects]] tables) whose effects are added to
    /// the job's own, e.g. a machine's calibration carried from part to part.
    #[arg(long, value_name = "FILE")]
    pub effects: Option<PathBuf>,
}

/// Prints the resolved job on stdout (so `check JOB > resolved.toml` is a job file) and
/// the verdict, warnings and resource estimate on stderr.
pub fn check(path: PathBuf) -> Result<(), Failure> {
    let job = load_job(Some(&path))?;
    let resolved =
        toml::to_string_pretty(&job.resolved).map_err(|e| Failure::Runtime(e.to_string()))?;
    print!("{resolved}");
    eprintln!("{}: valid (hash {})", path.display(), job.hash());
    for warning in &job.warnings {
        eprintln!("warning: {warning}");
    }
    let estimate = resources::estimate(&job);
    eprintln!("estimate: {estimate}");
    check_memory(&job, estimate.cpu_bytes.min(estimate.gpu_bytes))
}

/// Refuses (exit 2, naming the grid fields) a job this machine cannot hold, before any
/// work: `bytes` is the estimated peak for the engine that will run it.
pub fn check_memory(job: &toolmark::model::Job, bytes: f64) -> Result<(), Failure> {
    match resources::available_bytes() {
        Some(available) => resources::check_fits(job, bytes, available)
            .map_err(|err| Failure::Input(err.to_string())),
        None => Ok(()),
    }
}

/// Creates the output folder, proves it writable and clears an earlier job's files, all
/// before the work starts; says on stderr what was removed.
pub fn prepare_out(out: &Path) -> Result<(), Failure> {
    let removed = prepare_output_dir(out)
        .map_err(|err| Failure::Runtime(format!("--out {}: {err}", out.display())))?;
    if !removed.is_empty() {
        eprintln!(
            "{}: removed {} files an earlier run left there",
            out.display(),
            removed.len()
        );
    }
    Ok(())
}

/// Simulates the job (or the built-in default) on the chosen engine with a progress bar,
/// writes every output into the output folder and prints the figures of the result.
pub fn run(args: RunArgs) -> Result<(), Failure> {
    let job = load_job_with_effects(args.job.as_ref(), args.effects.as_ref())?;
    if args.job.is_none() {
        println!(
            "no job file given: running the built-in default job ({})",
            job.name
        );
    }
    for warning in &job.warnings {
        eprintln!("warning: {warning}");
    }
    let mut engine = open_engine(args.engine, &job)?;
    let info = engine.info();
    println!(
        "engine: {} — {} ({}{}{})",
        info.kind,
        info.adapter,
        info.backend,
        if info.driver.is_empty() { "" } else { ", " },
        info.driver
    );
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("toolmark-out").join(slug(&job.name)));
    let estimate = resources::estimate(&job);
    let bytes = if info.kind == "gpu" {
        estimate.gpu_bytes
    } else {
        estimate.cpu_bytes
    };
    check_memory(&job, bytes)?;
    prepare_out(&out)?;

    let result = simulate_with_progress(job, engine.as_mut())?;
    let made = products(&result);
    let started = Instant::now();
    let written = write_outputs(&out, &result, &made)
        .map_err(|err| Failure::Runtime(format!("writing outputs to {}: {err}", out.display())))?;
    print_result(&result, &made, started.elapsed().as_secs_f64());
    println!("wrote {} files to {}", written.len(), out.display());
    Ok(())
}

/// Simulates `job` with a progress bar of the material removal, cleared when it is done.
fn simulate_with_progress(
    job: toolmark::model::Job,
    engine: &mut dyn RemovalEngine,
) -> Result<RunResult, Failure> {
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent:>3}% {elapsed} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message("removing material");
    let progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done.max(bar.position()));
    };
    let result =
        simulate(job, engine, &progress).map_err(|err| Failure::Runtime(err.to_string()))?;
    bar.finish_and_clear();
    Ok(result)
}

/// The grid and motion, the stage times, the deviation, the scallop, the central feature
/// and, for a generated part, its fitted sphere.
fn print_result(result: &RunResult, made: &Products, output_s: f64) {
    let grid = result.grid();
    let t = &result.timings;
    println!(
        "{}: {} rings × {} azimuths = {} samples, {}, {:.3e} dexel–pass pairs",
        result.job.name,
        grid.ring_count(),
        grid.azimuths,
        grid.sample_count(),
        motion(result),
        result.pair_count() as f64
    );
    println!(
        "time: prepare {:.2} s, removal {:.2} s ({:.3e} pairs/s), analysis {:.2} s (maps and texture {:.2} s), output {:.2} s",
        t.prepare_s,
        t.removal_s,
        result.pair_count() as f64 / t.removal_s.max(1e-12),
        t.analysis_s + made.elapsed_s,
        made.elapsed_s,
        output_s
    );
    println!(
        "deviation: PV {:.2} nm, RMS {:.2} nm (mean {:.2} nm)",
        result.deviation.pv_nm, result.deviation.rms_nm, result.deviation.mean_nm
    );
    match &result.scallops.stats {
        Some(s) => println!(
            "scallop: max {:.2} nm, mean {:.2} nm over {} cusps",
            s.max_nm, s.mean_nm, s.count
        ),
        None => println!(
            "scallop: not measured ({})",
            result.scallops.resolution_note.as_deref().unwrap_or("")
        ),
    }
    let p = &result.protrusion;
    match p.shape {
        toolmark::analysis::ProtrusionShape::None => {
            println!("central feature: none above the surround's texture")
        }
        shape => println!(
            "central feature: {shape:?}, {:.1} nm high, radius {:.2} µm, volume {:.3} µm³",
            p.height_nm, p.radius_um, p.volume_um3
        ),
    }
    if let Some(fit) = &result.part_sphere {
        println!(
            "part sphere: R = {:.6} mm ({:+.3} µm from nominal, fit RMS {:.2} nm)",
            fit.radius_mm,
            (fit.radius_mm - 1.0 / result.job.surface.curvature_per_mm) * 1e3,
            fit.rms_residual_nm
        );
    }
}

/// How the tool moved: spindle revolutions (turning), the path and its passes (milling),
/// the spark-out and speeds (generating).
fn motion(result: &RunResult) -> String {
    match &result.job.process {
        Process::Turning(_) => format!("{:.0} spindle revolutions", result.revolutions()),
        Process::Milling(m) => format!(
            "{:?} path with {} passes",
            m.setup.path,
            result
                .scenes
                .iter()
                .map(|s| match s {
                    toolmark::engine::Scene::Milling(scene) => scene.path.passes.len(),
                    _ => 0,
                })
                .sum::<usize>()
        ),
        Process::Generating(g) => format!(
            "{} workpiece revolutions of spark-out, wheel {} rpm / part {} rpm",
            g.setup.spark_out_revolutions, g.setup.tool_rpm, g.setup.workpiece_rpm
        ),
    }
}

#[derive(clap::Args)]
pub struct ReportArgs {
    /// An output folder of run, diagnose, compensate or correct (holding summary.json,
    /// diagnosis.json, compensation.json or correction.json and the images).
    pub dir: PathBuf,
}

/// Writes (or rewrites) `report.html` for an existing output folder.
pub fn report(args: ReportArgs) -> Result<(), Failure> {
    use toolmark::output::html;
    let read = |name: &str| -> Option<serde_json::Value> {
        let text = std::fs::read_to_string(args.dir.join(name)).ok()?;
        serde_json::from_str(&text).ok()
    };
    let written = if let Some(doc) = read("diagnosis.json") {
        html::write_diagnosis_html(&args.dir, &doc)
    } else if let Some(doc) = read("summary.json") {
        html::write_run_html(&args.dir, &doc)
    } else if let Some(doc) = read("compensation.json") {
        html::write_compensation_html(&args.dir, &doc)
    } else if let Some(doc) = read("correction.json") {
        html::write_correction_html(&args.dir, &doc)
    } else {
        return Err(Failure::Input(format!(
            "{}: no summary.json, diagnosis.json, compensation.json or correction.json",
            args.dir.display()
        )));
    };
    let path = written.map_err(|err| Failure::Runtime(err.to_string()))?;
    println!("wrote {}", path.display());
    Ok(())
}

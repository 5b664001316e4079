//! The `toolmark` command line.

use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use toolmark::bench;
use toolmark::engine::RemovalEngine;
use toolmark::engine::cpu::CpuEngine;
use toolmark::engine::gpu::GpuEngine;
use toolmark::io::job::Job;
use toolmark::io::outputs::write_outputs;
use toolmark::run::simulate;

#[derive(Parser)]
#[command(
    name = "toolmark",
    version,
    about = "Predict the surface a machining process leaves"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a job and write maps, profiles and a summary (default: the built-in
    /// seed-002 asphere turned XZ).
    Run(RunArgs),
    /// Check a job file and print it with every default filled in.
    Check {
        /// Job file (TOML).
        job: PathBuf,
    },
    /// Measure engine throughput (dexel–pass evaluations per second) and scaling.
    Bench(BenchArgs),
}

#[derive(clap::Args, Default)]
struct RunArgs {
    /// Job file (TOML); omit to run the built-in default job.
    job: Option<PathBuf>,
    /// Which removal engine to use.
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    engine: EngineChoice,
    /// Output folder (default: toolmark-out/<job name>).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Engines to measure.
    #[arg(long, value_enum, default_value_t = BenchEngines::Both)]
    engine: BenchEngines,
    /// Skip the grid larger than one 128 MiB storage binding (tiling check).
    #[arg(long)]
    skip_large: bool,
}

#[derive(Clone, Copy, Default, PartialEq, Eq, ValueEnum)]
enum EngineChoice {
    /// The GPU when an adapter is found, else the CPU (and say so).
    #[default]
    Auto,
    Cpu,
    Gpu,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum BenchEngines {
    Cpu,
    Gpu,
    Both,
}

fn main() -> ExitCode {
    // Mesa's Vulkan device-select layer probes for a Wayland display and prints an
    // error when there is none; a compute-only program has no use for it.
    if std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: first thing in main, before any thread exists.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
    let cli = Cli::parse();
    let result = match cli.command.unwrap_or(Command::Run(RunArgs::default())) {
        Command::Run(args) => run(args),
        Command::Check { job } => check(job),
        Command::Bench(args) => bench::run_benchmarks(
            args.engine != BenchEngines::Gpu,
            args.engine != BenchEngines::Cpu,
            !args.skip_large,
        )
        .map_err(Failure::Runtime),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Input(message)) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
        Err(Failure::Runtime(message)) => {
            eprintln!("error: {message}");
            ExitCode::from(1)
        }
    }
}

/// Bad input (exit 2) or a failure while running (exit 1).
enum Failure {
    Input(String),
    Runtime(String),
}

fn load_job(path: Option<&PathBuf>) -> Result<Job, Failure> {
    match path {
        Some(path) => {
            Job::load(path).map_err(|err| Failure::Input(format!("{}: {err}", path.display())))
        }
        None => Ok(Job::default_job()),
    }
}

fn check(path: PathBuf) -> Result<(), Failure> {
    let job = load_job(Some(&path))?;
    let resolved =
        toml::to_string_pretty(&job.resolved).map_err(|e| Failure::Runtime(e.to_string()))?;
    println!(
        "{}: valid (hash {})\n\n{resolved}",
        path.display(),
        job.hash()
    );
    for warning in &job.warnings {
        println!("warning: {warning}");
    }
    Ok(())
}

fn open_engine(choice: EngineChoice) -> Result<Box<dyn RemovalEngine>, Failure> {
    match choice {
        EngineChoice::Cpu => Ok(Box::new(CpuEngine)),
        EngineChoice::Gpu => GpuEngine::new()
            .map(|engine| Box::new(engine) as Box<dyn RemovalEngine>)
            .map_err(|err| Failure::Runtime(format!("--engine gpu: {err}"))),
        EngineChoice::Auto => match GpuEngine::new() {
            Ok(engine) => Ok(Box::new(engine)),
            Err(err) => {
                eprintln!("{err}\nusing the CPU engine instead");
                Ok(Box::new(CpuEngine))
            }
        },
    }
}

/// A file-name-safe form of the job name.
fn slug(name: &str) -> String {
    let slug: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    let slug = slug
        .split('-')
        .filter(|part| !part.is_empty())
        .collect::<Vec<_>>()
        .join("-");
    if slug.is_empty() { "job".into() } else { slug }
}

fn run(args: RunArgs) -> Result<(), Failure> {
    let job = load_job(args.job.as_ref())?;
    if args.job.is_none() {
        println!(
            "no job file given: running the built-in default job ({})",
            job.name
        );
    }
    for warning in &job.warnings {
        eprintln!("warning: {warning}");
    }
    let mut engine = open_engine(args.engine)?;
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
    let result = simulate(job, engine.as_mut(), &progress)
        .map_err(|err| Failure::Runtime(err.to_string()))?;
    bar.finish_and_clear();

    let written = write_outputs(&out, &result)
        .map_err(|err| Failure::Runtime(format!("writing outputs to {}: {err}", out.display())))?;
    let grid = result.grid();
    let t = &result.timings;
    println!(
        "{}: {} rings × {} azimuths = {} samples, {:.0} revolutions, {:.3e} dexel–pass pairs",
        result.job.name,
        grid.ring_count(),
        grid.azimuths,
        grid.sample_count(),
        result.scene.poses.end_angle_rad() / std::f64::consts::TAU,
        result.scene.pair_count() as f64
    );
    println!(
        "time: prepare {:.2} s, removal {:.2} s ({:.3e} pairs/s), analysis {:.2} s",
        t.prepare_s,
        t.removal_s,
        result.scene.pair_count() as f64 / t.removal_s.max(1e-12),
        t.analysis_s
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
    println!("wrote {} files to {}", written.len(), out.display());
    Ok(())
}

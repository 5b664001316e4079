//! The `toolmark` command line.

use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use toolmark::analysis::profile_compare::{compare_profiles, residual_nm, simulated_profile};
use toolmark::bench;
use toolmark::compensate::compensation_loop;
use toolmark::engine::RemovalEngine;
use toolmark::engine::cpu::CpuEngine;
use toolmark::engine::gpu::GpuEngine;
use toolmark::io::job::Job;
use toolmark::io::measured::{LengthUnit, read_wli_profile_csv};
use toolmark::io::outputs::write_outputs;
use toolmark::io::plot::{LinePlot, PALETTE, Series, write_line_plot};
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
    /// Simulate a job and compare it with a measured radial profile (period, PV, RMS).
    CompareProfile(CompareArgs),
    /// Run the machining–measurement–compensation loop in simulation and write the
    /// compensated path.
    Compensate(CompensateArgs),
}

#[derive(clap::Args)]
struct CompensateArgs {
    /// Job file (TOML); its effects play the machine's unknown errors.
    job: PathBuf,
    /// Compensations after the first part.
    #[arg(long, default_value_t = 3)]
    cycles: usize,
    /// Gaussian cutoff of the form measurement (µm; default 20 pass spacings).
    #[arg(long)]
    cutoff_um: Option<f64>,
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    engine: EngineChoice,
    /// Output folder (default: toolmark-out/<job name>-compensation).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(clap::Args)]
struct CompareArgs {
    /// Job file (TOML).
    job: PathBuf,
    /// Measured profile: `X,Y` CSV as white-light interferometers export it (empty Y = invalid).
    #[arg(long)]
    measured: PathBuf,
    /// Unit of the measured X column.
    #[arg(long, value_enum, default_value_t = Unit::Um)]
    x_unit: Unit,
    /// Unit of the measured height column.
    #[arg(long, value_enum, default_value_t = Unit::Um)]
    height_unit: Unit,
    /// Polynomial order removed from both profiles as form (2 = piston, tilt, curvature).
    #[arg(long, default_value_t = 2)]
    form_order: usize,
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    engine: EngineChoice,
    /// Output folder (default: toolmark-out/<job name>-vs-measured).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Unit {
    Mm,
    Um,
    Nm,
}

impl Unit {
    fn length_unit(self) -> LengthUnit {
        match self {
            Unit::Mm => LengthUnit::Millimetre,
            Unit::Um => LengthUnit::Micrometre,
            Unit::Nm => LengthUnit::Nanometre,
        }
    }
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
        Command::CompareProfile(args) => compare_profile(args),
        Command::Compensate(args) => compensate(args),
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
        result.revolutions(),
        result.pair_count() as f64
    );
    println!(
        "time: prepare {:.2} s, removal {:.2} s ({:.3e} pairs/s), analysis {:.2} s",
        t.prepare_s,
        t.removal_s,
        result.pair_count() as f64 / t.removal_s.max(1e-12),
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
    println!("wrote {} files to {}", written.len(), out.display());
    Ok(())
}

fn compare_profile(args: CompareArgs) -> Result<(), Failure> {
    let job = load_job(Some(&args.job))?;
    let measured = read_wli_profile_csv(
        &args.measured,
        args.x_unit.length_unit(),
        args.height_unit.length_unit(),
    )
    .map_err(|err| Failure::Input(err.to_string()))?;
    if measured.x_mm.len() < 16 {
        return Err(Failure::Input(format!(
            "{}: only {} valid points; a comparison needs at least 16",
            args.measured.display(),
            measured.x_mm.len()
        )));
    }
    let out = args.out.unwrap_or_else(|| {
        PathBuf::from("toolmark-out").join(format!("{}-vs-measured", slug(&job.name)))
    });
    let mut engine = open_engine(args.engine)?;
    let name = job.name.clone();
    let outer = job.aperture.outer_radius_mm;
    let result = simulate(job, engine.as_mut(), &|_, _| {})
        .map_err(|err| Failure::Runtime(err.to_string()))?;
    let (from, to) = (measured.x_mm[0], measured.x_mm[measured.x_mm.len() - 1]);
    if from < 0.0 || to > outer {
        return Err(Failure::Input(format!(
            "{}: the profile spans {from:.4}–{to:.4} mm but the simulated part ends at r = {outer:.4} mm (are the units right? use --x-unit)",
            args.measured.display()
        )));
    }
    let comparison = compare_profiles(
        result.grid(),
        &result.field,
        &measured.x_mm,
        &measured.height_mm,
        args.form_order,
    );
    let m = &comparison.measured;
    println!(
        "measured {}: {} points over {:.4}–{:.4} mm, {} invalid rows: period {:.2} µm, PV {:.1} nm, RMS {:.1} nm",
        args.measured.display(),
        m.points,
        m.from_mm,
        m.to_mm,
        measured.invalid_rows,
        m.dominant_period_um,
        m.pv_nm,
        m.rms_nm
    );
    let summary =
        |pick: fn(&toolmark::analysis::ProfileStats) -> f64| comparison.simulated_summary(pick);
    let (period, pv, rms) = (
        summary(|s| s.dominant_period_um),
        summary(|s| s.pv_nm),
        summary(|s| s.rms_nm),
    );
    println!(
        "simulated {name} ({} azimuths, {} engine): period {:.2} µm ({:.2}–{:.2}), PV {:.1} nm ({:.1}–{:.1}), RMS {:.1} nm ({:.1}–{:.1})",
        comparison.simulated.len(),
        result.engine.kind,
        period.0,
        period.1,
        period.2,
        pv.0,
        pv.1,
        pv.2,
        rms.0,
        rms.1,
        rms.2
    );
    std::fs::create_dir_all(&out)
        .map_err(|err| Failure::Runtime(format!("{}: {err}", out.display())))?;
    let json = serde_json::json!({
        "schema": "toolmark.profile_comparison/1",
        "job_name": name,
        "job_hash": result.job.hash(),
        "measured_file": args.measured,
        "engine": result.engine,
        "comparison": comparison,
    });
    let text = serde_json::to_string_pretty(&json).map_err(|e| Failure::Runtime(e.to_string()))?;
    toolmark::io::atomic::write_bytes_atomically(
        &out.join("profile_comparison.json"),
        text.as_bytes(),
    )
    .map_err(|err| Failure::Runtime(err.to_string()))?;
    let (sim_x, sim_h) = simulated_profile(result.grid(), &result.field, 0, from, to);
    let measured_nm = residual_nm(&measured.x_mm, &measured.height_mm, args.form_order);
    let simulated_nm = residual_nm(&sim_x, &sim_h, args.form_order);
    write_line_plot(
        &out.join("profile_comparison.png"),
        &LinePlot {
            title: &format!("{name} vs measured"),
            x_label: "radius (mm)",
            y_label: "height, form removed (nm)",
            series: &[
                Series {
                    label: "measured",
                    x: &measured.x_mm,
                    y: &measured_nm,
                    colour: PALETTE[0],
                },
                Series {
                    label: "simulated, azimuth 0",
                    x: &sim_x,
                    y: &simulated_nm,
                    colour: PALETTE[1],
                },
            ],
        },
    )
    .map_err(|err| Failure::Runtime(err.to_string()))?;
    println!(
        "wrote profile_comparison.json and profile_comparison.png to {}",
        out.display()
    );
    Ok(())
}

fn compensate(args: CompensateArgs) -> Result<(), Failure> {
    let job = load_job(Some(&args.job))?;
    let Some(turning) = job.process.turning().cloned() else {
        return Err(Failure::Input(format!(
            "{}: compensate corrects a turning path along the normal; for a generating job use `toolmark correct`",
            args.job.display()
        )));
    };
    if !(1..=20).contains(&args.cycles) {
        return Err(Failure::Input(format!(
            "--cycles {}: allowed 1 to 20",
            args.cycles
        )));
    }
    let cutoff_mm = match args.cutoff_um {
        Some(c) if c.is_finite() && c > 0.0 => c * 1e-3,
        Some(c) => {
            return Err(Failure::Input(format!(
                "--cutoff-um {c}: allowed a finite number > 0"
            )));
        }
        None => 20.0 * turning.path.pass_spacing_mm(),
    };
    let out = args.out.unwrap_or_else(|| {
        PathBuf::from("toolmark-out").join(format!("{}-compensation", slug(&job.name)))
    });
    let mut engine = open_engine(args.engine)?;
    println!(
        "{}: {} compensation cycles, form measured with a {:.1} µm Gaussian cutoff",
        job.name,
        args.cycles,
        cutoff_mm * 1e3
    );
    println!(
        "| cycle | form PV (nm) | form RMS (nm) | deviation PV (nm) | largest correction (nm) |"
    );
    println!("| --- | --- | --- | --- | --- |");
    let run = compensation_loop(&job, engine.as_mut(), args.cycles, cutoff_mm, &|r| {
        println!(
            "| {} | {:.1} | {:.2} | {:.1} | {:.1} |",
            r.cycle, r.form_pv_nm, r.form_rms_nm, r.deviation_pv_nm, r.correction_max_nm
        )
    })
    .map_err(|err| Failure::Runtime(err.to_string()))?;

    let write = |name: &str, bytes: &[u8]| {
        toolmark::io::atomic::write_bytes_atomically(&out.join(name), bytes)
            .map_err(|err| Failure::Runtime(format!("{}: {err}", out.join(name).display())))
    };
    std::fs::create_dir_all(&out)
        .map_err(|err| Failure::Runtime(format!("{}: {err}", out.display())))?;
    write("correction.csv", run.next_correction.to_csv().as_bytes())?;
    let mut compensated = job.resolved.clone();
    compensated.name = Some(format!("{} (compensated)", job.name));
    compensated.process.compensation = Some(PathBuf::from("correction.csv"));
    let toml = toml::to_string_pretty(&compensated).map_err(|e| Failure::Runtime(e.to_string()))?;
    write(
        "compensated.toml",
        format!(
            "# {} with the correction of {} simulated compensation cycles\n{toml}",
            job.name, args.cycles
        )
        .as_bytes(),
    )?;
    let mut files = vec![
        "correction.csv",
        "compensated.toml",
        "compensation.json",
        "form_error.png",
    ];
    if turning.path.mode() == toolmark::process::TurningMode::Xz {
        // The program the machine would run next: the nominal path plus the correction.
        // (The job's effects are the machine's errors, not part of the program.)
        let meridian = job.meridian();
        let tables: Vec<_> = turning
            .path
            .pose_tables(&job.surface, &meridian, &turning.tool)
            .into_iter()
            .map(|mut table| {
                run.next_correction
                    .apply(&mut table, &job.surface, &meridian);
                table
            })
            .collect();
        let program = toolmark::io::nc_write::c_x_z_program(
            &tables,
            0.001,
            &format!("{} compensated", job.name),
        );
        write("compensated.nc", program.as_bytes())?;
        files.push("compensated.nc");
    }
    let json = serde_json::json!({
        "schema": "toolmark.compensation/1",
        "job_name": job.name,
        "job_hash": job.hash(),
        "cutoff_um": cutoff_mm * 1e3,
        "engine": run.last.engine,
        "cycles": run.cycles,
    });
    write(
        "compensation.json",
        serde_json::to_string_pretty(&json)
            .map_err(|e| Failure::Runtime(e.to_string()))?
            .as_bytes(),
    )?;
    let labels: Vec<String> = run
        .cycles
        .iter()
        .map(|c| format!("cycle {}: {:.0} nm", c.cycle, c.form_pv_nm))
        .collect();
    let nm: Vec<Vec<f64>> = run
        .forms
        .iter()
        .map(|f| f.error_mm.iter().map(|v| v * 1e6).collect())
        .collect();
    let series: Vec<Series> = run
        .forms
        .iter()
        .enumerate()
        .map(|(i, f)| Series {
            label: &labels[i],
            x: &f.arc_length_mm,
            y: &nm[i],
            colour: PALETTE[i % PALETTE.len()],
        })
        .collect();
    write_line_plot(
        &out.join("form_error.png"),
        &LinePlot {
            title: "form error per compensation cycle",
            x_label: "arc length along the meridian from the axis (mm)",
            y_label: "form error along the normal (nm)",
            series: &series,
        },
    )
    .map_err(|err| Failure::Runtime(err.to_string()))?;
    let (first, last) = (
        run.cycles[0].form_pv_nm,
        run.cycles[run.cycles.len() - 1].form_pv_nm,
    );
    println!(
        "form PV {first:.1} → {last:.1} nm ({:.1}×); wrote {} to {}",
        first / last,
        files.join(", "),
        out.display()
    );
    Ok(())
}

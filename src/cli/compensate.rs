//! `toolmark compensate`: the turning compensation loop in simulation.

use super::{EngineChoice, Failure, load_job_with_effects, open_engine, slug};
use std::path::{Path, PathBuf};
use toolmark::engine::RemovalEngine;
use toolmark::loops::compensate::{CompensationRun, compensation_loop};
use toolmark::model::Job;
use toolmark::output::plot::{LinePlot, PALETTE, Series, write_line_plot};
use toolmark::process::TurningProcess;

#[derive(clap::Args)]
pub struct CompensateArgs {
    /// Job file (TOML); its effects play the machine's unknown errors.
    pub job: PathBuf,
    /// Compensations after the first part.
    #[arg(long, default_value_t = 3)]
    pub cycles: usize,
    /// Gaussian cutoff of the form measurement (µm; default 20 pass spacings).
    #[arg(long)]
    pub cutoff_um: Option<f64>,
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    pub engine: EngineChoice,
    /// Output folder (default: toolmark-out/<job name>-compensation).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// An effects file (TOML with only [[effects]] tables) whose effects are added to
    /// the job's own: more of the machine's errors the loop is not told.
    #[arg(long, value_name = "FILE")]
    pub effects: Option<PathBuf>,
}

/// Runs the loop on the job, printing a row per cycle, then writes the correction, the
/// compensated job (and, for XZ, its program), `compensation.json`, the plot and the report.
pub fn compensate(args: CompensateArgs) -> Result<(), Failure> {
    let job = load_job_with_effects(Some(&args.job), args.effects.as_ref())?;
    let (turning, cutoff_mm) = turning_and_cutoff(&args, &job)?;
    let out = args.out.unwrap_or_else(|| {
        PathBuf::from("toolmark-out").join(format!("{}-compensation", slug(&job.name)))
    });
    let mut engine = open_engine(args.engine, &job)?;
    super::run::prepare_out(&out)?;
    let run = run_cycles(&job, engine.as_mut(), args.cycles, cutoff_mm)?;

    std::fs::create_dir_all(&out)
        .map_err(|err| Failure::Runtime(format!("{}: {err}", out.display())))?;
    write_correction(&out, &job, &run, args.cycles)?;
    let mut files = vec![
        "correction.csv",
        "compensated.toml",
        "compensation.json",
        "form_error.png",
    ];
    if turning.path.mode() == toolmark::process::TurningMode::Xz {
        write_program(&out, &job, &turning, &run)?;
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
    write_file(
        &out,
        "compensation.json",
        serde_json::to_string_pretty(&json)
            .map_err(|e| Failure::Runtime(e.to_string()))?
            .as_bytes(),
    )?;
    write_form_plot(&out, &run)?;
    toolmark::output::html::write_compensation_html(&out, &json)
        .map_err(|err| Failure::Runtime(format!("report.html: {err}")))?;
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

/// The job's turning process and the form measurement's Gaussian cutoff (mm), once the job
/// is a turning job and `--cycles` and `--cutoff-um` lie in their allowed ranges.
fn turning_and_cutoff(args: &CompensateArgs, job: &Job) -> Result<(TurningProcess, f64), Failure> {
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
    Ok((turning, cutoff_mm))
}

/// Runs the loop of `cycles` compensations, printing its table a row per cycle.
fn run_cycles(
    job: &Job,
    engine: &mut dyn RemovalEngine,
    cycles: usize,
    cutoff_mm: f64,
) -> Result<CompensationRun, Failure> {
    println!(
        "{}: {} compensation cycles, form measured with a {:.1} µm Gaussian cutoff",
        job.name,
        cycles,
        cutoff_mm * 1e3
    );
    println!(
        "| cycle | form PV (nm) | form RMS (nm) | deviation PV (nm) | largest correction (nm) |"
    );
    println!("| --- | --- | --- | --- | --- |");
    compensation_loop(job, engine, cycles, cutoff_mm, &|r| {
        println!(
            "| {} | {:.1} | {:.2} | {:.1} | {:.1} |",
            r.cycle, r.form_pv_nm, r.form_rms_nm, r.deviation_pv_nm, r.correction_max_nm
        )
    })
    .map_err(|err| Failure::Runtime(err.to_string()))
}

/// Writes `name` into `out` atomically; an error names the file.
fn write_file(out: &Path, name: &str, bytes: &[u8]) -> Result<(), Failure> {
    toolmark::formats::atomic::write_bytes_atomically(&out.join(name), bytes)
        .map_err(|err| Failure::Runtime(format!("{}: {err}", out.join(name).display())))
}

/// `correction.csv`, the correction the next part is machined with, and
/// `compensated.toml`, the job that applies it.
fn write_correction(
    out: &Path,
    job: &Job,
    run: &CompensationRun,
    cycles: usize,
) -> Result<(), Failure> {
    write_file(
        out,
        "correction.csv",
        run.next_correction.to_csv().as_bytes(),
    )?;
    let mut compensated = job.resolved.clone();
    compensated.name = Some(format!("{} (compensated)", job.name));
    let compensated = compensated
        .with_compensation(PathBuf::from("correction.csv"))
        .map_err(|e| Failure::Runtime(e.to_string()))?;
    let toml = toml::to_string_pretty(&compensated).map_err(|e| Failure::Runtime(e.to_string()))?;
    write_file(
        out,
        "compensated.toml",
        format!(
            "# {} with the correction of {} simulated compensation cycles\n{toml}",
            job.name, cycles
        )
        .as_bytes(),
    )
}

/// `compensated.nc`: the program the machine would run next, the nominal path plus the
/// correction. (The job's effects are the machine's errors, not part of the program.)
fn write_program(
    out: &Path,
    job: &Job,
    turning: &TurningProcess,
    run: &CompensationRun,
) -> Result<(), Failure> {
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
    let program = toolmark::output::nc_write::c_x_z_program(
        &tables,
        0.001,
        &format!("{} compensated", job.name),
    );
    write_file(out, "compensated.nc", program.as_bytes())
}

/// `form_error.png`: each cycle's form error along the meridian (nm).
fn write_form_plot(out: &Path, run: &CompensationRun) -> Result<(), Failure> {
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
    .map_err(|err| Failure::Runtime(err.to_string()))
}

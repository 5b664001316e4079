//! `toolmark diagnose`, `toolmark synth` and `toolmark bench-diagnose`.

use super::{EngineChoice, Failure, Unit, load_job, load_job_with_effects, open_engine, slug};
use clap::ValueEnum;
use std::path::{Path, PathBuf};
use toolmark::diagnose::files::{Placement, load_measurement, merge_source};
use toolmark::diagnose::measurement::Instrument;
use toolmark::diagnose::register::Terms;
use toolmark::diagnose::report::write_outputs;
use toolmark::diagnose::synth::{MeasurementModel, synthesize};
use toolmark::diagnose::withheld;
use toolmark::diagnose::{DiagnoseError, Options, diagnose};
use toolmark::formats::atomic::write_bytes_atomically;
use toolmark::formats::measured::ReadOptions;

/// How a measured file is read and placed on the part: shared by `diagnose` and
/// `compare-profile` (one vocabulary: `--lateral-unit`, `--height-unit`, never a
/// silent default).
#[derive(clap::Args)]
pub struct MeasuredArgs {
    /// Measured surface: a profile (CSV/TXT/XYZ, X3P PRF) or a height map (X3P, GSF,
    /// f32 EXR, CSV grid).
    #[arg(long)]
    pub measured: PathBuf,
    /// Unit of the file's lateral coordinates, when the file does not state it.
    #[arg(long, value_enum)]
    pub lateral_unit: Option<Unit>,
    /// Unit of the file's heights, when the file does not state it.
    #[arg(long, value_enum)]
    pub height_unit: Option<Unit>,
    /// Pixel pitch of a map (µm; "X" or "X,Y"), when the file does not state it.
    #[arg(long, value_delimiter = ',', num_args = 1..=2)]
    pub pixel_um: Option<Vec<f64>>,
    /// Direction of a profile on the part (degrees from +X; a multiple of 0.5°). On a
    /// turned part, where it lies on the program's spiral (C = 0 along +X): stated, it
    /// is believed where the data cannot tell; unstated, it is found from the marks.
    #[arg(long, allow_negative_numbers = true)]
    pub azimuth_deg: Option<f64>,
    /// Where the search for the part's axis starts in the file's frame (mm; "X" for a
    /// profile, "X,Y" for a map; default: a profile's zero, a map's centre). The axis
    /// is searched anywhere the points stay on the part unless --fixed-axis.
    #[arg(long, value_delimiter = ',', num_args = 1..=2, allow_negative_numbers = true)]
    pub axis_at_mm: Option<Vec<f64>>,
    /// Keep the axis where --axis-at-mm puts it (no search).
    #[arg(long)]
    pub fixed_axis: bool,
    /// Keep the instrument's lateral scale at 1 (no fit).
    #[arg(long)]
    pub fixed_scale: bool,
    /// A stylus profiler's tip radius (µm): the simulation is traced the same way.
    #[arg(long)]
    pub stylus_tip_um: Option<f64>,
    /// A map's pixels average the surface over their footprint.
    #[arg(long)]
    pub pixel_averaging: bool,
    /// Also remove power (r²) in registration: for a file whose form was removed.
    #[arg(long)]
    pub remove_power: bool,
    /// Effects known from an earlier part (an `[[effects]]` file such as a diagnosis's
    /// effects.toml): added to the job before comparing, so that only what remains is
    /// fitted — calibrate on one part, predict the next.
    #[arg(long)]
    pub effects: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    pub engine: EngineChoice,
    /// Output folder (default: toolmark-out/<job name>-diagnosis).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct DiagnoseArgs {
    /// Job file (TOML): the model, with the effects you already know.
    #[arg(long)]
    pub job: PathBuf,
    #[command(flatten)]
    pub measured: MeasuredArgs,
    /// Fit only on points between FROM and TO (mm, along the profile or X of a map, in
    /// the file's frame): the rest is held out to judge the calibration.
    #[arg(long, value_name = "FROM:TO")]
    pub calibrate_on: Option<String>,
    /// Fit only these effects (job-file names, comma-separated).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Most effects combined.
    #[arg(long, default_value_t = 3)]
    pub max_effects: usize,
    /// Evidence (ΔBIC) an effect must add to be accepted.
    #[arg(long, default_value_t = 10.0)]
    pub min_evidence: f64,
}

/// `toolmark compare-profile`: the diagnosis's registration and comparison alone (the
/// job, with any carried effects, against the measurement; no effect is fitted).
#[derive(clap::Args)]
pub struct CompareArgs {
    /// Job file (TOML).
    pub job: PathBuf,
    #[command(flatten)]
    pub measured: MeasuredArgs,
}

fn read_options(
    lateral: Option<Unit>,
    height: Option<Unit>,
    pixel_um: &Option<Vec<f64>>,
) -> Result<ReadOptions, Failure> {
    let pixel_mm = match pixel_um.as_deref() {
        None => None,
        Some(values) => {
            if values
                .iter()
                .any(|v| !v.is_finite() || *v <= 0.0 || *v > 1e5)
            {
                return Err(Failure::Input(format!(
                    "--pixel-um: {values:?} is out of range; allowed: positive numbers up to 100000 µm"
                )));
            }
            let dx = values[0] * 1e-3;
            Some((dx, values.get(1).map_or(dx, |v| v * 1e-3)))
        }
    };
    Ok(ReadOptions {
        lateral_unit: lateral.map(Unit::length_unit),
        height_unit: height.map(Unit::length_unit),
        pixel_mm,
    })
}

pub fn diagnose_cmd(args: DiagnoseArgs) -> Result<(), Failure> {
    if !(1..=5).contains(&args.max_effects) {
        return Err(Failure::Input(format!(
            "--max-effects: {} is out of range; allowed: 1 to 5",
            args.max_effects
        )));
    }
    if !args.min_evidence.is_finite() || args.min_evidence < 0.0 {
        return Err(Failure::Input(format!(
            "--min-evidence: {} is out of range; allowed: a number ≥ 0",
            args.min_evidence
        )));
    }
    let calibrate_on_mm = match &args.calibrate_on {
        None => None,
        Some(text) => Some(parse_range(text)?),
    };
    let job = load_job_with_effects(Some(&args.job), args.measured.effects.as_ref())?;
    let known: Vec<&str> = toolmark::diagnose::candidates::candidates_for(&job)
        .0
        .iter()
        .map(|c| c.kind())
        .collect();
    if let Some(bad) = args.only.iter().find(|o| !known.contains(&o.as_str())) {
        return Err(Failure::Input(format!(
            "--only: \"{bad}\" is not a diagnosable effect of this job; allowed: {}",
            known.join(", ")
        )));
    }
    let mut options = base_options(&args.measured);
    options.max_effects = args.max_effects;
    options.min_evidence = args.min_evidence;
    options.only = args.only.clone();
    options.calibrate_on_mm = calibrate_on_mm;
    run_diagnosis(job, &args.measured, options)
}

pub fn compare_cmd(args: CompareArgs) -> Result<(), Failure> {
    let job = load_job_with_effects(Some(&args.job), args.measured.effects.as_ref())?;
    let mut options = base_options(&args.measured);
    options.compare_only = true;
    run_diagnosis(job, &args.measured, options)
}

/// The diagnosis options the measurement's flags set.
fn base_options(m: &MeasuredArgs) -> Options {
    Options {
        terms: Terms {
            power: m.remove_power,
            shift: !m.fixed_axis,
        },
        lateral_scale: !m.fixed_scale,
        ..Options::default()
    }
}

/// Reads and places the measurement, diagnoses it against `job` and writes the outputs.
fn run_diagnosis(
    job: toolmark::model::Job,
    args: &MeasuredArgs,
    options: Options,
) -> Result<(), Failure> {
    if let Some(a) = args.azimuth_deg
        && !(a.is_finite() && a.abs() <= 360.0)
    {
        return Err(Failure::Input(format!(
            "--azimuth-deg: {a} is out of range; allowed: −360 to 360"
        )));
    }
    let instrument = Instrument {
        stylus_tip_mm: match args.stylus_tip_um {
            Some(t) if !(t.is_finite() && t > 0.0 && t <= 1e4) => {
                return Err(Failure::Input(format!(
                    "--stylus-tip-um: {t} is out of range; allowed: (0, 10000] µm"
                )));
            }
            t => t.map(|t| t * 1e-3),
        },
        pixel_averaging: args.pixel_averaging,
        line_bin_mm: None,
    };
    let placement = Placement {
        azimuth_deg: args.azimuth_deg,
        axis_at_mm: args
            .axis_at_mm
            .as_ref()
            .map(|v| [v[0], v.get(1).copied().unwrap_or(0.0)]),
    };
    if placement
        .axis_at_mm
        .is_some_and(|a| a.iter().any(|v| !v.is_finite()))
    {
        return Err(Failure::Input("--axis-at-mm: give finite numbers".into()));
    }
    let read = read_options(args.lateral_unit, args.height_unit, &args.pixel_um)?;
    let (measurement, source) =
        load_measurement(&args.measured, &read, &placement, instrument).map_err(Failure::Input)?;
    let mut engine = open_engine(args.engine, &job)?;
    println!("engine: {} — {}", engine.info().kind, engine.info().adapter);
    let out = args.out.clone().unwrap_or_else(|| {
        let what = if options.compare_only {
            "vs-measured"
        } else {
            "diagnosis"
        };
        PathBuf::from("toolmark-out").join(format!("{}-{what}", slug(&job.name)))
    });
    // Progress: each step as it starts, with the time so far.
    let started = std::time::Instant::now();
    let log = |s: &str| eprintln!("[{:6.1} s] {s}", started.elapsed().as_secs_f64());
    let mut outcome = match diagnose(&job, &measurement, engine.as_mut(), &options, &log) {
        Ok(outcome) => outcome,
        Err(DiagnoseError::DoesNotFit(why)) => {
            return Err(Failure::Input(format!(
                "{}: the measurement does not fit the job: {why}",
                args.measured.display()
            )));
        }
        Err(err) => return Err(Failure::Runtime(err.to_string())),
    };
    merge_source(&mut outcome.diagnosis.measurement, &source);
    outcome.diagnosis.job.carried_effects = args.effects.as_ref().map(|p| p.display().to_string());
    if let Some(path) = &args.effects {
        outcome.effects_fragment = carried_fragment(path, &outcome.effects_fragment)?;
    }
    let written = write_outputs(&out, &outcome)
        .map_err(|err| Failure::Runtime(format!("writing outputs to {}: {err}", out.display())))?;
    print_summary(&outcome.diagnosis);
    println!(
        "\n{} simulations ({} engine), {:.1} s; wrote {} files to {}",
        outcome.diagnosis.run.simulations,
        outcome.diagnosis.run.engine,
        outcome.diagnosis.run.total_s,
        written.len(),
        out.display()
    );
    if outcome.diagnosis.verdict.status == "does_not_fit" {
        return Err(Failure::Input(format!(
            "{}: {}",
            args.measured.display(),
            outcome.diagnosis.verdict.sentence
        )));
    }
    Ok(())
}

/// The effects file to carry on: what was carried in, then what this diagnosis added.
fn carried_fragment(carried: &Path, fitted: &str) -> Result<String, Failure> {
    let text = std::fs::read_to_string(carried)
        .map_err(|e| Failure::Input(format!("--effects {}: {e}", carried.display())))?;
    Ok(format!(
        "# Carried from {} (applied before this diagnosis):\n{text}\n{fitted}",
        carried.display()
    ))
}

/// A length's σ as a person reads it: nm below 0.1 µm, else µm.
fn sigma_text(sigma_mm: f64) -> String {
    if sigma_mm < 1e-4 {
        format!("± {:.1} nm", sigma_mm * 1e6)
    } else if sigma_mm.is_finite() {
        format!("± {:.2} µm", sigma_mm * 1e3)
    } else {
        "σ not determined".into()
    }
}

/// What a person reads first: the verdict, what to do, where the data lies, the
/// comparison and the shrinkage.
fn print_summary(d: &toolmark::diagnose::report::Diagnosis) {
    println!("\n{}\n", d.verdict.sentence);
    for a in &d.verdict.advice {
        println!("  at the machine: {a}");
    }
    for f in d.fit_check.findings.iter().filter(|f| f.severity == "note") {
        println!("  note: {}", f.message);
    }
    let r = &d.registration;
    let axis = match (r.axis_y_mm, r.axis_y_sigma_mm) {
        (Some(y), Some(y_sigma)) => format!(
            "({:.4} ({}), {:.4} ({})) mm",
            r.axis_x_mm,
            sigma_text(r.axis_x_sigma_mm),
            y,
            sigma_text(y_sigma)
        ),
        _ => format!("{:.4} mm ({})", r.axis_x_mm, sigma_text(r.axis_x_sigma_mm)),
    };
    println!(
        "\n  placed: a {} with the axis at {axis} of the file; lateral scale {:.4} ({}){}",
        r.trace,
        r.lateral_scale,
        r.lateral_scale_status,
        r.azimuth_deg
            .map_or(String::new(), |a| format!("; {a:.1}° round the spiral"))
    );
    let c = &d.comparison;
    println!(
        "  measured PV {:.0} nm, RMS {:.1} nm; simulated PV {:.0} nm, RMS {:.1} nm{}",
        c.measured.pv_nm,
        c.measured.rms_nm,
        c.simulated.pv_nm,
        c.simulated.rms_nm,
        c.mark_spacing_ratio.map_or(String::new(), |q| format!(
            "; mark spacing measured/simulated {q:.4} (median of {} bands)",
            c.mark_spacing.len()
        ))
    );
    let width = d
        .shrinkage
        .iter()
        .map(|step| step.model.chars().count())
        .fold(34, usize::max);
    println!(
        "\n  {:<width$} {:>10} {:>10}",
        "model", "PV (nm)", "RMS (nm)"
    );
    for step in &d.shrinkage {
        println!(
            "  {:<width$} {:>10.1} {:>10.2}",
            step.model, step.pv_nm, step.rms_nm
        );
    }
    if let Some(h) = &d.held_out {
        println!(
            "  held out ({} points): {:.2} → {:.2} nm RMS",
            h.points, h.before_rms_nm, h.after_rms_nm
        );
    }
}

fn parse_range(text: &str) -> Result<(f64, f64), Failure> {
    let bad = || {
        Failure::Input(format!(
            "--calibrate-on: \"{text}\" is not a range; give FROM:TO in mm with FROM < TO"
        ))
    };
    let (a, b) = text.split_once(':').ok_or_else(bad)?;
    let (a, b): (f64, f64) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if a.is_finite() && b.is_finite() && a < b {
        Ok((a, b))
    } else {
        Err(bad())
    }
}

#[derive(clap::Args)]
pub struct SynthArgs {
    /// Job file (TOML): the part as the diagnosis will be told it.
    #[arg(long)]
    pub job: PathBuf,
    /// The effects the diagnosis is not told (an `[[effects]]` fragment), if any.
    #[arg(long)]
    pub effects: Option<PathBuf>,
    /// The instrument and mount: a TOML file with a `[measurement]` table.
    #[arg(long)]
    pub measurement: PathBuf,
    /// The measured file to write (.csv profile; .x3p, .gsf, .exr or .csv for a map).
    #[arg(long)]
    pub out: PathBuf,
    /// Where to write the truth (JSON), apart from the data.
    #[arg(long)]
    pub truth: PathBuf,
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    pub engine: EngineChoice,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct MeasurementFile {
    measurement: MeasurementModel,
}

pub fn synth_cmd(args: SynthArgs) -> Result<(), Failure> {
    let public = load_job(Some(&args.job))?;
    let truth_job = load_job_with_effects(Some(&args.job), args.effects.as_ref())?;
    let text = std::fs::read_to_string(&args.measurement)
        .map_err(|e| Failure::Input(format!("{}: {e}", args.measurement.display())))?;
    let file: MeasurementFile = toml::from_str(&text)
        .map_err(|e| Failure::Input(format!("{}: {e}", args.measurement.display())))?;
    let model = file.measurement;
    model
        .validate(&public)
        .map_err(|e| Failure::Input(format!("{}: {e}", args.measurement.display())))?;
    if same_folder(&args.out, &args.truth) {
        eprintln!(
            "note: the truth {} sits beside the data; keep it where the diagnosis will not look",
            args.truth.display()
        );
    }
    let mut engine = open_engine(args.engine, &truth_job)?;
    let data = synthesize(&truth_job, &model, engine.as_mut())
        .map_err(|e| Failure::Runtime(e.to_string()))?;
    withheld::write_data(&args.out, &data).map_err(Failure::Runtime)?;
    let effects = match &args.effects {
        Some(p) => std::fs::read_to_string(p).unwrap_or_default(),
        None => String::new(),
    };
    let truth = serde_json::json!({
        "job": args.job.display().to_string(),
        "effects_toml": effects,
        "measurement": model,
        "data": args.out.display().to_string(),
    });
    let text = serde_json::to_string_pretty(&truth).map_err(|e| Failure::Runtime(e.to_string()))?;
    write_bytes_atomically(&args.truth, text.as_bytes())
        .map_err(|e| Failure::Runtime(format!("{}: {e}", args.truth.display())))?;
    let valid = data.height_mm.iter().filter(|v| v.is_finite()).count();
    println!(
        "wrote {} ({} points, {} valid) and the truth to {}",
        args.out.display(),
        data.height_mm.len(),
        valid,
        args.truth.display()
    );
    Ok(())
}

fn same_folder(a: &Path, b: &Path) -> bool {
    let parent = |p: &Path| p.parent().map(Path::to_path_buf).unwrap_or_default();
    parent(a) == parent(b)
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Phase {
    /// Generate, diagnose and score.
    All,
    /// Write the cases and the sealed truth.
    Generate,
    /// Diagnose every case (reads cases/ only).
    Diagnose,
    /// Open the truth and score the diagnoses.
    Score,
}

#[derive(clap::Args)]
pub struct BenchDiagnoseArgs {
    /// Which phase to run.
    #[arg(value_enum, default_value_t = Phase::All)]
    pub phase: Phase,
    /// The suite's folder.
    #[arg(long, default_value = "toolmark-out/diagnosis-suite")]
    pub dir: PathBuf,
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    pub engine: EngineChoice,
    /// Diagnose and score only the cases whose ids contain this (repeatable), e.g.
    /// `--cases milling --cases 003-`.
    #[arg(long = "cases")]
    pub cases: Vec<String>,
}

pub fn bench_diagnose_cmd(args: BenchDiagnoseArgs) -> Result<(), Failure> {
    let default_job = toolmark::model::Job::default_job();
    let log = |s: &str| eprintln!("{s}");
    if matches!(args.phase, Phase::All | Phase::Generate) {
        let mut engine = open_engine(args.engine, &default_job)?;
        let ids = withheld::generate(&args.dir, engine.as_mut(), &log).map_err(Failure::Runtime)?;
        println!("generated {} cases in {}", ids.len(), args.dir.display());
    }
    if matches!(args.phase, Phase::All | Phase::Diagnose) {
        let mut engine = open_engine(args.engine, &default_job)?;
        let runs = withheld::diagnose_suite(&args.dir, engine.as_mut(), &args.cases, &log)
            .map_err(Failure::Runtime)?;
        let total: f64 = runs.iter().map(|r| r.seconds).sum();
        println!("diagnosed {} cases in {total:.0} s", runs.len());
    }
    if matches!(args.phase, Phase::All | Phase::Score) {
        let scores = withheld::score(&args.dir, &args.cases).map_err(Failure::Runtime)?;
        let text = withheld::scores_markdown(&scores);
        println!("{text}");
        let json =
            serde_json::to_string_pretty(&scores).map_err(|e| Failure::Runtime(e.to_string()))?;
        for (name, bytes) in [
            ("scores.md", text.as_bytes()),
            ("scores.json", json.as_bytes()),
        ] {
            let path = args.dir.join(name);
            write_bytes_atomically(&path, bytes)
                .map_err(|e| Failure::Runtime(format!("{}: {e}", path.display())))?;
        }
    }
    Ok(())
}

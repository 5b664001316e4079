//! `toolmark correct`: a generator's setup correction (seed 000) from the pip and the
//! radius error of its part, simulated from the job or read from a measured profile.

use super::{EngineChoice, Failure, load_job, open_engine, slug};
use std::path::{Path, PathBuf};
use toolmark::analysis::sphere_fit::part_sphere;
use toolmark::analysis::{Surround, analyse_protrusion, default_zone_radius_mm};
use toolmark::field::{DexelField, PolarGrid};
use toolmark::formats::atomic::write_bytes_atomically;
use toolmark::formats::measured::read_radial_deviation_csv;
use toolmark::loops::correct::{MissSide, SetupEstimate, correction_loop, estimate_setup};
use toolmark::model::{Job, JobFile};
use toolmark::output::run_files::{write_centre_map, write_centre_profile, write_outputs};
use toolmark::pipeline::{centre_map, products};

#[derive(clap::Args)]
pub struct CorrectArgs {
    /// Generating job (TOML); without --measured its effects play the machine's
    /// unknown errors and the correction is tried on simulated parts.
    pub job: PathBuf,
    /// A measured radial deviation profile from the axis outward: CSV with columns
    /// radius_mm and deviation_nm (as `toolmark run` writes radial_profile.csv).
    #[arg(long)]
    pub measured: Option<PathBuf>,
    /// Radius of the central zone whose PV is reported (mm; default a tenth of the part).
    #[arg(long)]
    pub zone_mm: Option<f64>,
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    pub engine: EngineChoice,
    /// Output folder (default: toolmark-out/<job name>-correction).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn correct(args: CorrectArgs) -> Result<(), Failure> {
    let job = load_job(Some(&args.job))?;
    if job.process.generating().is_none() {
        return Err(Failure::Input(format!(
            "{}: correct adjusts a generator's wheel position and inclination; this is not a generating job (for turning use `toolmark compensate`)",
            args.job.display()
        )));
    }
    let zone = match args.zone_mm {
        Some(z) if z.is_finite() && z > 0.0 && z < job.aperture.outer_radius_mm => z,
        Some(z) => {
            return Err(Failure::Input(format!(
                "--zone-mm {z}: allowed a finite number in (0, {}) (the part's radius)",
                job.aperture.outer_radius_mm
            )));
        }
        None => default_zone_radius_mm(job.aperture.outer_radius_mm, None),
    };
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("toolmark-out").join(format!("{}-correction", slug(&job.name)))
    });
    let write = |name: &str, bytes: &[u8]| {
        write_bytes_atomically(&out.join(name), bytes)
            .map_err(|err| Failure::Runtime(format!("{}: {err}", out.join(name).display())))
    };
    super::run::prepare_out(&out)?;
    match &args.measured {
        Some(measured) => correct_measured(&job, measured, zone, &out, &write),
        None => correct_simulated(&job, zone, args.engine, &out, &write),
    }
}

type Write<'a> = dyn Fn(&str, &[u8]) -> Result<(), Failure> + 'a;

fn print_estimate(estimate: &SetupEstimate) {
    println!(
        "the cutting circle misses the axis by {:.3} µm (pip {:.1} nm high, {:.2} µm radius); the part's sphere is R = {:.6} mm (target {:.6} mm, error {:+.3} µm, fit RMS {:.2} nm)",
        estimate.miss_mm * 1e3,
        estimate.pip_height_nm,
        estimate.pip_radius_um,
        estimate.sphere.radius_mm,
        estimate.target_radius_mm,
        (estimate.sphere.radius_mm - estimate.target_radius_mm) * 1e3,
        estimate.sphere.rms_residual_nm
    );
    for h in &estimate.hypotheses {
        println!(
            "  if it {}: inclination is {:.6}°; move X by {:+.3} µm and change the inclination by {:+.6}°",
            match h.side {
                MissSide::Short => "stops short of the axis",
                MissSide::Past => "passes the axis",
            },
            h.inclination_deg,
            h.move_mm * 1e3,
            h.tilt_deg
        );
    }
    for note in &estimate.notes {
        println!("  note: {note}");
    }
}

/// A job file with the settings one hypothesis's correction gives.
fn corrected_toml(
    job: &Job,
    inclination_deg: f64,
    offset_mm: f64,
    why: &str,
) -> Result<String, Failure> {
    let mut file: JobFile = job.resolved.clone();
    file.name = Some(format!("{} (corrected)", job.name));
    let file = file
        .with_generator_setting(inclination_deg, offset_mm)
        .map_err(|e| Failure::Runtime(e.to_string()))?;
    let text = toml::to_string_pretty(&file).map_err(|e| Failure::Runtime(e.to_string()))?;
    Ok(format!("# {} — {why}\n{text}", job.name))
}

fn correct_measured(
    job: &Job,
    measured: &Path,
    zone: f64,
    out: &Path,
    write: &Write,
) -> Result<(), Failure> {
    let (radius, deviation) =
        read_radial_deviation_csv(measured).map_err(|err| Failure::Input(err.to_string()))?;
    let spacing = {
        let mut steps: Vec<f64> = radius.windows(2).map(|w| w[1] - w[0]).collect();
        steps.sort_by(f64::total_cmp);
        steps[steps.len() / 2]
    };
    let last = radius[radius.len() - 1];
    if radius[0] > spacing {
        return Err(Failure::Input(format!(
            "{}: the profile starts at r = {} mm; it must start at the axis, where the pip is",
            measured.display(),
            radius[0]
        )));
    }
    if last > job.aperture.outer_radius_mm * (1.0 + 1e-9) {
        return Err(Failure::Input(format!(
            "{}: the profile reaches r = {last} mm, beyond the job's part (r = {} mm): is it this part, in mm?",
            measured.display(),
            job.aperture.outer_radius_mm
        )));
    }
    // The profile on rings of the nominal surface, one azimuth.
    let grid = PolarGrid::new(&job.surface, &job.meridian(), 0.0, last, spacing, 1);
    let depth_mm = grid
        .rings
        .iter()
        .map(|ring| {
            let i = radius
                .partition_point(|&r| r <= ring.radius_mm)
                .clamp(1, radius.len() - 1);
            let t = (ring.radius_mm - radius[i - 1]) / (radius[i] - radius[i - 1]);
            deviation[i - 1] + t * (deviation[i] - deviation[i - 1])
        })
        .collect();
    let field = DexelField {
        depth_mm,
        pass: vec![0; grid.sample_count()],
    };
    let protrusion = analyse_protrusion(&grid, &field, zone, Surround::Even);
    let sphere = part_sphere(&grid, &field, &protrusion).ok_or_else(|| {
        Failure::Input(format!(
            "{}: too few points to fit the part's sphere",
            measured.display()
        ))
    })?;
    let setup = &job.process.generating().expect("checked").setup;
    let target = 1.0 / job.surface.curvature_per_mm;
    let estimate = estimate_setup(setup, target, &protrusion, sphere).map_err(Failure::Input)?;
    println!("{} measured in {}:", job.name, measured.display());
    print_estimate(&estimate);
    println!(
        "the form cannot tell the side: try the first correction, and if the pip does not shrink, the second (both from the settings the part was cut with)"
    );
    let mut files = vec!["correction.json"];
    for (h, name) in estimate
        .hypotheses
        .iter()
        .zip(["corrected_short.toml", "corrected_past.toml"])
    {
        let text = corrected_toml(
            job,
            (setup.inclination_rad.to_degrees()) + h.tilt_deg,
            setup.cutter_offset_mm + h.move_mm,
            &format!(
                "settings corrected assuming the circle {:?} the axis",
                h.side
            ),
        )?;
        write(name, text.as_bytes())?;
        files.push(name);
    }
    let json = serde_json::json!({
        "schema": "toolmark.correction/1",
        "job_name": job.name,
        "job_hash": job.hash(),
        "measured_file": measured,
        "central_zone_radius_mm": zone,
        "estimate": estimate,
    });
    write(
        "correction.json",
        serde_json::to_string_pretty(&json)
            .map_err(|e| Failure::Runtime(e.to_string()))?
            .as_bytes(),
    )?;
    toolmark::output::html::write_correction_html(out, &json)
        .map_err(|err| Failure::Runtime(format!("report.html: {err}")))?;
    println!(
        "wrote {}, report.html to {}",
        files.join(", "),
        out.display()
    );
    Ok(())
}

fn correct_simulated(
    job: &Job,
    zone: f64,
    engine: EngineChoice,
    out: &Path,
    write: &Write,
) -> Result<(), Failure> {
    let mut engine = open_engine(engine, job)?;
    let run = correction_loop(job, engine.as_mut(), zone)
        .map_err(|err| Failure::Runtime(err.to_string()))?;
    println!(
        "{}: the part as set, with the job's effects as the machine's errors:",
        job.name
    );
    print_estimate(&run.first_estimate);
    println!(
        "\n| cut | settings | central PV (nm, r ≤ {zone:.3} mm) | pip height (nm) | pip radius (µm) | radius error (µm) |"
    );
    println!("| --- | --- | --- | --- | --- | --- |");
    for cut in &run.cuts {
        println!(
            "| {} | {} | {:.2} | {:.1} | {:.2} | {:+.3} |",
            cut.cut,
            cut.settings,
            cut.central_pv_nm,
            cut.pip_height_nm,
            cut.pip_radius_um,
            cut.radius_error_um
        );
    }
    let (before, after) = (
        run.cuts[0].central_pv_nm,
        run.cuts[run.cuts.len() - 1].central_pv_nm,
    );
    println!(
        "central-zone PV {before:.1} → {after:.3} nm ({:.0}×)",
        before / after.max(1e-12)
    );

    let runtime = |err: std::io::Error| Failure::Runtime(err.to_string());
    write_outputs(&out.join("before"), &run.first, &products(&run.first)).map_err(runtime)?;
    write_outputs(&out.join("after"), &run.last, &products(&run.last)).map_err(runtime)?;
    // Both zooms on one scale, symmetric about zero and set by the part before
    // correction, so "after" reads as clean.
    let half_width = (3.0 * run.first.protrusion.radius_um * 1e-3)
        .max(20.0 * job.pitch_mm)
        .min(zone);
    let before_png = out.join("centre_before.png");
    let (before_map, after_map) = (
        centre_map(&run.first, half_width),
        centre_map(&run.last, half_width),
    );
    let (low, high) = write_centre_map(&before_png, &run.first, (&before_map, half_width), None)
        .map_err(runtime)?;
    let extent = low.abs().max(high.abs());
    for (path, result, map) in [
        (before_png, &run.first, &before_map),
        (out.join("centre_after.png"), &run.last, &after_map),
    ] {
        write_centre_map(&path, result, (map, half_width), Some((-extent, extent)))
            .map_err(runtime)?;
    }
    write_centre_profile(
        &out.join("centre_profiles.png"),
        &[("before", &run.first), ("after", &run.last)],
        half_width,
    )
    .map_err(runtime)?;
    let (inclination, offset) = {
        let setup = &run
            .corrected
            .process
            .generating()
            .expect("generating")
            .setup;
        (setup.inclination_rad.to_degrees(), setup.cutter_offset_mm)
    };
    let text = corrected_toml(
        job,
        inclination,
        offset,
        &format!("settings after {} correction cut(s)", run.cuts.len() - 1),
    )?;
    write("corrected.toml", text.as_bytes())?;
    let json = serde_json::json!({
        "schema": "toolmark.correction/1",
        "job_name": job.name,
        "job_hash": job.hash(),
        "central_zone_radius_mm": zone,
        "engine": run.last.engine,
        "estimate": run.first_estimate,
        "cuts": run.cuts,
    });
    write(
        "correction.json",
        serde_json::to_string_pretty(&json)
            .map_err(|e| Failure::Runtime(e.to_string()))?
            .as_bytes(),
    )?;
    toolmark::output::html::write_correction_html(out, &json)
        .map_err(|err| Failure::Runtime(format!("report.html: {err}")))?;
    println!(
        "wrote before/, after/, centre_before.png, centre_after.png, centre_profiles.png, corrected.toml, correction.json and report.html to {}",
        out.display()
    );
    Ok(())
}

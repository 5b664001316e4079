//! `toolmark compare-profile`: a simulated part against a measured profile.

use super::{EngineChoice, Failure, Unit, load_job, open_engine, slug};
use std::path::PathBuf;
use toolmark::analysis::profile_compare::{compare_profiles, residual_nm, simulated_profile};
use toolmark::io::measured::read_wli_profile_csv;
use toolmark::io::plot::{LinePlot, PALETTE, Series, write_line_plot};
use toolmark::run::simulate;

#[derive(clap::Args)]
pub struct CompareArgs {
    /// Job file (TOML).
    pub job: PathBuf,
    /// Measured profile: `X,Y` CSV as white-light interferometers export it (empty Y = invalid).
    #[arg(long)]
    pub measured: PathBuf,
    /// Unit of the measured X column.
    #[arg(long, value_enum, default_value_t = Unit::Um)]
    pub x_unit: Unit,
    /// Unit of the measured height column.
    #[arg(long, value_enum, default_value_t = Unit::Um)]
    pub height_unit: Unit,
    /// Polynomial order removed from both profiles as form (2 = piston, tilt, curvature).
    #[arg(long, default_value_t = 2)]
    pub form_order: usize,
    #[arg(long, value_enum, default_value_t = EngineChoice::Auto)]
    pub engine: EngineChoice,
    /// Output folder (default: toolmark-out/<job name>-vs-measured).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn compare_profile(args: CompareArgs) -> Result<(), Failure> {
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
    let mut engine = open_engine(args.engine, &job)?;
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

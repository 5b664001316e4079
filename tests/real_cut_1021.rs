//! Real cut 1021 of data/upm-spdt: its own NC program simulated with an ideal
//! 0.191 mm arc and with each measured edge, against the measured WLI profile.
//! Asserted: what independent sources fix (the data README's measured period and PV;
//! the contact-point spacing the program implies); the table itself is printed for the
//! README.

mod common;
use common::*;
use glam::DVec2;
use toolmark::analysis::profile_compare::compare_profiles;
use toolmark::io::job::Job;
use toolmark::io::measured::{LengthUnit, read_wli_profile_csv};

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/upm-spdt");

fn job_with_edge(edge: Option<usize>) -> Job {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/upm_1021_ideal.toml"
    ))
    .unwrap();
    let text = match edge {
        None => text,
        Some(k) => text.replace(
            "included_angle_deg = 120.0",
            &format!("included_angle_deg = 120.0\nedge_profile = \"{DATA}/D906-{k}.csv\""),
        ),
    };
    let examples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    Job::from_toml_in(&text, "upm-1021", &examples).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn cut_1021_simulated_with_ideal_and_measured_edges_against_the_wli_profile() {
    let measured = read_wli_profile_csv(
        std::path::Path::new(&format!("{DATA}/1021-WLI-2D.csv")),
        LengthUnit::Micrometre,
        LengthUnit::Micrometre,
    )
    .unwrap();
    let ideal_job = job_with_edge(None);

    // Independent estimate of the scallop period: the spacing of the cutting points of
    // consecutive revolutions at azimuth 0 (foot of each nose centre on the nominal).
    let Some(toolmark::process::TurningPath::Nc(nc)) = ideal_job.process.turning().map(|t| &t.path)
    else {
        panic!("an NC job")
    };
    let table = &nc.tables[0];
    let feet: Vec<f64> = table
        .poses
        .iter()
        .step_by(table.steps_per_rev as usize)
        .map(|p| ideal_job.surface.distance_to(DVec2::new(p.x_mm, p.z_mm)).1)
        .filter(|r| (measured.x_mm[0]..measured.x_mm[measured.x_mm.len() - 1]).contains(r))
        .collect();
    let spacing_um = (feet[0] - feet[feet.len() - 1]) / (feet.len() - 1) as f64 * 1e3;

    println!("| tool edge | period (µm) | PV (nm) | RMS (nm) |");
    println!("| --- | --- | --- | --- |");
    let mut rows = Vec::new();
    for edge in [None, Some(1), Some(2), Some(3), Some(4), Some(5)] {
        let result = run_cpu(job_with_edge(edge));
        let c = compare_profiles(
            result.grid(),
            &result.field,
            &measured.x_mm,
            &measured.height_mm,
            2,
        );
        let (period, pv, rms) = (
            c.simulated_summary(|s| s.dominant_period_um),
            c.simulated_summary(|s| s.pv_nm),
            c.simulated_summary(|s| s.rms_nm),
        );
        let name = edge.map_or("ideal 0.191 mm arc".to_string(), |k| {
            format!("measured D906-{k}")
        });
        println!(
            "| {name} | {:.2} ({:.2}–{:.2}) | {:.0} ({:.0}–{:.0}) | {:.0} ({:.0}–{:.0}) |",
            period.0, period.1, period.2, pv.0, pv.1, pv.2, rms.0, rms.1, rms.2
        );
        if edge.is_none() {
            let m = &c.measured;
            println!(
                "| measured 1021-WLI-2D | {:.2} | {:.0} | {:.0} |",
                m.dominant_period_um, m.pv_nm, m.rms_nm
            );
            // The data README: "PV about 1.26 µm, dominant period about 41 µm" (raw heights;
            // ours is after removing a quadratic, which moves PV a few per cent).
            assert!(
                (m.dominant_period_um - 41.0).abs() < 1.0,
                "{}",
                m.dominant_period_um
            );
            assert!((m.pv_nm / 1260.0 - 1.0).abs() < 0.05, "{}", m.pv_nm);
            // The simulated scallops sit where the program puts the cutting points.
            println!("contact-point spacing from the program over the span: {spacing_um:.2} µm");
            assert!(
                (period.0 / spacing_um - 1.0).abs() < 0.01,
                "{} vs {spacing_um}",
                period.0
            );
        }
        rows.push((period.0, pv.0, rms.0));
    }
    // Every simulation is a scallop field of the same period; the edges change its height.
    for (period, _, _) in &rows {
        assert!(
            (period / spacing_um - 1.0).abs() < 0.02,
            "{period} vs {spacing_um}"
        );
    }
}

/// The diagnosis of the gap on cut 1021: the units as the data README gives them fit;
/// the profile read in the wrong lateral unit is refused. Calibrated on the first half
/// (x < 0.5 mm), the second half is held out: its residual must not grow, and the
/// counts of fitted and held-out points are those of the file.
#[test]
fn cut_1021_diagnosis_with_a_held_out_half() {
    use toolmark::diagnose::files::{Placement, load_measurement};
    use toolmark::diagnose::measurement::Instrument;
    use toolmark::diagnose::{Options, diagnose, register::Terms};
    use toolmark::engine::cpu::CpuEngine;
    use toolmark::io::measured::ReadOptions;
    let path = std::path::Path::new(DATA).join("1021-WLI-2D.csv");
    let read = |lateral: LengthUnit| {
        let options = ReadOptions {
            lateral_unit: Some(lateral),
            height_unit: Some(LengthUnit::Micrometre),
            pixel_mm: None,
        };
        load_measurement(
            &path,
            &options,
            &Placement::default(),
            Instrument::default(),
        )
        .unwrap()
        .0
    };
    let job = job_with_edge(None);
    let mut options = Options {
        terms: Terms {
            power: true,
            shift: true,
        },
        ..Options::default()
    };
    // Positions in µm declared as mm: a 1 m profile on a Ø2 mm part.
    let wrong = diagnose(
        &job,
        &read(LengthUnit::Millimetre),
        &mut CpuEngine,
        &options,
        &|_| {},
    );
    assert!(
        wrong.is_err() || wrong.as_ref().unwrap().diagnosis.verdict.status == "does_not_fit",
        "µm read as mm gave a verdict"
    );

    let measured =
        read_wli_profile_csv(&path, LengthUnit::Micrometre, LengthUnit::Micrometre).unwrap();
    let first_half = measured
        .x_mm
        .iter()
        .zip(&measured.height_mm)
        .filter(|(x, h)| **x < 0.5 && h.is_finite())
        .count();
    let second_half = measured
        .x_mm
        .iter()
        .zip(&measured.height_mm)
        .filter(|(x, h)| **x >= 0.5 && h.is_finite())
        .count();
    options.calibrate_on_mm = Some((0.0, 0.5));
    let outcome = diagnose(
        &job,
        &read(LengthUnit::Micrometre),
        &mut CpuEngine,
        &options,
        &|_| {},
    )
    .unwrap();
    let d = &outcome.diagnosis;
    println!("{}", d.verdict.sentence);
    assert!(d.fit_check.fits, "{:?}", d.fit_check.findings);
    let held = d.held_out.as_ref().expect("the second half held out");
    println!(
        "fitted {} points: {:.1} → {:.1} nm RMS; held out {} points: {:.1} → {:.1} nm RMS",
        d.measurement.points_fitted,
        d.residual_before.rms_nm,
        d.residual_after.rms_nm,
        held.points,
        held.before_rms_nm,
        held.after_rms_nm
    );
    assert_eq!(
        (d.measurement.points_fitted, held.points),
        (first_half, second_half)
    );
    assert!(held.after_rms_nm <= held.before_rms_nm * 1.001);
}

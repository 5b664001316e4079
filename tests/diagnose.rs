//! The diagnosis on synthetic measurements whose effects are known: `synth` makes the
//! measured-like data from the job plus effects the diagnosis is not told, and each
//! test checks what the diagnosis finds against those effects (the truth is the
//! independent source), within stated tolerances.

mod common;
use common::*;
use toolmark::diagnose::measurement::Measurement;
use toolmark::diagnose::synth::{MeasurementModel, synthesize};
use toolmark::diagnose::withheld;
use toolmark::diagnose::{DiagnoseError, Options, Outcome, diagnose};
use toolmark::engine::RemovalEngine;
use toolmark::engine::cpu::CpuEngine;
use toolmark::geometry::Form;
use toolmark::model::{
    DirectionSpec, EffectSpec, EffectsFragment, Job, JobFile, RunoutSpec, SurfaceSpec,
};

/// A suite base's job file.
fn base(text: &str) -> JobFile {
    JobFile::from_toml_str(text).expect("a suite base reads")
}

/// The suite's turned sphere (R8 convex, Ø3 mm, 10 µm/rev) on a 1 µm grid (the suite
/// uses 0.5 µm; these cases need no finer).
fn sphere() -> JobFile {
    let mut file = base(withheld::TURNING_SPHERE.job);
    assert_eq!(file.grid.pitch_um, Some(0.5));
    file.grid.pitch_um = Some(1.0);
    file
}

/// A stylus profile through the axis with a mount of known tilt, piston and offset.
const PROFILE: &str = r#"kind = "profile"
spacing_um = 1.0
stylus_tip_um = 2.0
tilt_urad = [35.0, 0.0]
piston_um = 3.0
decentre_um = [6.0, 0.0]
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
seed = 3
"#;

fn model(text: &str) -> MeasurementModel {
    toml::from_str(text).unwrap()
}

/// Synthesizes `truth_effects` on `base` as `measurement` describes, and returns the
/// measured line as the diagnosis reads it (no truth).
fn measure(
    base: &JobFile,
    truth_effects: &[EffectSpec],
    measurement: &MeasurementModel,
) -> Measurement {
    let mut truth = base.clone();
    truth.effects.extend_from_slice(truth_effects);
    let truth = checked(truth);
    let data = synthesize(&truth, measurement, &mut CpuEngine).unwrap();
    Measurement::line(
        &data.positions_mm,
        &data.height_mm,
        measurement.azimuth_deg.to_radians(),
        0.0,
        measurement.instrument(),
    )
}

fn run(
    base: &JobFile,
    m: &Measurement,
    engine: &mut dyn RemovalEngine,
    options: &Options,
) -> Outcome {
    diagnose(&checked(base.clone()), m, engine, options, &|_| {})
        .unwrap_or_else(|e| panic!("diagnosis failed: {e}"))
}

/// The accepted effect's fitted parameter values.
fn accepted(outcome: &Outcome, effect: &str) -> Vec<(f64, f64)> {
    let d = &outcome.diagnosis;
    let found = d
        .accepted
        .iter()
        .find(|c| c.effect == effect)
        .unwrap_or_else(|| {
            panic!(
                "{effect} not accepted; verdict: {}; candidates: {:?}",
                d.verdict.sentence,
                d.candidates
                    .iter()
                    .map(|c| (&c.effect, c.delta_bic))
                    .collect::<Vec<_>>()
            )
        });
    found
        .parameters
        .iter()
        .map(|p| (p.value, p.sigma))
        .collect()
}

/// The accepted effects leave under a fifth of the residual RMS (the 80 % target).
fn assert_residual_shrinks_fivefold(d: &toolmark::diagnose::report::Diagnosis, effect: &str) {
    let shrink = d.residual_after.rms_nm / d.residual_before.rms_nm;
    assert!(
        shrink < 0.2,
        "{effect}: RMS {} → {} nm",
        d.residual_before.rms_nm,
        d.residual_after.rms_nm
    );
}

#[test]
fn registration_reports_the_mount_it_removed_and_a_clean_part_shows_no_effect() {
    let m = measure(&sphere(), &[], &model(PROFILE));
    let outcome = run(&sphere(), &m, &mut CpuEngine, &Options::default());
    let d = &outcome.diagnosis;
    let reg = &d.registration.nominal;
    println!("registration: {reg:?}; verdict: {}", d.verdict.sentence);
    // The mount: piston 3 µm, tilt 35 µrad, axis 6 µm along the line. The 1/f noise's
    // longest waves are part of what piston and tilt absorb: bounds of 20 nm, 3 µrad.
    assert!(
        (reg.piston_nm - 3000.0).abs() < 20.0,
        "piston {} nm",
        reg.piston_nm
    );
    assert!(
        (reg.tilt_urad[0] - 35.0).abs() < 3.0,
        "tilt {} µrad",
        reg.tilt_urad[0]
    );
    assert!(
        (reg.axis_at_um[0] - 6.0).abs() < 0.2,
        "axis {} µm",
        reg.axis_at_um[0]
    );
    assert_eq!(
        d.verdict.status, "no_effect_beyond_noise",
        "{}",
        d.verdict.sentence
    );
    assert!(d.accepted.is_empty());
    // What remains is the instrument's noise: 1.5 nm white + 1 nm 1/f.
    assert!(
        d.residual_before.rms_nm < 3.0,
        "{} nm RMS",
        d.residual_before.rms_nm
    );
}

#[test]
fn single_turning_effects_are_ranked_first_sized_and_removed() {
    for (table, effect, truth) in [
        (EffectSpec::centre_height(0.003), "centre_height", 3.0),
        (EffectSpec::x_decentre(0.004), "x_decentre", 4.0),
        (
            EffectSpec::nose_radius_error(0.005),
            "nose_radius_error",
            5.0,
        ),
    ] {
        let m = measure(&sphere(), &[table], &model(PROFILE));
        // On a sphere a nose-radius error Δρ moves the marks out as a lateral scale of
        // 1 + Δρ/R does and bends the form as a scale of 1 + Δρ/2R: with the scale
        // free the two leave only a 0.4 µm mark shift at the rim to tell them apart (see
        // the next test). The instrument's scale is known here (a stylus).
        let options = Options {
            lateral_scale: effect != "nose_radius_error",
            ..Options::default()
        };
        let outcome = run(&sphere(), &m, &mut CpuEngine, &options);
        let d = &outcome.diagnosis;
        println!("{effect}: {}", d.verdict.sentence);
        let evidence: Vec<(&str, f64)> = d
            .candidates
            .iter()
            .map(|c| (c.effect.as_str(), c.delta_bic))
            .collect();
        assert_eq!(d.verdict.status, "effects_found", "{evidence:?}");
        assert_eq!(d.candidates[0].effect, effect, "ranked first");
        assert_eq!(d.accepted[0].effect, effect, "accepted first");
        let (value, _) = accepted(&outcome, effect)[0];
        assert!(
            (value / truth - 1.0).abs() < 0.05,
            "{effect}: {value} µm against {truth} µm"
        );
        assert_residual_shrinks_fivefold(d, effect);
    }
}

#[test]
fn a_nose_radius_error_with_the_lateral_scale_free_is_never_claimed_wrong() {
    // The same 5 µm error with the scale fitted beside it: the diagnosis either finds
    // it (within 10 %) or, the two being close to degenerate on a sphere, claims
    // nothing — never another effect, and never a nose radius off by more than 10 %.
    let m = measure(
        &sphere(),
        &[EffectSpec::nose_radius_error(0.005)],
        &model(PROFILE),
    );
    let outcome = run(&sphere(), &m, &mut CpuEngine, &Options::default());
    let d = &outcome.diagnosis;
    println!("{}", d.verdict.sentence);
    assert_eq!(d.candidates[0].effect, "nose_radius_error", "ranked first");
    let value = d.candidates[0].parameters[0].value;
    assert!((value / 5.0 - 1.0).abs() < 0.1, "{value} µm against 5 µm");
    for a in &d.accepted {
        assert_eq!(a.effect, "nose_radius_error");
        assert!((a.parameters[0].value / 5.0 - 1.0).abs() < 0.1);
    }
    let scale = d.registration.lateral_scale;
    assert!(
        (scale - 1.0).abs() < 1e-3,
        "lateral scale {scale} (truth 1)"
    );
}

/// The suite's generating base (seed 000's wheel on a concave R53.5).
fn generated() -> JobFile {
    base(withheld::GENERATED_SPHERE.job)
}

#[test]
fn a_displaced_wheel_is_told_from_an_inclination_error_by_its_pip() {
    // Both change the generated radius; only the displacement leaves a pip on the axis.
    let measurement = model(
        "kind = \"profile\"\nspacing_um = 2.0\ntilt_urad = [20.0, 0.0]\ndecentre_um = [8.0, 0.0]\nwhite_noise_nm = 1.0\npink_noise_nm = 1.0\nseed = 5\n",
    );
    let m = measure(
        &generated(),
        &[EffectSpec::cutter_displacement(0.02)],
        &measurement,
    );
    let outcome = run(&generated(), &m, &mut CpuEngine, &Options::default());
    println!("{}", outcome.diagnosis.verdict.sentence);
    assert_eq!(
        outcome.diagnosis.candidates[0].effect,
        "cutter_displacement"
    );
    let (value, _) = accepted(&outcome, "cutter_displacement")[0];
    assert!((value - 20.0).abs() < 1.0, "{value} µm against 20 µm");
}

/// The suite's feed-mark base: a two-flute ball-end mill along X over a flat.
fn feed_marks() -> JobFile {
    base(withheld::BALL_FEED_MARKS_FLAT.job)
}

#[test]
fn runout_is_sized_along_the_feed_and_its_unseen_component_is_said_so() {
    // ε = 2 µm at 30°: (1.732, 1.0) µm along and across the feed. A profile along the
    // feed sees the mark spacing alternate by 2·ε·cos φ, never the across component.
    let measurement = model(
        "kind = \"profile\"\nspacing_um = 0.5\nstylus_tip_um = 2.0\ntilt_urad = [15.0, 0.0]\nwhite_noise_nm = 1.5\npink_noise_nm = 1.0\nseed = 9\n",
    );
    let runout = EffectSpec::RadialRunout(RunoutSpec {
        offset_mm: Some(0.002),
        phase_deg: Some(30.0),
    });
    let m = measure(&feed_marks(), &[runout], &measurement);
    let outcome = run(&feed_marks(), &m, &mut CpuEngine, &Options::default());
    let d = &outcome.diagnosis;
    println!("{}", d.verdict.sentence);
    let values = accepted(&outcome, "radial_runout");
    assert!(
        (values[0].0 / 1.732 - 1.0).abs() < 0.05,
        "along the feed: {:?}",
        values[0]
    );
    assert!(
        values[1].1.is_infinite() && values[1].0 == 0.0,
        "across: {:?}",
        values[1]
    );
    assert!(
        d.verdict.sentence.contains("not seen"),
        "{}",
        d.verdict.sentence
    );
}

/// The reason a diagnosis refused the data, or a panic when it gave a verdict.
fn refusal(result: Result<Outcome, DiagnoseError>) -> String {
    match result {
        Err(DiagnoseError::DoesNotFit(reason)) => reason,
        Err(other) => panic!("expected 'does not fit', got the error {other}"),
        Ok(outcome) => {
            let v = &outcome.diagnosis.verdict;
            assert_eq!(
                v.status, "does_not_fit",
                "a verdict on data that does not fit: {}",
                v.sentence
            );
            assert!(outcome.diagnosis.accepted.is_empty());
            v.sentence.clone()
        }
    }
}

#[test]
fn data_that_does_not_fit_the_job_is_refused_plainly() {
    let clean = model(PROFILE);
    let m = measure(&sphere(), &[], &clean);
    let nominal = checked(sphere());
    let try_it =
        |m: &Measurement| diagnose(&nominal, m, &mut CpuEngine, &Options::default(), &|_| {});
    let rescaled = |lateral: f64, height: f64| {
        Measurement::line(
            &m.along_mm.iter().map(|x| x * lateral).collect::<Vec<_>>(),
            &m.height_mm.iter().map(|z| z * height).collect::<Vec<_>>(),
            0.0,
            0.0,
            clean.instrument(),
        )
    };
    // Positions in µm read as mm: the profile lies mostly off the Ø3 mm part.
    let reason = refusal(try_it(&rescaled(1000.0, 1.0)));
    println!("µm read as mm: {reason}");
    // Positions in mm read as µm: 3 µm of profile, the marks 1000× too close.
    let reason = refusal(try_it(&rescaled(0.001, 1.0)));
    println!("mm read as µm: {reason}");
    // Heights in µm read as nm: a thousandth of the form and of the marks.
    let reason = refusal(try_it(&rescaled(1.0, 0.001)));
    println!("heights µm read as nm: {reason}");
    assert!(
        reason.contains("unit") || reason.contains("another part"),
        "{reason}"
    );
    // Another part: the concave sphere of the same radius.
    let mut concave = sphere();
    let SurfaceSpec::Sphere(part) = &mut concave.surface else {
        panic!("the suite's sphere")
    };
    part.form = Some(Form::Concave);
    let other = measure(&concave, &[], &clean);
    let reason = refusal(try_it(&other));
    println!("another part: {reason}");
    // Empty: no valid point.
    let empty = Measurement::line(
        &[0.0, 0.1],
        &[f64::NAN, f64::NAN],
        0.0,
        0.0,
        clean.instrument(),
    );
    let reason = refusal(try_it(&empty));
    assert!(reason.contains("valid points"), "{reason}");
}

#[test]
fn the_suite_is_diagnosed_without_its_truth_and_scored_after() {
    let dir = std::env::temp_dir().join(format!("toolmark-suite-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let ids = withheld::generate(&dir, &mut CpuEngine, &|_| {}).unwrap();
    assert!(ids.len() >= 48, "{} cases", ids.len());
    // What a diagnosis may read holds no effect: the jobs are the bases as given.
    for id in &ids {
        let job = std::fs::read_to_string(dir.join("cases").join(id).join("job.toml")).unwrap();
        assert!(
            !job.contains("[[effects]]"),
            "{id}: the public job carries effects"
        );
    }
    // Seal the truth away while diagnosing: the diagnosis cannot open it.
    let sealed = dir.join("sealed");
    let away = std::env::temp_dir().join(format!("toolmark-sealed-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&away);
    std::fs::rename(&sealed, &away).unwrap();
    // A turned part of cut 1021's family (bare C X Z program, line from the file's zero
    // with the axis inside it), the same part with material piled up beside each cusp
    // (an effect toolmark does not model), a generated part and its control, a milled
    // part (the whole suite runs in `bench-diagnose`).
    let chosen: Vec<String> = ["025-", "034-", "036-", "044-", "046-"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let runs = withheld::diagnose_suite(&dir, &mut CpuEngine, &chosen, &|_| {}).unwrap();
    assert_eq!(runs.len(), 5);
    assert!(
        withheld::score(&dir, &chosen).is_err(),
        "scoring needs the truth"
    );
    std::fs::rename(&away, &sealed).unwrap();
    let scores = withheld::score(&dir, &chosen).unwrap();
    println!("{}", withheld::scores_markdown(&scores));
    assert_eq!(scores.cases.len(), 5);
    assert_eq!((scores.singles, scores.controls), (3, 1));
    // The pile-up (6 nm high, 1.5 µm wide, under 2 nm of noise) is near the noise point
    // by point; folded over the marks it stands out, and no effect stands in for it.
    assert_eq!((scores.unmodelled, scores.unmodelled_unexplained), (1, 1));
    assert_eq!(scores.singles_ranked_first, 3);
    assert_eq!(scores.singles_parameter_within_10_percent, 3);
    assert_eq!(scores.controls_false_claims, 0);
    // The synthesis put the axis 350–650 µm along the turned part's line: its marks
    // place it within 20 µm. (A generated sphere without marks hardly fixes its axis
    // along a line: a sideways shift of a sphere is a tilt.)
    let turned = &scores.cases[0];
    assert!(turned.axis_error_um < 20.0, "{}", turned.axis_error_um);
    // Its centre height's truth lies within 2σ (2.3σ before the refit on finer rings).
    assert!(
        turned.parameters_within_2_sigma,
        "{:?}",
        turned.sigma_ratios
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The 1021-family part's white-light line as the suite reads it (0.871 µm points from
/// the file's zero, the axis 578.8 µm along), without noise or mount.
const VARYING_FEED_LINE: &str = r#"kind = "profile"
from_mm = 0.0
to_mm = 1.3
spacing_um = 0.871
decentre_um = [578.8, 0.0]
"#;

/// The forward model's ring pitch biases a fit in proportion to it: a 2 µm centre height
/// on the 1021-family part, measured without noise, came back 1.956 ± 0.008 µm on the
/// job's 0.5 µm rings — 5.7σ from the truth, with no noise to blame (1.977 on 0.25 µm
/// rings, 1.995 on 0.125 µm). The reported fit is refitted on rings half as far apart
/// and its σ carries the move.
#[test]
fn a_reported_fit_is_refined_on_finer_rings_and_its_sigma_carries_the_ring_pitch() {
    let base = &withheld::SPIRAL_VARYING_FEED;
    let dir = std::env::temp_dir().join(format!("toolmark-rings-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text) in (base.files)() {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let truth_um = 2.0;
    let truth = self::base(base.job).effect(EffectSpec::centre_height(truth_um * 1e-3));
    let truth = Job::from_file(truth, "truth", &dir).unwrap();
    let measurement = model(VARYING_FEED_LINE);
    let data = synthesize(&truth, &measurement, &mut CpuEngine).unwrap();
    let m = Measurement::line(
        &data.positions_mm,
        &data.height_mm,
        0.0,
        0.0,
        measurement.instrument(),
    );
    let job = Job::from_toml_in(base.job, "job", &dir).unwrap();
    let mut options = Options {
        only: vec!["centre_height".into()],
        ..Options::default()
    };
    options.terms.power = base.remove_power;
    let outcome = diagnose(&job, &m, &mut CpuEngine, &options, &|_| {}).unwrap();
    let (h, sigma) = accepted(&outcome, "centre_height")[0];
    println!("{h:.4} ± {sigma:.4} µm for {truth_um}");
    // Within 1.5 % (2.2 % on the job's rings alone) and 2σ.
    assert!((h - truth_um).abs() < 0.015 * truth_um, "{h} µm");
    assert!((h - truth_um).abs() <= 2.0 * sigma, "{h} ± {sigma} µm");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A white-light map of the centre, 81 × 81 pixels of 1 µm (each the mean over its
/// footprint), on a mount that slides the part's axis 8 µm along X and −5 µm along Y.
const CENTRE_MAP: &str = r#"kind = "map"
pixels = [81, 81]
pixel_um = 1.0
pixel_averaging = true
tilt_urad = [20.0, -30.0]
piston_um = 2.0
decentre_um = [8.0, -5.0]
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
seed = 5
"#;

#[test]
fn a_map_of_the_centre_finds_the_axis_and_sizes_the_centre_height() {
    // The suite's job (0.5 µm rings: the 3 µm protrusion needs them).
    let base = base(withheld::TURNING_SPHERE.job);
    let measurement = model(CENTRE_MAP);
    let truth = checked(base.clone().effect(EffectSpec::centre_height(0.003)));
    let data = synthesize(&truth, &measurement, &mut CpuEngine).unwrap();
    let m = Measurement::raster(
        (data.pixels[0], data.pixels[1]),
        data.origin_mm,
        [data.pixel_mm; 2],
        &data.height_mm,
        glam::DVec2::ZERO,
        measurement.instrument(),
    );
    let options = Options {
        only: vec!["centre_height".into(), "x_decentre".into()],
        ..Options::default()
    };
    let outcome = run(&base, &m, &mut CpuEngine, &options);
    let d = &outcome.diagnosis;
    let axis = d.registration.fitted.axis_at_um;
    println!(
        "{}; axis at {axis:?} µm; centre zone share {:.2}",
        d.verdict.sentence, d.residual_before.zones[0].share
    );
    // The axis to 0.1 µm (the rings' curvature pins it; their spacing is 10 µm).
    assert!(
        (axis[0] - 8.0).abs() < 0.1 && (axis[1] + 5.0).abs() < 0.1,
        "axis at {axis:?} µm"
    );
    assert_eq!(d.candidates[0].effect, "centre_height", "ranked first");
    let (height, _) = accepted(&outcome, "centre_height")[0];
    assert!(
        (height / 3.0 - 1.0).abs() < 0.05,
        "{height} µm against 3 µm"
    );
    // Where: the protrusion (radius ≈ the height error) lies in the centre zone.
    let centre = &d.residual_before.zones[0];
    assert!(centre.rms_nm > 5.0 * d.residual_after.rms_nm, "{centre:?}");
    assert_residual_shrinks_fivefold(d, "centre_height");
}

#[test]
fn gpu_diagnosis_agrees_with_the_cpu_one() {
    let m = measure(&sphere(), &[EffectSpec::x_decentre(0.004)], &model(PROFILE));
    let options = Options {
        only: vec!["x_decentre".into()],
        ..Options::default()
    };
    let cpu = accepted(&run(&sphere(), &m, &mut CpuEngine, &options), "x_decentre")[0];
    let mut gpu_engine = gpu_engine();
    let gpu_outcome = run(&sphere(), &m, &mut gpu_engine, &options);
    let gpu = accepted(&gpu_outcome, "x_decentre")[0];
    println!(
        "x decentre: CPU {:.4} ± {:.4} µm, GPU {:.4} ± {:.4} µm",
        cpu.0, cpu.1, gpu.0, gpu.1
    );
    assert!(
        gpu_outcome.diagnosis.run.engine.contains("gpu"),
        "{}",
        gpu_outcome.diagnosis.run.engine
    );
    // The engines agree to 0.5 nm on a part; the fitted offset to 0.5 %.
    assert!((gpu.0 / cpu.0 - 1.0).abs() < 0.005);
    assert!((gpu.0 / 4.0 - 1.0).abs() < 0.05);
}

#[test]
fn fitted_effects_change_the_job_as_the_fit_says() {
    // The fragment the diagnosis writes, added to the job, reproduces the fitted model.
    // (A centre height: on this sphere a drift's print is also a decentre's — the
    // diagnosis calls those two ambiguous — and a nose-radius error's a lateral scale's.)
    let m = measure(
        &sphere(),
        &[EffectSpec::centre_height(0.003)],
        &model(PROFILE),
    );
    let outcome = run(&sphere(), &m, &mut CpuEngine, &Options::default());
    let fragment = &outcome.effects_fragment;
    let mut with = sphere();
    with.effects.extend(
        EffectsFragment::from_toml_str(fragment)
            .expect("the fragment reads")
            .effects,
    );
    let with = checked(with);
    let toolmark::process::Process::Turning(t) = &with.process else {
        panic!("a turning job")
    };
    // The table holds six significant digits.
    let (value, _) = accepted(&outcome, "centre_height")[0];
    assert!(
        (t.effects.centre_height_mm * 1e3 / value - 1.0).abs() < 1e-5,
        "{fragment}"
    );
}

#[test]
fn a_fractional_depth_vibration_is_found_at_its_rate_modulo_the_profiles_aliases() {
    // 8 nm at 0.37 cycles per revolution along the depth, made by the section model. A
    // line through the axis reads the cut clock at two spindle angles half a turn
    // apart, so 0.37 and 0.63 (= 1 − 0.37, phase mirrored) leave the same trace; the
    // amplitude within 10 %, the rate within 0.01 of one of them.
    let vibration = EffectSpec::vibration(0.000008, DirectionSpec::Depth, 0.37, 20.0);
    let m = measure(&sphere(), &[vibration], &model(PROFILE));
    let outcome = run(&sphere(), &m, &mut CpuEngine, &Options::default());
    let d = &outcome.diagnosis;
    println!("{}", d.verdict.sentence);
    assert_eq!(d.verdict.status, "effects_found");
    assert_eq!(d.accepted[0].effect, "vibration");
    let rate = d.accepted[0].order.expect("a vibration has a rate");
    assert!(
        (rate - 0.37).abs() < 0.01 || (rate - 0.63).abs() < 0.01,
        "{rate} cycles per revolution"
    );
    let v = accepted(&outcome, "vibration");
    let amplitude = v[0].0.hypot(v[1].0);
    assert!(
        (amplitude / 8.0 - 1.0).abs() < 0.1,
        "{amplitude} nm against 8 nm"
    );
}

#[test]
fn wear_on_a_sphere_is_never_claimed_as_another_effect() {
    // On a sphere a spiral's wear lifts the face by w(r₀² − r²)/r₀² and a nose-radius
    // error bends it by e·r²/2R²: with the lateral scale free, one profile cannot tell
    // them apart. The diagnosis must then claim neither (ambiguous) or the wear within
    // 10 % — never a nose radius.
    let m = measure(
        &sphere(),
        &[EffectSpec::tool_wear(0.00015)],
        &model(PROFILE),
    );
    let outcome = run(&sphere(), &m, &mut CpuEngine, &Options::default());
    let d = &outcome.diagnosis;
    println!("{}: {}", d.verdict.status, d.verdict.sentence);
    for a in &d.accepted {
        assert_eq!(a.effect, "tool_wear", "{}", d.verdict.sentence);
        assert!((a.parameters[0].value / 150.0 - 1.0).abs() < 0.1);
    }
    assert!(
        d.verdict.status == "ambiguous" || d.verdict.status == "effects_found",
        "{}",
        d.verdict.status
    );
}

#[test]
fn wear_beside_a_drift_is_found_as_the_pair_or_called_ambiguous_never_one_waviness() {
    // A drift of 200 nm (a cone in r: the cut's clock) and a wear of 150 nm (power:
    // its length cut) on the sphere. One edge waviness of half a cycle over the used
    // edge imitates both at once and fits best alone, at the lowest order the edge span
    // can tell (a search bound: not a fit). On a sphere an X decentre is a cone too:
    // only the marks' phase and the rings at the axis tell it from the drift, and here
    // a decentre in the drift's place explains the data within 3σ. The diagnosis must
    // find the pair (each within 10 % of the truth) or say that it cannot tell the
    // drift from a decentre (beside the wear) — never claim a waviness or a decentre.
    let m = measure(
        &sphere(),
        &[
            EffectSpec::tool_wear(0.00015),
            EffectSpec::axial_drift(0.0002),
        ],
        &model(PROFILE),
    );
    let outcome = run(&sphere(), &m, &mut CpuEngine, &Options::default());
    let d = &outcome.diagnosis;
    println!("{}: {}", d.verdict.status, d.verdict.sentence);
    if d.verdict.status == "ambiguous" {
        assert!(d.accepted.is_empty(), "{}", d.verdict.sentence);
        assert!(
            d.ambiguous.iter().any(|a| a == "axial drift + tool wear"),
            "the truth is among the explanations: {:?}",
            d.ambiguous
        );
        assert!(
            d.ambiguous.iter().all(|a| !a.contains("waviness")),
            "{:?}",
            d.ambiguous
        );
        return;
    }
    let mut kinds: Vec<&str> = d.accepted.iter().map(|a| a.effect.as_str()).collect();
    kinds.sort_unstable();
    assert_eq!(
        kinds,
        ["axial_drift", "tool_wear"],
        "{}",
        d.verdict.sentence
    );
    let (drift, _) = accepted(&outcome, "axial_drift")[0];
    let (wear, _) = accepted(&outcome, "tool_wear")[0];
    assert!(
        (drift / 200.0 - 1.0).abs() < 0.1,
        "drift {drift} nm against 200"
    );
    assert!(
        (wear / 150.0 - 1.0).abs() < 0.1,
        "wear {wear} nm against 150"
    );
}

/// A white-light diameter of the suite's R20 sphere (8 µm/rev, 0.5 mm nose, 0.5 µm
/// pixels, azimuth not told) whose axis lies 63 µm from the file's zero: the even marks
/// repeat every half feed (with the line half a turn round), so they alone place it
/// only up to 16 teeth of a comb; the +5 µm centre height's cone, at the axis, tells
/// which — the issue's case the old search placed one mark off (taking a tilt instead)
/// and never found.
const WHITE_LIGHT_LINE: &str = r#"kind = "profile"
from_mm = -0.85
to_mm = 0.95
spacing_um = 0.5
white_noise_nm = 1.5
pink_noise_nm = 1.5
tilt_urad = [40.0, 0.0]
decentre_um = [63.0, 0.0]
seed = 5
"#;

/// A stylus diameter (2 µm tip) of an R5 sphere turned at 2 µm/rev with a 0.2 mm nose
/// (marks 2.5 nm high: the form alone placed it), its axis 27 µm from the file's zero;
/// the tool 5 µm below centre leaves a boss of the 3 µm stock, 10 µm across — the
/// issue's case that came back as +14.97 µm (a cone) from a scan growing from zero.
const FINE_FEED_LINE: &str = r#"kind = "profile"
from_mm = -0.45
to_mm = 0.45
spacing_um = 0.5
stylus_tip_um = 2.0
white_noise_nm = 1.0
pink_noise_nm = 1.0
decentre_um = [27.0, 0.0]
seed = 3
"#;

#[test]
fn a_centre_height_is_found_where_the_marks_cannot_place_the_axis() {
    let options = Options {
        only: vec!["centre_height".into(), "x_decentre".into()],
        ..Options::default()
    };
    for (base, measurement, truth_um, axis_um) in [
        (
            withheld::WHITE_LIGHT_SPHERE.job,
            WHITE_LIGHT_LINE,
            5.0,
            63.0,
        ),
        (withheld::FINE_FEED_SPHERE.job, FINE_FEED_LINE, -5.0, 27.0),
    ] {
        let base = self::base(base);
        let effect = EffectSpec::centre_height(truth_um * 1e-3);
        let m = measure(&base, &[effect], &model(measurement));
        let outcome = run(&base, &m, &mut CpuEngine, &options);
        let d = &outcome.diagnosis;
        let (h, sigma) = accepted(&outcome, "centre_height")[0];
        let axis = d.registration.axis_x_mm * 1e3;
        let axis_sigma = d.registration.axis_x_sigma_mm * 1e3;
        println!(
            "truth {truth_um} µm at {axis_um} µm: {h:.3} ± {sigma:.3} µm, axis {axis:.2} ± {axis_sigma:.2} µm"
        );
        // The sign (cone or boss) and the size within 2 %, the truth within 2σ; the axis
        // within a micrometre (a fifth of the boss or cone's radius), inside its 2σ plus
        // the synthesis's point spacing.
        assert!(
            (h - truth_um).abs() < 0.02 * truth_um.abs(),
            "{h} µm for {truth_um}"
        );
        assert!(
            (h - truth_um).abs() <= 2.0 * sigma,
            "{h} ± {sigma} µm for {truth_um}"
        );
        assert!((axis - axis_um).abs() < 1.0, "axis {axis} µm for {axis_um}");
        assert!(
            (axis - axis_um).abs() <= 2.0 * axis_sigma + 0.5,
            "axis {axis} ± {axis_sigma} µm"
        );
        assert_residual_shrinks_fivefold(d, "centre_height");
    }
}

#[test]
fn spring_back_threshold_is_fitted_where_its_share_trades_with_it() {
    // The suite's case 084 on its own grid (0.5 µm rings: the ploughed flanks are a few
    // µm wide): h_min 40 nm, ρ 0.9, through synth's section model (not the forward
    // model). A higher share with a lower threshold raises a cusp alike; fitted from one
    // share the threshold stopped at 34.7 nm on 084. The truth is the independent
    // source: the threshold within 10 %. The share is printed, not asserted: here it
    // comes back 0.79 ± 0.04 for 0.9 (the README's open σ cases: the step of ρ·h_min
    // where the chip crosses h_min is placed only to a ring of the forward model).
    let base = base(withheld::TURNING_SPHERE.job);
    let truth = EffectSpec::spring_back(4.0e-5, 0.9);
    let m = measure(&base, &[truth], &model(PROFILE));
    let options = Options {
        only: vec!["spring_back".into()],
        ..Options::default()
    };
    let outcome = run(&base, &m, &mut CpuEngine, &options);
    let fit = outcome
        .diagnosis
        .candidates
        .iter()
        .find(|c| c.effect == "spring_back")
        .expect("spring-back fitted");
    let [h_min, share] = [&fit.parameters[0], &fit.parameters[1]];
    println!(
        "h_min {:.2} ± {:.2} nm, ρ {:.3} ± {:.3}{}; explains {:.1} %; {}",
        h_min.value,
        h_min.sigma,
        share.value,
        share.sigma,
        if share.at_bound {
            " (at its bound)"
        } else {
            ""
        },
        100.0 * fit.explained,
        outcome.diagnosis.verdict.sentence
    );
    assert!((h_min.value - 40.0).abs() < 4.0, "h_min {} nm", h_min.value);
}

/// The withheld suite's case 094 as drawn: the suite's sphere on its 0.5 µm rings, a
/// stylus line through the axis with its mount, noise and dropouts.
const CASE_094_LINE: &str = r#"kind = "profile"
spacing_um = 1.0
stylus_tip_um = 2.0
tilt_urad = [-59.92893322241063, 0.0]
piston_um = -3.4561633608253146
decentre_um = [11.918132987611049, 0.0]
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
dropout_run = 4.0
seed = 94
"#;

/// Two edge-waviness orders (20 at 40 nm, 45 at 24.2 nm) on the sphere, whose measured
/// edge spans 0.6 and 1.3 of their cycles: the suite's case 094. One order beside an X
/// decentre (its cone standing in for the low order's bend) explains the data to the
/// noise; so do two orders. The decentre must not be claimed: either the two orders
/// are found, or the verdict says the explanations cannot be told apart, or that
/// nothing modelled explains the gap. (Before: "the tool stops 0.558 ± 0.023 µm short
/// of the axis" beside order 50.5. On 1 µm rings with another draw both orders are
/// found, before and now. Since vibrations slower than two cycles across the data are
/// no longer tried, no near-DC vibration's pair ties the decentre's: the verdict is
/// `unexplained_residual`, nothing claimed.)
#[test]
fn two_waviness_orders_are_never_claimed_as_a_decentre_beside_one() {
    let base = base(withheld::TURNING_SPHERE.job);
    let m = measure(
        &base,
        &[
            EffectSpec::edge_waviness(20.0, 4.0e-5, 0.0),
            EffectSpec::edge_waviness(45.0, 2.418677e-5, 60.255),
        ],
        &model(CASE_094_LINE),
    );
    let outcome = run(&base, &m, &mut CpuEngine, &Options::default());
    let d = &outcome.diagnosis;
    println!(
        "{}: {} {:?}",
        d.verdict.status, d.verdict.sentence, d.ambiguous
    );
    for a in &d.accepted {
        assert_eq!(a.effect, "edge_waviness", "{}", d.verdict.sentence);
    }
    assert!(
        ["effects_found", "ambiguous", "unexplained_residual"].contains(&d.verdict.status.as_str()),
        "{}",
        d.verdict.sentence
    );
}

//! Profiles made by code written apart from toolmark (`tests/independent/`: a brute-force
//! section model of an XZ-turned R10 sphere, with the form taken out by a least-squares
//! quadratic as interferometer software does), diagnosed with the README's command
//! (`diagnose --job … --measured … --lateral-unit um --height-unit um --remove-power`).
//!
//! With the form removed, a sphere of R10 over ±0.8 mm keeps only ~5 nm RMS of form, so
//! a set-up error leaves more smooth residual than the form has: such a part is a set-up
//! error to diagnose, not another part (these three came back `does_not_fit` before).
//! The later files (see `tests/data/independent/README.md`) keep the form in, use other
//! spheres, and one is a map (`turned_sphere_map.py`, the same section model per pixel).

use std::path::{Path, PathBuf};
use std::process::Command;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/independent");

/// Runs the README's diagnose command on `profile` (form removed: `--remove-power`) and
/// reads its diagnosis.json.
fn diagnose(profile: &str) -> serde_json::Value {
    diagnose_with(profile, &["--remove-power"])
}

/// Runs the README's diagnose command on `profile` with `extra` options.
fn diagnose_with(profile: &str, extra: &[&str]) -> serde_json::Value {
    diagnose_job("r10_sphere.toml", profile, extra)
}

/// Runs the README's diagnose command with `job` on `profile` with `extra` options.
fn diagnose_job(job: &str, profile: &str, extra: &[&str]) -> serde_json::Value {
    let job = Path::new(DATA).join(job);
    let head = ["diagnose".as_ref(), "--job".as_ref(), job.as_os_str()];
    let d = toolmark_json(&head, profile, extra, profile, &[]);
    assert_claims_stand_clear(&d);
    d
}

/// Runs toolmark's `head` arguments on `profile` (µm in the file) with `extra` options
/// and environment `env`, the CPU engine, into a folder named after `tag`; reads its
/// diagnosis.json.
fn toolmark_json(
    head: &[&std::ffi::OsStr],
    profile: &str,
    extra: &[&str],
    tag: &str,
    env: &[(&str, &str)],
) -> serde_json::Value {
    let out: PathBuf = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("independent-{tag}"));
    let _ = std::fs::remove_dir_all(&out);
    let status = Command::new(env!("CARGO_BIN_EXE_toolmark"))
        .args(head)
        .arg("--measured")
        .arg(Path::new(DATA).join(profile))
        .args(["--lateral-unit", "um", "--height-unit", "um"])
        .args(extra)
        .args(["--engine", "cpu", "--out"])
        .arg(&out)
        .envs(env.iter().copied())
        .output()
        .expect("toolmark runs");
    assert!(
        status.status.success(),
        "{profile}: {}",
        String::from_utf8_lossy(&status.stderr)
    );
    let text = std::fs::read_to_string(out.join("diagnosis.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Every accepted effect stands at least 3σ from zero (its parameters together), as
/// reported: a claim is never one its own σ doubts.
fn assert_claims_stand_clear(d: &serde_json::Value) {
    for a in d["accepted"].as_array().unwrap() {
        let z: f64 = a["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| (p["value"].as_f64().unwrap() / p["sigma"].as_f64().unwrap()).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            z > 3.0,
            "{} claimed at {z:.2}σ: {}",
            a["label"],
            d["verdict"]["sentence"]
        );
    }
}

/// The verdict's status, its sentence shown when it is another.
fn assert_status(d: &serde_json::Value, status: &str) {
    assert_eq!(
        d["verdict"]["status"], status,
        "{}",
        d["verdict"]["sentence"]
    );
}

/// The accepted effect's first parameter (value, σ), after checking it is the only one.
fn accepted(d: &serde_json::Value, effect: &str) -> (f64, f64) {
    let accepted = d["accepted"].as_array().unwrap();
    let names: Vec<&str> = accepted
        .iter()
        .map(|a| a["effect"].as_str().unwrap())
        .collect();
    assert_eq!(names, [effect], "verdict: {}", d["verdict"]["sentence"]);
    first_parameter(&accepted[0])
}

/// An effect's first parameter as reported: (value, σ).
fn first_parameter(effect: &serde_json::Value) -> (f64, f64) {
    let p = &effect["parameters"][0];
    (p["value"].as_f64().unwrap(), p["sigma"].as_f64().unwrap())
}

/// Where the generator put the axis (file x, mm): the diagnosis must find it within
/// 20 µm (the bound); it finds it within a micrometre.
/// The reported axis and its σ (the file's own x, mm).
fn axis_and_sigma(d: &serde_json::Value) -> (f64, f64) {
    let r = &d["registration"];
    (
        r["axis_x_mm"].as_f64().unwrap(),
        r["axis_x_sigma_mm"].as_f64().unwrap(),
    )
}

/// The reported lateral scale and its σ.
fn scale_and_sigma(d: &serde_json::Value) -> (f64, f64) {
    let r = &d["registration"];
    (
        r["lateral_scale"].as_f64().unwrap(),
        r["lateral_scale_sigma"].as_f64().unwrap(),
    )
}

/// Nothing accepted.
fn assert_none_accepted(d: &serde_json::Value) {
    assert!(
        d["accepted"].as_array().unwrap().is_empty(),
        "verdict: {}",
        d["verdict"]["sentence"]
    );
}

/// Nothing accepted, and the verdict says so with `status`.
fn assert_nothing_claimed(d: &serde_json::Value, status: &str) {
    assert_status(d, status);
    assert_none_accepted(d);
}

/// A fit-check finding whose message holds `fragment`; `what` says what it shows.
fn assert_finding(d: &serde_json::Value, fragment: &str, what: &str) {
    let findings = d["fit_check"]["findings"].as_array().unwrap();
    assert!(
        findings
            .iter()
            .any(|f| f["message"].as_str().unwrap().contains(fragment)),
        "{what}: {findings:?}"
    );
}

fn assert_axis(d: &serde_json::Value, file_x_mm: f64) {
    let (axis, _) = axis_and_sigma(d);
    assert!(
        (axis - file_x_mm).abs() < 1e-3,
        "axis at {axis} mm, planted {file_x_mm}"
    );
}

/// The truth within 2σ of the fit (σ at least 0.5 % of it: the independent model and
/// toolmark's agree to 0.06 nm RMS with a decentre, not to the last bit) and within 10 %.
fn assert_sized(fit: (f64, f64), truth: f64) {
    let (value, sigma) = fit;
    let error = (value - truth).abs();
    assert!(
        error <= 2.0 * sigma.max(0.005 * truth.abs()),
        "{value} ± {sigma} for {truth}"
    );
    assert!(error <= 0.1 * truth.abs(), "{value} for {truth}");
}

#[test]
fn a_decentre_on_a_form_removed_profile_is_found_not_refused() {
    let d = diagnose("decentre_2um_form_removed.csv");
    assert_status(&d, "effects_found");
    // The generator's +2 µm: the tool stops short of the axis.
    assert_sized(accepted(&d, "x_decentre"), 2.0);
    assert_axis(&d, 0.137);
    assert_finding(
        &d,
        "set-up error",
        "the departure from the form is said to be a set-up error",
    );
}

#[test]
fn a_centre_height_boss_on_a_form_removed_profile_is_found_not_refused() {
    let d = diagnose("centre_height_-3um_form_removed.csv");
    assert_status(&d, "effects_found");
    // Only the boss, known to its edge's gap between two points, not to 10 %.
    accepted(&d, "centre_height");
    assert_boss(&d, -3.0);
    assert_axis(&d, -0.085);
}

#[test]
fn a_clean_form_removed_profile_shows_no_effect() {
    let d = diagnose("control_form_removed.csv");
    assert_nothing_claimed(&d, "no_effect_beyond_noise");
    assert_axis(&d, 0.042);
}

/// The accepted effect `effect` (a job-file name) among others.
fn accepted_effect<'d>(d: &'d serde_json::Value, effect: &str) -> &'d serde_json::Value {
    d["accepted"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["effect"] == effect)
        .unwrap_or_else(|| panic!("no {effect}: {}", d["verdict"]["sentence"]))
}

/// The accepted edge waviness: (order, amplitude nm, σ of the amplitude nm).
fn waviness(d: &serde_json::Value) -> (f64, f64, f64) {
    let w = accepted_effect(d, "edge_waviness");
    let p = |i: usize| {
        let q = &w["parameters"][i];
        (q["value"].as_f64().unwrap(), q["sigma"].as_f64().unwrap())
    };
    let ((a, sa), (b, sb)) = (p(0), p(1));
    let amplitude = a.hypot(b);
    // The σ along the amplitude (the cos/sin σs projected on the pair's direction).
    let sigma = ((a * sa).powi(2) + (b * sb).powi(2)).sqrt() / amplitude;
    (w["order"].as_f64().unwrap(), amplitude, sigma)
}

/// Form left in, order 20 and 40 nm planted (`waviness_o20_40nm.csv`). The harmonic
/// spans under half a cycle each side of the axis, so a lateral scale (power on a
/// sphere) takes its quadratic part and the order and amplitude trade along A·k⁴: the
/// data pin them to ±0.44 orders and ±3.5 nm. This draw's own maximum-likelihood
/// estimate, from `tests/independent/fit_waviness_profile.py` (the generator as the
/// model, Gauss–Newton, not toolmark): order 19.30 ± 0.44, 46.87 ± 3.50 nm, scale
/// +63 ± 29 ppm. toolmark must land on that estimate, and its σ must be the data's.
/// (Before: order 28.5, 14.4 ± 1.8 nm — the scale held a lower order's power, and the
/// order's re-fit stopped at its bracket's end.)
#[test]
fn an_edge_waviness_with_the_form_in_is_found_where_its_own_noise_puts_it() {
    let d = diagnose_with("waviness_o20_40nm.csv", &[]);
    assert_status(&d, "effects_found");
    let (order, amplitude, sigma) = waviness(&d);
    assert!((order / 20.0 - 1.0).abs() <= 0.05, "order {order} for 20");
    assert!(
        (order - 19.30).abs() <= 2.0 * 0.44,
        "order {order}, oracle 19.30"
    );
    assert!(
        (amplitude - 46.87).abs() <= 3.50,
        "{amplitude} nm, oracle 46.87 ± 3.50"
    );
    assert!(
        (0.5 * 3.50..=2.0 * 3.50).contains(&sigma),
        "σ {sigma} nm, oracle 3.50"
    );
    assert_axis(&d, 0.137);
}

/// Form left in, a centre height of −2 µm (a boss) and edge waviness order 30, 30 nm
/// (`centre_height_-2um_waviness_o30_30nm.csv`). Alone, the centre height explains
/// 98.5 % of the residual; its σ is its boss's edge (the profile across the step, not a
/// finite difference, which the waviness left correlated over ~800 points once inflated
/// to "within 3σ of zero"), and the waviness is found beside it. (Before that:
/// `unexplained_residual`, the axis one mark off.)
#[test]
fn a_boss_beside_an_edge_waviness_is_found_as_the_pair() {
    let d = diagnose_with("centre_height_-2um_waviness_o30_30nm.csv", &[]);
    assert_status(&d, "effects_found");
    assert_boss(&d, -2.0);
    let (order, amplitude, a_sigma) = waviness(&d);
    assert!((order / 30.0 - 1.0).abs() <= 0.05, "order {order} for 30");
    assert!(
        (amplitude / 30.0 - 1.0).abs() <= 0.1,
        "{amplitude} nm for 30"
    );
    assert!(
        (amplitude - 30.0).abs() <= 2.0 * a_sigma,
        "{amplitude} ± {a_sigma} nm for 30"
    );
    assert_axis(&d, 0.137);
}

/// The same boss beside a weaker waviness, order 30, 20 nm
/// (`centre_height_-2um_waviness_o30_20nm.csv`). This draw's own estimate, from
/// `tests/independent/fit_waviness_profile.py --order 30 --cos-nm 20 --h-um -2
/// --exclude-um 3` (the generator as the model, the boss held at its −2 µm and the points
/// within 3 µm of the axis left out): order 28.80 ± 0.69, 21.94 ± 1.27 nm (sin −0.58 ±
/// 0.33). toolmark must land on it with the data's σ. Before: `unexplained_residual` —
/// the boss's σ, read from a finite difference across its step, came out 24 µm (the step
/// moved no sample); with that mended, the order screen (its span of edge angles
/// stretched by the boss's steep wall) tried three peaks of one harmonic, 47–52, and the
/// order's golden section stayed in that basin: order 46.9 at 9.3 nm, where order 30
/// leaves 22 % less Σr².
#[test]
fn a_boss_beside_a_weaker_waviness_is_found_with_it_at_its_own_order() {
    let d = diagnose_with("centre_height_-2um_waviness_o30_20nm.csv", &[]);
    assert_status(&d, "effects_found");
    assert_boss(&d, -2.0);
    let (order, amplitude, sigma) = waviness(&d);
    assert!(
        (order - 28.80).abs() <= 2.0 * 0.69,
        "order {order}, oracle 28.80 ± 0.69"
    );
    assert!(
        (amplitude - 21.95).abs() <= 2.0 * 1.27,
        "{amplitude} nm, oracle 21.95 ± 1.27"
    );
    assert!(
        (0.5 * 1.27..=2.0 * 1.27).contains(&sigma),
        "σ {sigma} nm, oracle 1.27"
    );
    assert_axis(&d, 0.137);
}

/// Form left in, a −1 µm boss beside an edge waviness of order 25, 20 nm, the axis at
/// file x 0.600 mm (`centre_height_-1um_waviness_o25_20nm.csv`). The boss leaves 3.9 nm
/// RMS over 2.0 nm of white noise (1.9×, under the 2× at which every candidate is tried
/// beside a boss); a feed vibration of about one cycle over the trace imitates the
/// waviness, and was accepted as a proxy when that ratio was lowered (see the data's
/// README). The boss must be found and nothing false claimed: anything accepted beside
/// it is the planted waviness.
#[test]
fn a_boss_beside_a_waviness_near_the_noise_claims_no_proxy() {
    let d = diagnose_with("centre_height_-1um_waviness_o25_20nm.csv", &[]);
    assert_status(&d, "effects_found");
    assert_boss(&d, -1.0);
    assert_axis(&d, 0.600);
    // The boss alone leaves 3.9 nm RMS over 2.0 nm of noise: the verdict says so.
    let sentence = d["verdict"]["sentence"].as_str().unwrap();
    if d["accepted"].as_array().unwrap().len() == 1 {
        assert!(
            sentence.contains("× the noise") && sentence.contains("something weaker may remain"),
            "{sentence}"
        );
    }
    for a in d["accepted"].as_array().unwrap() {
        match a["effect"].as_str().unwrap() {
            "centre_height" => {}
            "edge_waviness" => {
                let (order, amplitude, sigma) = waviness(&d);
                assert!((order - 25.0).abs() <= 0.25 * 25.0, "order {order} for 25");
                assert!(
                    (amplitude - 20.0).abs() <= (2.0 * sigma).max(5.0),
                    "{amplitude} ± {sigma} nm for 20"
                );
            }
            other => panic!("{other} claimed: {sentence}"),
        }
    }
}

/// A control on another sphere (`r6_sphere.toml`: R6, 0.4 mm nose, 8 µm/rev), the axis at
/// file x 0.050 mm (`control_r6_axis_50um.csv`). The placement lands a comb tooth (200 µm)
/// off with a lateral scale, and the fit moves the axis back and stretches the line: the
/// axis must be reported where the fit puts it, in the file's own x, within 2σ of the
/// truth (σ ≥ 1 nm). Before: 146 nm off at ± 5.2 nm — the fit's stretch left out of the
/// conversion to the file's x.
#[test]
fn an_axis_moved_by_the_fit_is_reported_in_the_files_own_x() {
    let d = diagnose_job("r6_sphere.toml", "control_r6_axis_50um.csv", &[]);
    assert_status(&d, "no_effect_beyond_noise");
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis - 0.050).abs() <= 2.0 * sigma.max(1e-6),
        "axis at {axis} ± {sigma} mm, planted 0.050"
    );
    let (scale, scale_sigma) = scale_and_sigma(&d);
    assert!(
        (scale - 1.0).abs() <= 2.0 * scale_sigma,
        "scale {scale} ± {scale_sigma}, planted 1"
    );
}

/// `d` accepts a centre height of `height` µm: its boss's edge lies between two points
/// 0.5 µm apart, so it is known to that, and its σ says so.
fn assert_boss(d: &serde_json::Value, height: f64) {
    let (value, sigma) = first_parameter(accepted_effect(d, "centre_height"));
    assert!(
        (value - height).abs() <= 0.5,
        "{value} ± {sigma} for {height}"
    );
    assert!(
        (value - height).abs() <= 2.0 * sigma,
        "{value} ± {sigma} for {height}"
    );
}

/// Form left in, an X decentre of +2 µm (the tool stops short of the axis) beside an
/// axial drift of +200 nm (away from the part), over ±1.45 mm with 1.5 nm of noise
/// (`decentre_2um_drift_200nm.csv`). On a sphere both leave a cone in r; only the marks'
/// phase and the rings at the axis tell them apart, and here they do not: either alone
/// leaves the noise (1.49 nm RMS). Before, the decentre was claimed alone as
/// 0.6701 ± 0.0029 µm — the cone of both, 460σ from its truth. A claimed effect must
/// now cover its truth within 2σ (its σ carries the look-alike it could be traded
/// for); otherwise the verdict says the two cannot be told apart.
#[test]
fn a_decentre_beside_a_drift_is_not_sized_as_either_alone() {
    let d = diagnose_with("decentre_2um_drift_200nm.csv", &[]);
    assert_pair_not_sized_alone(&d, 2.0, 200.0);
    assert_axis(&d, 0.137);
}

/// Form removed, an X decentre of −3.59 µm (the tool runs past the axis) beside an
/// axial drift of +337 nm, on an R12 sphere (0.8 mm nose, 3 µm/rev, a diameter of
/// 0.5 µm points, the axis at file x 0.550 mm, 0.5 nm of noise; random-batch draw y09,
/// `decentre_-3.59um_drift_337nm_r12_nose08_feed3_form_removed.csv`). Past the axis the
/// decentre leaves no boss, and the two cones trade along a valley flat to Δχ² ≈ 2 from
/// the decentre alone at −6.18 µm to the truth and beyond; the decentre was claimed
/// alone as −6.18 ± 0.21 µm (12σ from the truth): the linearised σ beside the drift,
/// from finite differences of the sampled marks, saw the valley closed. The drift is
/// now stepped along its profile with the rest re-fitted, and the decentre's σ carries
/// how far it moves there.
#[test]
fn a_decentre_past_the_axis_beside_a_drift_is_not_sized_as_either_alone() {
    let d = diagnose_job(
        "r12_nose08_feed3_sphere.toml",
        "decentre_-3.59um_drift_337nm_r12_nose08_feed3_form_removed.csv",
        &["--remove-power"],
    );
    assert_pair_not_sized_alone(&d, -3.59, 337.0);
    assert_axis(&d, 0.550);
}

/// Form left in, an X decentre of −1.81 µm (past the axis) beside an axial drift of
/// +180 nm on an R28 sphere (0.3 mm nose, 12 µm/rev, 1 µm points, 0.5 nm of noise, the
/// axis at file x 0.418 mm; random-batch draw k10,
/// `decentre_-1.81um_drift_180nm_r28_nose03_feed12.csv`). The cones trade: +1.64 µm
/// beside 346 nm leaves the same 0.57 nm RMS as the truth, and only the rings at the
/// axis (a boss short of it, none past it) prefer the truth, by ΔBIC 48. The greedy
/// search settled on the mirror — "the tool stops 1.64 ± 0.12 µm short of the axis",
/// 29σ and the wrong way: a correction that doubles the error. The mirror check
/// started the decentre at −1.64 µm beside the 346 nm drift, which pulled it straight
/// back; now each member is held at its mirror while its partners re-size, then all
/// are freed, and a better basin replaces the accepted one. The drift is held to 5 %,
/// not to its σ: the generator spreads it over its own revolutions (from its rim, plus
/// one at the axis), toolmark over the job's path, and the two counts differ by ~2 %.
#[test]
fn a_decentre_beside_a_drift_is_not_claimed_on_the_wrong_side_of_the_axis() {
    let d = diagnose_job(
        "r28_nose03_feed12_sphere.toml",
        "decentre_-1.81um_drift_180nm_r28_nose03_feed12.csv",
        &["--remove-power"],
    );
    assert_pair_found(&d, -1.81, 180.0);
    assert_axis(&d, 0.418);
}

/// Form left in, an X decentre of +3.67 µm (short of the axis: a boss) beside an axial
/// drift of −455 nm on an R16 sphere (0.5 mm nose, 2 µm/rev, 1 µm points, 0.5 nm of
/// noise, the axis at file x 0.482 mm; random-batch draw m02,
/// `decentre_3.67um_drift_-455nm_r16_nose05_feed2.csv`). The drift alone takes the
/// cones (−704.6 ± 1.4 nm, leaving 0.72 nm RMS); the decentre beside it, fitted at
/// 3.67 µm, predicted three folds (shares 0.7–1.6) and was refused by the fourth, the
/// outer half, whose predicted change is small beside its noise (chi2 ≈ 7.7, a right
/// prediction's share scattering ±0.72 about 1) and showed a tenth of it. The drift
/// was claimed alone, 183σ from its truth. A fold now refutes only a share 2σ of its
/// noise short of 1 (and under 0.3).
#[test]
fn a_decentre_is_not_refused_by_a_fold_its_noise_cannot_judge() {
    let d = diagnose_job(
        "r16_nose05_feed2_d216_sphere.toml",
        "decentre_3.67um_drift_-455nm_r16_nose05_feed2.csv",
        &["--remove-power"],
    );
    assert_pair_found(&d, 3.67, -455.0);
    assert_axis(&d, 0.482);
}

/// Form left in, an X decentre of +0.95 µm alone on an R22 sphere (0.2 mm nose,
/// 5 µm/rev, 1 µm points, 3 nm of noise over 16 nm marks, the axis at file x
/// −0.096 mm; random-batch draw a04, `decentre_0.95um_r22_nose02_feed5_noise3nm.csv`).
/// A drift alone ties with it, and the axis σ of a tie is widened to reach the tied
/// explanation's axis; the drift of that tie, fitted from the decentre's frame without
/// the decentre, stopped on a far tooth of the axis comb (0.54 mm away, worse than the
/// drift's own fit), so the axis was reported ± 537 µm. The tie's set is now fitted
/// again from where its look-alike's own fit placed the axis, and the better kept.
#[test]
fn a_tie_does_not_widen_the_axis_to_a_fit_that_stopped_on_a_far_tooth() {
    let d = diagnose_job(
        "r22_nose02_feed5_sphere.toml",
        "decentre_0.95um_r22_nose02_feed5_noise3nm.csv",
        &["--remove-power"],
    );
    assert_pair_not_sized_alone(&d, 0.95, 0.0);
    assert_axis(&d, -0.096);
    let (_, sigma) = axis_and_sigma(&d);
    // Within the marks' reach: a tie moves the axis by at most a few marks (5 µm each).
    assert!(sigma < 0.02, "axis σ {} µm", sigma * 1e3);
}

/// Form left in, an edge waviness of order 36, 19 nm, on an R22 sphere (0.3 mm nose,
/// 5 µm/rev, 1 µm points — five a mark, too few for the placement to use the marks —
/// 1 nm of noise, the axis at file x −0.159 mm; random-batch draw c02,
/// `waviness_o36_19nm_r22_nose03_feed5.csv`). The waviness is found, the axis half a
/// mark off with the line read half a turn round: on a spiral of even feed the marks
/// repeat so, and only the few points at the axis could tell. The axis σ was 4 nm
/// (629σ): the fits' comb had no mirrored teeth. Its σ now reads every tooth both ways.
#[test]
fn an_axis_half_a_mark_off_half_a_turn_round_is_within_its_sigma() {
    let d = diagnose_job(
        "r22_nose03_feed5_sphere.toml",
        "waviness_o36_19nm_r22_nose03_feed5.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis + 0.159).abs() <= 2.0 * sigma && sigma < 0.01,
        "axis {axis} ± {sigma} mm, planted −0.159"
    );
}

/// Form left in, an X decentre of +3.14 µm (short of the axis: a boss) beside an axial
/// drift of +214 nm on an R9 sphere (0.2 mm nose, 8 µm/rev, 0.25 µm points, 2 nm of
/// noise, the axis at file x −0.017 mm; random-batch draw c06,
/// `decentre_3.14um_drift_214nm_r9_nose02_feed8.csv`). The decentre alone (+1.26 µm)
/// settled half a mark off with the line half a turn round; the drift fitted beside it
/// from there kept that alias (the comb picks the best tooth for each trial's values),
/// and the verdict was `ambiguous`. A round's best one-parameter partners are now also
/// fitted with the axis held at that alias, then freed; and two tied singles both held
/// by the accepted set no longer withdraw it.
#[test]
#[allow(clippy::approx_constant)] // 3.14 µm is the planted decentre, not π
fn a_decentre_and_a_drift_are_found_across_the_spirals_half_turn_alias() {
    let d = diagnose_job(
        "r9_nose02_feed8_sphere.toml",
        "decentre_3.14um_drift_214nm_r9_nose02_feed8.csv",
        &["--remove-power"],
    );
    assert_pair_found(&d, 3.14, 214.0);
    assert_axis(&d, -0.017);
}

/// A planted decentre (µm) + drift (nm) pair found as the pair: the decentre sized
/// ([`assert_sized`]), the drift within 5 % (the generator spreads it over its own
/// revolutions, toolmark over the job's path: ~2 % apart).
fn assert_pair_found(d: &serde_json::Value, decentre_um: f64, drift_nm: f64) {
    assert_status(d, "effects_found");
    assert_sized(
        first_parameter(accepted_effect(d, "x_decentre")),
        decentre_um,
    );
    let (drift, _) = first_parameter(accepted_effect(d, "axial_drift"));
    assert!(
        (drift - drift_nm).abs() <= 0.05 * drift_nm.abs(),
        "drift {drift} nm for {drift_nm}"
    );
}

/// Whatever of a planted decentre (µm) + drift (nm) pair is claimed covers its truth
/// within 2σ, and nothing else is claimed; where the verdict is `ambiguous`, the two
/// are what it cannot tell apart.
fn assert_pair_not_sized_alone(d: &serde_json::Value, decentre_um: f64, drift_nm: f64) {
    for a in d["accepted"].as_array().unwrap() {
        let (value, sigma) = first_parameter(a);
        let truth = match a["effect"].as_str().unwrap() {
            "x_decentre" => decentre_um,
            "axial_drift" => drift_nm,
            other => panic!("{other} claimed: {}", d["verdict"]["sentence"]),
        };
        assert!(
            (value - truth).abs() <= 2.0 * sigma,
            "{value} ± {sigma} for {truth}: {}",
            d["verdict"]["sentence"]
        );
    }
    if d["verdict"]["status"] == "ambiguous" {
        let tied: Vec<&str> = d["ambiguous"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a.as_str().unwrap())
            .collect();
        assert!(
            tied.contains(&"x decentre") && tied.contains(&"axial drift"),
            "{tied:?}"
        );
        // What each would correct, and what tells the two apart at the machine.
        let sentence = d["verdict"]["sentence"].as_str().unwrap();
        assert!(sentence.contains("Fitted alone: "), "{sentence}");
        let advice = d["verdict"]["advice"][0].as_str().unwrap();
        assert!(advice.contains("another feed per revolution"), "{advice}");
    } else {
        assert_status(d, "effects_found");
    }
}

/// The first failure, on the independent generator's R5 sphere (0.2 mm nose,
/// 2 µm/rev, form in): a centre height of −5 µm came back +14.97 ± 0.22 µm (the scan
/// started at zero and grew one way). Found below centre, sized to its boss's edge
/// (the point spacing), the axis where the generator put it.
#[test]
fn an_r5_boss_of_5um_is_found_below_centre() {
    let d = diagnose_job("r5_sphere.toml", "centre_height_-5um_r5.csv", &[]);
    assert_status(&d, "effects_found");
    accepted(&d, "centre_height");
    assert_boss(&d, -5.0);
    assert_axis(&d, 0.137);
}

/// The second failure, on the independent generator's R20 sphere (0.5 mm
/// nose, 8 µm/rev, WLI-like 0.5 µm pixels, form in): +5 µm above centre (the flank
/// sweeping the core: a cone) was never found, the axis placed a mark off with a tilt
/// instead. Found within 2σ and 10 %, the axis within a micrometre.
#[test]
fn an_r20_cone_of_5um_is_found_above_centre() {
    let d = diagnose_job("r20_sphere.toml", "centre_height_+5um_r20_cone.csv", &[]);
    assert_status(&d, "effects_found");
    assert_sized(accepted(&d, "centre_height"), 5.0);
    assert_axis(&d, 0.137);
}

/// A radius that misses the axis by 50 µm (the R20 sphere's trace from file x
/// 0.187 mm, the axis at 0.137 mm; +4 µm above centre, its cone not in the data): the
/// form's far reach and the marks' comb place the axis. Placed within the issue's
/// 20 µm, nothing claimed, and the σ a placement (finite, under 50 µm). Known gap, not
/// asserted: the truth lies 3.0σ off (0.1513 ± 0.0047 mm with the halves' disagreement;
/// 5.7σ at ± 0.0025 mm before it).
#[test]
fn a_radius_missing_the_axis_is_placed_within_20um() {
    let d = diagnose_job(
        "r20_sphere.toml",
        "centre_height_+4um_r20_radius_off_axis.csv",
        &[],
    );
    assert_status(&d, "no_effect_beyond_noise");
    let r = &d["registration"];
    assert_eq!(r["trace"], "radius");
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis - 0.137).abs() < 0.020 && sigma.is_finite() && sigma < 0.050,
        "axis {axis} ± {sigma} mm, planted 0.137"
    );
}

/// An R22 sphere turned at 2 µm/rev with a 0.8 mm nose (marks 0.6 nm deep) measured
/// at 0.25 µm under 3 nm of noise, form removed, +2.5 µm above centre (its cone
/// 441 nm high), the axis at file x −0.040 mm (`centre_height_+2.5um_r22_marks_in_noise.csv`,
/// job `r22_sphere.toml`). Neither marks nor form can place it: the search had matched
/// the noise with marks, put the axis 0.5 mm off at a lateral scale of 0.994, and found
/// nothing (`unexplained_residual`). Marks that would not stand out of the noise place
/// nothing now, and the compact feature does: found within 2σ and 10 %, the axis within
/// a micrometre, the scale not fitted.
#[test]
fn a_cone_whose_marks_sink_into_the_noise_is_placed_by_the_cone() {
    let d = diagnose_job(
        "r22_sphere.toml",
        "centre_height_+2.5um_r22_marks_in_noise.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    assert_sized(accepted(&d, "centre_height"), 2.5);
    assert_axis(&d, -0.040);
    assert_eq!(d["registration"]["lateral_scale_fitted"], false);
}

/// A −2.38 µm boss on an R5 sphere (0.8 mm nose, 12 µm/rev, form removed, 0.5 nm
/// noise; `centre_height_-2.38um_r5_feed12_form_removed.csv`, job `r5_nose08_sphere.toml`,
/// the axis at file x 0.010 mm). Two faults had refused it: the fit stopped where it
/// started in the spiral's azimuth (the boss height's finite difference, a step
/// crossing a point, spoiled every joint step: 3.5 nm RMS left, 0.5 nm is the noise),
/// and the outer half in radius, where a boss changes nothing, "judged" it on the
/// placement's pull alone (9 % of a predicted change). Found now with the noise left,
/// and the axis within 2σ of its truth (its σ no longer a sub-nanometre figure from the
/// boss's steps: 0.4 nm for 7.7 nm on another draw).
#[test]
fn a_boss_on_a_form_removed_profile_is_fitted_to_the_noise_and_accepted() {
    let d = diagnose_job(
        "r5_nose08_sphere.toml",
        "centre_height_-2.38um_r5_feed12_form_removed.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    assert_boss(&d, -2.38);
    let left = d["residual_after"]["rms_nm"].as_f64().unwrap();
    assert!(left < 1.0, "{left} nm RMS left (noise 0.5 nm)");
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis - 0.010).abs() <= 2.0 * sigma,
        "axis at {axis} ± {sigma} mm, planted 0.010"
    );
}

/// A decentre of about a quarter feed on a diameter (R5, 0.5 mm nose, 8 µm/rev, form in,
/// 0.5 nm noise, the axis at file x 0.113 mm; `decentre_2.11um_r5_feed8_diameter.csv`, job
/// `r5_feed8_sphere.toml`, the fourth random batch's case s10 at 0.5 µm points). The job
/// as given places a diameter's marks alike at an azimuth and half a turn from it; the
/// decentre's fit started from the first and stopped there, leaving 4.0 nm RMS at the
/// axis that a spring-back was then accepted for (a false second claim). Its scan now
/// starts from both: the decentre alone, within 2σ and 10 %, the noise left.
#[test]
fn a_decentre_on_a_diameter_is_fitted_half_a_turn_round_where_it_lies() {
    let d = diagnose_job(
        "r5_feed8_sphere.toml",
        "decentre_2.11um_r5_feed8_diameter.csv",
        &["--remove-power"],
    );
    assert_decentre_alone(&d, 2.11, 0.75, 0.113);
}

/// The decentre alone within 2σ and 10 % of `truth` (µm), under `left_nm` RMS left (the
/// noise is 0.5 nm), the axis where the generator put it (file x, mm).
fn assert_decentre_alone(d: &serde_json::Value, truth: f64, left_nm: f64, axis_mm: f64) {
    assert_status(d, "effects_found");
    assert_sized(accepted(d, "x_decentre"), truth);
    let left = d["residual_after"]["rms_nm"].as_f64().unwrap();
    assert!(left < left_nm, "{left} nm RMS left (noise 0.5 nm)");
    assert_axis(d, axis_mm);
}

/// A +1.11 µm decentre on an R28 sphere, 0.8 mm nose, 5 µm/rev, a diameter at 1 µm
/// points (random-batch draw u02). An edge waviness of order 50.9 — a third of a cycle
/// over the 2° of edge the part's slopes use: a bend — leaves the decentre's print;
/// fitted beside it, its linear σ widened the decentre's to 0.57 µm (1.9σ) and the
/// look-alike alone was kept as an equal explanation (`ambiguous`, nothing claimed),
/// though alone it explains the data far worse (ΔBIC −718). A look-alike refuted alone
/// now widens the σ by the move it makes: the decentre alone, within 2σ and 10 %, the
/// noise left.
#[test]
fn a_decentre_on_a_long_radius_is_not_taken_for_a_bend_of_the_edge() {
    let d = diagnose_job(
        "r28_nose08_sphere.toml",
        "decentre_1.11um_r28_nose08_diameter.csv",
        &["--remove-power"],
    );
    assert_decentre_alone(&d, 1.11, 0.6, 0.103);
}

/// A 25 × 25 map of 100 µm pixels whose field reaches past the part's rim (corners
/// 1.7 mm from the middle of a Ø3 mm part; `wide_map_control.csv`, nothing planted,
/// the axis at file (1.237, 1.177) mm). The axis search had judged every shift on 98 %
/// of all the points, found none keeping them, and returned a corner of its grid
/// (`does_not_fit`). Now it keeps 98 % of what its best-covered shift keeps: placed
/// within a micrometre, nothing claimed.
#[test]
fn a_map_reaching_past_the_part_is_placed_not_refused() {
    let d = diagnose_with("wide_map_control.csv", &["--pixel-um", "100"]);
    assert_status(&d, "no_effect_beyond_noise");
    assert_map_axis(&d);
}

/// Where the map generator put the axis (file (1.237, 1.177) mm), found within a
/// micrometre on both axes.
fn assert_map_axis(d: &serde_json::Value) {
    assert_axis(d, 1.237);
    let y = d["registration"]["axis_y_mm"].as_f64().unwrap();
    assert!(
        (y - 1.177).abs() < 1e-3,
        "{}: axis y at {y} mm, planted 1.177",
        d["measurement"]["file"]
    );
}

/// The same 25 × 25 map of 100 µm pixels with an X decentre of +2 µm
/// (`decentre_2um_map.csv`) and with an axial drift of −300 nm (`drift_-300nm_map.csv`):
/// both cones, told apart by the aliased marks once the axis is placed to a fraction of
/// a micrometre. Both had come back `ambiguous` (the axis 3–19 µm off; vibrations at
/// 48 or 128 per revolution, constants on the simulation's 16 azimuths, standing in
/// for the cones). Each is now found within 2σ and 10 %, the axis within a micrometre.
#[test]
fn a_decentre_and_a_drift_on_coarse_maps_are_told_apart() {
    for (file, effect, truth) in [
        ("decentre_2um_map.csv", "x_decentre", 2.0),
        ("drift_-300nm_map.csv", "axial_drift", -300.0),
    ] {
        let d = diagnose_with(file, &["--pixel-um", "100"]);
        assert_status(&d, "effects_found");
        assert_sized(accepted(&d, effect), truth);
        assert_map_axis(&d);
    }
}

/// Maps whose point-sampled pixels (25 and 35 µm) alias the 5 µm marks, the axis off the
/// field's middle (`aliased_map_control.csv`: nothing planted, 2 nm of noise, axis at
/// file (0.660, 0.788) mm; `decentre_-1.24um_aliased_map.csv`: an X decentre of
/// −1.24 µm, 0.5 nm of noise, axis at (0.515, 0.802) mm), with the README's
/// `--remove-power`. The aliased marks make the registration's measure a speckle a
/// quarter of a feed across, and a grid over the field refined into a wrong minimum:
/// the control's axis (17, 11) µm off at ± 0.7 µm, the decentre's (15, 14) µm off. The
/// form now places the axis first and the marks pin it near there (the decentre's fit
/// and its placement alternating): each axis within 0.5 µm and within 3σ on both axes;
/// the control clean, the decentre within 2σ and 10 %.
#[test]
fn maps_whose_pixels_alias_the_marks_are_placed_by_form_then_marks() {
    let cases = [
        ("aliased_map_control.csv", "25", [0.660, 0.788], None),
        (
            "decentre_-1.24um_aliased_map.csv",
            "35",
            [0.515, 0.802],
            Some(-1.24),
        ),
    ];
    for (file, pixel_um, axis_mm, decentre_um) in cases {
        let d = diagnose_with(file, &["--pixel-um", pixel_um, "--remove-power"]);
        match decentre_um {
            None => assert_status(&d, "no_effect_beyond_noise"),
            Some(truth) => {
                assert_status(&d, "effects_found");
                assert_sized(accepted(&d, "x_decentre"), truth);
            }
        }
        assert_map_axis_within_its_sigma(&d, axis_mm);
    }
}

/// A map's axis within 0.5 µm and within 3σ of where the generator put it (file mm) on
/// both axes.
fn assert_map_axis_within_its_sigma(d: &serde_json::Value, axis_mm: [f64; 2]) {
    let r = &d["registration"];
    for (axis, truth) in [("x", axis_mm[0]), ("y", axis_mm[1])] {
        let at = r[format!("axis_{axis}_mm")].as_f64().unwrap();
        let sigma = r[format!("axis_{axis}_sigma_mm")].as_f64().unwrap();
        let off = (at - truth).abs();
        assert!(
            off < 5e-4 && off <= 3.0 * sigma,
            "{}: axis {axis} at {at} ± {sigma} mm, planted {truth}",
            d["measurement"]["file"]
        );
    }
}

/// A map whose field reaches past the rim with the axis 270 µm off its middle
/// (`decentre_-1.18um_map_past_the_rim.csv`: 81 × 81 pixels of 35 µm on the Ø3 mm part,
/// an X decentre of −1.18 µm, the axis at file (1.638, 1.522) mm), compared with the
/// planted decentre carried. At the truth 94 % of the best-covered shift's pixels lie on
/// the part, and a registration that admitted only shifts keeping 98 % put the axis
/// 107 µm off. Placed within 0.5 µm (and 3σ) on both axes, the noise (1 nm) left.
#[test]
fn a_map_past_the_rim_with_its_axis_off_the_middle_is_placed_where_the_part_is() {
    let job = Path::new(DATA).join("r10_sphere.toml");
    let planted = Path::new(DATA).join("decentre_-1.18um_planted.toml");
    let d = toolmark_json(
        &["compare-profile".as_ref(), job.as_os_str()],
        "decentre_-1.18um_map_past_the_rim.csv",
        &[
            "--pixel-um",
            "35",
            "--remove-power",
            "--effects",
            planted.to_str().unwrap(),
        ],
        "map-past-the-rim",
        &[],
    );
    assert_map_axis_within_its_sigma(&d, [1.638, 1.522]);
    let left = d["residual_before"]["rms_nm"].as_f64().unwrap();
    assert!(left < 1.2, "{left} nm RMS left, the noise 1 nm");
}

/// Form removed, a +4 µm boss (above centre) beside an edge waviness of order 34, 50 nm
/// (`centre_height_4um_waviness_o34_50nm_form_removed.csv`, a diameter, the axis at file
/// x 0.095 mm). Each alone bends to imitate the other and falls short of the evidence an
/// effect needs (the boss alone ΔBIC 4), so the verdict was `unexplained_residual`; on a
/// finer draw of the same family, `does_not_fit` (the smooth residual beyond the little
/// form left after the power, which no single candidate explained). The boss must be
/// offered a partner and the pair found: the boss within 5 % and 2σ (its cone hung from
/// the real, wavy edge; from the nominal circle it came out 3.935 ± 0.030 µm), the
/// waviness's order within 5 % and its amplitude within 10 % and 3σ of the truth.
#[test]
fn a_boss_beside_a_waviness_on_a_form_removed_profile_is_found_as_the_pair() {
    let d = diagnose("centre_height_4um_waviness_o34_50nm_form_removed.csv");
    assert_status(&d, "effects_found");
    let (boss, sigma) = first_parameter(accepted_effect(&d, "centre_height"));
    assert!(
        (boss / 4.0 - 1.0).abs() <= 0.05 && (boss - 4.0).abs() <= 2.0 * sigma,
        "boss {boss} ± {sigma} µm for 4"
    );
    let (order, amplitude, a_sigma) = waviness(&d);
    assert!((order / 34.0 - 1.0).abs() <= 0.05, "order {order} for 34");
    assert!(
        (amplitude / 50.0 - 1.0).abs() <= 0.1 && (amplitude - 50.0).abs() <= 3.0 * a_sigma,
        "{amplitude} ± {a_sigma} nm for 50"
    );
    assert_axis(&d, 0.095);
}

/// A +3.26 µm boss (above centre: the flank's clearance face trims the core to a cone)
/// beside an edge waviness of order 33, 35 nm, phase 26°
/// (`boss_3.26um_waviness_o33_35nm_r5_nose08.csv`, 1 nm of noise). Compared with both
/// planted effects carried, the job must leave only the noise: the generator hangs the
/// cone from the real, wavy edge (the tool set at its tip); toolmark hung it from the
/// edge's nominal circle, w(0) = 31.5 nm higher — 3.62 nm RMS and 40.6 nm PV left at the
/// axis, and a boss fitted beside a waviness 119σ from its truth. Now 1.02 nm RMS,
/// 5.9 nm PV: asserted within 1.2 nm RMS and 10 nm PV.
#[test]
fn a_boss_above_centre_beside_a_waviness_hangs_its_cone_from_the_real_edge() {
    let job = Path::new(DATA).join("r5_nose08_feed3_sphere.toml");
    let planted = Path::new(DATA).join("boss_3.26um_waviness_o33_35nm_planted.toml");
    let d = toolmark_json(
        &["compare-profile".as_ref(), job.as_os_str()],
        "boss_3.26um_waviness_o33_35nm_r5_nose08.csv",
        &["--remove-power", "--effects", planted.to_str().unwrap()],
        "flank-cone",
        &[],
    );
    let left = &d["residual_before"];
    let (rms, pv) = (
        left["rms_nm"].as_f64().unwrap(),
        left["pv_nm"].as_f64().unwrap(),
    );
    assert!(rms <= 1.2 && pv <= 10.0, "{rms} nm RMS, {pv} nm PV left");
}

/// An edge waviness of order 33, 22 nm on an R9 sphere (0.2 mm nose, 2 µm feed, 1 µm
/// points, 3 nm of noise, form removed: `waviness_o33_22nm_r9_nose02_feed2_form_removed.csv`,
/// random-batch draw w08). Order, amplitude and phase trade along a curved valley here:
/// the fit lands on order 26.9 at 28.8 nm, and the linearised σ of the order, ± 2.1,
/// put the truth 2.9σ off. The order's σ is its profile's (every value re-fitted at each
/// order): the truth must lie within 2σ of the order and of the amplitude, and the
/// order's σ stay under a fifth of the order (a σ that only grows would pass the first).
#[test]
fn a_waviness_order_carries_the_doubt_its_valley_leaves() {
    let d = diagnose_job(
        "r9_nose02_feed2_sphere.toml",
        "waviness_o33_22nm_r9_nose02_feed2_form_removed.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    let w = accepted_effect(&d, "edge_waviness");
    let sigma = w["order_sigma"].as_f64().unwrap();
    let (order, amplitude, a_sigma) = waviness(&d);
    assert!(
        (order - 33.0).abs() <= 2.0 * sigma && sigma <= 0.2 * order,
        "order {order} ± {sigma} for 33"
    );
    assert!(
        (amplitude - 22.0).abs() <= 2.0 * a_sigma,
        "{amplitude} ± {a_sigma} nm for 22"
    );
}

/// The candidates' fits run side by side on the CPU engine (`diagnose::side_by_side`:
/// each worker thread on a copy of the problem with an engine of its own). The same
/// diagnosis must come out on one thread, where they run one after the other, as on two
/// — every value, σ, score and word of `diagnosis.json` but the run's counts and times —
/// here on a pair found together (a boss above centre beside a waviness: the single
/// candidates, the partner round and the waviness order's grid all run side by side).
#[test]
fn the_diagnosis_is_the_same_on_one_thread_as_on_two() {
    let job = Path::new(DATA).join("r5_nose08_feed3_sphere.toml");
    let head = ["diagnose".as_ref(), "--job".as_ref(), job.as_os_str()];
    let profile = "boss_3.26um_waviness_o33_35nm_r5_nose08.csv";
    let run = |threads: &str| {
        let tag = format!("threads-{threads}");
        let env = [("RAYON_NUM_THREADS", threads)];
        let mut d = toolmark_json(&head, profile, &["--remove-power"], &tag, &env);
        d.as_object_mut().unwrap().remove("run");
        d
    };
    let (one, two) = (run("1"), run("2"));
    assert_eq!(one["verdict"]["status"], "effects_found");
    assert!(one == two, "one thread:\n{one}\ntwo threads:\n{two}");
}

/// Form removed, an X decentre of −3.97 µm (past the axis) on an R16 sphere at 2 µm/rev
/// sampled every 1 µm: the marks (1 nm deep) are lost in the 1 nm noise, and the job as
/// given has no cone, so the form placed the axis 364 µm from the truth (file x
/// 0.881 mm). The fits search the axis along a comb over the whole range the placement
/// searched; it had been capped at 400 teeth a quarter feed apart (200 µm a side), and
/// the diagnosis came back `unexplained_residual` with the axis 164 µm off (on the batch
/// draw z07 a vibration and a waviness were claimed instead). Now the comb spans the
/// range: the axis is where the cone's tip is, and the decentre is found or called a
/// look-alike of a drift (the two cones), never anything else.
#[test]
fn a_decentre_whose_marks_are_lost_in_the_noise_is_placed_by_its_cone() {
    let d = diagnose_job(
        "r16_nose05_feed2_sphere.toml",
        "decentre_-3.97um_r16_nose05_feed2_marks_unresolved_form_removed.csv",
        &["--remove-power"],
    );
    assert_axis(&d, 0.881);
    assert_pair_not_sized_alone(&d, -3.97, 0.0);
}

/// On a sphere a nose radius error Δρ moves the marks as a lateral scale 1 + Δρ/R does;
/// beyond power it leaves little else. Where the marks fix the scale, the scale takes
/// the nose error and the verdict names it as what the scale could equally be: nothing
/// is claimed (a stretch claimed as a nose error would spoil the next part), and the
/// note's Δρ = (s − 1)·R is the planted error within 2σ.
fn assert_scale_names_the_nose_error(d: &serde_json::Value, radius_mm: f64, truth_um: f64) {
    assert_none_accepted(d);
    let (scale, sigma) = scale_and_sigma(d);
    let (nose, nose_sigma) = ((scale - 1.0) * radius_mm * 1e3, sigma * radius_mm * 1e3);
    assert!(
        (nose - truth_um).abs() < 2.0 * nose_sigma,
        "scale {scale} ± {sigma}: nose {nose:.2} ± {nose_sigma:.2} µm for {truth_um}"
    );
    assert_finding(d, "--fixed-scale", "the note names the scale's look-alike");
}

/// Form removed, a nose radius 14.8 µm over its 0.2 mm nominal on an R5 sphere, 3 nm RMS
/// of noise, 2 µm marks read four points a mark (random-batch draw z04). The error was
/// claimed (14.41 ± 0.39 µm) while six points a mark were needed for the marks to fix
/// the scale; now they fix it at 1.0028, which is the nose error.
#[test]
fn a_nose_radius_error_on_a_form_removed_profile_is_named_as_the_scale_it_moves_alike() {
    let d = diagnose_job(
        "r5_nose02_feed2_sphere.toml",
        "nose_radius_+14.8um_r5_nose02_feed2_noise3nm_form_removed.csv",
        &["--remove-power"],
    );
    assert_status(&d, "no_effect_beyond_noise");
    assert_scale_names_the_nose_error(&d, 5.0, 14.8);
    assert_axis(&d, -0.193);
}

/// Form in, power removed, a nose radius 8.9 µm under its 0.3 mm nominal on an R5
/// sphere, 60 nm marks under 3 nm of noise (random-batch draw d04). Claimed
/// (−8.87 ± 0.37 µm) while the placement's high-pass lag at the profile's ends held the
/// scale at 1; placed right, the scale comes out 0.9982 and the nose error fitted beside
/// it is −8.5 ± 3.1 µm: the ~2 nm its cusps change cannot pin it apart from the scale.
#[test]
fn a_nose_radius_error_whose_cusps_barely_change_is_named_as_the_scale_it_moves_alike() {
    let d = diagnose_job(
        "r5_nose03_feed12_sphere.toml",
        "nose_radius_-8.9um_r5_nose03_feed12_noise3nm.csv",
        &["--remove-power"],
    );
    assert_scale_names_the_nose_error(&d, 5.0, -8.9);
    assert_axis(&d, 0.815);
}

/// Form in, an edge waviness of order 24, 52 nm, phase 127° on an R7 sphere (0.8 mm
/// nose, 12 µm/rev; random-batch draw z09). The waviness alone fits to the noise; a
/// decentre beside a waviness of order 23.6 fits as well (ΔBIC 0.9), and the two sets
/// were called `ambiguous`, nothing claimed — though both hold the waviness. Now the
/// waviness both hold is claimed, and the decentre named as what the data cannot rule
/// in or out.
#[test]
fn a_waviness_that_two_tied_explanations_share_is_claimed() {
    let d = diagnose_job(
        "r7_nose08_feed12_sphere.toml",
        "waviness_o24_52nm_r7_nose08_feed12.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    let (order, amplitude, sigma) = waviness(&d);
    assert!((order - 24.0).abs() <= 1.0, "order {order} for 24");
    assert_sized((amplitude, sigma), 52.0);
    assert_axis(&d, 0.015);
}

/// An R12 sphere (0.5 mm nose, 3 µm/rev: marks 2.3 nm deep, 0.5 nm of noise) read with
/// the instrument's lateral calibration 0.57 % long, the diameter's ends sloping 0.14
/// (`lateral_stretch_0.57pct_r12_nose05_feed3.csv`). The marks' high-pass lagged the
/// form by ~0.15 µm at the file's ends (the model's trace runs on past them), so the
/// placement that pushed an end off the part won, and the scale went unsearched: a
/// nose radius −68 µm off was claimed. The scale is the instrument's: 1/1.0057.
#[test]
fn a_lateral_stretch_is_fitted_as_the_scale_not_claimed_as_a_nose_radius_error() {
    let d = diagnose_job(
        "r12_nose05_feed3_d398_sphere.toml",
        "lateral_stretch_0.57pct_r12_nose05_feed3.csv",
        &["--remove-power"],
    );
    assert_nothing_claimed(&d, "no_effect_beyond_noise");
    let (scale, sigma) = scale_and_sigma(&d);
    let truth = 1.0 / 1.0057;
    assert!(
        (scale - truth).abs() < 2.0 * sigma && sigma < 3e-4,
        "scale {scale} ± {sigma}, planted {truth}"
    );
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis - 0.4917873).abs() < 3.0 * sigma.max(1e-6),
        "axis {axis} ± {sigma} mm, planted 0.4917873"
    );
}

/// An 80 nm dig 4 µm wide on an R9 sphere whose 2 µm marks the 1 µm points cannot
/// resolve (`dig_80nm_beyond_the_axis_range_r9_nose02_feed2.csv`): a compact feature
/// far out of the noise bounds the axis search, but this one lies where the axis would
/// leave the part behind — the range came out inverted and toolmark panicked. Nothing
/// models a dig: nothing may be claimed, and the axis is where the form puts it.
#[test]
fn a_dig_where_the_axis_cannot_be_is_left_unexplained_not_a_panic() {
    let d = diagnose_job(
        "r9_nose02_feed2_d332_sphere.toml",
        "dig_80nm_beyond_the_axis_range_r9_nose02_feed2.csv",
        &["--remove-power"],
    );
    assert_nothing_claimed(&d, "unexplained_residual");
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis + 0.016).abs() < 2.0 * sigma && sigma < 0.02,
        "axis {axis} ± {sigma} mm, planted -0.016"
    );
}

/// 10 nm marks read five points a mark under 1 nm of noise, on an R22 sphere whose form
/// was removed, the lateral calibration 0.81 % long
/// (`lateral_stretch_0.81pct_r22_nose03_feed5_five_points_a_mark.csv`): six points a
/// mark were needed for the marks to place a line, so the weak form did, 62.7 µm off at
/// ± 12.8 µm. The marks place it now, and fix the scale.
#[test]
fn marks_read_five_points_a_mark_place_the_line_and_its_scale() {
    let d = diagnose_job(
        "r22_nose03_feed5_d276_sphere.toml",
        "lateral_stretch_0.81pct_r22_nose03_feed5_five_points_a_mark.csv",
        &["--remove-power"],
    );
    assert_nothing_claimed(&d, "no_effect_beyond_noise");
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis - 0.48086).abs() < 1e-3 && (axis - 0.48086).abs() < 3.0 * sigma.max(1e-5),
        "axis {axis} ± {sigma} mm, planted 0.48086"
    );
    let (scale, sigma) = scale_and_sigma(&d);
    let truth = 1.0 / 1.0081;
    assert!(
        (scale - truth).abs() < 2.0 * sigma.max(1e-4),
        "scale {scale} ± {sigma}, planted {truth}"
    );
}

/// A 39 nm bump 55 µm wide beside the axis of an R7 sphere whose form beyond power is
/// 8 nm RMS over the trace (`bump_39nm_on_a_weak_form_r7_nose02_feed2.csv`): as strong
/// as the form, it made the part "not follow its form" — `does_not_fit`, "another part,
/// or heights in the wrong unit". The job's form takes half the measured smooth variance
/// out: this part, with a gap no candidate explains, and the axis within its σ.
#[test]
fn a_bump_as_strong_as_a_weak_form_is_unexplained_not_another_part() {
    let d = diagnose_job(
        "r7_nose02_feed2_d220_sphere.toml",
        "bump_39nm_on_a_weak_form_r7_nose02_feed2.csv",
        &["--remove-power"],
    );
    assert_nothing_claimed(&d, "unexplained_residual");
    assert_eq!(d["fit_check"]["fits"], true);
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis - 0.064).abs() < 2.0 * sigma,
        "axis {axis} ± {sigma} mm, planted 0.064"
    );
}

/// Cut 1021's family from code written apart from toolmark
/// (`tests/independent/nc_turned_profile.py`): a bare `C X Z` spiral program for the
/// 0.191 mm arc over an R10.8 bowl whose feed falls from 24 µm/rev at 0.6 mm to 14 at
/// the axis, measured as a white-light line (0.871 µm pixels, blank pixels at both ends,
/// the axis inside it, the azimuth not told, 3 nm of noise). The job is `from_path`, as
/// a user of a real program writes it.
const SPIRAL_JOB: &str = "spiral_feed_14_24um_bowl.toml";

/// The median over the comparison's radius bands of the measured over the simulated
/// local mark spacing.
fn median_mark_spacing_ratio(d: &serde_json::Value) -> f64 {
    let mut ratios: Vec<f64> = d["comparison"]["mark_spacing"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["measured_um"].as_f64().unwrap() / b["simulated_um"].as_f64().unwrap())
        .collect();
    assert!(ratios.len() >= 3, "bands: {ratios:?}");
    ratios.sort_by(f64::total_cmp);
    ratios[ratios.len() / 2]
}

/// The bounds for a good cut of the family: the nominal prediction's PV within
/// 15 % of the measured one, the local mark spacing within 2 % (median over bands).
/// Measured on the control: PV 284.3 against 286.8 nm, spacing ratio 1.0001.
#[test]
fn a_spiral_program_whose_feed_varies_is_placed_and_compared_band_by_band() {
    let d = diagnose_job(
        SPIRAL_JOB,
        "spiral_feed_14_24um_control.csv",
        &["--remove-power"],
    );
    assert_nothing_claimed(&d, "no_effect_beyond_noise");
    assert_axis(&d, 0.526);
    let c = &d["comparison"];
    let (measured, simulated) = (
        c["measured"]["pv_nm"].as_f64().unwrap(),
        c["simulated"]["pv_nm"].as_f64().unwrap(),
    );
    assert!(
        (simulated / measured - 1.0).abs() < 0.15,
        "PV {simulated} nm simulated, {measured} nm measured"
    );
    let ratio = median_mark_spacing_ratio(&d);
    assert!((ratio - 1.0).abs() < 0.02, "mark spacing ratio {ratio}");
}

/// The same program, the tool stopping 2.4 µm short of the axis: found within 2σ and
/// 10 % (2.406 ± 0.082 µm), the axis where the generator put it (file x 0.450 mm).
#[test]
fn a_decentre_on_a_spiral_program_whose_feed_varies_is_found() {
    let d = diagnose_job(
        SPIRAL_JOB,
        "spiral_feed_14_24um_decentre_+2.4um.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    assert_sized(accepted(&d, "x_decentre"), 2.4);
    assert_axis(&d, 0.450);
}

/// The same program, the tool 2.6 µm below centre (an uncut boss of the 3 µm stock):
/// found to its boss's edge (2.61 ± 0.44 µm), the axis at file x 0.600 mm.
#[test]
fn a_boss_on_a_spiral_program_whose_feed_varies_is_found_below_centre() {
    let d = diagnose_job(
        SPIRAL_JOB,
        "spiral_feed_14_24um_centre_height_-2.6um.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    accepted(&d, "centre_height");
    assert_boss(&d, -2.6);
    assert_axis(&d, 0.600);
}

/// The same program, the tool 3.3 µm above centre (the flank's cone), the line reaching
/// 5 µm past the radius where the program's second revolution starts (the `from_path`
/// part's rim): at the true axis it loses a few points there, and the axis comb had
/// judged only the teeth that lose none — the tooth half a mark in, half a turn round,
/// won, and the cone was never seen (`unexplained_residual`, the axis 8.8 µm off). Each
/// lost point now costs the tooth four times the mean square of those it keeps: found
/// (3.301 ± 0.095 µm), the axis where the generator put it.
#[test]
fn a_cone_on_a_line_reaching_the_programs_rim_is_found_above_centre() {
    let d = diagnose_job(
        SPIRAL_JOB,
        "spiral_feed_14_24um_centre_height_+3.3um_to_the_rim.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    assert_sized(accepted(&d, "centre_height"), 3.3);
    assert_axis(&d, 0.652);
}

/// A dome of the family (`spiral_feed_16_32um_dome.toml`: R16, the feed falling from
/// 32 µm/rev at 0.7 mm to 16 at the axis), the tool 5 µm above centre (the flank's cone),
/// the axis at file x 0.560 mm, 2 nm of noise. The height is found (5.00 ± 0.02 µm) but
/// the cone at the axis, where no model matches a part exactly, pulls the axis 52 nm
/// off; the marks' σ alone said ± 4.6 nm (11σ). Placed again without the centre (the cone
/// and two marks of it) the axis moves by that pull, which the σ now carries: the truth
/// must lie within 2σ.
#[test]
fn a_cones_pull_on_a_diameters_axis_is_in_its_sigma() {
    let d = diagnose_job(
        "spiral_feed_16_32um_dome.toml",
        "spiral_feed_16_32um_dome_centre_height_+5um.csv",
        &["--remove-power"],
    );
    assert_status(&d, "effects_found");
    assert_sized(accepted(&d, "centre_height"), 5.0);
    let (axis, sigma) = axis_and_sigma(&d);
    assert!(
        (axis - 0.560).abs() <= 2.0 * sigma && sigma < 1e-4,
        "axis {axis} ± {sigma} mm, planted 0.560"
    );
}

/// An edge waviness of order 45, 34 nm, phase 327° on a map whose 25 µm pixels alias the
/// 5 µm marks (`waviness_o45_34nm_aliased_map.csv`, 41 × 41 pixels, 1 nm of noise, the
/// axis at file (0.366, 0.433) mm). The order was screened where the job as given had
/// placed the axis (pulled by the waviness's print) and only refitted near it once the
/// axis moved back: order 58.7, 10.6 nm, beside a second order 34.6 at 26.6 nm. Screened
/// again where the axis settles it is one order, within 2 % and 2σ of 45, its amplitude
/// within 10 % and 2σ of 34 nm.
#[test]
fn a_waviness_on_an_aliased_map_is_screened_where_its_axis_settles() {
    let d = diagnose_with(
        "waviness_o45_34nm_aliased_map.csv",
        &["--pixel-um", "25", "--remove-power"],
    );
    assert_status(&d, "effects_found");
    let orders = d["accepted"].as_array().unwrap().len();
    assert_eq!(orders, 1, "{}", d["verdict"]["sentence"]);
    let (order, amplitude, a_sigma) = waviness(&d);
    let order_sigma = accepted_effect(&d, "edge_waviness")["order_sigma"]
        .as_f64()
        .unwrap();
    assert!(
        (order / 45.0 - 1.0).abs() <= 0.02 && (order - 45.0).abs() <= 2.0 * order_sigma,
        "order {order} ± {order_sigma} for 45"
    );
    assert_sized((amplitude, a_sigma), 34.0);
    assert_map_axis_within_its_sigma(&d, [0.366, 0.433]);
}

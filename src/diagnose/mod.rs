//! Sim-to-real diagnosis (DESIGN §8): given a job (the model, without the unknown
//! effect) and a measured surface, say where the gap between them lies, which
//! unmodelled effect causes it, and how far it shrinks once that effect is added.
//!
//! 1. Register (piston, tilt, optionally power; the axis found in the measurement's
//!    frame) and check that the measurement fits the job at all.
//! 2. Residual = measured − simulated: its zones, bands and (maps) azimuthal orders.
//! 3. Fit every candidate effect of the job's process by re-simulating (the removal
//!    engine is the forward model), rank them by the evidence they add (BIC on the
//!    effective point count, so correlated residuals do not count as independent
//!    evidence), combine greedily, and accept only what beats noise.
//! 4. Report the residual before and after each accepted effect, overall and per zone,
//!    and — when part of the data was held out — on the part the fit never saw.

pub mod candidates;
pub mod checks;
pub mod compare;
pub mod files;
pub mod fit;
pub mod forward;
pub mod locate;
pub mod marks;
pub mod measurement;
pub mod register;
pub mod report;
pub mod screen;
pub mod search;
pub mod side_by_side;
pub mod spectrum;
pub mod synth;
pub mod validate;
pub mod verdict;
pub mod withheld;
pub mod zones;

use crate::engine::RemovalEngine;
use crate::model::Job;
use candidates::{Candidate, NotDiagnosable, candidates_for};
use fit::{AzimuthPrior, Fit, Problem};
use forward::{ForwardError, ForwardModel};
use glam::DVec2;
use locate::Located;
use marks::MarkShape;
use measurement::{Measurement, Shape};
use register::{Comb, Registered, ShiftSearch, Terms};
use report::*;
use search::{Search, TIE_EVIDENCE};
use std::sync::Arc;
use std::time::Instant;
use zones::{Zones, band_cutoffs, bands, pv, radii, rms, white_noise_mm};

/// How the diagnosis runs.
#[derive(Debug, Clone)]
pub struct Options {
    pub terms: Terms,
    /// Most effects combined.
    pub max_effects: usize,
    /// ΔBIC an effect must add to be accepted (10: "very strong" evidence).
    pub min_evidence: f64,
    /// Fit only these effect kinds (job-file names); all of the process's when empty.
    pub only: Vec<String>,
    /// Fit on the points whose position (along the line, or X for a map, in the file's
    /// frame, mm) lies in this range; the rest is held out to judge the fit.
    pub calibrate_on_mm: Option<(f64, f64)>,
    /// Fit the instrument's lateral scale (within ±2 %) where the part's marks fix it.
    pub lateral_scale: bool,
    /// Register and compare only: no effect is fitted.
    pub compare_only: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            terms: Terms {
                power: false,
                shift: true,
            },
            max_effects: 3,
            min_evidence: 10.0,
            only: Vec::new(),
            calibrate_on_mm: None,
            lateral_scale: true,
            compare_only: false,
        }
    }
}

#[derive(Debug)]
pub enum DiagnoseError {
    /// The measurement cannot be compared with this job at all.
    DoesNotFit(String),
    Forward(String),
}

impl std::fmt::Display for DiagnoseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DiagnoseError::DoesNotFit(why) => {
                write!(f, "the measurement does not fit the job: {why}")
            }
            DiagnoseError::Forward(why) => f.write_str(why),
        }
    }
}

impl From<ForwardError> for DiagnoseError {
    fn from(err: ForwardError) -> Self {
        DiagnoseError::Forward(err.0)
    }
}

/// The diagnosis and the per-point data behind its images.
pub struct Outcome {
    pub diagnosis: Diagnosis,
    /// The points fitted (the calibration part when some were held out).
    pub fitted: Measurement,
    /// Registered model heights and residuals (mm) at the fitted points: nominal job,
    /// then with the accepted effects.
    pub model_before_mm: Vec<f64>,
    pub model_after_mm: Vec<f64>,
    pub residual_before_mm: Vec<f64>,
    pub residual_after_mm: Vec<f64>,
    /// Per fitted point, its radial zone.
    pub zone: Vec<usize>,
    pub zones: Zones,
    /// The accepted effects as an `[[effects]]` fragment.
    pub effects_fragment: String,
}

/// Diagnoses `measurement` against `job` (the job's own effects are part of the model).
pub fn diagnose(
    job: &Job,
    measurement: &Measurement,
    engine: &mut dyn RemovalEngine,
    options: &Options,
    log: &dyn Fn(&str),
) -> Result<Outcome, DiagnoseError> {
    let started = Instant::now();
    require_points(measurement)?;
    let binned = binned_for_the_model(job, measurement, log);
    let bin_mm = binned.as_ref().and_then(|b| b.instrument.line_bin_mm);
    let measurement = binned.as_ref().unwrap_or(measurement);
    let located = locate::locate(
        job,
        measurement,
        engine,
        locate::LocateOptions {
            terms: options.terms,
            scale: options.lateral_scale,
        },
        log,
    )?;
    let fitted = check_coverage(job, &measurement.placed(located.frame))?;
    let calibration = calibration_mask(&fitted, options.calibrate_on_mm)?;
    let stage = Stage {
        job,
        fitted: &fitted,
        period: mark_period_mm(job, &fitted),
        options,
        log,
    };
    let period = stage.period;
    let folds = validate::Folds {
        measurement: &fitted,
        calibration: calibration.clone(),
    };
    let (mut problem, base) =
        registered_problem(&stage, measurement, &located, calibration.clone(), engine)?;
    let nominal = base.evaluation.registered.clone();
    // Marks that placed nothing (lost in the noise) have no spacing to compare.
    let spacing = |from: f64, to: f64| {
        located
            .marks_mm
            .and_then(|_| locate::local_mark_spacing_mm(job, from, to))
    };
    let comparison = compare::compare(&fitted, &nominal, options.terms.power, &spacing);
    let mut check = checks::fit_check(&fitted, &nominal, job, options.terms, period, &comparison);
    let (candidates, not_diagnosable) = candidates_to_try(job, &fitted, options);
    let Settled {
        mut found,
        indistinguishable,
        ambiguous,
        rival_axes,
    } = search_and_settle(
        &stage,
        &mut problem,
        &base,
        (&candidates, &folds),
        &mut check,
    )?;
    let zones = Zones::new(fitted.max_radius_mm());
    let analysis = ResidualAnalysis {
        measurement: &fitted,
        zones: &zones,
        period_mm: period,
        mark_spacing_mm: folded_mark_spacing_mm(job),
    };
    let (nominal_marks, after_marks) =
        judge_marks(&mut problem, &analysis, &base, &mut found, log)?;
    let rss0 = base.evaluation.rss();
    let after = found
        .accepted
        .as_ref()
        .map_or(base.evaluation.clone(), |f| f.evaluation.clone());
    let zone: Vec<usize> = radii(&fitted, nominal.shift_mm)
        .iter()
        .map(|r| zones.of(*r))
        .collect();
    let residual_before = nominal.residual_mm.clone();
    let residual_after = after.registered.residual_mm.clone();
    let before_info = analysis.of(&nominal, nominal_marks);
    let after_info = analysis.of(&after.registered, after_marks);
    let accepted = found.accepted.as_ref();
    let (candidate_results, accepted_results) = candidate_results(&found, rss0);
    let shrinkage = shrinkage(&fitted, &nominal, &found, &zones);
    let held = calibration
        .as_ref()
        .filter(|_| check.fits)
        .map(|c| judge_held_out(&mut problem, c, &base, accepted))
        .transpose()?;
    let fragment = effects_fragment(job, accepted);
    let verdict = verdict::verdict(
        options.compare_only.then_some(&comparison),
        &check,
        accepted,
        (&before_info, &after_info),
        &ties(&found, &ambiguous),
        held.as_ref(),
        &found.refused,
    );
    let registration = final_placement(
        &stage,
        &mut problem,
        (&found, &ambiguous, &rival_axes),
        &base,
        located,
        measurement,
        check.fits,
    )?;
    if let Some(note) = scale_or_nose_radius(job, &registration, accepted, &candidates) {
        check.findings.push(note);
    }
    let diagnosis = Diagnosis {
        schema: SCHEMA,
        toolmark_version: env!("CARGO_PKG_VERSION"),
        job: job_info(job),
        measurement: MeasurementInfo::of(
            &fitted,
            measurement,
            calibration.as_deref().map(Vec::as_slice),
            bin_mm.map(|w| w * 1e3),
        ),
        registration,
        comparison,
        fit_check: check,
        residual_before: before_info,
        residual_after: after_info,
        candidates: candidate_results,
        not_diagnosable,
        accepted: accepted_results,
        cross_validation: found.validations.clone(),
        shrinkage,
        indistinguishable,
        ambiguous,
        held_out: held,
        verdict,
        run: run_info(&problem, started, period),
    };
    Ok(Outcome {
        diagnosis,
        model_before_mm: nominal.model_mm.clone(),
        model_after_mm: after.registered.model_mm.clone(),
        residual_before_mm: residual_before,
        residual_after_mm: residual_after,
        zone,
        zones,
        effects_fragment: fragment,
        fitted,
    })
}

/// What every stage of one diagnosis reads: the job, the points fitted, the marks'
/// period (mm), the options and the log.
struct Stage<'s> {
    job: &'s Job,
    fitted: &'s Measurement,
    period: f64,
    options: &'s Options,
    log: &'s dyn Fn(&str),
}

/// The measurement averaged in runs of up to half the job's pitch where its points lie
/// closer than that (the model is averaged alike); `None` where they do not.
fn binned_for_the_model(
    job: &Job,
    measurement: &Measurement,
    log: &dyn Fn(&str),
) -> Option<Measurement> {
    let binned = measurement.binned(0.5 * job.pitch_mm);
    let bin_mm = binned.as_ref().and_then(|b| b.instrument.line_bin_mm);
    if let (Some(b), Some(width)) = (&binned, bin_mm) {
        log(&format!(
            "averaging {} points in {} runs of {:.3} µm (up to half the job's pitch; the model averaged alike)",
            measurement.len(),
            b.len(),
            width * 1e3
        ));
    }
    binned
}

/// The forward model around the fitted points, the problem that fits effects on it,
/// and the job as given registered on it (the spiral's azimuth and the lateral scale
/// fitted with it where the placement found them).
fn registered_problem<'a, 'e>(
    stage: &Stage<'a>,
    measurement: &Measurement,
    located: &Located,
    calibration: Option<Arc<Vec<bool>>>,
    engine: &'e mut dyn RemovalEngine,
) -> Result<(Problem<'a, 'e>, Fit), DiagnoseError> {
    let (job, fitted, period, terms) = (stage.job, stage.fitted, stage.period, stage.options.terms);
    let comb = axis_comb(job, measurement, located, period).filter(|_| terms.shift);
    let room = forward::shift_room_mm(fitted).max(comb_reach_mm(comb) + 0.5 * period);
    let mut model = ForwardModel::around(job, fitted, room, engine)?;
    if located.azimuth_fitted {
        model.set_azimuth(located.azimuth_rad);
    }
    (stage.log)("simulating the job as given and registering it");
    let mut problem = Problem::new(
        fitted,
        model,
        terms,
        local_search(DVec2::ZERO, period, comb),
    );
    problem.calibrate_on(calibration);
    let spiral = located.azimuth_fitted && fitted.is_line();
    let members: Vec<Candidate> = [
        (spiral, Candidate::SpiralAzimuth),
        (located.scale_fitted, Candidate::LateralScale),
    ]
    .into_iter()
    .filter_map(|(on, c)| on.then_some(c))
    .collect();
    if spiral && measurement.azimuth_stated {
        believe_stated_azimuth(&mut problem, measurement, located, &members)?;
    }
    let base = search::registration_base(&mut problem, &members)?;
    Ok((problem, base))
}

/// What the search for effects settled: what it found (withdrawn where ambiguous or
/// not significant), the candidates the data cannot tell from the job, the tied labels
/// and the axis positions of the rivals.
struct Settled {
    found: Search,
    indistinguishable: Vec<String>,
    ambiguous: Vec<String>,
    rival_axes: Vec<DVec2>,
}

/// The search for effects where the fit check allows one, then what settles it: the
/// form's departure explained by a candidate or not, ties withdrawn as ambiguous, and
/// on a line the accepted effects refitted on finer rings and kept while significant.
fn search_and_settle<'a>(
    stage: &Stage<'a>,
    problem: &mut Problem<'a, '_>,
    base: &Fit,
    (candidates, folds): (&[Candidate], &'a validate::Folds<'a>),
    check: &mut FitCheck,
) -> Result<Settled, DiagnoseError> {
    let (fitted, options, log) = (stage.fitted, stage.options, stage.log);
    let mut found = if checks::may_search(check) && !options.compare_only {
        search::search(
            problem,
            base,
            candidates,
            stage.job,
            folds,
            stage.period,
            options,
            log,
        )?
    } else {
        Search::default()
    };
    // What may settle a departure from the form: each candidate alone, and what the
    // search accepted (two effects can each bend the other's print alone).
    let explanations: Vec<(String, &[f64])> = found
        .singles
        .iter()
        .map(|(fit, _)| (search::labels(&fit.set[fit.set.len() - 1..]), fit))
        .chain(
            found
                .accepted
                .iter()
                .map(|fit| (search::labels(&fit.effects()), fit)),
        )
        .map(|(label, fit)| (label, fit.evaluation.registered.residual_mm.as_slice()))
        .collect();
    checks::settle_form(check, fitted, stage.period, &explanations);
    if !check.fits {
        found = Search::default();
    }
    let indistinguishable = indistinguishable(&found.singles, &base.evaluation.registered);
    let contenders: Vec<DVec2> = found
        .accepted
        .iter()
        .chain(&found.alternative)
        .map(|f| f.evaluation.registered.shift_mm)
        .collect();
    let ambiguous = withdraw_if_ambiguous(&mut found, &indistinguishable, log);
    let rival_axes = rival_axes(&found, contenders, &ambiguous);
    if fitted.is_line() && check.fits {
        refine_reported(problem, &mut found, log)?;
        withdraw_if_not_significant(problem, &mut found, log)?;
    }
    Ok(Settled {
        found,
        indistinguishable,
        ambiguous,
        rival_axes,
    })
}

/// The marks' shape judged before and after (the accepted effects withdrawn where the
/// marks they leave are no better explained): the nominal job's fold, and the fold
/// after what stays accepted.
fn judge_marks(
    problem: &mut Problem,
    analysis: &ResidualAnalysis,
    base: &Fit,
    found: &mut Search,
    log: &dyn Fn(&str),
) -> Result<(Option<MarkShape>, Option<MarkShape>), DiagnoseError> {
    let nominal_marks = judged_mark_shape(problem, analysis, base)?;
    let accepted_marks = match &found.accepted {
        Some(fit) => judged_mark_shape(problem, analysis, fit)?,
        None => None,
    };
    withdraw_if_marks_unexplained(
        found,
        (nominal_marks.as_ref(), accepted_marks.as_ref()),
        analysis,
        &base.evaluation.registered,
        log,
    );
    let after_marks = if found.accepted.is_some() {
        accepted_marks
    } else {
        nominal_marks.clone()
    };
    Ok((nominal_marks, after_marks))
}

/// Where the data lies: as the final model places it — or, when rivals tie, as the
/// best of them does (they explain the same residual and place the axis alike; the
/// job as given, without what they explain, may not).
fn final_placement(
    stage: &Stage,
    problem: &mut Problem,
    (found, ambiguous, rival_axes): (&Search, &[String], &[DVec2]),
    base: &Fit,
    located: Located,
    measurement: &Measurement,
    fits: bool,
) -> Result<RegistrationInfo, DiagnoseError> {
    let final_fit = found
        .accepted
        .as_ref()
        .or_else(|| {
            found
                .singles
                .first()
                .map(|s| &s.0)
                .filter(|_| !ambiguous.is_empty())
        })
        .unwrap_or(base);
    let terms = stage.options.terms;
    let judge_axis = stage.fitted.is_line() && terms.shift && fits;
    placement(
        problem,
        final_fit,
        located,
        (measurement, stage.fitted),
        (terms, judge_axis),
        base.evaluation
            .registered
            .registration
            .unstretched(fit::fitted_stretch(base).0),
        rival_axes,
    )
}

/// The job as the diagnosis names it (effects carried from an earlier part are added
/// by the caller that carried them).
fn job_info(job: &Job) -> JobInfo {
    JobInfo {
        name: job.name.clone(),
        process: process_name(job).into(),
        carried_effects: None,
    }
}

/// What the diagnosis ran: the engine, its simulations and their time.
fn run_info(problem: &Problem, started: Instant, period: f64) -> RunInfo {
    RunInfo {
        engine: problem.model.engine_kind(),
        simulations: problem.model.simulations,
        prepare_s: problem.model.prepare_s,
        removal_s: problem.model.removal_s,
        total_s: started.elapsed().as_secs_f64(),
        mark_period_um: period * 1e3,
    }
}

/// Weighs the spiral's azimuth the profile's file states ([`AzimuthPrior`]), its weight
/// in units of the white noise the registration alone leaves.
fn believe_stated_azimuth(
    problem: &mut Problem,
    measurement: &Measurement,
    located: &Located,
    members: &[Candidate],
) -> Result<(), DiagnoseError> {
    let Shape::Line { azimuth_rad } = measurement.shape else {
        return Ok(());
    };
    let first = search::registration_base(problem, members)?;
    let noise = white_noise_mm(
        problem.measurement,
        &first.evaluation.registered.residual_mm,
    );
    problem.prior = Some(AzimuthPrior {
        centre_deg: (azimuth_rad - located.azimuth_rad).to_degrees(),
        sigma_deg: AZIMUTH_PRIOR_DEG,
        weight_mm: AZIMUTH_PRIOR_WEIGHT * noise.max(1e-7),
    });
    problem.clear_cache();
    Ok(())
}

/// The candidates the search tries (those `--only` names, if any) and the effects the
/// job's process or this measurement cannot diagnose, with why.
fn candidates_to_try(
    job: &Job,
    fitted: &Measurement,
    options: &Options,
) -> (Vec<Candidate>, Vec<NotDiagnosable>) {
    let (all_candidates, mut not_diagnosable) = candidates_for(job);
    if fitted.is_line() && all_candidates.contains(&Candidate::TiltErrorMotion { order: 0.0 }) {
        not_diagnosable.push(NotDiagnosable {
            effect: "tilt_error_motion",
            reason: "along one line its print is a tilt, or a cone across the axis, which registration and the set-up effects take: it needs a map".into(),
        });
    }
    let candidates = all_candidates
        .into_iter()
        .filter(|c| options.only.is_empty() || options.only.iter().any(|o| o == c.kind()))
        .collect();
    (candidates, not_diagnosable)
}

/// Every candidate fitted alone, ranked (whether accepted, its evidence and the share
/// of Σr² it explains), and the accepted set's effects.
fn candidate_results(found: &Search, rss0: f64) -> (Vec<CandidateResult>, Vec<CandidateResult>) {
    let accepted = found.accepted.as_ref();
    let singles = found
        .singles
        .iter()
        .enumerate()
        .map(|(rank, (fit, evidence))| {
            let member = fit.set.len() - 1;
            let kind = fit.set[member].kind();
            CandidateResult {
                rank: rank + 1,
                accepted: accepted.is_some_and(|f| f.effects().iter().any(|c| c.kind() == kind)),
                delta_bic: *evidence,
                explained: 1.0 - fit.evaluation.rss() / rss0.max(1e-300),
                ..effect_result(fit, member, rss0)
            }
        })
        .collect();
    let accepted = accepted
        .map(|f| {
            f.effect_members()
                .into_iter()
                .map(|i| effect_result(f, i, rss0))
                .collect()
        })
        .unwrap_or_default();
    (singles, accepted)
}

/// How the residual shrank: the nominal job's, then after each accepted step.
fn shrinkage(
    fitted: &Measurement,
    nominal: &Registered,
    found: &Search,
    zones: &Zones,
) -> Vec<ShrinkageStep> {
    let first = shrink_step(
        "nominal job",
        &nominal.residual_mm,
        &radii(fitted, nominal.shift_mm),
        zones,
    );
    let steps = found.steps.iter().map(|step| {
        shrink_step(
            &format!("+ {}", search::labels(&step.set)),
            &step.evaluation.registered.residual_mm,
            &radii(fitted, step.evaluation.registered.shift_mm),
            zones,
        )
    });
    std::iter::once(first).chain(steps).collect()
}

/// The smallest one σ the fitted lateral scale is reported with (relative to 1): the
/// forward model's own error. On a decentred R7 sphere (the fourth random batch's s05)
/// toolmark and the independent section model differ by 0.02 nm RMS, which a scale
/// 6.6e-5 from the truth takes up — fitted at 1.000066 ± 0.000005 under 0.05 nm of noise,
/// 1.000083 ± 0.000013 under 0.5 nm; the other decentres of that batch came back 3–5e-5
/// off at ± 1–2e-5. No profile tells the scale finer than this model error.
const SCALE_SIGMA_FLOOR: f64 = 1e-4;

/// Where the data lies as `final_fit` places it: the spiral's turn, the fitted lateral
/// scale and (`judge_axis`, a line whose axis was searched) the axis σ
/// ([`line_axis_sigma_mm`]), widened to reach the farthest of `rival_axes`.
fn placement(
    problem: &mut Problem,
    final_fit: &Fit,
    located: Located,
    (measurement, fitted): (&Measurement, &Measurement),
    (terms, judge_axis): (Terms, bool),
    nominal: register::Registration,
    rival_axes: &[DVec2],
) -> Result<RegistrationInfo, DiagnoseError> {
    let half_turn = if final_fit.evaluation.registered.mirrored {
        180.0
    } else {
        0.0
    };
    let turn_deg = half_turn
        + fit::spiral_turn_deg(&final_fit.set, &final_fit.values, problem.model.base_job());
    let (stretch, mut stretch_sigma) = fit::fitted_stretch(final_fit);
    if let Some(mark) = located.marks_mm.filter(|_| located.scale_fitted) {
        stretch_sigma = problem.scale_sigma_with_aliases(final_fit, mark)?;
    }
    if located.scale_fitted {
        stretch_sigma = stretch_sigma.max(SCALE_SIGMA_FLOOR);
    }
    // The σ in the read measurement's mm: through the located scale, the fit's stretch
    // already taken out.
    let own = final_fit.evaluation.registered.shift_mm;
    let rivals_apart = rival_axes
        .iter()
        .map(|r| (*r - own).length() / located.frame.scale)
        .fold(0.0, f64::max);
    let sigma = judge_axis
        .then(|| line_axis_sigma_mm(problem, final_fit, &located, measurement))
        .transpose()?
        .map(|s| s.hypot(rivals_apart));
    // A map's axis σ as the final model places it (the placement's was taken on the job
    // as given: a cone it lacked made it 8 µm where the final fit pins the axis to
    // 0.1 µm), with its halves' disagreement (model error) and the rivals' axes.
    let map_sigmas = (!measurement.is_line() && terms.shift)
        .then(|| problem.map_axis_sigmas_mm(final_fit))
        .transpose()?
        .map(|s| s.map(|s| (s / located.frame.scale).hypot(rivals_apart)));
    let mut located = located.with_fitted_scale(stretch, stretch_sigma);
    if let Some(sigma) = sigma {
        located.sigma_shift_mm[0] = sigma;
    }
    if let Some(sigmas) = map_sigmas {
        located.sigma_shift_mm = sigmas;
    }
    Ok(RegistrationInfo::new(
        term_names(terms),
        &located,
        turn_deg,
        measurement,
        fitted,
        nominal,
        final_fit
            .evaluation
            .registered
            .registration
            .unstretched(stretch),
    ))
}

/// On a turned sphere a nose radius Δρ off nominal (the tool set at its tip) moves the
/// marks along the radius by Δρ·r/R — as a lateral scale of 1 + Δρ/R does (1 − Δρ/R on
/// a concave one) — and bends the form beyond power only in r⁴. Where the lateral scale
/// came out clear of 1 and no nose-radius error was claimed, a note says which nose
/// error the scale could equally be, and how to tell them apart.
fn scale_or_nose_radius(
    job: &Job,
    registration: &RegistrationInfo,
    accepted: Option<&Fit>,
    candidates: &[Candidate],
) -> Option<Finding> {
    let surface = &job.surface;
    let sphere = surface.curvature_per_mm > 0.0
        && surface.conic == 0.0
        && surface.even_coefficients.iter().all(|a| *a == 0.0);
    let (scale, sigma) = (registration.lateral_scale, registration.lateral_scale_sigma);
    let clear = registration.lateral_scale_fitted
        && !registration.lateral_scale_at_bound
        && (scale - 1.0).abs() > 2.0 * sigma;
    let claimed = accepted.is_some_and(|f| f.effects().contains(&Candidate::NoseRadiusError));
    if !(job.process.turning().is_some()
        && sphere
        && clear
        && candidates.contains(&Candidate::NoseRadiusError)
        && !claimed)
    {
        return None;
    }
    let radius_um = 1e3 / surface.curvature_per_mm;
    // The marks move outward with Δρ on a convex part (z falling with r), inward on a
    // concave one.
    let sign = -surface.sign();
    Some(Finding::note(format!(
        "the lateral scale came out {scale:.5} ± {sigma:.5}: on this R{} mm sphere a nose radius {:+.2} ± {:.2} µm off nominal (the tool set at its tip) moves the marks alike and leaves no other print beyond power; if the instrument's lateral scale is known, diagnose again with --fixed-scale to tell the two apart",
        (radius_um).round() * 1e-3,
        sign * (scale - 1.0) * radius_um,
        sigma * radius_um
    )))
}

/// What is reported of a residual: where it lies (zones, bands, orders), its noise, and
/// along a profile with marks, its fold over them.
struct ResidualAnalysis<'a> {
    measurement: &'a Measurement,
    zones: &'a Zones,
    period_mm: f64,
    mark_spacing_mm: Option<f64>,
}

impl ResidualAnalysis<'_> {
    /// `mark_shape`: the residual's fold as judged ([`judged_mark_shape`]).
    fn of(&self, r: &Registered, mark_shape: Option<MarkShape>) -> ResidualInfo {
        let m = self.measurement;
        let residual = &r.residual_mm;
        let (marks_cutoff, form_cutoff) = band_cutoffs(m, Some(self.period_mm));
        ResidualInfo {
            pv_nm: pv(residual) * 1e6,
            rms_nm: rms(residual) * 1e6,
            zones: self.zones.stats(&radii(m, r.shift_mm), residual),
            bands: bands(m, residual, marks_cutoff, form_cutoff),
            azimuthal_orders: if m.is_line() {
                Vec::new()
            } else {
                zones::azimuthal_orders(m, residual, r.shift_mm)
            },
            white_noise_nm: white_noise_mm(m, residual) * 1e6,
            correlation_length_points: zones::correlation_length(m, residual),
            mark_shape,
        }
    }

    /// Along a profile with marks: its residual folded over them.
    fn mark_shape(&self, r: &Registered) -> Option<MarkShape> {
        self.fold(r, &r.residual_mm)
    }

    /// `values` folded over the marks of `r`'s model.
    fn fold(&self, r: &Registered, values: &[f64]) -> Option<MarkShape> {
        let m = self.measurement;
        self.mark_spacing_mm
            .filter(|_| m.is_line())
            .and_then(|s| marks::fold(&m.along_mm, &r.model_mm, values, s))
    }
}

/// The spacing a profile's residual is folded over its marks at (turning only: the
/// milling forward model's scallops differ from the withheld suite's independent ones
/// by about 1 nm RMS folded, 0.6 of the noise, even on its control, a model error that
/// would read as a gap on every milled part).
pub(super) fn folded_mark_spacing_mm(job: &Job) -> Option<f64> {
    job.process
        .pass_spacing_mm()
        .filter(|_| matches!(job.process, crate::process::Process::Turning(_)))
}

/// The share of an accepted set's gain (residual energy removed) that must come off the
/// marks' folded shape for the set to count as reshaping the marks.
const RESHAPES_MARKS: f64 = 0.5;

/// How far (one σ) a stated profile azimuth is believed on a turned part (degrees), and
/// its weight in units of the residual's white noise: one σ off costs as much as one
/// point three times the noise off, so the marks overrule it wherever they can tell.
const AZIMUTH_PRIOR_DEG: f64 = 45.0;
const AZIMUTH_PRIOR_WEIGHT: f64 = 3.0;

/// A diagnosis needs some points.
fn require_points(m: &Measurement) -> Result<(), DiagnoseError> {
    if m.len() < 16 {
        return Err(DiagnoseError::DoesNotFit(format!(
            "only {} valid points (of {}); a diagnosis needs at least 16",
            m.len(),
            m.total_points
        )));
    }
    Ok(())
}

/// The spacing of the process's marks along the measurement (mm); a twentieth of the
/// extent for a process without marks.
fn mark_period_mm(job: &Job, m: &Measurement) -> f64 {
    job.process
        .pass_spacing_mm()
        .filter(|s| *s > 0.0)
        .unwrap_or(m.extent_mm() / 40.0)
        .min(m.extent_mm() / 8.0)
}

/// A fit's search for the axis: within an eighth of a mark period of where the last
/// registration put it, and of each tooth of `comb`.
fn local_search(start: DVec2, period: f64, comb: Option<Comb>) -> ShiftSearch {
    ShiftSearch {
        start,
        half_width_mm: 0.125 * period,
        step_mm: 0.03125 * period,
        refine: 1,
        mirrored: false,
        comb,
    }
}

/// Most teeth of an axis comb on each side (and most far teeth beyond them).
const MAX_TEETH: usize = 400;
/// The far teeth lie at least this many of the near teeth's steps apart.
const FAR_STEPS: f64 = 4.0;

/// A diameter's axis is also placed without the centre: the points within the fit's
/// centre-height feature and this many marks of it left out.
const CENTRE_MARKS: f64 = 2.0;

/// One σ of a line's axis where the final model put it: what its fit left open (the
/// azimuth held; the comb's aliases in). On a diameter whose marks placed it, the move
/// of the axis when the centre is left out ([`CENTRE_MARKS`],
/// [`fit::Problem::axis_pull_of_centre_mm`]: the model's error at the axis) is added in
/// quadrature. On a radius whose marks placed it, the marks
/// let the azimuth trade with the axis, which that fit cannot see: there the
/// placement's own σ (the azimuth free) and the final fit's move from the placement
/// (the marks alone against the whole model: model error) are added in quadrature. A
/// move of half a mark or more is to another tooth of the comb: the tooth then depends
/// on the model, and the two halves' disagreement stands for that move
/// ([`fit::Problem::axis_split_mm`]); a radius without resolved marks was placed by the
/// form alone and takes the halves' disagreement always.
fn line_axis_sigma_mm(
    problem: &mut fit::Problem,
    final_fit: &fit::Fit,
    located: &Located,
    m: &Measurement,
) -> Result<f64, DiagnoseError> {
    let held = problem.axis_sigma_mm(final_fit)? / located.frame.scale;
    if located.crosses_axis(m) {
        let Some(mark) = located.marks_mm else {
            return Ok(held);
        };
        let clear = fit::Problem::centre_feature_radius_mm(final_fit) + CENTRE_MARKS * mark;
        let pulled = problem.axis_pull_of_centre_mm(final_fit, clear)? / located.frame.scale;
        return Ok(held.hypot(pulled));
    }
    let placement = located.marks_mm.map_or(0.0, |_| located.sigma_shift_mm[0]);
    let moved = final_fit.evaluation.registered.shift_mm.length() / located.frame.scale;
    let moved = match located.marks_mm {
        Some(mark) if moved < 0.5 * mark => moved,
        _ => problem.axis_split_mm(final_fit)? / located.frame.scale,
    };
    Ok((held * held + placement * placement + moved * moved).sqrt())
}

/// The axis positions along a turned line that the placement could not tell apart
/// (see [`Comb`]), searched by every fit: where the profile resolves the marks, every
/// half mark (odd ones read half a turn round); where it does not, the form alone
/// placed it, and every quarter period — up to [`MAX_TEETH`] a side, and beyond them
/// up to as many again, sparser, so that the teeth span the range still (the form has
/// no marks to alias: a decentre's cone may lie anywhere in it). Across the whole range
/// where the placement searched the axis (`Located::axis_range_mm`, here in the placed
/// frame).
fn axis_comb(job: &Job, m: &Measurement, located: &Located, period: f64) -> Option<Comb> {
    let (lo, hi) = located.axis_range_mm?;
    job.process.turning()?;
    let (step_mm, mirror_odd) = match located.marks_mm {
        Some(mark) => (0.5 * mark, true),
        None => (0.25 * period, false),
    };
    let at = located.frame.shift_mm.dot(m.line_direction());
    let scale = located.frame.scale;
    let fine = |reach: f64| ((reach * scale / step_mm).floor().max(0.0) as usize).min(MAX_TEETH);
    let beyond = |reach: f64| reach * scale - fine(reach) as f64 * step_mm;
    let widest_beyond = beyond(at - lo).max(beyond(hi - at));
    let far_step_mm = if mirror_odd || widest_beyond <= step_mm {
        0.0
    } else {
        (FAR_STEPS * step_mm).max(widest_beyond / (MAX_TEETH as f64 - 0.5))
    };
    let teeth = |reach: f64| {
        let far = if far_step_mm > 0.0 {
            (beyond(reach) / far_step_mm).floor().max(0.0) as usize
        } else {
            0
        };
        fine(reach) + far.min(MAX_TEETH)
    };
    let comb = Comb {
        step_mm,
        below: teeth(at - lo),
        above: teeth(hi - at),
        mirror_odd,
        fine: MAX_TEETH,
        far_step_mm,
    };
    (comb.below + comb.above > 0).then_some(comb)
}

/// How far from the placed axis the comb's teeth reach (mm), for the simulated region.
fn comb_reach_mm(comb: Option<Comb>) -> f64 {
    comb.map_or(0.0, |c| c.reach_mm())
}

/// Keeps the points on the part; refuses a measurement mostly off it.
fn check_coverage(job: &Job, m: &Measurement) -> Result<Measurement, DiagnoseError> {
    if m.len() < 16 {
        return Err(DiagnoseError::DoesNotFit(format!(
            "only {} valid points (of {}); a diagnosis needs at least 16",
            m.len(),
            m.total_points
        )));
    }
    let (inner, outer) = (job.aperture.inner_radius_mm, job.aperture.outer_radius_mm);
    let on = |i: usize| {
        let r = m.xy_mm[i].length();
        r >= inner * 0.98 && r <= outer * 1.02
    };
    let count = (0..m.len()).filter(|&i| on(i)).count();
    if (count as f64) < 0.5 * m.len() as f64 || count < 16 {
        return Err(DiagnoseError::DoesNotFit(format!(
            "its points reach {:.4} mm from the axis over an extent of {:.4} mm, but the part spans r = {:.4}–{:.4} mm: only {count} of {} points lie on it (a lateral unit error, or another part?)",
            m.max_radius_mm(),
            m.extent_mm(),
            inner,
            outer,
            m.len()
        )));
    }
    Ok(m.subset(on))
}

/// The points to fit on when `--calibrate-on FROM:TO` holds the rest out (positions
/// along the profile, or X of a map, in the file's frame); None without a range.
fn calibration_mask(
    m: &Measurement,
    range: Option<(f64, f64)>,
) -> Result<Option<Arc<Vec<bool>>>, DiagnoseError> {
    let Some((from, to)) = range else {
        return Ok(None);
    };
    let mask: Vec<bool> = (0..m.len())
        .map(|i| (from..=to).contains(&m.file_position_mm(i).x))
        .collect();
    let fitted = mask.iter().filter(|k| **k).count();
    if fitted < 16 || m.len() - fitted < 16 {
        return Err(DiagnoseError::DoesNotFit(format!(
            "calibrating on {from}–{to} mm leaves {fitted} points to fit and {} held out; each needs at least 16",
            m.len() - fitted
        )));
    }
    Ok(Some(Arc::new(mask)))
}

/// A fitted effect (member `i` of a fit) as a result row.
fn effect_result(fit: &Fit, i: usize, rss0: f64) -> CandidateResult {
    let c = fit.set[i];
    let (values, sigmas) = fit.values_of(i);
    let span = fit.parameter_span(i);
    let at_bound = &fit.at_bound[span.clone()];
    let mut description = fit.describe(i);
    let order_sigma = fit.order_sigma(i);
    let at_limit = fit.parameters[span.clone()]
        .iter()
        .zip(values.iter())
        .find(|(p, v)| p.at_physical_limit(**v));
    if let Some((p, _)) = at_limit {
        description.push_str(&format!(
            " — at its physical limit ({} ≥ {} {}): the data asks for less, not a fit",
            p.name, p.lower, p.unit
        ));
    } else if at_bound.iter().any(|b| *b) {
        description.push_str(" — at the search bound, not a fit");
    }
    CandidateResult {
        effect: c.kind().into(),
        label: c.label(),
        order: c.order(),
        order_sigma,
        parameters: values
            .iter()
            .zip(sigmas)
            .zip(&fit.parameters[span])
            .zip(at_bound)
            .map(|(((v, s), p), b)| ParameterValue {
                name: p.name.into(),
                unit: p.unit.into(),
                value: *v,
                sigma: *s,
                bound: p.bound,
                lower_bound: p.is_one_sided().then_some(p.lower),
                at_bound: *b,
            })
            .collect(),
        description,
        advice: c.advice(values),
        rank: 0,
        accepted: true,
        delta_bic: 0.0,
        explained: 1.0 - fit.evaluation.rss() / rss0.max(1e-300),
    }
}

fn shrink_step(model: &str, residual: &[f64], radii: &[f64], zones: &Zones) -> ShrinkageStep {
    ShrinkageStep {
        model: model.into(),
        pv_nm: pv(residual) * 1e6,
        rms_nm: rms(residual) * 1e6,
        zones: zones.stats(radii, residual),
    }
}

/// The fits whose values the report states — the accepted set and the candidate
/// ranked first — refined as reported ([`refine_as_reported`]).
fn refine_reported(
    problem: &mut Problem,
    found: &mut Search,
    log: &dyn Fn(&str),
) -> Result<(), ForwardError> {
    log("refitting what is reported on rings half as far apart");
    if let Some(fit) = found.accepted.as_mut() {
        refine_as_reported(problem, fit)?;
    }
    let Some((first, _)) = found.singles.first_mut() else {
        return Ok(());
    };
    // The single ranked first is most often the accepted set itself, fitted alike.
    match &found.accepted {
        Some(accepted) if accepted.set == first.set => {
            first.values.clone_from(&accepted.values);
            first.sigmas.clone_from(&accepted.sigmas);
            first.at_bound.clone_from(&accepted.at_bound);
            first.order_sigmas.clone_from(&accepted.order_sigmas);
            Ok(())
        }
        _ => refine_as_reported(problem, first),
    }
}

/// `fit` as the report states it: refitted on rings half as far apart
/// ([`Problem::refine_on_finer_rings`]), a waviness order's σ widened to its profile
/// ([`Problem::widen_by_order_profile`]).
fn refine_as_reported(problem: &mut Problem, fit: &mut Fit) -> Result<(), ForwardError> {
    problem.refine_on_finer_rings(fit)?;
    problem.widen_by_order_profile(fit)
}

/// An accepted effect whose σ the finer rings widened (each σ is at least the move
/// between the two pitches' fits) until it no longer stands 3σ from zero is the forward
/// model's resolution, not the part's: it is withdrawn. What the search had accepted
/// before adding it (its last step without the doubtful effects) stands again, refined
/// and judged alike: a centre height that predicted both sides of the axis is not lost
/// with a partner the finer rings do not bear out.
fn withdraw_if_not_significant(
    problem: &mut Problem,
    found: &mut Search,
    log: &dyn Fn(&str),
) -> Result<(), ForwardError> {
    while let Some(accepted) = &found.accepted {
        let doubtful: Vec<Candidate> = accepted
            .effect_members()
            .into_iter()
            .filter(|&m| !search::significant(accepted, m))
            .map(|m| accepted.set[m])
            .collect();
        if doubtful.is_empty() {
            return Ok(());
        }
        let earlier = earlier_step_without(found, accepted, &doubtful);
        let why = "fitted again on rings half as far apart, it lies within 3σ of zero";
        withdraw(found, &doubtful, why, log);
        let Some(index) = earlier else {
            return Ok(());
        };
        found.steps.truncate(index + 1);
        let mut fit = found.steps[index].clone();
        log(&format!(
            "{} stands again, as accepted before",
            search::labels(&fit.effects())
        ));
        problem.search_from(fit.frame);
        refine_as_reported(problem, &mut fit)?;
        found.accepted = Some(fit);
    }
    Ok(())
}

/// The index of the last step of the search whose effects `accepted` holds, none of
/// `doubtful` among them, and at least one.
fn earlier_step_without(found: &Search, accepted: &Fit, doubtful: &[Candidate]) -> Option<usize> {
    let held = accepted.effects();
    found.steps.iter().rposition(|step| {
        let effects = step.effects();
        !effects.is_empty()
            && effects
                .iter()
                .all(|c| held.contains(c) && !doubtful.contains(c))
    })
}

/// Withdraws the accepted set, `why` given first in `refused` for each of `members`.
fn withdraw(found: &mut Search, members: &[Candidate], why: &str, log: &dyn Fn(&str)) {
    if let Some(accepted) = found.accepted.take() {
        log(&format!(
            "{} withdrawn: {why}",
            search::labels(&accepted.effects())
        ));
    }
    for c in members.iter().rev() {
        found.refused.insert(0, (c.label(), why.to_string()));
    }
}

/// Accepted effects whose gain lies in the marks' shape must leave none of that shape
/// unexplained: when the data's marks still differ from the fitted model's, beyond
/// chance and not by a sliver of the noise, the effects stand in for a shape they do
/// not model (material piled up beside the cusps read as spring-back, say), and
/// carrying them would not make the next part's marks right. They are withdrawn. An
/// accepted set that gains mostly elsewhere (a centre height's print at the axis) stays.
fn withdraw_if_marks_unexplained(
    found: &mut Search,
    (before, after): (Option<&MarkShape>, Option<&MarkShape>),
    analysis: &ResidualAnalysis,
    baseline: &Registered,
    log: &dyn Fn(&str),
) {
    let (Some(accepted), Some(shape), Some(before)) = (&found.accepted, after, before) else {
        return;
    };
    let after = &accepted.evaluation.registered;
    let noise_nm = white_noise_mm(analysis.measurement, &after.residual_mm) * 1e6;
    let energy_nm2 = |r: &Registered| (rms(&r.residual_mm) * 1e6).powi(2);
    let gain = energy_nm2(baseline) - energy_nm2(after);
    let gain_in_marks = before.rms_nm.powi(2) - shape.rms_nm.powi(2);
    if !shape.unexplained(noise_nm) || gain_in_marks < RESHAPES_MARKS * gain {
        return;
    }
    let effects = accepted.effects();
    let why = format!(
        "it reshapes the marks, yet with it fitted they still differ: {}",
        shape.describe()
    );
    withdraw(found, &effects, &why, log);
}

/// The marks' fold of `fit`'s residual as it is judged: with the model on rings half
/// as far apart (the model's own mark shape converges with its ring pitch), and the
/// fold of what halving the pitch changed as the model's remaining resolution error.
fn judged_mark_shape(
    problem: &mut Problem,
    analysis: &ResidualAnalysis,
    fit: &Fit,
) -> Result<Option<MarkShape>, ForwardError> {
    let coarse = &fit.evaluation.registered;
    if analysis.mark_shape(coarse).is_none() {
        return Ok(None);
    }
    let fine = problem.evaluate_on_finer_rings(fit)?;
    let fine = &fine.registered;
    let Some(mut shape) = analysis.mark_shape(fine) else {
        return Ok(None);
    };
    let change: Vec<f64> = coarse
        .residual_mm
        .iter()
        .zip(&fine.residual_mm)
        .map(|(a, b)| a - b)
        .collect();
    shape.model_error_nm = analysis
        .fold(fine, &change)
        .map_or(0.0, |c| c.rms_nm.max(0.0));
    Ok(Some(shape))
}

/// When the first candidate has rivals the data cannot tell from it, or another set of
/// effects explains the data as well as the accepted one (`found.alternative`), nothing
/// is accepted: acting on one of two causes that leave the same print is a coin toss
/// that may make the next part worse. Where the two sets share the effects of an
/// earlier step and differ only in what was added after it, that step stays accepted
/// (both explanations hold it). Returns the tied labels, the first first.
fn withdraw_if_ambiguous(found: &mut Search, rivals: &[String], log: &dyn Fn(&str)) -> Vec<String> {
    let Some(accepted) = &found.accepted else {
        return Vec::new();
    };
    let tied = if let Some(alternative) = &found.alternative {
        if let Some((shared, tied)) = shared_step(found, accepted, alternative) {
            log(&format!(
                "{} cannot be told apart on this measurement: {} (held by both) accepted",
                tied.join(", "),
                search::labels(&shared.effects())
            ));
            found.accepted = Some(shared);
            return tied;
        }
        search::distinct_labels(accepted, alternative).to_vec()
    } else {
        let Some((best, _)) = found.singles.first() else {
            return Vec::new();
        };
        let best = best.set[best.set.len() - 1];
        // A rival accepted beside the first is no rival: the set holds both prints.
        let held = |label: &String| accepted.effects().iter().any(|c| c.label() == *label);
        let rivals: Vec<String> = rivals.iter().filter(|r| !held(r)).cloned().collect();
        if rivals.is_empty() || accepted.effects().iter().all(|c| c.kind() != best.kind()) {
            return Vec::new();
        }
        std::iter::once(best.label()).chain(rivals).collect()
    };
    log(&format!(
        "{} cannot be told apart on this measurement: nothing accepted",
        tied.join(", ")
    ));
    found.accepted = None;
    tied
}

/// The tied explanations, each with its fit alone where there is one.
fn ties<'f>(found: &'f Search, ambiguous: &[String]) -> Vec<verdict::Tie<'f>> {
    ambiguous
        .iter()
        .map(|label| verdict::Tie {
            label: label.clone(),
            alone: found
                .singles
                .iter()
                .map(|(fit, _)| fit)
                .find(|fit| fit.set.last().is_some_and(|c| c.label() == *label)),
        })
        .collect()
}

/// Where the explanations the data cannot tell apart (`ambiguous`) put the axis (in the
/// placed frame): the withdrawn set and its tied alternative (`contenders`, taken
/// before the withdrawal) and each tied effect's fit alone. A decentre moves the axis
/// by up to its own size (independent batch k, draw k04: the decentre's fit 1.47
/// µm from the truth, the drift's beside it); while the data cannot choose, the axis σ
/// covers them all. Empty where nothing ties.
fn rival_axes(found: &Search, contenders: Vec<DVec2>, ambiguous: &[String]) -> Vec<DVec2> {
    if ambiguous.is_empty() {
        return Vec::new();
    }
    let tied_alone = found
        .singles
        .iter()
        .filter(|(fit, _)| {
            fit.set
                .last()
                .is_some_and(|c| ambiguous.contains(&c.label()))
        })
        .map(|(fit, _)| fit.evaluation.registered.shift_mm);
    contenders.into_iter().chain(tied_alone).collect()
}

/// The last accepted step whose effects both `accepted` and `alternative` hold (a
/// harmonic at orders a fraction apart held by both), when the two differ in nothing
/// else but effects added after it — by one of them at least (the other may be the step
/// itself: a further effect the data neither asks for nor rules out); with the labels
/// of those differing effects (accepted's first, an empty side left out).
fn shared_step(found: &Search, accepted: &Fit, alternative: &Fit) -> Option<(Fit, Vec<String>)> {
    let (a, b) = (accepted.effects(), alternative.effects());
    let shared: Vec<Candidate> = a
        .iter()
        .filter(|c| b.iter().any(|d| c.same_effect(d)))
        .copied()
        .collect();
    let step = found.steps.iter().rev().find(|step| {
        let held = step.effects();
        !held.is_empty() && held.iter().all(|c| shared.contains(c))
    })?;
    let held = step.effects();
    let beyond = |set: &[Candidate]| -> String {
        search::labels(
            &set.iter()
                .filter(|c| !held.iter().any(|h| h.same_effect(c)))
                .copied()
                .collect::<Vec<_>>(),
        )
    };
    let tied: Vec<String> = [beyond(&a), beyond(&b)]
        .into_iter()
        .filter(|t| !t.is_empty())
        .collect();
    if tied.is_empty() {
        return None;
    }
    // What the step holds moves as either further effect is added: its σ covers that.
    let mut step = step.clone();
    for member in step.effect_members() {
        let values = step.values_of(member).0.to_vec();
        let mut spread = vec![0.0_f64; values.len()];
        for other in [accepted, alternative] {
            if let Some(at) = other
                .set
                .iter()
                .position(|c| c.same_effect(&step.set[member]))
            {
                for (s, (v, w)) in spread
                    .iter_mut()
                    .zip(values.iter().zip(other.values_of(at).0))
                {
                    *s = s.max((v - w).abs());
                }
            }
        }
        search::widen_sigmas(&mut step, member, &spread);
    }
    Some((step, tied))
}

/// Candidates the data cannot tell from the best: evidence within [`TIE_EVIDENCE`] of
/// its ΔBIC (short of the conventional "strong" preference, Kass & Raftery 1995) and the
/// same print ([`search::SAME_PRINT`]).
fn indistinguishable(singles: &[(Fit, f64)], baseline: &Registered) -> Vec<String> {
    let Some((best, best_evidence)) = singles.first() else {
        return Vec::new();
    };
    singles[1..]
        .iter()
        .filter(|(f, evidence)| {
            *best_evidence > 0.0
                && (best_evidence - evidence).abs() < TIE_EVIDENCE
                && search::print_correlation(f, best, baseline) > search::SAME_PRINT
        })
        .map(|(f, _)| f.set[f.set.len() - 1].label())
        .collect()
}

/// Judges the fitted effects on the points held out from the fit, with and without
/// them (each trial registered on all the points, as every fit is).
fn judge_held_out(
    problem: &mut Problem,
    calibration: &[bool],
    base: &Fit,
    fit: Option<&Fit>,
) -> Result<HeldOut, DiagnoseError> {
    let m = problem.measurement;
    let held: Vec<usize> = (0..m.len()).filter(|&i| !calibration[i]).collect();
    let mut residual = |f: &Fit| -> Result<Vec<f64>, DiagnoseError> {
        problem.search_from(f.frame);
        let e = problem.evaluate(&f.set, &f.values)?;
        Ok(held.iter().map(|&i| e.registered.residual_mm[i]).collect())
    };
    let before = residual(base)?;
    let after = match fit {
        Some(f) => residual(f)?,
        None => before.clone(),
    };
    let (from, to) = held
        .iter()
        .map(|&i| m.file_position_mm(i).x)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    Ok(HeldOut {
        points: held.len(),
        from_mm: from,
        to_mm: to,
        before_pv_nm: pv(&before) * 1e6,
        before_rms_nm: rms(&before) * 1e6,
        after_pv_nm: pv(&after) * 1e6,
        after_rms_nm: rms(&after) * 1e6,
    })
}

/// The accepted effects as a job fragment (TOML), with a header saying where it came from.
fn effects_fragment(job: &Job, fit: Option<&Fit>) -> String {
    let mut text = format!(
        "# Effects fitted by `toolmark diagnose` for job \"{}\".\n# Use: toolmark run JOB --effects THIS_FILE (or compensate … --effects THIS_FILE).\n",
        job.name
    );
    match fit {
        Some(f) => {
            for i in f.effect_members() {
                text.push('\n');
                text.push_str(&f.set[i].effects_table(f.values_of(i).0));
            }
        }
        None => text.push_str("# No effect was accepted: nothing to carry over.\n"),
    }
    text
}

fn process_name(job: &Job) -> &'static str {
    match job.process {
        crate::process::Process::Turning(_) => "turning",
        crate::process::Process::Generating(_) => "generating",
        crate::process::Process::Milling(_) => "milling",
    }
}

fn term_names(terms: Terms) -> Vec<String> {
    let mut names = vec!["piston".to_string(), "tilt".to_string()];
    if terms.power {
        names.push("power".into());
    }
    if terms.shift {
        names.push("axis position (decentre)".into());
    }
    names
}

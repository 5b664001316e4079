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
pub mod files;
pub mod fit;
pub mod forward;
pub mod measurement;
pub mod register;
pub mod report;
pub mod withheld;
pub mod zones;

use crate::analysis::profile_stats::dominant_period_mm;
use crate::engine::RemovalEngine;
use crate::io::job::Job;
use candidates::{Candidate, NotDiagnosable, candidates_for};
use fit::{Fit, Problem, apply_set, bic, width};
use forward::{ForwardError, ForwardModel, SimulatedSurface, shift_room_mm};
use glam::DVec2;
use measurement::Measurement;
use register::{Registered, ShiftSearch, Terms, register};
use report::*;
use std::time::Instant;
use zones::{Zones, band_cutoffs, bands, gaussian_lowpass, pv, radii, rms, white_noise_mm};

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
    let on_part = check_coverage(job, measurement)?;
    let (fitted, held_out) = split(&on_part, options.calibrate_on_mm)?;
    let model = ForwardModel::new(job, &on_part, engine)?;
    let period = mark_period_mm(job, &fitted);

    // The nominal model, registered with a wide search for the axis.
    log("simulating the job as given and registering it");
    let wide = wide_search(&fitted, period);
    let mut problem = Problem::new(&fitted, model, options.terms, wide);
    let nominal_sim = problem.model.simulate(&|_| {}, &fitted)?;
    let nominal = register(&fitted, &nominal_sim, options.terms, Some(wide));
    // Fits re-solve the axis only near where the nominal model put it.
    problem.shift = local_search(nominal.shift_mm, period);
    let check = fit_check(&fitted, &nominal, job, options.terms, period);
    let zones = Zones::new(fitted.max_radius_mm());

    let (all_candidates, not_diagnosable) = candidates_for(job);
    let candidates: Vec<Candidate> = all_candidates
        .into_iter()
        .filter(|c| options.only.is_empty() || options.only.iter().any(|o| o == c.kind()))
        .collect();
    let mut singles: Vec<(Fit, f64)> = Vec::new();
    let mut steps: Vec<Fit> = Vec::new();
    let mut final_fit: Option<Fit> = None;
    if check.fits {
        let nominal_frame = problem.shift;
        let mut fits = fit_singles(&mut problem, &candidates, job, &fitted, log)?;
        // A strong effect the nominal model lacked can mislead the nominal registration
        // by whole mark periods: register again with each single effect, and refit it
        // around the axis it finds if that moved. Each effect is judged in its own
        // frame; the combinations then start from the best one's.
        let mut frames = vec![nominal_frame; fits.len()];
        for (fit, frame) in fits.iter_mut().zip(frames.iter_mut()) {
            let sim = problem
                .model
                .simulate(&|job| apply_set(&fit.set, &fit.values, job), &fitted)?;
            let again = register(&fitted, &sim, options.terms, Some(wide));
            if (again.shift_mm - nominal_frame.start).length() > 0.25 * period {
                log(&format!(
                    "{} moves the axis: registering again and refitting it",
                    fit.set[0].label()
                ));
                problem.shift = local_search(again.shift_mm, period);
                problem.clear_cache();
                if let Some(refit) = fit_new(&mut problem, &[], &[], fit.set[0], job, &fitted)?
                    && refit.evaluation.rss() < fit.evaluation.rss()
                {
                    *fit = refit;
                    *frame = problem.shift;
                }
            }
        }
        problem.shift = (0..fits.len())
            .min_by(|&a, &b| {
                fits[a]
                    .evaluation
                    .rss()
                    .total_cmp(&fits[b].evaluation.rss())
            })
            .map_or(nominal_frame, |best| frames[best]);
        problem.clear_cache();
        let rss0 = problem.evaluate(&[], &[])?.rss();
        let n_eff = common_effective_points(&fits, &*problem.evaluate(&[], &[])?, &fitted);
        singles = fits
            .into_iter()
            .map(|fit| {
                let e = evidence(rss0, 0, &fit, n_eff);
                (fit, e)
            })
            .collect();
        singles.sort_by(|a, b| b.1.total_cmp(&a.1));
        // Greedy: the strongest, then whatever adds most to what is accepted.
        let mut current: Option<Fit> = None;
        while current.as_ref().map_or(0, |c| c.set.len()) < options.max_effects {
            let taken: Vec<Candidate> = current.as_ref().map_or(Vec::new(), |f| f.set.clone());
            let mut round: Vec<Fit> = Vec::new();
            for (single, _) in &singles {
                let c = single.set[0];
                if taken.iter().any(|t| t.kind() == c.kind()) {
                    continue;
                }
                match &current {
                    None => round.push(single.clone()),
                    Some(cur) => {
                        log(&format!("fitting {} with {}", c.label(), labels(&cur.set)));
                        if let Some(fit) =
                            fit_new(&mut problem, &cur.set, &cur.values, c, job, &fitted)?
                        {
                            round.push(fit);
                        }
                    }
                }
            }
            let (rss_before, k_before) = current
                .as_ref()
                .map_or((rss0, 0), |f| (f.evaluation.rss(), f.values.len()));
            let n_eff = common_effective_points(&round, &*problem.evaluate(&[], &[])?, &fitted);
            let best = round
                .into_iter()
                .map(|fit| {
                    let e = evidence(rss_before, k_before, &fit, n_eff);
                    (fit, e)
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            match best {
                Some((fit, e))
                    if e > options.min_evidence && significant(&fit, fit.set.len() - 1) =>
                {
                    steps.push(fit.clone());
                    current = Some(fit);
                }
                _ => break,
            }
        }
        // One backward pass: an effect the others now explain is dropped.
        if let Some(cur) = current.clone().filter(|c| c.set.len() > 1) {
            for drop in 0..cur.set.len() {
                let rest: Vec<Candidate> = cur
                    .set
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != drop)
                    .map(|(_, c)| *c)
                    .collect();
                let start: Vec<f64> = (0..cur.set.len())
                    .filter(|i| *i != drop)
                    .flat_map(|i| cur.values_of(i).0.to_vec())
                    .collect();
                let reduced = problem.fit(&rest, start, &[])?;
                let e = evidence(
                    reduced.evaluation.rss(),
                    reduced.values.len(),
                    &cur,
                    cur.effective_points,
                );
                if e < options.min_evidence {
                    log(&format!(
                        "{} adds nothing beyond the others: dropped",
                        cur.set[drop].label()
                    ));
                    steps.push(reduced.clone());
                    current = Some(reduced);
                    break;
                }
            }
        }
        final_fit = current;
    }
    let baseline = problem.evaluate(&[], &[])?;
    let rss0 = baseline.rss();

    let after = final_fit
        .as_ref()
        .map_or(baseline.clone(), |f| f.evaluation.clone());
    let radii_fitted = radii(&fitted, nominal.shift_mm);
    let zone: Vec<usize> = radii_fitted.iter().map(|r| zones.of(*r)).collect();
    // The job as given, as well registered as the diagnosis managed: the wide search's
    // frame, or the final one when that fits it better.
    let mean_square = |r: &Registered| r.rss / r.used.max(1) as f64;
    let nominal = if mean_square(&baseline.registered) < mean_square(&nominal) {
        baseline.registered.clone()
    } else {
        nominal
    };
    let residual_before = nominal.residual_mm.clone();
    let residual_after = after.registered.residual_mm.clone();
    let (marks_cutoff, form_cutoff) = band_cutoffs(&fitted, Some(period));
    let analyse = |residual: &[f64], axis: DVec2| ResidualInfo {
        pv_nm: pv(residual) * 1e6,
        rms_nm: rms(residual) * 1e6,
        zones: zones.stats(&radii(&fitted, axis), residual),
        bands: bands(&fitted, residual, marks_cutoff, form_cutoff),
        azimuthal_orders: if fitted.is_line() {
            Vec::new()
        } else {
            zones::azimuthal_orders(&fitted, residual, axis)
        },
        white_noise_nm: white_noise_mm(&fitted, residual) * 1e6,
        correlation_length_points: zones::correlation_length(&fitted, residual),
    };
    let before_info = analyse(&residual_before, nominal.shift_mm);
    let after_info = analyse(&residual_after, after.registered.shift_mm);

    let candidate_results: Vec<CandidateResult> = singles
        .iter()
        .enumerate()
        .map(|(rank, (fit, evidence))| CandidateResult {
            rank: rank + 1,
            accepted: final_fit
                .as_ref()
                .is_some_and(|f| f.set.iter().any(|c| c.kind() == fit.set[0].kind())),
            delta_bic: *evidence,
            explained: 1.0 - fit.evaluation.rss() / rss0.max(1e-300),
            ..effect_result(fit, 0, rss0)
        })
        .collect();
    let accepted_results: Vec<CandidateResult> = final_fit
        .as_ref()
        .map(|f| {
            (0..f.set.len())
                .map(|i| effect_result(f, i, rss0))
                .collect()
        })
        .unwrap_or_default();

    let mut shrinkage = vec![shrink_step(
        "nominal job",
        &residual_before,
        &radii(&fitted, nominal.shift_mm),
        &zones,
    )];
    for step in &steps {
        shrinkage.push(shrink_step(
            &format!("+ {}", labels(&step.set)),
            &step.evaluation.registered.residual_mm,
            &radii(&fitted, step.evaluation.registered.shift_mm),
            &zones,
        ));
    }
    let indistinguishable = indistinguishable(&singles, &baseline.registered);

    let held = match (&held_out, check.fits) {
        (Some(held), true) => Some(judge_held_out(
            &mut problem.model,
            held,
            final_fit.as_ref(),
            options.terms,
            period,
        )?),
        _ => None,
    };
    let fragment = effects_fragment(job, final_fit.as_ref());
    let verdict = verdict(
        &check,
        final_fit.as_ref(),
        &before_info,
        &after_info,
        &indistinguishable,
        held.as_ref(),
    );
    let diagnosis = Diagnosis {
        schema: SCHEMA,
        toolmark_version: env!("CARGO_PKG_VERSION"),
        job: JobInfo {
            name: job.name.clone(),
            process: process_name(job).into(),
        },
        measurement: MeasurementInfo::of(&on_part, measurement, &fitted, held_out.as_ref()),
        registration: RegistrationInfo {
            terms: term_names(options.terms),
            nominal: nominal.registration,
            fitted: after.registered.registration,
        },
        fit_check: check,
        residual_before: before_info,
        residual_after: after_info,
        candidates: candidate_results,
        not_diagnosable,
        accepted: accepted_results,
        shrinkage,
        indistinguishable,
        held_out: held,
        verdict,
        run: RunInfo {
            engine: problem.model.engine_kind(),
            simulations: problem.model.simulations,
            prepare_s: problem.model.prepare_s,
            removal_s: problem.model.removal_s,
            total_s: started.elapsed().as_secs_f64(),
            mark_period_um: period * 1e3,
        },
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

/// Fits candidate `c` on top of `base` (at `base_values`); `None` when it cannot be
/// fitted here (waviness with no resolvable order).
fn fit_new(
    problem: &mut Problem,
    base: &[Candidate],
    base_values: &[f64],
    c: Candidate,
    job: &Job,
    fitted: &Measurement,
) -> Result<Option<Fit>, DiagnoseError> {
    let mut set = base.to_vec();
    let mut start = base_values.to_vec();
    let first = start.len();
    match c {
        // A waviness candidate not yet fitted: its order is screened first.
        Candidate::EdgeWaviness { order: 0.0 } => {
            let orders = waviness_orders(job, fitted);
            if orders.is_empty() {
                return Ok(None);
            }
            let Some((order, a, b)) = problem.screen_waviness(base, base_values, &orders, 20.0)?
            else {
                return Ok(None);
            };
            set.push(Candidate::EdgeWaviness { order });
            start.extend([a, b]);
            Ok(Some(problem.fit(&set, start, &[])?))
        }
        _ => {
            set.push(c);
            start.extend(std::iter::repeat_n(0.0, width(&c)));
            let scan: Vec<usize> = (first..start.len()).collect();
            Ok(Some(problem.fit(&set, start, &scan)?))
        }
    }
}

/// Every candidate fitted alone.
fn fit_singles(
    problem: &mut Problem,
    candidates: &[Candidate],
    job: &Job,
    fitted: &Measurement,
    log: &dyn Fn(&str),
) -> Result<Vec<Fit>, DiagnoseError> {
    let mut fits = Vec::new();
    for c in candidates {
        log(&format!("fitting {}", c.label()));
        if let Some(fit) = fit_new(problem, &[], &[], *c, job, fitted)? {
            fits.push(fit);
        }
    }
    Ok(fits)
}

/// The effective number of independent points for comparing models: from the
/// correlation of the residual the best of them leaves (closest to the noise), the
/// same for all so that no model is favoured by its own residual's texture.
fn common_effective_points(fits: &[Fit], baseline: &fit::Evaluation, m: &Measurement) -> f64 {
    let used = baseline.registered.used as f64;
    let tau = fits
        .iter()
        .min_by(|a, b| a.evaluation.rss().total_cmp(&b.evaluation.rss()))
        .map_or_else(
            || zones::correlation_length(m, &baseline.registered.residual_mm),
            |f| f.correlation_length,
        );
    used / tau
}

/// Evidence `fit` adds over a model leaving `rss_before` with `k_before` parameters.
fn evidence(rss_before: f64, k_before: usize, fit: &Fit, n_eff: f64) -> f64 {
    let used = fit.evaluation.registered.used;
    bic(rss_before, used, n_eff, k_before)
        - bic(fit.evaluation.rss(), used, n_eff, fit.values.len())
}

/// Whether member `member`'s parameters stand 3σ clear of zero together.
fn significant(fit: &Fit, member: usize) -> bool {
    let (values, sigmas) = fit.values_of(member);
    let z2: f64 = values
        .iter()
        .zip(sigmas)
        .map(|(v, s)| (v / s).powi(2))
        .sum();
    z2.sqrt() > 3.0
}

fn labels(set: &[Candidate]) -> String {
    set.iter()
        .map(Candidate::label)
        .collect::<Vec<_>>()
        .join(" + ")
}

/// Harmonic orders to screen for edge waviness: from half a cycle over the edge angles
/// the measured region uses to a wavelength of a quarter of one mark's contact, in
/// steps that shift the phase by at most a quarter cycle across the range (at most 40).
fn waviness_orders(job: &Job, m: &Measurement) -> Vec<f64> {
    let Some(turning) = job.process.turning() else {
        return Vec::new();
    };
    let nose = turning.tool.nose_radius_mm;
    let contact = (turning.path.pass_spacing_mm() / nose).max(0.01);
    let r_max = m.max_radius_mm().min(job.aperture.outer_radius_mm);
    let slope_angle = |r: f64| job.surface.slope(r).atan();
    let (lo, hi) = match turning.path.mode() {
        crate::process::TurningMode::Xz => {
            let samples = (0..=64).map(|i| slope_angle(r_max * i as f64 / 64.0));
            let (a, b) = samples.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            // A line through the axis meets both sides: the edge angle changes sign.
            if m.xy_mm.iter().any(|p| p.x < 0.0) || m.is_line() {
                (-(a.abs().max(b.abs())), a.abs().max(b.abs()))
            } else {
                (a, b)
            }
        }
        crate::process::TurningMode::Xzb => (0.0, 0.0),
    };
    let span = (hi - lo) + contact;
    let k_min = (std::f64::consts::PI / span).max(1.0);
    let k_max = (std::f64::consts::TAU / (0.25 * contact)).min(400.0);
    if k_max <= k_min {
        return Vec::new();
    }
    // A quarter cycle of phase across the range between neighbours, at most 30 orders
    // (the refinement between neighbours recovers what a coarser grid misses).
    let step = (0.5 * std::f64::consts::PI / span).max((k_max - k_min) / 30.0);
    let count = ((k_max - k_min) / step).floor() as usize + 1;
    (0..count).map(|i| k_min + i as f64 * step).collect()
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

/// The nominal registration's search: most of the simulation's room for a shift,
/// scanned at an eighth of the mark period (coarser on maps, whose scan is
/// two-dimensional).
fn wide_search(m: &Measurement, period: f64) -> ShiftSearch {
    let half = 0.8 * shift_room_mm(m);
    let step = if m.is_line() {
        (0.125 * period).max(half / 400.0)
    } else {
        (0.125 * period).max(half / 12.0)
    };
    ShiftSearch {
        start: DVec2::ZERO,
        half_width_mm: half,
        step_mm: step,
        refine: 3,
    }
}

/// A fit's search for the axis: within half a mark period of where the last
/// registration put it.
fn local_search(start: DVec2, period: f64) -> ShiftSearch {
    ShiftSearch {
        start,
        half_width_mm: 0.5 * period,
        step_mm: 0.125 * period,
        refine: 1,
    }
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

/// Splits into the fitted part and the held-out rest.
fn split(
    m: &Measurement,
    range: Option<(f64, f64)>,
) -> Result<(Measurement, Option<Measurement>), DiagnoseError> {
    let Some((from, to)) = range else {
        return Ok((m.clone(), None));
    };
    let position = |i: usize| {
        if m.is_line() {
            m.along_mm[i]
        } else {
            m.xy_mm[i].x
        }
    };
    let fitted = m.subset(|i| (from..=to).contains(&position(i)));
    let held = m.subset(|i| !(from..=to).contains(&position(i)));
    if fitted.len() < 16 || held.len() < 16 {
        return Err(DiagnoseError::DoesNotFit(format!(
            "calibrating on {from}–{to} mm leaves {} points to fit and {} held out; each needs at least 16",
            fitted.len(),
            held.len()
        )));
    }
    Ok((fitted, Some(held)))
}

/// Whether the measurement can be this job's part at all: its marks, its form.
fn fit_check(
    m: &Measurement,
    nominal: &Registered,
    job: &Job,
    terms: Terms,
    period: f64,
) -> FitCheck {
    let mut findings = Vec::new();
    let measured: Vec<f64> = m.height_mm.clone();
    let model = &nominal.model_mm;
    let used = nominal.used as f64 / m.len() as f64;
    if used < 0.9 {
        findings.push(Finding::note(format!(
            "{:.0} % of the points fall outside the simulated region after registration",
            100.0 * (1.0 - used)
        )));
    }
    // Form: the simulated surface's smooth variation (marks filtered out) against the
    // smooth part of what registration leaves.
    let smooth = |values: &[f64]| gaussian_lowpass(m, values, 5.0 * period);
    let detrend = |values: &[f64]| -> Vec<f64> {
        // Points the model does not cover (NaN) stay out of the fit.
        let zero: Vec<f64> = values.iter().map(|v| v * 0.0).collect();
        let flat = Measurement {
            height_mm: values.to_vec(),
            ..m.clone()
        };
        register::fit_linear(&flat, &zero, nominal.shift_mm, terms.power).residual_mm
    };
    let form_rms = rms(&smooth(&detrend(model)));
    let measured_rms = rms(&detrend(&measured));
    let measured_smooth_rms = rms(&smooth(&detrend(&measured)));
    let residual_rms = rms(&smooth(&nominal.residual_mm));
    let (mut mark_measured_um, mut mark_simulated_um) = (None, None);
    if m.is_line() && job.process.pass_spacing_mm().is_some() && m.extent_mm() > 30.0 * period {
        let high_pass = |values: &[f64]| -> Vec<f64> {
            let low = gaussian_lowpass(m, values, 5.0 * period);
            values.iter().zip(&low).map(|(v, l)| v - l).collect()
        };
        let (hm, hs) = (high_pass(&measured), high_pass(model));
        // Away from the ends, where the filter sees one side only.
        let (lo, hi) = m
            .along_mm
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        // Away from the centre too, where setup errors leave a feature of any width.
        let margin = 10.0 * period;
        let central = (20.0 * period).min(0.25 * m.max_radius_mm());
        let finite: Vec<usize> = (0..m.len())
            .filter(|&i| hm[i].is_finite() && hs[i].is_finite())
            .filter(|&i| m.along_mm[i] > lo + margin && m.along_mm[i] < hi - margin)
            .filter(|&i| (m.xy_mm[i] - nominal.shift_mm).length() > central)
            .collect();
        let pick = |v: &[f64]| finite.iter().map(|&i| v[i]).collect::<Vec<f64>>();
        let x = pick(&m.along_mm);
        let (ym, ys) = (pick(&hm), pick(&hs));
        // Looked for within a factor 3 of the process's own spacing: a lateral unit
        // error moves the marks out of that band altogether.
        let band = |y: &[f64]| dominant_period_mm(&x, y, period / 3.0, 3.0 * period);
        let (rms_m, rms_s) = (rms(&ym) * 1e6, rms(&ys) * 1e6);
        if let (Some(pm), Some(ps)) = (band(&ym), band(&ys))
            && rms_s > 0.5
            && x.len() > 16
        {
            mark_measured_um = Some(pm * 1e3);
            mark_simulated_um = Some(ps * 1e3);
            let ratio = pm / ps;
            if !(0.8..=1.25).contains(&ratio) {
                findings.push(Finding::severe(format!(
                    "the measured tool marks are {:.2} µm apart, the simulated {:.2} µm: not this feed, or the lateral unit is wrong",
                    pm * 1e3,
                    ps * 1e3
                )));
            }
            let amplitude = rms_m / rms_s;
            if !(1.0 / 30.0..=30.0).contains(&amplitude) {
                findings.push(Finding::severe(format!(
                    "the measured tool marks are {amplitude:.3}× as high as the simulated ({rms_m:.1} nm against {rms_s:.1} nm RMS): the height unit is wrong, or this is another process"
                )));
            }
        }
    }
    let noise = white_noise_mm(m, &nominal.residual_mm);
    let hint = if terms.power {
        ""
    } else {
        " — if the file's form was removed before export, diagnose with --remove power"
    };
    if let Some(marks) = job.process.pass_spacing_mm().filter(|s| *s > 0.0)
        && m.extent_mm() < 2.0 * marks
    {
        findings.push(Finding::severe(format!(
            "the measurement spans {:.3} µm, less than two tool marks ({:.2} µm apart): the lateral unit is wrong, or the region is too small to diagnose",
            m.extent_mm() * 1e3,
            marks * 1e3
        )));
    }
    // Setup errors leave micrometres at most on these parts; tens of micrometres of
    // smooth residual is another part or a unit error.
    if residual_rms > 5e-3 {
        findings.push(Finding::severe(format!(
            "the measured form departs from the simulated part's by {:.1} µm RMS: another part, or heights in the wrong unit",
            residual_rms * 1e3
        )));
    }
    // Judged only where the part has a form to follow (well above the noise).
    if form_rms > 5.0 * noise.max(1e-7) {
        if measured_smooth_rms > 30.0 * form_rms {
            findings.push(Finding::severe(format!(
                "the measured form varies {:.0}× as much as the simulated part's ({:.1} nm against {:.1} nm RMS): heights in the wrong unit, or another part",
                measured_smooth_rms / form_rms,
                measured_smooth_rms * 1e6,
                form_rms * 1e6
            )));
        } else if form_rms > 0.2 * measured_rms && residual_rms > 0.5 * form_rms {
            findings.push(Finding::severe(format!(
                "the measured surface does not follow the part's form: {:.1} nm RMS of smooth residual against {:.1} nm RMS of form (measured {:.1} nm RMS): another part, or heights in the wrong unit{hint}",
                residual_rms * 1e6,
                form_rms * 1e6,
                measured_rms * 1e6
            )));
        }
    }
    FitCheck {
        fits: findings.iter().all(|f| f.severity != "severe"),
        findings,
        form_rms_nm: form_rms * 1e6,
        measured_rms_nm: measured_rms * 1e6,
        mark_period_measured_um: mark_measured_um,
        mark_period_simulated_um: mark_simulated_um,
    }
}

/// A fitted effect (member `i` of a fit) as a result row.
fn effect_result(fit: &Fit, i: usize, rss0: f64) -> CandidateResult {
    let c = fit.set[i];
    let (values, sigmas) = fit.values_of(i);
    let start: usize = fit.set[..i].iter().map(width).sum();
    CandidateResult {
        effect: c.kind().into(),
        label: c.label(),
        order: match c {
            Candidate::EdgeWaviness { order } => Some(order),
            _ => None,
        },
        parameters: values
            .iter()
            .zip(sigmas)
            .zip(&fit.parameters[start..start + values.len()])
            .map(|((v, s), p)| ParameterValue {
                name: p.name.into(),
                unit: p.unit.into(),
                value: *v,
                sigma: *s,
            })
            .collect(),
        description: c.describe(values, sigmas),
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

/// Candidates the data cannot tell from the best: nearly the same evidence and nearly
/// the same change to the residual.
fn indistinguishable(singles: &[(Fit, f64)], baseline: &Registered) -> Vec<String> {
    let Some((best, best_evidence)) = singles.first() else {
        return Vec::new();
    };
    let change = |f: &Fit| -> Vec<f64> {
        f.evaluation
            .registered
            .residual_mm
            .iter()
            .zip(&baseline.residual_mm)
            .map(|(a, b)| {
                if a.is_finite() && b.is_finite() {
                    b - a
                } else {
                    0.0
                }
            })
            .collect()
    };
    let reference = change(best);
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    singles[1..]
        .iter()
        .filter(|(f, evidence)| {
            let other = change(f);
            let cos = reference
                .iter()
                .zip(&other)
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / (norm(&reference) * norm(&other)).max(1e-300);
            *best_evidence > 0.0
                && (best_evidence - evidence).abs() < 0.02 * best_evidence.abs() + 2.0
                && cos > 0.98
        })
        .map(|(f, _)| f.set[0].label())
        .collect()
}

/// Judges the fitted effects on the held-out points: each registered on its own
/// (metrology, not calibration), with and without the effects.
fn judge_held_out(
    model: &mut ForwardModel,
    held: &Measurement,
    fit: Option<&Fit>,
    terms: Terms,
    period: f64,
) -> Result<HeldOut, DiagnoseError> {
    let search = wide_search(held, period);
    let nominal: SimulatedSurface = model.simulate(&|_| {}, held)?;
    let before = register(held, &nominal, terms, Some(search));
    let after = match fit {
        Some(f) => {
            let apply = |job: &mut Job| {
                for i in 0..f.set.len() {
                    f.set[i].apply(f.values_of(i).0, job);
                }
            };
            let sim = model.simulate(&apply, held)?;
            register(held, &sim, terms, Some(search))
        }
        None => before.clone(),
    };
    let position = |i: usize| {
        if held.is_line() {
            held.along_mm[i]
        } else {
            held.xy_mm[i].x
        }
    };
    let (from, to) = (0..held.len()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), i| {
        (a.min(position(i)), b.max(position(i)))
    });
    Ok(HeldOut {
        points: held.len(),
        from_mm: from,
        to_mm: to,
        before_pv_nm: pv(&before.residual_mm) * 1e6,
        before_rms_nm: rms(&before.residual_mm) * 1e6,
        after_pv_nm: pv(&after.residual_mm) * 1e6,
        after_rms_nm: rms(&after.residual_mm) * 1e6,
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
            for i in 0..f.set.len() {
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

/// The one sentence first, then what to do.
fn verdict(
    check: &FitCheck,
    fit: Option<&Fit>,
    before: &ResidualInfo,
    after: &ResidualInfo,
    alternatives: &[String],
    held: Option<&HeldOut>,
) -> Verdict {
    if !check.fits {
        let why: Vec<&str> = check
            .findings
            .iter()
            .filter(|f| f.severity == "severe")
            .map(|f| f.message.as_str())
            .collect();
        return Verdict {
            status: "does_not_fit".into(),
            sentence: format!(
                "The measurement does not fit this job, so no effect is claimed: {}.",
                why.join("; ")
            ),
            advice: vec!["check the units, the part and the job before diagnosing".into()],
        };
    }
    let shrink = format!(
        "from {:.0} nm to {:.0} nm PV ({:.1} → {:.1} nm RMS)",
        before.pv_nm, after.pv_nm, before.rms_nm, after.rms_nm
    );
    match fit {
        Some(f) => {
            let parts: Vec<String> = (0..f.set.len())
                .map(|i| {
                    let (v, s) = f.values_of(i);
                    f.set[i].describe(v, s)
                })
                .collect();
            let mut sentence = capitalise(&parts.join("; "));
            let which = if f.set.len() == 1 {
                "correcting it"
            } else {
                "correcting them"
            };
            sentence.push_str(&format!("; {which} cuts the residual {shrink}."));
            if !alternatives.is_empty() {
                sentence.push_str(&format!(
                    " The data cannot tell this from: {}.",
                    alternatives.join(", ")
                ));
            }
            if let Some(h) = held {
                sentence.push_str(&format!(
                    " On the {} held-out points it cuts the residual from {:.1} to {:.1} nm RMS.",
                    h.points, h.before_rms_nm, h.after_rms_nm
                ));
            }
            Verdict {
                status: "effects_found".into(),
                sentence,
                advice: (0..f.set.len())
                    .map(|i| f.set[i].advice(f.values_of(i).0))
                    .collect(),
            }
        }
        None => {
            let noise = after.white_noise_nm;
            if after.rms_nm <= 2.0 * noise.max(1e-3) || after.correlation_length_points < 3.0 {
                Verdict {
                    status: "no_effect_beyond_noise".into(),
                    sentence: format!(
                        "No modelled effect explains the residual beyond noise: it is {:.1} nm RMS ({:.0} nm PV) against a noise level of {:.1} nm.",
                        after.rms_nm, after.pv_nm, noise
                    ),
                    advice: vec!["nothing to correct from this measurement".into()],
                }
            } else {
                let largest = |parts: &[zones::ZoneStats]| {
                    parts
                        .iter()
                        .max_by(|a, b| a.share.total_cmp(&b.share))
                        .map(|p| (p.name.clone(), 100.0 * p.share))
                };
                let zone = largest(&before.zones).map_or(String::new(), |(name, share)| {
                    format!("; most of it in the {name} ({share:.0} %)")
                });
                let band = largest(&before.bands).map_or(String::new(), |(name, share)| {
                    format!(" and the {name} band ({share:.0} %)")
                });
                Verdict {
                    status: "unexplained_residual".into(),
                    sentence: format!(
                        "No modelled effect explains the residual: {:.1} nm RMS ({:.0} nm PV) remains, well above the noise level of {:.1} nm{zone}{band}.",
                        after.rms_nm, after.pv_nm, noise
                    ),
                    advice: vec!["look for a cause outside the model (material, measurement, machine dynamics)".into()],
                }
            }
        }
    }
}

fn capitalise(text: &str) -> String {
    let mut chars = text.chars();
    match chars.next() {
        Some(c) => c.to_uppercase().chain(chars).collect(),
        None => String::new(),
    }
}

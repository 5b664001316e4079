//! Whether the measurement can be this job's part at all, before any verdict: its tool
//! marks (spacing band by band, height), its extent and its form. A lateral unit error
//! moves the marks' spacing far out of the program's; a height unit error scales their
//! height; another part leaves micrometres of smooth residual. Only such gross
//! mismatches refuse the data: a real cut whose marks are 10 % off is a gap to
//! diagnose, not a reason to refuse it.

use super::compare::Comparison;
use super::measurement::Measurement;
use super::register::{Registered, Terms, fit_linear, trimmed_mean_square};
use super::report::{Finding, FitCheck};
use super::zones::{gaussian_lowpass, rms, white_noise_mm};
use crate::model::Job;

/// Smooth residual, as a share of the part's form, above which the measurement does not
/// follow the form — unless a candidate effect explains it (see [`settle_form`]).
const DEPARTS: f64 = 0.5;

/// Share of the measured smooth variance the job's form must leave for a departure no
/// candidate settles to refuse the measurement: a part whose form the job takes a
/// fifth or more out of is this part with a gap to diagnose (a local bump as strong as
/// a weak form beyond power), not another part.
const FORM_LEAVES: f64 = 0.8;

/// How far the median mark spacing may differ from the job's before a note says so:
/// beyond the lateral scale's bound (2 %) and the bands' scatter (~1 %).
const SPACING_NOTE: f64 = 0.03;

/// Whether `m` (placed on the part; `nominal` the job registered to it) fits the job.
/// A departure from the form is left pending: a set-up error can leave more smooth
/// residual than the form itself has (a decentre's cone on a sphere whose power was
/// removed), which another part cannot explain away.
pub fn fit_check(
    m: &Measurement,
    nominal: &Registered,
    job: &Job,
    terms: Terms,
    period: f64,
    comparison: &Comparison,
) -> FitCheck {
    let mut findings = Vec::new();
    let model = &nominal.model_mm;
    let used = nominal.used as f64 / m.len() as f64;
    if used < 0.9 {
        findings.push(Finding::note(format!(
            "{:.0} % of the points fall outside the simulated region after registration",
            100.0 * (1.0 - used)
        )));
    }
    let smooth = |values: &[f64]| gaussian_lowpass(m, values, 5.0 * period);
    let detrend = |values: &[f64]| -> Vec<f64> {
        // Points the model does not cover (NaN) stay out of the fit.
        let zero: Vec<f64> = values.iter().map(|v| v * 0.0).collect();
        let flat = Measurement {
            height_mm: values.to_vec(),
            ..m.clone()
        };
        fit_linear(&flat, &zero, nominal.shift_mm, terms.power).residual_mm
    };
    let form_rms = rms(&smooth(&detrend(model)));
    let measured_rms = rms(&detrend(&m.height_mm));
    let measured_smooth_rms = rms(&smooth(&detrend(&m.height_mm)));
    let residual_rms = rms(&smooth(&nominal.residual_mm));
    if let Some(ratio) = comparison.mark_spacing_ratio {
        let bands = comparison.mark_spacing.len();
        if !(0.8..=1.25).contains(&ratio) {
            findings.push(Finding::severe(format!(
                "the measured tool marks are {ratio:.2}× as far apart as the job puts them (median over {bands} bands of radius): not this program, or the lateral unit is wrong"
            )));
        } else if (ratio - 1.0).abs() > SPACING_NOTE {
            findings.push(Finding::note(format!(
                "the measured tool marks lie {ratio:.3}× as far apart as the job puts them (median over {bands} bands of radius), more than the lateral scale's ±2 % takes: check the job's feed (`feed_per_rev_mm` is the contact point's radial advance per revolution) and the instrument's lateral calibration"
            )));
        }
    }
    if let Some(amplitude) = mark_amplitude_ratio(m, model, period)
        && !(1.0 / 30.0..=30.0).contains(&amplitude)
    {
        findings.push(Finding::severe(format!(
            "the measured tool marks are {amplitude:.3}× as high as the simulated: the height unit is wrong, or this is another process"
        )));
    }
    let noise = white_noise_mm(m, &nominal.residual_mm);
    let hint = if terms.power {
        ""
    } else {
        " — if the file's form was removed before export, diagnose with --remove-power"
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
            "the measured form departs from the simulated part's by {:.1} µm RMS: another part, or heights in the wrong unit{hint}",
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
        } else if form_rms > 0.2 * measured_rms && residual_rms > DEPARTS * form_rms {
            findings.push(Finding::pending(format!(
                "the measured surface does not follow the part's form: {:.1} nm RMS of smooth residual against {:.1} nm RMS of form (measured {:.1} nm RMS): another part, or heights in the wrong unit{hint}",
                residual_rms * 1e6,
                form_rms * 1e6,
                measured_rms * 1e6
            )));
        }
    }
    FitCheck {
        fits: only_notes(&findings),
        findings,
        form_rms_nm: form_rms * 1e6,
        measured_rms_nm: measured_rms * 1e6,
        smooth_residual_nm: residual_rms * 1e6,
        measured_smooth_nm: measured_smooth_rms * 1e6,
        mark_period_measured_um: None,
        mark_period_simulated_um: None,
    }
}

/// Settles a pending departure from the form once the candidates are fitted: where the
/// best-explaining candidate's residual (`fits`: label and residual of each candidate
/// fitted alone) follows the form — its smooth part within [`DEPARTS`] of it — the
/// departure was a set-up error and stays as a note; where none does but the job's form
/// leaves at most [`FORM_LEAVES`] of the measured smooth variance, it is a gap on this
/// part (a note); else the measurement does not fit the job.
pub fn settle_form(check: &mut FitCheck, m: &Measurement, period: f64, fits: &[(String, &[f64])]) {
    let Some(at) = check.findings.iter().position(|f| f.severity == "pending") else {
        return;
    };
    let best = fits
        .iter()
        .map(|(label, r)| (rms(&gaussian_lowpass(m, r, 5.0 * period)), label))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    let finding = &mut check.findings[at];
    match best.filter(|(left, _)| *left <= DEPARTS * check.form_rms_nm * 1e-6) {
        Some((left, label)) => {
            finding.severity = "note";
            finding.message = format!(
                "the job as given leaves {:.1} nm RMS of smooth residual against {:.1} nm RMS of form, but with a {label} fitted it follows the measured form ({:.1} nm left): a set-up error, not another part",
                check.smooth_residual_nm,
                check.form_rms_nm,
                left * 1e6
            );
        }
        None if check.smooth_residual_nm.powi(2)
            <= FORM_LEAVES * check.measured_smooth_nm.powi(2) =>
        {
            finding.severity = "note";
            finding.message = format!(
                "the job as given leaves {:.1} nm RMS of smooth residual against {:.1} nm RMS of form, and no candidate takes it below half the form; but the form takes {:.0} % of the measured smooth variance ({:.1} nm RMS) out: this part, with a gap no modelled effect explains",
                check.smooth_residual_nm,
                check.form_rms_nm,
                100.0 * (1.0 - (check.smooth_residual_nm / check.measured_smooth_nm).powi(2)),
                check.measured_smooth_nm
            );
        }
        None => finding.severity = "severe",
    }
    check.fits = only_notes(&check.findings);
}

/// The measurement fits the job: nothing severe, nothing pending.
fn only_notes(findings: &[Finding]) -> bool {
    findings.iter().all(|f| f.severity == "note")
}

/// Whether the candidates may be fitted: nothing severe (a pending departure from the
/// form is settled by them).
pub fn may_search(check: &FitCheck) -> bool {
    check.findings.iter().all(|f| f.severity != "severe")
}

/// The measured marks' RMS over the simulated marks' (both high-passed at five mark
/// periods, over the points the model covers, the largest tenth of each left out),
/// when the model has marks to compare.
fn mark_amplitude_ratio(m: &Measurement, model: &[f64], period: f64) -> Option<f64> {
    let covered: Vec<usize> = (0..m.len()).filter(|&i| model[i].is_finite()).collect();
    if covered.len() < 16 {
        return None;
    }
    let points = m.subset(|i| model[i].is_finite());
    let pick = |v: &[f64]| covered.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let high_pass = |values: &[f64]| -> Vec<f64> {
        let low = gaussian_lowpass(&points, values, 5.0 * period);
        values.iter().zip(&low).map(|(v, l)| v - l).collect()
    };
    // The bulk of the marks: a local feature (a centre height's boss, a scratch) a few
    // marks wide is not their height.
    let bulk = |values: &[f64]| trimmed_mean_square(values, 0.9).sqrt();
    let (measured, simulated) = (
        bulk(&high_pass(&pick(&m.height_mm))),
        bulk(&high_pass(&pick(model))),
    );
    (simulated > 0.5e-6).then(|| measured / simulated)
}

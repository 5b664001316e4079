//! Scoring the withheld suite against its sealed truth: the right effect, its size and
//! whether the stated σ covers it, where the axis was found, the lateral scale, nothing
//! claimed in controls, and unmodelled effects called unexplained.

use super::{Truth, TruthEffect, selected};
use serde::Serialize;
use std::path::Path;

/// How one case scored.
#[derive(Debug, Clone, Serialize)]
pub struct CaseScore {
    pub case: String,
    pub process: String,
    pub kind: String,
    pub truth: Vec<String>,
    /// The diagnosis's first-ranked candidate and what it accepted.
    pub ranked_first: Option<String>,
    pub accepted: Vec<String>,
    /// The verdict's status.
    pub status: String,
    /// Single: the first-ranked is the truth. Pair: both truths accepted. Control:
    /// nothing accepted. Unmodelled: nothing accepted and the gap called unexplained.
    pub right: bool,
    /// Per truth effect: relative parameter error and whether it is within 10 % (or
    /// within twice the fit's stated uncertainty).
    pub parameter_errors: Vec<f64>,
    pub parameters_within_10_percent: bool,
    pub parameters_within_bound: bool,
    /// Every truth effect within twice the fit's stated σ of the truth.
    pub parameters_within_2_sigma: bool,
    /// How far from the truth the diagnosis put the spindle axis (µm; in the plane for
    /// a map).
    pub axis_error_um: f64,
    /// The instrument's lateral scale as synth states it (file distance per true
    /// distance): found (the inverse of `registration.lateral_scale`) and true.
    pub lateral_scale: f64,
    pub lateral_scale_truth: f64,
    pub rms_before_nm: f64,
    pub rms_after_nm: f64,
    pub rms_reduction: f64,
    pub seconds: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Scores {
    pub cases: Vec<CaseScore>,
    pub singles: usize,
    pub singles_ranked_first: usize,
    pub singles_parameter_within_10_percent: usize,
    pub singles_parameter_within_bound: usize,
    pub effect_cases: usize,
    pub effect_cases_rms_reduced_80_percent: usize,
    pub pairs: usize,
    pub pairs_both_found: usize,
    pub controls: usize,
    pub controls_false_claims: usize,
    pub singles_within_2_sigma: usize,
    pub unmodelled: usize,
    pub unmodelled_unexplained: usize,
    pub axis_within_20_um: usize,
}

/// Opens the truth and the diagnoses and scores the `selected` cases.
pub fn score(dir: &Path, cases_selected: &[String]) -> Result<Scores, String> {
    let sealed = dir.join("sealed");
    let mut truths: Vec<Truth> = std::fs::read_dir(&sealed)
        .map_err(|e| format!("{}: {e}", sealed.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .map(|p| {
            let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
            serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))
        })
        .collect::<Result<_, String>>()?;
    truths.retain(|t| selected(&t.case, cases_selected));
    truths.sort_by(|a, b| a.case.cmp(&b.case));
    let mut cases = Vec::new();
    for truth in &truths {
        let path = dir
            .join("cases")
            .join(&truth.case)
            .join("diagnosis")
            .join("diagnosis.json");
        let diagnosis: serde_json::Value = std::fs::read_to_string(&path)
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or(serde_json::Value::Null);
        cases.push(score_case(truth, &diagnosis));
    }
    let singles: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "single").collect();
    let effect_cases: Vec<&CaseScore> = cases
        .iter()
        .filter(|c| matches!(c.kind.as_str(), "single" | "pair"))
        .collect();
    let pairs: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "pair").collect();
    let controls: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "control").collect();
    Ok(Scores {
        singles: singles.len(),
        singles_ranked_first: singles.iter().filter(|c| c.right).count(),
        singles_parameter_within_10_percent: singles
            .iter()
            .filter(|c| c.parameters_within_10_percent)
            .count(),
        singles_parameter_within_bound: singles
            .iter()
            .filter(|c| c.parameters_within_bound)
            .count(),
        effect_cases: effect_cases.len(),
        effect_cases_rms_reduced_80_percent: effect_cases
            .iter()
            .filter(|c| c.rms_reduction >= 0.8)
            .count(),
        pairs: pairs.len(),
        pairs_both_found: pairs.iter().filter(|c| c.right).count(),
        controls: controls.len(),
        controls_false_claims: controls.iter().filter(|c| !c.right).count(),
        singles_within_2_sigma: singles
            .iter()
            .filter(|c| c.parameters_within_2_sigma)
            .count(),
        unmodelled: cases.iter().filter(|c| c.kind == "unmodelled").count(),
        unmodelled_unexplained: cases
            .iter()
            .filter(|c| c.kind == "unmodelled" && c.right)
            .count(),
        axis_within_20_um: cases.iter().filter(|c| c.axis_error_um <= 20.0).count(),
        cases,
    })
}

fn score_case(truth: &Truth, d: &serde_json::Value) -> CaseScore {
    let names = |list: &serde_json::Value| -> Vec<String> {
        list.as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|c| c["effect"].as_str().map(String::from))
                    .collect()
            })
            .unwrap_or_default()
    };
    let ranked_first = names(&d["candidates"]).into_iter().next();
    let accepted = names(&d["accepted"]);
    let truth_names: Vec<String> = truth.effects.iter().map(|e| e.effect.clone()).collect();
    let status = d["verdict"]["status"]
        .as_str()
        .unwrap_or("none")
        .to_string();
    let right = match truth.kind.as_str() {
        "control" => accepted.is_empty(),
        "unmodelled" => accepted.is_empty() && status == "unexplained_residual",
        "single" => ranked_first.as_deref() == Some(truth_names[0].as_str()),
        _ => truth_names.iter().all(|t| accepted.contains(t)),
    };
    // The fitted values: from the accepted set when there, else the candidate alone.
    let fitted = |effect: &str| -> Option<(Vec<f64>, Vec<f64>, Option<f64>)> {
        let find = |list: &serde_json::Value| {
            list.as_array()?
                .iter()
                .find(|c| c["effect"].as_str() == Some(effect))
                .cloned()
        };
        let row = find(&d["accepted"]).or_else(|| find(&d["candidates"]))?;
        let params = row["parameters"].as_array()?;
        let values = params.iter().filter_map(|p| p["value"].as_f64()).collect();
        let sigmas = params
            .iter()
            .map(|p| p["sigma"].as_f64().unwrap_or(f64::INFINITY))
            .collect();
        Some((values, sigmas, row["order"].as_f64()))
    };
    let mut errors = Vec::new();
    let (mut within, mut bound, mut covered) = (true, true, true);
    for t in &truth.effects {
        match fitted(&t.effect) {
            Some((values, sigmas, order)) => {
                let (error, sigma_ratio) = parameter_error(t, &values, &sigmas, order);
                errors.push(error);
                within &= error <= 0.1;
                bound &= error <= 0.1 || sigma_ratio <= 2.0;
                covered &= sigma_ratio <= 2.0;
            }
            None => {
                errors.push(f64::INFINITY);
                (within, bound, covered) = (false, false, false);
            }
        }
    }
    let before = d["residual_before"]["rms_nm"].as_f64().unwrap_or(f64::NAN);
    let after = d["residual_after"]["rms_nm"].as_f64().unwrap_or(f64::NAN);
    let registration = &d["registration"];
    let axis = truth.measurement.decentre_um;
    let found = |key: &str| registration[key].as_f64().map(|mm| mm * 1e3);
    let axis_error_um = match (found("axis_x_mm"), found("axis_y_mm")) {
        (Some(x), Some(y)) => (x - axis[0]).hypot(y - axis[1]),
        (Some(x), None) => (x - axis[0]).abs(),
        _ => f64::INFINITY,
    };
    let effect_case = matches!(truth.kind.as_str(), "single" | "pair");
    CaseScore {
        case: truth.case.clone(),
        process: truth.process.clone(),
        kind: truth.kind.clone(),
        status,
        parameters_within_2_sigma: covered && effect_case,
        axis_error_um,
        lateral_scale: 1.0 / registration["lateral_scale"].as_f64().unwrap_or(f64::NAN),
        lateral_scale_truth: truth.measurement.lateral_scale,
        truth: truth_names,
        ranked_first,
        accepted,
        right,
        parameter_errors: errors,
        parameters_within_10_percent: within && effect_case,
        parameters_within_bound: bound && effect_case,
        rms_before_nm: before,
        rms_after_nm: after,
        rms_reduction: 1.0 - after / before,
        seconds: d["run"]["total_s"].as_f64().unwrap_or(f64::NAN),
    }
}

/// Relative error of a fitted effect against the truth (vector norm; waviness: the
/// amplitude, and the order must match within 5 %), and |error| in fitted sigmas.
fn parameter_error(
    t: &TruthEffect,
    values: &[f64],
    sigmas: &[f64],
    order: Option<f64>,
) -> (f64, f64) {
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if let (Some(truth_order), Some(fit_order)) = (t.order, order) {
        if (fit_order / truth_order - 1.0).abs() > 0.05 {
            return (f64::INFINITY, f64::INFINITY);
        }
        let (a_true, a_fit) = (norm(&t.values), norm(values));
        let sigma = norm(sigmas) / 2f64.sqrt();
        return (
            (a_fit - a_true).abs() / a_true,
            (a_fit - a_true).abs() / sigma,
        );
    }
    // Scored on the components the fit saw (σ finite): the others it reports as not seen.
    let seen: Vec<usize> = (0..values.len())
        .filter(|&j| sigmas[j].is_finite())
        .collect();
    let pick = |v: &[f64]| seen.iter().map(|&j| v[j]).collect::<Vec<f64>>();
    let (values, truth, sigmas) = (pick(values), pick(&t.values), pick(sigmas));
    if seen.is_empty() {
        return (f64::INFINITY, f64::INFINITY);
    }
    let mut difference: Vec<f64> = values.iter().zip(&truth).map(|(a, b)| a - b).collect();
    if t.effect == "radial_runout" {
        // Which tooth runs out is a shift of the marks by one feed per tooth, which the
        // registration of a slid profile absorbs: ε and −ε are the same measurement.
        let flipped: Vec<f64> = values.iter().zip(&truth).map(|(a, b)| a + b).collect();
        if norm(&flipped) < norm(&difference) {
            difference = flipped;
        }
    }
    let sigma = norm(&sigmas).max(1e-300);
    (
        norm(&difference) / norm(&truth).max(1e-300),
        norm(&difference) / sigma,
    )
}

/// The scores as a Markdown report: totals against the targets, then a table per effect.
pub fn scores_markdown(s: &Scores) -> String {
    let pct = |a: usize, b: usize| {
        if b == 0 {
            0.0
        } else {
            100.0 * a as f64 / b as f64
        }
    };
    let mut out = String::new();
    out += "| score | result | target |\n|---|---|---|\n";
    out += &format!(
        "| right effect ranked first (single-effect cases) | {}/{} = {:.1} % | ≥ 95 % |\n",
        s.singles_ranked_first,
        s.singles,
        pct(s.singles_ranked_first, s.singles)
    );
    out += &format!(
        "| fitted parameter within 10 % (single) | {}/{} = {:.1} % | |\n",
        s.singles_parameter_within_10_percent,
        s.singles,
        pct(s.singles_parameter_within_10_percent, s.singles)
    );
    out += &format!(
        "| … within 10 % or 2σ of the fit's noise bound | {}/{} = {:.1} % | |\n",
        s.singles_parameter_within_bound,
        s.singles,
        pct(s.singles_parameter_within_bound, s.singles)
    );
    out += &format!(
        "| truth within 2σ of the fit (single) | {}/{} = {:.1} % | ≥ 90 % |\n",
        s.singles_within_2_sigma,
        s.singles,
        pct(s.singles_within_2_sigma, s.singles)
    );
    out += &format!(
        "| unmodelled effect called unexplained, nothing claimed | {}/{} = {:.1} % | ≥ 90 % |\n",
        s.unmodelled_unexplained,
        s.unmodelled,
        pct(s.unmodelled_unexplained, s.unmodelled)
    );
    out += &format!(
        "| spindle axis found within 20 µm (all cases) | {}/{} = {:.1} % | |\n",
        s.axis_within_20_um,
        s.cases.len(),
        pct(s.axis_within_20_um, s.cases.len())
    );
    out += &format!(
        "| residual RMS reduced ≥ 80 % (cases with an effect) | {}/{} = {:.1} % | |\n",
        s.effect_cases_rms_reduced_80_percent,
        s.effect_cases,
        pct(s.effect_cases_rms_reduced_80_percent, s.effect_cases)
    );
    out += &format!(
        "| both effects found (pairs) | {}/{} | |\n",
        s.pairs_both_found, s.pairs
    );
    out += &format!(
        "| false effect claimed (controls) | {}/{} | 0 |\n\n",
        s.controls_false_claims, s.controls
    );
    out += "| effect | cases | ranked first | parameter within 10 % | median parameter error | median RMS reduction |\n|---|---|---|---|---|---|\n";
    let mut effects: Vec<String> = s
        .cases
        .iter()
        .filter(|c| c.kind == "single")
        .map(|c| c.truth[0].clone())
        .collect();
    effects.sort();
    effects.dedup();
    for e in effects {
        let rows: Vec<&CaseScore> = s
            .cases
            .iter()
            .filter(|c| c.kind == "single" && c.truth[0] == e)
            .collect();
        let mut errors: Vec<f64> = rows.iter().map(|c| c.parameter_errors[0]).collect();
        let mut reductions: Vec<f64> = rows.iter().map(|c| c.rms_reduction).collect();
        errors.sort_by(f64::total_cmp);
        reductions.sort_by(f64::total_cmp);
        out += &format!(
            "| {e} | {} | {} | {} | {:.1} % | {:.1} % |\n",
            rows.len(),
            rows.iter().filter(|c| c.right).count(),
            rows.iter()
                .filter(|c| c.parameters_within_10_percent)
                .count(),
            100.0 * errors[errors.len() / 2],
            100.0 * reductions[reductions.len() / 2]
        );
    }
    out += "\n| case | truth | status | ranked first | accepted | parameter error | axis error (µm) | lateral scale (truth) | RMS before → after (nm) | s |\n|---|---|---|---|---|---|---|---|---|---|\n";
    for c in &s.cases {
        let errors: Vec<String> = c
            .parameter_errors
            .iter()
            .map(|e| format!("{:.1} %", 100.0 * e))
            .collect();
        out += &format!(
            "| {} | {} | {} | {} | {} | {} | {:.1} | {:.4} ({:.4}) | {:.1} → {:.1} | {:.1} |\n",
            c.case,
            if c.truth.is_empty() {
                "—".into()
            } else {
                c.truth.join(" + ")
            },
            c.status,
            c.ranked_first.as_deref().unwrap_or("—"),
            if c.accepted.is_empty() {
                "—".into()
            } else {
                c.accepted.join(" + ")
            },
            errors.join(", "),
            c.axis_error_um,
            c.lateral_scale,
            c.lateral_scale_truth,
            c.rms_before_nm,
            c.rms_after_nm,
            c.seconds
        );
    }
    out
}

//! Scoring the withheld suite against its sealed truth: the right effect, its size and
//! whether the stated σ covers it, where the axis was found, the lateral scale, nothing
//! claimed in controls, and unmodelled effects called unexplained; per process, a
//! confusion matrix of the truth against what the diagnosis claimed first, and for
//! each pair of effects whether each was found.

use super::{Truth, TruthEffect, selected};
use crate::diagnose::candidates::pair_sigma;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// What a diagnosis that claims no effect says instead: the gap unexplained, or nothing
/// beyond noise (or no fit, no diagnosis).
pub const UNEXPLAINED: &str = "unexplained";
pub const NONE: &str = "none";

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
    /// The effect the diagnosis claimed first (its highest-ranked accepted candidate);
    /// with none accepted, [`UNEXPLAINED`] when the verdict calls the gap unexplained,
    /// else [`NONE`].
    pub claimed_first: String,
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
    /// Per truth effect: the fit's distance from the truth in its stated σ.
    pub sigma_ratios: Vec<f64>,
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
    /// The unmodelled effects the measurement added (their kinds).
    pub unmodelled: Vec<String>,
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
    /// Per process: the truth of each single, control and unmodelled case against what
    /// the diagnosis claimed first.
    pub confusion: Vec<Confusion>,
    /// Per process and pair of effects: how often each was found.
    pub pairs_found: Vec<PairFound>,
}

/// One process's confusion matrix: `counts[row][column]` cases whose truth is `rows[row]`
/// (a single-effect case's effect, "control", or "unmodelled: <kind>") and whose
/// diagnosis claimed `columns[column]` first (an effect, [`UNEXPLAINED`] or [`NONE`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Confusion {
    pub process: String,
    pub rows: Vec<String>,
    pub columns: Vec<String>,
    pub counts: Vec<Vec<usize>>,
}

/// The pair cases of one process with the same two true effects: how many there are,
/// in how many each effect was found (accepted), and both.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairFound {
    pub process: String,
    pub effects: [String; 2],
    pub cases: usize,
    pub found: [usize; 2],
    pub both: usize,
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
    Ok(scores_of(cases))
}

/// The totals, the confusion matrices and the pair table of scored cases.
fn scores_of(cases: Vec<CaseScore>) -> Scores {
    let singles: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "single").collect();
    let effect_cases: Vec<&CaseScore> = cases
        .iter()
        .filter(|c| matches!(c.kind.as_str(), "single" | "pair"))
        .collect();
    let pairs: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "pair").collect();
    let controls: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "control").collect();
    Scores {
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
        confusion: confusion(&cases),
        pairs_found: pairs_found(&cases),
        cases,
    }
}

/// A case's row in its process's confusion matrix (`None`: a pair, tabled apart).
fn confusion_row(c: &CaseScore) -> Option<String> {
    match c.kind.as_str() {
        "single" => c.truth.first().cloned(),
        "control" => Some("control".into()),
        "unmodelled" => Some(if c.unmodelled.is_empty() {
            "unmodelled".into()
        } else {
            format!("unmodelled: {}", c.unmodelled.join(" + "))
        }),
        _ => None,
    }
}

/// Per process (in name order): rows the true effects (by name), then "control", then
/// the unmodelled kinds; columns the true effects in the same order (so that right
/// claims lie on the diagonal), then other effects claimed, then [`UNEXPLAINED`] and
/// [`NONE`].
fn confusion(cases: &[CaseScore]) -> Vec<Confusion> {
    let mut by_process: BTreeMap<&str, Vec<(String, &str)>> = BTreeMap::new();
    for c in cases {
        if let Some(row) = confusion_row(c) {
            by_process
                .entry(c.process.as_str())
                .or_default()
                .push((row, c.claimed_first.as_str()));
        }
    }
    by_process
        .into_iter()
        .map(|(process, entries)| {
            let rank = |row: &str| match row {
                "control" => 1,
                r if r.starts_with("unmodelled") => 2,
                _ => 0,
            };
            let mut rows: Vec<String> = entries.iter().map(|(r, _)| r.clone()).collect();
            rows.sort_by(|a, b| (rank(a), a).cmp(&(rank(b), b)));
            rows.dedup();
            let mut columns: Vec<String> = rows.iter().filter(|r| rank(r) == 0).cloned().collect();
            let mut others: Vec<String> = entries
                .iter()
                .map(|(_, claimed)| claimed.to_string())
                .filter(|c| !columns.contains(c) && c != UNEXPLAINED && c != NONE)
                .collect();
            others.sort();
            others.dedup();
            columns.extend(others);
            columns.extend([UNEXPLAINED.to_string(), NONE.to_string()]);
            let mut counts = vec![vec![0; columns.len()]; rows.len()];
            for (row, claimed) in &entries {
                let i = rows.iter().position(|r| r == row).unwrap_or(0);
                let j = columns.iter().position(|c| c == claimed).unwrap_or(0);
                counts[i][j] += 1;
            }
            Confusion {
                process: process.to_string(),
                rows,
                columns,
                counts,
            }
        })
        .collect()
}

/// The pair cases grouped by process and their two true effects (in suite order).
fn pairs_found(cases: &[CaseScore]) -> Vec<PairFound> {
    let mut groups: BTreeMap<(String, [String; 2]), PairFound> = BTreeMap::new();
    for c in cases
        .iter()
        .filter(|c| c.kind == "pair" && c.truth.len() == 2)
    {
        let effects = [c.truth[0].clone(), c.truth[1].clone()];
        let entry = groups
            .entry((c.process.clone(), effects.clone()))
            .or_insert_with(|| PairFound {
                process: c.process.clone(),
                effects,
                cases: 0,
                found: [0, 0],
                both: 0,
            });
        let found = [0, 1].map(|k| c.accepted.contains(&c.truth[k]));
        entry.cases += 1;
        for (count, was) in entry.found.iter_mut().zip(found) {
            *count += usize::from(was);
        }
        entry.both += usize::from(found[0] && found[1]);
    }
    groups.into_values().collect()
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
    let claimed = d["candidates"].as_array().and_then(|list| {
        list.iter()
            .find(|c| c["accepted"].as_bool() == Some(true))
            .and_then(|c| c["effect"].as_str())
    });
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
    let (mut errors, mut sigma_ratios) = (Vec::new(), Vec::new());
    let (mut within, mut bound) = (true, true);
    for t in &truth.effects {
        match fitted(&t.effect) {
            Some((values, sigmas, order)) => {
                let line =
                    truth.measurement.kind == crate::diagnose::synth::MeasurementKind::Profile;
                let (error, sigma_ratio) = parameter_error(t, &values, &sigmas, order, line);
                errors.push(error);
                sigma_ratios.push(sigma_ratio);
                within &= error <= 0.1;
                bound &= error <= 0.1 || sigma_ratio <= 2.0;
            }
            None => {
                errors.push(f64::INFINITY);
                sigma_ratios.push(f64::INFINITY);
                (within, bound) = (false, false);
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
    let claimed_first = match (claimed, accepted.first()) {
        (Some(effect), _) => effect.to_string(),
        (None, Some(effect)) => effect.clone(),
        (None, None) if status == "unexplained_residual" => UNEXPLAINED.into(),
        (None, None) => NONE.into(),
    };
    CaseScore {
        claimed_first,
        unmodelled: truth
            .measurement
            .unmodelled
            .iter()
            .map(|u| u.name().to_string())
            .collect(),
        case: truth.case.clone(),
        process: truth.process.clone(),
        kind: truth.kind.clone(),
        status,
        parameters_within_2_sigma: effect_case && sigma_ratios.iter().all(|r| *r <= 2.0),
        sigma_ratios,
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

/// Whether a fitted harmonic order matches the truth's: within 5 %; a vibration's rate
/// along a profile within 0.01 cycles per revolution of one of its aliases (a line sees
/// the cut clock at one or two spindle angles only, so k ± 1 and 1 − k leave the same
/// trace, the phase mirrored for the latter).
fn orders_match(effect: &str, truth: f64, fit: f64, line: bool) -> bool {
    if effect == "vibration" && line {
        let near_whole = |x: f64| {
            let d = x.rem_euclid(1.0);
            d.min(1.0 - d) <= 0.01
        };
        return near_whole(fit - truth) || near_whole(fit + truth);
    }
    (fit / truth - 1.0).abs() <= 0.05
}

/// Relative error of a fitted effect against the truth (vector norm; harmonics: the
/// amplitude, the order matching as [`orders_match`] says), and |error| in fitted sigmas.
fn parameter_error(
    t: &TruthEffect,
    values: &[f64],
    sigmas: &[f64],
    order: Option<f64>,
    line: bool,
) -> (f64, f64) {
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if let (Some(truth_order), Some(fit_order)) = (t.order, order) {
        if !orders_match(&t.effect, truth_order, fit_order, line) {
            return (f64::INFINITY, f64::INFINITY);
        }
        let (a_true, a_fit) = (norm(&t.values), norm(values));
        let sigma = pair_sigma(values, sigmas);
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
    out += &confusion_markdown(s);
    out += "\n| case | truth | status | ranked first | accepted | parameter error | error / σ | axis error (µm) | lateral scale (truth) | RMS before → after (nm) | s |\n|---|---|---|---|---|---|---|---|---|---|---|\n";
    for c in &s.cases {
        let errors: Vec<String> = c
            .parameter_errors
            .iter()
            .map(|e| format!("{:.1} %", 100.0 * e))
            .collect();
        let ratios: Vec<String> = c.sigma_ratios.iter().map(|r| format!("{r:.1}")).collect();
        out += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {:.1} | {:.4} ({:.4}) | {:.1} → {:.1} | {:.1} |\n",
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
            ratios.join(", "),
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

/// The confusion matrices (a zero as "·") and the pair table, as Markdown.
fn confusion_markdown(s: &Scores) -> String {
    let mut out = String::new();
    for m in &s.confusion {
        out += &format!(
            "\n**Confusion, {}** (rows: the truth; columns: the effect the diagnosis claimed first)\n\n| truth \\ claimed | {} |\n|---|{}\n",
            m.process,
            m.columns.join(" | "),
            "---|".repeat(m.columns.len())
        );
        for (row, counts) in m.rows.iter().zip(&m.counts) {
            let cells: Vec<String> = counts
                .iter()
                .map(|&n| if n == 0 { "·".into() } else { n.to_string() })
                .collect();
            out += &format!("| {row} | {} |\n", cells.join(" | "));
        }
    }
    if !s.pairs_found.is_empty() {
        out += "\n**Pairs** (each effect found: accepted by the diagnosis)\n\n| process | effect A | A found | effect B | B found | both found | cases |\n|---|---|---|---|---|---|---|\n";
        for p in &s.pairs_found {
            out += &format!(
                "| {} | {} | {} | {} | {} | {} | {} |\n",
                p.process, p.effects[0], p.found[0], p.effects[1], p.found[1], p.both, p.cases
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_profile_knows_a_vibration_rate_modulo_its_aliases_and_a_map_knows_it_whole() {
        // Along one azimuth the clock is 2πm (+ π on the far side): 3.37, 0.37 and
        // 1 − 0.37 = 0.63 cycles per revolution leave the same trace; 0.5 does not.
        assert!(orders_match("vibration", 3.37, 0.63, true));
        assert!(orders_match("vibration", 3.37, 0.374, true));
        assert!(!orders_match("vibration", 3.37, 0.5, true));
        assert!(!orders_match("vibration", 3.37, 0.37, false));
        assert!(orders_match("edge_waviness", 30.0, 31.0, true));
        assert!(!orders_match("edge_waviness", 30.0, 32.0, true));
    }

    /// A truth record: `effects` the true effect names, `unmodelled` a chatter added.
    fn truth(case: &str, process: &str, kind: &str, effects: &[&str], unmodelled: bool) -> Truth {
        let mut text = "kind = \"profile\"\n".to_string();
        if unmodelled {
            text +=
                "[[unmodelled]]\nkind = \"chatter\"\namplitude_nm = 8.0\nper_revolution = 3.37\n";
        }
        Truth {
            case: case.into(),
            process: process.into(),
            kind: kind.into(),
            effects: effects
                .iter()
                .map(|e| TruthEffect {
                    effect: e.to_string(),
                    values: vec![1.0],
                    order: None,
                })
                .collect(),
            effects_toml: String::new(),
            measurement: toml::from_str(&text).unwrap(),
        }
    }

    /// A diagnosis record: the candidates in rank order with whether each was accepted.
    fn diagnosis(candidates: &[(&str, bool)], status: &str) -> serde_json::Value {
        let row =
            |e: &str, accepted: bool| json!({"effect": e, "accepted": accepted, "parameters": []});
        json!({
            "candidates": candidates.iter().map(|(e, a)| row(e, *a)).collect::<Vec<_>>(),
            "accepted": candidates.iter().filter(|(_, a)| *a).map(|(e, _)| row(e, true)).collect::<Vec<_>>(),
            "verdict": {"status": status},
        })
    }

    #[test]
    fn the_confusion_matrix_counts_each_truth_against_the_effect_claimed_first() {
        let found = "effects_found";
        let records = [
            // Turning singles: centre height claimed twice, once as a decentre (ranked
            // first and accepted); a nose radius ranked first but not accepted (none);
            // a drift claimed below a rejected waviness (the claim counts, not the rank).
            (
                truth("01", "turning", "single", &["centre_height"], false),
                diagnosis(&[("centre_height", true)], found),
            ),
            (
                truth("02", "turning", "single", &["centre_height"], false),
                diagnosis(&[("centre_height", true), ("axial_drift", false)], found),
            ),
            (
                truth("03", "turning", "single", &["centre_height"], false),
                diagnosis(&[("x_decentre", true), ("centre_height", false)], found),
            ),
            (
                truth("04", "turning", "single", &["nose_radius_error"], false),
                diagnosis(&[("nose_radius_error", false)], "no_effect_beyond_noise"),
            ),
            (
                truth("05", "turning", "single", &["axial_drift"], false),
                diagnosis(&[("edge_waviness", false), ("axial_drift", true)], found),
            ),
            // Controls: one clean, one false claim; chatter called unexplained.
            (
                truth("06", "turning", "control", &[], false),
                diagnosis(&[("axial_drift", false)], "no_effect_beyond_noise"),
            ),
            (
                truth("07", "turning", "control", &[], false),
                diagnosis(&[("axial_drift", true)], found),
            ),
            (
                truth("08", "turning", "unmodelled", &[], true),
                diagnosis(&[("axial_drift", false)], "unexplained_residual"),
            ),
            // Pairs: centre height + nose radius twice (one found, then both), decentre +
            // drift once (the drift found).
            (
                truth(
                    "09",
                    "turning",
                    "pair",
                    &["centre_height", "nose_radius_error"],
                    false,
                ),
                diagnosis(&[("centre_height", true)], found),
            ),
            (
                truth(
                    "10",
                    "turning",
                    "pair",
                    &["centre_height", "nose_radius_error"],
                    false,
                ),
                diagnosis(
                    &[("nose_radius_error", true), ("centre_height", true)],
                    found,
                ),
            ),
            (
                truth(
                    "11",
                    "turning",
                    "pair",
                    &["x_decentre", "axial_drift"],
                    false,
                ),
                diagnosis(&[("axial_drift", true)], found),
            ),
            // Milling: one right claim, and a control with no diagnosis at all.
            (
                truth("12", "milling", "single", &["tool_radius_error"], false),
                diagnosis(&[("tool_radius_error", true)], found),
            ),
            (
                truth("13", "milling", "control", &[], false),
                serde_json::Value::Null,
            ),
        ];
        let scores = scores_of(records.iter().map(|(t, d)| score_case(t, d)).collect());
        let turning = Confusion {
            process: "turning".into(),
            rows: [
                "axial_drift",
                "centre_height",
                "nose_radius_error",
                "control",
                "unmodelled: chatter",
            ]
            .map(String::from)
            .to_vec(),
            columns: [
                "axial_drift",
                "centre_height",
                "nose_radius_error",
                "x_decentre",
                "unexplained",
                "none",
            ]
            .map(String::from)
            .to_vec(),
            counts: vec![
                vec![1, 0, 0, 0, 0, 0],
                vec![0, 2, 0, 1, 0, 0],
                vec![0, 0, 0, 0, 0, 1],
                vec![1, 0, 0, 0, 0, 1],
                vec![0, 0, 0, 0, 1, 0],
            ],
        };
        let milling = Confusion {
            process: "milling".into(),
            rows: vec!["tool_radius_error".into(), "control".into()],
            columns: ["tool_radius_error", "unexplained", "none"]
                .map(String::from)
                .to_vec(),
            counts: vec![vec![1, 0, 0], vec![0, 0, 1]],
        };
        assert_eq!(scores.confusion, vec![milling, turning]);
        let pair = |a: &str, b: &str, cases, found, both| PairFound {
            process: "turning".into(),
            effects: [a.into(), b.into()],
            cases,
            found,
            both,
        };
        assert_eq!(
            scores.pairs_found,
            vec![
                pair("centre_height", "nose_radius_error", 2, [2, 1], 1),
                pair("x_decentre", "axial_drift", 1, [0, 1], 0),
            ]
        );
        // "Ranked first" (the older score) counts case 04 right and 05 wrong; the matrix
        // counts what was claimed: 01, 02, 05 and 12 on its diagonals.
        assert_eq!((scores.singles, scores.singles_ranked_first), (6, 4));
        let markdown = scores_markdown(&scores);
        println!("{markdown}");
        assert!(
            markdown.contains("| centre_height | · | 2 | · | 1 | · | · |"),
            "{markdown}"
        );
        assert!(
            markdown.contains("| turning | centre_height | 2 | nose_radius_error | 1 | 1 | 2 |")
        );
        let value = serde_json::to_value(&scores).unwrap();
        assert_eq!(
            value["confusion"][1]["counts"][3],
            json!([1, 0, 0, 0, 0, 1])
        );
        assert_eq!(value["cases"][2]["claimed_first"], json!("x_decentre"));
    }
}

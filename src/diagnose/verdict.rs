//! The verdict: one sentence first, then what to do at the machine. An effect is named
//! only when it was accepted (it predicts data it was not fitted on); when what is
//! accepted leaves most of the gap standing, or nothing is accepted while the residual
//! stands well above the noise, the verdict says the gap is unexplained and where it
//! lies — an honest "unknown" beats a proxy that makes the next part worse. A
//! comparison alone (`compare-profile`) says how far the job's prediction is off.

use super::candidates::Candidate;
use super::compare::Comparison;
use super::fit::Fit;
use super::report::{FitCheck, HeldOut, ResidualInfo, Verdict};
use super::zones::ZoneStats;

/// Share of the residual's excess over noise (RMS²) the accepted effects must remove for
/// the gap to count as explained.
const EXPLAINED: f64 = 0.8;
/// Times the white noise above which what the accepted effects leave is said to hold
/// more than noise, even where the gap counts as explained.
const LEFT_OVER: f64 = 1.5;

/// One of the explanations the data cannot tell apart: its label and, where it was
/// fitted alone, that fit (its last member the effect).
pub struct Tie<'a> {
    pub label: String,
    pub alone: Option<&'a Fit>,
}

impl Tie<'_> {
    /// The effect, where it was fitted alone.
    fn effect(&self) -> Option<Candidate> {
        self.alone.and_then(|fit| fit.set.last().copied())
    }

    /// What the fit alone reads ("the tool stops 3.01 ± 0.02 µm short of the axis").
    fn reading(&self) -> Option<String> {
        self.alone.map(|fit| fit.describe(fit.set.len() - 1))
    }
}

fn labels<'t>(ties: &'t [Tie]) -> Vec<&'t str> {
    ties.iter().map(|t| t.label.as_str()).collect()
}

/// " Fitted alone: A; or B." — what each tied explanation would have the user correct,
/// so the size of what is at stake is on the page.
fn each_alone(ties: &[Tie]) -> String {
    let readings: Vec<String> = ties.iter().filter_map(Tie::reading).collect();
    if readings.is_empty() {
        return String::new();
    }
    format!(" Fitted alone: {}.", readings.join("; or "))
}

/// What to do when explanations tie: for the commonest pair, a decentre and a drift
/// (each a cone on a sphere), what tells them apart at the machine — a drift's cone
/// grows with the time the cut takes, a decentre's does not, and a decentre leaves a
/// feature within its own size of the axis; otherwise the general advice.
fn tie_advice(ties: &[Tie]) -> String {
    let has = |effect: Candidate| ties.iter().any(|t| t.effect() == Some(effect));
    if has(Candidate::XDecentre) && has(Candidate::AxialDrift) {
        "correct nothing yet: cut the next part at another feed per revolution or spindle speed (a drift's cone grows with the time the cut takes, a decentre's stays), or measure the centre at finer lateral spacing (a decentre leaves a boss or a dip within its own size of the axis), and diagnose again".into()
    } else {
        "correct nothing yet: measure what separates them (another radius range, a map of the part, or a part cut with another program) and diagnose again".into()
    }
}

pub fn verdict(
    compared_only: Option<&Comparison>,
    check: &FitCheck,
    fit: Option<&Fit>,
    (before, after): (&ResidualInfo, &ResidualInfo),
    ambiguous: &[Tie],
    held: Option<&HeldOut>,
    refused: &[(String, String)],
) -> Verdict {
    if !check.fits {
        return does_not_fit(check);
    }
    if let Some(c) = compared_only {
        return compared(c);
    }
    let gap = Gap::of(before, after);
    match fit {
        Some(f) => effects_found(f, &gap, (before, after), ambiguous, held),
        None if !ambiguous.is_empty() => Verdict {
            status: "ambiguous".into(),
            sentence: format!(
                "The gap is explained about equally well by {}: this measurement cannot tell them apart, so none is claimed{}.{}",
                labels(ambiguous).join(" or "),
                gap.location,
                each_alone(ambiguous)
            ),
            advice: vec![tie_advice(ambiguous)],
        },
        None if gap.near_noise && gap.marks_left.is_none() => Verdict {
            status: "no_effect_beyond_noise".into(),
            sentence: format!(
                "No modelled effect explains the residual beyond noise: it is {:.1} nm RMS ({:.0} nm PV) against a noise level of {:.1} nm{}.",
                after.rms_nm,
                after.pv_nm,
                gap.noise,
                refused
                    .first()
                    .map_or(String::new(), |(label, why)| format!(
                        "; the strongest candidate, {label}, was not accepted: {why}"
                    ))
            ),
            advice: vec!["nothing to correct from this measurement".into()],
        },
        None => unexplained(&gap, after, refused),
    }
}

/// The measurement does not fit the job: its severe findings.
fn does_not_fit(check: &FitCheck) -> Verdict {
    let why: Vec<&str> = check
        .findings
        .iter()
        .filter(|f| f.severity == "severe")
        .map(|f| f.message.as_str())
        .collect();
    Verdict {
        status: "does_not_fit".into(),
        sentence: format!(
            "The measurement does not fit this job, so no effect is claimed: {}.",
            why.join("; ")
        ),
        advice: vec!["check the units, the part and the job before diagnosing".into()],
    }
}

/// `compare-profile`: the measured and predicted figures, nothing fitted.
fn compared(c: &Comparison) -> Verdict {
    Verdict {
        status: "compared".into(),
        sentence: format!(
            "Measured PV {:.0} nm, RMS {:.1} nm; the job predicts PV {:.0} nm ({:+.1} %), RMS {:.1} nm ({:+.1} %){}; no effect was fitted (toolmark diagnose fits them).",
            c.measured.pv_nm,
            c.measured.rms_nm,
            c.simulated.pv_nm,
            100.0 * (c.simulated.pv_nm / c.measured.pv_nm - 1.0),
            c.simulated.rms_nm,
            100.0 * (c.simulated.rms_nm / c.measured.rms_nm - 1.0),
            c.mark_spacing_ratio.map_or(String::new(), |q| format!(
                "; the marks lie {q:.4}× as far apart as the job puts them (median of {} bands)",
                c.mark_spacing.len()
            ))
        ),
        advice: Vec::new(),
    }
}

/// What the gap is against the noise, once the accepted effects (if any) are taken out.
struct Gap {
    /// The white noise level (nm).
    noise: f64,
    /// The share of the gap above the noise the accepted effects explain.
    explained: f64,
    /// Whether what is left is within reach of the noise.
    near_noise: bool,
    /// Where the gap lies (a clause, or empty).
    location: String,
    /// The marks' shape the model lacks, said as a sentence.
    marks_left: Option<String>,
}

impl Gap {
    fn of(before: &ResidualInfo, after: &ResidualInfo) -> Gap {
        let noise = after.white_noise_nm.max(1e-3);
        let excess = |r: &ResidualInfo| (r.rms_nm.powi(2) - noise.powi(2)).max(0.0);
        let explained = 1.0 - excess(after) / excess(before).max(1e-300);
        // Near the noise: within twice its level, or a residual as short-correlated as noise
        // that is not far above it (a mark-scale structure, such as ploughed bands beside
        // each cusp, is short-correlated too, and stands well above the noise).
        let near_noise = after.rms_nm <= 2.0 * noise
            || (after.correlation_length_points < 3.0 && after.rms_nm <= 3.0 * noise);
        let location = where_it_lies(before);
        // Marks whose shape the model lacks stand out only once folded over hundreds of
        // marks: near the noise point by point, they are still a gap.
        let marks_left = after
            .mark_shape
            .as_ref()
            .filter(|s| s.unexplained(noise))
            .map(|s| format!(" The marks are not explained: {}.", s.describe()));
        Gap {
            noise,
            explained,
            near_noise,
            location,
            marks_left,
        }
    }
}

/// Effects were accepted: what they are, how much they explain, and what is left.
fn effects_found(
    f: &Fit,
    gap: &Gap,
    (before, after): (&ResidualInfo, &ResidualInfo),
    ambiguous: &[Tie],
    held: Option<&HeldOut>,
) -> Verdict {
    let members = f.effect_members();
    let parts: Vec<String> = members.iter().map(|&i| f.describe(i)).collect();
    let mut sentence = capitalise(&parts.join("; "));
    let which = if members.len() == 1 {
        "correcting it"
    } else {
        "correcting them"
    };
    sentence.push_str(&format!(
        "; {which} cuts the residual from {:.0} nm to {:.0} nm PV ({:.1} → {:.1} nm RMS).",
        before.pv_nm, after.pv_nm, before.rms_nm, after.rms_nm
    ));
    if let Some(h) = held {
        sentence.push_str(&format!(
            " On the {} held-out points it cuts the residual from {:.1} to {:.1} nm RMS.",
            h.points, h.before_rms_nm, h.after_rms_nm
        ));
    }
    let beyond = if members.len() == 1 { "it" } else { "them" };
    match ambiguous {
        [] => {}
        [one] => sentence.push_str(&format!(
            " Beyond {beyond}, {} would explain about as much: this measurement cannot tell whether it is there, so it is not claimed.",
            one.label
        )),
        _ => sentence.push_str(&format!(
            " Beyond {beyond}, {} would explain about as much more: this measurement cannot tell them apart, so neither is claimed.",
            labels(ambiguous).join(" or ")
        )),
    }
    let mut advice: Vec<String> = members
        .iter()
        .map(|&i| f.set[i].advice(f.values_of(i).0))
        .collect();
    if let Some(marks) = &gap.marks_left {
        sentence.push_str(marks);
    }
    let status = if gap.near_noise || gap.explained >= EXPLAINED {
        if gap.marks_left.is_none() {
            sentence.push_str(&left_over(after, gap.noise));
        }
        "effects_found"
    } else {
        sentence.push_str(&format!(
            " It explains {:.0} % of the gap: {:.1} nm RMS remains, well above the noise of {:.1} nm, that no modelled effect explains{}.",
            100.0 * gap.explained.max(0.0),
            after.rms_nm,
            gap.noise,
            gap.location
        ));
        advice.push(
            "look for a cause outside the model for the rest (material, measurement, machine dynamics)".into(),
        );
        "unexplained_residual"
    };
    Verdict {
        status: status.into(),
        sentence,
        advice,
    }
}

/// Nothing accepted and nothing tied, and the residual stands above the noise.
fn unexplained(gap: &Gap, after: &ResidualInfo, refused: &[(String, String)]) -> Verdict {
    let mut sentence = match &gap.marks_left {
        Some(marks) if gap.near_noise => format!(
            "This gap is not explained by any modelled effect: {:.1} nm RMS ({:.0} nm PV) remains against a noise level of {:.1} nm, and it is not noise.{marks}",
            after.rms_nm, after.pv_nm, gap.noise
        ),
        _ => format!(
            "This gap is not explained by any modelled effect: {:.1} nm RMS ({:.0} nm PV) remains, well above the noise level of {:.1} nm{}.{}",
            after.rms_nm,
            after.pv_nm,
            gap.noise,
            gap.location,
            gap.marks_left.as_deref().unwrap_or("")
        ),
    };
    if let Some((label, why)) = refused.first() {
        sentence.push_str(&format!(
            " The strongest candidate, {label}, was not accepted: {why}."
        ));
    }
    Verdict {
        status: "unexplained_residual".into(),
        sentence,
        advice: vec![
            "correct nothing on the strength of this measurement; look for a cause outside the model (material, measurement, machine dynamics)".into(),
        ],
    }
}

/// What the accepted effects leave, said where it stands over [`LEFT_OVER`] times the
/// white noise `noise` (nm): a weaker effect may be there, which the search did not
/// accept or try (it tries every candidate beside a large effect only from twice the
/// noise). Empty otherwise.
fn left_over(after: &ResidualInfo, noise: f64) -> String {
    let ratio = after.rms_nm / noise;
    if ratio <= LEFT_OVER {
        return String::new();
    }
    format!(
        " What is left, {:.1} nm RMS, is {ratio:.1}× the noise ({noise:.1} nm): no accepted effect explains it, and something weaker may remain{}.",
        after.rms_nm,
        where_it_lies(after)
    )
}

/// "; most of it in the centre (60 %) and the tool marks band (70 %)".
fn where_it_lies(r: &ResidualInfo) -> String {
    let largest = |parts: &[ZoneStats]| {
        parts
            .iter()
            .max_by(|a, b| a.share.total_cmp(&b.share))
            .map(|p| (p.name.clone(), 100.0 * p.share))
    };
    let zone = largest(&r.zones).map_or(String::new(), |(name, share)| {
        format!("; most of it in the {name} ({share:.0} %)")
    });
    let band = largest(&r.bands).map_or(String::new(), |(name, share)| {
        format!(" and the {name} band ({share:.0} %)")
    });
    format!("{zone}{band}")
}

fn capitalise(text: &str) -> String {
    let mut chars = text.chars();
    match chars.next() {
        Some(c) => c.to_uppercase().chain(chars).collect(),
        None => String::new(),
    }
}

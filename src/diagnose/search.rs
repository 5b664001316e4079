//! Which effect (DESIGN §8.3): every candidate is fitted alone and ranked by the evidence
//! it adds (ΔBIC on the residual's effective point count); then effects are combined
//! greedily. An effect is accepted only when it adds ΔBIC above the threshold, stands 3σ
//! from zero, sits inside its search range (a value at the bound is not a fit), removes
//! at least a tenth of the residual's RMS, and predicts the data it was not fitted on
//! (`validate`). A last backward pass drops an effect the others have come to explain.
//! Then the accepted set is weighed against what could stand in for it: a pair of
//! runners-up, a further waviness order in a set-up effect's place, and a candidate
//! leaving an accepted effect's print (`widen_for_look_alikes`, which also widens that
//! effect's σ). One that explains the data about as well is kept as `alternative`, and
//! nothing is claimed: the verdict names both.

use super::candidates::Candidate;
use super::fit::{Fit, Fitted, Problem, WAVINESS_PROBE_NM, bic, width};
use super::forward::ForwardError;
use super::marks;
use super::measurement::Measurement;
use super::register::{Registered, ShiftSearch};
use super::side_by_side;
use super::validate::{Folds, Validation, cross_validate};
use super::zones;
use super::{DiagnoseError, Options};
use crate::model::Job;
use crate::process::TurningMode;
use glam::DVec2;

/// Most edge-waviness orders combined.
const MAX_WAVINESS_ORDERS: usize = 3;
/// Candidates of one greedy round tried for acceptance, best evidence first.
const TRIES_PER_ROUND: usize = 3;
/// Least share of the residual's RMS an accepted effect removes.
const MIN_REDUCTION: f64 = 0.1;
/// The lowest share of the residual's white noise (read from its point-to-point
/// scatter, which errs by a few per cent) a fit can bring the RMS to: below it an effect
/// would be fitting the noise.
const NOISE_FLOOR: f64 = 0.95;
/// The share of the job's own Σr² below which what is accepted masked the singles'
/// evidence against it (see [`search`]).
const MASKED_SHARE: f64 = 0.25;
/// Strongest runners-up, after the single greedy selection began with, that are each
/// given a partner to see whether two effects explain better what one imitates.
const RIVALS: usize = 2;
/// A runner-up is given a partner when alone it adds at least this share of the
/// evidence of the single the selection began with.
const RIVAL_SHARE: f64 = 0.5;
/// Times the bracket of a waviness order re-fit may move past its end.
const WAVINESS_BRACKET_MOVES: usize = 2;

/// What the search found.
#[derive(Default)]
pub struct Search {
    /// Every candidate fitted alone, strongest evidence first, with its evidence.
    pub singles: Vec<(Fit, f64)>,
    /// The accepted set after each step (greedy additions, then a drop).
    pub steps: Vec<Fit>,
    pub accepted: Option<Fit>,
    /// The cross-validation of every effect tried for acceptance.
    pub validations: Vec<Validation>,
    /// Effects with evidence that were not accepted, and why.
    pub refused: Vec<(String, String)>,
    /// Another set of effects that explains the data about as well as the accepted one
    /// (within [`TIE_EVIDENCE`] on BIC), each of its members a fit: the data cannot
    /// tell the two apart.
    pub alternative: Option<Fit>,
}

/// Evidence (ΔBIC) within which two explanations tie: short of the conventional
/// "strong" preference (Kass & Raftery 1995).
pub const TIE_EVIDENCE: f64 = 6.0;

/// The job as given, registered: the registration terms that are fitted like effects
/// (`members`: a turned profile's azimuth on the spiral, the lateral scale) fitted
/// alone, from where the placement put them.
pub fn registration_base(
    problem: &mut Problem,
    members: &[Candidate],
) -> Result<Fit, ForwardError> {
    problem.fit(members, vec![0.0; members.len()], &[])
}

/// Runs the search on `problem` from `base` (the job as given, registered in the
/// nominal frame).
#[allow(clippy::too_many_arguments)]
pub fn search<'a>(
    problem: &mut Problem<'a, '_>,
    base: &Fit,
    candidates: &[Candidate],
    job: &Job,
    folds: &'a Folds<'a>,
    period_mm: f64,
    options: &Options,
    log: &dyn Fn(&str),
) -> Result<Search, DiagnoseError> {
    let mut found = Search::default();
    let fitted = problem.measurement;
    let seen = Seen::new(fitted, job);
    let orders = OrderRange::new(job, fitted);
    found.singles = fit_singles(problem, base, candidates, job, period_mm, log)?;

    let mut current: Fit = base.clone();
    while current.effect_members().len() < options.max_effects {
        if !current.effect_members().is_empty() {
            if !above_noise_floor(&current, fitted) {
                log("what is accepted leaves white noise alone: no further effect looked for");
                break;
            }
            problem.search_from(current.frame);
        }
        // The singles were judged against the job as given: where what is accepted took
        // most of that residual (a boss) and leaves more than noise, it hid what the
        // rest can explain, and every candidate is tried beside it.
        let masked =
            current.objective < MASKED_SHARE * base.objective && leaves_structure(&current, fitted);
        let round = partners_round(
            problem,
            &found.singles,
            &current,
            (job, fitted),
            masked,
            log,
        )?;
        let round = if current.effect_members().is_empty() {
            round
        } else {
            with_aliases(problem, round)?
        };
        let (rss_before, k_before) = (current.objective, current.parameter_count());
        let n_eff = common_effective_points(&round, problem, fitted)?;
        let mut ranked: Vec<(Fit, f64)> = round
            .into_iter()
            .map(|fit| {
                let e = evidence(rss_before, k_before, &fit, n_eff);
                (fit, e)
            })
            .collect();
        ranked.sort_by(|a, b| b.1.total_cmp(&a.1));
        let mut taken = None;
        let mut refused = Vec::new();
        let mut weak = None;
        for (mut fit, e) in ranked.into_iter().take(TRIES_PER_ROUND) {
            if e <= options.min_evidence {
                weak = (e > 0.0).then_some(fit);
                break;
            }
            let member = fit.set.len() - 1;
            let label = fit.set[member].label();
            if let Some(why) =
                not_a_fit(&fit, member, orders).or_else(|| too_small(&current, &fit, seen))
            {
                log(&format!("{label}: {why}"));
                found.refused.push((label, why));
                // A large print whose σ the residual's unexplained structure inflated
                // may stand once a partner takes that structure: it is offered one.
                if only_doubtful(&fit, member, &current, seen, orders) {
                    refused.push(fit);
                }
                continue;
            }
            log(&format!(
                "{label}: checking that it predicts data it was not fitted on"
            ));
            if let Some(spread) = predicts_unseen(problem, folds, &mut found, &fit, log)? {
                widen_sigmas(&mut fit, member, &spread);
                taken = Some(fit);
                break;
            }
            refused.push(fit);
        }
        // Nothing refused, yet more than noise left: the best single short of the
        // evidence can be bent by a second effect it hides (a centre height's boss beside
        // an edge waviness on a profile whose form was removed): it is offered a partner.
        if refused.is_empty()
            && leaves_structure(&current, fitted)
            && let Some(fit) = weak
            && not_a_fit(&fit, fit.set.len() - 1, orders).is_none()
            && too_small(&current, &fit, seen).is_none()
        {
            refused.push(fit);
        }
        let taken = match taken {
            Some(fit) => Some(fit),
            None => joint_pair(
                problem, folds, &mut found, &current, &refused, job, options, log,
            )?,
        };
        match taken {
            Some(fit) => {
                found.steps.push(fit.clone());
                current = fit;
            }
            None => break,
        }
    }
    if current.effect_members().len() > 1
        && let Some(reduced) = drop_redundant(problem, &current, options, log)?
    {
        let kept = keep_what_predicts(problem, folds, &mut found, reduced, log)?;
        found.steps.push(kept.clone());
        current = kept;
    }
    if let Some(pair) = rival_pair(problem, &mut found, &current, job, folds, options, log)? {
        found.steps = vec![pair.clone()];
        current = pair;
    }
    if let Some(better) = mirrored_member(problem, &mut found, &current, job, log)? {
        found.steps = vec![better.clone()];
        current = better;
    }
    waviness_swap(problem, &mut found, &current, job, log)?;
    found.accepted = (!current.effect_members().is_empty()).then_some(current);
    widen_for_look_alikes(problem, &mut found, job, &base.evaluation.registered, log)?;
    Ok(found)
}

/// Each candidate fitted alone beside the registration (side by side on worker threads),
/// a fit whose axis moved re-fitted there, ranked by evidence against `base`; the
/// problem is left in the frame of the single that fits best.
fn fit_singles(
    problem: &mut Problem,
    base: &Fit,
    candidates: &[Candidate],
    job: &Job,
    period_mm: f64,
    log: &dyn Fn(&str),
) -> Result<Vec<(Fit, f64)>, DiagnoseError> {
    let numbered: Vec<(usize, Candidate)> = candidates.iter().copied().enumerate().collect();
    let fitted = problem.measurement;
    let nominal_frame = problem.shift;
    let singles = side_by_side::each(
        problem,
        &numbered,
        |(_, c)| c.is_waviness(),
        |problem, &(i, c), log| -> Result<Option<Fit>, DiagnoseError> {
            let n = candidates.len();
            log(&format!(
                "fitting {} (candidate {} of {n})",
                c.label(),
                i + 1
            ));
            let Some(fit) = fit_new(problem, &base.set, &base.values, c, job, fitted)? else {
                return Ok(None);
            };
            let fit = refit_if_axis_moves(
                problem,
                fit,
                base,
                nominal_frame,
                period_mm,
                job,
                fitted,
                log,
            )?;
            Ok(Some(fit))
        },
        log,
    );
    let mut fits = Vec::new();
    for fit in singles {
        fits.extend(fit?);
    }
    // The combinations start in the frame of the single that fits best.
    if let Some(best) = fits
        .iter()
        .min_by(|a, b| a.objective.total_cmp(&b.objective))
    {
        problem.search_from(best.frame);
    }
    let (rss0, k0) = (base.objective, base.parameter_count());
    let n_eff = common_effective_points(&fits, problem, fitted)?;
    let mut singles: Vec<(Fit, f64)> = fits
        .into_iter()
        .map(|fit| {
            let e = evidence(rss0, k0, &fit, n_eff);
            (fit, e)
        })
        .collect();
    singles.sort_by(|a, b| b.1.total_cmp(&a.1));
    Ok(singles)
}

/// Greedy selection commits to the single that fits best, and a flexible effect (two
/// or more parameters: an edge waviness of a fraction of a cycle over the edge the part
/// used) or a combination can fit best by imitating other effects at once. The
/// strongest runners-up (that are fits themselves) are each given the partner a greedy
/// round would give them; the best such pair replaces the accepted set when it beats it
/// on BIC (its parameters paid for) by more than the evidence threshold, both its
/// members are fits, the partner removes a tenth of what the runner-up leaves, and the
/// pair predicts the data it was not fitted on. A pair that passes the same tests but
/// only ties the accepted set (within [`TIE_EVIDENCE`] of it, short of the threshold)
/// is kept in `found.alternative`: the data cannot tell the two explanations apart —
/// unless the pair holds every effect of the accepted set and more: then the extras
/// are unearned and the accepted set stands (nested families are judged by parsimony).
fn rival_pair<'a>(
    problem: &mut Problem<'a, '_>,
    found: &mut Search,
    current: &Fit,
    job: &Job,
    folds: &'a Folds<'a>,
    options: &Options,
    log: &dyn Fn(&str),
) -> Result<Option<Fit>, DiagnoseError> {
    // One effect of one parameter imitates no combination (ties between singles are
    // judged apart, on the singles).
    let effects = current.effects();
    if effects.len() < 2 && effects.iter().all(|c| width(c) < 2) {
        return Ok(None);
    }
    let orders = OrderRange::new(job, problem.measurement);
    let strongest = effects
        .iter()
        .filter_map(|c| single_of(&found.singles, c.kind()).map(|(_, e)| *e))
        .fold(f64::NEG_INFINITY, f64::max);
    if !strongest.is_finite() {
        return Ok(None);
    }
    let rivals: Vec<Fit> = found
        .singles
        .iter()
        .filter(|(f, e)| {
            let last = f.set.len() - 1;
            *e >= RIVAL_SHARE * strongest
                && effects.iter().all(|c| c.kind() != f.set[last].kind())
                && not_a_fit(f, last, orders).is_none()
        })
        .take(RIVALS)
        .map(|(f, _)| f.clone())
        .collect();
    let fitted = problem.measurement;
    let mut best: Option<(Fit, f64, Fit)> = None;
    for rival in &rivals {
        problem.search_from(rival.frame);
        for pair in greedy_round(problem, &found.singles, rival, job, fitted, log)? {
            let gain = evidence(
                current.objective,
                current.parameter_count(),
                &pair,
                current.effective_points,
            );
            if best.as_ref().is_none_or(|(_, g, _)| gain > *g) {
                best = Some((pair, gain, rival.clone()));
            }
        }
    }
    problem.search_from(current.frame);
    let Some((mut pair, gain, rival)) = best else {
        return Ok(None);
    };
    let label = labels(&pair.set);
    let ties = gain > -TIE_EVIDENCE && gain <= options.min_evidence;
    if gain <= -TIE_EVIDENCE {
        log(&format!(
            "the best pair of runners-up, {label}, adds ΔBIC {gain:.1} over {}: kept",
            labels(&current.set)
        ));
        return Ok(None);
    }
    if ties && holds_every_effect_of(&pair.set, &current.set) {
        log(&format!(
            "{label} holds {} and more, yet only ties it (ΔBIC {gain:.1}): the data does not ask for the rest, the simpler set stands",
            labels(&current.set)
        ));
        return Ok(None);
    }
    let members = pair.effect_members();
    if let Some(why) = members
        .iter()
        .find_map(|&m| not_a_fit(&pair, m, orders))
        .or_else(|| too_small(&rival, &pair, Seen::new(problem.measurement, job)))
    {
        log(&format!(
            "{label} (instead of {}): {why}",
            labels(&current.set)
        ));
        found.refused.push((label, why));
        return Ok(None);
    }
    log(&format!(
        "{label} explains {} {} (ΔBIC {gain:.1}): checking that each predicts data it was not fitted on",
        if ties {
            "about as well as"
        } else {
            "more than"
        },
        labels(&current.set)
    ));
    // The runner-up alone, then its partner beside it (the pair's last member), as the
    // greedy rounds judge them.
    let Some(rival_spread) = predicts_unseen(problem, folds, found, &rival, log)? else {
        return Ok(None);
    };
    let Some(partner_spread) = predicts_unseen(problem, folds, found, &pair, log)? else {
        return Ok(None);
    };
    widen_sigmas(&mut pair, rival.set.len() - 1, &rival_spread);
    let partner = pair.set.len() - 1;
    widen_sigmas(&mut pair, partner, &partner_spread);
    if ties {
        keep_alternative(found, current, pair, log);
        return Ok(None);
    }
    Ok(Some(pair))
}

/// Whether set `larger` holds every effect of set `smaller` (by kind, as many of each;
/// registration members aside): a set nested in another's family, so a tie between
/// them is no tie but the larger one's extra effects unearned (a waviness alone, made
/// so, tied "axial drift + waviness" at another order within 0.3 on the ΔBIC scale).
fn holds_every_effect_of(larger: &[Candidate], smaller: &[Candidate]) -> bool {
    let count = |set: &[Candidate], kind: &str| {
        set.iter()
            .filter(|c| !c.is_registration() && c.kind() == kind)
            .count()
    };
    smaller
        .iter()
        .filter(|c| !c.is_registration())
        .all(|c| count(larger, c.kind()) >= count(smaller, c.kind()))
}

/// An accepted edge waviness beside set-up effects may be two waviness orders whose
/// second the set-up effect imitates over the few cycles the measured edge spans (a
/// decentre's cone as the low half of a harmonic): each set-up member is replaced by a
/// further waviness order (every order re-fitted), and where that explains the data as
/// well as the accepted set — its log-likelihood within [`TIE_EVIDENCE`] of it, the
/// further order's parameters not charged — with every member a fit, it is kept in
/// `found.alternative`.
fn waviness_swap(
    problem: &mut Problem,
    found: &mut Search,
    current: &Fit,
    job: &Job,
    log: &dyn Fn(&str),
) -> Result<(), DiagnoseError> {
    let effects = current.effect_members();
    let wavy = |i: &usize| matches!(current.set[*i], Candidate::EdgeWaviness { .. });
    let waviness = effects.iter().filter(|i| wavy(i)).count();
    if waviness == 0 || waviness >= MAX_WAVINESS_ORDERS || found.alternative.is_some() {
        return Ok(());
    }
    let orders = OrderRange::new(job, problem.measurement);
    let fitted = problem.measurement;
    // The likelihoods compared, the further order's parameters not charged: the
    // question is whether the set-up effect is needed, not which model is leaner.
    let gain = |alternative: &Fit| {
        evidence(
            current.objective,
            alternative.parameter_count(),
            alternative,
            current.effective_points,
        )
    };
    for &m in effects.iter().filter(|i| !wavy(i)) {
        let rest = with_member_last(problem, current, m, false)?;
        let Some(mut swapped) = fit_new(
            problem,
            &rest.set,
            &rest.values,
            Candidate::EdgeWaviness { order: 0.0 },
            job,
            fitted,
        )?
        else {
            continue;
        };
        // Re-fitting every order costs a golden-section search each: only where the
        // screened orders come near a tie.
        if (-SWAP_REFIT_MARGIN..=-TIE_EVIDENCE).contains(&gain(&swapped)) {
            swapped = refit_every_order(problem, swapped, orders)?;
        }
        // An order at the lowest end stands for a smooth bend of the edge, which is
        // just what the set-up effect's print may be: it counts for the tie.
        let all_fit = swapped
            .effect_members()
            .iter()
            .all(|&i| not_a_fit(&swapped, i, OrderRange::ANY).is_none());
        let gain = gain(&swapped);
        log(&format!(
            "{} instead of {}: log-likelihood gain {gain:.1} (ΔBIC scale)",
            labels(&swapped.set),
            labels(&current.set)
        ));
        if gain > -TIE_EVIDENCE && all_fit {
            keep_alternative(found, current, swapped, log);
            return Ok(());
        }
    }
    Ok(())
}

/// Two set-up effects whose prints add (a decentre's cone and a drift's on a sphere)
/// can match the data with one of them on the other side of zero and its partner
/// re-sized: a tool stopping 2.3 µm short of the axis beside a 277 nm drift reads
/// alike as one running 2.3 µm past it beside a −71 nm drift. Where the accepted set
/// holds two effects or more, each one-parameter member is moved to its mirror, the
/// others re-sized around it with it held there, and the set fitted again from that.
/// Where that fit ends in another basin (a one-parameter member on the other side of
/// zero: the moved one, or a partner — independent batch k's k10, x decentre −1.81 µm
/// beside a 180 nm drift, was accepted as +1.64 µm beside 346 nm; the drift moved to
/// −346 nm came back to +183 nm with the decentre re-sized past zero), every member a
/// fit, and explains the data better by more than [`TIE_EVIDENCE`], it is returned to
/// replace the accepted set (the greedy search settled in the worse basin); within
/// [`TIE_EVIDENCE`] of it, it is kept in `found.alternative`: the data cannot tell the
/// two apart.
fn mirrored_member(
    problem: &mut Problem,
    found: &mut Search,
    current: &Fit,
    job: &Job,
    log: &dyn Fn(&str),
) -> Result<Option<Fit>, DiagnoseError> {
    let members = current.effect_members();
    if members.len() < 2 || found.alternative.is_some() {
        return Ok(None);
    }
    let orders = OrderRange::new(job, problem.measurement);
    for &m in members.iter().filter(|&&m| width(&current.set[m]) == 1) {
        let j = current.parameter_span(m).start;
        let mut start = current.values.clone();
        start[j] = -start[j];
        let mirrored = problem.fit_around(&current.set, start, &[j])?;
        // Another basin: some one-parameter member on the other side of zero (the
        // moved one, or a partner it re-sized past zero before coming back itself).
        let elsewhere = members
            .iter()
            .filter(|&&i| width(&current.set[i]) == 1)
            .map(|&i| current.parameter_span(i).start)
            .any(|k| mirrored.values[k].signum() != current.values[k].signum());
        let all_fit = mirrored
            .effect_members()
            .iter()
            .all(|&i| not_a_fit(&mirrored, i, orders).is_none());
        let gain = evidence(
            current.objective,
            current.parameter_count(),
            &mirrored,
            current.effective_points,
        );
        log(&format!(
            "{} from its mirror: {:.4} {}, ΔBIC {gain:.1} against {}",
            current.set[m].label(),
            mirrored.values[j],
            current.parameters[j].unit,
            labels(&current.set)
        ));
        if !(elsewhere && all_fit) || gain <= -TIE_EVIDENCE {
            continue;
        }
        if gain >= TIE_EVIDENCE {
            log(&format!(
                "{} replaces {}",
                labels_with_values(&mirrored),
                labels_with_values(current)
            ));
            return Ok(Some(mirrored));
        }
        keep_alternative(found, current, mirrored, log);
        return Ok(None);
    }
    Ok(None)
}

/// The effects of `fit` with the value of each one-parameter member, to tell apart two
/// sets of the same effects.
pub fn labels_with_values(fit: &Fit) -> String {
    fit.effect_members()
        .into_iter()
        .map(|m| {
            let span = fit.parameter_span(m);
            match fit.values[span.clone()] {
                [v] => format!(
                    "{} ({v:.3} {})",
                    fit.set[m].label(),
                    fit.parameters[span.start].unit
                ),
                _ => fit.set[m].label(),
            }
        })
        .collect::<Vec<_>>()
        .join(" + ")
}

/// Keeps `alternative` as the explanation the data cannot tell from `accepted`.
fn keep_alternative(found: &mut Search, accepted: &Fit, alternative: Fit, log: &dyn Fn(&str)) {
    let [a, b] = distinct_labels(&alternative, accepted);
    log(&format!(
        "{a} and {b} cannot be told apart on this measurement"
    ));
    found.alternative = Some(alternative);
}

/// The two sets' labels, with their values where the effects are the same.
pub fn distinct_labels(a: &Fit, b: &Fit) -> [String; 2] {
    let (la, lb) = (labels(&a.set), labels(&b.set));
    if la == lb {
        [labels_with_values(a), labels_with_values(b)]
    } else {
        [la, lb]
    }
}

/// How far below a tie (ΔBIC scale) a swapped waviness set's screened orders may leave
/// it and still have every order re-fitted (see [`waviness_swap`]).
const SWAP_REFIT_MARGIN: f64 = 30.0;

/// Two changes to a residual (each fit's against `baseline`) correlated above this leave
/// the same print: four fifths of each one's energy shared.
pub const SAME_PRINT: f64 = 0.9;

/// Cosine between the changes two fits make to `baseline`'s residual: 1 when they leave
/// the same print.
pub fn print_correlation(a: &Fit, b: &Fit, baseline: &Registered) -> f64 {
    let change = |f: &Fit| -> Vec<f64> {
        f.evaluation
            .registered
            .residual_mm
            .iter()
            .zip(&baseline.residual_mm)
            .map(|(x, b)| {
                if x.is_finite() && b.is_finite() {
                    b - x
                } else {
                    0.0
                }
            })
            .collect()
    };
    let (ca, cb) = (change(a), change(b));
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    ca.iter().zip(&cb).map(|(x, y)| x * y).sum::<f64>() / (norm(&ca) * norm(&cb)).max(1e-300)
}

/// The strongest single fit of an effect of `kind` (the singles are sorted strongest
/// first), with its evidence.
fn single_of<'s>(singles: &'s [(Fit, f64)], kind: &str) -> Option<&'s (Fit, f64)> {
    singles
        .iter()
        .find(|(f, _)| f.set.last().is_some_and(|c| c.kind() == kind))
}

/// Look-alikes weighed per accepted member, strongest first.
const LOOK_ALIKES: usize = 2;

/// An accepted effect pinned only as far as the data tells it from a candidate that
/// leaves the same print (a decentre and a drift are both a cone on a sphere: only the
/// marks' phase and the few rings at the axis tell them apart, and a part with both
/// reads as either alone). For each accepted member, the candidates not accepted whose
/// single fit leaves its print ([`SAME_PRINT`]) and explains at least [`RIVAL_SHARE`]
/// of its evidence are fitted beside the accepted set; the member's σ becomes at least
/// its σ in that fit and the distance its value moved there (a model that lets the
/// look-alike in). Where the member then no longer stands 3σ clear of zero, the set
/// with the look-alike in its place is kept in `found.alternative`: the data cannot
/// tell the two apart — unless that set explains the data worse than the accepted one
/// by [`TIE_EVIDENCE`] or more and the member's distance moved alone leaves it clear:
/// then the member is needed, its σ beside the look-alike is the linear width of a
/// direction the data close before zero, and the move is what widens it (a decentre on
/// a long-radius sphere beside a third of a cycle of edge waviness, which alone fits
/// far worse).
fn widen_for_look_alikes(
    problem: &mut Problem,
    found: &mut Search,
    job: &Job,
    baseline: &Registered,
    log: &dyn Fn(&str),
) -> Result<(), DiagnoseError> {
    let Some(mut accepted) = found.accepted.clone() else {
        return Ok(());
    };
    let fitted = problem.measurement;
    let orders = OrderRange::new(job, fitted);
    problem.search_from(accepted.frame);
    for member in accepted.effect_members() {
        let Some((own, own_evidence)) = single_of(&found.singles, accepted.set[member].kind())
        else {
            continue;
        };
        let look_alikes: Vec<Candidate> = found
            .singles
            .iter()
            .filter(|(f, e)| {
                let last = f.set.len() - 1;
                let c = f.set[last];
                *e >= RIVAL_SHARE * own_evidence
                    && accepted.effects().iter().all(|a| a.kind() != c.kind())
                    && not_a_fit(f, last, orders).is_none()
                    && print_correlation(f, own, baseline) > SAME_PRINT
            })
            .take(LOOK_ALIKES)
            .map(|(f, _)| f.set[f.set.len() - 1])
            .collect();
        let span = accepted.parameter_span(member);
        for c in look_alikes {
            let Some(beside) = fit_new(problem, &accepted.set, &accepted.values, c, job, fitted)?
            else {
                continue;
            };
            let along = moves_along_look_alike(problem, &beside)?;
            // The member's σs widened to the distance it moved beside the look-alike
            // (or along the look-alike's profile), and (`by_sigma`) to its σ there.
            let widened_by = |by_sigma: bool| {
                let mut widened = accepted.clone();
                for j in span.clone() {
                    let moved = (beside.values[j] - accepted.values[j]).abs().max(along[j]);
                    let sigma = if by_sigma { beside.sigmas[j] } else { 0.0 };
                    widened.sigmas[j] = accepted.sigmas[j].max(sigma).max(moved);
                }
                widened
            };
            let mut widened = widened_by(true);
            if !significant(&widened, member) {
                let instead = with_member_last(problem, &beside, member, false)?;
                let instead = from_single_frame(problem, instead, &found.singles)?;
                let gain = evidence(
                    accepted.objective,
                    accepted.parameter_count(),
                    &instead,
                    accepted.effective_points,
                );
                // The look-alike alone refuted, the member is needed, and its σ beside
                // the look-alike is the linear width of a direction the data close
                // before zero: where the move it makes leaves the member clear, the σ
                // is widened by the move alone.
                let moved_only = widened_by(false);
                if gain <= -TIE_EVIDENCE && significant(&moved_only, member) {
                    log(&format!(
                        "{} alone explains less than {} (ΔBIC {gain:.1}): it widens that σ by the move it makes",
                        c.label(),
                        accepted.set[member].label(),
                    ));
                    widened = moved_only;
                } else if found.alternative.is_none() {
                    keep_alternative(found, &accepted, instead, log);
                }
            }
            for j in span.clone() {
                if widened.sigmas[j] > accepted.sigmas[j] {
                    log(&format!(
                        "{} leaves the print of {}: its σ widened from {:.4} to {:.4} {}",
                        c.label(),
                        accepted.set[member].label(),
                        accepted.sigmas[j],
                        widened.sigmas[j],
                        accepted.parameters[j].unit
                    ));
                    accepted.sigmas[j] = widened.sigmas[j];
                }
            }
        }
    }
    found.accepted = Some(accepted);
    Ok(())
}

/// `fit` (a set whose last member is a look-alike) fitted again from where that
/// look-alike's own single fit placed the axis, kept where it explains more. The set
/// starts in the accepted fit's frame without the member it replaced, and losing that
/// member can leave the registration on a far tooth of its comb: a local minimum worse
/// than the look-alike alone (a04 of batch a: a drift's axis 0.54 mm from its single's,
/// which made the tie's axis σ 0.54 mm).
fn from_single_frame(
    problem: &mut Problem,
    fit: Fit,
    singles: &[(Fit, f64)],
) -> Result<Fit, DiagnoseError> {
    let last = fit.set.len() - 1;
    let Some((single, _)) = single_of(singles, fit.set[last].kind()) else {
        return Ok(fit);
    };
    if single.objective >= fit.objective {
        return Ok(fit);
    }
    let mut start = fit.values.clone();
    start[fit.parameter_span(last)].copy_from_slice(single.values_of(single.set.len() - 1).0);
    let again = problem.fit_in_frame(single.frame, &fit.set, start)?;
    Ok(if again.objective < fit.objective {
        again
    } else {
        fit
    })
}

/// How far each value of `beside` moves while the look-alike (its last member) is
/// stepped along its profile with every other value re-fitted ([`Problem::value_profile`]):
/// where two prints are nearly one, the valley between them is as flat as the data
/// leave it, however closed the linearised σs make it look.
fn moves_along_look_alike(problem: &mut Problem, beside: &Fit) -> Result<Vec<f64>, DiagnoseError> {
    let noise = problem.profile_noise(
        &beside.evaluation,
        beside.parameter_count(),
        beside.correlation_length,
    );
    let mut along = vec![0.0_f64; beside.values.len()];
    for j in beside.parameter_span(beside.set.len() - 1) {
        let sigma = beside.sigmas[j];
        if !(sigma.is_finite() && sigma > 0.0) || beside.at_bound[j] {
            continue;
        }
        let profile = problem.value_profile(beside, j, sigma, &noise)?;
        for (a, m) in along.iter_mut().zip(profile.moved) {
            *a = (*a).max(m);
        }
    }
    Ok(along)
}

/// `fit` with the order of each of its edge-waviness members re-fitted in turn, the
/// others held (each moved last, where the order's re-fit acts), the new orders kept
/// where they lower the objective.
fn refit_every_order(
    problem: &mut Problem,
    mut fit: Fit,
    orders: OrderRange,
) -> Result<Fit, DiagnoseError> {
    let count = fit.set.iter().filter(|c| c.is_waviness()).count();
    for _ in 0..count {
        let Some(first) = fit.set.iter().position(|c| c.is_waviness()) else {
            break;
        };
        let last = with_member_last(problem, &fit, first, true)?;
        let Some(Candidate::EdgeWaviness { order }) = last.set.last().copied() else {
            break;
        };
        let refitted = refit_waviness_order(problem, &last, order, orders)?;
        let moved = problem.fit(&refitted.set, refitted.values, &[])?;
        fit = if moved.objective < last.objective {
            moved
        } else {
            last
        };
    }
    Ok(fit)
}

/// When no effect of a round predicts the data it was not fitted on alone, two present
/// together can still be the cause — each fitted alone bends to imitate the other, and
/// that bend does not carry to unseen data (a centre height beside an edge waviness,
/// two waviness orders), or each alone falls short of the evidence. The strongest effect
/// refused for that (or, where none was, the best single short of the evidence) is given the best
/// partner of all the candidates (one that explains nothing alone included), and the
/// two are accepted together when the pair beats
/// `current` on BIC by more than the evidence threshold, both are fits, the partner
/// removes a tenth of what the first leaves, and the two, fitted together on part of
/// the data, predict the rest.
#[allow(clippy::too_many_arguments)]
fn joint_pair<'a>(
    problem: &mut Problem<'a, '_>,
    folds: &'a Folds<'a>,
    found: &mut Search,
    current: &Fit,
    refused: &[Fit],
    job: &Job,
    options: &Options,
    log: &dyn Fn(&str),
) -> Result<Option<Fit>, DiagnoseError> {
    let Some(first) = refused.first() else {
        return Ok(None);
    };
    if current.effect_members().len() + 2 > options.max_effects {
        return Ok(None);
    }
    let fitted = problem.measurement;
    problem.search_from(first.frame);
    let round = partners_round(problem, &found.singles, first, (job, fitted), true, log)?;
    problem.search_from(current.frame);
    let Some(mut pair) = round
        .into_iter()
        .min_by(|a, b| a.objective.total_cmp(&b.objective))
    else {
        return Ok(None);
    };
    let label = labels(&pair.set[current.set.len()..]);
    let gain = evidence(
        current.objective,
        current.parameter_count(),
        &pair,
        current.effective_points,
    );
    if gain <= options.min_evidence {
        return Ok(None);
    }
    let members: Vec<usize> = (current.set.len()..pair.set.len()).collect();
    let orders = OrderRange::new(job, problem.measurement);
    if let Some(why) = members
        .iter()
        .find_map(|&m| not_a_fit(&pair, m, orders))
        .or_else(|| too_small(first, &pair, Seen::new(problem.measurement, job)))
    {
        log(&format!("{label} together: {why}"));
        found.refused.push((label, why));
        return Ok(None);
    }
    log(&format!(
        "{label} together (ΔBIC {gain:.1}): checking that they predict data they were not fitted on"
    ));
    let tested = members.len();
    let Some(spread) = predict_unseen_together(problem, folds, found, &pair, tested, log)? else {
        return Ok(None);
    };
    let mut offset = 0;
    for &m in &members {
        let n = width(&pair.set[m]);
        widen_sigmas(&mut pair, m, &spread[offset..offset + n]);
        offset += n;
    }
    Ok(Some(pair))
}

/// Whether the last member of `fit` predicts the data it was not fitted on; the
/// validation, and a failure's reason, are recorded in `found`. Returns the folds'
/// spread of its values (a floor for its σ) when it passed.
fn predicts_unseen(
    problem: &mut Problem,
    folds: &Folds,
    found: &mut Search,
    fit: &Fit,
    log: &dyn Fn(&str),
) -> Result<Option<Vec<f64>>, DiagnoseError> {
    predict_unseen_together(problem, folds, found, fit, 1, log)
}

/// [`predicts_unseen`] for the last `tested` members of `fit` fitted and judged together.
fn predict_unseen_together(
    problem: &mut Problem,
    folds: &Folds,
    found: &mut Search,
    fit: &Fit,
    tested: usize,
    log: &dyn Fn(&str),
) -> Result<Option<Vec<f64>>, DiagnoseError> {
    let validation = cross_validate(
        problem,
        folds,
        (&fit.set, &fit.values),
        tested,
        &fit.evaluation.registered,
    )?;
    let spread = validation.passed.then(|| validation.spread.clone());
    if !validation.passed {
        let label = validation.effect.clone();
        log(&format!("{label}: not accepted — {}", validation.reason));
        found.refused.push((label, validation.reason.clone()));
    }
    found.validations.push(validation);
    Ok(spread)
}

/// Why member `member` of a fit is not a fit at all, if it is not: a value at its search
/// bound, or values within 3σ of zero.
fn not_a_fit(fit: &Fit, member: usize, orders: OrderRange) -> Option<String> {
    if let Some(why) = order_at_bound(fit.set[member], orders) {
        return Some(why);
    }
    if let Some(j) = fit.parameter_span(member).find(|&j| fit.at_bound[j]) {
        let p = &fit.parameters[j];
        return Some(format!(
            "{} {:.4} {} sits at its search bound ({}): not a fit",
            p.name,
            fit.values[j],
            p.unit,
            p.range_text()
        ));
    }
    if !significant(fit, member) {
        return Some("within 3σ of zero".into());
    }
    None
}

/// The waviness orders a measurement can tell (see [`waviness_orders`]): the lowest is
/// half a cycle over the edge angles it used, the highest a quarter of one mark's contact.
#[derive(Clone, Copy, Debug)]
pub struct OrderRange {
    pub lowest: f64,
    pub highest: f64,
}

impl OrderRange {
    /// No order is at an end.
    pub const ANY: OrderRange = OrderRange {
        lowest: 0.0,
        highest: 0.0,
    };

    pub fn new(job: &Job, m: &Measurement) -> Self {
        Self::of(&waviness_orders(job, m))
    }

    /// The ends of a grid of orders (none: [`OrderRange::ANY`]).
    fn of(grid: &[f64]) -> Self {
        OrderRange {
            lowest: grid.first().copied().unwrap_or(0.0),
            highest: grid.last().copied().unwrap_or(0.0),
        }
    }
}

/// Share of an end of the order range within which a fitted order sits at that end.
const ORDER_AT_END: f64 = 0.03;

/// Why an edge waviness's order is not a fit, if it is not: it sits at an end of the
/// range the measurement can tell. At the lowest (half a cycle over the edge angles
/// used) the harmonic is a smooth bend along the edge that the data wants smoother
/// still: it imitates a form error (a drift, a wear, a decentre), not a waviness.
fn order_at_bound(c: Candidate, range: OrderRange) -> Option<String> {
    let Candidate::EdgeWaviness { order } = c else {
        return None;
    };
    let low = order <= range.lowest * (1.0 + ORDER_AT_END);
    let high = order >= range.highest * (1.0 - ORDER_AT_END);
    (range.highest > 0.0 && (low || high)).then(|| {
        let (end, what) = if low {
            (range.lowest, "the lowest this measurement can tell, half a cycle over the edge angles it used: a smooth bend of the form, not a waviness")
        } else {
            (range.highest, "the highest this measurement can tell")
        };
        format!("order {order:.1} sits at its search bound ({end:.1}, {what}): not a fit")
    })
}

/// Whether the member's only fault is its doubt: within its bounds and removing enough of
/// the residual, but within 3σ of zero.
fn only_doubtful(fit: &Fit, member: usize, before: &Fit, seen: Seen, orders: OrderRange) -> bool {
    let within_bounds = fit.parameter_span(member).all(|j| !fit.at_bound[j])
        && order_at_bound(fit.set[member], orders).is_none();
    within_bounds && !significant(fit, member) && too_small(before, fit, seen).is_none()
}

/// Why an effect that takes the residual from `before`'s to `after`'s explains too
/// little to act on, if it does: less than [`MIN_REDUCTION`] of the residual's RMS,
/// unless it leaves the white noise alone where more was there before (see
/// [`takes_all_structure`]). Such an effect, however significant, is a fit to the
/// residual's own structure (a correlated noise, a small unmodelled feature) as often
/// as a cause.
fn too_small(before: &Fit, after: &Fit, seen: Seen) -> Option<String> {
    let reduction = rms_reduction(before.objective, after.objective);
    (reduction < MIN_REDUCTION && !takes_all_structure(before, after, seen)).then(|| {
        format!(
            "it removes {:.1} % of the residual's RMS, less than the {:.0} % an effect must remove to be acted on",
            100.0 * reduction,
            100.0 * MIN_REDUCTION
        )
    })
}

/// The share of the residual's RMS a fit removes, from its Σr² `before` and `after`.
fn rms_reduction(before: f64, after: f64) -> f64 {
    1.0 - (after / before.max(1e-300)).max(0.0).sqrt()
}

/// What [`too_small`] judges a fit against: the fitted points, and the spacing their
/// marks are folded at (a turned profile's; `None` elsewhere).
#[derive(Clone, Copy)]
struct Seen<'a> {
    m: &'a Measurement,
    marks_mm: Option<f64>,
}

impl<'a> Seen<'a> {
    fn new(m: &'a Measurement, job: &Job) -> Seen<'a> {
        Seen {
            m,
            marks_mm: super::folded_mark_spacing_mm(job).filter(|_| m.is_line()),
        }
    }

    /// `fit`'s residual folded over its model's marks.
    fn fold(&self, fit: &Fit) -> Option<marks::MarkShape> {
        let r = &fit.evaluation.registered;
        let spacing = self.marks_mm?;
        marks::fold(&self.m.along_mm, &r.model_mm, &r.residual_mm, spacing)
    }
}

/// Whether `after` leaves no structure where `before` left some, however small a share
/// of the RMS it removes: `before`'s RMS was over its white noise (by more than the
/// noise reading's own error, [`NOISE_FLOOR`]) and `after`'s is not — a weak print in a
/// noisy measurement (a nose-radius error's form under 3 nm of noise) is all there was
/// to explain; or, folded over the marks, `before`'s residual carried a shape beyond
/// chance and `after`'s folds to chance — a nose-radius error's 2 nm on 40–60 nm marks
/// under 2–3 nm of noise is too little RMS for the white noise to tell, plain in the
/// marks averaged over hundreds.
fn takes_all_structure(before: &Fit, after: &Fit, seen: Seen) -> bool {
    let residual = &before.evaluation.registered.residual_mm;
    let noise = zones::white_noise_mm(seen.m, residual);
    let floor = noise / NOISE_FLOOR;
    let above_noise = |fit: &Fit| zones::rms(&fit.evaluation.registered.residual_mm) > floor;
    let marks_explained = || match (seen.fold(before), seen.fold(after)) {
        (Some(b), Some(a)) => b.significant && !a.significant,
        _ => false,
    };
    (above_noise(before) && !above_noise(after)) || marks_explained()
}

/// A fold-tested effect's σ is at least half the spread of its values over the folds.
pub(super) fn widen_sigmas(fit: &mut Fit, member: usize, spread: &[f64]) {
    let start = fit.parameter_span(member).start;
    for (j, s) in spread.iter().enumerate() {
        if s.is_finite() && fit.sigmas[start + j].is_finite() {
            fit.sigmas[start + j] = fit.sigmas[start + j].max(*s);
        }
    }
}

/// One greedy round: every candidate not yet taken fitted on top of `cur` (the singles
/// themselves in the first round); a further waviness order while fewer than
/// `MAX_WAVINESS_ORDERS` are taken. An effect that explains nothing alone is not
/// looked for beside others.
fn greedy_round(
    problem: &mut Problem,
    singles: &[(Fit, f64)],
    cur: &Fit,
    job: &Job,
    fitted: &Measurement,
    log: &dyn Fn(&str),
) -> Result<Vec<Fit>, DiagnoseError> {
    partners_round(problem, singles, cur, (job, fitted), false, log)
}

/// [`greedy_round`], with every candidate tried when `all` (an effect can explain
/// nothing alone while a stronger one it bends is missing).
fn partners_round(
    problem: &mut Problem,
    singles: &[(Fit, f64)],
    cur: &Fit,
    (job, fitted): (&Job, &Measurement),
    all: bool,
    log: &dyn Fn(&str),
) -> Result<Vec<Fit>, DiagnoseError> {
    if cur.effect_members().is_empty() {
        return Ok(singles.iter().map(|(f, _)| f.clone()).collect());
    }
    let mut round = Vec::new();
    let effects = cur.effects();
    let waviness_taken = effects.iter().filter(|c| c.is_waviness()).count();
    let mut partners = Vec::new();
    for (single, evidence) in singles {
        if *evidence <= 0.0 && !all {
            continue;
        }
        let c = *single.set.last().expect("a single has its candidate");
        let is_waviness = c.is_waviness();
        let taken = effects.iter().any(|t| t.kind() == c.kind());
        if taken && !(is_waviness && waviness_taken < MAX_WAVINESS_ORDERS) {
            continue;
        }
        partners.push(if is_waviness {
            Candidate::EdgeWaviness { order: 0.0 }
        } else {
            c
        });
    }
    let fits = side_by_side::each(
        problem,
        &partners,
        Candidate::is_waviness,
        |problem, &c, log| {
            log(&format!("fitting {} with {}", c.label(), labels(&effects)));
            fit_new(problem, &cur.set, &cur.values, c, job, fitted)
        },
        log,
    );
    for fit in fits {
        round.extend(fit?);
    }
    Ok(round)
}

/// One-parameter partners of a round fitted again from the spiral's half-turn alias
/// ([`from_the_alias`]), the best [`ALIAS_TRIES`] of them (least Σr²): a set-up effect
/// added beside another can move the axis by that alias.
const ALIAS_TRIES: usize = 2;

fn with_aliases(problem: &mut Problem, mut round: Vec<Fit>) -> Result<Vec<Fit>, ForwardError> {
    let mut order: Vec<usize> = (0..round.len())
        .filter(|&k| round[k].set.last().is_some_and(|c| width(c) == 1))
        .collect();
    order.sort_by(|&a, &b| round[a].objective.total_cmp(&round[b].objective));
    for &k in order.iter().take(ALIAS_TRIES) {
        let fit = round[k].clone();
        round[k] = from_the_alias(problem, fit)?;
    }
    Ok(round)
}

/// `fit` on a line whose axis comb has mirrored teeth, fitted again with the axis held
/// half a mark to either side and the line read half a turn round — where a spiral of
/// even feed repeats but at the axis — then freed; the best of the three kept. The
/// comb picks the best tooth for each trial's values, so values that settled on that
/// alias keep it: batch c06's decentre + drift, fitted from the decentre's frame, stayed
/// half an 8 µm mark off, where the pair fitted at the true axis leaves Δχ² ≈ 500 less.
fn from_the_alias(problem: &mut Problem, fit: Fit) -> Result<Fit, ForwardError> {
    let Some(comb) = problem.shift.comb.filter(|c| c.mirror_odd) else {
        return Ok(fit);
    };
    let frame = problem.shift;
    let registered = fit.evaluation.registered.clone();
    let direction = problem.measurement.line_direction();
    let mut best = fit;
    for side in [-1.0, 1.0] {
        let alias = ShiftSearch {
            start: registered.shift_mm + side * comb.step_mm * direction,
            mirrored: !registered.mirrored,
            comb: None,
            ..frame
        };
        let held = problem.fit_in_frame(alias, &best.set, best.values.clone())?;
        let freed = problem.fit(&best.set, held.values, &[])?;
        if freed.objective < best.objective {
            best = freed;
        }
    }
    Ok(best)
}

/// Whether `fit` leaves more than noise: its residual's RMS over twice the white noise
/// read from the residual's point-to-point scatter.
fn leaves_structure(fit: &Fit, m: &Measurement) -> bool {
    let residual = &fit.evaluation.registered.residual_mm;
    zones::rms(residual) > 2.0 * zones::white_noise_mm(m, residual)
}

/// Whether a further effect could still remove [`MIN_REDUCTION`] of `fit`'s residual
/// RMS without taking it below [`NOISE_FLOOR`] of its white noise. Where it could not,
/// no partner would be accepted (see [`too_small`]), and none is fitted.
fn above_noise_floor(fit: &Fit, m: &Measurement) -> bool {
    let residual = &fit.evaluation.registered.residual_mm;
    (1.0 - MIN_REDUCTION) * zones::rms(residual) > NOISE_FLOOR * zones::white_noise_mm(m, residual)
}

/// One backward pass: the first effect the others explain as well without it is dropped.
fn drop_redundant(
    problem: &mut Problem,
    cur: &Fit,
    options: &Options,
    log: &dyn Fn(&str),
) -> Result<Option<Fit>, DiagnoseError> {
    for drop in cur.effect_members() {
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
            reduced.objective,
            reduced.parameter_count(),
            cur,
            cur.effective_points,
        );
        if e < options.min_evidence {
            log(&format!(
                "{} adds nothing beyond the others: dropped",
                cur.set[drop].label()
            ));
            return Ok(Some(reduced));
        }
    }
    Ok(None)
}

/// After an effect is dropped, each one left must still predict the data it was not
/// fitted on by itself beside the others: one accepted only as the dropped effect's
/// partner may have stood on it (a decentre beside a vibration that a waviness then
/// replaced). The first that does not is dropped too, and the rest checked again.
fn keep_what_predicts(
    problem: &mut Problem,
    folds: &Folds,
    found: &mut Search,
    mut fit: Fit,
    log: &dyn Fn(&str),
) -> Result<Fit, DiagnoseError> {
    'check: loop {
        for member in fit.effect_members() {
            let last = with_member_last(problem, &fit, member, true)?;
            if predicts_unseen(problem, folds, found, &last, log)?.is_none() {
                log(&format!(
                    "{} does not predict unseen data beside the others: dropped",
                    fit.set[member].label()
                ));
                fit = with_member_last(problem, &fit, member, false)?;
                if fit.effect_members().is_empty() {
                    return Ok(fit);
                }
                continue 'check;
            }
        }
        return Ok(fit);
    }
}

/// `fit`'s set refitted with `member` moved last (`keep`; `fit` itself where it is
/// last already) or left out.
fn with_member_last(
    problem: &mut Problem,
    fit: &Fit,
    member: usize,
    keep: bool,
) -> Result<Fit, DiagnoseError> {
    if keep && member + 1 == fit.set.len() {
        return Ok(fit.clone());
    }
    let order: Vec<usize> = (0..fit.set.len())
        .filter(|&i| i != member)
        .chain(keep.then_some(member))
        .collect();
    let set: Vec<Candidate> = order.iter().map(|&i| fit.set[i]).collect();
    let start: Vec<f64> = order
        .iter()
        .flat_map(|&i| fit.values_of(i).0.to_vec())
        .collect();
    Ok(problem.fit(&set, start, &[])?)
}

/// A strong effect the nominal model lacked can mislead the nominal registration by
/// whole mark periods — or, on a turned spiral of even feed, by half a mark with the
/// spiral half a turn round: the single fit is registered again over ±2.5 marks (a map
/// whose pixels do not resolve the marks over its whole field), as it
/// is and (where the spiral's azimuth is fitted) half a turn round, and refitted where
/// that puts the axis if it moved; the better of the two fits is kept. (A turned line
/// searches those placements in every trial: its registration has an axis comb.)
#[allow(clippy::too_many_arguments)]
fn refit_if_axis_moves(
    problem: &mut Problem,
    fit: Fit,
    base: &Fit,
    nominal: ShiftSearch,
    period_mm: f64,
    job: &Job,
    fitted: &Measurement,
    log: &dyn Fn(&str),
) -> Result<Fit, DiagnoseError> {
    // A comb searches every such placement in each trial already.
    if !problem.terms.shift || problem.shift.comb.is_some() {
        return Ok(fit);
    }
    // A map whose pixels do not resolve the marks was placed by its form alone, which
    // the effect's own form (a cone) pulled by more than marks: placed again over its
    // field, its form first and then the marks near it (`locate::register_on_field`).
    let unresolved_map = (!fitted.is_line())
        .then(|| super::locate::field_search(job, fitted, nominal.start))
        .filter(|(_, resolved)| !resolved);
    let wide = match unresolved_map {
        Some((field, _)) => field,
        None => ShiftSearch {
            start: nominal.start,
            half_width_mm: 2.5 * period_mm,
            step_mm: 0.125 * period_mm,
            refine: 3,
            mirrored: false,
            comb: None,
        },
    };
    let spiral = fit.set.iter().position(|c| *c == Candidate::SpiralAzimuth);
    let turns: &[f64] = if spiral.is_some() {
        &[0.0, 180.0]
    } else {
        &[0.0]
    };
    let mut best: Option<(f64, Vec<f64>, DVec2)> = None;
    for &turn in turns {
        let mut values = fit.values.clone();
        if let Some(i) = spiral {
            values[i] += turn;
        }
        let sim = problem
            .model
            .simulate(&|job| super::fit::apply_set(&fit.set, &values, job))?;
        let again = match unresolved_map {
            // (its scale is not fitted: the pixels do not resolve the marks)
            Some((field, _)) => {
                super::locate::register_on_field(job, fitted, &sim, problem.terms, field)
            }
            None => super::fit::register_trial(
                fitted,
                &sim,
                problem.terms,
                wide,
                (&fit.set, &values),
                None,
            ),
        };
        if best.as_ref().is_none_or(|b| again.rss < b.0) {
            best = Some((again.rss, values, again.shift_mm));
        }
    }
    let Some((_, values, shift)) = best else {
        return Ok(fit);
    };
    if values == fit.values && (shift - nominal.start).length() <= 0.25 * period_mm {
        return Ok(fit);
    }
    let c = *fit.set.last().expect("a single has its candidate");
    log(&format!(
        "{} moves the axis: registering again and refitting it",
        c.label()
    ));
    problem.search_from(super::local_search(shift, period_mm, problem.shift.comb));
    let refit = problem.fit(&fit.set, values, &[])?;
    let mut refit = match fit_new(problem, &base.set, &base.values, c, job, fitted)? {
        Some(r) if r.objective < refit.objective => r,
        _ => refit,
    };
    if let Some((field, _)) = unresolved_map {
        refit = alternate_on_field(problem, refit, field, (period_mm, job, fitted))?;
    }
    // A harmonic's order was screened where the axis lay before: screened again where
    // it has settled (independent map batch m, m03: an order-45 edge waviness screened
    // at the nominal placement came back as order 58.7, and a second order, 34.6, was
    // accepted for what it missed; screened at the axis its own fit settled on, 45.0).
    if c.order().is_some() {
        problem.search_from(refit.frame);
        let fresh = c.with_order(0.0);
        if let Some(again) = fit_new(problem, &base.set, &base.values, fresh, job, fitted)?
            && again.objective < refit.objective
        {
            refit = again;
        }
    }
    Ok(if refit.objective < fit.objective {
        refit
    } else {
        fit
    })
}

/// A map whose pixels alias the marks: the effect's size and the axis pull on each
/// other through the form (a cone fitted short of its slope puts its vertex elsewhere —
/// independent map batch m, m00: a decentre of −1.24 µm fitted at −0.86 µm from the
/// nominal placement, whose form then put the axis 150 µm from the truth, with its σ
/// 8 µm). Placed again over the field with the refitted values and refitted there, while
/// the axis moves by more than a quarter of a mark and the fit improves, up to
/// [`ALTERNATIONS`] times.
fn alternate_on_field(
    problem: &mut Problem,
    mut fit: Fit,
    field: ShiftSearch,
    (period_mm, job, fitted): (f64, &Job, &Measurement),
) -> Result<Fit, DiagnoseError> {
    for _ in 0..ALTERNATIONS {
        let sim = problem
            .model
            .simulate(&|job| super::fit::apply_set(&fit.set, &fit.values, job))?;
        let again = super::locate::register_on_field(job, fitted, &sim, problem.terms, field);
        let from = fit.evaluation.registered.shift_mm;
        if (again.shift_mm - from).length() <= 0.25 * period_mm {
            break;
        }
        let kept = problem.shift;
        problem.search_from(super::local_search(again.shift_mm, period_mm, kept.comb));
        let next = problem.fit(&fit.set, fit.values.clone(), &[])?;
        if next.objective >= fit.objective {
            problem.search_from(kept);
            break;
        }
        fit = next;
    }
    Ok(fit)
}

/// Placements and refits a map's fit alternates at most ([`alternate_on_field`]).
const ALTERNATIONS: usize = 4;

/// `set` fitted from `start` and from `start` with its lateral scale at one (where it is
/// fitted, and away from one there), the better kept. The job as given, registered,
/// can take a harmonic's print into its scale (a percent's stretch of a form-removed
/// trace under a 30 nm waviness, its marks under the noise), and the harmonic fitted
/// from that scale stays in the wrong basin of the marks' comb.
fn fit_from_placement_too(
    problem: &mut Problem,
    set: &[Candidate],
    start: Vec<f64>,
) -> Result<Fit, ForwardError> {
    let mut best: Option<Fit> = None;
    for from in super::fit::with_unit_scale(set, start) {
        let fit = problem.fit(set, from, &[])?;
        if best.as_ref().is_none_or(|b| fit.objective < b.objective) {
            best = Some(fit);
        }
    }
    Ok(best.expect("at least one start"))
}

/// Fits candidate `c` on top of `base` (at `base_values`); `None` when it cannot be
/// fitted here (waviness with no resolvable order).
pub fn fit_new(
    problem: &mut Problem,
    base: &[Candidate],
    base_values: &[f64],
    c: Candidate,
    job: &Job,
    fitted: &Measurement,
) -> Result<Option<Fit>, ForwardError> {
    let mut set = base.to_vec();
    let mut start = base_values.to_vec();
    let first = start.len();
    match c {
        // A waviness candidate not yet fitted: its order is screened first, away from
        // the orders already in the set.
        Candidate::EdgeWaviness { order: 0.0 } => {
            let taken: Vec<f64> = base
                .iter()
                .filter_map(|b| match b {
                    Candidate::EdgeWaviness { order } => Some(*order),
                    _ => None,
                })
                .collect();
            let WavinessTrials {
                orders,
                half_width,
                range,
            } = waviness_trials(problem, base, base_values, job, fitted)?;
            let orders: Vec<f64> = orders
                .into_iter()
                .filter(|o| taken.iter().all(|t| (o / t - 1.0).abs() > 0.1))
                .collect();
            if orders.is_empty() {
                return Ok(None);
            }
            let Some((order, a, b)) = problem.screen_waviness(
                base,
                base_values,
                &orders,
                half_width,
                WAVINESS_PROBE_NM,
            )?
            else {
                return Ok(None);
            };
            set.push(Candidate::EdgeWaviness { order });
            start.extend([a, b]);
            let fit = fit_from_placement_too(problem, &set, start)?;
            // Where the harmonic could be acted on (it removes a tenth of the RMS), its
            // order is re-fitted over ±40 % of the screened one (within the grid).
            let before = {
                let e = problem.evaluate(base, base_values)?;
                problem.rss(&e)
            };
            if rms_reduction(before, fit.objective) < MIN_REDUCTION {
                return Ok(Some(fit));
            }
            let refitted = refit_waviness_order(problem, &fit, order, range)?;
            Ok(Some(problem.fit(&refitted.set, refitted.values, &[])?))
        }
        // A moving effect's rate is screened on the residual's projection on its
        // signature at the cut clock; a tilt error motion only on a map (along a line
        // its print is a tilt or a cone, which registration and the set-up effects take).
        Candidate::Vibration { cycles: 0.0, .. } | Candidate::TiltErrorMotion { order: 0.0 } => {
            if fitted.is_line() && matches!(c, Candidate::TiltErrorMotion { .. }) {
                return Ok(None);
            }
            let Some(points) = problem.screen_points(base, base_values)? else {
                return Ok(None);
            };
            let nyquist = 0.5 * problem.model.base_job().azimuths as f64;
            let Some((rate, [a, b], _)) =
                super::screen::screen_rate(c, &points, fitted.is_line(), nyquist)
            else {
                return Ok(None);
            };
            set.push(c.with_order(rate));
            // mm → nm, rad → µrad.
            start.extend([a * 1e6, b * 1e6]);
            Ok(Some(problem.fit(&set, start, &[])?))
        }
        // Spring-back does nothing until both its threshold and its share are above
        // zero, and a higher share with a lower threshold raises a cusp alike: the
        // threshold is scanned at a low share and both fitted (the spiral's azimuth
        // moving with the marks' shape); where that fit ends at a bound, from a middle
        // and a high share too, the best kept.
        Candidate::SpringBack => {
            set.push(c);
            let mut best: Option<Fit> = None;
            for share in SPRING_BACK_SHARES {
                let mut from = start.clone();
                from.extend([0.0, share]);
                let fit = problem.fit(&set, from, &[first])?;
                let inside = !fit.at_bound[first..].iter().any(|b| *b);
                if best.as_ref().is_none_or(|b| fit.objective < b.objective) {
                    best = Some(fit);
                }
                if inside {
                    break;
                }
            }
            Ok(best)
        }
        _ => {
            set.push(c);
            start.extend(std::iter::repeat_n(0.0, width(&c)));
            let scan: Vec<usize> = (first..start.len()).collect();
            Ok(Some(problem.fit(&set, start, &scan)?))
        }
    }
}

/// Recovered shares a spring-back fit starts from (see [`fit_new`]).
const SPRING_BACK_SHARES: [f64; 3] = [0.3, 0.6, 0.9];

/// The effective number of independent points for comparing models: from the
/// correlation of the residual the best of them leaves (closest to the noise), the
/// same for all so that no model is favoured by its own residual's texture.
fn common_effective_points(
    fits: &[Fit],
    problem: &mut Problem,
    m: &Measurement,
) -> Result<f64, ForwardError> {
    let baseline = problem.evaluate(&[], &[])?;
    let used = baseline.registered.used as f64;
    let tau = fits
        .iter()
        .min_by(|a, b| a.objective.total_cmp(&b.objective))
        .map_or_else(
            || zones::correlation_length(m, &baseline.registered.residual_mm),
            |f| f.correlation_length,
        );
    Ok(used / tau)
}

/// Evidence `fit` adds over a model leaving `rss_before` with `k_before` parameters.
pub fn evidence(rss_before: f64, k_before: usize, fit: &Fit, n_eff: f64) -> f64 {
    let used = fit.evaluation.registered.used;
    bic(rss_before, used, n_eff, k_before) - bic(fit.objective, used, n_eff, fit.parameter_count())
}

/// Whether member `member`'s parameters stand 3σ clear of zero together. A centre height
/// below centre stands 2σ clear: its σ is not a Gaussian width but half the gap between
/// the measured points its boss's edge lies between (widened by the profile where the
/// data allow more), so ±2σ spans that gap, and zero beyond it means a measured point
/// lies on the boss (a 2 µm boss between points 1 µm apart read "within 3σ of zero").
pub(super) fn significant(fit: &Fit, member: usize) -> bool {
    let (values, sigmas) = fit.values_of(member);
    let z2: f64 = values
        .iter()
        .zip(sigmas)
        .map(|(v, s)| (v / s).powi(2))
        .sum();
    let clear = if fit.set[member].is_boss(values[0]) {
        BOSS_CLEAR_SIGMAS
    } else {
        3.0
    };
    z2.sqrt() > clear
}

/// How many σ a boss's height must stand clear of zero (see [`significant`]).
const BOSS_CLEAR_SIGMAS: f64 = 2.0;

pub fn labels(set: &[Candidate]) -> String {
    set.iter()
        .filter(|c| !c.is_registration())
        .map(Candidate::label)
        .collect::<Vec<_>>()
        .join(" + ")
}

/// Waviness orders for the simulation to try, the half-width it refines the best one
/// in, and the range of orders the data can tell.
struct WavinessTrials {
    orders: Vec<f64>,
    half_width: f64,
    range: OrderRange,
}

/// The order of `fit`'s last member, an edge waviness screened at `order`, re-fitted
/// over ±40 % of it within `range`; where the best order lies at an end of that bracket
/// (the residual still falls beyond it: a scale fitted beside a low order takes its
/// power, and the screens see a higher one), the bracket moves on past that end, at most
/// [`WAVINESS_BRACKET_MOVES`] times.
fn refit_waviness_order(
    problem: &mut Problem,
    fit: &Fit,
    order: f64,
    range: OrderRange,
) -> Result<Fitted, ForwardError> {
    let (range_lo, range_hi) = (range.lowest, range.highest);
    let bracket = |order: f64| ((0.6 * order).max(range_lo), (1.4 * order).min(range_hi));
    let (mut lo, mut hi) = bracket(order);
    let mut best = fit.fitted();
    // A quarter cycle across the edge span: the lowest order is half a cycle.
    let apart = 0.5 * range_lo;
    for _ in 0..=WAVINESS_BRACKET_MOVES {
        best = problem.best_waviness_order_within(&fit.parameters, best, (lo, hi), apart)?;
        let Some(Candidate::EdgeWaviness { order }) = best.set.last().copied() else {
            break;
        };
        let end = 0.05 * (hi - lo);
        (lo, hi) = if order - lo < end && lo > range_lo {
            (bracket(order).0, order + end)
        } else if hi - order < end && hi < range_hi {
            (order - end, bracket(order).1)
        } else {
            break;
        };
    }
    Ok(best)
}

/// The waviness orders the simulation tries, and the half-width it refines the best
/// in: the orders [`super::screen::screen_waviness`] ranks best on the residual's
/// edge-angle signature; without one (XZB, or no slope to read the edge angle from) the
/// grid of [`waviness_orders`] and its step. With the grid's range.
fn waviness_trials(
    problem: &mut Problem,
    base: &[Candidate],
    base_values: &[f64],
    job: &Job,
    fitted: &Measurement,
) -> Result<WavinessTrials, ForwardError> {
    let grid = waviness_orders(job, fitted);
    let range = OrderRange::of(&grid);
    let (Some(&lo), Some(&hi)) = (grid.first(), grid.last()) else {
        return Ok(WavinessTrials {
            orders: grid,
            half_width: 0.0,
            range,
        });
    };
    // Along XZ the edge meets the surface at its slope; XZB holds the edge angle.
    let xz = job
        .process
        .turning()
        .is_some_and(|t| matches!(t.path.mode(), TurningMode::Xz));
    let screened = match problem.screen_points(base, base_values)? {
        Some(points) if xz => super::screen::screen_waviness(&points, lo, hi),
        _ => None,
    };
    let (orders, half_width) = screened.unwrap_or_else(|| {
        let step = grid.get(1).map_or(0.0, |second| second - lo);
        (grid, step)
    });
    Ok(WavinessTrials {
        orders,
        half_width,
        range,
    })
}

/// Harmonic orders to screen for edge waviness: from half a cycle over the edge angles
/// the measured region uses to a wavelength of a quarter of one mark's contact, in
/// steps that shift the phase by at most a quarter cycle across the range (at most 20).
fn waviness_orders(job: &Job, m: &Measurement) -> Vec<f64> {
    let Some(turning) = job.process.turning() else {
        return Vec::new();
    };
    let nose = turning.tool.nose_radius_mm;
    let contact = (turning.path.pass_spacing_mm() / nose).max(0.01);
    let r_max = m.max_radius_mm().min(job.aperture.outer_radius_mm);
    let slope_angle = |r: f64| job.surface.slope(r).atan();
    let (lo, hi) = match turning.path.mode() {
        TurningMode::Xz => {
            let samples = (0..=64).map(|i| slope_angle(r_max * i as f64 / 64.0));
            let (a, b) = samples.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            // A point across the axis lies at the radius |x| and was cut by the same
            // edge angle as its mirror, so a diameter uses no more edge than its longer
            // radius; its range is kept twice that span (the lowest order a quarter cycle
            // over the angles used, not half): a 40 nm harmonic of 0.4 cycle over them is
            // pinned to half an order on a diameter (`tests/independent_profiles.rs`), and
            // where a bend that low imitates a set-up effect, the look-alike widening
            // judges it (`widen_for_look_alikes`).
            if m.xy_mm.iter().any(|p| p.x < 0.0) || m.is_line() {
                (-(a.abs().max(b.abs())), a.abs().max(b.abs()))
            } else {
                (a, b)
            }
        }
        TurningMode::Xzb => (0.0, 0.0),
    };
    let span = (hi - lo) + contact;
    let k_min = (std::f64::consts::PI / span).max(1.0);
    let k_max = (std::f64::consts::TAU / (0.25 * contact)).min(400.0);
    if k_max <= k_min {
        return Vec::new();
    }
    let step = (0.5 * std::f64::consts::PI / span).max((k_max - k_min) / 20.0);
    let count = ((k_max - k_min) / step).floor() as usize + 1;
    (0..count).map(|i| k_min + i as f64 * step).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_holds_another_only_with_every_effect_as_many_times() {
        let waviness = Candidate::EdgeWaviness { order: 19.2 };
        let other_order = Candidate::EdgeWaviness { order: 24.3 };
        let (drift, decentre) = (Candidate::AxialDrift, Candidate::XDecentre);
        let placed = [Candidate::LateralScale, waviness];
        // Registration members aside; an order is the same effect at another value.
        assert!(holds_every_effect_of(&[drift, other_order], &placed));
        assert!(!holds_every_effect_of(&[drift, decentre], &placed));
        // Two orders are not held by one.
        assert!(!holds_every_effect_of(
            &[drift, waviness],
            &[waviness, other_order]
        ));
        assert!(holds_every_effect_of(
            &[waviness, drift, other_order],
            &[other_order, waviness]
        ));
    }
}

//! Fitting effects by re-simulation: a trial set of effect values is simulated, seen as
//! the instrument sees it, registered (piston, tilt, power, the axis shift re-solved for
//! every trial), and judged by its residual. A candidate's start comes from a global scan
//! along each parameter — both signs, magnitudes from a third of its typical size to its
//! bound in steps of about 3 — refined by golden section between the best value's
//! neighbours; Levenberg–Marquardt with finite-difference Jacobians then refines all
//! parameters together. Uncertainties: the larger of the Jacobian's (the residual's
//! variance inflated by its correlation length) and a block sandwich estimate (residual
//! structure and model error that the Jacobian's noise model ignores). A value at its
//! search bound is flagged as such, never reported as a fit.

use super::candidates::{Candidate, Parameter};
use super::forward::{ForwardError, ForwardModel, Frame, ModelParts, SimulatedSurface};
use super::measurement::Measurement;
use super::register::{Registered, ShiftSearch, Terms, register, register_beside};
use super::spectrum::LineNoise;
use super::zones::correlation_length;
use crate::engine::RemovalEngine;
use crate::numeric::{
    LeastSquaresProblem, LmLimits, dot, invert, least_squares, levenberg_marquardt, normal_matrix,
    observable, student_t_975, try_golden_section,
};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::Arc;

/// Everything a fit needs: the points fitted, the forward model, what registration may
/// remove and where it may look for the axis.
/// Golden-section steps refining a scan (the bracket shrinks to 0.618^n).
const GOLDEN_STEPS: usize = 10;
/// Golden-section steps refining a waviness order by re-fitting, between its grid's
/// neighbours (0.618^6: 6 % of that bracket).
const WAVINESS_ORDER_STEPS: usize = 6;
/// Most orders of a waviness order's grid (see [`Problem::best_waviness_order_within`]).
const WAVINESS_GRID_ORDERS: usize = 8;
/// Jacobians a fit takes at most.
const LM_ITERATIONS: usize = 12;
/// Jacobians a waviness order's fit on the order grid takes at most: the grid only
/// brackets the best order for the golden section, whose fits run to the end.
const GRID_ITERATIONS: usize = 3;
/// Amplitude (nm) of the harmonics whose responses project a waviness order's residual.
pub const WAVINESS_PROBE_NM: f64 = 20.0;
/// Simulations a problem keeps for re-registration.
const SIMULATIONS_KEPT: usize = 32;
/// Doublings of the step a σ's profile takes beyond ±σ (up to 16σ).
const PROFILE_DOUBLINGS: usize = 4;
/// The lowest order a waviness order's profile steps to (an order below one is a slope
/// across the edge, which the nose radius and the registration already carry).
const MIN_PROFILE_ORDER: f64 = 1.0;

pub struct Problem<'a, 'e> {
    pub measurement: &'a Measurement,
    pub model: ForwardModel<'e>,
    pub terms: Terms,
    pub shift: ShiftSearch,
    /// The points a fit is judged on (a fold's part when some are held out); every
    /// trial is still registered on all the points: registration places the
    /// measurement, and one part alone would let a tilt absorb half of a cone.
    mask: Option<Arc<Vec<bool>>>,
    /// The points the whole search may judge fits on (`--calibrate-on`: the rest is
    /// held out); every mask is cut from these.
    calibration: Option<Arc<Vec<bool>>>,
    pub prior: Option<AzimuthPrior>,
    cache: HashMap<(String, Vec<u64>), Arc<Evaluation>>,
    /// Simulations by the job the set makes (a lateral scale trial re-registers the
    /// same simulation); emptied when it grows past [`SIMULATIONS_KEPT`].
    simulations: HashMap<(String, Vec<u64>), Arc<SimulatedSurface>>,
}

/// A [`Problem`] without its engine and caches (see [`Problem::parts`]).
pub struct ProblemParts<'a> {
    measurement: &'a Measurement,
    model: ModelParts,
    terms: Terms,
    shift: ShiftSearch,
    mask: Option<Arc<Vec<bool>>>,
    calibration: Option<Arc<Vec<bool>>>,
    prior: Option<AzimuthPrior>,
}

impl<'a> ProblemParts<'a> {
    /// The problem on `engine`, with empty caches.
    pub fn on(self, engine: &mut dyn RemovalEngine) -> Problem<'a, '_> {
        let mut problem = Problem::new(
            self.measurement,
            self.model.on(engine),
            self.terms,
            self.shift,
        );
        problem.mask = self.mask;
        problem.calibration = self.calibration;
        problem.prior = self.prior;
        problem
    }
}

/// One trial: the effect values and the registered residual they leave.
#[derive(Debug)]
pub struct Evaluation {
    pub values: Vec<f64>,
    pub registered: Registered,
    /// The azimuth prior's pseudo-residual (mm; 0 without one): see [`AzimuthPrior`].
    pub prior_mm: f64,
}

/// What the user said about where a turned profile lies on the spiral, held as a
/// belief the data may overrule: a decentre and a drift move the marks alike on a
/// sphere (as does the azimuth), so only the stated azimuth can tell them apart there.
/// It enters the fit as one pseudo-residual, `weight · Δ / σ`, Δ the fitted azimuth's
/// distance from the stated one: at Δ = σ it weighs as much as one effective point.
#[derive(Debug, Clone, Copy)]
pub struct AzimuthPrior {
    /// The stated azimuth relative to the located one (the spiral azimuth member's
    /// value that agrees with the statement), degrees.
    pub centre_deg: f64,
    pub sigma_deg: f64,
    /// The residual's RMS per effective point (mm).
    pub weight_mm: f64,
}

impl Evaluation {
    pub fn rss(&self) -> f64 {
        self.registered.rss
    }

    /// Residual per point (mm), 0 where the simulation had no data.
    pub fn residual(&self) -> Vec<f64> {
        self.registered
            .residual_mm
            .iter()
            .map(|v| if v.is_finite() { *v } else { 0.0 })
            .collect()
    }
}

/// A fitted set of effects.
#[derive(Debug, Clone)]
pub struct Fit {
    pub set: Vec<Candidate>,
    pub parameters: Vec<Parameter>,
    pub values: Vec<f64>,
    /// One standard deviation per value (∞ when the data cannot pin it).
    pub sigmas: Vec<f64>,
    pub evaluation: Arc<Evaluation>,
    /// Σ r² the fit minimised (mm²): the registered residual on the judged points, and
    /// the azimuth prior's term.
    pub objective: f64,
    /// Correlation length of the residual (points) and the effective point count.
    pub correlation_length: f64,
    pub effective_points: f64,
    /// Per value: it sits at its search bound (the data wants more than the job files
    /// allow, or the model cannot explain it): not a fit.
    pub at_bound: Vec<bool>,
    /// Where registration looked for the axis in this fit.
    pub frame: ShiftSearch,
    /// One σ of each edge waviness member's order (in set order; the order is fitted
    /// outside the Jacobian, its column joining the σs' estimate): ∞ when unobservable.
    pub order_sigmas: Vec<f64>,
}

/// A set, its values and the objective they leave: a fit before its σs.
#[derive(Clone, Debug)]
pub struct Fitted {
    pub objective: f64,
    pub set: Vec<Candidate>,
    pub values: Vec<f64>,
}

impl Fit {
    /// The set, values and objective of this fit.
    pub fn fitted(&self) -> Fitted {
        Fitted {
            objective: self.objective,
            set: self.set.clone(),
            values: self.values.clone(),
        }
    }

    /// Bayesian information criterion on the effective point count.
    pub fn bic(&self) -> f64 {
        bic(
            self.objective,
            self.evaluation.registered.used,
            self.effective_points,
            self.parameter_count(),
        )
    }

    /// The parameters the fit chose: its values, and each edge waviness's order (found
    /// by search, not held: it is paid for in BIC like a value).
    pub fn parameter_count(&self) -> usize {
        let orders = self.set.iter().filter(|c| c.is_waviness()).count();
        self.values.len() + orders
    }

    /// The members that are effects (not registration terms), by index.
    pub fn effect_members(&self) -> Vec<usize> {
        (0..self.set.len())
            .filter(|&i| !self.set[i].is_registration())
            .collect()
    }

    /// The effects in the set.
    pub fn effects(&self) -> Vec<Candidate> {
        self.set
            .iter()
            .copied()
            .filter(|c| !c.is_registration())
            .collect()
    }

    /// Where one member's parameters lie in `values`, `sigmas` and `parameters`.
    pub fn parameter_span(&self, member: usize) -> std::ops::Range<usize> {
        let start: usize = self.set[..member].iter().map(width).sum();
        start..start + width(&self.set[member])
    }

    /// `member` at its values in words (with its order's σ where it is a waviness).
    pub fn describe(&self, member: usize) -> String {
        let (values, sigmas) = self.values_of(member);
        self.set[member].describe(values, sigmas, self.order_sigma(member))
    }

    /// One σ of `member`'s order, where it is an edge waviness.
    pub fn order_sigma(&self, member: usize) -> Option<f64> {
        self.order_sigmas.get(self.order_index(member)?).copied()
    }

    /// Where `member`, an edge waviness, lies among the set's waviness members (its
    /// place in `order_sigmas`).
    fn order_index(&self, member: usize) -> Option<usize> {
        if !self.set[member].is_waviness() {
            return None;
        }
        Some(
            self.set[..member]
                .iter()
                .filter(|c| c.is_waviness())
                .count(),
        )
    }

    /// The values and sigmas of one member of the set.
    pub fn values_of(&self, member: usize) -> (&[f64], &[f64]) {
        let span = self.parameter_span(member);
        (&self.values[span.clone()], &self.sigmas[span])
    }
}

/// Adds every member of `set` at its values (concatenated) to the job's effects.
///
/// Where the set fits the spiral's azimuth, an effect that moves the marks along the
/// radius (a decentre moves them out by δ) is paired with the turn of the spiral that
/// moves them back (−2π δ / feed): the azimuth member then holds where the marks are
/// and the effect what it does besides, so a scan over the effect does not have to
/// drag the azimuth round the spiral with it.
pub fn apply_set(set: &[Candidate], values: &[f64], job: &mut crate::model::Job) {
    let mut at = 0;
    for c in set {
        let n = width(c);
        c.apply(&values[at..at + n], job);
        at += n;
    }
    let turn = spiral_compensation_rad(set, values, job);
    if let crate::process::Process::Turning(t) = &mut job.process {
        t.azimuth_offset_rad += turn;
    }
}

/// How far round the spiral from the located azimuth the set puts the measurement
/// (degrees): the azimuth member's value and the turn paired with the set's effects.
pub fn spiral_turn_deg(set: &[Candidate], values: &[f64], job: &crate::model::Job) -> f64 {
    let mut at = 0;
    let mut member = 0.0;
    for c in set {
        if *c == Candidate::SpiralAzimuth {
            member += values[at];
        }
        at += width(c);
    }
    member + spiral_compensation_rad(set, values, job).to_degrees()
}

/// The turn of the spiral that moves back the marks the set's effects move (rad; 0
/// when the set does not fit the azimuth).
fn spiral_compensation_rad(set: &[Candidate], values: &[f64], job: &crate::model::Job) -> f64 {
    let Some(turning) = job.process.turning() else {
        return 0.0;
    };
    if !set.contains(&Candidate::SpiralAzimuth) {
        return 0.0;
    }
    let mut at = 0;
    let mut shift_mm = 0.0;
    for c in set {
        shift_mm += c.mark_shift_mm(&values[at..at + width(c)]);
        at += width(c);
    }
    -std::f64::consts::TAU * shift_mm / turning.path.pass_spacing_mm()
}

/// The fit's lateral scale member as a factor on the placement's scale, and its one σ
/// relative to 1 (1 and 0 without the member).
pub fn fitted_stretch(fit: &Fit) -> (f64, f64) {
    match fit.set.iter().position(|c| *c == Candidate::LateralScale) {
        Some(member) => {
            let (v, s) = fit.values_of(member);
            (1.0 + v[0] * 1e-6, s[0] * 1e-6)
        }
        None => (1.0, 0.0),
    }
}

/// The indices of the parameters of `set`'s members for which `which` holds.
pub fn member_parameters(set: &[Candidate], which: impl Fn(&Candidate) -> bool) -> Vec<usize> {
    let mut at = 0;
    let mut found = Vec::new();
    for c in set {
        if which(c) {
            found.extend(at..at + width(c));
        }
        at += width(c);
    }
    found
}

/// Registers `m`, stretched by the set's lateral scale member, to `sim`.
pub(super) fn register_trial(
    m: &Measurement,
    sim: &SimulatedSurface,
    terms: Terms,
    shift: ShiftSearch,
    (set, values): (&[Candidate], &[f64]),
    near: Option<&Registered>,
) -> Registered {
    let stretch = stretch_of(set, values);
    let placed = if stretch == 1.0 {
        std::borrow::Cow::Borrowed(m)
    } else {
        std::borrow::Cow::Owned(stretched(m, stretch))
    };
    match near {
        Some(near) => register_beside(&placed, sim, terms, shift, near),
        None => register(&placed, sim, terms, Some(shift)),
    }
}

/// `m` placed about its own axis (no shift) at `stretch`: its distances from the axis
/// scaled.
fn stretched(m: &Measurement, stretch: f64) -> Measurement {
    m.placed(Frame {
        scale: stretch,
        ..Frame::IDENTITY
    })
}

/// The lateral scale the set's registration members stretch the measurement by.
fn stretch_of(set: &[Candidate], values: &[f64]) -> f64 {
    member_parameters(set, |c| *c == Candidate::LateralScale)
        .iter()
        .map(|&j| 1.0 + values[j] * 1e-6)
        .product()
}

/// Parameters a candidate takes.
pub fn width(candidate: &Candidate) -> usize {
    match candidate {
        Candidate::EdgeWaviness { .. }
        | Candidate::Vibration { .. }
        | Candidate::TiltErrorMotion { .. }
        | Candidate::SpindleTram
        | Candidate::RadialRunout
        | Candidate::SpringBack => 2,
        _ => 1,
    }
}

/// What a parameter's profile rise is judged against (see [`Problem::profile_noise`]).
pub struct ProfileNoise {
    rss: f64,
    point_variance: f64,
    tau: f64,
}

/// One step of a profile: from its offset δ and the last step's values, the set and the
/// values to re-fit from (`None` past where the parameter may go).
type ProfileStep<'a> = dyn Fn(f64, &[f64]) -> Option<(Vec<Candidate>, Vec<f64>)> + 'a;

/// A profile ([`Problem::refitted_profile`]): its half-width, and how far each value
/// moved over it.
pub struct Profile {
    pub half_width: f64,
    pub moved: Vec<f64>,
}

/// The rises of Σr² a profile crosses on one side, in effective points' variance: one
/// (Δχ² = 1, the σ of a parabola) and four (2σ of a parabola).
const PROFILE_LEVELS: [f64; 2] = [1.0, 4.0];

/// One side of a [`Problem::refitted_profile`] as it steps out: for each of
/// [`PROFILE_LEVELS`], the last step below it and where it was crossed (read off a
/// parabola through the origin and the step that crossed, no nearer than the last
/// step below it), with how far each value had moved there (scaled alike).
struct ProfileSide {
    variance: f64,
    below: [f64; 2],
    crossed: [Option<(f64, Vec<f64>)>; 2],
    last: (f64, Vec<f64>),
}

impl ProfileSide {
    /// A side for `values` values; `at_four`: read half the Δχ² = 4 width too (else
    /// that level counts as crossed at once, and the side stops at Δχ² = 1).
    fn new(variance: f64, values: usize, at_four: bool) -> Self {
        let four = (!at_four).then(|| (0.0, vec![0.0; values]));
        Self {
            variance,
            below: [0.0; 2],
            crossed: [None, four],
            last: (0.0, vec![0.0; values]),
        }
    }

    /// Takes the step at `delta` (Σr² risen by `rise`, the values moved by `moved`);
    /// true once the profile has risen past every level.
    fn step(&mut self, delta: f64, rise: f64, moved: Vec<f64>) -> bool {
        for (k, level) in PROFILE_LEVELS.iter().enumerate() {
            let threshold = level * self.variance;
            if self.crossed[k].is_some() {
                continue;
            }
            if rise >= threshold {
                let share = (self.below[k] / delta).max((threshold / rise).sqrt());
                let at = moved.iter().map(|m| m * share).collect();
                self.crossed[k] = Some((delta * share, at));
            } else {
                self.below[k] = delta;
            }
        }
        self.last = (delta, moved);
        self.crossed.iter().all(Option::is_some)
    }

    /// The side's half-width and the values' moves there: the wider of the Δχ² = 1
    /// crossing and half the Δχ² = 4 one (a level never crossed counts at the last
    /// step: the profile is at least that wide).
    fn half_width(self) -> (f64, Vec<f64>) {
        let [one, four] = self.crossed.map(|c| c.unwrap_or_else(|| self.last.clone()));
        if 0.5 * four.0 > one.0 {
            (0.5 * four.0, four.1.iter().map(|m| 0.5 * m).collect())
        } else {
            one
        }
    }
}

/// BIC = n_eff ln(RSS / n) + k ln(n_eff).
pub fn bic(rss: f64, used: usize, effective_points: f64, parameters: usize) -> f64 {
    let n = used.max(1) as f64;
    let n_eff = effective_points.max(2.0);
    n_eff * (rss.max(1e-300) / n).ln() + parameters as f64 * n_eff.ln()
}

impl<'a, 'e> Problem<'a, 'e> {
    pub fn new(
        measurement: &'a Measurement,
        model: ForwardModel<'e>,
        terms: Terms,
        shift: ShiftSearch,
    ) -> Self {
        Self {
            measurement,
            model,
            terms,
            shift,
            mask: None,
            calibration: None,
            prior: None,
            cache: HashMap::new(),
            simulations: HashMap::new(),
        }
    }

    /// Everything the problem is but its engine and caches: the same problem, rebuilt on
    /// another engine ([`ProblemParts::on`]), fits alike.
    pub fn parts(&self) -> ProblemParts<'a> {
        ProblemParts {
            measurement: self.measurement,
            model: self.model.parts(),
            terms: self.terms,
            shift: self.shift,
            mask: self.mask.clone(),
            calibration: self.calibration.clone(),
            prior: self.prior,
        }
    }

    /// Forgets the cached trials (after the axis search moved).
    pub fn clear_cache(&mut self) {
        self.cache.clear();
    }

    /// Places every trial from now on by `shift`'s search; the cached trials, placed by
    /// the search before, are forgotten.
    pub fn search_from(&mut self, shift: ShiftSearch) {
        self.shift = shift;
        self.clear_cache();
    }

    /// Judges fits on the points where `mask` holds (None: all); returns the mask in
    /// force before.
    pub fn judge_on(&mut self, mask: Option<Arc<Vec<bool>>>) -> Option<Arc<Vec<bool>>> {
        std::mem::replace(&mut self.mask, mask)
    }

    /// Holds out the points where `calibration` is false from every fit (None: none).
    pub fn calibrate_on(&mut self, calibration: Option<Arc<Vec<bool>>>) {
        self.calibration = calibration;
    }

    /// Whether point `i` judges fits now.
    fn judged(&self, i: usize) -> bool {
        self.mask.as_ref().is_none_or(|m| m[i]) && self.calibration.as_ref().is_none_or(|c| c[i])
    }

    /// A trial's residual on the judged points (0 elsewhere and where the simulation
    /// has no data), then the azimuth prior's pseudo-residual.
    pub fn residual(&self, e: &Evaluation) -> Vec<f64> {
        let mut r = e.residual();
        for (i, v) in r.iter_mut().enumerate() {
            if !self.judged(i) {
                *v = 0.0;
            }
        }
        r.push(e.prior_mm);
        r
    }

    /// Σ residual² on the judged points.
    pub fn rss(&self, e: &Evaluation) -> f64 {
        self.residual(e).iter().map(|v| v * v).sum()
    }

    /// Simulates `set` at `values` and registers it (cached by the exact values).
    pub fn evaluate(
        &mut self,
        set: &[Candidate],
        values: &[f64],
    ) -> Result<Arc<Evaluation>, ForwardError> {
        let key = cache_key(set, values);
        if let Some(hit) = self.cache.get(&key) {
            return Ok(hit.clone());
        }
        let sim = self.simulation(set, values)?;
        let registered = register_trial(
            self.measurement,
            &sim,
            self.terms,
            self.shift,
            (set, values),
            None,
        );
        let evaluation = Arc::new(Evaluation {
            values: values.to_vec(),
            registered,
            prior_mm: self.prior_term(set, values),
        });
        self.cache.insert(key, evaluation.clone());
        Ok(evaluation)
    }

    /// Evaluates each (set, values) trial (those not cached simulated side by side where
    /// the engine allows), so that later `evaluate` calls find them.
    pub fn evaluate_many(
        &mut self,
        trials: &[(Vec<Candidate>, Vec<f64>)],
    ) -> Result<(), ForwardError> {
        let mut missing: Vec<(Vec<Candidate>, Vec<f64>)> = Vec::new();
        for trial in trials {
            let key = cache_key(&trial.0, &trial.1);
            if !self.cache.contains_key(&key)
                && !missing.iter().any(|m| cache_key(&m.0, &m.1) == key)
            {
                missing.push(trial.clone());
            }
        }
        self.forget_simulations(missing.len());
        self.simulate_all(&missing)?;
        let registered = self.register_all(&missing, None);
        for ((set, values), registered) in missing.into_iter().zip(registered) {
            let evaluation = Arc::new(Evaluation {
                prior_mm: self.prior_term(&set, &values),
                values,
                registered,
            });
            self.cache
                .insert(cache_key(&set, &evaluation.values), evaluation);
        }
        Ok(())
    }

    /// The finite-difference steps `steps` of `set` from `at`, each registered beside
    /// `at` ([`register_beside`]), and last `at` itself registered the same way: the
    /// columns taken between them carry no part of the whole search's own tolerance,
    /// and a step that changes nothing gives a zero column. Not cached (a later
    /// evaluation at the same values searches the whole comb).
    fn evaluate_beside(
        &mut self,
        set: &[Candidate],
        steps: Vec<Vec<f64>>,
        at: &Evaluation,
    ) -> Result<Vec<Evaluation>, ForwardError> {
        let mut trials: Vec<(Vec<Candidate>, Vec<f64>)> =
            steps.into_iter().map(|v| (set.to_vec(), v)).collect();
        trials.push((set.to_vec(), at.values.clone()));
        self.forget_simulations(trials.len());
        self.simulate_all(&trials)?;
        let registered = self.register_all(&trials, Some(&at.registered));
        Ok(trials
            .into_iter()
            .zip(registered)
            .map(|((set, values), registered)| Evaluation {
                prior_mm: self.prior_term(&set, &values),
                values,
                registered,
            })
            .collect())
    }

    /// Simulates the trials whose jobs are not kept yet, side by side where the engine
    /// allows.
    fn simulate_all(&mut self, trials: &[(Vec<Candidate>, Vec<f64>)]) -> Result<(), ForwardError> {
        let mut to_simulate: Vec<&(Vec<Candidate>, Vec<f64>)> = Vec::new();
        for trial in trials {
            let key = job_key(&trial.0, &trial.1);
            if !self.simulations.contains_key(&key)
                && !to_simulate.iter().any(|t| job_key(&t.0, &t.1) == key)
            {
                to_simulate.push(trial);
            }
        }
        type Modify<'b> = Box<dyn Fn(&mut crate::model::Job) + Sync + 'b>;
        let modifies: Vec<Modify> = to_simulate
            .iter()
            .map(|(set, values)| {
                Box::new(move |job: &mut crate::model::Job| apply_set(set, values, job)) as Modify
            })
            .collect();
        let refs: Vec<&(dyn Fn(&mut crate::model::Job) + Sync)> =
            modifies.iter().map(|m| m.as_ref()).collect();
        let sims = self.model.simulate_many(&refs)?;
        for ((set, values), sim) in to_simulate.into_iter().zip(sims) {
            self.simulations.insert(job_key(set, values), Arc::new(sim));
        }
        Ok(())
    }

    /// The trials (simulated) registered side by side; beside `near` where given.
    fn register_all(
        &self,
        trials: &[(Vec<Candidate>, Vec<f64>)],
        near: Option<&Registered>,
    ) -> Vec<Registered> {
        let sims: Vec<&SimulatedSurface> = trials
            .iter()
            .map(|(set, values)| self.simulations[&job_key(set, values)].as_ref())
            .collect();
        let (m, terms, shift) = (self.measurement, self.terms, self.shift);
        trials
            .par_iter()
            .zip(sims)
            .map(|((set, values), sim)| register_trial(m, sim, terms, shift, (set, values), near))
            .collect()
    }

    /// The simulation of the job `set` at `values` makes (kept for trials that differ
    /// only in registration members).
    fn simulation(
        &mut self,
        set: &[Candidate],
        values: &[f64],
    ) -> Result<Arc<SimulatedSurface>, ForwardError> {
        let key = job_key(set, values);
        if let Some(sim) = self.simulations.get(&key) {
            return Ok(sim.clone());
        }
        let sim = Arc::new(self.model.simulate(&|job| apply_set(set, values, job))?);
        self.forget_simulations(1);
        self.simulations.insert(key, sim.clone());
        Ok(sim)
    }

    /// The measured points as the rate screen sees them with `set` at `values`: the
    /// residual (0 where not judged), the simulation's cut clock and radial slope where
    /// the registration puts each point, and its radius; `None` without a clock.
    pub fn screen_points(
        &mut self,
        set: &[Candidate],
        values: &[f64],
    ) -> Result<Option<Vec<super::screen::Point>>, ForwardError> {
        let e = self.evaluate(set, values)?;
        let sim = self.simulation(set, values)?;
        let stretch = stretch_of(set, values);
        let frame = Frame {
            shift_mm: e.registered.shift_mm / stretch,
            scale: stretch,
            mirrored: e.registered.mirrored,
        };
        let Some(clock) = sim.clock_and_slope(self.measurement, frame) else {
            return Ok(None);
        };
        let residual = self.residual(&e);
        Ok(Some(
            clock
                .iter()
                .zip(&residual)
                .zip(&self.measurement.xy_mm)
                .map(
                    |((&(clock_rad, slope), &residual_mm), p)| super::screen::Point {
                        residual_mm,
                        clock_rad,
                        slope,
                        radius_mm: frame.to_part(*p).length(),
                    },
                )
                .collect(),
        ))
    }

    /// `fit`'s simulation, its lateral stretch, and the measurement read at that stretch:
    /// what each of the axis σs below judges the fit's placement on.
    fn as_fitted(
        &mut self,
        fit: &Fit,
    ) -> Result<(Arc<SimulatedSurface>, f64, Measurement), ForwardError> {
        let sim = self.simulation(&fit.set, &fit.values)?;
        let stretch = stretch_of(&fit.set, &fit.values);
        Ok((sim, stretch, stretched(self.measurement, stretch)))
    }

    /// One σ of a line's axis position in `fit` (mm, in the placed measurement's frame):
    /// see [`super::register::axis_sigma_mm`].
    pub fn axis_sigma_mm(&mut self, fit: &Fit) -> Result<f64, ForwardError> {
        let (sim, stretch, stretched) = self.as_fitted(fit)?;
        let sigma = super::register::axis_sigma_mm(
            &stretched,
            &sim,
            self.terms,
            fit.frame,
            &fit.evaluation.registered,
            (fit.correlation_length, self.boss_of(fit)),
        );
        Ok(sigma / stretch)
    }

    /// One σ of a map's axis position in `fit` along X and Y (mm, in the placed
    /// measurement's frame): the fit's linearised σ of the shift alone
    /// ([`super::locate::map_sigmas`]), widened by half the largest disagreement between
    /// where the halves of the map put the axis — left and right of its middle, below
    /// and above — each placed alone with `fit`'s model over the whole map's field
    /// ([`super::locate::register_on_field`]). The linearised σ sees only the noise; an
    /// error of the model (an effect the data carry but no fold accepted still bends the
    /// form) places the halves apart (random map p04: an order-18 edge waviness refused,
    /// the axis 55 µm off at ± 2.5 µm).
    pub fn map_axis_sigmas_mm(&mut self, fit: &Fit) -> Result<[f64; 2], ForwardError> {
        let (sim, stretch, stretched) = self.as_fitted(fit)?;
        let start = fit.evaluation.registered.shift_mm;
        let linear =
            super::locate::map_sigmas(&stretched, &sim, Frame::at(start), self.terms.power, false);
        let job = self.model.base_job();
        let (field, _) = super::locate::field_search(job, &stretched, start);
        let middle = stretched
            .xy_mm
            .iter()
            .fold(glam::DVec2::ZERO, |sum, p| sum + *p)
            / stretched.len().max(1) as f64;
        let axis_of = |lower: bool, along: usize| {
            let half = stretched.subset(|i| (stretched.xy_mm[i][along] < middle[along]) == lower);
            super::locate::register_on_field(job, &half, &sim, self.terms, field).shift_mm
        };
        let mut split = [0.0_f64; 2];
        for along in 0..2 {
            let apart = 0.5 * (axis_of(true, along) - axis_of(false, along)).abs();
            split[0] = split[0].max(apart.x);
            split[1] = split[1].max(apart.y);
        }
        Ok([0, 1].map(|k| linear[k].hypot(split[k]) / stretch))
    }

    /// Half the difference between where the two halves of a line put its axis (mm, in
    /// the placed measurement's frame), each registered alone with `fit`'s model by the
    /// fits' own search (a jackknife over halves): on a radius the axis lies outside the
    /// data and is placed by the form's reach and the marks' comb, and an error of the
    /// model there (an effect too small to accept still bends the form) moves it by teeth
    /// that the fit's own σ counts as excluded; the halves see the form differently and
    /// disagree by it. (More segments were tried: a segment without the feature that
    /// pins the axis wanders by whole teeth, and the spread with it.)
    pub fn axis_split_mm(&mut self, fit: &Fit) -> Result<f64, ForwardError> {
        let (sim, stretch, stretched) = self.as_fitted(fit)?;
        let mut along = stretched.along_mm.clone();
        along.sort_by(f64::total_cmp);
        let middle = along[along.len() / 2];
        let direction = stretched.line_direction();
        let axis = |lower: bool| {
            let half = stretched.subset(|i| (stretched.along_mm[i] < middle) == lower);
            register(&half, &sim, self.terms, Some(self.shift))
                .shift_mm
                .dot(direction)
        };
        let (a, b) = (axis(true), axis(false));
        Ok(0.5 * (a - b).abs() / stretch)
    }

    /// How far a diameter's axis moves (mm, in the placed measurement's frame) when the
    /// points within `clear_mm` of it are left out and the rest re-registered beside
    /// `fit`'s placement with `fit`'s model: what the centre alone pulls. A model's cone or
    /// boss at the axis never matches a part's exactly (the flank, the spiral's end), and
    /// the mismatch moves the axis by more than the marks' σ allows (independent spiral
    /// batch d: a +4.96 µm centre height's cone put the axis 55 nm off at ± 5 nm; the marks
    /// beyond 25 µm put it 3 nm off).
    pub fn axis_pull_of_centre_mm(
        &mut self,
        fit: &Fit,
        clear_mm: f64,
    ) -> Result<f64, ForwardError> {
        let (sim, stretch, stretched) = self.as_fitted(fit)?;
        let best = &fit.evaluation.registered;
        let away = stretched.subset(|i| (stretched.xy_mm[i] - best.shift_mm).length() > clear_mm);
        let moved = register_beside(&away, &sim, self.terms, fit.frame, best);
        let along = (moved.shift_mm - best.shift_mm).dot(stretched.line_direction());
        Ok(along.abs() / stretch)
    }

    /// The radius of `fit`'s centre-height feature (its boss or cone, mm), 0 without one.
    pub fn centre_feature_radius_mm(fit: &Fit) -> f64 {
        member_parameters(&fit.set, |c| *c == Candidate::CentreHeight)
            .into_iter()
            .map(|j| fit.values[j].abs() * 1e-3)
            .fold(0.0, f64::max)
    }

    /// Makes room for `coming` simulations among those kept.
    fn forget_simulations(&mut self, coming: usize) {
        if self.simulations.len() + coming > SIMULATIONS_KEPT {
            self.simulations.clear();
        }
    }

    /// The prior's pseudo-residual for `set` at `values` (0 without a prior, or when the
    /// set does not fit the azimuth).
    fn prior_term(&self, set: &[Candidate], values: &[f64]) -> f64 {
        let Some(prior) = self.prior else {
            return 0.0;
        };
        if !set.contains(&Candidate::SpiralAzimuth) {
            return 0.0;
        }
        let turn = spiral_turn_deg(set, values, self.model.base_job());
        let d = (turn - prior.centre_deg + 180.0).rem_euclid(360.0) - 180.0;
        prior.weight_mm * d / prior.sigma_deg
    }

    /// The parameters of `set`'s members, in order, for this job.
    fn parameters_of(&self, set: &[Candidate]) -> Vec<Parameter> {
        set.iter()
            .flat_map(|c| c.parameters(self.model.base_job()))
            .collect()
    }

    /// [`Problem::fit`] (no scan) with the registration searched in `frame`, the
    /// problem's own frame restored after.
    pub fn fit_in_frame(
        &mut self,
        frame: ShiftSearch,
        set: &[Candidate],
        start: Vec<f64>,
    ) -> Result<Fit, ForwardError> {
        let own = std::mem::replace(&mut self.shift, frame);
        self.clear_cache();
        let fit = self.fit(set, start, &[]);
        self.search_from(own);
        fit
    }

    /// Fits `set` starting from `start`: a scan along each parameter listed in `scan`
    /// (the others re-adjusted linearly at every step, so a new effect can trade off
    /// against those already there), then Levenberg–Marquardt on all of them.
    pub fn fit(
        &mut self,
        set: &[Candidate],
        start: Vec<f64>,
        scan: &[usize],
    ) -> Result<Fit, ForwardError> {
        let parameters = self.parameters_of(set);
        // The lateral scale is not re-adjusted linearly along a scan: the marks make the
        // residual far from linear in it, and a linear step there misjudges every trial.
        let scale_member = member_parameters(set, |c| *c == Candidate::LateralScale);
        let others: Vec<usize> = (0..start.len())
            .filter(|j| !scan.contains(j) && !scale_member.contains(j))
            .collect();
        let mut best: Option<Fit> = None;
        for mut values in scan_starts(set, start, scan) {
            for &j in scan {
                values = self.scan(set, &parameters, &values, j, &others)?;
            }
            let fitted = self.levenberg_marquardt(set, &parameters, values, &[])?;
            let (values, jacobian) = self.round_the_turn(set, &parameters, fitted, &[])?;
            let fit = self.finish(set, parameters.clone(), values, &jacobian, &[])?;
            if best.as_ref().is_none_or(|b| fit.objective < b.objective) {
                best = Some(fit);
            }
        }
        let mut fit = best.expect("at least one start");
        // A component whose uncertainty exceeds its whole range is not seen by this
        // measurement (runout across the feed on a profile along it): it goes back to
        // zero, stays there, and is reported as not seen (σ = ∞).
        let unseen: Vec<usize> = (0..fit.values.len())
            .filter(|&j| fit.sigmas[j].is_nan() || fit.sigmas[j] > parameters[j].bound)
            .collect();
        if !unseen.is_empty() && unseen.len() < fit.values.len() {
            let mut values = fit.values.clone();
            for &j in &unseen {
                values[j] = 0.0;
            }
            let (values, jacobian) = self.levenberg_marquardt(set, &parameters, values, &unseen)?;
            fit = self.finish(set, parameters, values, &jacobian, &unseen)?;
        }
        self.widen_to_profile(&mut fit)?;
        Ok(fit)
    }

    /// Fits `set` from `start` with the parameters `held` kept where `start` puts them
    /// first, so that the others settle around them, then all of them free: a member
    /// moved to another basin (its mirror) is not pulled straight back by partners
    /// still sized for the old one.
    pub fn fit_around(
        &mut self,
        set: &[Candidate],
        start: Vec<f64>,
        held: &[usize],
    ) -> Result<Fit, ForwardError> {
        let parameters = self.parameters_of(set);
        let (settled, _) = self.levenberg_marquardt(set, &parameters, start, held)?;
        self.fit(set, settled, &[])
    }

    /// Where the fit left the spiral's azimuth at its bound (half a turn either way), the
    /// same azimuth from the other side: the turn is periodic and the bound only keeps
    /// it in one turn, so a fit started near half a turn ([`scan_starts`]) that leans
    /// past it goes on from there. The better of the two is kept.
    fn round_the_turn(
        &mut self,
        set: &[Candidate],
        parameters: &[Parameter],
        (values, jacobian): (Vec<f64>, Vec<Vec<f64>>),
        frozen: &[usize],
    ) -> Result<(Vec<f64>, Vec<Vec<f64>>), ForwardError> {
        let at_bound = member_parameters(set, |c| *c == Candidate::SpiralAzimuth)
            .into_iter()
            .filter(|&j| values[j].abs() >= 0.98 * parameters[j].bound)
            .collect::<Vec<_>>();
        if at_bound.is_empty() {
            return Ok((values, jacobian));
        }
        let wrapped = turned_toward_zero(&values, &at_bound, 360.0);
        let (other, other_jacobian) = self.levenberg_marquardt(set, parameters, wrapped, frozen)?;
        let here = {
            let e = self.evaluate(set, &values)?;
            self.rss(&e)
        };
        let there = {
            let e = self.evaluate(set, &other)?;
            self.rss(&e)
        };
        Ok(if there < here {
            (other, other_jacobian)
        } else {
            (values, jacobian)
        })
    }

    /// Fits `fit`'s set again on rings half as far apart, from where it ended, and
    /// keeps those values: the forward model's own resolution error (a cusp between
    /// rings, the marks' shift near the axis read between rings) biases a fit in
    /// proportion to the ring pitch, and halving the pitch halves that bias. Each σ
    /// becomes at least the move between the two fits, the size of the bias left.
    /// Parameters not seen (σ = ∞) stay where they are. The residuals stay those of the
    /// job's own pitch, which every other figure of the diagnosis is judged on.
    pub fn refine_on_finer_rings(&mut self, fit: &mut Fit) -> Result<(), ForwardError> {
        let held: Vec<usize> = (0..fit.values.len())
            .filter(|&j| !fit.sigmas[j].is_finite())
            .collect();
        let fine = self.on_finer_rings(|p| {
            let (values, jacobian) =
                p.levenberg_marquardt(&fit.set, &fit.parameters, fit.values.clone(), &held)?;
            p.finish(&fit.set, fit.parameters.clone(), values, &jacobian, &held)
        })?;
        for j in 0..fit.values.len() {
            if held.contains(&j) {
                continue;
            }
            let moved = (fine.values[j] - fit.values[j]).abs();
            fit.sigmas[j] = fit.sigmas[j].max(fine.sigmas[j]).max(moved);
            fit.values[j] = fine.values[j];
        }
        for (s, f) in fit.order_sigmas.iter_mut().zip(&fine.order_sigmas) {
            *s = s.max(*f);
        }
        fit.at_bound = fine.at_bound;
        Ok(())
    }

    /// `fit`'s set and values simulated on rings half as far apart and registered.
    pub fn evaluate_on_finer_rings(&mut self, fit: &Fit) -> Result<Arc<Evaluation>, ForwardError> {
        self.on_finer_rings(|p| p.evaluate(&fit.set, &fit.values))
    }

    /// Runs `work` with the forward model on rings half as far apart, then puts the
    /// job's own pitch back; nothing simulated on either pitch is reused on the other.
    fn on_finer_rings<T>(
        &mut self,
        work: impl FnOnce(&mut Self) -> Result<T, ForwardError>,
    ) -> Result<T, ForwardError> {
        let pitch = self.model.pitch_mm();
        self.model.set_pitch_mm(0.5 * pitch)?;
        self.forget_all();
        let out = work(self);
        self.model.set_pitch_mm(pitch)?;
        self.forget_all();
        out
    }

    fn forget_all(&mut self) {
        self.cache.clear();
        self.simulations.clear();
    }

    /// Widens each effect parameter's σ to its profile's half-width
    /// ([`Self::profile_half_width`], stepped out from ±σ at most [`PROFILE_DOUBLINGS`]
    /// times). Where the residual is not the parabola the Jacobian assumes — a slow
    /// rise, then a steep one — this is the honest width; where it is, it changes
    /// nothing. A boss's height was sized by its profile alone in [`Self::finish`].
    fn widen_to_profile(&mut self, fit: &mut Fit) -> Result<(), ForwardError> {
        let noise = self.profile_noise(&fit.evaluation, fit.values.len(), fit.correlation_length);
        let effects = member_parameters(&fit.set, |c| !c.is_registration());
        for j in effects {
            let sigma = fit.sigmas[j];
            let boss = self.boss_edge_sigma(&fit.set, j, fit.values[j]) > 0.0;
            if boss || !(sigma.is_finite() && sigma > 0.0) || fit.at_bound[j] {
                continue;
            }
            let at = (&fit.set[..], &fit.values[..], fit.parameters[j].bound);
            let width = self.profile_half_width(at, j, sigma, PROFILE_DOUBLINGS, &noise)?;
            fit.sigmas[j] = sigma.max(width);
        }
        Ok(())
    }

    /// Widens each edge waviness member's order σ to its profile's half-width, every
    /// value re-fitted at each order ([`Self::order_profile`]), and every value's σ to
    /// how far it moves over that half-width. Order and amplitude trade along a curved
    /// valley (a nearby order with another amplitude and phase leaves nearly the same
    /// residual): the linearised σs, and a profile that holds the other values, see
    /// only the valley's floor at the fit.
    pub fn widen_by_order_profile(&mut self, fit: &mut Fit) -> Result<(), ForwardError> {
        // (member, its place among the set's waviness orders)
        let members: Vec<(usize, usize)> = (0..fit.set.len())
            .filter(|&m| fit.order_sigma(m).is_some_and(|s| s.is_finite() && s > 0.0))
            .filter_map(|m| Some((m, fit.order_index(m)?)))
            .collect();
        if members.is_empty() {
            return Ok(());
        }
        let noise = self.profile_noise(
            &fit.evaluation,
            fit.parameter_count(),
            fit.correlation_length,
        );
        for (m, k) in members {
            let profile = self.order_profile(fit, m, fit.order_sigmas[k], &noise)?;
            fit.order_sigmas[k] = fit.order_sigmas[k].max(profile.half_width);
            for (s, moved) in fit.sigmas.iter_mut().zip(&profile.moved) {
                if s.is_finite() {
                    *s = s.max(*moved);
                }
            }
        }
        Ok(())
    }

    /// The profile of member `m`'s waviness order in `fit`: the order stepped out from
    /// ±`start` ([`Self::refitted_profile`]), never below [`MIN_PROFILE_ORDER`].
    fn order_profile(
        &mut self,
        fit: &Fit,
        m: usize,
        start: f64,
        noise: &ProfileNoise,
    ) -> Result<Profile, ForwardError> {
        let Candidate::EdgeWaviness { order } = fit.set[m] else {
            unreachable!("an order profile of a waviness member");
        };
        let trial = |delta: f64, values: &[f64]| {
            let mut set = fit.set.clone();
            set[m] = Candidate::EdgeWaviness {
                order: order + delta,
            };
            (order + delta >= MIN_PROFILE_ORDER).then(|| (set, values.to_vec()))
        };
        self.refitted_profile(fit, start, &trial, (&[], true), noise)
    }

    /// The profile of value `j` of `fit`: the value stepped out from ±`start`
    /// ([`Self::refitted_profile`]) within its bound, every other value re-fitted. Two
    /// effects whose prints are nearly one (a decentre's cone and a drift's) trade along a
    /// valley whose floor the linearised σs, taken from finite differences of a sampled
    /// model, misjudge: a few hundredths of a nanometre of the marks' interpolation in a
    /// column is enough to make the valley look closed. Read at Δχ² = 1 alone: its moves
    /// decide a tie whose evidence rule ([`super::search::TIE_EVIDENCE`]) weighs the
    /// rest (half the Δχ² = 4 width made suite case 093's drift, which the decentre
    /// alone explains 7.2 worse in ΔBIC, a tie).
    pub fn value_profile(
        &mut self,
        fit: &Fit,
        j: usize,
        start: f64,
        noise: &ProfileNoise,
    ) -> Result<Profile, ForwardError> {
        let (lower, upper) = fit.parameters[j].range();
        let trial = |delta: f64, values: &[f64]| {
            let stepped = fit.values[j] + delta;
            (lower..=upper).contains(&stepped).then(|| {
                let mut values = values.to_vec();
                values[j] = stepped;
                (fit.set.clone(), values)
            })
        };
        self.refitted_profile(fit, start, &trial, (&[j], false), noise)
    }

    /// A profile of `fit` along the trials `trial(δ, last values)` gives (`None` past
    /// where the parameter may go): δ stepped out from ±`start` by doubling (at most
    /// [`PROFILE_DOUBLINGS`] times), the values re-fitted at each step from the last
    /// step's (Levenberg–Marquardt, `frozen` held), until Σr² rises by one effective
    /// point's variance (Δχ² = 1, as in [`Self::profile_half_width`]) — or, `at_four`,
    /// by four, the half-width then the wider of the Δχ² = 1 one and half the Δχ² = 4
    /// one ([`ProfileSide`]): the same for a parabola, wider where the valley flattens
    /// out (a waviness order whose neighbours fit nearly as well a few orders away).
    fn refitted_profile(
        &mut self,
        fit: &Fit,
        start: f64,
        trial: &ProfileStep,
        (frozen, at_four): (&[usize], bool),
        noise: &ProfileNoise,
    ) -> Result<Profile, ForwardError> {
        let mut out = Profile {
            half_width: 0.0,
            moved: vec![0.0; fit.values.len()],
        };
        let print = match trial(start, &fit.values).or_else(|| trial(-start, &fit.values)) {
            Some((set, values)) => {
                let e = self.evaluate(&set, &values)?;
                self.residual_change(&e, &fit.evaluation, 1.0)
            }
            None => return Ok(out),
        };
        let variance = noise.point_variance * inflation(noise.tau, &print);
        for side in [1.0, -1.0] {
            let mut walk = ProfileSide::new(variance, fit.values.len(), at_four);
            let mut values = fit.values.clone();
            for doubling in 0..=PROFILE_DOUBLINGS {
                let delta = start * (1u64 << doubling) as f64;
                let Some((set, from)) = trial(side * delta, &values) else {
                    break;
                };
                let fitted = self.levenberg_marquardt(&set, &fit.parameters, from, frozen)?;
                (values, _) = self.round_the_turn(&set, &fit.parameters, fitted, frozen)?;
                let rise = {
                    let e = self.evaluate(&set, &values)?;
                    self.rss(&e) - noise.rss
                };
                let moved: Vec<f64> = (values.iter().zip(&fit.values))
                    .map(|(v, v0)| (v - v0).abs())
                    .collect();
                if walk.step(delta, rise, moved) {
                    break;
                }
            }
            let (half_width, moved) = walk.half_width();
            out.half_width = out.half_width.max(half_width);
            for (o, mv) in out.moved.iter_mut().zip(moved) {
                *o = o.max(mv);
            }
        }
        Ok(out)
    }

    /// What a profile's rise is judged against, for a fit that left `at` with `k`
    /// values and its residual correlated over `tau` points: Σr² there and one point's
    /// variance.
    pub fn profile_noise(&self, at: &Evaluation, k: usize, tau: f64) -> ProfileNoise {
        let used = at.registered.used.max(1) as f64;
        let rss = self.rss(at);
        ProfileNoise {
            rss,
            point_variance: rss / (used - k as f64 - 4.0).max(1.0),
            tau,
        }
    }

    /// The half-width of the interval of parameter `j` (of `set` fitted at `values`,
    /// within ±`bound`) over which Σr² rises by less than one effective point's
    /// variance (Δχ² = 1: the point variance inflated by [`inflation`] for the
    /// parameter's print), stepped out from ±`start` by doubling (at most `doublings`
    /// times) and read off a parabola through the first step that rises more; or half
    /// the interval where it rises by less than four, where that is wider
    /// ([`ProfileSide`]). A residual flat up to a step (a boss's edge crossing a
    /// sample) counts as flat at least that far. A side that never rises that much
    /// gives the last step.
    fn profile_half_width(
        &mut self,
        (set, values, bound): (&[Candidate], &[f64], f64),
        j: usize,
        start: f64,
        doublings: usize,
        noise: &ProfileNoise,
    ) -> Result<f64, ForwardError> {
        let step_at = |delta: f64| {
            let mut trial = values.to_vec();
            trial[j] = (values[j] + delta).clamp(-bound, bound);
            trial
        };
        let at = self.evaluate(set, values)?;
        // The parameter's print: what its first step changes in the residual.
        let print = {
            let e = self.evaluate(set, &step_at(start))?;
            self.residual_change(&e, &at, 1.0)
        };
        let variance = noise.point_variance * inflation(noise.tau, &print);
        let mut width: f64 = 0.0;
        for side in [1.0, -1.0] {
            let mut walk = ProfileSide::new(variance, 0, true);
            for doubling in 0..=doublings {
                let delta = start * (1u64 << doubling) as f64;
                let e = self.evaluate(set, &step_at(side * delta))?;
                if walk.step(delta, self.rss(&e) - noise.rss, Vec::new()) {
                    break;
                }
            }
            width = width.max(walk.half_width().0);
        }
        Ok(width)
    }

    /// A boss's height (below centre) prints as a step: a finite difference moves a
    /// measured point across its edge or none, so the Jacobian's σ means nothing there
    /// (10⁻³ to 10¹ µm on the same data). Its σ is its profile's half-width, stepped
    /// out from the edge's own floor ([`Self::boss_edge_sigma`]) as far as the bound,
    /// and no less than that floor; ∞ where the profile never rises (the data does not
    /// reach the boss).
    fn boss_sigma(
        &mut self,
        (set, values, bound): (&[Candidate], &[f64], f64),
        j: usize,
        noise: &ProfileNoise,
    ) -> Result<Option<f64>, ForwardError> {
        let edge = self.boss_edge_sigma(set, j, values[j]);
        if edge <= 0.0 {
            return Ok(None);
        }
        let doublings = (bound / edge).log2().ceil().max(0.0) as usize;
        let width = self.profile_half_width((set, values, bound), j, edge, doublings, noise)?;
        Ok(Some(if width >= bound {
            f64::INFINITY
        } else {
            width.max(edge)
        }))
    }

    /// One σ of the lateral scale (relative to 1) in `fit`, widened by its aliases: the
    /// scales at which the marks (`mark_mm` apart) at the line's far end lie one and two
    /// whole marks further along, which a profile with little else to go by barely tells
    /// from the best — each weighted by its likelihood against the best, exp(−Δχ²/2), as
    /// the axis comb's teeth are.
    pub fn scale_sigma_with_aliases(
        &mut self,
        fit: &Fit,
        mark_mm: f64,
    ) -> Result<f64, ForwardError> {
        let (_, sigma) = fitted_stretch(fit);
        let Some(&j) = member_parameters(&fit.set, |c| *c == Candidate::LateralScale).first()
        else {
            return Ok(sigma);
        };
        let axis = fit.evaluation.registered.shift_mm;
        let reach = self
            .measurement
            .xy_mm
            .iter()
            .map(|p| (*p - axis).length())
            .fold(0.0, f64::max);
        if reach <= 0.0 || !sigma.is_finite() {
            return Ok(sigma);
        }
        let variance = fit.objective / fit.effective_points.max(1.0);
        let (mut weight, mut spread) = (1.0, 0.0);
        for k in [-2.0, -1.0, 1.0, 2.0] {
            let alias = k * mark_mm / reach;
            let mut values = fit.values.clone();
            values[j] += alias * 1e6;
            let evaluation = self.evaluate(&fit.set, &values)?;
            let rise = (self.rss(&evaluation) - fit.objective).max(0.0);
            let w = (-rise / (2.0 * variance)).exp();
            weight += w;
            spread += w * alias * alias;
        }
        Ok((sigma * sigma + spread / weight).sqrt())
    }

    /// A fit's boss at the axis, if it has one: its radius and its edges' σ (mm).
    fn boss_of(&self, fit: &Fit) -> Option<(f64, f64)> {
        let j = member_parameters(&fit.set, |c| *c == Candidate::CentreHeight)
            .into_iter()
            .next()?;
        let edge_um = self.boss_edge_sigma(&fit.set, j, fit.values[j]);
        (edge_um > 0.0).then(|| (fit.values[j].abs() * 1e-3, edge_um * 1e-3))
    }

    /// A floor on a centre height's σ below centre (µm): its boss's edge, at radius
    /// |height|, lies somewhere between two measured points, and the fit may put it
    /// anywhere there (the model's own edge, a ramp between rings, pins it far finer than
    /// the data can) — half the point spacing, so that ±2σ spans the whole gap.
    fn boss_edge_sigma(&self, set: &[Candidate], j: usize, value: f64) -> f64 {
        let heights = member_parameters(set, |c| *c == Candidate::CentreHeight);
        if heights.contains(&j) && Candidate::CentreHeight.is_boss(value) {
            0.5 * self.measurement.spacing_mm() * 1e3
        } else {
            0.0
        }
    }

    /// Fits `set` from `start` by Levenberg–Marquardt with the parameters `held` kept
    /// at their start values (a fold's fit keeps the registration the whole data fixed).
    pub fn fit_holding(
        &mut self,
        set: &[Candidate],
        start: Vec<f64>,
        held: &[usize],
    ) -> Result<Fit, ForwardError> {
        let parameters = self.parameters_of(set);
        let (values, jacobian) = self.levenberg_marquardt(set, &parameters, start, held)?;
        self.finish(set, parameters, values, &jacobian, held)
    }

    /// The best value of parameter `j` along its axis, searched globally: the current
    /// value, then both signs at magnitudes from a third of the parameter's scale to its
    /// bound in steps of about 3 (a cone and a cylinder, a larger and a smaller radius, are
    /// all tried); then golden section between the best value's neighbours. At each
    /// value the `others` are re-adjusted by least squares on their Jacobian at the
    /// start. Returns all values at the best one.
    fn scan(
        &mut self,
        set: &[Candidate],
        parameters: &[Parameter],
        base: &[f64],
        j: usize,
        others: &[usize],
    ) -> Result<Vec<f64>, ForwardError> {
        let start = self.evaluate(set, base)?;
        let columns: Vec<Vec<f64>> = others
            .iter()
            .map(|&o| self.column(set, parameters, base, o, &start))
            .collect::<Result<_, _>>()?;
        // (rss, all values) at parameter j = v.
        let at = |problem: &mut Self, v: f64| -> Result<(f64, Vec<f64>), ForwardError> {
            let mut trial = base.to_vec();
            trial[j] = v;
            let evaluation = problem.evaluate(set, &trial)?;
            let r = problem.residual(&evaluation);
            if columns.is_empty() {
                return Ok((dot(&r, &r), trial));
            }
            let rows: Vec<Vec<f64>> = (0..r.len())
                .map(|i| columns.iter().map(|c| c[i]).collect())
                .collect();
            let target: Vec<f64> = r.iter().map(|v| -v).collect();
            let Some(delta) = least_squares(&rows, &target) else {
                return Ok((dot(&r, &r), trial));
            };
            let rss = (0..r.len())
                .map(|i| {
                    (r[i]
                        + (0..columns.len())
                            .map(|c| columns[c][i] * delta[c])
                            .sum::<f64>())
                    .powi(2)
                })
                .sum();
            for (&o, d) in others.iter().zip(&delta) {
                trial[o] = parameters[o].clamp(trial[o] + d);
            }
            Ok((rss, trial))
        };
        let p = &parameters[j];
        let origin = base[j];
        let trials: Vec<(Vec<Candidate>, Vec<f64>)> = std::iter::once(origin)
            .chain(scan_values(origin, p))
            .map(|v| {
                let mut trial = base.to_vec();
                trial[j] = v;
                (set.to_vec(), trial)
            })
            .collect();
        self.evaluate_many(&trials)?;
        let mut best = at(self, origin)?;
        // Every value tried, to bracket the best afterwards.
        let mut tried = vec![(origin, best.0)];
        for v in scan_values(origin, p) {
            let trial = at(self, v)?;
            tried.push((v, trial.0));
            if trial.0 < best.0 {
                best = trial;
            }
        }
        // Golden-section search between the neighbours of the best value on each side
        // of the origin (a cone and a cylinder, a larger and a smaller radius, are
        // different shapes: the coarse scan can rank the wrong side first): features
        // that move in steps (a centre cylinder's edge between samples) leave the
        // residual too rough for derivatives there.
        tried.sort_by(|a, b| a.0.total_cmp(&b.0));
        for k in best_on_each_side(&tried, origin, best.0) {
            let (a, b) = (tried[k - 1].0, tried[k + 1].0);
            let bracket = try_golden_section(|v| at(self, v).map(|t| t.0), a, b, GOLDEN_STEPS)?;
            // Re-evaluated for their values (the simulations are cached).
            for (v, _) in bracket.inner {
                let candidate = at(self, v)?;
                if candidate.0 < best.0 {
                    best = candidate;
                }
            }
        }
        // The linear re-adjustment is a prediction: keep it only if it really helps.
        let (now, then) = (
            {
                let e = self.evaluate(set, base)?;
                self.rss(&e)
            },
            {
                let e = self.evaluate(set, &best.1)?;
                self.rss(&e)
            },
        );
        Ok(if then < now { best.1 } else { base.to_vec() })
    }

    /// One column of the residual's Jacobian by a forward difference (toward the open
    /// side of the bound).
    fn column(
        &mut self,
        set: &[Candidate],
        parameters: &[Parameter],
        values: &[f64],
        j: usize,
        at: &Evaluation,
    ) -> Result<Vec<f64>, ForwardError> {
        let h = step(parameters, values, j);
        let mut trial = values.to_vec();
        trial[j] += h;
        let e = self.evaluate(set, &trial)?;
        Ok(self.residual_change(&e, at, h))
    }

    /// The residual of `moved` less that of `at`, per `h`: a finite-difference column.
    fn residual_change(&self, moved: &Evaluation, at: &Evaluation, h: f64) -> Vec<f64> {
        self.residual(moved)
            .iter()
            .zip(self.residual(at))
            .map(|(a, b)| (a - b) / h)
            .collect()
    }

    /// The residual's Jacobian, column by column.
    fn jacobian(
        &mut self,
        set: &[Candidate],
        parameters: &[Parameter],
        values: &[f64],
        at: &Evaluation,
    ) -> Result<Vec<Vec<f64>>, ForwardError> {
        let steps: Vec<f64> = (0..values.len())
            .map(|j| step(parameters, values, j))
            .collect();
        let trials: Vec<Vec<f64>> = steps
            .iter()
            .enumerate()
            .map(|(j, h)| {
                let mut trial = values.to_vec();
                trial[j] += h;
                trial
            })
            .collect();
        let mut moved = self.evaluate_beside(set, trials, at)?;
        let base = moved.pop().expect("the base registered last");
        Ok(moved
            .iter()
            .zip(&steps)
            .map(|(e, h)| self.residual_change(e, &base, *h))
            .collect())
    }

    fn levenberg_marquardt(
        &mut self,
        set: &[Candidate],
        parameters: &[Parameter],
        values: Vec<f64>,
        frozen: &[usize],
    ) -> Result<(Vec<f64>, Vec<Vec<f64>>), ForwardError> {
        self.levenberg_marquardt_within(set, parameters, values, frozen, LM_ITERATIONS)
    }

    /// As [`Problem::levenberg_marquardt`], with at most `iterations` Jacobians.
    fn levenberg_marquardt_within(
        &mut self,
        set: &[Candidate],
        parameters: &[Parameter],
        values: Vec<f64>,
        frozen: &[usize],
        iterations: usize,
    ) -> Result<(Vec<f64>, Vec<Vec<f64>>), ForwardError> {
        let bounds: Vec<(f64, f64)> = parameters.iter().map(Parameter::range).collect();
        let small_step: Vec<f64> = parameters.iter().map(|p| 1e-4 * p.scale).collect();
        let limits = LmLimits {
            iterations,
            bounds: &bounds,
            small_step: &small_step,
            min_gain: 1e-6,
            frozen,
        };
        let mut model = SetModel {
            problem: self,
            set,
            parameters,
        };
        let fit = levenberg_marquardt(&mut model, values, &limits)?
            .expect("a set's evaluation is defined for any values");
        Ok((fit.values, fit.jacobian))
    }

    fn finish(
        &mut self,
        set: &[Candidate],
        parameters: Vec<Parameter>,
        values: Vec<f64>,
        jacobian: &[Vec<f64>],
        frozen: &[usize],
    ) -> Result<Fit, ForwardError> {
        let evaluation = self.evaluate(set, &values)?;
        let tau = correlation_length(self.measurement, &evaluation.registered.residual_mm);
        let used = (0..self.measurement.len())
            .filter(|&i| self.judged(i) && evaluation.registered.residual_mm[i].is_finite())
            .count() as f64;
        let free = observable(jacobian, frozen);
        let residual = self.residual(&evaluation);
        let line = self.measurement.is_line();
        // A waviness order is fitted too (outside the Jacobian): its column joins the
        // σs' estimate so that the amplitudes' carry what the order's doubt leaves.
        let orders = self.order_columns(set, &values, &evaluation)?;
        let mut extended = jacobian.to_vec();
        let mut free_extended = free.clone();
        for column in orders {
            free_extended.push(extended.len());
            extended.push(column);
        }
        let sigmas_free = uncertainties(&extended, &free_extended, &residual, tau, line);
        let mut sigmas = vec![f64::INFINITY; values.len()];
        for (&j, s) in free.iter().zip(&sigmas_free) {
            sigmas[j] = *s;
        }
        let order_sigmas = sigmas_free[free.len()..].to_vec();
        let heights = member_parameters(set, |c| *c == Candidate::CentreHeight);
        if !heights.is_empty() {
            let noise = self.profile_noise(&evaluation, values.len(), tau);
            for j in heights {
                let at = (set, &values[..], parameters[j].bound);
                if !frozen.contains(&j)
                    && let Some(sigma) = self.boss_sigma(at, j, &noise)?
                {
                    sigmas[j] = sigma;
                }
            }
        }
        let at_bound = values
            .iter()
            .zip(&parameters)
            .map(|(v, p)| p.at_bound(*v))
            .collect();
        let objective = self.rss(&evaluation);
        Ok(Fit {
            set: set.to_vec(),
            parameters,
            values,
            sigmas,
            evaluation,
            objective,
            correlation_length: tau,
            effective_points: used / tau,
            at_bound,
            frame: self.shift,
            order_sigmas,
        })
    }

    /// Picks the waviness order that best explains the residual left by `base` (the
    /// accepted effects at `base_values`): for each order tried, the residual's
    /// projection on the responses to a cosine and a sine harmonic; then the best order
    /// refined within ±`half_width`. Returns (order, cos, sin) in nm.
    pub fn screen_waviness(
        &mut self,
        base: &[Candidate],
        base_values: &[f64],
        orders: &[f64],
        half_width: f64,
        amplitude_nm: f64,
    ) -> Result<Option<(f64, f64, f64)>, ForwardError> {
        let r0 = {
            let e = self.evaluate(base, base_values)?;
            self.residual(&e)
        };
        let trials: Vec<(Vec<Candidate>, Vec<f64>)> = orders
            .iter()
            .flat_map(|&order| {
                let mut set = base.to_vec();
                set.push(Candidate::EdgeWaviness { order });
                [[amplitude_nm, 0.0], [0.0, amplitude_nm]].map(|ab| {
                    let mut v = base_values.to_vec();
                    v.extend(ab);
                    (set.clone(), v)
                })
            })
            .collect();
        self.evaluate_many(&trials)?;
        let mut best: Option<(f64, f64, f64, f64)> = None;
        for &order in orders {
            let (rss, a, b) = self.waviness_at(base, base_values, order, amplitude_nm, &r0)?;
            if best.is_none_or(|x| rss < x.0) {
                best = Some((rss, order, a, b));
            }
        }
        let Some(mut best) = best else {
            return Ok(None);
        };
        if half_width > 0.0 {
            // Golden section on the order around the best tried, keeping the best
            // order evaluated (7 steps).
            let lowest = orders.iter().copied().fold(f64::INFINITY, f64::min);
            let (lo, hi) = ((best.1 - half_width).max(lowest * 0.5), best.1 + half_width);
            try_golden_section(
                |order| {
                    let f = self.waviness_at(base, base_values, order, amplitude_nm, &r0)?;
                    if f.0 < best.0 {
                        best = (f.0, order, f.1, f.2);
                    }
                    Ok::<f64, ForwardError>(f.0)
                },
                lo,
                hi,
                7,
            )?;
        }
        Ok(Some((best.1, best.2, best.3)))
    }

    /// The residual's derivative by each edge waviness member's order (forward
    /// difference of half a percent), the values held.
    fn order_columns(
        &mut self,
        set: &[Candidate],
        values: &[f64],
        at: &Evaluation,
    ) -> Result<Vec<Vec<f64>>, ForwardError> {
        let mut columns = Vec::new();
        for (m, c) in set.iter().enumerate() {
            let Candidate::EdgeWaviness { order } = *c else {
                continue;
            };
            let h = (0.005 * order).max(0.05);
            let mut moved = set.to_vec();
            moved[m] = Candidate::EdgeWaviness { order: order + h };
            let e = self.evaluate(&moved, values)?;
            columns.push(self.residual_change(&e, at, h));
        }
        Ok(columns)
    }

    /// The order of the fitted set's last member, an edge waviness, that leaves the
    /// least residual when every value is fitted with it (Levenberg–Marquardt), within
    /// `lo..hi`. The residual over the order has a basin for each harmonic the data
    /// holds, and the one the screen began in need not be the deepest: orders `apart`
    /// (a quarter cycle across the edge span) over the bracket are each fitted from
    /// their own projection's amplitudes, then a golden section refines between the
    /// best one's neighbours. The responses the order screens use hold the registration
    /// members still, and a scale or spiral azimuth re-fitted beside the waviness moves
    /// the best order by a fifth and more: each order is fitted at the unit scale too.
    /// Returns the best of `fitted` and the orders tried.
    pub fn best_waviness_order_within(
        &mut self,
        parameters: &[Parameter],
        fitted: Fitted,
        (lo, hi): (f64, f64),
        apart: f64,
    ) -> Result<Fitted, ForwardError> {
        let at = |order: f64| {
            let mut set = fitted.set.clone();
            *set.last_mut().expect("a waviness member") = Candidate::EdgeWaviness { order };
            set
        };
        let (base_set, base_values) = (
            &fitted.set[..fitted.set.len() - 1],
            &fitted.values[..fitted.values.len() - 2],
        );
        let r0 = {
            let e = self.evaluate(base_set, base_values)?;
            self.residual(&e)
        };
        let mut best = fitted.clone();
        let count = (((hi - lo) / apart).ceil() as usize + 1).clamp(2, WAVINESS_GRID_ORDERS);
        let grid: Vec<f64> = (0..count)
            .map(|i| lo + (hi - lo) * i as f64 / (count - 1) as f64)
            .collect();
        // The grid's fits are independent: side by side, then kept in the grid's order.
        let fits = super::side_by_side::each(
            self,
            &grid,
            |_| false,
            |p, &order, _| {
                let (_, a, b) =
                    p.waviness_at(base_set, base_values, order, WAVINESS_PROBE_NM, &r0)?;
                let mut start = base_values.to_vec();
                start.extend([a, b]);
                p.fits_at_order(parameters, &at(order), start, GRID_ITERATIONS)
            },
            &|_| {},
        );
        let mut scores = Vec::with_capacity(count);
        for fits in fits {
            scores.push(keep_lowest(fits?, &mut best));
        }
        let i = (0..count)
            .min_by(|&a, &b| scores[a].total_cmp(&scores[b]))
            .expect("a grid of two orders or more");
        try_golden_section(
            |order| {
                let start = best.values.clone();
                self.fit_order(parameters, &at(order), start, &mut best, LM_ITERATIONS)
            },
            grid[i.saturating_sub(1)],
            grid[(i + 1).min(count - 1)],
            WAVINESS_ORDER_STEPS,
        )?;
        Ok(best)
    }

    /// Fits `trial` (Levenberg–Marquardt) from `start` and from it at the unit scale;
    /// returns the lower Σr² and keeps the fit in `best` where it is lower there.
    fn fit_order(
        &mut self,
        parameters: &[Parameter],
        trial: &[Candidate],
        start: Vec<f64>,
        best: &mut Fitted,
        iterations: usize,
    ) -> Result<f64, ForwardError> {
        let fits = self.fits_at_order(parameters, trial, start, iterations)?;
        Ok(keep_lowest(fits, best))
    }

    /// `trial` fitted (Levenberg–Marquardt, at most `iterations` Jacobians) from `start`
    /// and from it at the unit scale (side by side), in that order.
    fn fits_at_order(
        &mut self,
        parameters: &[Parameter],
        trial: &[Candidate],
        start: Vec<f64>,
        iterations: usize,
    ) -> Result<Vec<Fitted>, ForwardError> {
        super::side_by_side::each(
            self,
            &with_unit_scale(trial, start),
            |_| false,
            |p, start, _| {
                let (values, _) = p.levenberg_marquardt_within(
                    trial,
                    parameters,
                    start.clone(),
                    &[],
                    iterations,
                )?;
                let e = p.evaluate(trial, &values)?;
                Ok(Fitted {
                    objective: p.rss(&e),
                    set: trial.to_vec(),
                    values,
                })
            },
            &|_| {},
        )
        .into_iter()
        .collect()
    }

    /// The least-squares cos/sin amplitudes (nm) of one waviness order against the
    /// residual `r0`, from the responses to each at `amplitude_nm`; with the rss left.
    fn waviness_at(
        &mut self,
        base: &[Candidate],
        base_values: &[f64],
        order: f64,
        amplitude_nm: f64,
        r0: &[f64],
    ) -> Result<(f64, f64, f64), ForwardError> {
        let mut set = base.to_vec();
        set.push(Candidate::EdgeWaviness { order });
        let mut response = |a: f64, b: f64| -> Result<Vec<f64>, ForwardError> {
            let mut v = base_values.to_vec();
            v.extend([a, b]);
            // The residual removed per nm.
            let r = {
                let e = self.evaluate(&set, &v)?;
                self.residual(&e)
            };
            Ok(r.iter()
                .zip(r0)
                .map(|(x, y)| (y - x) / amplitude_nm)
                .collect())
        };
        let dc = response(amplitude_nm, 0.0)?;
        let ds = response(0.0, amplitude_nm)?;
        let rows: Vec<Vec<f64>> = dc.iter().zip(&ds).map(|(c, s)| vec![*c, *s]).collect();
        let Some(ab) = least_squares(&rows, r0) else {
            return Ok((dot(r0, r0), 0.0, 0.0));
        };
        let rss = r0
            .iter()
            .zip(&rows)
            .map(|(r, row)| (r - ab[0] * row[0] - ab[1] * row[1]).powi(2))
            .sum();
        Ok((rss, ab[0], ab[1]))
    }
}

/// The lowest Σr² of `fits`; each, in order, replaces `best` where it is lower.
fn keep_lowest(fits: Vec<Fitted>, best: &mut Fitted) -> f64 {
    let mut lowest = f64::INFINITY;
    for fit in fits {
        lowest = lowest.min(fit.objective);
        if fit.objective < best.objective {
            *best = fit;
        }
    }
    lowest
}

/// How much a residual correlated over `tau` points inflates one point's variance for
/// a parameter whose print is `print`: the correlation length, but no more than the
/// number of points the print covers ((Σ|p|)² / Σp²): a boss's few points near the axis
/// see a slow waviness in the residual as one offset, not as many independent ones.
pub(super) fn inflation(tau: f64, print: &[f64]) -> f64 {
    let (mut sum, mut squares) = (0.0, 0.0);
    for &p in print {
        sum += p.abs();
        squares += p * p;
    }
    let covered = if squares > 0.0 {
        sum * sum / squares
    } else {
        tau
    };
    tau.min(covered).max(1.0)
}

/// The finite-difference step of parameter `j`: a twentieth of its value or a fifth of
/// its scale, toward the open side of its bound.
fn step(parameters: &[Parameter], values: &[f64], j: usize) -> f64 {
    let p = &parameters[j];
    let h = (0.05 * values[j].abs()).max(0.2 * p.scale);
    if values[j] + h > p.bound { -h } else { h }
}

/// Multiples of a parameter's scale the global scan tries on each side (steps of about
/// 3; golden section then refines between the best value's neighbours).
const SCAN_MULTIPLES: [f64; 9] = [0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0];

/// Of the values a scan tried (sorted by value, with their Σr²), the lowest inside the
/// range on each side of `origin` (the origin itself counts on both): the indices to
/// bracket, best first, one per distinct index. The other side's is bracketed only
/// where it takes at least [`OTHER_SIDE`] of the drop from the origin's Σr² to the
/// scan's `lowest`: a shape that comes near is refined, noise on the far side is not.
fn best_on_each_side(tried: &[(f64, f64)], origin: f64, lowest: f64) -> Vec<usize> {
    let on_side = |keep: &dyn Fn(f64) -> bool| {
        (1..tried.len().saturating_sub(1))
            .filter(|&k| keep(tried[k].0))
            .min_by(|&a, &b| tried[a].1.total_cmp(&tried[b].1))
    };
    let at_origin = tried
        .iter()
        .find(|t| t.0 == origin)
        .map_or(f64::INFINITY, |t| t.1);
    let mut sides: Vec<usize> = [on_side(&|v| v >= origin), on_side(&|v| v <= origin)]
        .into_iter()
        .flatten()
        .collect();
    sides.sort_by(|&a, &b| tried[a].1.total_cmp(&tried[b].1));
    sides.dedup();
    let drop = at_origin - lowest;
    sides
        .into_iter()
        .enumerate()
        .filter(|&(i, k)| i == 0 || at_origin - tried[k].1 >= OTHER_SIDE * drop)
        .map(|(_, k)| k)
        .collect()
}

/// Share of the best side's drop in Σr² the other side must take to be refined too.
const OTHER_SIDE: f64 = 0.25;

/// The values a global scan of parameter `p` tries around `origin`: both signs, every
/// multiple of its scale within its range, and each end of the range.
fn scan_values(origin: f64, p: &Parameter) -> Vec<f64> {
    let (lower, upper) = p.range();
    let mut values: Vec<f64> = Vec::new();
    for sign in [1.0, -1.0] {
        for m in SCAN_MULTIPLES {
            let v = origin + sign * m * p.scale;
            if lower < v && v < upper {
                values.push(v);
            }
        }
    }
    values.extend([lower, upper]);
    values.sort_by(f64::total_cmp);
    values.dedup_by(|a, b| (*a - *b).abs() <= 1e-12 * p.bound);
    values.retain(|v| *v != origin);
    values
}

/// Where a fit's scans start: at `start`, and — where the set fits the lateral scale
/// and `start` has it away from 1 — again at the unit scale. On a surface with its form
/// the scale bends the form (a stretched sphere has more power), so a scale fitted
/// beside one effect can hold what a new one explains, and held there along the scan
/// it hides it.
///
/// Where the set also holds an effect that moves the marks (a decentre, paired with the
/// spiral's turn that moves them back: [`apply_set`]), every start is taken again half a
/// turn round the spiral: on a diameter the job as given places the marks alike at an
/// azimuth and half a turn from it (each side's marks move by half a feed, in
/// opposite directions along the radius), and which of the two the effect needs only
/// the effect can tell.
fn scan_starts(set: &[Candidate], start: Vec<f64>, scan: &[usize]) -> Vec<Vec<f64>> {
    if scan.is_empty() {
        return vec![start];
    }
    let mut starts = with_unit_scale(set, start);
    let azimuth = member_parameters(set, |c| *c == Candidate::SpiralAzimuth);
    if azimuth.is_empty() || !set.iter().any(Candidate::moves_marks) {
        return starts;
    }
    let turned: Vec<Vec<f64>> = starts
        .iter()
        .map(|s| turned_toward_zero(s, &azimuth, 180.0))
        .collect();
    starts.extend(turned);
    starts
}

/// `values` with each of the spiral-azimuth members `azimuth` turned by `deg` toward
/// (and past) zero: the same line half a turn round (180°), or the same azimuth read
/// from the other side of the bound (360°).
fn turned_toward_zero(values: &[f64], azimuth: &[usize], deg: f64) -> Vec<f64> {
    let mut turned = values.to_vec();
    for &j in azimuth {
        turned[j] -= deg.copysign(turned[j]);
    }
    turned
}

/// `start`, and — where the set fits the lateral scale and `start` has it away from 1 —
/// `start` at the unit scale.
pub(super) fn with_unit_scale(set: &[Candidate], start: Vec<f64>) -> Vec<Vec<f64>> {
    let scale = member_parameters(set, |c| *c == Candidate::LateralScale);
    if scale.iter().all(|&j| start[j] == 0.0) {
        return vec![start];
    }
    let mut unit = start.clone();
    for &j in &scale {
        unit[j] = 0.0;
    }
    vec![start, unit]
}

/// One-σ uncertainties of the `free` parameters: the largest of the Jacobian's — the
/// residual's variance inflated by its correlation length `tau` (points), or by the
/// points a parameter's column covers where fewer ([`inflation`]) — a block
/// sandwich estimate, (JᵀJ)⁻¹ (Σ_b g_b g_bᵀ) (JᵀJ)⁻¹ with g_b = J_bᵀ r_b over blocks of
/// 5 τ points, which also carries structure the noise model ignores (model error,
/// correlated residuals), and, along a `line` (points in order), the autocovariance
/// estimate [`line_hac_variances`]; then scaled by t₀.₉₇₅(ν)/1.96 with ν the residual's
/// effective points less the parameters, so that ±2σ stays a 95 % interval when a
/// long-correlated residual (1/f noise, form error) leaves only a few independent
/// points. ∞ when JᵀJ is singular.
pub(super) fn uncertainties(
    jacobian: &[Vec<f64>],
    free: &[usize],
    residual: &[f64],
    tau: f64,
    line: bool,
) -> Vec<f64> {
    let k = free.len();
    let n = residual.len();
    let Some(inverse) = invert(&normal_matrix(jacobian, free)) else {
        return vec![f64::INFINITY; k];
    };
    let used = residual.iter().filter(|r| **r != 0.0).count() as f64;
    let point_variance = dot(residual, residual) / (used - k as f64 - 4.0).max(1.0);
    let dof = used / tau.max(1.0) - k as f64;
    let few_points = student_t_975(dof) / student_t_975(f64::INFINITY);
    let block = ((5.0 * tau).ceil() as usize).max(n / 200).max(1);
    let mut meat = vec![vec![0.0; k]; k];
    for start in (0..n).step_by(block) {
        let end = (start + block).min(n);
        let g: Vec<f64> = free
            .iter()
            .map(|&a| (start..end).map(|i| jacobian[a][i] * residual[i]).sum())
            .collect();
        for a in 0..k {
            for b in 0..k {
                meat[a][b] += g[a] * g[b];
            }
        }
    }
    let line_variances = if line {
        line_variances(jacobian, free, &inverse, residual)
    } else {
        vec![0.0; k]
    };
    (0..k)
        .map(|a| {
            let variance = point_variance * inflation(tau, &jacobian[free[a]]);
            let jacobian_sigma = (inverse[a][a] * variance).max(0.0).sqrt();
            let sandwich: f64 = (0..k)
                .flat_map(|b| (0..k).map(move |c| (b, c)))
                .map(|(b, c)| inverse[a][b] * meat[b][c] * inverse[c][a])
                .sum();
            few_points
                * jacobian_sigma
                    .max(sandwich.max(0.0).sqrt())
                    .max(line_variances[a].sqrt())
        })
        .collect()
}

/// Per free parameter, the variance of its least-squares estimate when the residual is
/// a stationary correlated noise along the line ([`LineNoise::variance`]: the larger of
/// the autocovariance estimate and the fitted-spectrum one, which carries a 1/f noise
/// below the wavelengths the fit took out of the residual).
fn line_variances(
    jacobian: &[Vec<f64>],
    free: &[usize],
    inverse: &[Vec<f64>],
    residual: &[f64],
) -> Vec<f64> {
    let n = residual.len();
    let noise = LineNoise::of(residual);
    (0..free.len())
        .map(|a| {
            // The estimator's weights: row a of (JᵀJ)⁻¹Jᵀ.
            let weights: Vec<f64> = (0..n)
                .map(|i| {
                    free.iter()
                        .enumerate()
                        .map(|(b, &column)| inverse[a][b] * jacobian[column][i])
                        .sum()
                })
                .collect();
            noise.variance(&weights)
        })
        .collect()
}

/// The key of the job a set makes: its members but the lateral scale, and their values.
fn job_key(set: &[Candidate], values: &[f64]) -> (String, Vec<u64>) {
    let in_job = |c: &Candidate| *c != Candidate::LateralScale;
    let members: Vec<Candidate> = set.iter().copied().filter(in_job).collect();
    let kept: Vec<f64> = member_parameters(set, in_job)
        .iter()
        .map(|&j| values[j])
        .collect();
    cache_key(&members, &kept)
}

fn cache_key(set: &[Candidate], values: &[f64]) -> (String, Vec<u64>) {
    (
        format!("{set:?}"),
        values.iter().map(|v| v.to_bits()).collect(),
    )
}

/// A candidate set's fit as a [`LeastSquaresProblem`]: the forward model's evaluations
/// and its finite-difference Jacobian.
struct SetModel<'m, 'a, 'e> {
    problem: &'m mut Problem<'a, 'e>,
    set: &'m [Candidate],
    parameters: &'m [Parameter],
}

impl LeastSquaresProblem for SetModel<'_, '_, '_> {
    type State = Arc<Evaluation>;
    type Error = ForwardError;

    fn evaluate(&mut self, values: &[f64]) -> Result<Option<Arc<Evaluation>>, ForwardError> {
        self.problem.evaluate(self.set, values).map(Some)
    }

    fn residual(&self, state: &Arc<Evaluation>) -> Vec<f64> {
        self.problem.residual(state)
    }

    fn rss(&self, state: &Arc<Evaluation>) -> f64 {
        self.problem.rss(state)
    }

    fn jacobian(
        &mut self,
        values: &[f64],
        state: &Arc<Evaluation>,
    ) -> Result<Vec<Vec<f64>>, ForwardError> {
        self.problem
            .jacobian(self.set, self.parameters, values, state)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scan_tries_both_signs_only_where_the_range_has_both() {
        // Scale 10 nm, bound 500 nm: the multiples 0.3 … 30 of the scale lie inside
        // (3, 10, 30, 100, 300 nm), then the bound; a two-sided range mirrors them, a
        // range that stops at 0 (wear) never tries a negative value.
        let two_sided = Parameter {
            name: "recession",
            unit: "nm",
            scale: 10.0,
            bound: 500.0,
            lower: -500.0,
        };
        let inside = [3.0, 10.0, 30.0, 100.0, 300.0, 500.0];
        let mirrored: Vec<f64> = inside.iter().rev().map(|v| -v).chain(inside).collect();
        assert_eq!(scan_values(0.0, &two_sided), mirrored);
        let one_sided = Parameter {
            lower: 0.0,
            ..two_sided
        };
        assert_eq!(scan_values(0.0, &one_sided), inside);
        assert!(one_sided.at_bound(0.0) && !one_sided.at_bound(3.0));
        assert!(!two_sided.at_bound(0.0) && two_sided.at_bound(-490.0));
    }

    /// One side of a profile stepped out from `start` by doubling, Σr² rising by
    /// `rise(δ)` (in units of one point's variance), each of two values moving by δ
    /// and 2δ: its half-width and the moves there.
    fn walk(rise: impl Fn(f64) -> f64, start: f64) -> (f64, Vec<f64>) {
        let mut side = ProfileSide::new(1.0, 2, true);
        for doubling in 0..=PROFILE_DOUBLINGS {
            let delta = start * (1u64 << doubling) as f64;
            if side.step(delta, rise(delta), vec![delta, 2.0 * delta]) {
                break;
            }
        }
        side.half_width()
    }

    #[test]
    fn a_parabolic_profile_gives_its_sigma() {
        // Δχ² = (δ/σ)², σ = 1.3: crosses 1 at σ and 4 at 2σ; both read off exactly.
        let (width, moved) = walk(|d| (d / 1.3).powi(2), 1.0);
        assert!((width - 1.3).abs() < 1e-12, "{width}");
        assert!((moved[0] - 1.3).abs() < 1e-12 && (moved[1] - 2.6).abs() < 1e-12);
    }

    #[test]
    fn a_profile_that_flattens_gives_half_its_two_sigma_width() {
        // Δχ² = |δ| (a valley that opens out, as a waviness order's does): crosses 1 at
        // δ = 1 but 4 only at δ = 4, so the σ is 2, not 1; the moves are halved alike.
        let (width, moved) = walk(f64::abs, 1.0);
        assert!((width - 2.0).abs() < 1e-12, "{width}");
        assert!((moved[0] - 2.0).abs() < 1e-12 && (moved[1] - 4.0).abs() < 1e-12);
    }

    #[test]
    fn a_profile_that_never_rises_four_counts_to_its_last_step() {
        // Δχ² = 1.5 beyond δ = 0.5: crossed 1 at the first step, never 4 within 16
        // steps of 1 — at least 16 wide at Δχ² = 4, so the half-width is 8.
        let (width, _) = walk(|d| if d > 0.5 { 1.5 } else { 0.0 }, 1.0);
        assert!((width - 8.0).abs() < 1e-12, "{width}");
    }
}

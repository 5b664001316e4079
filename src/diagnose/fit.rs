//! Fitting effects by re-simulation: a trial set of effect values is simulated, seen as
//! the instrument sees it, registered (piston, tilt, power, the axis shift re-solved for
//! every trial), and judged by its residual. A candidate's start comes from scans along
//! each parameter (outward in ×3 steps while the residual falls); Levenberg–Marquardt
//! with finite-difference Jacobians refines all parameters together. Uncertainties
//! come from the Jacobian at the optimum with the residual's variance, inflated by its
//! correlation length (neighbouring points are not independent).

use super::candidates::{Candidate, Parameter};
use super::forward::{ForwardError, ForwardModel};
use super::measurement::Measurement;
use super::register::{Registered, ShiftSearch, Terms, register};
use super::zones::correlation_length;
use crate::numeric::{invert, least_squares, solve_linear};
use std::collections::HashMap;
use std::rc::Rc;

/// Everything a fit needs: the points fitted, the forward model, what registration may
/// remove and where it may look for the axis.
pub struct Problem<'a, 'e> {
    pub measurement: &'a Measurement,
    pub model: ForwardModel<'e>,
    pub terms: Terms,
    pub shift: ShiftSearch,
    cache: HashMap<(String, Vec<u64>), Rc<Evaluation>>,
}

/// One trial: the effect values and the registered residual they leave.
#[derive(Debug)]
pub struct Evaluation {
    pub values: Vec<f64>,
    pub registered: Registered,
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
    pub evaluation: Rc<Evaluation>,
    /// Correlation length of the residual (points) and the effective point count.
    pub correlation_length: f64,
    pub effective_points: f64,
}

impl Fit {
    /// Bayesian information criterion on the effective point count.
    pub fn bic(&self) -> f64 {
        bic(self.evaluation.rss(), self.evaluation.registered.used, self.effective_points, self.values.len())
    }

    /// The values and sigmas of one member of the set.
    pub fn values_of(&self, member: usize) -> (&[f64], &[f64]) {
        let start: usize = self.set[..member].iter().map(width).sum();
        let end = start + width(&self.set[member]);
        (&self.values[start..end], &self.sigmas[start..end])
    }
}

/// Parameters a candidate takes.
pub fn width(candidate: &Candidate) -> usize {
    match candidate {
        Candidate::EdgeWaviness { .. } => 2,
        _ => 1,
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
            cache: HashMap::new(),
        }
    }

    /// Simulates `set` at `values` and registers it (cached by the exact values).
    pub fn evaluate(&mut self, set: &[Candidate], values: &[f64]) -> Result<Rc<Evaluation>, ForwardError> {
        let key = cache_key(set, values);
        if let Some(hit) = self.cache.get(&key) {
            return Ok(hit.clone());
        }
        let apply = |job: &mut crate::io::job::Job| {
            let mut at = 0;
            for c in set {
                let n = width(c);
                c.apply(&values[at..at + n], job);
                at += n;
            }
        };
        let sim = self.model.simulate(&apply, self.measurement)?;
        let registered = register(self.measurement, &sim, self.terms, Some(self.shift));
        let evaluation = Rc::new(Evaluation {
            values: values.to_vec(),
            registered,
        });
        self.cache.insert(key, evaluation.clone());
        Ok(evaluation)
    }

    /// Fits `set` starting from `start`: a scan along each parameter listed in `scan`,
    /// then Levenberg–Marquardt on all of them.
    pub fn fit(
        &mut self,
        set: &[Candidate],
        start: Vec<f64>,
        scan: &[usize],
    ) -> Result<Fit, ForwardError> {
        let parameters: Vec<Parameter> = set
            .iter()
            .flat_map(|c| c.parameters(self.model.base_job()))
            .collect();
        let mut values = start;
        for &j in scan {
            let mut trial = values.clone();
            trial[j] = self.scan(set, &values, j, &parameters[j])?;
            let (now, then) = (self.evaluate(set, &values)?.rss(), self.evaluate(set, &trial)?.rss());
            if then < now {
                values = trial;
            }
        }
        let (values, jacobian) = self.levenberg_marquardt(set, &parameters, values)?;
        Ok(self.finish(set, parameters, values, &jacobian)?)
    }

    /// The best value of parameter `j` along its axis (others held): outward from the
    /// current value in ×3 steps of its scale, each way, while the residual falls; finer
    /// steps when neither way helps.
    fn scan(&mut self, set: &[Candidate], base: &[f64], j: usize, p: &Parameter) -> Result<f64, ForwardError> {
        let at = |problem: &mut Self, v: f64| -> Result<f64, ForwardError> {
            let mut trial = base.to_vec();
            trial[j] = v;
            Ok(problem.evaluate(set, &trial)?.rss())
        };
        let origin = base[j];
        let mut best = (origin, at(self, origin)?);
        for direction in [1.0, -1.0] {
            let mut previous = best.1.max(at(self, origin)?);
            for multiple in [1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0] {
                let v = (origin + direction * multiple * p.scale).clamp(-p.bound, p.bound);
                let rss = at(self, v)?;
                if rss < best.1 {
                    best = (v, rss);
                }
                if rss >= previous || v.abs() >= p.bound {
                    break;
                }
                previous = rss;
            }
        }
        if best.0 == origin {
            for multiple in [0.3, -0.3, 0.1, -0.1] {
                let v = origin + multiple * p.scale;
                let rss = at(self, v)?;
                if rss < best.1 {
                    best = (v, rss);
                }
            }
        }
        Ok(best.0)
    }

    /// Residual vectors' Jacobian by forward differences (toward the open side of a bound).
    fn jacobian(
        &mut self,
        set: &[Candidate],
        parameters: &[Parameter],
        values: &[f64],
        at: &Evaluation,
    ) -> Result<Vec<Vec<f64>>, ForwardError> {
        let r0 = at.residual();
        let mut columns = Vec::with_capacity(values.len());
        for (j, p) in parameters.iter().enumerate() {
            let mut h = (0.05 * values[j].abs()).max(0.2 * p.scale);
            if values[j] + h > p.bound {
                h = -h;
            }
            let mut trial = values.to_vec();
            trial[j] += h;
            let r1 = self.evaluate(set, &trial)?.residual();
            columns.push(r1.iter().zip(&r0).map(|(a, b)| (a - b) / h).collect());
        }
        Ok(columns)
    }

    fn levenberg_marquardt(
        &mut self,
        set: &[Candidate],
        parameters: &[Parameter],
        mut values: Vec<f64>,
    ) -> Result<(Vec<f64>, Vec<Vec<f64>>), ForwardError> {
        let k = values.len();
        let mut current = self.evaluate(set, &values)?;
        let mut jacobian = self.jacobian(set, parameters, &values, &current)?;
        let mut mu = 1e-3;
        for _ in 0..12 {
            let r = current.residual();
            let jtj: Vec<Vec<f64>> = (0..k)
                .map(|a| (0..k).map(|b| dot(&jacobian[a], &jacobian[b])).collect())
                .collect();
            let jtr: Vec<f64> = (0..k).map(|a| dot(&jacobian[a], &r)).collect();
            let mut improved = false;
            for _ in 0..8 {
                let damped: Vec<Vec<f64>> = (0..k)
                    .map(|a| {
                        (0..k)
                            .map(|b| jtj[a][b] + if a == b { mu * jtj[a][a].max(1e-300) } else { 0.0 })
                            .collect()
                    })
                    .collect();
                let Some(step) = solve_linear(&damped, &jtr.iter().map(|v| -v).collect::<Vec<_>>()) else {
                    mu *= 10.0;
                    continue;
                };
                let trial: Vec<f64> = values
                    .iter()
                    .zip(&step)
                    .zip(parameters)
                    .map(|((v, s), p)| (v + s).clamp(-p.bound, p.bound))
                    .collect();
                let evaluation = self.evaluate(set, &trial)?;
                if evaluation.rss() < current.rss() {
                    let gain = 1.0 - evaluation.rss() / current.rss();
                    let small = step.iter().zip(parameters).all(|(s, p)| s.abs() < 1e-4 * p.scale);
                    values = trial;
                    current = evaluation;
                    mu = (mu / 3.0).max(1e-9);
                    improved = gain > 1e-6 && !small;
                    break;
                }
                mu *= 4.0;
            }
            if !improved {
                break;
            }
            jacobian = self.jacobian(set, parameters, &values, &current)?;
        }
        Ok((values, jacobian))
    }

    fn finish(
        &mut self,
        set: &[Candidate],
        parameters: Vec<Parameter>,
        values: Vec<f64>,
        jacobian: &[Vec<f64>],
    ) -> Result<Fit, ForwardError> {
        let evaluation = self.evaluate(set, &values)?;
        let tau = correlation_length(self.measurement, &evaluation.registered.residual_mm);
        let used = evaluation.registered.used as f64;
        let k = values.len();
        let dof = (used - k as f64 - 4.0).max(1.0);
        let variance = evaluation.rss() / dof * tau;
        let jtj: Vec<Vec<f64>> = (0..k)
            .map(|a| (0..k).map(|b| dot(&jacobian[a], &jacobian[b])).collect())
            .collect();
        let sigmas = match invert(&jtj) {
            Some(inv) => (0..k).map(|j| (inv[j][j] * variance).max(0.0).sqrt()).collect(),
            None => vec![f64::INFINITY; k],
        };
        Ok(Fit {
            set: set.to_vec(),
            parameters,
            values,
            sigmas,
            evaluation,
            correlation_length: tau,
            effective_points: used / tau,
        })
    }

    /// Picks the waviness order that best explains the residual left by `base` (the
    /// accepted effects at `base_values`): for each order, the residual's projection on
    /// the responses to a cosine and a sine harmonic. Returns (order, cos, sin) in nm.
    pub fn screen_waviness(
        &mut self,
        base: &[Candidate],
        base_values: &[f64],
        orders: &[f64],
        amplitude_nm: f64,
    ) -> Result<Option<(f64, f64, f64)>, ForwardError> {
        let reference = self.evaluate(base, base_values)?;
        let r0 = reference.residual();
        let mut best: Option<(f64, f64, f64, f64)> = None;
        for &order in orders {
            let mut set = base.to_vec();
            set.push(Candidate::EdgeWaviness { order });
            let response = |problem: &mut Self, a: f64, b: f64| -> Result<Vec<f64>, ForwardError> {
                let mut v = base_values.to_vec();
                v.extend([a, b]);
                // The change in the registered residual per nm.
                let r = problem.evaluate(&set, &v)?.residual();
                Ok(r.iter().zip(&r0).map(|(x, y)| (y - x) / amplitude_nm).collect())
            };
            let dc = response(self, amplitude_nm, 0.0)?;
            let ds = response(self, 0.0, amplitude_nm)?;
            let rows: Vec<Vec<f64>> = dc.iter().zip(&ds).map(|(c, s)| vec![*c, *s]).collect();
            let Some(ab) = least_squares(&rows, &r0) else {
                continue;
            };
            let rss: f64 = r0
                .iter()
                .zip(&rows)
                .map(|(r, row)| (r - ab[0] * row[0] - ab[1] * row[1]).powi(2))
                .sum();
            if best.is_none_or(|b| rss < b.0) {
                best = Some((rss, order, ab[0], ab[1]));
            }
        }
        Ok(best.map(|(_, order, a, b)| (order, a, b)))
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn cache_key(set: &[Candidate], values: &[f64]) -> (String, Vec<u64>) {
    (
        format!("{set:?}"),
        values.iter().map(|v| v.to_bits()).collect(),
    )
}

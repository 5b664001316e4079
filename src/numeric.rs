//! Small numerical tools shared across modules.

/// 1/φ: the share of a golden-section bracket kept at each step.
const INVERSE_PHI: f64 = 0.618_033_988_749_894_9;

/// What a golden-section search leaves: the final bracket and its two inner points
/// with their values (`inner[0].0 < inner[1].0`).
#[derive(Debug, Clone, Copy)]
pub struct GoldenBracket {
    pub lo: f64,
    pub hi: f64,
    pub inner: [(f64, f64); 2],
}

impl GoldenBracket {
    pub fn mid(&self) -> f64 {
        0.5 * (self.lo + self.hi)
    }

    /// The lower of the two inner values.
    pub fn lowest_value(&self) -> f64 {
        self.inner[0].1.min(self.inner[1].1)
    }
}

/// Golden-section search for the minimum of a unimodal `f` on [lo, hi]: `steps`
/// shrinkings of the bracket by 1/φ, one new evaluation each (ties keep the lower
/// side). The first error `f` returns ends the search.
pub fn try_golden_section<E>(
    mut f: impl FnMut(f64) -> Result<f64, E>,
    lo: f64,
    hi: f64,
    steps: usize,
) -> Result<GoldenBracket, E> {
    let (mut a, mut b) = (lo, hi);
    let mut c = b - INVERSE_PHI * (b - a);
    let mut d = a + INVERSE_PHI * (b - a);
    let (mut fc, mut fd) = (f(c)?, f(d)?);
    for _ in 0..steps {
        if fc <= fd {
            b = d;
            d = c;
            fd = fc;
            c = b - INVERSE_PHI * (b - a);
            fc = f(c)?;
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + INVERSE_PHI * (b - a);
            fd = f(d)?;
        }
    }
    Ok(GoldenBracket {
        lo: a,
        hi: b,
        inner: [(c, fc), (d, fd)],
    })
}

/// [`try_golden_section`] for a function that cannot fail.
pub fn golden_section(
    mut f: impl FnMut(f64) -> f64,
    lo: f64,
    hi: f64,
    steps: usize,
) -> GoldenBracket {
    match try_golden_section(|x| Ok::<f64, std::convert::Infallible>(f(x)), lo, hi, steps) {
        Ok(bracket) => bracket,
        Err(never) => match never {},
    }
}

/// Least-squares solution of `A x ≈ y` for a tall `A` (rows × columns, row-major) by
/// Householder QR, which stays accurate where the normal equations would square the
/// condition number (polynomial bases). Returns `None` when A is rank-deficient.
pub fn least_squares(a: &[Vec<f64>], y: &[f64]) -> Option<Vec<f64>> {
    let rows = a.len();
    let columns = a.first()?.len();
    if rows < columns || y.len() != rows {
        return None;
    }
    // Column-major copy so each reflection sweeps contiguous memory.
    let mut q: Vec<Vec<f64>> = (0..columns)
        .map(|j| a.iter().map(|row| row[j]).collect())
        .collect();
    let mut b = y.to_vec();
    let scale = q
        .iter()
        .map(|c| c.iter().map(|v| v * v).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    for k in 0..columns {
        let norm = q[k][k..].iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm <= 1e-13 * scale {
            return None;
        }
        let alpha = if q[k][k] > 0.0 { -norm } else { norm };
        // v = x − α e₁ (stored in place), then H = I − 2 v vᵀ / vᵀv.
        q[k][k] -= alpha;
        let v: Vec<f64> = q[k][k..].to_vec();
        let vv: f64 = v.iter().map(|x| x * x).sum();
        for column in q.iter_mut().skip(k + 1) {
            let dot: f64 = v.iter().zip(&column[k..]).map(|(a, b)| a * b).sum();
            let factor = 2.0 * dot / vv;
            for (c, vi) in column[k..].iter_mut().zip(&v) {
                *c -= factor * vi;
            }
        }
        let dot: f64 = v.iter().zip(&b[k..]).map(|(a, b)| a * b).sum();
        let factor = 2.0 * dot / vv;
        for (bi, vi) in b[k..].iter_mut().zip(&v) {
            *bi -= factor * vi;
        }
        q[k][k] = alpha;
    }
    let mut x = vec![0.0; columns];
    for k in (0..columns).rev() {
        let known: f64 = (k + 1..columns).map(|j| q[j][k] * x[j]).sum();
        x[k] = (b[k] - known) / q[k][k];
    }
    Some(x)
}

/// Solution of the small square system `A x = b` by Gaussian elimination with partial
/// pivoting; `None` when A is singular (a pivot below 1e-300 or 1e-14 of the largest).
pub fn solve_linear(a: &[Vec<f64>], b: &[f64]) -> Option<Vec<f64>> {
    let n = b.len();
    let mut m: Vec<Vec<f64>> = a
        .iter()
        .zip(b)
        .map(|(row, bi)| {
            let mut r = row.clone();
            r.push(*bi);
            r
        })
        .collect();
    let scale = a.iter().flatten().fold(0.0_f64, |s, v| s.max(v.abs()));
    for k in 0..n {
        let pivot = (k..n).max_by(|&i, &j| m[i][k].abs().total_cmp(&m[j][k].abs()))?;
        if m[pivot][k].abs() <= (1e-14 * scale).max(1e-300) {
            return None;
        }
        m.swap(k, pivot);
        let (upper, lower) = m.split_at_mut(k + 1);
        let pivot_row = &upper[k];
        for row in lower.iter_mut() {
            let factor = row[k] / pivot_row[k];
            for (value, p) in row[k..=n].iter_mut().zip(&pivot_row[k..=n]) {
                *value -= factor * p;
            }
        }
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        let known: f64 = (k + 1..n).map(|j| m[k][j] * x[j]).sum();
        x[k] = (m[k][n] - known) / m[k][k];
    }
    Some(x)
}

/// The inverse of a small square matrix (`None` when singular).
pub fn invert(a: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let n = a.len();
    let columns: Option<Vec<Vec<f64>>> = (0..n)
        .map(|j| {
            let e: Vec<f64> = (0..n).map(|i| f64::from(u8::from(i == j))).collect();
            solve_linear(a, &e)
        })
        .collect();
    let columns = columns?;
    Some(
        (0..n)
            .map(|i| (0..n).map(|j| columns[j][i]).collect())
            .collect(),
    )
}

/// A least-squares problem for [`levenberg_marquardt`]: the model at given values, the
/// residual and objective of what it leaves, and its Jacobian there.
pub trait LeastSquaresProblem {
    /// What one evaluation leaves (its residual and whatever else the caller keeps).
    type State;
    type Error;
    /// The model at `values`; `Ok(None)` outside its domain (a step there is refused).
    fn evaluate(&mut self, values: &[f64]) -> Result<Option<Self::State>, Self::Error>;
    /// The residual vector of a state.
    fn residual(&self, state: &Self::State) -> Vec<f64>;
    /// The objective of a state: its residual's sum of squares.
    fn rss(&self, state: &Self::State) -> f64;
    /// The Jacobian at `values` (where `state` was evaluated), one column per parameter.
    fn jacobian(
        &mut self,
        values: &[f64],
        state: &Self::State,
    ) -> Result<Vec<Vec<f64>>, Self::Error>;
}

/// Where [`levenberg_marquardt`] stops and what it may move.
pub struct LmLimits<'a> {
    /// Jacobians taken at most.
    pub iterations: usize,
    /// Each parameter's range: lower ≤ value ≤ upper (±∞: unbounded).
    pub bounds: &'a [(f64, f64)],
    /// An accepted step smaller than this in every parameter ends the fit.
    pub small_step: &'a [f64],
    /// An accepted step gaining no more than this share of the objective ends it.
    pub min_gain: f64,
    /// Parameters held where they start.
    pub frozen: &'a [usize],
}

/// The values [`levenberg_marquardt`] ends at, with the state and Jacobian there.
pub struct LmFit<S> {
    pub values: Vec<f64>,
    pub state: S,
    pub jacobian: Vec<Vec<f64>>,
}

/// Levenberg–Marquardt with Marquardt's diagonal damping, bounds and an active set:
/// per Jacobian up to eight damped steps are tried (the damping ×4 after each refused
/// one, ÷3 after an accepted one). Parameters the data does not see stay where they
/// are; so, for a step, does one at its bound that the descent would push beyond it (a
/// step solved with it free, then clamped, would move the others as if it had gone
/// on). `Ok(None)` when the start lies outside the model's domain.
pub fn levenberg_marquardt<P: LeastSquaresProblem>(
    problem: &mut P,
    mut values: Vec<f64>,
    limits: &LmLimits,
) -> Result<Option<LmFit<P::State>>, P::Error> {
    let Some(mut current) = problem.evaluate(&values)? else {
        return Ok(None);
    };
    let mut jacobian = problem.jacobian(&values, &current)?;
    let mut mu = 1e-3;
    for _ in 0..limits.iterations {
        let r = problem.residual(&current);
        let free: Vec<usize> = observable(&jacobian, limits.frozen)
            .into_iter()
            .filter(|&j| {
                let descent = -dot(&jacobian[j], &r);
                let (lower, upper) = limits.bounds[j];
                !((values[j] >= upper && descent > 0.0) || (values[j] <= lower && descent < 0.0))
            })
            .collect();
        if free.is_empty() {
            break;
        }
        let before = problem.rss(&current);
        let at = (&values[..], &jacobian[..], &r[..], before);
        let mut accepted = damped_step(problem, at, &free, &mut mu, limits)?;
        if accepted.is_none() {
            accepted = single_steps(problem, at, &free, limits)?;
        }
        let Some((trial, evaluation, small)) = accepted else {
            break;
        };
        let gain = 1.0 - problem.rss(&evaluation) / before;
        values = trial;
        current = evaluation;
        if gain <= limits.min_gain || small {
            break;
        }
        jacobian = problem.jacobian(&values, &current)?;
    }
    Ok(Some(LmFit {
        values,
        state: current,
        jacobian,
    }))
}

/// Least share of the objective a parameter's own step must promise for
/// [`single_steps`] to try it.
const SINGLE_STEP_GAIN: f64 = 1e-3;

/// Where a step starts: the values, the Jacobian and residual there, and the objective.
type At<'a> = (&'a [f64], &'a [Vec<f64>], &'a [f64], f64);

/// An accepted step: the values, their state, and whether the step was small in every
/// parameter.
type Step<S> = Option<(Vec<f64>, S, bool)>;

/// Up to eight damped Gauss–Newton steps in the `free` parameters together (the damping
/// ×4 after each refused one, ÷3 after the accepted one); the first that lowers the
/// objective.
fn damped_step<P: LeastSquaresProblem>(
    problem: &mut P,
    (values, jacobian, r, before): At,
    free: &[usize],
    mu: &mut f64,
    limits: &LmLimits,
) -> Result<Step<P::State>, P::Error> {
    let k = free.len();
    let jtj = normal_matrix(jacobian, free);
    let jtr: Vec<f64> = free.iter().map(|&a| -dot(&jacobian[a], r)).collect();
    for _ in 0..8 {
        let damped: Vec<Vec<f64>> = (0..k)
            .map(|a| {
                (0..k)
                    .map(|b| jtj[a][b] + if a == b { *mu * jtj[a][a] } else { 0.0 })
                    .collect()
            })
            .collect();
        let Some(step) = solve_linear(&damped, &jtr) else {
            *mu *= 10.0;
            continue;
        };
        let moves: Vec<(usize, f64)> = free.iter().copied().zip(step).collect();
        if let Some(accepted) = try_step(problem, values, &moves, before, limits)? {
            *mu = (*mu / 3.0).max(1e-9);
            return Ok(Some(accepted));
        }
        *mu *= 4.0;
    }
    Ok(None)
}

/// Where the joint step fails, each free parameter alone whose own Gauss–Newton step
/// promises to gain at least [`SINGLE_STEP_GAIN`] of the objective (that step, halved up
/// to three times): a parameter whose column misleads — a step edge in the model
/// crossing a sample, whose finite difference is all or nothing — must not hold the
/// others where they start. (At a minimum no parameter promises that much, and nothing
/// is tried.)
fn single_steps<P: LeastSquaresProblem>(
    problem: &mut P,
    (values, jacobian, r, before): At,
    free: &[usize],
    limits: &LmLimits,
) -> Result<Step<P::State>, P::Error> {
    for &j in free {
        let curvature = dot(&jacobian[j], &jacobian[j]);
        let slope = dot(&jacobian[j], r);
        if slope * slope / curvature < SINGLE_STEP_GAIN * before {
            continue;
        }
        let mut step = -slope / curvature;
        for _ in 0..4 {
            if let Some(accepted) = try_step(problem, values, &[(j, step)], before, limits)? {
                return Ok(Some(accepted));
            }
            step *= 0.5;
        }
    }
    Ok(None)
}

/// `values` moved by `moves` (clamped to the bounds), kept when the objective falls
/// below `before`.
fn try_step<P: LeastSquaresProblem>(
    problem: &mut P,
    values: &[f64],
    moves: &[(usize, f64)],
    before: f64,
    limits: &LmLimits,
) -> Result<Step<P::State>, P::Error> {
    let mut trial = values.to_vec();
    for &(j, s) in moves {
        let (lower, upper) = limits.bounds[j];
        trial[j] = (values[j] + s).clamp(lower, upper);
    }
    let Some(evaluation) = problem.evaluate(&trial)? else {
        return Ok(None);
    };
    if problem.rss(&evaluation) >= before {
        return Ok(None);
    }
    let small = moves.iter().all(|&(j, s)| s.abs() < limits.small_step[j]);
    Ok(Some((trial, evaluation, small)))
}

/// The Jacobian columns the data sees (norm above 1e-12 of the largest), but `frozen`.
pub fn observable(jacobian: &[Vec<f64>], frozen: &[usize]) -> Vec<usize> {
    let norms: Vec<f64> = jacobian.iter().map(|c| dot(c, c)).collect();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    (0..norms.len())
        .filter(|&j| norms[j] > 1e-12 * largest && norms[j] > 0.0 && !frozen.contains(&j))
        .collect()
}

/// JᵀJ over the columns `free`.
pub fn normal_matrix(jacobian: &[Vec<f64>], free: &[usize]) -> Vec<Vec<f64>> {
    free.iter()
        .map(|&a| {
            free.iter()
                .map(|&b| dot(&jacobian[a], &jacobian[b]))
                .collect()
        })
        .collect()
}

pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The two-sided 95 % quantile of Student's t with `dof` degrees of freedom (≥ 1;
/// fractional values allowed): exact for 1 and 2, the Cornish–Fisher expansion about
/// the normal quantile beyond (within 0.2 % of the tables from 3 on).
pub fn student_t_975(dof: f64) -> f64 {
    let nu = dof.max(1.0);
    if nu < 2.0 {
        // Between 1 and 2 degrees of freedom: linear in 1/ν between the exact values.
        let (t1, t2) = (12.706_204_736_174_7, 4.302_652_729_749_464);
        let w = (1.0 / nu - 0.5) / 0.5;
        return t2 + w * (t1 - t2);
    }
    if nu < 3.0 {
        let t2 = 4.302_652_729_749_464;
        let t3 = cornish_fisher_975(3.0);
        let w = (1.0 / nu - 1.0 / 3.0) / (0.5 - 1.0 / 3.0);
        return t3 + w * (t2 - t3);
    }
    cornish_fisher_975(nu)
}

/// Cornish–Fisher expansion of t₀.₉₇₅(ν) to the fourth order in 1/ν.
fn cornish_fisher_975(nu: f64) -> f64 {
    let z: f64 = 1.959_963_984_540_054;
    let (z3, z5, z7, z9) = (z.powi(3), z.powi(5), z.powi(7), z.powi(9));
    z + (z3 + z) / (4.0 * nu)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu.powi(3))
        + (79.0 * z9 + 776.0 * z7 + 1482.0 * z5 - 1920.0 * z3 - 945.0 * z) / (92160.0 * nu.powi(4))
}

/// χ²'s upper quantile with `dof` degrees of freedom at tail probability `tail`
/// (Wilson–Hilferty: within a few per cent of the exact value for dof ≥ 3).
pub fn chi2_upper_quantile(dof: usize, tail: f64) -> f64 {
    let k = dof as f64;
    let z = normal_upper_quantile(tail);
    let c = 2.0 / (9.0 * k);
    k * (1.0 - c + z * c.sqrt()).powi(3)
}

/// The standard normal's upper quantile (Acklam's rational approximation of the
/// inverse, relative error below 1.2e-9).
pub fn normal_upper_quantile(tail: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let p = tail.clamp(1e-300, 0.5);
    // The lower tail's quantile at p, negated.
    let q = (-2.0 * p.ln()).sqrt();
    let lower = (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
        / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0);
    if p < 0.02425 {
        return -lower;
    }
    let q = p - 0.5;
    let r = q * q;
    -(((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
        / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_high_order_even_polynomial_exactly() {
        // y = Σ c_k u^{2k}, k = 0..10 on u ∈ [0, 1]: the normal equations lose ~13 digits
        // here; QR keeps the coefficients to ~1e-6 relative and the fit to round-off.
        let truth: Vec<f64> = (0..11).map(|k| (k as f64 * 0.7).sin()).collect();
        let us: Vec<f64> = (0..2000).map(|i| i as f64 / 1999.0).collect();
        let rows: Vec<Vec<f64>> = us
            .iter()
            .map(|u| (0..11).map(|k| u.powi(2 * k)).collect())
            .collect();
        let ys: Vec<f64> = rows
            .iter()
            .map(|r| r.iter().zip(&truth).map(|(a, b)| a * b).sum())
            .collect();
        let fit = least_squares(&rows, &ys).unwrap();
        let worst_value = rows
            .iter()
            .zip(&ys)
            .map(|(r, y)| (r.iter().zip(&fit).map(|(a, b)| a * b).sum::<f64>() - y).abs())
            .fold(0.0, f64::max);
        assert!(worst_value < 1e-12, "{worst_value}");
        for (f, t) in fit.iter().zip(&truth) {
            assert!((f - t).abs() < 1e-4, "{f} vs {t}");
        }
    }

    #[test]
    fn rank_deficient_systems_are_refused() {
        let rows = vec![vec![1.0, 2.0], vec![2.0, 4.0], vec![3.0, 6.0]];
        assert!(least_squares(&rows, &[1.0, 2.0, 3.0]).is_none());
    }

    #[test]
    fn small_systems_solve_and_invert() {
        // A 3×3 system with the exact solution (1, −2, 3).
        let a = vec![
            vec![4.0, -2.0, 1.0],
            vec![-2.0, 4.0, -2.0],
            vec![1.0, -2.0, 4.0],
        ];
        let b = [
            4.0 * 1.0 - 2.0 * -2.0 + 3.0,
            -2.0 - 8.0 - 6.0,
            1.0 + 4.0 + 12.0,
        ];
        let x = solve_linear(&a, &b).unwrap();
        for (xi, ti) in x.iter().zip([1.0, -2.0, 3.0]) {
            assert!((xi - ti).abs() < 1e-12, "{x:?}");
        }
        let inv = invert(&a).unwrap();
        for (i, row) in a.iter().enumerate() {
            for j in 0..3 {
                let p: f64 = row
                    .iter()
                    .zip(&inv)
                    .map(|(x, inv_row)| x * inv_row[j])
                    .sum();
                assert!((p - f64::from(u8::from(i == j))).abs() < 1e-12);
            }
        }
        assert!(solve_linear(&[vec![1.0, 2.0], vec![2.0, 4.0]], &[1.0, 2.0]).is_none());
    }

    #[test]
    fn student_t_quantiles_match_the_tables() {
        // Two-sided 95 % points of Student's t (any statistics table, e.g. NIST/SEMATECH
        // e-Handbook 1.3.6.7.2): ν = 1, 2, 3, 5, 10, 30, and the normal limit.
        for (nu, table) in [
            (1.0, 12.706),
            (2.0, 4.303),
            (3.0, 3.182),
            (5.0, 2.571),
            (10.0, 2.228),
            (30.0, 2.042),
            (1e9, 1.960),
        ] {
            let t = student_t_975(nu);
            assert!(
                (t / table - 1.0).abs() < 0.002,
                "ν = {nu}: {t} against {table}"
            );
        }
    }

    #[test]
    fn normal_and_chi_square_quantiles_match_the_tables() {
        // Upper points of the standard normal and of χ² (NIST/SEMATECH e-Handbook
        // 1.3.6.7.1 and 1.3.6.7.4).
        for (tail, table) in [
            (0.3, 0.524401),
            (0.025, 1.959964),
            (0.001, 3.090232),
            (1e-6, 4.753424),
        ] {
            let z = normal_upper_quantile(tail);
            assert!((z - table).abs() < 1e-5, "{tail}: {z} against {table}");
        }
        for (dof, table) in [(3, 16.266), (5, 20.515), (10, 29.588), (20, 45.315)] {
            let q = chi2_upper_quantile(dof, 0.001);
            assert!(
                (q / table - 1.0).abs() < 0.02,
                "dof {dof}: {q} against {table}"
            );
        }
    }

    /// A line fit a·t + c to points, beside a parameter `b` whose Jacobian column
    /// misleads (a step in the model: its finite difference is all or nothing; here a
    /// column t² that promises to explain the points' curvature, where the model's `b`
    /// only ever adds a wall of 10⁶ once it moves from 0).
    struct MisleadingStep {
        t: Vec<f64>,
        z: Vec<f64>,
    }

    impl LeastSquaresProblem for MisleadingStep {
        type State = Vec<f64>;
        type Error = ();
        fn evaluate(&mut self, v: &[f64]) -> Result<Option<Vec<f64>>, ()> {
            let mut r: Vec<f64> = self
                .t
                .iter()
                .zip(&self.z)
                .map(|(t, z)| v[0] * t + v[1] - z)
                .collect();
            r.push(if v[2] != 0.0 { 1e6 } else { 0.0 });
            Ok(Some(r))
        }
        fn residual(&self, state: &Vec<f64>) -> Vec<f64> {
            state.clone()
        }
        fn rss(&self, state: &Vec<f64>) -> f64 {
            dot(state, state)
        }
        fn jacobian(&mut self, _: &[f64], _: &Vec<f64>) -> Result<Vec<Vec<f64>>, ()> {
            let column = |f: &dyn Fn(f64) -> f64| -> Vec<f64> {
                self.t.iter().map(|t| f(*t)).chain([0.0]).collect()
            };
            Ok(vec![column(&|t| t), column(&|_| 1.0), column(&|t| t * t)])
        }
    }

    #[test]
    fn a_misleading_column_does_not_hold_the_others_where_they_start() {
        // Points on z = 2t + 1 + 5 t², t symmetric about 0: the least-squares line
        // is a = 2, c = 1 + 5·mean(t²) (t and t² orthogonal); every joint step moves
        // b off 0, into its wall, and is refused however damped.
        let t: Vec<f64> = (0..20).map(|i| (f64::from(i) - 9.5) * 0.1).collect();
        let z: Vec<f64> = t.iter().map(|t| 2.0 * t + 1.0 + 5.0 * t * t).collect();
        let mean_t2 = t.iter().map(|t| t * t).sum::<f64>() / t.len() as f64;
        let mut problem = MisleadingStep { t, z };
        let limits = LmLimits {
            iterations: 20,
            bounds: &[(f64::NEG_INFINITY, f64::INFINITY); 3],
            small_step: &[1e-12; 3],
            min_gain: 1e-12,
            frozen: &[],
        };
        let fit = levenberg_marquardt(&mut problem, vec![0.0; 3], &limits)
            .unwrap()
            .unwrap();
        assert!((fit.values[0] - 2.0).abs() < 1e-9, "{:?}", fit.values);
        let c = 1.0 + 5.0 * mean_t2;
        assert!(
            (fit.values[1] - c).abs() < 1e-9,
            "{:?} for c = {c}",
            fit.values
        );
        assert_eq!(fit.values[2], 0.0, "{:?}", fit.values);
    }

    #[test]
    fn a_one_sided_range_holds_its_end_and_frees_the_rest() {
        // Points on z = −3t + 2 + 0.1·(−1)^i, t from 0 to 1.9, fitted as the line
        // a·t + c of `MisleadingStep` (its third parameter frozen at 0): a slope held
        // at ≥ 0 (as wear only recedes an edge) ends at 0, and the offset is then the
        // points' mean, 2 − 3·mean(t) — the closed form of the fit with the slope at 0;
        // a two-sided range finds the free least-squares line instead.
        let t: Vec<f64> = (0..20).map(|i| f64::from(i) * 0.1).collect();
        let z: Vec<f64> = (0..20)
            .map(|i| -3.0 * t[i] + 2.0 + 0.1 * if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let fit_within = |bounds: &[(f64, f64)]| {
            let mut problem = MisleadingStep {
                t: t.clone(),
                z: z.clone(),
            };
            let limits = LmLimits {
                iterations: 30,
                bounds,
                small_step: &[1e-12; 3],
                min_gain: 1e-14,
                frozen: &[2],
            };
            levenberg_marquardt(&mut problem, vec![0.0; 3], &limits)
                .unwrap()
                .unwrap()
                .values
        };
        let free_range = (f64::NEG_INFINITY, f64::INFINITY);
        let held = fit_within(&[(0.0, 10.0), free_range, free_range]);
        assert_eq!(held[0], 0.0, "{held:?}");
        assert!(
            (held[1] - mean(&z)).abs() < 1e-9,
            "{held:?} for {}",
            mean(&z)
        );
        let free = fit_within(&[(-10.0, 10.0), free_range, free_range]);
        let (mt, mz) = (mean(&t), mean(&z));
        let slope = t
            .iter()
            .zip(&z)
            .map(|(t, z)| (t - mt) * (z - mz))
            .sum::<f64>()
            / t.iter().map(|t| (t - mt).powi(2)).sum::<f64>();
        assert!((free[0] - slope).abs() < 1e-9, "{free:?} for slope {slope}");
        assert!((free[1] - (mz - slope * mt)).abs() < 1e-9, "{free:?}");
    }
}

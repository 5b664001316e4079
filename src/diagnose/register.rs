//! Registration as metrology software does it: the measured surface is compared with the
//! simulated one after removing what the mounting adds — piston and tilt — and, when
//! asked, power (for a file whose form was already removed); the part's axis is found in
//! the measurement's frame by a lateral shift (a map's decentre, a profile's offset along
//! its line). Linear terms are solved by least squares for each trial shift; the shift by
//! a grid search and a golden-section refinement.

use super::forward::{Frame, SimulatedSurface};
use super::measurement::Measurement;
use crate::numeric::solve_linear;
use glam::DVec2;

/// What registration may remove besides piston and tilt.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Terms {
    /// A coefficient of r² (the measured file had its form removed, or the radius is
    /// not to be judged).
    pub power: bool,
    /// The part's axis is searched for in the measurement's frame.
    pub shift: bool,
}

/// Where to look for the axis: a square (line: a segment) of half-width `half_width_mm`
/// around `start`, scanned every `step_mm` then refined.
#[derive(Debug, Clone, Copy)]
pub struct ShiftSearch {
    pub start: DVec2,
    pub half_width_mm: f64,
    pub step_mm: f64,
    /// How many of the scan's lowest local minima are refined.
    pub refine: usize,
}

/// What registration removed, in report units.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Registration {
    pub piston_nm: f64,
    /// Slope removed along the line (first value) or along X and Y (µrad).
    pub tilt_urad: [f64; 2],
    /// Coefficient of r² removed (nm/mm²), when power is a term.
    pub power_nm_per_mm2: Option<f64>,
    /// Where the part's axis lies in the measurement's frame (µm).
    pub axis_at_um: [f64; 2],
}

#[derive(Debug, Clone)]
pub struct Registered {
    pub registration: Registration,
    pub shift_mm: DVec2,
    /// measured − (simulated + removed terms) per point (mm); NaN where the simulation
    /// has no data.
    pub residual_mm: Vec<f64>,
    /// simulated + removed terms per point (mm).
    pub model_mm: Vec<f64>,
    /// Σ residual² over the points used (mm²).
    pub rss: f64,
    pub used: usize,
}

/// Registers `sim` to the measurement; `search` = None keeps the axis where the
/// measurement puts it (or at a given shift).
pub fn register(
    m: &Measurement,
    sim: &SimulatedSurface,
    terms: Terms,
    search: Option<ShiftSearch>,
) -> Registered {
    let Some(search) = search.filter(|_| terms.shift) else {
        let shift = search.map_or(DVec2::ZERO, |s| s.start);
        return fit_linear(m, &sim.sample(m, Frame::at(shift)), shift, terms.power);
    };
    let direction = match m.shape {
        super::measurement::Shape::Line { azimuth_rad } => Some(DVec2::from_angle(azimuth_rad)),
        super::measurement::Shape::Raster { .. } => None,
    };
    // A subsample keeps the scan cheap (a map's scan is two-dimensional).
    let scanned = if direction.is_some() { 4000 } else { 1500 };
    let stride = (m.len() / scanned).max(1);
    let coarse = m.subset(|i| i % stride == 0);
    // A map's shift may not move its points off the simulated region (judging the rest
    // alone would favour losing the hard ones); a profile may lose its ends at the rim.
    let kept = |points: &Measurement| match direction {
        Some(_) => points.len() / 2,
        None => points.len() * 98 / 100,
    };
    // The axis is judged on the bulk of the points: the worst 5 % (an unmodelled local
    // feature, spikes) do not steer it.
    let objective = |points: &Measurement, shift: DVec2| {
        let r = fit_linear(
            points,
            &sim.sample(points, Frame::at(shift)),
            shift,
            terms.power,
        );
        if r.used < kept(points) {
            return f64::INFINITY;
        }
        trimmed_mean_square(&r.residual_mm, 0.95)
    };
    let steps = (search.half_width_mm / search.step_mm).ceil().max(1.0) as i64;
    let offsets: Vec<f64> = (-steps..=steps)
        .map(|k| k as f64 * search.step_mm)
        .collect();
    let width = search.step_mm;
    let best = match direction {
        Some(d) => {
            let values: Vec<f64> = offsets
                .iter()
                .map(|&a| objective(&coarse, search.start + a * d))
                .collect();
            local_minima(&values, search.refine)
                .into_iter()
                .map(|k| {
                    let centre = search.start + offsets[k] * d;
                    let along = |a: f64| objective(m, centre + a * d);
                    let a = golden_section(&along, -width, width, 14);
                    (along(a), centre + a * d)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
        }
        None => {
            let n = offsets.len();
            let values: Vec<f64> = (0..n * n)
                .map(|k| {
                    objective(
                        &coarse,
                        search.start + DVec2::new(offsets[k % n], offsets[k / n]),
                    )
                })
                .collect();
            // Local minima on the grid: no lower value among the four neighbours.
            let mut minima: Vec<usize> = (0..n * n)
                .filter(|&k| {
                    let (i, j) = ((k % n) as i64, (k / n) as i64);
                    [(-1, 0), (1, 0), (0, -1), (0, 1)].iter().all(|(di, dj)| {
                        let (a, b) = (i + di, j + dj);
                        a < 0
                            || b < 0
                            || a >= n as i64
                            || b >= n as i64
                            || values[(b as usize) * n + a as usize] >= values[k]
                    })
                })
                .collect();
            minima.sort_by(|a, b| values[*a].total_cmp(&values[*b]));
            minima
                .into_iter()
                .take(search.refine)
                .map(|k| {
                    let at = search.start + DVec2::new(offsets[k % n], offsets[k / n]);
                    let on_all = |shift: DVec2| objective(m, shift);
                    refine_shift(m, sim, terms.power, &on_all, at, 0.25 * width)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
        }
    };
    let shift = best.map_or(search.start, |b| b.1);
    fit_linear(m, &sim.sample(m, Frame::at(shift)), shift, terms.power)
}

/// Mean of the smallest `keep` share of the squared finite values.
pub fn trimmed_mean_square(values: &[f64], keep: f64) -> f64 {
    let mut squares: Vec<f64> = values
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| v * v)
        .collect();
    if squares.is_empty() {
        return f64::INFINITY;
    }
    let count = ((squares.len() as f64 * keep) as usize).clamp(1, squares.len());
    squares.select_nth_unstable_by(count - 1, f64::total_cmp);
    squares[..count].iter().sum::<f64>() / count as f64
}

/// Indices of up to `count` lowest local minima of a sequence (ends count when lower
/// than their one neighbour).
fn local_minima(values: &[f64], count: usize) -> Vec<usize> {
    let n = values.len();
    let mut minima: Vec<usize> = (0..n)
        .filter(|&k| {
            (k == 0 || values[k - 1] >= values[k]) && (k + 1 == n || values[k + 1] >= values[k])
        })
        .collect();
    minima.sort_by(|a, b| values[*a].total_cmp(&values[*b]));
    minima.truncate(count);
    minima
}

/// Least-squares piston, tilt (and power) of measured − simulated at a fixed shift,
/// by the normal equations on centred coordinates (at most four well-scaled columns).
pub fn fit_linear(m: &Measurement, simulated: &[f64], shift: DVec2, power: bool) -> Registered {
    let terms = LinearTerms::new(m, simulated, shift, power);
    let coefficients = terms.solve(m, simulated, &[]);
    let (raster, width, centre) = (terms.raster, terms.width, terms.centre);
    let mut residual_mm = vec![f64::NAN; m.len()];
    let mut model_mm = vec![f64::NAN; m.len()];
    let mut rss = 0.0;
    for &i in &terms.used {
        let row = terms.row(m, i);
        let removed: f64 = (0..width).map(|a| row[a] * coefficients[a]).sum();
        model_mm[i] = simulated[i] + removed;
        residual_mm[i] = m.height_mm[i] - model_mm[i];
        rss += residual_mm[i] * residual_mm[i];
    }
    // Piston at the measurement's origin (the centred columns moved it); slopes in
    // mm/mm are 1e6 µrad.
    let piston = coefficients[0]
        - coefficients[1] * centre[0]
        - if raster {
            coefficients[2] * centre[1]
        } else {
            0.0
        };
    let tilt_urad = [
        coefficients[1] * 1e6,
        if raster { coefficients[2] * 1e6 } else { 0.0 },
    ];
    Registered {
        registration: Registration {
            piston_nm: piston * 1e6,
            tilt_urad,
            power_nm_per_mm2: power.then(|| coefficients[width - 1] * 1e6),
            axis_at_um: (shift * 1e3).to_array(),
        },
        shift_mm: shift,
        residual_mm,
        model_mm,
        rss,
        used: terms.used.len(),
    }
}

/// The linear terms registration removes (piston, tilt, optionally power), on
/// coordinates centred over the points the simulation covers.
pub struct LinearTerms {
    raster: bool,
    power: bool,
    shift: DVec2,
    /// How many terms (piston, tilt X[, tilt Y][, power]).
    pub width: usize,
    centre: [f64; 2],
    used: Vec<usize>,
}

impl LinearTerms {
    pub fn new(m: &Measurement, simulated: &[f64], shift: DVec2, power: bool) -> Self {
        let raster = !m.is_line();
        let used: Vec<usize> = (0..m.len()).filter(|&i| simulated[i].is_finite()).collect();
        let n = used.len().max(1) as f64;
        let centre = used.iter().fold([0.0, 0.0], |c, &i| {
            let t = m.tilt_coordinates(i);
            [c[0] + t[0] / n, c[1] + t[1] / n]
        });
        Self {
            raster,
            power,
            shift,
            width: 2 + usize::from(raster) + usize::from(power),
            centre,
            used,
        }
    }

    pub fn row(&self, m: &Measurement, i: usize) -> [f64; 4] {
        let t = m.tilt_coordinates(i);
        let mut row = [1.0, t[0] - self.centre[0], 0.0, 0.0];
        let mut k = 2;
        if self.raster {
            row[k] = t[1] - self.centre[1];
            k += 1;
        }
        if self.power {
            row[k] = (m.xy_mm[i] - self.shift).length_squared();
        }
        row
    }

    /// Coefficients of the terms, then of the `extra` columns, fitted together to
    /// measured − simulated (zeros when singular).
    pub fn solve(&self, m: &Measurement, simulated: &[f64], extra: &[Vec<f64>]) -> Vec<f64> {
        let width = self.width + extra.len();
        let mut normal = vec![vec![0.0; width]; width];
        let mut rhs = vec![0.0; width];
        let mut row = vec![0.0; width];
        for &i in &self.used {
            if extra.iter().any(|column| !column[i].is_finite()) {
                continue;
            }
            row[..self.width].copy_from_slice(&self.row(m, i)[..self.width]);
            for (k, column) in extra.iter().enumerate() {
                row[self.width + k] = column[i];
            }
            let target = m.height_mm[i] - simulated[i];
            for a in 0..width {
                rhs[a] += row[a] * target;
                for b in 0..width {
                    normal[a][b] += row[a] * row[b];
                }
            }
        }
        solve_linear(&normal, &rhs).unwrap_or_else(|| vec![0.0; width])
    }
}

/// Gauss–Newton on a map's axis position from `start`: the model's slopes along X and
/// Y (central differences over `h`) are fitted with piston and tilt as one linear
/// step; a step is kept only while it lowers `objective`, else it is halved once.
fn refine_shift(
    m: &Measurement,
    sim: &SimulatedSurface,
    power: bool,
    objective: &dyn Fn(DVec2) -> f64,
    start: DVec2,
    h: f64,
) -> (f64, DVec2) {
    let (mut at, mut best) = (start, objective(start));
    for _ in 0..8 {
        let model = sim.sample(m, Frame::at(at));
        let slope = |d: DVec2| -> Vec<f64> {
            let (ahead, behind) = (
                sim.sample(m, Frame::at(at + d)),
                sim.sample(m, Frame::at(at - d)),
            );
            ahead
                .iter()
                .zip(&behind)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect()
        };
        let columns = [slope(DVec2::new(h, 0.0)), slope(DVec2::new(0.0, h))];
        let terms = LinearTerms::new(m, &model, at, power);
        let c = terms.solve(m, &model, &columns);
        let step = DVec2::new(c[terms.width], c[terms.width + 1]);
        let Some((value, next)) = [step, 0.5 * step]
            .into_iter()
            .map(|s| (objective(at + s), at + s))
            .find(|(value, _)| *value < best)
        else {
            break;
        };
        (at, best) = (next, value);
        if step.length() < 1e-6 {
            break;
        }
    }
    (best, at)
}

/// Minimum of `f` on [lo, hi] by golden-section search (`steps` shrinkings).
pub fn golden_section(f: &dyn Fn(f64) -> f64, lo: f64, hi: f64, steps: usize) -> f64 {
    let bracket = crate::numeric::golden_section(f, lo, hi, steps);
    // The bracket's ends count too: the minimum may sit on the boundary.
    [
        (f(lo), lo),
        (bracket.lowest_value(), bracket.mid()),
        (f(hi), hi),
    ]
    .into_iter()
    .min_by(|x, y| x.0.total_cmp(&y.0))
    .map_or(bracket.mid(), |b| b.1)
}

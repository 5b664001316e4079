//! Screening the rate of a moving effect before it is fitted: a vibration's cycles per
//! revolution, a tilt error motion's order. Each leaves, to first order, a known
//! signature at each measured point — written in the cut clock t (the spindle angle
//! turned when the pass that left the point cut it) — so the residual's projection on
//! that signature is tried at every rate on a grid fine enough to keep a quarter-cycle
//! phase error across the data, and the best refined; the simulation then fits it.
//!
//! | candidate | signature at a point (per unit amplitude) |
//! | --- | --- |
//! | depth vibration | cos(k·t), sin(k·t): the surface lifts with the tool |
//! | feed vibration | −s·cos(k·t), −s·sin(k·t), s = dz/dr there: the marks move out |
//! | tilt error motion | −r·cos(k·t), −r·sin(k·t), whole k: the face turns under the tool |

use super::candidates::Candidate;
use crate::numeric::golden_section;
use crate::process::effects::MAX_CYCLES_PER_REV;
use std::f64::consts::TAU;

/// Most rates tried on the grid (the step widens beyond it).
const MAX_RATES: usize = 20_000;
/// Local maxima of the grid refined by golden section.
const REFINED: usize = 6;
/// Fewest cycles a vibration makes across the data to be tried: a slower one is a form
/// term to this data (a drift's ramp, a decentre's cone), which the candidates that
/// are form terms fit; tried as a vibration it came back as a runner-up at 0.007/rev
/// on 3 mm profiles and its pairs took half of a diagnosis's time (suite case 012).
const MIN_CYCLES: f64 = 2.0;

/// One measured point as the screen sees it.
#[derive(Debug, Clone, Copy)]
pub struct Point {
    pub residual_mm: f64,
    pub clock_rad: f64,
    /// dz/dr of the simulated surface there.
    pub slope: f64,
    pub radius_mm: f64,
}

/// The best rate for `candidate` and its cos/sin amplitudes (mm, or rad for a tilt),
/// with the share of the residual's sum of squares it explains; `None` when the points
/// cannot carry the signature (no clock, a single revolution). On a map no rate is
/// tried above `nyquist` (cycles per revolution: half the simulation's azimuths): the
/// simulation samples the clock at its azimuths only, so a rate k and k less a whole
/// number of azimuths leave the same simulated surface, and a rate past half of them
/// is the alias of a slower one (a 128/rev feed vibration on 16 azimuths is a
/// synchronous shift: a decentre's cone).
pub fn screen_rate(
    candidate: Candidate,
    points: &[Point],
    line: bool,
    nyquist: f64,
) -> Option<(f64, [f64; 2], f64)> {
    let points: Vec<Point> = points
        .iter()
        .copied()
        .filter(|p| p.clock_rad.is_finite() && p.residual_mm.is_finite() && p.residual_mm != 0.0)
        .collect();
    let (t_lo, t_hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.clock_rad), b.max(p.clock_rad))
        });
    let revolutions = (t_hi - t_lo) / TAU;
    if points.len() < 8 || revolutions < 2.0 {
        return None;
    }
    let total: f64 = points.iter().map(|p| p.residual_mm.powi(2)).sum();
    let explained = |k: f64| project(candidate, &points, k).1;
    let rates = rate_grid(candidate, revolutions, line, nyquist);
    if rates.is_empty() {
        return None;
    }
    let scores: Vec<f64> = rates.iter().map(|&k| explained(k)).collect();
    let peaks = local_maxima(&scores);
    let mut best = (0.0, f64::NEG_INFINITY);
    for &i in peaks.iter().take(REFINED) {
        let k = if matches!(candidate, Candidate::TiltErrorMotion { .. }) {
            rates[i]
        } else {
            let (lo, hi) = (
                rates[i.saturating_sub(1)],
                rates[(i + 1).min(rates.len() - 1)],
            );
            let bracket = golden_section(|k| -explained(k), lo, hi, 24);
            bracket
                .inner
                .iter()
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map_or(rates[i], |x| x.0)
        };
        let score = explained(k);
        if score > best.1 {
            best = (k, score);
        }
    }
    // Rates the sampling cannot tell apart (aliases on a map's pixel grid explain the
    // same): the lowest of those within 2 % of the best, the simplest cause.
    let mut lowest = best;
    for &i in peaks.iter().take(4 * REFINED) {
        if rates[i] < lowest.0 && scores[i] >= 0.98 * best.1 {
            lowest = (rates[i], scores[i]);
        }
    }
    let best = lowest;
    let (coefficients, score) = project(candidate, &points, best.0);
    Some((best.0, coefficients, score / total.max(f64::MIN_POSITIVE)))
}

/// Rates to try: whole orders for a tilt (up to 60); for a vibration steps of a quarter
/// cycle over the revolutions the data spans, from [`MIN_CYCLES`] across the data up to
/// 1 cycle per revolution on a line or to the job files' bound on a map; on a map below `nyquist`
/// (see [`screen_rate`]). A line through the axis
/// sees the clock at two spindle angles half a turn apart only, t = 2πm or 2πm + π, so
/// rates k + 2 and 2 − k (with the phase mirrored) leave the same trace as k, and a
/// profile knows a vibration's rate only modulo that.
fn rate_grid(candidate: Candidate, revolutions: f64, line: bool, nyquist: f64) -> Vec<f64> {
    let top = if line {
        1.0
    } else {
        MAX_CYCLES_PER_REV.min(nyquist)
    };
    if matches!(candidate, Candidate::TiltErrorMotion { .. }) {
        return (1..=60).map(f64::from).filter(|k| *k < top).collect();
    }
    let step = (0.25 / revolutions).max(top / MAX_RATES as f64);
    let count = (top / step).floor() as usize;
    (1..=count)
        .map(|i| i as f64 * step)
        .filter(|k| k * revolutions >= MIN_CYCLES)
        .collect()
}

/// Indices of the grid's local maxima, highest first.
fn local_maxima(scores: &[f64]) -> Vec<usize> {
    let mut peaks: Vec<usize> = (0..scores.len())
        .filter(|&i| {
            let left = i == 0 || scores[i - 1] <= scores[i];
            let right = i + 1 == scores.len() || scores[i + 1] < scores[i];
            left && right
        })
        .collect();
    peaks.sort_by(|a, b| scores[*b].total_cmp(&scores[*a]));
    peaks
}

/// The least-squares cos/sin coefficients of the signature at rate `k` and the sum of
/// squares they explain.
fn project(candidate: Candidate, points: &[Point], k: f64) -> ([f64; 2], f64) {
    let (mut cc, mut cs, mut ss, mut rc, mut rs) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        let weight = match candidate {
            Candidate::Vibration { depth: true, .. } => 1.0,
            Candidate::Vibration { depth: false, .. } => -p.slope,
            _ => -p.radius_mm,
        };
        let (sin, cos) = (k * p.clock_rad).sin_cos();
        let (c, s) = (weight * cos, weight * sin);
        cc += c * c;
        cs += c * s;
        ss += s * s;
        rc += p.residual_mm * c;
        rs += p.residual_mm * s;
    }
    let det = cc * ss - cs * cs;
    if det <= 1e-12 * (cc * ss).max(f64::MIN_POSITIVE) {
        return ([0.0, 0.0], 0.0);
    }
    let a = (rc * ss - rs * cs) / det;
    let b = (rs * cc - rc * cs) / det;
    ([a, b], a * rc + b * rs)
}

/// Points the waviness screen keeps (evenly strided; the screen only ranks orders).
const WAVINESS_SCREEN_POINTS: usize = 4000;
/// Screened waviness orders the simulation then tries.
const WAVINESS_TRIED: usize = 3;

/// Edge waviness orders in `lo..=hi` ranked by how much of the residual an edge
/// harmonic of that order explains, best first (at most [`WAVINESS_TRIED`], each
/// refined on the screen). To first order the edge deviation at the edge angle in
/// contact, ψ = atan(dz/dr) of the surface there, lifts the surface by itself, so the
/// signature is cos(k·ψ), sin(k·ψ), fitted beside 1, r and r² (what registration and
/// the power term take). The grid keeps a sixteenth-cycle phase error across the angles
/// the points span; `None` when they span too little to tell orders apart. With the
/// orders, the half-width (an eighth cycle across the span) a simulation refines in.
/// The orders tried are apart by at least a quarter cycle across the span: the peaks of
/// one harmonic's screen (its side lobes, the noise on its crest) are one order to this
/// data, and three of them would leave another harmonic untried.
pub fn screen_waviness(points: &[Point], lo: f64, hi: f64) -> Option<(Vec<f64>, f64)> {
    let stride = points.len().div_ceil(WAVINESS_SCREEN_POINTS).max(1);
    let points: Vec<(f64, f64, f64)> = points
        .iter()
        .step_by(stride)
        .filter(|p| p.residual_mm.is_finite() && p.residual_mm != 0.0 && p.slope.is_finite())
        .map(|p| (p.slope.atan(), p.radius_mm, p.residual_mm))
        .collect();
    let span = angle_span(&points);
    if points.len() < 16 || span <= 0.0 || hi <= lo {
        return None;
    }
    let rss = |k: f64| waviness_rss(&points, k);
    let step = (std::f64::consts::FRAC_PI_8 / span).max((hi - lo) / 2000.0);
    let orders: Vec<f64> = (0..=((hi - lo) / step).floor() as usize)
        .map(|i| lo + i as f64 * step)
        .collect();
    let scores: Vec<f64> = orders.iter().map(|&k| -rss(k)).collect();
    let mut ranked: Vec<(f64, f64)> = local_maxima(&scores)
        .into_iter()
        .take(4 * WAVINESS_TRIED)
        .map(|i| {
            let (a, b) = (
                orders[i.saturating_sub(1)],
                orders[(i + 1).min(orders.len() - 1)],
            );
            let bracket = golden_section(&rss, a, b, 16);
            let (k, value) = bracket
                .inner
                .into_iter()
                .chain([(orders[i], -scores[i])])
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .expect("three values");
            (k, value)
        })
        .collect();
    ranked.sort_by(|a, b| a.1.total_cmp(&b.1));
    let apart = std::f64::consts::FRAC_PI_2 / span;
    let mut orders: Vec<f64> = Vec::new();
    for (k, _) in ranked {
        if orders.len() < WAVINESS_TRIED && orders.iter().all(|o| (k - o).abs() >= apart) {
            orders.push(k);
        }
    }
    Some((orders, std::f64::consts::FRAC_PI_4 / span))
}

/// The edge angles (ψ, …) the points span, between the [`SPAN_TAIL`] quantiles: a
/// boss's edge (a few points of a steep wall) says nothing of the orders the rest can
/// tell apart.
fn angle_span(points: &[(f64, f64, f64)]) -> f64 {
    let mut angles: Vec<f64> = points.iter().map(|p| p.0).collect();
    if angles.is_empty() {
        return 0.0;
    }
    angles.sort_by(f64::total_cmp);
    let at = |q: f64| angles[(q * (angles.len() - 1) as f64).round() as usize];
    at(1.0 - SPAN_TAIL) - at(SPAN_TAIL)
}

/// Share of the points at each end of the edge angles left out of their span.
const SPAN_TAIL: f64 = 0.005;

/// Σ r² left after fitting 1, r, r², cos(k·ψ), sin(k·ψ) to the points (ψ, r, residual).
fn waviness_rss(points: &[(f64, f64, f64)], k: f64) -> f64 {
    let rows: Vec<Vec<f64>> = points
        .iter()
        .map(|&(psi, r, _)| {
            let (sin, cos) = (k * psi).sin_cos();
            vec![1.0, r, r * r, cos, sin]
        })
        .collect();
    let y: Vec<f64> = points.iter().map(|p| p.2).collect();
    let Some(c) = crate::numeric::least_squares(&rows, &y) else {
        return y.iter().map(|v| v * v).sum();
    };
    rows.iter()
        .zip(&y)
        .map(|(row, v)| (v - row.iter().zip(&c).map(|(a, b)| a * b).sum::<f64>()).powi(2))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points along a diameter of a facing cut, 10 µm per revolution: a point at radius
    /// r is left by revolution m = ⌊(1.2 − r)/0.01⌋, on the far side half a turn later.
    fn points(residual: impl Fn(f64, f64) -> f64) -> Vec<Point> {
        (0..4000)
            .map(|i| {
                let x = -1.1 + 1e-3 * i as f64 * 0.55;
                let r = x.abs();
                let m = ((1.2 - r) / 0.01).floor();
                let clock = TAU * m + if x < 0.0 { std::f64::consts::PI } else { 0.0 };
                Point {
                    residual_mm: residual(clock, r),
                    clock_rad: clock,
                    slope: 0.0,
                    radius_mm: r,
                }
            })
            .filter(|p| p.radius_mm > 0.1)
            .collect()
    }

    #[test]
    fn a_fractional_depth_vibration_is_found_at_its_rate_and_amplitude() {
        // Data made as 3 nm·cos(0.37·t + 0.5) plus a slower form term it must not take.
        let data = points(|t, r| 3e-6 * (0.37 * t + 0.5).cos() + 2e-6 * (4.0 * r).sin());
        let candidate = Candidate::Vibration {
            cycles: 0.0,
            depth: true,
        };
        let (k, [a, b], share) = screen_rate(candidate, &data, true, f64::INFINITY).unwrap();
        assert!((k - 0.37).abs() < 2e-4, "k = {k}");
        // a·cos + b·sin = A·cos(kt + φ): A = 3 nm, φ = 0.5 (a = A cos φ, b = −A sin φ).
        assert!((a.hypot(b) - 3e-6).abs() < 0.1e-6, "A = {}", a.hypot(b));
        assert!(((-b).atan2(a) - 0.5).abs() < 0.05, "φ = {}", (-b).atan2(a));
        assert!(share > 0.5);
    }

    #[test]
    fn a_vibration_slower_than_two_cycles_across_the_data_is_not_tried() {
        // One cycle across the data's ~100 revolutions (0.01/rev): a form term.
        let data = points(|t, _| 3e-6 * (0.01 * t + 0.5).cos());
        let span = data
            .iter()
            .map(|p| p.clock_rad)
            .fold(f64::NEG_INFINITY, f64::max)
            - data
                .iter()
                .map(|p| p.clock_rad)
                .fold(f64::INFINITY, f64::min);
        let revolutions = span / TAU;
        let candidate = Candidate::Vibration {
            cycles: 0.0,
            depth: true,
        };
        let (k, _, _) = screen_rate(candidate, &data, true, f64::INFINITY).unwrap();
        assert!(
            k * revolutions >= MIN_CYCLES - 1e-9,
            "k = {k} over {revolutions} revolutions"
        );
        // Three cycles across the same data: tried, and found.
        let k3 = 3.0 / revolutions;
        let data = points(|t, _| 3e-6 * (k3 * t + 0.5).cos());
        let (k, _, share) = screen_rate(candidate, &data, true, f64::INFINITY).unwrap();
        assert!((k - k3).abs() < 0.02 * k3, "k = {k}, made at {k3}");
        assert!(share > 0.9, "share {share}");
    }

    /// A diameter over an R8 convex sphere at 1 µm steps (edge angles 0 to −10.8°):
    /// `point(x, r, ψ)` gives each point's (slope, residual), the slope None for the
    /// sphere's own.
    fn r8_diameter(point: impl Fn(f64, f64, f64) -> (Option<f64>, f64)) -> Vec<Point> {
        let radius: f64 = 8.0;
        (0..3000)
            .map(|i| {
                let x = -1.5 + 1e-3 * i as f64;
                let r = x.abs();
                let sphere = -r / (radius * radius - r * r).sqrt();
                let (slope, residual) = point(x, r, sphere.atan());
                Point {
                    residual_mm: residual,
                    clock_rad: 0.0,
                    slope: slope.unwrap_or(sphere),
                    radius_mm: r,
                }
            })
            .collect()
    }

    #[test]
    fn an_edge_harmonic_is_screened_at_its_order_on_a_sphere_profile() {
        // 40 nm·cos(20·ψ + 0.7), a power term registration leaves and a 1 nm ripple.
        let k_true = 20.0;
        let data = r8_diameter(|x, r, psi| {
            let residual =
                40e-6 * (k_true * psi + 0.7).cos() + 3e-5 * r * r + 1e-6 * (977.0 * x).sin();
            (None, residual)
        });
        let (orders, half_width) = screen_waviness(&data, 4.0, 400.0).unwrap();
        assert!((orders[0] / k_true - 1.0).abs() < 0.01, "orders {orders:?}");
        // An eighth of a cycle across the 0.19 rad the edge angles span.
        assert!((half_width - std::f64::consts::FRAC_PI_4 / (1.5f64 / 8.0).asin()).abs() < 0.05);
    }

    #[test]
    fn a_boss_wall_leaves_the_span_and_a_second_harmonic_is_tried() {
        // 40 nm·cos(20ψ + 0.7) and 15 nm·cos(48ψ), and a modelled boss at the axis: a
        // few points whose simulated slope is its steep wall (ψ = −1.5 rad), their
        // residual 5 nm.
        let k2 = 48.0;
        let data = r8_diameter(|_, r, psi| {
            if r < 0.002 {
                (Some(-14.0), 5e-6)
            } else {
                let residual = 40e-6 * (20.0 * psi + 0.7).cos() + 15e-6 * (k2 * psi).cos();
                (None, residual)
            }
        });
        let (orders, half_width) = screen_waviness(&data, 4.0, 400.0).unwrap();
        // The half-width of the bulk's 0.19 rad, not of the wall's 1.5.
        let bulk = std::f64::consts::FRAC_PI_4 / (1.5f64 / 8.0).asin();
        assert!(
            (half_width / bulk - 1.0).abs() < 0.05,
            "{half_width} for {bulk}"
        );
        // The orders tried lie a quarter cycle apart, and the second harmonic is one.
        for (i, a) in orders.iter().enumerate() {
            for b in &orders[i + 1..] {
                assert!((a - b).abs() >= 2.0 * bulk * 0.95, "orders {orders:?}");
            }
        }
        assert!(
            orders.iter().any(|k| (k / k2 - 1.0).abs() < 0.05),
            "orders {orders:?}"
        );
    }
}

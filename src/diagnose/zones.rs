//! Where a residual lies: radial zones (centre, annuli, rim), azimuthal orders (maps)
//! and spatial-frequency bands (form, waviness, tool marks), each with its share of the
//! residual's energy (Σ residual²); and the statistics that judge a residual against
//! noise (a white-noise estimate, the correlation length).

use super::measurement::{Measurement, Shape};
use crate::numeric::least_squares;
use glam::DVec2;
use std::f64::consts::TAU;

/// PV, RMS and share of one part of a residual.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ZoneStats {
    pub name: String,
    /// Radii (zones) or wavelengths (bands) the part covers (mm).
    pub from_mm: f64,
    pub to_mm: f64,
    pub points: usize,
    pub pv_nm: f64,
    pub rms_nm: f64,
    /// Share of the residual's Σ r² (0–1).
    pub share: f64,
}

/// Radial zones: the centre (to 10 % of the largest radius), three equal annuli, the rim
/// (beyond 90 %).
#[derive(Debug, Clone, PartialEq)]
pub struct Zones {
    pub bounds: Vec<(String, f64, f64)>,
}

impl Zones {
    pub fn new(max_radius_mm: f64) -> Self {
        let (centre, rim) = (0.1 * max_radius_mm, 0.9 * max_radius_mm);
        let step = (rim - centre) / 3.0;
        let mut bounds = vec![("centre".to_string(), 0.0, centre)];
        for k in 0..3 {
            let (a, b) = (centre + k as f64 * step, centre + (k + 1) as f64 * step);
            bounds.push((format!("annulus {}", k + 1), a, b));
        }
        bounds.push(("rim".to_string(), rim, max_radius_mm));
        Self { bounds }
    }

    /// The zone a radius falls in.
    pub fn of(&self, radius_mm: f64) -> usize {
        self.bounds
            .iter()
            .position(|(_, _, to)| radius_mm < *to)
            .unwrap_or(self.bounds.len() - 1)
    }

    /// Per zone statistics of `residual_mm` at `radii_mm` (NaN residuals skipped).
    pub fn stats(&self, radii_mm: &[f64], residual_mm: &[f64]) -> Vec<ZoneStats> {
        let total: f64 = residual_mm
            .iter()
            .filter(|v| v.is_finite())
            .map(|v| v * v)
            .sum();
        self.bounds
            .iter()
            .enumerate()
            .map(|(z, (name, from, to))| {
                let values: Vec<f64> = radii_mm
                    .iter()
                    .zip(residual_mm)
                    .filter(|(r, v)| v.is_finite() && self.of(**r) == z)
                    .map(|(_, v)| *v)
                    .collect();
                let mut stats = summary(name, *from, *to, &values);
                stats.share = share(&values, total);
                stats
            })
            .collect()
    }
}

/// PV and RMS (nm) of values in mm; share left 0.
pub fn summary(name: &str, from_mm: f64, to_mm: f64, values_mm: &[f64]) -> ZoneStats {
    let (lo, hi) = values_mm
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let n = values_mm.len();
    ZoneStats {
        name: name.to_string(),
        from_mm,
        to_mm,
        points: n,
        pv_nm: if n > 0 { (hi - lo) * 1e6 } else { 0.0 },
        rms_nm: rms(values_mm) * 1e6,
        share: 0.0,
    }
}

fn share(values: &[f64], total: f64) -> f64 {
    if total > 0.0 {
        values.iter().map(|v| v * v).sum::<f64>() / total
    } else {
        0.0
    }
}

/// Root mean square of the finite values.
pub fn rms(values: &[f64]) -> f64 {
    let (sum, n) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n > 0 { (sum / n as f64).sqrt() } else { 0.0 }
}

/// Peak-to-valley of the finite values.
pub fn pv(values: &[f64]) -> f64 {
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    if hi >= lo { hi - lo } else { 0.0 }
}

/// The residual split by wavelength with ISO 16610-21 Gaussian filters: tool marks and
/// roughness below `marks_cutoff_mm`, waviness up to `form_cutoff_mm`, form above.
/// Gaps (invalid points) are bridged by normalised convolution.
pub fn bands(
    m: &Measurement,
    residual_mm: &[f64],
    marks_cutoff_mm: f64,
    form_cutoff_mm: f64,
) -> Vec<ZoneStats> {
    let smooth_marks = gaussian_lowpass(m, residual_mm, marks_cutoff_mm);
    let smooth_form = gaussian_lowpass(m, residual_mm, form_cutoff_mm);
    let part = |f: &dyn Fn(usize) -> f64| -> Vec<f64> {
        (0..residual_mm.len())
            .filter(|&i| residual_mm[i].is_finite())
            .map(f)
            .collect()
    };
    let marks = part(&|i| residual_mm[i] - smooth_marks[i]);
    let waviness = part(&|i| smooth_marks[i] - smooth_form[i]);
    let form = part(&|i| smooth_form[i]);
    let energy = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>();
    let total = energy(&marks) + energy(&waviness) + energy(&form);
    let mut out = vec![
        summary("tool marks and roughness", 0.0, marks_cutoff_mm, &marks),
        summary("waviness", marks_cutoff_mm, form_cutoff_mm, &waviness),
        summary("form", form_cutoff_mm, f64::INFINITY, &form),
    ];
    for (stats, values) in out.iter_mut().zip([&marks, &waviness, &form]) {
        stats.share = if total > 0.0 {
            energy(values) / total
        } else {
            0.0
        };
    }
    out
}

/// Gaussian profile filter (50 % transmission at `cutoff_mm`): along the line, or
/// separably along a raster's rows and columns.
pub fn gaussian_lowpass(m: &Measurement, values: &[f64], cutoff_mm: f64) -> Vec<f64> {
    let (weight, reach) = gaussian_weight(cutoff_mm);
    match m.shape {
        Shape::Line { .. } => gaussian_lowpass_line(&m.along_mm, values, cutoff_mm),
        Shape::Raster { nx, ny, pixel_mm } => {
            let mut grid = vec![f64::NAN; nx * ny];
            for (i, &k) in m.index.iter().enumerate() {
                grid[k] = values[i];
            }
            let (sum, norm) = raster_lowpass(&grid, nx, ny, pixel_mm, &weight, reach);
            m.index
                .iter()
                .map(|&k| {
                    if norm[k] > 0.0 {
                        sum[k] / norm[k]
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        }
    }
}

/// ISO 16610-21's Gaussian weighting, s(x) ∝ exp(−π (x / (α λc))²) with α = √(ln 2 / π)
/// (50 % transmission at the cut-off λc), and how far it reaches (2 α λc).
fn gaussian_weight(cutoff_mm: f64) -> (impl Fn(f64) -> f64, f64) {
    let width = (std::f64::consts::LN_2 / std::f64::consts::PI).sqrt() * cutoff_mm;
    let weight = move |d: f64| (-std::f64::consts::PI * (d / width).powi(2)).exp();
    (weight, 2.0 * width)
}

/// The Gaussian profile filter on points at ascending positions `x` (NaN values are
/// gaps, bridged by normalised convolution).
pub fn gaussian_lowpass_line(x: &[f64], values: &[f64], cutoff_mm: f64) -> Vec<f64> {
    gaussian_line(x, values, cutoff_mm, false)
}

/// The Gaussian profile filter as a regression of order one (ISO 16610-21's end-effect
/// correction): at each point the Gaussian-weighted straight line through its
/// neighbours (NaN gaps left out). A sloped profile keeps its level up to its ends and
/// gaps, where the normalised convolution bends toward the inside by the slope times a
/// fraction of the filter's width (0.14 × 1.04 µm ≈ 150 nm at the end of a sphere's
/// trace sloping 0.14, points 0.25 µm apart, high-passed at 7.5 µm: more than the tool
/// marks that place it).
pub fn gaussian_regression_line(x: &[f64], values: &[f64], cutoff_mm: f64) -> Vec<f64> {
    gaussian_line(x, values, cutoff_mm, true)
}

/// The Gaussian filter's weighted mean (or, `linear`, weighted straight line) about each
/// point.
fn gaussian_line(x: &[f64], values: &[f64], cutoff_mm: f64, linear: bool) -> Vec<f64> {
    let (exact, reach) = gaussian_weight(cutoff_mm);
    let table = WeightTable::new(&exact, reach);
    let weight = |d: f64| table.at(d);
    let mut out = vec![f64::NAN; values.len()];
    let mut first = 0;
    for i in 0..x.len() {
        while x[first] < x[i] - reach {
            first += 1;
        }
        // Σw, Σw d, Σw d², Σw v, Σw d v over the neighbours, d = x_j − x_i.
        let mut sums = [0.0; 5];
        for j in first..x.len() {
            let d = x[j] - x[i];
            if d > reach {
                break;
            }
            if values[j].is_finite() {
                let w = weight(d);
                sums[0] += w;
                sums[3] += w * values[j];
                if linear {
                    sums[1] += w * d;
                    sums[2] += w * d * d;
                    sums[4] += w * d * values[j];
                }
            }
        }
        out[i] = line_at_zero(sums);
    }
    out
}

/// The weighted line's value at d = 0 from its sums (the weighted mean where the
/// points cannot fix a slope: one point, or none off this one's position).
fn line_at_zero([s0, s1, s2, t0, t1]: [f64; 5]) -> f64 {
    if s0 <= 0.0 {
        return f64::NAN;
    }
    let det = s0 * s2 - s1 * s1;
    if det > 1e-9 * s0 * s2 {
        (s2 * t0 - s1 * t1) / det
    } else {
        t0 / s0
    }
}

/// Intervals of [`WeightTable`]: linear interpolation of the Gaussian over its reach
/// (two widths) at this many steps is within 1.2e-8 of its peak (h²/8 · 2π/width²).
const WEIGHT_STEPS: usize = 16384;

/// A weight function of |d| tabulated over [0, reach] and interpolated linearly: the
/// line filter weighs each point against hundreds of neighbours, and one `exp` per pair
/// was most of placing a long trace.
struct WeightTable {
    step: f64,
    values: Vec<f64>,
}

impl WeightTable {
    fn new(weight: &dyn Fn(f64) -> f64, reach: f64) -> Self {
        let step = reach / WEIGHT_STEPS as f64;
        let values = (0..=WEIGHT_STEPS + 1)
            .map(|k| weight(k as f64 * step))
            .collect();
        Self { step, values }
    }

    fn at(&self, d: f64) -> f64 {
        let u = (d.abs() / self.step).min(WEIGHT_STEPS as f64);
        let k = u as usize;
        let t = u - k as f64;
        self.values[k] + t * (self.values[k + 1] - self.values[k])
    }
}

/// Separable normalised convolution of a raster with NaN gaps: (Σ w v, Σ w) per pixel.
fn raster_lowpass(
    grid: &[f64],
    nx: usize,
    ny: usize,
    pixel_mm: [f64; 2],
    weight: &dyn Fn(f64) -> f64,
    reach: f64,
) -> (Vec<f64>, Vec<f64>) {
    let pass = |sum_in: &[f64], norm_in: &[f64], along_x: bool| {
        let (len, lines, pitch) = if along_x {
            (nx, ny, pixel_mm[0])
        } else {
            (ny, nx, pixel_mm[1])
        };
        let half = (reach / pitch).floor() as i64;
        let kernel: Vec<f64> = (-half..=half).map(|k| weight(k as f64 * pitch)).collect();
        let at = |line: usize, k: usize| {
            if along_x {
                line * nx + k
            } else {
                k * nx + line
            }
        };
        let (mut sum, mut norm) = (vec![0.0; nx * ny], vec![0.0; nx * ny]);
        for line in 0..lines {
            for k in 0..len {
                let (mut s, mut w) = (0.0, 0.0);
                for (o, kw) in kernel.iter().enumerate() {
                    let q = k as i64 + o as i64 - half;
                    if q < 0 || q >= len as i64 {
                        continue;
                    }
                    let idx = at(line, q as usize);
                    s += kw * sum_in[idx];
                    w += kw * norm_in[idx];
                }
                sum[at(line, k)] = s;
                norm[at(line, k)] = w;
            }
        }
        (sum, norm)
    };
    let sum0: Vec<f64> = grid
        .iter()
        .map(|v| if v.is_finite() { *v } else { 0.0 })
        .collect();
    let norm0: Vec<f64> = grid
        .iter()
        .map(|v| if v.is_finite() { 1.0 } else { 0.0 })
        .collect();
    let (sum1, norm1) = pass(&sum0, &norm0, true);
    pass(&sum1, &norm1, false)
}

/// Shares of a map's residual in azimuthal orders about the axis (at `axis_mm` in the
/// measurement's frame): per narrow annulus, a Fourier series to order 8 by least
/// squares; order 0 is what is rotationally symmetric, 1 a decentre- or tilt-like
/// structure, 2 astigmatism or a saddle; what no order up to 8 holds is "above 8".
pub fn azimuthal_orders(
    m: &Measurement,
    residual_mm: &[f64],
    axis_mm: DVec2,
) -> Vec<(String, f64)> {
    const MAX_ORDER: usize = 8;
    let points: Vec<(f64, f64, f64)> = (0..m.len())
        .filter(|&i| residual_mm[i].is_finite())
        .map(|i| {
            let p = m.xy_mm[i] - axis_mm;
            (p.length(), p.y.atan2(p.x), residual_mm[i])
        })
        .collect();
    let total: f64 = points.iter().map(|p| p.2 * p.2).sum();
    let mut energy = [0.0; MAX_ORDER + 2];
    if total <= 0.0 || points.len() < 64 {
        return Vec::new();
    }
    let mut sorted = points.clone();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let bins = (sorted.len() / 400).clamp(4, 48);
    for chunk in sorted.chunks(sorted.len().div_ceil(bins)) {
        if chunk.len() < 4 * MAX_ORDER {
            energy[MAX_ORDER + 1] += chunk.iter().map(|p| p.2 * p.2).sum::<f64>();
            continue;
        }
        let rows: Vec<Vec<f64>> = chunk
            .iter()
            .map(|&(_, theta, _)| {
                let mut row = vec![1.0];
                for k in 1..=MAX_ORDER {
                    let (s, c) = (k as f64 * theta).sin_cos();
                    row.extend([c, s]);
                }
                row
            })
            .collect();
        let values: Vec<f64> = chunk.iter().map(|p| p.2).collect();
        let Some(c) = least_squares(&rows, &values) else {
            energy[MAX_ORDER + 1] += values.iter().map(|v| v * v).sum::<f64>();
            continue;
        };
        let mut explained = 0.0;
        for (row, _) in rows.iter().zip(&values) {
            for k in 0..=MAX_ORDER {
                let part = if k == 0 {
                    c[0]
                } else {
                    row[2 * k - 1] * c[2 * k - 1] + row[2 * k] * c[2 * k]
                };
                energy[k] += part * part;
                explained += part * part;
            }
        }
        let own: f64 = values.iter().map(|v| v * v).sum();
        energy[MAX_ORDER + 1] += (own - explained).max(0.0);
    }
    let sum: f64 = energy.iter().sum();
    let pick = |range: std::ops::RangeInclusive<usize>| range.map(|k| energy[k]).sum::<f64>() / sum;
    vec![
        ("0 (rotationally symmetric)".into(), pick(0..=0)),
        ("1".into(), pick(1..=1)),
        ("2".into(), pick(2..=2)),
        ("3".into(), pick(3..=3)),
        ("4–8".into(), pick(4..=MAX_ORDER)),
        ("above 8".into(), pick(MAX_ORDER + 1..=MAX_ORDER + 1)),
    ]
}

/// Sequences of consecutive valid residuals: along the line, or along raster rows
/// (`along_x`) or columns.
fn sequences(m: &Measurement, residual_mm: &[f64], along_x: bool) -> Vec<Vec<f64>> {
    match m.shape {
        Shape::Line { .. } => vec![
            residual_mm
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .collect(),
        ],
        Shape::Raster { nx, ny, .. } => {
            let mut grid = vec![f64::NAN; nx * ny];
            for (i, &k) in m.index.iter().enumerate() {
                grid[k] = residual_mm[i];
            }
            let (lines, len) = if along_x { (ny, nx) } else { (nx, ny) };
            (0..lines)
                .map(|l| {
                    (0..len)
                        .map(|k| {
                            if along_x {
                                grid[l * nx + k]
                            } else {
                                grid[k * nx + l]
                            }
                        })
                        .filter(|v| v.is_finite())
                        .collect()
                })
                .collect()
        }
    }
}

/// The white-noise level of a residual (mm): from second differences of neighbouring
/// points, robustly (median absolute value), which smooth structure hardly reaches.
pub fn white_noise_mm(m: &Measurement, residual_mm: &[f64]) -> f64 {
    let mut d: Vec<f64> = sequences(m, residual_mm, true)
        .iter()
        .flat_map(|s| {
            s.windows(3)
                .map(|w| (w[0] - 2.0 * w[1] + w[2]).abs())
                .collect::<Vec<_>>()
        })
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    d.sort_by(f64::total_cmp);
    // For white noise σ, the second difference has σ√6; its median |·| is 0.6745 σ√6.
    d[d.len() / 2] / (0.6745 * 6f64.sqrt())
}

/// Integrated autocorrelation length (points, ≥ 1): how many neighbouring residuals
/// carry one independent value. Summed over lags while the autocorrelation stays
/// positive (Geyer's initial positive sequence, in pairs).
pub fn correlation_length(m: &Measurement, residual_mm: &[f64]) -> f64 {
    let along = |x: bool| -> f64 {
        let seqs = sequences(m, residual_mm, x);
        let n: usize = seqs.iter().map(Vec::len).sum();
        if n < 8 {
            return 1.0;
        }
        let mean = seqs.iter().flatten().sum::<f64>() / n as f64;
        let var = seqs
            .iter()
            .flatten()
            .map(|v| (v - mean).powi(2))
            .sum::<f64>()
            / n as f64;
        if var <= 0.0 {
            return 1.0;
        }
        let rho = |lag: usize| -> f64 {
            let (mut s, mut count) = (0.0, 0usize);
            for seq in &seqs {
                for w in seq.windows(lag + 1) {
                    s += (w[0] - mean) * (w[lag] - mean);
                    count += 1;
                }
            }
            if count == 0 {
                0.0
            } else {
                s / count as f64 / var
            }
        };
        let max_lag = (seqs.iter().map(Vec::len).max().unwrap_or(0) / 4).max(2);
        let mut tau = 1.0;
        let mut lag = 1;
        while lag < max_lag {
            let pair = rho(lag) + rho(lag + 1);
            if pair <= 0.0 {
                break;
            }
            tau += 2.0 * pair;
            lag += 2;
        }
        tau.max(1.0)
    };
    match m.shape {
        Shape::Line { .. } => along(true),
        Shape::Raster { .. } => along(true) * along(false),
    }
}

/// Wavelength cut-offs for the bands: marks below 2.5 mark spacings (or 5 point
/// spacings when the process leaves none), form above a quarter of the extent.
pub fn band_cutoffs(m: &Measurement, mark_spacing_mm: Option<f64>) -> (f64, f64) {
    let marks = mark_spacing_mm.map_or(5.0 * m.spacing_mm(), |s| 2.5 * s);
    let form = (0.25 * m.extent_mm()).max(2.0 * marks);
    (marks, form)
}

/// Radius of every point about the axis at `axis_mm`.
pub fn radii(m: &Measurement, axis_mm: DVec2) -> Vec<f64> {
    m.xy_mm.iter().map(|p| (*p - axis_mm).length()).collect()
}

/// Angle helper for tests and reports: a point's azimuth in [0, 2π).
pub fn azimuth(p: DVec2) -> f64 {
    p.y.atan2(p.x).rem_euclid(TAU)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::measurement::Instrument;

    fn line(x: &[f64], h: &[f64]) -> Measurement {
        Measurement::line(x, h, 0.0, 0.0, Instrument::default())
    }

    #[test]
    fn gaussian_filter_passes_half_at_the_cutoff() {
        // ISO 16610-21: a sinusoid at the cut-off wavelength keeps 50 % of its amplitude.
        let x: Vec<f64> = (0..20001).map(|i| i as f64 * 1e-4 - 1.0).collect();
        let cutoff = 0.08;
        let h: Vec<f64> = x.iter().map(|v| (TAU * v / cutoff).sin()).collect();
        let m = line(&x, &h);
        let low = gaussian_lowpass(&m, &h, cutoff);
        // Away from the ends, amplitude = 0.5.
        let amp = low[5000..15000].iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        assert!((amp - 0.5).abs() < 1e-3, "{amp}");
    }

    #[test]
    fn the_regression_filter_keeps_a_sloped_line_level_to_its_ends_and_gaps() {
        // A straight line sloping 0.14 (a sphere's trace near its end), points 0.25 µm
        // apart with a gap, filtered at 7.5 µm: a regression of order one returns the
        // line itself (to rounding) everywhere; the normalised convolution is off at
        // the ends by the slope times its window's one-sided mean distance.
        let x: Vec<f64> = (0..4001).map(|i| i as f64 * 2.5e-4).collect();
        let mut h: Vec<f64> = x.iter().map(|v| 0.14 * v - 0.01).collect();
        for v in &mut h[2000..2040] {
            *v = f64::NAN;
        }
        let cutoff = 7.5e-3;
        let line = gaussian_regression_line(&x, &h, cutoff);
        for (i, (l, v)) in line.iter().zip(&h).enumerate() {
            if v.is_finite() {
                assert!((l - v).abs() < 1e-12, "point {i}: {l} against {v}");
            }
        }
        // The plain filter at the first point: the one-sided Gaussian exp(−π d²/W²)'s
        // mean distance, W/π for the integral (W = α λc, α = √(ln 2/π)); summed over
        // points h apart (Euler–Maclaurin) (W/π − h²/6W) / (1 + h/W): 1.04 µm here.
        let plain = gaussian_lowpass_line(&x, &h, cutoff);
        let (w, step) = (
            (std::f64::consts::LN_2 / std::f64::consts::PI).sqrt() * cutoff,
            2.5e-4,
        );
        let mean = (w / std::f64::consts::PI - step * step / (6.0 * w)) / (1.0 + step / w);
        let expected = 0.14 * mean;
        assert!(
            ((plain[0] - h[0]) / expected - 1.0).abs() < 0.01,
            "{} against {expected}",
            plain[0] - h[0]
        );
    }

    #[test]
    fn band_shares_of_a_two_tone_residual() {
        // A short-wave tone (marks) and a long-wave one (form) of equal amplitude: half
        // the energy each (the filters pass 1e-6 of the other at these wavelengths).
        let x: Vec<f64> = (0..30001).map(|i| i as f64 * 1e-4 - 1.5).collect();
        let h: Vec<f64> = x
            .iter()
            .map(|v| 1e-6 * ((TAU * v / 0.01).sin() + (TAU * v / 6.0 + 0.3).sin()))
            .collect();
        let m = line(&x, &h);
        let b = bands(&m, &h, 0.025, 0.75);
        assert!((b[0].share - 0.5).abs() < 0.02, "{:?}", b);
        assert!(b[1].share < 0.02, "{:?}", b);
        assert!((b[2].share - 0.5).abs() < 0.03, "{:?}", b);
    }

    #[test]
    fn white_noise_level_and_correlation_of_known_sequences() {
        // Deterministic pseudo-white sequence: σ from the generator; τ ≈ 1.
        let mut state = 12345u64;
        let mut next = || {
            // Box–Muller on a 64-bit LCG: independent of the code under test.
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u1 = ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u2 = ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
        };
        let n: usize = 20000;
        let x: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let h: Vec<f64> = (0..n).map(|_| 2e-6 * next()).collect();
        let m = line(&x, &h);
        let sigma = white_noise_mm(&m, &h);
        assert!((sigma / 2e-6 - 1.0).abs() < 0.05, "{sigma}");
        let tau = correlation_length(&m, &h);
        assert!(tau < 1.2, "{tau}");
        // A 5-point moving average of white noise: τ = 5 (Σ of its triangular ACF).
        let smooth: Vec<f64> = (0..n)
            .map(|i| h[i.saturating_sub(2)..(i + 3).min(n)].iter().sum::<f64>() / 5.0)
            .collect();
        let tau = correlation_length(&m, &smooth);
        assert!((tau - 5.0).abs() < 0.5, "{tau}");
    }

    #[test]
    fn zones_split_the_energy_by_radius() {
        let x: Vec<f64> = (0..1000).map(|i| i as f64 * 1e-3).collect();
        // Residual 1 in the centre zone (r < 0.0999), 0 elsewhere.
        let h: Vec<f64> = x
            .iter()
            .map(|v| if *v < 0.05 { 1e-6 } else { 0.0 })
            .collect();
        let m = line(&x, &h);
        let zones = Zones::new(m.max_radius_mm());
        let stats = zones.stats(&radii(&m, DVec2::ZERO), &h);
        assert_eq!(stats[0].name, "centre");
        assert!((stats[0].share - 1.0).abs() < 1e-12);
        assert!(
            (stats[0].rms_nm - (50f64 / 100.0).sqrt()).abs() < 1e-9,
            "{:?}",
            stats[0]
        );
    }

    #[test]
    fn azimuthal_orders_of_a_pure_coma_like_map() {
        // Residual ∝ r cos θ (order 1) on a disc: all its energy in order 1.
        let (nx, ny) = (81, 81);
        let h: Vec<f64> = (0..nx * ny)
            .map(|k| {
                let (x, y) = ((k % nx) as f64 - 40.0, (k / nx) as f64 - 40.0);
                if x.hypot(y) <= 40.0 {
                    1e-6 * x * 0.01
                } else {
                    f64::NAN
                }
            })
            .collect();
        let m = Measurement::raster(
            (nx, ny),
            DVec2::new(-0.04, -0.04),
            [1e-3, 1e-3],
            &h,
            DVec2::ZERO,
            Instrument::default(),
        );
        let orders = azimuthal_orders(&m, &m.height_mm, DVec2::ZERO);
        assert!((orders[1].1 - 1.0).abs() < 0.02, "{orders:?}");
    }
}

//! The residual folded over the tool marks: along a profile, each point's phase between
//! the two cusps of the simulated profile around it, and the residual averaged per
//! phase bin. What the marks' shape carries that the model lacks — material piled up
//! beside each cusp, a chipped or ploughing edge, spring-back — repeats mark after mark
//! and stands out of the noise once averaged over hundreds of marks, however small it
//! is against the noise of one point; a residual that is noise folds to nothing.
//!
//! The test is a one-way analysis of variance over the phase bins: the between-bin
//! sum of squares against the within-bin variance, its χ² deflated by the residual's
//! neighbour correlation (an AR(1) long-run factor), compared with χ²'s 10⁻⁶ quantile.
//! The cusps are found on the model, never on the data, so the folding cannot
//! manufacture the structure it then finds.

use super::zones::gaussian_lowpass_line;
use crate::numeric::chi2_upper_quantile;

/// Phase bins: at least this many, and at least this many points per mark per bin.
const MIN_BINS: usize = 4;
const MAX_BINS: usize = 12;
const POINTS_PER_BIN: f64 = 1.5;
/// Marks must span at least this many points for their shape to be resolved.
const MIN_POINTS_PER_MARK: f64 = 5.0;
/// At least this many whole marks to fold.
const MIN_MARKS: usize = 8;
/// The upper tail probability the fold's χ² must reach: far out, as one profile
/// folds once and a false "unexplained" sends a user looking for what is not there.
const TAIL: f64 = 1e-6;
/// A cusp is the highest point of the high-passed model within this share of a mark.
const CUSP_WINDOW: f64 = 0.4;
/// Intervals between neighbouring cusps further than this from the median are not
/// marks (a gap, the axis, a lost cusp).
const INTERVAL_RANGE: (f64, f64) = (0.5, 1.6);

/// The residual averaged over the marks' phase.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MarkShape {
    /// Whole marks folded and the points in them.
    pub marks: usize,
    pub points: usize,
    /// Mean residual per phase bin (nm), the cusp at phase 0.
    pub bins_nm: Vec<f64>,
    /// RMS of the folded shape with the noise's share taken out (nm).
    pub rms_nm: f64,
    /// RMS of the residual about its bin's mean (nm).
    pub within_nm: f64,
    /// χ² of the bin means (correlation-deflated), its degrees of freedom, and the
    /// value it must exceed to count.
    pub chi2: f64,
    pub dof: usize,
    pub threshold: f64,
    pub significant: bool,
    /// The model's own error in the marks' shape (nm RMS folded), where the diagnosis
    /// measured it (what halving the ring pitch changes); 0 where not.
    pub model_error_nm: f64,
}

/// How large a significant fold must be, against the residual's white noise, to count:
/// below it the model's marks and the data's agree to a fraction of one point's noise
/// (the independent suite's controls fold to 0.1–0.3 of it), above it a shape is
/// missing from the model (its pile-up cases fold to 0.6–1.3 of it). It must also
/// stand this many times above the model's own resolution error.
const MATERIAL: f64 = 0.3;
const ABOVE_MODEL_ERROR: f64 = 2.0;

impl MarkShape {
    /// The marks carry a shape the model lacks: the fold stands out of chance and is
    /// not a small share of one point's noise.
    pub fn unexplained(&self, white_noise_nm: f64) -> bool {
        self.significant
            && self.rms_nm >= MATERIAL * white_noise_nm
            && self.rms_nm >= ABOVE_MODEL_ERROR * self.model_error_nm
    }

    /// "averaged over 269 marks, the marks differ from the model's by 2.2 nm RMS
    /// (χ² 4140, chance stays below 37.5), most at the cusps".
    pub fn describe(&self) -> String {
        let bins = self.bins_nm.len();
        let peak = (0..bins)
            .max_by(|&a, &b| self.bins_nm[a].abs().total_cmp(&self.bins_nm[b].abs()))
            .unwrap_or(0);
        let phase = (peak as f64 + 0.5) / bins as f64;
        let sign = if self.bins_nm[peak] > 0.0 {
            "raised"
        } else {
            "lowered"
        };
        let place = if !(0.2..=0.8).contains(&phase) {
            "at the cusps"
        } else if (0.35..=0.65).contains(&phase) {
            "in the valleys"
        } else {
            "on the flanks"
        };
        let shape = if self.significant {
            format!("{sign} most {place}")
        } else {
            "no shape beyond chance".into()
        };
        format!(
            "averaged over {} marks, their shape differs from the model's by {:.2} nm RMS (χ² {:.0}; chance stays below {:.0}), {shape}",
            self.marks, self.rms_nm, self.chi2, self.threshold
        )
    }
}

/// Folds `residual_mm` over the marks of `model_mm` (both at ascending `along_mm`);
/// `None` when the marks are too few or too finely sampled to resolve.
pub fn fold(
    along_mm: &[f64],
    model_mm: &[f64],
    residual_mm: &[f64],
    period_mm: f64,
) -> Option<MarkShape> {
    let n = along_mm.len();
    if n < 16 || period_mm.is_nan() || period_mm <= 0.0 {
        return None;
    }
    let spacing = (along_mm[n - 1] - along_mm[0]) / (n - 1) as f64;
    let per_mark = period_mm / spacing;
    if per_mark.is_nan() || per_mark < MIN_POINTS_PER_MARK {
        return None;
    }
    let cutoff = 2.5 * period_mm;
    let marks_only = |v: &[f64]| -> Vec<f64> {
        let smooth = gaussian_lowpass_line(along_mm, v, cutoff);
        v.iter().zip(&smooth).map(|(a, b)| a - b).collect()
    };
    let cusps = cusps(along_mm, &marks_only(model_mm), period_mm);
    let intervals = mark_intervals(&cusps);
    if intervals.len() < MIN_MARKS {
        return None;
    }
    let bins = ((per_mark / POINTS_PER_BIN).floor() as usize).clamp(MIN_BINS, MAX_BINS);
    let phases = phase_bins(along_mm, &intervals, bins);
    anova(&marks_only(residual_mm), &phases, bins, intervals.len())
}

/// Positions (mm) of the model's cusps: its highest points within a window.
fn cusps(along_mm: &[f64], marks: &[f64], period_mm: f64) -> Vec<f64> {
    let reach = CUSP_WINDOW * period_mm;
    let mut out = Vec::new();
    let mut first = 0;
    for i in 0..along_mm.len() {
        if !marks[i].is_finite() {
            continue;
        }
        while along_mm[first] < along_mm[i] - reach {
            first += 1;
        }
        let highest = (first..along_mm.len())
            .take_while(|&j| along_mm[j] <= along_mm[i] + reach)
            .all(|j| j == i || marks[j].is_nan() || marks[j] <= marks[i]);
        let inside = along_mm[i] - along_mm[0] >= reach
            && along_mm[along_mm.len() - 1] - along_mm[i] >= reach;
        if highest && inside && out.last().is_none_or(|&c: &f64| along_mm[i] - c > reach) {
            out.push(along_mm[i]);
        }
    }
    out
}

/// Neighbouring cusps whose distance is a mark's (within range of the median).
fn mark_intervals(cusps: &[f64]) -> Vec<(f64, f64)> {
    let mut lengths: Vec<f64> = cusps.windows(2).map(|w| w[1] - w[0]).collect();
    if lengths.is_empty() {
        return Vec::new();
    }
    lengths.sort_by(f64::total_cmp);
    let median = lengths[lengths.len() / 2];
    cusps
        .windows(2)
        .filter(|w| {
            let q = (w[1] - w[0]) / median;
            q >= INTERVAL_RANGE.0 && q <= INTERVAL_RANGE.1
        })
        .map(|w| (w[0], w[1]))
        .collect()
}

/// Each point's phase bin (`None` outside every mark interval).
fn phase_bins(along_mm: &[f64], intervals: &[(f64, f64)], bins: usize) -> Vec<Option<usize>> {
    let mut k = 0;
    along_mm
        .iter()
        .map(|&x| {
            while k < intervals.len() && intervals[k].1 <= x {
                k += 1;
            }
            let (a, b) = *intervals.get(k)?;
            (x >= a).then(|| (((x - a) / (b - a) * bins as f64) as usize).min(bins - 1))
        })
        .collect()
}

/// One-way analysis of variance of `values` over the phase bins.
fn anova(values: &[f64], phases: &[Option<usize>], bins: usize, marks: usize) -> Option<MarkShape> {
    let mut sum = vec![0.0; bins];
    let mut count = vec![0usize; bins];
    for (v, p) in values.iter().zip(phases) {
        if let (Some(b), true) = (p, v.is_finite()) {
            sum[*b] += v;
            count[*b] += 1;
        }
    }
    if count.iter().any(|&c| c < 2) {
        return None;
    }
    let means: Vec<f64> = sum.iter().zip(&count).map(|(s, &c)| s / c as f64).collect();
    let points: usize = count.iter().sum();
    let grand = sum.iter().sum::<f64>() / points as f64;
    // Deviations from the bin means, in order along the line (NaN where unused).
    let deviation: Vec<f64> = values
        .iter()
        .zip(phases)
        .map(|(v, p)| {
            p.filter(|_| v.is_finite())
                .map_or(f64::NAN, |b| v - means[b])
        })
        .collect();
    let within = deviation
        .iter()
        .filter(|d| d.is_finite())
        .map(|d| d * d)
        .sum::<f64>()
        / (points - bins) as f64;
    if within.is_nan() || within <= 0.0 {
        return None;
    }
    let between: f64 = means
        .iter()
        .zip(&count)
        .map(|(m, &c)| c as f64 * (m - grand).powi(2))
        .sum();
    let dof = bins - 1;
    let chi2 = between / within / correlation_factor(&deviation);
    let threshold = chi2_upper_quantile(dof, TAIL);
    let shape_energy = (between - dof as f64 * within).max(0.0) / points as f64;
    Some(MarkShape {
        marks,
        points,
        bins_nm: means.iter().map(|m| (m - grand) * 1e6).collect(),
        rms_nm: shape_energy.sqrt() * 1e6,
        within_nm: within.sqrt() * 1e6,
        chi2,
        dof,
        threshold,
        significant: chi2 > threshold,
        model_error_nm: 0.0,
    })
}

/// An AR(1) process's long-run variance factor (1 + ρ)/(1 − ρ) from the lag-one
/// correlation of neighbouring valid values; 1 for uncorrelated or alternating ones.
fn correlation_factor(values: &[f64]) -> f64 {
    let (mut cross, mut power) = (0.0, 0.0);
    for w in values.windows(2) {
        if w[0].is_finite() && w[1].is_finite() {
            cross += w[0] * w[1];
            power += 0.5 * (w[0] * w[0] + w[1] * w[1]);
        }
    }
    let rho = if power > 0.0 {
        (cross / power).clamp(0.0, 0.9)
    } else {
        0.0
    };
    (1.0 + rho) / (1.0 - rho)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::synth::Rng;

    /// A turned profile's marks, built here: arcs of radius `nose_mm` meeting in cusps
    /// at `cusps_mm`, on a slope; sampled every `spacing_mm` over `length_mm`.
    struct Marks {
        along: Vec<f64>,
        model: Vec<f64>,
        cusps: Vec<f64>,
    }

    fn marks(length_mm: f64, spacing_mm: f64, spacing_at: impl Fn(f64) -> f64) -> Marks {
        let mut cusps = vec![0.0];
        while *cusps.last().unwrap() < length_mm {
            let c = *cusps.last().unwrap();
            cusps.push(c + spacing_at(c));
        }
        let nose_mm = 0.5;
        let along: Vec<f64> = (0..)
            .map(|i| i as f64 * spacing_mm)
            .take_while(|x| *x <= length_mm)
            .collect();
        let model = along
            .iter()
            .map(|&x| {
                let k = cusps.partition_point(|c| *c <= x) - 1;
                let mid = 0.5 * (cusps[k] + cusps[k + 1]);
                let half = 0.5 * (cusps[k + 1] - cusps[k]);
                ((x - mid).powi(2) - half * half) / (2.0 * nose_mm) + 0.01 * x
            })
            .collect();
        Marks {
            along,
            model,
            cusps,
        }
    }

    fn noise(n: usize, sigma_mm: f64, rho: f64, rng: &mut Rng) -> Vec<f64> {
        let mut last = 0.0;
        (0..n)
            .map(|_| {
                last = rho * last + (1.0 - rho * rho).sqrt() * rng.normal();
                sigma_mm * last
            })
            .collect()
    }

    /// `signal` with white noise of `sigma_mm` added.
    fn under_white_noise(signal: &[f64], sigma_mm: f64, rng: &mut Rng) -> Vec<f64> {
        noise(signal.len(), sigma_mm, 0.0, rng)
            .iter()
            .zip(signal)
            .map(|(a, b)| a + b)
            .collect()
    }

    /// A bump of `height_mm`, `width_mm` wide (Gaussian σ = width / 2), on every cusp.
    fn pile_up(m: &Marks, height_mm: f64, width_mm: f64) -> Vec<f64> {
        m.along
            .iter()
            .map(|&x| {
                let k = m.cusps.partition_point(|c| *c <= x);
                let near = [k.saturating_sub(1), k.min(m.cusps.len() - 1)]
                    .iter()
                    .map(|&j| (x - m.cusps[j]).abs())
                    .fold(f64::INFINITY, f64::min);
                height_mm * (-0.5 * (2.0 * near / width_mm).powi(2)).exp()
            })
            .collect()
    }

    #[test]
    fn noise_folds_to_nothing_white_or_correlated() {
        // 10 µm marks at 1 µm points over 1 mm: 100 marks, 10 points each. The test's
        // tail is 1e-6: in 200 profiles of white noise, and of noise correlated
        // neighbour to neighbour at 0.6, not one may count.
        let m = marks(1.0, 1e-3, |_| 0.010);
        let mut rng = Rng::new(7);
        for rho in [0.0, 0.6] {
            let alarms = (0..200)
                .filter(|_| {
                    let r = noise(m.along.len(), 2e-6, rho, &mut rng);
                    fold(&m.along, &m.model, &r, 0.010).unwrap().significant
                })
                .count();
            assert_eq!(alarms, 0, "ρ = {rho}");
        }
    }

    #[test]
    fn a_pile_up_below_the_noise_is_found_and_its_size_read() {
        // 3 nm bumps 1.5 µm wide on every cusp under 2 nm white noise: each is lost in
        // the noise of its points, the fold over 100 marks finds them all the same. Its
        // RMS is that of the bumps averaged over each phase bin: below the bump train's
        // own RMS (computed from the bumps directly), above 70 % of it here, and with the
        // noise within 25 % of the noise-free fold (three of its σ, from the bins' mean noise).
        let m = marks(1.0, 1e-3, |_| 0.010);
        let bumps = pile_up(&m, 3e-6, 1.5e-3);
        let mean = bumps.iter().sum::<f64>() / bumps.len() as f64;
        let train_nm = (bumps.iter().map(|b| (b - mean).powi(2)).sum::<f64>() / bumps.len() as f64)
            .sqrt()
            * 1e6;
        let clean = fold(&m.along, &m.model, &bumps, 0.010).unwrap().rms_nm;
        assert!(
            clean <= train_nm && clean > 0.7 * train_nm,
            "{clean} vs {train_nm}"
        );
        let mut rng = Rng::new(11);
        for _ in 0..20 {
            let r = under_white_noise(&bumps, 2e-6, &mut rng);
            let f = fold(&m.along, &m.model, &r, 0.010).unwrap();
            assert!(f.significant, "{f:?}");
            assert!(
                (f.rms_nm / clean - 1.0).abs() < 0.25,
                "{} vs {clean}",
                f.rms_nm
            );
            assert!(f.marks >= 95, "{}", f.marks);
            // The cusp's bin stands highest.
            let top = f.bins_nm.iter().cloned().fold(f64::MIN, f64::max);
            assert!(
                f.bins_nm[0] == top || f.bins_nm[f.bins_nm.len() - 1] == top,
                "{:?}",
                f.bins_nm
            );
        }
    }

    #[test]
    fn marks_whose_spacing_varies_along_the_trace_are_folded_mark_by_mark() {
        // A feed from 14 to 26 µm across 2 mm (as a program planned for even marks
        // leaves): one period folds none of it in phase, the cusps of the model do.
        let m = marks(2.0, 0.87e-3, |x| 0.014 + 0.006 * x);
        let bumps = pile_up(&m, 3e-6, 1.5e-3);
        let mut rng = Rng::new(3);
        let r = under_white_noise(&bumps, 2e-6, &mut rng);
        let f = fold(&m.along, &m.model, &r, 0.019).unwrap();
        assert!(f.significant, "{f:?}");
        let whole_marks = m.cusps.iter().filter(|c| **c < 2.0).count() - 1;
        assert!(f.marks + 3 >= whole_marks, "{} of {whole_marks}", f.marks);
    }

    #[test]
    fn marks_finer_than_the_points_resolve_are_not_folded() {
        let m = marks(1.0, 1e-3, |_| 0.004);
        let r = vec![0.0; m.along.len()];
        assert!(fold(&m.along, &m.model, &r, 0.004).is_none());
    }
}

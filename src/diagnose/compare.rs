//! The job against the measurement, before any effect is fitted: PV and RMS of each over
//! their common span with the same detrending, and the local spacing of the tool marks
//! band by band of radius (programs may vary the feed with radius, so one "dominant
//! period" would mean nothing). The fit check uses the same bands.

use super::measurement::Measurement;
use super::register::{Registered, fit_linear};
use super::zones::{pv, rms};
use crate::analysis::profile_stats::{dominant_period_mm, periodic_share};
use glam::DVec2;

/// PV and RMS of one surface (nm).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct SurfaceStats {
    pub pv_nm: f64,
    pub rms_nm: f64,
}

/// The local mark spacing in one band of radius, on one side of the axis.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SpacingBand {
    /// The band's middle radius and extent on the part (mm).
    pub radius_mm: f64,
    pub from_mm: f64,
    pub to_mm: f64,
    /// "+" or "−": the side of the axis along the profile (the file's increasing
    /// coordinate is "+").
    pub side: String,
    /// The marks' spacing as the instrument recorded it (µm, in the file's lateral
    /// units) and as the job puts it there (µm, on the part).
    pub measured_um: f64,
    pub simulated_um: f64,
    /// How many marks the band holds.
    pub marks: f64,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// The measurement and the job (with any carried effects), registered, over the
    /// points both cover, each with the same terms removed (piston, tilt, and power
    /// when registration removes it).
    pub measured: SurfaceStats,
    pub simulated: SurfaceStats,
    pub points: usize,
    pub detrended: Vec<String>,
    pub mark_spacing: Vec<SpacingBand>,
    /// Median over the bands of measured / simulated spacing.
    pub mark_spacing_ratio: Option<f64>,
}

/// Compares the registered job with the measurement (placed on the part);
/// `spacing(from, to)` is the process's own mark spacing between two radii (mm), None
/// for a process without marks.
pub fn compare(
    m: &Measurement,
    nominal: &Registered,
    power: bool,
    spacing: &dyn Fn(f64, f64) -> Option<f64>,
) -> Comparison {
    let common: Vec<usize> = (0..m.len())
        .filter(|&i| nominal.model_mm[i].is_finite())
        .collect();
    let detrend = |values: &[f64]| -> Vec<f64> {
        let points = m.subset(|i| nominal.model_mm[i].is_finite());
        let picked: Vec<f64> = common.iter().map(|&i| values[i]).collect();
        let flat = Measurement {
            height_mm: picked,
            ..points
        };
        let zero = vec![0.0; flat.len()];
        fit_linear(&flat, &zero, DVec2::ZERO, power).residual_mm
    };
    let (measured, simulated) = (detrend(&m.height_mm), detrend(&nominal.model_mm));
    let stats = |v: &[f64]| SurfaceStats {
        pv_nm: pv(v) * 1e6,
        rms_nm: rms(v) * 1e6,
    };
    let mut detrended = vec!["piston".to_string(), "tilt".to_string()];
    if power {
        detrended.push("power".into());
    }
    let mark_spacing = if m.is_line() {
        spacing_bands(m, &nominal.model_mm, spacing)
    } else {
        Vec::new()
    };
    let mut ratios: Vec<f64> = mark_spacing
        .iter()
        .map(|b| b.measured_um / b.simulated_um)
        .collect();
    ratios.sort_by(f64::total_cmp);
    Comparison {
        measured: stats(&measured),
        simulated: stats(&simulated),
        points: common.len(),
        detrended,
        mark_spacing,
        mark_spacing_ratio: (!ratios.is_empty()).then(|| ratios[ratios.len() / 2]),
    }
}

/// Marks a band must hold, and the band's width in marks.
const BAND_MARKS: f64 = 6.0;
const MIN_BAND_MARKS: f64 = 4.0;

/// The share of a band's measured variance its marks must hold (the sinusoid at the
/// found period) for the band's spacing to count: where the marks sink into the noise
/// (a stylus wider than the marks, nanometre marks under nanometres of noise) the
/// periodogram's peak is the noise's and its "spacing" anything in the search range.
/// White noise alone over n points gives about 2/n per frequency (0.06 at the fewest
/// points a band takes, 32).
const MIN_MARK_SHARE: f64 = 0.25;

/// The local mark spacing of the measurement and of the model at the same points, in
/// bands of about eight marks of radius on each side of the axis, from two marks out
/// (the centre's last revolution is special). Each band's spacing is the dominant
/// period within a factor 1.6 of the process's own spacing there, found the same way
/// in both; a band whose measured marks are lost in the noise ([`MIN_MARK_SHARE`]) is
/// left out.
fn spacing_bands(
    m: &Measurement,
    model: &[f64],
    spacing: &dyn Fn(f64, f64) -> Option<f64>,
) -> Vec<SpacingBand> {
    let mut bands = Vec::new();
    for (side, sign) in [("+", 1.0), ("−", -1.0)] {
        let on_side: Vec<usize> = (0..m.len())
            .filter(|&i| m.along_mm[i] * sign > 0.0 && model[i].is_finite())
            .collect();
        let r_max = on_side
            .iter()
            .map(|&i| m.along_mm[i].abs())
            .fold(0.0, f64::max);
        let Some(first) = spacing(0.0, 4.0 * spacing(0.0, r_max).unwrap_or(0.0)) else {
            continue;
        };
        let mut from = 2.0 * first;
        while let Some(marks_mm) = spacing(from, from + BAND_MARKS * first)
            && from + MIN_BAND_MARKS * marks_mm <= r_max
        {
            let to = (from + BAND_MARKS * marks_mm).min(r_max);
            let marks_mm = spacing(from, to).unwrap_or(marks_mm);
            // A short last band joins the one before.
            let to = if r_max - to < MIN_BAND_MARKS * marks_mm {
                r_max
            } else {
                to
            };
            let picked: Vec<usize> = on_side
                .iter()
                .copied()
                .filter(|&i| (from..=to).contains(&m.along_mm[i].abs()))
                .collect();
            if picked.len() >= 32 {
                let x: Vec<f64> = picked.iter().map(|&i| m.along_mm[i].abs()).collect();
                let order: Vec<usize> = sorted_order(&x);
                let xs: Vec<f64> = order.iter().map(|&k| x[k]).collect();
                // Each series with the band's share of the form removed.
                let series = |values: &[f64]| -> Vec<f64> {
                    let y: Vec<f64> = order.iter().map(|&k| values[picked[k]]).collect();
                    detrended_line(&xs, &y)
                };
                let (ym, ys) = (series(&m.height_mm), series(model));
                let period = |y: &[f64]| dominant_period_mm(&xs, y, marks_mm / 1.6, 1.6 * marks_mm);
                let detectable = |p: &f64| periodic_share(&xs, &ym, *p) >= MIN_MARK_SHARE;
                if let (Some(pm), Some(ps)) = (period(&ym).filter(detectable), period(&ys)) {
                    bands.push(SpacingBand {
                        radius_mm: 0.5 * (from + to),
                        from_mm: from,
                        to_mm: to,
                        side: side.into(),
                        measured_um: pm * m.file_per_mm * 1e3,
                        simulated_um: ps * 1e3,
                        marks: (to - from) / ps,
                    });
                }
            }
            from = to;
        }
    }
    bands.sort_by(|a, b| a.radius_mm.total_cmp(&b.radius_mm));
    bands
}

/// Indices that sort `x` ascending.
fn sorted_order(x: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..x.len()).collect();
    order.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
    order
}

/// `y` with its least-squares line removed (the band's share of the form).
fn detrended_line(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    x.iter()
        .zip(y)
        .map(|(a, b)| b - my - slope * (a - mx))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::measurement::Instrument;

    /// Marks whose spacing grows with radius (a program that varies its feed): each
    /// band reports the local spacing, within 1 % of the spacing laid out there.
    #[test]
    fn bands_follow_a_feed_that_varies_with_radius() {
        // Spacing f(r) = 14 µm + 12 µm · r / 0.6 mm; mark phase φ(r) = ∫ dr / f(r).
        let (f0, k) = (0.014, 0.012 / 0.6);
        let phase = |r: f64| ((f0 + k * r) / f0).ln() / k;
        let x: Vec<f64> = (0..1201).map(|i| -0.6 + i as f64 * 0.001).collect();
        let z: Vec<f64> = x
            .iter()
            .map(|s| 3e-4 * (std::f64::consts::TAU * phase(s.abs())).cos())
            .collect();
        let m = Measurement::line(&x, &z, 0.0, 0.0, Instrument::default());
        let laid_out = |from: f64, to: f64| Some(f0 + k * 0.5 * (from + to));
        let bands = spacing_bands(&m, &z, &laid_out);
        assert!(bands.len() >= 6, "{} bands", bands.len());
        for b in &bands {
            let laid = (f0 + k * b.radius_mm) * 1e3;
            assert!(
                (b.measured_um / laid - 1.0).abs() < 0.01,
                "at {:.3} mm: {:.3} µm against {laid:.3} µm",
                b.radius_mm,
                b.measured_um
            );
            assert_eq!(b.measured_um, b.simulated_um);
        }
    }

    /// Marks lost in the noise (the measurement a pseudo-random noise, the model marks
    /// every 14 µm) give no band: a spacing read from noise is not a spacing.
    #[test]
    fn marks_lost_in_the_noise_give_no_band() {
        let x: Vec<f64> = (0..1201).map(|i| -0.6 + i as f64 * 0.001).collect();
        let model: Vec<f64> = x
            .iter()
            .map(|s| 3e-4 * (std::f64::consts::TAU * s.abs() / 0.014).cos())
            .collect();
        let mut state = 7u64;
        let noise: Vec<f64> = x
            .iter()
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 1e-6
            })
            .collect();
        let m = Measurement::line(&x, &noise, 0.0, 0.0, Instrument::default());
        let laid_out = |_: f64, _: f64| Some(0.014);
        assert!(spacing_bands(&m, &model, &laid_out).is_empty());
    }
}

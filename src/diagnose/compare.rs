//! The job against the measurement, before any effect is fitted: PV and RMS of each over
//! their common span with the same detrending, and the local spacing of the tool marks
//! band by band of radius (programs may vary the feed with radius, so one "dominant
//! period" would mean nothing). The fit check uses the same bands.

use super::measurement::Measurement;
use super::register::{Registered, fit_linear};
use super::zones::{pv, rms};
use crate::analysis::profile_stats::{dominant_period_mm, periodic_share};
use crate::numeric::least_squares;
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
/// White noise alone over n points gives a share of about 2/n·E per frequency (E
/// exponential, mean 1), so the peak of the ~6 independent frequencies a band searches
/// passes s with chance ≈ 6·exp(−s·n/2): a band must also pass [`NOISE_SHARE_POINTS`]/n,
/// under 3e-4 a band, so that one among a trace's hundreds of bands rarely passes by
/// chance (a 0.25 share alone let 5 of 170 bands of 48 points through on 1 nm marks
/// under 2 nm of noise: their median "spacing" 0.75× the job's).
const MIN_MARK_SHARE: f64 = 0.25;
const NOISE_SHARE_POINTS: f64 = 20.0;
/// Of the bands with points enough, the least share whose marks must be found for any
/// to be reported: where only a few pass, the marks are not resolved and those few are
/// chance or other structure.
const MIN_BANDS_FOUND: f64 = 0.25;

/// The local mark spacing of the measurement and of the model at the same points, in
/// bands of about eight marks of radius on each side of the axis, from two marks out
/// (the centre's last revolution is special). Each band's spacing is the dominant
/// period within a factor 1.6 of the process's own spacing there, found the same way
/// in both; a band whose measured marks are lost in the noise ([`MIN_MARK_SHARE`]) is
/// left out, and none is reported where most are ([`MIN_BANDS_FOUND`]).
fn spacing_bands(
    m: &Measurement,
    model: &[f64],
    spacing: &dyn Fn(f64, f64) -> Option<f64>,
) -> Vec<SpacingBand> {
    let mut bands = Vec::new();
    let mut tried = 0usize;
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
                tried += 1;
                let x: Vec<f64> = picked.iter().map(|&i| m.along_mm[i].abs()).collect();
                let order: Vec<usize> = sorted_order(&x);
                let xs: Vec<f64> = order.iter().map(|&k| x[k]).collect();
                // Each series with the band's share of the form removed.
                let series = |values: &[f64]| -> Vec<f64> {
                    let y: Vec<f64> = order.iter().map(|&k| values[picked[k]]).collect();
                    detrended_parabola(&xs, &y)
                };
                let (ym, ys) = (series(&m.height_mm), series(model));
                let period = |y: &[f64]| dominant_period_mm(&xs, y, marks_mm / 1.6, 1.6 * marks_mm);
                let least = MIN_MARK_SHARE.max(NOISE_SHARE_POINTS / xs.len() as f64);
                let detectable = |p: &f64| periodic_share(&xs, &ym, *p) >= least;
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
    if (bands.len() as f64) < MIN_BANDS_FOUND * tried as f64 {
        return Vec::new();
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

/// `y` with its least-squares parabola removed (the band's share of the form: over a
/// band of a few marks a sphere's or asphere's curvature, left in, leaks into the
/// periodogram's longest searched periods and can outweigh nanometre marks).
fn detrended_parabola(x: &[f64], y: &[f64]) -> Vec<f64> {
    let (lo, hi) = (x[0], x[x.len() - 1]);
    let (mid, half) = (0.5 * (lo + hi), (0.5 * (hi - lo)).max(f64::MIN_POSITIVE));
    let t: Vec<f64> = x.iter().map(|a| (a - mid) / half).collect();
    let basis: Vec<Vec<f64>> = t.iter().map(|&u| vec![1.0, u, u * u]).collect();
    match least_squares(&basis, y) {
        Some(c) => y
            .iter()
            .zip(&t)
            .map(|(b, u)| b - c[0] - u * (c[1] + u * c[2]))
            .collect(),
        None => y.to_vec(),
    }
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

    /// 25 nm marks every 10 µm on an R8 sphere whose form is left in (a profile with
    /// only its power removed is still curved over a band): every band from two marks
    /// out reads the laid-out spacing within 0.5 %. With only a line removed per band
    /// the sphere's curvature outweighed the marks and all but one band was dropped.
    #[test]
    fn marks_on_a_sphere_with_its_form_left_in_give_their_spacing() {
        let (radius, feed) = (8.0, 0.010);
        let x: Vec<f64> = (0..2801).map(|i| -1.4 + i as f64 * 0.001).collect();
        let z: Vec<f64> = x
            .iter()
            .map(|s| {
                let sag = radius - (radius * radius - s * s).sqrt();
                sag + 2.5e-5 * (std::f64::consts::TAU * s.abs() / feed).cos()
            })
            .collect();
        let m = Measurement::line(&x, &z, 0.0, 0.0, Instrument::default());
        let laid_out = |_: f64, _: f64| Some(feed);
        let bands = spacing_bands(&m, &z, &laid_out);
        // Bands of six marks from 20 µm to 1.4 mm on each side.
        assert!(bands.len() >= 40, "{} bands", bands.len());
        for b in &bands {
            assert!(
                (b.measured_um / 10.0 - 1.0).abs() < 0.005,
                "at {:.3} mm: {:.3} µm",
                b.radius_mm,
                b.measured_um
            );
        }
    }

    /// 1 nm marks every 2 µm under 2 nm RMS of noise at 0.25 µm points (independent batch
    /// draw c04): ~170 bands of 48 points, none of which sees the marks. A share of 0.25
    /// alone let a few noise peaks through, whose median "spacing" was 0.75× the job's and
    /// refused the measurement as another program; now no band is reported.
    #[test]
    fn marks_under_the_noise_of_a_long_fine_trace_give_no_band() {
        let x: Vec<f64> = (0..8481).map(|i| -1.06 + i as f64 * 0.00025).collect();
        let marks = |s: &f64| 5e-7 * (std::f64::consts::TAU * s.abs() / 0.002).cos();
        let model: Vec<f64> = x.iter().map(marks).collect();
        let mut state = 11u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        // The sum of twelve uniforms: unit variance, near enough to Gaussian.
        let measured: Vec<f64> = x
            .iter()
            .map(|s| marks(s) + 2e-6 * (0..12).map(|_| uniform()).sum::<f64>())
            .collect();
        let m = Measurement::line(&x, &measured, 0.0, 0.0, Instrument::default());
        let laid_out = |_: f64, _: f64| Some(0.002);
        let bands = spacing_bands(&m, &model, &laid_out);
        assert!(bands.is_empty(), "{} bands", bands.len());
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

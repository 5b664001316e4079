//! Statistics of a 1-D surface profile as a profilometer reports them: form removed by a
//! low-order polynomial, then PV, RMS and the dominant spatial period (the scallop
//! spacing of a turned part), so simulated and measured profiles compare like for like.

use crate::numeric::least_squares;

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ProfileStats {
    pub points: usize,
    pub from_mm: f64,
    pub to_mm: f64,
    /// Peak-to-valley after form removal (nm).
    pub pv_nm: f64,
    /// RMS after form removal (nm).
    pub rms_nm: f64,
    /// Period of the strongest periodogram peak between 4 samples and a third of the span (µm).
    pub dominant_period_um: f64,
}

/// Removes a least-squares polynomial of `order` in x (0 = piston, 1 = tilt, 2 = curvature).
pub fn remove_form(x: &[f64], y: &[f64], order: usize) -> Vec<f64> {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let (mid, half) = (0.5 * (lo + hi), (0.5 * (hi - lo)).max(1e-300));
    let rows: Vec<Vec<f64>> = x
        .iter()
        .map(|v| {
            (0..=order)
                .map(|k| ((v - mid) / half).powi(k as i32))
                .collect()
        })
        .collect();
    let Some(coefficients) = least_squares(&rows, y) else {
        return y.to_vec();
    };
    rows.iter()
        .zip(y)
        .map(|(row, v)| {
            v - row
                .iter()
                .zip(&coefficients)
                .map(|(a, c)| a * c)
                .sum::<f64>()
        })
        .collect()
}

/// Power of the profile at spatial frequency `frequency` (cycles per mm): |Σ y e^{−2πifx}|².
fn power(x: &[f64], y: &[f64], frequency: f64) -> f64 {
    let (mut re, mut im) = (0.0, 0.0);
    for (xi, yi) in x.iter().zip(y) {
        let phase = std::f64::consts::TAU * frequency * xi;
        re += yi * phase.cos();
        im -= yi * phase.sin();
    }
    re * re + im * im
}

/// The period (mm) of the strongest periodogram peak between `shortest_mm` and
/// `longest_mm`: frequencies scanned on a grid four times finer than the span resolves,
/// the peak polished by a parabola. `None` when the band holds no frequency.
pub fn dominant_period_mm(x: &[f64], y: &[f64], shortest_mm: f64, longest_mm: f64) -> Option<f64> {
    let span = x.last().copied().unwrap_or(0.0) - x.first().copied().unwrap_or(0.0);
    let (f_low, f_high) = (1.0 / longest_mm.max(1e-300), 1.0 / shortest_mm.max(1e-300));
    let step = 0.25 / span.max(1e-300);
    if f_high.is_nan() || f_low.is_nan() || f_high < f_low || !step.is_finite() {
        return None;
    }
    let count = ((f_high - f_low) / step) as usize + 1;
    let powers: Vec<f64> = (0..count)
        .map(|i| power(x, y, f_low + step * i as f64))
        .collect();
    let best = powers
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    let offset = if best > 0 && best + 1 < count {
        let (a, b, c) = (powers[best - 1], powers[best], powers[best + 1]);
        let curvature = a - 2.0 * b + c;
        if curvature < 0.0 {
            0.5 * (a - c) / curvature
        } else {
            0.0
        }
    } else {
        0.0
    };
    let frequency = f_low + step * (best as f64 + offset);
    (frequency > 0.0).then(|| 1.0 / frequency)
}

/// Statistics of the profile (x, height in mm, x increasing) after removing a polynomial
/// of `form_order`.
pub fn profile_stats(x: &[f64], height: &[f64], form_order: usize) -> ProfileStats {
    let residual = remove_form(x, height, form_order);
    let (low, high) = residual
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let rms = (residual.iter().map(|v| v * v).sum::<f64>() / residual.len().max(1) as f64).sqrt();
    let span = x.last().copied().unwrap_or(0.0) - x.first().copied().unwrap_or(0.0);
    let mut steps: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let spacing = steps.get(steps.len() / 2).copied().unwrap_or(span);
    // From 3 cycles over the span to a quarter of the sampling rate.
    let period = dominant_period_mm(x, &residual, 4.0 * spacing, span / 3.0);
    ProfileStats {
        points: x.len(),
        from_mm: x.first().copied().unwrap_or(0.0),
        to_mm: x.last().copied().unwrap_or(0.0),
        pv_nm: (high - low) * 1e6,
        rms_nm: rms * 1e6,
        dominant_period_um: period.map_or(0.0, |p| p * 1e3),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sine_on_a_parabola_gives_its_period_pv_and_rms() {
        // 0.5 µm-amplitude ripple of period 41 µm on a curved, tilted form, 1 µm sampling.
        let x: Vec<f64> = (0..1000).map(|i| 0.05 + i as f64 * 0.001).collect();
        let y: Vec<f64> = x
            .iter()
            .map(|v| 0.02 * v * v - 0.003 * v + 5e-4 * (std::f64::consts::TAU * v / 0.041).sin())
            .collect();
        let stats = profile_stats(&x, &y, 2);
        assert!(
            (stats.dominant_period_um - 41.0).abs() < 0.1,
            "{}",
            stats.dominant_period_um
        );
        // PV of a sine is 2A = 1000 nm and its RMS A/√2 = 353.6 nm; over n ≈ 24 periods
        // the quadratic form fit also takes a share of the sine, ~1/(πn) ≈ 1.3 % on each
        // side of its crest, so allow 3 %.
        assert!((stats.pv_nm / 1000.0 - 1.0).abs() < 0.03, "{}", stats.pv_nm);
        assert!(
            (stats.rms_nm / 353.55 - 1.0).abs() < 0.03,
            "{}",
            stats.rms_nm
        );
    }
}

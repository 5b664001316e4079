//! The dominant spatial period of a 1-D profile (a turned part's mark spacing): the
//! periodogram's strongest peak in a band of periods.

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

/// The share of `y`'s variance (about its mean) that the least-squares sinusoid of
/// period `period_mm` holds: 1 for a pure sine, about 2/n for white noise over n points.
pub fn periodic_share(x: &[f64], y: &[f64], period_mm: f64) -> f64 {
    let n = y.len() as f64;
    let mean = y.iter().sum::<f64>() / n.max(1.0);
    let omega = std::f64::consts::TAU / period_mm;
    let (mut cc, mut ss, mut cs, mut yc, mut ys, mut yy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (xi, yi) in x.iter().zip(y) {
        let (s, c) = (omega * xi).sin_cos();
        let v = yi - mean;
        (cc, ss, cs) = (cc + c * c, ss + s * s, cs + c * s);
        (yc, ys, yy) = (yc + v * c, ys + v * s, yy + v * v);
    }
    let det = cc * ss - cs * cs;
    if !(det > 0.0 && yy > 0.0) {
        return 0.0;
    }
    let (a, b) = ((yc * ss - ys * cs) / det, (ys * cc - yc * cs) / det);
    ((a * yc + b * ys) / yy).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sine_gives_its_period() {
        // A 0.5 µm ripple of period 41 µm over 1 mm, 1 µm sampling: the peak, polished by
        // its parabola, within 0.1 µm (a 24-cycle span resolves 41 µm / 24 ≈ 1.7 µm; the
        // parabola does better).
        let x: Vec<f64> = (0..1000).map(|i| 0.05 + i as f64 * 0.001).collect();
        let y: Vec<f64> = x
            .iter()
            .map(|v| 5e-4 * (std::f64::consts::TAU * v / 0.041).sin())
            .collect();
        let period = dominant_period_mm(&x, &y, 0.02, 0.1).unwrap() * 1e3;
        assert!((period - 41.0).abs() < 0.1, "{period}");
    }

    /// A sine holds all of its variance at its period; with an equal-variance white
    /// noise added (a fixed pseudo-random sequence), half within a few 2/n.
    #[test]
    fn a_sine_holds_its_share_of_the_variance() {
        let x: Vec<f64> = (0..400).map(|i| i as f64 * 0.001).collect();
        let sine: Vec<f64> = x
            .iter()
            .map(|v| (std::f64::consts::TAU * v / 0.02).sin())
            .collect();
        assert!((periodic_share(&x, &sine, 0.02) - 1.0).abs() < 1e-12);
        let mut state = 12345u64;
        let noisy: Vec<f64> = sine
            .iter()
            .map(|s| {
                // Uniform on ±√3·(1/√2): variance ½, the sine's.
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (state >> 11) as f64 / (1u64 << 53) as f64;
                s + (2.0 * u - 1.0) * (1.5f64).sqrt()
            })
            .collect();
        let share = periodic_share(&x, &noisy, 0.02);
        assert!((share - 0.5).abs() < 0.1, "{share}");
    }
}

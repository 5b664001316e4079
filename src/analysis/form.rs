//! Form error: the deviation with the scallops filtered out, as a profilometer's form
//! measurement reports it — the azimuth-mean normal deviation along the meridian,
//! Gaussian-filtered (ISO 16610-21: weights exp(−π(x/(α λc))²), α = √(ln 2/π), so a
//! wavelength λc keeps half its amplitude) with the weights renormalised at the ends.

use crate::field::{DexelField, PolarGrid};
use rayon::prelude::*;

/// α of the ISO Gaussian profile filter.
const GAUSSIAN_ALPHA: f64 = 0.469_718_639_349_825_8;

#[derive(Debug, Clone, PartialEq)]
pub struct FormProfile {
    pub radius_mm: Vec<f64>,
    pub arc_length_mm: Vec<f64>,
    /// Filtered normal deviation with its area-weighted mean (piston) removed (mm).
    pub error_mm: Vec<f64>,
    /// The removed piston (mm).
    pub piston_mm: f64,
    pub pv_nm: f64,
    pub rms_nm: f64,
}

impl FormProfile {
    /// The form error at radius r (linear between rings, held at the ends).
    pub fn at_radius(&self, r: f64) -> f64 {
        let i = self.radius_mm.partition_point(|&x| x < r);
        if i == 0 {
            return self.error_mm[0];
        }
        if i >= self.radius_mm.len() {
            return self.error_mm[self.error_mm.len() - 1];
        }
        let t = (r - self.radius_mm[i - 1]) / (self.radius_mm[i] - self.radius_mm[i - 1]);
        self.error_mm[i - 1] + t * (self.error_mm[i] - self.error_mm[i - 1])
    }
}

/// Gaussian low-pass of evenly spaced samples (spacing `pitch`) with cutoff `cutoff`.
pub fn gaussian_filter(values: &[f64], pitch: f64, cutoff: f64) -> Vec<f64> {
    let width = GAUSSIAN_ALPHA * cutoff;
    let half = ((cutoff / pitch).ceil() as usize).max(1);
    let weights: Vec<f64> = (0..=half)
        .map(|k| (-std::f64::consts::PI * (k as f64 * pitch / width).powi(2)).exp())
        .collect();
    (0..values.len())
        .into_par_iter()
        .map(|i| {
            let (mut sum, mut total) = (0.0, 0.0);
            for (k, w) in weights.iter().enumerate() {
                for j in [i.checked_sub(k), (k > 0).then_some(i + k)]
                    .into_iter()
                    .flatten()
                {
                    if j < values.len() {
                        sum += w * values[j];
                        total += w;
                    }
                }
            }
            sum / total
        })
        .collect()
}

/// The form error of a machined field, filtered with cutoff `cutoff_mm` along the meridian.
pub fn form_error(grid: &PolarGrid, field: &DexelField, cutoff_mm: f64) -> FormProfile {
    let rings = grid.ring_count();
    let mean: Vec<f64> = (0..rings)
        .map(|i| {
            (0..grid.azimuths)
                .map(|j| field.depth_mm[grid.sample_index(i, j)])
                .sum::<f64>()
                / grid.azimuths as f64
        })
        .collect();
    let filtered = gaussian_filter(&mean, grid.pitch_mm, cutoff_mm);
    let (weight_sum, weighted) = (0..rings).fold((0.0, 0.0), |(w, s), i| {
        let a = grid.area_weight(i);
        (w + a, s + a * filtered[i])
    });
    let piston = weighted / weight_sum;
    let error_mm: Vec<f64> = filtered.iter().map(|v| v - piston).collect();
    let (lo, hi) = error_mm
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let rms = ((0..rings)
        .map(|i| grid.area_weight(i) * error_mm[i].powi(2))
        .sum::<f64>()
        / weight_sum)
        .sqrt();
    FormProfile {
        radius_mm: grid.rings.iter().map(|r| r.radius_mm).collect(),
        arc_length_mm: grid.rings.iter().map(|r| r.arc_length_mm).collect(),
        error_mm,
        piston_mm: piston,
        pv_nm: (hi - lo) * 1e6,
        rms_nm: rms * 1e6,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filter_passes_long_waves_halves_the_cutoff_and_stops_scallops() {
        let pitch = 0.001;
        let n = 20_000;
        let wave = |period: f64| -> Vec<f64> {
            (0..n)
                .map(|i| (std::f64::consts::TAU * i as f64 * pitch / period).sin())
                .collect()
        };
        let cutoff = 0.2;
        let amplitude = |period: f64| {
            let out = gaussian_filter(&wave(period), pitch, cutoff);
            // Away from the ends, the peak of the filtered sine.
            out[5000..15000].iter().fold(0.0f64, |m, v| m.max(v.abs()))
        };
        // ISO 16610-21: transmission exp(−π(αλc/λ)²): 50 % at λ = λc.
        assert!(
            (amplitude(cutoff) - 0.5).abs() < 0.01,
            "{}",
            amplitude(cutoff)
        );
        assert!(
            (amplitude(10.0 * cutoff)
                - (-std::f64::consts::PI * (GAUSSIAN_ALPHA / 10.0).powi(2)).exp())
            .abs()
                < 0.01
        );
        assert!(
            amplitude(cutoff / 20.0) < 1e-6,
            "{}",
            amplitude(cutoff / 20.0)
        );
    }
}

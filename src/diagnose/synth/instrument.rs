//! How the synthetic instrument sees a surface, written apart from the diagnosis's
//! model of the instrument (`diagnose::forward`): a stylus tip's trace as a brute-force
//! maximum over a dense sampling of the surface, and a pixel's value as the mean of the
//! surface over a lattice of points across its footprint.

use glam::DVec2;

/// The dense positions a stylus of radius `tip_mm` touches while tracing points `at_mm`
/// (increasing): the multiples of `step_mm` within `tip_mm` of any of them, increasing.
pub fn stylus_lattice(at_mm: &[f64], tip_mm: f64, step_mm: f64) -> Vec<i64> {
    let mut indices: Vec<i64> = Vec::new();
    for &s in at_mm {
        let from = ((s - tip_mm) / step_mm).floor() as i64;
        let to = ((s + tip_mm) / step_mm).ceil() as i64;
        let start = indices.last().map_or(from, |&l| from.max(l + 1));
        indices.extend(start..=to);
    }
    indices
}

/// The trace of a stylus tip of radius `tip_mm` over a surface known at points
/// (`t_mm` increasing, heights `z_mm`): at each position s of `at_mm`, the lowest tip
/// that touches no point, max over |t − s| ≤ ρ of z(t) + √(ρ² − (t − s)²), less ρ (the
/// height of the tip's lowest point). NaN where a point under the tip is (off the part).
/// Between points the surface may rise above its samples by up to (Δt/2)·|slope change|
/// at a kink, and the tip's circle by Δt²/(8ρ): the sampling error of the trace.
pub fn stylus_trace(t_mm: &[f64], z_mm: &[f64], at_mm: &[f64], tip_mm: f64) -> Vec<f64> {
    at_mm
        .iter()
        .map(|&s| {
            let from = t_mm.partition_point(|&t| t < s - tip_mm);
            let to = t_mm.partition_point(|&t| t <= s + tip_mm);
            let mut top = f64::NEG_INFINITY;
            for (t, z) in t_mm[from..to].iter().zip(&z_mm[from..to]) {
                if z.is_nan() {
                    return f64::NAN;
                }
                let d = t - s;
                top = top.max(z + ((tip_mm - d) * (tip_mm + d)).max(0.0).sqrt());
            }
            top - tip_mm
        })
        .collect()
}

/// The `n` × `n` midpoints of a square footprint of side `pixel_mm` about its centre:
/// the midpoint rule over the pixel.
pub fn footprint(pixel_mm: f64, n: usize) -> Vec<DVec2> {
    let offset = |i: usize| ((i as f64 + 0.5) / n as f64 - 0.5) * pixel_mm;
    (0..n)
        .flat_map(|j| (0..n).map(move |i| DVec2::new(offset(i), offset(j))))
        .collect()
}

/// A pixel's value: the mean of `height` over its footprint's points about `centre`.
pub fn pixel_mean(height: &dyn Fn(DVec2) -> f64, centre: DVec2, footprint: &[DVec2]) -> f64 {
    footprint.iter().map(|d| height(centre + *d)).sum::<f64>() / footprint.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lattice_covers_every_tip_window_once() {
        // Points 1 and 1.5 with a tip of 0.25 on a 0.125 lattice (exact in binary):
        // 0.75…1.25 and 1.25…1.75, merged without repeats.
        let lattice = stylus_lattice(&[1.0, 1.5], 0.25, 0.125);
        assert_eq!(lattice, (6..=14).collect::<Vec<i64>>());
    }

    #[test]
    fn a_tip_over_a_flat_traces_the_flat_and_a_hole_under_it_is_no_data() {
        let t: Vec<f64> = (0..101).map(|i| i as f64 * 0.01).collect();
        let mut z = vec![0.25; t.len()];
        let trace = stylus_trace(&t, &z, &[0.5], 0.1);
        assert!((trace[0] - 0.25).abs() < 1e-15);
        z[52] = f64::NAN;
        assert!(stylus_trace(&t, &z, &[0.5], 0.1)[0].is_nan());
    }
}

//! Generating and milling parts for synthetic data: the simulation engine's surface
//! (`pipeline::simulate`) on a grid finer than the job's, trimmed to the radii the
//! instrument needs, and read at any point of the part by this module's own
//! interpolation (the turned section model has no such counterpart for these
//! processes yet).

use crate::engine::RemovalEngine;
use crate::field::PolarGrid;
use crate::model::{Aperture, Job};
use crate::pipeline::simulate;
use glam::DVec2;
use std::f64::consts::TAU;

/// Largest grid a synthetic measurement simulates (samples).
const MAX_SAMPLES: usize = 30_000_000;

/// The machined surface on the rows of a polar grid: per row, the surface points the
/// engine found (where each sample's dexel ray meets the cut), in increasing radius.
pub struct SimulatedPart {
    rows: Vec<Row>,
}

struct Row {
    r_mm: Vec<f64>,
    z_mm: Vec<f64>,
}

impl SimulatedPart {
    /// Simulates `job` (a part of revolution) between radii `inner_mm` and `outer_mm`
    /// on rings `pitch_mm` apart and `rows` rows.
    pub fn new(
        job: &Job,
        (inner_mm, outer_mm): (f64, f64),
        pitch_mm: f64,
        rows: u32,
        engine: &mut dyn RemovalEngine,
    ) -> Result<Self, String> {
        let annulus = Aperture {
            inner_radius_mm: inner_mm.max(job.aperture.inner_radius_mm),
            outer_radius_mm: outer_mm.min(job.aperture.outer_radius_mm),
        };
        let fine = job
            .on_grid(annulus, pitch_mm, rows)
            .map_err(|e| format!("the synthetic part's fine grid: {e}"))?;
        let rings = ((fine.aperture.outer_radius_mm - fine.aperture.inner_radius_mm) / pitch_mm)
            .ceil() as usize
            + 1;
        if rings * rows as usize > MAX_SAMPLES {
            return Err(format!(
                "the measurement needs {rings} × {rows} simulated samples; allowed: at most {MAX_SAMPLES} (fewer points or pixels)"
            ));
        }
        let result = simulate(fine, engine, &|_, _| {}).map_err(|e| e.0)?;
        Ok(Self::from_field(result.grid(), &result.field.depth_mm))
    }

    /// Each sample's surface point: its nominal point moved along the normal by its depth.
    fn from_field(grid: &PolarGrid, depth_mm: &[f64]) -> Self {
        let rows = (0..grid.azimuths)
            .map(|row| {
                let mut points: Vec<(f64, f64)> = grid
                    .rings
                    .iter()
                    .enumerate()
                    .map(|(k, ring)| {
                        let p = ring.point() + depth_mm[grid.sample_index(k, row)] * ring.normal;
                        (p.x, p.y)
                    })
                    .collect();
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                Row {
                    r_mm: points.iter().map(|p| p.0).collect(),
                    z_mm: points.iter().map(|p| p.1).collect(),
                }
            })
            .collect();
        Self { rows }
    }

    /// The height at part point `p` (mm): linear along the rows, then between the two
    /// rows about its azimuth; NaN off the simulated annulus.
    pub fn height_at(&self, p: DVec2) -> f64 {
        let count = self.rows.len();
        let turn = p.y.atan2(p.x).rem_euclid(TAU) / TAU * count as f64;
        let j0 = (turn.floor() as usize) % count;
        let t = turn - turn.floor();
        let r = p.length();
        let a = self.rows[j0].at(r);
        if t < 1e-12 {
            return a;
        }
        let b = self.rows[(j0 + 1) % count].at(r);
        a + t * (b - a)
    }
}

impl Row {
    fn at(&self, r: f64) -> f64 {
        let k = self.r_mm.partition_point(|&v| v <= r);
        if k == 0 || k == self.r_mm.len() {
            let end = if k == 0 { 0 } else { self.r_mm.len() - 1 };
            return if (r - self.r_mm[end]).abs() <= 1e-12 {
                self.z_mm[end]
            } else {
                f64::NAN
            };
        }
        let (r0, r1) = (self.r_mm[k - 1], self.r_mm[k]);
        let t = if r1 > r0 { (r - r0) / (r1 - r0) } else { 0.0 };
        self.z_mm[k - 1] + t * (self.z_mm[k] - self.z_mm[k - 1])
    }
}

/// The fewest (even) rows with one along `azimuth_deg`; `None` when it is not a
/// multiple of 0.5°.
pub fn rows_along(azimuth_deg: f64) -> Option<u32> {
    let turns = azimuth_deg.rem_euclid(360.0) / 360.0;
    (2..=720u32).step_by(2).find(|&rows| {
        let at = turns * rows as f64;
        (at - at.round()).abs() < 1e-6
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_put_one_on_the_azimuth() {
        assert_eq!(rows_along(0.0), Some(2));
        assert_eq!(rows_along(90.0), Some(4));
        assert_eq!(rows_along(-45.0), Some(8));
        assert_eq!(rows_along(0.5), Some(720));
        assert_eq!(rows_along(0.25), None);
    }

    #[test]
    fn rows_interpolate_along_and_between() {
        // Two rows (azimuths 0 and π) of z = r and z = 2r: at azimuth π/2 the mean.
        let part = SimulatedPart {
            rows: vec![
                Row {
                    r_mm: vec![0.0, 1.0],
                    z_mm: vec![0.0, 1.0],
                },
                Row {
                    r_mm: vec![0.0, 1.0],
                    z_mm: vec![0.0, 2.0],
                },
            ],
        };
        assert!((part.height_at(DVec2::new(0.5, 0.0)) - 0.5).abs() < 1e-15);
        assert!((part.height_at(DVec2::new(-0.5, 0.0)) - 1.0).abs() < 1e-15);
        assert!((part.height_at(DVec2::new(0.0, 0.5)) - 0.75).abs() < 1e-15);
        assert!(part.height_at(DVec2::new(1.5, 0.0)).is_nan());
    }
}

//! A simulated part against a measured radial profile: the simulated surface along each
//! azimuth row over the measured span, both form-removed the same way, compared by
//! dominant period, PV and RMS.
//!
//! The measured x is taken as the radius (the profile runs outward from the axis); the
//! simulated deviation (along the normal) is turned into height along Z, as a
//! profilometer measures it.

use super::profile_stats::{ProfileStats, profile_stats, remove_form};
use crate::field::{DexelField, PolarGrid};

#[derive(Debug, Clone, serde::Serialize)]
pub struct ProfileComparison {
    pub measured: ProfileStats,
    /// One per azimuth row of the simulation.
    pub simulated: Vec<ProfileStats>,
    pub form_order: usize,
}

impl ProfileComparison {
    /// Mean and spread (min, max) of a statistic over the simulated rows.
    pub fn simulated_summary(&self, pick: fn(&ProfileStats) -> f64) -> (f64, f64, f64) {
        let values: Vec<f64> = self.simulated.iter().map(pick).collect();
        let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
        let (lo, hi) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        (mean, lo, hi)
    }
}

/// The simulated height profile (x = radius, height along Z, mm) of azimuth row `azimuth`
/// over [from, to].
pub fn simulated_profile(
    grid: &PolarGrid,
    field: &DexelField,
    azimuth: u32,
    from_mm: f64,
    to_mm: f64,
) -> (Vec<f64>, Vec<f64>) {
    grid.rings
        .iter()
        .enumerate()
        .filter(|(_, ring)| ring.radius_mm >= from_mm && ring.radius_mm <= to_mm)
        .map(|(i, ring)| {
            (
                ring.radius_mm,
                field.depth_mm[grid.sample_index(i, azimuth)] / ring.normal.y,
            )
        })
        .unzip()
}

pub fn compare_profiles(
    grid: &PolarGrid,
    field: &DexelField,
    measured_x_mm: &[f64],
    measured_height_mm: &[f64],
    form_order: usize,
) -> ProfileComparison {
    let (from, to) = (measured_x_mm[0], measured_x_mm[measured_x_mm.len() - 1]);
    let simulated = (0..grid.azimuths)
        .map(|j| {
            let (x, h) = simulated_profile(grid, field, j, from, to);
            profile_stats(&x, &h, form_order)
        })
        .collect();
    ProfileComparison {
        measured: profile_stats(measured_x_mm, measured_height_mm, form_order),
        simulated,
        form_order,
    }
}

/// The form-removed profile itself (for plots), in nm.
pub fn residual_nm(x: &[f64], height: &[f64], form_order: usize) -> Vec<f64> {
    remove_form(x, height, form_order)
        .iter()
        .map(|v| v * 1e6)
        .collect()
}

//! Best-fit sphere with its centre on the workpiece axis: the radius a generated part
//! actually has (for the sphere-radius error a generator's inclination leaves).

use super::Protrusion;
use crate::field::{DexelField, NO_PASS, PolarGrid};
use crate::numeric::least_squares;
use glam::DVec2;

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SphereFit {
    pub radius_mm: f64,
    /// Height of the centre on the axis.
    pub centre_z_mm: f64,
    /// RMS distance of the points from the sphere (nm).
    pub rms_residual_nm: f64,
    /// Rings used, from this radius outward.
    pub from_radius_mm: f64,
}

/// Fits ρ² + z² = 2 z·z_c + (R² − z_c²), linear in (z_c, R² − z_c²), to points in the
/// meridional half-plane (ρ, z): exact for points on a sphere centred on the axis.
pub fn fit_axial_sphere(points: &[DVec2]) -> Option<(f64, f64)> {
    // Shift heights to their mean so the two columns are not nearly collinear.
    let mean_z = points.iter().map(|p| p.y).sum::<f64>() / points.len().max(1) as f64;
    let rows: Vec<Vec<f64>> = points
        .iter()
        .map(|p| vec![2.0 * (p.y - mean_z), 1.0])
        .collect();
    let values: Vec<f64> = points
        .iter()
        .map(|p| p.x * p.x + (p.y - mean_z).powi(2))
        .collect();
    let solution = least_squares(&rows, &values)?;
    let (centre, constant) = (solution[0], solution[1]);
    let radius_squared = constant + centre * centre;
    (radius_squared > 0.0).then(|| (radius_squared.sqrt(), centre + mean_z))
}

/// The sphere through the machined surface (azimuth-mean per ring) over the rings at
/// or beyond `from_radius_mm` that the tool cut all round (an uncut sample shows the
/// stock, not the part).
pub fn fit_machined_sphere(
    grid: &PolarGrid,
    field: &DexelField,
    from_radius_mm: f64,
) -> Option<SphereFit> {
    let points: Vec<DVec2> = grid
        .rings
        .iter()
        .enumerate()
        .filter(|(i, ring)| {
            ring.radius_mm >= from_radius_mm
                && (0..grid.azimuths).all(|j| field.pass[grid.sample_index(*i, j)] != NO_PASS)
        })
        .map(|(i, ring)| {
            let mean = (0..grid.azimuths)
                .map(|j| field.depth_mm[grid.sample_index(i, j)])
                .sum::<f64>()
                / grid.azimuths as f64;
            ring.point() + mean * ring.normal
        })
        .collect();
    if points.len() < 3 {
        return None;
    }
    let (radius_mm, centre_z_mm) = fit_axial_sphere(&points)?;
    let centre = DVec2::new(0.0, centre_z_mm);
    let rms = (points
        .iter()
        .map(|p| ((*p - centre).length() - radius_mm).powi(2))
        .sum::<f64>()
        / points.len() as f64)
        .sqrt();
    Some(SphereFit {
        radius_mm,
        centre_z_mm,
        rms_residual_nm: rms * 1e6,
        from_radius_mm,
    })
}

/// The sphere fit of a machined field, outside the central feature.
pub fn part_sphere(
    grid: &PolarGrid,
    field: &DexelField,
    protrusion: &Protrusion,
) -> Option<SphereFit> {
    let outer = grid.rings[grid.ring_count() - 1].radius_mm;
    let from = (2.0 * protrusion.radius_um * 1e-3).min(0.5 * outer);
    fit_machined_sphere(grid, field, from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_sphere_from_points_on_a_shallow_cap() {
        let (radius, centre) = (53.5, 53.49);
        let points: Vec<DVec2> = (0..50)
            .map(|i| {
                let rho = 0.1 * i as f64;
                DVec2::new(rho, centre - (radius * radius - rho * rho).sqrt())
            })
            .collect();
        let (r, c) = fit_axial_sphere(&points).unwrap();
        assert!((r - radius).abs() < 1e-9, "{r}");
        assert!((c - centre).abs() < 1e-9, "{c}");
    }
}

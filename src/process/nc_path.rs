//! Turning from an NC program: its C-X-Z cutting passes as pose tables, and the nominal
//! surface the path was planned for when no design is given (the envelope of the ideal
//! tool along the path).
//!
//! Assumptions (stated because the programs do not say): the program's X/Z address the
//! tool's nose centre (or, with `NcReference::Tip`, its tip, the centre then lying one
//! nose radius above); the controller moves X, Z and C linearly within a block; the
//! spindle turns counter-clockwise seen from +Z as C increases (a program whose C
//! decreases is run with the angle negated, mirroring the part in azimuth only).

use super::pose_table::{PoseTable, ToolPose};
use crate::formats::nc::NcPass;
use crate::geometry::surface::EVEN_TERMS;
use crate::geometry::{Form, SurfaceOfRevolution};
use crate::numeric::least_squares;

/// An NC program's passes, ready to run, with what the job needs to know of them.
#[derive(Debug, Clone, PartialEq)]
pub struct NcPath {
    /// The program file, as resolved.
    pub program: std::path::PathBuf,
    pub reference: NcReference,
    /// One table per cutting pass (shifted so the nominal surface's vertex is at z = 0).
    pub tables: Vec<PoseTable>,
    pub stock_allowance_mm: f64,
    /// Largest |distance from the path's ideal envelope to the nominal surface| (mm).
    pub cut_band_mm: f64,
    /// Median radial advance per revolution.
    pub pass_spacing_mm: f64,
    /// Largest cutting-point radius (mm).
    pub outer_contact_radius_mm: f64,
}

impl NcPath {
    /// Median over revolutions of the nose centre's radial advance per revolution.
    pub fn median_radial_feed_mm(tables: &[PoseTable]) -> f64 {
        let mut feeds: Vec<f64> = tables
            .iter()
            .flat_map(|t| {
                let steps = t.steps_per_rev as usize;
                t.poses
                    .iter()
                    .zip(t.poses.iter().skip(steps))
                    .step_by(steps)
                    .map(|(a, b)| (a.x_mm - b.x_mm).abs())
            })
            .filter(|f| *f > 0.0)
            .collect();
        feeds.sort_by(f64::total_cmp);
        feeds.get(feeds.len() / 2).copied().unwrap_or(0.0)
    }
}

/// What the program's X/Z coordinates locate on the tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NcReference {
    NoseCentre,
    Tip,
}

/// One cutting pass as a pose table with evenly spaced nodes.
pub fn pass_pose_table(
    pass: &NcPass,
    reference: NcReference,
    nose_radius_mm: f64,
) -> Result<PoseTable, String> {
    let blocks = &pass.blocks;
    if blocks.len() < 2 {
        return Err(format!(
            "the cutting pass at line {} has a single block",
            blocks.first().map_or(0, |b| b.line)
        ));
    }
    let step_deg = blocks[1].c_deg - blocks[0].c_deg;
    for pair in blocks.windows(2) {
        let step = pair[1].c_deg - pair[0].c_deg;
        if (step - step_deg).abs() > 1e-6 {
            return Err(format!(
                "line {}: C steps by {step:.6}° where the pass began with {step_deg:.6}°; only evenly stepped passes are supported",
                pair[1].line
            ));
        }
    }
    let steps_per_rev = 360.0 / step_deg;
    if (steps_per_rev - steps_per_rev.round()).abs() > 1e-6 {
        return Err(format!(
            "line {}: a C step of {step_deg}° does not divide a revolution",
            blocks[1].line
        ));
    }
    let lift = match reference {
        NcReference::NoseCentre => 0.0,
        NcReference::Tip => nose_radius_mm,
    };
    Ok(PoseTable {
        start_angle_rad: blocks[0].c_deg.to_radians(),
        steps_per_rev: steps_per_rev.round() as u32,
        poses: blocks
            .iter()
            .map(|b| ToolPose {
                x_mm: b.x_mm,
                z_mm: b.z_mm + lift,
                b_rad: 0.0,
            })
            .collect(),
    })
}

/// The surface an ideal tool of `nose_radius_mm` cuts along the paths, fitted as an even
/// polynomial z(r) = Σ d_k r^{2k} (k ≤ 10) — the nominal for a program without a design.
#[derive(Debug, Clone)]
pub struct PathEnvelope {
    pub surface: SurfaceOfRevolution,
    /// Height of the surface's vertex in machine Z; poses are shifted by −this so the
    /// vertex sits at z = 0 as every nominal surface does.
    pub vertex_z_mm: f64,
    /// Largest |fit − envelope point| (nm).
    pub fit_residual_nm: f64,
    /// Cutting-point radius at the end of the first revolution (the lead-in's inner edge).
    pub finished_radius_mm: f64,
}

const POLYNOMIAL_TERMS: usize = EVEN_TERMS + 2; // r⁰, r², r⁴ … r²⁰

/// Fits an even polynomial in r/scale to (r, z) points; returns coefficients of r^{2k}.
fn fit_even(points: &[(f64, f64)], scale: f64) -> Option<Vec<f64>> {
    let rows: Vec<Vec<f64>> = points
        .iter()
        .map(|(r, _)| {
            (0..POLYNOMIAL_TERMS)
                .map(|k| (r / scale).powi(2 * k as i32))
                .collect()
        })
        .collect();
    let z: Vec<f64> = points.iter().map(|(_, z)| *z).collect();
    let scaled = least_squares(&rows, &z)?;
    Some(
        scaled
            .iter()
            .enumerate()
            .map(|(k, c)| c / scale.powi(2 * k as i32))
            .collect(),
    )
}

fn even_polynomial(coefficients: &[f64], r: f64, derivative: bool) -> f64 {
    coefficients
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let power = 2 * k as i32;
            if derivative {
                if k == 0 {
                    0.0
                } else {
                    c * power as f64 * r.powi(power - 1)
                }
            } else {
                c * r.powi(power)
            }
        })
        .sum()
}

/// The nominal surface for NC passes: fit the nose-centre path Z(X), offset it inward by
/// the nose radius along its normal, and fit the offset points.
pub fn path_envelope(tables: &[PoseTable], nose_radius_mm: f64) -> Result<PathEnvelope, String> {
    let path: Vec<(f64, f64)> = tables
        .iter()
        .flat_map(|t| t.poses.iter().map(|p| (p.x_mm, p.z_mm)))
        .filter(|(x, _)| *x >= 0.0)
        .collect();
    let scale = path.iter().fold(0.0f64, |m, (x, _)| m.max(*x));
    if path.len() < POLYNOMIAL_TERMS * 4 || scale <= 0.0 {
        return Err("the NC path has too few points on the +X side to derive its surface".into());
    }
    let centre_fit = fit_even(&path, scale).ok_or("the NC path's Z(X) cannot be fitted")?;
    let envelope: Vec<(f64, f64)> = path
        .iter()
        .map(|&(x, _)| {
            let z = even_polynomial(&centre_fit, x, false);
            let slope = even_polynomial(&centre_fit, x, true);
            let norm = (1.0 + slope * slope).sqrt();
            // Outward normal of the centre path (−Z′, 1)/|·|; the surface lies R below it.
            (x + nose_radius_mm * slope / norm, z - nose_radius_mm / norm)
        })
        .filter(|(r, _)| *r >= 0.0)
        .collect();
    let surface_fit =
        fit_even(&envelope, scale).ok_or("the NC path's envelope cannot be fitted")?;
    let fit_residual_nm = envelope
        .iter()
        .map(|&(r, z)| (even_polynomial(&surface_fit, r, false) - z).abs())
        .fold(0.0, f64::max)
        * 1e6;
    let mut even_coefficients = [0.0; EVEN_TERMS];
    even_coefficients.copy_from_slice(&surface_fit[2..]);
    // k = −1 makes the conic term exactly c r²/2: a paraboloid, so c = 2·d₁.
    let surface = SurfaceOfRevolution {
        curvature_per_mm: 2.0 * surface_fit[1],
        conic: -1.0,
        even_coefficients,
        form: Form::Concave,
    };
    let first = &tables[0];
    let after_first_revolution = first.pose_at(first.start_angle_rad + std::f64::consts::TAU);
    let finished_radius_mm = after_first_revolution.map_or(scale, |p| {
        let slope = even_polynomial(&centre_fit, p.x_mm, true);
        p.x_mm + nose_radius_mm * slope / (1.0 + slope * slope).sqrt()
    });
    Ok(PathEnvelope {
        surface,
        vertex_z_mm: surface_fit[0],
        fit_residual_nm,
        finished_radius_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::nc::{FeedMode, NcBlock};

    /// A spiral nose-centre path over a concave R = 12 mm sphere, tool R = 0.2 mm, as an
    /// NC pass in 1° steps.
    fn spiral_pass() -> NcPass {
        let (sphere, tool, feed) = (12.0, 0.2, 0.01);
        let blocks = (0..=36_000)
            .map(|i| {
                let c_deg = i as f64;
                let r = 1.0 - feed * c_deg / 360.0;
                // Centre on the concentric sphere of radius R_s − R about (0, R_s).
                let angle = (r / sphere).asin();
                NcBlock {
                    line: i + 1,
                    c_deg,
                    x_mm: (sphere - tool) * angle.sin(),
                    z_mm: sphere - (sphere - tool) * angle.cos() + 0.5,
                    feed: 1.0,
                }
            })
            .take_while(|b| b.x_mm >= 0.0)
            .collect();
        NcPass {
            blocks,
            spindle_direction: 1,
            feed_mode: FeedMode::InverseTime,
        }
    }

    #[test]
    fn the_envelope_of_a_sphere_path_is_that_sphere() {
        let table = pass_pose_table(&spiral_pass(), NcReference::NoseCentre, 0.2).unwrap();
        assert_eq!(table.steps_per_rev, 360);
        let envelope = path_envelope(&[table], 0.2).unwrap();
        // Vertex at the programmed +0.5 mm; the concave R12 sphere below it.
        assert!(
            (envelope.vertex_z_mm - 0.5).abs() < 1e-9,
            "{}",
            envelope.vertex_z_mm
        );
        let sphere = SurfaceOfRevolution::sphere(12.0, Form::Concave);
        for r in [0.0, 0.3, 0.7, 0.95] {
            let error = (envelope.surface.height(r) - sphere.height(r)).abs();
            assert!(error < 1e-9, "r = {r}: {error}");
        }
        assert!(
            envelope.fit_residual_nm < 0.01,
            "{}",
            envelope.fit_residual_nm
        );
    }

    #[test]
    fn uneven_c_steps_are_refused_with_their_line() {
        let mut pass = spiral_pass();
        pass.blocks[10].c_deg += 0.25;
        let error = pass_pose_table(&pass, NcReference::NoseCentre, 0.2).unwrap_err();
        assert!(error.contains("line 11"), "{error}");
    }
}

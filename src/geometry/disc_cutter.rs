//! A disc (side) milling cutter carrying straight-edged inserts (seed 003).
//!
//! Each insert's edge is a segment of length L through the point at radius a = d/2,
//! with direction D = (cos φ, sin φ sin λ, sin φ cos λ) along (radial, tangential,
//! axial) there: φ the lead angle of the edge from the radial direction (90° = parallel to
//! the axis) and λ the side rake that skews it tangentially. Spinning, the edge sweeps
//! the surface of revolution of a line: with t along the edge, s = t sin φ cos λ along
//! the axis and ρ² = (a + t cos φ)² + (t sin φ sin λ)², so
//! ρ²(s) = A s² + B s + a² with A = (cos²φ + sin²φ sin²λ)/(sin φ cos λ)² and
//! B = 2a cos φ/(sin φ cos λ) — a one-sheet hyperboloid. For φ = 90° it is
//! ρ² = a² + s² tan²λ, whose meridian has curvature radius a/tan²λ at the throat.
//! The cutter is the solid ρ² ≤ ρ²(s) between the edge's end planes.

use super::cutter::CutterPose;
use glam::DVec3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscCutter {
    /// Diameter at the edges' mid points (d = 2a).
    pub diameter_mm: f64,
    /// Length of each straight edge.
    pub insert_length_mm: f64,
    /// Side rake λ, [0, π/2).
    pub side_rake_rad: f64,
    /// Lead φ of the edge from the radial direction, (0, π); π/2 = parallel to the axis.
    pub lead_rad: f64,
}

impl DiscCutter {
    /// (A, B, C, s_lo, s_hi): ρ² = A s² + B s + C over s ∈ [s_lo, s_hi].
    pub fn profile(&self) -> (f64, f64, f64, f64, f64) {
        let a = 0.5 * self.diameter_mm;
        let (sin_phi, cos_phi) = self.lead_rad.sin_cos();
        let (sin_l, cos_l) = self.side_rake_rad.sin_cos();
        let axial = sin_phi * cos_l;
        let quadratic = (cos_phi * cos_phi + sin_phi * sin_phi * sin_l * sin_l) / (axial * axial);
        let linear = 2.0 * a * cos_phi / axial;
        let half = 0.5 * self.insert_length_mm * axial;
        (quadratic, linear, a * a, -half, half)
    }

    /// The cutter's largest radius (at an end of the edges).
    pub fn outer_radius_mm(&self) -> f64 {
        let (quadratic, linear, constant, lo, hi) = self.profile();
        let at = |s: f64| (quadratic * s * s + linear * s + constant).max(0.0).sqrt();
        at(lo).max(at(hi))
    }

    /// Radius of the throat (the narrowest section) and where it lies along the axis.
    pub fn throat(&self) -> (f64, f64) {
        let (quadratic, linear, constant, lo, hi) = self.profile();
        let s = if quadratic > 0.0 {
            (-0.5 * linear / quadratic).clamp(lo, hi)
        } else {
            0.0
        };
        (
            (quadratic * s * s + linear * s + constant).max(0.0).sqrt(),
            s,
        )
    }

    /// Signed distance to the solid to first order: the radial excess over the profile
    /// scaled by the profile's slope, combined with the end planes (zero on the surface).
    pub fn signed_distance_estimate(&self, pose: &CutterPose, point: DVec3) -> f64 {
        let (quadratic, linear, constant, lo, hi) = self.profile();
        let w = pose.axis.normalize_or(DVec3::Z);
        let v = point - pose.centre;
        let s = v.dot(w);
        let rho = (v - s * w).length();
        let clamped = s.clamp(lo, hi);
        let surface = (quadratic * clamped * clamped + linear * clamped + constant)
            .max(0.0)
            .sqrt();
        let slope = if surface > 0.0 {
            (2.0 * quadratic * clamped + linear) / (2.0 * surface)
        } else {
            0.0
        };
        let radial = (rho - surface) / (1.0 + slope * slope).sqrt();
        radial.max(s - hi).max(lo - s)
    }

    /// Parameters where `origin + t·dir` enters and leaves the solid, the first piece of
    /// it the ray meets: `None` on a miss. The solid is not convex (a waist), so the
    /// ray may leave and re-enter; only the first piece is returned.
    pub fn ray_interval(&self, pose: &CutterPose, origin: DVec3, dir: DVec3) -> Option<(f64, f64)> {
        let (quadratic, linear, constant, lo, hi) = self.profile();
        let w = pose.axis.normalize_or(DVec3::Z);
        let o = origin - pose.centre;
        let (s0, sd) = (o.dot(w), dir.dot(w));
        let (v0, vd) = (o - s0 * w, dir - sd * w);
        // F(t) = |v0 + t vd|² − (A s² + B s + C) ≤ 0 inside the surface of revolution.
        let qa = vd.dot(vd) - quadratic * sd * sd;
        let qb = v0.dot(vd) - quadratic * s0 * sd - 0.5 * linear * sd;
        let qc = v0.dot(v0) - quadratic * s0 * s0 - linear * s0 - constant;
        let inside = inside_pieces(qa, qb, qc);
        // The slab between the end planes.
        let slab = if sd == 0.0 {
            if (lo..=hi).contains(&s0) {
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                return None;
            }
        } else {
            let (ta, tb) = ((lo - s0) / sd, (hi - s0) / sd);
            (ta.min(tb), ta.max(tb))
        };
        inside
            .into_iter()
            .flatten()
            .map(|(a, b)| (a.max(slab.0), b.min(slab.1)))
            .filter(|(a, b)| a <= b)
            .min_by(|x, y| x.0.total_cmp(&y.0))
    }
}

/// The intervals of t where qa t² + 2 qb t + qc ≤ 0 (at most two), unbounded ends as ±∞.
fn inside_pieces(qa: f64, qb: f64, qc: f64) -> [Option<(f64, f64)>; 2] {
    const INF: f64 = f64::INFINITY;
    if qa == 0.0 {
        return match qb.partial_cmp(&0.0) {
            Some(std::cmp::Ordering::Greater) => [Some((-INF, -qc / (2.0 * qb))), None],
            Some(std::cmp::Ordering::Less) => [Some((-qc / (2.0 * qb), INF)), None],
            _ => [(qc <= 0.0).then_some((-INF, INF)), None],
        };
    }
    let discriminant = qb * qb - qa * qc;
    if discriminant < 0.0 {
        // No real roots: the sign of qa holds everywhere.
        return [(qa < 0.0).then_some((-INF, INF)), None];
    }
    // Roots without cancellation.
    let q = -(qb + qb.signum() * discriminant.sqrt());
    let (r1, r2) = if q == 0.0 {
        (0.0, 0.0)
    } else {
        let (x, y) = (q / qa, qc / q);
        (x.min(y), x.max(y))
    };
    if qa > 0.0 {
        [Some((r1, r2)), None]
    } else {
        [Some((-INF, r1)), Some((r2, INF))]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seed_003() -> DiscCutter {
        DiscCutter {
            diameter_mm: 30.0,
            insert_length_mm: 10.0,
            side_rake_rad: 19f64.to_radians(),
            lead_rad: std::f64::consts::FRAC_PI_2,
        }
    }

    #[test]
    fn the_swept_surface_is_the_hyperboloid_of_the_rotated_edge() {
        let cutter = seed_003();
        let pose = CutterPose::new(DVec3::ZERO, DVec3::Y);
        // Points of the edge itself, turned about the axis, lie on the surface: a ray from
        // far out toward the axis enters exactly there.
        let (a, lambda) = (15.0f64, 19f64.to_radians());
        for (t, turn) in [(0.0f64, 0.3f64), (2.0, 1.1), (-4.0, 2.5), (4.9, 4.0)] {
            // Edge at angle `turn`: radial (cos, 0, sin) in the x–z plane, axis y.
            let radial = DVec3::new(turn.cos(), 0.0, turn.sin());
            let tangential = DVec3::Y.cross(radial);
            let point = a * radial + t * (lambda.sin() * tangential + lambda.cos() * DVec3::Y);
            let rho = (point - point.dot(DVec3::Y) * DVec3::Y).length();
            let outward = (point - point.dot(DVec3::Y) * DVec3::Y) / rho;
            let origin = point + 5.0 * outward;
            let (entry, _) = cutter.ray_interval(&pose, origin, -outward).unwrap();
            assert!((entry - 5.0).abs() < 1e-12, "t {t}: {entry}");
        }
        // Throat radius a, outer radius at the edge ends.
        assert!((cutter.throat().0 - 15.0).abs() < 1e-12);
        let end = (225.0 + (5.0 * lambda.sin()).powi(2)).sqrt();
        assert!((cutter.outer_radius_mm() - end).abs() < 1e-12);
    }

    #[test]
    fn a_ray_along_the_axis_misses_and_one_through_the_waist_exits_and_reenters() {
        let cutter = seed_003();
        let pose = CutterPose::new(DVec3::ZERO, DVec3::Y);
        // Along the axis inside the solid: the whole slab.
        let (a, b) = cutter
            .ray_interval(&pose, DVec3::new(0.0, -20.0, 0.0), DVec3::Y)
            .unwrap();
        assert!((a - (20.0 - 5.0 * 19f64.to_radians().cos())).abs() < 1e-12 && b > a);
        // Parallel to the axis just outside the throat: enters only where the surface has
        // widened beyond it.
        let (a, _) = cutter
            .ray_interval(&pose, DVec3::new(15.001, -20.0, 0.0), DVec3::Y)
            .unwrap();
        assert!(a > 0.0 && a < 20.0);
    }
}

//! The cup (ring) wheel of a lens generator: a ring of cutting edge whose profile is a
//! circle of radius r (the edge radius) around the *cutting circle* Γ of radius R_t
//! (major radius), spinning fast about its own axis. What it sweeps while spinning is the
//! tube of radius r around Γ (a ring torus).
//!
//! Why a generator makes spheres: every point of Γ is √(R_t² + c²) from any point of
//! its axis at distance c from its centre. If the axis meets the workpiece axis Z at C
//! and Γ passes through a point V of Z (the vertex), then C, V and Γ's centre M form a
//! right angle at M with the angle α (the inclination) at C, so |CV| = R_t / sin α and
//! all of Γ lies on the sphere of that radius about C. Turning the workpiece about Z
//! (through C) keeps it there: the tube sweeps the shell between R_t/sin α − r and
//! R_t/sin α + r, and the part is left with a sphere of radius R_t/sin α + r when it lies
//! beyond the shell (concave, C on the tool side) or R_t/sin α − r inside it (convex).
//!
//! A circle that misses the axis still generates a sphere. Put its point nearest the
//! axis at (x₀, 0, z₀) with the tangent there along Y and its plane tilted by α (so its
//! centre is at (x₀ + R_t cos α, 0, z₀ + s R_t sin α), s = +1 concave, −1 convex). With
//! w = 1 − cos θ its points are (x₀ + R_t w cos α, R_t sin θ, z₀ + s R_t w sin α), and
//! since sin²θ = w(2 − w), their distance ρ from the axis and height z satisfy
//! ρ² = x₀² + 2 R_t w (x₀ cos α + R_t) − R_t² w² sin²α with z − z₀ = s R_t w sin α, i.e.
//! ρ² + (z − z₀ − s k)² = x₀² + k², k = (R_t + x₀ cos α) / sin α.
//! Seen in the meridional half-plane the circle is an arc of the circle of radius
//! √(x₀² + k²) about (0, z₀ + s k): turning the part sweeps it into a sphere, and the
//! edge's tube into the sphere of radius √(x₀² + k²) + s r, but only where the arc
//! exists, ρ ≥ |x₀|. Inside, the disc about the arc's end (|x₀|, z₀) alone cuts and
//! leaves a pip of radius ≈ |x₀| topped at z₀ − √(r² − x₀²). The sign of x₀ (short of
//! the axis or past it) changes only k, so a displaced wheel's part is indistinguishable
//! from that of the opposite displacement at another inclination: the form tells |x₀|
//! and the radius, never the side.

use glam::{DVec2, DVec3};

/// A circle in space: centre, unit axis, radius, and a unit reference direction in its
/// plane (θ = 0 points along it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CuttingCircle {
    pub centre: DVec3,
    pub axis: DVec3,
    pub radius_mm: f64,
    pub reference: DVec3,
}

impl CuttingCircle {
    /// The point at angle θ (counter-clockwise about the axis from the reference).
    pub fn point(&self, theta: f64) -> DVec3 {
        let side = self.axis.cross(self.reference);
        self.centre + self.radius_mm * (theta.cos() * self.reference + theta.sin() * side)
    }

    /// Distance from a point to the circle, and the angle of the circle's nearest point.
    pub fn distance(&self, point: DVec3) -> (f64, f64) {
        let v = point - self.centre;
        let along = v.dot(self.axis);
        let in_plane = v - along * self.axis;
        let side = self.axis.cross(self.reference);
        let theta = in_plane.dot(side).atan2(in_plane.dot(self.reference));
        let radial = in_plane.length() - self.radius_mm;
        (radial.hypot(along), theta)
    }

    /// The circle turned by `angle` about the machine Z axis (the workpiece axis).
    pub fn turned_about_z(&self, angle: f64) -> CuttingCircle {
        let turn = |v: DVec3| {
            DVec3::new(
                v.x * angle.cos() - v.y * angle.sin(),
                v.x * angle.sin() + v.y * angle.cos(),
                v.z,
            )
        };
        CuttingCircle {
            centre: turn(self.centre),
            axis: turn(self.axis),
            radius_mm: self.radius_mm,
            reference: turn(self.reference),
        }
    }

    /// The point at θ seen in a meridional half-plane of the workpiece: (distance from
    /// the Z axis, height).
    pub fn meridional_point(&self, theta: f64) -> DVec2 {
        let p = self.point(theta);
        DVec2::new(p.x.hypot(p.y), p.z)
    }
}

/// A cup wheel: cutting circle radius, edge radius, and its teeth (0 = a continuous edge,
/// such as a diamond-grit ring).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CupWheel {
    pub cutting_radius_mm: f64,
    pub edge_radius_mm: f64,
    pub teeth: u32,
}

/// The radius of the sphere a cup wheel generates at inclination α with its circle
/// through the axis (derivation in the module doc): R_t / sin α + r for a concave part,
/// − r for a convex one.
pub fn generated_sphere_radius(wheel: &CupWheel, inclination_rad: f64, concave: bool) -> f64 {
    generated_sphere(wheel, inclination_rad, concave, 0.0, wheel.edge_radius_mm).radius_mm
}

/// What a wheel whose circle passes nearest the axis at (x₀, 0, z₀) generates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeneratedSphere {
    pub radius_mm: f64,
    /// Height of the sphere's centre (on the axis).
    pub centre_z_mm: f64,
    /// Height where the sphere, extended inward, would cross the axis.
    pub vertex_z_mm: f64,
    /// Radius of the central pip: where the sphere begins, |x₀|·(1 + s r / √(x₀² + k²)).
    pub pip_radius_mm: f64,
    /// Height of the pip's top above `vertex_z_mm`.
    pub pip_height_mm: f64,
}

/// The generated sphere and pip for a circle placed as in the module doc.
pub fn generated_sphere(
    wheel: &CupWheel,
    inclination_rad: f64,
    concave: bool,
    x0_mm: f64,
    z0_mm: f64,
) -> GeneratedSphere {
    let s = if concave { 1.0 } else { -1.0 };
    let (sin, cos) = inclination_rad.sin_cos();
    let r = wheel.edge_radius_mm;
    let k = (wheel.cutting_radius_mm + x0_mm * cos) / sin;
    let arc_radius = x0_mm.hypot(k);
    let radius_mm = arc_radius + s * r;
    let centre_z_mm = z0_mm + s * k;
    let vertex_z_mm = centre_z_mm - s * radius_mm;
    // Without cancellation: z₀ − √(r² − x₀²) − vertex = [r − √(r² − x₀²)] + s(√(x₀² + k²) − k).
    let x2 = x0_mm * x0_mm;
    let pip_height_mm = x2 / (r + (r * r - x2).sqrt()) + s * x2 / (arc_radius + k);
    GeneratedSphere {
        radius_mm,
        centre_z_mm,
        vertex_z_mm,
        pip_radius_mm: x0_mm.abs() * (1.0 + s * r / arc_radius),
        pip_height_mm,
    }
}

/// The inclination that generates radius `sphere_radius_mm` (inverse of the above).
pub fn inclination_for(wheel: &CupWheel, sphere_radius_mm: f64, concave: bool) -> f64 {
    let shell = if concave {
        sphere_radius_mm - wheel.edge_radius_mm
    } else {
        sphere_radius_mm + wheel.edge_radius_mm
    };
    (wheel.cutting_radius_mm / shell).asin()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle() -> CuttingCircle {
        CuttingCircle {
            centre: DVec3::new(1.0, 2.0, 3.0),
            axis: DVec3::new(0.3, -0.2, 0.9).normalize(),
            radius_mm: 3.5,
            reference: DVec3::new(0.9, 0.0, -0.3).normalize(),
        }
        .orthonormalised()
    }

    impl CuttingCircle {
        fn orthonormalised(mut self) -> Self {
            self.reference =
                (self.reference - self.reference.dot(self.axis) * self.axis).normalize();
            self
        }
    }

    #[test]
    fn distance_to_the_circle_matches_a_brute_force_search() {
        let c = circle();
        for point in [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(4.0, 2.0, 3.5),
            DVec3::new(1.0, 2.0, 6.0),
        ] {
            let brute = (0..200_000)
                .map(|i| (c.point(i as f64 * std::f64::consts::TAU / 200_000.0) - point).length())
                .fold(f64::INFINITY, f64::min);
            let (distance, theta) = c.distance(point);
            assert!((distance - brute).abs() < 1e-9, "{distance} vs {brute}");
            assert!(((c.point(theta) - point).length() - distance).abs() < 1e-12);
        }
    }

    #[test]
    fn a_displaced_circle_lies_in_the_meridional_circle_of_the_closed_form() {
        let wheel = CupWheel {
            cutting_radius_mm: 3.5,
            edge_radius_mm: 0.5,
            teeth: 0,
        };
        for (concave, x0) in [(true, 0.02), (true, -0.03), (false, 0.01), (false, -0.02)] {
            let s: f64 = if concave { 1.0 } else { -1.0 };
            let alpha = 4f64.to_radians();
            let z0 = 0.5;
            let circle = CuttingCircle {
                centre: DVec3::new(x0 + 3.5 * alpha.cos(), 0.0, z0 + s * 3.5 * alpha.sin()),
                axis: DVec3::new(alpha.sin(), 0.0, -s * alpha.cos()),
                radius_mm: 3.5,
                reference: DVec3::new(-alpha.cos(), 0.0, -s * alpha.sin()),
            };
            let sphere = generated_sphere(&wheel, alpha, concave, x0, z0);
            let arc_radius = sphere.radius_mm - s * 0.5;
            for i in 0..20 {
                let m = circle.meridional_point(i as f64 * 0.3);
                let distance = m.x.hypot(m.y - sphere.centre_z_mm);
                assert!(
                    (distance - arc_radius).abs() < 1e-12,
                    "{distance} vs {arc_radius}"
                );
            }
        }
    }

    #[test]
    fn the_circle_through_the_vertex_lies_on_the_sphere_of_radius_rt_over_sin_alpha() {
        // Concave set-up: C at height R on the Z axis, tool axis tilted by α.
        let (rt, alpha) = (3.5f64, 3.8f64.to_radians());
        let rho = rt / alpha.sin();
        let c_point = DVec3::new(0.0, 0.0, rho);
        let axis = DVec3::new(alpha.sin(), 0.0, -alpha.cos());
        let circle = CuttingCircle {
            centre: c_point + rho * alpha.cos() * axis,
            axis,
            radius_mm: rt,
            reference: DVec3::new(-alpha.cos(), 0.0, -alpha.sin()),
        };
        assert!(
            (circle.point(0.0) - DVec3::ZERO).length() < 1e-12,
            "θ = 0 is the vertex"
        );
        for i in 0..16 {
            let p = circle.point(i as f64 * 0.39);
            assert!(((p - c_point).length() - rho).abs() < 1e-12);
        }
    }
}

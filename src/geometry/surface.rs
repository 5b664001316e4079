//! Nominal surfaces of revolution about the workpiece axis Z: plane, sphere and
//! conic + even asphere (seed 002 eq. (3)), in f64.
//!
//! Frame: the tool approaches from +Z, material lies below the surface. The
//! surface height is `z(r) = sign · sag(r)` with `sign = −1` for a convex part
//! (it bulges toward the tool) and `+1` for a concave one. The outward normal
//! (pointing out of the material, toward the tool) in the meridional (r, z)
//! half-plane is `n = (−z′, 1)/√(1 + z′²) = (sin θ, cos θ)`, where θ is the
//! signed angle of the normal from +Z (positive when it leans toward +r).

use glam::DVec2;

/// Highest even power accepted in the asphere polynomial (x²⁰), as the issue asks.
pub const MAX_EVEN_POWER: usize = 20;
/// Number of polynomial coefficients a4, a6, …, a20.
pub const EVEN_TERMS: usize = (MAX_EVEN_POWER - 4) / 2 + 1;

/// Which side of the surface faces the tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Form {
    /// Bulges toward the tool (a lens vertex up): height falls off with radius.
    Convex,
    /// Hollow toward the tool: height rises with radius.
    Concave,
}

/// A surface of revolution `z(r) = sign · sag(r)` with
/// `sag(r) = c r² / (1 + √(1 − (1+k) c² r²)) + Σ a_{2i} r^{2i}` (i = 2..10).
/// A plane is `c = 0`, a sphere `k = 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceOfRevolution {
    /// Paraxial curvature c = 1/R0 (1/mm), ≥ 0.
    pub curvature_per_mm: f64,
    /// Conic constant k.
    pub conic: f64,
    /// a4, a6, …, a20 in mm^(1−2i).
    pub even_coefficients: [f64; EVEN_TERMS],
    pub form: Form,
}

impl SurfaceOfRevolution {
    pub fn plane() -> Self {
        Self {
            curvature_per_mm: 0.0,
            conic: 0.0,
            even_coefficients: [0.0; EVEN_TERMS],
            form: Form::Convex,
        }
    }

    pub fn sphere(radius_mm: f64, form: Form) -> Self {
        Self {
            curvature_per_mm: 1.0 / radius_mm,
            conic: 0.0,
            even_coefficients: [0.0; EVEN_TERMS],
            form,
        }
    }

    pub fn asphere(
        base_radius_mm: f64,
        conic: f64,
        even_coefficients: [f64; EVEN_TERMS],
        form: Form,
    ) -> Self {
        Self {
            curvature_per_mm: 1.0 / base_radius_mm,
            conic,
            even_coefficients,
            form,
        }
    }

    /// The sign of `z` against the sag: −1 convex (height falls with radius), +1 concave.
    pub fn sign(&self) -> f64 {
        match self.form {
            Form::Convex => -1.0,
            Form::Concave => 1.0,
        }
    }

    /// `1 − (1+k) c² r²`: the conic's square-root argument; the sag exists where it is > 0.
    pub fn conic_root_argument(&self, r: f64) -> f64 {
        let c = self.curvature_per_mm;
        1.0 - (1.0 + self.conic) * c * c * r * r
    }

    /// Largest radius at which the sag is defined (infinite when it always is).
    pub fn sag_limit_radius_mm(&self) -> f64 {
        let q = (1.0 + self.conic) * self.curvature_per_mm * self.curvature_per_mm;
        if q > 0.0 {
            1.0 / q.sqrt()
        } else {
            f64::INFINITY
        }
    }

    /// Sag in mm, cancellation-free (never `R − √(R² − r²)`).
    pub fn sag(&self, r: f64) -> f64 {
        let c = self.curvature_per_mm;
        let conic_part = c * r * r / (1.0 + self.conic_root_argument(r).sqrt());
        conic_part + self.polynomial(r, 0)
    }

    /// d(sag)/dr.
    pub fn sag_slope(&self, r: f64) -> f64 {
        let c = self.curvature_per_mm;
        c * r / self.conic_root_argument(r).sqrt() + self.polynomial(r, 1)
    }

    /// d²(sag)/dr².
    pub fn sag_second_derivative(&self, r: f64) -> f64 {
        let c = self.curvature_per_mm;
        let a = self.conic_root_argument(r);
        c / (a * a.sqrt()) + self.polynomial(r, 2)
    }

    /// The `derivative`-th derivative of Σ a_{2i} r^{2i}.
    fn polynomial(&self, r: f64, derivative: u32) -> f64 {
        let mut sum = 0.0;
        for (index, &a) in self.even_coefficients.iter().enumerate() {
            if a == 0.0 {
                continue;
            }
            let power = 4 + 2 * index as i32;
            let mut factor = 1.0;
            for step in 0..derivative as i32 {
                factor *= (power - step) as f64;
            }
            sum += a * factor * r.powi(power - derivative as i32);
        }
        sum
    }

    /// Surface height z(r) in mm.
    pub fn height(&self, r: f64) -> f64 {
        self.sign() * self.sag(r)
    }

    /// dz/dr.
    pub fn slope(&self, r: f64) -> f64 {
        self.sign() * self.sag_slope(r)
    }

    /// d²z/dr².
    pub fn second_derivative(&self, r: f64) -> f64 {
        self.sign() * self.sag_second_derivative(r)
    }

    /// The point (r, z(r)) of the meridian.
    pub fn point(&self, r: f64) -> DVec2 {
        DVec2::new(r, self.height(r))
    }

    /// Unit outward normal (toward the tool) in the (r, z) half-plane.
    pub fn normal(&self, r: f64) -> DVec2 {
        let slope = self.slope(r);
        DVec2::new(-slope, 1.0) / (1.0 + slope * slope).sqrt()
    }

    /// Signed normal angle θ from +Z (rad): `n = (sin θ, cos θ)`.
    pub fn normal_angle(&self, r: f64) -> f64 {
        (-self.slope(r)).atan()
    }

    /// Meridional curvature (1/mm), positive where the surface is hollow toward the
    /// tool (a concave region a round tool must fit into).
    pub fn meridional_curvature(&self, r: f64) -> f64 {
        let slope = self.slope(r);
        self.second_derivative(r) / (1.0 + slope * slope).powf(1.5)
    }

    /// d(arc length)/dr along the meridian.
    pub fn arc_length_rate(&self, r: f64) -> f64 {
        let slope = self.slope(r);
        (1.0 + slope * slope).sqrt()
    }

    /// Signed distance from a point of the (r, z) half-plane to the meridian (+ on the
    /// tool side) and the radius of its foot point. The foot lies within the distance to
    /// the surface point at the same radius, so that interval is sampled for the nearest
    /// point (robust on steep flanks, where a plain Newton from the point's own radius
    /// wanders off), then bisection on (p − P(r))·(1, z′) = 0 polishes it.
    pub fn distance_to(&self, point: DVec2) -> (f64, f64) {
        let limit = self.sag_limit_radius_mm() * (1.0 - 1e-12);
        let r0 = point.x.clamp(0.0, limit);
        let reach = (point - self.point(r0)).length();
        let (lo, hi) = ((r0 - reach).max(0.0), (r0 + reach).min(limit));
        const SAMPLES: usize = 256;
        let at = |i: usize| lo + (hi - lo) * i as f64 / SAMPLES as f64;
        let nearest = (0..=SAMPLES)
            .min_by(|&a, &b| {
                let da = (point - self.point(at(a))).length_squared();
                let db = (point - self.point(at(b))).length_squared();
                da.total_cmp(&db)
            })
            .unwrap_or(0);
        // f(r) = (p − P(r))·(1, z′) changes sign across the foot.
        let f = |r: f64| (point.x - r) + (point.y - self.height(r)) * self.slope(r);
        let (mut a, mut b) = (
            at(nearest.saturating_sub(1)),
            at((nearest + 1).min(SAMPLES)),
        );
        let foot = if f(a) * f(b) <= 0.0 {
            for _ in 0..100 {
                let mid = 0.5 * (a + b);
                if f(a) * f(mid) <= 0.0 {
                    b = mid
                } else {
                    a = mid
                }
                if b - a < 1e-15 {
                    break;
                }
            }
            0.5 * (a + b)
        } else {
            at(nearest) // at an end of the interval (the axis): the nearest sample
        };
        ((point - self.point(foot)).dot(self.normal(foot)), foot)
    }
}

/// Meridian arc length s(r) from the axis and its inverse r(s), accurate to f64
/// round-off: a table of Gauss–Legendre integrals with Newton polishing.
#[derive(Debug, Clone)]
pub struct MeridianArcLength {
    surface: SurfaceOfRevolution,
    node_radius_mm: Vec<f64>,
    node_arc_length_mm: Vec<f64>,
}

/// 8-point Gauss–Legendre abscissae and weights on [−1, 1].
const GAUSS_LEGENDRE_8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

impl MeridianArcLength {
    /// Tabulates s(r) on [0, max_radius_mm].
    pub fn new(surface: &SurfaceOfRevolution, max_radius_mm: f64) -> Self {
        const NODES: usize = 4096;
        let mut node_radius_mm = Vec::with_capacity(NODES + 1);
        let mut node_arc_length_mm = Vec::with_capacity(NODES + 1);
        let mut s = 0.0;
        for i in 0..=NODES {
            let r = max_radius_mm * i as f64 / NODES as f64;
            if i > 0 {
                s += integrate_arc_length(surface, node_radius_mm[i - 1], r);
            }
            node_radius_mm.push(r);
            node_arc_length_mm.push(s);
        }
        Self {
            surface: surface.clone(),
            node_radius_mm,
            node_arc_length_mm,
        }
    }

    pub fn max_radius_mm(&self) -> f64 {
        *self.node_radius_mm.last().unwrap_or(&0.0)
    }

    pub fn total_mm(&self) -> f64 {
        *self.node_arc_length_mm.last().unwrap_or(&0.0)
    }

    /// s(r) for 0 ≤ r ≤ max radius.
    pub fn arc_length_at(&self, r: f64) -> f64 {
        let upper = self.node_radius_mm.partition_point(|&node| node <= r);
        let index = upper.saturating_sub(1).min(self.node_radius_mm.len() - 1);
        self.node_arc_length_mm[index]
            + integrate_arc_length(&self.surface, self.node_radius_mm[index], r)
    }

    /// r(s) for 0 ≤ s ≤ total length: table bracket, then Newton with ds/dr.
    pub fn radius_at(&self, s: f64) -> f64 {
        let upper = self.node_arc_length_mm.partition_point(|&node| node <= s);
        let index = upper
            .saturating_sub(1)
            .min(self.node_arc_length_mm.len() - 2);
        let (r0, r1) = (self.node_radius_mm[index], self.node_radius_mm[index + 1]);
        let (s0, s1) = (
            self.node_arc_length_mm[index],
            self.node_arc_length_mm[index + 1],
        );
        let mut r = r0 + (r1 - r0) * ((s - s0) / (s1 - s0)).clamp(0.0, 1.0);
        for _ in 0..6 {
            let error = s0 + integrate_arc_length(&self.surface, r0, r) - s;
            let step = error / self.surface.arc_length_rate(r);
            r = (r - step).clamp(r0, r1);
            if step.abs() < 1e-15 {
                break;
            }
        }
        r
    }
}

/// ∫ √(1 + z′²) dr from a to b, one 8-point Gauss–Legendre panel (a and b are close).
fn integrate_arc_length(surface: &SurfaceOfRevolution, a: f64, b: f64) -> f64 {
    let half = 0.5 * (b - a);
    let mid = 0.5 * (a + b);
    GAUSS_LEGENDRE_8
        .iter()
        .map(|&(x, w)| w * surface.arc_length_rate(mid + half * x))
        .sum::<f64>()
        * half
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Seed 002 eq. (3): R0 = 5.5 mm, k = −0.7, A2 (x⁴) = 0.000284, Ø20 mm, convex.
    fn seed_002_asphere() -> SurfaceOfRevolution {
        let mut coefficients = [0.0; EVEN_TERMS];
        coefficients[0] = 0.000284;
        SurfaceOfRevolution::asphere(5.5, -0.7, coefficients, Form::Convex)
    }

    /// The textbook (non cancellation-free) conic sag `(1 − √(1 − (1+k)c²r²)) / ((1+k)c)`
    /// plus the polynomial: an algebraically equal but independently computed form.
    fn textbook_sag(r: f64) -> f64 {
        let (c, k) = (1.0 / 5.5, -0.7);
        (1.0 - (1.0 - (1.0 + k) * c * c * r * r).sqrt()) / ((1.0 + k) * c) + 0.000284 * r.powi(4)
    }

    /// Fourth-order central difference of `f` at `x` with step `h`.
    fn derivative(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
        (-f(x + 2.0 * h) + 8.0 * f(x + h) - 8.0 * f(x - h) + f(x - 2.0 * h)) / (12.0 * h)
    }

    #[test]
    fn seed_002_asphere_sag_slope_and_normal_match_independent_evaluation_across_aperture() {
        let surface = seed_002_asphere();
        let mut worst = (0.0f64, 0.0f64, 0.0f64);
        // Every 10 µm over the Ø20 mm aperture, the rim included.
        for i in 0..=1000 {
            let r = 10.0 * i as f64 / 1000.0;
            let sag_error = (surface.sag(r) - textbook_sag(r)).abs();
            // Height = −sag for convex; differentiate the independent form numerically
            // (sixth order: Richardson on two fourth-order differences, so the steep rim,
            // where each derivative grows ~12×, needs no tiny step and its round-off).
            let h = 2e-4;
            let fd = |h: f64| derivative(|x| -textbook_sag(x), r, h);
            let fd_slope = (16.0 * fd(0.5 * h) - fd(h)) / 15.0;
            let slope_error = (surface.slope(r) - fd_slope).abs();
            let fd_normal = DVec2::new(-fd_slope, 1.0).normalize();
            let normal_error = (surface.normal(r) - fd_normal).length();
            worst = (
                worst.0.max(sag_error),
                worst.1.max(slope_error),
                worst.2.max(normal_error),
            );
        }
        println!(
            "seed-002 asphere: max |sag − textbook| = {:.2e} mm, max |slope − FD| = {:.2e}, max |n − n_FD| = {:.2e}",
            worst.0, worst.1, worst.2
        );
        assert!(worst.0 < 1e-9, "sag error {:.3e} mm", worst.0);
        // The slope is dimensionless: 1e-9 of slope is 1e-9 mm of height per mm of radius.
        assert!(worst.1 < 1e-9, "slope error {:.3e}", worst.1);
        assert!(worst.2 < 1e-9, "normal error {:.3e}", worst.2);
    }

    #[test]
    fn seed_002_asphere_is_steep_at_the_rim() {
        // DESIGN §1: the slope reaches ~87° at the Ø20 mm rim.
        let surface = seed_002_asphere();
        let angle_deg = surface.normal_angle(10.0).abs().to_degrees();
        assert!(
            (87.0..87.6).contains(&angle_deg),
            "rim slope {angle_deg:.3}°"
        );
        // Sag exists to r = R0/√(1+k) = 5.5/√0.3 = 10.0416 mm.
        assert!((surface.sag_limit_radius_mm() - 10.041_580).abs() < 1e-5);
    }

    #[test]
    fn second_derivative_matches_finite_difference_of_slope() {
        let surface = seed_002_asphere();
        for i in 0..=100 {
            let r = 9.9 * i as f64 / 100.0;
            let fd = derivative(|x| surface.slope(x), r, 1e-5);
            let exact = surface.second_derivative(r);
            assert!(
                (exact - fd).abs() < 1e-7 * exact.abs().max(1.0),
                "r = {r}: z″ {exact} vs FD {fd}"
            );
        }
    }

    #[test]
    fn sphere_arc_length_is_radius_times_angle() {
        // A sphere's meridian: s(r) = R asin(r/R) (closed form).
        for form in [Form::Convex, Form::Concave] {
            let surface = SurfaceOfRevolution::sphere(20.0, form);
            let table = MeridianArcLength::new(&surface, 15.0);
            for &r in &[0.0, 1.0, 7.3, 12.0, 15.0] {
                let exact = 20.0 * (r / 20.0f64).asin();
                assert!((table.arc_length_at(r) - exact).abs() < 1e-12);
                assert!((table.radius_at(exact) - r).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn asphere_arc_length_inverse_round_trips_near_the_rim() {
        let surface = seed_002_asphere();
        let table = MeridianArcLength::new(&surface, 10.0);
        for i in 0..=200 {
            let r = 10.0 * i as f64 / 200.0;
            let s = table.arc_length_at(r);
            assert!((table.radius_at(s) - r).abs() < 1e-12, "r = {r}");
        }
        // Sanity: the meridian is longer than the chord from vertex to rim.
        let chord = surface.point(10.0).length();
        assert!(table.total_mm() > chord);
    }

    #[test]
    fn distance_to_a_sphere_is_the_radial_gap() {
        // Convex R10 sphere centred at (0, −10): distance = |p − c| − 10.
        let surface = SurfaceOfRevolution::sphere(10.0, Form::Convex);
        for &(x, z) in &[(0.0, 0.3), (2.0, -0.1), (5.0, -1.2), (7.0, -2.0)] {
            let point = DVec2::new(x, z);
            let expected = (point - DVec2::new(0.0, -10.0)).length() - 10.0;
            assert!(
                (surface.distance_to(point).0 - expected).abs() < 1e-12,
                "{point}"
            );
        }
    }

    #[test]
    fn distance_to_the_steep_asphere_flank_finds_the_true_foot() {
        // A nose centre 0.5 mm off the seed-002 asphere along its normal at r = 9.7 mm
        // (slope ≈ 80°): the distance is 0.5 and the foot is 9.7.
        let surface = seed_002_asphere();
        for r in [2.0, 7.0, 9.7, 9.99] {
            let centre = surface.point(r) + 0.5 * surface.normal(r);
            let (distance, foot) = surface.distance_to(centre);
            assert!((distance - 0.5).abs() < 1e-9, "r = {r}: {distance}");
            assert!((foot - r).abs() < 1e-9, "r = {r}: foot {foot}");
        }
    }

    #[test]
    fn concave_sphere_curvature_is_positive_and_equals_one_over_radius() {
        let concave = SurfaceOfRevolution::sphere(8.0, Form::Concave);
        let convex = SurfaceOfRevolution::sphere(8.0, Form::Convex);
        for &r in &[0.0, 2.0, 5.0] {
            assert!((concave.meridional_curvature(r) - 0.125).abs() < 1e-12);
            assert!((convex.meridional_curvature(r) + 0.125).abs() < 1e-12);
        }
    }
}

//! Rotating milling cutters (ball, flat and bull-nose end mills) as exact f64 solids.
//!
//! A spinning cutter sweeps a convex solid of revolution. With `a` the axial and `ρ` the
//! radial coordinate relative to the pose centre, major radius `R` and corner radius `r`,
//! the solid is `S = {p : dist(p, Z) ≤ r} ∩ {a ≤ L}`, where `Z = {ρ ≤ R, a ≥ 0}` is a
//! half-infinite solid cylinder (the "core"). Offsetting `Z` by `r` gives exactly the
//! bull-nose profile: flat tip at `a = −r` for `ρ ≤ R`, toroidal corner (distance `r` from
//! the corner-arc-centre circle) for `−r ≤ a ≤ 0`, shank cylinder `ρ = R + r` for `a ≥ 0`.
//!
//! Ray casting: `g(t) = dist(origin + t·dir, Z)` is convex in `t` (distance to a convex set
//! along a line), so `g(t) = r` has at most two roots, the entry and the exit. We clip the
//! line to the exact analytic box of revolution (tip plane, cap plane, shank cylinder),
//! find one inside point (or prove a miss with convexity tangent bounds), then polish each
//! root on a bracket with a proven sign change by Newton's method, which is monotone and
//! cannot overshoot on a convex function, with bisection as the safeguard.

use glam::DVec3;

/// A bull-nose (toroidal) end mill; ball (`R = 0`) and flat (`r = 0`) are special cases.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cutter {
    /// `R`: radius of the circle traced by the corner-arc centre.
    pub major_radius_mm: f64,
    /// `r`: corner (minor) radius; the tip plane sits at axial coordinate `−r`.
    pub corner_radius_mm: f64,
    /// `L`: the flat top cap sits at axial coordinate `+L` (measured from the centre).
    pub length_mm: f64,
}

/// Placement of a cutter: `centre` is the centre of the corner-arc-centre circle (a ball's
/// centre), `axis` the unit vector from the tip into the shank (normalised defensively).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutterPose {
    pub centre: DVec3,
    pub axis: DVec3,
}

impl CutterPose {
    pub fn new(centre: DVec3, axis: DVec3) -> Self {
        Self { centre, axis }
    }
}

/// Default length above the centre, as a multiple of the cutter radius `R + r`.
const DEFAULT_LENGTH_PER_RADIUS: f64 = 4.0;
/// Iteration cap for the 1-D searches (each normally needs well under 60 steps).
const MAX_ITER: usize = 200;

impl Cutter {
    pub fn ball(radius_mm: f64) -> Self {
        Self::bull_nose(0.0, radius_mm)
    }

    pub fn flat(radius_mm: f64) -> Self {
        Self::bull_nose(radius_mm, 0.0)
    }

    pub fn bull_nose(major_radius_mm: f64, corner_radius_mm: f64) -> Self {
        let length_mm = DEFAULT_LENGTH_PER_RADIUS * (major_radius_mm + corner_radius_mm);
        Self {
            major_radius_mm,
            corner_radius_mm,
            length_mm,
        }
    }

    /// Outer radius `R + r` of the cutter.
    pub fn radius_mm(&self) -> f64 {
        let [big, small, _] = self.dims();
        big + small
    }

    /// `(R, r, L)` with negative or NaN values read as 0, so no input can produce NaN.
    fn dims(&self) -> [f64; 3] {
        [self.major_radius_mm, self.corner_radius_mm, self.length_mm].map(|x| x.max(0.0))
    }

    /// Radius of the profile at height `h` above the tip: `R + √(r² − (r − h)²)`, written
    /// as `R + √(h(2r − h))` to avoid cancellation. `h` is clamped to `[0, r]` (the tip
    /// disc below, the shank radius `R + r` above).
    pub fn profile_radius_at_height(&self, height_above_tip_mm: f64) -> f64 {
        let [big, small, _] = self.dims();
        let h = height_above_tip_mm.max(0.0).min(small);
        big + (h * (2.0 * small - h)).sqrt()
    }

    /// Exact signed distance from `point` to the cutter surface (negative inside).
    pub fn signed_distance(&self, pose: &CutterPose, point: DVec3) -> f64 {
        let [big, small, len] = self.dims();
        let w = pose.axis.normalize_or(DVec3::Z);
        let p = point - pose.centre;
        let a = p.dot(w);
        let rho = (p - a * w).length();
        if !(a.is_finite() && rho.is_finite()) {
            return f64::INFINITY;
        }
        let above_cap = a - len;
        if above_cap > 0.0 {
            // Nearest point is on the top cap disc of radius R + r or on its rim.
            return (rho - big - small).max(0.0).hypot(above_cap);
        }
        // Signed distance to the core Z (exact: Euclidean outside, max of faces inside);
        // offsetting a convex set by r shifts it by exactly −r. Inside, the distance to the
        // boundary of an intersection of convex sets is the max of the two signed distances.
        let core = if rho > big || a < 0.0 {
            let (radial, axial) = ((rho - big).max(0.0), a.min(0.0));
            (radial * radial + axial * axial).sqrt()
        } else {
            (rho - big).max(-a)
        };
        (core - small).max(above_cap)
    }

    /// Parameters `(t_in, t_out)` where `origin + t·dir` enters and leaves the solid, or
    /// `None` on a miss. `t` may be negative; it is in units of `|dir|` (unit expected).
    pub fn ray_interval(&self, pose: &CutterPose, origin: DVec3, dir: DVec3) -> Option<(f64, f64)> {
        let [big, small, len] = self.dims();
        let finite = origin.is_finite() && dir.is_finite() && pose.centre.is_finite();
        if !(finite && pose.axis.is_finite() && big + small > 0.0 && dir != DVec3::ZERO) {
            return None;
        }
        let ray = LocalRay::new(pose, origin, dir);
        // Exact analytic box of revolution: between the tip and cap planes, inside the shank.
        let (s0, s1) = slab(ray.a0, ray.ad, -small, len)?;
        let (c0, c1) = cylinder(ray.v0, ray.vd, big + small)?;
        let (t0, t1) = (s0.max(c0), s1.min(c1));
        if t0 > t1 {
            return None;
        }
        if small == 0.0 {
            return Some((t0, t1)); // flat end mill: the box is the solid itself
        }
        // h(t) = dist(point, core) − r: convex, ≤ 0 exactly inside the solid (within the box).
        let h = |t: f64| {
            let (g, dg) = ray.core_distance(big, t);
            (g - small, dg)
        };
        let inside = find_inside(&h, t0, t1)?;
        Some((solve(&h, t0, inside), solve(&h, t1, inside)))
    }

    /// Where `origin + t·dir` (unit `dir`) first enters the solid, as the engines need it:
    /// the analytic box's entry, then Newton's steps on the convex h(t) = dist(point,
    /// core) − r. From outside, a convex function's tangent meets zero before the root,
    /// so the steps climb to it monotonically; a tangent that does not fall toward zero,
    /// or reaches zero past the box, proves a miss. Equal to `ray_interval`'s entry
    /// (tested), without its bracketing.
    pub fn ray_entry(&self, pose: &CutterPose, origin: DVec3, dir: DVec3) -> Option<f64> {
        let [big, small, len] = self.dims();
        let ray = LocalRay::new(pose, origin, dir);
        let (s0, s1) = slab(ray.a0, ray.ad, -small, len)?;
        let (c0, c1) = cylinder(ray.v0, ray.vd, big + small)?;
        let (mut t, t1) = (s0.max(c0), s1.min(c1));
        if t > t1 || !t.is_finite() {
            return None;
        }
        if small == 0.0 {
            return Some(t);
        }
        for _ in 0..ENTRY_NEWTON_STEPS {
            let (g, dg) = ray.core_distance(big, t);
            let h = g - small;
            if h <= 0.0 {
                return Some(t);
            }
            if dg >= 0.0 {
                return None;
            }
            let step = -h / dg;
            t += step;
            if t > t1 {
                return None;
            }
            if step <= ENTRY_TOLERANCE_MM {
                return Some(t);
            }
        }
        Some(t)
    }
}

/// Newton steps the fast entry takes at most (quadratic convergence needs about five
/// from the box; grazing rays converge linearly and stop here).
pub const ENTRY_NEWTON_STEPS: usize = 32;
/// A Newton step below this ends the fast entry (mm).
pub const ENTRY_TOLERANCE_MM: f64 = 1e-13;

/// The ray in the cutter frame: axial part `a0 + t·ad`, radial part `v0 + t·vd`.
struct LocalRay {
    a0: f64,
    ad: f64,
    v0: DVec3,
    vd: DVec3,
}

impl LocalRay {
    fn new(pose: &CutterPose, origin: DVec3, dir: DVec3) -> Self {
        let w = pose.axis.normalize_or(DVec3::Z);
        let o = origin - pose.centre;
        let (a0, ad) = (o.dot(w), dir.dot(w));
        let (v0, vd) = (o - a0 * w, dir - ad * w);
        Self { a0, ad, v0, vd }
    }

    /// Distance `g` from the ray point at `t` to the core `Z = {ρ ≤ R, a ≥ 0}`, and `dg/dt`
    /// (a valid subgradient where `g` is not differentiable).
    fn core_distance(&self, big: f64, t: f64) -> (f64, f64) {
        let a = self.a0 + t * self.ad;
        let v = self.v0 + t * self.vd;
        let rho = v.length();
        // Offset from the nearest core point: radial excess beyond R, axial depth below 0.
        let (er, ea) = ((rho - big).max(0.0), a.min(0.0));
        let g = (er * er + ea * ea).sqrt();
        // dg/dt = (er·dρ/dt + ea·da/dt) / g; a term drops out where its offset is 0.
        let drho = if er > 0.0 { v.dot(self.vd) / rho } else { 0.0 };
        (g, (er * drho + ea * self.ad) / g.max(f64::MIN_POSITIVE))
    }
}

/// Parameter interval where `lo ≤ a0 + t·ad ≤ hi`.
fn slab(a0: f64, ad: f64, lo: f64, hi: f64) -> Option<(f64, f64)> {
    if ad == 0.0 {
        let inside = lo <= a0 && a0 <= hi;
        return inside.then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    let (ta, tb) = ((lo - a0) / ad, (hi - a0) / ad);
    Some((ta.min(tb), ta.max(tb)))
}

/// Parameter interval where `|v0 + t·vd| ≤ radius` (vectors perpendicular to the axis).
fn cylinder(v0: DVec3, vd: DVec3, radius: f64) -> Option<(f64, f64)> {
    let aa = vd.length_squared();
    if aa == 0.0 {
        let inside = v0.length() <= radius;
        return inside.then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    // aa·t² + 2b·t + c = 0. The discriminant b² − aa·c equals aa·(radius² − perp²) with
    // perp the line's distance from the axis, computed directly to avoid cancellation.
    let b = v0.dot(vd);
    let perp = (v0 - (b / aa) * vd).length();
    if perp > radius {
        return None;
    }
    let disc = aa * (radius - perp) * (radius + perp);
    let rho0 = v0.length();
    let c = (rho0 - radius) * (rho0 + radius);
    let q = -(b + b.signum() * disc.sqrt());
    if q == 0.0 {
        return Some((0.0, 0.0)); // tangent at t = 0
    }
    let (ta, tb) = (q / aa, c / q);
    Some((ta.min(tb), ta.max(tb)))
}

/// A parameter in `[lo, hi]` where the convex `h` is ≤ 0, or `None` if `h > 0` throughout.
/// Bisects on the sign of `h'` towards the minimum; stops early at any inside point, and
/// proves a miss once the end tangents (lower bounds by convexity) meet above zero.
fn find_inside(h: &impl Fn(f64) -> (f64, f64), mut lo: f64, mut hi: f64) -> Option<f64> {
    let (mut h_lo, mut d_lo) = h(lo);
    if h_lo <= 0.0 {
        return Some(lo);
    }
    let (mut h_hi, mut d_hi) = h(hi);
    if h_hi <= 0.0 {
        return Some(hi);
    }
    for _ in 0..MAX_ITER {
        if d_lo >= 0.0 || d_hi <= 0.0 {
            return None; // the minimum over [lo, hi] is at an end, where h > 0
        }
        let cross = (h_hi - h_lo + d_lo * lo - d_hi * hi) / (d_lo - d_hi);
        let mid = 0.5 * lo + 0.5 * hi;
        if h_lo + d_lo * (cross - lo) > 0.0 || !(lo < mid && mid < hi) {
            return None;
        }
        let (h_mid, d_mid) = h(mid);
        if h_mid <= 0.0 {
            return Some(mid);
        }
        if d_mid < 0.0 {
            (lo, h_lo, d_lo) = (mid, h_mid, d_mid);
        } else if d_mid > 0.0 {
            (hi, h_hi, d_hi) = (mid, h_mid, d_mid);
        } else {
            return None; // zero slope: the global minimum of a convex function, above 0
        }
    }
    None
}

/// The root of the convex `h` between `outer` and `inner` (with `h(inner) ≤ 0`). If
/// `h(outer) ≤ 0` the solid is entered through the analytic box and `outer` is exact.
/// Otherwise the sign change is proven and the root unique; Newton's steps from the
/// outside stay on the outside of the root, bisection takes over when one leaves the bracket.
fn solve(h: &impl Fn(f64) -> (f64, f64), mut outer: f64, mut inner: f64) -> f64 {
    let (mut hx, mut dx) = h(outer);
    if hx <= 0.0 {
        return outer;
    }
    let (mut h_outer, mut h_inner) = (hx, h(inner).0);
    let mut x = outer;
    for _ in 0..MAX_ITER {
        let newton = x - hx / dx;
        let bracketed = (newton - outer) * (newton - inner) < 0.0;
        let next = if bracketed {
            newton
        } else {
            0.5 * (outer + inner)
        };
        if next == outer || next == inner {
            break; // adjacent floats: nothing left to refine
        }
        (hx, dx) = h(next);
        x = next;
        if hx == 0.0 {
            return x;
        } else if hx > 0.0 {
            (outer, h_outer) = (x, hx);
        } else {
            (inner, h_inner) = (x, hx);
        }
    }
    if h_outer <= -h_inner { outer } else { inner }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn v(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    fn upright(centre: DVec3) -> CutterPose {
        CutterPose::new(centre, DVec3::Z)
    }

    fn cutters(dims: &[(f64, f64)]) -> Vec<Cutter> {
        dims.iter()
            .map(|&(big, small)| Cutter::bull_nose(big, small))
            .collect()
    }

    fn report(what: &str, worst: f64, tolerance: f64) {
        println!("{what}: worst error {worst:e} (tolerance {tolerance:e})");
        assert!(worst < tolerance, "{what}");
    }

    /// Entry of `origin + t·dir` (dir unit) into a sphere, by the textbook quadratic
    /// `t² + 2bt + k = 0` in the cancellation-free form (roots q and k/q).
    fn sphere_entry(centre: DVec3, radius: f64, origin: DVec3, dir: DVec3) -> f64 {
        let oc = origin - centre;
        let (b, len) = (oc.dot(dir), oc.length());
        let k = (len - radius) * (len + radius);
        let q = -(b + b.signum() * (b * b - k).sqrt());
        q.min(k / q)
    }

    /// Deterministic 64-bit LCG (Knuth's MMIX constants).
    struct Lcg(u64);
    impl Lcg {
        fn unit(&mut self) -> f64 {
            self.0 = self.0.wrapping_mul(6364136223846793005);
            self.0 = self.0.wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.unit()
        }
        fn dir(&mut self) -> DVec3 {
            loop {
                let p = DVec3::from_array(std::array::from_fn(|_| self.range(-1.0, 1.0)));
                if (0.1..=1.0).contains(&p.length()) {
                    return p.normalize();
                }
            }
        }
    }

    #[test]
    fn ball_entry_matches_textbook_quadratic() {
        let (cutter, pose) = (Cutter::ball(3.0), upright(v(1.0, -2.0, 0.5)));
        let rays = [
            (v(1.0, -2.0, -10.0), DVec3::Z),
            (v(2.0, -1.0, -6.0), v(-0.1, -0.05, 1.0)),
            (v(-4.0, -6.0, -3.0), v(1.0, 1.0, 0.8)),
            (v(8.0, 3.0, -1.0), v(-1.0, -0.7, 0.05)),
            (v(1.5, -2.5, 0.0), v(0.3, 0.2, 1.0)), // starts inside: t_in < 0
        ];
        let mut worst: f64 = 0.0;
        for (origin, dir) in rays.map(|(o, d)| (o, d.normalize())) {
            let (t_in, _) = cutter.ray_interval(&pose, origin, dir).unwrap();
            assert!((origin + t_in * dir - pose.centre).z <= 0.0, "on the ball");
            worst = worst.max((t_in - sphere_entry(pose.centre, 3.0, origin, dir)).abs());
        }
        report("ball vs quadratic", worst, 1e-12);
    }

    #[test]
    fn tilted_axis_equals_rotated_ray() {
        // Rotating the pose and the ray by the same Q must give identical parameters.
        let rot = DQuat::from_axis_angle(v(1.0, 2.0, 0.5).normalize(), 0.7);
        let centre = v(0.4, -1.3, 2.2);
        let tilted = CutterPose::new(centre, rot * DVec3::Z);
        let (mut rng, mut worst) = (Lcg(7), 0.0_f64);
        for cutter in cutters(&[(0.0, 2.0), (2.0, 1.5), (2.5, 0.0)]) {
            for _ in 0..200 {
                let local = 6.0 * rng.dir() * rng.unit();
                let dir = (3.0 * rng.dir() * rng.unit() - local).normalize();
                let a = cutter.ray_interval(&upright(centre), centre + local, dir);
                let b = cutter.ray_interval(&tilted, centre + rot * local, rot * dir);
                assert_eq!(a.is_some(), b.is_some());
                if let (Some(a), Some(b)) = (a, b) {
                    worst = worst.max((a.0 - b.0).abs()).max((a.1 - b.1).abs());
                }
            }
        }
        report("tilted vs rotated", worst, 1e-12);
    }

    #[test]
    fn vertical_rays_follow_the_bull_nose_profile() {
        // Ray parallel to the axis at radial offset ρ: entry height above the tip is 0 on
        // the flat (ρ < R), r − √(r² − (ρ − R)²) on the corner; the exit is the top cap.
        let (big, small) = (2.0, 1.0);
        let (cutter, pose) = (Cutter::bull_nose(big, small), upright(v(0.3, -0.2, 1.0)));
        let tip = pose.centre.z - small;
        let (mut worst, mut worst_rim): (f64, f64) = (0.0, 0.0);
        for i in 0..=340 {
            let (rho, theta) = (i as f64 * 0.01, i as f64 * 0.37);
            let origin = pose.centre + v(rho * theta.cos(), rho * theta.sin(), -5.0);
            let hit = cutter.ray_interval(&pose, origin, DVec3::Z);
            if rho > big + small {
                assert!(hit.is_none(), "ρ = {rho} must miss, shank included");
                continue;
            }
            let (t_in, t_out) = hit.unwrap();
            let height = origin.z + t_in - tip;
            let corner = small - (small * small - (rho - big).powi(2)).sqrt();
            let expected = if rho < big { 0.0 } else { corner };
            assert!(height >= expected - 1e-7, "never enters below the profile");
            // Past ρ − R = 0.99 r the wall is near vertical: the height is ill-conditioned.
            let slot = if rho - big <= 0.99 * small {
                &mut worst
            } else {
                &mut worst_rim
            };
            *slot = slot.max((height - expected).abs());
            assert!((origin.z + t_out - (pose.centre.z + cutter.length_mm)).abs() < 1e-12);
        }
        report("vertical rays", worst, 1e-12);
        report("vertical rays at the rim", worst_rim, 1e-7);
    }

    #[test]
    fn horizontal_ray_enters_at_profile_radius() {
        let (cutter, pose) = (Cutter::bull_nose(1.5, 2.0), upright(v(-0.7, 0.9, 3.0)));
        let mut worst: f64 = 0.0;
        for height in [1e-4, 0.01, 0.3, 1.0, 1.7, 2.0, 2.5, 7.0] {
            let origin = pose.centre + v(-10.0, 0.0, height - 2.0);
            let (t_in, _) = cutter.ray_interval(&pose, origin, DVec3::X).unwrap();
            let radius = pose.centre.x - (origin.x + t_in);
            worst = worst.max((radius - cutter.profile_radius_at_height(height)).abs());
        }
        report("horizontal rays", worst, 1e-12);
    }

    #[test]
    fn tilted_flat_end_mill_bottom_matches_plane_intersection() {
        let (cutter, centre) = (Cutter::flat(4.0), v(1.0, 2.0, 3.0));
        let mut worst: f64 = 0.0;
        for lambda in [0.05_f64, 0.3, 0.7, 1.2] {
            let pose = CutterPose::new(centre, v(lambda.sin(), 0.0, lambda.cos()));
            let e1 = v(lambda.cos(), 0.0, -lambda.sin()); // in the bottom plane
            for (s, t) in [(0.0, 0.0), (3.5, 0.0), (-2.0, 3.0), (1.0, -3.8)] {
                let origin = centre + s * e1 + t * DVec3::Y - 7.0 * DVec3::Z;
                // Plane (p − c)·w = 0 met by origin + t·z at t = (c − o)·w / (z·w).
                let expected = (centre - origin).dot(pose.axis) / pose.axis.z;
                let (t_in, _) = cutter.ray_interval(&pose, origin, DVec3::Z).unwrap();
                worst = worst.max((t_in - expected).abs());
            }
        }
        report("tilted flat", worst, 1e-12);
    }

    #[test]
    fn random_rays_agree_with_signed_distance() {
        let mut rng = Lcg(2024);
        let mut all = cutters(&[(0.0, 2.5), (3.0, 0.0), (2.0, 1.0), (0.5, 3.0), (3.0, 1e-3)]);
        all.push(Cutter {
            length_mm: 0.2,
            ..all[2]
        });
        let (mut hits, mut misses, mut worst): (usize, usize, f64) = (0, 0, 0.0);
        for cutter in all {
            for _ in 0..1500 {
                let pose = CutterPose::new(v(rng.range(-5.0, 5.0), 0.3, 1.0), rng.dir());
                let origin = pose.centre + 8.0 * rng.dir();
                let aim = pose.centre + pose.axis * rng.range(-4.0, 2.0) + 3.0 * rng.dir();
                let anywhere = origin + rng.dir();
                let target = if rng.unit() < 0.5 { aim } else { anywhere };
                let dir = (target - origin).normalize();
                let sd = |t: f64| cutter.signed_distance(&pose, origin + t * dir);
                let mut samples = (0..=200).map(|i| -30.0 + 0.3 * i as f64);
                let Some((t_in, t_out)) = cutter.ray_interval(&pose, origin, dir) else {
                    misses += 1;
                    assert!(samples.all(|t| sd(t) > -1e-9));
                    continue;
                };
                hits += 1;
                assert!(t_in <= t_out);
                worst = worst.max(sd(t_in).abs()).max(sd(t_out).abs());
                assert!(t_out - t_in < 1e-6 || sd(0.5 * (t_in + t_out)) < 0.0);
                let outside = |t: f64| t < t_in || t > t_out;
                assert!(samples.all(|t| outside(t) == (sd(t) > 0.0) || sd(t).abs() < 1e-9));
            }
        }
        println!("random rays: {hits} hits, {misses} misses");
        assert!(hits > 3000 && misses > 1500);
        report(
            "random rays |signed distance| at entry and exit",
            worst,
            1e-9,
        );
    }

    #[test]
    fn micrometre_entries_far_from_the_origin_of_coordinates() {
        // 5 mm tools centred at (20, 0, 15); rays start 1 µm outside the surface.
        let (centre, eps) = (v(20.0, 0.0, 15.0), 1e-6);
        let mut worst: f64 = 0.0;
        // Tilted bull-nose: a ray along the inward corner normal passes through the corner-
        // arc centre q and, by convexity, enters at the foot point: t_in = |o − q| − r.
        let (big, small) = (3.0, 2.0);
        let cutter = Cutter::bull_nose(big, small);
        let rot = DQuat::from_axis_angle(v(0.3, -1.0, 0.2).normalize(), 0.4);
        let pose = CutterPose::new(centre, rot * DVec3::Z);
        for i in 0..40 {
            let (phi, theta) = (0.7 * i as f64, 0.04 * i as f64); // theta from the tip direction
            let radial = rot * v(phi.cos(), phi.sin(), 0.0);
            let q = centre + big * radial;
            let normal = theta.sin() * radial - theta.cos() * pose.axis;
            let origin = q + (small + eps) * normal;
            let (t_in, _) = cutter.ray_interval(&pose, origin, -normal).unwrap();
            worst = worst.max((t_in - ((origin - q).length() - small)).abs());
        }
        // Same cutter upright, vertical ray at ρ on the corner: entry height from the profile.
        let upright_pose = upright(centre);
        for rho in [3.0, 3.5, 4.0, 4.5, 4.9] {
            let z_entry = centre.z - (small * small - (rho - big) * (rho - big)).sqrt();
            let origin = v(centre.x + rho, 0.0, z_entry - eps);
            let (t_in, _) = cutter
                .ray_interval(&upright_pose, origin, DVec3::Z)
                .unwrap();
            worst = worst.max((t_in - (z_entry - origin.z)).abs());
        }
        // Ball of radius 5, oblique rays entering the lower hemisphere.
        let (ball, mut rng) = (Cutter::ball(5.0), Lcg(99));
        for _ in 0..40 {
            let m = v(rng.range(-0.6, 0.6), rng.range(-0.6, 0.6), -1.0).normalize();
            let dir = (-m + 0.6 * rng.dir()).normalize();
            let origin = centre + 5.0 * m - eps * dir;
            let (t_in, _) = ball.ray_interval(&upright_pose, origin, dir).unwrap();
            worst = worst.max((t_in - sphere_entry(centre, 5.0, origin, dir)).abs());
        }
        report("micrometre entries", worst, 1e-12);
    }

    #[test]
    fn degenerate_inputs_and_hand_signed_distances() {
        let centre = v(0.0, 0.0, 2.0);
        let (pose, bad_pose) = (upright(centre), CutterPose::new(centre, DVec3::ZERO));
        for cutter in cutters(&[(0.0, 1.0), (1.0, 0.0), (1.0, 0.5), (0.0, 0.0)]) {
            let (big, small) = (cutter.major_radius_mm, cutter.corner_radius_mm);
            let entry = |o, d| cutter.ray_interval(&pose, o, d).map(|(t, _)| t);
            let (along, across) = (
                entry(DVec3::ZERO, DVec3::Z),
                entry(v(-5.0, 0.0, 2.0), DVec3::X),
            );
            if big + small == 0.0 {
                assert!(
                    along.is_none() && across.is_none(),
                    "a zero-size cutter never cuts"
                );
                continue;
            }
            // Along the axis: enters at the tip. Through the axis at a = 0: at radius R + r.
            assert!((along.unwrap() - (2.0 - small)).abs() < 1e-12);
            assert!((across.unwrap() - (5.0 - big - small)).abs() < 1e-12);
            // Grazing: tip plane, shank tangent, vertical along the shank, rim of the cap.
            for (o, d) in [
                (v(-5.0, 0.3, 2.0 - small), DVec3::X),
                (v(-5.0, big + small, 2.5), DVec3::X),
                (v(big + small, 0.0, -3.0), DVec3::Z),
                (v(-5.0, 0.0, 2.0 + cutter.length_mm), DVec3::X),
            ] {
                let interval = cutter.ray_interval(&pose, o, d);
                assert!(interval.is_none_or(|(a, b)| a.is_finite() && b.is_finite() && a <= b));
            }
            assert_eq!(entry(DVec3::ZERO, DVec3::ZERO), None);
            assert_eq!(entry(DVec3::NAN, DVec3::Z), None);
            assert!(
                cutter
                    .ray_interval(&bad_pose, DVec3::ZERO, DVec3::Z)
                    .is_some()
            );
            assert!(!cutter.signed_distance(&bad_pose, DVec3::ONE).is_nan());
        }
        let nan_ball = Cutter::ball(f64::NAN);
        assert!(!nan_ball.signed_distance(&pose, DVec3::ONE).is_nan());
        // By hand for R = 2, r = 1, L = 12 (corner-arc circle at ρ = 2, a = 0).
        let bull = Cutter::bull_nose(2.0, 1.0);
        assert_eq!(bull.profile_radius_at_height(-1.0), 2.0);
        for (p, expected) in [
            (v(0.0, 0.0, -0.5), -0.5),         // nearest: the tip plane a = −1
            (v(0.0, 0.0, 5.0), -3.0),          // nearest: the shank side ρ = 3
            (v(0.0, 4.0, -1.5), 1.5),          // |(4, −1.5) − (2, 0)| − r
            (v(0.5, 0.0, 14.0), 2.0),          // above the cap a = 12
            (v(5.0, 0.0, 14.0), 8_f64.sqrt()), // to the cap rim (ρ, a) = (3, 12)
        ] {
            let sd = bull.signed_distance(&pose, centre + p);
            assert!((sd - expected).abs() < 1e-14, "{p}: {sd} vs {expected}");
        }
    }
}

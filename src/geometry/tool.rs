//! The arc-nosed turning tool: a cutting edge of nose radius R spanning ±(included
//! angle)/2 about the tool's tip direction, lying in its rake plane, with a flank below
//! it that recedes at the clearance angle.
//!
//! The real edge may depart from the nominal arc by a radius error e and a radial
//! deviation w(ψ) (waviness, or a measured profile), ψ being the angle from the tip.
//! The machine knows where the tip is (tools are set by touching off their tip), so the
//! real arc's centre sits δ₀ = e + w(0) behind the nominal one along the tool axis and
//! the tip point stays where the path puts it.
//!
//! `EdgeModel::entry` is the f64 twin of `edge_entry` in `shaders/turning.wgsl`; keep the
//! two in step (the GPU-vs-CPU tests compare them on whole jobs).

use glam::DVec2;

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ArcNoseTool {
    pub nose_radius_mm: f64,
    /// Angle subtended by the edge arc; the edge spans ±half of it about the tip direction.
    pub included_angle_deg: f64,
    /// Angle by which the flank under the edge recedes behind the rake face.
    pub clearance_angle_deg: f64,
}

impl ArcNoseTool {
    pub fn half_span_rad(&self) -> f64 {
        0.5 * self.included_angle_deg.to_radians()
    }

    /// The widest feed per revolution whose neighbouring arcs still meet on the edge:
    /// the edge covers ±R·sin(half span) sideways of the cutting point.
    pub fn coverable_feed_mm(&self) -> f64 {
        2.0 * self.nose_radius_mm * self.half_span_rad().min(std::f64::consts::FRAC_PI_2).sin()
    }
}

/// Direction from the nose centre to the tool tip for a B rotation of `b_rad`
/// (B = 0: straight down, −Z; positive B leans the tip toward −r, following a
/// normal that leans toward +r).
pub fn tip_direction(b_rad: f64) -> DVec2 {
    if b_rad == 0.0 {
        return DVec2::NEG_Y; // XZ: skip the trigonometry
    }
    DVec2::new(-b_rad.sin(), -b_rad.cos())
}

/// A function of the edge angle ψ sampled on an even grid, linear in between and held
/// at its end values outside.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AngleTable {
    pub start_rad: f64,
    pub step_rad: f64,
    pub values_mm: Vec<f64>,
}

impl AngleTable {
    pub fn at(&self, psi_rad: f64) -> f64 {
        match self.values_mm.len() {
            0 => 0.0,
            1 => self.values_mm[0],
            n => {
                let u = ((psi_rad - self.start_rad) / self.step_rad).clamp(0.0, (n - 1) as f64);
                let i = (u.floor() as usize).min(n - 2);
                let t = u - i as f64;
                self.values_mm[i] + t * (self.values_mm[i + 1] - self.values_mm[i])
            }
        }
    }

    /// The values at the nodes from the last at or below `lo` to the first at or above
    /// `hi` (rad), each read both as stored and as [`AngleTable::at`] interpolates it.
    fn nodes_within(&self, lo: f64, hi: f64) -> impl Iterator<Item = f64> + '_ {
        let n = self.values_mm.len();
        let index = |psi: f64| (psi - self.start_rad) / self.step_rad;
        let first = index(lo).floor().max(0.0) as usize;
        let last = (index(hi).ceil().max(0.0) as usize).min(n.saturating_sub(1));
        (first..=last).filter(move |_| n > 0).map(move |i| {
            let psi = self.start_rad + self.step_rad * i as f64;
            self.values_mm[i].max(self.at(psi))
        })
    }

    pub fn is_zero(&self) -> bool {
        self.values_mm.iter().all(|&v| v == 0.0)
    }

    pub fn max_abs_mm(&self) -> f64 {
        self.values_mm.iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    /// Σ A cos(n ψ + φ) over [−π/2, π/2] at `samples` points: roundness-style harmonics,
    /// order n being the number of undulations a full circle would carry.
    pub fn from_harmonics(harmonics: &[(f64, f64, f64)], samples: usize) -> Self {
        let start = -std::f64::consts::FRAC_PI_2;
        let step = std::f64::consts::PI / (samples - 1) as f64;
        let values_mm = (0..samples)
            .map(|i| {
                let psi = start + step * i as f64;
                harmonics
                    .iter()
                    .map(|&(order, amplitude_mm, phase_rad)| {
                        amplitude_mm * (order * psi + phase_rad).cos()
                    })
                    .sum()
            })
            .collect();
        Self {
            start_rad: start,
            step_rad: step,
            values_mm,
        }
    }
}

/// The edge as the removal engines see it.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeModel {
    pub nominal_radius_mm: f64,
    pub half_span_rad: f64,
    /// Actual minus nominal radius (mm).
    pub radius_error_mm: f64,
    /// Radial deviation w(ψ) of the edge from its own circle (mm, + = outward).
    pub deviation: AngleTable,
}

/// Solver passes for an edge that is not a circle: the local radius ρ(ψ) moves the hit
/// angle by ~(dw/dψ)/R per pass, so two corrections leave sub-picometre changes.
pub const EDGE_REFINEMENTS: usize = 2;

impl EdgeModel {
    pub fn ideal(tool: &ArcNoseTool) -> Self {
        Self {
            nominal_radius_mm: tool.nose_radius_mm,
            half_span_rad: tool.half_span_rad(),
            radius_error_mm: 0.0,
            deviation: AngleTable::default(),
        }
    }

    pub fn cos_half_span(&self) -> f64 {
        self.half_span_rad.min(std::f64::consts::PI).cos()
    }

    /// How far the real arc's centre sits behind the nominal one (tip-set tool).
    pub fn tip_offset_mm(&self) -> f64 {
        self.radius_error_mm + self.deviation.at(0.0)
    }

    pub fn radius_at(&self, psi_rad: f64) -> f64 {
        self.nominal_radius_mm + self.radius_error_mm + self.deviation.at(psi_rad)
    }

    /// Largest distance the real edge reaches beyond the nominal arc (for reach tests).
    pub fn max_excess_mm(&self) -> f64 {
        2.0 * (self.radius_error_mm.abs() + self.deviation.max_abs_mm())
    }

    /// Where the line `origin + d·direction` enters the edge, as `d`, or `None` when it
    /// misses the edge arc (see [`EdgeSolver::entry`]; engines prepare the solver once).
    pub fn entry(
        &self,
        from_pivot: DVec2,
        direction: DVec2,
        tip: DVec2,
        psi_sign: f64,
    ) -> Option<f64> {
        self.solver().entry(from_pivot, direction, tip, psi_sign)
    }

    /// The per-edge constants of [`EdgeSolver::entry`], computed once.
    pub fn solver(&self) -> EdgeSolver<'_> {
        EdgeSolver {
            edge: self,
            tip_offset_mm: self.tip_offset_mm(),
            cos_half_span: self.cos_half_span(),
            circle_radius_mm: self.nominal_radius_mm + self.radius_error_mm,
            outer_radius_mm: self.nominal_radius_mm
                + self.radius_error_mm
                + self
                    .deviation
                    .values_mm
                    .iter()
                    .fold(0.0_f64, |m, &v| m.max(v)),
            inner_radius_mm: self.nominal_radius_mm
                + self.radius_error_mm
                + self
                    .deviation
                    .values_mm
                    .iter()
                    .fold(0.0_f64, |m, &v| m.min(v)),
            refinements: if self.deviation.is_zero() {
                0
            } else {
                EDGE_REFINEMENTS
            },
        }
    }
}

/// An edge ready for many entries: what does not change from one ray to the next
/// (the tip offset, cos of the half span, the real circle's radius, whether the edge
/// departs from its circle) evaluated once, so an entry costs one square root and one
/// division when the edge is a circle.
#[derive(Debug, Clone, Copy)]
pub struct EdgeSolver<'a> {
    pub edge: &'a EdgeModel,
    pub tip_offset_mm: f64,
    pub cos_half_span: f64,
    /// R + e: the circle of the edge without its radial deviation.
    pub circle_radius_mm: f64,
    /// R + e + the deviation's outward maximum: a circle the whole edge lies within.
    pub outer_radius_mm: f64,
    /// R + e + the deviation's inward maximum: a circle within the whole edge.
    pub inner_radius_mm: f64,
    /// Hit-angle corrections: 0 for a circle, [`EDGE_REFINEMENTS`] otherwise.
    pub refinements: usize,
}

impl EdgeSolver<'_> {
    /// Where the line `origin + d·direction` enters the edge, as `d`, or `None` when it
    /// misses the edge arc. `from_pivot` is `origin − nominal nose centre`, `tip` the
    /// unit tip direction and `psi_sign` ±1 maps the frame's clockwise angle to the
    /// tool's ψ (−1 in the mirrored branch, where the frame is the machine's mirror).
    pub fn entry(
        &self,
        from_pivot: DVec2,
        direction: DVec2,
        tip: DVec2,
        psi_sign: f64,
    ) -> Option<f64> {
        // Origin relative to the real arc centre, which is tip_offset behind the pivot.
        let w = from_pivot + self.tip_offset_mm * tip;
        let mut radius = self.circle_radius_mm;
        let passes = self.refinements;
        let mut d = circle_entry(w, direction, radius)?;
        for pass in 0..=passes {
            // The hit lies on the circle of `radius`: its angle from the tip is within the
            // edge arc when hit·tip ≥ radius·cos(half span).
            let hit = w + d * direction;
            if hit.dot(tip) < radius * self.cos_half_span {
                return None;
            }
            if pass == passes {
                break;
            }
            let psi = psi_sign * psi_from_tip(hit, tip);
            radius = self.edge.radius_at(psi);
            d = circle_entry(w, direction, radius)?;
        }
        Some(d)
    }
}

/// ψ of `point` (relative to the arc centre): its clockwise angle from the unit tip
/// direction `tip`, as the edge's deviation w(ψ) is tabulated.
pub fn psi_from_tip(point: DVec2, tip: DVec2) -> f64 {
    (point.x * tip.y - point.y * tip.x).atan2(point.dot(tip))
}

impl EdgeSolver<'_> {
    /// A lower bound of [`EdgeSolver::entry`] (same arguments): the line's entry into
    /// the circle that holds the whole edge, `None` where it misses that circle (and so
    /// the edge). The edge lies within it, and a circle's entry only falls as its
    /// radius grows; one square root, no arctangent.
    pub fn entry_bound(&self, from_pivot: DVec2, direction: DVec2, tip: DVec2) -> Option<f64> {
        circle_entry(
            from_pivot + self.tip_offset_mm * tip,
            direction,
            self.outer_radius_mm,
        )
    }
}

impl EdgeSolver<'_> {
    /// A lower bound of [`EdgeSolver::entry`] (same arguments) as tight as the edge's
    /// deviation near where the line meets it: `None` only where the entry is `None`.
    /// The entry is the line's entry into the circle of radius R + e + w(ψ₁), ψ₁ the
    /// angle of its hit on a circle of radius between `inner_radius_mm` and
    /// `outer_radius_mm`; every such hit lies on the line between its entries into
    /// those two circles (the inner one's, or the point nearest the centre where the
    /// line misses it), an arc whose sin ψ range `maxima` bounds w over. Falls back to
    /// [`EdgeSolver::entry_bound`] where that arc reaches behind the centre or is long.
    /// Five square roots (three circle entries, two lengths), no arctangent.
    pub fn local_entry_bound(
        &self,
        maxima: &DeviationMaxima,
        from_pivot: DVec2,
        direction: DVec2,
        tip: DVec2,
        psi_sign: f64,
    ) -> Option<f64> {
        let outer = self.entry_bound(from_pivot, direction, tip)?;
        let w = from_pivot + self.tip_offset_mm * tip;
        let first = w + outer * direction;
        let last = match circle_entry(w, direction, self.inner_radius_mm) {
            Some(d) => w + d * direction,
            None => w - (w.dot(direction) / direction.length_squared()) * direction,
        };
        if first.dot(tip) <= 0.0 || last.dot(tip) <= 0.0 {
            return Some(outer);
        }
        let sine = |p: DVec2| psi_sign * (p.x * tip.y - p.y * tip.x) / p.length();
        let (a, b) = (sine(first), sine(last));
        let Some(most) = maxima.over(a.min(b), a.max(b)) else {
            return Some(outer);
        };
        let radius = (self.circle_radius_mm + most).min(self.outer_radius_mm);
        circle_entry(w, direction, radius).map(|d| d.max(outer))
    }
}

/// The largest radial deviation w(ψ) of an edge over short arcs, tabulated by sin ψ
/// (even bins over [−1, 1]; for |ψ| ≤ π/2, where sin ψ orders the angles): what bounds
/// a pass's entry where its ray meets the edge near a known angle (see
/// [`EdgeSolver::local_entry_bound`]). Each bin holds the maximum of the table's
/// linear interpolation over the bin's angles (at its ends and the nodes within), a
/// femtometre more; a query reads one more bin each side, so an angle a rounding off
/// the range is still covered.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DeviationMaxima {
    bins_mm: Vec<f64>,
}

/// Bins of [`DeviationMaxima`] over sin ψ ∈ [−1, 1] (~0.03° each near the tip).
const MAXIMA_BINS: usize = 4096;
/// Most bins a query reads; a longer range gives no bound.
const MAXIMA_QUERY_BINS: usize = 32;
/// Added to each bin's maximum against the interpolation's rounding (mm).
const MAXIMA_SLACK_MM: f64 = 1e-15;

impl DeviationMaxima {
    /// The bins of `table` (none for a circle: no query answers).
    pub fn new(table: &AngleTable) -> Self {
        if table.is_zero() {
            return Self::default();
        }
        let edge = |k: usize| {
            (-1.0 + 2.0 * k as f64 / MAXIMA_BINS as f64)
                .clamp(-1.0, 1.0)
                .asin()
        };
        let bins_mm = (0..MAXIMA_BINS)
            .map(|k| {
                let (lo, hi) = (edge(k), edge(k + 1));
                let ends = table.at(lo).max(table.at(hi));
                let nodes = table.nodes_within(lo, hi).fold(ends, f64::max);
                nodes + MAXIMA_SLACK_MM
            })
            .collect();
        Self { bins_mm }
    }

    /// The largest deviation over angles whose sines lie in `[lo, hi]`; `None` without
    /// bins or over more than [`MAXIMA_QUERY_BINS`] of them.
    pub fn over(&self, lo: f64, hi: f64) -> Option<f64> {
        // A NaN end (or an empty range) answers nothing.
        if self.bins_mm.is_empty() || lo.partial_cmp(&hi).is_none_or(|o| o.is_gt()) {
            return None;
        }
        let last = MAXIMA_BINS as f64 - 1.0;
        let bin = |s: f64| {
            ((s + 1.0) * 0.5 * MAXIMA_BINS as f64)
                .floor()
                .clamp(0.0, last)
        };
        let (first, end) = ((bin(lo) - 1.0).max(0.0), (bin(hi) + 1.0).min(last));
        let (first, end) = (first as usize, end as usize);
        if end - first >= MAXIMA_QUERY_BINS {
            return None;
        }
        self.bins_mm[first..=end].iter().copied().reduce(f64::max)
    }
}

/// Lower root of `|w + d m|² = ρ²` (the entry of the line into the circle), written as
/// `d = c / (√(b² − a c) − b)` when `b < 0`, which avoids cancelling two ρ-sized numbers
/// when the entry is nanometres from the origin.
pub fn circle_entry(w: DVec2, m: DVec2, radius: f64) -> Option<f64> {
    let a = m.length_squared();
    let b = w.dot(m);
    let c = w.length_squared() - radius * radius;
    let discriminant = b * b - a * c;
    if discriminant < 0.0 {
        return None;
    }
    let root = discriminant.sqrt();
    Some(if b < 0.0 {
        c / (root - b)
    } else {
        (-b - root) / a
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ideal(radius: f64, included_deg: f64) -> EdgeModel {
        EdgeModel::ideal(&ArcNoseTool {
            nose_radius_mm: radius,
            included_angle_deg: included_deg,
            clearance_angle_deg: 10.0,
        })
    }

    #[test]
    fn vertical_ray_under_the_nose_meets_the_circle_where_the_closed_form_says() {
        // Nose centre at the origin, sample at lateral offset u, height z0 below the
        // centre: the lower arc is at z = −√(R² − u²), so d = −√(R² − u²) − z0.
        let edge = ideal(0.5, 180.0);
        for &(u, z0) in &[(0.0, -0.6), (0.1, -0.49), (0.3, -0.45), (-0.2, -0.3)] {
            let d = edge
                .entry(DVec2::new(u, z0), DVec2::Y, tip_direction(0.0), 1.0)
                .unwrap();
            let expected = -(0.25 - u * u).sqrt() - z0;
            assert!((d - expected).abs() < 1e-15, "u={u}: {d} vs {expected}");
        }
    }

    #[test]
    fn nanometre_entries_keep_full_precision() {
        // Sample 1 nm below the arc's lowest point: d = +1e-6 mm exactly.
        let d = ideal(0.5, 180.0)
            .entry(
                DVec2::new(0.0, -0.5 - 1e-6),
                DVec2::Y,
                tip_direction(0.0),
                1.0,
            )
            .unwrap();
        assert!((d - 1e-6).abs() < 1e-16, "{d:e}");
    }

    #[test]
    fn hits_outside_the_edge_arc_are_misses() {
        // Included angle 60°: the edge spans ±30° about the tip. A sample straight
        // sideways of the centre would be hit at 90° from the tip: a miss.
        let edge = ideal(0.5, 60.0);
        assert!(
            edge.entry(DVec2::new(-0.6, 0.0), DVec2::X, tip_direction(0.0), 1.0)
                .is_none()
        );
        // Tilting the tool by B = 90° turns the tip toward −r, to face that sample.
        let d = edge
            .entry(
                DVec2::new(-0.6, 0.0),
                DVec2::X,
                tip_direction(std::f64::consts::FRAC_PI_2),
                1.0,
            )
            .unwrap();
        assert!((d - 0.1).abs() < 1e-15);
    }

    #[test]
    fn coverable_feed_is_the_chord_of_the_edge() {
        let tool = ArcNoseTool {
            nose_radius_mm: 0.5,
            included_angle_deg: 60.0,
            clearance_angle_deg: 10.0,
        };
        assert!((tool.coverable_feed_mm() - 0.5).abs() < 1e-15);
        let wide = ArcNoseTool {
            included_angle_deg: 180.0,
            ..tool
        };
        assert!((wide.coverable_feed_mm() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn a_tip_set_tool_with_a_radius_error_cuts_the_tip_point_unchanged_and_flanks_deeper() {
        // e = +1 µm, tip set: at ψ = 0 nothing moves; at ψ = θ the edge point moves by
        // e(u − t̂), whose normal part is −e(1 − cos θ) (derived in the module doc).
        let mut edge = ideal(0.5, 180.0);
        edge.radius_error_mm = 1e-3;
        let tip = tip_direction(0.0);
        let at_tip = edge
            .entry(DVec2::new(0.0, -0.5), DVec2::Y, tip, 1.0)
            .unwrap();
        assert!(at_tip.abs() < 1e-15);
        for theta_deg in [10.0f64, 40.0, 70.0] {
            let theta = theta_deg.to_radians();
            // Sample on the nominal arc at angle θ from the tip (toward −x), ray along the
            // surface normal there, which points back at the nominal centre.
            let normal = DVec2::new(theta.sin(), theta.cos());
            let sample = -0.5 * normal;
            let d = edge.entry(sample, normal, tip, 1.0).unwrap();
            // Exact: the real centre is e above the pivot, off the ray by e·sin θ.
            let (e, r) = (1e-3, 0.5);
            let exact =
                (e * theta.cos() + r) - ((r + e).powi(2) - (e * theta.sin()).powi(2)).sqrt();
            assert!((d - exact).abs() < 1e-15, "θ = {theta_deg}: {d} vs {exact}");
            // The signature −e(1 − cos θ) holds to O(e²/R).
            assert!((d + e * (1.0 - theta.cos())).abs() < e * e / r);
        }
    }

    #[test]
    fn waviness_moves_the_cut_to_the_local_edge_radius() {
        // w(ψ) = A cos(6ψ), tip set. Oracle: bisection on d of |P + d n − c′| − ρ(ψ(d)),
        // with the analytic w and ψ the clockwise angle of the point from the tip.
        let (amplitude, radius) = (50e-6, 0.5);
        let mut edge = ideal(radius, 180.0);
        edge.deviation = AngleTable::from_harmonics(&[(6.0, amplitude, 0.0)], 4001);
        let tip = tip_direction(0.0);
        let centre = -amplitude * tip; // the real centre, w(0) behind the pivot
        for theta_deg in [0.0f64, 12.0, 33.0, -25.0] {
            let theta = theta_deg.to_radians();
            let normal = DVec2::new(theta.sin(), theta.cos());
            let sample = -radius * normal;
            let d = edge.entry(sample, normal, tip, 1.0).unwrap();
            let gap = |d: f64| {
                let v = sample + d * normal - centre;
                let psi = (v.x * tip.y - v.y * tip.x).atan2(v.dot(tip));
                v.length() - (radius + amplitude * (6.0 * psi).cos())
            };
            let (mut lo, mut hi) = (-1e-3, 1e-3);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if gap(mid) > 0.0 { lo = mid } else { hi = mid }
            }
            let oracle = 0.5 * (lo + hi);
            // Linear interpolation of a 4001-point table (Δψ = π/4000): error
            // ≤ A·(6Δψ)²/8 = 1.4e-10 mm, against the analytic w of the oracle.
            assert!(
                (d - oracle).abs() < 1.5e-10,
                "θ = {theta_deg}: {d} vs {oracle}"
            );
            // To first order the cut moves by −(w(θ) − w(0)·cos θ): the tip-set arc is
            // shifted by w(0) along the tool axis, cos θ of it along this normal. The hit
            // sits ~A·sin θ/R off θ, so w′ = 6A leaves a remainder below 6A²/R.
            let first_order = -(amplitude * (6.0 * theta).cos() - amplitude * theta.cos());
            let bound = 6.0 * amplitude * amplitude / radius;
            assert!(
                (d - first_order).abs() < bound,
                "θ = {theta_deg}: {d} vs {first_order}"
            );
        }
    }

    /// The local bound of a wavy edge's entry never lies above the entry (the engines
    /// skip a pass on it), and reads the edge near the hit: over rays that sweep
    /// the edge at every angle and lean up to 40°, it is within the deviation's local
    /// rise of the entry where the global bound sits up to 2A above.
    #[test]
    fn the_local_bound_lies_below_the_entry_and_close_to_it() {
        let (radius, amplitude) = (0.3, 5e-5);
        let mut edge = ideal(radius, 120.0);
        edge.deviation =
            AngleTable::from_harmonics(&[(43.0, amplitude, 0.5), (7.0, 2e-5, 2.0)], 2001);
        let solver = edge.solver();
        let maxima = DeviationMaxima::new(&edge.deviation);
        let tip = tip_direction(0.0);
        let (mut local_gaps, mut global_gaps) = (Vec::new(), Vec::new());
        for i in 0..400 {
            let lateral = -0.25 + 0.5 * i as f64 / 399.0;
            for lean_deg in [-40.0_f64, -10.0, 0.0, 25.0] {
                let direction =
                    DVec2::new(lean_deg.to_radians().sin(), lean_deg.to_radians().cos());
                let from_pivot = DVec2::new(lateral, -0.4) - 0.1 * direction;
                let Some(entry) = solver.entry(from_pivot, direction, tip, 1.0) else {
                    continue;
                };
                let local = solver
                    .local_entry_bound(&maxima, from_pivot, direction, tip, 1.0)
                    .expect("an entered edge has a bound");
                let global = solver.entry_bound(from_pivot, direction, tip).unwrap();
                assert!(
                    local <= entry + 1e-15,
                    "x = {lateral}, lean {lean_deg}°: {local} > {entry}"
                );
                assert!(global <= local + 1e-15);
                local_gaps.push(entry - local);
                global_gaps.push(entry - global);
            }
        }
        assert!(local_gaps.len() > 1000, "{}", local_gaps.len());
        let median = |gaps: &mut Vec<f64>| {
            gaps.sort_by(f64::total_cmp);
            gaps[gaps.len() / 2]
        };
        // Typically the global bound sits about A above the entry (the deviation's
        // maximum against its mean), the local one within the rise of w over a few
        // bins of sin ψ: 3·(2/4096) rad × w′ (≤ 43·A + 7·2e-5) ≈ 0.07 A.
        let (local, global) = (median(&mut local_gaps), median(&mut global_gaps));
        println!("median gap: local {local:e} mm, global {global:e} mm");
        assert!(local < 0.1 * amplitude && global > 0.8 * amplitude);
        assert_eq!(
            DeviationMaxima::new(&AngleTable::default()).over(-0.1, 0.1),
            None
        );
    }
}

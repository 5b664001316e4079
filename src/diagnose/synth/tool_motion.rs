//! Where the tool stands against the part at each instant of the cut, for the section
//! model: the program's nose centre moved by the set-up errors and by everything that
//! changes as the part turns, and the edge's recession by wear. Written from the
//! definitions (the effect table in `process/effects/mod.rs`), apart from the engine's
//! `process/effects/motion.rs`, so that the two check each other.
//!
//! Three clocks at a pose of a pass:
//! - `turned`: the spindle angle turned since the first pose of the first pass (passes
//!   in program order). Drift grows linearly in it; a vibration a·cos(2πk·n + φ₀),
//!   n = turned/2π, moves the nose centre along +X (feed) or +Z (depth, away from the part).
//! - C: the table's own spindle angle. Spindle error motion is synchronous with it (the
//!   part's azimuth φ passes the tool at C ≡ −φ): axial Σ a·cos(kC + φ₀) moves the part
//!   toward the tool (the nose centre's Z less that, relative to the part); tilt
//!   θ(C) = Σ θ_k·cos(kC + φ₀) turns the face about machine Y through the spindle origin,
//!   rising toward the tool at +X, so a nose centre at X (as the machine runs it) cuts
//!   X·θ deeper (small angles: the edge does not turn).
//! - the cut length L = ∫|x| dC along the programmed nose-centre X (linear in C between
//!   nodes, so integrated exactly): the edge recedes by w·L/L_total, its circle's
//!   radius shrinking about the same centre (the tool is not set again at its tip).

use crate::process::effects::{SpindleHarmonic, TurningEffects, Vibration, VibrationDirection};
use crate::process::{PoseTable, ToolPose};

/// The moving effects of a turning job and the totals their clocks run to.
pub struct ToolMotion {
    x_decentre_mm: f64,
    drift_mm: f64,
    /// Spindle angle of all passes together (rad).
    total_angle_rad: f64,
    vibrations: Vec<Vibration>,
    axial: Vec<SpindleHarmonic>,
    tilt: Vec<SpindleHarmonic>,
    /// Edge recession at the end of the cut (mm) and the cut length there (mm).
    wear_mm: f64,
    total_length_mm: f64,
}

/// The tool at one instant: its nose centre as the machine runs it relative to the part,
/// and how far its edge has receded.
#[derive(Debug, Clone, Copy)]
pub struct ToolAt {
    pub pose: ToolPose,
    pub recession_mm: f64,
    /// Spindle angle turned since the first pose (rad): the time order of cuts.
    pub turned_rad: f64,
}

impl ToolMotion {
    /// The motion of `effects` (plus `extra` vibrations) over `passes` (program order).
    pub fn new(effects: &TurningEffects, extra: &[Vibration], passes: &[PoseTable]) -> Self {
        let wears = effects.wear_recession_mm != 0.0;
        Self {
            x_decentre_mm: effects.x_decentre_mm,
            drift_mm: effects.axial_drift_mm,
            total_angle_rad: passes
                .iter()
                .map(|p| p.end_angle_rad() - p.start_angle_rad)
                .sum(),
            vibrations: effects.vibrations.iter().chain(extra).cloned().collect(),
            axial: effects.axial_error_motion.clone(),
            tilt: effects.tilt_error_motion.clone(),
            wear_mm: effects.wear_recession_mm,
            total_length_mm: if wears {
                passes.iter().map(|p| CutLength::new(p, 0.0).end_mm()).sum()
            } else {
                0.0
            },
        }
    }

    /// Whether the edge wears (then a pass needs its cut length).
    pub fn wears(&self) -> bool {
        self.wear_mm != 0.0 && self.total_length_mm > 0.0
    }

    pub fn x_decentre_mm(&self) -> f64 {
        self.x_decentre_mm
    }

    /// How far the nose centre's X strays from the program's besides the decentre (mm).
    pub fn x_spread_mm(&self) -> f64 {
        self.vibrations
            .iter()
            .filter(|v| matches!(v.direction, VibrationDirection::Feed))
            .map(|v| v.amplitude_mm.abs())
            .sum()
    }

    /// Largest recession of the edge either way (mm).
    pub fn max_recession_mm(&self) -> f64 {
        self.wear_mm.abs()
    }

    /// The tool at the program's pose `programmed`, spindle angle `c_rad` of its table,
    /// `turned_rad` since the first pose, with `length_mm` cut so far.
    pub fn at(&self, programmed: ToolPose, c_rad: f64, turned_rad: f64, length_mm: f64) -> ToolAt {
        let mut pose = programmed;
        pose.x_mm += self.x_decentre_mm;
        if self.total_angle_rad > 0.0 {
            pose.z_mm += self.drift_mm * turned_rad / self.total_angle_rad;
        }
        for v in &self.vibrations {
            let u = v.amplitude_mm * (v.cycles_per_rev * turned_rad + v.phase_rad).cos();
            match v.direction {
                VibrationDirection::Feed => pose.x_mm += u,
                VibrationDirection::Depth => pose.z_mm += u,
            }
        }
        pose.z_mm -= synchronous(&self.axial, c_rad);
        pose.z_mm -= pose.x_mm * synchronous(&self.tilt, c_rad);
        let recession_mm = if self.wears() {
            self.wear_mm * length_mm / self.total_length_mm
        } else {
            0.0
        };
        ToolAt {
            pose,
            recession_mm,
            turned_rad,
        }
    }
}

/// Σ a·cos(kC + φ₀) of spindle harmonics at spindle angle `c_rad`.
fn synchronous(harmonics: &[SpindleHarmonic], c_rad: f64) -> f64 {
    harmonics
        .iter()
        .map(|h| h.amplitude * (h.order as f64 * c_rad + h.phase_rad).cos())
        .sum()
}

/// The cut length along one pass, ∫|x| dC (mm) from the first pose of the first pass, at
/// each of its nodes.
pub struct CutLength {
    at_node_mm: Vec<f64>,
}

impl CutLength {
    /// The pass `table`, after `before_mm` cut by the passes before it.
    pub fn new(table: &PoseTable, before_mm: f64) -> Self {
        let step = table.step_rad();
        let mut at_node_mm = Vec::with_capacity(table.poses.len());
        let mut sum = before_mm;
        at_node_mm.push(sum);
        for pair in table.poses.windows(2) {
            sum += step * abs_integral(pair[0].x_mm, pair[1].x_mm, 1.0);
            at_node_mm.push(sum);
        }
        Self { at_node_mm }
    }

    pub fn end_mm(&self) -> f64 {
        self.at_node_mm.last().copied().unwrap_or(0.0)
    }

    /// The cut length at spindle angle `c_rad` of `table` (the table it was made from).
    pub fn at(&self, table: &PoseTable, c_rad: f64) -> f64 {
        let u = (c_rad - table.start_angle_rad) / table.step_rad();
        let last = self.at_node_mm.len() - 1;
        if last == 0 || u <= 0.0 {
            return self.at_node_mm[0];
        }
        let i = (u.floor() as usize).min(last - 1);
        let (a, b) = (table.poses[i].x_mm, table.poses[i + 1].x_mm);
        self.at_node_mm[i] + table.step_rad() * abs_integral(a, b, (u - i as f64).min(1.0))
    }
}

/// ∫₀ᵗ |a + (b − a)τ| dτ: the trapezoid of |x| where x keeps its sign, else the two
/// triangles either side of its zero.
fn abs_integral(a: f64, b: f64, t: f64) -> f64 {
    let end = a + (b - a) * t;
    if a * end >= 0.0 {
        0.5 * (a.abs() + end.abs()) * t
    } else {
        let zero = a / (a - b);
        0.5 * (a.abs() * zero + end.abs() * (t - zero))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_integral_of_a_linear_x_is_its_trapezoid_or_its_two_triangles() {
        // x from 2 to 4: (2 + 4)/2 = 3; half way, from 2 to 3: 2.5/2 = 1.25.
        assert!((abs_integral(2.0, 4.0, 1.0) - 3.0).abs() < 1e-15);
        assert!((abs_integral(2.0, 4.0, 0.5) - 1.25).abs() < 1e-15);
        // x from −1 to 3 crosses 0 at τ = 1/4: triangles 1·¼/2 + 3·¾/2 = 1.25.
        assert!((abs_integral(-1.0, 3.0, 1.0) - 1.25).abs() < 1e-15);
        // … to τ = 1/2 (x = 1): 1/8 + 1·¼/2 = 0.25.
        assert!((abs_integral(-1.0, 3.0, 0.5) - 0.25).abs() < 1e-15);
    }

    #[test]
    fn a_faced_spiral_has_cut_length_pi_x_squared_over_f() {
        // x = x₀ − f·C/2π over n revolutions: ∫x dC = 2π(x₀n − fn²/2)… from x₀ to 0 that is
        // π x₀²/f (the engine's wear test uses the same closed form).
        let (x0, f, steps) = (0.3, 0.01, 64u32);
        let revolutions = 30usize;
        let table = PoseTable {
            start_angle_rad: 0.7,
            steps_per_rev: steps,
            poses: (0..=revolutions * steps as usize)
                .map(|i| ToolPose {
                    x_mm: x0 - f * i as f64 / steps as f64,
                    ..ToolPose::default()
                })
                .collect(),
        };
        let length = CutLength::new(&table, 0.0);
        let expected = std::f64::consts::PI * x0 * x0 / f;
        assert!((length.end_mm() - expected).abs() < 1e-9 * expected);
        // After 10.25 revolutions the nose centre is at x = x₀ − 10.25 f: π(x₀² − x²)/f.
        let c = 0.7 + std::f64::consts::TAU * 10.25;
        let x = x0 - 10.25 * f;
        let expected = std::f64::consts::PI * (x0 * x0 - x * x) / f;
        assert!((length.at(&table, c) - expected).abs() < 1e-9 * expected);
    }
}

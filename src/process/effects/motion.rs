//! The turning effects that move the tool against the part while it cuts, as the
//! machine's clock and spindle see them: relative vibration, spindle axial and tilt
//! error motion, and edge recession by wear. Each is a displacement of the pose-table
//! nodes, so both engines cut with it unchanged.
//!
//! Clocks (per node, over the passes in program order):
//! - `turned` (rad): the spindle angle turned since the first pose of the first pass
//!   (machining time at constant speed; `n = turned/2π` revolutions);
//! - `spindle` (rad): the spindle's own angle C as the program gives it (what error
//!   motion is synchronous with);
//! - `cut` (mm): the length the edge has travelled over the part, ∫|x| dC with x the
//!   programmed nose-centre X (trapezoids between nodes): π(r₀² − r²)/f when facing.

use super::TurningEffects;
use crate::process::PoseTable;
use glam::DVec2;
use std::f64::consts::TAU;

/// Which way a vibration moves the tool against the part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VibrationDirection {
    /// Along machine X (+ = toward +X): the marks move along the radius.
    Feed,
    /// Along machine Z (+ = toward +Z, away from the part): the depth of cut changes.
    Depth,
}

/// Relative tool–workpiece vibration: the tool displaced by
/// `amplitude·cos(2π·cycles_per_rev·n + phase)`, n the revolutions turned since the
/// first pose. A whole number of cycles per revolution is synchronous with the spindle
/// (lobes fixed on the part); any other number drifts against it (spiral "ribbons").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vibration {
    pub amplitude_mm: f64,
    pub cycles_per_rev: f64,
    pub phase_rad: f64,
    pub direction: VibrationDirection,
}

/// One synchronous harmonic of spindle error motion: `amplitude·cos(order·C + phase)`,
/// C the spindle angle. Axial: amplitude in mm, the part moving toward +Z (toward the
/// tool, cutting deeper). Tilt: amplitude in rad, the face turned about the machine Y
/// axis through the spindle origin so that it rises toward the tool at +X: the tool at
/// nose-centre X cuts x·θ deeper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpindleHarmonic {
    pub order: u32,
    pub amplitude: f64,
    pub phase_rad: f64,
}

impl SpindleHarmonic {
    fn at(&self, spindle_rad: f64) -> f64 {
        self.amplitude * (self.order as f64 * spindle_rad + self.phase_rad).cos()
    }
}

/// The largest chord sag a motion may leave between pose nodes, as a share of its
/// amplitude (0.1 %), or 0.01 nm when that is larger.
const SAG_SHARE: f64 = 1e-3;
const SAG_FLOOR_MM: f64 = 1e-8;

/// Highest cycles per revolution a motion may have (the job files' bound): keeps the
/// pose tables within ~14 000 nodes per revolution.
pub const MAX_CYCLES_PER_REV: f64 = 200.0;

impl TurningEffects {
    /// Whether any moving effect is set.
    pub fn has_motion(&self) -> bool {
        !self.vibrations.is_empty()
            || !self.axial_error_motion.is_empty()
            || !self.tilt_error_motion.is_empty()
            || self.wear_recession_mm != 0.0
    }

    /// Refines the tables so linear interpolation follows each motion to within 0.1 %
    /// of its amplitude (or 0.01 nm), and returns each node's wear displacement, taken
    /// from the programmed path before any effect moves it (none without wear).
    pub(super) fn prepare_motions(&self, passes: &mut [PoseTable]) -> Option<Vec<Vec<DVec2>>> {
        if !self.has_motion() {
            return None;
        }
        let steps = self.steps_needed(max_abs_x_mm(passes));
        for poses in passes.iter_mut() {
            refine(poses, steps);
        }
        if self.wear_recession_mm == 0.0 {
            return None;
        }
        let cut = cut_lengths_mm(passes);
        let total = cut.iter().flatten().copied().fold(0.0, f64::max);
        let per_mm = if total > 0.0 {
            self.wear_recession_mm / total
        } else {
            0.0
        };
        Some(
            passes
                .iter()
                .zip(&cut)
                .map(|(poses, cut)| {
                    let normals = path_normals(poses);
                    normals
                        .iter()
                        .zip(cut)
                        .map(|(n, c)| per_mm * c * *n)
                        .collect()
                })
                .collect(),
        )
    }

    /// The effects that run with machining time, applied to tables `prepare_motions`
    /// refined (program order): the drift so far, then vibration and error motion at
    /// each node's clocks (the tilt at the node's X as the machine runs it) and the wear
    /// displacement prepared.
    pub(super) fn apply_timed(&self, passes: &mut [PoseTable], wear: Option<Vec<Vec<DVec2>>>) {
        let span = |poses: &PoseTable| poses.end_angle_rad() - poses.start_angle_rad;
        let total: f64 = passes.iter().map(span).sum();
        let drifts = self.axial_drift_mm != 0.0 && total > 0.0;
        let moves = self.has_motion();
        if !drifts && !moves {
            return;
        }
        let mut before = 0.0;
        for (p, poses) in passes.iter_mut().enumerate() {
            let step = poses.step_rad();
            let start = poses.start_angle_rad;
            let pass_span = span(poses);
            for (i, pose) in poses.poses.iter_mut().enumerate() {
                let turned = before + step * i as f64;
                if drifts {
                    pose.z_mm += self.axial_drift_mm * turned / total;
                }
                if moves {
                    let spindle = start + step * i as f64;
                    let (dx, dz) = self.vibration_at(turned);
                    let part_up = self.axial_at(spindle) + pose.x_mm * self.tilt_at(spindle);
                    let worn = wear.as_ref().map_or(DVec2::ZERO, |w| w[p][i]);
                    pose.x_mm += dx + worn.x;
                    pose.z_mm += dz - part_up + worn.y;
                }
            }
            before += pass_span;
        }
    }

    /// The tool's (X, Z) displacement by the vibrations after `turned` rad.
    fn vibration_at(&self, turned_rad: f64) -> (f64, f64) {
        let revolutions = turned_rad / TAU;
        self.vibrations.iter().fold((0.0, 0.0), |(x, z), v| {
            let u = v.amplitude_mm * (TAU * v.cycles_per_rev * revolutions + v.phase_rad).cos();
            match v.direction {
                VibrationDirection::Feed => (x + u, z),
                VibrationDirection::Depth => (x, z + u),
            }
        })
    }

    fn axial_at(&self, spindle_rad: f64) -> f64 {
        self.axial_error_motion
            .iter()
            .map(|h| h.at(spindle_rad))
            .sum()
    }

    fn tilt_at(&self, spindle_rad: f64) -> f64 {
        self.tilt_error_motion
            .iter()
            .map(|h| h.at(spindle_rad))
            .sum()
    }

    /// How far the moving effects can take the tool beyond its programmed path, for a
    /// path reaching out to `max_x_mm`.
    pub(super) fn motion_reach_mm(&self, max_x_mm: f64) -> f64 {
        let vibration: f64 = self.vibrations.iter().map(|v| v.amplitude_mm.abs()).sum();
        let axial: f64 = self
            .axial_error_motion
            .iter()
            .map(|h| h.amplitude.abs())
            .sum();
        let tilt: f64 = self
            .tilt_error_motion
            .iter()
            .map(|h| h.amplitude.abs())
            .sum();
        vibration + axial + max_x_mm * tilt + self.wear_recession_mm.abs()
    }

    /// Nodes per revolution that keep every motion's chord sag within bounds: a
    /// sinusoid of amplitude a and k cycles per revolution sags a·(kΔ)²/8 over a step Δ.
    fn steps_needed(&self, max_x_mm: f64) -> f64 {
        let vibrations = self
            .vibrations
            .iter()
            .map(|v| (v.amplitude_mm, v.cycles_per_rev));
        let axial = self
            .axial_error_motion
            .iter()
            .map(|h| (h.amplitude, h.order as f64));
        let tilt = self
            .tilt_error_motion
            .iter()
            .map(|h| (h.amplitude * max_x_mm, h.order as f64));
        vibrations
            .chain(axial)
            .chain(tilt)
            .filter(|&(a, k)| a != 0.0 && k > 0.0)
            .map(|(a, k)| {
                let a = a.abs();
                let sag = (SAG_SHARE * a).max(SAG_FLOOR_MM);
                TAU * k / (8.0 * sag / a).sqrt()
            })
            .fold(0.0, f64::max)
    }
}

/// The farthest any pose's nose centre lies from the axis (mm).
pub fn max_abs_x_mm(passes: &[PoseTable]) -> f64 {
    passes
        .iter()
        .flat_map(|p| p.poses.iter())
        .map(|pose| pose.x_mm.abs())
        .fold(0.0, f64::max)
}

/// The table with a whole multiple of its nodes per revolution, at least `steps`,
/// each new node on the straight line between the old ones (the path as the machine
/// ran it before the motion).
fn refine(poses: &mut PoseTable, steps: f64) {
    let factor = (steps / poses.steps_per_rev as f64).ceil().max(1.0) as usize;
    if factor == 1 || poses.poses.len() < 2 {
        return;
    }
    let old = std::mem::take(&mut poses.poses);
    let mut refined = Vec::with_capacity((old.len() - 1) * factor + 1);
    for pair in old.windows(2) {
        refined.extend((0..factor).map(|j| pair[0].lerp(pair[1], j as f64 / factor as f64)));
    }
    refined.extend(old.last());
    poses.poses = refined;
    poses.steps_per_rev *= factor as u32;
}

/// Per pass and node, the cut length since the first pose of the first pass (mm).
fn cut_lengths_mm(passes: &[PoseTable]) -> Vec<Vec<f64>> {
    let mut so_far = 0.0;
    passes
        .iter()
        .map(|poses| {
            let step = poses.step_rad();
            let mut lengths = Vec::with_capacity(poses.poses.len());
            for (i, pose) in poses.poses.iter().enumerate() {
                if i > 0 {
                    so_far += 0.5 * step * (poses.poses[i - 1].x_mm.abs() + pose.x_mm.abs());
                }
                lengths.push(so_far);
            }
            lengths
        })
        .collect()
}

/// The unit normal of the nose-centre path in the XZ plane at each node, on the tool's
/// side (+Z): for an arc edge, moving the centre along it by w is the edge receding by
/// w (both offset the cut surface by w along its normal). Where the path stands still
/// or runs along Z (a dwell, a plunge), the last good normal is kept (+Z before any).
fn path_normals(poses: &PoseTable) -> Vec<DVec2> {
    let at = |i: usize| DVec2::new(poses.poses[i].x_mm, poses.poses[i].z_mm);
    let last = poses.poses.len().saturating_sub(1);
    let mut normal = DVec2::Y;
    (0..poses.poses.len())
        .map(|i| {
            let tangent = at((i + 1).min(last)) - at(i.saturating_sub(1));
            let candidate = DVec2::new(-tangent.y, tangent.x);
            let candidate = if candidate.y < 0.0 {
                -candidate
            } else {
                candidate
            };
            if tangent.length() > 1e-12 && candidate.y > 1e-9 * candidate.length() {
                normal = candidate.normalize();
            }
            normal
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::process::ToolPose;

    /// A facing table: the nose centre from x₀ inward by f per revolution, z = 0.
    fn facing(x0: f64, feed: f64, revolutions: usize, steps: u32) -> PoseTable {
        let n = revolutions * steps as usize + 1;
        PoseTable {
            start_angle_rad: 0.0,
            steps_per_rev: steps,
            poses: (0..n)
                .map(|i| ToolPose {
                    x_mm: x0 - feed * i as f64 / steps as f64,
                    z_mm: 0.0,
                    b_rad: 0.0,
                })
                .collect(),
        }
    }

    #[test]
    fn a_synchronous_depth_vibration_is_the_same_at_the_same_spindle_angle_every_revolution() {
        // Closed form: z = a·cos(2π·k·n + φ); with k whole, every node one revolution on
        // has the same displacement, and a quarter of a cycle on it is a·cos(φ + π/2).
        let effects = TurningEffects {
            vibrations: vec![Vibration {
                amplitude_mm: 2e-5,
                cycles_per_rev: 3.0,
                phase_rad: 0.4,
                direction: VibrationDirection::Depth,
            }],
            ..TurningEffects::default()
        };
        let mut passes = vec![facing(1.0, 0.01, 4, 16)];
        effects.apply_to_passes(&mut passes);
        let table = &passes[0];
        // 3 cycles need 70.2·3 ≈ 211 nodes per revolution: refined ×14 to 224.
        assert_eq!(table.steps_per_rev, 224);
        let z = |i: usize| table.poses[i].z_mm;
        assert!((z(0) - 2e-5 * 0.4f64.cos()).abs() < 1e-18);
        assert!((z(224) - z(0)).abs() < 1e-17 && (z(3 * 224 + 5) - z(5)).abs() < 1e-17);
        // A quarter cycle: 1/12 of a revolution = 224/12 nodes (not whole; use 56 = 1/4 rev
        // = 3/4 cycle): a·cos(φ + 3π/2).
        let expected = 2e-5 * (0.4 + 1.5 * std::f64::consts::PI).cos();
        assert!((z(56) - expected).abs() < 1e-17);
        // x untouched by a depth vibration.
        assert_eq!(table.poses[56].x_mm, 1.0 - 0.01 * 56.0 / 224.0);
    }

    #[test]
    fn tilt_error_motion_cuts_deeper_in_proportion_to_the_radius() {
        // Closed form: z = −x·θ·cos(k·C + φ).
        let effects = TurningEffects {
            tilt_error_motion: vec![SpindleHarmonic {
                order: 2,
                amplitude: 1e-5,
                phase_rad: 0.0,
            }],
            axial_error_motion: vec![SpindleHarmonic {
                order: 1,
                amplitude: 3e-6,
                phase_rad: 0.0,
            }],
            ..TurningEffects::default()
        };
        let mut passes = vec![facing(2.0, 0.01, 2, 512)];
        effects.apply_to_passes(&mut passes);
        let table = &passes[0];
        assert_eq!(table.steps_per_rev, 512);
        for i in [0usize, 100, 700] {
            let c = table.step_rad() * i as f64;
            let x = table.poses[i].x_mm;
            let expected = -(3e-6 * c.cos() + x * 1e-5 * (2.0 * c).cos());
            assert!((table.poses[i].z_mm - expected).abs() < 1e-18, "node {i}");
        }
    }

    #[test]
    fn wear_grows_with_the_cut_length_along_the_path_normal() {
        // Facing from x₀ = 1 mm by f per revolution to x₀ − 2f: the cut length after a
        // turn of C is ∫(x₀ − fC/2π)dC = x₀C − fC²/4π (trapezoids are exact for a line),
        // and the normal of a path along X is +Z.
        let (x0, f, w) = (1.0, 0.01, 1e-4);
        let effects = TurningEffects {
            wear_recession_mm: w,
            ..TurningEffects::default()
        };
        let mut passes = vec![facing(x0, f, 2, 64)];
        effects.apply_to_passes(&mut passes);
        let length = |c: f64| x0 * c - f * c * c / (2.0 * TAU);
        let total = length(2.0 * TAU);
        for i in [0usize, 64, 100, 128] {
            let c = TAU * i as f64 / 64.0;
            let pose = passes[0].poses[i];
            assert!(
                (pose.z_mm - w * length(c) / total).abs() < 1e-15,
                "node {i}"
            );
            assert!((pose.x_mm - (x0 - f * i as f64 / 64.0)).abs() < 1e-15);
        }
    }

    #[test]
    fn on_a_slope_wear_moves_the_nose_centre_along_the_path_normal() {
        // A nose-centre path z = 0.1·x (falling toward the axis): normal (−0.1, 1)/|·|.
        let mut table = facing(1.0, 0.01, 1, 32);
        for pose in &mut table.poses {
            pose.z_mm = 0.1 * pose.x_mm;
        }
        let normals = path_normals(&table);
        let expected = DVec2::new(-0.1, 1.0).normalize();
        assert!(normals.iter().all(|n| (*n - expected).length() < 1e-12));
    }
}

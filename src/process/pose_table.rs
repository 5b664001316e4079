//! A turning tool path as the machine's controller runs it: tool poses at evenly
//! spaced spindle angles C, moved between linearly (X, Z and B all linear in C, as
//! `G93` inverse-time blocks are). Generated spirals and NC programs both end up here,
//! and both engines read the same table.

use std::f64::consts::TAU;

/// The tool's nose-centre position in the machine XZ plane and its B rotation.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct ToolPose {
    pub x_mm: f64,
    pub z_mm: f64,
    pub b_rad: f64,
}

impl ToolPose {
    pub fn lerp(self, other: ToolPose, t: f64) -> ToolPose {
        ToolPose {
            x_mm: self.x_mm + t * (other.x_mm - self.x_mm),
            z_mm: self.z_mm + t * (other.z_mm - self.z_mm),
            b_rad: self.b_rad + t * (other.b_rad - self.b_rad),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct PoseTable {
    /// Spindle angle of `poses[0]` (rad, unwrapped).
    pub start_angle_rad: f64,
    /// Nodes per spindle revolution; a whole number so pass indices stay integer.
    pub steps_per_rev: u32,
    pub poses: Vec<ToolPose>,
}

impl PoseTable {
    pub fn step_rad(&self) -> f64 {
        TAU / self.steps_per_rev as f64
    }

    pub fn end_angle_rad(&self) -> f64 {
        self.start_angle_rad + self.step_rad() * (self.poses.len().saturating_sub(1)) as f64
    }

    /// The pose at spindle angle `c_rad` (linear between nodes), or `None` outside the table.
    pub fn pose_at(&self, c_rad: f64) -> Option<ToolPose> {
        let u = (c_rad - self.start_angle_rad) / self.step_rad();
        self.pose_at_step(u)
    }

    /// The nose centre's radial advance over one revolution from each node on (mm), with
    /// the radius midway (mm): where the program puts its marks, and how far apart.
    pub fn radial_feeds_mm(&self) -> Vec<(f64, f64)> {
        let steps = self.steps_per_rev as usize;
        self.poses
            .iter()
            .zip(self.poses.iter().skip(steps))
            .map(|(a, b)| (0.5 * (a.x_mm + b.x_mm), (a.x_mm - b.x_mm).abs()))
            .collect()
    }

    /// The pose at fractional node index `u`.
    pub fn pose_at_step(&self, u: f64) -> Option<ToolPose> {
        let last = self.poses.len().checked_sub(1)? as f64;
        if !(0.0..=last).contains(&u) || self.poses.len() < 2 {
            return None;
        }
        let index = (u.floor() as usize).min(self.poses.len() - 2);
        Some(self.poses[index].lerp(self.poses[index + 1], u - index as f64))
    }
}

//! Single-point turning (XZ and XZB): a spiral from the rim to the centre whose
//! nominal nose-centre path follows the target surface offset along its normal,
//! finishing with one revolution at the end radius.
//!
//! XZ: the tool keeps B = 0 and its contact point slides over the edge (at slope θ the
//! edge cuts at θ from its tip). XZB: the tool turns by B = θ so its tip always cuts.
//! With an ideal arc both put the nose centre on the same offset curve; they differ
//! once the edge is not a perfect arc (issue 3's effects).

use super::pose_table::{PoseTable, ToolPose};
use crate::geometry::{ArcNoseTool, MeridianArcLength, SurfaceOfRevolution};
use rayon::prelude::*;
use std::f64::consts::TAU;

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TurningMode {
    Xz,
    Xzb,
}

/// What the feed per revolution is measured along.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeedAlong {
    /// Radial (X) advance of the cutting point per revolution: cusps spread out on slopes.
    Radial,
    /// Advance along the meridian per revolution: even scallops on steep parts.
    ArcLength,
}

#[derive(Debug, Clone, PartialEq)]
pub struct TurningSpiral {
    pub mode: TurningMode,
    pub feed_per_rev_mm: f64,
    pub feed_along: FeedAlong,
    /// Radius of the cutting point at the start (the rim side).
    pub start_radius_mm: f64,
    /// Radius of the cutting point at the end (0 = the centre).
    pub end_radius_mm: f64,
    /// Material above the nominal surface before the pass (along the normal).
    pub stock_allowance_mm: f64,
    /// How deep the pass cuts into the stock; the path targets `stock − depth` above nominal.
    pub depth_of_cut_mm: f64,
}

/// Largest chord sag allowed between pose-table nodes (mm): 0.01 nm.
const CHORD_TOLERANCE_MM: f64 = 1e-8;
const MIN_STEPS_PER_REV: u32 = 16;
const MAX_STEPS_PER_REV: u32 = 4096;

impl TurningSpiral {
    /// Offset of the nose-centre path from the nominal surface beyond the nose radius.
    pub fn target_offset_mm(&self) -> f64 {
        self.stock_allowance_mm - self.depth_of_cut_mm
    }

    /// The spiral as a pose table, with the fewest nodes per revolution that keep the
    /// linear interpolation between nodes within 0.01 nm of the true path.
    pub fn pose_table(
        &self,
        surface: &SurfaceOfRevolution,
        meridian: &MeridianArcLength,
        tool: &ArcNoseTool,
    ) -> PoseTable {
        let path = SpiralPath::new(self, surface, meridian, tool);
        let mut steps_per_rev = MIN_STEPS_PER_REV;
        while steps_per_rev < MAX_STEPS_PER_REV
            && path.max_chord_sag(steps_per_rev) > CHORD_TOLERANCE_MM
        {
            steps_per_rev *= 2;
        }
        let step = TAU / steps_per_rev as f64;
        let node_count = (path.end_angle_rad / step).ceil() as usize + 1;
        PoseTable {
            start_angle_rad: 0.0,
            steps_per_rev,
            poses: (0..node_count)
                .into_par_iter()
                .map(|n| path.pose(n as f64 * step))
                .collect(),
        }
    }

    /// Number of spindle revolutions from start to end, the final dwell revolution included.
    pub fn revolutions(&self, meridian: &MeridianArcLength) -> f64 {
        let (start, end) = self.contact_parameter_range(meridian);
        (start - end) / self.feed_per_rev_mm + 1.0
    }

    /// The contact-point parameter (radius or arc length) at the start and the end.
    fn contact_parameter_range(&self, meridian: &MeridianArcLength) -> (f64, f64) {
        match self.feed_along {
            FeedAlong::Radial => (self.start_radius_mm, self.end_radius_mm),
            FeedAlong::ArcLength => (
                meridian.arc_length_at(self.start_radius_mm),
                meridian.arc_length_at(self.end_radius_mm),
            ),
        }
    }
}

/// The continuous spiral: spindle angle → nominal tool pose.
struct SpiralPath<'a> {
    spiral: &'a TurningSpiral,
    surface: &'a SurfaceOfRevolution,
    meridian: &'a MeridianArcLength,
    centre_offset_mm: f64,
    start_parameter: f64,
    end_parameter: f64,
    end_angle_rad: f64,
}

impl<'a> SpiralPath<'a> {
    fn new(
        spiral: &'a TurningSpiral,
        surface: &'a SurfaceOfRevolution,
        meridian: &'a MeridianArcLength,
        tool: &ArcNoseTool,
    ) -> Self {
        let (start_parameter, end_parameter) = spiral.contact_parameter_range(meridian);
        Self {
            spiral,
            surface,
            meridian,
            centre_offset_mm: tool.nose_radius_mm + spiral.target_offset_mm(),
            start_parameter,
            end_parameter,
            // One extra revolution at the end radius: without it each azimuth's last
            // pass stops up to a feed short of the end (a real program dwells or overshoots).
            end_angle_rad: TAU * ((start_parameter - end_parameter) / spiral.feed_per_rev_mm + 1.0),
        }
    }

    /// Radius of the cutting point at spindle angle `c` (held at the end once reached).
    fn contact_radius(&self, c_rad: f64) -> f64 {
        let parameter = (self.start_parameter - self.spiral.feed_per_rev_mm * c_rad / TAU)
            .max(self.end_parameter);
        match self.spiral.feed_along {
            FeedAlong::Radial => parameter,
            FeedAlong::ArcLength => self.meridian.radius_at(parameter),
        }
    }

    fn pose(&self, c_rad: f64) -> ToolPose {
        let r = self.contact_radius(c_rad);
        let centre = self.surface.point(r) + self.centre_offset_mm * self.surface.normal(r);
        let b_rad = match self.spiral.mode {
            super::TurningMode::Xz => 0.0,
            super::TurningMode::Xzb => self.surface.normal_angle(r),
        };
        ToolPose {
            x_mm: centre.x,
            z_mm: centre.y,
            b_rad,
        }
    }

    /// Largest distance between the path and its chord over one node step, sampled
    /// at 2000 places along the spiral.
    fn max_chord_sag(&self, steps_per_rev: u32) -> f64 {
        let step = TAU / steps_per_rev as f64;
        let samples = 2000;
        (0..samples)
            .into_par_iter()
            .map(|i| {
                let c = (self.end_angle_rad - step).max(0.0) * i as f64 / (samples - 1) as f64;
                let a = self.pose(c);
                let b = self.pose(c + step);
                let mid = self.pose(c + 0.5 * step);
                let chord_mid = a.lerp(b, 0.5);
                (mid.x_mm - chord_mid.x_mm).hypot(mid.z_mm - chord_mid.z_mm)
            })
            .reduce(|| 0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Form;

    fn spiral(feed_along: FeedAlong) -> TurningSpiral {
        TurningSpiral {
            mode: TurningMode::Xz,
            feed_per_rev_mm: 0.01,
            feed_along,
            start_radius_mm: 5.0,
            end_radius_mm: 0.0,
            stock_allowance_mm: 0.002,
            depth_of_cut_mm: 0.002,
        }
    }

    #[test]
    fn radial_spiral_advances_one_feed_per_revolution_on_the_offset_surface() {
        let surface = SurfaceOfRevolution::sphere(20.0, Form::Convex);
        let meridian = MeridianArcLength::new(&surface, 5.0);
        let tool = ArcNoseTool {
            nose_radius_mm: 0.5,
            included_angle_deg: 120.0,
            clearance_angle_deg: 10.0,
        };
        let table = spiral(FeedAlong::Radial).pose_table(&surface, &meridian, &tool);
        // Convex sphere of radius 20 centred at (0, −20): nose centres lie on the
        // concentric sphere of radius 20.5 (stock − depth = 0).
        for rev in [0.0, 1.0, 123.0, 499.0] {
            let pose = table.pose_at(TAU * rev).unwrap();
            let centre_distance = pose.x_mm.hypot(pose.z_mm + 20.0);
            assert!(
                (centre_distance - 20.5).abs() < 1e-8,
                "rev {rev}: {centre_distance}"
            );
            // Contact radius r = x·20/20.5 advances by the feed each revolution.
            let contact_radius = pose.x_mm * 20.0 / 20.5;
            assert!((contact_radius - (5.0 - 0.01 * rev)).abs() < 1e-8);
        }
    }

    #[test]
    fn arc_length_spiral_spaces_cutting_points_evenly_along_the_meridian() {
        let surface = SurfaceOfRevolution::sphere(20.0, Form::Concave);
        let meridian = MeridianArcLength::new(&surface, 5.0);
        let tool = ArcNoseTool {
            nose_radius_mm: 0.5,
            included_angle_deg: 120.0,
            clearance_angle_deg: 10.0,
        };
        let table = spiral(FeedAlong::ArcLength).pose_table(&surface, &meridian, &tool);
        // Concave sphere centred at (0, 20): nose centres at distance 19.5 from it,
        // on the ray through the cutting point; its polar angle advances 0.01/20 per rev.
        let angle = |rev: f64| {
            let pose = table.pose_at(TAU * rev).unwrap();
            pose.x_mm.atan2(20.0 - pose.z_mm)
        };
        for rev in [0.0, 10.0, 200.0] {
            let step = angle(rev) - angle(rev + 1.0);
            assert!((step - 0.01 / 20.0).abs() < 1e-10, "rev {rev}: {step}");
        }
    }

    #[test]
    fn xzb_turns_the_tool_by_the_normal_angle() {
        let surface = SurfaceOfRevolution::sphere(10.0, Form::Convex);
        let meridian = MeridianArcLength::new(&surface, 5.0);
        let tool = ArcNoseTool {
            nose_radius_mm: 0.5,
            included_angle_deg: 40.0,
            clearance_angle_deg: 10.0,
        };
        let table = TurningSpiral {
            mode: TurningMode::Xzb,
            ..spiral(FeedAlong::Radial)
        }
        .pose_table(&surface, &meridian, &tool);
        let first = table.poses[0];
        // At r = 5 on a convex R10 sphere the normal leans out by asin(5/10) = 30°.
        assert!((first.b_rad - 30f64.to_radians()).abs() < 1e-12);
    }
}

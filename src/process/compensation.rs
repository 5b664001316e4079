//! Path compensation along the surface normal (seed 002 eq. (2)): where a part was
//! measured E above nominal, the next path moves the tool by E into the part along the
//! normal, X = x + E sin θ, Z = z − E cos θ, B = θ (for the tip; the nose centre moves
//! the same way). The correction is a table of normal offsets against the meridian arc
//! length (radius alone would crowd the steep rim of a part like seed 002's into a few
//! micrometres of r).

use super::pose_table::PoseTable;
use crate::geometry::{MeridianArcLength, SurfaceOfRevolution};
use glam::DVec2;
use std::fmt::Write as _;

/// Normal offsets (mm, + = cut deeper) against meridian arc length, linear in between,
/// 0 outside; the radius of each row is kept for people reading the file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NormalCorrection {
    pub arc_length_mm: Vec<f64>,
    pub radius_mm: Vec<f64>,
    pub offset_mm: Vec<f64>,
}

impl NormalCorrection {
    pub fn is_empty(&self) -> bool {
        self.arc_length_mm.is_empty()
    }

    /// The offset at meridian arc length `s`.
    pub fn at(&self, s: f64) -> f64 {
        let n = self.arc_length_mm.len();
        if n == 0 || s < self.arc_length_mm[0] || s > self.arc_length_mm[n - 1] {
            return 0.0;
        }
        let i = self
            .arc_length_mm
            .partition_point(|&x| x < s)
            .clamp(1, n - 1);
        let t =
            (s - self.arc_length_mm[i - 1]) / (self.arc_length_mm[i] - self.arc_length_mm[i - 1]);
        self.offset_mm[i - 1] + t * (self.offset_mm[i] - self.offset_mm[i - 1])
    }

    pub fn max_abs_mm(&self) -> f64 {
        self.offset_mm.iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    /// Moves every nose centre by the correction at its cutting point, into the part
    /// along the surface normal there.
    pub fn apply(
        &self,
        poses: &mut PoseTable,
        surface: &SurfaceOfRevolution,
        meridian: &MeridianArcLength,
    ) {
        if self.is_empty() {
            return;
        }
        for pose in &mut poses.poses {
            let (_, foot) = surface.distance_to(DVec2::new(pose.x_mm.abs(), pose.z_mm));
            let shift = self.at(meridian.arc_length_at(foot.min(meridian.max_radius_mm())))
                * surface.normal(foot);
            pose.x_mm -= shift.x * pose.x_mm.signum();
            pose.z_mm -= shift.y;
        }
    }

    /// CSV: `arc_length_mm,radius_mm,normal_offset_nm` (what `from_csv` reads back).
    pub fn to_csv(&self) -> String {
        let mut csv = String::from(
            "# toolmark normal correction: + = the tool cuts deeper along the surface normal\narc_length_mm,radius_mm,normal_offset_nm\n",
        );
        for ((s, r), o) in self
            .arc_length_mm
            .iter()
            .zip(&self.radius_mm)
            .zip(&self.offset_mm)
        {
            let _ = writeln!(csv, "{s:.9},{r:.9},{:.6}", o * 1e6);
        }
        csv
    }

    /// Parses `arc_length_mm,radius_mm,normal_offset_nm` rows (a header and `#` comments
    /// allowed); arc length must increase.
    pub fn from_csv(text: &str) -> Result<Self, String> {
        let mut correction = NormalCorrection::default();
        for (number, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') || line.starts_with("arc_length_mm") {
                continue;
            }
            let mut cells = line.split(',').map(str::trim);
            let mut value = |what: &str| -> Result<f64, String> {
                cells
                    .next()
                    .and_then(|c| c.parse::<f64>().ok())
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("line {}: {what} is not a finite number", number + 1))
            };
            let (s, r, offset_nm) = (
                value("arc_length_mm")?,
                value("radius_mm")?,
                value("normal_offset_nm")?,
            );
            if correction
                .arc_length_mm
                .last()
                .is_some_and(|&last| s <= last)
            {
                return Err(format!("line {}: arc_length_mm must increase", number + 1));
            }
            correction.arc_length_mm.push(s);
            correction.radius_mm.push(r);
            correction.offset_mm.push(offset_nm * 1e-6);
        }
        if correction.arc_length_mm.len() < 2 {
            return Err("a correction needs at least two rows".into());
        }
        Ok(correction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Form;
    use crate::process::ToolPose;

    #[test]
    fn a_correction_moves_the_nose_centre_into_the_part_along_the_normal() {
        // Convex R10 sphere (centre (0, −10)); nose centre R = 0.5 above the point at r = 3.
        let surface = SurfaceOfRevolution::sphere(10.0, Form::Convex);
        let r = 3.0;
        let centre = surface.point(r) + 0.5 * surface.normal(r);
        let mut poses = PoseTable {
            start_angle_rad: 0.0,
            steps_per_rev: 16,
            poses: vec![ToolPose {
                x_mm: centre.x,
                z_mm: centre.y,
                b_rad: 0.0,
            }],
        };
        let meridian = MeridianArcLength::new(&surface, 6.0);
        let correction = NormalCorrection {
            arc_length_mm: vec![0.0, 6.0],
            radius_mm: vec![0.0, meridian.radius_at(6.0)],
            offset_mm: vec![2e-4, 2e-4],
        };
        correction.apply(&mut poses, &surface, &meridian);
        // The centre's distance from the sphere's centre drops by exactly the offset.
        let moved = DVec2::new(poses.poses[0].x_mm, poses.poses[0].z_mm);
        assert!(((moved - DVec2::new(0.0, -10.0)).length() - (10.5 - 2e-4)).abs() < 1e-12);
        // CSV round trip.
        let back = NormalCorrection::from_csv(&correction.to_csv()).unwrap();
        assert_eq!(back.arc_length_mm, correction.arc_length_mm);
        assert!((back.offset_mm[0] - 2e-4).abs() < 1e-15);
    }
}

//! The milling tools as spinning solids: end mills (ball, bull-nose, flat) and disc
//! cutters with straight-edged inserts, behind one interface the milling engine uses.

use super::cutter::{Cutter, CutterPose};
use super::disc_cutter::DiscCutter;
use glam::DVec3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MillingTool {
    EndMill(Cutter),
    Disc(DiscCutter),
}

impl MillingTool {
    /// Where `origin + t·dir` first enters the tool at `pose` (None on a miss).
    pub fn ray_entry(&self, pose: &CutterPose, origin: DVec3, dir: DVec3) -> Option<f64> {
        match self {
            MillingTool::EndMill(cutter) if cutter.major_radius_mm == 0.0 => {
                ball_entry(cutter, pose, origin, dir)
            }
            MillingTool::EndMill(cutter) => cutter.ray_entry(pose, origin, dir),
            MillingTool::Disc(disc) => disc.ray_interval(pose, origin, dir).map(|i| i.0),
        }
    }

    /// Signed distance from `point` to the tool (negative inside): exact for end mills, a
    /// first-order estimate for disc cutters (zero on the surface, growing away from it,
    /// which is all its use — steering a search toward the tool — needs).
    pub fn signed_distance(&self, pose: &CutterPose, point: DVec3) -> f64 {
        match self {
            MillingTool::EndMill(cutter) => cutter.signed_distance(pose, point),
            MillingTool::Disc(disc) => disc.signed_distance_estimate(pose, point),
        }
    }

    /// Whether the entry along a pass is smooth at its minimum: a ball's, a bull-nose's
    /// corner and a disc's hyperboloid cut with their smooth faces (a disc's edge ends
    /// rarely), a flat end with its sharp rim, which leaves a kink there.
    pub fn is_smooth(&self) -> bool {
        !matches!(self, MillingTool::EndMill(cutter) if cutter.corner_radius_mm == 0.0)
    }

    /// The tool's outer radius about its axis.
    pub fn outer_radius_mm(&self) -> f64 {
        match self {
            MillingTool::EndMill(cutter) => cutter.radius_mm(),
            MillingTool::Disc(disc) => disc.outer_radius_mm(),
        }
    }

    /// The solid one tooth sweeps whose edge stands `radial_mm` (≥ 0) beyond the
    /// nominal radius: an end mill's profile moved out (a ball's becomes a torus); a disc
    /// as it is.
    pub fn with_radial_runout(&self, radial_mm: f64) -> MillingTool {
        match self {
            MillingTool::EndMill(cutter) if radial_mm > 0.0 => MillingTool::EndMill(Cutter {
                major_radius_mm: cutter.major_radius_mm + radial_mm,
                ..*cutter
            }),
            _ => *self,
        }
    }

    /// The tip's axial coordinate below the pose centre (an end mill's corner radius;
    /// a disc has no tip: 0).
    pub fn tip_depth_mm(&self) -> f64 {
        match self {
            MillingTool::EndMill(cutter) => cutter.corner_radius_mm,
            MillingTool::Disc(_) => 0.0,
        }
    }

    /// The largest distance of the cutting solid from its pose centre.
    pub fn reach_mm(&self) -> f64 {
        match self {
            MillingTool::EndMill(cutter) => cutter.radius_mm() + cutter.corner_radius_mm,
            MillingTool::Disc(disc) => disc.outer_radius_mm().hypot(0.5 * disc.insert_length_mm),
        }
    }

    /// The pose with axis `axis` whose surface touches the point `contact` where the
    /// part's outward normal is `normal` (the tool's surface normal there is −normal).
    /// End mill: the corner-arc centre sits r along the normal, and the corner circle's
    /// centre R further along the normal's part across the axis; a disc cutter, whose
    /// axis lies across the normal, touches with its throat.
    pub fn touching_pose(&self, contact: DVec3, normal: DVec3, axis: DVec3) -> CutterPose {
        match self {
            MillingTool::EndMill(cutter) => {
                let across = normal - normal.dot(axis) * axis;
                let radial = if across.length() > 1e-12 {
                    across.normalize()
                } else {
                    DVec3::ZERO // the flat tip touches: any point of it will do
                };
                CutterPose::new(
                    contact + cutter.corner_radius_mm * normal + cutter.major_radius_mm * radial,
                    axis,
                )
            }
            MillingTool::Disc(disc) => {
                let (throat, along) = disc.throat();
                CutterPose::new(contact + throat * normal - along * axis, axis)
            }
        }
    }

    /// Where a touching pose's centre sits from the contact along the normal (the corner
    /// radius; a disc's throat radius), and how far across the normal it can sit besides
    /// (an end mill's flat radius R; half a disc's edge span along its axis).
    pub fn centre_offset_and_lateral_reach(&self) -> (f64, f64) {
        match self {
            MillingTool::EndMill(cutter) => (cutter.corner_radius_mm, cutter.major_radius_mm),
            MillingTool::Disc(disc) => (
                disc.throat().0,
                0.5 * disc.insert_length_mm + disc.throat().1.abs(),
            ),
        }
    }

    /// Distance from the tool axis of a point (for the cutting diameter at a contact).
    pub fn radius_at(pose: &CutterPose, point: DVec3) -> f64 {
        let v = point - pose.centre;
        (v - v.dot(pose.axis) * pose.axis).length()
    }
}

/// A ball-end mill's first entry in closed form: the ball (a quadratic) where the ray
/// meets its lower half, else its shank (the cylinder of the same radius from the
/// centre up to the cap, a quadratic). Equal to `Cutter::ray_interval`'s entry (tested), much cheaper.
fn ball_entry(cutter: &Cutter, pose: &CutterPose, origin: DVec3, dir: DVec3) -> Option<f64> {
    let r = cutter.corner_radius_mm;
    let w = pose.axis;
    let o = origin - pose.centre;
    // |o + t d|² = r² (unit d): t = −b ∓ √(b² − c); the entry is the smaller root.
    let b = o.dot(dir);
    let length = o.length();
    let c = (length - r) * (length + r);
    let discriminant = b * b - c;
    if discriminant >= 0.0 {
        let root = discriminant.sqrt();
        // −b − root without cancellation when b < 0.
        let t = if b < 0.0 { c / (root - b) } else { -b - root };
        // On the lower half of the ball it is the solid's entry (the solid is convex);
        // the upper half lies inside the shank.
        if (o + t * dir).dot(w) <= 1e-12 {
            return Some(t);
        }
    }
    // Shank: radial |v0 + t vd| ≤ r with 0 ≤ a ≤ L.
    let (a0, ad) = (o.dot(w), dir.dot(w));
    let (v0, vd) = (o - a0 * w, dir - ad * w);
    let aa = vd.length_squared();
    if aa > 0.0 {
        let bb = v0.dot(vd);
        let perp = (v0 - (bb / aa) * vd).length();
        (perp <= r)
            .then(|| {
                let half = (aa * (r - perp) * (r + perp)).sqrt();
                let (t_in, t_out) = ((-bb - half) / aa, (-bb + half) / aa);
                // Clip to the axial slab [0, L].
                let (lo, hi) = if ad == 0.0 {
                    if (0.0..=cutter.length_mm).contains(&a0) {
                        (f64::NEG_INFINITY, f64::INFINITY)
                    } else {
                        (1.0, 0.0)
                    }
                } else {
                    let (x, y) = ((0.0 - a0) / ad, (cutter.length_mm - a0) / ad);
                    (x.min(y), x.max(y))
                };
                let (start, end) = (t_in.max(lo), t_out.min(hi));
                (start <= end).then_some(start)
            })
            .flatten()
    } else {
        ((v0.length() <= r) && ad != 0.0).then(|| {
            let (x, y) = ((0.0 - a0) / ad, (cutter.length_mm - a0) / ad);
            x.min(y)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ball_shortcut_matches_the_general_solid() {
        let cutter = Cutter::ball(1.5);
        let tool = MillingTool::EndMill(cutter);
        let pose = CutterPose::new(
            DVec3::new(0.1, -0.2, 1.3),
            DVec3::new(0.1, 0.2, 1.0).normalize(),
        );
        let mut checked = 0;
        for i in 0..400 {
            let a = i as f64 * 0.7;
            let origin = DVec3::new(
                3.0 * a.cos(),
                3.0 * (1.3 * a).sin(),
                -1.0 + (0.37 * a).sin() * 4.0,
            );
            let dir = (pose.centre
                + DVec3::new((0.11 * a).sin(), (0.23 * a).cos(), (0.05 * a).sin())
                - origin)
                .normalize();
            let general = cutter.ray_interval(&pose, origin, dir).map(|i| i.0);
            let fast = tool.ray_entry(&pose, origin, dir);
            match (general, fast) {
                (Some(g), Some(f)) => {
                    assert!((g - f).abs() < 1e-9, "{i}: {g} vs {f}");
                    checked += 1;
                }
                (None, None) => {}
                other => panic!("{i}: {other:?}"),
            }
        }
        assert!(checked > 200, "{checked}");
    }

    #[test]
    fn touching_poses_touch_the_contact_point() {
        let normal = DVec3::new(0.3, -0.2, 0.9).normalize();
        let contact = DVec3::new(1.0, 2.0, 0.5);
        let tools = [
            MillingTool::EndMill(Cutter::ball(2.0)),
            MillingTool::EndMill(Cutter::bull_nose(3.0, 1.0)),
            MillingTool::EndMill(Cutter::flat(4.0)),
        ];
        for tool in tools {
            for axis in [DVec3::Z, DVec3::new(0.2, 0.1, 1.0).normalize()] {
                let pose = tool.touching_pose(contact, normal, axis);
                // A ray up the normal from below the contact enters the tool there.
                let entry = tool.ray_entry(&pose, contact - normal, normal).unwrap();
                assert!((entry - 1.0).abs() < 1e-9, "{tool:?} {axis}: {entry}");
            }
        }
    }
}

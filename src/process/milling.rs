//! Milling (seeds 001, 003, 004): a spinning tool fed over a stationary part along a
//! planned path — parallel raster passes, a spiral, or a spiral whose step keeps a set
//! scallop height — in 3-axis (tool axis = Z) or 5-axis (the axis leaned from the surface
//! normal by a lead λ toward the feed and turned by a tilt ω about the normal, as in seed
//! 001), each constant or varying linearly along the path.
//!
//! With `five_axis` false the tool axis stays along the machine Z (lead and tilt are
//! then zero); with it true the axis follows the surface normal, leaned by the lead and
//! tilt (λ = ω = 0: along the normal).
//!
//! The path is planned on the nominal surface as contact points; each becomes the tool
//! pose that touches the surface there (`MillingTool::touching_pose`) raised by the
//! stock left after the cut (stock − depth of cut). Raster passes are straight lines in
//! XY, their nodes close enough that the chord between them strays < 0.1 nm from the
//! curved pose path; spiral nodes are interpolated in cylindrical coordinates, which
//! keeps the turns exact.

use crate::geometry::SurfaceOfRevolution;
use crate::geometry::cutter::CutterPose;
use crate::geometry::formulas::{ball_stepover_for_scallop, sphere_scallop_height};
use crate::geometry::milling_tool::MillingTool;
use glam::{DVec2, DVec3};
use std::f64::consts::{PI, TAU};

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MillingPathKind {
    /// Parallel straight passes, zig-zag, a constant step apart in XY.
    Raster,
    /// A spiral from the rim to the centre with a constant radial step in XY.
    Spiral,
    /// A spiral whose radial step keeps the scallop at `scallop_mm` everywhere, from the
    /// local meridian curvature and slope.
    ConstantScallop,
}

#[derive(Debug, Clone, PartialEq)]
pub struct MillingSetup {
    pub tool: MillingTool,
    /// Cutting edges (feed marks need feed_per_tooth_mm > 0 too).
    pub teeth: u32,
    pub path: MillingPathKind,
    /// Step between passes in XY (raster, spiral); for constant_scallop the tightest
    /// spacing of its turns along the surface (planned).
    pub stepover_mm: f64,
    /// Target scallop height (constant_scallop).
    pub scallop_mm: f64,
    /// Direction of the raster passes from +X.
    pub raster_angle_rad: f64,
    /// Five-axis: the axis follows the normal (leaned by lead/tilt); three-axis: it is Z.
    pub five_axis: bool,
    /// Lead λ at the path's start and end, linear in between (five-axis).
    pub lead_rad: [f64; 2],
    /// Tilt ω at the path's start and end.
    pub tilt_rad: [f64; 2],
    /// A disc cutter's turn ξ about the normal away from square to the feed.
    pub turn_rad: f64,
    /// Advance per tooth (0 = no feed marks: the tool body sweeps continuously).
    pub feed_per_tooth_mm: f64,
    /// How the teeth cut, with a feed per tooth.
    pub flutes: Flutes,
    pub spindle_rpm: Option<f64>,
    pub stock_allowance_mm: f64,
    pub depth_of_cut_mm: f64,
    /// The contact path covers the part out to this radius (for a cylinder: out to this
    /// distance across its axis).
    pub contact_radius_mm: f64,
    /// A cylinder's length along Y (its profile extruded along Y); `None` for parts of
    /// revolution.
    pub part_length_mm: Option<f64>,
}

/// How a milling tool's teeth cut (with a feed per tooth): each as its edge — the cut at
/// a point is made where the edge passes it, sweeping its trochoid — or as the tool
/// body at the tooth's position; the edges with a helix and per-tooth runout.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Flutes {
    pub edges: bool,
    /// Helix angle β of a constant-lead flute: the edge lags tan β / R radians per mm of
    /// height above the tip (R the tool's outer radius).
    pub helix_rad: f64,
    /// Per tooth: its edge beyond the nominal radius (mm, ≥ 0); empty: none.
    pub radial_runout_mm: Vec<f64>,
    /// Per tooth: its tip below the nominal tip along the axis (mm); empty: none.
    pub axial_runout_mm: Vec<f64>,
}

/// How poses between two nodes are interpolated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// Straight lines (raster passes).
    Linear,
    /// Radius, angle and height linear (spiral turns).
    Polar,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathNode {
    /// Arc length of the tool-centre path from the start of the whole path.
    pub arc_mm: f64,
    pub pose: CutterPose,
    /// The centre's (radius, unwrapped angle, height), for polar interpolation.
    pub polar: DVec3,
}

impl PathNode {
    /// Moves the pose centre by `offset`, keeping the polar form (and its unwrapped
    /// angle) in step.
    pub fn translate(&mut self, offset: DVec3) {
        let centre = self.pose.centre + offset;
        let turn = centre.y.atan2(centre.x) - self.pose.centre.y.atan2(self.pose.centre.x);
        let turn = (turn + PI).rem_euclid(TAU) - PI;
        self.polar = DVec3::new(centre.truncate().length(), self.polar.y + turn, centre.z);
        self.pose.centre = centre;
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct MillingPass {
    pub interpolation: Interpolation,
    pub nodes: Vec<PathNode>,
}

impl MillingPass {
    pub fn start_arc(&self) -> f64 {
        self.nodes[0].arc_mm
    }

    pub fn end_arc(&self) -> f64 {
        self.nodes[self.nodes.len() - 1].arc_mm
    }

    /// The nodes either side of path arc length `arc` (clamped to the pass) and the
    /// fraction of the way between them.
    fn segment_at(&self, arc: f64) -> (&PathNode, &PathNode, f64) {
        let nodes = &self.nodes;
        let i = nodes
            .partition_point(|n| n.arc_mm <= arc)
            .clamp(1, nodes.len() - 1);
        let (a, b) = (&nodes[i - 1], &nodes[i]);
        let span = b.arc_mm - a.arc_mm;
        let t = if span > 0.0 {
            ((arc - a.arc_mm) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (a, b, t)
    }

    /// The pose at path arc length `arc` (clamped to the pass).
    pub fn pose_at(&self, arc: f64) -> CutterPose {
        let (a, b, t) = self.segment_at(arc);
        let centre = match self.interpolation {
            Interpolation::Linear => a.pose.centre.lerp(b.pose.centre, t),
            Interpolation::Polar => {
                let p = a.polar.lerp(b.polar, t);
                DVec3::new(p.x * p.y.cos(), p.x * p.y.sin(), p.z)
            }
        };
        CutterPose::new(centre, a.pose.axis.lerp(b.pose.axis, t).normalize())
    }

    /// The unit direction of travel of the pose centre at path arc length `arc` (the
    /// derivative of the interpolation; zero where the centre stands still).
    pub fn feed_direction_at(&self, arc: f64) -> DVec3 {
        let (a, b, t) = self.segment_at(arc);
        let velocity = match self.interpolation {
            Interpolation::Linear => b.pose.centre - a.pose.centre,
            Interpolation::Polar => {
                let p = a.polar.lerp(b.polar, t);
                let d = b.polar - a.polar;
                let (sin, cos) = p.y.sin_cos();
                DVec3::new(
                    d.x * cos - p.x * d.y * sin,
                    d.x * sin + p.x * d.y * cos,
                    d.z,
                )
            }
        };
        velocity.normalize_or_zero()
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct MillingPath {
    pub passes: Vec<MillingPass>,
}

impl MillingPath {
    pub fn length_mm(&self) -> f64 {
        self.passes.last().map_or(0.0, MillingPass::end_arc)
    }

    pub fn node_count(&self) -> usize {
        self.passes.iter().map(|p| p.nodes.len()).sum()
    }
}

/// Largest chord deviation allowed between raster nodes (mm).
pub const CHORD_TOLERANCE_MM: f64 = 1e-7;
/// Spiral nodes per turn.
pub const SPIRAL_NODES_PER_TURN: usize = 720;

impl MillingSetup {
    /// The tool axis at a contact (normal n, feed direction along the tangent plane).
    pub fn tool_axis(&self, normal: DVec3, feed: DVec3, progress: f64) -> DVec3 {
        let lead = self.lead_rad[0] + (self.lead_rad[1] - self.lead_rad[0]) * progress;
        let tilt = self.tilt_rad[0] + (self.tilt_rad[1] - self.tilt_rad[0]) * progress;
        let x1 = (feed - feed.dot(normal) * normal).normalize_or(DVec3::X);
        let y1 = normal.cross(x1);
        match self.tool {
            // A disc cutter's axis lies across the feed in the tangent plane, turned by ξ.
            MillingTool::Disc(_) => {
                (self.turn_rad.cos() * y1 + self.turn_rad.sin() * x1).normalize()
            }
            MillingTool::EndMill(_) if !self.five_axis => DVec3::Z,
            MillingTool::EndMill(_) => {
                (lead.cos() * normal + lead.sin() * (tilt.cos() * x1 + tilt.sin() * y1)).normalize()
            }
        }
    }

    /// Plans the path over `surface`.
    pub fn plan(&self, surface: &SurfaceOfRevolution) -> MillingPath {
        let contacts = match (self.path, self.part_length_mm) {
            (MillingPathKind::Raster, Some(length)) => self.cylinder_contacts(surface, length),
            (MillingPathKind::Raster, None) => self.raster_contacts(surface),
            _ => self.spiral_contacts(surface),
        };
        let interpolation = match self.path {
            MillingPathKind::Raster => Interpolation::Linear,
            _ => Interpolation::Polar,
        };
        let total: usize = contacts.iter().map(Vec::len).sum::<usize>().max(2);
        let mut done = 0usize;
        let lift = self.stock_allowance_mm - self.depth_of_cut_mm;
        let mut arc = 0.0;
        let mut previous: Option<DVec3> = None;
        let mut passes = Vec::with_capacity(contacts.len());
        for pass_contacts in contacts {
            let mut nodes = Vec::with_capacity(pass_contacts.len());
            let mut unwrapped: Option<f64> = None;
            for (i, &contact) in pass_contacts.iter().enumerate() {
                let normal = self.surface_normal(surface, contact);
                // Feed direction: toward the next contact (or from the previous one).
                let next = pass_contacts.get(i + 1).copied();
                let feed = match next {
                    Some(n) => n - contact,
                    None if i > 0 => contact - pass_contacts[i - 1],
                    None => DVec3::X,
                };
                let progress = done as f64 / (total - 1) as f64;
                done += 1;
                let axis = self.tool_axis(normal, feed, progress);
                let mut pose = self.tool.touching_pose(contact, normal, axis);
                pose.centre += lift * normal;
                if let Some(p) = previous {
                    arc += (pose.centre - p).length();
                }
                previous = Some(pose.centre);
                let angle = pose.centre.y.atan2(pose.centre.x);
                let theta = match unwrapped {
                    None => angle,
                    Some(last) => {
                        last + (angle - last + std::f64::consts::PI).rem_euclid(TAU)
                            - std::f64::consts::PI
                    }
                };
                unwrapped = Some(theta);
                nodes.push(PathNode {
                    arc_mm: arc,
                    pose,
                    polar: DVec3::new(pose.centre.truncate().length(), theta, pose.centre.z),
                });
            }
            if nodes.len() >= 2 {
                passes.push(MillingPass {
                    interpolation,
                    nodes,
                });
            }
        }
        MillingPath { passes }
    }

    /// The part's outward normal at a contact point: revolved about Z, or (a cylinder)
    /// the profile's normal in the XZ plane.
    fn surface_normal(&self, surface: &SurfaceOfRevolution, contact: DVec3) -> DVec3 {
        match self.part_length_mm {
            Some(_) => {
                let n = surface.normal(contact.x.abs());
                DVec3::new(n.x * contact.x.signum(), 0.0, n.y)
            }
            None => {
                let radius = contact.truncate().length();
                let n = surface.normal(radius);
                let radial = if radius > 0.0 {
                    contact.truncate() / radius
                } else {
                    DVec2::X
                };
                DVec3::new(n.x * radial.x, n.x * radial.y, n.y)
            }
        }
    }

    /// A cylinder's raster: passes along its axis (Y), a step apart in arc length around
    /// its profile (as indexing it on a rotary table does), one over the crest, zig-zag;
    /// the passes run a node past each end.
    fn cylinder_contacts(&self, surface: &SurfaceOfRevolution, length: f64) -> Vec<Vec<DVec3>> {
        let meridian = crate::geometry::MeridianArcLength::new(surface, self.contact_radius_mm);
        let limit = meridian.arc_length_at(self.contact_radius_mm);
        let spacing = (0.25 * self.tool.reach_mm()).min(0.05);
        let half = 0.5 * length + 2.0 * spacing;
        let count = ((2.0 * half / spacing).ceil() as usize).max(1);
        let reach = (limit / self.stepover_mm).floor() as i64;
        (-reach..=reach)
            .map(|k| {
                let arc = k as f64 * self.stepover_mm;
                let x = meridian.radius_at(arc.abs()).copysign(arc);
                let z = surface.height(x.abs());
                let mut points: Vec<DVec3> = (0..=count)
                    .map(|i| DVec3::new(x, -half + 2.0 * half * i as f64 / count as f64, z))
                    .collect();
                if k.rem_euclid(2) == 1 {
                    points.reverse();
                }
                points
            })
            .collect()
    }

    /// Node spacing along raster passes from the chord tolerance and the surface's largest
    /// curvature (capped at a quarter of the tool's reach).
    fn raster_node_spacing(&self, surface: &SurfaceOfRevolution) -> f64 {
        let steps = 400;
        let curvature = (0..=steps)
            .map(|i| {
                let r = self.contact_radius_mm * i as f64 / steps as f64;
                let meridional = surface.meridional_curvature(r).abs();
                let slope = surface.slope(r);
                let sagittal = if r > 0.0 {
                    (slope / (r * (1.0 + slope * slope).sqrt())).abs()
                } else {
                    meridional
                };
                meridional.max(sagittal)
            })
            .fold(0.0, f64::max);
        let chord = if curvature > 0.0 {
            (8.0 * CHORD_TOLERANCE_MM / curvature).sqrt()
        } else {
            f64::INFINITY
        };
        // Capped so the node search of the engine stays tight (a cutting pose may lie
        // anywhere between two nodes).
        chord.min(0.05).min(0.25 * self.tool.reach_mm()).max(1e-4)
    }

    /// Raster contacts: straight passes `stepover` apart across the contact disc, one
    /// through the axis, zig-zag.
    fn raster_contacts(&self, surface: &SurfaceOfRevolution) -> Vec<Vec<DVec3>> {
        let (sin, cos) = self.raster_angle_rad.sin_cos();
        let along = DVec2::new(cos, sin);
        let across = DVec2::new(-sin, cos);
        let limit = self.contact_radius_mm;
        let spacing = self.raster_node_spacing(surface);
        // Offsets k·step, so the middle pass runs through the axis.
        let reach = (limit / self.stepover_mm).floor() as i64;
        (-reach..=reach)
            .map(|k| {
                let offset = k as f64 * self.stepover_mm;
                let half = (limit * limit - offset * offset).max(0.0).sqrt();
                let count = ((2.0 * half / spacing).ceil() as usize).max(1);
                let mut points: Vec<DVec3> = (0..=count)
                    .map(|i| {
                        let u = -half + 2.0 * half * i as f64 / count as f64;
                        let xy = u * along + offset * across;
                        DVec3::new(xy.x, xy.y, surface.height(xy.length()))
                    })
                    .collect();
                if k.rem_euclid(2) == 1 {
                    points.reverse();
                }
                points
            })
            .collect()
    }

    /// Radial step in XY at contact radius `r`: constant, or the one that leaves the target
    /// scallop between neighbouring turns given the meridian's curvature there.
    pub fn radial_step(&self, surface: &SurfaceOfRevolution, r: f64) -> f64 {
        match self.path {
            MillingPathKind::ConstantScallop => {
                // Positive curvature: hollow toward the tool (concave there).
                let curvature = surface.meridional_curvature(r);
                let spacing = stepover_for_scallop(
                    self.scallop_mm,
                    self.profile_radius_mm(),
                    curvature.abs(),
                    curvature < 0.0,
                );
                spacing / surface.arc_length_rate(r)
            }
            _ => self.stepover_mm,
        }
    }

    /// Radius of the tool's profile in the plane across the feed at its contact: the
    /// ball's or the corner's radius; a flat end's effective radius r cos²ω / sin λ.
    pub fn profile_radius_mm(&self) -> f64 {
        match self.tool {
            MillingTool::EndMill(cutter) if cutter.corner_radius_mm > 0.0 => {
                cutter.corner_radius_mm
            }
            MillingTool::EndMill(cutter) => crate::geometry::formulas::effective_radius(
                cutter.major_radius_mm,
                self.lead_rad[0],
                self.tilt_rad[0],
            ),
            MillingTool::Disc(disc) => crate::geometry::formulas::oblique_section_radius(
                disc.diameter_mm,
                disc.side_rake_rad,
                self.turn_rad,
            ),
        }
    }

    /// Spiral contacts from the rim to the centre, split into turns.
    fn spiral_contacts(&self, surface: &SurfaceOfRevolution) -> Vec<Vec<DVec3>> {
        let step_angle = TAU / SPIRAL_NODES_PER_TURN as f64;
        let mut turns = Vec::new();
        let mut turn = Vec::with_capacity(SPIRAL_NODES_PER_TURN + 1);
        let (mut r, mut theta) = (self.contact_radius_mm, 0.0f64);
        let point =
            |r: f64, theta: f64| DVec3::new(r * theta.cos(), r * theta.sin(), surface.height(r));
        // dr/dθ = −step(r)/2π, integrated with RK4 on a table of the step (planning a
        // constant-scallop step is a root search; the table keeps it to once per entry).
        const TABLE: usize = 4096;
        let limit = self.contact_radius_mm;
        let table: Vec<f64> = (0..=TABLE)
            .map(|i| self.radial_step(surface, limit * i as f64 / TABLE as f64))
            .collect();
        let rate = |r: f64| {
            let u = (r.max(0.0) / limit * TABLE as f64).min(TABLE as f64);
            let i = (u.floor() as usize).min(TABLE - 1);
            let t = u - i as f64;
            -(table[i] + t * (table[i + 1] - table[i])) / TAU
        };
        let mut index = 0usize;
        loop {
            turn.push(point(r, theta));
            if r <= 0.0 {
                break;
            }
            let k1 = rate(r);
            let k2 = rate(r + 0.5 * step_angle * k1);
            let k3 = rate(r + 0.5 * step_angle * k2);
            let k4 = rate(r + step_angle * k3);
            r = (r + step_angle / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)).max(0.0);
            theta += step_angle;
            index += 1;
            if index.is_multiple_of(SPIRAL_NODES_PER_TURN) {
                let last = *turn.last().expect("a turn has points");
                turns.push(std::mem::take(&mut turn));
                turn.push(last); // turns share their boundary node
            }
        }
        if turn.len() >= 2 {
            turns.push(turn);
        }
        turns
    }
}

/// The spacing between passes along the surface that leaves a scallop `scallop` between
/// round profiles of radius `profile` on a section of curvature `curvature` (1/mm,
/// ≥ 0): the exact inverse of `sphere_scallop_height` (flat: `ball_stepover_for_scallop`),
/// by bisection.
pub fn stepover_for_scallop(scallop: f64, profile: f64, curvature: f64, convex: bool) -> f64 {
    let flat = ball_stepover_for_scallop(2.0 * profile, scallop);
    if curvature.abs() < 1e-12 {
        return flat;
    }
    let radius = 1.0 / curvature.abs();
    let height = |spacing: f64| sphere_scallop_height(profile, radius, spacing / radius, convex);
    let (mut lo, mut hi) = (0.0, 4.0 * flat);
    while height(hi) < scallop && hi < 2.0 * profile {
        hi *= 2.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if height(mid) < scallop {
            lo = mid
        } else {
            hi = mid
        }
    }
    0.5 * (lo + hi)
}

//! The f64 reference removal for milling scenes — the twin of `shaders/milling.wgsl`,
//! step for step: change them together. Which passes can cut a sample:
//! `milling_scene.rs`; the search along a pass: `milling_search.rs`.
//!
//! Everything is done in the sample's own frame: origin at its nominal point, axes
//! (e_r, e_φ, e_z) at its azimuth (a part of revolution) or (x, y, z) (an extruded one),
//! so a pose is its centre's offset Δ from the sample and its axis, and the dexel ray is
//! t·n. A node's offset comes from its cylindrical coordinates without cancelling:
//! Δ = ((ρ − r) − 2ρ sin²(δ/2), 2ρ sin(δ/2) cos(δ/2), z − z_s), δ the azimuth difference —
//! the form the f32 kernel needs to resolve nanometres on a 20 mm part.
//!
//! Per candidate pass the cut is the lowest entry of the ray into the tool over the
//! pass's poses. The pass is *located*: its point nearest the sample's anchor (for a
//! ball the sample itself: the cutting pose is the centre-path point nearest the entry
//! point; for other tools the expected centre). For a ball on a pass that cannot come
//! round to the sample twice, a bracket about that point is widened downhill; otherwise
//! the pass's nodes near it are scanned. The bracket is narrowed and refined (Brent's
//! method; golden-section steps at a flat end's or a disc's kinked rim). The entry at
//! each pose is closed form (ball: sphere and shank; flat end: tip plane and cylinder;
//! disc: the hyperboloid's quadratic) or Newton's steps on a convex distance
//! (bull-nose). Where the ray misses or enters above the stock top, the entry is
//! extended by the stock-top point's distance from the tool, which keeps it continuous
//! and steers the search toward the tool. With teeth only the stamps (tooth positions)
//! around the optimum cut; displaced teeth: every stamp over the span. Passes are
//! searched in the order of their cut at the located point; for a ball the search stops
//! once that, less the slack between nodes, cannot beat the best.

use super::milling_scene::{
    Candidate, CandidateList, Edges, MAX_CANDIDATES, MillingScene, Node, PassSpan,
};
use super::milling_search::{GOLDEN, REFINE_GAIN_MM, REFINE_WIDTH, narrow, refine, scan, widen};
use crate::field::{Layout, NO_PASS};
use crate::geometry::cutter::CutterPose;
use crate::geometry::milling_tool::MillingTool;
use glam::DVec3;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Depths closer than this count as a tie (1e-13 mm, far below any resolved feature).
pub const TIE_MM: f64 = 1e-13;

/// A sample's dexel ray in its own frame.
#[derive(Debug, Clone, Copy)]
pub struct SampleFrame {
    polar: bool,
    /// Polar: distance from Z, height and azimuth; extruded: the point (x, y, z).
    radius_mm: f64,
    height_mm: f64,
    azimuth_rad: f64,
    y_mm: f64,
    cos: f64,
    sin: f64,
    /// The ray's direction in the frame: (n_r, 0, n_z).
    pub normal: DVec3,
    /// The sample point and normal in the machine frame (for the bins).
    pub world_point: DVec3,
    pub world_normal: DVec3,
}

impl SampleFrame {
    pub fn new(scene: &MillingScene, ring: usize, row: u32) -> Self {
        let grid = &scene.grid;
        let r = &grid.rings[ring];
        let polar = grid.layout == Layout::Polar;
        let azimuth_rad = if polar { grid.azimuth_rad(row) } else { 0.0 };
        let (sin, cos) = azimuth_rad.sin_cos();
        Self {
            polar,
            radius_mm: r.radius_mm,
            height_mm: r.height_mm,
            azimuth_rad,
            y_mm: grid.row_y_mm(row),
            cos,
            sin,
            normal: DVec3::new(r.normal.x, 0.0, r.normal.y),
            world_point: grid.sample_point(ring, row),
            world_normal: grid.sample_normal(ring, row),
        }
    }

    /// A machine-frame direction in this frame.
    pub fn direction(&self, v: DVec3) -> DVec3 {
        if self.polar {
            DVec3::new(
                v.x * self.cos + v.y * self.sin,
                -v.x * self.sin + v.y * self.cos,
                v.z,
            )
        } else {
            v
        }
    }

    /// A node's azimuth less the sample's, in (−π, π].
    fn delta(&self, node: &Node) -> f64 {
        wrap_angle(node.angle_rad - self.azimuth_rad)
    }

    /// A node's centre relative to the sample, in this frame.
    pub fn offset(&self, node: &Node) -> DVec3 {
        if self.polar {
            let z = node.centre.z - self.height_mm;
            polar_offset(
                node.radius_mm - self.radius_mm,
                node.radius_mm,
                self.delta(node),
                z,
            )
        } else {
            node.centre - DVec3::new(self.radius_mm, self.y_mm, self.height_mm)
        }
    }
}

/// The offset of the point ρ from Z (given as ρ − r and ρ), δ past the sample's
/// azimuth, z − z_s above it.
fn polar_offset(rho_less_r: f64, rho: f64, delta: f64, z_less: f64) -> DVec3 {
    let (sin_half, cos_half) = sin_cos_small(0.5 * delta);
    DVec3::new(
        rho_less_r - 2.0 * rho * sin_half * sin_half,
        2.0 * rho * sin_half * cos_half,
        z_less,
    )
}

/// sin and cos of an angle, by their Taylor series where that is exact in f64 (the
/// azimuths between a sample and the nodes near it are mostly small).
fn sin_cos_small(x: f64) -> (f64, f64) {
    if x.abs() > 0.02 {
        return x.sin_cos();
    }
    // Truncation below x⁹/9! < 1e-21 relative.
    let x2 = x * x;
    let sin = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)));
    let cos = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0)));
    (sin, cos)
}

/// The difference of two angles in [0, 2π), brought into (−π, π].
fn wrap_angle(angle: f64) -> f64 {
    if angle > PI {
        angle - TAU
    } else if angle <= -PI {
        angle + TAU
    } else {
        angle
    }
}

/// A pose in a sample's frame: the centre's offset from the sample, the unit axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalPose {
    pub centre: DVec3,
    pub axis: DVec3,
}

impl LocalPose {
    fn cutter(&self) -> CutterPose {
        CutterPose::new(self.centre, self.axis)
    }
}

/// A pass's poses in a sample's frame, interpolated as the planner does: centres
/// linearly (raster) or in cylindrical coordinates (spiral turns), axes linearly and
/// normalised. The segment last used is held (the kernel's `Segment`), so consecutive
/// evaluations within it read no nodes: linear, `a` and `b` the nodes' offsets and
/// `step` the machine-frame step from a to b turned into the frame (its direction is
/// the feed's: the kernel's difference of two offsets a few mm long would lose it);
/// polar, `a` = (ρ_a − r, δ_a, z_a − z_s) and `b` the polar steps to the next node.
pub struct PassPoses<'a> {
    frame: &'a SampleFrame,
    span: &'a PassSpan,
    nodes: &'a [Node],
    segment: Option<Segment>,
}

#[derive(Debug, Clone, Copy)]
struct Segment {
    index: usize,
    a: DVec3,
    b: DVec3,
    rho: f64,
    axis_a: DVec3,
    axis_b: DVec3,
    /// The unit axis all along, where both nodes hold the same one (3-axis paths),
    /// normalised once: the interpolation would give it again at every pose, up to
    /// rounding.
    fixed_axis: Option<DVec3>,
    step: DVec3,
}

impl<'a> PassPoses<'a> {
    pub fn new(scene: &'a MillingScene, frame: &'a SampleFrame, pass: u32) -> Self {
        Self {
            frame,
            span: &scene.passes[pass as usize],
            nodes: scene.pass_nodes(pass),
            segment: None,
        }
    }

    fn polar(&self) -> bool {
        self.span.polar && self.frame.polar
    }

    /// The segment holding node coordinate `u`, and the fraction along it.
    fn segment(&mut self, u: f64) -> (Segment, f64) {
        let last = self.nodes.len() - 1;
        let i = (u.floor().max(0.0) as usize).min(last.saturating_sub(1));
        let t = (u - i as f64).clamp(0.0, 1.0);
        if self.segment.is_none_or(|s| s.index != i) {
            let frame = self.frame;
            let (na, nb) = (&self.nodes[i], &self.nodes[(i + 1).min(last)]);
            let (a, b, rho, step) = if self.polar() {
                let z = na.centre.z - frame.height_mm;
                let a = DVec3::new(na.radius_mm - frame.radius_mm, frame.delta(na), z);
                (a, na.polar_step, na.radius_mm, DVec3::ZERO)
            } else {
                let step = frame.direction(nb.centre - na.centre);
                (frame.offset(na), frame.offset(nb), 0.0, step)
            };
            let (axis_a, axis_b) = (frame.direction(na.axis), frame.direction(nb.axis));
            self.segment = Some(Segment {
                index: i,
                a,
                b,
                rho,
                axis_a,
                axis_b,
                fixed_axis: (axis_a == axis_b).then(|| axis_a.normalize()),
                step,
            });
        }
        (self.segment.expect("just set"), t)
    }

    pub fn pose(&mut self, u: f64) -> LocalPose {
        let (g, t) = self.segment(u);
        let centre = if self.polar() {
            let s = g.b;
            polar_offset(
                g.a.x + t * s.x,
                g.rho + t * s.x,
                g.a.y + t * s.y,
                g.a.z + t * s.z,
            )
        } else {
            g.a + t * (g.b - g.a)
        };
        let axis = match g.fixed_axis {
            Some(axis) => axis,
            None => g.axis_a.lerp(g.axis_b, t).normalize(),
        };
        LocalPose { centre, axis }
    }

    /// The unit direction of travel of the pose centre at `u` (the derivative of the
    /// interpolation; zero where the centre stands still).
    pub fn feed(&mut self, u: f64) -> DVec3 {
        let (g, t) = self.segment(u);
        let velocity = if self.polar() {
            let s = g.b;
            let (rho, delta) = (g.rho + t * s.x, g.a.y + t * s.y);
            let (sin, cos) = delta.sin_cos();
            DVec3::new(
                s.x * cos - rho * s.y * sin,
                s.x * sin + rho * s.y * cos,
                s.z,
            )
        } else {
            g.step
        };
        velocity.normalize_or_zero()
    }

    /// The extended entry at `u`.
    pub fn entry(&mut self, scene: &MillingScene, u: f64) -> f64 {
        let pose = self.pose(u);
        extended_entry(scene, self.frame, &pose)
    }
}

/// The entry of the ray t·n into the tool at `pose`, extended above the stock top by
/// the stock-top point's distance from the tool.
pub fn extended_entry(scene: &MillingScene, frame: &SampleFrame, pose: &LocalPose) -> f64 {
    tool_entry(&scene.tool, scene.stock_top_mm, frame, pose)
}

/// `extended_entry` for a given tool (a tooth's own solid) below the stock top `top`.
fn tool_entry(tool: &MillingTool, top: f64, frame: &SampleFrame, pose: &LocalPose) -> f64 {
    let cutter = pose.cutter();
    match tool.ray_entry(&cutter, DVec3::ZERO, frame.normal) {
        Some(entry) if entry < top => entry,
        _ => top + tool.signed_distance(&cutter, top * frame.normal).max(0.0),
    }
}

/// One pass's cut at a sample: the depth along the ray, where on the pass (node
/// coordinate) and the pose that made it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassCut {
    pub depth_mm: f64,
    pub node: f64,
    pub pose: LocalPose,
}

/// Where along a candidate pass a sample can be cut: its nodes from `lo` to `hi` (those
/// within the search radius of the expected centre, a scan step wider each side), the
/// point of the pass nearest the sample's anchor (node coordinate) and the extended
/// entry there (an upper bound of the pass's cut).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Located {
    pub pass: u32,
    pub lo: u32,
    pub hi: u32,
    pub nearest: f64,
    pub estimate: f64,
}

/// Locates a candidate pass: its point nearest the anchor from where the pass's
/// geometry puts it (a spiral turn's node at the anchor's azimuth, a raster pass's
/// projection onto its line), downhill node by node, then projected onto the better
/// adjacent segment.
pub fn locate(scene: &MillingScene, frame: &SampleFrame, candidate: Candidate) -> Located {
    let span = &scene.passes[candidate.pass as usize];
    let nodes = scene.pass_nodes(candidate.pass);
    let last = span.node_count - 1;
    let (lo, hi) = (
        candidate.first.saturating_sub(1),
        (candidate.last + 1).min(last),
    );
    let middle = nodes[((lo + hi) / 2) as usize].axis;
    let (expected, radius) = scene.expected_centre(frame.world_point, frame.world_normal, middle);
    let ball = scene.ball_slack.is_some();
    let anchor = if ball { frame.world_point } else { expected };
    let azimuth = if ball && frame.polar {
        frame.azimuth_rad
    } else {
        anchor.y.atan2(anchor.x)
    };
    let distance = |i: u32| (nodes[i as usize].centre - anchor).length_squared();
    let (mut nearest, mut d) = (lo, f64::INFINITY);
    for guess in span.nearest_guesses(anchor, azimuth) {
        let node = guess.clamp(lo as f64, hi as f64).round() as u32;
        let at = distance(node);
        if at < d {
            (nearest, d) = (node, at);
        }
    }
    let (nearest, d) = walk_downhill(distance, nearest, d, lo, hi);
    // Onto the adjacent segments (in machine coordinates: a node spacing's fraction).
    let project = |i: u32| {
        let (a, b) = (nodes[i as usize].centre, nodes[i as usize + 1].centre);
        let along = b - a;
        let t = ((anchor - a).dot(along) / along.length_squared().max(1e-300)).clamp(0.0, 1.0);
        (i as f64 + t, (a + t * along - anchor).length_squared())
    };
    let mut point = (nearest as f64, d);
    for i in [
        nearest.saturating_sub(1).max(lo),
        nearest.min(hi.saturating_sub(1)),
    ] {
        if i < hi {
            let p = project(i);
            if p.1 < point.1 {
                point = p;
            }
        }
    }
    // Nodes within the radius of the expected centre, and a scan step more.
    let s = nearest.min(last - 1) as usize;
    let step = (nodes[s + 1].centre - nodes[s].centre).length();
    let half = (radius / step.max(1e-12)).ceil() + span.stride as f64;
    let half = half.min((hi - lo) as f64) as u32;
    let mut poses = PassPoses::new(scene, frame, candidate.pass);
    Located {
        pass: candidate.pass,
        lo: nearest.saturating_sub(half).max(lo),
        hi: (nearest + half).min(hi),
        nearest: point.0,
        estimate: poses.entry(scene, point.0),
    }
}

/// From node `nearest` (at distance `d`) downhill node by node, toward `lo` and then
/// toward `hi`, across runs of equal distances (coincident nodes, as where a spiral
/// ends on the axis, or nodes f32 cannot tell apart) when a strictly nearer node lies
/// past them.
fn walk_downhill(
    distance: impl Fn(u32) -> f64,
    mut nearest: u32,
    mut d: f64,
    lo: u32,
    hi: u32,
) -> (u32, f64) {
    for down in [true, false] {
        loop {
            let mut k = nearest;
            let next = loop {
                if (down && k == lo) || (!down && k == hi) {
                    break None;
                }
                k = if down { k - 1 } else { k + 1 };
                let at = distance(k);
                if at != d {
                    break Some(at);
                }
            };
            match next {
                Some(at) if at < d => (nearest, d) = (k, at),
                _ => break,
            }
        }
    }
    (nearest, d)
}

/// The lowest cut of a located pass on the sample's ray (None: it stays above the
/// stock top). For an end mill on a pass that cannot come round to the sample twice (a
/// raster pass, or less than a quarter of a spiral's turn in reach) the entry has one
/// valley — the poses whose entry lies below a depth are those whose centre lies in the
/// convex set the ray segment less the (convex) tool sweeps out, an interval of a
/// straight pass — so a bracket about the located point is widened until the entry
/// rises on both sides. Otherwise its nodes are scanned `stride` apart and half a node
/// either side of the located point, and the best bracket narrowed to one valley. Then
/// the bracket is refined; with teeth, the stamps there.
pub fn pass_cut(scene: &MillingScene, frame: &SampleFrame, located: &Located) -> Option<PassCut> {
    let span = &scene.passes[located.pass as usize];
    let mut poses = PassPoses::new(scene, frame, located.pass);
    let entry = &mut |u: f64| poses.entry(scene, u);
    let (lo, hi) = (located.lo as f64, located.hi as f64);
    let single_valley = matches!(scene.tool, MillingTool::EndMill(_))
        && (!span.polar || (hi - lo) * span.step.y.abs() < FRAC_PI_2);
    let start = (located.nearest, located.estimate);
    let bracket = if single_valley {
        widen(entry, start, lo, hi)
    } else {
        let near = [(start.0 - 0.5).max(lo), start.0, (start.0 + 0.5).min(hi)];
        scan(entry, located.lo, located.hi, span.stride, near, start.1)
    };
    let stamps = &scene.stamps;
    // Displaced teeth as bodies: every stamp over the span is tried, no optimum needed.
    let every_stamp =
        stamps.feed_per_tooth_mm > 0.0 && stamps.edges.is_none() && !stamps.offsets_mm.is_empty();
    let best = if every_stamp {
        bracket.best
    } else {
        let bracket = if single_valley {
            bracket
        } else {
            narrow(entry, bracket)
        };
        refine(
            entry,
            bracket,
            scene.tool.is_smooth(),
            REFINE_GAIN_MM,
            REFINE_WIDTH,
        )
    };
    if stamps.feed_per_tooth_mm > 0.0 {
        return stamp_cut(scene, &mut poses, located, best.0);
    }
    (best.1 < scene.stock_top_mm).then(|| PassCut {
        depth_mm: best.1,
        node: best.0,
        pose: poses.pose(best.0),
    })
}

/// With teeth: the lowest cut of the stamps (tooth positions) around the pass's
/// continuous optimum at node coordinate `node`: as bodies, the nearest ones, or with
/// displaced teeth every stamp over the located span; as edges, `edges_cut`.
fn stamp_cut(
    scene: &MillingScene,
    poses: &mut PassPoses,
    located: &Located,
    node: f64,
) -> Option<PassCut> {
    let nodes = poses.nodes;
    let last = nodes.len() - 1;
    let stamps = &scene.stamps;
    let mut walker = StampWalker::new(nodes, node);
    if let Some(edges) = &stamps.edges {
        return edges_cut(scene, poses, &mut walker, node, edges);
    }
    let nearest = walker.teeth_at(node).floor();
    let (from, to) = if stamps.offsets_mm.is_empty() {
        (nearest - 1.0, nearest + 2.0)
    } else {
        let (lo, hi) = (located.lo as usize, located.hi as usize);
        (nodes[lo].teeth.ceil(), nodes[hi].teeth.floor())
    };
    let mut best: Option<PassCut> = None;
    let mut k = from.max(nodes[0].teeth.ceil());
    while k <= to.min(nodes[last].teeth.floor()) {
        let u = walker.node_at(k);
        let pose = stamp_pose(poses, &stamps.offsets_mm, k, u, 0.0);
        let cut = PassCut {
            depth_mm: extended_entry(scene, poses.frame, &pose),
            node: u,
            pose,
        };
        keep_lower(&mut best, cut, scene.stock_top_mm);
        k += 1.0;
    }
    best
}

/// Keeps `cut` if it lies below the stock top and below the best so far.
fn keep_lower(best: &mut Option<PassCut>, cut: PassCut, stock_top_mm: f64) {
    if cut.depth_mm < stock_top_mm && best.is_none_or(|b| cut.depth_mm < b.depth_mm) {
        *best = Some(cut);
    }
}

/// Teeth as edges: the lowest of the stamps' edge cuts (`edge_cut`), taken outward
/// from the pass's continuous optimum (node coordinate `node`) each way until the
/// tool body, at the position nearest the optimum that the stamp's window reaches,
/// less the teeth's reach beyond the nominal tool, lies no lower than the best cut: no
/// edge cuts deeper than its tooth's solid, and the body rises away from the optimum.
/// (A fixed ±(z/2 + 1) stamps missed deeper passes of a leaned flat end's edges.)
fn edges_cut(
    scene: &MillingScene,
    poses: &mut PassPoses,
    walker: &mut StampWalker,
    node: f64,
    edges: &Edges,
) -> Option<PassCut> {
    let nodes = poses.nodes;
    let (first, last) = (nodes[0].teeth.ceil(), nodes[nodes.len() - 1].teeth.floor());
    let optimum = walker.teeth_at(node);
    let half = 0.5 * edges.teeth as f64;
    let slack = scene.stamps.reach_beyond_mm();
    let scan = scan_frame(scene, poses, walker, node);
    let mut best: Option<PassCut> = None;
    for (mut k, step) in [(optimum.floor(), 1.0), (optimum.floor() - 1.0, -1.0)] {
        while (first..=last).contains(&k) {
            let nearest = optimum.clamp(k - half, k + half);
            let body = poses.pose(walker.node_at(nearest));
            let bound = extended_entry(scene, poses.frame, &body) - slack;
            if bound >= best.map_or(scene.stock_top_mm, |b| b.depth_mm) {
                break;
            }
            let mut tooth = ToothEdge::new(scene, poses, walker, edges, k);
            keep_lower(&mut best, edge_cut(&mut tooth, k, scan), scene.stock_top_mm);
            k += step;
        }
    }
    best
}

/// Where the sample lies from the tool's path at the pass's continuous optimum (node
/// coordinate `node`): the side (+1: to the left of the feed about the axis), and the
/// tooth count where the tool's axis runs abeam of it — the optimum moved by the
/// sample's lead over the axis, one feed per tooth per tooth count (the optimum found
/// to the search's gain can lie some way off it).
fn scan_frame(
    scene: &MillingScene,
    poses: &mut PassPoses,
    walker: &StampWalker,
    node: f64,
) -> Scan {
    let pose = poses.pose(node);
    let depth = extended_entry(scene, poses.frame, &pose);
    let entry = depth * poses.frame.normal - pose.centre;
    let radial = entry - entry.dot(pose.axis) * pose.axis;
    let (along, across) = spindle_frame(poses, node, pose.axis);
    Scan {
        side: if radial.dot(across) < 0.0 { -1.0 } else { 1.0 },
        on_path: radial.length() < EDGE_ON_PATH_MM,
        abeam: walker.teeth_at(node) + radial.dot(along) / scene.stamps.feed_per_tooth_mm,
    }
}

/// Node coordinates of tooth counts along a pass (`Node::teeth`, linear between
/// nodes), walking from the segment last used.
struct StampWalker<'a> {
    nodes: &'a [Node],
    segment: usize,
}

impl<'a> StampWalker<'a> {
    fn new(nodes: &'a [Node], node: f64) -> Self {
        let segment = (node.floor().max(0.0) as usize).min(nodes.len().saturating_sub(2));
        Self { nodes, segment }
    }

    /// The tooth count at node coordinate `u`.
    fn teeth_at(&self, u: f64) -> f64 {
        let last = self.nodes.len() - 1;
        let i = (u.floor().max(0.0) as usize).min(last.saturating_sub(1));
        let t = (u - i as f64).clamp(0.0, 1.0);
        self.nodes[i].teeth + t * (self.nodes[(i + 1).min(last)].teeth - self.nodes[i].teeth)
    }

    /// The node coordinate where the tooth count is `teeth` (clamped to the pass).
    fn node_at(&mut self, teeth: f64) -> f64 {
        let (nodes, last) = (self.nodes, self.nodes.len() - 1);
        while self.segment > 0 && nodes[self.segment].teeth > teeth {
            self.segment -= 1;
        }
        while self.segment + 1 < last && nodes[self.segment + 1].teeth < teeth {
            self.segment += 1;
        }
        let (a, b) = (
            nodes[self.segment].teeth,
            nodes[(self.segment + 1).min(last)].teeth,
        );
        let t = if b > a {
            ((teeth - a) / (b - a)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.segment as f64 + t
    }
}

/// Stamp k's tooth as its edge: its lowest cut where the edge passes the sample. At
/// tooth count k + σ the tooth has turned 2πσ/z past pointing along the feed; there
/// its solid (the tool with the edge's runout, displaced as the tooth is) meets the ray
/// at a point at angle ψ about the axis and height h above the tip, which the edge
/// reaches once the tooth has turned to ψ + lag(h). The edge passes the sample where
/// G(σ) = ψ + lag − turn is a whole number of turns, σ in [−z/2, z/2) (each pass of
/// the tooth belongs to one stamp). As the tool goes by, ψ swings through up to half
/// a turn, so a window can hold none, one, two or three passes (near the path, where
/// the edges' trochoids loop, ψ even outruns the turn): G is scanned (a swing of about
/// half a turn unwrapped round the side the sample lies on) and each whole turn it
/// crosses (ends included) refined by Illinois steps. (Secant steps from the stamp
/// that assume one pass per window missed the deeper of two passes, cuts ~800 nm
/// shallow, within 1.5 loop radii z·f_z/2π of the path.)
fn edge_cut(tooth: &mut ToothEdge, k: f64, scan: Scan) -> PassCut {
    let z = tooth.teeth;
    // The scan: points a step apart, off the stamp by a golden fraction of a step,
    // covering the window and a step more; `EDGE_ABEAM` either side of where the
    // tool's axis runs abeam of the sample, which split ψ's swing there (on the path,
    // a jump by half a turn) from the passes before and after it; and where the tooth
    // points along the feed or back (on the path, those passes), so that no two
    // crossings share an interval.
    let step = z / EDGE_SCAN as f64;
    let at = |i: u32| -0.5 * z + (i as f64 - 1.0 + GOLDEN) * step;
    let abeam = scan.abeam - k;
    let mut extras = [
        abeam - EDGE_ABEAM,
        abeam + EDGE_ABEAM,
        -0.5 * z,
        0.0,
        0.5 * z,
    ];
    extras.sort_by(f64::total_cmp);
    let mut extra = extras
        .into_iter()
        .filter(|&p| (at(0)..at(EDGE_SCAN + 1)).contains(&p))
        .peekable();
    let mut regular = (0..=EDGE_SCAN + 1).map(at).peekable();
    let mut next = || match (regular.peek(), extra.peek()) {
        (Some(&r), Some(&e)) if e < r => extra.next(),
        (Some(_), _) => regular.next(),
        (None, _) => extra.next(),
    };
    let first = next().expect("the scan has points");
    let mut low = Turned::first(first, tooth.phase(k, first));
    // No pass in the window: no cut.
    let mut best = PassCut {
        depth_mm: f64::INFINITY,
        ..low.phase.cut
    };
    while let Some(sigma) = next() {
        let high = low.next(sigma, tooth.phase(k, sigma), scan.side);
        tooth.passes_between(k, low, high, scan.side, &mut best);
        // On the path ψ's half-turn swing as the axis runs over the sample has no side:
        // every tooth's tip passes there, so the other way round is searched too.
        if scan.on_path && (high.turned - low.turned).abs() > EDGE_SWING {
            let other = Turned {
                turned: high.turned - TAU * scan.side,
                ..high
            };
            tooth.passes_between(k, low, other, -scan.side, &mut best);
        }
        low = high;
    }
    best
}

/// Where a sample lies from the path: the side (+1: left of the feed about the axis),
/// whether on it (within `EDGE_ON_PATH_MM` of the tool's axis), and the tooth count
/// where the tool's axis runs abeam of it.
#[derive(Debug, Clone, Copy)]
struct Scan {
    side: f64,
    on_path: bool,
    abeam: f64,
}

/// The turn (rad) below which an edge's pass is found; the points a scan takes, the
/// steps and the bracket (tooth counts) that end a pass's refinement, how far either
/// side of abeam it looks (tooth counts), and the swing between two scan points taken
/// for half a turn round the sample's side; how near the tool's axis a sample is on
/// the path (mm: f32 rounding of a few-mm pose stays well below it).
pub const EDGE_TOLERANCE_RAD: f64 = 1e-10;
pub const EDGE_SCAN: u32 = 8;
pub const EDGE_BRACKET_STEPS: u32 = 40;
pub const EDGE_WIDTH: f64 = 1e-9;
pub const EDGE_ABEAM: f64 = 1e-3;
pub const EDGE_SWING: f64 = 0.75 * PI;
pub const EDGE_ON_PATH_MM: f64 = 1e-6;

/// A swing of ψ from one point to the next, unwrapped: the nearest turn, but about half
/// a turn goes round `side` (+1: through +π/2).
fn unwrap_step(step: f64, side: f64) -> f64 {
    let step = (step + PI).rem_euclid(TAU) - PI;
    if step.abs() > EDGE_SWING {
        step.abs().copysign(side)
    } else {
        step
    }
}

/// A tooth's state at one tooth count: its cut there, the entry's angle ψ about the
/// axis (−π, π], and lag − turn (rad).
#[derive(Debug, Clone, Copy)]
struct Phase {
    cut: PassCut,
    psi: f64,
    rest: f64,
}

/// A phase at σ with ψ unwrapped along a scan (`turned`).
#[derive(Debug, Clone, Copy)]
struct Turned {
    sigma: f64,
    phase: Phase,
    turned: f64,
}

impl Turned {
    fn first(sigma: f64, phase: Phase) -> Self {
        Self {
            sigma,
            phase,
            turned: phase.psi,
        }
    }

    /// The phase at σ, ψ unwrapped from this one.
    fn next(&self, sigma: f64, phase: Phase, side: f64) -> Self {
        Self {
            sigma,
            phase,
            turned: self.turned + unwrap_step(phase.psi - self.phase.psi, side),
        }
    }

    /// G = ψ (unwrapped) + lag − turn.
    fn g(&self) -> f64 {
        self.turned + self.phase.rest
    }
}

/// One stamp's tooth as an edge at a sample: its solid, its axial runout, and what it
/// moves with.
struct ToothEdge<'p, 's, 'a, 'w> {
    scene: &'s MillingScene,
    poses: &'p mut PassPoses<'a>,
    walker: &'p mut StampWalker<'w>,
    tool: MillingTool,
    axial_mm: f64,
    teeth: f64,
    lag_per_mm: f64,
}

impl<'p, 's, 'a, 'w> ToothEdge<'p, 's, 'a, 'w> {
    fn new(
        scene: &'s MillingScene,
        poses: &'p mut PassPoses<'a>,
        walker: &'p mut StampWalker<'w>,
        edges: &Edges,
        k: f64,
    ) -> Self {
        let tooth = (k as i64).rem_euclid(edges.teeth as i64) as usize;
        let runout = |v: &Vec<f64>| v.get(tooth).copied().unwrap_or(0.0);
        Self {
            scene,
            poses,
            walker,
            tool: scene.tool.with_radial_runout(runout(&edges.radial_mm)),
            axial_mm: runout(&edges.axial_mm),
            teeth: edges.teeth as f64,
            lag_per_mm: edges.lag_per_mm,
        }
    }

    /// Stamp k's tooth at tooth count k + σ.
    fn phase(&mut self, k: f64, sigma: f64) -> Phase {
        let u = self.walker.node_at(k + sigma);
        let turn = TAU * sigma / self.teeth;
        let offsets = &self.scene.stamps.offsets_mm;
        let mut pose = stamp_pose(self.poses, offsets, k, u, turn);
        pose.centre -= self.axial_mm * pose.axis;
        let frame = self.poses.frame;
        let depth = tool_entry(&self.tool, self.scene.stock_top_mm, frame, &pose);
        let (along, across) = spindle_frame(self.poses, u, pose.axis);
        let entry = depth * frame.normal - pose.centre;
        let lag = self.lag_per_mm * (entry.dot(pose.axis) + self.tool.tip_depth_mm());
        Phase {
            cut: PassCut {
                depth_mm: depth,
                node: u,
                pose,
            },
            psi: entry.dot(across).atan2(entry.dot(along)),
            rest: lag - turn,
        }
    }

    /// The lowest of the edge's passes between two scan points (each whole turn G
    /// crosses, ends included), kept in `best` if lower.
    fn passes_between(&mut self, k: f64, low: Turned, high: Turned, side: f64, best: &mut PassCut) {
        let (g_low, g_high) = (low.g(), high.g());
        let mut level = (g_low.min(g_high) / TAU).ceil() * TAU;
        while level <= g_low.max(g_high) {
            let cut = self.pass_at(k, low, high, level, side);
            if cut.depth_mm < best.depth_mm {
                *best = cut;
            }
            level += TAU;
        }
    }

    /// The pass of the edge where G crosses `level` between two scan points: Illinois
    /// steps (regula falsi halving a stuck end's value), a bisection where the bracket
    /// has not halved in two steps (G jumps where the tool's axis runs over the
    /// sample), to `EDGE_BRACKET_STEPS` steps or a bracket of `EDGE_WIDTH` tooth counts.
    fn pass_at(&mut self, k: f64, low: Turned, high: Turned, level: f64, side: f64) -> PassCut {
        let (mut a, mut b) = (low, high);
        let (mut fa, mut fb) = (a.g() - level, b.g() - level);
        let mut cut = if fa.abs() < fb.abs() {
            a.phase.cut
        } else {
            b.phase.cut
        };
        let mut spans = [f64::INFINITY; 2];
        for _ in 0..EDGE_BRACKET_STEPS {
            let span = (b.sigma - a.sigma).abs();
            if fa.abs().min(fb.abs()) <= EDGE_TOLERANCE_RAD || span <= EDGE_WIDTH || fa == fb {
                break;
            }
            let sigma = if span < 0.5 * spans[0] {
                (a.sigma * fb - b.sigma * fa) / (fb - fa)
            } else {
                0.5 * (a.sigma + b.sigma)
            };
            spans = [spans[1], span];
            let c = a.next(sigma, self.phase(k, sigma), side);
            let fc = c.g() - level;
            cut = c.phase.cut;
            if fc * fb < 0.0 {
                (a, fa) = (b, fb);
            } else {
                fa *= 0.5;
            }
            (b, fb) = (c, fc);
        }
        cut
    }
}

/// The directions the spindle's turn is measured in at node coordinate `u`: the feed
/// direction across the axis (any direction across it where the feed runs along it),
/// and its right-handed quarter turn about the axis.
fn spindle_frame(poses: &mut PassPoses, u: f64, axis: DVec3) -> (DVec3, DVec3) {
    let feed = poses.feed(u);
    let along = (feed - feed.dot(axis) * axis).normalize_or(axis.any_orthonormal_vector());
    (along, axis.cross(along))
}

/// The pose of stamp `k` (at node coordinate `u`): the tool there, its centre moved by
/// tooth k mod z's displacement in the spindle's frame turned by `turn` (the tooth's
/// turn past pointing along the feed).
fn stamp_pose(
    poses: &mut PassPoses,
    offsets: &[glam::DVec2],
    k: f64,
    u: f64,
    turn: f64,
) -> LocalPose {
    let pose = poses.pose(u);
    if offsets.is_empty() {
        return pose;
    }
    let offset = offsets[(k as i64).rem_euclid(offsets.len() as i64) as usize];
    let offset = glam::DVec2::from_angle(turn).rotate(offset);
    let (along, across) = spindle_frame(poses, u, pose.axis);
    LocalPose {
        centre: pose.centre + offset.x * along + offset.y * across,
        axis: pose.axis,
    }
}

/// The machined surface at one sample and the pass that left it (the pass index).
pub fn milling_dexel(scene: &MillingScene, ring: usize, row: u32) -> (f64, u32) {
    let frame = SampleFrame::new(scene, ring, row);
    let mut best = (scene.stock_top_mm, NO_PASS);
    let mut list = CandidateList::default();
    let mut overflowed = Vec::new();
    scene.candidates(frame.world_point, frame.world_normal, &mut list, |c| {
        overflowed.push(c)
    });
    // Locate the passes (an estimate of each one's cut) and search them lowest
    // estimate first.
    let mut ranked = [Located::default(); MAX_CANDIDATES];
    for (slot, candidate) in ranked.iter_mut().zip(&list.items[..list.len]) {
        *slot = locate(scene, &frame, *candidate);
    }
    let ranked = &mut ranked[..list.len];
    ranked.sort_by(|a, b| a.estimate.total_cmp(&b.estimate).then(a.pass.cmp(&b.pass)));
    for located in ranked.iter() {
        // A ball: the rest cannot cut deeper than the best (their estimates, less the
        // slack between nodes, are no lower).
        if let Some(slack) = scene.ball_slack {
            let spacing = scene.passes[located.pass as usize].spacing_mm;
            let room = slack.per_spacing_squared * spacing * spacing + slack.displacement_mm;
            if located.estimate - room >= best.0 {
                break;
            }
        }
        offer(&mut best, pass_cut(scene, &frame, located), located.pass);
    }
    // Passes beyond the first MAX_CANDIDATES: run by run.
    for candidate in overflowed {
        let located = locate(scene, &frame, candidate);
        offer(&mut best, pass_cut(scene, &frame, &located), candidate.pass);
    }
    best
}

/// Keeps a pass's cut if it is measurably deeper than the best (on a cusp line two
/// passes tie, and rounding must not make the winner flicker), or ties with a lower id.
fn offer(best: &mut (f64, u32), cut: Option<PassCut>, pass: u32) {
    if let Some(cut) = cut
        && (cut.depth_mm < best.0 - TIE_MM || (cut.depth_mm < best.0 + TIE_MM && pass < best.1))
    {
        *best = (cut.depth_mm, pass);
    }
}

impl MillingScene {
    /// Per sample, the diameter of the circle about the tool axis on which the edge cut
    /// the finished surface there (NaN where no pass cut): the effective cutting diameter
    /// at the generating contact (seed 004's De at the point K). Re-runs the search of
    /// the winning pass only.
    pub fn cutting_diameters(&self, field: &crate::field::DexelField) -> Vec<f64> {
        use rayon::prelude::*;
        let rings = self.grid.ring_count();
        (0..self.grid.sample_count())
            .into_par_iter()
            .map(|s| {
                let pass = field.pass[s];
                if pass == NO_PASS {
                    return f64::NAN;
                }
                let frame = SampleFrame::new(self, s % rings, (s / rings) as u32);
                let mut list = CandidateList::default();
                let mut winner: Option<Candidate> = None;
                let mut merge = |c: Candidate| {
                    if c.pass == pass {
                        let w = winner.get_or_insert(c);
                        w.first = w.first.min(c.first);
                        w.last = w.last.max(c.last);
                    }
                };
                self.candidates(frame.world_point, frame.world_normal, &mut list, &mut merge);
                for c in &list.items[..list.len] {
                    merge(*c);
                }
                winner
                    .and_then(|c| pass_cut(self, &frame, &locate(self, &frame, c)))
                    .map_or(f64::NAN, |cut| {
                        let contact = cut.depth_mm * frame.normal;
                        2.0 * MillingTool::radius_at(&cut.pose.cutter(), contact)
                    })
            })
            .collect()
    }
}

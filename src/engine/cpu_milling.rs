//! The f64 reference removal for milling scenes — the twin of `shaders/milling.wgsl`,
//! step for step: change them together. Geometry of the candidates: `milling_scene.rs`.
//!
//! Everything is done in the sample's own frame: origin at its nominal point, axes
//! (e_r, e_φ, e_z) at its azimuth (a part of revolution) or (x, y, z) (an extruded one),
//! so a pose is its centre's offset Δ from the sample and its axis, and the dexel ray is
//! t·n. A node's offset comes from its cylindrical coordinates without cancelling:
//! Δ = ((ρ − r) − 2ρ sin²(δ/2), ρ sin δ, z − z_s) with δ the azimuth difference — the form
//! the f32 kernel needs to resolve nanometres on a 20 mm part.
//!
//! Per candidate pass the cut is the lowest entry of the ray into the tool over the
//! pass's poses: a coarse scan of the nodes (`PassSpan::stride` apart), then the best
//! bracket refined by parabolic steps (Brent's method: golden-section steps where a
//! parabola is not trusted) until the parabola promises less than `REFINE_GAIN_MM`.
//! The entry at each pose is closed form (ball: sphere and shank; flat end: tip plane
//! and cylinder; disc: the hyperboloid's quadratic) or Newton's steps on a convex
//! distance (bull-nose). Where the ray misses or enters above the stock top, the entry
//! is extended by the stock-top point's distance from the tool, which keeps it
//! continuous and steers the search toward the tool. With teeth only the stamps (tooth
//! positions) around the optimum cut; displaced teeth: every stamp over the span.
//! For a ball, passes are ranked by their cut at the nodes around the one nearest the
//! expected centre and searched only while that estimate, less the slack between nodes,
//! can still beat the best.

use super::milling_scene::{Candidate, CandidateList, MAX_CANDIDATES, MillingScene, Node, PassSpan};
use crate::field::{Layout, NO_PASS};
use crate::geometry::cutter::CutterPose;
use crate::geometry::milling_tool::MillingTool;
use glam::DVec3;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Depths closer than this count as a tie (1e-13 mm, far below any resolved feature).
pub const TIE_MM: f64 = 1e-13;
/// The refinement stops when a parabola through its best points promises less (mm).
pub const REFINE_GAIN_MM: f64 = 1e-14;
/// … or when its bracket is this narrow (node spacings).
pub const REFINE_WIDTH: f64 = 1e-9;
/// Refinement steps at most (a kink is found by golden-section steps: 45 shrink a
/// bracket of two node spacings to `REFINE_WIDTH`).
pub const REFINE_STEPS: u32 = 60;
/// The golden ratio's complement: the share of a bracket a golden-section step takes.
const GOLDEN: f64 = 0.381_966_011_250_105_1;

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

    /// A node's centre relative to the sample, in this frame.
    pub fn offset(&self, node: &Node) -> DVec3 {
        if self.polar {
            let delta = wrap_angle(node.angle_rad - self.azimuth_rad);
            self.polar_offset(node.radius_mm, delta, node.centre.z)
        } else {
            node.centre - DVec3::new(self.radius_mm, self.y_mm, self.height_mm)
        }
    }

    /// The offset of the point at distance ρ from Z, δ past the sample's azimuth, height z.
    fn polar_offset(&self, rho: f64, delta: f64, z: f64) -> DVec3 {
        let (sin_half, cos_half) = sin_cos_small(0.5 * delta);
        DVec3::new(
            (rho - self.radius_mm) - 2.0 * rho * sin_half * sin_half,
            2.0 * rho * sin_half * cos_half,
            z - self.height_mm,
        )
    }
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

/// The pose of pass `span` at node coordinate `u` (node ⌊u⌋ plus the fraction to the
/// next), interpolated as the planner does: centres linearly (raster) or in
/// cylindrical coordinates (spiral turns), axes linearly and normalised.
pub fn pose_at(frame: &SampleFrame, span: &PassSpan, nodes: &[Node], u: f64) -> LocalPose {
    let last = span.node_count as usize - 1;
    let i = (u.floor().max(0.0) as usize).min(last.saturating_sub(1));
    let t = (u - i as f64).clamp(0.0, 1.0);
    let (a, b) = (&nodes[i], &nodes[(i + 1).min(last)]);
    let centre = if span.polar && frame.polar {
        let step = a.polar_step;
        let delta = wrap_angle(a.angle_rad - frame.azimuth_rad) + t * step.y;
        frame.polar_offset(
            a.radius_mm + t * step.x,
            delta,
            a.centre.z + t * step.z,
        )
    } else {
        let (da, db) = (frame.offset(a), frame.offset(b));
        da + t * (db - da)
    };
    let axis = frame.direction(a.axis.lerp(b.axis, t).normalize());
    LocalPose { centre, axis }
}

/// The entry of the ray t·n into the tool at `pose`, extended above the stock top by
/// the stock-top point's distance from the tool.
pub static EVALS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
pub static SEARCHES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
pub static REFINES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
pub static NODESCAN: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
pub fn extended_entry(scene: &MillingScene, frame: &SampleFrame, pose: &LocalPose) -> f64 {
    EVALS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let top = scene.stock_top_mm;
    let cutter = pose.cutter();
    match scene.tool.ray_entry(&cutter, DVec3::ZERO, frame.normal) {
        Some(entry) if entry < top => entry,
        _ => {
            top + scene
                .tool
                .signed_distance(&cutter, top * frame.normal)
                .max(0.0)
        }
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

/// Where along a pass its cut at a sample lies: the pass's point nearest the sample's
/// anchor — for a ball the sample itself (the cutting pose is the centre-path point
/// nearest the entry point, which lies within the stock of the sample, along its
/// normal), for other tools the expected centre. From where the pass's geometry puts
/// it (a spiral turn's node at the anchor's azimuth, a raster pass's projection onto its
/// line), downhill node by node, then projected onto the better adjacent segment.
pub fn locate(scene: &MillingScene, frame: &SampleFrame, candidate: Candidate) -> Located {
    let span = &scene.passes[candidate.pass as usize];
    let nodes = scene.pass_nodes(candidate.pass);
    let last = span.node_count - 1;
    let (lo, hi) = (candidate.first.saturating_sub(1), (candidate.last + 1).min(last));
    let middle = nodes[((lo + hi) / 2) as usize].axis;
    let (expected, radius) = scene.expected_centre(frame.world_point, frame.world_normal, middle);
    let anchor = if scene.ball_slack.is_some() {
        frame.world_point
    } else {
        expected
    };
    let distance = |i: u32| (nodes[i as usize].centre - anchor).length_squared();
    let (mut nearest, mut d) = (lo, f64::INFINITY);
    let azimuth = if anchor == frame.world_point && frame.polar {
        frame.azimuth_rad
    } else {
        anchor.y.atan2(anchor.x)
    };
    for guess in span.nearest_guesses(anchor, azimuth) {
        let node = guess.clamp(lo as f64, hi as f64).round() as u32;
        let at = distance(node);
        if at < d {
            (nearest, d) = (node, at);
        }
    }
    while nearest > lo && distance(nearest - 1) < d {
        nearest -= 1;
        d = distance(nearest);
    }
    while nearest < hi && distance(nearest + 1) < d {
        nearest += 1;
        d = distance(nearest);
    }
    // Onto the adjacent segments (in world coordinates: a node spacing's fraction).
    let project = |i: u32| {
        let (a, b) = (nodes[i as usize].centre, nodes[i as usize + 1].centre);
        let along = b - a;
        let t = ((anchor - a).dot(along) / along.length_squared().max(1e-300)).clamp(0.0, 1.0);
        (i as f64 + t, (a + t * along - anchor).length_squared())
    };
    let mut point = (nearest as f64, d);
    for i in [nearest.saturating_sub(1).max(lo), nearest.min(hi.saturating_sub(1))] {
        if i < hi {
            let p = project(i);
            if p.1 < point.1 {
                point = p;
            }
        }
    }
    // Nodes within the radius of the expected centre, and a scan step more.
    let step = (nodes[nearest.min(last - 1) as usize + 1].centre
        - nodes[nearest.min(last - 1) as usize].centre)
        .length();
    let half = (radius / step.max(1e-12)).ceil() + span.stride as f64;
    let half = half.min((hi - lo) as f64) as u32;
    Located {
        pass: candidate.pass,
        lo: nearest.saturating_sub(half).max(lo),
        hi: (nearest + half).min(hi),
        nearest: point.0,
        estimate: extended_entry(scene, frame, &pose_at(frame, span, nodes, point.0)),
    }
}

/// The lowest cut of a located pass on the sample's ray (None: it stays above the
/// stock top). For a ball on a pass that cannot come round to the sample twice (a
/// raster pass, or less than a quarter of a spiral's turn in reach), the cut lies at
/// the located point: a bracket about it is widened until the entry rises on both
/// sides. Otherwise its nodes are scanned `stride` apart and half a node either side of
/// the located point. Then the best bracket is refined; with teeth, the stamps there.
pub fn pass_cut(scene: &MillingScene, frame: &SampleFrame, located: &Located) -> Option<PassCut> {
    SEARCHES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let span = &scene.passes[located.pass as usize];
    let nodes = scene.pass_nodes(located.pass);
    let entry_at = |u: f64| extended_entry(scene, frame, &pose_at(frame, span, nodes, u));
    let (lo, hi) = (located.lo as f64, located.hi as f64);
    let single_valley = scene.ball_slack.is_some()
        && (!span.polar || (hi - lo) * span.step.y.abs() < FRAC_PI_2);
    let bracket = if single_valley {
        widen(&entry_at, (located.nearest, located.estimate), lo, hi)
    } else {
        scan(&entry_at, located, span.stride)
    };
    let stamps = &scene.stamps;
    if stamps.feed_per_tooth_mm > 0.0 && !stamps.offsets_mm.is_empty() {
        return stamp_cut(scene, frame, located.pass, bracket.best.0, located.lo, located.hi);
    }
    if std::env::var("DBG_REFINE").is_ok() { eprintln!("scan bracket {bracket:?}"); }
    let bracket = narrow(&entry_at, bracket);
    if std::env::var("DBG_REFINE").is_ok() { eprintln!("refine from {bracket:?}"); }
    let before_refine = EVALS.load(std::sync::atomic::Ordering::Relaxed);
    let (node, depth) = refine(&entry_at, bracket, scene.tool.is_smooth());
    REFINES.fetch_add(EVALS.load(std::sync::atomic::Ordering::Relaxed) - before_refine, std::sync::atomic::Ordering::Relaxed);
    if stamps.feed_per_tooth_mm > 0.0 {
        return stamp_cut(scene, frame, located.pass, node, located.lo, located.hi);
    }
    (depth < scene.stock_top_mm).then(|| PassCut {
        depth_mm: depth,
        node,
        pose: pose_at(frame, span, nodes, node),
    })
}

/// Node coordinates either side of a located point a first bracket spans.
pub const FIRST_BRACKET: f64 = 0.05;

/// A bracket about `start` (its value known) within [lo, hi]: points `FIRST_BRACKET`
/// either side, moved downhill with doubling steps until the value rises on both
/// sides (or the range ends).
fn widen(f: &dyn Fn(f64) -> f64, start: (f64, f64), lo: f64, hi: f64) -> Bracket {
    let at = |u: f64| (u, f(u));
    let mut low = at((start.0 - FIRST_BRACKET).max(lo));
    let mut best = start;
    let mut high = at((start.0 + FIRST_BRACKET).min(hi));
    while low.1 < best.1 && low.0 > lo {
        let next = at((low.0 - 2.0 * (best.0 - low.0)).max(lo));
        (high, best, low) = (best, low, next);
    }
    while high.1 < best.1 && high.0 < hi {
        let next = at((high.0 + 2.0 * (high.0 - best.0)).min(hi));
        (low, best, high) = (best, high, next);
    }
    // A range end that is still lowest: the bracket closes on it.
    if low.1 < best.1 {
        (high, best) = (best, low);
    } else if high.1 < best.1 {
        (low, best) = (best, high);
    }
    Bracket { low, best, high }
}

/// A bracket is narrowed by evenly spaced points while it is wider than this (node
/// spacings), so the refinement starts within one valley.
pub const NARROW_WIDTH: f64 = 4.0;
/// Intervals a narrowing step splits a bracket into.
pub const NARROW_STEPS: usize = 8;

/// Narrows a wide bracket: `NARROW_STEPS` even intervals over it, the best point (of
/// those and its old best) between its neighbours, until it is `NARROW_WIDTH` wide.
fn narrow(f: &dyn Fn(f64) -> f64, mut bracket: Bracket) -> Bracket {
    while bracket.high.0 - bracket.low.0 > NARROW_WIDTH {
        let (low, high) = (bracket.low, bracket.high);
        let step = (high.0 - low.0) / NARROW_STEPS as f64;
        let mut points = [low; NARROW_STEPS + 1];
        for (k, point) in points.iter_mut().enumerate().skip(1) {
            *point = if k == NARROW_STEPS {
                high
            } else {
                let u = low.0 + k as f64 * step;
                (u, f(u))
            };
        }
        let mut j = 0;
        for k in 1..=NARROW_STEPS {
            if points[k].1 < points[j].1 {
                j = k;
            }
        }
        bracket = if bracket.best.1 < points[j].1 {
            // The old best stays, between the points either side of the one nearest it
            // (so a point a hair from it, lower but for rounding, cannot close it in).
            let k = ((bracket.best.0 - low.0) / step).round().clamp(1.0, (NARROW_STEPS - 1) as f64);
            let k = k as usize;
            Bracket {
                low: points[k - 1],
                best: bracket.best,
                high: points[k + 1],
            }
        } else {
            Bracket {
                low: points[j.saturating_sub(1)],
                best: points[j],
                high: points[(j + 1).min(NARROW_STEPS)],
            }
        };
    }
    bracket
}

/// The bracket a coarse scan finds: every `stride`-th node over the located span and
/// the points half a node either side of the located one, in order; the best and its
/// neighbours in the scan.
fn scan(f: &dyn Fn(f64) -> f64, located: &Located, stride: u32) -> Bracket {
    let (lo, hi) = (located.lo as f64, located.hi as f64);
    let near = [
        (located.nearest - 0.5).max(lo),
        located.nearest,
        (located.nearest + 0.5).min(hi),
    ];
    let (mut best, mut before, mut after) = ((lo, f64::INFINITY), None, None);
    let mut previous: Option<(f64, f64)> = None;
    let mut points = ScanPoints::new(located.lo, located.hi, stride, near);
    while let Some(u) = points.next() {
        let value = if u == located.nearest {
            located.estimate
        } else {
            f(u)
        };
        if value < best.1 {
            best = (u, value);
            before = previous;
            after = None;
        } else if after.is_none() && previous.is_some_and(|p| p.0 == best.0) {
            after = Some((u, value));
        }
        previous = Some((u, value));
    }
    Bracket {
        low: before.unwrap_or(best),
        best,
        high: after.unwrap_or(best),
    }
}

/// The scan's points in increasing order: every `stride`-th node from `lo`, `hi`, and
/// three more (sorted) merged in.
struct ScanPoints {
    next_stride: Option<u32>,
    hi: u32,
    stride: u32,
    extra: [f64; 3],
    taken: usize,
    last: Option<f64>,
}

impl ScanPoints {
    fn new(lo: u32, hi: u32, stride: u32, extra: [f64; 3]) -> Self {
        Self {
            next_stride: Some(lo),
            hi,
            stride,
            extra,
            taken: 0,
            last: None,
        }
    }

    fn next(&mut self) -> Option<f64> {
        loop {
            let stride = self.next_stride.map(|s| s as f64);
            let extra = (self.taken < 3).then(|| self.extra[self.taken]);
            let point = match (stride, extra) {
                (Some(a), Some(b)) => a.min(b),
                (Some(a), None) => a,
                (None, Some(b)) => b,
                (None, None) => return None,
            };
            if stride == Some(point) {
                let s = self.next_stride.unwrap_or(self.hi);
                self.next_stride = (s < self.hi).then(|| (s + self.stride).min(self.hi));
            }
            if extra == Some(point) {
                self.taken += 1;
            }
            if self.last != Some(point) {
                self.last = Some(point);
                return Some(point);
            }
        }
    }
}

/// A node's own pose in the frame.
fn node_pose(frame: &SampleFrame, node: &Node) -> LocalPose {
    LocalPose {
        centre: frame.offset(node),
        axis: frame.direction(node.axis),
    }
}

/// Three points of a function along the pass: the best of a scan between its two
/// neighbours (equal to it at the scan's ends).
#[derive(Debug, Clone, Copy)]
pub struct Bracket {
    pub low: (f64, f64),
    pub best: (f64, f64),
    pub high: (f64, f64),
}

/// The minimum of `f` over [low, high] from a scan's bracket. For a smooth tool,
/// Brent's method with the bracket's ends as its first parabola, stopping once a
/// parabola through the three best points promises less than `REFINE_GAIN_MM` below the
/// best; a flat end's or a disc's rim leaves a kink there (where parabolas creep), found
/// by golden-section steps to `REFINE_WIDTH`.
pub fn refine(f: &dyn Fn(f64) -> f64, bracket: Bracket, smooth: bool) -> (f64, f64) {
    let (mut a, mut b) = (bracket.low.0, bracket.high.0);
    let (mut x, mut fx) = bracket.best;
    // w: second best, v: the previous w.
    let (mut w, mut fw) = bracket.low;
    let (mut v, mut fv) = bracket.high;
    let mut e = b - a; // the step before last: lets the first parabola through
    let mut d = 0.0f64;
    for _ in 0..REFINE_STEPS {
        let middle = 0.5 * (a + b);
        let tol = REFINE_WIDTH;
        if b - a <= 2.0 * tol {
            break;
        }
        let mut parabolic = false;
        if smooth && e.abs() > tol && w != x && v != x && v != w {
            let r = (x - w) * (fx - fv);
            let q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            let mut q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            // Its curvature and the gain it promises at its vertex.
            let curvature = 2.0 * ((fw - fx) / (w - x) - (fv - fx) / (v - x)) / (w - v);
            let step = p / q;
            if curvature > 0.0 && 0.5 * curvature * step * step < REFINE_GAIN_MM {
                break;
            }
            if p.abs() < (0.5 * q * e).abs() && p > q * (a - x) && p < q * (b - x) {
                e = d;
                d = step;
                parabolic = true;
                let u = x + d;
                if u - a < 2.0 * tol || b - u < 2.0 * tol {
                    d = tol.copysign(middle - x);
                }
            }
        }
        if !parabolic {
            e = if x >= middle { a - x } else { b - x };
            d = GOLDEN * e;
        }
        let u = if d.abs() >= tol {
            x + d
        } else {
            x + tol.copysign(d)
        };
        let fu = f(u);
        if std::env::var("DBG_REFINE").is_ok() { eprintln!("  refine step u {u:.9} fu {fu:.15e} (x {x:.9} fx {fx:.15e}) parabolic {parabolic} a {a:.6} b {b:.6}"); }
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                (v, fv, w, fw) = (w, fw, u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
    (x, fx)
}

/// With teeth: the lowest cut of the stamps (tooth positions) around the pass's
/// continuous optimum at node coordinate `node` — or, with displaced teeth, of every
/// stamp over the span of nodes lo..=hi.
fn stamp_cut(
    scene: &MillingScene,
    frame: &SampleFrame,
    pass: u32,
    node: f64,
    lo: u32,
    hi: u32,
) -> Option<PassCut> {
    let span = &scene.passes[pass as usize];
    let nodes = scene.pass_nodes(pass);
    let last = nodes.len() - 1;
    let teeth_at = |u: f64| {
        let i = (u.floor().max(0.0) as usize).min(last.saturating_sub(1));
        let t = (u - i as f64).clamp(0.0, 1.0);
        nodes[i].teeth + t * (nodes[(i + 1).min(last)].teeth - nodes[i].teeth)
    };
    let (first_stamp, last_stamp) = (nodes[0].teeth.ceil(), nodes[last].teeth.floor());
    let (from, to) = if scene.stamps.offsets_mm.is_empty() {
        let nearest = teeth_at(node).floor();
        (nearest - 1.0, nearest + 2.0)
    } else {
        (nodes[lo as usize].teeth.ceil(), nodes[hi as usize].teeth.floor())
    };
    let mut best: Option<PassCut> = None;
    let mut segment = (node.floor().max(0.0) as usize).min(last.saturating_sub(1));
    let mut k = from.max(first_stamp);
    while k <= to.min(last_stamp) {
        // The segment holding stamp k, walked to from the last one.
        while segment > 0 && nodes[segment].teeth > k {
            segment -= 1;
        }
        while segment + 1 < last && nodes[segment + 1].teeth < k {
            segment += 1;
        }
        let (a, b) = (nodes[segment].teeth, nodes[segment + 1].teeth);
        let t = if b > a { ((k - a) / (b - a)).clamp(0.0, 1.0) } else { 0.0 };
        let u = segment as f64 + t;
        let pose = stamp_pose(scene, frame, span, nodes, k, u);
        let depth = extended_entry(scene, frame, &pose);
        if depth < scene.stock_top_mm && best.is_none_or(|b| depth < b.depth_mm) {
            best = Some(PassCut {
                depth_mm: depth,
                node: u,
                pose,
            });
        }
        k += 1.0;
    }
    best
}

/// The pose of stamp `k` (at node coordinate `u`): the tool there, its centre moved by
/// tooth k mod z's displacement in the frame (feed direction across the axis, its
/// right-handed quarter turn about the axis).
fn stamp_pose(
    scene: &MillingScene,
    frame: &SampleFrame,
    span: &PassSpan,
    nodes: &[Node],
    k: f64,
    u: f64,
) -> LocalPose {
    let pose = pose_at(frame, span, nodes, u);
    let offsets = &scene.stamps.offsets_mm;
    if offsets.is_empty() {
        return pose;
    }
    let offset = offsets[(k as i64).rem_euclid(offsets.len() as i64) as usize];
    let feed = feed_direction(frame, span, nodes, u);
    let along = (feed - feed.dot(pose.axis) * pose.axis)
        .normalize_or(pose.axis.any_orthonormal_vector());
    let across = pose.axis.cross(along);
    LocalPose {
        centre: pose.centre + offset.x * along + offset.y * across,
        axis: pose.axis,
    }
}

/// The unit direction of travel of the pose centre at node coordinate `u` (the
/// derivative of the interpolation), in the frame.
pub fn feed_direction(frame: &SampleFrame, span: &PassSpan, nodes: &[Node], u: f64) -> DVec3 {
    let last = span.node_count as usize - 1;
    let i = (u.floor().max(0.0) as usize).min(last.saturating_sub(1));
    let t = (u - i as f64).clamp(0.0, 1.0);
    let (a, b) = (&nodes[i], &nodes[(i + 1).min(last)]);
    let velocity = if span.polar && frame.polar {
        let step = a.polar_step;
        let rho = a.radius_mm + t * step.x;
        let delta = wrap_angle(a.angle_rad - frame.azimuth_rad) + t * step.y;
        let (sin, cos) = delta.sin_cos();
        DVec3::new(
            step.x * cos - rho * step.y * sin,
            step.x * sin + rho * step.y * cos,
            step.z,
        )
    } else {
        frame.offset(b) - frame.offset(a)
    };
    velocity.normalize_or_zero()
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
    for candidate in overflowed {
        let located = locate(scene, &frame, candidate);
        offer(&mut best, pass_cut(scene, &frame, &located), candidate.pass);
    }
    // Rank the passes by their cut near the expected centre (an upper bound of it).
    let mut ranked = [Located::default(); MAX_CANDIDATES];
    for (slot, candidate) in ranked.iter_mut().zip(&list.items[..list.len]) {
        *slot = locate(scene, &frame, *candidate);
    }
    let ranked = &mut ranked[..list.len];
    ranked.sort_by(|a, b| a.estimate.total_cmp(&b.estimate).then(a.pass.cmp(&b.pass)));
    for located in ranked.iter() {
        // For a ball, the rest cannot cut deeper than the best (their estimates, less
        // the slack between nodes, are no lower).
        if let Some(slack) = scene.ball_slack {
            let spacing = scene.passes[located.pass as usize].spacing_mm;
            let room = slack.per_spacing_squared * spacing * spacing + slack.displacement_mm;
            if located.estimate - room >= best.0 {
                break;
            }
        }
        offer(&mut best, pass_cut(scene, &frame, located), located.pass);
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

#[cfg(test)]
mod debug_tests {
    use super::*;
    use crate::engine::Scene;
    use crate::io::job::Job;

    #[test]
    #[ignore]
    fn debug_sample() {
        let path = std::env::var("DBG_JOB").unwrap();
        let ring: usize = std::env::var("DBG_RING").unwrap().parse().unwrap();
        let row: u32 = std::env::var("DBG_ROW").unwrap().parse().unwrap();
        let job = Job::load(std::path::Path::new(&path)).unwrap();
        let Scene::Milling(scene) = crate::run::prepare_scenes(&job).remove(0) else { panic!() };
        let frame = SampleFrame::new(&scene, ring, row);
        let mut list = CandidateList::default();
        scene.candidates(frame.world_point, frame.world_normal, &mut list, |c| println!("overflow {c:?}"));
        for c in &list.items[..list.len] {
            let cut = pass_cut(&scene, &frame, &locate(&scene, &frame, *c));
            let span = &scene.passes[c.pass as usize];
            let nodes = scene.pass_nodes(c.pass);
            let lo = c.first.saturating_sub(1) as f64;
            let hi = (c.last + 1).min(span.node_count - 1) as f64;
            let n = 200000;
            let mut brute = (f64::INFINITY, 0.0);
            for k in 0..=n {
                let u = lo + (hi - lo) * k as f64 / n as f64;
                let v = extended_entry(&scene, &frame, &pose_at(&frame, span, nodes, u));
                if v < brute.0 { brute = (v, u); }
            }
            let loc = locate(&scene, &frame, *c);
            let dus: Vec<f64> = match std::env::var("DBG_U") { Ok(v) => { let a: f64 = v.parse().unwrap(); (0..=60).map(|k| a - loc.nearest.floor() + k as f64 * 0.05).collect() }, Err(_) => vec![-0.03f64, -0.01, 0.0, 0.0004, 0.01, 0.029, 0.05] };
            if std::env::var("DBG_PASS").map_or(true, |v| v.parse::<u32>().unwrap() == c.pass) { for du in dus {
                let u = loc.nearest.floor() + du;
                if u < 0.0 || u > (span.node_count - 1) as f64 { continue; }
                let pose = pose_at(&frame, span, nodes, u);
                let world = nodes[u.floor() as usize].centre.lerp(nodes[(u.floor() as usize + 1).min(nodes.len()-1)].centre, u - u.floor());
                println!("   u {u:.4} |Δ| {:.12} f {:.12e} world-dist {:.12}", pose.centre.length(), extended_entry(&scene, &frame, &pose), (world - frame.world_point).length());
            } }
            println!("{c:?} stride {} cut {:?} brute {:?} est {:?}", span.stride, cut.map(|c| (c.depth_mm, c.node)), brute, locate(&scene, &frame, *c));
        }
        println!("dexel {:?}", milling_dexel(&scene, ring, row));
    }
    #[test]
    #[ignore]
    fn debug_counts() {
        use std::sync::atomic::Ordering::Relaxed;
        let path = std::env::var("DBG_JOB").unwrap();
        let job = Job::load(std::path::Path::new(&path)).unwrap();
        let Scene::Milling(scene) = crate::run::prepare_scenes(&job).remove(0) else { panic!() };
        let t = std::time::Instant::now();
        let f = crate::engine::RemovalEngine::remove(&mut crate::engine::cpu::CpuEngine, &crate::engine::Scene::Milling(scene.clone()), &|_, _| {}).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let pairs = scene.pair_count();
        println!("removal {secs:.3} s, pairs {pairs}, {:.3} µs/pair; evals {} ({:.2}/pair), searches {} ({:.2}/pair), node scan {:.1}/pair refine evals {:.2}/search", secs / pairs as f64 * 1e6, EVALS.load(Relaxed), EVALS.load(Relaxed) as f64 / pairs as f64, SEARCHES.load(Relaxed), SEARCHES.load(Relaxed) as f64 / pairs as f64, NODESCAN.load(Relaxed) as f64 / pairs as f64, REFINES.load(Relaxed) as f64 / SEARCHES.load(Relaxed) as f64);
        let _ = f;
    }
}
#[cfg(test)]
mod debug_cpu_time {
    #[test]
    #[ignore]
    fn debug_cputime() {
        use crate::engine::Scene;
        let path = std::env::var("DBG_JOB").unwrap();
        let job = crate::io::job::Job::load(std::path::Path::new(&path)).unwrap();
        let Scene::Milling(scene) = crate::run::prepare_scenes(&job).remove(0) else { panic!() };
        let cpu = || { let mut u: libc::rusage = unsafe { std::mem::zeroed() }; unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) }; u.ru_utime.tv_sec as f64 + u.ru_utime.tv_usec as f64 * 1e-6 };
        let pairs = scene.pair_count();
        let t0 = cpu();
        let w = std::time::Instant::now();
        let _ = crate::engine::RemovalEngine::remove(&mut crate::engine::cpu::CpuEngine, &Scene::Milling(scene.clone()), &|_, _| {}).unwrap();
        let t1 = cpu();
        println!("cpu {:.3} s, wall {:.3} s, pairs {pairs}, {:.3} µs cpu per pair", t1 - t0, w.elapsed().as_secs_f64(), (t1 - t0) / pairs as f64 * 1e6);
    }
}

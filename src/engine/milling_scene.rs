//! Everything a removal engine needs for a milling job, prepared once in f64: the path's
//! nodes as the engines read them, the passes, and the nodes binned in 3-D so that a
//! sample looks only at the passes that can cut it. The search each sample runs on this
//! is `cpu_milling.rs` (f64) and its twin `shaders/milling.wgsl` (f32).
//!
//! Which passes can cut a sample. A tool touching the sample's point p has its centre
//! at p + κ·n (κ the corner or ball radius, a disc's throat radius) plus at most its
//! flat radius R across n, and one that dips below the stock top t there lies within
//! √(2 r_p (t + lift)) more (r_p the profile radius across the pass). So the path's nodes
//! are binned in 3-D by their centre as runs of consecutive nodes of one pass in one
//! cell, and a sample takes the runs within that search radius (plus one node spacing)
//! of p + κ·n, merged per pass into the span of its nodes found there: its *candidates*.

use crate::field::{Layout, PolarGrid};
use crate::geometry::milling_tool::MillingTool;
use crate::process::milling::{Interpolation, MillingPath};
use glam::{DVec2, DVec3};
use std::f64::consts::{FRAC_PI_4, TAU};
use std::sync::OnceLock;

/// Candidate passes a sample keeps for ranking; further ones are searched at once
/// (the same result, without the early stop). Shared with the kernel.
pub const MAX_CANDIDATES: usize = 16;

/// Where the teeth cut along the path: stamp k at arc length k·`feed_per_tooth_mm` from
/// the path's start (0: the tool body sweeps continuously), when tooth k mod z points
/// along the feed, its sweep displaced from the tool axis by `offsets_mm[k mod z]` in
/// the frame (feed direction, its right-handed quarter turn about the axis); no
/// offsets: every tooth on the axis. With `edges`, each tooth cuts as its edge.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ToothStamps {
    pub feed_per_tooth_mm: f64,
    pub offsets_mm: Vec<DVec2>,
    pub edges: Option<Box<Edges>>,
}

/// Teeth as edges. Stamp k's tooth turns with the spindle, 2π/z per feed per tooth, and
/// cuts a sample where its edge passes it: at the turn where the edge, at the height of
/// the sample's entry into that tooth's solid of revolution, points at the entry. The
/// tooth's displacement turns with it; its solid is the tool's profile with the edge
/// `radial_mm` further out and `axial_mm` lower.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Edges {
    pub teeth: u32,
    /// How far the edge lags behind its tip's turn per mm of height above the tip (rad/mm):
    /// tan β / R for a constant-lead helix of angle β on a tool of outer radius R.
    pub lag_per_mm: f64,
    /// Per tooth (empty: none), mm.
    pub radial_mm: Vec<f64>,
    pub axial_mm: Vec<f64>,
}

impl ToothStamps {
    /// How far a tooth's cut can lie beyond the nominal tool's (mm): its displacement
    /// and its runout.
    pub fn reach_beyond_mm(&self) -> f64 {
        let largest = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0, f64::max);
        let edges = self.edges.as_deref();
        largest(&mut self.offsets_mm.iter().map(|o| o.length()))
            + edges.map_or(0.0, |e| largest(&mut e.radial_mm.iter().copied()))
            + edges.map_or(0.0, |e| largest(&mut e.axial_mm.iter().map(|a| a.abs())))
    }
}

/// A path node as the engines read it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    pub centre: DVec3,
    pub axis: DVec3,
    /// The centre's distance from Z and its azimuth in [0, 2π).
    pub radius_mm: f64,
    pub angle_rad: f64,
    /// (radius, angle, height) of the next node of the pass less this one's: the steps
    /// of the polar interpolation (zero at a pass's last node).
    pub polar_step: DVec3,
    /// Path arc length in feeds per tooth: stamp k sits at k (0 without teeth).
    pub teeth: f64,
}

/// One pass's nodes in `MillingScene::nodes`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassSpan {
    pub first_node: u32,
    pub node_count: u32,
    pub polar: bool,
    /// Nodes between the points of the coarse scan along the pass.
    pub stride: u32,
    /// The longest step between two of its nodes (mm).
    pub spacing_mm: f64,
    /// Where the pass's geometry puts node coordinates: a spiral turn's first node's
    /// unwrapped azimuth and the azimuth step per node; a raster pass's first node and
    /// its step per node in XY (its nodes lie evenly along a line in XY).
    pub origin: DVec3,
    pub step: DVec3,
}

impl PassSpan {
    /// Node coordinates near a point by the pass's geometry: a spiral turn's nodes at
    /// the point's azimuth (the first two from the turn's start: a turn may come round
    /// to it twice), a raster pass's projection onto its line in XY (twice). `azimuth`
    /// is the point's.
    pub fn nearest_guesses(&self, point: DVec3, azimuth: f64) -> [f64; 2] {
        if self.polar {
            if self.step.y == 0.0 {
                return [0.0; 2];
            }
            // Node coordinates where the azimuth comes round: u₀ + k·(2π/|step|).
            let per_turn = TAU / self.step.y.abs();
            let u0 = ((azimuth - self.origin.y) / self.step.y).rem_euclid(per_turn);
            [u0, u0 + per_turn]
        } else {
            let along = DVec2::new(self.step.x, self.step.y);
            let length = along.length_squared();
            let u = if length > 0.0 {
                (point - self.origin).truncate().dot(along) / length
            } else {
                0.0
            };
            [u, u]
        }
    }
}

/// A pass that can cut a sample, and the span of its nodes (pass-local) found near it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Candidate {
    pub pass: u32,
    pub first: u32,
    pub last: u32,
}

/// Path nodes binned in 3-D by their pose centre, as runs of consecutive nodes of one
/// pass lying in one cell (with the run's bounding box and the axis at its start); the
/// runs of cell c are `runs[cell_start[c]..cell_start[c + 1]]`.
#[derive(Debug, Clone)]
pub struct NodeBins {
    pub origin: DVec3,
    pub cell_mm: f64,
    pub size: [u32; 3],
    pub cell_start: Vec<u32>,
    pub runs: Vec<Run>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Run {
    pub pass: u32,
    pub first: u32,
    pub last: u32,
    pub low: DVec3,
    pub high: DVec3,
    pub axis: DVec3,
}

impl Run {
    /// Distance from a point to the run's bounding box.
    pub fn distance(&self, point: DVec3) -> f64 {
        (self.low - point)
            .max(point - self.high)
            .max(DVec3::ZERO)
            .length()
    }
}

/// Cells a bin grid may have; a larger part gets larger cells.
const MAX_CELLS: f64 = 4.0e6;

impl NodeBins {
    fn new(path: &MillingPath, cell_mm: f64) -> Self {
        let (mut low, mut high) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for node in path.passes.iter().flat_map(|p| &p.nodes) {
            low = low.min(node.pose.centre);
            high = high.max(node.pose.centre);
        }
        let extent = (high - low).max(DVec3::ZERO);
        let count = |span: f64, cell: f64| ((span / cell).floor() as u32 + 1).max(1);
        let mut cell_mm = cell_mm;
        while [extent.x, extent.y, extent.z]
            .iter()
            .map(|&s| count(s, cell_mm) as f64)
            .product::<f64>()
            > MAX_CELLS
        {
            cell_mm *= 1.5;
        }
        let size = [
            count(extent.x, cell_mm),
            count(extent.y, cell_mm),
            count(extent.z, cell_mm),
        ];
        let cell_of = |centre: DVec3| {
            let c = ((centre - low) / cell_mm).floor();
            let clamp = |v: f64, n: u32| (v.max(0.0) as u32).min(n - 1) as usize;
            let (x, y, z) = (
                clamp(c.x, size[0]),
                clamp(c.y, size[1]),
                clamp(c.z, size[2]),
            );
            (z * size[1] as usize + y) * size[0] as usize + x
        };
        let mut cells: Vec<Vec<Run>> = vec![Vec::new(); (size[0] * size[1] * size[2]) as usize];
        for (p, pass) in path.passes.iter().enumerate() {
            let mut current: Option<(usize, Run)> = None;
            for (n, node) in pass.nodes.iter().enumerate() {
                let centre = node.pose.centre;
                let cell = cell_of(centre);
                match &mut current {
                    Some((c, run)) if *c == cell => {
                        run.last = n as u32;
                        run.low = run.low.min(centre);
                        run.high = run.high.max(centre);
                    }
                    _ => {
                        if let Some((c, run)) = current.take() {
                            cells[c].push(run);
                        }
                        let run = Run {
                            pass: p as u32,
                            first: n as u32,
                            last: n as u32,
                            low: centre,
                            high: centre,
                            axis: node.pose.axis,
                        };
                        current = Some((cell, run));
                    }
                }
            }
            if let Some((c, run)) = current {
                cells[c].push(run);
            }
        }
        let mut cell_start = Vec::with_capacity(cells.len() + 1);
        let mut runs = Vec::new();
        for cell in cells {
            cell_start.push(runs.len() as u32);
            runs.extend(cell);
        }
        cell_start.push(runs.len() as u32);
        Self {
            origin: low,
            cell_mm,
            size,
            cell_start,
            runs,
        }
    }

    /// Calls `visit` with every run in the 3 × 3 × 3 cells around `point`.
    pub fn for_each_run_near(&self, point: DVec3, mut visit: impl FnMut(&Run)) {
        let c = ((point - self.origin) / self.cell_mm).floor();
        let range = |centre: f64, size: u32| {
            let low = (centre - 1.0).max(0.0);
            let high = (centre + 1.0).min(size as f64 - 1.0);
            (low as i64)..=(high as i64)
        };
        for z in range(c.z, self.size[2]) {
            for y in range(c.y, self.size[1]) {
                for x in range(c.x, self.size[0]) {
                    let cell = ((z * self.size[1] as i64 + y) * self.size[0] as i64 + x) as usize;
                    let (from, to) = (self.cell_start[cell], self.cell_start[cell + 1]);
                    for run in &self.runs[from as usize..to as usize] {
                        visit(run);
                    }
                }
            }
        }
    }
}

#[derive(Debug, Clone)]
pub struct MillingScene {
    pub grid: PolarGrid,
    pub tool: MillingTool,
    pub path: MillingPath,
    /// Normal distance of the stock's top above nominal: the value of uncut samples.
    pub stock_top_mm: f64,
    /// Where a cutting pose's centre sits from the sample point, along its normal (an
    /// end mill's corner radius, a disc's throat radius).
    pub centre_offset_mm: f64,
    /// How far across the normal it can sit besides (an end mill's flat radius R, which
    /// the axis of each run of nodes pins down; half a disc's edge span).
    pub lateral_mm: f64,
    /// How far from the expected centre a node's centre can be and its tool still cut
    /// the sample: the dip below the stock top a profile of radius r_p allows across
    /// the pass, plus one node spacing.
    pub search_radius_mm: f64,
    /// The tool's profile radius across the passes (sizes the search).
    pub profile_radius_mm: f64,
    /// Where the teeth cut (no feed per tooth: the tool body sweeps continuously).
    pub stamps: ToothStamps,
    /// For a ball, how far a pass's cut can lie below its cut at the nodes around the
    /// one nearest the expected centre, per squared node spacing: the ball's curvature
    /// (twice the flat-bottom value, for contacts up to 50° off the ray), plus the teeth's
    /// displacement; `None` for other tools, whose every candidate pass is searched.
    pub ball_slack: Option<BallSlack>,
    pub nodes: Vec<Node>,
    pub passes: Vec<PassSpan>,
    pub bins: NodeBins,
    /// Dexel–pass pairs (samples × candidate passes), counted when first asked for.
    pairs: OnceLock<u64>,
}

/// The early stop of a ball's pass ranking: a pass whose nodes around the expected
/// centre cut no deeper than the best so far plus `per_spacing_squared · h²` (h its
/// node spacing) plus `displacement_mm` cannot win.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallSlack {
    pub per_spacing_squared: f64,
    pub displacement_mm: f64,
}

impl MillingScene {
    /// `lift_mm` is how far above the nominal the path's contacts sit (stock − depth),
    /// `profile_radius_mm` the tool's profile radius across the passes; `extra_reach_mm`
    /// widens the search for anything that moves a cutting pose off the planned one
    /// (effects; 0 for a nominal job).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        grid: PolarGrid,
        tool: MillingTool,
        path: MillingPath,
        stock_top_mm: f64,
        lift_mm: f64,
        profile_radius_mm: f64,
        stamps: ToothStamps,
        extra_reach_mm: f64,
    ) -> Self {
        let (centre_offset_mm, lateral) = tool.centre_offset_and_lateral_reach();
        let passes = pass_spans(&path, 0.0);
        let spacing = passes.iter().map(|p| p.spacing_mm).fold(0.0, f64::max);
        let extra_reach_mm = extra_reach_mm + stamps.reach_beyond_mm();
        let dip = (stock_top_mm.abs() + lift_mm.abs() + extra_reach_mm).max(0.0);
        // Along a profile of radius r_p the tool dips within √(2 r_p dip); no centre
        // farther than the tool's own size from a cutting one can cut (a face that may
        // stand square has r_p = ∞).
        let across = (2.0 * profile_radius_mm.max(1e-3) * dip)
            .sqrt()
            .min(2.0 * tool.reach_mm());
        let search_radius_mm = across + dip + spacing + 1e-6;
        // Scan spans longer than the search radius in steps of half of it (and, on a
        // spiral's turn, of at most 45°), then refine the best bracket.
        let scan_mm = 0.5 * (search_radius_mm + lateral);
        let passes = pass_spans(&path, scan_mm);
        let bins = NodeBins::new(&path, search_radius_mm + lateral);
        let is_ball = matches!(tool, MillingTool::EndMill(c) if c.major_radius_mm == 0.0);
        // A displaced tooth can cut up to its displacement below the undisplaced sweep.
        let displacement = stamps.reach_beyond_mm();
        let ball_slack = is_ball.then(|| BallSlack {
            per_spacing_squared: 2.0 * 0.25 / (2.0 * profile_radius_mm.max(1e-3)),
            displacement_mm: displacement + 1e-9,
        });
        let nodes = engine_nodes(&path, stamps.feed_per_tooth_mm);
        Self {
            grid,
            tool,
            path,
            stock_top_mm,
            centre_offset_mm,
            lateral_mm: lateral,
            search_radius_mm,
            profile_radius_mm,
            stamps,
            ball_slack,
            nodes,
            passes,
            bins,
            pairs: OnceLock::new(),
        }
    }

    /// The nodes of pass `pass`.
    pub fn pass_nodes(&self, pass: u32) -> &[Node] {
        let span = &self.passes[pass as usize];
        let first = span.first_node as usize;
        &self.nodes[first..first + span.node_count as usize]
    }

    /// The centre a pose cutting a sample at `point` (outward normal `normal`) would
    /// have, for the runs with axis `axis`, and how far from it the run's nodes may lie.
    /// For an end mill with a flat radius the axis fixes the centre's offset across the
    /// normal (toward n's part across the axis); a flat tip square to the normal may
    /// cut from anywhere within R.
    pub fn expected_centre(&self, point: DVec3, normal: DVec3, axis: DVec3) -> (DVec3, f64) {
        let core = point + self.centre_offset_mm * normal;
        match self.tool {
            MillingTool::EndMill(cutter) if cutter.major_radius_mm > 0.0 => {
                let across = normal - normal.dot(axis) * axis;
                if across.length() > 1e-6 {
                    // The axis turns a little along a run (five-axis): allow for it.
                    let centre = core + cutter.major_radius_mm * across.normalize();
                    (centre, 2.0 * self.search_radius_mm)
                } else {
                    (core, cutter.major_radius_mm + self.search_radius_mm)
                }
            }
            _ => (core, self.lateral_mm + self.search_radius_mm),
        }
    }

    /// Calls `visit` with each pass that can cut the sample at `point` (world) with
    /// outward normal `normal`, merged over its runs near it, in the order the kernel
    /// sees them; passes beyond `MAX_CANDIDATES` distinct ones are handed over run by
    /// run as they come (`overflow`).
    pub fn candidates(
        &self,
        point: DVec3,
        normal: DVec3,
        list: &mut CandidateList,
        mut overflow: impl FnMut(Candidate),
    ) {
        list.len = 0;
        let core = point + self.centre_offset_mm * normal;
        self.bins.for_each_run_near(core, |run| {
            let (expected, radius) = self.expected_centre(point, normal, run.axis);
            if run.distance(expected) > radius {
                return;
            }
            let found = Candidate {
                pass: run.pass,
                first: run.first,
                last: run.last,
            };
            if let Some(c) = list.items[..list.len]
                .iter_mut()
                .find(|c| c.pass == run.pass)
            {
                c.first = c.first.min(run.first);
                c.last = c.last.max(run.last);
            } else if list.len < MAX_CANDIDATES {
                list.items[list.len] = found;
                list.len += 1;
            } else {
                overflow(found);
            }
        });
    }

    /// Dexel–pass pairs the engines evaluate (samples × candidate passes): the work
    /// measure for throughput, counted on the CPU the first time it is asked for.
    pub fn pair_count(&self) -> u64 {
        *self.pairs.get_or_init(|| {
            use rayon::prelude::*;
            let rings = self.grid.ring_count();
            (0..self.grid.sample_count())
                .into_par_iter()
                .map(|s| {
                    let (ring, row) = (s % rings, (s / rings) as u32);
                    let (point, normal) = (
                        self.grid.sample_point(ring, row),
                        self.grid.sample_normal(ring, row),
                    );
                    let mut list = CandidateList::default();
                    let mut extra = 0u64;
                    self.candidates(point, normal, &mut list, |_| extra += 1);
                    list.len as u64 + extra
                })
                .sum()
        })
    }

    /// Whether the grid is revolved about Z (polar sample frames) or extruded.
    pub fn polar_grid(&self) -> bool {
        self.grid.layout == Layout::Polar
    }
}

/// A sample's candidate passes (at most `MAX_CANDIDATES`).
#[derive(Debug, Clone, Copy)]
pub struct CandidateList {
    pub items: [Candidate; MAX_CANDIDATES],
    pub len: usize,
}

impl Default for CandidateList {
    fn default() -> Self {
        Self {
            items: [Candidate::default(); MAX_CANDIDATES],
            len: 0,
        }
    }
}

/// The passes as spans of the engines' node array, with their scan strides: about
/// `scan_mm` of travel and at most 45° of a spiral's turn between scan points.
fn pass_spans(path: &MillingPath, scan_mm: f64) -> Vec<PassSpan> {
    let mut first = 0u32;
    path.passes
        .iter()
        .map(|pass| {
            let spacing = pass
                .nodes
                .windows(2)
                .map(|w| (w[1].pose.centre - w[0].pose.centre).length())
                .fold(0.0, f64::max);
            let polar = pass.interpolation == Interpolation::Polar;
            let mut stride = if spacing > 0.0 {
                (scan_mm / spacing).floor().max(1.0)
            } else {
                1.0
            };
            if polar {
                let turn = pass
                    .nodes
                    .windows(2)
                    .map(|w| (w[1].polar.y - w[0].polar.y).abs())
                    .fold(0.0, f64::max);
                if turn > 0.0 {
                    stride = stride.min((FRAC_PI_4 / turn).floor().max(1.0));
                }
            }
            let (origin, step) = if polar {
                let turned = pass.nodes[pass.nodes.len() - 1].polar.y - pass.nodes[0].polar.y;
                (
                    DVec3::new(0.0, pass.nodes[0].polar.y, 0.0),
                    DVec3::new(0.0, turned / (pass.nodes.len() as f64 - 1.0), 0.0),
                )
            } else {
                let (a, b) = (
                    pass.nodes[0].pose.centre,
                    pass.nodes[pass.nodes.len() - 1].pose.centre,
                );
                (a, (b - a) / (pass.nodes.len() as f64 - 1.0))
            };
            let span = PassSpan {
                first_node: first,
                node_count: pass.nodes.len() as u32,
                polar,
                stride: stride.min((pass.nodes.len() as f64 - 1.0).max(1.0)) as u32,
                spacing_mm: spacing,
                origin,
                step,
            };
            first += pass.nodes.len() as u32;
            span
        })
        .collect()
}

/// The path's nodes in the engines' form.
fn engine_nodes(path: &MillingPath, feed_per_tooth_mm: f64) -> Vec<Node> {
    let mut nodes = Vec::with_capacity(path.node_count());
    for pass in &path.passes {
        for (i, node) in pass.nodes.iter().enumerate() {
            let centre = node.pose.centre;
            let polar_step = pass
                .nodes
                .get(i + 1)
                .map_or(DVec3::ZERO, |next| next.polar - node.polar);
            nodes.push(Node {
                centre,
                axis: node.pose.axis,
                radius_mm: centre.truncate().length(),
                angle_rad: centre.y.atan2(centre.x).rem_euclid(TAU),
                polar_step,
                teeth: if feed_per_tooth_mm > 0.0 {
                    node.arc_mm / feed_per_tooth_mm
                } else {
                    0.0
                },
            });
        }
    }
    nodes
}

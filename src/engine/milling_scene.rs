//! Everything a removal engine needs for a milling job, and the f64 search it runs per
//! sample (the CPU engine's body).
//!
//! A sample's dexel ray meets the tool swept along a pass at the lowest entry over the
//! pass's arc length. Only poses whose centre lies near where a cutting pose's centre
//! must be can cut the sample below the stock top: a tool touching the sample's point p
//! has its centre at p + r·n plus at most its flat radius R across n, and one that dips
//! below the stock top t there lies within √(2 r_p (t + lift)) more (r_p the profile
//! radius across the pass). So the path's nodes are binned in 3-D by their centre, and a
//! sample looks only at the nodes within that radius (plus one node spacing) of p + r·n,
//! over the span of each pass's nodes found there. Along the span the entry, extended
//! past the stock top by the distance of the stock-top point from the tool (continuous
//! where the entry reaches the stock top, growing away from the tool), is minimised by
//! golden-section search, after a coarse scan when the span is long. With teeth, the
//! tool cuts only where a tooth passes (every `feed_per_tooth` of travel): the stamps
//! around the continuous optimum are evaluated instead. When the teeth's sweeps are
//! displaced from the axis (each by up to half a tooth's advance), a stamp farther
//! along than its neighbours can still cut deepest where the displacement has a part
//! across the feed, so then every stamp over the pass's span is evaluated.

use super::generating_scene::golden_section_min_steps;
use crate::field::{NO_PASS, PolarGrid};
use crate::geometry::cutter::CutterPose;
use crate::geometry::milling_tool::MillingTool;
use crate::process::milling::{Interpolation, MillingPass, MillingPath};
use glam::{DVec2, DVec3};
use std::f64::consts::FRAC_PI_4;

/// Where the teeth cut along the path: stamp k at arc length k·`feed_per_tooth_mm` from
/// the path's start (0: the tool body sweeps continuously), cut by tooth k mod z whose
/// sweep is displaced from the tool axis by `offsets_mm[k mod z]` in the frame (feed
/// direction, its right-handed quarter turn about the axis); no offsets: every tooth
/// on the axis.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ToothStamps {
    pub feed_per_tooth_mm: f64,
    pub offsets_mm: Vec<DVec2>,
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
    /// Where the teeth cut (no feed per tooth: the tool body sweeps continuously).
    pub stamps: ToothStamps,
    /// For a ball, how far a pass's cut can lie below its value at the node nearest the
    /// expected centre (half a node spacing of travel under the ball); `None` for other
    /// tools, whose cut need not be near that node (every candidate pass is searched).
    pub node_slack_mm: Option<f64>,
    bins: NodeBins,
    /// Dexel–pass pairs the engine evaluates (samples × candidate passes).
    pairs: u64,
}

/// Path nodes binned in 3-D by their pose centre, as runs of consecutive nodes of one
/// pass lying in one cell (with the run's bounding box and the axis at its start).
#[derive(Debug, Clone)]
struct NodeBins {
    origin: DVec3,
    cell_mm: f64,
    size: [usize; 3],
    cells: Vec<Vec<Run>>,
}

#[derive(Debug, Clone, Copy)]
struct Run {
    pass: u32,
    first: u32,
    last: u32,
    low: DVec3,
    high: DVec3,
    axis: DVec3,
}

impl Run {
    /// Distance from a point to the run's bounding box.
    fn distance(&self, point: DVec3) -> f64 {
        (self.low - point)
            .max(point - self.high)
            .max(DVec3::ZERO)
            .length()
    }
}

impl NodeBins {
    fn new(path: &MillingPath, cell_mm: f64) -> Self {
        let (mut low, mut high) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for node in path.passes.iter().flat_map(|p| &p.nodes) {
            low = low.min(node.pose.centre);
            high = high.max(node.pose.centre);
        }
        let count = |span: f64| ((span / cell_mm).floor() as usize + 1).max(1);
        let size = [
            count(high.x - low.x),
            count(high.y - low.y),
            count(high.z - low.z),
        ];
        let mut cells: Vec<Vec<Run>> = vec![Vec::new(); size[0] * size[1] * size[2]];
        let cell_of = |centre: DVec3| {
            let c = ((centre - low) / cell_mm).floor();
            (c.z as usize * size[1] + c.y as usize) * size[0] + c.x as usize
        };
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
        Self {
            origin: low,
            cell_mm,
            size,
            cells,
        }
    }

    /// The runs in the cells around `point`.
    fn runs_near(&self, point: DVec3) -> impl Iterator<Item = &Run> {
        let c = ((point - self.origin) / self.cell_mm).floor();
        let range = |centre: f64, size: usize| {
            let low = (centre as i64 - 1).max(0);
            let high = (centre as i64 + 1).min(size as i64 - 1);
            low..=high
        };
        let mut indices = Vec::with_capacity(27);
        for z in range(c.z, self.size[2]) {
            for y in range(c.y, self.size[1]) {
                for x in range(c.x, self.size[0]) {
                    let index =
                        (z as usize * self.size[1] + y as usize) * self.size[0] + x as usize;
                    indices.push(index);
                }
            }
        }
        indices.into_iter().flat_map(move |i| self.cells[i].iter())
    }
}

/// One pass's cut at a sample: depth along the ray, the path arc length of the pose
/// that made it, and the pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassCut {
    pub depth_mm: f64,
    pub arc_mm: f64,
    pub pose: CutterPose,
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
        // Node spacing: a cutting pose may lie between two nodes.
        let spacing = path
            .passes
            .iter()
            .flat_map(|p| {
                p.nodes
                    .windows(2)
                    .map(|w| (w[1].pose.centre - w[0].pose.centre).length())
            })
            .fold(0.0, f64::max);
        let dip = (stock_top_mm.abs() + lift_mm.abs() + extra_reach_mm).max(0.0);
        // Along a profile of radius r_p the tool dips within √(2 r_p dip); no centre
        // farther than the tool's own size from a cutting one can cut (a face that may
        // stand square has r_p = ∞).
        let across = (2.0 * profile_radius_mm.max(1e-3) * dip)
            .sqrt()
            .min(2.0 * tool.reach_mm());
        let search_radius_mm = across + dip + spacing + 1e-6;
        let bins = NodeBins::new(&path, search_radius_mm + lateral);
        let is_ball = matches!(tool, MillingTool::EndMill(c) if c.major_radius_mm == 0.0);
        // A displaced tooth can cut up to its displacement below the undisplaced sweep.
        let displacement = stamps
            .offsets_mm
            .iter()
            .map(|o| o.length())
            .fold(0.0, f64::max);
        let node_slack_mm = is_ball.then(|| {
            (0.5 * spacing).powi(2) / (2.0 * profile_radius_mm.max(1e-3)) + 1e-9 + displacement
        });
        let mut scene = Self {
            grid,
            tool,
            path,
            stock_top_mm,
            centre_offset_mm,
            lateral_mm: lateral,
            search_radius_mm,
            stamps,
            node_slack_mm,
            bins,
            pairs: 0,
        };
        scene.pairs = scene.count_pairs();
        scene
    }

    /// A sample's nominal point and outward normal in 3-D.
    pub fn sample_ray(&self, ring: usize, azimuth: u32) -> (DVec3, DVec3) {
        (
            self.grid.sample_point(ring, azimuth),
            self.grid.sample_normal(ring, azimuth),
        )
    }

    /// Passes with nodes within the search radius of where a pose cutting the sample
    /// would sit: (pass, first node, last node) over their runs near it. For an end mill
    /// with a flat radius, each run's axis fixes the centre's offset across the normal
    /// (toward n's part across the axis); a flat tip square to the normal may cut from
    /// anywhere within R.
    pub fn candidate_passes(&self, origin: DVec3, normal: DVec3) -> Vec<(u32, u32, u32)> {
        let core = origin + self.centre_offset_mm * normal;
        let mut found: Vec<(u32, u32, u32)> = Vec::new();
        for run in self.bins.runs_near(core) {
            let (expected, radius) = match self.tool {
                MillingTool::EndMill(cutter) if cutter.major_radius_mm > 0.0 => {
                    let across = normal - normal.dot(run.axis) * run.axis;
                    if across.length() > 1e-6 {
                        // The axis turns a little along a run (five-axis): allow for it.
                        let centre = core + cutter.major_radius_mm * across.normalize();
                        (centre, 2.0 * self.search_radius_mm)
                    } else {
                        (core, cutter.major_radius_mm + self.search_radius_mm)
                    }
                }
                _ => (core, self.lateral_mm + self.search_radius_mm),
            };
            if run.distance(expected) > radius {
                continue;
            }
            match found.iter_mut().find(|f| f.0 == run.pass) {
                Some(f) => {
                    f.1 = f.1.min(run.first);
                    f.2 = f.2.max(run.last);
                }
                None => found.push((run.pass, run.first, run.last)),
            }
        }
        found.sort_unstable();
        found
    }

    /// Dexel–pass pairs the engine evaluates (samples × candidate passes).
    pub fn pair_count(&self) -> u64 {
        self.pairs
    }

    fn count_pairs(&self) -> u64 {
        use rayon::prelude::*;
        let rings = self.grid.ring_count();
        (0..self.grid.sample_count())
            .into_par_iter()
            .map(|s| {
                let (origin, normal) = self.sample_ray(s % rings, (s / rings) as u32);
                self.candidate_passes(origin, normal).len() as u64
            })
            .sum()
    }

    /// The entry of the ray into the tool at `pose`, extended above the stock top by
    /// the stock-top point's distance from the tool.
    fn extended_entry(&self, pose: &CutterPose, origin: DVec3, normal: DVec3) -> f64 {
        let top = self.stock_top_mm;
        match self.tool.ray_entry(pose, origin, normal) {
            Some(entry) if entry < top => entry,
            _ => {
                top + self
                    .tool
                    .signed_distance(pose, origin + top * normal)
                    .max(0.0)
            }
        }
    }

    /// A pass's cut at its node nearest the expected pose centre and that node's
    /// neighbours: an upper bound of its lowest cut, which for a ball lies at most
    /// `node_slack_mm` lower.
    fn node_estimate(&self, pass: u32, first: u32, last: u32, origin: DVec3, normal: DVec3) -> f64 {
        let nodes = &self.path.passes[pass as usize].nodes;
        let expected = origin + self.centre_offset_mm * normal;
        let nearest = (first as usize..=last as usize)
            .min_by(|&a, &b| {
                let da = (nodes[a].pose.centre - expected).length_squared();
                let db = (nodes[b].pose.centre - expected).length_squared();
                da.total_cmp(&db)
            })
            .unwrap_or(first as usize);
        (nearest.saturating_sub(1)..=(nearest + 1).min(nodes.len() - 1))
            .map(|i| self.extended_entry(&nodes[i].pose, origin, normal))
            .fold(f64::INFINITY, f64::min)
    }

    /// The lowest cut of pass `pass` (nodes first..=last near the sample) on the ray.
    pub fn pass_cut(
        &self,
        pass: u32,
        first: u32,
        last: u32,
        origin: DVec3,
        normal: DVec3,
    ) -> Option<PassCut> {
        let pass = &self.path.passes[pass as usize];
        let nodes = &pass.nodes;
        let (start, end) = (
            &nodes[(first as usize).saturating_sub(1)],
            &nodes[(last as usize + 1).min(nodes.len() - 1)],
        );
        let (from, to) = (start.arc_mm, end.arc_mm);
        let pitch = self.stamps.feed_per_tooth_mm;
        if pitch > 0.0 && !self.stamps.offsets_mm.is_empty() {
            // Displaced teeth: every stamp over the span.
            let stamps = (from / pitch).ceil() as i64..=(to / pitch).floor() as i64;
            return self.best_stamp(pass, stamps, origin, normal);
        }
        let entry_at = |arc: f64| self.extended_entry(&pass.pose_at(arc), origin, normal);
        // Scan spans longer than the search radius (tight spiral turns), then refine the
        // best bracket.
        let scan = 0.5 * (self.search_radius_mm + self.lateral_mm);
        let mut steps = (((to - from) / scan).ceil() as usize).max(2);
        if pass.interpolation == Interpolation::Polar {
            // On a tight turn at most 45° of it between scan points, so the best
            // bracket (two steps) spans less than the half turn over which the entry
            // can only fall and then rise.
            let turned = (end.polar.y - start.polar.y).abs();
            steps = steps.max((turned / FRAC_PI_4).ceil() as usize);
        }
        let at = |i: usize| from + (to - from) * i as f64 / steps as f64;
        let best = (0..=steps)
            .map(|i| (i, entry_at(at(i))))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(0, |b| b.0);
        let (lo, hi) = (at(best.saturating_sub(1)), at((best + 1).min(steps)));
        // 40 steps shrink the bracket (a few node spacings) to 4e-9 of it.
        let arc = golden_section_min_steps(&entry_at, lo, hi, 40);
        if pitch > 0.0 {
            // Only the tooth positions cut: the stamps around the optimum.
            let nearest = (arc / pitch).floor() as i64;
            return self.best_stamp(pass, nearest - 1..=nearest + 2, origin, normal);
        }
        let depth = entry_at(arc);
        (depth < self.stock_top_mm).then(|| PassCut {
            depth_mm: depth,
            arc_mm: arc,
            pose: pass.pose_at(arc),
        })
    }

    /// The lowest cut on the ray of the stamps `stamps` that lie on the pass.
    fn best_stamp(
        &self,
        pass: &MillingPass,
        stamps: std::ops::RangeInclusive<i64>,
        origin: DVec3,
        normal: DVec3,
    ) -> Option<PassCut> {
        let pitch = self.stamps.feed_per_tooth_mm;
        stamps
            .filter(|&k| (pass.start_arc()..=pass.end_arc()).contains(&(k as f64 * pitch)))
            .map(|k| {
                let arc = k as f64 * pitch;
                let pose = self.stamp_pose(pass, k, arc);
                (arc, pose, self.extended_entry(&pose, origin, normal))
            })
            .min_by(|a, b| a.2.total_cmp(&b.2))
            .filter(|cut| cut.2 < self.stock_top_mm)
            .map(|(arc, pose, depth)| PassCut {
                depth_mm: depth,
                arc_mm: arc,
                pose,
            })
    }

    /// The pose of stamp `k` (at path arc length `arc`): the tool at that point of the
    /// pass, its centre moved by tooth k mod z's displacement.
    fn stamp_pose(&self, pass: &MillingPass, k: i64, arc: f64) -> CutterPose {
        let pose = pass.pose_at(arc);
        let offsets = &self.stamps.offsets_mm;
        if offsets.is_empty() {
            return pose;
        }
        let offset = offsets[k.rem_euclid(offsets.len() as i64) as usize];
        let feed = pass.feed_direction_at(arc);
        let along = (feed - feed.dot(pose.axis) * pose.axis)
            .normalize_or(pose.axis.any_orthonormal_vector());
        let across = pose.axis.cross(along);
        CutterPose::new(
            pose.centre + offset.x * along + offset.y * across,
            pose.axis,
        )
    }
}

impl MillingScene {
    /// Per sample, the diameter of the circle about the tool axis on which the edge cut
    /// the finished surface there (NaN where no pass cut): the effective cutting diameter
    /// at the generating contact (seed 004's De at the point K).
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
                let (origin, normal) = self.sample_ray(s % rings, (s / rings) as u32);
                self.candidate_passes(origin, normal)
                    .into_iter()
                    .find(|c| c.0 == pass)
                    .and_then(|(p, first, last)| self.pass_cut(p, first, last, origin, normal))
                    .map_or(f64::NAN, |cut| {
                        let contact = origin + cut.depth_mm * normal;
                        2.0 * MillingTool::radius_at(&cut.pose, contact)
                    })
            })
            .collect()
    }
}

/// Depths closer than this count as a tie (1e-13 mm, far below any resolved feature).
const TIE_MM: f64 = 1e-13;

/// The machined surface at one sample and the pass that left it (the pass index).
/// For a ball, candidate passes are ranked by their cut at the nearest nodes and one is
/// searched in full only while that estimate, less the slack between nodes, can still
/// beat the best; other tools search every candidate.
pub fn milling_dexel(scene: &MillingScene, ring: usize, azimuth: u32) -> (f64, u32) {
    let (origin, normal) = scene.sample_ray(ring, azimuth);
    let mut ranked: Vec<(f64, u32, u32, u32)> = scene
        .candidate_passes(origin, normal)
        .into_iter()
        .map(|(pass, first, last)| {
            let estimate = match scene.node_slack_mm {
                Some(_) => scene.node_estimate(pass, first, last, origin, normal),
                None => f64::NEG_INFINITY,
            };
            (estimate, pass, first, last)
        })
        .collect();
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut best = (scene.stock_top_mm, NO_PASS);
    for (estimate, pass, first, last) in ranked {
        if scene
            .node_slack_mm
            .is_some_and(|slack| estimate - slack >= best.0)
        {
            break;
        }
        // A pass must cut measurably deeper to win: on a cusp line two passes tie, and
        // rounding must not make the winner flicker from sample to sample.
        if let Some(cut) = scene.pass_cut(pass, first, last, origin, normal)
            && (cut.depth_mm < best.0 - TIE_MM || (cut.depth_mm < best.0 + TIE_MM && pass < best.1))
        {
            best = (cut.depth_mm, pass);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::Scene;
    use crate::io::job::Job;

    /// A ball raster over a plane, passes 0.5 mm apart, with a runout (ε, φ).
    fn runout_scene(teeth: u32, feed_mm: f64, offset_mm: f64, phase_deg: f64) -> MillingScene {
        let job = Job::from_toml_str(
            &format!(
                r#"version = 1
[surface]
kind = "plane"
aperture_diameter_mm = 1.0
[tool]
kind = "ball_end"
diameter_mm = 1.0
teeth = {teeth}
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.5
feed_per_tooth_mm = {feed_mm}
stock_allowance_mm = 0.01
[grid]
pitch_um = 5.0
azimuths = 12
[[effects]]
kind = "radial_runout"
offset_mm = {offset_mm}
phase_deg = {phase_deg}
"#
            ),
            "runout",
        )
        .expect("valid job");
        match crate::run::prepare_scenes(&job).remove(0) {
            Scene::Milling(scene) => scene,
            _ => panic!("a milling scene"),
        }
    }

    #[test]
    fn tooth_zero_at_a_quarter_turn_sits_to_the_left_of_the_feed() {
        // Right-handed about the (vertical) axis, a quarter turn from +X is +Y.
        let scene = runout_scene(2, 0.05, 0.01, 90.0);
        let pass = scene
            .path
            .passes
            .iter()
            .find(|p| p.nodes[1].pose.centre.x > p.nodes[0].pose.centre.x)
            .expect("a pass feeding along +X");
        let k = (pass.start_arc() / 0.05).ceil() as i64 + 2;
        let arc = k as f64 * 0.05;
        let nominal = pass.pose_at(arc).centre;
        let even = 2 * k.div_euclid(2);
        let shift = scene.stamp_pose(pass, even, arc).centre - nominal;
        assert!(
            (shift - DVec3::new(0.0, 0.01, 0.0)).length() < 1e-12,
            "{shift}"
        );
        let shift = scene.stamp_pose(pass, even + 1, arc).centre - nominal;
        assert!(
            (shift - DVec3::new(0.0, -0.01, 0.0)).length() < 1e-12,
            "{shift}"
        );
    }

    #[test]
    fn displaced_teeth_cut_as_deep_as_every_stamp_of_every_pass_allows() {
        // The largest runout allowed (f/2), across the feed, on 6 teeth: near the cusps
        // between passes (0.25 mm off them) the tooth displaced toward a sample cuts it
        // deepest even three stamps from the nearest (2bε > 9f² + ε²), beyond the 4
        // stamps around the continuous optimum. The engine's candidate passes and stamps
        // against all stamps of all passes, at every sample.
        let scene = runout_scene(6, 0.01, 0.005, 90.0);
        let pitch = scene.stamps.feed_per_tooth_mm;
        let rings = scene.grid.ring_count();
        let mut worst = 0.0f64;
        for s in 0..scene.grid.sample_count() {
            let (ring, azimuth) = (s % rings, (s / rings) as u32);
            let (origin, normal) = scene.sample_ray(ring, azimuth);
            let brute = scene
                .path
                .passes
                .iter()
                .flat_map(|pass| {
                    let first = (pass.start_arc() / pitch).ceil() as i64;
                    let last = (pass.end_arc() / pitch).floor() as i64;
                    (first..=last).map(move |k| (pass, k))
                })
                .map(|(pass, k)| {
                    let pose = scene.stamp_pose(pass, k, k as f64 * pitch);
                    scene
                        .tool
                        .ray_entry(&pose, origin, normal)
                        .unwrap_or(f64::INFINITY)
                })
                .fold(scene.stock_top_mm, f64::min);
            let (depth, _) = milling_dexel(&scene, ring, azimuth);
            worst = worst.max((depth - brute).abs());
        }
        assert!(worst < 1e-12, "{worst}");
    }
}

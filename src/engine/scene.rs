//! Everything a removal engine needs for a turning job, prepared once in f64: the
//! grid, the pose table, the edge, and for each ring the spindle revolutions whose tool
//! can reach it, so cost follows the dexel–pass pairs that can touch (a rotating process
//! revisits a sample once per revolution) rather than samples × all poses.
//!
//! Pass geometry. The tool's edge lies in its rake plane y = y₀ of the machine frame
//! (y₀ = 0 on centre). The workpiece turns by the spindle angle C (counter-clockwise
//! seen from +Z), so a sample at workpiece azimuth φ and radius r meets the edge point
//! at machine x = ±q, q = √(r² − y₀²), whenever its machine azimuth φ + C equals that
//! point's azimuth α = atan2(y₀, ±q): once per revolution k, at C = 2πk − β with
//! β = (φ − α) mod 2π (rev k spans C ∈ (2π(k−1), 2πk]). The + side is the *direct*
//! branch; near the axis the edge also reaches past it and cuts with its x < 0 part, the
//! *mirrored* branch (frame mirrored: nose-centre x negated). Samples closer to the axis
//! than |y₀| never meet the edge; with the tool above centre its flank, which straddles
//! the axis, reaches them at machine (0, −r): the *flank* branch.

use crate::field::PolarGrid;
use crate::geometry::tool::{ArcNoseTool, DeviationMaxima, EdgeModel};
use crate::process::PoseTable;
use crate::process::effects::TurningEffects;
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// The ways a pass can reach a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    Direct = 0,
    Mirrored = 1,
    Flank = 2,
}

impl Branch {
    pub const ALL: [Branch; 3] = [Branch::Direct, Branch::Mirrored, Branch::Flank];

    /// +1 or −1: the factor on machine x in this branch's frame.
    pub fn x_sign(self) -> f64 {
        match self {
            Branch::Mirrored => -1.0,
            _ => 1.0,
        }
    }
}

/// Pass ids: `rev · PASS_ID_STRIDE + branch`.
pub const PASS_ID_STRIDE: u32 = 4;

/// An inclusive range of revolutions (relative to the scene's first), empty when first > last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RevRange {
    pub first: u32,
    pub last: u32,
}

impl RevRange {
    pub const EMPTY: RevRange = RevRange { first: 1, last: 0 };

    pub fn len(self) -> u64 {
        if self.first > self.last {
            0
        } else {
            (self.last - self.first) as u64 + 1
        }
    }

    pub fn is_empty(self) -> bool {
        self.len() == 0
    }

    /// The smallest range holding both.
    fn union(&mut self, other: RevRange) {
        if !other.is_empty() {
            self.include(other.first);
            self.include(other.last);
        }
    }

    fn include(&mut self, rev: u32) {
        if self.is_empty() {
            *self = RevRange {
                first: rev,
                last: rev,
            };
        } else {
            self.first = self.first.min(rev);
            self.last = self.last.max(rev);
        }
    }
}

/// How a pass changes the height it finds at a sample (heights along the sample's ray,
/// higher = more material): an edge reaching depth d below the height h cuts a chip
/// c = h − d and leaves d when c ≥ `min_chip_mm`; a thinner chip ploughs and the
/// material springs back to d + `recovery`·c. Zero parameters ([`SpringBack::NONE`])
/// give the running minimum bit for bit.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpringBack {
    pub min_chip_mm: f64,
    pub recovery: f64,
}

impl SpringBack {
    /// The removal rule a tool with `effects` leaves (the running minimum without
    /// spring-back).
    pub fn of(effects: &TurningEffects) -> SpringBack {
        SpringBack {
            min_chip_mm: effects.spring_back_min_chip_mm,
            recovery: effects.spring_back_recovery,
        }
    }

    pub const NONE: SpringBack = SpringBack {
        min_chip_mm: 0.0,
        recovery: 0.0,
    };

    /// The height after a pass whose edge reaches depth `depth` (+∞ or NaN: it misses)
    /// where the surface stands at `height`. The pass changed the sample when the result
    /// is below `height`. Written as selects so that the CPU's lanes vectorise it (a
    /// miss makes `cut` NaN, which the last select drops, as `depth < height` would).
    #[inline(always)]
    pub fn after(self, height: f64, depth: f64) -> f64 {
        let chip = height - depth;
        let cut = if chip < self.min_chip_mm {
            depth + self.recovery * chip
        } else {
            depth
        };
        if chip > 0.0 { cut } else { height }
    }
}

/// Per ring: the edge's lateral coordinate q = √(r² − y₀²) there (0 when the edge
/// cannot reach the ring), the direct branch's pass azimuth α, and the revolutions
/// each branch can reach it in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingPasses {
    pub lateral_mm: f64,
    pub direct_azimuth_rad: f64,
    pub revs: [RevRange; 3],
}

#[derive(Debug, Clone)]
pub struct TurningScene {
    pub grid: PolarGrid,
    /// The poses the machine runs (effects such as a decentre already applied).
    pub poses: PoseTable,
    pub edge: EdgeModel,
    /// The edge's deviation bounded over short arcs, for pruning passes (empty for a
    /// circle).
    pub deviation_maxima: DeviationMaxima,
    /// Machine y of the edge's rake plane (0 = on centre).
    pub edge_plane_y_mm: f64,
    /// tan(clearance angle) of the flank.
    pub tan_clearance: f64,
    /// Normal distance of the stock's top above nominal: the value of uncut samples.
    pub stock_top_mm: f64,
    /// How each pass changes a sample's height (spring-back below a minimum chip).
    pub spring_back: SpringBack,
    /// Number of revolutions with passes (relative index 0 = the first).
    pub rev_count: u32,
    /// Node index of pass (rev 0, β = 0) before subtracting the phase: (k_first − k0)·S.
    pub base_steps: i64,
    /// Spindle angle of the table start within its revolution, C₀ − 2πk₀ ∈ [0, 2π).
    pub start_phase_rad: f64,
    pub rings: Vec<RingPasses>,
}

impl TurningScene {
    /// `cut_band_mm` is how far from nominal the path's nominal cuts lie; `extra_reach_mm`
    /// widens the reach test for anything that can push the cut beyond that band
    /// (effects; 0 for a nominal job).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        grid: PolarGrid,
        poses: PoseTable,
        tool: &ArcNoseTool,
        edge: EdgeModel,
        edge_plane_y_mm: f64,
        stock_allowance_mm: f64,
        cut_band_mm: f64,
        extra_reach_mm: f64,
    ) -> Self {
        let steps = poses.steps_per_rev as i64;
        let start = poses.start_angle_rad;
        let whole_revs_before_start = (start / TAU).floor();
        let start_phase_rad = start - whole_revs_before_start * TAU;
        let first_rev = (start / TAU).ceil() as i64;
        let last_rev = (poses.end_angle_rad() / TAU).ceil() as i64;
        let rev_count = (last_rev - first_rev + 1).max(0) as u32;
        let base_steps = (first_rev - whole_revs_before_start as i64) * steps;

        // A pass farther than R + margin from a sample cannot enter its dexel within
        // ±margin of the nominal surface, where every cut of this job lies.
        let margin = stock_allowance_mm + cut_band_mm + extra_reach_mm + 1e-6;
        let reach = edge.nominal_radius_mm + margin;
        let rings =
            reachable_revolutions(&grid, &poses, first_rev, rev_count, reach, edge_plane_y_mm);

        Self {
            grid,
            poses,
            deviation_maxima: DeviationMaxima::new(&edge.deviation),
            edge,
            edge_plane_y_mm,
            tan_clearance: tool.clearance_angle_deg.to_radians().tan(),
            stock_top_mm: stock_allowance_mm,
            spring_back: SpringBack::NONE,
            rev_count,
            base_steps,
            start_phase_rad,
            rings,
        }
    }

    /// Spindle-angle phase β of a branch's passes for a sample (rad, in [0, 2π)).
    pub fn pass_phase(&self, ring: usize, azimuth_rad: f64, branch: Branch) -> f64 {
        let alpha = match branch {
            Branch::Direct => self.rings[ring].direct_azimuth_rad,
            Branch::Mirrored => PI - self.rings[ring].direct_azimuth_rad,
            Branch::Flank => -FRAC_PI_2,
        };
        (azimuth_rad - alpha).rem_euclid(TAU)
    }

    /// The pose-table position (node index, fraction) of pass `rev` at phase β, or
    /// `None` when the pass lies outside the table. Integer node arithmetic keeps the
    /// f32 GPU path indexing exactly like this one.
    pub fn pass_position(&self, rev: u32, phase_rad: f64) -> Option<(usize, f64)> {
        let steps_in = (phase_rad + self.start_phase_rad) / self.poses.step_rad();
        let whole = steps_in.floor();
        let fraction = steps_in - whole;
        let base = self.base_steps + rev as i64 * self.poses.steps_per_rev as i64 - whole as i64;
        let (mut index, mut t) = if fraction > 0.0 {
            (base - 1, 1.0 - fraction)
        } else {
            (base, 0.0)
        };
        let last = self.poses.poses.len() as i64 - 1;
        if index == last && t == 0.0 {
            index -= 1;
            t = 1.0;
        }
        if index < 0 || index >= last {
            return None;
        }
        Some((index as usize, t))
    }

    /// The spindle angle turned since this table's first node when this scene's pass
    /// `pass_id` crosses `sample` (rad); `None` outside the table.
    pub fn pass_angle_rad(&self, sample: usize, pass_id: u32) -> Option<f64> {
        let rings = self.grid.ring_count();
        let (ring, row) = (sample % rings, (sample / rings) as u32);
        let branch = *Branch::ALL.get((pass_id % PASS_ID_STRIDE) as usize)?;
        let phase = self.pass_phase(ring, self.grid.azimuth_rad(row), branch);
        let (index, t) = self.pass_position(pass_id / PASS_ID_STRIDE, phase)?;
        Some((index as f64 + t) * self.poses.step_rad())
    }

    /// Dexel–pass pairs an engine evaluates: the work measure for throughput.
    pub fn pair_count(&self) -> u64 {
        let per_row: u64 = self
            .rings
            .iter()
            .map(|ring| ring.revs.iter().map(|r| r.len()).sum::<u64>())
            .sum();
        per_row * self.grid.azimuths as u64
    }
}

/// For each ring and branch, the revolutions whose nose centre comes within `reach`
/// of the ring's point in that branch's frame (tested against each revolution's
/// bounding box). Revolutions are tested in parallel; a ring's range is the union of
/// the revolutions that reach it, whatever order they are found in.
fn reachable_revolutions(
    grid: &PolarGrid,
    poses: &PoseTable,
    first_rev: i64,
    rev_count: u32,
    reach: f64,
    edge_plane_y: f64,
) -> Vec<RingPasses> {
    let y0 = edge_plane_y;
    let laterals: Vec<f64> = grid
        .rings
        .iter()
        .map(|ring| (ring.radius_mm * ring.radius_mm - y0 * y0).max(0.0).sqrt())
        .collect();
    let blocks = RingBlocks::new(grid, &laterals);
    let revs = (0..rev_count)
        .into_par_iter()
        .fold(
            || vec![[RevRange::EMPTY; 3]; grid.ring_count()],
            |mut revs, rev| {
                let k = first_rev + rev as i64;
                if let Some(bounds) = revolution_bounds(poses, TAU * (k - 1) as f64, TAU * k as f64)
                {
                    let rings = (grid, &laterals[..], &blocks);
                    revolution_reach(rings, &bounds, reach, y0, |ring, branch| {
                        revs[ring][branch as usize].include(rev)
                    });
                }
                revs
            },
        )
        .reduce_with(|mut a, b| {
            for (a, b) in a.iter_mut().flatten().zip(b.iter().flatten()) {
                a.union(*b);
            }
            a
        })
        .unwrap_or_else(|| vec![[RevRange::EMPTY; 3]; grid.ring_count()]);
    laterals
        .iter()
        .zip(revs)
        .map(|(&lateral, revs)| RingPasses {
            lateral_mm: lateral,
            direct_azimuth_rad: y0.atan2(lateral),
            revs,
        })
        .collect()
}

/// Calls `reached(ring, branch)` for every ring and branch one revolution of bounding
/// box `bounds` reaches.
fn revolution_reach(
    (grid, laterals, blocks): (&PolarGrid, &[f64], &RingBlocks),
    bounds: &Bounds,
    reach: f64,
    y0: f64,
    mut reached: impl FnMut(usize, Branch),
) {
    // Rings the edge reaches have r > |y₀|; those inside are the flank's (tool above centre).
    let edge_reaches = |ring: &crate::field::Ring| y0 == 0.0 || ring.radius_mm > y0.abs();
    let dz = |ring: &crate::field::Ring| {
        (bounds.z_min - ring.height_mm)
            .max(ring.height_mm - bounds.z_max)
            .max(0.0)
    };
    for branch in [Branch::Direct, Branch::Mirrored] {
        let (x_lo, x_hi) = if branch == Branch::Direct {
            (bounds.x_min, bounds.x_max)
        } else {
            (-bounds.x_max, -bounds.x_min)
        };
        let first_ring = laterals.partition_point(|&q| q < x_lo - reach);
        let end_ring = laterals
            .partition_point(|&q| q <= x_hi + reach)
            .max(first_ring);
        let mut start = first_ring;
        while start < end_ring {
            let block = start / RING_BLOCK;
            let end = ((block + 1) * RING_BLOCK).min(end_ring);
            if blocks.out_of_reach(block, bounds, (x_lo, x_hi), reach) {
                start = end;
                continue;
            }
            let candidates = grid.rings[start..end].iter().zip(&laterals[start..end]);
            for (index, (ring, &q)) in (start..).zip(candidates) {
                let dx = (x_lo - q).max(q - x_hi).max(0.0);
                if edge_reaches(ring) && within(dx, dz(ring), reach) {
                    reached(index, branch);
                }
            }
            start = end;
        }
    }
    // The flank touches the pip where the edge spans the axis (|x| < R).
    if y0 < 0.0 && bounds.x_min < reach && bounds.x_max > -reach {
        for (index, ring) in grid
            .rings
            .iter()
            .enumerate()
            .take_while(|(_, r)| !edge_reaches(r))
        {
            if dz(ring) <= reach {
                reached(index, Branch::Flank);
            }
        }
    }
}

/// Rings per block of [`RingBlocks`].
const RING_BLOCK: usize = 32;

/// Consecutive rings in blocks, each with the span of its laterals and heights: a
/// revolution whose bounding box lies out of reach of a block's span reaches none of
/// its rings (each ring's distances are at least the block's, and IEEE arithmetic is
/// monotonic, so the ring-by-ring test would refuse every one), and the block is skipped.
struct RingBlocks {
    lateral: Vec<(f64, f64)>,
    height: Vec<(f64, f64)>,
}

impl RingBlocks {
    fn new(grid: &PolarGrid, laterals: &[f64]) -> Self {
        let span = |values: &mut dyn Iterator<Item = f64>| {
            values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
        };
        RingBlocks {
            lateral: laterals
                .chunks(RING_BLOCK)
                .map(|c| span(&mut c.iter().copied()))
                .collect(),
            height: grid
                .rings
                .chunks(RING_BLOCK)
                .map(|c| span(&mut c.iter().map(|r| r.height_mm)))
                .collect(),
        }
    }

    /// Whether no ring of `block` lies within `reach` of the box (`x_lo..x_hi` the
    /// branch's lateral span) by [`within`]'s own rule.
    fn out_of_reach(
        &self,
        block: usize,
        bounds: &Bounds,
        (x_lo, x_hi): (f64, f64),
        reach: f64,
    ) -> bool {
        let (q_lo, q_hi) = self.lateral[block];
        let (h_lo, h_hi) = self.height[block];
        let dx = (x_lo - q_hi).max(q_lo - x_hi).max(0.0);
        let dz = (bounds.z_min - h_hi).max(h_lo - bounds.z_max).max(0.0);
        // NaN spans (no such ring) never skip.
        dx * dx + dz * dz > reach * reach * (1.0 + 1e-12)
    }
}

/// `dx.hypot(dz) <= reach`, decided from the squares unless they lie within rounding
/// of the boundary (then by `hypot` itself, so the decision is always hypot's).
fn within(dx: f64, dz: f64, reach: f64) -> bool {
    let (squared, limit) = (dx * dx + dz * dz, reach * reach);
    if squared < limit * (1.0 - 1e-12) {
        true
    } else if squared > limit * (1.0 + 1e-12) {
        false
    } else {
        dx.hypot(dz) <= reach
    }
}

struct Bounds {
    x_min: f64,
    x_max: f64,
    z_min: f64,
    z_max: f64,
}

/// Bounding box of the nose centre over spindle angles [c_from, c_to] (exact for the
/// piecewise-linear path: its extremes are at nodes or the interval's ends).
fn revolution_bounds(poses: &PoseTable, c_from: f64, c_to: f64) -> Option<Bounds> {
    let c_from = c_from.max(poses.start_angle_rad);
    let c_to = c_to.min(poses.end_angle_rad());
    if c_from > c_to {
        return None;
    }
    let step = poses.step_rad();
    let first_inner = ((c_from - poses.start_angle_rad) / step).ceil() as usize;
    let last_inner =
        (((c_to - poses.start_angle_rad) / step).floor() as usize).min(poses.poses.len() - 1);
    let inner = if first_inner <= last_inner {
        &poses.poses[first_inner..=last_inner]
    } else {
        &[]
    };
    let ends = [poses.pose_at(c_from), poses.pose_at(c_to)];
    let mut bounds = Bounds {
        x_min: f64::INFINITY,
        x_max: f64::NEG_INFINITY,
        z_min: f64::INFINITY,
        z_max: f64::NEG_INFINITY,
    };
    for pose in ends.into_iter().flatten().chain(inner.iter().copied()) {
        bounds.x_min = bounds.x_min.min(pose.x_mm);
        bounds.x_max = bounds.x_max.max(pose.x_mm);
        bounds.z_min = bounds.z_min.min(pose.z_mm);
        bounds.z_max = bounds.z_max.max(pose.z_mm);
    }
    bounds.x_min.is_finite().then_some(bounds)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::Scene;

    /// Every ring tested against every revolution's box by [`within`], no window and no
    /// blocks: what [`reachable_revolutions`] must find.
    fn every_ring(
        grid: &PolarGrid,
        poses: &PoseTable,
        (first_rev, rev_count): (i64, u32),
        reach: f64,
        y0: f64,
    ) -> Vec<[RevRange; 3]> {
        let mut revs = vec![[RevRange::EMPTY; 3]; grid.ring_count()];
        for rev in 0..rev_count {
            let k = first_rev + rev as i64;
            let Some(b) = revolution_bounds(poses, TAU * (k - 1) as f64, TAU * k as f64) else {
                continue;
            };
            for (i, ring) in grid.rings.iter().enumerate() {
                let q = (ring.radius_mm * ring.radius_mm - y0 * y0).max(0.0).sqrt();
                let edge = y0 == 0.0 || ring.radius_mm > y0.abs();
                let dz = (b.z_min - ring.height_mm)
                    .max(ring.height_mm - b.z_max)
                    .max(0.0);
                for (branch, (lo, hi)) in [
                    (Branch::Direct, (b.x_min, b.x_max)),
                    (Branch::Mirrored, (-b.x_max, -b.x_min)),
                ] {
                    let dx = (lo - q).max(q - hi).max(0.0);
                    if edge && within(dx, dz, reach) {
                        revs[i][branch as usize].include(rev);
                    }
                }
                if y0 < 0.0 && !edge && b.x_min < reach && b.x_max > -reach && dz <= reach {
                    revs[i][Branch::Flank as usize].include(rev);
                }
            }
        }
        revs
    }

    #[test]
    fn skipped_ring_blocks_change_no_reachable_range() {
        use crate::geometry::Form;
        use crate::model::{JobFile, ProcessSpec, SurfaceSpec, ToolSpec, TurningSpec};
        let job = JobFile::new(
            SurfaceSpec::sphere(Form::Convex, 3.0, 1.0),
            ToolSpec::arc_nose(0.1, 120.0),
            ProcessSpec::Turning(TurningSpec {
                stock_allowance_mm: Some(0.002),
                ..TurningSpec::xz(0.005)
            }),
        )
        .named("reach")
        .grid(0.5, 4)
        .check()
        .expect("valid job");
        let scenes = crate::pipeline::prepare_scenes(&job);
        let Some(Scene::Turning(scene)) = scenes.first() else {
            panic!("a turning scene");
        };
        let first_rev = (scene.poses.start_angle_rad / TAU).ceil() as i64;
        let revs = (first_rev, scene.rev_count);
        let mut reached = 0;
        for (reach, y0) in [(0.103, 0.0), (0.103, 0.004), (0.103, -0.004), (0.02, 0.0)] {
            let found =
                reachable_revolutions(&scene.grid, &scene.poses, first_rev, revs.1, reach, y0);
            let expected = every_ring(&scene.grid, &scene.poses, revs, reach, y0);
            for (ring, (f, e)) in found.iter().zip(&expected).enumerate() {
                assert_eq!(f.revs, *e, "reach {reach}, y0 {y0}: ring {ring}");
                reached += e.iter().filter(|r| !r.is_empty()).count();
            }
        }
        assert!(reached > 1000, "only {reached} ring ranges reached");
    }
}

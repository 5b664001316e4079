//! Everything a removal engine needs for a turning job, prepared once in f64: the
//! grid, the pose table, and for each ring the spindle revolutions whose tool can
//! reach it, so cost follows the dexel–pass pairs that can touch (a rotating process
//! revisits a sample once per revolution) rather than samples × all poses.
//!
//! Pass geometry. The tool sits at machine azimuth 0; the workpiece turns by the
//! spindle angle C, so a sample at workpiece azimuth φ meets the edge whenever
//! `C = 2πk − φ`: one pass per revolution k (rev k spans C ∈ (2π(k−1), 2πk]).
//! Near the axis the edge also reaches past it, cutting samples on the far side
//! (φ + π) with its x < 0 part: the *mirrored* branch, with the nose-centre x negated.

use crate::field::PolarGrid;
use crate::geometry::tool::ArcNoseTool;
use crate::process::PoseTable;
use std::f64::consts::{PI, TAU};

/// The two ways an edge point can reach a sample: on the tool's side of the axis, or past it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    Direct = 0,
    Mirrored = 1,
}

impl Branch {
    pub const BOTH: [Branch; 2] = [Branch::Direct, Branch::Mirrored];

    /// +1 or −1: the factor on the nose-centre x in this branch.
    pub fn x_sign(self) -> f64 {
        match self {
            Branch::Direct => 1.0,
            Branch::Mirrored => -1.0,
        }
    }
}

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

/// Where a sample row's passes fall in the pose table: for pass k the fractional node
/// index is `(k_rel·S + base) − (whole + fraction)`, kept as integer + fraction so the
/// f32 GPU path indexes exactly like the f64 path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AzimuthPhase {
    pub whole_steps: u32,
    pub fraction: f64,
}

#[derive(Debug, Clone)]
pub struct TurningScene {
    pub grid: PolarGrid,
    pub poses: PoseTable,
    pub tool: ArcNoseTool,
    /// Normal distance of the stock's top above nominal: the value of uncut samples.
    pub stock_top_mm: f64,
    /// Number of revolutions with passes (relative index 0 = the first).
    pub rev_count: u32,
    /// Node index of pass (k_rel = 0, φ = 0) before subtracting the phase: (k_first − k0)·S.
    pub base_steps: i64,
    /// Per ring, per branch: the revolutions whose tool can reach it.
    pub ring_revs: Vec<[RevRange; 2]>,
    /// Per azimuth row, per branch.
    pub azimuth_phases: Vec<[AzimuthPhase; 2]>,
}

impl TurningScene {
    /// `extra_reach_mm` widens the reach test for anything that can push the tool
    /// further than its nominal path (none in a nominal job).
    pub fn new(
        grid: PolarGrid,
        poses: PoseTable,
        tool: ArcNoseTool,
        stock_allowance_mm: f64,
        target_offset_mm: f64,
        extra_reach_mm: f64,
    ) -> Self {
        let steps = poses.steps_per_rev as i64;
        let start = poses.start_angle_rad;
        let whole_revs_before_start = (start / TAU).floor();
        let start_fraction_rad = start - whole_revs_before_start * TAU;
        let first_rev = (start / TAU).ceil() as i64;
        let last_rev = (poses.end_angle_rad() / TAU).ceil() as i64;
        let rev_count = (last_rev - first_rev + 1).max(0) as u32;
        let base_steps = (first_rev - whole_revs_before_start as i64) * steps;

        let azimuth_phases = (0..grid.azimuths)
            .map(|j| {
                let phi = grid.azimuth_rad(j);
                Branch::BOTH.map(|branch| {
                    let azimuth = match branch {
                        Branch::Direct => phi,
                        Branch::Mirrored => (phi + PI) % TAU,
                    };
                    let steps_in = (azimuth + start_fraction_rad) / poses.step_rad();
                    let whole = steps_in.floor();
                    AzimuthPhase {
                        whole_steps: whole as u32,
                        fraction: steps_in - whole,
                    }
                })
            })
            .collect();

        // A pass farther than R + margin from a sample cannot enter its dexel within
        // ±margin of the nominal surface, where every nominal cut lies.
        let margin = stock_allowance_mm + target_offset_mm.abs() + extra_reach_mm + 1e-6;
        let reach = tool.nose_radius_mm + margin;
        let ring_revs = reachable_revolutions(&grid, &poses, first_rev, rev_count, reach);

        Self {
            grid,
            poses,
            tool,
            stock_top_mm: stock_allowance_mm,
            rev_count,
            base_steps,
            ring_revs,
            azimuth_phases,
        }
    }

    pub fn cos_half_span(&self) -> f64 {
        self.tool.half_span_rad().min(PI).cos()
    }

    /// The pose-table position (node index, fraction) of pass `rev` for a row's phase,
    /// or `None` when that pass lies outside the table.
    pub fn pass_position(&self, rev: u32, phase: AzimuthPhase) -> Option<(usize, f64)> {
        let base = self.base_steps + rev as i64 * self.poses.steps_per_rev as i64
            - phase.whole_steps as i64;
        let (mut index, mut t) = if phase.fraction > 0.0 {
            (base - 1, 1.0 - phase.fraction)
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

    /// Dexel–pass pairs an engine evaluates: the work measure for throughput.
    pub fn pair_count(&self) -> u64 {
        let per_row: u64 = self
            .ring_revs
            .iter()
            .map(|ranges| ranges[0].len() + ranges[1].len())
            .sum();
        per_row * self.grid.azimuths as u64
    }
}

/// For each ring and branch, the revolutions whose nose centre comes within `reach`
/// of the ring's nominal point (tested against each revolution's bounding box).
fn reachable_revolutions(
    grid: &PolarGrid,
    poses: &PoseTable,
    first_rev: i64,
    rev_count: u32,
    reach: f64,
) -> Vec<[RevRange; 2]> {
    let mut ranges = vec![[RevRange::EMPTY; 2]; grid.ring_count()];
    let ring_radii: Vec<f64> = grid.rings.iter().map(|ring| ring.radius_mm).collect();
    for rev in 0..rev_count {
        let k = first_rev + rev as i64;
        let Some(bounds) = revolution_bounds(poses, TAU * (k - 1) as f64, TAU * k as f64) else {
            continue;
        };
        for branch in Branch::BOTH {
            let sign = branch.x_sign();
            let (x_lo, x_hi) = if sign > 0.0 {
                (bounds.x_min, bounds.x_max)
            } else {
                (-bounds.x_max, -bounds.x_min)
            };
            let first_ring = ring_radii.partition_point(|&r| r < x_lo - reach);
            let end_ring = ring_radii.partition_point(|&r| r <= x_hi + reach);
            for (ring_index, ring) in grid.rings[first_ring..end_ring].iter().enumerate() {
                let dx = (x_lo - ring.radius_mm).max(ring.radius_mm - x_hi).max(0.0);
                let dz = (bounds.z_min - ring.height_mm)
                    .max(ring.height_mm - bounds.z_max)
                    .max(0.0);
                if dx.hypot(dz) <= reach {
                    ranges[first_ring + ring_index][branch as usize].include(rev);
                }
            }
        }
    }
    ranges
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

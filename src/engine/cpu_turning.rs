//! The CPU engine's turning removal: the arithmetic of the scalar twin
//! ([`super::cpu_turning_scalar::sample_dexel`]) rearranged so that nothing transcendental runs per
//! dexel–pass pair and eight neighbouring rings of one azimuth row are evaluated side by
//! side in SIMD lanes. Every pair goes through the same IEEE operations in the same
//! order as in the twin (Rust never fuses a multiply and an add), and each sample keeps
//! the first of equal lowest entries in the twin's pass order, so the field is the
//! twin's bit for bit on any instruction set (tested against it).
//!
//! - Per scene: each pose node with its step to the next (the lerp `a + t·(b − a)` reads
//!   `b − a`, the same value), the edge's constants ([`EdgeSolver`]), the rings as lanes,
//!   and the tip direction when B stays 0 (XZ).
//! - Per block of eight rings and branch: the pass phase, the node of revolution 0 and
//!   the fraction t. On centre (y₀ = 0) these are the same for every ring of a row, so a
//!   pass's pose — and with B moving, its tip direction's sine and cosine — is computed
//!   once for the eight rings; off centre each ring has its own.
//! - Per pair: the ray's entry into the edge circle (one square root, one division; off
//!   centre a second entry after the ray's re-linearisation), the span test and the
//!   height update (the running minimum, or with spring-back the same
//!   [`SpringBack::after`](super::scene::SpringBack::after) as the twin: the passes of a
//!   lane run in the twin's order, so the sequential rule holds lane-wise).
//!
//! An edge that departs from its circle (waviness, a measured edge: the hit angle needs
//! an arctangent) runs in lanes on centre without spring-back as the twin prunes it:
//! each pass's bound (the circle holding the whole edge) in lanes, the twin's own full
//! entry only where the bound reaches below the lowest entry. Left to the scalar twin:
//! such an edge off centre or with spring-back, the flank branch (the few rings inside
//! |y₀|) and a pass that falls exactly on the table's last node.

use super::cpu_turning_scalar::{
    PRUNE_MARGIN_MM, RAY_REFINEMENTS, branch_dexel, local_bound_entry, pass_entry,
};
use super::scene::{Branch, PASS_ID_STRIDE, RevRange, SpringBack, TurningScene};
use crate::field::NO_PASS;
use crate::geometry::tool::{EdgeSolver, tip_direction};
use crate::process::ToolPose;
use glam::DVec2;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Rings evaluated side by side.
pub const LANES: usize = 8;

/// Each pose node (but the last) with its step to the next: what the lerp reads.
struct NodeSteps {
    x: Vec<f64>,
    dx: Vec<f64>,
    z: Vec<f64>,
    dz: Vec<f64>,
    b: Vec<f64>,
    db: Vec<f64>,
}

impl NodeSteps {
    fn new(poses: &[ToolPose]) -> Self {
        let steps = || poses.windows(2).map(|pair| (pair[0], pair[1]));
        NodeSteps {
            x: steps().map(|(a, _)| a.x_mm).collect(),
            dx: steps().map(|(a, b)| b.x_mm - a.x_mm).collect(),
            z: steps().map(|(a, _)| a.z_mm).collect(),
            dz: steps().map(|(a, b)| b.z_mm - a.z_mm).collect(),
            b: steps().map(|(a, _)| a.b_rad).collect(),
            db: steps().map(|(a, b)| b.b_rad - a.b_rad).collect(),
        }
    }

    /// `ToolPose::lerp` from `node` by `t`: (x, z, b).
    #[inline(always)]
    fn lerp(&self, node: usize, t: f64) -> (f64, f64, f64) {
        (
            self.x[node] + t * self.dx[node],
            self.z[node] + t * self.dz[node],
            self.b[node] + t * self.db[node],
        )
    }
}

/// The rings as lanes read them, padded to whole blocks with rings no pass reaches.
struct RingLanes {
    radius_mm: Vec<f64>,
    height_mm: Vec<f64>,
    normal_x: Vec<f64>,
    normal_y: Vec<f64>,
    lateral_mm: Vec<f64>,
    /// The ray's direction in the rake plane is (direction_x, normal_y) (the normal on
    /// centre), of squared length `direction_squared`.
    direction_x: Vec<f64>,
    direction_squared: Vec<f64>,
    /// Per edge branch (direct, mirrored): each ring's reachable revolutions.
    revs: [Vec<RevRange>; 2],
}

impl RingLanes {
    fn new(scene: &TurningScene) -> Self {
        let y0 = scene.edge_plane_y_mm;
        let count = scene.rings.len().next_multiple_of(LANES);
        let ring = |i: usize| {
            scene
                .grid
                .rings
                .get(i)
                .copied()
                .unwrap_or(scene.grid.rings[0])
        };
        let lateral = |i: usize| scene.rings.get(i).map_or(1.0, |r| r.lateral_mm);
        let direction_x = |i: usize| {
            let (r, n) = (ring(i).radius_mm, ring(i).normal);
            if y0 == 0.0 { n.x } else { r * n.x / lateral(i) }
        };
        let revs = |branch: Branch| {
            (0..count)
                .map(|i| {
                    scene
                        .rings
                        .get(i)
                        .map_or(RevRange::EMPTY, |r| r.revs[branch as usize])
                })
                .collect()
        };
        RingLanes {
            radius_mm: (0..count).map(|i| ring(i).radius_mm).collect(),
            height_mm: (0..count).map(|i| ring(i).height_mm).collect(),
            normal_x: (0..count).map(|i| ring(i).normal.x).collect(),
            normal_y: (0..count).map(|i| ring(i).normal.y).collect(),
            lateral_mm: (0..count).map(lateral).collect(),
            direction_x: (0..count).map(direction_x).collect(),
            direction_squared: (0..count)
                .map(|i| {
                    let (x, y) = (direction_x(i), ring(i).normal.y);
                    x * x + y * y
                })
                .collect(),
            revs: [revs(Branch::Direct), revs(Branch::Mirrored)],
        }
    }
}

/// Eight rings' worth of one per-ring quantity.
type Lanes = [f64; LANES];

#[inline(always)]
fn lanes(values: &[f64], first: usize) -> Lanes {
    values[first..first + LANES]
        .try_into()
        .expect("padded lanes")
}

/// One branch's passes at a sample: the node of revolution 0 (revolution k's is
/// `node0 + k·S`) with the fraction t along the node's step, the revolutions whose node
/// lies inside the table, and the one (if any) whose pass falls exactly on its last node.
#[derive(Clone, Copy)]
struct PassWindow {
    node0: i64,
    t: f64,
    first: i64,
    last: i64,
    table_end: Option<i64>,
}

impl PassWindow {
    const EMPTY: PassWindow = PassWindow {
        node0: 0,
        t: 0.0,
        first: 1,
        last: 0,
        table_end: None,
    };
}

/// A turning scene ready for the lanes.
pub struct TurningKernel<'a> {
    scene: &'a TurningScene,
    edge: EdgeSolver<'a>,
    nodes: NodeSteps,
    rings: RingLanes,
    /// Tip direction per edge branch when B is 0 throughout (XZ).
    fixed_tip: Option<[[f64; 2]; 2]>,
    /// An edge off its circle: every sample goes through the scalar twin.
    scalar_only: bool,
    simd: Simd,
}

#[derive(Clone, Copy, PartialEq)]
enum Simd {
    Avx512,
    Avx2,
    Baseline,
}

impl Simd {
    fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Simd::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                return Simd::Avx2;
            }
        }
        Simd::Baseline
    }
}

impl<'a> TurningKernel<'a> {
    pub fn new(scene: &'a TurningScene) -> Self {
        let edge = scene.edge.solver();
        let fixed_tip = scene.poses.poses.iter().all(|p| p.b_rad == 0.0).then(|| {
            [Branch::Direct, Branch::Mirrored].map(|branch| {
                let tip = tip_direction(0.0) * DVec2::new(branch.x_sign(), 1.0);
                [tip.x, tip.y]
            })
        });
        Self {
            scene,
            scalar_only: edge.refinements > 0,
            edge,
            nodes: NodeSteps::new(&scene.poses.poses),
            rings: RingLanes::new(scene),
            fixed_tip,
            simd: Simd::detect(),
        }
    }

    /// Fills the dexels of row `azimuth` from ring `first_ring` (a multiple of
    /// [`LANES`]) on, as many as `depths` holds.
    pub fn fill(&self, azimuth: u32, first_ring: usize, depths: &mut [f64], passes: &mut [u32]) {
        if self.scene.spring_back == SpringBack::NONE {
            self.fill_on::<false>(azimuth, first_ring, depths, passes)
        } else {
            self.fill_on::<true>(azimuth, first_ring, depths, passes)
        }
    }

    /// [`Self::fill`] on the processor's widest lanes. Without spring-back
    /// (`SPRING_BACK` false) the lanes keep the running minimum, which is
    /// `SpringBack::NONE.after` (the entry when it lies below the height), without the
    /// rule's arithmetic: a fifth of the removal time.
    #[inline(always)]
    fn fill_on<const SPRING_BACK: bool>(
        &self,
        azimuth: u32,
        first_ring: usize,
        depths: &mut [f64],
        passes: &mut [u32],
    ) {
        match self.simd {
            // SAFETY: the instruction sets were detected on this processor.
            #[cfg(target_arch = "x86_64")]
            Simd::Avx512 => unsafe {
                self.fill_avx512::<SPRING_BACK>(azimuth, first_ring, depths, passes)
            },
            #[cfg(target_arch = "x86_64")]
            Simd::Avx2 => unsafe {
                self.fill_avx2::<SPRING_BACK>(azimuth, first_ring, depths, passes)
            },
            _ => self.fill_lanes::<SPRING_BACK>(azimuth, first_ring, depths, passes),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
    fn fill_avx512<const SPRING_BACK: bool>(
        &self,
        azimuth: u32,
        first_ring: usize,
        depths: &mut [f64],
        passes: &mut [u32],
    ) {
        self.fill_lanes::<SPRING_BACK>(azimuth, first_ring, depths, passes)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx")]
    fn fill_avx2<const SPRING_BACK: bool>(
        &self,
        azimuth: u32,
        first_ring: usize,
        depths: &mut [f64],
        passes: &mut [u32],
    ) {
        self.fill_lanes::<SPRING_BACK>(azimuth, first_ring, depths, passes)
    }

    #[inline(always)]
    fn fill_lanes<const SPRING_BACK: bool>(
        &self,
        azimuth: u32,
        first_ring: usize,
        depths: &mut [f64],
        passes: &mut [u32],
    ) {
        debug_assert_eq!(first_ring % LANES, 0);
        let azimuth_rad = self.scene.grid.azimuth_rad(azimuth);
        // On centre every ring of a row has the same pass phase: one window per branch.
        let on_centre = (self.scene.edge_plane_y_mm == 0.0)
            .then(|| [Branch::Direct, Branch::Mirrored].map(|b| self.window(0, azimuth_rad, b)));
        let blocks = depths.chunks_mut(LANES).zip(passes.chunks_mut(LANES));
        for (block, (depths, passes)) in blocks.enumerate() {
            let ring = first_ring + block * LANES;
            // An edge off its circle runs in lanes only where the twin prunes its passes
            // (on centre, no spring-back).
            let (depth, pass) = if self.scalar_only && (SPRING_BACK || on_centre.is_none()) {
                self.scalar_block(azimuth_rad, ring)
            } else if let Some(row) = &on_centre {
                self.block::<false, SPRING_BACK>(azimuth_rad, ring, row)
            } else {
                self.block::<true, SPRING_BACK>(azimuth_rad, ring, &[PassWindow::EMPTY; 2])
            };
            depths.copy_from_slice(&depth[..depths.len()]);
            passes.copy_from_slice(&pass[..passes.len()]);
        }
    }

    /// The scalar twin, ring by ring (padding lanes left uncut).
    fn scalar_block(&self, azimuth_rad: f64, first_ring: usize) -> (Lanes, [u32; LANES]) {
        let scene = self.scene;
        let mut depth = [scene.stock_top_mm; LANES];
        let mut pass = [NO_PASS; LANES];
        for (l, ring) in (first_ring..scene.rings.len().min(first_ring + LANES)).enumerate() {
            let mut best = (scene.stock_top_mm, NO_PASS);
            for branch in Branch::ALL {
                branch_dexel(scene, &self.edge, ring, azimuth_rad, branch, &mut best);
            }
            (depth[l], pass[l]) = best;
        }
        (depth, pass)
    }

    /// The dexels of rings `first_ring..first_ring + LANES` in one row.
    #[inline(always)]
    fn block<const OFF_CENTRE: bool, const SPRING_BACK: bool>(
        &self,
        azimuth_rad: f64,
        first_ring: usize,
        row: &[PassWindow; 2],
    ) -> (Lanes, [u32; LANES]) {
        let scene = self.scene;
        let mut best = [scene.stock_top_mm; LANES];
        let mut best_pass = [NO_PASS; LANES];
        for branch in [Branch::Direct, Branch::Mirrored] {
            let revs: &[RevRange; LANES] = self.rings.revs[branch as usize]
                [first_ring..first_ring + LANES]
                .try_into()
                .expect("padded lanes");
            if revs.iter().all(|r| r.is_empty()) {
                continue;
            }
            let mut windows = [PassWindow::EMPTY; LANES];
            for (l, lane) in windows.iter_mut().enumerate() {
                let window = if OFF_CENTRE {
                    let ring = (first_ring + l).min(scene.rings.len() - 1);
                    self.window(ring, azimuth_rad, branch)
                } else {
                    row[branch as usize]
                };
                let (first, last) = (revs[l].first as i64, revs[l].last as i64);
                *lane = PassWindow {
                    first: window.first.max(first),
                    last: window.last.min(last),
                    table_end: window.table_end.filter(|rev| (first..=last).contains(rev)),
                    ..window
                };
            }
            if self.scalar_only {
                self.run_off_circle(first_ring, branch, &windows, &mut best, &mut best_pass);
            } else {
                self.run::<OFF_CENTRE, SPRING_BACK>(
                    first_ring,
                    branch,
                    &windows,
                    &mut best,
                    &mut best_pass,
                );
            }
            for (l, window) in windows.iter().enumerate() {
                if let Some(rev) = window.table_end {
                    self.table_end_pass(
                        first_ring + l,
                        branch,
                        window,
                        rev,
                        &mut best[l],
                        &mut best_pass[l],
                    );
                }
            }
        }
        if OFF_CENTRE {
            for (l, ring) in (first_ring..scene.rings.len().min(first_ring + LANES)).enumerate() {
                let mut lane = (best[l], best_pass[l]);
                branch_dexel(
                    scene,
                    &self.edge,
                    ring,
                    azimuth_rad,
                    Branch::Flank,
                    &mut lane,
                );
                (best[l], best_pass[l]) = lane;
            }
        }
        (best, best_pass)
    }

    /// Every pass of one branch over the block, in revolution order, changing each
    /// lane's (height, pass) by the scene's spring-back rule where the pass lies in the
    /// lane's window (see [`Self::fill_on`] for `SPRING_BACK`).
    #[inline(always)]
    fn run<const OFF_CENTRE: bool, const SPRING_BACK: bool>(
        &self,
        first_ring: usize,
        branch: Branch,
        windows: &[PassWindow; LANES],
        best: &mut Lanes,
        best_pass: &mut [u32; LANES],
    ) {
        let Some((first, last)) = revolutions(windows) else {
            return;
        };
        let sign = branch.x_sign();
        let ray = RayLanes::new(&self.rings, first_ring);
        let (lane_first, lane_last) = (windows.map(|w| w.first), windows.map(|w| w.last));
        for rev in first..=last {
            let mut pose = PoseLanes::default();
            if OFF_CENTRE {
                for (l, window) in windows.iter().enumerate() {
                    let (x, z, [tip_x, tip_y]) = self.pose(window, rev, branch);
                    (pose.x[l], pose.z[l], pose.tip_x[l], pose.tip_y[l]) = (x, z, tip_x, tip_y);
                }
            } else {
                // One pose (and tip) for the whole block.
                let (x, z, [tip_x, tip_y]) = self.pose(&windows[0], rev, branch);
                pose = PoseLanes {
                    x: [x; LANES],
                    z: [z; LANES],
                    tip_x: [tip_x; LANES],
                    tip_y: [tip_y; LANES],
                };
            }
            // A trip count the compiler cannot see, so that it vectorises this loop whole
            // rather than unrolling it into scalar code.
            let mut depth = [0.0; LANES];
            let lanes = std::hint::black_box(LANES).min(LANES);
            #[allow(clippy::needless_range_loop)]
            for l in 0..lanes {
                let tip = [pose.tip_x[l], pose.tip_y[l]];
                let entry = self.edge_entry::<OFF_CENTRE>(&ray, l, sign, pose.x[l], pose.z[l], tip);
                let inside = rev >= lane_first[l] && rev <= lane_last[l];
                depth[l] = if inside { entry } else { f64::INFINITY };
            }
            let pass_id = rev as u32 * PASS_ID_STRIDE + branch as u32;
            let rule = self.scene.spring_back;
            for l in 0..LANES {
                let height = if SPRING_BACK {
                    rule.after(best[l], depth[l])
                } else {
                    depth[l]
                };
                let changed = height < best[l];
                best[l] = if changed { height } else { best[l] };
                best_pass[l] = if changed { pass_id } else { best_pass[l] };
            }
        }
    }

    /// [`Self::run`] for an edge off its circle (waviness, a measured edge), on centre
    /// without spring-back, as the twin prunes it (`cpu_turning_scalar::prune_limit`): every pass's
    /// [`EdgeSolver::entry_bound`] in lanes (a circle holding the whole edge: one square
    /// root), the full entry (arctangents) only where the bound reaches below the lane's
    /// limit — the lowest entry so far, and the entry of the pass whose bound is lowest.
    /// A pass whose bound lies above an entry some pass reaches cannot be the lowest, so
    /// the samples are the twin's to the bit; its full entries are the twin's own.
    #[inline(always)]
    fn run_off_circle(
        &self,
        first_ring: usize,
        branch: Branch,
        windows: &[PassWindow; LANES],
        best: &mut Lanes,
        best_pass: &mut [u32; LANES],
    ) {
        let Some((first, last)) = revolutions(windows) else {
            return;
        };
        let ray = RayLanes::new(&self.rings, first_ring);
        // The lowest bound of each lane, and its pass's full entry: the limit.
        let mut lowest = [(f64::INFINITY, None); LANES];
        for rev in first..=last {
            let bounds = self.bounds(&ray, branch, windows, rev);
            for l in 0..LANES {
                if bounds[l] < lowest[l].0 {
                    lowest[l] = (bounds[l], Some(rev));
                }
            }
        }
        let mut limit = *best;
        for l in 0..LANES {
            if let Some(rev) = lowest[l].1
                && let Some(d) = self.full_entry(first_ring + l, branch, &windows[l], rev)
            {
                limit[l] = limit[l].min(d);
            }
        }
        for rev in first..=last {
            let bounds = self.bounds(&ray, branch, windows, rev);
            for l in 0..LANES {
                let height = limit[l].min(best[l]) + PRUNE_MARGIN_MM;
                if bounds[l] > height {
                    continue;
                }
                // The bound as tight as the edge near where the ray meets it.
                let (ring, pose) = (first_ring + l, self.twin_pose(&windows[l], rev));
                let local = local_bound_entry(self.scene, &self.edge, ring, pose, branch);
                if local.is_none_or(|bound| bound > height) {
                    continue;
                }
                if let Some(d) = pass_entry(self.scene, &self.edge, ring, pose, branch)
                    && d < best[l]
                {
                    best[l] = d;
                    best_pass[l] = rev as u32 * PASS_ID_STRIDE + branch as u32;
                }
            }
        }
    }

    /// [`EdgeSolver::entry_bound`] of pass `rev` in every lane: +∞ outside the lane's
    /// window and where the ray misses the circle (NaN kept: the twin enters those).
    #[inline(always)]
    fn bounds(
        &self,
        ray: &RayLanes,
        branch: Branch,
        windows: &[PassWindow; LANES],
        rev: i64,
    ) -> Lanes {
        // On centre one pose serves the block.
        let (x, z, tip) = self.pose(&windows[0], rev, branch);
        let sign = branch.x_sign();
        let edge = &self.edge;
        let mut bounds = [f64::INFINITY; LANES];
        for l in 0..LANES {
            let from_pivot = [ray.lateral[l] - sign * x, ray.height[l] - z];
            let direction = [ray.direction_x[l], ray.normal_y[l]];
            let (d, _, discriminant) = circle_root(
                from_pivot,
                direction,
                ray.direction_squared[l],
                tip,
                edge,
                edge.outer_radius_mm,
            );
            let inside = rev >= windows[l].first && rev <= windows[l].last;
            // The twin skips a pass only where the discriminant is negative (NaN enters).
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            let enters = !(discriminant < 0.0);
            bounds[l] = if inside && enters { d } else { f64::INFINITY };
        }
        bounds
    }

    /// The twin's entry of pass `rev` into ring `ring`'s ray (its own pose and edge).
    fn full_entry(
        &self,
        ring: usize,
        branch: Branch,
        window: &PassWindow,
        rev: i64,
    ) -> Option<f64> {
        pass_entry(
            self.scene,
            &self.edge,
            ring,
            self.twin_pose(window, rev),
            branch,
        )
    }

    /// Pass `rev`'s pose in a lane's `window`, interpolated as the twin does.
    fn twin_pose(&self, window: &PassWindow, rev: i64) -> ToolPose {
        let steps = self.scene.poses.steps_per_rev as i64;
        let node = (window.node0 + rev * steps) as usize;
        let poses = &self.scene.poses.poses;
        poses[node].lerp(poses[node + 1], window.t)
    }

    /// Pass `rev`'s pose in a lane's `window`: the nose centre (x, z) and the tip
    /// direction in the branch's frame.
    #[inline(always)]
    fn pose(&self, window: &PassWindow, rev: i64, branch: Branch) -> (f64, f64, [f64; 2]) {
        let steps = self.scene.poses.steps_per_rev as i64;
        let node = (window.node0 + rev * steps).clamp(0, self.nodes.x.len() as i64 - 1);
        let (x, z, b) = self.nodes.lerp(node as usize, window.t);
        (x, z, self.tip(branch, b))
    }

    /// The tip direction in a branch's frame for B = `b_rad`.
    #[inline(always)]
    fn tip(&self, branch: Branch, b_rad: f64) -> [f64; 2] {
        match self.fixed_tip {
            Some(tips) => tips[branch as usize],
            None => {
                let tip = tip_direction(b_rad) * DVec2::new(branch.x_sign(), 1.0);
                [tip.x, tip.y]
            }
        }
    }

    /// The pass on the table's last node, through the twin's own bookkeeping.
    fn table_end_pass(
        &self,
        ring: usize,
        branch: Branch,
        window: &PassWindow,
        rev: i64,
        best: &mut f64,
        best_pass: &mut u32,
    ) {
        let scene = self.scene;
        let last = scene.poses.poses.len() - 1;
        let pose = scene.poses.poses[last - 1].lerp(scene.poses.poses[last], 1.0);
        debug_assert_eq!(window.t, 0.0);
        if let Some(depth) = pass_entry(scene, &self.edge, ring, pose, branch) {
            let height = scene.spring_back.after(*best, depth);
            if height < *best {
                *best = height;
                *best_pass = rev as u32 * PASS_ID_STRIDE + branch as u32;
            }
        }
    }

    /// `TurningScene::pass_phase` and `pass_position` for every revolution at once.
    #[inline(always)]
    fn window(&self, ring: usize, azimuth_rad: f64, branch: Branch) -> PassWindow {
        let scene = self.scene;
        let phase = pass_phase(scene.rings[ring].direct_azimuth_rad, azimuth_rad, branch);
        let steps = scene.poses.steps_per_rev as i64;
        let steps_in = (phase + scene.start_phase_rad) / scene.poses.step_rad();
        let whole = steps_in.floor();
        let fraction = steps_in - whole;
        let (node0, t) = if fraction > 0.0 {
            (scene.base_steps - whole as i64 - 1, 1.0 - fraction)
        } else {
            (scene.base_steps - whole as i64, 0.0)
        };
        // Revolutions with 0 ≤ node < last node; the twin moves a pass on the last node
        // itself (t = 0) to t = 1 on the step before.
        let last_node = scene.poses.poses.len() as i64 - 1;
        let on_last = last_node - node0;
        PassWindow {
            node0,
            t,
            first: -(node0.div_euclid(steps)),
            last: (last_node - 1 - node0).div_euclid(steps),
            table_end: (t == 0.0 && on_last.rem_euclid(steps) == 0).then(|| on_last / steps),
        }
    }

    /// `cpu_turning_scalar::edge_entry` for an edge on its circle, lane `l`: +∞ for a miss.
    #[inline(always)]
    fn edge_entry<const OFF_CENTRE: bool>(
        &self,
        ray: &RayLanes,
        l: usize,
        sign: f64,
        pose_x: f64,
        pose_z: f64,
        tip: [f64; 2],
    ) -> f64 {
        let from_pivot = [ray.lateral[l] - sign * pose_x, ray.height[l] - pose_z];
        let direction = [ray.direction_x[l], ray.normal_y[l]];
        let (d, hit) = self.circle_entry(from_pivot, direction, ray.direction_squared[l], tip);
        if !OFF_CENTRE || RAY_REFINEMENTS == 0 {
            return if hit { d } else { f64::INFINITY };
        }
        // One re-linearisation of the ray's image in the rake plane (see `cpu_turning_scalar::edge_entry`).
        let y0 = self.scene.edge_plane_y_mm;
        let (r, n) = (ray.radius[l], [ray.normal_x[l], ray.normal_y[l]]);
        let rho = r + d * n[0];
        let q = (rho * rho - y0 * y0).sqrt();
        let shift = d * n[0] * (2.0 * r + d * n[0]) / (q + ray.lateral[l]);
        let slope = [rho * n[0] / q, n[1]];
        let moved = [
            (from_pivot[0] + shift) - d * slope[0],
            (from_pivot[1] + d * n[1]) - d * slope[1],
        ];
        let slope_squared = slope[0] * slope[0] + slope[1] * slope[1];
        let (d2, hit2) = self.circle_entry(moved, slope, slope_squared, tip);
        if hit && rho > y0.abs() && hit2 {
            d2
        } else {
            f64::INFINITY
        }
    }

    /// `EdgeSolver::entry` for an edge on its circle: (d, whether it is a hit).
    #[inline(always)]
    fn circle_entry(
        &self,
        from_pivot: [f64; 2],
        m: [f64; 2],
        m_squared: f64,
        tip: [f64; 2],
    ) -> (f64, bool) {
        let edge = &self.edge;
        let radius = edge.circle_radius_mm;
        let (d, w, discriminant) = circle_root(from_pivot, m, m_squared, tip, edge, radius);
        let hit = [w[0] + d * m[0], w[1] + d * m[1]];
        // Negated as in the twin, whose `if x < y { return None }` lets NaN through.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        let hit = !(discriminant < 0.0)
            && !(hit[0] * tip[0] + hit[1] * tip[1] < radius * edge.cos_half_span);
        (d, hit)
    }
}

/// The revolutions any lane's window holds (first, last); `None` when none does.
fn revolutions(windows: &[PassWindow; LANES]) -> Option<(i64, i64)> {
    let live = windows.iter().filter(|w| w.first <= w.last);
    Some((
        live.clone().map(|w| w.first).min()?,
        live.map(|w| w.last).max()?,
    ))
}

/// The lower root of the ray `from_pivot + d·m` in the circle of `radius` about the
/// edge's arc centre (`circle_entry`'s arithmetic): (d, the origin from that centre, the
/// discriminant).
#[inline(always)]
fn circle_root(
    from_pivot: [f64; 2],
    m: [f64; 2],
    m_squared: f64,
    tip: [f64; 2],
    edge: &EdgeSolver,
    radius: f64,
) -> (f64, [f64; 2], f64) {
    let w = [
        from_pivot[0] + edge.tip_offset_mm * tip[0],
        from_pivot[1] + edge.tip_offset_mm * tip[1],
    ];
    let b = w[0] * m[0] + w[1] * m[1];
    let c = (w[0] * w[0] + w[1] * w[1]) - radius * radius;
    let discriminant = b * b - m_squared * c;
    let root = discriminant.sqrt();
    let (numerator, denominator) = if b < 0.0 {
        (c, root - b)
    } else {
        (-b - root, m_squared)
    };
    (numerator / denominator, w, discriminant)
}

/// One pass's pose per lane: the nose centre and the tip direction in the branch's frame.
#[derive(Default)]
struct PoseLanes {
    x: Lanes,
    z: Lanes,
    tip_x: Lanes,
    tip_y: Lanes,
}

/// One block's rings, loaded once.
struct RayLanes {
    radius: Lanes,
    height: Lanes,
    normal_x: Lanes,
    normal_y: Lanes,
    lateral: Lanes,
    direction_x: Lanes,
    direction_squared: Lanes,
}

impl RayLanes {
    #[inline(always)]
    fn new(rings: &RingLanes, first: usize) -> Self {
        RayLanes {
            radius: lanes(&rings.radius_mm, first),
            height: lanes(&rings.height_mm, first),
            normal_x: lanes(&rings.normal_x, first),
            normal_y: lanes(&rings.normal_y, first),
            lateral: lanes(&rings.lateral_mm, first),
            direction_x: lanes(&rings.direction_x, first),
            direction_squared: lanes(&rings.direction_squared, first),
        }
    }
}

/// `TurningScene::pass_phase` without a library `fmod` call: every branch's angle lies
/// in (−2π, 4π), where `x % 2π` is x or x − 2π exactly (Sterbenz), so the result is
/// `rem_euclid`'s to the bit.
#[inline(always)]
fn pass_phase(direct_azimuth_rad: f64, azimuth_rad: f64, branch: Branch) -> f64 {
    let alpha = match branch {
        Branch::Direct => direct_azimuth_rad,
        Branch::Mirrored => PI - direct_azimuth_rad,
        Branch::Flank => -FRAC_PI_2,
    };
    let angle = azimuth_rad - alpha;
    if angle > -TAU && angle < TAU {
        if angle < 0.0 { angle + TAU } else { angle }
    } else if (TAU..2.0 * TAU).contains(&angle) {
        angle - TAU
    } else {
        angle.rem_euclid(TAU)
    }
}

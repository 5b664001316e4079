//! The scalar f64 twin of `shaders/turning.wgsl`: the same pass loop, with absolute
//! coordinates in f64 (no local-frame tricks needed). The CPU engine runs the SIMD lanes
//! of `cpu_turning.rs`, which give the same bits; this is the reference they and the
//! shader are held to.

use super::scene::{Branch, PASS_ID_STRIDE, TurningScene};
use crate::field::{NO_PASS, Ring};
use crate::geometry::tool::{EdgeSolver, psi_from_tip, tip_direction};
use crate::process::ToolPose;
use glam::DVec2;

/// Re-linearisations of a dexel ray's image in an off-centre rake plane: the map
/// r → √(r² − y₀²) is smooth over the micrometres a cut spans, so one suffices.
pub const RAY_REFINEMENTS: usize = 1;

/// The machined surface at one sample: the passes' entries into the sample's dexel ray
/// applied in machining order by the scene's [`SpringBack`](super::scene::SpringBack) rule (without spring-back the
/// lowest entry), and which pass last changed it (`rev · PASS_ID_STRIDE + branch`).
/// The scalar twin of the shader; the engine runs [`TurningKernel`](super::cpu_turning::TurningKernel), which gives the
/// same bits.
pub fn sample_dexel(scene: &TurningScene, ring_index: usize, azimuth: u32) -> (f64, u32) {
    let edge = scene.edge.solver();
    let azimuth_rad = scene.grid.azimuth_rad(azimuth);
    let mut best = (scene.stock_top_mm, NO_PASS);
    for branch in Branch::ALL {
        branch_dexel(scene, &edge, ring_index, azimuth_rad, branch, &mut best);
    }
    best
}

/// Applies one branch's passes, in revolution order, to `best` (height, pass id) of
/// sample (`ring_index`, `azimuth_rad`): each entry into the dexel ray changes the height
/// by the scene's [`SpringBack`](super::scene::SpringBack) rule.
pub fn branch_dexel(
    scene: &TurningScene,
    edge: &EdgeSolver,
    ring_index: usize,
    azimuth_rad: f64,
    branch: Branch,
    best: &mut (f64, u32),
) {
    let range = scene.rings[ring_index].revs[branch as usize];
    if range.is_empty() {
        return;
    }
    let phase = scene.pass_phase(ring_index, azimuth_rad, branch);
    let pose_of = |rev: u32| {
        let (node, t) = scene.pass_position(rev, phase)?;
        Some(scene.poses.poses[node].lerp(scene.poses.poses[node + 1], t))
    };
    let limit = prune_limit(scene, edge, ring_index, branch, best.0, &pose_of);
    for rev in range.first..=range.last {
        let Some(pose) = pose_of(rev) else {
            continue;
        };
        if let Some(limit) = limit
            && !may_enter_below(scene, edge, ring_index, pose, branch, limit.min(best.0))
        {
            continue;
        }
        if let Some(depth) = pass_entry_below(scene, edge, ring_index, pose, branch, best.0) {
            let height = scene.spring_back.after(best.0, depth);
            if height < best.0 {
                *best = (height, rev * PASS_ID_STRIDE + branch as u32);
            }
        }
    }
}

/// How far a pass's bound must lie above the height to be skipped (mm): the bound and
/// the entry are each correctly rounded, so an ulp of disorder must not skip a pass.
pub(super) const PRUNE_MARGIN_MM: f64 = 1e-12;

/// Where an edge departs from its circle (waviness, a measured edge), its entry needs
/// arctangents (~70 ns a pair); there, on centre and without spring-back (the surface
/// is then the lowest entry), a pass whose [`EdgeSolver::entry_bound`] lies above the
/// lowest entry found so far cannot change the sample and is skipped: the same bits,
/// a few full entries per sample instead of every reachable pass. The limit to start
/// from: the entry of the pass whose bound is lowest (`None`: no pruning here).
fn prune_limit(
    scene: &TurningScene,
    edge: &EdgeSolver,
    ring_index: usize,
    branch: Branch,
    height: f64,
    pose_of: &dyn Fn(u32) -> Option<ToolPose>,
) -> Option<f64> {
    let prunable = edge.refinements > 0
        && branch != Branch::Flank
        && scene.edge_plane_y_mm == 0.0
        && scene.spring_back == super::scene::SpringBack::NONE;
    if !prunable {
        return None;
    }
    let range = scene.rings[ring_index].revs[branch as usize];
    let lowest = (range.first..=range.last)
        .filter_map(|rev| {
            let pose = pose_of(rev)?;
            Some((bound_entry(scene, edge, ring_index, pose, branch)?, pose))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0));
    let seeded = lowest.and_then(|(_, pose)| pass_entry(scene, edge, ring_index, pose, branch));
    Some(seeded.map_or(height, |d| d.min(height)))
}

/// Whether the pass at `pose` may enter the dexel ray of ring `ring_index` below
/// `height` (on centre): its [`bound_entry`] (one square root) and then, where that
/// reaches below, its [`local_bound_entry`] (five, no arctangent) do not rule it out.
pub(super) fn may_enter_below(
    scene: &TurningScene,
    edge: &EdgeSolver,
    ring_index: usize,
    pose: ToolPose,
    branch: Branch,
    height: f64,
) -> bool {
    // A NaN bound rules nothing out (the entry is taken, as the kernel's lanes do).
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    let below = |bound: Option<f64>| bound.is_some_and(|b| !(b > height + PRUNE_MARGIN_MM));
    below(bound_entry(scene, edge, ring_index, pose, branch))
        && below(local_bound_entry(scene, edge, ring_index, pose, branch))
}

/// [`EdgeSolver::local_entry_bound`] for the dexel ray of ring `ring_index` at `pose`
/// (on centre).
pub(super) fn local_bound_entry(
    scene: &TurningScene,
    edge: &EdgeSolver,
    ring_index: usize,
    pose: ToolPose,
    branch: Branch,
) -> Option<f64> {
    let (from_pivot, normal, tip) = on_centre_ray(scene, ring_index, pose, branch);
    let maxima = &scene.deviation_maxima;
    edge.local_entry_bound(maxima, from_pivot, normal, tip, branch.x_sign())
}

/// [`EdgeSolver::entry_bound`] for the dexel ray of ring `ring_index` at `pose` (on
/// centre: the frame [`edge_entry`] uses).
fn bound_entry(
    scene: &TurningScene,
    edge: &EdgeSolver,
    ring_index: usize,
    pose: ToolPose,
    branch: Branch,
) -> Option<f64> {
    let (from_pivot, normal, tip) = on_centre_ray(scene, ring_index, pose, branch);
    edge.entry_bound(from_pivot, normal, tip)
}

/// The dexel ray of ring `ring_index` against the pass at `pose` on centre, as the edge
/// solver takes it: (origin − nose centre, direction, tip) in the branch's frame.
fn on_centre_ray(
    scene: &TurningScene,
    ring_index: usize,
    pose: ToolPose,
    branch: Branch,
) -> (DVec2, DVec2, DVec2) {
    let ring = &scene.grid.rings[ring_index];
    let (centre, tip) = nose_in_branch(pose, branch.x_sign());
    let origin = DVec2::new(scene.rings[ring_index].lateral_mm, ring.height_mm);
    (origin - centre, ring.normal, tip)
}

/// A pass's nose centre and tip direction in the frame of the branch of x-sign `sign`
/// (−1: the mirrored branch, the machine's mirror image).
fn nose_in_branch(pose: ToolPose, sign: f64) -> (DVec2, DVec2) {
    (
        DVec2::new(sign * pose.x_mm, pose.z_mm),
        tip_direction(pose.b_rad) * DVec2::new(sign, 1.0),
    )
}

/// Entry of the dexel ray of ring `ring_index` into the tool at `pose` in `branch`.
pub fn pass_entry(
    scene: &TurningScene,
    edge: &EdgeSolver,
    ring_index: usize,
    pose: ToolPose,
    branch: Branch,
) -> Option<f64> {
    pass_entry_below(scene, edge, ring_index, pose, branch, f64::INFINITY)
}

/// As [`pass_entry`], but `None` may also mean an entry above `height` (where the pass
/// cannot change the sample): an edge off its circle, off centre, is not entered along
/// the refined ray when the circle holding the whole edge is entered above `height`.
fn pass_entry_below(
    scene: &TurningScene,
    edge: &EdgeSolver,
    ring_index: usize,
    pose: ToolPose,
    branch: Branch,
    height: f64,
) -> Option<f64> {
    let ring = &scene.grid.rings[ring_index];
    match branch {
        Branch::Flank => flank_entry(scene, ring, pose),
        _ => edge_entry(
            scene,
            edge,
            ring,
            scene.rings[ring_index].lateral_mm,
            pose,
            branch.x_sign(),
            height,
        ),
    }
}

/// Entry of the dexel ray into the edge of one pass. The ray lives in the sample's
/// meridional plane; the edge in the rake plane y = y₀, where the sample's radius r
/// appears at lateral q = √(r² − y₀²). On centre the two planes coincide; off centre the
/// ray's image is curved, so it is linearised at the sample and once more at the hit
/// (where an edge off its circle is entered only if the circle holding it is entered
/// below `height`: above it the pass cannot change the sample).
fn edge_entry(
    scene: &TurningScene,
    edge: &EdgeSolver,
    ring: &Ring,
    lateral: f64,
    pose: ToolPose,
    sign: f64,
    height: f64,
) -> Option<f64> {
    let y0 = scene.edge_plane_y_mm;
    let (centre, tip) = nose_in_branch(pose, sign);
    let (r, n) = (ring.radius_mm, ring.normal);
    let origin = DVec2::new(lateral, ring.height_mm);
    let direction = if y0 == 0.0 {
        n
    } else {
        DVec2::new(r * n.x / lateral, n.y)
    };
    let mut d = edge.entry(origin - centre, direction, tip, sign)?;
    if y0 != 0.0 {
        for _ in 0..RAY_REFINEMENTS {
            let rho = r + d * n.x;
            if rho <= y0.abs() {
                return None;
            }
            let q = (rho * rho - y0 * y0).sqrt();
            // q − q₀ without cancelling: (ρ² − r²)/(q + q₀).
            let shift = d * n.x * (2.0 * r + d * n.x) / (q + lateral);
            let slope = DVec2::new(rho * n.x / q, n.y);
            // The line through the ray's image at d with the local slope, still in d.
            let from_pivot = origin - centre + DVec2::new(shift, d * n.y) - d * slope;
            if edge.refinements > 0
                && edge
                    .entry_bound(from_pivot, slope, tip)
                    .is_none_or(|bound| bound > height + PRUNE_MARGIN_MM)
            {
                return None;
            }
            d = edge.entry(from_pivot, slope, tip, sign)?;
        }
    }
    Some(d)
}

/// Entry of a pip sample's dexel ray into the flank of a tool above centre: the flank
/// passes the sample at machine (0, −r), |y₀| − r behind the rake plane, where it stands
/// (|y₀| − r)·tan(clearance) above the edge's height at x = 0 — the real edge's, its
/// deviation w(ψ) there included (the flank falls from the edge the tool was set by).
fn flank_entry(scene: &TurningScene, ring: &Ring, pose: ToolPose) -> Option<f64> {
    let edge = &scene.edge;
    let tip = tip_direction(pose.b_rad);
    let centre = DVec2::new(pose.x_mm, pose.z_mm) - edge.tip_offset_mm() * tip;
    let mut radius = edge.nominal_radius_mm + edge.radius_error_mm;
    if centre.x.abs() >= radius {
        return None;
    }
    if !edge.deviation.is_zero() {
        // ψ of the circle's point at x = 0, measured as the edge solver measures it.
        let hit = DVec2::new(-centre.x, -(radius * radius - centre.x * centre.x).sqrt());
        radius = edge.radius_at(psi_from_tip(hit, tip));
        if centre.x.abs() >= radius {
            return None;
        }
    }
    let behind = scene.edge_plane_y_mm.abs() - ring.radius_mm;
    let flank_above_sample = (centre.y - ring.height_mm)
        - (radius * radius - centre.x * centre.x).sqrt()
        + behind * scene.tan_clearance;
    // The flank is a cone of slope tan(clearance) falling outward; meet it along the ray.
    Some(flank_above_sample / (ring.normal.y + ring.normal.x * scene.tan_clearance))
}

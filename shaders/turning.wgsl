// Turning removal kernel: one invocation per dexel (sample of the nominal surface).
// For every spindle revolution whose tool can reach the sample (ranges prepared on
// the CPU), find where the arc-nosed edge enters the sample's normal ray and keep the
// lowest entry. f64 twin: `sample_dexel` in src/engine/cpu.rs + `edge_entry` in
// src/geometry/tool.rs — change them together.
//
// Precision: nanometre features on 20 mm parts do not fit f32 absolute coordinates
// (ulp at 20 mm ≈ 2 nm), so every absolute coordinate arrives as a hi + lo pair of
// f32 (value = hi + lo to f64 accuracy) and is only ever used in the difference
// sample − nose centre, which is sub-millimetre: (a_hi − b_hi) + (a_lo − b_lo) keeps
// ~0.03 nm.

struct Params {
    ring_count: u32,
    azimuth_count: u32,
    sample_offset: u32,
    sample_count: u32,
    pose_count: u32,
    steps_per_rev: u32,
    base_steps: i32,
    dispatch_width: u32,
    nose_radius_mm: f32,
    cos_half_span: f32,
    stock_top_mm: f32,
    _padding: f32,
}

struct Ring {
    r_hi: f32,
    r_lo: f32,
    z_hi: f32,
    z_lo: f32,
    normal_r: f32,
    normal_z: f32,
    direct_first: u32,
    direct_last: u32,
    mirrored_first: u32,
    mirrored_last: u32,
}

struct Phase {
    direct_whole: u32,
    direct_fraction: f32,
    mirrored_whole: u32,
    mirrored_fraction: f32,
}

struct Pose {
    x_hi: f32,
    x_lo: f32,
    z_hi: f32,
    z_lo: f32,
    b_rad: f32,
    _padding: f32,
}

struct Dexel {
    depth_mm: f32,
    pass_id: u32,
}

const NO_PASS: u32 = 0xffffffffu;
const MISS: f32 = 3.0e38;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> rings: array<Ring>;
@group(0) @binding(2) var<storage, read> phases: array<Phase>;
@group(0) @binding(3) var<storage, read> poses: array<Pose>;
@group(0) @binding(4) var<storage, read_write> dexels: array<Dexel>;

// Lower entry of the ray w + d·n (w = sample − nose centre) into the edge circle,
// or MISS when the ray misses the circle or meets it outside the edge arc.
// d = c / (√(b² − c) − b) for b < 0 avoids cancelling two ~R-sized numbers.
fn edge_entry(w: vec2<f32>, n: vec2<f32>, tip: vec2<f32>, radius: f32, cos_half_span: f32) -> f32 {
    let b = dot(w, n);
    let c = dot(w, w) - radius * radius;
    let discriminant = b * b - c;
    if discriminant < 0.0 {
        return MISS;
    }
    let root = sqrt(discriminant);
    var d: f32;
    if b < 0.0 {
        d = c / (root - b);
    } else {
        d = -b - root;
    }
    let hit = w + d * n;
    if dot(hit, tip) < radius * cos_half_span {
        return MISS;
    }
    return d;
}

struct Best {
    depth_mm: f32,
    pass_id: u32,
}

// Scans one branch's revolutions (sign = +1 direct, −1 mirrored past the axis).
fn scan_branch(ring: Ring, first: u32, last: u32, whole: u32, fraction: f32, sign: f32, branch: u32, best_in: Best) -> Best {
    var best = best_in;
    let n = vec2<f32>(ring.normal_r, ring.normal_z);
    let last_node = i32(params.pose_count) - 1;
    for (var rev = first; rev <= last; rev = rev + 1u) {
        let base = params.base_steps + i32(rev * params.steps_per_rev) - i32(whole);
        var node = base;
        var t = 0.0;
        if fraction > 0.0 {
            node = base - 1;
            t = 1.0 - fraction;
        }
        if node == last_node && t == 0.0 {
            node = node - 1;
            t = 1.0;
        }
        if node < 0 || node >= last_node {
            continue;
        }
        let p0 = poses[node];
        let p1 = poses[node + 1];
        let step_x = (p1.x_hi - p0.x_hi) + (p1.x_lo - p0.x_lo);
        let step_z = (p1.z_hi - p0.z_hi) + (p1.z_lo - p0.z_lo);
        let w = vec2<f32>(
            (ring.r_hi - sign * p0.x_hi) + (ring.r_lo - sign * p0.x_lo) - sign * t * step_x,
            (ring.z_hi - p0.z_hi) + (ring.z_lo - p0.z_lo) - t * step_z,
        );
        let b_rad = p0.b_rad + t * (p1.b_rad - p0.b_rad);
        let tip = vec2<f32>(-sin(b_rad) * sign, -cos(b_rad));
        let depth = edge_entry(w, n, tip, params.nose_radius_mm, params.cos_half_span);
        if depth < best.depth_mm {
            best = Best(depth, rev * 2u + branch);
        }
    }
    return best;
}

@compute @workgroup_size(64)
fn remove_turning(@builtin(global_invocation_id) id: vec3<u32>) {
    let local_index = id.x + id.y * params.dispatch_width;
    if local_index >= params.sample_count {
        return;
    }
    let sample = params.sample_offset + local_index;
    let ring_index = sample % params.ring_count;
    let azimuth = sample / params.ring_count;
    let ring = rings[ring_index];
    let phase = phases[azimuth];

    var best = Best(params.stock_top_mm, NO_PASS);
    best = scan_branch(ring, ring.direct_first, ring.direct_last, phase.direct_whole, phase.direct_fraction, 1.0, 0u, best);
    best = scan_branch(ring, ring.mirrored_first, ring.mirrored_last, phase.mirrored_whole, phase.mirrored_fraction, -1.0, 1u, best);
    dexels[local_index] = Dexel(best.depth_mm, best.pass_id);
}

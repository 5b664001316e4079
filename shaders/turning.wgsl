// Turning removal kernel: one invocation per dexel (sample of the nominal surface).
// For every spindle revolution whose tool can reach the sample (ranges prepared on the
// CPU, per branch: direct, mirrored past the axis, flank), find where the tool enters
// the sample's normal ray and apply the entries in that order by the spring-back rule
// (`after_pass`; without spring-back: keep the lowest entry).
// f64 twin: `sample_dexel` and its helpers in src/engine/cpu_turning_scalar.rs, `EdgeModel::entry` in
// src/geometry/tool.rs, pass bookkeeping in src/engine/scene.rs — change them together.
//
// Precision: nanometre features on 20 mm parts do not fit f32 absolute coordinates
// (ulp at 20 mm ≈ 2 nm), so every absolute coordinate arrives as a hi + lo pair of f32
// (value = hi + lo to f64 accuracy) and is only used in the difference sample − nose
// centre, which is sub-millimetre: (a_hi − b_hi) + (a_lo − b_lo) keeps ~0.03 nm.

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
    radius_error_mm: f32,
    tip_offset_mm: f32,
    cos_half_span: f32,
    stock_top_mm: f32,
    edge_plane_y_mm: f32,
    tan_clearance: f32,
    start_phase_rad: f32,
    azimuth_step_rad: f32,
    inverse_step_rad: f32,
    deviation_start_rad: f32,
    deviation_inverse_step: f32,
    deviation_count: u32,
    edge_refinements: u32,
    ray_refinements: u32,
    min_chip_mm: f32,
    recovery: f32,
    _padding0: u32,
    _padding1: u32,
    _padding2: u32,
}

struct Ring {
    r_hi: f32,
    r_lo: f32,
    z_hi: f32,
    z_lo: f32,
    q_hi: f32,
    q_lo: f32,
    normal_r: f32,
    normal_z: f32,
    direct_azimuth_rad: f32,
    _padding: f32,
    direct_first: u32,
    direct_last: u32,
    mirrored_first: u32,
    mirrored_last: u32,
    flank_first: u32,
    flank_last: u32,
}

struct Pose {
    x_hi: f32,
    x_lo: f32,
    z_hi: f32,
    z_lo: f32,
    b_rad: f32,
    _padding: f32,
}


@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> rings: array<Ring>;
@group(0) @binding(2) var<storage, read> poses: array<Pose>;
@group(0) @binding(3) var<storage, read> edge_deviation: array<f32>;
@group(0) @binding(4) var<storage, read_write> dexels: array<Dexel>;

fn tip_direction(b_rad: f32) -> vec2<f32> {
    if b_rad == 0.0 {
        return vec2<f32>(0.0, -1.0); // XZ: skip the trigonometry
    }
    return vec2<f32>(-sin(b_rad), -cos(b_rad));
}

// Radial deviation w(ψ) of the edge from its circle: linear in the table, held outside.
fn deviation_at(psi: f32) -> f32 {
    let count = params.deviation_count;
    if count == 0u {
        return 0.0;
    }
    if count == 1u {
        return edge_deviation[0];
    }
    let u = clamp((psi - params.deviation_start_rad) * params.deviation_inverse_step, 0.0, f32(count - 1u));
    let i = min(u32(floor(u)), count - 2u);
    let t = u - f32(i);
    return edge_deviation[i] + t * (edge_deviation[i + 1u] - edge_deviation[i]);
}

// Lower root of |w + d m|² = ρ²; d = c / (√(b² − a c) − b) for b < 0 avoids cancelling
// two ρ-sized numbers when the entry is nanometres from the origin.
fn circle_entry(w: vec2<f32>, m: vec2<f32>, radius: f32) -> f32 {
    let a = dot(m, m);
    let b = dot(w, m);
    let c = dot(w, w) - radius * radius;
    let discriminant = b * b - a * c;
    if discriminant < 0.0 {
        return MISS;
    }
    let root = sqrt(discriminant);
    if b < 0.0 {
        return c / (root - b);
    }
    return (-b - root) / a;
}

// Entry of the line (pivot + from_pivot) + d·m into the real edge: the arc of radius
// R + e + w(ψ) about a centre tip_offset behind the pivot (tools are set at their tip).
fn edge_entry(from_pivot: vec2<f32>, m: vec2<f32>, tip: vec2<f32>, psi_sign: f32) -> f32 {
    let w = from_pivot + params.tip_offset_mm * tip;
    var radius = params.nose_radius_mm + params.radius_error_mm;
    var passes = 0u;
    if params.deviation_count > 0u {
        passes = params.edge_refinements;
    }
    var d = circle_entry(w, m, radius);
    if d == MISS {
        return MISS;
    }
    for (var refinement = 0u; refinement <= passes; refinement = refinement + 1u) {
        // The hit lies on the circle of `radius`: within the edge arc when
        // hit·tip ≥ radius·cos(half span).
        let hit = w + d * m;
        if dot(hit, tip) < radius * params.cos_half_span {
            return MISS;
        }
        if refinement == passes {
            break;
        }
        let psi = psi_sign * atan2(hit.x * tip.y - hit.y * tip.x, dot(hit, tip));
        radius = params.nose_radius_mm + params.radius_error_mm + deviation_at(psi);
        d = circle_entry(w, m, radius);
        if d == MISS {
            return MISS;
        }
    }
    return d;
}

struct PassNode {
    node: i32,
    t: f32,
    valid: bool,
}

// Pose-table position of pass `rev` at spindle phase β (integer node arithmetic).
fn pass_node(rev: u32, phase_rad: f32) -> PassNode {
    let steps_in = (phase_rad + params.start_phase_rad) * params.inverse_step_rad;
    let whole = floor(steps_in);
    let fraction = steps_in - whole;
    let base = params.base_steps + i32(rev * params.steps_per_rev) - i32(whole);
    var node = base;
    var t = 0.0;
    if fraction > 0.0 {
        node = base - 1;
        t = 1.0 - fraction;
    }
    let last = i32(params.pose_count) - 1;
    if node == last && t == 0.0 {
        node = node - 1;
        t = 1.0;
    }
    return PassNode(node, t, node >= 0 && node < last);
}

fn wrap_phase(angle: f32) -> f32 {
    return angle - TAU * floor(angle / TAU);
}

struct Best {
    depth_mm: f32,
    pass_id: u32,
}

// `SpringBack::after` (src/engine/scene.rs): the height a pass whose edge reaches `depth`
// leaves where the surface stands at `height`. A chip below min_chip_mm ploughs and
// springs back by `recovery` of itself; both 0 = the running minimum.
fn after_pass(height: f32, depth: f32) -> f32 {
    let chip = height - depth;
    if !(chip > 0.0) {
        return height;
    }
    if chip < params.min_chip_mm {
        return depth + params.recovery * chip;
    }
    return depth;
}

// The pass `pass_id` reaching `depth`: `best` changed by `after_pass`, the id kept when
// the height does not change.
fn apply_pass(best: Best, depth: f32, pass_id: u32) -> Best {
    let height = after_pass(best.depth_mm, depth);
    if height < best.depth_mm {
        return Best(height, pass_id);
    }
    return best;
}

// Direct (sign +1, branch 0) or mirrored (sign −1, branch 1) passes through the edge.
fn scan_edge(ring: Ring, first: u32, last: u32, phase: f32, sign: f32, branch: u32, best_in: Best) -> Best {
    var best = best_in;
    let n = vec2<f32>(ring.normal_r, ring.normal_z);
    let y0 = params.edge_plane_y_mm;
    let r = ring.r_hi;
    let lateral = ring.q_hi;
    var direction = n;
    if y0 != 0.0 {
        direction = vec2<f32>(r * n.x / lateral, n.y);
    }
    for (var rev = first; rev <= last; rev = rev + 1u) {
        let pn = pass_node(rev, phase);
        if !pn.valid {
            continue;
        }
        let p0 = poses[pn.node];
        let p1 = poses[pn.node + 1];
        let t = pn.t;
        let step_x = (p1.x_hi - p0.x_hi) + (p1.x_lo - p0.x_lo);
        let step_z = (p1.z_hi - p0.z_hi) + (p1.z_lo - p0.z_lo);
        let from_pivot = vec2<f32>(
            (ring.q_hi - sign * p0.x_hi) + (ring.q_lo - sign * p0.x_lo) - sign * t * step_x,
            (ring.z_hi - p0.z_hi) + (ring.z_lo - p0.z_lo) - t * step_z,
        );
        let b_rad = p0.b_rad + t * (p1.b_rad - p0.b_rad);
        let tip = tip_direction(b_rad) * vec2<f32>(sign, 1.0);
        var d = edge_entry(from_pivot, direction, tip, sign);
        if y0 != 0.0 {
            for (var i = 0u; i < params.ray_refinements && d != MISS; i = i + 1u) {
                let rho = r + d * n.x;
                if rho <= abs(y0) {
                    d = MISS;
                    break;
                }
                let q = sqrt(rho * rho - y0 * y0);
                let shift = d * n.x * (2.0 * r + d * n.x) / (q + lateral);
                let slope = vec2<f32>(rho * n.x / q, n.y);
                d = edge_entry(from_pivot + vec2<f32>(shift, d * n.y) - d * slope, slope, tip, sign);
            }
        }
        best = apply_pass(best, d, rev * PASS_ID_STRIDE + branch);
    }
    return best;
}

// Flank passes over the pip of a tool above centre (branch 2): the flank meets the sample
// at machine (0, −r), (|y₀| − r)·tan(clearance) above the real edge's height at x = 0
// (its deviation w(ψ) there included).
fn scan_flank(ring: Ring, first: u32, last: u32, phase: f32, best_in: Best) -> Best {
    var best = best_in;
    let circle = params.nose_radius_mm + params.radius_error_mm;
    let behind = abs(params.edge_plane_y_mm) - ring.r_hi;
    let slope_factor = ring.normal_z + ring.normal_r * params.tan_clearance;
    for (var rev = first; rev <= last; rev = rev + 1u) {
        let pn = pass_node(rev, phase);
        if !pn.valid {
            continue;
        }
        let p0 = poses[pn.node];
        let p1 = poses[pn.node + 1];
        let t = pn.t;
        let b_rad = p0.b_rad + t * (p1.b_rad - p0.b_rad);
        let tip = tip_direction(b_rad);
        let offset = params.tip_offset_mm * tip;
        let centre_x = (p0.x_hi + p0.x_lo) + t * ((p1.x_hi - p0.x_hi) + (p1.x_lo - p0.x_lo)) - offset.x;
        if abs(centre_x) >= circle {
            continue;
        }
        var radius = circle;
        if params.deviation_count > 0u {
            let hit = vec2<f32>(-centre_x, -sqrt(circle * circle - centre_x * centre_x));
            radius = circle + deviation_at(atan2(hit.x * tip.y - hit.y * tip.x, dot(hit, tip)));
            if abs(centre_x) >= radius {
                continue;
            }
        }
        let centre_above = (p0.z_hi - ring.z_hi) + (p0.z_lo - ring.z_lo)
            + t * ((p1.z_hi - p0.z_hi) + (p1.z_lo - p0.z_lo)) - offset.y;
        let above = centre_above - sqrt(radius * radius - centre_x * centre_x) + behind * params.tan_clearance;
        let d = above / slope_factor;
        best = apply_pass(best, d, rev * PASS_ID_STRIDE + 2u);
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
    let azimuth = f32(sample / params.ring_count) * params.azimuth_step_rad;
    let ring = rings[ring_index];

    var best = Best(params.stock_top_mm, NO_PASS);
    let alpha = ring.direct_azimuth_rad;
    best = scan_edge(ring, ring.direct_first, ring.direct_last, wrap_phase(azimuth - alpha), 1.0, 0u, best);
    best = scan_edge(ring, ring.mirrored_first, ring.mirrored_last, wrap_phase(azimuth - (PI - alpha)), -1.0, 1u, best);
    best = scan_flank(ring, ring.flank_first, ring.flank_last, wrap_phase(azimuth + 0.5 * PI), best);
    dexels[local_index] = Dexel(best.depth_mm, best.pass_id);
}

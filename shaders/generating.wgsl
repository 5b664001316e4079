// Generating removal kernel (cup wheel, seed 000): one invocation per dexel.
// The per-ring contacts of the continuous edge (circle angle, depth, local frame) are
// found once on the CPU in f64 (src/engine/generating_scene.rs). A continuous edge
// leaves each ring's lowest contact. With teeth, every tooth pass near each contact, in
// each distinct spark-out revolution, is solved for where it enters the sample's ray,
// and the lowest entry is kept.
// f64 twin: `generating_dexel` and `tooth_pass_entry` in src/engine/cpu_generating.rs —
// change them together.
//
// Precision: the pass equations only see differences from the contact point (the
// frame's offset is at most the edge radius, the sample's travel a few tooth
// spacings), and q − R_t, D − r are formed without cancelling; tooth phases arrive
// as whole + fractional tooth counts split in f64, so nothing large meets f32.

struct GeneratingParams {
    ring_count: u32,
    azimuth_count: u32,
    sample_offset: u32,
    sample_count: u32,
    dispatch_width: u32,
    teeth: u32,
    revolutions: u32,
    newton_steps: u32,
    cutting_radius_mm: f32,
    edge_radius_mm: f32,
    stock_top_mm: f32,
    speed_ratio: f32,
    pitch_rad: f32,
    window_rad: f32,
    azimuth_step_rad: f32,
    passes_per_turn_fraction: f32,
    passes_per_turn_whole: i32,
    _padding0: u32,
    _padding1: u32,
    _padding2: u32,
}

struct GeneratingRing {
    normal_r: f32,
    normal_z: f32,
    contact_count: u32,
    _padding: u32,
}

struct GeneratingContact {
    depth_mm: f32,
    radius_mm: f32,
    azimuth_rad: f32,
    phase_fraction: f32,
    offset_rho: f32,
    offset_phi: f32,
    offset_z: f32,
    phase_whole: i32,
    radial_rho: f32,
    radial_phi: f32,
    radial_z: f32,
    _padding0: f32,
    tangent_rho: f32,
    tangent_phi: f32,
    tangent_z: f32,
    _padding1: f32,
    axis_rho: f32,
    axis_phi: f32,
    axis_z: f32,
    _padding2: f32,
}

struct AzimuthPhase {
    fraction: f32,
    whole: i32,
}


@group(0) @binding(0) var<uniform> params: GeneratingParams;
@group(0) @binding(1) var<storage, read> rings: array<GeneratingRing>;
@group(0) @binding(2) var<storage, read> contacts: array<GeneratingContact>;
@group(0) @binding(3) var<storage, read> azimuth_phases: array<AzimuthPhase>;
@group(0) @binding(4) var<storage, read_write> dexels: array<Dexel>;

struct PassEntry {
    depth_mm: f32,
    shift_rad: f32,
    valid: bool,
}

// The tooth pass `lead` ahead of the contact, in the contact's frame: Newton on
// g₁ = atan2(w·t, R_t + w·u) − Kδ − lead (the sample in the tooth's plane) and
// g₂ = √((q − R_t)² + (w·a)²) − r (the sample on the edge's tube), from δ = −lead/K,
// d = d_c, with w = offset + ((d − d_c)n_r − 2ρ sin²(δ/2), ρ sin δ, (d − d_c)n_z).
fn tooth_pass_entry(c: GeneratingContact, n: vec2<f32>, lead: f32) -> PassEntry {
    let offset = vec3<f32>(c.offset_rho, c.offset_phi, c.offset_z);
    let u = vec3<f32>(c.radial_rho, c.radial_phi, c.radial_z);
    let t = vec3<f32>(c.tangent_rho, c.tangent_phi, c.tangent_z);
    let a = vec3<f32>(c.axis_rho, c.axis_phi, c.axis_z);
    let rt = params.cutting_radius_mm;
    let r = params.edge_radius_mm;
    let k = params.speed_ratio;
    var shift = -lead / k;
    var along = 0.0;
    for (var step = 0u; step < params.newton_steps; step = step + 1u) {
        let rho = c.radius_mm + along * n.x;
        let s = sin(shift);
        let co = cos(shift);
        let half = sin(0.5 * shift);
        let w = offset + vec3<f32>(along * n.x - 2.0 * rho * half * half, rho * s, along * n.y);
        let dw_shift = vec3<f32>(-rho * s, rho * co, 0.0);
        let dw_depth = vec3<f32>(n.x * co, n.x * s, n.y);
        let wu = dot(w, u);
        let wt = dot(w, t);
        let wa = dot(w, a);
        let reach = rt + wu;
        let q2 = reach * reach + wt * wt;
        let q = sqrt(q2);
        let radial = (wu * (2.0 * rt + wu) + wt * wt) / (q + rt);
        let distance = sqrt(radial * radial + wa * wa);
        let g1 = atan2(wt, reach) - k * shift - lead;
        let g2 = (radial * radial + wa * wa - r * r) / (distance + r);
        let du_s = dot(dw_shift, u);
        let dt_s = dot(dw_shift, t);
        let da_s = dot(dw_shift, a);
        let du_d = dot(dw_depth, u);
        let dt_d = dot(dw_depth, t);
        let da_d = dot(dw_depth, a);
        let g1_shift = (reach * dt_s - wt * du_s) / q2 - k;
        let g1_depth = (reach * dt_d - wt * du_d) / q2;
        let g2_shift = (radial * (reach * du_s + wt * dt_s) / q + wa * da_s) / distance;
        let g2_depth = (radial * (reach * du_d + wt * dt_d) / q + wa * da_d) / distance;
        let det = g1_shift * g2_depth - g1_depth * g2_shift;
        if det == 0.0 {
            return PassEntry(0.0, 0.0, false);
        }
        shift = shift - (g1 * g2_depth - g2 * g1_depth) / det;
        along = along - (g1_shift * g2 - g2_shift * g1) / det;
        if abs(shift) >= PI || along > r {
            return PassEntry(0.0, 0.0, false);
        }
    }
    return PassEntry(c.depth_mm + along, shift, true);
}

@compute @workgroup_size(64)
fn remove_generating(@builtin(global_invocation_id) id: vec3<u32>) {
    let local_index = id.x + id.y * params.dispatch_width;
    if local_index >= params.sample_count {
        return;
    }
    let sample = params.sample_offset + local_index;
    let ring_index = sample % params.ring_count;
    let azimuth_index = sample / params.ring_count;
    let ring = rings[ring_index];
    var best_depth = params.stock_top_mm;
    var best_pass = NO_PASS;
    if params.teeth == 0u {
        if ring.contact_count > 0u {
            best_depth = contacts[ring_index * MAX_CONTACTS].depth_mm;
            best_pass = 0u;
        }
        dexels[local_index] = Dexel(best_depth, best_pass);
        return;
    }
    let azimuth = f32(azimuth_index) * params.azimuth_step_rad;
    let phase = azimuth_phases[azimuth_index];
    let n = vec2<f32>(ring.normal_r, ring.normal_z);
    for (var index = 0u; index < ring.contact_count; index = index + 1u) {
        let c = contacts[ring_index * MAX_CONTACTS + index];
        var wrap = 0i;
        if c.azimuth_rad < azimuth {
            wrap = 1i;
        }
        for (var revolution = 0u; revolution <= params.revolutions; revolution = revolution + 1u) {
            let turns = wrap + i32(revolution);
            let contact_time = c.azimuth_rad - azimuth + TAU * f32(turns);
            if contact_time > params.window_rad + PI {
                break;
            }
            // Tooth passes counted from the spark-out start, whole + fraction.
            let raw = c.phase_fraction - phase.fraction + f32(turns) * params.passes_per_turn_fraction;
            let carry = floor(raw);
            let fraction = raw - carry;
            let nearest = c.phase_whole - phase.whole + turns * params.passes_per_turn_whole + i32(carry);
            for (var offset = -PASSES_PER_CONTACT / 2; offset < PASSES_PER_CONTACT / 2; offset = offset + 1) {
                let lead = (fraction + f32(offset)) * params.pitch_rad;
                let entry = tooth_pass_entry(c, n, lead);
                if !entry.valid {
                    continue;
                }
                let time = contact_time + entry.shift_rad;
                if entry.depth_mm < best_depth && time >= 0.0 && time < params.window_rad {
                    best_depth = entry.depth_mm;
                    best_pass = u32((nearest - offset) * 2 + i32(index)) & 0x7fffffffu;
                }
            }
        }
    }
    dexels[local_index] = Dexel(best_depth, best_pass);
}

// Milling removal kernel: one invocation per dexel (sample of the nominal surface).
// The sample gathers the passes binned near it, locates on each the point nearest it,
// ranks them and searches them: a bracket about the located point (a ball on a pass
// with one valley) or a coarse scan, refined by Brent's method; with teeth, the stamps.
// f64 twin: `milling_dexel` and its helpers in src/engine/cpu_milling.rs, candidates
// in src/engine/milling_scene.rs, entries in src/geometry/milling_tool.rs, cutter.rs and
// disc_cutter.rs — change them together.
//
// Precision: everything happens in the sample's own frame (origin at its nominal
// point, axes e_r, e_φ, e_z at its azimuth, or x, y, z on an extruded part). A node's
// offset comes from its cylindrical coordinates as hi + lo pairs: δ = θ − φ and ρ − r
// are differences of hi + lo pairs, and Δ = ((ρ − r) − 2ρ sin²(δ/2), 2ρ sin(δ/2)cos(δ/2),
// z − z_s) has no cancellation, so f32 keeps ~0.05 nm where the coordinates are 20 mm.
// Unlike the f64 twin, the kernel carries a pose's centre less κ·n (κ the centre's
// offset along the normal of a tool touching the sample: `centre_offset_mm`): the
// rings give the point p + κ·n as hi + lo pairs, so that offset keeps ~0.05 nm where κ
// is 15 mm (a disc's throat), and the ball's and the disc's entries are written in it
// without cancellation. Positions along a pass are a node index plus an f32 fraction
// relative to it.

struct MillingParams {
    ring_count: u32,
    row_count: u32,
    sample_offset: u32,
    sample_count: u32,
    dispatch_width: u32,
    polar: u32,
    cells_x: u32,
    cells_y: u32,
    cells_z: u32,
    offset_count: u32,
    refine_steps: u32,
    entry_steps: u32,
    stock_top_mm: f32,
    centre_offset_mm: f32,
    lateral_mm: f32,
    search_radius_mm: f32,
    major_radius_mm: f32,
    corner_radius_mm: f32,
    length_mm: f32,
    slack_per_spacing_squared: f32,
    slack_displacement_mm: f32,
    disc_quadratic: f32,
    disc_linear: f32,
    disc_constant: f32,
    disc_low: f32,
    disc_high: f32,
    cell_mm: f32,
    refine_width: f32,
    refine_gain_mm: f32,
    tie_mm: f32,
    entry_tolerance_mm: f32,
    first_bracket: f32,
    origin_x: f32,
    origin_y: f32,
    origin_z: f32,
    // A disc: κ² − C, its throat radius squared less the profile's constant (mm²).
    disc_gap_mm2: f32,
    // Teeth as edges (STAMP_MODE 3): the count, the edge's lag per mm above the tip
    // (rad/mm), and the turn (rad) that ends a pass's refinement.
    teeth: u32,
    lag_per_mm: f32,
    edge_tolerance_rad: f32,
    // … and how far a tooth's solid can reach beyond the nominal tool (mm).
    edge_reach_mm: f32,
    // … the feed per tooth (mm) and the bracket (tooth counts) that ends a pass's search.
    feed_per_tooth_mm: f32,
    edge_width: f32,
    _padding0: f32,
    _padding1: f32,
}

// A ring of samples: its point (r, z) and the core point (r, z) + κ·(n_r, n_z), as
// hi + lo pairs, and the normal.
struct MillingRing {
    r_hi: f32,
    r_lo: f32,
    z_hi: f32,
    z_lo: f32,
    core_r_hi: f32,
    core_r_lo: f32,
    core_z_hi: f32,
    core_z_lo: f32,
    normal_r: f32,
    normal_z: f32,
    _padding0: f32,
    _padding1: f32,
}

struct MillingRow {
    value_hi: f32,
    value_lo: f32,
    cos: f32,
    sin: f32,
}

struct MillingNode {
    x_hi: f32,
    x_lo: f32,
    y_hi: f32,
    y_lo: f32,
    z_hi: f32,
    z_lo: f32,
    rho_hi: f32,
    rho_lo: f32,
    angle_hi: f32,
    angle_lo: f32,
    axis_x: f32,
    axis_y: f32,
    axis_z: f32,
    step_rho: f32,
    step_angle: f32,
    step_z: f32,
    teeth_whole: i32,
    teeth_fraction: f32,
    _padding0: f32,
    _padding1: f32,
}

struct MillingPass {
    first_node: u32,
    node_count: u32,
    polar: u32,
    stride: u32,
    spacing_mm: f32,
    origin_x: f32,
    origin_y: f32,
    origin_z: f32,
    step_x: f32,
    step_y: f32,
    step_z: f32,
    _padding: f32,
}

struct MillingRun {
    pass_index: u32,
    first: u32,
    last: u32,
    _padding0: u32,
    low_x: f32,
    low_y: f32,
    low_z: f32,
    high_x: f32,
    high_y: f32,
    high_z: f32,
    axis_x: f32,
    axis_y: f32,
    axis_z: f32,
    _padding1: f32,
    _padding2: f32,
    _padding3: f32,
}

// Pipeline constants: each pipeline is compiled for one tool and one stamp mode, so the
// compiler drops the code of the others (src/engine/gpu/mod.rs sets them).
// TOOL_KIND: 0 ball, 1 bull-nose, 2 flat end, 3 disc.
override TOOL_KIND: u32;
// STAMP_MODE: 0 the body sweeps, 1 stamps about the optimum, 2 every stamp (displaced
// teeth), 3 teeth as edges.
override STAMP_MODE: u32;

@group(0) @binding(0) var<uniform> params: MillingParams;
@group(0) @binding(1) var<storage, read> rings: array<MillingRing>;
@group(0) @binding(2) var<storage, read> rows: array<MillingRow>;
@group(0) @binding(3) var<storage, read> nodes: array<MillingNode>;
@group(0) @binding(4) var<storage, read> passes: array<MillingPass>;
@group(0) @binding(5) var<storage, read> cell_start: array<u32>;
@group(0) @binding(6) var<storage, read> runs: array<MillingRun>;
// Per tooth: its displacement in the spindle's frame (x, y), and as an edge its radial
// and axial runout (z, w).
@group(0) @binding(7) var<storage, read> teeth_table: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> dexels: array<Dexel>;

// ---------------------------------------------------------------- the sample's frame

struct Frame {
    // The core point p + κ·n: (r, z), or (x, z) on an extruded part.
    r_hi: f32,
    r_lo: f32,
    z_hi: f32,
    z_lo: f32,
    // Polar: the azimuth; extruded: the row's y.
    value_hi: f32,
    value_lo: f32,
    cos: f32,
    sin: f32,
    normal: vec3<f32>,
    world_point: vec3<f32>,
    world_normal: vec3<f32>,
}

fn make_frame(ring: MillingRing, row: MillingRow) -> Frame {
    var f: Frame;
    f.r_hi = ring.core_r_hi;
    f.r_lo = ring.core_r_lo;
    f.z_hi = ring.core_z_hi;
    f.z_lo = ring.core_z_lo;
    f.value_hi = row.value_hi;
    f.value_lo = row.value_lo;
    f.cos = row.cos;
    f.sin = row.sin;
    f.normal = vec3<f32>(ring.normal_r, 0.0, ring.normal_z);
    let r = ring.r_hi + ring.r_lo;
    let z = ring.z_hi + ring.z_lo;
    if params.polar == 1u {
        f.world_point = vec3<f32>(r * row.cos, r * row.sin, z);
        f.world_normal = vec3<f32>(ring.normal_r * row.cos, ring.normal_r * row.sin, ring.normal_z);
    } else {
        f.world_point = vec3<f32>(r, row.value_hi + row.value_lo, z);
        f.world_normal = vec3<f32>(ring.normal_r, 0.0, ring.normal_z);
    }
    return f;
}

// A machine-frame direction in the frame.
fn frame_direction(f: Frame, v: vec3<f32>) -> vec3<f32> {
    if params.polar == 1u {
        return vec3<f32>(v.x * f.cos + v.y * f.sin, -v.x * f.sin + v.y * f.cos, v.z);
    }
    return v;
}

// The difference of two angles in [0, 2π), brought into (−π, π].
fn wrap_angle(angle: f32) -> f32 {
    if angle > PI {
        return angle - TAU;
    }
    if angle <= -PI {
        return angle + TAU;
    }
    return angle;
}

// A node's azimuth less the sample's, in (−π, π].
fn node_delta(f: Frame, n: MillingNode) -> f32 {
    return wrap_angle((n.angle_hi - f.value_hi) + (n.angle_lo - f.value_lo));
}

// The offset of the point ρ from Z (given as ρ − r and ρ), δ past the sample, at
// height z − z_s (r, z_s: the core point's).
fn polar_offset(rho_less_r: f32, rho: f32, delta: f32, z_less: f32) -> vec3<f32> {
    let s = sin(0.5 * delta);
    let c = cos(0.5 * delta);
    return vec3<f32>(rho_less_r - 2.0 * rho * s * s, 2.0 * rho * s * c, z_less);
}

// A node's centre relative to the core point, in the frame.
fn node_offset(f: Frame, n: MillingNode) -> vec3<f32> {
    let z_less = (n.z_hi - f.z_hi) + (n.z_lo - f.z_lo);
    if params.polar == 1u {
        let rho_less_r = (n.rho_hi - f.r_hi) + (n.rho_lo - f.r_lo);
        return polar_offset(rho_less_r, n.rho_hi, node_delta(f, n), z_less);
    }
    return vec3<f32>(
        (n.x_hi - f.r_hi) + (n.x_lo - f.r_lo),
        (n.y_hi - f.value_hi) + (n.y_lo - f.value_lo),
        z_less,
    );
}

fn node_axis(n: MillingNode) -> vec3<f32> {
    return vec3<f32>(n.axis_x, n.axis_y, n.axis_z);
}

fn node_world(n: MillingNode) -> vec3<f32> {
    return vec3<f32>(n.x_hi + n.x_lo, n.y_hi + n.y_lo, n.z_hi + n.z_lo);
}

// The step from node a to node b in the machine frame, as differences of their hi + lo
// pairs: nearby nodes' hi parts subtract exactly, so the step keeps f32's relative
// precision however short it is. Its direction is the feed's, from which a tooth's turn
// is measured: as the difference of the nodes' offsets from the sample (a few mm each,
// rounded to f32) a 6 µm step lost up to 1.4e-4 rad of it, an edge passed the sample
// that much early or late, and a leaned flat end's edge marks moved by up to 48 nm.
fn node_step(a: MillingNode, b: MillingNode) -> vec3<f32> {
    return vec3<f32>(
        (b.x_hi - a.x_hi) + (b.x_lo - a.x_lo),
        (b.y_hi - a.y_hi) + (b.y_lo - a.y_lo),
        (b.z_hi - a.z_hi) + (b.z_lo - a.z_lo),
    );
}

// A pose in the frame: its centre less the sample's core point p + κ·n, and the unit
// axis.
struct Pose {
    offset: vec3<f32>,
    axis: vec3<f32>,
}

// The pose's centre relative to the sample (rounded to f32: for the entries that
// have no form without it).
fn pose_centre(f: Frame, pose: Pose) -> vec3<f32> {
    return params.centre_offset_mm * f.normal + pose.offset;
}

// A position along a pass: node `base` plus `x` node spacings.
// The segment of pass p holding base + x, and the fraction along it.
struct SegmentPoint {
    index: u32,
    t: f32,
}

fn segment_at(p: MillingPass, base: u32, x: f32) -> SegmentPoint {
    let last = i32(p.node_count) - 1;
    let whole = floor(x);
    var i = clamp(i32(base) + i32(whole), 0, max(last - 1, 0));
    let t = clamp(x - f32(i - i32(base)), 0.0, 1.0);
    return SegmentPoint(u32(i), t);
}

const NO_SEGMENT: u32 = 0xffffffffu;

// The segment of a pass last evaluated, in the sample's frame, so consecutive
// evaluations within one segment read no nodes. Linear: a, b the nodes' offsets and
// `step` the step from a to b (`node_step`); polar: a = (ρ_a − r, δ_a, z_a − z_s), b =
// the polar steps to the next node, rho = ρ_a. The axes and the step are turned into
// the frame.
struct Segment {
    index: u32,
    a: vec3<f32>,
    b: vec3<f32>,
    rho: f32,
    axis_a: vec3<f32>,
    axis_b: vec3<f32>,
    step: vec3<f32>,
}

fn empty_segment() -> Segment {
    return Segment(NO_SEGMENT, vec3<f32>(0.0), vec3<f32>(0.0), 0.0, vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
}

fn is_polar(p: MillingPass) -> bool {
    return p.polar == 1u && params.polar == 1u;
}

fn load_segment(f: Frame, p: MillingPass, i: u32) -> Segment {
    let last = p.node_count - 1u;
    let na = nodes[p.first_node + i];
    let nb = nodes[p.first_node + min(i + 1u, last)];
    var g: Segment;
    g.index = i;
    g.axis_a = frame_direction(f, node_axis(na));
    g.axis_b = frame_direction(f, node_axis(nb));
    if is_polar(p) {
        g.a = vec3<f32>(
            (na.rho_hi - f.r_hi) + (na.rho_lo - f.r_lo),
            node_delta(f, na),
            (na.z_hi - f.z_hi) + (na.z_lo - f.z_lo),
        );
        g.b = vec3<f32>(na.step_rho, na.step_angle, na.step_z);
        g.rho = na.rho_hi;
    } else {
        g.a = node_offset(f, na);
        g.b = node_offset(f, nb);
        g.rho = 0.0;
        g.step = frame_direction(f, node_step(na, nb));
    }
    return g;
}

// The pose at base + x (see `pose_at`), through the segment held in `seg`.
fn pose_at(f: Frame, p: MillingPass, base: u32, x: f32, seg: ptr<function, Segment>) -> Pose {
    let s = segment_at(p, base, x);
    if (*seg).index != s.index {
        *seg = load_segment(f, p, s.index);
    }
    let g = *seg;
    var offset: vec3<f32>;
    if is_polar(p) {
        offset = polar_offset(g.a.x + s.t * g.b.x, g.rho + s.t * g.b.x, g.a.y + s.t * g.b.y, g.a.z + s.t * g.b.z);
    } else {
        offset = g.a + s.t * (g.b - g.a);
    }
    return Pose(offset, normalize(mix(g.axis_a, g.axis_b, s.t)));
}

// The direction of travel at base + x, in the frame (see `feed_direction`).
fn feed_at(f: Frame, p: MillingPass, base: u32, x: f32, seg: ptr<function, Segment>) -> vec3<f32> {
    let s = segment_at(p, base, x);
    if (*seg).index != s.index {
        *seg = load_segment(f, p, s.index);
    }
    let g = *seg;
    var velocity: vec3<f32>;
    if is_polar(p) {
        let rho = g.rho + s.t * g.b.x;
        let delta = g.a.y + s.t * g.b.y;
        let sd = sin(delta);
        let cd = cos(delta);
        velocity = vec3<f32>(g.b.x * cd - rho * g.b.y * sd, g.b.x * sd + rho * g.b.y * cd, g.b.z);
    } else {
        velocity = g.step;
    }
    if dot(velocity, velocity) > 0.0 {
        return normalize(velocity);
    }
    return vec3<f32>(0.0);
}

// ---------------------------------------------------------------- the tools

// Parameter interval where lo ≤ a0 + t·ad ≤ hi (empty: x > y).
fn slab(a0: f32, ad: f32, lo: f32, hi: f32) -> vec2<f32> {
    if ad == 0.0 {
        if lo <= a0 && a0 <= hi {
            return vec2<f32>(-MISS, MISS);
        }
        return vec2<f32>(1.0, 0.0);
    }
    let ta = (lo - a0) / ad;
    let tb = (hi - a0) / ad;
    return vec2<f32>(min(ta, tb), max(ta, tb));
}

// Parameter interval where |v0 + t·vd| ≤ radius (vectors across the axis).
fn cylinder(v0: vec3<f32>, vd: vec3<f32>, radius: f32) -> vec2<f32> {
    let aa = dot(vd, vd);
    if aa == 0.0 {
        if length(v0) <= radius {
            return vec2<f32>(-MISS, MISS);
        }
        return vec2<f32>(1.0, 0.0);
    }
    let b = dot(v0, vd);
    let perp = length(v0 - (b / aa) * vd);
    if perp > radius {
        return vec2<f32>(1.0, 0.0);
    }
    let disc = aa * (radius - perp) * (radius + perp);
    let rho0 = length(v0);
    let c = (rho0 - radius) * (rho0 + radius);
    var q = -(b + sign(b) * sqrt(disc));
    if b == 0.0 {
        q = -sqrt(disc);
    }
    if q == 0.0 {
        return vec2<f32>(0.0, 0.0);
    }
    let ta = q / aa;
    let tb = c / q;
    return vec2<f32>(min(ta, tb), max(ta, tb));
}

// The ray t·n in the pose's axis frame: axial a0 + t·ad, radial v0 + t·vd.
struct AxisRay {
    a0: f32,
    ad: f32,
    v0: vec3<f32>,
    vd: vec3<f32>,
}

fn axis_ray(f: Frame, pose: Pose) -> AxisRay {
    let o = -pose_centre(f, pose);
    let dir = f.normal;
    let w = pose.axis;
    let a0 = dot(o, w);
    let ad = dot(dir, w);
    return AxisRay(a0, ad, o - a0 * w, dir - ad * w);
}

// A ball's entry: the sphere where the ray meets its lower half, else the shank. With
// the centre at r·n + d: |t n − c|² = r² has b = −(r + d·n), c = 2r d·n + |d|².
fn ball_entry(f: Frame, pose: Pose) -> f32 {
    let r = params.corner_radius_mm;
    let dir = f.normal;
    let d = pose.offset;
    let dn = dot(d, dir);
    let b = -(r + dn);
    let c = 2.0 * r * dn + dot(d, d);
    let o = -pose_centre(f, pose);
    let discriminant = b * b - c;
    if discriminant >= 0.0 {
        let root = sqrt(discriminant);
        var t = -b - root;
        if b < 0.0 {
            t = c / (root - b);
        }
        if dot(o + t * dir, pose.axis) <= 1.0e-9 {
            return t;
        }
    }
    let ray = axis_ray(f, pose);
    let aa = dot(ray.vd, ray.vd);
    if aa > 0.0 {
        let bb = dot(ray.v0, ray.vd);
        let perp = length(ray.v0 - (bb / aa) * ray.vd);
        if perp > r {
            return MISS;
        }
        let half = sqrt(aa * (r - perp) * (r + perp));
        let t_in = (-bb - half) / aa;
        let t_out = (-bb + half) / aa;
        let s = slab(ray.a0, ray.ad, 0.0, params.length_mm);
        let start = max(t_in, s.x);
        if start <= min(t_out, s.y) {
            return start;
        }
        return MISS;
    }
    if length(ray.v0) <= r && ray.ad != 0.0 {
        let x = (0.0 - ray.a0) / ray.ad;
        let y = (params.length_mm - ray.a0) / ray.ad;
        return min(x, y);
    }
    return MISS;
}

// Distance from the ray point at t to the core {ρ ≤ R, a ≥ 0}, and its derivative.
fn core_distance(ray: AxisRay, t: f32, big: f32) -> vec2<f32> {
    let a = ray.a0 + t * ray.ad;
    let v = ray.v0 + t * ray.vd;
    let rho = length(v);
    let er = max(rho - big, 0.0);
    let ea = min(a, 0.0);
    let g = sqrt(er * er + ea * ea);
    var drho = 0.0;
    if er > 0.0 {
        drho = dot(v, ray.vd) / rho;
    }
    return vec2<f32>(g, (er * drho + ea * ray.ad) / max(g, 1.0e-30));
}

// A bull-nose or flat end's entry: the analytic box, then Newton's steps on the convex
// distance to the core less r (monotone from outside; a non-falling tangent: a miss).
// `big`: the corner arc's centre circle radius R (a tooth's own, with its runout).
fn end_mill_entry(f: Frame, pose: Pose, big: f32) -> f32 {
    let small = params.corner_radius_mm;
    let ray = axis_ray(f, pose);
    let s = slab(ray.a0, ray.ad, -small, params.length_mm);
    let c = cylinder(ray.v0, ray.vd, big + small);
    var t = max(s.x, c.x);
    let t1 = min(s.y, c.y);
    if s.x > s.y || c.x > c.y || t > t1 || abs(t) >= MISS {
        return MISS;
    }
    if TOOL_KIND == 2u {
        return t;
    }
    for (var i = 0u; i < params.entry_steps; i = i + 1u) {
        let g = core_distance(ray, t, big);
        let h = g.x - small;
        if h <= 0.0 {
            return t;
        }
        if g.y >= 0.0 {
            return MISS;
        }
        let step = -h / g.y;
        t = t + step;
        if t > t1 {
            return MISS;
        }
        if step <= params.entry_tolerance_mm {
            return t;
        }
    }
    return t;
}

// A disc cutter's entry: the first piece of the ray inside its hyperboloid
// ρ² ≤ A s² + B s + C between the edge's end planes. With the centre at κ·n + d (κ the
// throat radius), n·w = ν, d·w = δ and n⊥, d⊥ across the axis, |t n − c|⊥² − ρ²(s) =
// qa t² + 2 qb t + qc with qa = 1 − ν²(1 + A), qb = −n⊥·d⊥ + Aνδ − Bν/2 − κ qa and
// qc = (κ² − C) − κ²ν²(1 + A) + 2κ(n⊥·d⊥ − Aνδ) + κBν + |d⊥|² − Aδ² + Bδ: no term
// cancels the 15 mm throat against itself (κ² − C comes exact from f64).
fn disc_entry(f: Frame, pose: Pose) -> f32 {
    let n = f.normal;
    let w = pose.axis;
    let d = pose.offset;
    let kappa = params.centre_offset_mm;
    let big_a = params.disc_quadratic;
    let big_b = params.disc_linear;
    let nu = dot(n, w);
    let delta = dot(d, w);
    let n_across = n - nu * w;
    let d_across = d - delta * w;
    let nd = dot(n_across, d_across);
    let qa = 1.0 - nu * nu * (1.0 + big_a);
    let qb = -nd + big_a * nu * delta - 0.5 * big_b * nu - kappa * qa;
    let qc = params.disc_gap_mm2 - kappa * kappa * nu * nu * (1.0 + big_a)
        + 2.0 * kappa * (nd - big_a * nu * delta) + kappa * big_b * nu
        + dot(d_across, d_across) - big_a * delta * delta + big_b * delta;
    // The slab between the end planes: s(t) = (t − κ)ν − δ.
    let ray = AxisRay(-kappa * nu - delta, nu, vec3<f32>(0.0), vec3<f32>(0.0));
    let s = slab(ray.a0, ray.ad, params.disc_low, params.disc_high);
    if s.x > s.y {
        return MISS;
    }
    // The pieces of qa t² + 2 qb t + qc ≤ 0.
    var first = vec2<f32>(1.0, 0.0);
    var second = vec2<f32>(1.0, 0.0);
    if qa == 0.0 {
        if qb > 0.0 {
            first = vec2<f32>(-MISS, -qc / (2.0 * qb));
        } else if qb < 0.0 {
            first = vec2<f32>(-qc / (2.0 * qb), MISS);
        } else if qc <= 0.0 {
            first = vec2<f32>(-MISS, MISS);
        }
    } else {
        let discriminant = qb * qb - qa * qc;
        if discriminant < 0.0 {
            if qa < 0.0 {
                first = vec2<f32>(-MISS, MISS);
            }
        } else {
            let q = -(qb + select(-1.0, 1.0, qb >= 0.0) * sqrt(discriminant));
            var r1 = 0.0;
            var r2 = 0.0;
            if q != 0.0 {
                r1 = min(q / qa, qc / q);
                r2 = max(q / qa, qc / q);
            }
            if qa > 0.0 {
                first = vec2<f32>(r1, r2);
            } else {
                first = vec2<f32>(-MISS, r1);
                second = vec2<f32>(r2, MISS);
            }
        }
    }
    var best = MISS;
    let a = vec2<f32>(max(first.x, s.x), min(first.y, s.y));
    if a.x <= a.y {
        best = a.x;
    }
    let b = vec2<f32>(max(second.x, s.x), min(second.y, s.y));
    if b.x <= b.y {
        best = min(best, b.x);
    }
    return best;
}

// The entry into the tool whose end mill has corner-circle radius `big` (a ball's
// tooth with runout is a torus).
fn ray_entry(f: Frame, pose: Pose, big: f32) -> f32 {
    if TOOL_KIND == 0u && big == 0.0 {
        return ball_entry(f, pose);
    }
    if TOOL_KIND == 3u {
        return disc_entry(f, pose);
    }
    return end_mill_entry(f, pose, big);
}

// Signed distance from a point (relative to the sample) to the tool: exact for end
// mills, a first-order estimate for disc cutters.
fn signed_distance(f: Frame, pose: Pose, point: vec3<f32>, big: f32) -> f32 {
    let w = pose.axis;
    let p = point - pose_centre(f, pose);
    let a = dot(p, w);
    let rho = length(p - a * w);
    if TOOL_KIND == 3u {
        let s = clamp(a, params.disc_low, params.disc_high);
        let surface = sqrt(max(params.disc_quadratic * s * s + params.disc_linear * s + params.disc_constant, 0.0));
        var slope = 0.0;
        if surface > 0.0 {
            slope = (2.0 * params.disc_quadratic * s + params.disc_linear) / (2.0 * surface);
        }
        let radial = (rho - surface) / sqrt(1.0 + slope * slope);
        return max(max(radial, a - params.disc_high), params.disc_low - a);
    }
    let small = params.corner_radius_mm;
    let above_cap = a - params.length_mm;
    if above_cap > 0.0 {
        let e = max(rho - big - small, 0.0);
        return sqrt(e * e + above_cap * above_cap);
    }
    var core: f32;
    if rho > big || a < 0.0 {
        let er = max(rho - big, 0.0);
        let ea = min(a, 0.0);
        core = sqrt(er * er + ea * ea);
    } else {
        core = max(rho - big, -a);
    }
    return max(core - small, above_cap);
}

// The entry of the ray into the tool, extended above the stock top by the stock-top
// point's distance from the tool.
fn extended_entry(f: Frame, pose: Pose) -> f32 {
    return tooth_entry(f, pose, params.major_radius_mm);
}

// `extended_entry` for a tooth whose end mill's corner circle has radius `big`.
fn tooth_entry(f: Frame, pose: Pose, big: f32) -> f32 {
    let top = params.stock_top_mm;
    let entry = ray_entry(f, pose, big);
    if entry < top {
        return entry;
    }
    return top + max(signed_distance(f, pose, top * f.normal, big), 0.0);
}

fn entry_at(f: Frame, p: MillingPass, base: u32, x: f32, seg: ptr<function, Segment>) -> f32 {
    return extended_entry(f, pose_at(f, p, base, x, seg));
}

// ---------------------------------------------------------------- candidates

struct Candidate {
    pass_index: u32,
    first: u32,
    last: u32,
    // After `locate`: the span to search (lo..=hi), the nearest point base + x, and
    // the extended entry there.
    lo: u32,
    hi: u32,
    base: u32,
    x: f32,
    estimate: f32,
}

struct Expected {
    centre: vec3<f32>,
    radius: f32,
}

fn expected_centre(point: vec3<f32>, normal: vec3<f32>, axis: vec3<f32>) -> Expected {
    let core = point + params.centre_offset_mm * normal;
    if TOOL_KIND == 1u || TOOL_KIND == 2u {
        let across = normal - dot(normal, axis) * axis;
        if length(across) > 1.0e-6 {
            return Expected(core + params.major_radius_mm * normalize(across), 2.0 * params.search_radius_mm);
        }
        return Expected(core, params.major_radius_mm + params.search_radius_mm);
    }
    return Expected(core, params.lateral_mm + params.search_radius_mm);
}

fn run_distance(run: MillingRun, point: vec3<f32>) -> f32 {
    let low = vec3<f32>(run.low_x, run.low_y, run.low_z);
    let high = vec3<f32>(run.high_x, run.high_y, run.high_z);
    return length(max(max(low - point, point - high), vec3<f32>(0.0)));
}

// ---------------------------------------------------------------- locating on a pass

fn distance_squared(n: MillingNode, anchor: vec3<f32>) -> f32 {
    let d = node_world(n) - anchor;
    return dot(d, d);
}

// Node coordinates near the anchor by the pass's geometry (see `nearest_guesses`).
fn nearest_guesses(p: MillingPass, anchor: vec3<f32>, azimuth: f32) -> vec2<f32> {
    if p.polar == 1u {
        if p.step_y == 0.0 {
            return vec2<f32>(0.0);
        }
        let per_turn = TAU / abs(p.step_y);
        let raw = (azimuth - p.origin_y) / p.step_y;
        let u0 = raw - per_turn * floor(raw / per_turn);
        return vec2<f32>(u0, u0 + per_turn);
    }
    let along = vec2<f32>(p.step_x, p.step_y);
    let length2 = dot(along, along);
    var u = 0.0;
    if length2 > 0.0 {
        u = dot(anchor.xy - vec2<f32>(p.origin_x, p.origin_y), along) / length2;
    }
    return vec2<f32>(u, u);
}

fn locate(f: Frame, c_in: Candidate) -> Candidate {
    var c = c_in;
    let p = passes[c.pass_index];
    let last = p.node_count - 1u;
    let lo = select(c.first - 1u, 0u, c.first == 0u);
    let hi = min(c.last + 1u, last);
    let middle = node_axis(nodes[p.first_node + (lo + hi) / 2u]);
    let expected = expected_centre(f.world_point, f.world_normal, middle);
    var anchor = expected.centre;
    var azimuth = atan2(anchor.y, anchor.x);
    if TOOL_KIND == 0u {
        anchor = f.world_point;
        if params.polar == 1u {
            azimuth = f.value_hi + f.value_lo;
        }
    }
    let guesses = nearest_guesses(p, anchor, azimuth);
    var nearest = lo;
    var d = MISS;
    for (var g = 0u; g < 2u; g = g + 1u) {
        let node = u32(round(clamp(guesses[g], f32(lo), f32(hi))));
        let at = distance_squared(nodes[p.first_node + node], anchor);
        if at < d {
            nearest = node;
            d = at;
        }
    }
    // Downhill toward lo, then toward hi, across runs of equal distances (see
    // `walk_downhill`).
    for (var down = 0u; down < 2u; down = down + 1u) {
        loop {
            var k = nearest;
            var at = d;
            loop {
                if (down == 0u && k <= lo) || (down == 1u && k >= hi) {
                    break;
                }
                k = select(k + 1u, k - 1u, down == 0u);
                at = distance_squared(nodes[p.first_node + k], anchor);
                if at != d {
                    break;
                }
            }
            if at >= d {
                break;
            }
            nearest = k;
            d = at;
        }
    }
    // Onto the adjacent segments.
    var base = nearest;
    var x = 0.0;
    var best = d;
    for (var k = 0u; k < 2u; k = k + 1u) {
        var i = min(nearest, hi - min(hi, 1u));
        if k == 0u {
            i = max(select(nearest - 1u, 0u, nearest == 0u), lo);
        }
        if i < hi {
            let a = node_world(nodes[p.first_node + i]);
            let along = node_world(nodes[p.first_node + i + 1u]) - a;
            let t = clamp(dot(anchor - a, along) / max(dot(along, along), 1.0e-30), 0.0, 1.0);
            let e = a + t * along - anchor;
            let at = dot(e, e);
            if at < best {
                best = at;
                base = i;
                x = t;
            }
        }
    }
    // Nodes within the radius, and a scan step more.
    let s = min(nearest, last - 1u);
    let step = length(node_world(nodes[p.first_node + s + 1u]) - node_world(nodes[p.first_node + s]));
    let half = u32(min(ceil(expected.radius / max(step, 1.0e-12)) + f32(p.stride), f32(hi - lo)));
    c.lo = max(select(nearest - half, 0u, half > nearest), lo);
    c.hi = min(nearest + half, hi);
    c.base = base;
    c.x = x;
    var seg = empty_segment();
    c.estimate = entry_at(f, p, base, x, &seg);
    return c;
}

// ---------------------------------------------------------------- the search

struct Point {
    x: f32,
    value: f32,
}

struct Bracket {
    low: Point,
    best: Point,
    high: Point,
}

// Widens a bracket about `start` until the entry rises on both sides (see `widen`):
// one evaluation per step — the first points either side, then doubling steps downhill.
fn widen(f: Frame, p: MillingPass, base: u32, start: Point, lo: f32, hi: f32, seg: ptr<function, Segment>) -> Bracket {
    var low = Point(max(start.x - params.first_bracket, lo), 0.0);
    var best = start;
    var high = Point(min(start.x + params.first_bracket, hi), 0.0);
    var phase = 0u;
    loop {
        var x: f32;
        if phase == 0u {
            x = low.x;
        } else if phase == 1u {
            x = high.x;
        } else if phase == 2u {
            if !(low.value < best.value && low.x > lo) {
                phase = 3u;
                continue;
            }
            x = max(low.x - 2.0 * (best.x - low.x), lo);
        } else {
            if !(high.value < best.value && high.x < hi) {
                break;
            }
            x = min(high.x + 2.0 * (high.x - best.x), hi);
        }
        let value = entry_at(f, p, base, x, seg);
        if phase == 0u {
            low.value = value;
            phase = 1u;
        } else if phase == 1u {
            high.value = value;
            phase = 2u;
        } else if phase == 2u {
            high = best;
            best = low;
            low = Point(x, value);
        } else {
            low = best;
            best = high;
            high = Point(x, value);
        }
    }
    if low.value < best.value {
        high = best;
        best = low;
    } else if high.value < best.value {
        low = best;
        best = high;
    }
    return Bracket(low, best, high);
}

// The coarse scan's bracket (see `scan`): every stride-th node over lo..=hi and the
// points half a node either side of the located one, in order.
fn scan(f: Frame, p: MillingPass, c: Candidate, seg: ptr<function, Segment>) -> Bracket {
    let lo = f32(c.lo) - f32(c.base);
    let hi = f32(c.hi) - f32(c.base);
    var extra = array<f32, 3>(max(c.x - 0.5, lo), c.x, min(c.x + 0.5, hi));
    var best = Point(lo, MISS);
    var before = Point(0.0, 0.0);
    var has_before = false;
    var after = Point(0.0, 0.0);
    var has_after = false;
    var previous = Point(0.0, 0.0);
    var has_previous = false;
    var next_stride = c.lo;
    var stride_done = false;
    var taken = 0u;
    var has_last = false;
    var last_point = 0.0;
    loop {
        let stride_point = f32(next_stride) - f32(c.base);
        var point = 0.0;
        if !stride_done && taken < 3u {
            point = min(stride_point, extra[taken]);
        } else if !stride_done {
            point = stride_point;
        } else if taken < 3u {
            point = extra[taken];
        } else {
            break;
        }
        if !stride_done && stride_point == point {
            if next_stride >= c.hi {
                stride_done = true;
            } else {
                next_stride = min(next_stride + p.stride, c.hi);
            }
        }
        if taken < 3u && extra[taken] == point {
            taken = taken + 1u;
        }
        if has_last && last_point == point {
            continue;
        }
        has_last = true;
        last_point = point;
        var value = 0.0;
        if point == c.x {
            value = c.estimate;
        } else {
            value = entry_at(f, p, c.base, point, seg);
        }
        if value < best.value {
            best = Point(point, value);
            before = previous;
            has_before = has_previous;
            has_after = false;
        } else if !has_after && has_previous && previous.x == best.x {
            after = Point(point, value);
            has_after = true;
        }
        previous = Point(point, value);
        has_previous = true;
    }
    if !has_before {
        before = best;
    }
    if !has_after {
        after = best;
    }
    return Bracket(before, best, after);
}

// Narrows a wide bracket by even points (see `narrow`).
fn narrow(f: Frame, p: MillingPass, base: u32, bracket_in: Bracket, seg: ptr<function, Segment>) -> Bracket {
    var bracket = bracket_in;
    loop {
        if bracket.high.x - bracket.low.x <= NARROW_WIDTH {
            break;
        }
        let low = bracket.low;
        let high = bracket.high;
        let step = (high.x - low.x) / f32(NARROW_STEPS);
        var points: array<Point, 9>;
        points[0] = low;
        for (var k = 1u; k < NARROW_STEPS; k = k + 1u) {
            let u = low.x + f32(k) * step;
            points[k] = Point(u, entry_at(f, p, base, u, seg));
        }
        points[NARROW_STEPS] = high;
        var j = 0u;
        for (var k = 1u; k <= NARROW_STEPS; k = k + 1u) {
            if points[k].value < points[j].value {
                j = k;
            }
        }
        if bracket.best.value < points[j].value {
            // The old best stays, between the points either side of the one nearest it.
            let k = u32(clamp(round((bracket.best.x - low.x) / step), 1.0, f32(NARROW_STEPS - 1u)));
            bracket = Bracket(points[k - 1u], bracket.best, points[k + 1u]);
        } else {
            bracket = Bracket(points[select(j - 1u, 0u, j == 0u)], points[j], points[min(j + 1u, NARROW_STEPS)]);
        }
    }
    return bracket;
}

// The minimum from a bracket (see `refine`): Brent's parabolas, or crossing lines at a
// flat end's kinked rim.
fn refine(f: Frame, p: MillingPass, base: u32, bracket: Bracket, seg: ptr<function, Segment>) -> Point {
    if TOOL_KIND == 2u {
        return kink(f, p, base, bracket, seg);
    }
    return brent(f, p, base, bracket, seg);
}

// Brent's method from a bracket (see `brent`): parabolas through the three best points,
// golden-section steps where one is not trusted, and a stop once a parabola promises
// less than the gain.
fn brent(f: Frame, p: MillingPass, base: u32, bracket: Bracket, seg: ptr<function, Segment>) -> Point {
    var a = bracket.low.x;
    var b = bracket.high.x;
    var x = bracket.best.x;
    var fx = bracket.best.value;
    var w = bracket.low.x;
    var fw = bracket.low.value;
    var v = bracket.high.x;
    var fv = bracket.high.value;
    var e = b - a;
    var d = 0.0;
    let tol = params.refine_width;
    for (var step = 0u; step < params.refine_steps; step = step + 1u) {
        let middle = 0.5 * (a + b);
        if b - a <= 2.0 * tol {
            break;
        }
        var parabolic = false;
        if abs(e) > tol && w != x && v != x && v != w {
            let r = (x - w) * (fx - fv);
            var q = (x - v) * (fx - fw);
            var pp = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                pp = -pp;
            }
            q = abs(q);
            let curvature = 2.0 * ((fw - fx) / (w - x) - (fv - fx) / (v - x)) / (w - v);
            let s = pp / q;
            if curvature > 0.0 && 0.5 * curvature * s * s < params.refine_gain_mm {
                break;
            }
            if abs(pp) < abs(0.5 * q * e) && pp > q * (a - x) && pp < q * (b - x) {
                e = d;
                d = s;
                parabolic = true;
                let u = x + d;
                if u - a < 2.0 * tol || b - u < 2.0 * tol {
                    d = select(-tol, tol, middle - x >= 0.0);
                }
            }
        }
        if !parabolic {
            if x >= middle {
                e = a - x;
            } else {
                e = b - x;
            }
            d = GOLDEN * e;
        }
        var u = x + d;
        if abs(d) < tol {
            u = x + select(-tol, tol, d >= 0.0);
        }
        let fu = entry_at(f, p, base, u, seg);
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            v = w;
            fv = fw;
            w = x;
            fw = fx;
            x = u;
            fx = fu;
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                v = w;
                fv = fw;
                w = u;
                fw = fu;
            } else if fu <= fv || v == x || v == w {
                v = u;
                fv = fu;
            }
        }
    }
    return Point(x, fx);
}

// Where the line through p1, p2 meets the line through p3, p4, when the first falls
// and the second rises, and the gentler slope (see `crossing`); valid = false otherwise.
struct Crossing {
    at: Point,
    // The gentler of the two lines' slopes.
    slope: f32,
    valid: bool,
}

fn crossing(p1: Point, p2: Point, p3: Point, p4: Point) -> Crossing {
    let falling = (p2.value - p1.value) / (p2.x - p1.x);
    let rising = (p4.value - p3.value) / (p4.x - p3.x);
    if !(falling < 0.0 && rising > 0.0) {
        return Crossing(Point(0.0, 0.0), 0.0, false);
    }
    let u = (p3.value - p2.value + falling * p2.x - rising * p3.x) / (falling - rising);
    return Crossing(Point(u, p2.value + falling * (u - p2.x)), min(rising, -falling), true);
}

// The minimum at a kink by crossing secant lines (see `kink`).
fn kink(f: Frame, p: MillingPass, base: u32, bracket: Bracket, seg: ptr<function, Segment>) -> Point {
    let tol = params.refine_width;
    var a = bracket.low;
    var x = bracket.best;
    var b = bracket.high;
    // The next points out on either side.
    var a2 = Point(0.0, 0.0);
    var b2 = Point(0.0, 0.0);
    var has_a2 = false;
    var has_b2 = false;
    var span_before_last = MISS;
    var span_last = MISS;
    for (var step = 0u; step < params.refine_steps; step = step + 1u) {
        let span = b.x - a.x;
        if span <= 2.0 * tol {
            break;
        }
        // Kink right of x: lines (a, x) and (b, b2); left of x: (a2, a) and (x, b).
        var right = Crossing(Point(0.0, 0.0), 0.0, false);
        if has_b2 {
            right = crossing(a, x, b, b2);
            right.valid = right.valid && right.at.x > x.x - tol && right.at.x < b.x;
        }
        var left = Crossing(Point(0.0, 0.0), 0.0, false);
        if has_a2 {
            left = crossing(a2, a, x, b);
            left.valid = left.valid && left.at.x > a.x && left.at.x < x.x + tol;
        }
        var guess = left;
        if right.valid && (!left.valid || right.at.value < left.at.value) {
            guess = right;
        }
        // One case alone meeting at x is the wrong case's signature.
        if !(left.valid && right.valid) && abs(guess.at.x - x.x) < tol && !(has_a2 && has_b2) {
            guess.valid = false;
        }
        var u: f32;
        // At least `margin` from x, while under a quarter of the bracket (see `kink`).
        let margin = max(tol, KINK_NOISE * params.refine_gain_mm / guess.slope);
        if guess.valid && span < 0.5 * span_before_last && span > 4.0 * margin {
            var aim = guess.at.x;
            if abs(guess.at.x - x.x) < margin {
                if guess.at.x > x.x || (guess.at.x == x.x && b.x - x.x > x.x - a.x) {
                    aim = x.x + margin;
                } else {
                    aim = x.x - margin;
                }
            }
            u = clamp(aim, a.x + tol, b.x - tol);
        } else {
            var e = b.x - x.x;
            if x.x >= 0.5 * (a.x + b.x) {
                e = a.x - x.x;
            }
            u = x.x + GOLDEN * e;
        }
        span_before_last = span_last;
        span_last = span;
        let point = Point(u, entry_at(f, p, base, u, seg));
        if point.value <= x.value {
            if u > x.x {
                a2 = a;
                has_a2 = true;
                a = x;
            } else {
                b2 = b;
                has_b2 = true;
                b = x;
            }
            x = point;
        } else if u > x.x {
            b2 = b;
            has_b2 = true;
            b = point;
        } else {
            a2 = a;
            has_a2 = true;
            a = point;
        }
    }
    return x;
}

// Tooth counts at a node: whole + fraction.
fn node_teeth(n: MillingNode) -> vec2<f32> {
    return vec2<f32>(f32(n.teeth_whole), n.teeth_fraction);
}

// The spindle's frame at base + x (see `spindle_frame`): the feed direction across the
// axis, and its right-handed quarter turn.
struct SpindleFrame {
    along: vec3<f32>,
    across: vec3<f32>,
}

fn spindle_frame(f: Frame, p: MillingPass, base: u32, x: f32, axis: vec3<f32>, seg: ptr<function, Segment>) -> SpindleFrame {
    let feed = feed_at(f, p, base, x, seg);
    var along = feed - dot(feed, axis) * axis;
    if dot(along, along) > 0.0 {
        along = normalize(along);
    } else {
        // Any unit vector across the axis (glam's any_orthonormal_vector).
        let w = axis;
        let sgn = select(-1.0, 1.0, w.z >= 0.0);
        let aa = -1.0 / (sgn + w.z);
        let bb = w.x * w.y * aa;
        along = vec3<f32>(1.0 + sgn * w.x * w.x * aa, sgn * bb, -sgn * w.x);
    }
    return SpindleFrame(along, cross(axis, along));
}

// The pose of stamp k at base + x, its centre moved by tooth k mod z's displacement
// turned by `turn` (see `stamp_pose`).
fn stamp_pose(f: Frame, p: MillingPass, base: u32, x: f32, k: i32, turn: f32, seg: ptr<function, Segment>) -> Pose {
    var pose = pose_at(f, p, base, x, seg);
    if params.offset_count == 0u {
        return pose;
    }
    let count = i32(params.offset_count);
    let offset = teeth_table[u32(((k % count) + count) % count)].xy;
    let c = cos(turn);
    let s = sin(turn);
    let turned = vec2<f32>(c * offset.x - s * offset.y, s * offset.x + c * offset.y);
    let frame = spindle_frame(f, p, base, x, pose.axis, seg);
    pose.offset = pose.offset + turned.x * frame.along + turned.y * frame.across;
    return pose;
}

struct Cut {
    depth_mm: f32,
    valid: bool,
}

// The node coordinate (relative to `base`) where a pass's tooth count is k + σ, the
// segment walked to from `*segment` (see `StampWalker::node_at`).
fn node_at_teeth(p: MillingPass, base: u32, k: i32, sigma: f32, segment: ptr<function, u32>) -> f32 {
    let last = p.node_count - 1u;
    // count(node) − (k + σ), from the whole and fraction parts without rounding k away.
    loop {
        if *segment == 0u {
            break;
        }
        let t = node_teeth(nodes[p.first_node + *segment]);
        if ((t.x - f32(k)) + t.y) - sigma <= 0.0 {
            break;
        }
        *segment = *segment - 1u;
    }
    loop {
        if *segment + 1u >= last {
            break;
        }
        let t = node_teeth(nodes[p.first_node + *segment + 1u]);
        if ((t.x - f32(k)) + t.y) - sigma >= 0.0 {
            break;
        }
        *segment = *segment + 1u;
    }
    let na = node_teeth(nodes[p.first_node + *segment]);
    let nb = node_teeth(nodes[p.first_node + min(*segment + 1u, last)]);
    let span = (nb.x - na.x) + (nb.y - na.y);
    var t = 0.0;
    if span > 0.0 {
        t = clamp((((f32(k) - na.x) - na.y) + sigma) / span, 0.0, 1.0);
    }
    return f32(*segment) - f32(base) + t;
}

// Stamp k's tooth at tooth count k + σ (see `ToothEdge::phase`): its cut, the entry's
// angle ψ about the axis and lag − turn.
struct Phase {
    depth_mm: f32,
    psi: f32,
    rest: f32,
}

fn edge_phase(f: Frame, p: MillingPass, base: u32, k: i32, sigma: f32, segment: ptr<function, u32>, seg: ptr<function, Segment>) -> Phase {
    let count = i32(params.teeth);
    let tooth = teeth_table[u32(((k % count) + count) % count)];
    let x = node_at_teeth(p, base, k, sigma, segment);
    let turn = TAU * sigma / f32(params.teeth);
    var pose = stamp_pose(f, p, base, x, k, turn, seg);
    pose.offset = pose.offset - tooth.w * pose.axis;
    let depth = tooth_entry(f, pose, params.major_radius_mm + tooth.z);
    let frame = spindle_frame(f, p, base, x, pose.axis, seg);
    let entry = depth * f.normal - pose_centre(f, pose);
    var tip = params.corner_radius_mm;
    if TOOL_KIND == 3u {
        tip = 0.0;
    }
    let lag = params.lag_per_mm * (dot(entry, pose.axis) + tip);
    return Phase(depth, atan2(dot(entry, frame.across), dot(entry, frame.along)), lag - turn);
}

// A swing of ψ unwrapped (see `unwrap_step`).
fn unwrap_step(step_in: f32, side: f32) -> f32 {
    let a = step_in + PI;
    let step = a - TAU * floor(a / TAU) - PI;
    if abs(step) > EDGE_SWING {
        return abs(step) * side;
    }
    return step;
}

// A phase at σ with ψ unwrapped along a scan (see `Turned`).
struct Turned {
    sigma: f32,
    phase: Phase,
    turned: f32,
}

fn turned_next(t: Turned, sigma: f32, ph: Phase, side: f32) -> Turned {
    return Turned(sigma, ph, t.turned + unwrap_step(ph.psi - t.phase.psi, side));
}

fn turned_g(t: Turned) -> f32 {
    return t.turned + t.phase.rest;
}

// The pass of the edge where G crosses `level` between two scan points (see
// `ToothEdge::pass_at`).
fn edge_pass_at(f: Frame, p: MillingPass, base: u32, k: i32, low: Turned, high: Turned, level: f32, side: f32, segment: ptr<function, u32>, seg: ptr<function, Segment>) -> f32 {
    var a = low;
    var b = high;
    var fa = turned_g(a) - level;
    var fb = turned_g(b) - level;
    var depth = select(b.phase.depth_mm, a.phase.depth_mm, abs(fa) < abs(fb));
    var span_before_last = MISS;
    var span_last = MISS;
    for (var step = 0u; step < EDGE_BRACKET_STEPS; step = step + 1u) {
        let span = abs(b.sigma - a.sigma);
        if min(abs(fa), abs(fb)) <= params.edge_tolerance_rad || span <= params.edge_width || fa == fb {
            break;
        }
        var sigma = 0.5 * (a.sigma + b.sigma);
        if span < 0.5 * span_before_last {
            sigma = (a.sigma * fb - b.sigma * fa) / (fb - fa);
        }
        span_before_last = span_last;
        span_last = span;
        let c = turned_next(a, sigma, edge_phase(f, p, base, k, sigma, segment, seg), side);
        let fc = turned_g(c) - level;
        depth = c.phase.depth_mm;
        if fc * fb < 0.0 {
            a = b;
            fa = fb;
        } else {
            fa = 0.5 * fa;
        }
        b = c;
        fb = fc;
    }
    return depth;
}

// Where a sample lies from the path (see `Scan`).
struct Scan {
    side: f32,
    on_path: bool,
    // The tooth count abeam, as whole + fraction.
    abeam_whole: i32,
    abeam_fraction: f32,
}

// The scan's point i (see `edge_cut`): a step apart, off the stamp by a golden fraction.
fn scan_at(i: u32) -> f32 {
    let z = f32(params.teeth);
    return -0.5 * z + (f32(i) - 1.0 + GOLDEN) * z / f32(EDGE_SCAN);
}

// Stamp k's tooth as its edge: its lowest cut where the edge passes the sample (see
// `edge_cut`).
fn edge_cut(f: Frame, p: MillingPass, base: u32, k: i32, scan: Scan, segment: ptr<function, u32>, seg: ptr<function, Segment>) -> f32 {
    let z = f32(params.teeth);
    // The scan's extra points (see `edge_cut`), sorted, those in its range.
    let abeam = f32(scan.abeam_whole - k) + scan.abeam_fraction;
    var extra = array<f32, 5>(abeam - EDGE_ABEAM, abeam + EDGE_ABEAM, -0.5 * z, 0.0, 0.5 * z);
    for (var a = 1u; a < 5u; a = a + 1u) {
        var b = a;
        loop {
            if b == 0u || extra[b - 1u] <= extra[b] {
                break;
            }
            let t = extra[b];
            extra[b] = extra[b - 1u];
            extra[b - 1u] = t;
            b = b - 1u;
        }
    }
    var extra_next = 0u;
    loop {
        if extra_next >= 5u || extra[extra_next] >= scan_at(0u) {
            break;
        }
        extra_next = extra_next + 1u;
    }
    var extra_end = extra_next;
    loop {
        if extra_end >= 5u || extra[extra_end] >= scan_at(EDGE_SCAN + 1u) {
            break;
        }
        extra_end = extra_end + 1u;
    }
    var regular_next = 0u;
    // The first point.
    var first = scan_at(0u);
    if extra_next < extra_end && extra[extra_next] < first {
        first = extra[extra_next];
        extra_next = extra_next + 1u;
    } else {
        regular_next = 1u;
    }
    var low = Turned(first, edge_phase(f, p, base, k, first, segment, seg), 0.0);
    low.turned = low.phase.psi;
    // No pass in the window: no cut.
    var best = MISS;
    loop {
        var sigma: f32;
        let regular_left = regular_next <= EDGE_SCAN + 1u;
        let extra_left = extra_next < extra_end;
        if !regular_left && !extra_left {
            break;
        }
        if extra_left && (!regular_left || extra[extra_next] < scan_at(regular_next)) {
            sigma = extra[extra_next];
            extra_next = extra_next + 1u;
        } else {
            sigma = scan_at(regular_next);
            regular_next = regular_next + 1u;
        }
        let high = turned_next(low, sigma, edge_phase(f, p, base, k, sigma, segment, seg), scan.side);
        best = min(best, edge_passes_between(f, p, base, k, low, high, scan.side, segment, seg));
        // On the path the half-turn swing has no side: the other way round too.
        if scan.on_path && abs(high.turned - low.turned) > EDGE_SWING {
            var other = high;
            other.turned = high.turned - TAU * scan.side;
            best = min(best, edge_passes_between(f, p, base, k, low, other, -scan.side, segment, seg));
        }
        low = high;
    }
    return best;
}

// The lowest of the edge's passes between two scan points (see
// `ToothEdge::passes_between`); MISS: none.
fn edge_passes_between(f: Frame, p: MillingPass, base: u32, k: i32, low: Turned, high: Turned, side: f32, segment: ptr<function, u32>, seg: ptr<function, Segment>) -> f32 {
    let g_low = turned_g(low);
    let g_high = turned_g(high);
    var best = MISS;
    var level = ceil(min(g_low, g_high) / TAU) * TAU;
    loop {
        if level > max(g_low, g_high) {
            break;
        }
        best = min(best, edge_pass_at(f, p, base, k, low, high, level, side, segment, seg));
        level = level + TAU;
    }
    return best;
}

// Where the sample lies from the path at the pass's continuous optimum base + x (see
// `scan_frame`).
fn scan_frame(f: Frame, p: MillingPass, base: u32, x: f32, seg: ptr<function, Segment>) -> Scan {
    let pose = pose_at(f, p, base, x, seg);
    let depth = extended_entry(f, pose);
    let entry = depth * f.normal - pose_centre(f, pose);
    let radial = entry - dot(entry, pose.axis) * pose.axis;
    let frame = spindle_frame(f, p, base, x, pose.axis, seg);
    let last = p.node_count - 1u;
    let s = segment_at(p, base, x);
    let ta = node_teeth(nodes[p.first_node + s.index]);
    let tb = node_teeth(nodes[p.first_node + min(s.index + 1u, last)]);
    // Abeam: the optimum moved by the sample's lead over the axis.
    let ahead = dot(radial, frame.along) / params.feed_per_tooth_mm;
    let local = ta.y + s.t * ((tb.x - ta.x) + (tb.y - ta.y)) + ahead;
    return Scan(
        select(1.0, -1.0, dot(radial, frame.across) < 0.0),
        length(radial) < EDGE_ON_PATH_MM,
        i32(ta.x) + i32(floor(local)),
        local - floor(local),
    );
}

// The lowest cut of the stamps around base + x (see `stamp_cut`).
fn stamp_cut(f: Frame, p: MillingPass, c: Candidate, x: f32, seg: ptr<function, Segment>) -> Cut {
    let last = p.node_count - 1u;
    let s = segment_at(p, c.base, x);
    let ta = node_teeth(nodes[p.first_node + s.index]);
    let tb = node_teeth(nodes[p.first_node + min(s.index + 1u, last)]);
    // teeth(x) = whole_a + (frac_a + t·(Δwhole + Δfrac)).
    let local = ta.y + s.t * ((tb.x - ta.x) + (tb.y - ta.y));
    let nearest = i32(ta.x) + i32(floor(local));
    let first_node = node_teeth(nodes[p.first_node]);
    let last_node = node_teeth(nodes[p.first_node + last]);
    let first_stamp = i32(first_node.x) + i32(ceil(first_node.y));
    let last_stamp = i32(last_node.x) + i32(floor(last_node.y));
    var from_k = nearest - 1;
    var to_k = nearest + 2;
    if STAMP_MODE == 2u {
        let lo_t = node_teeth(nodes[p.first_node + c.lo]);
        let hi_t = node_teeth(nodes[p.first_node + c.hi]);
        from_k = i32(lo_t.x) + i32(ceil(lo_t.y));
        to_k = i32(hi_t.x) + i32(floor(hi_t.y));
    }
    var best = Cut(params.stock_top_mm, false);
    var segment = s.index;
    if STAMP_MODE == 3u {
        // Teeth as edges (see `edges_cut`): stamps outward from the optimum, each way
        // until the body at the nearest position a stamp's window reaches, less the
        // teeth's reach beyond it, lies no lower than the best cut.
        let scan = scan_frame(f, p, c.base, x, seg);
        let half = 0.5 * f32(params.teeth);
        for (var way = 0; way < 2; way = way + 1) {
            var step = 1;
            var k = nearest;
            if way == 1 {
                step = -1;
                k = nearest - 1;
            }
            loop {
                if k < first_stamp || k > last_stamp {
                    break;
                }
                let towards = clamp(f32(nearest - k) + (local - floor(local)), -half, half);
                let bx = node_at_teeth(p, c.base, k, towards, &segment);
                let bound = extended_entry(f, pose_at(f, p, c.base, bx, seg)) - params.edge_reach_mm;
                if bound >= best.depth_mm {
                    break;
                }
                let depth = edge_cut(f, p, c.base, k, scan, &segment, seg);
                if depth < params.stock_top_mm && (!best.valid || depth < best.depth_mm) {
                    best = Cut(depth, true);
                }
                k = k + step;
            }
        }
        return best;
    }
    for (var k = max(from_k, first_stamp); k <= min(to_k, last_stamp); k = k + 1) {
        let sx = node_at_teeth(p, c.base, k, 0.0, &segment);
        let depth = extended_entry(f, stamp_pose(f, p, c.base, sx, k, 0.0, seg));
        if depth < params.stock_top_mm && (!best.valid || depth < best.depth_mm) {
            best = Cut(depth, true);
        }
    }
    return best;
}

// The lowest cut of a located pass (see `pass_cut`).
fn pass_cut(f: Frame, c: Candidate) -> Cut {
    let p = passes[c.pass_index];
    let lo = f32(c.lo) - f32(c.base);
    let hi = f32(c.hi) - f32(c.base);
    var seg = empty_segment();
    let single_valley = TOOL_KIND <= 2u && (p.polar == 0u || (hi - lo) * abs(p.step_y) < 0.5 * PI);
    var bracket: Bracket;
    if single_valley {
        bracket = widen(f, p, c.base, Point(c.x, c.estimate), lo, hi, &seg);
    } else {
        bracket = scan(f, p, c, &seg);
    }
    var best = bracket.best;
    if STAMP_MODE != 2u {
        if !single_valley {
            bracket = narrow(f, p, c.base, bracket, &seg);
        }
        best = refine(f, p, c.base, bracket, &seg);
    }
    if STAMP_MODE != 0u {
        return stamp_cut(f, p, c, best.x, &seg);
    }
    return Cut(best.value, best.value < params.stock_top_mm);
}

struct Best {
    depth_mm: f32,
    pass_id: u32,
}

fn offer(best: Best, cut: Cut, pass_index: u32) -> Best {
    if cut.valid && (cut.depth_mm < best.depth_mm - params.tie_mm || (cut.depth_mm < best.depth_mm + params.tie_mm && pass_index < best.pass_id)) {
        return Best(cut.depth_mm, pass_index);
    }
    return best;
}

// Whether a run of nodes can cut the sample: its box within reach of the expected centre.
fn run_in_reach(f: Frame, run: MillingRun) -> bool {
    let expected = expected_centre(f.world_point, f.world_normal, vec3<f32>(run.axis_x, run.axis_y, run.axis_z));
    return run_distance(run, expected.centre) <= expected.radius;
}

// The bin cells around the sample's core point: low corner, high corner (inclusive).
struct CellRange {
    low: vec3<i32>,
    high: vec3<i32>,
}

fn cells_around(f: Frame) -> CellRange {
    let core = f.world_point + params.centre_offset_mm * f.world_normal;
    let origin = vec3<f32>(params.origin_x, params.origin_y, params.origin_z);
    let cell = floor((core - origin) / params.cell_mm);
    let size = vec3<f32>(f32(params.cells_x), f32(params.cells_y), f32(params.cells_z));
    return CellRange(vec3<i32>(max(cell - 1.0, vec3<f32>(0.0))), vec3<i32>(min(cell + 1.0, size - 1.0)));
}

fn cell_index(x: i32, y: i32, z: i32) -> u32 {
    return (u32(z) * params.cells_y + u32(y)) * params.cells_x + u32(x);
}

@compute @workgroup_size(64)
fn remove_milling(@builtin(global_invocation_id) id: vec3<u32>) {
    let local_index = id.x + id.y * params.dispatch_width;
    if local_index >= params.sample_count {
        return;
    }
    let sample = params.sample_offset + local_index;
    let f = make_frame(rings[sample % params.ring_count], rows[sample / params.ring_count]);
    var best = Best(params.stock_top_mm, NO_PASS);
    let cells = cells_around(f);
    let span = cells.high - cells.low + vec3<i32>(1);
    let cell_count = u32(max(span.x * span.y * span.z, 0));

    // Batches of candidates. The first: the runs in reach in the 3 × 3 × 3 cells around
    // the core point, merged per pass (the first MAX_CANDIDATES passes). Later ones, if
    // there are more passes: their runs one by one, from where the last batch stopped.
    var c_pass: array<u32, MAX_CANDIDATES>;
    var c_first: array<u32, MAX_CANDIDATES>;
    var c_last: array<u32, MAX_CANDIDATES>;
    var c_lo: array<u32, MAX_CANDIDATES>;
    var c_hi: array<u32, MAX_CANDIDATES>;
    var c_base: array<u32, MAX_CANDIDATES>;
    var c_x: array<f32, MAX_CANDIDATES>;
    var c_estimate: array<f32, MAX_CANDIDATES>;
    var listed: array<u32, MAX_CANDIDATES>;
    var listed_count = 0u;
    var first_batch = true;
    var resume_cell = 0u;
    var resume_run = 0u;
    loop {
        var count = 0u;
        var more = false;
        var cell = resume_cell;
        var r = resume_run;
        loop {
            if cell >= cell_count || (more && !first_batch) {
                break;
            }
            let index = cell_index(
                cells.low.x + i32(cell % u32(span.x)),
                cells.low.y + i32((cell / u32(span.x)) % u32(span.y)),
                cells.low.z + i32(cell / u32(span.x * span.y)),
            );
            r = max(r, cell_start[index]);
            if r >= cell_start[index + 1u] {
                cell = cell + 1u;
                r = 0u;
                continue;
            }
            let run = runs[r];
            r = r + 1u;
            if !run_in_reach(f, run) {
                continue;
            }
            var k = 0u;
            loop {
                if k >= listed_count || listed[k] == run.pass_index {
                    break;
                }
                k = k + 1u;
            }
            if first_batch && k < listed_count {
                c_first[k] = min(c_first[k], run.first);
                c_last[k] = max(c_last[k], run.last);
            } else if first_batch && listed_count < MAX_CANDIDATES {
                listed[listed_count] = run.pass_index;
                c_pass[count] = run.pass_index;
                c_first[count] = run.first;
                c_last[count] = run.last;
                listed_count = listed_count + 1u;
                count = count + 1u;
            } else if first_batch {
                // A pass beyond the list: the next batches take it.
                more = true;
            } else if k >= listed_count {
                c_pass[count] = run.pass_index;
                c_first[count] = run.first;
                c_last[count] = run.last;
                count = count + 1u;
                if count == MAX_CANDIDATES {
                    more = true;
                }
            }
        }
        if first_batch {
            // The later batches begin again from the first cell.
            resume_cell = 0u;
            resume_run = 0u;
        } else {
            resume_cell = cell;
            resume_run = r;
        }

        // Locate each (an estimate of its cut), then search them lowest estimate first.
        for (var k = 0u; k < count; k = k + 1u) {
            let located = locate(f, Candidate(c_pass[k], c_first[k], c_last[k], 0u, 0u, 0u, 0.0, 0.0));
            c_lo[k] = located.lo;
            c_hi[k] = located.hi;
            c_base[k] = located.base;
            c_x[k] = located.x;
            c_estimate[k] = located.estimate;
        }
        var done = 0u;
        for (var round = 0u; round < count; round = round + 1u) {
            var k = MAX_CANDIDATES;
            for (var i = 0u; i < count; i = i + 1u) {
                if (done & (1u << i)) == 0u && (k == MAX_CANDIDATES || c_estimate[i] < c_estimate[k] || (c_estimate[i] == c_estimate[k] && c_pass[i] < c_pass[k])) {
                    k = i;
                }
            }
            done = done | (1u << k);
            if TOOL_KIND == 0u {
                // A ball: the rest cannot cut deeper than the best.
                let spacing = passes[c_pass[k]].spacing_mm;
                let room = params.slack_per_spacing_squared * spacing * spacing + params.slack_displacement_mm;
                if c_estimate[k] - room >= best.depth_mm {
                    break;
                }
            }
            let c = Candidate(c_pass[k], c_first[k], c_last[k], c_lo[k], c_hi[k], c_base[k], c_x[k], c_estimate[k]);
            best = offer(best, pass_cut(f, c), c.pass_index);
        }
        if !more {
            break;
        }
        first_batch = false;
    }
    dexels[local_index] = Dexel(best.depth_mm, best.pass_id);
}

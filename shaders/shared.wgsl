// Declarations every removal kernel shares, prepended to each kernel's source by
// src/engine/gpu.rs (WGSL has no include). Their Rust twins: `layout::Dexel` and the
// constants named in tests/shaders.rs, which checks that both sides agree.

// A sample no pass reached (`field::NO_PASS`).
const NO_PASS: u32 = 0xffffffffu;
// Turning pass ids: rev · PASS_ID_STRIDE + branch (`scene::PASS_ID_STRIDE`).
const PASS_ID_STRIDE: u32 = 4u;
// Generating: contacts per ring and tooth passes around each
// (`generating_scene::MAX_CONTACTS`, `PASSES_PER_CONTACT`).
const MAX_CONTACTS: u32 = 2u;
const PASSES_PER_CONTACT: i32 = 4;
// Milling: candidate passes a sample ranks (`milling_scene::MAX_CANDIDATES`).
const MAX_CANDIDATES: u32 = 16u;
// … and the narrowing of a wide bracket (`milling_search::NARROW_WIDTH`, `NARROW_STEPS`).
const NARROW_WIDTH: f32 = 4.0;
const NARROW_STEPS: u32 = 8u;
// … and a golden-section step's share of a bracket (`milling_search::GOLDEN`).
const GOLDEN: f32 = 0.3819660112501051;
// … and how many times the entries' rounding a crossing-lines step keeps clear of
// (`milling_search::KINK_NOISE`).
const KINK_NOISE: f32 = 16.0;
// Teeth as edges (`cpu_milling::EDGE_SCAN`, `EDGE_BRACKET_STEPS`, `EDGE_ABEAM`,
// `EDGE_SWING`, `EDGE_ON_PATH_MM`).
const EDGE_SCAN: u32 = 8u;
const EDGE_BRACKET_STEPS: u32 = 40u;
const EDGE_ABEAM: f32 = 0.001;
const EDGE_SWING: f32 = 2.356194490192345;
const EDGE_ON_PATH_MM: f32 = 0.000001;

const TAU: f32 = 6.283185307179586;
const PI: f32 = 3.141592653589793;
const MISS: f32 = 3.0e38;

// One sample's result: its depth along the normal and the pass that left it.
struct Dexel {
    depth_mm: f32,
    pass_id: u32,
}

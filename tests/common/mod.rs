//! Shared helpers for the integration tests.
#![allow(dead_code)]

use toolmark::engine::cpu::CpuEngine;
use toolmark::engine::gpu::GpuEngine;
use toolmark::model::{Job, JobFile, MillingSpec, ProcessSpec, SurfaceSpec, ToolSpec};
use toolmark::pipeline::{RunResult, simulate};
use toolmark::process::MillingPathKind;

/// The GPU engine, or a failing test: in CI a missing adapter is an error, never a skip.
pub fn gpu_engine() -> GpuEngine {
    match GpuEngine::new() {
        Ok(engine) => engine,
        Err(err) => panic!(
            "GPU tests need a wgpu adapter (CI uses Mesa lavapipe: apt-get install mesa-vulkan-drivers): {err}"
        ),
    }
}

pub fn job(toml: &str) -> Job {
    Job::from_toml_str(toml, "test").unwrap_or_else(|err| panic!("test job invalid: {err}"))
}

pub fn example(name: &str) -> Job {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name);
    Job::load(&path).unwrap_or_else(|err| panic!("{name}: {err}"))
}

/// An example job's file, to change in Rust before checking it with [`in_examples`].
pub fn example_file(name: &str) -> JobFile {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|err| panic!("{name}: {err}"));
    JobFile::from_toml_str(&text).unwrap_or_else(|err| panic!("{name}: {err}"))
}

/// A job file checked as if it lay in `examples/` (its file names resolve there).
pub fn in_examples(file: JobFile) -> Job {
    let examples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    Job::from_file(file, "test", &examples).unwrap_or_else(|err| panic!("test job invalid: {err}"))
}

/// A job built in Rust, checked (a test's own job: it must be valid).
pub fn checked(file: JobFile) -> Job {
    Job::from_file(file, "test", std::path::Path::new("."))
        .unwrap_or_else(|err| panic!("test job invalid: {err}"))
}

/// Seed 002's asphere (R0 5.5 mm, k −0.7, A2 0.000284, Ø20 mm, convex): the default
/// job's surface.
pub fn seed_002_asphere() -> SurfaceSpec {
    example_file("asphere_xz.toml").surface
}

/// A milling job's file on a grid of `pitch_um` and `azimuths`.
pub fn milling_file(
    surface: SurfaceSpec,
    tool: ToolSpec,
    process: MillingSpec,
    pitch_um: f64,
    azimuths: u32,
) -> JobFile {
    JobFile::new(surface, tool, ProcessSpec::Milling(process)).grid(pitch_um, azimuths)
}

/// A path of passes `stepover_mm` apart over stock `stock_mm` high.
pub fn stepped(path: MillingPathKind, stepover_mm: f64, stock_mm: f64) -> MillingSpec {
    MillingSpec {
        stock_allowance_mm: Some(stock_mm),
        ..MillingSpec::stepped(path, stepover_mm)
    }
}

pub fn run_cpu(job: Job) -> RunResult {
    simulate(job, &mut CpuEngine, &|_, _| {}).expect("CPU engine run")
}

pub fn run_gpu(job: Job) -> RunResult {
    simulate(job, &mut gpu_engine(), &|_, _| {}).expect("GPU engine run")
}

/// Runs `job` on both engines and asserts the GPU's field matches the CPU's sample by
/// sample: max |Δ depth| ≤ max(0.5 nm, 0.1 % of the CPU map's PV) (DESIGN §5, issue
/// 14), and at most 0.1 % of the samples cut by one engine only (an entry within f32
/// rounding of the stock top; the depth bound holds there too). Returns the max
/// difference (nm) and the bound.
pub fn assert_engines_agree(name: &str, job: Job) -> (f64, f64) {
    use toolmark::field::NO_PASS;
    let cpu = run_cpu(job.clone());
    let gpu = run_gpu(job);
    let (mut worst, mut at) = (0.0f64, 0);
    for (i, (a, b)) in cpu
        .field
        .depth_mm
        .iter()
        .zip(&gpu.field.depth_mm)
        .enumerate()
    {
        let difference = (a - b).abs();
        if difference > worst || difference.is_nan() {
            (worst, at) = (
                if difference.is_nan() {
                    f64::INFINITY
                } else {
                    difference
                },
                i,
            );
        }
    }
    let worst_nm = worst * 1e6;
    let bound_nm = (0.001 * cpu.deviation.pv_nm).max(0.5);
    let rings = cpu.grid().ring_count();
    let same_pass = cpu
        .field
        .pass
        .iter()
        .zip(&gpu.field.pass)
        .filter(|(a, b)| a == b)
        .count();
    let cut_differs = cpu
        .field
        .pass
        .iter()
        .zip(&gpu.field.pass)
        .filter(|(a, b)| (**a == NO_PASS) != (**b == NO_PASS))
        .count();
    println!(
        "{name}: {} samples, PV {:.3} nm; max |GPU − CPU| = {worst_nm:.4} nm at ring {} row {} (bound {bound_nm:.3} nm); same winning pass at {:.3} % of samples; {cut_differs} samples cut by one engine only",
        cpu.field.depth_mm.len(),
        cpu.deviation.pv_nm,
        at % rings,
        at / rings,
        100.0 * same_pass as f64 / cpu.field.pass.len() as f64
    );
    assert!(
        worst_nm <= bound_nm,
        "{name}: GPU differs from CPU by {worst_nm} nm > {bound_nm} nm"
    );
    assert!(
        cut_differs * 1000 <= cpu.field.pass.len(),
        "{name}: {cut_differs} samples differ in being cut"
    );
    (worst_nm, bound_nm)
}

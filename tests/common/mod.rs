//! Shared helpers for the integration tests.
#![allow(dead_code)]

use toolmark::engine::cpu::CpuEngine;
use toolmark::engine::gpu::GpuEngine;
use toolmark::io::job::Job;
use toolmark::run::{RunResult, simulate};

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

pub fn run_cpu(job: Job) -> RunResult {
    simulate(job, &mut CpuEngine, &|_, _| {}).expect("CPU engine run")
}

pub fn run_gpu(job: Job) -> RunResult {
    simulate(job, &mut gpu_engine(), &|_, _| {}).expect("GPU engine run")
}

/// A turning job on a given surface table, with the common tool/process/grid keys.
pub fn turning_job(
    surface: &str,
    tool_radius_mm: f64,
    feed_mm: f64,
    extra_process: &str,
    grid: &str,
) -> Job {
    job(&format!(
        r#"version = 1
[surface]
{surface}
[tool]
kind = "arc_nose"
nose_radius_mm = {tool_radius_mm}
included_angle_deg = 160.0
[process]
kind = "turning"
feed_per_rev_mm = {feed_mm}
{extra_process}
[grid]
{grid}
"#
    ))
}

//! `toolmark bench`: throughput of the removal engines in dexel–pass evaluations per
//! second, wall time of the default job, the scaling check (a 10× longer spiral over a
//! 10× wider part at the same feed and pitch must cost about the same per dexel), and
//! a grid larger than one 128 MiB storage binding (tiled on the GPU).
//! Numbers are printed, never asserted: timings don't belong in tests.

use crate::engine::RemovalEngine;
use crate::engine::cpu::CpuEngine;
use crate::engine::gpu::GpuEngine;
use crate::io::job::Job;
use crate::run::{prepare_scenes, remove_all, simulate};
use std::time::Instant;

/// A flat facing job of the given aperture radius (mm) used for scaling and tiling.
pub fn facing_job(radius_mm: f64, feed_mm: f64, pitch_um: f64, azimuths: u32) -> Job {
    let text = format!(
        r#"version = 1
name = "bench facing r{radius_mm}"
[surface]
kind = "plane"
aperture_diameter_mm = {diameter}
[tool]
kind = "arc_nose"
nose_radius_mm = 0.5
included_angle_deg = 120.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = {feed_mm}
[grid]
pitch_um = {pitch_um}
azimuths = {azimuths}
"#,
        diameter = 2.0 * radius_mm
    );
    Job::from_toml_str(&text, "bench").expect("the bench job is valid")
}

/// The generating benchmark: a toothed wheel, where every sample solves its passes.
fn generating_teeth_job() -> Job {
    let text = r#"version = 1
name = "bench generating teeth"
[surface]
kind = "sphere"
form = "concave"
radius_mm = 53.5
aperture_diameter_mm = 6.0
[tool]
kind = "cup_wheel"
cutting_radius_mm = 3.5
edge_radius_mm = 0.5
teeth = 6
[process]
kind = "generating"
tool_rpm = 1000.0
workpiece_rpm = 10.0
spark_out_revolutions = 1.5
[grid]
pitch_um = 5.0
azimuths = 4096
"#;
    Job::from_toml_str(text, "bench").expect("the bench job is valid")
}

/// The milling benchmark, every tool: a ball on a spiral (the early stop of the pass
/// ranking), a five-axis bull-nose and flat end (every candidate pass searched, kinked
/// entries), a disc, and a two-flute ball's feed marks with its teeth as edges and as
/// bodies.
fn milling_cases() -> Vec<(&'static str, String)> {
    let feed_marks = include_str!("../examples/milling_ball_feed_marks.toml");
    vec![
        (
            "Ø1 ball, constant-scallop spiral on the seed-002 asphere",
            include_str!("../examples/milling_asphere_constant_scallop.toml").into(),
        ),
        (
            "Ø8 bull-nose, 5-axis raster in a concave sphere",
            include_str!("../examples/milling_bull_nose_concave_5axis.toml").into(),
        ),
        (
            "Ø6 flat end, 5-axis raster on a convex sphere",
            include_str!("../examples/milling_flat_end_5axis.toml").into(),
        ),
        (
            "Ø30 disc, oblique raster on a convex sphere",
            include_str!("../examples/milling_disc_oblique.toml").into(),
        ),
        (
            "Ø2 ball, 2 teeth at 0.05 mm as edges (feed-marks example)",
            feed_marks.into(),
        ),
        (
            "same, teeth as bodies",
            feed_marks.replace("teeth = 2", "teeth = 2\nflutes = \"body\""),
        ),
    ]
}

struct Measurement {
    seconds: f64,
    samples: u64,
    pairs: u64,
}

/// Times the removal stage alone (scene prepared beforehand, outputs not written).
fn time_removal(engine: &mut dyn RemovalEngine, job: &Job) -> Result<Measurement, String> {
    let scenes = prepare_scenes(job);
    let started = Instant::now();
    remove_all(&scenes, engine, &|_, _| {}).map_err(|e| e.to_string())?;
    Ok(Measurement {
        seconds: started.elapsed().as_secs_f64(),
        samples: scenes[0].grid().sample_count() as u64,
        pairs: scenes.iter().map(|s| s.pair_count()).sum(),
    })
}

fn processor_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|line| line.starts_with("model name"))
                .and_then(|line| line.split(':').nth(1))
                .map(|name| name.trim().to_string())
        })
        .unwrap_or_else(|| "unknown processor".into())
}

pub fn run_benchmarks(cpu: bool, gpu: bool, large: bool) -> Result<(), String> {
    let mut engines: Vec<Box<dyn RemovalEngine>> = Vec::new();
    if cpu {
        engines.push(Box::new(CpuEngine));
    }
    if gpu {
        engines.push(Box::new(GpuEngine::new().map_err(|e| e.to_string())?));
    }
    println!(
        "host: {} ({} threads)",
        processor_name(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    for engine in &engines {
        let info = engine.info();
        println!(
            "{}: {} [{} {}] {}",
            info.kind, info.adapter, info.backend, info.device_type, info.driver
        );
    }

    println!("\n## default job (seed-002 asphere, XZ), whole pipeline without file output");
    println!("| engine | samples | pairs | removal s | pairs/s | wall s |");
    println!("| --- | --- | --- | --- | --- | --- |");
    for engine in engines.iter_mut() {
        let started = Instant::now();
        let result =
            simulate(Job::default_job(), engine.as_mut(), &|_, _| {}).map_err(|e| e.to_string())?;
        let wall = started.elapsed().as_secs_f64();
        let pairs = result.pair_count();
        println!(
            "| {} | {} | {:.3e} | {:.3} | {:.3e} | {:.3} |",
            result.engine.kind,
            result.grid().sample_count(),
            pairs as f64,
            result.timings.removal_s,
            pairs as f64 / result.timings.removal_s,
            wall
        );
    }

    println!(
        "\n## scaling: flat facing, feed 10 µm, pitch 1 µm, 16 azimuths; aperture ×10 → spiral ×10"
    );
    println!(
        "| engine | radius mm | revolutions | samples | pairs/sample | removal s | µs per dexel | ratio |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for engine in engines.iter_mut() {
        let mut first = None;
        for radius in [1.0, 10.0] {
            let job = facing_job(radius, 0.01, 1.0, 16);
            let m = time_removal(engine.as_mut(), &job)?;
            let per_dexel = m.seconds / m.samples as f64 * 1e6;
            let ratio = per_dexel / *first.get_or_insert(per_dexel);
            println!(
                "| {} | {radius} | {:.0} | {} | {:.1} | {:.3} | {:.3} | {ratio:.2} |",
                engine.info().kind,
                radius / 0.01,
                m.samples,
                m.pairs as f64 / m.samples as f64,
                m.seconds,
                per_dexel
            );
        }
    }

    println!(
        "\n## generating with teeth: seed-000 wheel (R_t 3.5 mm, r 0.5 mm, 6 teeth, 1000 rpm on a part at 10 rpm), Ø6 mm, 5 µm × 4096 azimuths"
    );
    println!("| engine | samples | pass evaluations | removal s | evaluations/s | ns per sample |");
    println!("| --- | --- | --- | --- | --- | --- |");
    for engine in engines.iter_mut() {
        let m = time_removal(engine.as_mut(), &generating_teeth_job())?;
        println!(
            "| {} | {} | {:.3e} | {:.3} | {:.3e} | {:.0} |",
            engine.info().kind,
            m.samples,
            m.pairs as f64,
            m.seconds,
            m.pairs as f64 / m.seconds,
            m.seconds / m.samples as f64 * 1e9
        );
    }

    println!(
        "\n## milling: dexel–pass pairs (samples × candidate passes) per second, from a second run (the first also compiles the GPU kernel's pipeline for the tool kind and tooth model); ratio to the CPU engine in this run"
    );
    println!(
        "| case | engine | samples | pairs | first run s | removal s | pairs/s | ns per pair | × CPU |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for (case, text) in milling_cases() {
        let job = Job::from_toml_str(&text, "bench").map_err(|e| e.to_string())?;
        let mut cpu_seconds = None;
        for engine in engines.iter_mut() {
            let first = time_removal(engine.as_mut(), &job)?;
            let m = time_removal(engine.as_mut(), &job)?;
            let kind = engine.info().kind;
            if kind == "cpu" {
                cpu_seconds = Some(m.seconds);
            }
            let ratio = cpu_seconds.map_or("–".into(), |c| format!("{:.2}", c / m.seconds));
            println!(
                "| {case} | {kind} | {} | {:.3e} | {:.3} | {:.3} | {:.3e} | {:.0} | {ratio} |",
                m.samples,
                m.pairs as f64,
                first.seconds,
                m.seconds,
                m.pairs as f64 / m.seconds,
                m.seconds / m.pairs as f64 * 1e9,
            );
        }
    }

    if large && gpu {
        // 50 001 rings × 400 azimuths × 8 bytes = 160 MB of results: more than lavapipe's
        // 128 MiB storage binding, so the GPU engine must tile.
        let job = facing_job(5.0, 0.2, 0.1, 400);
        let samples = prepare_scenes(&job)[0].grid().sample_count();
        println!(
            "\n## large grid: {samples} samples, {:.0} MiB of dexels",
            samples as f64 * 8.0 / 1048576.0
        );
        for engine in engines.iter_mut().filter(|e| e.info().kind == "gpu") {
            let m = time_removal(engine.as_mut(), &job)?;
            println!(
                "{}: {} samples, {:.3e} pairs in {:.2} s ({:.3e} pairs/s), tiled",
                engine.info().kind,
                m.samples,
                m.pairs as f64,
                m.seconds,
                m.pairs as f64 / m.seconds
            );
        }
    }
    Ok(())
}

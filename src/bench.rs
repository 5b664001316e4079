//! `toolmark bench`: throughput of the removal engines in dexel–pass evaluations per
//! second, wall time of the default job (and its stages with every output written),
//! the scaling check (a 10× longer spiral over a
//! 10× wider part at the same feed and pitch must cost about the same per dexel), and
//! a grid larger than one 128 MiB storage binding (tiled on the GPU).
//! Numbers are printed, never asserted: timings don't belong in tests.

use crate::engine::RemovalEngine;
use crate::engine::cpu::CpuEngine;
use crate::engine::gpu::GpuEngine;
use crate::geometry::Form;
use crate::model::{
    EffectSpec, FluteModel, GeneratingSpec, Job, JobError, JobFile, ProcessSpec, SurfaceSpec,
    ToolSpec, TurningSpec,
};
use crate::pipeline::{prepare_scenes, remove_all, simulate};
use std::path::Path;
use std::time::Instant;

/// A flat facing job of the given aperture radius (mm) used for scaling and tiling.
pub fn facing_job(radius_mm: f64, feed_mm: f64, pitch_um: f64, azimuths: u32) -> Job {
    JobFile::new(
        SurfaceSpec::plane(2.0 * radius_mm),
        ToolSpec::arc_nose(0.5, 120.0),
        ProcessSpec::Turning(TurningSpec::xz(feed_mm)),
    )
    .named(&format!("bench facing r{radius_mm}"))
    .grid(pitch_um, azimuths)
    .check()
    .expect("the bench job is valid")
}

/// The generating benchmark: a toothed wheel, where every sample solves its passes.
fn generating_teeth_job() -> Job {
    JobFile::new(
        SurfaceSpec::sphere(Form::Concave, 53.5, 6.0),
        ToolSpec::cup_wheel(3.5, 0.5, 6),
        ProcessSpec::Generating(GeneratingSpec {
            spark_out_revolutions: Some(1.5),
            ..GeneratingSpec::at_speeds(1000.0, 10.0)
        }),
    )
    .named("bench generating teeth")
    .grid(5.0, 4096)
    .check()
    .expect("the bench job is valid")
}

/// The milling benchmark, every tool: a ball on a spiral (the early stop of the pass
/// ranking), a five-axis bull-nose and flat end (every candidate pass searched, kinked
/// entries), a disc, and a two-flute ball's feed marks with its teeth as edges and as
/// bodies.
fn milling_cases() -> Vec<(&'static str, JobFile)> {
    let example = |text: &str| JobFile::from_toml_str(text).expect("the example reads");
    let feed_marks = example(include_str!("../examples/milling_ball_feed_marks.toml"));
    let mut bodies = feed_marks.clone();
    if let ToolSpec::BallEnd(tool) = &mut bodies.tool {
        tool.flutes = Some(FluteModel::Body);
    }
    vec![
        (
            "Ø1 ball, constant-scallop spiral on the seed-002 asphere",
            example(include_str!(
                "../examples/milling_asphere_constant_scallop.toml"
            )),
        ),
        (
            "Ø8 bull-nose, 5-axis raster in a concave sphere",
            example(include_str!(
                "../examples/milling_bull_nose_concave_5axis.toml"
            )),
        ),
        (
            "Ø6 flat end, 5-axis raster on a convex sphere",
            example(include_str!("../examples/milling_flat_end_5axis.toml")),
        ),
        (
            "Ø30 disc, oblique raster on a convex sphere",
            example(include_str!("../examples/milling_disc_oblique.toml")),
        ),
        (
            "Ø2 ball, 2 teeth at 0.05 mm as edges (feed-marks example)",
            feed_marks,
        ),
        ("same, teeth as bodies", bodies),
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

/// The 1-minute load average (other work sharing the cores), or "unknown".
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|text| text.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "unknown".into())
}

/// Runs every benchmark on the chosen engines and prints the tables: the host, the NumPy
/// comparison and the default job's stages (CPU), the default job, scaling, generating
/// and milling throughput, and the large tiled grid (`large`, GPU).
pub fn run_benchmarks(cpu: bool, gpu: bool, large: bool) -> Result<(), String> {
    let mut engines = open_engines(cpu, gpu)?;
    print_host(&engines);

    if cpu && let Err(err) = numpy_comparison(&[32, 256]) {
        println!("\n(the NumPy comparison did not run: {err})");
    }

    bench_default_job(&mut engines)?;

    if cpu {
        default_run_with_outputs(5)?;
    }

    bench_scaling(&mut engines)?;
    if cpu {
        bench_wavy_edge()?;
    }
    bench_generating(&mut engines)?;
    bench_milling(&mut engines)?;

    if large && gpu {
        bench_large_grid(&mut engines)?;
    }
    Ok(())
}

/// The engines to measure: the CPU's, then the GPU's.
fn open_engines(cpu: bool, gpu: bool) -> Result<Vec<Box<dyn RemovalEngine>>, String> {
    let mut engines: Vec<Box<dyn RemovalEngine>> = Vec::new();
    if cpu {
        engines.push(Box::new(CpuEngine));
    }
    if gpu {
        engines.push(Box::new(GpuEngine::new().map_err(|e| e.to_string())?));
    }
    Ok(engines)
}

/// The processor, its threads and load, and each engine's adapter.
fn print_host(engines: &[Box<dyn RemovalEngine>]) {
    println!(
        "host: {} ({} threads), load average {}",
        processor_name(),
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        load_average()
    );
    for engine in engines {
        let info = engine.info();
        println!(
            "{}: {} [{} {}] {}",
            info.kind, info.adapter, info.backend, info.device_type, info.driver
        );
    }
}

/// The default job through the whole pipeline (no file output) on each engine.
fn bench_default_job(engines: &mut [Box<dyn RemovalEngine>]) -> Result<(), String> {
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
    Ok(())
}

/// The scaling check: a facing job 10× wider (a 10× longer spiral) must cost about the
/// same per dexel.
fn bench_scaling(engines: &mut [Box<dyn RemovalEngine>]) -> Result<(), String> {
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
    Ok(())
}

/// An R9 sphere turned at 2 µm/rev under a 0.3 mm nose whose edge is wavy (order 20,
/// 50 nm): the diagnosis's edge-waviness trials.
fn wavy_edge_job() -> Result<Job, JobError> {
    JobFile::new(
        SurfaceSpec::sphere(Form::Convex, 9.0, 2.0),
        ToolSpec::arc_nose(0.3, 120.0),
        ProcessSpec::Turning(TurningSpec {
            stock_allowance_mm: Some(0.002),
            ..TurningSpec::xz(0.002)
        }),
    )
    .named("wavy edge")
    .grid(0.25, 16)
    .effect(EffectSpec::edge_waviness(20.0, 0.00005, 10.0))
    .check()
}

/// An edge off its circle: the engine (its passes' bounds in lanes, the full entries
/// with their arctangents only where a bound reaches below the lowest entry) against
/// the scalar twin it must match bit for bit, sample by sample on the same threads, in
/// the same run.
fn bench_wavy_edge() -> Result<(), String> {
    use crate::engine::Scene;
    use crate::engine::cpu_turning_scalar::sample_dexel;
    use rayon::prelude::*;
    println!("\n## wavy edge (R9 sphere, 2 µm/rev, 0.3 mm nose, order-20 waviness of 50 nm), CPU");
    println!("| path | samples | pairs | removal s | pairs/s | ratio |");
    println!("| --- | --- | --- | --- | --- | --- |");
    let job = wavy_edge_job().map_err(|e| e.to_string())?;
    let engine = median_removal(3, &job)?;
    let scenes = prepare_scenes(&job);
    let Some(Scene::Turning(scene)) = scenes.first() else {
        return Err("the wavy-edge job is not a turning job".into());
    };
    let grid = &scene.grid;
    let twin = median_seconds(3, || {
        let rows: Vec<u32> = (0..grid.azimuths).collect();
        let depth: f64 = rows
            .par_iter()
            .map(|&row| {
                (0..grid.ring_count())
                    .map(|ring| sample_dexel(scene, ring, row).0)
                    .sum::<f64>()
            })
            .sum();
        std::hint::black_box(depth);
        Ok(())
    })?;
    for (path, seconds) in [
        ("engine (bounds in lanes)", engine.seconds),
        ("scalar twin", twin),
    ] {
        println!(
            "| {path} | {} | {:.3e} | {seconds:.3} | {:.3e} | {:.2} |",
            engine.samples,
            engine.pairs as f64,
            engine.pairs as f64 / seconds,
            twin / seconds
        );
    }
    Ok(())
}

/// [`time_removal`] on the CPU engine, the median of `runs`.
fn median_removal(runs: usize, job: &Job) -> Result<Measurement, String> {
    let mut all = (0..runs)
        .map(|_| time_removal(&mut CpuEngine, job))
        .collect::<Result<Vec<_>, _>>()?;
    all.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
    Ok(all.swap_remove(runs / 2))
}

/// Generating with a toothed wheel: pass evaluations per second.
fn bench_generating(engines: &mut [Box<dyn RemovalEngine>]) -> Result<(), String> {
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
    Ok(())
}

/// Milling, every case of [`milling_cases`]: pairs per second from a second run, and the
/// ratio to the CPU engine.
fn bench_milling(engines: &mut [Box<dyn RemovalEngine>]) -> Result<(), String> {
    println!(
        "\n## milling: dexel–pass pairs (samples × candidate passes) per second, from a second run (the first also compiles the GPU kernel's pipeline for the tool kind and tooth model); ratio to the CPU engine in this run"
    );
    println!(
        "| case | engine | samples | pairs | first run s | removal s | pairs/s | ns per pair | × CPU |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for (case, file) in milling_cases() {
        let job = Job::from_file(file, "bench", Path::new(".")).map_err(|e| e.to_string())?;
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
    Ok(())
}

/// A grid larger than one 128 MiB storage binding on the GPU engines (tiled).
fn bench_large_grid(engines: &mut [Box<dyn RemovalEngine>]) -> Result<(), String> {
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
    Ok(())
}

/// The NumPy reference sweep (`benches/numpy_facing.py`) and the job it runs.
const NUMPY_FACING: &str = include_str!("../benches/numpy_facing.py");
const FLAT_FACING: &str = include_str!("../examples/flat_facing.toml");

/// What the NumPy sweep reports, with the field it wrote.
struct NumpySweep {
    pairs: u64,
    sweep_s: f64,
    numpy: String,
    depth_mm: Vec<f64>,
    pass: Vec<u32>,
}

/// Runs the NumPy sweep of the flat-facing example at `azimuths` in `dir`.
fn numpy_sweep(python: &str, dir: &Path, azimuths: u32) -> Result<NumpySweep, String> {
    let (script, job, out) = (
        dir.join("numpy_facing.py"),
        dir.join("flat_facing.toml"),
        dir.join("facing"),
    );
    std::fs::write(&script, NUMPY_FACING).map_err(|e| e.to_string())?;
    std::fs::write(&job, FLAT_FACING).map_err(|e| e.to_string())?;
    let output = std::process::Command::new(python)
        .arg(&script)
        .arg(&job)
        .arg("--out")
        .arg(&out)
        .args(["--azimuths", &azimuths.to_string()])
        .output()
        .map_err(|e| format!("{python}: {e}"))?;
    if !output.status.success() {
        return Err(String::from_utf8_lossy(&output.stderr).into_owned());
    }
    let report: serde_json::Value =
        serde_json::from_slice(&output.stdout).map_err(|e| format!("NumPy sweep output: {e}"))?;
    let read = |suffix: &str| {
        std::fs::read(out.with_extension(suffix)).map_err(|e| format!("{suffix}: {e}"))
    };
    let depth_mm = read("depth_mm.f64")?
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
        .collect();
    let pass = read("pass.u32")?
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
        .collect();
    Ok(NumpySweep {
        pairs: report["pairs"].as_u64().unwrap_or(0),
        sweep_s: report["sweep_s"].as_f64().unwrap_or(f64::NAN),
        numpy: report["numpy"].as_str().unwrap_or("?").to_string(),
        depth_mm,
        pass,
    })
}

/// Median of `runs` timings of `f`.
/// The default job on the CPU engine with every output written (what `toolmark run
/// --engine cpu` does, the files into a temporary folder), `runs` times: each run's
/// stages, the output stage's share of their sum, and the median share.
fn default_run_with_outputs(runs: usize) -> Result<(), String> {
    println!(
        "\n## default job (seed-002 asphere, XZ) on the CPU engine with every output written ({runs} runs)"
    );
    println!("| run | prepare s | removal s | analysis s | output s | total s | output share |");
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    let dir = std::env::temp_dir().join(format!("toolmark-bench-outputs-{}", std::process::id()));
    let mut shares = Vec::with_capacity(runs);
    for run in 1..=runs {
        let result =
            simulate(Job::default_job(), &mut CpuEngine, &|_, _| {}).map_err(|e| e.to_string())?;
        crate::output::run_files::prepare_output_dir(&dir).map_err(|e| e.to_string())?;
        let products = crate::pipeline::products(&result);
        let started = Instant::now();
        crate::output::run_files::write_outputs(&dir, &result, &products)
            .map_err(|e| e.to_string())?;
        let output_s = started.elapsed().as_secs_f64();
        let t = result.timings;
        let analysis_s = t.analysis_s + products.elapsed_s;
        let total = t.prepare_s + t.removal_s + analysis_s + output_s;
        shares.push(output_s / total);
        println!(
            "| {run} | {:.3} | {:.3} | {:.3} | {output_s:.3} | {total:.3} | {:.0} % |",
            t.prepare_s,
            t.removal_s,
            analysis_s,
            100.0 * output_s / total
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    shares.sort_by(f64::total_cmp);
    println!(
        "(output: every file, the summary and report included; median share {:.0} %)",
        100.0 * shares[runs / 2]
    );
    Ok(())
}

fn median_seconds(runs: usize, mut f: impl FnMut() -> Result<(), String>) -> Result<f64, String> {
    let mut times = Vec::with_capacity(runs);
    for _ in 0..runs {
        let started = Instant::now();
        f()?;
        times.push(started.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    Ok(times[runs / 2])
}

/// The CPU engine against the NumPy sweep of one flat-facing job, run side by side.
#[derive(Debug, Clone)]
pub struct NumpyComparison {
    pub azimuths: u32,
    /// Dexel–pass pairs; the script and the engine evaluated the same count.
    pub pairs: u64,
    pub numpy_s: f64,
    pub numpy_version: String,
    /// Median of the engine's runs.
    pub cpu_s: f64,
    /// Largest |engine − NumPy| depth over the field, nm.
    pub max_depth_difference_nm: f64,
    /// Samples whose winning pass id differs.
    pub passes_differing: usize,
}

/// Runs `benches/numpy_facing.py` on the flat-facing example at `azimuths` (with the
/// interpreter in `TOOLMARK_PYTHON`, else `python3`), then the CPU engine on the same
/// job (median of `cpu_runs`), and compares the two fields. An error when the script
/// cannot run or the two evaluated different pairs.
pub fn compare_with_numpy(azimuths: u32, cpu_runs: usize) -> Result<NumpyComparison, String> {
    let python = std::env::var("TOOLMARK_PYTHON").unwrap_or_else(|_| "python3".into());
    let dir = std::env::temp_dir().join(format!(
        "toolmark-bench-numpy-{}-{azimuths}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let reference = numpy_sweep(&python, &dir, azimuths);
    let _ = std::fs::remove_dir_all(&dir);
    let reference = reference?;
    let mut file = JobFile::from_toml_str(FLAT_FACING).map_err(|e| e.to_string())?;
    file.grid.azimuths = Some(azimuths);
    let job = Job::from_file(file, "bench", Path::new(".")).map_err(|e| e.to_string())?;
    let scenes = prepare_scenes(&job);
    let pairs: u64 = scenes.iter().map(|s| s.pair_count()).sum();
    let mut field = None;
    let cpu_s = median_seconds(cpu_runs, || {
        field = Some(remove_all(&scenes, &mut CpuEngine, &|_, _| {}).map_err(|e| e.to_string())?);
        Ok(())
    })?;
    let field = field.expect("ran");
    if reference.pairs != pairs || reference.depth_mm.len() != field.depth_mm.len() {
        return Err(format!(
            "the NumPy sweep evaluated {} pairs on {} samples, the engine {pairs} on {}",
            reference.pairs,
            reference.depth_mm.len(),
            field.depth_mm.len()
        ));
    }
    let max_depth_difference_nm = field
        .depth_mm
        .iter()
        .zip(&reference.depth_mm)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
        * 1e6;
    let passes_differing = field
        .pass
        .iter()
        .zip(&reference.pass)
        .filter(|(a, b)| a != b)
        .count();
    Ok(NumpyComparison {
        azimuths,
        pairs,
        numpy_s: reference.sweep_s,
        numpy_version: reference.numpy,
        cpu_s,
        max_depth_difference_nm,
        passes_differing,
    })
}

/// The CPU engine against the NumPy sweep of the same flat-facing job, in the same run:
/// time per pair on both, and how far their fields differ.
pub fn numpy_comparison(azimuth_counts: &[u32]) -> Result<(), String> {
    println!(
        "\n## CPU removal against a vectorised NumPy sweep of the same pairs (benches/numpy_facing.py): flat facing example, Ø10 mm, 1 µm pitch"
    );
    println!(
        "| azimuths | pairs | NumPy s | NumPy ns/pair | CPU s (median of 5) | CPU ns/pair | CPU ÷ NumPy speed | max \\|Δ depth\\| nm | pass ids differing |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let mut version = String::new();
    for &azimuths in azimuth_counts {
        let c = compare_with_numpy(azimuths, 5)?;
        let pairs = c.pairs as f64;
        println!(
            "| {azimuths} | {pairs:.3e} | {:.3} | {:.1} | {:.4} | {:.2} | {:.1}× | {:.1e} | {} |",
            c.numpy_s,
            c.numpy_s / pairs * 1e9,
            c.cpu_s,
            c.cpu_s / pairs * 1e9,
            c.numpy_s / c.cpu_s,
            c.max_depth_difference_nm,
            c.passes_differing
        );
        version = c.numpy_version;
    }
    println!(
        "(NumPy {version}, one thread; the CPU engine on {} threads)",
        rayon::current_num_threads()
    );
    Ok(())
}

/// The issue-10 target job: the seed-002 asphere (the default job's surface, tool and
/// spiral, XZ) over its full Ø20 mm at 0.5 µm along the meridian × `azimuths` rows.
/// 8192 azimuths is the full job (47 409 rings, 3.88e8 samples); fewer scale it down
/// with the same rings and passes per sample.
pub fn target_job(azimuths: u32) -> Result<Job, String> {
    let file = JobFile::from_toml_str(crate::model::DEFAULT_JOB_TOML)
        .map_err(|e| e.to_string())?
        .named(&format!("seed-002 full aperture, 0.5 um x {azimuths}"))
        .grid(0.5, azimuths);
    Job::from_file(file, "target", Path::new(".")).map_err(|e| e.to_string())
}

/// Peak resident memory of this process so far (Linux `VmHWM`, bytes), if known.
fn peak_rss_bytes() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// `toolmark bench --target`: the target job end to end on each chosen engine (prepare,
/// removal, analysis, every output file), with each stage's wall time, the removal's
/// time per pair and the process's peak resident memory so far. Outputs go to `out`, or
/// to a temporary folder removed afterwards.
pub fn run_target(cpu: bool, gpu: bool, azimuths: u32, out: Option<&Path>) -> Result<(), String> {
    let mut engines = open_engines(cpu, gpu)?;
    print_host(&engines);
    let job = target_job(azimuths)?;
    let grid = crate::pipeline::job_grid(&job, &crate::pipeline::Groundwork::of(&job));
    println!(
        "\n## target job: {} ({} rings × {} azimuths = {:.3e} samples), end to end",
        job.name,
        grid.ring_count(),
        azimuths,
        job.sample_count() as f64
    );
    println!(
        "| engine | samples | pairs | prepare s | removal s | ns/pair | analysis s | output s | wall s | peak RSS so far GiB | files |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let temporary = std::env::temp_dir().join(format!("toolmark-target-{}", std::process::id()));
    for engine in engines.iter_mut() {
        let dir = out.map_or_else(|| temporary.clone(), |o| o.join(engine.info().kind));
        target_row(engine.as_mut(), job.clone(), &dir)?;
        if out.is_none() {
            let _ = std::fs::remove_dir_all(&temporary);
        }
    }
    if !crate::output::run_files::polar_exr_written(&grid) {
        println!(
            "(polar.exr is not written above {} samples; the top views, profile and statistics cover the whole field)",
            crate::model::resources::POLAR_EXR_MAX_SAMPLES
        );
    }
    Ok(())
}

/// One engine's row of the target table: the job run end to end into `dir`.
fn target_row(engine: &mut dyn RemovalEngine, job: Job, dir: &Path) -> Result<(), String> {
    let started = Instant::now();
    let result = simulate(job, engine, &|_, _| {}).map_err(|e| e.to_string())?;
    let products = crate::pipeline::products(&result);
    let outputs = Instant::now();
    crate::output::run_files::prepare_output_dir(dir).map_err(|e| e.to_string())?;
    let written = crate::output::run_files::write_outputs(dir, &result, &products)
        .map_err(|e| e.to_string())?;
    let output_s = outputs.elapsed().as_secs_f64();
    let wall = started.elapsed().as_secs_f64();
    let t = result.timings;
    let pairs = result.pair_count();
    println!(
        "| {} | {:.3e} | {:.3e} | {:.2} | {:.2} | {:.3} | {:.2} | {:.2} | {:.2} | {} | {} |",
        result.engine.kind,
        result.grid().sample_count() as f64,
        pairs as f64,
        t.prepare_s,
        t.removal_s,
        t.removal_s / pairs as f64 * 1e9,
        t.analysis_s + products.elapsed_s,
        output_s,
        wall,
        peak_rss_bytes().map_or("unknown".into(), |b| format!("{:.2}", b / 1024f64.powi(3))),
        written.len()
    );
    Ok(())
}

//! The GPU engine (f32, local frames) against the CPU reference (f64) on whole jobs.
//! Bound (DESIGN §5 / issue 2): max |Δ deviation| ≤ max(0.5 nm, 0.1 % of the map's PV).

mod common;
use common::*;
use toolmark::field::NO_PASS;

fn compare(name: &str, job: toolmark::io::job::Job) {
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
        if difference > worst {
            (worst, at) = (difference, i);
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
    println!(
        "{name}: {} samples, PV {:.3} nm; max |GPU − CPU| = {worst_nm:.4} nm at ring {} azimuth {} (bound {bound_nm:.3} nm); same winning pass at {:.3} % of samples",
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
    // Both engines must agree on which samples were cut at all.
    let cut = |p: &u32| *p != NO_PASS;
    assert_eq!(
        cpu.field.pass.iter().filter(|p| cut(p)).count(),
        gpu.field.pass.iter().filter(|p| cut(p)).count(),
        "{name}: engines cut different sample sets"
    );
}

#[test]
fn flat_facing_gpu_matches_cpu() {
    compare("flat facing", example("flat_facing.toml"));
}

#[test]
fn convex_sphere_radial_feed_gpu_matches_cpu() {
    compare("convex sphere", example("convex_sphere.toml"));
}

#[test]
fn concave_sphere_xzb_gpu_matches_cpu() {
    compare("concave sphere XZB", example("concave_sphere.toml"));
}

#[test]
fn seed_002_asphere_xz_gpu_matches_cpu() {
    compare("seed-002 asphere XZ", example("asphere_xz.toml"));
}

#[test]
fn seed_002_asphere_xzb_gpu_matches_cpu() {
    compare("seed-002 asphere XZB", example("asphere_xzb.toml"));
}

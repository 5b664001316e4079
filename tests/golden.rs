//! Golden results (golden/README.md): each case's field from both engines against
//! the stored CPU field, one test per case. `TOOLMARK_BLESS=1` rewrites the stored
//! files from the CPU.

mod common;
use common::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use toolmark::formats::exr_io::{ExrImage, read_exr, write_exr};
use toolmark::model::Job;
use toolmark::output::colour::ColourMap;
use toolmark::output::png_out::{FalseColourPlot, write_false_colour_png};
use toolmark::pipeline::RunResult;

/// CPU against its own stored result: only f32 storage and libm differences.
const CPU_TOLERANCE_NM: f64 = 1e-3;

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("golden")
}

fn field_image(result: &RunResult) -> ExrImage {
    let grid = result.grid();
    ExrImage {
        width: grid.ring_count(),
        height: grid.azimuths as usize,
        channels: vec![
            (
                "deviation_nm".into(),
                result
                    .field
                    .depth_mm
                    .iter()
                    .map(|d| (d * 1e6) as f32)
                    .collect(),
            ),
            ("pass".into(), result.field.pass_channel()),
        ],
        attributes: BTreeMap::from([
            ("job_hash".to_string(), result.job.hash()),
            (
                "units".to_string(),
                "deviation_nm: nm along the outward normal, + = material left".to_string(),
            ),
        ]),
    }
}

/// Compares `actual` with the golden image; on failure writes the evidence and panics.
fn compare(
    case: &str,
    engine: &str,
    actual: &ExrImage,
    golden: &ExrImage,
    tolerance_nm: f64,
    check_pass: bool,
) {
    assert_eq!(
        (actual.width, actual.height),
        (golden.width, golden.height),
        "{case} [{engine}]: grid changed from the golden one (re-bless if intended)"
    );
    let a = actual.channel("deviation_nm").expect("deviation channel");
    let g = golden
        .channel("deviation_nm")
        .expect("golden deviation channel");
    let difference: Vec<f32> = a.iter().zip(g).map(|(x, y)| x - y).collect();
    let max_nm = difference.iter().fold(0.0f64, |m, d| m.max(d.abs() as f64));
    let rms_nm = (difference.iter().map(|d| (*d as f64).powi(2)).sum::<f64>()
        / difference.len() as f64)
        .sqrt();
    let pass_mismatch = if check_pass {
        let (ap, gp) = (
            actual.channel("pass").unwrap(),
            golden.channel("pass").unwrap(),
        );
        ap.iter().zip(gp).filter(|(x, y)| x != y).count() as f64 / ap.len() as f64
    } else {
        0.0
    };
    println!(
        "{case} [{engine}]: max |Δ| = {max_nm:.2e} nm, RMS Δ = {rms_nm:.2e} nm (tolerance {tolerance_nm} nm); pass mismatch {:.4} %",
        pass_mismatch * 100.0
    );
    if max_nm <= tolerance_nm && pass_mismatch <= 1e-3 {
        return;
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/golden-failures");
    let stem = format!("{case}-{engine}");
    let _ = write_exr(&dir.join(format!("{stem}-actual.exr")), actual);
    let diff_image = ExrImage {
        channels: vec![("difference_nm".into(), difference.clone())],
        ..actual.clone()
    };
    let _ = write_exr(&dir.join(format!("{stem}-diff.exr")), &diff_image);
    let limit = max_nm as f32;
    let _ = write_false_colour_png(
        &dir.join(format!("{stem}-diff.png")),
        &FalseColourPlot {
            values: &difference,
            valid: &vec![true; difference.len()],
            width: actual.width as u32,
            height: actual.height as u32,
            range: (-limit, limit),
            colour_map: ColourMap::Diverging,
            title: &format!("{case} {engine} minus golden"),
            unit_label: "difference (nm)",
            footer: &format!("max {max_nm:.3e} nm  RMS {rms_nm:.3e} nm"),
        },
        &[],
    );
    panic!(
        "{case} [{engine}] differs from golden/{case}.exr: max {max_nm:.3e} nm, RMS {rms_nm:.3e} nm, pass mismatch {:.3} %; evidence in {}",
        pass_mismatch * 100.0,
        dir.display()
    );
}

macro_rules! golden_cases {
    ($($test:ident,)*) => {
        $(
            #[test]
            fn $test() {
                golden_case(stringify!($test));
            }
        )*
    };
}

golden_cases! {
    flat_facing,
    concave_sphere_xzb,
    asphere_xz,
    generating_teeth,
    milling_ball_edges,
    milling_bull_nose_5axis,
}

fn golden_case(case: &str) {
    let bless = std::env::var("TOOLMARK_BLESS").is_ok_and(|v| v == "1");
    let job = Job::load(&golden_dir().join(format!("{case}.toml"))).expect("golden job");
    let cpu = run_cpu(job.clone());
    let cpu_image = field_image(&cpu);
    let path = golden_dir().join(format!("{case}.exr"));
    if bless {
        write_exr(&path, &cpu_image).expect("write golden");
        println!("blessed {}", path.display());
        return;
    }
    let golden = read_exr(&path)
        .unwrap_or_else(|err| panic!("{err}: bless with TOOLMARK_BLESS=1 if the case is new"));
    compare(case, "cpu", &cpu_image, &golden, CPU_TOLERANCE_NM, true);

    let gpu_image = field_image(&run_gpu(job));
    let golden_values = golden.channel("deviation_nm").unwrap();
    let (lo, hi) = golden_values
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let gpu_tolerance = (0.001 * (hi - lo) as f64).max(0.5);
    compare(case, "gpu", &gpu_image, &golden, gpu_tolerance, false);
}

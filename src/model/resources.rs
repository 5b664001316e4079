//! What a job will cost before it runs: memory and a rough time, and whether this
//! machine can hold it. `check` prints the estimate; `run` refuses a job whose peak
//! memory would exceed what the machine has available, before any work or output.
//!
//! The per-sample figures were measured (peak resident set, `/usr/bin/time -f %M`, and
//! `toolmark bench --target`'s VmHWM) on the 2-core project machine after issue 10 made
//! the analysis stream (no full-resolution copies): flat facing with 256 and 2048
//! azimuths (1.3 M and 10.2 M samples) rises 47.5 bytes per sample on both engines, the
//! seed-002 target job at 512 azimuths (24 M samples) peaks at 62 bytes per sample —
//! `polar.exr`'s f32 channels and the encoder's copies of them; above
//! `POLAR_EXR_MAX_SAMPLES` that file is not written and the target job at 2048 azimuths
//! (97 M samples) peaks at 17.4 bytes per sample (the field's 12, its scallop cusps and
//! the maps' bands). The estimate rounds up to 70 and 24 bytes and adds 40 bytes per map
//! pixel per map written.

use super::Job;
use crate::process::Process;

/// Peak bytes per grid sample while `polar.exr` is written (see the module docs).
pub const CPU_BYTES_PER_SAMPLE: f64 = 70.0;
pub const GPU_BYTES_PER_SAMPLE: f64 = 70.0;
/// The native grid's samples above which `polar.exr` is not written: its f32 channels
/// (and the encoder's copy of them) would need gigabytes; the top views, profile and
/// statistics still cover the whole field. Recorded in `summary.json`;
/// the writers (`output::run_files`) read it from here, where the memory check needs it.
pub const POLAR_EXR_MAX_SAMPLES: usize = 50_000_000;

/// Peak bytes per grid sample above `POLAR_EXR_MAX_SAMPLES` (no `polar.exr`).
pub const BYTES_PER_SAMPLE_WITHOUT_POLAR: f64 = 24.0;
const BASE_BYTES: f64 = 64.0e6;
const BYTES_PER_MAP_PIXEL: f64 = 40.0 * 6.0;

/// A job's expected peak memory and run time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub samples: f64,
    pub cpu_bytes: f64,
    pub gpu_bytes: f64,
    /// Rough CPU-engine removal time on the 2-core project machine (s).
    pub cpu_seconds: f64,
}

/// Rough removal cost per sample on the CPU engine, 2 cores (README "Performance":
/// turning 0.06 µs since issue 10, a toothed generator 1.7 µs, milling 11 µs per sample).
fn seconds_per_sample(process: &Process) -> f64 {
    match process {
        Process::Turning(_) => 0.06e-6,
        Process::Generating(g) if g.setup.wheel.teeth > 0 => 1.7e-6,
        Process::Generating(_) => 0.1e-6,
        Process::Milling(_) => 11.0e-6,
    }
}

pub fn estimate(job: &Job) -> Estimate {
    let samples = job.sample_count() as f64;
    let maps = f64::from(job.map_pixels).powi(2) * BYTES_PER_MAP_PIXEL;
    let polar = samples <= POLAR_EXR_MAX_SAMPLES as f64;
    let per_sample = |with_polar: f64| {
        if polar {
            with_polar
        } else {
            BYTES_PER_SAMPLE_WITHOUT_POLAR
        }
    };
    Estimate {
        samples,
        cpu_bytes: BASE_BYTES + samples * per_sample(CPU_BYTES_PER_SAMPLE) + maps,
        gpu_bytes: BASE_BYTES + samples * per_sample(GPU_BYTES_PER_SAMPLE) + maps,
        cpu_seconds: samples * seconds_per_sample(&job.process),
    }
}

/// Memory this machine has available now (Linux `MemAvailable`), if known.
pub fn available_bytes() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    available_from_meminfo(&text)
}

fn available_from_meminfo(text: &str) -> Option<f64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// Refuses, naming the grid fields, a job whose estimated peak memory (`bytes`) exceeds
/// `available` bytes.
pub fn check_fits(job: &Job, bytes: f64, available: f64) -> Result<(), super::JobError> {
    if bytes <= available {
        return Ok(());
    }
    Err(super::error(
        "grid.pitch_um",
        format!(
            "{:.3e} samples need about {:.1} GB, but this machine has {:.1} GB available; raise grid.pitch_um (now {:.3} µm) or lower grid.azimuths (now {}) by {:.1}× at least",
            job.sample_count() as f64,
            bytes / 1e9,
            available / 1e9,
            job.pitch_mm * 1e3,
            job.azimuths,
            bytes / available
        ),
    ))
}

impl std::fmt::Display for Estimate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:.3e} samples: about {:.2} GB of memory on the CPU engine ({:.2} GB on the GPU engine), removal roughly {} on the CPU engine (2 cores)",
            self.samples,
            self.cpu_bytes / 1e9,
            self.gpu_bytes / 1e9,
            human_seconds(self.cpu_seconds)
        )
    }
}

fn human_seconds(s: f64) -> String {
    match s {
        s if s < 60.0 => format!("{s:.1} s"),
        s if s < 3600.0 => format!("{:.1} min", s / 60.0),
        s => format!("{:.1} h", s / 3600.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_is_read_in_kib() {
        let text = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   20000000 kB\n";
        assert_eq!(available_from_meminfo(text), Some(20_000_000.0 * 1024.0));
        assert_eq!(available_from_meminfo("MemTotal: 1 kB\n"), None);
    }

    #[test]
    fn the_issue_job_of_3_9e8_samples_is_refused_on_an_8_gib_machine() {
        // The issue's case: flat facing at 3.9e8 samples wanted ~48 GB and aborted; with
        // the analysis streaming (issue 10) it needs ~9.4 GB.
        // 10 mm flat, 1 µm pitch → 5001 rings; 78 000 azimuths would exceed the 65 536
        // allowed, so use a finer pitch: 0.0128 µm × 1000 azimuths ≈ 3.9e8 samples.
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/examples/flat_facing.toml"
        ))
        .unwrap()
        .replace("pitch_um = 1.0", "pitch_um = 0.0128")
        .replace("azimuths = 32", "azimuths = 1000");
        let job = Job::from_toml_str(&text, "big").unwrap();
        let estimate = estimate(&job);
        assert!((estimate.samples - 3.9e8).abs() < 0.01e8, "{estimate}");
        // 24 B/sample × 3.9e8 = 9.4 GB (no polar.exr at this size): more than 8 GiB.
        assert!(
            (estimate.cpu_bytes / 9.5e9 - 1.0).abs() < 0.02,
            "{estimate}"
        );
        let err = check_fits(&job, estimate.cpu_bytes, 8.0 * 1024f64.powi(3)).unwrap_err();
        assert_eq!(err.field, "grid.pitch_um");
        assert!(err.message.contains("GB"), "{err}");
        // The default job (0.95 M samples) fits in 1 GB.
        let default = Job::default_job();
        assert!(check_fits(&default, estimate_of(&default), 1e9).is_ok());
    }

    fn estimate_of(job: &Job) -> f64 {
        estimate(job).cpu_bytes
    }
}

//! The `toolmark` command line.

mod cli;

use clap::{Parser, Subcommand, ValueEnum};
use cli::Failure;
use std::path::PathBuf;
use std::process::ExitCode;
use toolmark::bench;

#[derive(Parser)]
#[command(
    name = "toolmark",
    version,
    about = "Predict the surface a machining process leaves"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a job and write maps, profiles and a summary (default: the built-in
    /// seed-002 asphere turned XZ).
    Run(cli::run::RunArgs),
    /// Check a job file and print it with every default filled in.
    Check {
        /// Job file (TOML).
        job: PathBuf,
    },
    /// Measure engine throughput (dexel–pass evaluations per second) and scaling.
    Bench(BenchArgs),
    /// Place a measured profile or map on the job's part and compare them (PV, RMS,
    /// local mark spacing); no effect is fitted (`diagnose` does that).
    CompareProfile(cli::diagnose::CompareArgs),
    /// Run the machining–measurement–compensation loop in simulation and write the
    /// compensated path.
    Compensate(cli::compensate::CompensateArgs),
    /// Correct a generator's setup (wheel X position and inclination) from the pip and
    /// radius error of its part: simulated from the job, or measured.
    Correct(cli::correct::CorrectArgs),
    /// Print the closed-form references (seeds 000–004) for given parameters.
    Formulas(cli::formulas::FormulasArgs),
    /// Diagnose the gap between a job and a measured surface: where it lies, which
    /// unmodelled effect causes it, and how far it shrinks once that effect is added.
    Diagnose(cli::diagnose::DiagnoseArgs),
    /// Make measured-like data from a job plus effects the diagnosis is not told, with
    /// the truth written apart.
    Synth(cli::diagnose::SynthArgs),
    /// The withheld benchmark: generate a suite of synthetic measurements with sealed
    /// truth, diagnose them without it, then score.
    BenchDiagnose(cli::diagnose::BenchDiagnoseArgs),
    /// Write the self-contained HTML report of an output folder (run, diagnose,
    /// compensate or correct).
    Report(cli::run::ReportArgs),
    /// Run a job over a parameter grid on Dask (LocalCluster or any scheduler) and
    /// gather the summaries into a table; needs the Python package (pip install ./python).
    Sweep(cli::sweep::SweepArgs),
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Engines to measure (default: both; with --target, the CPU's).
    #[arg(long, value_enum)]
    engine: Option<BenchEngines>,
    /// Skip the grid larger than one 128 MiB storage binding (tiling check).
    #[arg(long)]
    skip_large: bool,
    /// Run only the target job (seed-002 full Ø20 mm aperture at 0.5 µm) end to end on
    /// the chosen engines (--engine; the CPU's by default): stage times, ns per pair,
    /// peak memory.
    #[arg(long)]
    target: bool,
    /// Azimuths of the target job (8192 = the full job; fewer scale it down).
    #[arg(long, default_value_t = 8192, value_parser = clap::value_parser!(u32).range(1..=65536))]
    target_azimuths: u32,
    /// Where the target job writes its outputs (default: a temporary folder, removed).
    #[arg(long)]
    target_out: Option<std::path::PathBuf>,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum BenchEngines {
    Cpu,
    Gpu,
    Both,
}

/// Blocks of up to 64 MiB come from the heap and freed memory up to 256 MiB stays
/// with the process. With glibc's defaults each simulation's field (a few MiB) was
/// mapped fresh and given back on free: a diagnosis spent a quarter of its time
/// zeroing pages in the kernel (a 24 s profile diagnosis took 19.5 s with these).
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets the allocator's thresholds; called before any thread.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 64 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}

fn main() -> ExitCode {
    // Mesa's Vulkan device-select layer probes for a Wayland display and prints an
    // error when there is none; a compute-only program has no use for it.
    if std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: first thing in main, before any thread exists.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
    // Piped into `head`, a closed pipe should end the program quietly, as for any Unix
    // tool, not make println! panic: restore the default SIGPIPE action Rust ignores.
    #[cfg(unix)]
    // SAFETY: installing the default handler for one signal, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    keep_freed_memory();
    // Ctrl-C removes half-written outputs and says what was kept (io::atomic).
    toolmark::formats::atomic::install_interrupt_handler();
    let cli = Cli::parse();
    let result = match cli.command.unwrap_or(Command::Run(Default::default())) {
        Command::Run(args) => cli::run::run(args),
        Command::Check { job } => cli::run::check(job),
        Command::CompareProfile(args) => cli::diagnose::compare_cmd(args),
        Command::Compensate(args) => cli::compensate::compensate(args),
        Command::Correct(args) => cli::correct::correct(args),
        Command::Formulas(args) => cli::formulas::formulas(args),
        Command::Diagnose(args) => cli::diagnose::diagnose_cmd(args),
        Command::Synth(args) => cli::diagnose::synth_cmd(args),
        Command::BenchDiagnose(args) => cli::diagnose::bench_diagnose_cmd(args),
        Command::Report(args) => cli::run::report(args),
        Command::Sweep(args) => cli::sweep::sweep(args),
        Command::Bench(args) if args.target => {
            let engine = args.engine.unwrap_or(BenchEngines::Cpu);
            bench::run_target(
                engine != BenchEngines::Gpu,
                engine != BenchEngines::Cpu,
                args.target_azimuths,
                args.target_out.as_deref(),
            )
            .map_err(Failure::Runtime)
        }
        Command::Bench(args) => {
            let engine = args.engine.unwrap_or(BenchEngines::Both);
            bench::run_benchmarks(
                engine != BenchEngines::Gpu,
                engine != BenchEngines::Cpu,
                !args.skip_large,
            )
            .map_err(Failure::Runtime)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Input(message)) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
        Err(Failure::Runtime(message)) => {
            eprintln!("error: {message}");
            ExitCode::from(1)
        }
    }
}

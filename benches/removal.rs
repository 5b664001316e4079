//! `cargo bench`: the same measurements as `toolmark bench` (CPU and GPU engines,
//! default job, scaling, tiled large grid). Throughput is printed, never asserted.

fn main() {
    if let Err(err) = toolmark::bench::run_benchmarks(true, true, true) {
        eprintln!("benchmark failed: {err}");
        std::process::exit(1);
    }
}

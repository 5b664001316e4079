//! `toolmark sweep JOB --grid GRID.toml`: a parameter sweep on Dask. Dask is Python, so
//! this hands the work to the Python package (`pip install ./python`), module
//! `toolmark.dask_sweep`, with the interpreter in `TOOLMARK_PYTHON` (default `python3`).

use super::Failure;
use std::path::PathBuf;
use std::process::Command;

#[derive(clap::Args)]
pub struct SweepArgs {
    /// Job file (TOML).
    pub job: PathBuf,
    /// Grid file (TOML): [parameters] "dotted.path" = [values…]; optional [cluster]
    /// (workers, address) and [output] (table).
    #[arg(long)]
    pub grid: PathBuf,
    /// Output table (.csv or .parquet).
    #[arg(long)]
    pub table: Option<PathBuf>,
    /// A Dask scheduler's address (default: a LocalCluster).
    #[arg(long)]
    pub address: Option<String>,
    /// LocalCluster workers (default 2).
    #[arg(long)]
    pub workers: Option<u32>,
    /// Run every grid point again instead of resuming from the table.
    #[arg(long)]
    pub no_resume: bool,
}

pub fn sweep(args: SweepArgs) -> Result<(), Failure> {
    let python = std::env::var("TOOLMARK_PYTHON").unwrap_or_else(|_| "python3".into());
    let mut command = Command::new(&python);
    command
        .args(["-m", "toolmark.dask_sweep"])
        .arg(&args.job)
        .arg("--grid")
        .arg(&args.grid);
    if let Some(table) = &args.table {
        command.arg("--table").arg(table);
    }
    if let Some(address) = &args.address {
        command.args(["--address", address]);
    }
    if let Some(workers) = args.workers {
        command.args(["--workers", &workers.to_string()]);
    }
    if args.no_resume {
        command.arg("--no-resume");
    }
    let status = command.status().map_err(|err| {
        Failure::Runtime(format!(
            "{python}: {err}; the sweep needs the Python package (pip install ./python) and Dask"
        ))
    })?;
    match status.code() {
        Some(0) => Ok(()),
        Some(2) => Err(Failure::Input("the sweep refused its input (above)".into())),
        _ => Err(Failure::Runtime(format!("the sweep failed ({status})"))),
    }
}

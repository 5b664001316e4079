//! The command line's subcommands and what they share.

pub mod compensate;
pub mod correct;
pub mod diagnose;
pub mod formulas;
pub mod run;
pub mod sweep;

use clap::ValueEnum;
use std::path::PathBuf;
use toolmark::engine::RemovalEngine;
use toolmark::engine::cpu::CpuEngine;
use toolmark::engine::gpu::GpuEngine;
use toolmark::formats::measured::LengthUnit;
use toolmark::model::{EffectsFragment, FragmentError, Job, JobError};

/// A length unit as the command line names it (a measured file's coordinates or heights).
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Unit {
    Mm,
    Um,
    Nm,
}

impl Unit {
    pub fn length_unit(self) -> LengthUnit {
        match self {
            Unit::Mm => LengthUnit::Millimetre,
            Unit::Um => LengthUnit::Micrometre,
            Unit::Nm => LengthUnit::Nanometre,
        }
    }
}

#[derive(Clone, Copy, Default, PartialEq, Eq, ValueEnum)]
pub enum EngineChoice {
    /// The GPU on a hardware adapter; else the CPU (and say so).
    #[default]
    Auto,
    Cpu,
    Gpu,
}

/// Bad input (exit 2) or a failure while running (exit 1).
pub enum Failure {
    Input(String),
    Runtime(String),
}

pub fn load_job(path: Option<&PathBuf>) -> Result<Job, Failure> {
    match path {
        Some(path) => {
            Job::load(path).map_err(|err| Failure::Input(format!("{}: {err}", path.display())))
        }
        None => Ok(Job::default_job()),
    }
}

/// A job (`None`: the built-in default) with an effects fragment's tables appended to
/// its own when one is given; errors name the file they are in.
pub fn load_job_with_effects(
    path: Option<&PathBuf>,
    effects: Option<&PathBuf>,
) -> Result<Job, Failure> {
    let Some(fragment_path) = effects else {
        return load_job(path);
    };
    let in_fragment = |err: JobError| Failure::Input(format!("{}: {err}", fragment_path.display()));
    let fragment = EffectsFragment::load(fragment_path).map_err(in_fragment)?;
    Job::load_with_fragment(path.map(PathBuf::as_path), &fragment).map_err(|err| match err {
        FragmentError::Fragment(err) => in_fragment(err),
        FragmentError::Job(err) => Failure::Input(match path {
            Some(path) => format!("{}: {err}", path.display()),
            None => format!("the built-in default job: {err}"),
        }),
    })
}

/// The engine a command runs on. `auto`: the GPU engine on a hardware adapter; the CPU
/// engine where the only adapter is a software rasteriser (Mesa lavapipe runs the
/// kernels on the same cores, slower than the native f64 engine) or there is none,
/// saying so. Every process has a GPU kernel, so the choice no longer depends on the
/// job.
pub fn open_engine(choice: EngineChoice, _job: &Job) -> Result<Box<dyn RemovalEngine>, Failure> {
    match choice {
        EngineChoice::Cpu => Ok(Box::new(CpuEngine)),
        EngineChoice::Gpu => GpuEngine::new()
            .map(|engine| Box::new(engine) as Box<dyn RemovalEngine>)
            .map_err(|err| Failure::Runtime(format!("--engine gpu: {err}"))),
        EngineChoice::Auto => match GpuEngine::new() {
            Ok(engine) if engine.is_software() => {
                eprintln!(
                    "{} is a software rasteriser, slower here than the CPU engine: using the CPU engine (--engine gpu uses it anyway)",
                    engine.info().adapter
                );
                Ok(Box::new(CpuEngine))
            }
            Ok(engine) => Ok(Box::new(engine)),
            Err(err) => {
                eprintln!("{err}\nusing the CPU engine instead");
                Ok(Box::new(CpuEngine))
            }
        },
    }
}

/// A file-name-safe form of the job name.
pub fn slug(name: &str) -> String {
    let slug: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    let slug = slug
        .split('-')
        .filter(|part| !part.is_empty())
        .collect::<Vec<_>>()
        .join("-");
    if slug.is_empty() { "job".into() } else { slug }
}

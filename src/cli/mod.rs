//! The command line's subcommands and what they share.

pub mod compare;
pub mod compensate;
pub mod correct;
pub mod diagnose;
pub mod formulas;
pub mod run;

use clap::ValueEnum;
use std::path::PathBuf;
use toolmark::engine::RemovalEngine;
use toolmark::engine::cpu::CpuEngine;
use toolmark::engine::gpu::GpuEngine;
use toolmark::io::job::Job;

#[derive(Clone, Copy, Default, PartialEq, Eq, ValueEnum)]
pub enum EngineChoice {
    /// The GPU when an adapter is found, else the CPU (and say so).
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

pub fn open_engine(choice: EngineChoice, job: &Job) -> Result<Box<dyn RemovalEngine>, Failure> {
    if choice == EngineChoice::Auto && !GpuEngine::runs(&job.process) {
        eprintln!("the GPU engine does not run this process yet: using the CPU engine");
        return Ok(Box::new(CpuEngine));
    }
    match choice {
        EngineChoice::Cpu => Ok(Box::new(CpuEngine)),
        EngineChoice::Gpu => GpuEngine::new()
            .map(|engine| Box::new(engine) as Box<dyn RemovalEngine>)
            .map_err(|err| Failure::Runtime(format!("--engine gpu: {err}"))),
        EngineChoice::Auto => match GpuEngine::new() {
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

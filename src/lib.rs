//! toolmark: GPU-accelerated machined-surface simulation.
//!
//! Data flows one way: job → process (+effects) → poses → engine → field →
//! analysis → outputs. Modules follow that flow:
//! - [`geometry`]: nominal surfaces and tools (pure f64 math)
//! - [`process`]: kinematics, machine motion → tool poses
//! - [`effects`]: the setup and tool errors that make a real part differ
//! - [`field`]: the normal-dexel grid and its machined result
//! - [`engine`]: material removal, CPU (f64 reference) and GPU (WGSL via wgpu)
//! - [`analysis`]: deviation, scallop, profile and map products
//! - [`formulas`]: closed-form references (the tests' oracles)
//! - [`io`]: job files and output writers
//! - [`run`]: the pipeline that ties them together
//!
//! Beside the pipeline, each reading its results:
//! - [`diagnose`]: the sim-to-real diagnosis of a measured part (registration, candidate
//!   effects, fits, acceptance by prediction, the verdict)
//! - [`synth`]: measured-like data made apart from the diagnosis's forward model (the
//!   withheld suite's parts and instrument)
//! - [`compensate`]: the machining–measurement–compensation loop (the next path moved
//!   along the normal by the measured form error)
//! - [`correct`]: the lens generator's set-up corrected from the part it made
//! - [`bench`]: `toolmark bench`, throughput against a reference measured in the same run
//! - [`numeric`]: the shared numerics (golden section, least squares, bounded
//!   Levenberg–Marquardt, quantiles)

pub mod analysis;
pub mod bench;
pub mod compensate;
pub mod correct;
pub mod diagnose;
pub mod effects;
pub mod engine;
pub mod field;
pub mod formulas;
pub mod geometry;
pub mod io;
pub mod numeric;
pub mod process;
pub mod run;
pub mod synth;

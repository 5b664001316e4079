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

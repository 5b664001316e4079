//! toolmark: GPU-accelerated machined-surface simulation.
//!
//! Data flows one way; each room imports only the rooms above it in this list:
//! - [`numeric`]: the shared numerics (golden section, least squares, bounded
//!   Levenberg–Marquardt, quantiles)
//! - [`geometry`]: nominal surfaces, tools and cutters, and the closed forms the tests
//!   hold the engines to (`geometry::formulas`) — pure f64 math
//! - [`field`]: the normal-dexel grid and its machined result
//! - [`formats`]: file formats read and written (measured data, NC text, EXR), and the
//!   one atomic way every file is written
//! - [`process`]: kinematics and the machine's and tool's errors (`process::effects`)
//!   → tool poses
//! - [`model`]: the job: TOML → checked job with every default filled in
//! - [`engine`]: material removal per process, CPU (f64 twin) and GPU (WGSL via wgpu)
//! - [`analysis`]: deviation, scallop, protrusion, profile and map products
//! - [`pipeline`]: job → scenes → engine → field → analysis
//! - [`output`]: writers of what the pipeline and analysis computed (EXR, PNG, CSV,
//!   JSON, HTML, NC)
//!
//! Beside the pipeline, each reading its results:
//! - [`diagnose`]: the sim-to-real diagnosis of a measured part (registration, candidate
//!   effects, fits, acceptance by prediction, the verdict), with `diagnose::synth`
//!   (measured-like data made apart from the diagnosis's forward model) and
//!   `diagnose::withheld` (the suite that scores it)
//! - [`loops`]: compensation and set-up correction over repeated runs
//! - [`bench`]: `toolmark bench`, throughput against a reference measured in the same run

pub mod analysis;
pub mod bench;
pub mod diagnose;
pub mod engine;
pub mod field;
pub mod formats;
pub mod geometry;
pub mod loops;
pub mod model;
pub mod numeric;
pub mod output;
pub mod pipeline;
pub mod process;

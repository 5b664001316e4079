//! Nominal surfaces and tools: pure f64 geometry, no knowledge of processes or GPUs.

pub mod cup_wheel;
pub mod cutter;
pub mod disc_cutter;
pub mod formulas;
pub mod milling_tool;
pub mod surface;
pub mod tool;

pub use surface::{Form, MeridianArcLength, SurfaceOfRevolution};
pub use tool::ArcNoseTool;

//! Material removal: one trait, two engines with the same semantics — `cpu` (f64,
//! the reference) and `gpu` (WGSL compute through wgpu, f32 in local frames).

pub mod cpu;
pub mod cpu_generating;
pub mod cpu_milling;
pub mod cpu_turning;
pub mod cpu_turning_scalar;
pub mod generating_scene;
pub mod gpu;
pub mod milling_scene;
pub mod milling_search;
pub mod scene;

pub use generating_scene::GeneratingScene;
pub use milling_scene::MillingScene;
pub use scene::TurningScene;

use crate::field::{DexelField, PolarGrid};

/// One cutting pass's worth of removal work, prepared for the engines.
#[derive(Debug, Clone)]
pub enum Scene {
    Turning(TurningScene),
    Generating(GeneratingScene),
    Milling(MillingScene),
}

impl Scene {
    pub fn grid(&self) -> &PolarGrid {
        match self {
            Scene::Turning(scene) => &scene.grid,
            Scene::Generating(scene) => &scene.grid,
            Scene::Milling(scene) => &scene.grid,
        }
    }

    /// Dexel–pass evaluations: the work measure for throughput.
    pub fn pair_count(&self) -> u64 {
        match self {
            Scene::Turning(scene) => scene.pair_count(),
            Scene::Generating(scene) => scene.pair_count(),
            Scene::Milling(scene) => scene.pair_count(),
        }
    }

    /// How far apart the pass ids of consecutive scenes must start so they stay distinct.
    pub fn pass_id_span(&self) -> u32 {
        match self {
            Scene::Turning(scene) => scene.rev_count * scene::PASS_ID_STRIDE,
            Scene::Generating(_) | Scene::Milling(_) => 0,
        }
    }
}

/// What ran a removal: recorded in every output.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EngineInfo {
    /// "cpu" or "gpu".
    pub kind: String,
    /// Adapter name (GPU) or processor description (CPU).
    pub adapter: String,
    pub backend: String,
    pub driver: String,
    /// e.g. "DiscreteGpu", "Cpu" (a software rasteriser such as lavapipe), "host".
    pub device_type: String,
}

/// Progress callback: `(samples finished, samples in total)`.
pub type Progress<'a> = &'a (dyn Fn(u64, u64) + Sync);

#[derive(Debug)]
pub struct EngineError(pub String);

impl std::fmt::Display for EngineError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for EngineError {}

pub trait RemovalEngine {
    fn info(&self) -> EngineInfo;
    /// Removes material for every sample of the scene's grid.
    fn remove(&mut self, scene: &Scene, progress: Progress<'_>) -> Result<DexelField, EngineError>;
}

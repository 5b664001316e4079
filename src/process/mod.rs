//! Kinematics: each process maps the machine's motion to tool poses in the workpiece frame.

pub mod compensation;
pub mod nc_path;
pub mod pose_table;
pub mod turning;

pub use compensation::NormalCorrection;
pub use nc_path::{NcPath, NcReference};
pub use pose_table::{PoseTable, ToolPose};
pub use turning::{FeedAlong, TurningMode, TurningSpiral};

use crate::geometry::{ArcNoseTool, MeridianArcLength, SurfaceOfRevolution};

/// Where a turning job's tool path comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum TurningPath {
    /// A spiral generated from the surface, feed and mode.
    Spiral(TurningSpiral),
    /// The cutting passes of an NC program.
    Nc(NcPath),
}

impl TurningPath {
    pub fn mode(&self) -> TurningMode {
        match self {
            TurningPath::Spiral(spiral) => spiral.mode,
            TurningPath::Nc(_) => TurningMode::Xz,
        }
    }

    pub fn stock_allowance_mm(&self) -> f64 {
        match self {
            TurningPath::Spiral(spiral) => spiral.stock_allowance_mm,
            TurningPath::Nc(nc) => nc.stock_allowance_mm,
        }
    }

    /// Half-width of the band about the nominal surface in which the path's nominal cuts
    /// lie (sizes the engines' reach test).
    pub fn cut_band_mm(&self) -> f64 {
        match self {
            TurningPath::Spiral(spiral) => spiral.target_offset_mm().abs(),
            TurningPath::Nc(nc) => nc.cut_band_mm,
        }
    }

    /// Typical spacing of neighbouring passes near the axis (the scallop period there).
    pub fn pass_spacing_mm(&self) -> f64 {
        match self {
            TurningPath::Spiral(spiral) => spiral.feed_per_rev_mm,
            TurningPath::Nc(nc) => nc.pass_spacing_mm,
        }
    }

    /// Largest radius the path's cutting point reaches (for tables over the surface).
    pub fn outer_radius_mm(&self) -> f64 {
        match self {
            TurningPath::Spiral(spiral) => spiral.start_radius_mm,
            TurningPath::Nc(nc) => nc.outer_contact_radius_mm,
        }
    }

    /// The pose tables the machine runs, one per cutting pass.
    pub fn pose_tables(
        &self,
        surface: &SurfaceOfRevolution,
        meridian: &MeridianArcLength,
        tool: &ArcNoseTool,
    ) -> Vec<PoseTable> {
        match self {
            TurningPath::Spiral(spiral) => vec![spiral.pose_table(surface, meridian, tool)],
            TurningPath::Nc(nc) => nc.tables.clone(),
        }
    }
}

//! Kinematics: each process maps the machine's motion to tool poses in the workpiece frame.

pub mod compensation;
pub mod effects;
pub mod generating;
pub mod milling;
pub mod nc_path;
pub mod pose_table;
pub mod turning;

pub use compensation::NormalCorrection;
pub use generating::{GeneratingSetup, PlungeAxis};
pub use milling::{MillingPathKind, MillingSetup};
pub use nc_path::{NcPath, NcReference};
pub use pose_table::{PoseTable, ToolPose};
pub use turning::{FeedAlong, TurningMode, TurningSpiral};

use crate::geometry::{ArcNoseTool, MeridianArcLength, SurfaceOfRevolution};
use crate::process::effects::{GeneratingEffects, MillingEffects, TurningEffects};

/// A job's machining process.
#[derive(Debug, Clone, PartialEq)]
pub enum Process {
    Turning(TurningProcess),
    Generating(GeneratingProcess),
    Milling(MillingProcess),
}

/// Single-point turning (XZ or XZB) with an arc-nosed tool.
#[derive(Debug, Clone, PartialEq)]
pub struct TurningProcess {
    pub tool: ArcNoseTool,
    pub path: TurningPath,
    /// Normal offsets applied to the path (empty: none).
    pub correction: NormalCorrection,
    pub effects: TurningEffects,
    pub spindle_rpm: Option<f64>,
    /// The program turned about the spindle axis by this angle (rad): the part is
    /// simulated as if rotated so that its azimuth `azimuth_offset_rad` lies at the
    /// grid's azimuth 0. Jobs run at 0; the diagnosis uses it to look along any azimuth
    /// of a spiral with few rows (a measured line's azimuth on the spiral is unknown).
    pub azimuth_offset_rad: f64,
}

/// Milling with an end mill or a disc cutter.
#[derive(Debug, Clone, PartialEq)]
pub struct MillingProcess {
    pub setup: MillingSetup,
    pub effects: MillingEffects,
}

/// Lens generating with a cup wheel.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratingProcess {
    pub setup: GeneratingSetup,
    pub effects: GeneratingEffects,
}

impl Process {
    pub fn turning(&self) -> Option<&TurningProcess> {
        match self {
            Process::Turning(turning) => Some(turning),
            _ => None,
        }
    }

    pub fn generating(&self) -> Option<&GeneratingProcess> {
        match self {
            Process::Generating(generating) => Some(generating),
            _ => None,
        }
    }

    pub fn milling(&self) -> Option<&MillingProcess> {
        match self {
            Process::Milling(milling) => Some(milling),
            _ => None,
        }
    }

    /// Largest radius the process's cuts reach (for tables over the surface).
    pub fn outer_radius_mm(&self) -> f64 {
        match self {
            Process::Turning(turning) => turning.path.outer_radius_mm(),
            Process::Generating(generating) => generating.setup.reach_radius_mm(),
            Process::Milling(milling) => milling.setup.contact_radius_mm,
        }
    }

    /// Spacing of the passes near the axis (turning feed, milling step-over); `None`
    /// for generating, whose marks run across the rings rather than along the meridian.
    pub fn pass_spacing_mm(&self) -> Option<f64> {
        match self {
            Process::Turning(turning) => Some(turning.path.pass_spacing_mm()),
            Process::Milling(milling) => Some(milling.setup.stepover_mm),
            Process::Generating(_) => None,
        }
    }
}

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

    /// The median radial feed per revolution between radii `from_mm` and `to_mm` (the
    /// nominal spacing where the path has no revolution there).
    pub fn median_feed_mm(&self, from_mm: f64, to_mm: f64) -> f64 {
        match self {
            TurningPath::Spiral(spiral) => spiral.feed_per_rev_mm,
            TurningPath::Nc(nc) => {
                let mut feeds: Vec<f64> = nc
                    .tables
                    .iter()
                    .flat_map(PoseTable::radial_feeds_mm)
                    .filter(|(r, f)| (from_mm..=to_mm).contains(r) && *f > 1e-6)
                    .map(|(_, f)| f)
                    .collect();
                feeds.sort_by(f64::total_cmp);
                feeds
                    .get(feeds.len() / 2)
                    .copied()
                    .unwrap_or(nc.pass_spacing_mm)
            }
        }
    }

    /// The smallest radial feed per revolution between radii `from_mm` and `to_mm`
    /// (programs may vary it with radius); the nominal spacing when none is found there.
    pub fn smallest_feed_mm(&self, from_mm: f64, to_mm: f64) -> f64 {
        match self {
            TurningPath::Spiral(spiral) => spiral.feed_per_rev_mm,
            TurningPath::Nc(nc) => nc
                .tables
                .iter()
                .flat_map(PoseTable::radial_feeds_mm)
                .filter(|(r, f)| (from_mm..=to_mm).contains(r) && *f > 1e-6)
                .map(|(_, f)| f)
                .reduce(f64::min)
                .unwrap_or(nc.pass_spacing_mm),
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

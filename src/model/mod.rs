//! Job files (TOML, `version = 1`): parsing, defaults and validation.
//!
//! Parsing rejects unknown fields and wrong types (serde, with the file position);
//! validation then checks every value against its allowed range and the physics
//! (sag defined over the aperture, feed the nose can cover, tool that fits the
//! curvature, edge that reaches the slope in XZ) and names the field in its error.
//! Lengths are in mm unless the name says otherwise; files named in a job are read
//! relative to the job file's folder.

mod builder;
mod effects;
mod generating;
mod milling;
mod process;
pub mod resources;
mod surface;

pub use effects::{
    AngleErrorSpec, CentreHeightSpec, DirectionSpec, DriftSpec, EffectKind, EffectSpec, ErrorSpec,
    HarmonicSpec, HarmonicsSpec, OffsetSpec, RunoutSpec, SpringBackSpec, TiltHarmonicSpec,
    TiltHarmonicsSpec, TramSpec, VibrationSpec, WearSpec, generating_effects, milling_effects,
    turning_effects,
};
pub use surface::MAX_SLOPE_DEG;

use crate::geometry::surface::EVEN_TERMS;
use crate::geometry::{Form, MeridianArcLength, SurfaceOfRevolution};
use crate::process::{FeedAlong, NcReference, PlungeAxis, Process, TurningMode};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};

/// The built-in default job: the seed-002 asphere turned XZ (`toolmark run` with no file).
pub const DEFAULT_JOB_TOML: &str = include_str!("../../examples/asphere_xz.toml");

pub const JOB_VERSION: u32 = 1;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobFile {
    pub version: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    pub surface: SurfaceSpec,
    pub tool: ToolSpec,
    pub process: ProcessSpec,
    #[serde(default)]
    pub grid: GridSpec,
    #[serde(default)]
    pub output: OutputSpec,
    /// Departures from the nominal process (see `effects`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<EffectSpec>,
}

impl JobFile {
    /// A job file's text as its types (no validation yet). A wrong value inside the
    /// `[surface]`, `[tool]` or `[process]` table is reported against its key: serde
    /// reads a kind-tagged table whole, and its own message names only the table.
    pub fn from_toml_str(text: &str) -> Result<JobFile, JobError> {
        toml::from_str(text).map_err(|err| read_error(text, err, "job"))
    }

    /// The same file with the generator set to an inclination and a cutter offset (what
    /// `toolmark correct` writes); an error for another process.
    pub fn with_generator_setting(
        mut self,
        inclination_deg: f64,
        cutter_offset_mm: f64,
    ) -> Result<JobFile, JobError> {
        let ProcessSpec::Generating(spec) = &mut self.process else {
            return Err(error(
                "process.kind",
                "a generator's setting applies to process.kind = \"generating\" only",
            ));
        };
        spec.inclination_deg = Some(inclination_deg);
        spec.cutter_offset_mm = Some(cutter_offset_mm);
        Ok(self)
    }

    /// The same file with a turning job's normal correction table (what
    /// `toolmark compensate` writes); an error for another process.
    pub fn with_compensation(mut self, table: PathBuf) -> Result<JobFile, JobError> {
        let ProcessSpec::Turning(spec) = &mut self.process else {
            return Err(error(
                "process.kind",
                "a normal correction applies to process.kind = \"turning\" only",
            ));
        };
        spec.compensation = Some(table);
        Ok(self)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SurfaceKind {
    Plane,
    Sphere,
    Asphere,
    /// A circular cylinder with its axis along Y (milling): `radius_mm`, `form`,
    /// `aperture_diameter_mm` the width across the axis, `length_mm` along it.
    Cylinder,
    /// The surface an ideal tool cuts along the job's NC program (when no design is known).
    FromPath,
}

/// The `[surface]` table, one kind of surface per variant: a key another kind uses is
/// refused as an unknown field of this one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SurfaceSpec {
    Plane(PlaneSpec),
    Sphere(SphereSpec),
    Asphere(AsphereSpec),
    /// A circular cylinder with its axis along Y (milling): `aperture_diameter_mm` the
    /// width across the axis, `length_mm` along it.
    Cylinder(CylinderSpec),
    /// The surface an ideal tool cuts along the job's NC program (when no design is known).
    FromPath(PlaneSpec),
}

impl SurfaceSpec {
    pub fn kind(&self) -> SurfaceKind {
        match self {
            SurfaceSpec::Plane(_) => SurfaceKind::Plane,
            SurfaceSpec::Sphere(_) => SurfaceKind::Sphere,
            SurfaceSpec::Asphere(_) => SurfaceKind::Asphere,
            SurfaceSpec::Cylinder(_) => SurfaceKind::Cylinder,
            SurfaceSpec::FromPath(_) => SurfaceKind::FromPath,
        }
    }

    /// The aperture's outer and inner diameters as given (a cylinder has no inner one).
    pub fn aperture_diameters_mm(&self) -> (Option<f64>, f64) {
        match self {
            SurfaceSpec::Plane(p) | SurfaceSpec::FromPath(p) => {
                (p.aperture_diameter_mm, p.inner_diameter_mm)
            }
            SurfaceSpec::Sphere(s) => (s.aperture_diameter_mm, s.inner_diameter_mm),
            SurfaceSpec::Asphere(a) => (a.aperture_diameter_mm, a.inner_diameter_mm),
            SurfaceSpec::Cylinder(c) => (c.aperture_diameter_mm, 0.0),
        }
    }

    /// The same surface with another aperture (what a derived grid or a path's finished
    /// part resolves to).
    pub fn with_aperture(mut self, outer_diameter_mm: f64, inner_diameter_mm: f64) -> SurfaceSpec {
        let (outer, inner) = match &mut self {
            SurfaceSpec::Plane(p) | SurfaceSpec::FromPath(p) => {
                (&mut p.aperture_diameter_mm, Some(&mut p.inner_diameter_mm))
            }
            SurfaceSpec::Sphere(s) => (&mut s.aperture_diameter_mm, Some(&mut s.inner_diameter_mm)),
            SurfaceSpec::Asphere(a) => {
                (&mut a.aperture_diameter_mm, Some(&mut a.inner_diameter_mm))
            }
            SurfaceSpec::Cylinder(c) => (&mut c.aperture_diameter_mm, None),
        };
        *outer = Some(outer_diameter_mm);
        if let Some(inner) = inner {
            *inner = inner_diameter_mm;
        }
        self
    }
}

/// `[surface] kind = "plane"` (or `"from_path"`): the aperture only.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// Required, except for `from_path` (default: the part the path finishes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aperture_diameter_mm: Option<f64>,
    /// A central hole not simulated (default 0).
    #[serde(default)]
    pub inner_diameter_mm: f64,
}

/// `[surface] kind = "sphere"`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereSpec {
    /// Which side faces the tool.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<Form>,
    /// Sphere radius.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_mm: Option<f64>,
    /// Required, except for `from_path` (default: the part the path finishes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aperture_diameter_mm: Option<f64>,
    /// A central hole not simulated (default 0).
    #[serde(default)]
    pub inner_diameter_mm: f64,
}

/// `[surface] kind = "asphere"`: an even asphere.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AsphereSpec {
    /// Which side faces the tool.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<Form>,
    /// Base (paraxial) radius R0 = 1/c.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_radius_mm: Option<f64>,
    /// Conic constant k (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub conic: Option<f64>,
    /// Even coefficients: sag += a4·r⁴ + a6·r⁶ + … + a20·r²⁰ (r in mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a4: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a6: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a8: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a10: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a12: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a14: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a16: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a18: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a20: Option<f64>,
    /// Required, except for `from_path` (default: the part the path finishes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aperture_diameter_mm: Option<f64>,
    /// A central hole not simulated (default 0).
    #[serde(default)]
    pub inner_diameter_mm: f64,
}

impl AsphereSpec {
    fn even_coefficients(&self) -> [(&'static str, Option<f64>); EVEN_TERMS] {
        [
            ("a4", self.a4),
            ("a6", self.a6),
            ("a8", self.a8),
            ("a10", self.a10),
            ("a12", self.a12),
            ("a14", self.a14),
            ("a16", self.a16),
            ("a18", self.a18),
            ("a20", self.a20),
        ]
    }
}

/// `[surface] kind = "cylinder"`: its axis along Y.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CylinderSpec {
    /// Which side faces the tool.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<Form>,
    /// Radius.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_mm: Option<f64>,
    /// The width across the axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aperture_diameter_mm: Option<f64>,
    /// The length along the axis (Y).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_mm: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ToolKind {
    /// A single-point turning tool with a circular-arc nose.
    ArcNose,
    /// A lens generator's cup (ring) wheel.
    CupWheel,
    /// Milling: a ball-end mill (diameter_mm).
    BallEnd,
    /// Milling: a bull-nose (toroidal) end mill (diameter_mm, corner_radius_mm).
    BullNose,
    /// Milling: a flat-end mill (diameter_mm).
    FlatEnd,
    /// Milling: a disc cutter with straight-edged inserts (diameter_mm at the inserts,
    /// insert_length_mm, side_rake_deg, lead_angle_deg).
    Disc,
}

/// The `[tool]` table, one kind of tool per variant: a key another kind uses is refused
/// as an unknown field of this one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ToolSpec {
    /// A single-point turning tool with a circular-arc nose.
    ArcNose(ArcNoseSpec),
    /// A lens generator's cup (ring) wheel.
    CupWheel(CupWheelSpec),
    /// Milling: a ball-end mill (diameter_mm).
    BallEnd(MillToolSpec),
    /// Milling: a bull-nose (toroidal) end mill (diameter_mm, corner_radius_mm).
    BullNose(MillToolSpec),
    /// Milling: a flat-end mill (diameter_mm).
    FlatEnd(MillToolSpec),
    /// Milling: a disc cutter with straight-edged inserts (diameter_mm at the inserts,
    /// insert_length_mm, side_rake_deg, lead_angle_deg).
    Disc(MillToolSpec),
}

impl ToolSpec {
    pub fn kind(&self) -> ToolKind {
        match self {
            ToolSpec::ArcNose(_) => ToolKind::ArcNose,
            ToolSpec::CupWheel(_) => ToolKind::CupWheel,
            ToolSpec::BallEnd(_) => ToolKind::BallEnd,
            ToolSpec::BullNose(_) => ToolKind::BullNose,
            ToolSpec::FlatEnd(_) => ToolKind::FlatEnd,
            ToolSpec::Disc(_) => ToolKind::Disc,
        }
    }

    /// A milling tool's fields (None for a turning tool or a cup wheel).
    pub fn milling(&self) -> Option<&MillToolSpec> {
        match self {
            ToolSpec::BallEnd(m)
            | ToolSpec::BullNose(m)
            | ToolSpec::FlatEnd(m)
            | ToolSpec::Disc(m) => Some(m),
            ToolSpec::ArcNose(_) | ToolSpec::CupWheel(_) => None,
        }
    }

    /// A turning tool's measured edge, if it has one.
    pub fn edge_profile(&self) -> Option<&Path> {
        match self {
            ToolSpec::ArcNose(a) => a.edge_profile.as_deref(),
            _ => None,
        }
    }

    fn milling_mut(&mut self) -> Option<&mut MillToolSpec> {
        match self {
            ToolSpec::BallEnd(m)
            | ToolSpec::BullNose(m)
            | ToolSpec::FlatEnd(m)
            | ToolSpec::Disc(m) => Some(m),
            ToolSpec::ArcNose(_) | ToolSpec::CupWheel(_) => None,
        }
    }
}

/// `[tool] kind = "arc_nose"`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArcNoseSpec {
    /// The nose radius the path assumes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nose_radius_mm: Option<f64>,
    /// Angle subtended by the edge arc (the edge spans ±half about the tip), (0, 180].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub included_angle_deg: Option<f64>,
    /// Flank clearance angle (default 10°), (0, 45].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance_angle_deg: Option<f64>,
    /// A measured edge (`X,Y,Z` rows in mm, the D906 form): the real radius and radial
    /// deviation the tool cuts with, set at its tip.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edge_profile: Option<PathBuf>,
    /// Moving-average width over the measured edge points (default 51, odd).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edge_profile_smoothing_points: Option<u32>,
    /// Whether the measured edge's counter-clockwise direction runs toward the part's
    /// axis (true) or its rim (false, default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edge_profile_mirror: Option<bool>,
}

/// `[tool] kind = "cup_wheel"`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CupWheelSpec {
    /// Radius of the cutting circle (R_t).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cutting_radius_mm: Option<f64>,
    /// Radius of the edge's profile about the cutting circle (r).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edge_radius_mm: Option<f64>,
    /// Discrete cutting edges; 0 (default) = a continuous edge.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub teeth: Option<u32>,
}

/// `[tool] kind = "ball_end" | "bull_nose" | "flat_end" | "disc"`: a corner radius only on a
/// bull-nose, the inserts' fields only on a disc (refused by name on the others).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MillToolSpec {
    /// The tool's diameter (end mills: outer; disc: at the inserts' middles).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diameter_mm: Option<f64>,
    /// Cutting edges (default 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub teeth: Option<u32>,
    /// Bull-nose: the corner radius, (0, diameter/2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub corner_radius_mm: Option<f64>,
    /// Disc: length of each straight edge.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub insert_length_mm: Option<f64>,
    /// Disc: the edges' side rake λ, [0, 80].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub side_rake_deg: Option<f64>,
    /// Disc: the edges' lead from the radial direction, (0, 180), 90 = parallel to the axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lead_angle_deg: Option<f64>,
    /// Milling with feed per tooth: "edges" (default) — each tooth's edge cuts a point
    /// where it passes it, sweeping its trochoid — or "body": the whole tool at each
    /// tooth's position (faster).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flutes: Option<FluteModel>,
    /// The flutes' helix angle, constant lead, [0, 60) (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub helix_deg: Option<f64>,
    /// How far each tooth's edge stands beyond the nominal
    /// radius (mm, one per tooth, [0, diameter/10]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tooth_radial_runout_mm: Option<Vec<f64>>,
    /// How far each tooth's tip lies below the nominal tip along
    /// the axis (mm, one per tooth, [−diameter/10, diameter/10]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tooth_axial_runout_mm: Option<Vec<f64>>,
}

/// How a milling tool's teeth cut (`[tool] flutes`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FluteModel {
    Edges,
    Body,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProcessKind {
    Turning,
    Generating,
    Milling,
}

/// Unit of an NC program's lengths.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum NcUnits {
    #[serde(rename = "mm")]
    Millimetre,
    #[serde(rename = "um", alias = "µm")]
    Micrometre,
}

impl NcUnits {
    pub fn mm_per_unit(self) -> f64 {
        match self {
            NcUnits::Millimetre => 1.0,
            NcUnits::Micrometre => 1e-3,
        }
    }
}

/// The `[process]` table, one kind of process per variant (`kind = "turning" | "generating"
/// | "milling"`): a key another kind uses is refused as an unknown field of this one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ProcessSpec {
    Turning(TurningSpec),
    Generating(GeneratingSpec),
    Milling(MillingSpec),
}

impl ProcessSpec {
    /// The stock allowance and the depth of cut, where the kind has them.
    fn stock_and_depth(&self) -> (Option<f64>, Option<f64>) {
        match self {
            ProcessSpec::Turning(t) => (t.stock_allowance_mm, t.depth_of_cut_mm),
            ProcessSpec::Generating(g) => (g.stock_allowance_mm, None),
            ProcessSpec::Milling(m) => (m.stock_allowance_mm, m.depth_of_cut_mm),
        }
    }
}

/// `[process] kind = "turning"`: a generated spiral (XZ or XZB) or an NC program.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurningSpec {
    /// "xz" or "xzb".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode: Option<TurningMode>,
    /// Feed per spindle revolution; or give spindle_rpm and feed_mm_per_min.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feed_per_rev_mm: Option<f64>,
    /// Spindle speed (rev/min): with feed_mm_per_min instead of feed_per_rev_mm;
    /// vibrations given in Hz need it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spindle_rpm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feed_mm_per_min: Option<f64>,
    /// What the feed is measured along: "radial" (X, default) or "arc_length".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feed_along: Option<FeedAlong>,
    /// Material above the nominal surface before the pass (default 0.002 mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stock_allowance_mm: Option<f64>,
    /// Depth the pass cuts into the stock (default: the stock allowance).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_of_cut_mm: Option<f64>,
    /// Radius of the cutting point where the spiral starts (default: the aperture rim).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_radius_mm: Option<f64>,
    /// Radius where it ends (default 0, the centre).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_radius_mm: Option<f64>,
    /// An NC program (C-X-Z blocks) to run instead of a generated spiral.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nc_program: Option<PathBuf>,
    /// What the program's X/Z locate: "nose_centre" (default) or "tip".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nc_reference: Option<NcReference>,
    /// The feed mode a program that sets none starts in (a planner's bare `C X Z`
    /// block file): "inverse_time" (G93) or "per_minute" (G94).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nc_feed_mode: Option<crate::formats::nc::FeedMode>,
    /// Unit of the program's X and Z: "mm" (default) or "um".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nc_units: Option<NcUnits>,
    /// A normal correction (`radius_mm,normal_offset_nm` CSV, as `toolmark compensate`
    /// writes): the path cuts that much deeper along the surface normal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compensation: Option<PathBuf>,
}

/// `[process] kind = "generating"`: a cup wheel generating a sphere.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeneratingSpec {
    /// The wheel axis to workpiece axis, (0, 90) (default: the angle that
    /// generates the surface's radius).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inclination_deg: Option<f64>,
    /// The infeed direction, "z" (default) or "tool_axis".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plunge_axis: Option<PlungeAxis>,
    /// Wheel speed (rev/min; negative turns it the other way), default 3000.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool_rpm: Option<f64>,
    /// Workpiece speed (rev/min), default 10.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub workpiece_rpm: Option<f64>,
    /// Workpiece revolutions at the final depth, [1, 100], default 2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spark_out_revolutions: Option<f64>,
    /// Angle of tooth 0 past the circle's vertex point when the spark-out
    /// starts (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tooth_phase_deg: Option<f64>,
    /// A deliberate X offset of the wheel from the position that puts its
    /// circle through the axis (+ = away from the axis), default 0; `toolmark correct`
    /// writes it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cutter_offset_mm: Option<f64>,
    /// Material above the nominal surface before the pass (default 0.1 mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stock_allowance_mm: Option<f64>,
}

/// `[process] kind = "milling"`: a planned path of an end mill or a disc cutter.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MillingSpec {
    /// Spindle speed (rev/min): the cutting speed at the effective diameter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spindle_rpm: Option<f64>,
    /// Material above the nominal surface before the pass (default 0.01 mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stock_allowance_mm: Option<f64>,
    /// Depth the pass cuts into the stock (default: the stock allowance).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_of_cut_mm: Option<f64>,
    /// "raster", "spiral" or "constant_scallop".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<crate::process::MillingPathKind>,
    /// 3 (the tool axis stays vertical, default) or 5 (it follows the surface
    /// normal, leaned by lead_deg and tilt_deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axes: Option<u8>,
    /// Step between passes in XY (raster, spiral); or give scallop_mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stepover_mm: Option<f64>,
    /// The allowed scallop height (sets the step-over; constant_scallop keeps it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scallop_mm: Option<f64>,
    /// Raster pass direction from +X (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raster_angle_deg: Option<f64>,
    /// Lead λ of the tool axis from the normal toward the feed, [0, 90) (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lead_deg: Option<f64>,
    /// Tilt ω turning the lean about the normal, [−90, 90] (default 0; 90 = a
    /// lean across the feed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tilt_deg: Option<f64>,
    /// Lead at the path's end (varies linearly; default: lead_deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lead_end_deg: Option<f64>,
    /// Tilt at the path's end (default: tilt_deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tilt_end_deg: Option<f64>,
    /// Disc cutter: the turn ξ of its axis about the normal from square to the feed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub turn_deg: Option<f64>,
    /// Advance per tooth (0 = a continuous sweep, no feed marks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feed_per_tooth_mm: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Sample spacing along the meridian in µm (default: feed / 8).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_um: Option<f64>,
    /// Azimuth rows (default 64).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub azimuths: Option<u32>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Side of the top-view maps in pixels (default 512).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub map_pixels: Option<u32>,
}

/// An effects fragment: a TOML file holding only `[[effects]]` tables (and comments),
/// whose effects a run appends to its job's own (`toolmark run JOB --effects FILE`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectsFragment {
    #[serde(default)]
    pub effects: Vec<EffectSpec>,
}

impl EffectsFragment {
    pub fn from_toml_str(text: &str) -> Result<Self, JobError> {
        let table: toml::Table =
            toml::from_str(text).map_err(|err| error("effects", err.to_string()))?;
        if let Some(key) = table.keys().find(|key| *key != "effects") {
            return Err(error(
                key,
                "an effects file holds only [[effects]] tables (and comments); remove it",
            ));
        }
        toml::from_str(text).map_err(|err| read_error(text, err, "effects"))
    }

    pub fn load(path: &Path) -> Result<Self, JobError> {
        let text = std::fs::read_to_string(path)
            .map_err(|err| error("effects", format!("cannot read {}: {err}", path.display())))?;
        Self::from_toml_str(&text)
    }
}

/// Where a job run with an effects fragment went wrong.
#[derive(Debug, Clone, PartialEq)]
pub enum FragmentError {
    /// In the job itself (or its own effects).
    Job(JobError),
    /// In one of the fragment's tables (`effects[i]` counting within the fragment).
    Fragment(JobError),
}

/// A job error: the field (dotted path) and what is wrong with it.
#[derive(Debug, Clone, PartialEq)]
pub struct JobError {
    pub field: String,
    pub message: String,
}

impl fmt::Display for JobError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.message)
    }
}

impl std::error::Error for JobError {}

fn error(field: &str, message: impl Into<String>) -> JobError {
    JobError {
        field: field.to_string(),
        message: message.into(),
    }
}

/// A finite number in an allowed range, or an error naming the field and range.
fn check(
    field: &str,
    value: f64,
    min: f64,
    max: f64,
    min_inclusive: bool,
) -> Result<f64, JobError> {
    let low = if min_inclusive {
        value >= min
    } else {
        value > min
    };
    if !value.is_finite() || !low || value > max {
        let bracket = if min_inclusive { "[" } else { "(" };
        return Err(error(
            field,
            format!("{value} is out of range; allowed: a finite number in {bracket}{min}, {max}]"),
        ));
    }
    Ok(value)
}

/// A file named in the job, resolved against the job's folder and made absolute.
fn resolve_file(field: &str, base_dir: &Path, file: &Path) -> Result<PathBuf, JobError> {
    let path = base_dir.join(file);
    std::fs::canonicalize(&path)
        .map_err(|err| error(field, format!("cannot open {}: {err}", path.display())))
}

/// The spatial extent of the part that is simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aperture {
    pub inner_radius_mm: f64,
    pub outer_radius_mm: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    pub name: String,
    /// The nominal profile: revolved about Z, or extruded along Y (see `layout`).
    pub surface: SurfaceOfRevolution,
    pub aperture: Aperture,
    /// How the profile makes the part (polar: revolved; extruded: a cylinder).
    pub layout: crate::field::Layout,
    /// The process, its tool and effects.
    pub process: Process,
    pub pitch_mm: f64,
    pub azimuths: u32,
    pub map_pixels: u32,
    /// The job as given with every default filled in (written to the outputs).
    pub resolved: JobFile,
    /// Things that are allowed but worth knowing (e.g. a grid too coarse for scallops).
    pub warnings: Vec<String>,
}

/// Largest number of samples a job may ask for (host memory: ~12 bytes each, plus maps).
pub const MAX_SAMPLES: f64 = 4.0e8;

impl Job {
    /// Parses a job whose relative file names resolve against the current folder.
    pub fn from_toml_str(text: &str, default_name: &str) -> Result<Job, JobError> {
        Job::from_toml_in(text, default_name, Path::new("."))
    }

    /// Parses a job whose relative file names resolve against `base_dir`.
    pub fn from_toml_in(text: &str, default_name: &str, base_dir: &Path) -> Result<Job, JobError> {
        let file = JobFile::from_toml_str(text)?;
        Job::from_file(file, default_name, base_dir)
    }

    pub fn load(path: &Path) -> Result<Job, JobError> {
        let (text, name, base_dir) = read_job_file(path)?;
        Job::from_toml_in(&text, &name, base_dir)
    }

    /// Loads a job (`None`: the built-in default job) with an effects fragment's tables
    /// appended to its own, before validation: a calibration carried from one part to the
    /// next. The resolved job lists them all. An error in one of the fragment's tables is
    /// reported against the fragment, `effects[i]` counting within it.
    pub fn load_with_fragment(
        path: Option<&Path>,
        fragment: &EffectsFragment,
    ) -> Result<Job, FragmentError> {
        let (text, name, base_dir) = match path {
            Some(path) => read_job_file(path).map_err(FragmentError::Job)?,
            None => (
                DEFAULT_JOB_TOML.to_string(),
                "default".into(),
                Path::new("."),
            ),
        };
        let mut file = JobFile::from_toml_str(&text).map_err(FragmentError::Job)?;
        let own = file.effects.len();
        file.effects.extend(fragment.effects.iter().cloned());
        Job::from_file(file, &name, base_dir).map_err(|err| {
            let index = err
                .field
                .strip_prefix("effects[")
                .and_then(|rest| rest.split_once(']'))
                .and_then(|(index, rest)| Some((index.parse::<usize>().ok()?, rest)));
            match index {
                Some((index, rest)) if index >= own => FragmentError::Fragment(JobError {
                    field: format!("effects[{}]{rest}", index - own),
                    message: err.message,
                }),
                _ => FragmentError::Job(err),
            }
        })
    }

    pub fn default_job() -> Job {
        Job::from_toml_str(DEFAULT_JOB_TOML, "default").expect("the built-in default job is valid")
    }

    pub fn from_file(file: JobFile, default_name: &str, base_dir: &Path) -> Result<Job, JobError> {
        if file.version != JOB_VERSION {
            return Err(error(
                "version",
                format!("{} is not supported; allowed: {JOB_VERSION}", file.version),
            ));
        }
        let mut resolved = file.clone();
        let name = file
            .name
            .clone()
            .unwrap_or_else(|| default_name.to_string());
        check_name(&name)?;
        resolved.name = Some(name.clone());
        let mut warnings = Vec::new();

        let (surface, aperture, process) = match &file.process {
            ProcessSpec::Turning(spec) => {
                process::validate_turning(&file, spec, base_dir, &mut resolved, &mut warnings)?
            }
            ProcessSpec::Generating(spec) => {
                generating::validate_generating(&file, spec, &mut resolved, &mut warnings)?
            }
            ProcessSpec::Milling(spec) => {
                milling::validate_milling(&file, spec, &mut resolved, &mut warnings)?
            }
        };
        warn_deep_cut(&resolved.process, &mut warnings);
        let layout = match &file.surface {
            SurfaceSpec::Cylinder(cylinder) => {
                let length = required(
                    "surface.length_mm",
                    cylinder.length_mm,
                    "a finite number in (0, 10000]",
                )?;
                crate::field::Layout::Extruded {
                    length_mm: check("surface.length_mm", length, 0.0, 1e4, false)?,
                }
            }
            _ => crate::field::Layout::Polar,
        };
        let meridian = MeridianArcLength::new(
            &surface,
            aperture.outer_radius_mm.max(process.outer_radius_mm()),
        );
        if let Process::Turning(turning) = &process {
            process::check_revolutions(&turning.path, &meridian)?;
        }

        // Default pitch: eight samples per turning pass; for generating, 4000 rings
        // over the aperture (a pip of radius |e| needs samples well under |e|).
        let pitch_mm = match (file.grid.pitch_um, process.pass_spacing_mm()) {
            (Some(pitch), _) => check("grid.pitch_um", pitch, 0.0, 1e4, false)? * 1e-3,
            (None, Some(pass_spacing)) => pass_spacing / 8.0,
            (None, None) => aperture.outer_radius_mm / 4000.0,
        };
        let azimuths = file.grid.azimuths.unwrap_or(64);
        check_grid_size(&meridian, &aperture, layout, pitch_mm, azimuths)?;
        match &process {
            Process::Turning(_) | Process::Milling(_) => {
                let pass_spacing = process.pass_spacing_mm().unwrap_or(f64::INFINITY);
                if pitch_mm * 4.0 > pass_spacing {
                    warnings.push(format!(
                        "grid.pitch_um = {:.3} is coarser than a quarter of the pass spacing ({:.3} µm): scallops will not be resolved",
                        pitch_mm * 1e3,
                        pass_spacing * 1e3
                    ));
                }
            }
            Process::Generating(generating) => {
                generating::check_tooth_resolution(&generating.setup, azimuths, &mut warnings)
            }
        }
        resolved.grid = GridSpec {
            pitch_um: Some(pitch_mm * 1e3),
            azimuths: Some(azimuths),
        };
        let map_pixels = file.output.map_pixels.unwrap_or(512);
        if !(16..=8192).contains(&map_pixels) {
            return Err(error(
                "output.map_pixels",
                format!("{map_pixels} is out of range; allowed: 16 to 8192"),
            ));
        }
        resolved.output.map_pixels = Some(map_pixels);

        Ok(Job {
            name,
            surface,
            aperture,
            layout,
            process,
            pitch_mm,
            azimuths,
            map_pixels,
            resolved,
            warnings,
        })
    }

    /// The same job on another grid — an annulus of its aperture, a ring pitch, a number
    /// of rows — as the diagnosis's model and a synthetic measurement's fine grid
    /// simulate it. A new job, checked as a job's own grid is, whose resolved file says
    /// the grid it has: nothing edits a checked job.
    pub fn on_grid(
        &self,
        aperture: Aperture,
        pitch_mm: f64,
        azimuths: u32,
    ) -> Result<Job, JobError> {
        let (inner, outer) = (aperture.inner_radius_mm, aperture.outer_radius_mm);
        if !(0.0 <= inner && inner < outer && outer <= self.aperture.outer_radius_mm) {
            return Err(error(
                "surface.aperture_diameter_mm",
                format!(
                    "the annulus {inner:.6}–{outer:.6} mm is not within the job's aperture; allowed: 0 ≤ inner < outer ≤ {:.6} mm",
                    self.aperture.outer_radius_mm
                ),
            ));
        }
        let pitch_um = check("grid.pitch_um", pitch_mm * 1e3, 0.0, 1e4, false)?;
        check_grid_size(&self.meridian(), &aperture, self.layout, pitch_mm, azimuths)?;
        let mut job = self.clone();
        job.aperture = aperture;
        job.pitch_mm = pitch_mm;
        job.azimuths = azimuths;
        job.resolved.grid = GridSpec {
            pitch_um: Some(pitch_um),
            azimuths: Some(azimuths),
        };
        job.resolved.surface = job.resolved.surface.with_aperture(2.0 * outer, 2.0 * inner);
        Ok(job)
    }

    /// The meridian arc-length table over the aperture and the path (shared by both).
    pub fn meridian(&self) -> MeridianArcLength {
        MeridianArcLength::new(
            &self.surface,
            self.aperture
                .outer_radius_mm
                .max(self.process.outer_radius_mm()),
        )
    }

    /// Samples on the job's grid (rings × azimuths), as validation counts them.
    pub fn sample_count(&self) -> u64 {
        let samples = grid_samples(
            &self.meridian(),
            &self.aperture,
            self.layout,
            self.pitch_mm,
            self.azimuths,
        );
        samples as u64
    }

    /// Canonical JSON of the resolved job.
    pub fn canonical_json(&self) -> String {
        serde_json::to_string(&self.resolved).unwrap_or_default()
    }

    /// FNV-1a 64-bit hash of the canonical resolved job, as 16 hex digits.
    pub fn hash(&self) -> String {
        let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
        for byte in self.canonical_json().bytes() {
            hash ^= byte as u64;
            hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
        }
        format!("{hash:016x}")
    }
}

/// Rings over the meridian span times azimuth rows.
/// A grid's row count in range and its samples within `MAX_SAMPLES` (a job file's own
/// grid and a grid derived from a checked job alike).
fn check_grid_size(
    meridian: &MeridianArcLength,
    aperture: &Aperture,
    layout: crate::field::Layout,
    pitch_mm: f64,
    azimuths: u32,
) -> Result<(), JobError> {
    if !(1..=65_536).contains(&azimuths) {
        return Err(error(
            "grid.azimuths",
            format!("{azimuths} is out of range; allowed: 1 to 65536"),
        ));
    }
    let samples = grid_samples(meridian, aperture, layout, pitch_mm, azimuths);
    if samples > MAX_SAMPLES {
        return Err(error(
            "grid.pitch_um",
            format!(
                "{pitch} µm with {azimuths} azimuths gives {samples:.3e} samples, more than the {MAX_SAMPLES:.0e} allowed; raise grid.pitch_um or lower grid.azimuths",
                pitch = pitch_mm * 1e3
            ),
        ));
    }
    Ok(())
}

fn grid_samples(
    meridian: &MeridianArcLength,
    aperture: &Aperture,
    layout: crate::field::Layout,
    pitch_mm: f64,
    azimuths: u32,
) -> f64 {
    let meridian_span = match layout {
        crate::field::Layout::Polar => {
            meridian.arc_length_at(aperture.outer_radius_mm)
                - meridian.arc_length_at(aperture.inner_radius_mm)
        }
        crate::field::Layout::Extruded { .. } => {
            2.0 * meridian.arc_length_at(aperture.outer_radius_mm)
        }
    };
    (meridian_span / pitch_mm + 1.0).floor() * azimuths as f64
}

/// Longest job name accepted (it becomes a folder name and file metadata).
pub const MAX_NAME_CHARS: usize = 200;

/// A job name must fit a folder name and the outputs' metadata: at most
/// [`MAX_NAME_CHARS`] characters, no control characters.
fn check_name(name: &str) -> Result<(), JobError> {
    let length = name.chars().count();
    if length > MAX_NAME_CHARS {
        return Err(error(
            "name",
            format!("{length} characters; allowed: 1 to {MAX_NAME_CHARS}"),
        ));
    }
    if name.trim().is_empty() || name.chars().any(char::is_control) {
        return Err(error(
            "name",
            "empty or holding control characters; allowed: 1 to 200 printable characters",
        ));
    }
    Ok(())
}

/// A depth of cut well beyond the stock allowance cuts below the nominal surface: allowed
/// (a deliberate undersize), but said.
fn warn_deep_cut(resolved: &ProcessSpec, warnings: &mut Vec<String>) {
    if let (Some(stock), Some(depth)) = resolved.stock_and_depth()
        && depth > 2.0 * stock
        && depth - stock > 1e-4
    {
        warnings.push(format!(
            "process.depth_of_cut_mm = {depth} mm is {:.0}× the stock allowance ({stock} mm): the tool cuts {:.1} µm below the nominal surface",
            depth / stock.max(f64::MIN_POSITIVE),
            (depth - stock) * 1e3
        ));
    }
}

/// A job file's text, its default name (the file's stem) and the folder its file names
/// resolve against.
fn read_job_file(path: &Path) -> Result<(String, String, &Path), JobError> {
    let text = std::fs::read_to_string(path)
        .map_err(|err| error("job", format!("cannot read {}: {err}", path.display())))?;
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
    let base_dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    Ok((text, stem.unwrap_or_else(|| "job".into()), base_dir))
}

/// The error of reading `text` whole (`err`), named by the key of a kind-tagged table
/// that holds it ([`tagged_field_error`]), else by `whole`.
fn read_error(text: &str, err: toml::de::Error, whole: &str) -> JobError {
    match tagged_field_error(text) {
        Some((field, message)) => error(&field, message.unwrap_or_else(|| err.to_string())),
        None => error(whole, err.to_string()),
    }
}

/// Which key of a kind-tagged table (`surface.radius_mm`, `effects[1].drift_mm`) holds
/// a value its kind's fields refuse, and what its kind's struct says of it (the whole
/// file's message points at the table's first line: "TOML parse error at line 1,
/// column 1"): the table is read again alone, as its kind's own struct. An unknown
/// kind names `kind` (the whole file's message lists the kinds).
fn tagged_field_error(text: &str) -> Option<(String, Option<String>)> {
    let table: toml::Table = toml::from_str(text).ok()?;
    let single = ["surface", "tool", "process"]
        .into_iter()
        .filter_map(|name| Some((name.to_string(), name, table.get(name)?.as_table()?)));
    let effects = table
        .get("effects")
        .and_then(|list| list.as_array())
        .into_iter()
        .flatten()
        .enumerate()
        .filter_map(|(i, effect)| Some((format!("effects[{i}]"), "effects", effect.as_table()?)));
    single.chain(effects).find_map(|(field, name, section)| {
        let mut section = section.clone();
        let kind = section.remove("kind")?.as_str()?.to_string();
        if !known_kind(name, &kind) {
            return Some((format!("{field}.kind"), None));
        }
        let alone = toml::to_string(&section).ok()?;
        let err = kind_fields_error(name, &kind, &alone)?;
        // An unknown key is named in the message; a wrong value by the line it is on.
        let key = match err.message().strip_prefix("unknown field `") {
            Some(rest) => rest.split('`').next()?,
            None => {
                let start = err.span()?.start;
                let line = alone[..start].rsplit('\n').next().unwrap_or_default();
                line.split('=').next()?.trim()
            }
        };
        (!key.is_empty() && !key.starts_with('['))
            .then(|| (format!("{field}.{key}"), Some(err.message().to_string())))
    })
}

/// Whether `kind` names a kind of the `table`'s (`surface`, `tool`, `process`, `effects`).
fn known_kind(table: &str, kind: &str) -> bool {
    fn names<T: serde::de::DeserializeOwned>(kind: &str) -> bool {
        let name = serde::de::value::StrDeserializer::<serde::de::value::Error>::new(kind);
        T::deserialize(name).is_ok()
    }
    match table {
        "surface" => names::<SurfaceKind>(kind),
        "tool" => names::<ToolKind>(kind),
        "process" => names::<ProcessKind>(kind),
        _ => names::<EffectKind>(kind),
    }
}

/// The error of reading `text` as the fields of `table`'s `kind`.
fn kind_fields_error(table: &str, kind: &str, text: &str) -> Option<toml::de::Error> {
    fn read<T: serde::de::DeserializeOwned>(text: &str) -> Option<toml::de::Error> {
        toml::from_str::<T>(text).err()
    }
    match (table, kind) {
        ("surface", "plane" | "from_path") => read::<PlaneSpec>(text),
        ("surface", "sphere") => read::<SphereSpec>(text),
        ("surface", "asphere") => read::<AsphereSpec>(text),
        ("surface", "cylinder") => read::<CylinderSpec>(text),
        ("tool", "arc_nose") => read::<ArcNoseSpec>(text),
        ("tool", "cup_wheel") => read::<CupWheelSpec>(text),
        ("tool", _) => read::<MillToolSpec>(text),
        ("process", "turning") => read::<TurningSpec>(text),
        ("process", "generating") => read::<GeneratingSpec>(text),
        ("process", "milling") => read::<MillingSpec>(text),
        ("effects", kind) => effects::effect_fields_error(kind, text),
        _ => None,
    }
}

/// Rejects fields given in a table that the chosen kind does not use.
fn reject_unused(table: &str, kind: &str, fields: &[(&str, bool)]) -> Result<(), JobError> {
    match fields.iter().find(|(_, given)| *given) {
        Some((name, _)) => Err(error(
            &format!("{table}.{name}"),
            format!("is not used by {table}.kind = \"{kind}\"; remove it"),
        )),
        None => Ok(()),
    }
}

/// A required field, or an error naming it and what is allowed.
fn required<T: Copy>(field: &str, value: Option<T>, allowed: &str) -> Result<T, JobError> {
    value.ok_or_else(|| error(field, format!("missing; allowed: {allowed}")))
}

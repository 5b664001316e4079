//! Job files (TOML, `version = 1`): parsing, defaults and validation.
//!
//! Parsing rejects unknown fields and wrong types (serde, with the file position);
//! validation then checks every value against its allowed range and the physics
//! (sag defined over the aperture, feed the nose can cover, tool that fits the
//! curvature, edge that reaches the slope in XZ) and names the field in its error.
//! Lengths are in mm unless the name says otherwise.

use super::job_effects::{EffectSpec, turning_effects};
use crate::effects::TurningEffects;
use crate::geometry::surface::EVEN_TERMS;
use crate::geometry::{ArcNoseTool, Form, MeridianArcLength, SurfaceOfRevolution};
use crate::process::{FeedAlong, TurningMode, TurningSpiral};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;

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
    /// Departures from the nominal process (see `io::job_effects`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<EffectSpec>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SurfaceKind {
    Plane,
    Sphere,
    Asphere,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceSpec {
    pub kind: SurfaceKind,
    /// Sphere and asphere: which side faces the tool.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<Form>,
    /// Sphere radius.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_mm: Option<f64>,
    /// Asphere base (paraxial) radius R0 = 1/c.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_radius_mm: Option<f64>,
    /// Asphere conic constant k.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub conic: Option<f64>,
    /// Even asphere coefficients: sag += a4·r⁴ + a6·r⁶ + … + a20·r²⁰ (r in mm).
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
    pub aperture_diameter_mm: f64,
    #[serde(default)]
    pub inner_diameter_mm: f64,
}

impl SurfaceSpec {
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

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ToolKind {
    ArcNose,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolSpec {
    pub kind: ToolKind,
    pub nose_radius_mm: f64,
    /// Angle subtended by the edge arc (the edge spans ±half about the tip), (0, 180].
    pub included_angle_deg: f64,
    /// Flank clearance angle (default 10°), (0, 45].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance_angle_deg: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProcessKind {
    Turning,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProcessSpec {
    pub kind: ProcessKind,
    pub mode: TurningMode,
    /// Feed per spindle revolution; or give spindle_rpm and feed_mm_per_min.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feed_per_rev_mm: Option<f64>,
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

/// The spatial extent of the part that is simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aperture {
    pub inner_radius_mm: f64,
    pub outer_radius_mm: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    pub name: String,
    pub surface: SurfaceOfRevolution,
    pub aperture: Aperture,
    pub tool: ArcNoseTool,
    pub spiral: TurningSpiral,
    pub effects: TurningEffects,
    pub spindle_rpm: Option<f64>,
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
/// Steepest surface slope accepted (deg): beyond it a normal-dexel grid stops making sense.
pub const MAX_SLOPE_DEG: f64 = 89.0;

impl Job {
    pub fn from_toml_str(text: &str, default_name: &str) -> Result<Job, JobError> {
        let file: JobFile = toml::from_str(text).map_err(|err| error("job", err.to_string()))?;
        Job::from_file(file, default_name)
    }

    pub fn load(path: &Path) -> Result<Job, JobError> {
        let text = std::fs::read_to_string(path)
            .map_err(|err| error("job", format!("cannot read {}: {err}", path.display())))?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
        Job::from_toml_str(&text, stem.as_deref().unwrap_or("job"))
    }

    pub fn default_job() -> Job {
        Job::from_toml_str(DEFAULT_JOB_TOML, "default").expect("the built-in default job is valid")
    }

    pub fn from_file(file: JobFile, default_name: &str) -> Result<Job, JobError> {
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
        resolved.name = Some(name.clone());

        let mut warnings = Vec::new();
        let (surface, aperture) = validate_surface(&file.surface)?;
        let tool = validate_tool(&file.tool)?;
        let (spiral, spindle_rpm) =
            validate_process(&file.process, &surface, &aperture, &tool, &mut warnings)?;
        let meridian = path_meridian(&surface, &aperture, &spiral);
        let p = &mut resolved.process;
        p.feed_per_rev_mm = Some(spiral.feed_per_rev_mm);
        p.feed_along = Some(spiral.feed_along);
        p.stock_allowance_mm = Some(spiral.stock_allowance_mm);
        p.depth_of_cut_mm = Some(spiral.depth_of_cut_mm);
        p.start_radius_mm = Some(spiral.start_radius_mm);
        p.end_radius_mm = Some(spiral.end_radius_mm);
        check_tool_against_surface(&surface, &spiral, &tool)?;
        check_revolutions(&spiral, &meridian)?;

        // The spacing of passes along the surface, at its widest.
        let widest_spacing_mm = widest_pass_spacing(&surface, &spiral);
        let pitch_mm = match file.grid.pitch_um {
            Some(pitch) => check("grid.pitch_um", pitch, 0.0, 1e4, false)? * 1e-3,
            None => spiral.feed_per_rev_mm / 8.0,
        };
        let azimuths = file.grid.azimuths.unwrap_or(64);
        if !(1..=65_536).contains(&azimuths) {
            return Err(error(
                "grid.azimuths",
                format!("{azimuths} is out of range; allowed: 1 to 65536"),
            ));
        }
        let meridian_span = meridian.total_mm() - meridian.arc_length_at(aperture.inner_radius_mm);
        let samples = (meridian_span / pitch_mm + 1.0).floor() * azimuths as f64;
        if samples > MAX_SAMPLES {
            return Err(error(
                "grid.pitch_um",
                format!(
                    "{pitch} µm with {azimuths} azimuths gives {samples:.3e} samples, more than the {MAX_SAMPLES:.0e} allowed; raise grid.pitch_um or lower grid.azimuths",
                    pitch = pitch_mm * 1e3
                ),
            ));
        }
        if pitch_mm * 4.0 > spiral.feed_per_rev_mm {
            warnings.push(format!(
                "grid.pitch_um = {:.3} is coarser than a quarter of the feed ({:.3} µm): scallops will not be resolved",
                pitch_mm * 1e3,
                spiral.feed_per_rev_mm * 1e3
            ));
        } else if pitch_mm * 4.0 > widest_spacing_mm && file.grid.pitch_um.is_some() {
            warnings.push(format!(
                "passes are {:.3} µm apart along the steepest part of the surface; grid.pitch_um = {:.3} resolves them",
                widest_spacing_mm * 1e3,
                pitch_mm * 1e3
            ));
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

        let effects = turning_effects(&file.effects, tool.nose_radius_mm)?;
        resolved.tool.clearance_angle_deg = Some(tool.clearance_angle_deg);
        Ok(Job {
            name,
            surface,
            aperture,
            tool,
            spiral,
            effects,
            spindle_rpm,
            pitch_mm,
            azimuths,
            map_pixels,
            resolved,
            warnings,
        })
    }

    /// The meridian arc-length table over the aperture and the path (shared by both).
    pub fn meridian(&self) -> MeridianArcLength {
        path_meridian(&self.surface, &self.aperture, &self.spiral)
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

fn validate_surface(spec: &SurfaceSpec) -> Result<(SurfaceOfRevolution, Aperture), JobError> {
    let outer_radius_mm = check(
        "surface.aperture_diameter_mm",
        spec.aperture_diameter_mm,
        0.0,
        1e4,
        false,
    )? / 2.0;
    let inner = check(
        "surface.inner_diameter_mm",
        spec.inner_diameter_mm,
        0.0,
        1e4,
        true,
    )?;
    if inner >= spec.aperture_diameter_mm {
        return Err(error(
            "surface.inner_diameter_mm",
            format!(
                "{inner} must be smaller than aperture_diameter_mm = {}",
                spec.aperture_diameter_mm
            ),
        ));
    }
    let aperture = Aperture {
        inner_radius_mm: inner / 2.0,
        outer_radius_mm,
    };
    let kind_name = match spec.kind {
        SurfaceKind::Plane => "plane",
        SurfaceKind::Sphere => "sphere",
        SurfaceKind::Asphere => "asphere",
    };
    let unused = |field: &str, present: bool| -> Result<(), JobError> {
        if present {
            Err(error(
                &format!("surface.{field}"),
                format!("is not used by kind = \"{kind_name}\"; remove it"),
            ))
        } else {
            Ok(())
        }
    };
    let form = |spec: &SurfaceSpec| {
        spec.form.ok_or_else(|| {
            error(
                "surface.form",
                "missing; allowed: \"convex\" or \"concave\"",
            )
        })
    };
    let has_polynomial = spec.even_coefficients().iter().any(|(_, v)| v.is_some());
    let surface = match spec.kind {
        SurfaceKind::Plane => {
            unused("form", spec.form.is_some())?;
            unused("radius_mm", spec.radius_mm.is_some())?;
            unused("base_radius_mm", spec.base_radius_mm.is_some())?;
            unused("conic", spec.conic.is_some())?;
            unused("a4..a20", has_polynomial)?;
            SurfaceOfRevolution::plane()
        }
        SurfaceKind::Sphere => {
            unused("base_radius_mm", spec.base_radius_mm.is_some())?;
            unused("conic", spec.conic.is_some())?;
            unused("a4..a20", has_polynomial)?;
            let radius = spec.radius_mm.ok_or_else(|| {
                error("surface.radius_mm", "missing; allowed: a finite number > 0")
            })?;
            let radius = check("surface.radius_mm", radius, 0.0, 1e7, false)?;
            SurfaceOfRevolution::sphere(radius, form(spec)?)
        }
        SurfaceKind::Asphere => {
            unused("radius_mm", spec.radius_mm.is_some())?;
            let base = spec.base_radius_mm.ok_or_else(|| {
                error(
                    "surface.base_radius_mm",
                    "missing; allowed: a finite number > 0",
                )
            })?;
            let base = check("surface.base_radius_mm", base, 0.0, 1e7, false)?;
            let conic = check("surface.conic", spec.conic.unwrap_or(0.0), -1e6, 1e6, true)?;
            let mut coefficients = [0.0; EVEN_TERMS];
            for (slot, (name, value)) in coefficients.iter_mut().zip(spec.even_coefficients()) {
                if let Some(value) = value {
                    *slot = check(&format!("surface.{name}"), value, -1e6, 1e6, true)?;
                }
            }
            SurfaceOfRevolution::asphere(base, conic, coefficients, form(spec)?)
        }
    };

    let limit = surface.sag_limit_radius_mm();
    if outer_radius_mm >= limit {
        return Err(error(
            "surface.aperture_diameter_mm",
            format!(
                "{}: the sag is undefined beyond r = {limit:.4} mm (1 − (1+k)c²r² ≤ 0 for base radius and conic given); allowed: aperture_diameter_mm < {:.4}",
                spec.aperture_diameter_mm,
                2.0 * limit
            ),
        ));
    }
    // The slope must stay finite and below MAX_SLOPE_DEG everywhere in the aperture.
    if let Some(r) = usable_over(&surface, aperture.inner_radius_mm, outer_radius_mm, 4000) {
        return Err(error(
            "surface.aperture_diameter_mm",
            format!(
                "the surface slope reaches {:.2}° at r = {r:.4} mm; allowed: at most {MAX_SLOPE_DEG}° inside the aperture",
                surface.normal_angle(r).to_degrees().abs()
            ),
        ));
    }
    Ok((surface, aperture))
}

fn path_meridian(
    surface: &SurfaceOfRevolution,
    aperture: &Aperture,
    spiral: &TurningSpiral,
) -> MeridianArcLength {
    MeridianArcLength::new(
        surface,
        aperture.outer_radius_mm.max(spiral.start_radius_mm),
    )
}

/// Whether the path may use the surface at radius r: sag defined, slope ≤ MAX_SLOPE_DEG.
fn usable_at(surface: &SurfaceOfRevolution, r: f64) -> bool {
    let angle = surface.normal_angle(r).to_degrees().abs();
    surface.conic_root_argument(r) > 0.0 && surface.height(r).is_finite() && angle <= MAX_SLOPE_DEG
}

/// Whether `usable_at` holds at `steps + 1` evenly spaced radii over [a, b].
fn usable_over(surface: &SurfaceOfRevolution, a: f64, b: f64, steps: usize) -> Option<f64> {
    (0..=steps)
        .map(|i| a + (b - a) * i as f64 / steps as f64)
        .find(|&r| !usable_at(surface, r))
}

fn validate_tool(spec: &ToolSpec) -> Result<ArcNoseTool, JobError> {
    Ok(ArcNoseTool {
        nose_radius_mm: check(
            "tool.nose_radius_mm",
            spec.nose_radius_mm,
            0.0,
            100.0,
            false,
        )?,
        included_angle_deg: check(
            "tool.included_angle_deg",
            spec.included_angle_deg,
            0.0,
            180.0,
            false,
        )?,
        clearance_angle_deg: check(
            "tool.clearance_angle_deg",
            spec.clearance_angle_deg.unwrap_or(10.0),
            0.0,
            45.0,
            false,
        )?,
    })
}

fn validate_process(
    spec: &ProcessSpec,
    surface: &SurfaceOfRevolution,
    aperture: &Aperture,
    tool: &ArcNoseTool,
    warnings: &mut Vec<String>,
) -> Result<(TurningSpiral, Option<f64>), JobError> {
    let spindle_rpm = spec
        .spindle_rpm
        .map(|rpm| check("process.spindle_rpm", rpm, 0.0, 1e6, false))
        .transpose()?;
    let feed_speed = spec
        .feed_mm_per_min
        .map(|f| check("process.feed_mm_per_min", f, 0.0, 1e6, false))
        .transpose()?;
    let feed = match (spec.feed_per_rev_mm, spindle_rpm, feed_speed) {
        (Some(feed), _, None) => check("process.feed_per_rev_mm", feed, 0.0, 100.0, false)?,
        (None, Some(rpm), Some(speed)) => speed / rpm,
        (Some(_), _, Some(_)) => {
            return Err(error(
                "process.feed_mm_per_min",
                "give either feed_per_rev_mm or spindle_rpm + feed_mm_per_min, not both",
            ));
        }
        (None, None, Some(_)) => {
            return Err(error(
                "process.spindle_rpm",
                "missing: feed_mm_per_min needs spindle_rpm",
            ));
        }
        (None, _, None) => {
            return Err(error(
                "process.feed_per_rev_mm",
                "missing; give feed_per_rev_mm, or spindle_rpm and feed_mm_per_min",
            ));
        }
    };
    let coverable = tool.coverable_feed_mm();
    if feed >= coverable {
        return Err(error(
            "process.feed_per_rev_mm",
            format!(
                "{feed} mm exceeds what the nose can cover: neighbouring passes must meet on the edge, so allowed: < 2·nose_radius·sin(min(included_angle/2, 90°)) = {coverable:.6} mm"
            ),
        ));
    }
    let stock = check(
        "process.stock_allowance_mm",
        spec.stock_allowance_mm.unwrap_or(0.002),
        0.0,
        10.0,
        true,
    )?;
    let depth = check(
        "process.depth_of_cut_mm",
        spec.depth_of_cut_mm.unwrap_or(stock.max(1e-6)),
        0.0,
        10.0,
        false,
    )?;
    let feed_along = spec.feed_along.unwrap_or(FeedAlong::Radial);
    let outer = aperture.outer_radius_mm;
    let start = match spec.start_radius_mm {
        Some(start) => {
            let start = check("process.start_radius_mm", start, 0.0, 1e4, false)?;
            if let Some(r) = usable_over(surface, outer.min(start), start, 4000) {
                return Err(error(
                    "process.start_radius_mm",
                    format!(
                        "{start}: the path would cross r = {r:.4} mm, where the surface is undefined or steeper than {MAX_SLOPE_DEG}°"
                    ),
                ));
            }
            start
        }
        // Start two passes outside the rim so the rim is finished like the rest,
        // unless the surface ends there.
        None => {
            let lead_in = match feed_along {
                FeedAlong::Radial => 2.0 * feed,
                FeedAlong::ArcLength => 2.0 * feed / surface.arc_length_rate(outer),
            };
            if usable_over(surface, outer, outer + lead_in, 100).is_none() {
                outer + lead_in
            } else {
                warnings.push(format!(
                    "the surface ends at the rim, so the spiral starts there: the outermost {:.3} µm are a lead-in zone, not finished like the rest",
                    feed * 1e3
                ));
                outer
            }
        }
    };
    let end = check(
        "process.end_radius_mm",
        spec.end_radius_mm.unwrap_or(0.0),
        0.0,
        start,
        true,
    )?;
    if end >= start {
        return Err(error(
            "process.end_radius_mm",
            format!("{end} must be smaller than start_radius_mm = {start}"),
        ));
    }
    Ok((
        TurningSpiral {
            mode: spec.mode,
            feed_per_rev_mm: feed,
            feed_along,
            start_radius_mm: start,
            end_radius_mm: end,
            stock_allowance_mm: stock,
            depth_of_cut_mm: depth,
        },
        spindle_rpm,
    ))
}

/// Spacing of neighbouring passes along the surface at radius r.
fn pass_spacing(surface: &SurfaceOfRevolution, spiral: &TurningSpiral, r: f64) -> f64 {
    match spiral.feed_along {
        FeedAlong::ArcLength => spiral.feed_per_rev_mm,
        FeedAlong::Radial => spiral.feed_per_rev_mm * surface.arc_length_rate(r),
    }
}

fn widest_pass_spacing(surface: &SurfaceOfRevolution, spiral: &TurningSpiral) -> f64 {
    let steps = 2000;
    (0..=steps)
        .map(|i| {
            let r = spiral.end_radius_mm
                + (spiral.start_radius_mm - spiral.end_radius_mm) * i as f64 / steps as f64;
            pass_spacing(surface, spiral, r)
        })
        .fold(0.0, f64::max)
}

/// The tool must fit concave curvature, and in XZ its edge must reach the slope
/// (plus the angle to the neighbouring pass's cusp).
fn check_tool_against_surface(
    surface: &SurfaceOfRevolution,
    spiral: &TurningSpiral,
    tool: &ArcNoseTool,
) -> Result<(), JobError> {
    let steps = 4000;
    let half_span_deg = tool.half_span_rad().to_degrees();
    // The widest angle from the tip the edge must cut at, and where.
    let mut widest = (0.0f64, 0.0f64);
    for i in 0..=steps {
        let r = spiral.end_radius_mm
            + (spiral.start_radius_mm - spiral.end_radius_mm) * i as f64 / steps as f64;
        let curvature = surface.meridional_curvature(r);
        if curvature > 0.0 && tool.nose_radius_mm >= 1.0 / curvature {
            return Err(error(
                "tool.nose_radius_mm",
                format!(
                    "{} mm does not fit the concave surface: its radius of curvature is {:.4} mm at r = {r:.4} mm; allowed: < {:.4} mm",
                    tool.nose_radius_mm,
                    1.0 / curvature,
                    1.0 / curvature
                ),
            ));
        }
        if !usable_at(surface, r) {
            return Err(error(
                "process.start_radius_mm",
                format!(
                    "the path reaches r = {r:.4} mm, where the surface is undefined or steeper than {MAX_SLOPE_DEG}°"
                ),
            ));
        }
        let spacing = pass_spacing(surface, spiral, r);
        let cusp_angle_deg = (spacing / (2.0 * tool.nose_radius_mm))
            .min(1.0)
            .asin()
            .to_degrees();
        let needed_deg = match spiral.mode {
            TurningMode::Xz => surface.normal_angle(r).to_degrees().abs() + cusp_angle_deg,
            TurningMode::Xzb => cusp_angle_deg,
        };
        if needed_deg > widest.0 {
            widest = (needed_deg, r);
        }
    }
    let (needed_deg, at_radius) = widest;
    if needed_deg > half_span_deg {
        let hint = if spiral.mode == TurningMode::Xz {
            " or mode = \"xzb\""
        } else {
            ""
        };
        return Err(error(
            "tool.included_angle_deg",
            format!(
                "{}° is too narrow: at r = {at_radius:.4} mm the edge must reach {needed_deg:.2}° from its tip (surface slope plus the angle to the neighbouring pass); allowed: included_angle_deg ≥ {:.2}{hint}",
                tool.included_angle_deg,
                2.0 * needed_deg
            ),
        ));
    }
    Ok(())
}

/// Refuses absurd path lengths (a feed far too fine for the part).
fn check_revolutions(spiral: &TurningSpiral, meridian: &MeridianArcLength) -> Result<(), JobError> {
    const MAX_REVOLUTIONS: f64 = 2.0e6;
    let revolutions = spiral.revolutions(meridian);
    if revolutions > MAX_REVOLUTIONS {
        return Err(error(
            "process.feed_per_rev_mm",
            format!(
                "{} mm makes the spiral {revolutions:.3e} revolutions long; allowed: at most {MAX_REVOLUTIONS:.0e} (raise the feed)",
                spiral.feed_per_rev_mm
            ),
        ));
    }
    Ok(())
}

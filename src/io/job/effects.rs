//! The `[[effects]]` tables of a job (and of an effects fragment file): parsing and
//! validation into [`TurningEffects`]. Lengths in mm, angles in degrees.
//!
//! ```toml
//! [[effects]]
//! kind = "centre_height"
//! height_mm = 0.005          # + = above centre
//!
//! [[effects]]
//! kind = "x_decentre"
//! offset_mm = 0.002          # + = the tool stops short of the axis
//!
//! [[effects]]
//! kind = "nose_radius_error"
//! error_mm = 0.001           # actual − nominal radius, tool set at its tip
//!
//! [[effects]]
//! kind = "edge_waviness"
//! harmonics = [{ order = 40, amplitude_mm = 0.00005, phase_deg = 0.0 }]
//! ```
//!
//! Generating jobs (cup wheel) take their own effects:
//!
//! ```toml
//! [[effects]]
//! kind = "cutter_displacement"
//! offset_mm = 0.02           # + = the cutting circle stops short of the axis
//!
//! [[effects]]
//! kind = "inclination_error"
//! error_deg = 0.01           # actual − set inclination
//!
//! [[effects]]
//! kind = "plunge_error"
//! error_mm = 0.001           # + = the wheel stops short along the plunge axis
//! ```

use super::{JobError, ToolSpec};
use crate::effects::{GeneratingEffects, TurningEffects, WAVINESS_SAMPLES};
use crate::geometry::ArcNoseTool;
use crate::geometry::tool::AngleTable;
use crate::io::measured::read_edge_csv;
use crate::process::GeneratingSetup;
use crate::process::TurningMode;
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    CentreHeight,
    XDecentre,
    NoseRadiusError,
    EdgeWaviness,
    CutterDisplacement,
    InclinationError,
    PlungeError,
}

impl EffectKind {
    /// The name used in job files.
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::CentreHeight => "centre_height",
            EffectKind::XDecentre => "x_decentre",
            EffectKind::NoseRadiusError => "nose_radius_error",
            EffectKind::EdgeWaviness => "edge_waviness",
            EffectKind::CutterDisplacement => "cutter_displacement",
            EffectKind::InclinationError => "inclination_error",
            EffectKind::PlungeError => "plunge_error",
        }
    }

    fn is_turning(self) -> bool {
        matches!(
            self,
            EffectKind::CentreHeight
                | EffectKind::XDecentre
                | EffectKind::NoseRadiusError
                | EffectKind::EdgeWaviness
        )
    }

    /// The parameter field each kind takes.
    fn parameter(self) -> &'static str {
        match self {
            EffectKind::CentreHeight => "height_mm",
            EffectKind::XDecentre | EffectKind::CutterDisplacement => "offset_mm",
            EffectKind::NoseRadiusError | EffectKind::PlungeError => "error_mm",
            EffectKind::EdgeWaviness => "harmonics",
            EffectKind::InclinationError => "error_deg",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HarmonicSpec {
    /// Undulations a full circle would carry (roundness convention).
    pub order: f64,
    pub amplitude_mm: f64,
    #[serde(default)]
    pub phase_deg: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectSpec {
    pub kind: EffectKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub harmonics: Option<Vec<HarmonicSpec>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_deg: Option<f64>,
}

impl EffectSpec {
    /// Each parameter field and whether it is given.
    fn given(&self) -> [(&'static str, bool); 5] {
        [
            ("height_mm", self.height_mm.is_some()),
            ("offset_mm", self.offset_mm.is_some()),
            ("error_mm", self.error_mm.is_some()),
            ("harmonics", self.harmonics.is_some()),
            ("error_deg", self.error_deg.is_some()),
        ]
    }

    /// Checks the table gives only its kind's parameter, and that the kind belongs to
    /// the job's process.
    fn check_fields(&self, index: usize, turning: bool) -> Result<(), JobError> {
        let field = |name: &str| format!("effects[{index}].{name}");
        if self.kind.is_turning() != turning {
            let (this, other, allowed) = if turning {
                (
                    "generating",
                    "turning",
                    "centre_height, x_decentre, nose_radius_error, edge_waviness",
                )
            } else {
                (
                    "turning",
                    "generating",
                    "cutter_displacement, inclination_error, plunge_error",
                )
            };
            return Err(error(
                field("kind"),
                format!(
                    "\"{}\" is a {this} effect and this is a {other} job; allowed: {allowed}",
                    self.kind.name()
                ),
            ));
        }
        for (name, given) in self.given() {
            if given && name != self.kind.parameter() {
                return Err(error(
                    field(name),
                    format!("is not a parameter of kind = \"{}\"", self.kind.name()),
                ));
            }
        }
        Ok(())
    }
}

fn error(field: String, message: impl Into<String>) -> JobError {
    JobError {
        field,
        message: message.into(),
    }
}

/// A required finite value within ±limit.
fn bounded(field: String, value: Option<f64>, limit: f64) -> Result<f64, JobError> {
    match value {
        None => Err(error(
            field,
            format!("missing; allowed: a finite number in [−{limit}, {limit}]"),
        )),
        Some(v) if !v.is_finite() || v.abs() > limit => Err(error(
            field,
            format!("{v} is out of range; allowed: a finite number in [−{limit}, {limit}]"),
        )),
        Some(v) => Ok(v),
    }
}

/// Combines the effect tables into one set of turning effects (waviness adds up).
/// `nose_radius_mm` bounds the effects that only make sense below the tool's size.
pub fn turning_effects(
    specs: &[EffectSpec],
    nose_radius_mm: f64,
) -> Result<TurningEffects, JobError> {
    let mut effects = TurningEffects::default();
    let mut harmonics = Vec::new();
    for (index, spec) in specs.iter().enumerate() {
        let field = |name: &str| format!("effects[{index}].{name}");
        spec.check_fields(index, true)?;
        match spec.kind {
            EffectKind::CentreHeight => {
                effects.centre_height_mm +=
                    bounded(field("height_mm"), spec.height_mm, 0.5 * nose_radius_mm)?;
            }
            EffectKind::XDecentre => {
                effects.x_decentre_mm +=
                    bounded(field("offset_mm"), spec.offset_mm, nose_radius_mm)?;
            }
            EffectKind::NoseRadiusError => {
                effects.radius_error_mm +=
                    bounded(field("error_mm"), spec.error_mm, 0.5 * nose_radius_mm)?;
            }
            EffectKind::EdgeWaviness => {
                let list = spec
                    .harmonics
                    .as_ref()
                    .filter(|list| !list.is_empty())
                    .ok_or_else(|| {
                        error(
                            field("harmonics"),
                            "missing; give at least one { order, amplitude_mm }",
                        )
                    })?;
                for (h, harmonic) in list.iter().enumerate() {
                    let at = |name: &str| field(&format!("harmonics[{h}].{name}"));
                    if !harmonic.order.is_finite() || !(0.0..=2000.0).contains(&harmonic.order) {
                        return Err(error(
                            at("order"),
                            format!("{} is out of range; allowed: 0 to 2000", harmonic.order),
                        ));
                    }
                    let amplitude = bounded(at("amplitude_mm"), Some(harmonic.amplitude_mm), 0.01)?;
                    let phase = bounded(at("phase_deg"), Some(harmonic.phase_deg), 360.0)?;
                    harmonics.push((harmonic.order, amplitude, phase.to_radians()));
                }
            }
            _ => unreachable!("check_fields admits turning kinds only"),
        }
    }
    if !harmonics.is_empty() {
        effects.edge_deviation = AngleTable::from_harmonics(&harmonics, WAVINESS_SAMPLES);
    }
    Ok(effects)
}

/// Combines the effect tables of a generating job (values of a kind add up). Bounds:
/// a displacement or plunge error below the edge radius (beyond it the edge no longer
/// reaches the axis at all), an inclination error below a tenth of the inclination.
pub fn generating_effects(
    specs: &[EffectSpec],
    setup: &GeneratingSetup,
) -> Result<GeneratingEffects, JobError> {
    let mut effects = GeneratingEffects::default();
    let edge_radius = setup.wheel.edge_radius_mm;
    let max_tilt_deg = 0.1 * setup.inclination_rad.to_degrees();
    for (index, spec) in specs.iter().enumerate() {
        spec.check_fields(index, false)?;
        let field = |name: &str| format!("effects[{index}].{name}");
        match spec.kind {
            EffectKind::CutterDisplacement => {
                effects.cutter_displacement_mm +=
                    bounded(field("offset_mm"), spec.offset_mm, 0.5 * edge_radius)?;
            }
            EffectKind::InclinationError => {
                effects.inclination_error_rad +=
                    bounded(field("error_deg"), spec.error_deg, max_tilt_deg)?.to_radians();
            }
            EffectKind::PlungeError => {
                effects.plunge_error_mm +=
                    bounded(field("error_mm"), spec.error_mm, 0.5 * edge_radius)?;
            }
            _ => unreachable!("check_fields admits generating kinds only"),
        }
    }
    Ok(effects)
}

/// Samples of a measured edge's deviation table.
const EDGE_PROFILE_SAMPLES: usize = 2001;

/// Makes the tool cut with a measured edge: its fitted radius (against the nominal the
/// path assumes) and its radial deviation from that circle, ψ measured from the middle
/// of the measured arc (taken as the tip).
pub fn apply_edge_profile(
    effects: &mut TurningEffects,
    spec: &ToolSpec,
    profile: &Path,
    tool: &ArcNoseTool,
    mode: TurningMode,
    warnings: &mut Vec<String>,
) -> Result<(), JobError> {
    if !effects.edge_deviation.is_zero() {
        return Err(error(
            "tool.edge_profile".into(),
            "cannot be combined with an edge_waviness effect: the measured edge already holds its waviness",
        ));
    }
    let edge =
        read_edge_csv(profile).map_err(|err| error("tool.edge_profile".into(), err.to_string()))?;
    let smoothing = spec.edge_profile_smoothing_points.unwrap_or(51);
    if !(1..=1001).contains(&smoothing) {
        return Err(error(
            "tool.edge_profile_smoothing_points".into(),
            format!("{smoothing} is out of range; allowed: 1 to 1001"),
        ));
    }
    let (start, step, mut values) =
        edge.radial_deviation_table(EDGE_PROFILE_SAMPLES, smoothing as usize);
    let mirror = spec.edge_profile_mirror.unwrap_or(false);
    let start = if mirror {
        values.reverse();
        -(start + step * (values.len() - 1) as f64)
    } else {
        start
    };
    effects.radius_error_mm += edge.radius_mm - tool.nose_radius_mm;
    effects.edge_deviation = AngleTable {
        start_rad: start,
        step_rad: step,
        values_mm: values,
    };
    let covered = (-start).min(start + step * (EDGE_PROFILE_SAMPLES - 1) as f64);
    let needed = match mode {
        TurningMode::Xz => tool.half_span_rad(),
        TurningMode::Xzb => tool.half_span_rad().min(0.35),
    };
    if covered < needed {
        warnings.push(format!(
            "the measured edge {} covers ±{:.1}° about its tip, less than the ±{:.1}° the tool may cut with; beyond it the deviation is held at its end values",
            profile.display(),
            covered.to_degrees(),
            needed.to_degrees()
        ));
    }
    warnings.push(format!(
        "measured edge {}: fitted radius {:.3} µm (nominal {:.3} µm), residual RMS {:.3} µm, deviation smoothed over {smoothing} points",
        profile.display(),
        edge.radius_mm * 1e3,
        tool.nose_radius_mm * 1e3,
        edge.rms_residual_um
    ));
    Ok(())
}

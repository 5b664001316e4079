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

use super::job::JobError;
use crate::effects::{TurningEffects, WAVINESS_SAMPLES};
use crate::geometry::tool::AngleTable;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    CentreHeight,
    XDecentre,
    NoseRadiusError,
    EdgeWaviness,
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
        let present = [
            (
                "height_mm",
                spec.height_mm.is_some(),
                EffectKind::CentreHeight,
            ),
            ("offset_mm", spec.offset_mm.is_some(), EffectKind::XDecentre),
            (
                "error_mm",
                spec.error_mm.is_some(),
                EffectKind::NoseRadiusError,
            ),
            (
                "harmonics",
                spec.harmonics.is_some(),
                EffectKind::EdgeWaviness,
            ),
        ];
        for (name, given, owner) in present {
            if given && owner != spec.kind {
                return Err(error(
                    field(name),
                    format!("is not a parameter of kind = {:?}", spec.kind),
                ));
            }
        }
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
        }
    }
    if !harmonics.is_empty() {
        effects.edge_deviation = AngleTable::from_harmonics(&harmonics, WAVINESS_SAMPLES);
    }
    Ok(effects)
}

//! The `[[effects]]` tables of a job (and of an effects fragment file): parsing and
//! validation into [`TurningEffects`], [`GeneratingEffects`] and [`MillingEffects`].
//! Lengths in mm, angles in degrees. Values of one kind add up across tables (a
//! runout's as vectors); each table and each total must lie within the kind's range.
//!
//! Turning jobs:
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
//!
//! [[effects]]
//! kind = "axial_drift"
//! drift_mm = 0.0005          # Z drift at the end of the cut, + = away from the part;
//!                            #   linear in the spindle angle turned
//!
//! [[effects]]
//! kind = "vibration"         # relative tool–workpiece vibration a·cos(2πk·n + φ), n the
//! amplitude_mm = 0.00001     #   revolutions turned since the first pose
//! direction = "depth"        # "depth" (along Z, + away from the part) or "feed" (along X)
//! per_revolution = 3.0       # k (synchronous when whole; ≤ 200), or instead
//! # frequency_hz = 85.0      #   a frequency (needs process.spindle_rpm: k = f·60/rpm)
//! phase_deg = 0.0
//!
//! [[effects]]
//! kind = "axial_error_motion" # spindle axial error motion: the part toward the tool by
//! harmonics = [{ order = 2, amplitude_mm = 0.00001, phase_deg = 0.0 }]  # Σ a·cos(kC + φ)
//!
//! [[effects]]
//! kind = "tilt_error_motion"  # spindle tilt error motion: the face rising toward the
//! tilt_harmonics = [{ order = 2, amplitude_deg = 0.0001, phase_deg = 0.0 }] # tool by x·θ
//!
//! [[effects]]
//! kind = "tool_wear"
//! recession_mm = 0.00002     # edge recession at the end of the cut, linear in cut length
//!                            #   (negative: the edge advanced, e.g. a built-up edge)
//!
//! [[effects]]
//! kind = "spring_back"       # once per job (its values do not add up)
//! min_chip_mm = 0.000005     # h_min: a thinner chip ploughs; 0 < h_min ≤ min(0.005, R/10)
//! recovery = 0.6             # ρ: the ploughed fraction that springs back; 0 < ρ ≤ 1
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
//!
//! Milling jobs:
//!
//! ```toml
//! [[effects]]
//! kind = "axial_drift"
//! drift_mm = 0.001           # Z drift at the end of the path, + = away from the part;
//!                            #   linear in path arc length
//!
//! [[effects]]
//! kind = "tool_radius_error"
//! error_mm = 0.002           # actual − nominal ball/corner radius, tool set at its tip
//!                            #   (ball_end and bull_nose; |e| < r/2)
//!
//! [[effects]]
//! kind = "spindle_tram"
//! tilt_x_deg = 0.02          # the axis leaning toward +X (bull_nose, flat_end; ≤ 1°)
//! tilt_y_deg = -0.01         # … and toward +Y (each defaults to 0; give at least one)
//!
//! [[effects]]
//! kind = "radial_runout"
//! offset_mm = 0.002          # ε: each tooth's sweep off the axis (|ε| ≤ feed_per_tooth/2,
//! phase_deg = 30.0           #   teeth ≥ 2); tooth 0's at φ from the feed (default 0),
//!                            #   tooth j's at φ + 360°·j/teeth, right-handed about the axis
//! ```

use super::{ArcNoseSpec, JobError, ProcessKind};
use crate::formats::measured::read_edge_csv;
use crate::geometry::ArcNoseTool;
use crate::geometry::milling_tool::MillingTool;
use crate::geometry::tool::AngleTable;
use crate::process::TurningMode;
use crate::process::effects::{
    GeneratingEffects, MAX_CYCLES_PER_REV, MillingEffects, SpindleHarmonic, TurningEffects,
    Vibration, VibrationDirection, WAVINESS_SAMPLES,
};
use crate::process::{GeneratingSetup, MillingSetup};
use glam::DVec2;
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
    AxialDrift,
    ToolRadiusError,
    SpindleTram,
    RadialRunout,
    Vibration,
    AxialErrorMotion,
    TiltErrorMotion,
    ToolWear,
    SpringBack,
}

impl EffectKind {
    pub const ALL: [EffectKind; 16] = [
        EffectKind::CentreHeight,
        EffectKind::XDecentre,
        EffectKind::NoseRadiusError,
        EffectKind::EdgeWaviness,
        EffectKind::CutterDisplacement,
        EffectKind::InclinationError,
        EffectKind::PlungeError,
        EffectKind::AxialDrift,
        EffectKind::ToolRadiusError,
        EffectKind::SpindleTram,
        EffectKind::RadialRunout,
        EffectKind::Vibration,
        EffectKind::AxialErrorMotion,
        EffectKind::TiltErrorMotion,
        EffectKind::ToolWear,
        EffectKind::SpringBack,
    ];

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
            EffectKind::AxialDrift => "axial_drift",
            EffectKind::ToolRadiusError => "tool_radius_error",
            EffectKind::SpindleTram => "spindle_tram",
            EffectKind::RadialRunout => "radial_runout",
            EffectKind::Vibration => "vibration",
            EffectKind::AxialErrorMotion => "axial_error_motion",
            EffectKind::TiltErrorMotion => "tilt_error_motion",
            EffectKind::ToolWear => "tool_wear",
            EffectKind::SpringBack => "spring_back",
        }
    }

    /// The kind of this job-file name.
    pub fn named(name: &str) -> Option<EffectKind> {
        EffectKind::ALL.into_iter().find(|kind| kind.name() == name)
    }

    /// The processes whose jobs take this kind.
    pub fn processes(self) -> &'static [ProcessKind] {
        match self {
            EffectKind::CentreHeight
            | EffectKind::XDecentre
            | EffectKind::NoseRadiusError
            | EffectKind::EdgeWaviness
            | EffectKind::Vibration
            | EffectKind::AxialErrorMotion
            | EffectKind::TiltErrorMotion
            | EffectKind::ToolWear
            | EffectKind::SpringBack => &[ProcessKind::Turning],
            EffectKind::CutterDisplacement
            | EffectKind::InclinationError
            | EffectKind::PlungeError => &[ProcessKind::Generating],
            EffectKind::AxialDrift => &[ProcessKind::Turning, ProcessKind::Milling],
            EffectKind::ToolRadiusError | EffectKind::SpindleTram | EffectKind::RadialRunout => {
                &[ProcessKind::Milling]
            }
        }
    }
}

fn process_name(process: ProcessKind) -> &'static str {
    match process {
        ProcessKind::Turning => "turning",
        ProcessKind::Generating => "generating",
        ProcessKind::Milling => "milling",
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

/// One harmonic of a tilt error motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TiltHarmonicSpec {
    pub order: f64,
    pub amplitude_deg: f64,
    #[serde(default)]
    pub phase_deg: f64,
}

/// Which way a vibration moves the tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DirectionSpec {
    Feed,
    Depth,
}

/// One `[[effects]]` table, one kind per variant: a key another kind uses is refused as
/// an unknown field of this one. Parameters are options so that a missing one is
/// reported with the range the job allows (which depends on the tool).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EffectSpec {
    CentreHeight(CentreHeightSpec),
    XDecentre(OffsetSpec),
    NoseRadiusError(ErrorSpec),
    EdgeWaviness(HarmonicsSpec),
    CutterDisplacement(OffsetSpec),
    InclinationError(AngleErrorSpec),
    PlungeError(ErrorSpec),
    AxialDrift(DriftSpec),
    ToolRadiusError(ErrorSpec),
    SpindleTram(TramSpec),
    RadialRunout(RunoutSpec),
    Vibration(VibrationSpec),
    AxialErrorMotion(HarmonicsSpec),
    TiltErrorMotion(TiltHarmonicsSpec),
    ToolWear(WearSpec),
    SpringBack(SpringBackSpec),
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CentreHeightSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_mm: Option<f64>,
}

/// A length offset: an x decentre, a cutter displacement.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OffsetSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_mm: Option<f64>,
}

/// A length error: a nose or tool radius error, a plunge error.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ErrorSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_mm: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AngleErrorSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_deg: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriftSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drift_mm: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WearSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recession_mm: Option<f64>,
}

/// Harmonics of a length: an edge waviness, an axial error motion.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HarmonicsSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub harmonics: Option<Vec<HarmonicSpec>>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TiltHarmonicsSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tilt_harmonics: Option<Vec<TiltHarmonicSpec>>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TramSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tilt_x_deg: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tilt_y_deg: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunoutSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase_deg: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VibrationSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<DirectionSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub per_revolution: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frequency_hz: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase_deg: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringBackSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_chip_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recovery: Option<f64>,
}

impl EffectSpec {
    pub fn kind(&self) -> EffectKind {
        match self {
            EffectSpec::CentreHeight(_) => EffectKind::CentreHeight,
            EffectSpec::XDecentre(_) => EffectKind::XDecentre,
            EffectSpec::NoseRadiusError(_) => EffectKind::NoseRadiusError,
            EffectSpec::EdgeWaviness(_) => EffectKind::EdgeWaviness,
            EffectSpec::CutterDisplacement(_) => EffectKind::CutterDisplacement,
            EffectSpec::InclinationError(_) => EffectKind::InclinationError,
            EffectSpec::PlungeError(_) => EffectKind::PlungeError,
            EffectSpec::AxialDrift(_) => EffectKind::AxialDrift,
            EffectSpec::ToolRadiusError(_) => EffectKind::ToolRadiusError,
            EffectSpec::SpindleTram(_) => EffectKind::SpindleTram,
            EffectSpec::RadialRunout(_) => EffectKind::RadialRunout,
            EffectSpec::Vibration(_) => EffectKind::Vibration,
            EffectSpec::AxialErrorMotion(_) => EffectKind::AxialErrorMotion,
            EffectSpec::TiltErrorMotion(_) => EffectKind::TiltErrorMotion,
            EffectSpec::ToolWear(_) => EffectKind::ToolWear,
            EffectSpec::SpringBack(_) => EffectKind::SpringBack,
        }
    }

    /// Checks that the kind belongs to the job's process.
    fn check_process(&self, index: usize, process: ProcessKind) -> Result<(), JobError> {
        let kind = self.kind();
        let owners = kind.processes();
        if owners.contains(&process) {
            return Ok(());
        }
        let owners: Vec<&str> = owners.iter().map(|&p| process_name(p)).collect();
        let allowed: Vec<&str> = EffectKind::ALL
            .iter()
            .filter(|kind| kind.processes().contains(&process))
            .map(|kind| kind.name())
            .collect();
        Err(error(
            format!("effects[{index}].kind"),
            format!(
                "\"{}\" is a {} effect and this is a {} job; allowed: {}",
                kind.name(),
                owners.join(" and "),
                process_name(process),
                allowed.join(", ")
            ),
        ))
    }
}

/// The error of reading `text` (an `[[effects]]` table without its `kind` key) as the
/// fields of the effect `kind`; `None` when the kind is unknown or the table reads.
pub(super) fn effect_fields_error(kind: &str, text: &str) -> Option<toml::de::Error> {
    fn read<T: serde::de::DeserializeOwned>(text: &str) -> Option<toml::de::Error> {
        toml::from_str::<T>(text).err()
    }
    match EffectKind::named(kind)? {
        EffectKind::CentreHeight => read::<CentreHeightSpec>(text),
        EffectKind::XDecentre | EffectKind::CutterDisplacement => read::<OffsetSpec>(text),
        EffectKind::NoseRadiusError | EffectKind::PlungeError | EffectKind::ToolRadiusError => {
            read::<ErrorSpec>(text)
        }
        EffectKind::EdgeWaviness | EffectKind::AxialErrorMotion => read::<HarmonicsSpec>(text),
        EffectKind::InclinationError => read::<AngleErrorSpec>(text),
        EffectKind::AxialDrift => read::<DriftSpec>(text),
        EffectKind::SpindleTram => read::<TramSpec>(text),
        EffectKind::RadialRunout => read::<RunoutSpec>(text),
        EffectKind::Vibration => read::<VibrationSpec>(text),
        EffectKind::TiltErrorMotion => read::<TiltHarmonicsSpec>(text),
        EffectKind::ToolWear => read::<WearSpec>(text),
        EffectKind::SpringBack => read::<SpringBackSpec>(text),
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

/// A required finite value in (0, limit].
fn positive_up_to(field: String, value: Option<f64>, limit: f64) -> Result<f64, JobError> {
    let range = format!("allowed: a finite number in (0, {limit}]");
    match value {
        None => Err(error(field, format!("missing; {range}"))),
        Some(v) if !v.is_finite() || v <= 0.0 || v > limit => {
            Err(error(field, format!("{v} is out of range; {range}")))
        }
        Some(v) => Ok(v),
    }
}

/// Largest minimum chip thickness (mm), and as a fraction of the nose radius: ploughing
/// is an edge-sharpness effect (h_min is a fraction of the cutting-edge radius, nm in
/// diamond turning, µm with honed carbide), far below the tool's nose.
const MAX_MIN_CHIP_MM: f64 = 0.005;
const MAX_MIN_CHIP_PER_NOSE_RADIUS: f64 = 0.1;

/// A running total of one kind's values over the tables, which must stay within the
/// same range as each table (checked at the last table that added to it).
struct Total {
    sum: f64,
    last: Option<String>,
}

impl Total {
    fn new() -> Self {
        Total {
            sum: 0.0,
            last: None,
        }
    }

    fn add(&mut self, field: String, value: f64) {
        self.sum += value;
        self.last = Some(field);
    }

    /// The total, or an error when several tables add up beyond `within`'s range
    /// (`within` tells whether a value is allowed and how the range reads).
    fn check(&self, within: impl Fn(f64) -> bool, range: &str) -> Result<f64, JobError> {
        match &self.last {
            Some(field) if !within(self.sum) => Err(error(
                field.clone(),
                format!(
                    "the tables of this kind add up to {}, out of range; allowed in total: {range}",
                    self.sum
                ),
            )),
            _ => Ok(self.sum),
        }
    }
}

/// Combines the effect tables into one set of turning effects (waviness adds up;
/// vibrations and error-motion harmonics are kept term by term). `nose_radius_mm`
/// bounds the effects that only make sense below the tool's size; `spindle_rpm` turns a
/// vibration's frequency into cycles per revolution.
pub fn turning_effects(
    specs: &[EffectSpec],
    nose_radius_mm: f64,
    spindle_rpm: Option<f64>,
) -> Result<TurningEffects, JobError> {
    let mut effects = TurningEffects::default();
    let mut harmonics = Vec::new();
    let mut spring_back_at = None;
    for (index, spec) in specs.iter().enumerate() {
        let field = |name: &str| format!("effects[{index}].{name}");
        spec.check_process(index, ProcessKind::Turning)?;
        match spec {
            EffectSpec::CentreHeight(s) => {
                effects.centre_height_mm +=
                    bounded(field("height_mm"), s.height_mm, 0.5 * nose_radius_mm)?;
            }
            EffectSpec::XDecentre(s) => {
                effects.x_decentre_mm += bounded(field("offset_mm"), s.offset_mm, nose_radius_mm)?;
            }
            EffectSpec::NoseRadiusError(s) => {
                effects.radius_error_mm +=
                    bounded(field("error_mm"), s.error_mm, 0.5 * nose_radius_mm)?;
            }
            EffectSpec::AxialDrift(s) => {
                effects.axial_drift_mm +=
                    bounded(field("drift_mm"), s.drift_mm, 0.5 * nose_radius_mm)?;
            }
            EffectSpec::SpringBack(s) => {
                if let Some(first) = spring_back_at.replace(index) {
                    return Err(error(
                        field("kind"),
                        format!(
                            "\"spring_back\" is already given in effects[{first}]; allowed: one spring_back table per job (its parameters do not add up)"
                        ),
                    ));
                }
                let limit = MAX_MIN_CHIP_MM.min(MAX_MIN_CHIP_PER_NOSE_RADIUS * nose_radius_mm);
                effects.spring_back_min_chip_mm =
                    positive_up_to(field("min_chip_mm"), s.min_chip_mm, limit)?;
                effects.spring_back_recovery = positive_up_to(field("recovery"), s.recovery, 1.0)?;
            }
            EffectSpec::EdgeWaviness(s) => {
                let list = s
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
            EffectSpec::Vibration(s) => {
                effects
                    .vibrations
                    .push(vibration(s, index, nose_radius_mm, spindle_rpm)?);
            }
            EffectSpec::AxialErrorMotion(s) => {
                let list = s.harmonics.as_deref().unwrap_or_default();
                let terms = list.iter().map(|h| (h.order, h.amplitude_mm, h.phase_deg));
                let limit = 0.1 * nose_radius_mm;
                effects.axial_error_motion.extend(spindle_harmonics(
                    terms,
                    &field("harmonics"),
                    "amplitude_mm",
                    limit,
                )?);
            }
            EffectSpec::TiltErrorMotion(s) => {
                let list = s.tilt_harmonics.as_deref().unwrap_or_default();
                let terms = list.iter().map(|h| (h.order, h.amplitude_deg, h.phase_deg));
                let tilts =
                    spindle_harmonics(terms, &field("tilt_harmonics"), "amplitude_deg", 0.05)?;
                effects
                    .tilt_error_motion
                    .extend(tilts.into_iter().map(|h| SpindleHarmonic {
                        amplitude: h.amplitude.to_radians(),
                        ..h
                    }));
            }
            EffectSpec::ToolWear(s) => {
                effects.wear_recession_mm +=
                    bounded(field("recession_mm"), s.recession_mm, 0.1 * nose_radius_mm)?;
            }
            _ => unreachable!("check_process admits turning kinds only"),
        }
    }
    if !harmonics.is_empty() {
        effects.edge_deviation = AngleTable::from_harmonics(&harmonics, WAVINESS_SAMPLES);
    }
    Ok(effects)
}

/// One `vibration` table: an amplitude below a tenth of the nose radius, a direction,
/// and exactly one of `per_revolution` and `frequency_hz` (with the spindle speed), at
/// most [`MAX_CYCLES_PER_REV`] cycles per revolution.
fn vibration(
    spec: &VibrationSpec,
    index: usize,
    nose_radius_mm: f64,
    spindle_rpm: Option<f64>,
) -> Result<Vibration, JobError> {
    let field = |name: &str| format!("effects[{index}].{name}");
    let amplitude_mm = bounded(
        field("amplitude_mm"),
        spec.amplitude_mm,
        0.1 * nose_radius_mm,
    )?;
    let direction = match spec.direction {
        Some(DirectionSpec::Feed) => VibrationDirection::Feed,
        Some(DirectionSpec::Depth) => VibrationDirection::Depth,
        None => {
            return Err(error(
                field("direction"),
                "missing; allowed: \"feed\" or \"depth\"",
            ));
        }
    };
    let range = format!("a number in (0, {MAX_CYCLES_PER_REV}] cycles per revolution");
    let cycles_per_rev = match (spec.per_revolution, spec.frequency_hz) {
        (Some(k), None) => k,
        (None, Some(f)) => {
            let rpm = spindle_rpm.ok_or_else(|| {
                error(
                    field("frequency_hz"),
                    "needs the spindle speed: give process.spindle_rpm, or per_revolution instead",
                )
            })?;
            if !f.is_finite() || f <= 0.0 {
                return Err(error(
                    field("frequency_hz"),
                    format!(
                        "{f} is out of range; allowed: a positive frequency up to {MAX_CYCLES_PER_REV} × rpm/60"
                    ),
                ));
            }
            f * 60.0 / rpm
        }
        (Some(_), Some(_)) => {
            return Err(error(
                field("frequency_hz"),
                "give either per_revolution or frequency_hz, not both",
            ));
        }
        (None, None) => {
            return Err(error(
                field("per_revolution"),
                format!("missing; give per_revolution ({range}) or frequency_hz"),
            ));
        }
    };
    if !cycles_per_rev.is_finite() || cycles_per_rev <= 0.0 || cycles_per_rev > MAX_CYCLES_PER_REV {
        let name = if spec.per_revolution.is_some() {
            "per_revolution"
        } else {
            "frequency_hz"
        };
        return Err(error(
            field(name),
            format!("{cycles_per_rev} cycles per revolution is out of range; allowed: {range}"),
        ));
    }
    let phase_rad = bounded(
        field("phase_deg"),
        Some(spec.phase_deg.unwrap_or(0.0)),
        360.0,
    )?
    .to_radians();
    Ok(Vibration {
        amplitude_mm,
        cycles_per_rev,
        phase_rad,
        direction,
    })
}

/// The harmonics of an error-motion table (`(order, amplitude, phase_deg)` as given):
/// whole orders 1 to [`MAX_CYCLES_PER_REV`], amplitudes within ±`limit`, at least one.
fn spindle_harmonics(
    terms: impl Iterator<Item = (f64, f64, f64)>,
    list_field: &str,
    amplitude_name: &str,
    limit: f64,
) -> Result<Vec<SpindleHarmonic>, JobError> {
    let mut harmonics = Vec::new();
    for (h, (order, amplitude, phase_deg)) in terms.enumerate() {
        let at = |name: &str| format!("{list_field}[{h}].{name}");
        if !order.is_finite()
            || order.fract() != 0.0
            || !(1.0..=MAX_CYCLES_PER_REV).contains(&order)
        {
            return Err(error(
                at("order"),
                format!(
                    "{order} is out of range; allowed: a whole number from 1 to {MAX_CYCLES_PER_REV}"
                ),
            ));
        }
        harmonics.push(SpindleHarmonic {
            order: order as u32,
            amplitude: bounded(at(amplitude_name), Some(amplitude), limit)?,
            phase_rad: bounded(at("phase_deg"), Some(phase_deg), 360.0)?.to_radians(),
        });
    }
    if harmonics.is_empty() {
        return Err(error(
            list_field.to_string(),
            format!("missing; give at least one {{ order, {amplitude_name} }}"),
        ));
    }
    Ok(harmonics)
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
        spec.check_process(index, ProcessKind::Generating)?;
        let field = |name: &str| format!("effects[{index}].{name}");
        match spec {
            EffectSpec::CutterDisplacement(s) => {
                effects.cutter_displacement_mm +=
                    bounded(field("offset_mm"), s.offset_mm, 0.5 * edge_radius)?;
            }
            EffectSpec::InclinationError(s) => {
                effects.inclination_error_rad +=
                    bounded(field("error_deg"), s.error_deg, max_tilt_deg)?.to_radians();
            }
            EffectSpec::PlungeError(s) => {
                effects.plunge_error_mm +=
                    bounded(field("error_mm"), s.error_mm, 0.5 * edge_radius)?;
            }
            _ => unreachable!("check_process admits generating kinds only"),
        }
    }
    Ok(effects)
}

/// Largest spindle tram per direction (degrees): the effect is a small-angle error.
const MAX_TRAM_DEG: f64 = 1.0;

/// Combines the effect tables of a milling job (values of a kind add up; runouts as
/// vectors) and fills the defaulted parameters into `resolved`. Bounds: a drift within
/// half the tool's radius; a radius error below half the ball / corner radius (ball and
/// bull-nose only); a tram of at most 1° each way, on tools it changes (bull-nose, flat
/// end); a runout within half the feed per tooth, on a tool with two or more teeth and a
/// feed per tooth.
pub fn milling_effects(
    specs: &[EffectSpec],
    setup: &MillingSetup,
    resolved: &mut [EffectSpec],
) -> Result<MillingEffects, JobError> {
    let (tool_name, tool_radius, corner_radius) = match setup.tool {
        MillingTool::EndMill(cutter) => {
            let name = if cutter.major_radius_mm == 0.0 {
                "ball_end"
            } else if cutter.corner_radius_mm == 0.0 {
                "flat_end"
            } else {
                "bull_nose"
            };
            (name, cutter.radius_mm(), cutter.corner_radius_mm)
        }
        MillingTool::Disc(disc) => ("disc", 0.5 * disc.diameter_mm, 0.0),
    };
    let (mut drift, mut radius_error) = (Total::new(), Total::new());
    let (mut tram_x, mut tram_y) = (Total::new(), Total::new());
    let (mut runout, mut runout_field) = (DVec2::ZERO, None);
    for (index, spec) in specs.iter().enumerate() {
        spec.check_process(index, ProcessKind::Milling)?;
        let field = |name: &str| format!("effects[{index}].{name}");
        match spec {
            EffectSpec::AxialDrift(s) => {
                let limit = 0.5 * tool_radius;
                drift.add(
                    field("drift_mm"),
                    bounded(field("drift_mm"), s.drift_mm, limit)?,
                );
            }
            EffectSpec::ToolRadiusError(s) => {
                if corner_radius == 0.0 {
                    return Err(error(
                        field("kind"),
                        format!(
                            "\"tool_radius_error\" changes a ball or corner radius, and tool.kind = \"{tool_name}\" has none; allowed with tool.kind = \"ball_end\" or \"bull_nose\""
                        ),
                    ));
                }
                let limit = 0.5 * corner_radius;
                let e = strictly_within(field("error_mm"), s.error_mm, limit)?;
                radius_error.add(field("error_mm"), e);
            }
            EffectSpec::SpindleTram(s) => {
                let reason = match setup.tool {
                    MillingTool::EndMill(cutter) if cutter.major_radius_mm == 0.0 => Some(
                        "has no effect on a ball end mill (a ball turned about its centre is the same ball)",
                    ),
                    MillingTool::Disc(_) => Some("is not modelled for disc cutters"),
                    MillingTool::EndMill(_) => None,
                };
                if let Some(reason) = reason {
                    return Err(error(
                        field("kind"),
                        format!(
                            "\"spindle_tram\" {reason}; allowed for bull-nose and flat-end tools (tool.kind = \"bull_nose\" or \"flat_end\")"
                        ),
                    ));
                }
                if s.tilt_x_deg.is_none() && s.tilt_y_deg.is_none() {
                    return Err(error(
                        field("tilt_x_deg"),
                        format!(
                            "missing: give tilt_x_deg, tilt_y_deg or both (each defaults to 0); allowed: a finite number in [−{MAX_TRAM_DEG}, {MAX_TRAM_DEG}]"
                        ),
                    ));
                }
                let x = bounded(
                    field("tilt_x_deg"),
                    s.tilt_x_deg.or(Some(0.0)),
                    MAX_TRAM_DEG,
                )?;
                let y = bounded(
                    field("tilt_y_deg"),
                    s.tilt_y_deg.or(Some(0.0)),
                    MAX_TRAM_DEG,
                )?;
                tram_x.add(field("tilt_x_deg"), x);
                tram_y.add(field("tilt_y_deg"), y);
                resolved[index] = EffectSpec::SpindleTram(TramSpec {
                    tilt_x_deg: Some(x),
                    tilt_y_deg: Some(y),
                });
            }
            EffectSpec::RadialRunout(s) => {
                let at = field("offset_mm");
                if setup.teeth < 2 {
                    return Err(error(
                        at,
                        format!(
                            "radial runout shows between teeth: it needs tool.teeth ≥ 2 (the job has {})",
                            setup.teeth
                        ),
                    ));
                }
                let feed = setup.feed_per_tooth_mm;
                if feed <= 0.0 {
                    return Err(error(
                        at,
                        "radial runout acts at each tooth's cut: it needs process.feed_per_tooth_mm > 0 (the job sweeps continuously)",
                    ));
                }
                let offset = bounded(at.clone(), s.offset_mm, 0.5 * feed)?;
                let phase = bounded(field("phase_deg"), s.phase_deg.or(Some(0.0)), 360.0)?;
                runout += offset * DVec2::from_angle(phase.to_radians());
                runout_field = Some(at);
                resolved[index] = EffectSpec::RadialRunout(RunoutSpec {
                    offset_mm: s.offset_mm,
                    phase_deg: Some(phase),
                });
            }
            _ => unreachable!("check_process admits milling kinds only"),
        }
    }
    let drift_limit = 0.5 * tool_radius;
    let tram_range = format!("[−{MAX_TRAM_DEG}, {MAX_TRAM_DEG}]");
    let effects = MillingEffects {
        axial_drift_mm: drift.check(
            |v| v.abs() <= drift_limit,
            &format!("[−{drift_limit}, {drift_limit}]"),
        )?,
        tool_radius_error_mm: radius_error.check(
            |v| v.abs() < 0.5 * corner_radius,
            &format!("(−{0}, {0})", 0.5 * corner_radius),
        )?,
        tram_x_rad: tram_x
            .check(|v| v.abs() <= MAX_TRAM_DEG, &tram_range)?
            .to_radians(),
        tram_y_rad: tram_y
            .check(|v| v.abs() <= MAX_TRAM_DEG, &tram_range)?
            .to_radians(),
        radial_runout_mm: runout,
    };
    if let Some(field) = runout_field
        && runout.length() > 0.5 * setup.feed_per_tooth_mm
    {
        return Err(error(
            field,
            format!(
                "the radial_runout tables add up to |ε| = {:.6}, out of range; allowed in total: at most feed_per_tooth/2 = {}",
                runout.length(),
                0.5 * setup.feed_per_tooth_mm
            ),
        ));
    }
    Ok(effects)
}

/// A required finite value strictly within ±limit.
fn strictly_within(field: String, value: Option<f64>, limit: f64) -> Result<f64, JobError> {
    let range = format!("allowed: a finite number in (−{limit}, {limit})");
    match value {
        None => Err(error(field, format!("missing; {range}"))),
        Some(v) if !v.is_finite() || v.abs() >= limit => {
            Err(error(field, format!("{v} is out of range; {range}")))
        }
        Some(v) => Ok(v),
    }
}

/// Samples of a measured edge's deviation table.
const EDGE_PROFILE_SAMPLES: usize = 2001;

/// Makes the tool cut with a measured edge: its fitted radius (against the nominal the
/// path assumes) and its radial deviation from that circle, ψ measured from the middle
/// of the measured arc (taken as the tip).
pub fn apply_edge_profile(
    effects: &mut TurningEffects,
    spec: &ArcNoseSpec,
    profile: &Path,
    tool: &ArcNoseTool,
    mode: TurningMode,
    warnings: &mut Vec<String>,
) -> Result<(), JobError> {
    // Edge waviness given as an effect (a calibration carried from an earlier part) is
    // added to the measured edge's own deviation.
    let waviness = std::mem::take(&mut effects.edge_deviation);
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
    for (i, v) in values.iter_mut().enumerate() {
        *v += waviness.at(start + step * i as f64);
    }
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

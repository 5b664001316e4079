//! The diagnosable effects: for each candidate, its parameters (in report units), how
//! trial values enter a job (added to the job's own effects), how fitted values are
//! written back as `[[effects]]` tables, and how a result is said to a machinist.

use crate::geometry::milling_tool::MillingTool;
use crate::geometry::tool::AngleTable;
use crate::model::Job;
use crate::process::effects::{SpindleHarmonic, Vibration, VibrationDirection, WAVINESS_SAMPLES};
use crate::process::{PlungeAxis, Process, TurningPath};
use glam::DVec2;

/// Relative difference within which two harmonic orders are one effect's.
const SAME_ORDER: f64 = 0.1;

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "effect")]
pub enum Candidate {
    CentreHeight,
    XDecentre,
    NoseRadiusError,
    AxialDrift,
    /// One harmonic of the edge's radial deviation; `order` is chosen by the fit.
    EdgeWaviness {
        order: f64,
    },
    CutterDisplacement,
    InclinationError,
    ToolRadiusError,
    SpindleTram,
    RadialRunout,
    /// Relative tool–workpiece vibration at `cycles` per revolution, along the depth
    /// (`depth`) or the feed; cos/sin amplitudes at the cut clock (nm). `cycles` 0 =
    /// screened on the residual first (`screen.rs`).
    Vibration {
        cycles: f64,
        depth: bool,
    },
    /// Spindle tilt error motion of one whole order (maps); cos/sin (µrad). `order` 0 =
    /// screened first.
    TiltErrorMotion {
        order: f64,
    },
    /// Edge recession by wear, linear in cut length (nm at the end of the cut).
    ToolWear,
    /// Spring-back below a minimum chip thickness: h_min (nm) and the recovered share ρ.
    SpringBack,
    /// Not an effect but registration: where a turned profile lies on the spiral (its
    /// azimuth from C = 0) sets where the marks fall. Re-fitted with every effect, as
    /// piston and tilt are re-solved, because a decentre, say, moves the marks too.
    SpiralAzimuth,
    /// Not an effect but registration: the instrument's lateral scale, as a correction
    /// (ppm) to where the placement put it. Fitted with the effects where the marks
    /// fix the scale: on a sphere a nose-radius error moves the marks out along the
    /// radius as a scale does (by Δρ/R), and it bends the form only half as much.
    LateralScale,
}

/// One fitted parameter.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Parameter {
    pub name: &'static str,
    pub unit: &'static str,
    /// A typical magnitude: the search's first step.
    pub scale: f64,
    /// The largest magnitude the job files allow.
    pub bound: f64,
    /// The smallest value the effect can physically take: −`bound`, or 0 for a
    /// one-sided effect (wear only recedes an edge).
    pub lower: f64,
}

impl Parameter {
    /// The search range, lower to upper.
    pub fn range(&self) -> (f64, f64) {
        (self.lower, self.bound)
    }

    /// `v` brought within the search range.
    pub fn clamp(&self, v: f64) -> f64 {
        v.clamp(self.lower, self.bound)
    }

    /// Whether `v` sits at an end of the search range: within 2 % of the bound's
    /// magnitude at a two-sided end, at the physical limit of a one-sided one.
    pub fn at_bound(&self, v: f64) -> bool {
        let near_lower = if self.is_one_sided() {
            self.at_physical_limit(v)
        } else {
            v <= -0.98 * self.bound
        };
        near_lower || v >= 0.98 * self.bound
    }

    /// Whether `v` sits at a one-sided range's lower end (within a thousandth of the
    /// scale): the data asks for less than the effect can be.
    pub fn at_physical_limit(&self, v: f64) -> bool {
        self.is_one_sided() && v <= self.lower + 1e-3 * self.scale
    }

    /// Whether the range stops short of −bound (a physical limit on one side).
    pub fn is_one_sided(&self) -> bool {
        self.lower > -self.bound
    }

    /// The range as a report writes it: `±bound`, or `lower to bound`.
    pub fn range_text(&self) -> String {
        if self.is_one_sided() {
            format!("{:.4} to {:.4} {}", self.lower, self.bound, self.unit)
        } else {
            format!("±{:.4} {}", self.bound, self.unit)
        }
    }

    /// The same parameter, never below `lower`.
    fn at_least(self, lower: f64) -> Parameter {
        Parameter { lower, ..self }
    }
}

fn parameter(name: &'static str, unit: &'static str, scale: f64, bound: f64) -> Parameter {
    Parameter {
        name,
        unit,
        scale,
        bound,
        lower: -bound,
    }
}

/// An effect the job's process has but the diagnosis cannot fit, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NotDiagnosable {
    pub effect: &'static str,
    pub reason: String,
}

/// The candidates for a job's process, and the process's effects left out (with why).
pub fn candidates_for(job: &Job) -> (Vec<Candidate>, Vec<NotDiagnosable>) {
    match &job.process {
        Process::Turning(t) => {
            let mut fit = vec![
                Candidate::CentreHeight,
                Candidate::XDecentre,
                Candidate::NoseRadiusError,
                Candidate::AxialDrift,
                Candidate::EdgeWaviness { order: 0.0 },
                Candidate::ToolWear,
                Candidate::Vibration {
                    cycles: 0.0,
                    depth: true,
                },
                Candidate::Vibration {
                    cycles: 0.0,
                    depth: false,
                },
                Candidate::TiltErrorMotion { order: 0.0 },
            ];
            let mut skip = vec![NotDiagnosable {
                effect: "axial_error_motion",
                reason: "a single cut records it exactly as a depth vibration of the same whole order; it is reported as one".to_string(),
            }];
            match &t.path {
                TurningPath::Nc(nc) if nc.tables.len() > 1 => skip.push(NotDiagnosable {
                    effect: "spring_back",
                    reason: format!(
                        "the engines run this program's {} cutting passes apart, and spring-back needs them in one sequence",
                        nc.tables.len()
                    ),
                }),
                _ => fit.push(Candidate::SpringBack),
            }
            (fit, skip)
        }
        Process::Generating(g) => {
            let reason = match g.setup.plunge_axis {
                PlungeAxis::Z => "a plunge error along Z only moves the part as a whole (a piston), which registration removes".to_string(),
                PlungeAxis::ToolAxis => "a plunge error along the tool axis acts exactly as a cutter displacement of −Δp·sin α plus a piston: the data cannot tell them apart, so it is reported as a displacement".to_string(),
            };
            (
                vec![Candidate::CutterDisplacement, Candidate::InclinationError],
                vec![NotDiagnosable {
                    effect: "plunge_error",
                    reason,
                }],
            )
        }
        Process::Milling(m) => {
            let setup = &m.setup;
            let (mut fit, mut skip) = (vec![Candidate::AxialDrift], Vec::new());
            let mut skip_because = |effect: &'static str, reason: &str| {
                skip.push(NotDiagnosable {
                    effect,
                    reason: reason.to_string(),
                })
            };
            match setup.tool {
                MillingTool::EndMill(c) => {
                    if c.corner_radius_mm > 0.0 {
                        fit.push(Candidate::ToolRadiusError);
                    } else {
                        skip_because("tool_radius_error", "a flat end mill has no corner radius");
                    }
                    if c.major_radius_mm > 0.0 {
                        fit.push(Candidate::SpindleTram);
                    } else {
                        skip_because(
                            "spindle_tram",
                            "a ball turned about its centre cuts the same part",
                        );
                    }
                }
                MillingTool::Disc(_) => {
                    skip_because("tool_radius_error", "not modelled for disc cutters");
                    skip_because("spindle_tram", "not modelled for disc cutters");
                }
            }
            if setup.teeth >= 2 && setup.feed_per_tooth_mm > 0.0 {
                fit.push(Candidate::RadialRunout);
            } else {
                skip_because(
                    "radial_runout",
                    "it shows only in feed marks: the job needs teeth ≥ 2 and feed_per_tooth_mm > 0",
                );
            }
            (fit, skip)
        }
    }
}

impl Candidate {
    /// The effect's `kind` in job files.
    pub fn kind(&self) -> &'static str {
        match self {
            Candidate::CentreHeight => "centre_height",
            Candidate::XDecentre => "x_decentre",
            Candidate::NoseRadiusError => "nose_radius_error",
            Candidate::AxialDrift => "axial_drift",
            Candidate::EdgeWaviness { .. } => "edge_waviness",
            Candidate::CutterDisplacement => "cutter_displacement",
            Candidate::InclinationError => "inclination_error",
            Candidate::ToolRadiusError => "tool_radius_error",
            Candidate::SpindleTram => "spindle_tram",
            Candidate::RadialRunout => "radial_runout",
            Candidate::Vibration { .. } => "vibration",
            Candidate::TiltErrorMotion { .. } => "tilt_error_motion",
            Candidate::ToolWear => "tool_wear",
            Candidate::SpringBack => "spring_back",
            Candidate::SpiralAzimuth => "spiral_azimuth",
            Candidate::LateralScale => "lateral_scale",
        }
    }

    /// Whether the effect moves a turned part's marks along the radius.
    pub fn moves_marks(&self) -> bool {
        *self == Candidate::XDecentre
    }

    /// How far the effect moves a turned part's marks out along the radius (mm).
    pub fn mark_shift_mm(&self, values: &[f64]) -> f64 {
        if self.moves_marks() {
            values[0] * 1e-3
        } else {
            0.0
        }
    }

    /// A centre height of `value` (µm) below centre: the tool leaves an uncut boss at the
    /// axis, whose edge — and so the height's σ — the data pin only between two points.
    pub fn is_boss(&self, value: f64) -> bool {
        *self == Candidate::CentreHeight && value < 0.0
    }

    /// An edge waviness (its order searched: the costliest fit).
    pub fn is_waviness(&self) -> bool {
        matches!(self, Candidate::EdgeWaviness { .. })
    }

    /// A registration term fitted like an effect, never reported as one.
    pub fn is_registration(&self) -> bool {
        matches!(self, Candidate::SpiralAzimuth | Candidate::LateralScale)
    }

    /// The harmonic order (cycles per revolution for a vibration) of a candidate that
    /// has one; 0 until screened.
    pub fn order(&self) -> Option<f64> {
        match *self {
            Candidate::EdgeWaviness { order } | Candidate::TiltErrorMotion { order } => Some(order),
            Candidate::Vibration { cycles, .. } => Some(cycles),
            _ => None,
        }
    }

    /// The same effect as `other`: the same kind, and for a harmonic its order within
    /// [`SAME_ORDER`] (two fits of one waviness land a fraction of an order apart).
    pub fn same_effect(&self, other: &Candidate) -> bool {
        let orders_agree = match (self.order(), other.order()) {
            (Some(a), Some(b)) => (a - b).abs() <= SAME_ORDER * a.abs().max(b.abs()),
            _ => true,
        };
        self.kind() == other.kind()
            && self.is_depth_vibration() == other.is_depth_vibration()
            && orders_agree
    }

    fn is_depth_vibration(&self) -> bool {
        matches!(self, Candidate::Vibration { depth: true, .. })
    }

    /// The candidate at harmonic order `order` (itself when it has none).
    pub fn with_order(self, order: f64) -> Candidate {
        match self {
            Candidate::EdgeWaviness { .. } => Candidate::EdgeWaviness { order },
            Candidate::TiltErrorMotion { .. } => Candidate::TiltErrorMotion { order },
            Candidate::Vibration { depth, .. } => Candidate::Vibration {
                cycles: order,
                depth,
            },
            c => c,
        }
    }

    /// A name for tables.
    pub fn label(&self) -> String {
        match *self {
            Candidate::EdgeWaviness { order } if order > 0.0 => {
                format!("edge waviness (order {order:.1})")
            }
            Candidate::Vibration { cycles, depth } => format!(
                "{} vibration{}",
                if depth { "depth" } else { "feed" },
                if cycles > 0.0 {
                    format!(" ({cycles:.3}/rev)")
                } else {
                    String::new()
                }
            ),
            Candidate::TiltErrorMotion { order } if order > 0.0 => {
                format!("tilt error motion (order {order:.0})")
            }
            _ => self.kind().replace('_', " "),
        }
    }

    /// The parameters, bounded as the job files bound them.
    pub fn parameters(&self, job: &Job) -> Vec<Parameter> {
        if *self == Candidate::LateralScale {
            return vec![parameter(
                "error",
                "ppm",
                100.0,
                super::locate::SCALE_BOUND * 1e6,
            )];
        }
        match (&job.process, self) {
            (Process::Turning(t), _) => {
                let nose_um = t.tool.nose_radius_mm * 1e3;
                match self {
                    Candidate::CentreHeight => vec![parameter("height", "µm", 1.0, 0.5 * nose_um)],
                    Candidate::XDecentre => vec![parameter("offset", "µm", 1.0, nose_um)],
                    Candidate::NoseRadiusError => {
                        vec![parameter("error", "µm", 1.0, 0.5 * nose_um)]
                    }
                    Candidate::AxialDrift => {
                        vec![parameter("drift", "nm", 10.0, 0.5 * nose_um * 1e3)]
                    }
                    // 7.2° moves the marks by a fiftieth of a feed.
                    Candidate::SpiralAzimuth => vec![parameter("offset", "deg", 7.2, 180.0)],
                    // Wear only recedes an edge: an edge that advances over the
                    // cut (a built-up edge) is a run's effect, not this diagnosis's.
                    Candidate::ToolWear => {
                        vec![parameter("recession", "nm", 10.0, 0.1 * nose_um * 1e3).at_least(0.0)]
                    }
                    Candidate::SpringBack => vec![
                        parameter("min_chip", "nm", 2.0, (0.1 * nose_um).min(5.0) * 1e3),
                        parameter("recovery", "1", 0.1, 1.0),
                    ],
                    Candidate::Vibration { depth, .. } => {
                        let scale = if *depth { 5.0 } else { 100.0 };
                        let bound = 0.1 * nose_um * 1e3 / 2f64.sqrt();
                        vec![
                            parameter("cos", "nm", scale, bound),
                            parameter("sin", "nm", scale, bound),
                        ]
                    }
                    Candidate::TiltErrorMotion { .. } => {
                        let bound = 0.05f64.to_radians() * 1e6 / 2f64.sqrt();
                        vec![
                            parameter("cos", "µrad", 1.0, bound),
                            parameter("sin", "µrad", 1.0, bound),
                        ]
                    }
                    _ => vec![
                        parameter("cos", "nm", 10.0, 1e4),
                        parameter("sin", "nm", 10.0, 1e4),
                    ],
                }
            }
            (Process::Generating(g), Candidate::CutterDisplacement) => vec![parameter(
                "offset",
                "µm",
                10.0,
                0.5 * g.setup.wheel.edge_radius_mm * 1e3,
            )],
            (Process::Generating(g), _) => vec![parameter(
                "error",
                "deg",
                0.002,
                0.1 * g.setup.inclination_rad.to_degrees(),
            )],
            (Process::Milling(m), _) => {
                let setup = &m.setup;
                let (corner, outer) = match setup.tool {
                    MillingTool::EndMill(c) => {
                        (c.corner_radius_mm, c.radius_mm() + c.corner_radius_mm)
                    }
                    MillingTool::Disc(d) => (0.0, 0.5 * d.outer_radius_mm()),
                };
                match self {
                    Candidate::AxialDrift => {
                        vec![parameter("drift", "nm", 10.0, 0.5 * outer * 1e6)]
                    }
                    Candidate::ToolRadiusError => {
                        vec![parameter("error", "µm", 1.0, 0.499 * corner * 1e3)]
                    }
                    Candidate::SpindleTram => vec![
                        parameter("tilt_x", "deg", 0.005, 1.0),
                        parameter("tilt_y", "deg", 0.005, 1.0),
                    ],
                    _ => {
                        // Each component within f/(2√2): the runout stays within f/2.
                        let bound = setup.feed_per_tooth_mm * 1e3 / 8f64.sqrt();
                        vec![
                            parameter("x", "µm", 0.5, bound),
                            parameter("y", "µm", 0.5, bound),
                        ]
                    }
                }
            }
        }
    }

    /// Adds the effect at `values` (report units) to the job's own effects.
    pub fn apply(&self, values: &[f64], job: &mut Job) {
        if *self == Candidate::LateralScale {
            return; // registration: it stretches the measurement, not the job
        }
        match (&mut job.process, self) {
            (Process::Turning(t), _) => {
                let e = &mut t.effects;
                match self {
                    Candidate::CentreHeight => e.centre_height_mm += values[0] * 1e-3,
                    Candidate::XDecentre => e.x_decentre_mm += values[0] * 1e-3,
                    Candidate::NoseRadiusError => e.radius_error_mm += values[0] * 1e-3,
                    Candidate::AxialDrift => e.axial_drift_mm += values[0] * 1e-6,
                    Candidate::SpiralAzimuth => t.azimuth_offset_rad += values[0].to_radians(),
                    Candidate::EdgeWaviness { order } => add_harmonic(
                        &mut e.edge_deviation,
                        *order,
                        values[0] * 1e-6,
                        values[1] * 1e-6,
                    ),
                    Candidate::ToolWear => e.wear_recession_mm += values[0] * 1e-6,
                    // Only a positive threshold and share spring back (a trial outside
                    // them leaves the cut as it is).
                    Candidate::SpringBack if values[0] > 0.0 && values[1] > 0.0 => {
                        e.spring_back_min_chip_mm = values[0] * 1e-6;
                        e.spring_back_recovery = values[1].min(1.0);
                    }
                    Candidate::SpringBack => {}
                    Candidate::Vibration { cycles, depth } => {
                        let (amplitude, phase) = amplitude_phase(values);
                        e.vibrations.push(Vibration {
                            amplitude_mm: amplitude * 1e-6,
                            cycles_per_rev: *cycles,
                            phase_rad: phase.to_radians(),
                            direction: if *depth {
                                VibrationDirection::Depth
                            } else {
                                VibrationDirection::Feed
                            },
                        });
                    }
                    Candidate::TiltErrorMotion { order } => {
                        let (amplitude, phase) = amplitude_phase(values);
                        e.tilt_error_motion.push(SpindleHarmonic {
                            order: order.round() as u32,
                            amplitude: amplitude * 1e-6,
                            phase_rad: phase.to_radians(),
                        });
                    }
                    _ => unreachable!("a turning candidate"),
                }
            }
            (Process::Generating(g), Candidate::CutterDisplacement) => {
                g.effects.cutter_displacement_mm += values[0] * 1e-3
            }
            (Process::Generating(g), Candidate::InclinationError) => {
                g.effects.inclination_error_rad += values[0].to_radians()
            }
            (Process::Milling(m), _) => {
                let e = &mut m.effects;
                match self {
                    Candidate::AxialDrift => e.axial_drift_mm += values[0] * 1e-6,
                    Candidate::ToolRadiusError => e.tool_radius_error_mm += values[0] * 1e-3,
                    Candidate::SpindleTram => {
                        e.tram_x_rad += values[0].to_radians();
                        e.tram_y_rad += values[1].to_radians();
                    }
                    Candidate::RadialRunout => {
                        e.radial_runout_mm += DVec2::new(values[0], values[1]) * 1e-3
                    }
                    _ => unreachable!("a milling candidate"),
                }
            }
            _ => unreachable!("candidates come from candidates_for"),
        }
    }

    /// The fitted effect as an `[[effects]]` table (TOML).
    pub fn effects_table(&self, values: &[f64]) -> String {
        let (key, value) = match self {
            Candidate::CentreHeight => ("height_mm", values[0] * 1e-3),
            Candidate::XDecentre | Candidate::CutterDisplacement => ("offset_mm", values[0] * 1e-3),
            Candidate::NoseRadiusError | Candidate::ToolRadiusError => {
                ("error_mm", values[0] * 1e-3)
            }
            Candidate::AxialDrift => ("drift_mm", values[0] * 1e-6),
            Candidate::SpindleTram => {
                return format!(
                    "[[effects]]\nkind = \"spindle_tram\"\ntilt_x_deg = {:.6e}\ntilt_y_deg = {:.6e}\n",
                    values[0], values[1]
                );
            }
            Candidate::RadialRunout => {
                let v = DVec2::new(values[0], values[1]);
                return format!(
                    "[[effects]]\nkind = \"radial_runout\"\noffset_mm = {:.6e}\nphase_deg = {:.3}\n",
                    v.length() * 1e-3,
                    v.y.atan2(v.x).to_degrees()
                );
            }
            Candidate::InclinationError => ("error_deg", values[0]),
            Candidate::ToolWear => ("recession_mm", values[0] * 1e-6),
            Candidate::SpringBack => {
                return format!(
                    "[[effects]]\nkind = \"spring_back\"\nmin_chip_mm = {:.6e}\nrecovery = {:.4}\n",
                    values[0] * 1e-6,
                    values[1]
                );
            }
            Candidate::Vibration { cycles, depth } => {
                let (amplitude, phase) = amplitude_phase(values);
                return format!(
                    "[[effects]]\nkind = \"vibration\"\namplitude_mm = {:.6e}\ndirection = \"{}\"\nper_revolution = {cycles:.6}\nphase_deg = {phase:.3}\n",
                    amplitude * 1e-6,
                    if *depth { "depth" } else { "feed" }
                );
            }
            Candidate::TiltErrorMotion { order } => {
                let (amplitude, phase) = amplitude_phase(values);
                return format!(
                    "[[effects]]\nkind = \"tilt_error_motion\"\ntilt_harmonics = [{{ order = {order:.0}, amplitude_deg = {:.6e}, phase_deg = {phase:.3} }}]\n",
                    (amplitude * 1e-6).to_degrees()
                );
            }
            Candidate::SpiralAzimuth | Candidate::LateralScale => return String::new(),
            Candidate::EdgeWaviness { order } => {
                let (amplitude, phase) = amplitude_phase(values);
                return format!(
                    "[[effects]]\nkind = \"edge_waviness\"\nharmonics = [{{ order = {order:.4}, amplitude_mm = {:.6e}, phase_deg = {phase:.3} }}]\n",
                    amplitude * 1e-6
                );
            }
        };
        format!(
            "[[effects]]\nkind = \"{}\"\n{key} = {value:.6e}\n",
            self.kind()
        )
    }

    /// What the fit says, with its uncertainty, in a machinist's words (`order_sigma`:
    /// one σ of an edge waviness's order, where known).
    pub fn describe(&self, values: &[f64], sigmas: &[f64], order_sigma: Option<f64>) -> String {
        let v = values[0];
        let s = sigmas[0];
        match self {
            Candidate::CentreHeight => format!(
                "the tool sits {} µm {} centre",
                pm(v.abs(), s),
                if v >= 0.0 { "above" } else { "below" }
            ),
            Candidate::XDecentre => {
                if v >= 0.0 {
                    format!("the tool stops {} µm short of the axis", pm(v, s))
                } else {
                    format!("the tool runs {} µm past the axis", pm(-v, s))
                }
            }
            Candidate::NoseRadiusError => format!(
                "the nose radius is {} µm {} than nominal",
                pm(v.abs(), s),
                if v >= 0.0 { "larger" } else { "smaller" }
            ),
            Candidate::AxialDrift => format!(
                "the tool drifted {} nm along Z over the cut ({})",
                pm(v.abs(), s),
                if v >= 0.0 {
                    "away from the part"
                } else {
                    "into the part"
                }
            ),
            Candidate::EdgeWaviness { order } => {
                let (amplitude, phase) = amplitude_phase(values);
                let sigma = pair_sigma(values, sigmas);
                let order = match order_sigma.filter(|s| s.is_finite()) {
                    Some(s) => format!("{order:.1} ± {s:.1}"),
                    None => format!("{order:.1}"),
                };
                format!(
                    "the edge carries waviness of order {order}: {} nm amplitude (phase {phase:.0}°)",
                    pm(amplitude, sigma)
                )
            }
            Candidate::CutterDisplacement => format!(
                "the wheel's cutting circle {} the axis by {} µm",
                if v >= 0.0 {
                    "stops short of"
                } else {
                    "runs past"
                },
                pm(v.abs(), s)
            ),
            Candidate::InclinationError => format!(
                "the wheel is inclined {}° {} than set",
                pm_digits(v.abs(), s, 4),
                if v >= 0.0 { "more" } else { "less" }
            ),
            Candidate::ToolRadiusError => format!(
                "the cutter's corner (ball) radius is {} µm {} than nominal",
                pm(v.abs(), s),
                if v >= 0.0 { "larger" } else { "smaller" }
            ),
            Candidate::SpindleTram if sigmas.iter().any(|s| s.is_infinite()) => {
                let seen = if sigmas[0].is_finite() { 0 } else { 1 };
                format!(
                    "the spindle is out of tram by at least {}° (tilt {} {}°; the other tilt is not seen by this measurement)",
                    pm_digits(values[seen].abs(), sigmas[seen], 4),
                    if seen == 0 { "X" } else { "Y" },
                    pm_digits(values[seen], sigmas[seen], 4)
                )
            }
            Candidate::SpindleTram => {
                let tilt = values[0].hypot(values[1]);
                let sigma = pair_sigma(values, sigmas);
                format!(
                    "the spindle is out of tram by {}° toward {:.0}° (tilt X {:.4}°, Y {:.4}°)",
                    pm_digits(tilt, sigma, 4),
                    values[1].atan2(values[0]).to_degrees(),
                    values[0],
                    values[1]
                )
            }
            Candidate::RadialRunout if sigmas.iter().any(|s| s.is_infinite()) => {
                let seen = if sigmas[0].is_finite() { 0 } else { 1 };
                format!(
                    "the cutter runs out at least {} µm: the teeth's marks alternate by 2 × {} µm {} the feed (the other component is not seen by this measurement, nor which tooth cuts the longer mark unless the profile's position along the feed is known)",
                    pm(values[seen].abs(), sigmas[seen]),
                    pm(values[seen].abs(), sigmas[seen]),
                    if seen == 0 { "along" } else { "across" },
                )
            }
            Candidate::RadialRunout => {
                let runout = values[0].hypot(values[1]);
                let sigma = pair_sigma(values, sigmas);
                format!(
                    "the cutter runs out {} µm (tooth 0 at {:.0}° from the feed)",
                    pm(runout, sigma),
                    values[1].atan2(values[0]).to_degrees()
                )
            }
            // The recession is searched from 0 up ([`Candidate::parameters`]).
            Candidate::ToolWear => format!(
                "the edge wore back {} nm over the cut (growing with the length cut)",
                pm(v, s)
            ),
            Candidate::SpringBack => format!(
                "chips thinner than {} nm plough and {} % of them springs back (raising the flank beside each cusp; the mark spacing stays)",
                pm(v, s),
                pm(100.0 * values[1], 100.0 * sigmas[1])
            ),
            Candidate::Vibration { cycles, depth } => {
                let (amplitude, phase) = amplitude_phase(values);
                let synchronous = (cycles - cycles.round()).abs() < 0.005;
                format!(
                    "the tool vibrated {} nm along the {} at {cycles:.3} cycles per revolution (phase {phase:.0}°){}",
                    pm(amplitude, pair_sigma(values, sigmas)),
                    if *depth { "depth (Z)" } else { "feed (X)" },
                    match (synchronous, depth) {
                        (true, true) => format!(
                            ": synchronous with the spindle, which an axial spindle error motion of order {:.0} leaves exactly alike",
                            cycles.round()
                        ),
                        (true, false) => ": synchronous with the spindle".to_string(),
                        _ => String::new(),
                    }
                )
            }
            Candidate::TiltErrorMotion { order } => {
                let (amplitude, phase) = amplitude_phase(values);
                format!(
                    "the spindle tilts {} µrad at order {order:.0} (phase {phase:.0}°)",
                    pm(amplitude, pair_sigma(values, sigmas))
                )
            }
            Candidate::SpiralAzimuth => format!(
                "the profile lies {}° round the spiral from where registration first put it",
                pm(v, s)
            ),
            Candidate::LateralScale => format!(
                "the lateral scale is {} ppm off where registration first put it",
                pm(v, s)
            ),
        }
    }

    /// What to do at the machine.
    pub fn advice(&self, values: &[f64]) -> String {
        let v = values[0];
        match self {
            Candidate::CentreHeight => format!(
                "{} the tool by {:.2} µm",
                if v >= 0.0 { "lower" } else { "raise" },
                v.abs()
            ),
            Candidate::XDecentre => format!(
                "shift the tool's X zero {:.2} µm {}",
                v.abs(),
                if v >= 0.0 { "toward the axis" } else { "away from the axis" }
            ),
            Candidate::NoseRadiusError => format!(
                "plan the path with the measured nose radius (nominal {:+.2} µm)",
                v
            ),
            Candidate::AxialDrift => {
                "let the machine reach thermal balance before finishing, or compensate Z over the cut".to_string()
            }
            Candidate::EdgeWaviness { .. } => {
                "compensate the edge waviness in the path (toolmark compensate --effects effects.toml)".to_string()
            }
            Candidate::CutterDisplacement => format!(
                "move the wheel {:.2} µm {} along X",
                v.abs(),
                if v >= 0.0 { "toward the axis" } else { "away from the axis" }
            ),
            Candidate::InclinationError => format!("change the wheel's inclination by {:+.4}°", -v),
            Candidate::ToolRadiusError => format!(
                "enter the measured corner radius (nominal {v:+.2} µm) in the CAM tool table"
            ),
            Candidate::SpindleTram => format!(
                "re-tram the spindle: {:.4}° back from {:.0}°",
                values[0].hypot(values[1]),
                values[1].atan2(values[0]).to_degrees()
            ),
            Candidate::RadialRunout => format!(
                "re-seat the tool or clean the collet: {:.2} µm of runout",
                values[0].hypot(values[1])
            ),
            Candidate::ToolWear => {
                "re-lap or replace the tool, or finish with a fresh edge on a shorter cut".to_string()
            }
            Candidate::SpringBack => {
                "a property of edge and material, not a machine error: carry it in the model (run --effects); a sharper edge or a finishing feed that keeps the chip thicker reduces it".to_string()
            }
            Candidate::Vibration { cycles, .. } => format!(
                "find what excites {cycles:.3} × the spindle frequency (balance, drives, pumps, the floor) and isolate it, or move the spindle speed so it no longer prints"
            ),
            Candidate::TiltErrorMotion { .. } => {
                "measure the spindle's tilt error motion (ISO 230-7) and service the bearing if it exceeds its specification".to_string()
            }
            Candidate::SpiralAzimuth | Candidate::LateralScale => String::new(),
        }
    }
}

/// The uncertainty of a pair's magnitude √(a² + b²): the components' σs projected on
/// the pair's direction; where the magnitude is within 2σ of zero (its direction
/// unknown), their RMS. Over the components the data sees (a component it does not see
/// stays at zero with an infinite sigma).
pub fn pair_sigma(values: &[f64], sigmas: &[f64]) -> f64 {
    let seen: Vec<(f64, f64)> = values
        .iter()
        .zip(sigmas)
        .map(|(&v, &s)| (v, s))
        .filter(|(_, s)| s.is_finite())
        .collect();
    if seen.is_empty() {
        return f64::INFINITY;
    }
    let rms = (seen.iter().map(|(_, s)| s * s).sum::<f64>() / seen.len() as f64).sqrt();
    let magnitude = seen.iter().map(|(v, _)| v * v).sum::<f64>().sqrt();
    if magnitude <= 2.0 * rms {
        return rms;
    }
    seen.iter()
        .map(|(v, s)| (v * s).powi(2))
        .sum::<f64>()
        .sqrt()
        / magnitude
}

/// A value ± its uncertainty at a sensible number of digits.
fn pm(value: f64, sigma: f64) -> String {
    let digits = if sigma.is_finite() && sigma > 0.0 {
        (-(sigma.log10().floor()) + 1.0).clamp(0.0, 4.0) as usize
    } else {
        2
    };
    pm_digits(value, sigma, digits)
}

fn pm_digits(value: f64, sigma: f64, digits: usize) -> String {
    if sigma.is_finite() {
        format!("{value:.digits$} ± {sigma:.digits$}")
    } else {
        format!("{value:.digits$} (uncertainty unknown)")
    }
}

/// (amplitude, phase°) of a cos/sin pair: a cos kψ + b sin kψ = A cos(kψ + φ).
fn amplitude_phase(values: &[f64]) -> (f64, f64) {
    (
        values[0].hypot(values[1]),
        (-values[1]).atan2(values[0]).to_degrees(),
    )
}

/// Adds a·cos(kψ) + b·sin(kψ) (mm) to an edge deviation table (a new table over the
/// edge when it was zero).
fn add_harmonic(table: &mut AngleTable, order: f64, a: f64, b: f64) {
    if table.values_mm.is_empty() || table.is_zero() {
        *table = AngleTable::from_harmonics(&[(order, 0.0, 0.0)], WAVINESS_SAMPLES);
    }
    for (i, v) in table.values_mm.iter_mut().enumerate() {
        let psi = table.start_rad + i as f64 * table.step_rad;
        *v += a * (order * psi).cos() + b * (order * psi).sin();
    }
}

//! Jobs built in Rust: the same file types a TOML job becomes, started from the fields
//! each kind needs and finished by the same validation (`JobFile::check`). Optional
//! fields are set on the specs themselves (`TurningSpec { spindle_rpm: Some(…),
//! ..TurningSpec::xz(0.005) }`).
//!
//! ```text
//! use toolmark::geometry::Form;
//! use toolmark::model::{JobFile, ProcessSpec, SurfaceSpec, ToolSpec, TurningSpec};
//! let job = JobFile::new(
//!     SurfaceSpec::sphere(Form::Convex, 8.0, 3.0),
//!     ToolSpec::arc_nose(0.5, 140.0),
//!     ProcessSpec::Turning(TurningSpec::xz(0.01)),
//! )
//! .named("turned sphere")
//! .grid(0.5, 8)
//! .check()
//! .expect("a valid job");
//! assert_eq!(job.azimuths, 8);
//! ```

use super::{
    AngleErrorSpec, ArcNoseSpec, AsphereSpec, CentreHeightSpec, CupWheelSpec, DirectionSpec,
    DriftSpec, EffectSpec, ErrorSpec, GeneratingSpec, GridSpec, HarmonicSpec, HarmonicsSpec,
    JOB_VERSION, Job, JobError, JobFile, MillToolSpec, MillingSpec, OffsetSpec, OutputSpec,
    PlaneSpec, ProcessSpec, SphereSpec, SpringBackSpec, SurfaceSpec, ToolSpec, TramSpec,
    TurningSpec, VibrationSpec, WearSpec,
};
use crate::geometry::Form;
use crate::process::{MillingPathKind, TurningMode};
use std::path::Path;

impl JobFile {
    /// A job of a surface, a tool and a process; no name, the default grid and outputs,
    /// no effects.
    pub fn new(surface: SurfaceSpec, tool: ToolSpec, process: ProcessSpec) -> JobFile {
        JobFile {
            version: JOB_VERSION,
            name: None,
            surface,
            tool,
            process,
            grid: GridSpec::default(),
            output: OutputSpec::default(),
            effects: Vec::new(),
        }
    }

    pub fn named(mut self, name: &str) -> JobFile {
        self.name = Some(name.to_string());
        self
    }

    /// The grid: ring pitch along the meridian (µm) and azimuth rows.
    pub fn grid(mut self, pitch_um: f64, azimuths: u32) -> JobFile {
        self.grid = GridSpec {
            pitch_um: Some(pitch_um),
            azimuths: Some(azimuths),
        };
        self
    }

    /// One more `[[effects]]` table.
    pub fn effect(mut self, effect: EffectSpec) -> JobFile {
        self.effects.push(effect);
        self
    }

    /// The checked job, as `toolmark check` would give it for this file (file names
    /// resolve against the current folder; the name defaults to "job").
    pub fn check(self) -> Result<Job, JobError> {
        Job::from_file(self, "job", Path::new("."))
    }

    /// The file as TOML (what `toolmark run` reads).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("a job file serialises")
    }
}

impl SurfaceSpec {
    pub fn plane(aperture_diameter_mm: f64) -> SurfaceSpec {
        SurfaceSpec::Plane(PlaneSpec {
            aperture_diameter_mm: Some(aperture_diameter_mm),
            inner_diameter_mm: 0.0,
        })
    }

    pub fn sphere(form: Form, radius_mm: f64, aperture_diameter_mm: f64) -> SurfaceSpec {
        SurfaceSpec::Sphere(SphereSpec {
            form: Some(form),
            radius_mm: Some(radius_mm),
            aperture_diameter_mm: Some(aperture_diameter_mm),
            inner_diameter_mm: 0.0,
        })
    }

    /// An even asphere's base: radius R0 and conic k (coefficients: set `a4`… on an
    /// `AsphereSpec`).
    pub fn asphere(
        form: Form,
        base_radius_mm: f64,
        conic: f64,
        aperture_diameter_mm: f64,
    ) -> SurfaceSpec {
        SurfaceSpec::Asphere(AsphereSpec {
            form: Some(form),
            base_radius_mm: Some(base_radius_mm),
            conic: Some(conic),
            aperture_diameter_mm: Some(aperture_diameter_mm),
            ..AsphereSpec::default()
        })
    }
}

impl ToolSpec {
    pub fn arc_nose(nose_radius_mm: f64, included_angle_deg: f64) -> ToolSpec {
        ToolSpec::ArcNose(ArcNoseSpec {
            nose_radius_mm: Some(nose_radius_mm),
            included_angle_deg: Some(included_angle_deg),
            ..ArcNoseSpec::default()
        })
    }

    /// A cup wheel of `teeth` edges (0: a continuous edge).
    pub fn cup_wheel(cutting_radius_mm: f64, edge_radius_mm: f64, teeth: u32) -> ToolSpec {
        ToolSpec::CupWheel(CupWheelSpec {
            cutting_radius_mm: Some(cutting_radius_mm),
            edge_radius_mm: Some(edge_radius_mm),
            teeth: Some(teeth),
        })
    }

    pub fn ball_end(diameter_mm: f64) -> ToolSpec {
        ToolSpec::BallEnd(MillToolSpec::of_diameter(diameter_mm))
    }

    pub fn bull_nose(diameter_mm: f64, corner_radius_mm: f64) -> ToolSpec {
        ToolSpec::BullNose(MillToolSpec {
            corner_radius_mm: Some(corner_radius_mm),
            ..MillToolSpec::of_diameter(diameter_mm)
        })
    }

    pub fn flat_end(diameter_mm: f64) -> ToolSpec {
        ToolSpec::FlatEnd(MillToolSpec::of_diameter(diameter_mm))
    }
}

impl EffectSpec {
    pub fn centre_height(height_mm: f64) -> EffectSpec {
        EffectSpec::CentreHeight(CentreHeightSpec {
            height_mm: Some(height_mm),
        })
    }

    pub fn x_decentre(offset_mm: f64) -> EffectSpec {
        EffectSpec::XDecentre(OffsetSpec {
            offset_mm: Some(offset_mm),
        })
    }

    pub fn nose_radius_error(error_mm: f64) -> EffectSpec {
        EffectSpec::NoseRadiusError(ErrorSpec {
            error_mm: Some(error_mm),
        })
    }

    /// One harmonic of edge waviness.
    pub fn edge_waviness(order: f64, amplitude_mm: f64, phase_deg: f64) -> EffectSpec {
        EffectSpec::EdgeWaviness(HarmonicsSpec {
            harmonics: Some(vec![HarmonicSpec {
                order,
                amplitude_mm,
                phase_deg,
            }]),
        })
    }

    /// A relative vibration of an amplitude along a direction, at cycles per spindle
    /// revolution and a phase (°).
    pub fn vibration(
        amplitude_mm: f64,
        direction: DirectionSpec,
        per_revolution: f64,
        phase_deg: f64,
    ) -> EffectSpec {
        EffectSpec::Vibration(VibrationSpec {
            amplitude_mm: Some(amplitude_mm),
            direction: Some(direction),
            per_revolution: Some(per_revolution),
            phase_deg: Some(phase_deg),
            ..VibrationSpec::default()
        })
    }

    pub fn axial_drift(drift_mm: f64) -> EffectSpec {
        EffectSpec::AxialDrift(DriftSpec {
            drift_mm: Some(drift_mm),
        })
    }

    pub fn tool_wear(recession_mm: f64) -> EffectSpec {
        EffectSpec::ToolWear(WearSpec {
            recession_mm: Some(recession_mm),
        })
    }

    pub fn spring_back(min_chip_mm: f64, recovery: f64) -> EffectSpec {
        EffectSpec::SpringBack(SpringBackSpec {
            min_chip_mm: Some(min_chip_mm),
            recovery: Some(recovery),
        })
    }

    pub fn cutter_displacement(offset_mm: f64) -> EffectSpec {
        EffectSpec::CutterDisplacement(OffsetSpec {
            offset_mm: Some(offset_mm),
        })
    }

    pub fn inclination_error(error_deg: f64) -> EffectSpec {
        EffectSpec::InclinationError(AngleErrorSpec {
            error_deg: Some(error_deg),
        })
    }

    pub fn plunge_error(error_mm: f64) -> EffectSpec {
        EffectSpec::PlungeError(ErrorSpec {
            error_mm: Some(error_mm),
        })
    }

    pub fn tool_radius_error(error_mm: f64) -> EffectSpec {
        EffectSpec::ToolRadiusError(ErrorSpec {
            error_mm: Some(error_mm),
        })
    }

    pub fn spindle_tram(tilt_x_deg: f64, tilt_y_deg: f64) -> EffectSpec {
        EffectSpec::SpindleTram(TramSpec {
            tilt_x_deg: Some(tilt_x_deg),
            tilt_y_deg: Some(tilt_y_deg),
        })
    }
}

impl MillToolSpec {
    /// A milling tool's table of a diameter, its other fields to be set.
    pub fn of_diameter(diameter_mm: f64) -> MillToolSpec {
        MillToolSpec {
            diameter_mm: Some(diameter_mm),
            ..MillToolSpec::default()
        }
    }
}

impl TurningSpec {
    /// An XZ spiral at a feed per revolution.
    pub fn xz(feed_per_rev_mm: f64) -> TurningSpec {
        TurningSpec {
            mode: Some(TurningMode::Xz),
            feed_per_rev_mm: Some(feed_per_rev_mm),
            ..TurningSpec::default()
        }
    }

    /// An XZB spiral (the tool turned to the normal) at a feed per revolution.
    pub fn xzb(feed_per_rev_mm: f64) -> TurningSpec {
        TurningSpec {
            mode: Some(TurningMode::Xzb),
            ..TurningSpec::xz(feed_per_rev_mm)
        }
    }
}

impl GeneratingSpec {
    /// Generating at the wheel and workpiece speeds (rpm), the rest by default.
    pub fn at_speeds(tool_rpm: f64, workpiece_rpm: f64) -> GeneratingSpec {
        GeneratingSpec {
            tool_rpm: Some(tool_rpm),
            workpiece_rpm: Some(workpiece_rpm),
            ..GeneratingSpec::default()
        }
    }
}

impl MillingSpec {
    /// A path of passes a step-over apart (raster or spiral).
    pub fn stepped(path: MillingPathKind, stepover_mm: f64) -> MillingSpec {
        MillingSpec {
            path: Some(path),
            stepover_mm: Some(stepover_mm),
            ..MillingSpec::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TURNED_SPHERE: &str = r#"version = 1
name = "turned sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 8.0
aperture_diameter_mm = 3.0
[tool]
kind = "arc_nose"
nose_radius_mm = 0.5
included_angle_deg = 140.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = 0.01
[grid]
pitch_um = 0.5
azimuths = 8
"#;

    fn turned_sphere() -> JobFile {
        JobFile::new(
            SurfaceSpec::sphere(Form::Convex, 8.0, 3.0),
            ToolSpec::arc_nose(0.5, 140.0),
            ProcessSpec::Turning(TurningSpec::xz(0.01)),
        )
        .named("turned sphere")
        .grid(0.5, 8)
    }

    #[test]
    fn a_job_built_in_rust_is_the_job_its_toml_gives() {
        let built = turned_sphere().check().expect("valid");
        let read = Job::from_toml_str(TURNED_SPHERE, "job").expect("valid");
        assert_eq!(built.resolved, read.resolved);
        assert_eq!(built.sample_count(), read.sample_count());
        assert_eq!(
            (built.pitch_mm, built.azimuths),
            (read.pitch_mm, read.azimuths)
        );
        // The resolved file filled in the defaults: the 2 µm stock allowance.
        let ProcessSpec::Turning(spec) = &built.resolved.process else {
            panic!("a turning job")
        };
        assert_eq!(spec.stock_allowance_mm, Some(0.002));
    }

    #[test]
    fn a_built_job_written_as_toml_reads_back_as_the_same_job() {
        let file = JobFile::new(
            SurfaceSpec::plane(4.0),
            ToolSpec::bull_nose(3.0, 0.5),
            ProcessSpec::Milling(MillingSpec::stepped(MillingPathKind::Raster, 0.1)),
        )
        .grid(2.0, 8);
        let text = file.to_toml();
        assert!(text.contains("kind = \"bull_nose\""), "{text}");
        let read = Job::from_toml_str(&text, "job").expect("valid");
        assert_eq!(read.resolved, file.check().expect("valid").resolved);
    }

    #[test]
    fn a_key_of_another_kind_is_refused_by_name() {
        let text = TURNED_SPHERE.replace("feed_per_rev_mm = 0.01", "stepover_mm = 0.01");
        let message = Job::from_toml_str(&text, "job")
            .expect_err("a milling key in a turning job")
            .to_string();
        assert!(message.contains("unknown field `stepover_mm`"), "{message}");
        assert!(message.contains("feed_per_rev_mm"), "{message}");
        let text = TURNED_SPHERE.replace("nose_radius_mm = 0.5", "diameter_mm = 0.5");
        let message = Job::from_toml_str(&text, "job")
            .expect_err("a milling tool's key on an arc-nosed tool")
            .to_string();
        assert!(message.contains("unknown field `diameter_mm`"), "{message}");
    }

    #[test]
    fn built_effects_are_the_tables_their_toml_gives() {
        let text = format!(
            "{TURNED_SPHERE}[[effects]]\nkind = \"centre_height\"\nheight_mm = 0.003\n\
             [[effects]]\nkind = \"edge_waviness\"\n\
             harmonics = [{{ order = 20, amplitude_mm = 4e-5, phase_deg = 30.0 }}]\n\
             [[effects]]\nkind = \"spring_back\"\nmin_chip_mm = 5e-6\nrecovery = 0.6\n"
        );
        let built = turned_sphere()
            .effect(EffectSpec::centre_height(0.003))
            .effect(EffectSpec::edge_waviness(20.0, 4e-5, 30.0))
            .effect(EffectSpec::spring_back(5e-6, 0.6));
        assert_eq!(JobFile::from_toml_str(&text).expect("valid"), built);
        // Written out, the tables read back as the same effects.
        let again = JobFile::from_toml_str(&built.to_toml()).expect("valid");
        assert_eq!(again.effects, built.effects);
        assert_eq!(
            built.check().expect("valid").process,
            Job::from_toml_str(&text, "job").expect("valid").process
        );
    }

    #[test]
    fn a_wrong_value_in_an_effect_is_named_by_its_table_and_key() {
        let text = format!(
            "{TURNED_SPHERE}[[effects]]\nkind = \"axial_drift\"\ndrift_mm = 1e-4\n\
             [[effects]]\nkind = \"tool_wear\"\nrecession_mm = \"a little\"\n"
        );
        let err = Job::from_toml_str(&text, "job").expect_err("a string for a length");
        assert_eq!(err.field, "effects[1].recession_mm", "{err}");
        let text = text.replace("recession_mm = \"a little\"", "drift_mm = 1e-4");
        let err = Job::from_toml_str(&text, "job").expect_err("another kind's key");
        assert_eq!(err.field, "effects[1].drift_mm", "{err}");
        assert!(err.message.contains("expected `recession_mm`"), "{err}");
    }

    /// An effects file's foreign key says what its kind expects, not where the table
    /// begins (the whole file's message reads "TOML parse error at line 1, column 1").
    #[test]
    fn an_effects_file_says_what_its_kind_expects() {
        let text = "[[effects]]\nkind = \"axial_drift\"\noffset_mm = 1e-3\n";
        let err =
            crate::model::EffectsFragment::from_toml_str(text).expect_err("another kind's key");
        assert_eq!(err.field, "effects[0].offset_mm", "{err}");
        assert_eq!(
            err.message, "unknown field `offset_mm`, expected `drift_mm`",
            "{err}"
        );
    }
}

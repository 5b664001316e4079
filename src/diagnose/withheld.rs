//! The withheld benchmark (`toolmark bench-diagnose`): a suite of synthetic measured
//! parts — turning, generating and milling, each effect alone and in pairs at several
//! magnitudes, and effect-free controls — diagnosed without their truth, then scored
//! against it.
//!
//! Three phases, each reading only what it may:
//! - `generate` writes, per case, a public folder (`cases/<id>/`: the job without its
//!   effects, the measured file, the instrument) and the truth apart (`sealed/<id>.json`);
//! - `diagnose_suite` reads the public folders only (it runs with `sealed/` moved away
//!   in the tests) and writes each diagnosis next to its case;
//! - `score` opens the truth and the diagnoses and prints the scores.

use super::candidates::Candidate;
use super::files::{Placement, load_measurement, merge_source};
use super::measurement::Instrument;
use super::report::write_outputs;
use super::{Options, diagnose};
use crate::engine::RemovalEngine;
use crate::io::atomic::write_bytes_atomically;
use crate::io::job::Job;
use crate::io::measured::{
    HeightMap, HeightProfile, LengthUnit, ReadInfo, ReadOptions, UnitSource, write_map,
    write_profile_csv,
};
use crate::synth::{MeasurementKind, MeasurementModel, Rng, Synthetic, synthesize};
use glam::DVec2;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What a case folder tells the diagnosis (no truth).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PublicCase {
    pub job: String,
    pub measured: String,
    pub placement: Placement,
    pub instrument: Instrument,
}

/// The sealed truth of one case.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Truth {
    pub case: String,
    pub process: String,
    /// single | pair | control
    pub kind: String,
    pub effects: Vec<TruthEffect>,
    /// The effects as the job file tables the synthesis used.
    pub effects_toml: String,
    pub measurement: MeasurementModel,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TruthEffect {
    pub effect: String,
    /// In the diagnosis's parameters and units (see `Candidate::parameters`).
    pub values: Vec<f64>,
    /// Edge waviness: the harmonic order.
    pub order: Option<f64>,
}

/// A base part: the public job and how it is measured.
pub struct Base {
    pub name: &'static str,
    pub process: &'static str,
    pub job: &'static str,
    pub measurement: &'static str,
    /// Measured file's extension.
    pub format: &'static str,
}

pub const TURNING_SPHERE: Base = Base {
    name: "turned convex sphere R8, Ø3 mm, 10 µm/rev, 0.5 mm nose",
    process: "turning",
    job: r#"version = 1
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
stock_allowance_mm = 0.003
[grid]
pitch_um = 0.5
azimuths = 8
"#,
    measurement: r#"kind = "profile"
spacing_um = 1.0
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
};

pub const GENERATED_SPHERE: Base = Base {
    name: "generated concave sphere R53.5 (seed 000's wheel), Ø4 mm",
    process: "generating",
    job: r#"version = 1
name = "generated sphere"
[surface]
kind = "sphere"
form = "concave"
radius_mm = 53.5
aperture_diameter_mm = 4.0
[tool]
kind = "cup_wheel"
cutting_radius_mm = 10.0
edge_radius_mm = 3.5
[process]
kind = "generating"
plunge_axis = "z"
tool_rpm = 3000.0
workpiece_rpm = 10.0
spark_out_revolutions = 2.0
stock_allowance_mm = 0.01
[grid]
pitch_um = 2.0
azimuths = 8
"#,
    measurement: r#"kind = "profile"
spacing_um = 2.0
white_noise_nm = 1.0
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
};

const BALL_MILLED_SPHERE: Base = Base {
    name: "ball-end raster (Ø1 mm, 20 µm step) over a convex sphere R3, Ø2 mm, profile across the passes",
    process: "milling",
    job: r#"version = 1
name = "milled sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 3.0
aperture_diameter_mm = 2.0
[tool]
kind = "ball_end"
diameter_mm = 1.0
teeth = 2
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.02
spindle_rpm = 20000.0
stock_allowance_mm = 0.005
[grid]
pitch_um = 1.0
azimuths = 8
"#,
    measurement: r#"kind = "profile"
azimuth_deg = 90.0
spacing_um = 1.0
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
};

const BALL_SPIRAL_FLAT: Base = Base {
    name: "ball-end spiral (Ø1 mm, 20 µm step) over a flat, Ø2 mm, profile through the centre",
    process: "milling",
    job: r#"version = 1
name = "spiral-milled flat"
[surface]
kind = "plane"
aperture_diameter_mm = 2.0
[tool]
kind = "ball_end"
diameter_mm = 1.0
teeth = 2
[process]
kind = "milling"
path = "spiral"
stepover_mm = 0.02
spindle_rpm = 20000.0
stock_allowance_mm = 0.005
[grid]
pitch_um = 1.0
azimuths = 8
"#,
    measurement: r#"kind = "profile"
azimuth_deg = 90.0
spacing_um = 1.0
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
};

pub const BALL_FEED_MARKS_FLAT: Base = Base {
    name: "two-flute ball-end (Ø2 mm, 20 µm per tooth) raster over a flat, Ø1 mm, profile along the feed",
    process: "milling",
    job: r#"version = 1
name = "feed marks on a flat"
[surface]
kind = "plane"
aperture_diameter_mm = 1.0
[tool]
kind = "ball_end"
diameter_mm = 2.0
teeth = 2
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.1
feed_per_tooth_mm = 0.02
spindle_rpm = 20000.0
stock_allowance_mm = 0.005
[grid]
pitch_um = 0.5
azimuths = 8
"#,
    measurement: r#"kind = "profile"
spacing_um = 0.5
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
};

const BALL_FEED_MARKS_SPHERE: Base = Base {
    name: "two-flute ball-end (Ø1 mm, 20 µm per tooth, 50 µm step) over a convex sphere R3, Ø1 mm, profile along the feed",
    process: "milling",
    job: r#"version = 1
name = "feed marks on a sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 3.0
aperture_diameter_mm = 1.0
[tool]
kind = "ball_end"
diameter_mm = 1.0
teeth = 2
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.05
feed_per_tooth_mm = 0.02
spindle_rpm = 20000.0
stock_allowance_mm = 0.005
[grid]
pitch_um = 0.5
azimuths = 8
"#,
    measurement: r#"kind = "profile"
spacing_um = 0.5
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
};

/// The turned sphere's centre as a white-light interferometer maps it: 81 × 81 pixels
/// of 1 µm, each the mean over its footprint.
pub const TURNING_CENTRE_MAP: Base = Base {
    name: "turned convex sphere R8 (as above), white-light map of the centre, 81 × 81 px of 1 µm",
    process: "turning",
    job: TURNING_SPHERE.job,
    measurement: r#"kind = "map"
pixels = [81, 81]
pixel_um = 1.0
pixel_averaging = true
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "x3p",
};

/// The turned sphere's whole aperture as a Fizeau interferometer maps it: 61 × 61
/// pixels of 50 µm (the tool marks average out; the form stays).
const TURNING_FORM_MAP: Base = Base {
    name: "turned convex sphere R8 (as above), interferometer map of the aperture, 61 × 61 px of 50 µm",
    process: "turning",
    job: TURNING_SPHERE.job,
    measurement: r#"kind = "map"
pixels = [61, 61]
pixel_um = 50.0
pixel_averaging = true
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "gsf",
};

/// A bull-nose raster over a flat, mapped across five passes: the map sees a spindle's
/// tram both ways (a profile across the passes sees only its component across them).
const BULL_NOSE_FLAT_MAP: Base = Base {
    name: "bull-nose (Ø3 mm, 0.5 mm corner, 0.1 mm step) raster over a flat, Ø2 mm, map of 21 × 21 px of 25 µm",
    process: "milling",
    job: r#"version = 1
name = "bull-nose raster over a flat"
[surface]
kind = "plane"
aperture_diameter_mm = 2.0
[tool]
kind = "bull_nose"
diameter_mm = 3.0
corner_radius_mm = 0.5
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.1
stock_allowance_mm = 0.01
[grid]
pitch_um = 2.0
azimuths = 8
"#,
    measurement: r#"kind = "map"
pixels = [21, 21]
pixel_um = 25.0
pixel_averaging = true
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "exr",
};

/// Every base, for the suite's README.
const BASES: [&Base; 9] = [
    &TURNING_SPHERE,
    &GENERATED_SPHERE,
    &BALL_MILLED_SPHERE,
    &BALL_SPIRAL_FLAT,
    &BALL_FEED_MARKS_FLAT,
    &BALL_FEED_MARKS_SPHERE,
    &TURNING_CENTRE_MAP,
    &TURNING_FORM_MAP,
    &BULL_NOSE_FLAT_MAP,
];

/// One case of the suite.
struct Spec {
    base: &'static Base,
    effects: Vec<(Candidate, Vec<f64>)>,
}

fn single(base: &'static Base, c: Candidate, values: &[f64]) -> Spec {
    Spec {
        base,
        effects: vec![(c, values.to_vec())],
    }
}

fn pair(base: &'static Base, a: (Candidate, &[f64]), b: (Candidate, &[f64])) -> Spec {
    Spec {
        base,
        effects: vec![(a.0, a.1.to_vec()), (b.0, b.1.to_vec())],
    }
}

fn control(base: &'static Base) -> Spec {
    Spec {
        base,
        effects: Vec::new(),
    }
}

/// The suite: every effect alone at several magnitudes, pairs, controls.
fn suite() -> Vec<Spec> {
    use Candidate::*;
    let t = &TURNING_SPHERE;
    let g = &GENERATED_SPHERE;
    let (ms, sp) = (&BALL_MILLED_SPHERE, &BALL_SPIRAL_FLAT);
    let (fm, fs) = (&BALL_FEED_MARKS_FLAT, &BALL_FEED_MARKS_SPHERE);
    let (cm, im, tm) = (&TURNING_CENTRE_MAP, &TURNING_FORM_MAP, &BULL_NOSE_FLAT_MAP);
    let wave = |order: f64| EdgeWaviness { order };
    vec![
        single(t, CentreHeight, &[3.0]),
        single(t, CentreHeight, &[-2.0]),
        single(t, CentreHeight, &[6.0]),
        single(t, XDecentre, &[4.0]),
        single(t, XDecentre, &[-3.0]),
        single(t, XDecentre, &[1.5]),
        single(t, NoseRadiusError, &[5.0]),
        single(t, NoseRadiusError, &[-8.0]),
        single(t, NoseRadiusError, &[15.0]),
        single(t, AxialDrift, &[200.0]),
        single(t, AxialDrift, &[-100.0]),
        single(t, AxialDrift, &[500.0]),
        single(t, wave(20.0), &[40.0, 0.0]),
        single(t, wave(45.0), &[12.0, -21.0]),
        pair(t, (CentreHeight, &[3.0]), (NoseRadiusError, &[5.0])),
        pair(t, (XDecentre, &[3.0]), (AxialDrift, &[200.0])),
        pair(t, (CentreHeight, &[-2.0]), (wave(30.0), &[30.0, 0.0])),
        pair(t, (NoseRadiusError, &[-6.0]), (AxialDrift, &[-150.0])),
        control(t),
        control(t),
        control(t),
        single(g, CutterDisplacement, &[20.0]),
        single(g, CutterDisplacement, &[-10.0]),
        single(g, CutterDisplacement, &[50.0]),
        single(g, InclinationError, &[0.01]),
        single(g, InclinationError, &[-0.02]),
        single(g, InclinationError, &[0.04]),
        pair(
            g,
            (CutterDisplacement, &[20.0]),
            (InclinationError, &[0.02]),
        ),
        pair(
            g,
            (CutterDisplacement, &[-30.0]),
            (InclinationError, &[-0.01]),
        ),
        control(g),
        control(g),
        single(ms, ToolRadiusError, &[4.0]),
        single(ms, ToolRadiusError, &[-2.0]),
        single(ms, ToolRadiusError, &[10.0]),
        single(ms, ToolRadiusError, &[-20.0]),
        control(ms),
        single(sp, AxialDrift, &[300.0]),
        single(sp, AxialDrift, &[-150.0]),
        single(sp, AxialDrift, &[80.0]),
        single(sp, AxialDrift, &[1000.0]),
        control(sp),
        // Runout as (along, across) the feed in µm: ε (cos φ, sin φ).
        single(fm, RadialRunout, &[2.0, 0.0]),
        single(fm, RadialRunout, &[1.732, 1.0]),
        single(fm, RadialRunout, &[-0.8, 0.6]),
        single(fm, RadialRunout, &[4.0, -3.0]),
        control(fm),
        pair(fs, (RadialRunout, &[1.732, 1.0]), (ToolRadiusError, &[4.0])),
        pair(fs, (RadialRunout, &[-1.5, 0.0]), (ToolRadiusError, &[-6.0])),
        // Maps: the centre, the form, a tram both ways.
        single(cm, CentreHeight, &[3.0]),
        single(cm, CentreHeight, &[-2.0]),
        single(cm, XDecentre, &[4.0]),
        control(cm),
        single(im, NoseRadiusError, &[8.0]),
        single(im, AxialDrift, &[300.0]),
        control(im),
        single(tm, SpindleTram, &[0.02, 0.05]),
        single(tm, SpindleTram, &[-0.05, 0.01]),
        control(tm),
    ]
}

/// Writes the suite into `dir` (cases/ and sealed/); returns the case ids.
pub fn generate(
    dir: &Path,
    engine: &mut dyn RemovalEngine,
    log: &dyn Fn(&str),
) -> Result<Vec<String>, String> {
    let cases = dir.join("cases");
    let sealed = dir.join("sealed");
    for d in [&cases, &sealed] {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    let mut ids = Vec::new();
    for (index, spec) in suite().into_iter().enumerate() {
        let kind = match spec.effects.len() {
            0 => "control",
            1 => "single",
            _ => "pair",
        };
        let names: Vec<&str> = spec.effects.iter().map(|(c, _)| c.kind()).collect();
        let id = format!(
            "{index:03}-{}-{}",
            spec.base.process,
            if names.is_empty() {
                "control".to_string()
            } else {
                names.join("+")
            }
        );
        log(&format!("generating {id}"));
        let tables: String = spec
            .effects
            .iter()
            .map(|(c, v)| c.effects_table(v))
            .collect::<Vec<_>>()
            .join("\n");
        let truth_job = Job::from_toml_str(&format!("{}\n{tables}", spec.base.job), "truth")
            .map_err(|e| format!("{id}: truth job: {e}"))?;
        let model = measurement_model(spec.base, index as u64)?;
        let data = synthesize(&truth_job, &model, engine).map_err(|e| format!("{id}: {e}"))?;
        let folder = cases.join(&id);
        std::fs::create_dir_all(&folder).map_err(|e| format!("{}: {e}", folder.display()))?;
        let measured = format!("measured.{}", spec.base.format);
        write_data(&folder.join(&measured), &data)?;
        let public = PublicCase {
            job: "job.toml".into(),
            measured,
            placement: Placement {
                azimuth_deg: Some(model.azimuth_deg),
                axis_at_mm: None,
            },
            instrument: model.instrument(),
        };
        let write = |path: PathBuf, text: String| {
            write_bytes_atomically(&path, text.as_bytes())
                .map_err(|e| format!("{}: {e}", path.display()))
        };
        write(folder.join("job.toml"), spec.base.job.to_string())?;
        write(
            folder.join("case.toml"),
            toml::to_string_pretty(&public).map_err(|e| e.to_string())?,
        )?;
        let truth = Truth {
            case: id.clone(),
            process: spec.base.process.into(),
            kind: kind.into(),
            effects: spec
                .effects
                .iter()
                .map(|(c, v)| TruthEffect {
                    effect: c.kind().into(),
                    values: v.clone(),
                    order: match c {
                        Candidate::EdgeWaviness { order } => Some(*order),
                        _ => None,
                    },
                })
                .collect(),
            effects_toml: tables,
            measurement: model,
        };
        write(
            sealed.join(format!("{id}.json")),
            serde_json::to_string_pretty(&truth).map_err(|e| e.to_string())?,
        )?;
        ids.push(id);
    }
    write_bytes_atomically(
        &dir.join("README.md"),
        format!(
            "# toolmark withheld diagnosis suite\n\n`cases/` holds what a diagnosis may see: per case the job without its effects, the measured file and the instrument. `sealed/` holds the truth; `toolmark bench-diagnose diagnose` never reads it, `toolmark bench-diagnose score` does.\n\nBases:\n{}",
            BASES.iter().map(|b| format!("- {} ({})\n", b.name, b.process)).collect::<String>()
        )
        .as_bytes(),
    )
    .map_err(|e| e.to_string())?;
    Ok(ids)
}

/// The base's instrument with a mount drawn for this case (tilt, piston, decentre) and
/// its own noise seed.
fn measurement_model(base: &Base, index: u64) -> Result<MeasurementModel, String> {
    let mut model: MeasurementModel =
        toml::from_str(base.measurement).map_err(|e| e.to_string())?;
    let mut rng = Rng::new(1000 + index);
    let spread = |rng: &mut Rng, half: f64| half * (2.0 * rng.uniform() - 1.0);
    model.tilt_urad = [spread(&mut rng, 60.0), spread(&mut rng, 60.0)];
    model.piston_um = spread(&mut rng, 5.0);
    model.decentre_um = [spread(&mut rng, 15.0), spread(&mut rng, 15.0)];
    model.seed = index;
    if model.kind == MeasurementKind::Profile {
        // A profile's mount tilts and slides it along its own line.
        let along = DVec2::from_angle(model.azimuth_deg.to_radians());
        let (tilt, slide) = (model.tilt_urad[0], model.decentre_um[0]);
        model.tilt_urad = (tilt * along).to_array();
        model.decentre_um = (slide * along).to_array();
    }
    Ok(model)
}

/// Writes synthetic data as a measured file (units in the file).
pub fn write_data(path: &Path, data: &Synthetic) -> Result<(), String> {
    let info = ReadInfo {
        format: "toolmark synth".into(),
        lateral_unit: LengthUnit::Millimetre,
        lateral_unit_source: UnitSource::FromFile,
        height_unit: LengthUnit::Millimetre,
        height_unit_source: UnitSource::FromFile,
        invalid_points: data.height_mm.iter().filter(|v| !v.is_finite()).count(),
        notes: Vec::new(),
    };
    match data.measurement.kind {
        MeasurementKind::Profile => {
            let profile = HeightProfile {
                x_mm: data.positions_mm.clone(),
                height_mm: data.height_mm.clone(),
                info,
            };
            write_profile_csv(
                path,
                &profile,
                &["synthetic profile from toolmark synth".to_string()],
            )
            .map_err(|e| format!("{}: {e}", path.display()))
        }
        MeasurementKind::Map => {
            let map = HeightMap {
                nx: data.pixels[0],
                ny: data.pixels[1],
                x0_mm: data.origin_mm.x,
                y0_mm: data.origin_mm.y,
                dx_mm: data.pixel_mm,
                dy_mm: data.pixel_mm,
                height_mm: data.height_mm.clone(),
                info,
            };
            write_map(path, &map).map_err(|e| e.to_string())
        }
    }
}

/// One case's diagnosis, as the suite's diagnose phase keeps it.
#[derive(Debug, Clone, Serialize)]
pub struct CaseRun {
    pub case: String,
    pub status: String,
    pub seconds: f64,
    pub simulations: usize,
}

/// Whether case `id` is among those `selected` (ids containing any of the given
/// strings; all when none is given).
pub fn selected(id: &str, selected: &[String]) -> bool {
    selected.is_empty() || selected.iter().any(|s| id.contains(s.as_str()))
}

/// Diagnoses the case folders under `dir/cases` whose ids are `selected` (never
/// opening `dir/sealed`).
pub fn diagnose_suite(
    dir: &Path,
    engine: &mut dyn RemovalEngine,
    cases_selected: &[String],
    log: &dyn Fn(&str),
) -> Result<Vec<CaseRun>, String> {
    let cases = dir.join("cases");
    let mut folders: Vec<PathBuf> = std::fs::read_dir(&cases)
        .map_err(|e| format!("{}: {e}", cases.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("case.toml").is_file())
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| selected(&n.to_string_lossy(), cases_selected))
        })
        .collect();
    folders.sort();
    let mut runs = Vec::new();
    for folder in folders {
        let id = folder
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned());
        let started = std::time::Instant::now();
        let text =
            std::fs::read_to_string(folder.join("case.toml")).map_err(|e| format!("{id}: {e}"))?;
        let case: PublicCase = toml::from_str(&text).map_err(|e| format!("{id}/case.toml: {e}"))?;
        let job = Job::load(&folder.join(&case.job)).map_err(|e| format!("{id}: {e}"))?;
        let (measurement, source) = load_measurement(
            &folder.join(&case.measured),
            &ReadOptions::default(),
            &case.placement,
            case.instrument,
        )?;
        let outcome = diagnose(&job, &measurement, engine, &Options::default(), &|_| {});
        let (status, simulations) = match outcome {
            Ok(mut outcome) => {
                merge_source(&mut outcome.diagnosis.measurement, &source);
                write_outputs(&folder.join("diagnosis"), &outcome)
                    .map_err(|e| format!("{id}: {e}"))?;
                (
                    outcome.diagnosis.verdict.status.clone(),
                    outcome.diagnosis.run.simulations,
                )
            }
            Err(err) => (format!("error: {err}"), 0),
        };
        let seconds = started.elapsed().as_secs_f64();
        log(&format!(
            "{id}: {status} ({seconds:.1} s, {simulations} simulations)"
        ));
        runs.push(CaseRun {
            case: id,
            status,
            seconds,
            simulations,
        });
    }
    Ok(runs)
}

/// How one case scored.
#[derive(Debug, Clone, Serialize)]
pub struct CaseScore {
    pub case: String,
    pub process: String,
    pub kind: String,
    pub truth: Vec<String>,
    /// The diagnosis's first-ranked candidate and what it accepted.
    pub ranked_first: Option<String>,
    pub accepted: Vec<String>,
    /// Single: the first-ranked is the truth. Pair: both truths accepted. Control: nothing accepted.
    pub right: bool,
    /// Per truth effect: relative parameter error and whether it is within 10 % (or
    /// within twice the fit's stated uncertainty).
    pub parameter_errors: Vec<f64>,
    pub parameters_within_10_percent: bool,
    pub parameters_within_bound: bool,
    pub rms_before_nm: f64,
    pub rms_after_nm: f64,
    pub rms_reduction: f64,
    pub seconds: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Scores {
    pub cases: Vec<CaseScore>,
    pub singles: usize,
    pub singles_ranked_first: usize,
    pub singles_parameter_within_10_percent: usize,
    pub singles_parameter_within_bound: usize,
    pub effect_cases: usize,
    pub effect_cases_rms_reduced_80_percent: usize,
    pub pairs: usize,
    pub pairs_both_found: usize,
    pub controls: usize,
    pub controls_false_claims: usize,
}

/// Opens the truth and the diagnoses and scores the `selected` cases.
pub fn score(dir: &Path, cases_selected: &[String]) -> Result<Scores, String> {
    let sealed = dir.join("sealed");
    let mut truths: Vec<Truth> = std::fs::read_dir(&sealed)
        .map_err(|e| format!("{}: {e}", sealed.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .map(|p| {
            let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
            serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))
        })
        .collect::<Result<_, String>>()?;
    truths.retain(|t| selected(&t.case, cases_selected));
    truths.sort_by(|a, b| a.case.cmp(&b.case));
    let mut cases = Vec::new();
    for truth in &truths {
        let path = dir
            .join("cases")
            .join(&truth.case)
            .join("diagnosis")
            .join("diagnosis.json");
        let diagnosis: serde_json::Value = std::fs::read_to_string(&path)
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or(serde_json::Value::Null);
        cases.push(score_case(truth, &diagnosis));
    }
    let singles: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "single").collect();
    let effect_cases: Vec<&CaseScore> = cases.iter().filter(|c| c.kind != "control").collect();
    let pairs: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "pair").collect();
    let controls: Vec<&CaseScore> = cases.iter().filter(|c| c.kind == "control").collect();
    Ok(Scores {
        singles: singles.len(),
        singles_ranked_first: singles.iter().filter(|c| c.right).count(),
        singles_parameter_within_10_percent: singles
            .iter()
            .filter(|c| c.parameters_within_10_percent)
            .count(),
        singles_parameter_within_bound: singles
            .iter()
            .filter(|c| c.parameters_within_bound)
            .count(),
        effect_cases: effect_cases.len(),
        effect_cases_rms_reduced_80_percent: effect_cases
            .iter()
            .filter(|c| c.rms_reduction >= 0.8)
            .count(),
        pairs: pairs.len(),
        pairs_both_found: pairs.iter().filter(|c| c.right).count(),
        controls: controls.len(),
        controls_false_claims: controls.iter().filter(|c| !c.right).count(),
        cases,
    })
}

fn score_case(truth: &Truth, d: &serde_json::Value) -> CaseScore {
    let names = |list: &serde_json::Value| -> Vec<String> {
        list.as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|c| c["effect"].as_str().map(String::from))
                    .collect()
            })
            .unwrap_or_default()
    };
    let ranked_first = names(&d["candidates"]).into_iter().next();
    let accepted = names(&d["accepted"]);
    let truth_names: Vec<String> = truth.effects.iter().map(|e| e.effect.clone()).collect();
    let right = match truth.kind.as_str() {
        "control" => accepted.is_empty(),
        "single" => ranked_first.as_deref() == Some(truth_names[0].as_str()),
        _ => truth_names.iter().all(|t| accepted.contains(t)),
    };
    // The fitted values: from the accepted set when there, else the candidate alone.
    let fitted = |effect: &str| -> Option<(Vec<f64>, Vec<f64>, Option<f64>)> {
        let find = |list: &serde_json::Value| {
            list.as_array()?
                .iter()
                .find(|c| c["effect"].as_str() == Some(effect))
                .cloned()
        };
        let row = find(&d["accepted"]).or_else(|| find(&d["candidates"]))?;
        let params = row["parameters"].as_array()?;
        let values = params.iter().filter_map(|p| p["value"].as_f64()).collect();
        let sigmas = params
            .iter()
            .map(|p| p["sigma"].as_f64().unwrap_or(f64::INFINITY))
            .collect();
        Some((values, sigmas, row["order"].as_f64()))
    };
    let mut errors = Vec::new();
    let (mut within, mut bound) = (true, true);
    for t in &truth.effects {
        match fitted(&t.effect) {
            Some((values, sigmas, order)) => {
                let (error, sigma_ratio) = parameter_error(t, &values, &sigmas, order);
                errors.push(error);
                within &= error <= 0.1;
                bound &= error <= 0.1 || sigma_ratio <= 2.0;
            }
            None => {
                errors.push(f64::INFINITY);
                within = false;
                bound = false;
            }
        }
    }
    let before = d["residual_before"]["rms_nm"].as_f64().unwrap_or(f64::NAN);
    let after = d["residual_after"]["rms_nm"].as_f64().unwrap_or(f64::NAN);
    CaseScore {
        case: truth.case.clone(),
        process: truth.process.clone(),
        kind: truth.kind.clone(),
        truth: truth_names,
        ranked_first,
        accepted,
        right,
        parameter_errors: errors,
        parameters_within_10_percent: within && truth.kind != "control",
        parameters_within_bound: bound && truth.kind != "control",
        rms_before_nm: before,
        rms_after_nm: after,
        rms_reduction: 1.0 - after / before,
        seconds: d["run"]["total_s"].as_f64().unwrap_or(f64::NAN),
    }
}

/// Relative error of a fitted effect against the truth (vector norm; waviness: the
/// amplitude, and the order must match within 5 %), and |error| in fitted sigmas.
fn parameter_error(
    t: &TruthEffect,
    values: &[f64],
    sigmas: &[f64],
    order: Option<f64>,
) -> (f64, f64) {
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if let (Some(truth_order), Some(fit_order)) = (t.order, order) {
        if (fit_order / truth_order - 1.0).abs() > 0.05 {
            return (f64::INFINITY, f64::INFINITY);
        }
        let (a_true, a_fit) = (norm(&t.values), norm(values));
        let sigma = norm(sigmas) / 2f64.sqrt();
        return (
            (a_fit - a_true).abs() / a_true,
            (a_fit - a_true).abs() / sigma,
        );
    }
    // Scored on the components the fit saw (σ finite): the others it reports as not seen.
    let seen: Vec<usize> = (0..values.len())
        .filter(|&j| sigmas[j].is_finite())
        .collect();
    let pick = |v: &[f64]| seen.iter().map(|&j| v[j]).collect::<Vec<f64>>();
    let (values, truth, sigmas) = (pick(values), pick(&t.values), pick(sigmas));
    if seen.is_empty() {
        return (f64::INFINITY, f64::INFINITY);
    }
    let mut difference: Vec<f64> = values.iter().zip(&truth).map(|(a, b)| a - b).collect();
    if t.effect == "radial_runout" {
        // Which tooth runs out is a shift of the marks by one feed per tooth, which the
        // registration of a slid profile absorbs: ε and −ε are the same measurement.
        let flipped: Vec<f64> = values.iter().zip(&truth).map(|(a, b)| a + b).collect();
        if norm(&flipped) < norm(&difference) {
            difference = flipped;
        }
    }
    let sigma = norm(&sigmas).max(1e-300);
    (
        norm(&difference) / norm(&truth).max(1e-300),
        norm(&difference) / sigma,
    )
}

/// The scores as a Markdown report: totals against the targets, then a table per effect.
pub fn scores_markdown(s: &Scores) -> String {
    let pct = |a: usize, b: usize| {
        if b == 0 {
            0.0
        } else {
            100.0 * a as f64 / b as f64
        }
    };
    let mut out = String::new();
    out += "| score | result | target |\n|---|---|---|\n";
    out += &format!(
        "| right effect ranked first (single-effect cases) | {}/{} = {:.1} % | ≥ 90 % |\n",
        s.singles_ranked_first,
        s.singles,
        pct(s.singles_ranked_first, s.singles)
    );
    out += &format!(
        "| fitted parameter within 10 % (single) | {}/{} = {:.1} % | |\n",
        s.singles_parameter_within_10_percent,
        s.singles,
        pct(s.singles_parameter_within_10_percent, s.singles)
    );
    out += &format!(
        "| … within 10 % or 2σ of the fit's noise bound | {}/{} = {:.1} % | ≥ 90 % |\n",
        s.singles_parameter_within_bound,
        s.singles,
        pct(s.singles_parameter_within_bound, s.singles)
    );
    out += &format!(
        "| residual RMS reduced ≥ 80 % (cases with an effect) | {}/{} = {:.1} % | |\n",
        s.effect_cases_rms_reduced_80_percent,
        s.effect_cases,
        pct(s.effect_cases_rms_reduced_80_percent, s.effect_cases)
    );
    out += &format!(
        "| both effects found (pairs) | {}/{} | |\n",
        s.pairs_both_found, s.pairs
    );
    out += &format!(
        "| false effect claimed (controls) | {}/{} | ≤ 1 |\n\n",
        s.controls_false_claims, s.controls
    );
    out += "| effect | cases | ranked first | parameter within 10 % | median parameter error | median RMS reduction |\n|---|---|---|---|---|---|\n";
    let mut effects: Vec<String> = s
        .cases
        .iter()
        .filter(|c| c.kind == "single")
        .map(|c| c.truth[0].clone())
        .collect();
    effects.sort();
    effects.dedup();
    for e in effects {
        let rows: Vec<&CaseScore> = s
            .cases
            .iter()
            .filter(|c| c.kind == "single" && c.truth[0] == e)
            .collect();
        let mut errors: Vec<f64> = rows.iter().map(|c| c.parameter_errors[0]).collect();
        let mut reductions: Vec<f64> = rows.iter().map(|c| c.rms_reduction).collect();
        errors.sort_by(f64::total_cmp);
        reductions.sort_by(f64::total_cmp);
        out += &format!(
            "| {e} | {} | {} | {} | {:.1} % | {:.1} % |\n",
            rows.len(),
            rows.iter().filter(|c| c.right).count(),
            rows.iter()
                .filter(|c| c.parameters_within_10_percent)
                .count(),
            100.0 * errors[errors.len() / 2],
            100.0 * reductions[reductions.len() / 2]
        );
    }
    out += "\n| case | truth | ranked first | accepted | parameter error | RMS before → after (nm) | s |\n|---|---|---|---|---|---|---|\n";
    for c in &s.cases {
        let errors: Vec<String> = c
            .parameter_errors
            .iter()
            .map(|e| format!("{:.1} %", 100.0 * e))
            .collect();
        out += &format!(
            "| {} | {} | {} | {} | {} | {:.1} → {:.1} | {:.1} |\n",
            c.case,
            if c.truth.is_empty() {
                "—".into()
            } else {
                c.truth.join(" + ")
            },
            c.ranked_first.as_deref().unwrap_or("—"),
            if c.accepted.is_empty() {
                "—".into()
            } else {
                c.accepted.join(" + ")
            },
            errors.join(", "),
            c.rms_before_nm,
            c.rms_after_nm,
            c.seconds
        );
    }
    out
}

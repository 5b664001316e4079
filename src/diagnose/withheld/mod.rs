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
use crate::diagnose::synth::{MeasurementKind, MeasurementModel, Rng, Synthetic, synthesize};
use crate::engine::RemovalEngine;
use crate::formats::atomic::write_bytes_atomically;
use crate::formats::measured::{
    HeightMap, HeightProfile, LengthUnit, ReadInfo, ReadOptions, UnitSource, write_map,
    write_profile_csv,
};
use crate::model::Job;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

mod bases;
mod score;
use bases::*;
pub use bases::{
    BALL_FEED_MARKS_FLAT, Base, FINE_FEED_SPHERE, GENERATED_SPHERE, SPIRAL_VARYING_FEED,
    TURNING_CENTRE_MAP, TURNING_SPHERE, WHITE_LIGHT_SPHERE,
};
pub use score::{CaseScore, Scores, score, scores_markdown};

/// What a case folder tells the diagnosis (no truth).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PublicCase {
    pub job: String,
    pub measured: String,
    pub placement: Placement,
    pub instrument: Instrument,
    /// Diagnose with power removed (`--remove-power`).
    #[serde(default)]
    pub remove_power: bool,
}

/// The sealed truth of one case.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Truth {
    pub case: String,
    pub process: String,
    /// single | pair | control | unmodelled (an effect no candidate models: the
    /// diagnosis must call the gap unexplained, not fit a proxy)
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

/// One case of the suite: the base, the effects put into the job, and what the
/// measurement adds to the base's (TOML: `lateral_scale`, `[[unmodelled]]`).
struct Spec {
    base: &'static Base,
    effects: Vec<(Candidate, Vec<f64>)>,
    measurement: String,
}

/// The cases as `suite.toml` lists them.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SuiteFile {
    case: Vec<CaseEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseEntry {
    base: String,
    #[serde(default)]
    effects: Vec<EffectEntry>,
    #[serde(default)]
    measurement: String,
}

/// An effect put into a case's job: a candidate's kind, its values (the diagnosis's
/// parameters and units), and the order, cycles or direction that name some kinds.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EffectEntry {
    kind: String,
    values: Vec<f64>,
    order: Option<f64>,
    cycles: Option<f64>,
    direction: Option<String>,
}

impl EffectEntry {
    /// The candidate of this kind (`Candidate::kind` names them), with the order,
    /// cycles or direction the kind needs.
    fn candidate(&self) -> Result<Candidate, String> {
        use Candidate::*;
        let needs = |what: Option<f64>, name: &str| {
            what.ok_or_else(|| format!("effect {:?} needs `{name}`", self.kind))
        };
        let plain = [
            CentreHeight,
            XDecentre,
            NoseRadiusError,
            AxialDrift,
            CutterDisplacement,
            InclinationError,
            ToolRadiusError,
            SpindleTram,
            RadialRunout,
            ToolWear,
            SpringBack,
        ];
        if let Some(candidate) = plain.into_iter().find(|c| c.kind() == self.kind) {
            return Ok(candidate);
        }
        Ok(match self.kind.as_str() {
            "edge_waviness" => EdgeWaviness {
                order: needs(self.order, "order")?,
            },
            "tilt_error_motion" => TiltErrorMotion {
                order: needs(self.order, "order")?,
            },
            "vibration" => Vibration {
                cycles: needs(self.cycles, "cycles")?,
                depth: match self.direction.as_deref() {
                    Some("depth") => true,
                    Some("feed") => false,
                    _ => return Err("a vibration needs direction = \"depth\" or \"feed\"".into()),
                },
            },
            other => return Err(format!("no effect {other:?} in the suite's candidates")),
        })
    }
}

impl Spec {
    fn kind(&self) -> &'static str {
        match self.effects.len() {
            _ if self.measurement.contains("[[unmodelled]]") => "unmodelled",
            0 => "control",
            1 => "single",
            _ => "pair",
        }
    }

    fn label(&self) -> String {
        let mut names: Vec<&str> = self.effects.iter().map(|(c, _)| c.kind()).collect();
        if let Some(kind) = self.measurement.split("kind = \"").nth(1) {
            names.push(kind.split('"').next().unwrap_or("unmodelled"));
        } else if self.measurement.contains("lateral_scale") {
            names.push("lateral_scale");
        }
        if names.is_empty() {
            "control".into()
        } else {
            names.join("+")
        }
    }
}

/// The suite (`suite.toml`): every effect alone at several magnitudes, pairs,
/// controls; instrument errors; effects no candidate models.
fn suite() -> Result<Vec<Spec>, String> {
    let file: SuiteFile =
        toml::from_str(include_str!("suite.toml")).map_err(|e| format!("suite.toml: {e}"))?;
    file.case
        .into_iter()
        .enumerate()
        .map(|(index, case)| {
            let in_case = |err: String| format!("suite.toml, case {index}: {err}");
            let base = BASES
                .iter()
                .find(|(name, _)| *name == case.base)
                .ok_or_else(|| in_case(format!("no base {:?}", case.base)))?
                .1;
            let effects = case
                .effects
                .iter()
                .map(|e| Ok((e.candidate().map_err(in_case)?, e.values.clone())))
                .collect::<Result<_, String>>()?;
            Ok(Spec {
                base,
                effects,
                measurement: case.measurement,
            })
        })
        .collect()
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
    for (index, spec) in suite()?.into_iter().enumerate() {
        let id = format!("{index:03}-{}-{}", spec.base.process, spec.label());
        log(&format!("generating {id}"));
        let truth = write_case(&spec, index as u64, &id, &cases.join(&id), engine)?;
        write_text(
            &sealed.join(format!("{id}.json")),
            serde_json::to_string_pretty(&truth).map_err(|e| e.to_string())?,
        )?;
        ids.push(id);
    }
    write_text(
        &dir.join("README.md"),
        format!(
            "# toolmark withheld diagnosis suite\n\n`cases/` holds what a diagnosis may see: per case the job without its effects, the files it reads, the measured file and the instrument. `sealed/` holds the truth; `toolmark bench-diagnose diagnose` never reads it, `toolmark bench-diagnose score` does.\n\nBases:\n{}",
            BASES
                .iter()
                .map(|(_, b)| format!("- {} ({})\n", b.name, b.process))
                .collect::<String>()
        ),
    )?;
    Ok(ids)
}

fn write_text(path: &Path, text: String) -> Result<(), String> {
    write_bytes_atomically(path, text.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))
}

/// Synthesises one case into its public `folder`; returns its truth.
fn write_case(
    spec: &Spec,
    index: u64,
    id: &str,
    folder: &Path,
    engine: &mut dyn RemovalEngine,
) -> Result<Truth, String> {
    std::fs::create_dir_all(folder).map_err(|e| format!("{}: {e}", folder.display()))?;
    for (name, text) in (spec.base.files)() {
        write_text(&folder.join(name), text)?;
    }
    write_text(&folder.join("job.toml"), spec.base.job.to_string())?;
    let tables: String = spec
        .effects
        .iter()
        .map(|(c, v)| c.effects_table(v))
        .collect::<Vec<_>>()
        .join("\n");
    let truth_job = Job::from_toml_in(&format!("{}\n{tables}", spec.base.job), "truth", folder)
        .map_err(|e| format!("{id}: truth job: {e}"))?;
    let model = measurement_model(spec, index)?;
    let data = synthesize(&truth_job, &model, engine).map_err(|e| format!("{id}: {e}"))?;
    let measured = format!("measured.{}", spec.base.format);
    write_data(&folder.join(&measured), &data)?;
    let public = PublicCase {
        job: "job.toml".into(),
        measured,
        placement: Placement {
            azimuth_deg: spec.base.azimuth_stated.then_some(model.azimuth_deg),
            axis_at_mm: None,
        },
        instrument: model.instrument(),
        remove_power: spec.base.remove_power,
    };
    write_text(
        &folder.join("case.toml"),
        toml::to_string_pretty(&public).map_err(|e| e.to_string())?,
    )?;
    Ok(Truth {
        case: id.into(),
        process: spec.base.process.into(),
        kind: spec.kind().into(),
        effects: spec
            .effects
            .iter()
            .map(|(c, v)| TruthEffect {
                effect: c.kind().into(),
                values: v.clone(),
                order: c.order(),
            })
            .collect(),
        effects_toml: tables,
        measurement: model,
    })
}

/// The case's instrument (the base's, with what the case adds) with a mount drawn for
/// this case (tilt, piston, where the axis sits) and its own noise seed.
fn measurement_model(spec: &Spec, index: u64) -> Result<MeasurementModel, String> {
    let text = format!("{}{}", spec.base.measurement, spec.measurement);
    let mut model: MeasurementModel = toml::from_str(&text).map_err(|e| e.to_string())?;
    let mut rng = Rng::new(1000 + index);
    let spread = |rng: &mut Rng, half: f64| half * (2.0 * rng.uniform() - 1.0);
    model.tilt_urad = [spread(&mut rng, 60.0), spread(&mut rng, 60.0)];
    model.piston_um = spread(&mut rng, 5.0);
    model.decentre_um = [spread(&mut rng, 15.0), spread(&mut rng, 15.0)];
    model.seed = index;
    if model.kind == MeasurementKind::Profile {
        // A profile's mount tilts it and slides it along its own line.
        let [lo, hi] = spec.base.axis_along_um;
        model.tilt_urad[1] = 0.0;
        model.decentre_um = [lo + (hi - lo) * rng.uniform(), 0.0];
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
        let mut options = Options::default();
        options.terms.power = case.remove_power;
        let outcome = diagnose(&job, &measurement, engine, &options, &|_| {});
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

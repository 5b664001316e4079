//! Correcting a lens generator's setup from the part it made (seed 000): the central
//! pip says how far the cutting circle misses the axis, the best-fit sphere radius says
//! what inclination the wheel really has, and together they give the X move and the
//! inclination change that remove the pip and restore the radius.
//!
//! The geometry (`geometry::cup_wheel`) makes the part depend on the miss |e| and on
//! k = (R_t + e cos α)/sin α only: the sphere's radius is √(e² + k²) ± r and the pip's
//! height r − √(r² − e²) ± (√(e² + k²) − k). So:
//! 1. from the fitted radius R: the arc radius ρ = R ∓ r;
//! 2. from the pip height h: |e|, solving that height equation (monotone in |e|);
//! 3. k = √(ρ² − e²), and for each side σ = ±1 (short of the axis or past it) the
//!    inclination α_σ = atan2(σ|e|, k) + asin(R_t / ρ) that explains the part.
//!
//! The form cannot tell the side: both hypotheses reproduce the part exactly. A
//! correction therefore moves the wheel by |e| toward the axis (the usual fault,
//! stopping short), cuts again, and if the pip has not gone, it was past the axis:
//! the second hypothesis's settings, taken from the first cut, finish it.

use crate::analysis::sphere_fit::SphereFit;
use crate::analysis::{Protrusion, ProtrusionShape};
use crate::engine::{EngineError, RemovalEngine};
use crate::field::{DexelField, PolarGrid};
use crate::geometry::cup_wheel::inclination_for;
use crate::model::Job;
use crate::pipeline::{RunResult, simulate};
use crate::process::{GeneratingSetup, Process};
use std::path::Path;

/// Which side of the axis the cutting circle passes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MissSide {
    /// The circle stops short of the axis (its centre side).
    Short,
    /// The circle passes beyond the axis.
    Past,
}

impl MissSide {
    fn sign(self) -> f64 {
        match self {
            MissSide::Short => 1.0,
            MissSide::Past => -1.0,
        }
    }
}

/// One explanation of the part and the setting changes it implies.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SetupHypothesis {
    pub side: MissSide,
    /// The circle's displacement from the axis (mm, + = short).
    pub displacement_mm: f64,
    /// The inclination the wheel really has under this hypothesis (deg).
    pub inclination_deg: f64,
    /// Move the wheel's X setting by this much (mm, + = away from the axis).
    pub move_mm: f64,
    /// Change the inclination setting by this much (deg).
    pub tilt_deg: f64,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SetupEstimate {
    /// How far the circle misses the axis (mm).
    pub miss_mm: f64,
    pub pip_height_nm: f64,
    pub pip_radius_um: f64,
    pub sphere: SphereFit,
    pub target_radius_mm: f64,
    /// Short first, then past.
    pub hypotheses: [SetupHypothesis; 2],
    /// Things worth knowing about the estimate.
    pub notes: Vec<String>,
}

/// Estimates the miss and the inclination from a part's central feature and sphere.
pub fn estimate_setup(
    setup: &GeneratingSetup,
    target_radius_mm: f64,
    protrusion: &Protrusion,
    sphere: SphereFit,
) -> Result<SetupEstimate, String> {
    let r = setup.wheel.edge_radius_mm;
    let s = setup.form_sign();
    let arc_radius = sphere.radius_mm - s * r;
    if arc_radius <= setup.wheel.cutting_radius_mm {
        return Err(format!(
            "the fitted sphere (R = {:.6} mm) is too small for this wheel: no inclination of a {} mm cutting circle generates it",
            sphere.radius_mm, setup.wheel.cutting_radius_mm
        ));
    }
    let mut notes = Vec::new();
    let height_mm = protrusion.height_nm * 1e-6;
    let miss_mm = match protrusion.shape {
        ProtrusionShape::None => 0.0,
        ProtrusionShape::Dimple | ProtrusionShape::Cylinder => {
            return Err(format!(
                "the central feature is a {:?}, which a cup wheel's miss does not leave (a pip, h = r − √(r² − e²) ± …); correct its cause first",
                protrusion.shape
            ));
        }
        shape => {
            if shape != ProtrusionShape::Pip {
                notes.push(format!(
                    "the central feature reads as a {shape:?} rather than a pip (tool marks or noise on its flanks); its height is used"
                ));
            }
            miss_from_pip_height(height_mm, r, s, arc_radius)
        }
    };
    let radius_from_pip = miss_mm * (1.0 + s * r / arc_radius) * 1e3;
    if protrusion.shape != ProtrusionShape::None
        && (protrusion.radius_um - radius_from_pip).abs() > 0.1 * radius_from_pip + 2.0
    {
        notes.push(format!(
            "the pip's radius ({:.2} µm) disagrees with the {radius_from_pip:.2} µm its height implies: the feature may not be a generator's pip alone",
            protrusion.radius_um
        ));
    }
    let k = (arc_radius * arc_radius - miss_mm * miss_mm).sqrt();
    let target_inclination = inclination_for(
        &setup.wheel,
        target_radius_mm,
        setup.form == crate::geometry::Form::Concave,
    );
    let hypothesis = |side: MissSide| {
        let displacement_mm = side.sign() * miss_mm;
        let inclination =
            displacement_mm.atan2(k) + (setup.wheel.cutting_radius_mm / arc_radius).asin();
        SetupHypothesis {
            side,
            displacement_mm,
            inclination_deg: inclination.to_degrees(),
            move_mm: -displacement_mm,
            tilt_deg: (target_inclination - inclination).to_degrees(),
        }
    };
    Ok(SetupEstimate {
        miss_mm,
        pip_height_nm: protrusion.height_nm,
        pip_radius_um: protrusion.radius_um,
        sphere,
        target_radius_mm,
        hypotheses: [hypothesis(MissSide::Short), hypothesis(MissSide::Past)],
        notes,
    })
}

/// |e| from the pip's height h = r − √(r² − e²) + s(√(e² + ρ²) − ρ)·… (with k² = ρ² − e²:
/// h = [r − √(r² − e²)] + s[ρ − √(ρ² − e²)]), increasing in |e| on [0, r): bisection.
fn miss_from_pip_height(height_mm: f64, r: f64, s: f64, arc_radius: f64) -> f64 {
    let height = |e: f64| {
        let e2 = e * e;
        e2 / (r + (r * r - e2).sqrt())
            + s * e2 / (arc_radius + (arc_radius * arc_radius - e2).sqrt())
    };
    let (mut lo, mut hi) = (0.0, r);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if height(mid) < height_mm {
            lo = mid
        } else {
            hi = mid
        }
    }
    0.5 * (lo + hi)
}

/// One cut of the correction sequence.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CutReport {
    pub cut: usize,
    /// What was changed before this cut.
    pub settings: String,
    pub inclination_setting_deg: f64,
    pub cutter_offset_mm: f64,
    /// PV of the deviation within the central zone (nm).
    pub central_pv_nm: f64,
    pub central_zone_radius_mm: f64,
    pub pip_height_nm: f64,
    pub pip_radius_um: f64,
    pub radius_error_um: f64,
    pub deviation_pv_nm: f64,
}

pub struct CorrectionRun {
    pub cuts: Vec<CutReport>,
    pub first_estimate: SetupEstimate,
    /// The job with the settings of the last cut (the machine's errors unchanged).
    pub corrected: Job,
    pub first: RunResult,
    pub last: RunResult,
}

/// PV of a field's deviation over the rings within `zone_radius_mm` of the axis.
pub fn central_pv_nm(grid: &PolarGrid, field: &DexelField, zone_radius_mm: f64) -> f64 {
    let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
    for (i, ring) in grid.rings.iter().enumerate() {
        if ring.radius_mm > zone_radius_mm {
            break;
        }
        for j in 0..grid.azimuths {
            let value = field.depth_mm[grid.sample_index(i, j)];
            low = low.min(value);
            high = high.max(value);
        }
    }
    (high - low).max(0.0) * 1e6
}

/// The job with the generator set to `inclination_rad` and `offset_mm`: derived from
/// the job as resolved and checked again (nothing edits a checked job), so a setting
/// out of the machine's range is refused by name.
fn with_settings(job: &Job, inclination_rad: f64, offset_mm: f64) -> Result<Job, EngineError> {
    let name = format!("{} (corrected)", job.name);
    let mut file = job.resolved.clone();
    file.name = Some(name.clone());
    file.with_generator_setting(inclination_rad.to_degrees(), offset_mm)
        .and_then(|file| Job::from_file(file, &name, Path::new(".")))
        .map_err(|e| EngineError(format!("the corrected set-up is not a valid job: {e}")))
}

/// Machines the job as set (its effects play the machine's unknown errors), estimates
/// the setup from the part, and corrects: first assuming the circle stopped short,
/// then, if the pip did not go, that it passed the axis. `zone_radius_mm` is the
/// central zone whose PV is reported.
pub fn correction_loop(
    job: &Job,
    engine: &mut dyn RemovalEngine,
    zone_radius_mm: f64,
) -> Result<CorrectionRun, EngineError> {
    let Some(generating) = job.process.generating() else {
        return Err(EngineError(
            "correction adjusts a generator's setup; this job is not a generating job".into(),
        ));
    };
    let setup = generating.setup.clone();
    let target = 1.0 / job.surface.curvature_per_mm;
    let report = |cut: usize, settings: String, result: &RunResult| {
        let (inclination, offset) = match &result.job.process {
            Process::Generating(g) => (g.setup.inclination_rad, g.setup.cutter_offset_mm),
            _ => (0.0, 0.0),
        };
        let sphere = result.part_sphere;
        CutReport {
            cut,
            settings,
            inclination_setting_deg: inclination.to_degrees(),
            cutter_offset_mm: offset,
            central_pv_nm: central_pv_nm(result.grid(), &result.field, zone_radius_mm),
            central_zone_radius_mm: zone_radius_mm,
            pip_height_nm: result.protrusion.height_nm,
            pip_radius_um: result.protrusion.radius_um,
            radius_error_um: sphere.map_or(f64::NAN, |s| (s.radius_mm - target) * 1e3),
            deviation_pv_nm: result.deviation.pv_nm,
        }
    };
    let first = simulate(job.clone(), engine, &|_, _| {})?;
    let mut cuts = vec![report(0, "as set".into(), &first)];
    let sphere = first
        .part_sphere
        .ok_or_else(|| EngineError("too few rings to fit the part's sphere".into()))?;
    let estimate =
        estimate_setup(&setup, target, &first.protrusion, sphere).map_err(EngineError)?;

    let mut last = None;
    let mut corrected = job.clone();
    for (index, hypothesis) in estimate.hypotheses.iter().enumerate() {
        let candidate = with_settings(
            job,
            setup.inclination_rad + hypothesis.tilt_deg.to_radians(),
            setup.cutter_offset_mm + hypothesis.move_mm,
        )?;
        let result = simulate(candidate.clone(), engine, &|_, _| {})?;
        cuts.push(report(
            index + 1,
            format!(
                "assume the circle {} the axis: move X by {:+.4} µm, tilt by {:+.6}°",
                if hypothesis.side == MissSide::Short {
                    "stops short of"
                } else {
                    "passes"
                },
                hypothesis.move_mm * 1e3,
                hypothesis.tilt_deg
            ),
            &result,
        ));
        corrected = candidate;
        // The pip gone (no feature, or one much smaller than before): this side was right.
        let pip_gone = result.protrusion.shape == ProtrusionShape::None
            || result.protrusion.height_nm < 0.25 * first.protrusion.height_nm;
        last = Some(result);
        if pip_gone || estimate.miss_mm == 0.0 {
            break;
        }
    }
    Ok(CorrectionRun {
        cuts,
        first_estimate: estimate,
        corrected,
        first,
        last: last.expect("at least one hypothesis is tried"),
    })
}

//! The machining–measurement–compensation loop (seed 002 §3.4, Fig. 9) in simulation:
//! machine the part (with whatever errors the job carries, which the loop is not told),
//! measure its form error, move the next path along the normal by that error, repeat.
//! The measurement is the form error profile of `analysis::form` (scallops filtered out
//! with a Gaussian cutoff, piston removed), the paper's "high-frequency filtering".

use crate::analysis::{FormProfile, form_error};
use crate::engine::{EngineError, RemovalEngine};
use crate::model::Job;
use crate::pipeline::{RunResult, simulate};
use crate::process::{NormalCorrection, Process};

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CycleReport {
    /// 0 = as programmed; k = after k compensations.
    pub cycle: usize,
    pub form_pv_nm: f64,
    pub form_rms_nm: f64,
    /// The unfiltered deviation, scallops included.
    pub deviation_pv_nm: f64,
    pub deviation_rms_nm: f64,
    /// Largest normal offset the path carried in this cycle.
    pub correction_max_nm: f64,
}

pub struct CompensationRun {
    pub cycles: Vec<CycleReport>,
    /// Each cycle's form error (for plots).
    pub forms: Vec<FormProfile>,
    /// The correction the next part would be machined with.
    pub next_correction: NormalCorrection,
    pub last: RunResult,
}

/// Machines one part with `correction` and measures it.
fn machine(
    job: &Job,
    engine: &mut dyn RemovalEngine,
    correction: &NormalCorrection,
    cycle: usize,
    cutoff_mm: f64,
) -> Result<(RunResult, FormProfile, CycleReport), EngineError> {
    let mut part = job.clone();
    if let Process::Turning(turning) = &mut part.process {
        turning.correction = correction.clone();
    }
    let result = simulate(part, engine, &|_, _| {})?;
    let form = form_error(result.grid(), &result.field, cutoff_mm);
    let report = CycleReport {
        cycle,
        form_pv_nm: form.pv_nm,
        form_rms_nm: form.rms_nm,
        deviation_pv_nm: result.deviation.pv_nm,
        deviation_rms_nm: result.deviation.rms_nm,
        correction_max_nm: correction.max_abs_mm() * 1e6,
    };
    Ok((result, form, report))
}

/// Runs `cycles` compensations after the first machining (so `cycles + 1` parts).
pub fn compensation_loop(
    job: &Job,
    engine: &mut dyn RemovalEngine,
    cycles: usize,
    cutoff_mm: f64,
    progress: &dyn Fn(&CycleReport),
) -> Result<CompensationRun, EngineError> {
    let Some(turning) = job.process.turning() else {
        return Err(EngineError(
            "compensation corrects a turning path; this job is not a turning job".into(),
        ));
    };
    let mut correction = turning.correction.clone();
    let (mut reports, mut forms) = (Vec::new(), Vec::new());
    let mut cycle = 0;
    loop {
        let (result, form, report) = machine(job, engine, &correction, cycle, cutoff_mm)?;
        progress(&report);
        // Next path: the correction so far plus what this part still shows, per ring.
        correction = NormalCorrection {
            arc_length_mm: form.arc_length_mm.clone(),
            radius_mm: form.radius_mm.clone(),
            offset_mm: form
                .arc_length_mm
                .iter()
                .zip(&form.error_mm)
                .map(|(s, e)| correction.at(*s) + e)
                .collect(),
        };
        reports.push(report);
        forms.push(form);
        if cycle == cycles {
            return Ok(CompensationRun {
                cycles: reports,
                forms,
                next_correction: correction,
                last: result,
            });
        }
        cycle += 1;
    }
}

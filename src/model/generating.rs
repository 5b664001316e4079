//! The generating process (`process.kind = "generating"`, `tool.kind = "cup_wheel"`):
//! a cup wheel generating a sphere (seed 000).

use super::effects::generating_effects;
use super::surface;
use super::{
    Aperture, CupWheelSpec, GeneratingSpec, JobError, JobFile, ProcessSpec, SurfaceKind, ToolSpec,
    check, error, required,
};
use crate::geometry::cup_wheel::{CupWheel, inclination_for};
use crate::geometry::{Form, SurfaceOfRevolution};
use crate::process::{GeneratingProcess, GeneratingSetup, PlungeAxis, Process};

/// Wheel/part speed ratio below which teeth no longer pass a sample one at a time.
pub const MIN_SPEED_RATIO: f64 = 10.0;

pub fn validate_generating(
    file: &JobFile,
    spec: &GeneratingSpec,
    resolved: &mut JobFile,
    warnings: &mut Vec<String>,
) -> Result<(SurfaceOfRevolution, Aperture, Process), JobError> {
    let wheel = validate_wheel(file)?;
    if file.surface.kind() != SurfaceKind::Sphere {
        return Err(error(
            "surface.kind",
            "a generator makes spheres; allowed with process.kind = \"generating\": \"sphere\"",
        ));
    }
    let (surface, aperture) = surface::validate(&file.surface)?;
    let radius = 1.0 / surface.curvature_per_mm;
    let concave = surface.form == Form::Concave;
    let s = if concave { 1.0 } else { -1.0 };

    // The circle lies on a shell of radius R − s·r about the sphere's centre and passes
    // through the vertex: it must fit on that shell (R_t < R − s·r).
    let shell = radius - s * wheel.edge_radius_mm;
    if wheel.cutting_radius_mm >= shell {
        return Err(error(
            "tool.cutting_radius_mm",
            format!(
                "{} mm cannot reach the vertex: a cutting circle through the axis lies on the shell of radius R {} r = {shell:.6} mm about the sphere's centre, so it must be smaller; allowed: < {shell:.6} mm",
                wheel.cutting_radius_mm,
                if concave { "−" } else { "+" }
            ),
        ));
    }
    let exact_inclination = inclination_for(&wheel, radius, concave);
    let inclination_rad = match spec.inclination_deg {
        Some(degrees) => {
            let degrees = check_open("process.inclination_deg", degrees, 0.0, 90.0)?;
            degrees.to_radians()
        }
        None => exact_inclination,
    };
    let plunge_axis = spec.plunge_axis.unwrap_or(PlungeAxis::Z);
    let (tool_rpm, workpiece_rpm) = validate_speeds(spec)?;
    let spark_out_revolutions = check(
        "process.spark_out_revolutions",
        spec.spark_out_revolutions.unwrap_or(2.0),
        1.0,
        100.0,
        true,
    )?;
    let tooth_phase_deg = check(
        "process.tooth_phase_deg",
        spec.tooth_phase_deg.unwrap_or(0.0),
        -360.0,
        360.0,
        true,
    )?;
    let stock_allowance_mm = check(
        "process.stock_allowance_mm",
        spec.stock_allowance_mm.unwrap_or(0.1),
        0.0,
        10.0,
        true,
    )?;
    let cutter_offset_mm = check(
        "process.cutter_offset_mm",
        spec.cutter_offset_mm.unwrap_or(0.0),
        -0.5 * wheel.edge_radius_mm,
        0.5 * wheel.edge_radius_mm,
        true,
    )?;
    let setup = GeneratingSetup {
        wheel,
        form: surface.form,
        inclination_rad,
        plunge_axis,
        tool_rpm,
        workpiece_rpm,
        spark_out_revolutions,
        tooth_phase_rad: tooth_phase_deg.to_radians(),
        stock_allowance_mm,
        cutter_offset_mm,
    };

    let reach = setup.reach_radius_mm();
    if aperture.outer_radius_mm >= reach {
        return Err(error(
            "surface.aperture_diameter_mm",
            format!(
                "{} mm is beyond the wheel's reach: at inclination {:.4}° the cutting circle spans part radii up to 2·R_t·cos α·R/(R_t/sin α) = {reach:.4} mm; allowed: < {:.4} mm (a larger cutting radius reaches further)",
                2.0 * aperture.outer_radius_mm,
                inclination_rad.to_degrees(),
                2.0 * reach
            ),
        ));
    }
    let generated = setup.generated_radius_mm();
    if (generated - radius).abs() > 1e-9 * radius {
        warnings.push(format!(
            "at inclination {:.6}° the wheel generates R = {generated:.6} mm, not the nominal {radius:.6} mm ({:.6}° would): the deviation map shows the radius error",
            inclination_rad.to_degrees(),
            exact_inclination.to_degrees()
        ));
    }
    let effects = generating_effects(&file.effects, &setup)?;

    resolved.tool = ToolSpec::CupWheel(CupWheelSpec {
        cutting_radius_mm: Some(wheel.cutting_radius_mm),
        edge_radius_mm: Some(wheel.edge_radius_mm),
        teeth: Some(wheel.teeth),
    });
    resolved.process = ProcessSpec::Generating(GeneratingSpec {
        inclination_deg: Some(inclination_rad.to_degrees()),
        plunge_axis: Some(plunge_axis),
        tool_rpm: Some(tool_rpm),
        workpiece_rpm: Some(workpiece_rpm),
        spark_out_revolutions: Some(spark_out_revolutions),
        tooth_phase_deg: Some(tooth_phase_deg),
        stock_allowance_mm: Some(stock_allowance_mm),
        cutter_offset_mm: Some(cutter_offset_mm),
    });
    Ok((
        surface,
        aperture,
        Process::Generating(GeneratingProcess { setup, effects }),
    ))
}

/// The wheel's and the workpiece's speeds (rpm): the wheel must pass each point many
/// times per workpiece turn.
fn validate_speeds(spec: &GeneratingSpec) -> Result<(f64, f64), JobError> {
    let workpiece_rpm = check(
        "process.workpiece_rpm",
        spec.workpiece_rpm.unwrap_or(10.0),
        0.0,
        1e4,
        false,
    )?;
    let tool_rpm = spec.tool_rpm.unwrap_or(3000.0);
    if !tool_rpm.is_finite()
        || tool_rpm.abs() > 1e6
        || tool_rpm.abs() < MIN_SPEED_RATIO * workpiece_rpm
    {
        return Err(error(
            "process.tool_rpm",
            format!(
                "{tool_rpm} is out of range; allowed: a finite number with {MIN_SPEED_RATIO}·workpiece_rpm = {} ≤ |tool_rpm| ≤ 1e6 (the wheel must pass each point many times per workpiece turn)",
                MIN_SPEED_RATIO * workpiece_rpm
            ),
        ));
    }
    Ok((tool_rpm, workpiece_rpm))
}

fn validate_wheel(file: &JobFile) -> Result<CupWheel, JobError> {
    let ToolSpec::CupWheel(spec) = &file.tool else {
        return Err(error(
            "tool.kind",
            "a generating job needs kind = \"cup_wheel\" (an arc-nosed tool is for process.kind = \"turning\")",
        ));
    };
    let cutting = required(
        "tool.cutting_radius_mm",
        spec.cutting_radius_mm,
        "a finite number in (0, 1000]",
    )?;
    let cutting = check("tool.cutting_radius_mm", cutting, 0.0, 1000.0, false)?;
    let edge = required(
        "tool.edge_radius_mm",
        spec.edge_radius_mm,
        "a finite number in (0, cutting_radius_mm)",
    )?;
    let edge = check("tool.edge_radius_mm", edge, 0.0, 1000.0, false)?;
    if edge >= cutting {
        return Err(error(
            "tool.edge_radius_mm",
            format!(
                "{edge} mm is not smaller than the cutting radius {cutting} mm: the edge's tube would cross the wheel axis; allowed: (0, {cutting})"
            ),
        ));
    }
    let teeth = spec.teeth.unwrap_or(0);
    if teeth > 1000 {
        return Err(error(
            "tool.teeth",
            format!("{teeth} is out of range; allowed: 0 (a continuous edge) to 1000"),
        ));
    }
    Ok(CupWheel {
        cutting_radius_mm: cutting,
        edge_radius_mm: edge,
        teeth,
    })
}

/// A value strictly inside (min, max).
fn check_open(field: &str, value: f64, min: f64, max: f64) -> Result<f64, JobError> {
    if !value.is_finite() || value <= min || value >= max {
        return Err(error(
            field,
            format!("{value} is out of range; allowed: a finite number in ({min}, {max})"),
        ));
    }
    Ok(value)
}

/// Warns when the azimuth rows are too few to resolve the tooth marks.
pub fn check_tooth_resolution(setup: &GeneratingSetup, azimuths: u32, warnings: &mut Vec<String>) {
    if setup.wheel.teeth == 0 {
        return;
    }
    let marks_per_rev = setup.wheel.teeth as f64 * setup.speed_ratio().abs();
    let needed = (4.0 * marks_per_rev).ceil();
    if (azimuths as f64) < needed {
        warnings.push(format!(
            "the teeth pass every {:.4}° of workpiece rotation ({marks_per_rev:.0} marks per turn); grid.azimuths = {azimuths} does not resolve them (≥ {needed:.0} would)",
            360.0 / marks_per_rev
        ));
    }
}

//! The milling process (`process.kind = "milling"`) with an end mill (`ball_end`,
//! `bull_nose`, `flat_end`) or a disc cutter (`disc`).

use super::effects::milling_effects;
use super::surface::{self, usable_at};
use super::{
    Aperture, FluteModel, JobError, JobFile, MillToolSpec, MillingSpec, ProcessSpec, ToolKind,
    ToolSpec, check, error, reject_unused, required,
};
use crate::geometry::SurfaceOfRevolution;
use crate::geometry::cutter::Cutter;
use crate::geometry::disc_cutter::DiscCutter;
use crate::geometry::milling_tool::MillingTool;
use crate::process::milling::Flutes;
use crate::process::milling::{SPIRAL_NODES_PER_TURN, stepover_for_scallop};
use crate::process::{MillingPathKind, MillingProcess, MillingSetup, Process};

/// Most path nodes a job may plan (memory: ~80 bytes each).
const MAX_NODES: f64 = 2.0e7;

pub fn validate_milling(
    file: &JobFile,
    spec: &MillingSpec,
    resolved: &mut JobFile,
    warnings: &mut Vec<String>,
) -> Result<(SurfaceOfRevolution, Aperture, Process), JobError> {
    let (tool, teeth, tool_spec) = validate_tool(&file.tool)?;
    let (surface, aperture) = surface::validate(&file.surface)?;
    let path = required(
        "process.path",
        spec.path,
        "\"raster\", \"spiral\" or \"constant_scallop\"",
    )?;
    let cylinder = file.surface.kind() == super::SurfaceKind::Cylinder;
    if cylinder {
        check_cylinder_path(spec, path)?;
    }
    let lean = Lean::validate(spec, &tool)?;
    let feed_per_tooth = check(
        "process.feed_per_tooth_mm",
        spec.feed_per_tooth_mm.unwrap_or(0.0),
        0.0,
        10.0,
        true,
    )?;
    let spindle_rpm = spec
        .spindle_rpm
        .map(|rpm| check("process.spindle_rpm", rpm, 0.0, 1e6, false))
        .transpose()?;
    let stock = check(
        "process.stock_allowance_mm",
        spec.stock_allowance_mm.unwrap_or(0.01),
        0.0,
        50.0,
        true,
    )?;
    let depth = check(
        "process.depth_of_cut_mm",
        spec.depth_of_cut_mm.unwrap_or(stock),
        0.0,
        50.0,
        false,
    )?;

    let mut setup = MillingSetup {
        tool,
        teeth,
        path,
        five_axis: lean.five_axis,
        stepover_mm: 0.0,
        scallop_mm: 0.0,
        raster_angle_rad: lean.raster_angle,
        lead_rad: lean.lead,
        tilt_rad: lean.tilt,
        turn_rad: lean.turn,
        feed_per_tooth_mm: feed_per_tooth,
        flutes: validate_flutes(tool_spec, &tool, teeth, feed_per_tooth)?,
        spindle_rpm,
        stock_allowance_mm: stock,
        depth_of_cut_mm: depth,
        contact_radius_mm: 0.0,
        part_length_mm: None,
    };
    let profile = setup.profile_radius_mm();
    if !(profile.is_finite() && profile > 0.0) {
        return Err(error(
            "process.lead_deg",
            "a flat-end mill square to the surface has no round profile across the feed (its scallops are steps); lean it (lead_deg > 0) or use a ball or bull-nose",
        ));
    }
    check_fit(&surface, &aperture, &tool, profile)?;
    (setup.stepover_mm, setup.scallop_mm) = plan_stepover(spec, path, &surface, &tool, profile)?;
    setup.contact_radius_mm = contact_radius_mm(&surface, &aperture, &tool, setup.stepover_mm);
    if cylinder {
        setup.part_length_mm = match &file.surface {
            super::SurfaceSpec::Cylinder(cylinder) => cylinder.length_mm,
            _ => None,
        };
    }
    if path == MillingPathKind::ConstantScallop {
        setup.stepover_mm = tightest_spacing_mm(&setup, &surface);
    }
    check_path_size(&setup, &surface)?;
    let expected_scallop =
        crate::geometry::formulas::flat_scallop_height(profile, setup.stepover_mm);
    if expected_scallop >= stock {
        warnings.push(format!(
            "the step-over leaves scallops of about {:.3} µm, more than the {:.3} µm stock allowance: their tops will show the uncut stock; raise process.stock_allowance_mm",
            expected_scallop * 1e3,
            stock * 1e3
        ));
    }

    record_resolved(resolved, spec, &setup, &lean);
    let effects = milling_effects(&file.effects, &setup, &mut resolved.effects)?;
    Ok((
        surface,
        aperture,
        Process::Milling(MillingProcess { setup, effects }),
    ))
}

/// A cylinder is milled in raster passes along its axis.
fn check_cylinder_path(spec: &MillingSpec, path: MillingPathKind) -> Result<(), JobError> {
    if path != MillingPathKind::Raster {
        return Err(error(
            "process.path",
            "a cylinder is milled in raster passes along its axis; allowed with surface.kind = \"cylinder\": \"raster\"",
        ));
    }
    if spec.raster_angle_deg.is_some() {
        return Err(error(
            "process.raster_angle_deg",
            "a cylinder's passes run along its axis (Y), stepping around it; remove it",
        ));
    }
    Ok(())
}

/// The tool's axes and leans (rad): lead and tilt at the path's start and end, a disc's
/// turn, and the raster's angle.
struct Lean {
    five_axis: bool,
    lead: [f64; 2],
    tilt: [f64; 2],
    turn: f64,
    raster_angle: f64,
}

impl Lean {
    fn validate(spec: &MillingSpec, tool: &MillingTool) -> Result<Lean, JobError> {
        let angle =
            |field: &str, value: Option<f64>, low: f64, high: f64| -> Result<f64, JobError> {
                let degrees = value.unwrap_or(0.0);
                if !degrees.is_finite() || degrees < low || degrees >= high {
                    return Err(error(
                        field,
                        format!("{degrees} is out of range; allowed: [{low}, {high})"),
                    ));
                }
                Ok(degrees.to_radians())
            };
        let five_axis = match spec.axes.unwrap_or(3) {
            3 => false,
            5 => true,
            other => {
                return Err(error(
                    "process.axes",
                    format!("{other} is not supported; allowed: 3 or 5"),
                ));
            }
        };
        if !five_axis && matches!(*tool, MillingTool::EndMill(_)) {
            for (field, value) in [
                ("lead_deg", spec.lead_deg),
                ("tilt_deg", spec.tilt_deg),
                ("lead_end_deg", spec.lead_end_deg),
                ("tilt_end_deg", spec.tilt_end_deg),
            ] {
                if value.is_some_and(|v| v != 0.0) {
                    return Err(error(
                        &format!("process.{field}"),
                        "leans the tool from the surface normal, which needs axes = 5 (with axes = 3 the axis stays vertical)",
                    ));
                }
            }
        }
        let lead = angle("process.lead_deg", spec.lead_deg, 0.0, 90.0)?;
        let tilt = check(
            "process.tilt_deg",
            spec.tilt_deg.unwrap_or(0.0),
            -90.0,
            90.0,
            true,
        )?
        .to_radians();
        let lead_end = angle(
            "process.lead_end_deg",
            spec.lead_end_deg.or(spec.lead_deg),
            0.0,
            90.0,
        )?;
        let tilt_end = check(
            "process.tilt_end_deg",
            spec.tilt_end_deg.or(spec.tilt_deg).unwrap_or(0.0),
            -90.0,
            90.0,
            true,
        )?
        .to_radians();
        let turn = angle("process.turn_deg", spec.turn_deg, 0.0, 90.0)?;
        if spec.turn_deg.is_some() && !matches!(*tool, MillingTool::Disc(_)) {
            return Err(error(
                "process.turn_deg",
                "is only used with tool.kind = \"disc\"; remove it",
            ));
        }
        let raster_angle = angle(
            "process.raster_angle_deg",
            spec.raster_angle_deg,
            -360.0,
            360.0,
        )?;
        Ok(Lean {
            five_axis,
            lead: [lead, lead_end],
            tilt: [tilt, tilt_end],
            turn,
            raster_angle,
        })
    }
}

/// The step-over and the scallop height it was planned from (0 when given as a
/// step-over): given, or from the scallop at the centre's curvature (the
/// constant-scallop spiral re-plans it at every radius); below the tool's cutting width.
fn plan_stepover(
    spec: &MillingSpec,
    path: MillingPathKind,
    surface: &SurfaceOfRevolution,
    tool: &MillingTool,
    profile: f64,
) -> Result<(f64, f64), JobError> {
    let curvature = surface.meridional_curvature(0.0);
    let (stepover, scallop) = match (spec.stepover_mm, spec.scallop_mm, path) {
        (Some(_), Some(_), _) => {
            return Err(error(
                "process.scallop_mm",
                "give either stepover_mm or scallop_mm, not both",
            ));
        }
        (Some(_), None, MillingPathKind::ConstantScallop)
        | (None, None, MillingPathKind::ConstantScallop) => {
            return Err(error(
                "process.scallop_mm",
                "missing: path = \"constant_scallop\" plans its step-over from the scallop height; allowed: a finite number > 0",
            ));
        }
        (Some(step), None, _) => (check("process.stepover_mm", step, 0.0, 1e3, false)?, 0.0),
        (None, Some(h), _) => {
            let h = check("process.scallop_mm", h, 0.0, profile, false)?;
            (
                stepover_for_scallop(h, profile, curvature.abs(), curvature < 0.0),
                h,
            )
        }
        (None, None, _) => {
            return Err(error(
                "process.stepover_mm",
                "missing; give stepover_mm, or scallop_mm to plan it",
            ));
        }
    };
    let width = cutting_width(tool);
    if stepover >= width {
        return Err(error(
            "process.stepover_mm",
            format!(
                "{stepover:.6} mm is not below the tool's cutting width {width:.6} mm: passes would leave uncut strips; allowed: (0, {width:.6})"
            ),
        ));
    }
    Ok((stepover, scallop))
}

/// How far the contact path runs: a little past the rim, as far as the surface is usable.
fn contact_radius_mm(
    surface: &SurfaceOfRevolution,
    aperture: &Aperture,
    tool: &MillingTool,
    stepover_mm: f64,
) -> f64 {
    let outer = aperture.outer_radius_mm;
    let mut contact = outer + (2.0 * stepover_mm).min(tool.reach_mm());
    while contact > outer && !usable_at(surface, contact) {
        contact = outer + 0.5 * (contact - outer);
        if contact - outer < 1e-6 {
            contact = outer;
        }
    }
    contact
}

/// The tightest spacing of a constant-scallop spiral's turns along the surface (for the
/// default grid and the reports).
fn tightest_spacing_mm(setup: &MillingSetup, surface: &SurfaceOfRevolution) -> f64 {
    let contact = setup.contact_radius_mm;
    (0..=200)
        .map(|i| {
            let r = contact * i as f64 / 200.0;
            setup.radial_step(surface, r) * surface.arc_length_rate(r)
        })
        .fold(f64::INFINITY, f64::min)
}

/// The path's node count, held below `MAX_NODES`.
fn check_path_size(setup: &MillingSetup, surface: &SurfaceOfRevolution) -> Result<(), JobError> {
    let (contact, tool) = (setup.contact_radius_mm, &setup.tool);
    let nodes = match setup.path {
        MillingPathKind::Raster => {
            let passes = 2.0 * contact / setup.stepover_mm;
            passes * 2.0 * contact / (0.25 * tool.reach_mm()).min(0.05)
        }
        MillingPathKind::Spiral => contact / setup.stepover_mm * SPIRAL_NODES_PER_TURN as f64,
        MillingPathKind::ConstantScallop => {
            let steps = 400;
            let turns: f64 = (0..steps)
                .map(|i| {
                    let r = contact * (i as f64 + 0.5) / steps as f64;
                    contact / steps as f64 / setup.radial_step(surface, r)
                })
                .sum();
            turns * SPIRAL_NODES_PER_TURN as f64
        }
    };
    if nodes > MAX_NODES {
        return Err(error(
            "process.stepover_mm",
            format!(
                "{:.6} mm plans about {nodes:.2e} path nodes, more than the {MAX_NODES:.0e} allowed; raise the step-over or the scallop height",
                setup.stepover_mm
            ),
        ));
    }
    Ok(())
}

/// The defaults a milling job filled in, written back to the resolved job.
fn record_resolved(resolved: &mut JobFile, spec: &MillingSpec, setup: &MillingSetup, lean: &Lean) {
    let [lead, lead_end] = lean.lead;
    let [tilt, tilt_end] = lean.tilt;
    if let Some(tool) = resolved.tool.milling_mut() {
        tool.teeth = Some(setup.teeth);
        if setup.feed_per_tooth_mm > 0.0 {
            tool.flutes = Some(if setup.flutes.edges {
                FluteModel::Edges
            } else {
                FluteModel::Body
            });
        }
    }
    let disc = matches!(setup.tool, MillingTool::Disc(_));
    resolved.process = ProcessSpec::Milling(MillingSpec {
        axes: Some(if setup.five_axis { 5 } else { 3 }),
        stepover_mm: (spec.scallop_mm.is_none()).then_some(setup.stepover_mm),
        raster_angle_deg: Some(lean.raster_angle.to_degrees()),
        lead_deg: Some(lead.to_degrees()),
        tilt_deg: Some(tilt.to_degrees()),
        lead_end_deg: Some(lead_end.to_degrees()),
        tilt_end_deg: Some(tilt_end.to_degrees()),
        feed_per_tooth_mm: Some(setup.feed_per_tooth_mm),
        stock_allowance_mm: Some(setup.stock_allowance_mm),
        depth_of_cut_mm: Some(setup.depth_of_cut_mm),
        turn_deg: if disc {
            Some(lean.turn.to_degrees())
        } else {
            spec.turn_deg
        },
        ..spec.clone()
    });
}

fn validate_tool(spec: &ToolSpec) -> Result<(MillingTool, u32, &MillToolSpec), JobError> {
    let kind = spec.kind();
    let Some(spec) = spec.milling() else {
        return Err(error(
            "tool.kind",
            "a milling job needs kind = \"ball_end\", \"bull_nose\", \"flat_end\" or \"disc\"",
        ));
    };
    let name = match kind {
        ToolKind::BallEnd => "ball_end",
        ToolKind::BullNose => "bull_nose",
        ToolKind::FlatEnd => "flat_end",
        _ => "disc",
    };
    // The milling tools share one table; a corner radius is a bull-nose's, the
    // inserts' fields a disc's.
    reject_unused(
        "tool",
        name,
        &[
            (
                "corner_radius_mm",
                spec.corner_radius_mm.is_some() && kind != ToolKind::BullNose,
            ),
            (
                "insert_length_mm",
                spec.insert_length_mm.is_some() && kind != ToolKind::Disc,
            ),
            (
                "side_rake_deg",
                spec.side_rake_deg.is_some() && kind != ToolKind::Disc,
            ),
            (
                "lead_angle_deg",
                spec.lead_angle_deg.is_some() && kind != ToolKind::Disc,
            ),
        ],
    )?;
    let diameter = required(
        "tool.diameter_mm",
        spec.diameter_mm,
        "a finite number in (0, 500]",
    )?;
    let diameter = check("tool.diameter_mm", diameter, 0.0, 500.0, false)?;
    let teeth = spec.teeth.unwrap_or(2);
    if !(1..=1000).contains(&teeth) {
        return Err(error(
            "tool.teeth",
            format!("{teeth} is out of range; allowed: 1 to 1000"),
        ));
    }
    let radius = 0.5 * diameter;
    let tool = match kind {
        ToolKind::BallEnd => MillingTool::EndMill(Cutter::ball(radius)),
        ToolKind::FlatEnd => MillingTool::EndMill(Cutter::flat(radius)),
        ToolKind::BullNose => {
            let corner = required(
                "tool.corner_radius_mm",
                spec.corner_radius_mm,
                "a finite number in (0, diameter/2)",
            )?;
            let corner = check("tool.corner_radius_mm", corner, 0.0, radius, false)?;
            if corner >= radius {
                return Err(error(
                    "tool.corner_radius_mm",
                    format!(
                        "{corner} is not below half the diameter ({radius}); allowed (0, {radius}) — use ball_end for a full radius"
                    ),
                ));
            }
            MillingTool::EndMill(Cutter::bull_nose(radius - corner, corner))
        }
        _ => {
            let length = required(
                "tool.insert_length_mm",
                spec.insert_length_mm,
                "a finite number in (0, diameter]",
            )?;
            let length = check("tool.insert_length_mm", length, 0.0, diameter, false)?;
            let rake = check(
                "tool.side_rake_deg",
                spec.side_rake_deg.unwrap_or(0.0),
                0.0,
                80.0,
                true,
            )?;
            let lead = spec.lead_angle_deg.unwrap_or(90.0);
            if !lead.is_finite() || lead <= 0.0 || lead >= 180.0 {
                return Err(error(
                    "tool.lead_angle_deg",
                    format!("{lead} is out of range; allowed: (0, 180)"),
                ));
            }
            MillingTool::Disc(DiscCutter {
                diameter_mm: diameter,
                insert_length_mm: length,
                side_rake_rad: rake.to_radians(),
                lead_rad: lead.to_radians(),
            })
        }
    };
    Ok((tool, teeth, spec))
}

/// How the teeth cut: `flutes` (edges by default), and for an end mill's edges the helix
/// and per-tooth runout — all of which act only at each tooth's cut, so they need a feed
/// per tooth.
fn validate_flutes(
    spec: &MillToolSpec,
    tool: &MillingTool,
    teeth: u32,
    feed_per_tooth: f64,
) -> Result<Flutes, JobError> {
    let given = [
        ("tool.flutes", spec.flutes.is_some()),
        ("tool.helix_deg", spec.helix_deg.is_some()),
        (
            "tool.tooth_radial_runout_mm",
            spec.tooth_radial_runout_mm.is_some(),
        ),
        (
            "tool.tooth_axial_runout_mm",
            spec.tooth_axial_runout_mm.is_some(),
        ),
    ];
    if feed_per_tooth == 0.0 {
        if let Some((field, _)) = given.iter().find(|(_, set)| *set) {
            return Err(error(
                field,
                "acts at each tooth's cut: it needs process.feed_per_tooth_mm > 0 (the job sweeps the tool body continuously)",
            ));
        }
        return Ok(Flutes::default());
    }
    let edges = spec.flutes != Some(FluteModel::Body);
    let edge_fields = &given[1..];
    let end_mill = match tool {
        MillingTool::EndMill(cutter) => Some(cutter),
        MillingTool::Disc(_) => None,
    };
    if let Some((field, _)) = edge_fields.iter().find(|(_, set)| *set) {
        if !edges {
            return Err(error(
                field,
                "shapes a tooth's edge: it needs flutes = \"edges\"",
            ));
        }
        if end_mill.is_none() {
            return Err(error(
                field,
                "is for end mills; a disc cutter's inserts are straight",
            ));
        }
    }
    let bound = end_mill.map_or(0.0, |c| 0.2 * c.radius_mm());
    let per_tooth = |field: &str, values: &Option<Vec<f64>>, low: f64| {
        let Some(values) = values else {
            return Ok(Vec::new());
        };
        if values.len() != teeth as usize {
            return Err(error(
                field,
                format!(
                    "has {} values; allowed: one per tooth (tool.teeth = {teeth})",
                    values.len()
                ),
            ));
        }
        values
            .iter()
            .map(|&v| check(field, v, low, bound, true))
            .collect::<Result<Vec<f64>, JobError>>()
    };
    let helix = spec.helix_deg.unwrap_or(0.0);
    if !(0.0..60.0).contains(&helix) {
        return Err(error(
            "tool.helix_deg",
            format!("{helix} is out of range; allowed: a finite number in [0, 60)"),
        ));
    }
    Ok(Flutes {
        edges,
        helix_rad: helix.to_radians(),
        radial_runout_mm: per_tooth(
            "tool.tooth_radial_runout_mm",
            &spec.tooth_radial_runout_mm,
            0.0,
        )?,
        axial_runout_mm: per_tooth(
            "tool.tooth_axial_runout_mm",
            &spec.tooth_axial_runout_mm,
            -bound,
        )?,
    })
}

/// The width across the feed one pass can cut (the step-over must stay below it).
fn cutting_width(tool: &MillingTool) -> f64 {
    match tool {
        MillingTool::EndMill(cutter) => 2.0 * cutter.radius_mm(),
        MillingTool::Disc(disc) => {
            disc.insert_length_mm * disc.lead_rad.sin() * disc.side_rake_rad.cos()
        }
    }
}

/// A round profile of radius `profile` (and an end mill's whole radius) must fit every
/// concave curvature of the part it touches.
fn check_fit(
    surface: &SurfaceOfRevolution,
    aperture: &Aperture,
    tool: &MillingTool,
    profile: f64,
) -> Result<(), JobError> {
    let outer = match tool {
        MillingTool::EndMill(cutter) if cutter.major_radius_mm > 0.0 => cutter.radius_mm(),
        MillingTool::EndMill(_) => profile,
        MillingTool::Disc(_) => return Ok(()),
    };
    let steps = 2000;
    for i in 0..=steps {
        let r = aperture.outer_radius_mm * i as f64 / steps as f64;
        let meridional = surface.meridional_curvature(r);
        let slope = surface.slope(r);
        let sagittal = if r > 0.0 {
            slope / (r * (1.0 + slope * slope).sqrt())
        } else {
            meridional
        };
        let hollow = meridional.max(sagittal);
        if hollow > 0.0 && outer >= 1.0 / hollow {
            return Err(error(
                "tool.diameter_mm",
                format!(
                    "the tool (radius {outer:.4} mm) does not fit the concave surface: its radius of curvature is {:.4} mm at r = {r:.4} mm; allowed: a radius < {:.4} mm",
                    1.0 / hollow,
                    1.0 / hollow
                ),
            ));
        }
    }
    Ok(())
}

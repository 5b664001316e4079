//! The `[process]` table: a generated spiral or an NC program, and the checks of the
//! tool against the surface along the path.

use super::effects::{EffectKind, apply_edge_profile, turning_effects};
use super::surface::{self, MAX_SLOPE_DEG, usable_at, usable_over};
use super::{
    Aperture, ArcNoseSpec, JobError, JobFile, NcUnits, ProcessSpec, SurfaceKind, SurfaceSpec,
    ToolSpec, TurningSpec, check, error, required, resolve_file,
};
use crate::formats::nc::{NcDeclared, parse_nc_declared};
use crate::geometry::{ArcNoseTool, MeridianArcLength, SurfaceOfRevolution};
use crate::process::nc_path::{pass_pose_table, path_envelope};
use crate::process::{
    FeedAlong, NcPath, NcReference, NormalCorrection, Process, TurningMode, TurningPath,
    TurningProcess, TurningSpiral,
};
use glam::DVec2;
use std::path::Path;

/// A turning job's process: tool, path (spiral or NC program), effects, measured edge
/// and normal correction; returns the surface and aperture it is judged against.
pub fn validate_turning(
    file: &JobFile,
    spec: &TurningSpec,
    base_dir: &Path,
    resolved: &mut JobFile,
    warnings: &mut Vec<String>,
) -> Result<(SurfaceOfRevolution, Aperture, Process), JobError> {
    let mut out = spec.clone();
    if file.surface.kind() == SurfaceKind::Cylinder {
        return Err(error(
            "surface.kind",
            "a cylinder (axis along Y) is milled, not turned; allowed with process.kind = \"turning\": \"plane\", \"sphere\", \"asphere\" or \"from_path\"",
        ));
    }
    let (tool, tool_spec) = validate_tool(&file.tool)?;
    let mut tool_out = tool_spec.clone();
    let (surface, aperture, path, spindle_rpm) = match &spec.nc_program {
        None => {
            let mode = required("process.mode", spec.mode, "\"xz\" or \"xzb\"")?;
            let (surface, aperture) = surface::validate(&file.surface)?;
            let (spiral, rpm) = validate_spiral(spec, mode, &surface, &aperture, &tool, warnings)?;
            resolve_spiral(&mut out, &spiral);
            (surface, aperture, TurningPath::Spiral(spiral), rpm)
        }
        Some(program) => {
            let program = resolve_file("process.nc_program", base_dir, program)?;
            let nc = validate_nc(spec, &file.surface, &program, &tool, warnings)?;
            out.mode = Some(TurningMode::Xz);
            out.nc_program = Some(program);
            out.nc_reference = Some(nc.path.reference);
            out.stock_allowance_mm = Some(nc.path.stock_allowance_mm);
            (
                nc.surface,
                nc.aperture,
                TurningPath::Nc(nc.path),
                nc.spindle_rpm,
            )
        }
    };
    if file.surface.kind() == SurfaceKind::FromPath {
        let inner = resolved.surface.aperture_diameters_mm().1;
        resolved.surface = resolved
            .surface
            .clone()
            .with_aperture(2.0 * aperture.outer_radius_mm, inner);
    }
    check_tool_against_surface(&surface, &path, &tool)?;

    let mut effects = turning_effects(&file.effects, tool.nose_radius_mm, spindle_rpm)?;
    // Spring-back applies each pass to the height the earlier ones left, and the engines
    // run an NC program's passes apart (keeping the lower of their surfaces).
    if let TurningPath::Nc(nc) = &path
        && nc.tables.len() > 1
        && let Some(index) = file
            .effects
            .iter()
            .position(|effect| effect.kind() == EffectKind::SpringBack)
    {
        return Err(error(
            &format!("effects[{index}].kind"),
            format!(
                "\"spring_back\" needs every pass in one sequence, and this NC program has {} cutting passes; allowed with a spiral or an NC program of one cutting pass",
                nc.tables.len()
            ),
        ));
    }
    if let Some(profile) = &tool_spec.edge_profile {
        let profile = resolve_file("tool.edge_profile", base_dir, profile)?;
        apply_edge_profile(
            &mut effects,
            tool_spec,
            &profile,
            &tool,
            path.mode(),
            warnings,
        )?;
        tool_out.edge_profile = Some(profile);
    }
    tool_out.clearance_angle_deg = Some(tool.clearance_angle_deg);
    resolved.tool = ToolSpec::ArcNose(tool_out);
    let correction = match &spec.compensation {
        None => NormalCorrection::default(),
        Some(file_name) => {
            let table = resolve_file("process.compensation", base_dir, file_name)?;
            let in_table = |message: String| {
                error(
                    "process.compensation",
                    format!("{}: {message}", table.display()),
                )
            };
            let text = std::fs::read_to_string(&table).map_err(|err| in_table(err.to_string()))?;
            let correction = NormalCorrection::from_csv(&text).map_err(in_table)?;
            if correction.max_abs_mm() > 0.5 * tool.nose_radius_mm {
                return Err(in_table(format!(
                    "offsets reach {:.3} mm; allowed: at most half the nose radius",
                    correction.max_abs_mm()
                )));
            }
            out.compensation = Some(table);
            correction
        }
    };
    // The resolved job carries the feed per revolution it derived; one that gave
    // `spindle_rpm + feed_mm_per_min` keeps the spindle speed and the derived feed only,
    // so `job.resolved.toml` passes `check` again (the two forms are exclusive).
    if out.feed_per_rev_mm.is_some() {
        out.feed_mm_per_min = None;
    }
    resolved.process = ProcessSpec::Turning(out);
    Ok((
        surface,
        aperture,
        Process::Turning(TurningProcess {
            tool,
            path,
            correction,
            effects,
            spindle_rpm,
            azimuth_offset_rad: 0.0,
        }),
    ))
}

fn validate_tool(spec: &ToolSpec) -> Result<(ArcNoseTool, &ArcNoseSpec), JobError> {
    let ToolSpec::ArcNose(spec) = spec else {
        return Err(error(
            "tool.kind",
            "a turning job needs kind = \"arc_nose\" (a cup wheel is for process.kind = \"generating\")",
        ));
    };
    let nose = required(
        "tool.nose_radius_mm",
        spec.nose_radius_mm,
        "a finite number in (0, 100]",
    )?;
    let included = required(
        "tool.included_angle_deg",
        spec.included_angle_deg,
        "a finite number in (0, 180]",
    )?;
    let tool = ArcNoseTool {
        nose_radius_mm: check("tool.nose_radius_mm", nose, 0.0, 100.0, false)?,
        included_angle_deg: check("tool.included_angle_deg", included, 0.0, 180.0, false)?,
        clearance_angle_deg: check(
            "tool.clearance_angle_deg",
            spec.clearance_angle_deg.unwrap_or(10.0),
            0.0,
            45.0,
            false,
        )?,
    };
    Ok((tool, spec))
}

/// The feed per revolution, from `feed_per_rev_mm` or `feed_mm_per_min / spindle_rpm`,
/// and the spindle speed if given.
fn feed_and_speed(spec: &TurningSpec) -> Result<(f64, Option<f64>), JobError> {
    let spindle_rpm = spec
        .spindle_rpm
        .map(|rpm| check("process.spindle_rpm", rpm, 0.0, 1e6, false))
        .transpose()?;
    let feed_speed = spec
        .feed_mm_per_min
        .map(|f| check("process.feed_mm_per_min", f, 0.0, 1e6, false))
        .transpose()?;
    let feed = match (spec.feed_per_rev_mm, spindle_rpm, feed_speed) {
        (Some(feed), _, None) => check("process.feed_per_rev_mm", feed, 0.0, 100.0, false)?,
        (None, Some(rpm), Some(speed)) => speed / rpm,
        (Some(_), _, Some(_)) => {
            return Err(error(
                "process.feed_mm_per_min",
                "give either feed_per_rev_mm or spindle_rpm + feed_mm_per_min, not both",
            ));
        }
        (None, None, Some(_)) => {
            return Err(error(
                "process.spindle_rpm",
                "missing: feed_mm_per_min needs spindle_rpm",
            ));
        }
        (None, _, None) => {
            return Err(error(
                "process.feed_per_rev_mm",
                "missing; give feed_per_rev_mm, or spindle_rpm and feed_mm_per_min, or nc_program",
            ));
        }
    };
    Ok((feed, spindle_rpm))
}

fn stock_allowance(spec: &TurningSpec) -> Result<f64, JobError> {
    check(
        "process.stock_allowance_mm",
        spec.stock_allowance_mm.unwrap_or(0.002),
        0.0,
        10.0,
        true,
    )
}

fn validate_spiral(
    spec: &TurningSpec,
    mode: TurningMode,
    surface: &SurfaceOfRevolution,
    aperture: &Aperture,
    tool: &ArcNoseTool,
    warnings: &mut Vec<String>,
) -> Result<(TurningSpiral, Option<f64>), JobError> {
    for (field, given) in [
        ("nc_reference", spec.nc_reference.is_some()),
        ("nc_feed_mode", spec.nc_feed_mode.is_some()),
        ("nc_units", spec.nc_units.is_some()),
    ] {
        if given {
            return Err(error(
                &format!("process.{field}"),
                "is only used with nc_program; remove it",
            ));
        }
    }
    let (feed, spindle_rpm) = feed_and_speed(spec)?;
    let coverable = tool.coverable_feed_mm();
    if feed >= coverable {
        return Err(error(
            "process.feed_per_rev_mm",
            format!(
                "{feed} mm exceeds what the nose can cover: neighbouring passes must meet on the edge, so allowed: < 2·nose_radius·sin(min(included_angle/2, 90°)) = {coverable:.6} mm"
            ),
        ));
    }
    let stock = stock_allowance(spec)?;
    let depth = check(
        "process.depth_of_cut_mm",
        spec.depth_of_cut_mm.unwrap_or(stock),
        0.0,
        10.0,
        false,
    )?;
    let feed_along = spec.feed_along.unwrap_or(FeedAlong::Radial);
    let outer = aperture.outer_radius_mm;
    let start = match spec.start_radius_mm {
        Some(start) => {
            let start = check("process.start_radius_mm", start, 0.0, 1e4, false)?;
            if let Some(r) = usable_over(surface, outer.min(start), start, 4000) {
                return Err(error(
                    "process.start_radius_mm",
                    format!(
                        "{start}: the path would cross r = {r:.4} mm, where the surface is undefined or steeper than {MAX_SLOPE_DEG}°"
                    ),
                ));
            }
            start
        }
        // Start two passes outside the rim so the rim is finished like the rest,
        // unless the surface ends there.
        None => {
            let lead_in = match feed_along {
                FeedAlong::Radial => 2.0 * feed,
                FeedAlong::ArcLength => 2.0 * feed / surface.arc_length_rate(outer),
            };
            if usable_over(surface, outer, outer + lead_in, 100).is_none() {
                outer + lead_in
            } else {
                warnings.push(format!(
                    "the surface ends at the rim, so the spiral starts there: the outermost {:.3} µm are a lead-in zone, not finished like the rest",
                    feed * 1e3
                ));
                outer
            }
        }
    };
    let end = check(
        "process.end_radius_mm",
        spec.end_radius_mm.unwrap_or(0.0),
        0.0,
        start,
        true,
    )?;
    if end >= start {
        return Err(error(
            "process.end_radius_mm",
            format!("{end} must be smaller than start_radius_mm = {start}"),
        ));
    }
    Ok((
        TurningSpiral {
            mode,
            feed_per_rev_mm: feed,
            feed_along,
            start_radius_mm: start,
            end_radius_mm: end,
            stock_allowance_mm: stock,
            depth_of_cut_mm: depth,
        },
        spindle_rpm,
    ))
}

/// Records the spiral's resolved values in the written job.
fn resolve_spiral(resolved: &mut TurningSpec, spiral: &TurningSpiral) {
    resolved.feed_per_rev_mm = Some(spiral.feed_per_rev_mm);
    resolved.feed_along = Some(spiral.feed_along);
    resolved.stock_allowance_mm = Some(spiral.stock_allowance_mm);
    resolved.depth_of_cut_mm = Some(spiral.depth_of_cut_mm);
    resolved.start_radius_mm = Some(spiral.start_radius_mm);
    resolved.end_radius_mm = Some(spiral.end_radius_mm);
}

/// An NC job's path, with the surface and aperture it is judged against.
struct NcJob {
    pub surface: SurfaceOfRevolution,
    pub aperture: Aperture,
    pub path: NcPath,
    pub spindle_rpm: Option<f64>,
}

fn validate_nc(
    spec: &TurningSpec,
    surface_spec: &SurfaceSpec,
    program: &Path,
    tool: &ArcNoseTool,
    warnings: &mut Vec<String>,
) -> Result<NcJob, JobError> {
    let not_with_nc = [
        ("feed_per_rev_mm", spec.feed_per_rev_mm.is_some()),
        ("feed_mm_per_min", spec.feed_mm_per_min.is_some()),
        ("feed_along", spec.feed_along.is_some()),
        ("depth_of_cut_mm", spec.depth_of_cut_mm.is_some()),
        ("start_radius_mm", spec.start_radius_mm.is_some()),
        ("end_radius_mm", spec.end_radius_mm.is_some()),
    ];
    if let Some((field, _)) = not_with_nc.iter().find(|(_, given)| *given) {
        return Err(error(
            &format!("process.{field}"),
            "is not used with nc_program (the program is the path); remove it",
        ));
    }
    if spec.mode == Some(TurningMode::Xzb) {
        return Err(error(
            "process.mode",
            "\"xzb\" needs B-axis blocks, and NC programs are read as C-X-Z; allowed with nc_program: \"xz\"",
        ));
    }
    let spindle_rpm = spec
        .spindle_rpm
        .map(|rpm| check("process.spindle_rpm", rpm, 0.0, 1e6, false))
        .transpose()?;
    let in_program = |message: String| {
        error(
            "process.nc_program",
            format!("{}: {message}", program.display()),
        )
    };
    let text = std::fs::read_to_string(program).map_err(|err| in_program(err.to_string()))?;
    let declared = NcDeclared {
        feed_mode: spec.nc_feed_mode,
        mm_per_length_unit: spec.nc_units.map_or(1.0, NcUnits::mm_per_unit),
    };
    let parsed = parse_nc_declared(&text, declared).map_err(|err| in_program(err.to_string()))?;
    if parsed.passes.is_empty() {
        return Err(in_program("no cutting pass (C-X-Z blocks) found".into()));
    }
    let reference = spec.nc_reference.unwrap_or(NcReference::NoseCentre);
    let mut tables = parsed
        .passes
        .iter()
        .map(|pass| pass_pose_table(pass, reference, tool.nose_radius_mm))
        .collect::<Result<Vec<_>, _>>()
        .map_err(in_program)?;

    let (surface, aperture) = if surface_spec.kind() == SurfaceKind::FromPath {
        let envelope = path_envelope(&tables, tool.nose_radius_mm).map_err(in_program)?;
        for pose in tables.iter_mut().flat_map(|t| t.poses.iter_mut()) {
            pose.z_mm -= envelope.vertex_z_mm;
        }
        warnings.push(format!(
            "nominal surface derived from the NC path: the ideal {} mm tool's envelope fitted as an even polynomial to r²⁰ (largest fit residual {:.3} nm)",
            tool.nose_radius_mm, envelope.fit_residual_nm
        ));
        let aperture = surface::aperture(surface_spec, Some(envelope.finished_radius_mm))?;
        (envelope.surface, aperture)
    } else {
        surface::validate(surface_spec)?
    };
    surface::check_defined(&surface, &aperture)?;

    // How far the ideal envelope strays from the nominal surface, and how far out it cuts.
    let (mut band, mut outer_contact) = (0.0f64, 0.0f64);
    for pose in tables
        .iter()
        .flat_map(|t| t.poses.iter())
        .step_by(7)
        .filter(|p| p.x_mm >= 0.0)
    {
        let (distance, foot) = surface.distance_to(DVec2::new(pose.x_mm, pose.z_mm));
        band = band.max((distance - tool.nose_radius_mm).abs());
        outer_contact = outer_contact.max(foot);
    }
    let stock_allowance_mm = stock_allowance(spec)?;
    let pass_spacing_mm = NcPath::median_radial_feed_mm(&tables);
    if pass_spacing_mm <= 0.0 {
        return Err(in_program(
            "the path does not advance radially from one revolution to the next".into(),
        ));
    }
    Ok(NcJob {
        surface,
        aperture,
        path: NcPath {
            program: program.to_path_buf(),
            reference,
            tables,
            stock_allowance_mm,
            cut_band_mm: 1.1 * band + 1e-6,
            pass_spacing_mm,
            outer_contact_radius_mm: outer_contact,
        },
        spindle_rpm,
    })
}

/// Spacing of neighbouring passes along the surface at radius r.
fn pass_spacing(surface: &SurfaceOfRevolution, path: &TurningPath, r: f64) -> f64 {
    match path {
        TurningPath::Spiral(spiral) if spiral.feed_along == FeedAlong::ArcLength => {
            spiral.feed_per_rev_mm
        }
        _ => path.pass_spacing_mm() * surface.arc_length_rate(r),
    }
}

/// The tool must fit concave curvature, and in XZ its edge must reach the slope
/// (plus the angle to the neighbouring pass's cusp).
fn check_tool_against_surface(
    surface: &SurfaceOfRevolution,
    path: &TurningPath,
    tool: &ArcNoseTool,
) -> Result<(), JobError> {
    let steps = 4000;
    let half_span_deg = tool.half_span_rad().to_degrees();
    let (inner, outer) = match path {
        TurningPath::Spiral(spiral) => (spiral.end_radius_mm, spiral.start_radius_mm),
        TurningPath::Nc(nc) => (0.0, nc.outer_contact_radius_mm),
    };
    // The widest angle from the tip the edge must cut at, and where.
    let mut widest = (0.0f64, 0.0f64);
    for i in 0..=steps {
        let r = inner + (outer - inner) * i as f64 / steps as f64;
        let curvature = surface.meridional_curvature(r);
        if curvature > 0.0 && tool.nose_radius_mm >= 1.0 / curvature {
            return Err(error(
                "tool.nose_radius_mm",
                format!(
                    "{} mm does not fit the concave surface: its radius of curvature is {:.4} mm at r = {r:.4} mm; allowed: < {:.4} mm",
                    tool.nose_radius_mm,
                    1.0 / curvature,
                    1.0 / curvature
                ),
            ));
        }
        if !usable_at(surface, r) {
            return Err(error(
                "process.start_radius_mm",
                format!(
                    "the path reaches r = {r:.4} mm, where the surface is undefined or steeper than {MAX_SLOPE_DEG}°"
                ),
            ));
        }
        let cusp_angle_deg = (pass_spacing(surface, path, r) / (2.0 * tool.nose_radius_mm))
            .min(1.0)
            .asin()
            .to_degrees();
        let needed_deg = match path.mode() {
            TurningMode::Xz => surface.normal_angle(r).to_degrees().abs() + cusp_angle_deg,
            TurningMode::Xzb => cusp_angle_deg,
        };
        if needed_deg > widest.0 {
            widest = (needed_deg, r);
        }
    }
    let (needed_deg, at_radius) = widest;
    if needed_deg > half_span_deg {
        let hint = if path.mode() == TurningMode::Xz {
            " or mode = \"xzb\""
        } else {
            ""
        };
        return Err(error(
            "tool.included_angle_deg",
            format!(
                "{}° is too narrow: at r = {at_radius:.4} mm the edge must reach {needed_deg:.2}° from its tip (surface slope plus the angle to the neighbouring pass); allowed: included_angle_deg ≥ {:.2}{hint}",
                tool.included_angle_deg,
                2.0 * needed_deg
            ),
        ));
    }
    Ok(())
}

/// Refuses absurd path lengths (a feed far too fine for the part).
pub fn check_revolutions(path: &TurningPath, meridian: &MeridianArcLength) -> Result<(), JobError> {
    const MAX_REVOLUTIONS: f64 = 2.0e6;
    let TurningPath::Spiral(spiral) = path else {
        return Ok(());
    };
    let revolutions = spiral.revolutions(meridian);
    if revolutions > MAX_REVOLUTIONS {
        return Err(error(
            "process.feed_per_rev_mm",
            format!(
                "{} mm makes the spiral {revolutions:.3e} revolutions long; allowed: at most {MAX_REVOLUTIONS:.0e} (raise the feed)",
                spiral.feed_per_rev_mm
            ),
        ));
    }
    Ok(())
}

//! The `[surface]` table: the nominal surface and the aperture that is simulated.

use super::{Aperture, CylinderSpec, JobError, SphereSpec, SurfaceSpec, check, error};
use crate::geometry::surface::EVEN_TERMS;
use crate::geometry::{Form, SurfaceOfRevolution};

/// Steepest surface slope accepted (deg): beyond it a normal-dexel grid stops making sense.
pub const MAX_SLOPE_DEG: f64 = 89.0;

/// The aperture: inner and outer radius, the outer one given or `default_outer_mm`.
pub fn aperture(spec: &SurfaceSpec, default_outer_mm: Option<f64>) -> Result<Aperture, JobError> {
    let (given_outer, given_inner) = spec.aperture_diameters_mm();
    let outer = match (given_outer, default_outer_mm) {
        (Some(diameter), _) => {
            check("surface.aperture_diameter_mm", diameter, 0.0, 1e4, false)? / 2.0
        }
        (None, Some(outer)) => outer,
        (None, None) => {
            return Err(error(
                "surface.aperture_diameter_mm",
                "missing; allowed: a finite number > 0",
            ));
        }
    };
    let inner = check("surface.inner_diameter_mm", given_inner, 0.0, 1e4, true)?;
    if inner >= 2.0 * outer {
        return Err(error(
            "surface.inner_diameter_mm",
            format!(
                "{inner} must be smaller than aperture_diameter_mm = {}",
                2.0 * outer
            ),
        ));
    }
    Ok(Aperture {
        inner_radius_mm: inner / 2.0,
        outer_radius_mm: outer,
    })
}

/// A designed surface (plane, sphere, asphere, cylinder) and its aperture.
pub fn validate(spec: &SurfaceSpec) -> Result<(SurfaceOfRevolution, Aperture), JobError> {
    if let SurfaceSpec::FromPath(_) = spec {
        return Err(error(
            "surface.kind",
            "\"from_path\" needs process.nc_program: the path defines the surface",
        ));
    }
    let aperture = aperture(spec, None)?;
    let surface = match spec {
        SurfaceSpec::Plane(_) | SurfaceSpec::FromPath(_) => SurfaceOfRevolution::plane(),
        SurfaceSpec::Sphere(SphereSpec {
            form, radius_mm, ..
        })
        | SurfaceSpec::Cylinder(CylinderSpec {
            form, radius_mm, ..
        }) => {
            let radius = radius_mm.ok_or_else(|| {
                error("surface.radius_mm", "missing; allowed: a finite number > 0")
            })?;
            let radius = check("surface.radius_mm", radius, 0.0, 1e7, false)?;
            SurfaceOfRevolution::sphere(radius, required_form(*form)?)
        }
        SurfaceSpec::Asphere(spec) => {
            let base = spec.base_radius_mm.ok_or_else(|| {
                error(
                    "surface.base_radius_mm",
                    "missing; allowed: a finite number > 0",
                )
            })?;
            let base = check("surface.base_radius_mm", base, 0.0, 1e7, false)?;
            let conic = check("surface.conic", spec.conic.unwrap_or(0.0), -1e6, 1e6, true)?;
            let mut coefficients = [0.0; EVEN_TERMS];
            for (slot, (name, value)) in coefficients.iter_mut().zip(spec.even_coefficients()) {
                if let Some(value) = value {
                    *slot = check(&format!("surface.{name}"), value, -1e6, 1e6, true)?;
                }
            }
            SurfaceOfRevolution::asphere(base, conic, coefficients, required_form(spec.form)?)
        }
    };
    check_defined(&surface, &aperture)?;
    Ok((surface, aperture))
}

fn required_form(form: Option<Form>) -> Result<Form, JobError> {
    form.ok_or_else(|| {
        error(
            "surface.form",
            "missing; allowed: \"convex\" or \"concave\"",
        )
    })
}

/// The sag must exist and the slope stay below MAX_SLOPE_DEG over the aperture.
pub fn check_defined(surface: &SurfaceOfRevolution, aperture: &Aperture) -> Result<(), JobError> {
    let outer = aperture.outer_radius_mm;
    let limit = surface.sag_limit_radius_mm();
    if outer >= limit {
        return Err(error(
            "surface.aperture_diameter_mm",
            format!(
                "{}: the sag is undefined beyond r = {limit:.4} mm (1 − (1+k)c²r² ≤ 0 for base radius and conic given); allowed: aperture_diameter_mm < {:.4}",
                2.0 * outer,
                2.0 * limit
            ),
        ));
    }
    if let Some(r) = usable_over(surface, aperture.inner_radius_mm, outer, 4000) {
        return Err(error(
            "surface.aperture_diameter_mm",
            format!(
                "the surface slope reaches {:.2}° at r = {r:.4} mm; allowed: at most {MAX_SLOPE_DEG}° inside the aperture",
                surface.normal_angle(r).to_degrees().abs()
            ),
        ));
    }
    Ok(())
}

/// Whether a path may use the surface at radius r: sag defined, slope ≤ MAX_SLOPE_DEG.
pub fn usable_at(surface: &SurfaceOfRevolution, r: f64) -> bool {
    let angle = surface.normal_angle(r).to_degrees().abs();
    surface.conic_root_argument(r) > 0.0 && surface.height(r).is_finite() && angle <= MAX_SLOPE_DEG
}

/// The first of `steps + 1` evenly spaced radii over [a, b] where `usable_at` fails.
pub fn usable_over(surface: &SurfaceOfRevolution, a: f64, b: f64, steps: usize) -> Option<f64> {
    (0..=steps)
        .map(|i| a + (b - a) * i as f64 / steps as f64)
        .find(|&r| !usable_at(surface, r))
}

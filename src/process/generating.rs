//! Lens generating (seed 000): the workpiece turns slowly about Z while a cup wheel,
//! its axis inclined by α to Z, spins fast and is plunged until its cutting circle
//! passes through the part's axis; the wheel then dwells there (spark-out) while the
//! part turns. Everything here is in the machine frame: Z the workpiece axis, the
//! wheel's axis in the XZ plane leaning toward +X, the part's vertex at the origin.
//!
//! Placement. With s = +1 for a concave part and −1 for a convex one, the circle passes
//! through V = (0, 0, r) (r the edge radius, so the edge's tube touches the vertex) and
//! its centre sits at V + R_t (cos α, 0, s sin α) with axis a = (sin α, 0, −s cos α):
//! the axis then meets Z at C = (0, 0, s R), R = R_t / sin α + s r, and every point of
//! the circle is R_t / sin α from C (see `geometry::cup_wheel`).
//!
//! Only the spark-out is simulated: the infeed before it ends with the wheel at the
//! final depth and every cut of the infeed lies above the final position's by the
//! plunge still to go, so with at least one spark-out revolution the last revolutions
//! alone decide the surface (up to a sliver of the last infeed revolution that can trim
//! tooth-mark cusps shallower than the plunge per revolution times its fraction).

use crate::geometry::Form;
use crate::geometry::cup_wheel::{CupWheel, CuttingCircle, generated_sphere_radius};
use crate::process::effects::GeneratingEffects;
use glam::DVec3;
use std::f64::consts::TAU;

/// The direction the wheel is fed into the part (and so the direction of a plunge error).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlungeAxis {
    /// Vertically, along the workpiece axis.
    Z,
    /// Along the wheel's own axis.
    ToolAxis,
}

#[derive(Debug, Clone, PartialEq)]
pub struct GeneratingSetup {
    pub wheel: CupWheel,
    /// Concave or convex part.
    pub form: Form,
    /// Angle between the wheel axis and the workpiece axis, in (0, π/2).
    pub inclination_rad: f64,
    pub plunge_axis: PlungeAxis,
    /// Wheel speed (rev/min; the sign gives the sense about the wheel axis).
    pub tool_rpm: f64,
    /// Workpiece speed (rev/min, counter-clockwise seen from +Z).
    pub workpiece_rpm: f64,
    /// Workpiece revolutions at the final depth.
    pub spark_out_revolutions: f64,
    /// Angle of tooth 0 from the circle's reference point when the spark-out starts.
    pub tooth_phase_rad: f64,
    /// Material above the nominal surface before the cut.
    pub stock_allowance_mm: f64,
    /// A deliberate X offset of the wheel from the position that puts its circle
    /// through the axis (+ = away from the axis): how a correction moves it.
    pub cutter_offset_mm: f64,
}

impl GeneratingSetup {
    /// ±1: +1 for a concave part, −1 for a convex one.
    pub fn form_sign(&self) -> f64 {
        match self.form {
            Form::Concave => 1.0,
            Form::Convex => -1.0,
        }
    }

    /// The sphere radius the nominal setup generates.
    pub fn generated_radius_mm(&self) -> f64 {
        generated_sphere_radius(
            &self.wheel,
            self.inclination_rad,
            self.form == Form::Concave,
        )
    }

    /// Wheel revolutions per workpiece revolution (signed).
    pub fn speed_ratio(&self) -> f64 {
        self.tool_rpm / self.workpiece_rpm
    }

    /// Length of the spark-out as workpiece rotation (rad).
    pub fn spark_out_rad(&self) -> f64 {
        TAU * self.spark_out_revolutions
    }

    /// Spark-out time (s).
    pub fn spark_out_s(&self) -> f64 {
        self.spark_out_revolutions / self.workpiece_rpm * 60.0
    }

    /// The cutting circle where the machine actually puts it: the nominal placement
    /// with the inclination error (pivoting about the vertex point V, so alone it only
    /// changes the radius), the displacement along X (+ = short of the axis) and the
    /// plunge error (+ = stopped short, along the plunge axis) applied.
    pub fn cutting_circle(&self, effects: &GeneratingEffects) -> CuttingCircle {
        let s = self.form_sign();
        let alpha = self.inclination_rad + effects.inclination_error_rad;
        let (sin, cos) = alpha.sin_cos();
        let radius = self.wheel.cutting_radius_mm;
        let vertex_point = DVec3::new(0.0, 0.0, self.wheel.edge_radius_mm);
        let axis = DVec3::new(sin, 0.0, -s * cos);
        // The wheel's rim points into the part along s·a (down in both forms).
        let into_part = s * axis;
        let plunge_direction = match self.plunge_axis {
            PlungeAxis::Z => DVec3::new(0.0, 0.0, -1.0),
            PlungeAxis::ToolAxis => into_part,
        };
        let shift = DVec3::new(
            self.cutter_offset_mm + effects.cutter_displacement_mm,
            0.0,
            0.0,
        ) - effects.plunge_error_mm * plunge_direction;
        CuttingCircle {
            centre: vertex_point + radius * DVec3::new(cos, 0.0, s * sin) + shift,
            axis,
            radius_mm: radius,
            reference: DVec3::new(-cos, 0.0, -s * sin),
        }
    }

    /// Largest part radius the wheel reaches: the far point of the circle (θ = π)
    /// projected onto the generated sphere from its centre.
    pub fn reach_radius_mm(&self) -> f64 {
        let shell = self.wheel.cutting_radius_mm / self.inclination_rad.sin();
        2.0 * self.wheel.cutting_radius_mm * self.inclination_rad.cos() * self.generated_radius_mm()
            / shell
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup(form: Form) -> GeneratingSetup {
        GeneratingSetup {
            wheel: CupWheel {
                cutting_radius_mm: 3.5,
                edge_radius_mm: 0.5,
                teeth: 0,
            },
            form,
            inclination_rad: 4f64.to_radians(),
            plunge_axis: PlungeAxis::ToolAxis,
            tool_rpm: 3000.0,
            workpiece_rpm: 10.0,
            spark_out_revolutions: 1.0,
            tooth_phase_rad: 0.0,
            stock_allowance_mm: 0.002,
            cutter_offset_mm: 0.0,
        }
    }

    #[test]
    fn the_nominal_circle_passes_r_above_the_vertex_and_lies_on_the_shell() {
        for form in [Form::Concave, Form::Convex] {
            let setup = setup(form);
            let circle = setup.cutting_circle(&GeneratingEffects::default());
            let r = setup.wheel.edge_radius_mm;
            assert!((circle.point(0.0) - DVec3::new(0.0, 0.0, r)).length() < 1e-15);
            let s = setup.form_sign();
            let centre = DVec3::new(0.0, 0.0, s * setup.generated_radius_mm());
            let shell = setup.generated_radius_mm() - s * r;
            for i in 0..12 {
                let p = circle.point(i as f64 * 0.5);
                assert!(((p - centre).length() - shell).abs() < 1e-12, "{form:?}");
            }
        }
    }

    #[test]
    fn a_plunge_error_along_the_tool_axis_moves_the_circle_off_the_axis() {
        let setup = setup(Form::Concave);
        let effects = GeneratingEffects {
            plunge_error_mm: 0.01,
            ..Default::default()
        };
        let circle = setup.cutting_circle(&effects);
        let at_vertex = circle.point(0.0);
        // Stopped short along a = (sin α, 0, −cos α): back by 0.01 mm along −a.
        assert!((at_vertex.x + 0.01 * setup.inclination_rad.sin()).abs() < 1e-15);
        assert!((at_vertex.z - 0.5 - 0.01 * setup.inclination_rad.cos()).abs() < 1e-15);
    }
}

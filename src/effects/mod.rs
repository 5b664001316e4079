//! Effects: the named, parameterised departures from the nominal process that make a
//! real part differ from its design (DESIGN §3). Each can be injected into a job and
//! (later) fitted as a diagnosis candidate.
//!
//! Turning:
//!
//! | effect | parameter | what it does in the model |
//! | --- | --- | --- |
//! | centre height | h (+ = above centre) | the edge lies in the plane y = −h instead of through the axis: no edge point reaches r < \|h\|; above centre the flank straddles the axis and trims the pip to a cone of slope tan(clearance), below centre it stays a cylinder |
//! | X decentre | δ (+ = stops short of the axis) | every nose-centre X is δ larger than programmed |
//! | nose-radius error | e | the real edge radius is R + e, the tool set at its tip |
//! | edge waviness | w(ψ) harmonics or a measured edge | the edge radius varies along the edge, ψ from the tip |
//!
//! Generating (cup wheel, seed 000):
//!
//! | effect | parameter | what it does in the model |
//! | --- | --- | --- |
//! | cutter displacement | e (+ = the circle stops short of the axis) | the cutting circle shifts by e along X: it misses the axis by \|e\| either way, leaving an uncut pip of radius \|e\|, and changes the generated radius (first order in e) |
//! | inclination error | Δα | the wheel pivots about the point where its circle crosses the axis: the generated radius becomes R_t / sin(α + Δα) ± r, no pip |
//! | plunge error | Δp (+ = stopped short) | the wheel stops Δp short along the plunge axis: along Z a piston; along the tool axis also a displacement of −Δp·sin α (a pip) |
//!
//! The engines never see effect names, only their consequences: a shifted pose table,
//! an edge plane offset and an `EdgeModel`.

use crate::geometry::tool::{AngleTable, ArcNoseTool, EdgeModel};
use crate::process::PoseTable;

/// Samples of a harmonic waviness table over ψ ∈ [−90°, 90°] (0.045° apart).
pub const WAVINESS_SAMPLES: usize = 4001;

#[derive(Debug, Clone, PartialEq, Default)]
pub struct TurningEffects {
    /// Tool centre height error (mm), + = above centre (edge displaced toward the
    /// material arriving at the tool, against the cutting velocity).
    pub centre_height_mm: f64,
    /// X decentre (mm), + = the nose centre sits further out than programmed.
    pub x_decentre_mm: f64,
    /// Actual minus nominal nose radius (mm).
    pub radius_error_mm: f64,
    /// Radial deviation of the edge from its own circle, w(ψ) (mm).
    pub edge_deviation: AngleTable,
    /// Z drift of the tool over the cut (mm) — placeholder until the effects branch lands.
    pub axial_drift_mm: f64,
}

impl TurningEffects {
    pub fn is_none(&self) -> bool {
        self.centre_height_mm == 0.0
            && self.x_decentre_mm == 0.0
            && self.radius_error_mm == 0.0
            && self.edge_deviation.is_zero()
    }

    /// The edge as cut by a tool with these effects.
    pub fn edge_model(&self, tool: &ArcNoseTool) -> EdgeModel {
        EdgeModel {
            radius_error_mm: self.radius_error_mm,
            deviation: self.edge_deviation.clone(),
            ..EdgeModel::ideal(tool)
        }
    }

    /// The machine Y of the edge plane: above centre moves it to −y, toward the
    /// material that the spindle (turning +C, counter-clockwise seen from +Z) brings in.
    pub fn edge_plane_y_mm(&self) -> f64 {
        -self.centre_height_mm
    }

    /// The pose table the machine actually runs.
    pub fn apply_to_poses(&self, poses: &mut PoseTable) {
        if self.x_decentre_mm != 0.0 {
            for pose in &mut poses.poses {
                pose.x_mm += self.x_decentre_mm;
            }
        }
    }

    /// How much further than nominal any part of the tool can reach (for reach tests).
    pub fn extra_reach_mm(&self, edge: &EdgeModel) -> f64 {
        self.x_decentre_mm.abs() + self.centre_height_mm.abs() + edge.max_excess_mm()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GeneratingEffects {
    /// Shift of the cutting circle along X (mm), + = away from the axis (short of it).
    pub cutter_displacement_mm: f64,
    /// Actual minus set inclination (rad), pivoting about the circle's axis crossing.
    pub inclination_error_rad: f64,
    /// Distance the wheel stops short of its final depth along the plunge axis (mm).
    pub plunge_error_mm: f64,
}

impl GeneratingEffects {
    pub fn is_none(&self) -> bool {
        *self == GeneratingEffects::default()
    }
}

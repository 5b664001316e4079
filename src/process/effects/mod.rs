//! Effects: the named, parameterised departures from the nominal process that make a
//! real part differ from its design (DESIGN §3). Each can be injected into a job and
//! (later) fitted as a diagnosis candidate, so each is a smooth function of its
//! parameters and exactly nothing at zero.
//!
//! Turning:
//!
//! | effect | parameter | what it does in the model |
//! | --- | --- | --- |
//! | centre height | h (+ = above centre) | the edge lies in the plane y = −h instead of through the axis: no edge point reaches r < \|h\|; above centre the flank straddles the axis and trims the pip to a cone of slope tan(clearance) falling from the real edge (an edge deviation included), below centre it stays a cylinder |
//! | X decentre | δ (+ = stops short of the axis) | every nose-centre X is δ larger than programmed |
//! | nose-radius error | e | the real edge radius is R + e, the tool set at its tip |
//! | edge waviness | w(ψ) harmonics or a measured edge | the edge radius varies along the edge, ψ from the tip |
//! | axial drift | d (+ = toward +Z, away from the part) | every pose's Z shifted by d·C/C_total: C the spindle angle turned since the first pose of the first pass, C_total over all passes in program order (thermal growth linear in machining time) |
//! | vibration | a, k cycles/rev (or f Hz = k·rpm/60), φ, feed or depth | every pose moved along X (feed) or Z (depth, + away from the part) by a·cos(2πk·n + φ), n the revolutions turned since the first pose; whole k: lobes fixed on the part, else spiral ribbons (`motion.rs`) |
//! | spindle axial error motion | harmonics (order k, a, φ) | the part moves toward the tool by Σ a·cos(kC + φ), C the spindle angle: every pose's Z lowered by it |
//! | spindle tilt error motion | harmonics (order k, θ, φ) | the face turns about machine Y through the spindle origin, rising toward the tool at +X: a pose at nose-centre X (as run) cuts X·Σ θ·cos(kC + φ) deeper |
//! | tool wear | w at the end of the cut | the edge recedes by w·L/L_total, L the cut length ∫\|x\| dC so far: the nose centre moves that far along its path's normal, away from the part (for an arc edge the same as the radius shrinking by it) |
//! | spring-back / minimum chip | h_min, ρ (0 < ρ ≤ 1) | per sample, the passes act in machining order from the stock top: one whose edge reaches depth d below the current height h cuts to d when the chip h − d ≥ h_min, and otherwise ploughs, the material springing back to d + ρ·(h − d) (heights along the sample's ray); raises and rounds the cusps, leaves their spacing |
//!
//! Generating (cup wheel, seed 000):
//!
//! | effect | parameter | what it does in the model |
//! | --- | --- | --- |
//! | cutter displacement | e (+ = the circle stops short of the axis) | the cutting circle shifts by e along X: it misses the axis by \|e\| either way, leaving an uncut pip of radius \|e\|, and changes the generated radius (first order in e) |
//! | inclination error | Δα | the wheel pivots about the point where its circle crosses the axis: the generated radius becomes R_t / sin(α + Δα) ± r, no pip |
//! | plunge error | Δp (+ = stopped short) | the wheel stops Δp short along the plunge axis: along Z a piston; along the tool axis also a displacement of −Δp·sin α (a pip) |
//!
//! Milling (end mills and disc cutters; the path is planned with the nominal tool):
//!
//! | effect | parameter | what it does in the model |
//! | --- | --- | --- |
//! | axial drift | d (+ = toward +Z, away from the part) | every path node's pose centre shifted along machine Z by d·s/s_total: s the path arc length from its start (machining time at constant feed) |
//! | tool radius error | e (ball and bull-nose only, \|e\| < r/2) | the ball / corner radius is r + e, the tool's length set at its tip: every pose centre moves e along the tool axis, the tip stays |
//! | spindle tram | τx, τy (≤ 1° each; bull-nose and flat end only) | the tool axis turned by one fixed rotation about each pose centre (the corner circle's centre, a flat end's face middle): the rotation taking +Z to (tan τx, tan τy, 1)/‖·‖, i.e. leaning toward +X by τx and toward +Y by τy |
//! | radial runout | ε, φ (\|ε\| ≤ f_z/2, 2+ teeth, f_z > 0) | stamp k (at arc k·f_z from the path start) is cut by tooth k mod z, whose sweep is displaced by ε·u_k: u_k ⟂ the tool axis at φ + 2πk/z from the feed direction, turning right-handed about the axis |
//!
//! Tram and radius error together: the axis is turned first, then the centre moved
//! along the turned axis (the real tool, set at its tip). Path arc lengths stay those of
//! the planned path (the machine's time parameter): drift and stamps count along it.
//!
//! The engines never see effect names, only their consequences: a shifted pose table,
//! an edge plane offset and an `EdgeModel` (turning); a moved cutting circle
//! (generating); a transformed path, a changed tool and displaced tooth sweeps (milling).

use crate::geometry::cutter::Cutter;
use crate::geometry::milling_tool::MillingTool;
use crate::geometry::tool::{AngleTable, ArcNoseTool, EdgeModel};
use crate::process::PoseTable;
use crate::process::milling::{MillingPath, MillingSetup};
use glam::{DQuat, DVec2, DVec3};
use std::f64::consts::TAU;

mod motion;
pub use motion::{
    MAX_CYCLES_PER_REV, SpindleHarmonic, Vibration, VibrationDirection, max_abs_x_mm,
};

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
    /// Tool drift along machine Z over the cut (mm), + = toward +Z (away from the part):
    /// 0 at the first pose, this at the last, linear in the spindle angle turned.
    pub axial_drift_mm: f64,
    /// Relative tool–workpiece vibrations (each term adds).
    pub vibrations: Vec<Vibration>,
    /// Spindle axial error motion (amplitudes in mm, + = the part toward the tool).
    pub axial_error_motion: Vec<SpindleHarmonic>,
    /// Spindle tilt error motion (amplitudes in rad, + = the face rising toward the
    /// tool at +X).
    pub tilt_error_motion: Vec<SpindleHarmonic>,
    /// Edge recession by wear at the end of the cut (mm), linear in cut length.
    pub wear_recession_mm: f64,
    /// Minimum chip thickness h_min (mm): a thinner chip ploughs instead of cutting
    /// (0 = no spring-back).
    pub spring_back_min_chip_mm: f64,
    /// Fraction ρ of a ploughed chip the material recovers (0 = no spring-back).
    pub spring_back_recovery: f64,
}

impl TurningEffects {
    pub fn is_none(&self) -> bool {
        self.centre_height_mm == 0.0
            && self.x_decentre_mm == 0.0
            && self.radius_error_mm == 0.0
            && self.edge_deviation.is_zero()
            && self.axial_drift_mm == 0.0
            && !self.has_motion()
            && self.spring_back_min_chip_mm == 0.0
            && self.spring_back_recovery == 0.0
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

    /// The pose tables the machine actually runs, one per cutting pass in program
    /// order: X shifted by the decentre, Z by the drift so far, then the moving effects
    /// (`motion.rs`; the tables refined first where they need more nodes). Machining
    /// time runs with the spindle angle, so the drift at a pose is d·C/C_total, C the
    /// angle turned since the first pose of the first pass and C_total the angle of all
    /// passes together (linear between nodes, as the poses are).
    pub fn apply_to_passes(&self, passes: &mut [PoseTable]) {
        let wear = self.prepare_motions(passes);
        if self.x_decentre_mm != 0.0 {
            for pose in passes.iter_mut().flat_map(|p| p.poses.iter_mut()) {
                pose.x_mm += self.x_decentre_mm;
            }
        }
        self.apply_timed(passes, wear);
    }

    /// How much further than nominal any part of the tool can reach (for reach tests),
    /// on a path reaching out to `max_x_mm` from the axis.
    pub fn extra_reach_mm(&self, edge: &EdgeModel, max_x_mm: f64) -> f64 {
        self.x_decentre_mm.abs()
            + self.centre_height_mm.abs()
            + edge.max_excess_mm()
            + self.axial_drift_mm.abs()
            + self.motion_reach_mm(max_x_mm + self.x_decentre_mm.abs())
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

/// The milling effects (see the module table). Every field 0 = the nominal process.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MillingEffects {
    /// Tool drift along machine Z over the path (mm), + = toward +Z (away from the
    /// part): 0 at the path's start, this at its end, linear in path arc length.
    pub axial_drift_mm: f64,
    /// Actual − nominal ball / corner radius (mm), the tool's length set at its tip.
    pub tool_radius_error_mm: f64,
    /// Spindle tram: the lean of the tool axis toward +X (rad, a rotation about +Y).
    pub tram_x_rad: f64,
    /// Spindle tram: the lean of the tool axis toward +Y (rad).
    pub tram_y_rad: f64,
    /// Radial runout as the displacement of tooth 0's sweep from the axis (mm), in the
    /// frame (feed direction, its right-handed quarter turn about the tool axis): ε·(cos φ,
    /// sin φ). Tooth j's is the same turned by 2πj/z. Runouts given twice add as vectors.
    pub radial_runout_mm: DVec2,
}

impl MillingEffects {
    pub fn is_none(&self) -> bool {
        *self == MillingEffects::default()
    }

    /// The tram's rotation: the one taking +Z to (tan τx, tan τy, 1)/‖·‖ about the axis
    /// square to both (identity without a tram).
    pub fn tram_rotation(&self) -> DQuat {
        let leaned = DVec3::new(self.tram_x_rad.tan(), self.tram_y_rad.tan(), 1.0).normalize();
        DQuat::from_rotation_arc(DVec3::Z, leaned)
    }

    /// The angle between the trammed axis and the spindle's nominal one.
    pub fn tram_angle_rad(&self) -> f64 {
        self.tram_x_rad.tan().hypot(self.tram_y_rad.tan()).atan()
    }

    /// The path the machine runs: each node's pose centre shifted along Z by the drift
    /// so far, its axis turned by the tram about the centre, then its centre moved by the
    /// radius error along the (turned) axis. Arc lengths stay the planned path's.
    pub fn apply_to_path(&self, path: &mut MillingPath) {
        let total = path.length_mm();
        let tram = (self.tram_x_rad != 0.0 || self.tram_y_rad != 0.0).then(|| self.tram_rotation());
        for node in path.passes.iter_mut().flat_map(|p| p.nodes.iter_mut()) {
            if self.axial_drift_mm != 0.0 && total > 0.0 {
                node.translate(DVec3::Z * (self.axial_drift_mm * node.arc_mm / total));
            }
            if let Some(rotation) = tram {
                node.pose.axis = (rotation * node.pose.axis).normalize();
            }
            if self.tool_radius_error_mm != 0.0 {
                node.translate(self.tool_radius_error_mm * node.pose.axis);
            }
        }
    }

    /// The cutting solid: an end mill's corner (or ball) radius r + e.
    pub fn cutting_tool(&self, tool: &MillingTool) -> MillingTool {
        match tool {
            MillingTool::EndMill(cutter) if self.tool_radius_error_mm != 0.0 => {
                MillingTool::EndMill(Cutter::bull_nose(
                    cutter.major_radius_mm,
                    cutter.corner_radius_mm + self.tool_radius_error_mm,
                ))
            }
            _ => *tool,
        }
    }

    /// The tool's profile radius across the passes, which sizes the engine's search for
    /// the poses that can cut a sample: the corner radius r + e; under a tram a flat face
    /// (radius R) leaned by β from the normal curves away as R/sin β, with β down to the
    /// planned lean less the tram (3-axis: the tram itself), infinite where the face can
    /// stand square (the engine then searches the tool's whole size).
    pub fn profile_radius_mm(&self, setup: &MillingSetup) -> f64 {
        let planned = setup.profile_radius_mm();
        let MillingTool::EndMill(cutter) = setup.tool else {
            return planned;
        };
        let profile = if cutter.corner_radius_mm > 0.0 {
            planned + self.tool_radius_error_mm
        } else {
            planned
        };
        let tram = self.tram_angle_rad();
        if tram == 0.0 || cutter.major_radius_mm == 0.0 {
            return profile;
        }
        let lean = if setup.five_axis {
            setup.lead_rad[0].min(setup.lead_rad[1]) - tram
        } else {
            tram
        };
        let face = if lean > 0.0 {
            cutter.major_radius_mm / lean.sin()
        } else {
            f64::INFINITY
        };
        profile.max(face)
    }

    /// The displacement of each tooth's sweep from the tool axis in the frame (feed
    /// direction, its right-handed quarter turn about the axis), tooth j at φ + 2πj/z;
    /// empty without runout.
    pub fn tooth_offsets_mm(&self, teeth: u32) -> Vec<DVec2> {
        if self.radial_runout_mm == DVec2::ZERO {
            return Vec::new();
        }
        (0..teeth)
            .map(|j| DVec2::from_angle(TAU * j as f64 / teeth as f64).rotate(self.radial_runout_mm))
            .collect()
    }

    /// How much further than the nominal cut any pose can reach (widens the engine's
    /// search): the drift, the radius error, a flat face's drop under the tram, the runout.
    pub fn extra_reach_mm(&self, tool: &MillingTool) -> f64 {
        let flat_radius = match tool {
            MillingTool::EndMill(cutter) => cutter.major_radius_mm,
            MillingTool::Disc(_) => 0.0,
        };
        self.axial_drift_mm.abs()
            + self.tool_radius_error_mm.abs()
            + flat_radius * self.tram_angle_rad().sin()
            + self.radial_runout_mm.length()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::process::ToolPose;

    #[test]
    fn drift_grows_with_the_spindle_angle_over_the_passes_in_order() {
        // Two passes of 2 and 1 revolutions (8 nodes per revolution): 3 revolutions in
        // all, so the second pass starts at 2/3 of the drift and ends at all of it.
        let pass = |revolutions: usize| PoseTable {
            start_angle_rad: 1.0,
            steps_per_rev: 8,
            poses: vec![ToolPose::default(); 8 * revolutions + 1],
        };
        let mut passes = vec![pass(2), pass(1)];
        let effects = TurningEffects {
            axial_drift_mm: 0.003,
            ..TurningEffects::default()
        };
        effects.apply_to_passes(&mut passes);
        let z = |p: usize, i: usize| passes[p].poses[i].z_mm;
        assert_eq!(z(0, 0), 0.0);
        assert!((z(0, 8) - 0.001).abs() < 1e-15);
        assert!((z(0, 16) - 0.002).abs() < 1e-15 && (z(1, 0) - 0.002).abs() < 1e-15);
        assert!((z(1, 8) - 0.003).abs() < 1e-15);
    }

    #[test]
    fn the_tram_leans_the_axis_by_its_two_angles_and_the_teeth_turn_right_handed() {
        let effects = MillingEffects {
            tram_x_rad: 0.5f64.to_radians(),
            tram_y_rad: (-0.3f64).to_radians(),
            radial_runout_mm: DVec2::new(0.002, 0.0),
            ..MillingEffects::default()
        };
        let axis = effects.tram_rotation() * DVec3::Z;
        // Seen in the XZ plane the axis leans 0.5° toward +X, in YZ 0.3° toward −Y.
        assert!((axis.x.atan2(axis.z).to_degrees() - 0.5).abs() < 1e-12);
        assert!((axis.y.atan2(axis.z).to_degrees() + 0.3).abs() < 1e-12);
        let tilt = (0.5f64.to_radians().tan())
            .hypot(0.3f64.to_radians().tan())
            .atan();
        assert!((effects.tram_angle_rad() - tilt).abs() < 1e-15);
        assert!((axis.z - tilt.cos()).abs() < 1e-15);
        // Three teeth: tooth 1 a third of a turn on from tooth 0 (along the feed).
        let teeth = effects.tooth_offsets_mm(3);
        let third = TAU / 3.0;
        assert!((teeth[1] - 0.002 * DVec2::new(third.cos(), third.sin())).length() < 1e-15);
        assert!(MillingEffects::default().tooth_offsets_mm(3).is_empty());
    }
}

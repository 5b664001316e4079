//! A turned surface computed from the physics of the cut, written apart from the
//! simulation engine (`engine/scene.rs`, `engine/cpu_turning_scalar.rs`) and the diagnosis's forward
//! model (`diagnose/forward.rs`), so that synthetic data made with it can check both.
//!
//! The surface height at part radius r and azimuth φ is the lowest point any pass of
//! the tool's cutting edge reaches there. The edge lies in the machine plane y = y₀
//! (y₀ = −h for a centre height h, see `TurningEffects::edge_plane_y_mm`); the workpiece
//! turns by the spindle angle C, counter-clockwise seen from +Z, so the part point
//! (r, φ) sits at machine azimuth φ + C and crosses the edge plane twice per
//! revolution when r ≥ |y₀|: at machine x = +q (azimuth α = atan2(y₀, q)) and at
//! x = −q (azimuth π − α), q = √(r² − y₀²). At each crossing C = α − φ + 2πk (or
//! π − α − φ + 2πk) the nose centre is read from the program's pose table (linear in C
//! between nodes, as the controller moves), moved as the machine runs it (`tool_motion.rs`:
//! the X decentre, the Z drift, vibration, spindle axial and tilt error motion, all at
//! that instant), and the edge's height at lateral x is solved for: the edge point at
//! direction (−sin θ, −cos θ) from the real arc centre, at radius
//! ρ(ψ) = R + e + w(ψ) − wear with ψ = θ − B, is the one with x = ±q (a fixed-point
//! iteration on θ when ρ varies). The tool is set at its tip before it cuts, so the real
//! arc centre sits (e + w(0)) behind the programmed one along the tool axis; wear then
//! shrinks the edge about that centre. Samples closer to the axis than |y₀| never meet
//! the edge: below centre (y₀ > 0) they keep the stock; above centre (y₀ < 0) the flank,
//! which lies behind the rake plane and straddles the axis, passes them at machine
//! (0, −r), |y₀| − r behind the edge, standing (|y₀| − r)·tan(clearance) above the
//! edge's height at x = 0 (the flank model `engine/scene.rs` documents). No pass below
//! the stock: the stock top, the nominal surface offset along its normal by the stock
//! allowance.
//!
//! Without spring-back the surface is the lowest cut. With spring-back (minimum chip
//! thickness h_min, recovery ρ) every cut below the stock is kept with its time, and
//! they act in machining order from the stock top: a cut d below the current height h
//! takes a chip c = h − d (along the surface normal: the Z gap times the nominal
//! normal's Z component); c ≥ h_min leaves d, a thinner chip springs back to d + ρ·c.

use super::tool_motion::{CutLength, ToolAt, ToolMotion};
use super::unmodelled::{Unmodelled, notch_depth_mm};
use crate::geometry::SurfaceOfRevolution;
use crate::geometry::tool::AngleTable;
use crate::model::{EffectSpec, Job};
use crate::process::effects::{Vibration, VibrationDirection};
use crate::process::{PoseTable, Process, TurningProcess};
use glam::DVec2;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Revolutions per block of the reach index (blocks whose nose centres stay too far
/// from a sample are skipped whole).
const BLOCK_REVOLUTIONS: f64 = 4.0;
/// Largest change of the edge angle at which the fixed-point iteration stops (rad).
const ANGLE_TOLERANCE_RAD: f64 = 1e-14;
const MAX_ITERATIONS: usize = 60;

/// The machined surface of a turning job, sample by sample.
pub struct TurnedSection {
    passes: Vec<Pass>,
    edge: Edge,
    /// Machine y of the edge's plane (mm).
    plane_y_mm: f64,
    tan_clearance: f64,
    motion: ToolMotion,
    spring_back: Option<SpringBack>,
    /// Cusp pile-up: (height mm, standard deviation mm).
    pileups: Vec<[f64; 2]>,
    surface: SurfaceOfRevolution,
    stock_mm: f64,
    inner_mm: f64,
    outer_mm: f64,
}

struct Pass {
    table: PoseTable,
    /// Spindle angle turned before this pass began, over the passes in program order.
    angle_before_rad: f64,
    /// The cut length along it (when the edge wears).
    length: Option<CutLength>,
    blocks: Vec<Block>,
}

/// A run of spindle angles [from, to) ([from, to] for a pass's last) and the range of
/// nose-centre X over it (decentre and feed vibration included).
struct Block {
    from_rad: f64,
    to_rad: f64,
    last: bool,
    x_min_mm: f64,
    x_max_mm: f64,
}

/// The cutting edge: an arc of radius R + e about its real centre with a radial
/// deviation along its normal, spanning ±half span about the tip.
struct Edge {
    radius_mm: f64,
    half_span_rad: f64,
    deviation: Deviation,
    /// Notches: (depth mm, edge angle rad, full width rad).
    chips: Vec<[f64; 3]>,
    /// How far the real centre sits behind the programmed one along the tool axis.
    tip_offset_mm: f64,
    /// Largest distance of an edge point from the real centre, worn or not (mm).
    reach_mm: f64,
}

/// The edge's radial deviation w(ψ).
enum Deviation {
    None,
    /// Σ A cos(nψ + φ): (n, A mm, φ rad), evaluated exactly.
    Harmonics(Vec<[f64; 3]>),
    /// A measured (or otherwise tabulated) deviation.
    Table(AngleTable),
}

impl Deviation {
    fn at(&self, psi_rad: f64) -> f64 {
        match self {
            Deviation::None => 0.0,
            Deviation::Harmonics(list) => list
                .iter()
                .map(|[n, a, phase]| a * (n * psi_rad + phase).cos())
                .sum(),
            Deviation::Table(table) => table.at(psi_rad),
        }
    }

    fn max_abs_mm(&self) -> f64 {
        match self {
            Deviation::None => 0.0,
            Deviation::Harmonics(list) => list.iter().map(|h| h[1].abs()).sum(),
            Deviation::Table(table) => table.max_abs_mm(),
        }
    }
}

impl TurnedSection {
    /// The section model of a turning job (its effects are the truth) with the
    /// `unmodelled` effects added.
    pub fn new(job: &Job, unmodelled: &[Unmodelled]) -> Result<Self, String> {
        let Process::Turning(turning) = &job.process else {
            return Err("the section model is for turning jobs".into());
        };
        let effects = &turning.effects;
        let spring_back = SpringBack::of(
            effects.spring_back_min_chip_mm,
            effects.spring_back_recovery,
        )?;
        let tables = program_passes(job, turning);
        let mut chips = Vec::new();
        let (mut chatter, mut pileups) = (Vec::new(), Vec::new());
        for effect in unmodelled {
            match *effect {
                Unmodelled::CuspPileup {
                    height_nm,
                    width_um,
                } => pileups.push([height_nm * 1e-6, width_um * 1e-3]),
                Unmodelled::Chatter {
                    amplitude_nm,
                    per_revolution,
                    phase_deg,
                } => chatter.push(Vibration {
                    amplitude_mm: amplitude_nm * 1e-6,
                    cycles_per_rev: per_revolution,
                    phase_rad: phase_deg.to_radians(),
                    direction: VibrationDirection::Depth,
                }),
                Unmodelled::EdgeChip {
                    depth_nm,
                    at_deg,
                    width_deg,
                } => chips.push([depth_nm * 1e-6, at_deg.to_radians(), width_deg.to_radians()]),
            }
        }
        let motion = ToolMotion::new(effects, &chatter, &tables);
        let deviation = deviation_of(job, &effects.edge_deviation);
        let radius_mm = turning.tool.nose_radius_mm + effects.radius_error_mm;
        let edge = Edge {
            radius_mm,
            half_span_rad: turning.tool.half_span_rad(),
            tip_offset_mm: effects.radius_error_mm + deviation.at(0.0),
            reach_mm: radius_mm + deviation.max_abs_mm() + motion.max_recession_mm() + 1e-6,
            deviation,
            chips,
        };
        Ok(Self {
            passes: passes_of(tables, &motion),
            edge,
            plane_y_mm: effects.edge_plane_y_mm(),
            tan_clearance: turning.tool.clearance_angle_deg.to_radians().tan(),
            motion,
            spring_back,
            pileups,
            surface: job.surface.clone(),
            stock_mm: turning.path.stock_allowance_mm(),
            inner_mm: job.aperture.inner_radius_mm,
            outer_mm: job.aperture.outer_radius_mm,
        })
    }

    /// The machined surface's height along Z at part point `p` (mm; azimuth 0 along +X
    /// of the part as programmed); NaN off the part.
    pub fn height_at(&self, p: DVec2) -> f64 {
        self.height(p.length(), p.y.atan2(p.x))
    }

    /// The machined surface's height along Z at part radius `r_mm` and azimuth
    /// `azimuth_rad` (mm); NaN off the part.
    pub fn height(&self, r_mm: f64, azimuth_rad: f64) -> f64 {
        if !(r_mm >= self.inner_mm - 1e-12 && r_mm <= self.outer_mm + 1e-12) {
            return f64::NAN;
        }
        let stock = self.stock_top(r_mm);
        // Cuts at or above the stock change nothing; with pile-ups the next-lowest cut
        // matters too, with spring-back every cut.
        let keep = match (&self.spring_back, self.pileups.is_empty()) {
            (Some(_), _) => usize::MAX,
            (None, false) => 2,
            (None, true) => 1,
        };
        let mut cuts = Cuts::below(stock, keep);
        let y0 = self.plane_y_mm;
        let mut radial_per_lateral = None;
        if y0 == 0.0 || r_mm > y0.abs() {
            let q = ((r_mm - y0.abs()) * (r_mm + y0.abs())).sqrt();
            radial_per_lateral = Some(if r_mm > 0.0 { q / r_mm } else { 1.0 });
            let alpha = y0.atan2(q);
            self.cuts(q, alpha - azimuth_rad, 0.0, &mut cuts);
            // Beyond the axis, the edge's far side (its x < 0 part); one crossing when
            // the edge plane is tangent to the ring.
            if q > 0.0 || y0 == 0.0 {
                self.cuts(-q, PI - alpha - azimuth_rad, 0.0, &mut cuts);
            }
        } else if y0 < 0.0 {
            let rise = (y0.abs() - r_mm) * self.tan_clearance;
            self.cuts(0.0, -FRAC_PI_2 - azimuth_rad, rise, &mut cuts);
        }
        let Some(first) = cuts.list.first() else {
            return stock;
        };
        let cut = match &self.spring_back {
            Some(spring_back) => spring_back.after(stock, &cuts.list, self.surface.normal(r_mm).y),
            None => first.z_mm,
        };
        // Cusps are where two passes of the edge meet (not on the flank).
        let pileup = match (cuts.list.get(1), radial_per_lateral) {
            (Some(second), Some(factor)) => self.pileup(first, second, factor),
            _ => 0.0,
        };
        cut + pileup
    }

    /// Adds to `cuts` the cut of every crossing of the part point with the edge plane
    /// at machine x = `lateral_mm` (raised by `rise_mm`: the flank), the crossings lying
    /// at spindle angles C ≡ `base_rad` (mod 2π). Blocks whose nose centres pass over
    /// the point go first, so that the bound below skips most of the rest.
    fn cuts(&self, lateral_mm: f64, base_rad: f64, rise_mm: f64, cuts: &mut Cuts) {
        let reach = self.edge.reach_mm;
        let over = |b: &Block| lateral_mm >= b.x_min_mm && lateral_mm <= b.x_max_mm;
        let near = |b: &Block| lateral_mm >= b.x_min_mm - reach && lateral_mm <= b.x_max_mm + reach;
        for first_sweep in [true, false] {
            for pass in &self.passes {
                let blocks = pass.blocks.iter().filter(|b| {
                    if first_sweep {
                        over(b)
                    } else {
                        near(b) && !over(b)
                    }
                });
                for block in blocks {
                    self.block_cuts(pass, block, lateral_mm, base_rad, rise_mm, cuts);
                }
            }
        }
    }

    fn block_cuts(
        &self,
        pass: &Pass,
        block: &Block,
        lateral_mm: f64,
        base_rad: f64,
        rise_mm: f64,
        cuts: &mut Cuts,
    ) {
        let first = ((block.from_rad - base_rad) / TAU).ceil() as i64;
        let end = (block.to_rad - base_rad) / TAU;
        let last = if block.last {
            end.floor() as i64
        } else {
            end.ceil() as i64 - 1
        };
        for k in first..=last {
            let Some(tool) = self.tool_at(pass, base_rad + TAU * k as f64) else {
                continue;
            };
            if self.edge.lowest_bound(lateral_mm, &tool) + rise_mm >= cuts.threshold() {
                continue;
            }
            if let Some((z, slope)) = self.edge.lowest_at(lateral_mm, &tool) {
                cuts.add(Cut {
                    z_mm: z + rise_mm,
                    slope,
                    turned_rad: tool.turned_rad,
                });
            }
        }
    }

    /// The tool at spindle angle `c_rad` of `pass` as the machine runs it (the
    /// program's pose moved by `tool_motion`), with its edge's wear then.
    fn tool_at(&self, pass: &Pass, c_rad: f64) -> Option<ToolAt> {
        let programmed = pass.table.pose_at(c_rad)?;
        let turned = pass.angle_before_rad + (c_rad - pass.table.start_angle_rad);
        let length = pass
            .length
            .as_ref()
            .map_or(0.0, |l| l.at(&pass.table, c_rad));
        Some(self.motion.at(programmed, c_rad, turned, length))
    }

    /// Cusp pile-up at a point whose lowest and next-lowest cuts are `first` and
    /// `second`: the distance to their cusp, where the two edges meet, is the height gap
    /// over the slope gap (exact for equal parabolic arcs), taken along the radius
    /// (`radial_per_lateral` = dr/dq = q/r).
    fn pileup(&self, first: &Cut, second: &Cut, radial_per_lateral: f64) -> f64 {
        let gap = (second.slope - first.slope).abs();
        if self.pileups.is_empty() || gap < 1e-12 {
            return 0.0;
        }
        let distance = (second.z_mm - first.z_mm) / gap * radial_per_lateral;
        self.pileups
            .iter()
            .map(|[height, sigma]| height * (-0.5 * (distance / sigma).powi(2)).exp())
            .sum()
    }

    /// The stock's top at radius `r_mm`: the nominal surface offset along its normal by
    /// the stock allowance (the point of the offset surface above r, found by moving
    /// the foot until foot + s·n lands on r).
    fn stock_top(&self, r_mm: f64) -> f64 {
        let s = self.stock_mm;
        let mut foot = r_mm;
        for _ in 0..4 {
            foot = r_mm - s * self.surface.normal(foot.max(0.0)).x;
        }
        let foot = foot.max(0.0);
        self.surface.height(foot) + s * self.surface.normal(foot).y
    }
}

/// One pass of the edge over a point: the height it leaves (mm), the edge's slope dz/dx
/// there, and when (the spindle angle turned since the first pose, rad).
#[derive(Debug, Clone, Copy)]
struct Cut {
    z_mm: f64,
    slope: f64,
    turned_rad: f64,
}

/// The cuts at a point below a ceiling (the stock's top), lowest first: as many as the
/// surface there needs (one; two for cusp pile-up; all for spring-back, where their
/// order in time matters).
struct Cuts {
    ceiling: f64,
    keep: usize,
    list: Vec<Cut>,
}

impl Cuts {
    fn below(ceiling: f64, keep: usize) -> Self {
        Self {
            ceiling,
            keep,
            list: Vec::new(),
        }
    }

    /// A cut at or above this height changes nothing kept.
    fn threshold(&self) -> f64 {
        match self.list.get(self.keep.saturating_sub(1)) {
            Some(kept) => kept.z_mm.min(self.ceiling),
            None => self.ceiling,
        }
    }

    fn add(&mut self, cut: Cut) {
        if cut.z_mm >= self.threshold() {
            return;
        }
        let at = self.list.partition_point(|c| c.z_mm <= cut.z_mm);
        self.list.insert(at, cut);
        self.list.truncate(self.keep);
    }
}

/// Spring-back below a minimum chip thickness (the material recovers by a share of a
/// chip too thin to form).
struct SpringBack {
    min_chip_mm: f64,
    recovery: f64,
}

impl SpringBack {
    /// None without a minimum chip; the values checked against their ranges.
    fn of(min_chip_mm: f64, recovery: f64) -> Result<Option<Self>, String> {
        if min_chip_mm == 0.0 {
            return Ok(None);
        }
        if !(min_chip_mm.is_finite() && min_chip_mm > 0.0) {
            return Err(format!(
                "effects.spring_back_min_chip_mm: {min_chip_mm} is out of range; allowed: 0 (none) or a positive thickness"
            ));
        }
        if !(recovery > 0.0 && recovery <= 1.0) {
            return Err(format!(
                "effects.spring_back_recovery: {recovery} is out of range; allowed: (0, 1]"
            ));
        }
        Ok(Some(Self {
            min_chip_mm,
            recovery,
        }))
    }

    /// The height (along Z) the `cuts` leave, acting in time order on the stock top
    /// `stock_mm`; `normal_z`: the nominal surface normal's Z component, a Z gap times
    /// it being the chip along the normal.
    fn after(&self, stock_mm: f64, cuts: &[Cut], normal_z: f64) -> f64 {
        let mut in_time = cuts.to_vec();
        in_time.sort_by(|a, b| a.turned_rad.total_cmp(&b.turned_rad));
        in_time.iter().fold(stock_mm, |h, cut| {
            let chip = h - cut.z_mm;
            if chip <= 0.0 {
                h
            } else if chip * normal_z >= self.min_chip_mm {
                cut.z_mm
            } else {
                cut.z_mm + self.recovery * chip
            }
        })
    }
}

impl Edge {
    /// The edge's radius at edge angle `psi_rad` when it has receded by `recession_mm`.
    fn radius_at(&self, psi_rad: f64, recession_mm: f64) -> f64 {
        let notches: f64 = self
            .chips
            .iter()
            .map(|[depth, at, width]| notch_depth_mm(*depth, *at, *width, psi_rad))
            .sum();
        self.radius_mm + self.deviation.at(psi_rad) - notches - recession_mm
    }

    fn is_circle(&self) -> bool {
        matches!(self.deviation, Deviation::None) && self.chips.is_empty()
    }

    /// A height no edge point at machine x = `x_mm` lies below for the tool at `tool`:
    /// the edge lies within ρ_max of its real centre, itself within |e + w(0)| of the
    /// programmed one, and √(ρ² − u²) ≤ ρ − u²/2ρ.
    fn lowest_bound(&self, x_mm: f64, tool: &ToolAt) -> f64 {
        let pose = tool.pose;
        let offset = self.tip_offset_mm.abs();
        let u = ((x_mm - pose.x_mm).abs() - offset).max(0.0);
        pose.z_mm - offset - self.reach_mm + u * u / (2.0 * self.reach_mm)
    }

    /// The lowest edge point at machine x = `x_mm` for the tool at `tool`: its height
    /// and the edge's slope dz/dx there; `None` when no edge point lies at that x.
    fn lowest_at(&self, x_mm: f64, tool: &ToolAt) -> Option<(f64, f64)> {
        let (pose, recession) = (tool.pose, tool.recession_mm);
        let (sin_b, cos_b) = pose.b_rad.sin_cos();
        let tip = DVec2::new(-sin_b, -cos_b);
        let centre = DVec2::new(pose.x_mm, pose.z_mm) - self.tip_offset_mm * tip;
        let u = x_mm - centre.x;
        // The edge point in direction (−sin θ, −cos θ) from the centre, at radius ρ, has
        // x = centre.x − ρ sin θ: θ = asin(−u/ρ) on the lower half of the arc.
        let angle = |rho: f64| (u.abs() <= rho).then(|| (-u / rho).asin());
        let mut rho = self.radius_at(angle(self.radius_mm - recession)? - pose.b_rad, recession);
        let mut theta = angle(rho)?;
        if !self.is_circle() {
            for _ in 0..MAX_ITERATIONS {
                rho = self.radius_at(theta - pose.b_rad, recession);
                let next = angle(rho)?;
                let change = (next - theta).abs();
                theta = next;
                if change < ANGLE_TOLERANCE_RAD {
                    break;
                }
            }
        }
        if (theta - pose.b_rad).abs() > self.half_span_rad {
            return None;
        }
        let depth = ((rho - u) * (rho + u)).sqrt();
        Some((centre.y - depth, -theta.tan()))
    }
}

/// The program's passes as the machine runs them before any error: the job's pose
/// tables with its normal correction, turned about the axis by `azimuth_offset_rad`.
fn program_passes(job: &Job, turning: &TurningProcess) -> Vec<PoseTable> {
    let meridian = job.meridian();
    let mut passes = turning
        .path
        .pose_tables(&job.surface, &meridian, &turning.tool);
    for table in &mut passes {
        turning.correction.apply(table, &job.surface, &meridian);
        table.start_angle_rad += turning.azimuth_offset_rad;
    }
    passes
}

/// The passes as the section reads them: each with the spindle angle and (when the edge
/// wears) the cut length before it, over the passes in program order, and its reach index.
fn passes_of(tables: Vec<PoseTable>, motion: &ToolMotion) -> Vec<Pass> {
    let (mut angle, mut length) = (0.0, 0.0);
    tables
        .into_iter()
        .map(|table| {
            let pass = Pass {
                angle_before_rad: angle,
                length: motion.wears().then(|| CutLength::new(&table, length)),
                blocks: blocks_of(&table, motion.x_decentre_mm(), motion.x_spread_mm()),
                table,
            };
            angle += pass.table.end_angle_rad() - pass.table.start_angle_rad;
            length = pass.length.as_ref().map_or(0.0, CutLength::end_mm);
            pass
        })
        .collect()
}

/// The reach index of a pass: blocks of a few revolutions and their nose-centre X range
/// (moved by `x_decentre_mm`, widened by `x_spread_mm` either way).
fn blocks_of(table: &PoseTable, x_decentre_mm: f64, x_spread_mm: f64) -> Vec<Block> {
    let (start, end) = (table.start_angle_rad, table.end_angle_rad());
    let span = TAU * BLOCK_REVOLUTIONS;
    let count = (((end - start) / span).ceil() as usize).max(1);
    let last_node = table.poses.len().saturating_sub(1);
    (0..count)
        .map(|i| {
            let from = start + span * i as f64;
            let last = i + 1 == count;
            let to = if last {
                end
            } else {
                start + span * (i + 1) as f64
            };
            let first_node = (((from - start) / table.step_rad()).floor() as usize).min(last_node);
            let end_node = (((to - start) / table.step_rad()).ceil() as usize).min(last_node);
            let (x_min, x_max) = table.poses[first_node..=end_node]
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(p.x_mm), hi.max(p.x_mm))
                });
            Block {
                from_rad: from,
                to_rad: to,
                last,
                x_min_mm: x_min + x_decentre_mm - x_spread_mm,
                x_max_mm: x_max + x_decentre_mm + x_spread_mm,
            }
        })
        .collect()
}

/// The edge deviation of a job: the waviness harmonics its tables give, evaluated
/// exactly, when they are what the job's deviation table holds (no measured edge);
/// otherwise the table itself.
fn deviation_of(job: &Job, table: &AngleTable) -> Deviation {
    if table.is_zero() {
        return Deviation::None;
    }
    let harmonics: Vec<[f64; 3]> = job
        .resolved
        .effects
        .iter()
        .filter_map(|spec| match spec {
            EffectSpec::EdgeWaviness(waviness) => waviness.harmonics.as_ref(),
            _ => None,
        })
        .flatten()
        .map(|h| [h.order, h.amplitude_mm, h.phase_deg.to_radians()])
        .collect();
    let exact = Deviation::Harmonics(harmonics);
    let matches = job.resolved.tool.edge_profile().is_none()
        && table.values_mm.iter().enumerate().all(|(i, v)| {
            let psi = table.start_rad + table.step_rad * i as f64;
            (exact.at(psi) - v).abs() < 1e-12
        });
    if matches {
        exact
    } else {
        Deviation::Table(table.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(extra: &str) -> Job {
        Job::from_toml_str(
            &format!(
                r#"version = 1
[surface]
kind = "plane"
aperture_diameter_mm = 0.2
[tool]
kind = "arc_nose"
nose_radius_mm = 0.5
included_angle_deg = 140.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = 0.01
[grid]
pitch_um = 1.0
azimuths = 4
{extra}"#
            ),
            "test",
        )
        .unwrap()
    }

    #[test]
    fn harmonics_are_used_exactly_when_the_table_is_theirs() {
        let wavy = job(
            "[[effects]]\nkind = \"edge_waviness\"\nharmonics = [{ order = 20, amplitude_mm = 4e-5, phase_deg = 30.0 }]\n",
        );
        let Process::Turning(t) = &wavy.process else {
            unreachable!()
        };
        let d = deviation_of(&wavy, &t.effects.edge_deviation);
        assert!(matches!(d, Deviation::Harmonics(_)));
        // A table that is not theirs (edited after parsing) is used as it is.
        let mut other = t.effects.edge_deviation.clone();
        other.values_mm[7] += 1e-6;
        assert!(matches!(deviation_of(&wavy, &other), Deviation::Table(_)));
        // The exact harmonic: 40 nm · cos(20ψ + 30°).
        let psi = 0.1234;
        let expected = 4e-5 * (20.0 * psi + 30f64.to_radians()).cos();
        assert!((d.at(psi) - expected).abs() < 1e-18);
    }

    #[test]
    fn spring_back_folds_the_cuts_in_time_order() {
        // Heights in nm from a stock top at 100, h_min = 5, ρ = 0.5, in time order:
        // 90 (chip 10: cut) → 87 (chip 3: springs back to 87 + 1.5 = 88.5) → 89 (above:
        // nothing) → 84 (chip 4.5: 84 + 2.25 = 86.25). Given out of order.
        let nm = |z: f64, t: f64| Cut {
            z_mm: z * 1e-6,
            slope: 0.0,
            turned_rad: t,
        };
        let cuts = [nm(84.0, 4.0), nm(90.0, 1.0), nm(89.0, 3.0), nm(87.0, 2.0)];
        let spring_back = SpringBack::of(5e-6, 0.5).unwrap().unwrap();
        let h = spring_back.after(100e-6, &cuts, 1.0);
        assert!((h * 1e6 - 86.25).abs() < 1e-9, "{}", h * 1e6);
        // On a slope the chip along the normal is the Z gap times the normal's Z
        // component: at 0.6 the first chip is 6 ≥ 5 (the same as above); at 0.4 it is 4,
        // so: 90 (Z gap 10: 90 + 5 = 95) → 87 (gap 8, chip 3.2: 87 + 4 = 91) → 89 (gap
        // 2, chip 0.8: 89 + 1 = 90) → 84 (gap 6, chip 2.4: 84 + 3 = 87).
        let h = spring_back.after(100e-6, &cuts, 0.6);
        assert!((h * 1e6 - 86.25).abs() < 1e-9, "{}", h * 1e6);
        let h = spring_back.after(100e-6, &cuts, 0.4);
        assert!((h * 1e6 - 87.0).abs() < 1e-9, "{}", h * 1e6);
        // Out-of-range values are refused, naming the field.
        assert!(SpringBack::of(0.0, 0.0).unwrap().is_none());
        let err = SpringBack::of(5e-6, 1.5).err().unwrap();
        assert!(
            err.starts_with("effects.spring_back_recovery: 1.5"),
            "{err}"
        );
    }

    #[test]
    fn the_edge_of_an_ideal_tool_is_its_arc_below_the_nose_centre() {
        // Closed form: z = z_c − √(R² − u²) for a point u sideways of the centre, slope
        // u/√(R² − u²); outside the ±70° span nothing.
        let section = TurnedSection::new(&job(""), &[]).unwrap();
        let tool = ToolAt {
            pose: crate::process::ToolPose {
                x_mm: 0.3,
                z_mm: 0.5,
                b_rad: 0.0,
            },
            recession_mm: 0.0,
            turned_rad: 0.0,
        };
        for u in [-0.2, -0.01, 0.0, 0.05, 0.4] {
            let (z, slope) = section.edge.lowest_at(0.3 + u, &tool).unwrap();
            let root = (0.25f64 - u * u).sqrt();
            assert!((z - (0.5 - root)).abs() < 1e-15, "{u}");
            assert!((slope - u / root).abs() < 1e-12, "{u}");
        }
        assert!(section.edge.lowest_at(0.3 + 0.48, &tool).is_none());
    }
}

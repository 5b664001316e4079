//! Effects that are not diagnosis candidates (`[[measurement.unmodelled]]`): real
//! departures a diagnosis has no model for, put into synthetic data so that a benchmark
//! can check they come back "unexplained" rather than as a proxy. Turning only; the
//! section model applies them (`section.rs`).
//!
//! `chatter` is now a modelled effect too: it is exactly a job's `vibration` with
//! `direction = "depth"` (amplitude_mm = amplitude_nm·1e-6, per_revolution and phase_deg
//! the same), and the section model applies it as one. It stays here so that older
//! suites still read; whether a suite keeps it as "unmodelled" is the suite's choice.
//!
//! ```toml
//! [[measurement.unmodelled]]
//! kind = "cusp_pileup"     # material side flow: each cusp raised by height_nm in a
//! height_nm = 5.0          #   Gaussian of standard deviation width_um (along the
//! width_um = 0.5           #   radius) about the cusp
//!
//! [[measurement.unmodelled]]
//! kind = "chatter"         # tool–workpiece vibration along Z: the tool displaced by
//! amplitude_nm = 3.0       #   amplitude·cos(2π·per_revolution·(revolutions turned since
//! per_revolution = 7.3     #   the first pose) + phase)
//! phase_deg = 0.0
//!
//! [[measurement.unmodelled]]
//! kind = "edge_chip"       # a notch in the edge (after the tool was set at its tip): the
//! depth_nm = 30.0          #   edge radius less depth·(1 + cos(2π(ψ − at)/width))/2 for
//! at_deg = 0.3             #   |ψ − at| < width/2, ψ the edge angle from the tip
//! width_deg = 0.1          #   (+ toward the axis side of the tool)
//! ```

use serde::{Deserialize, Serialize};

/// One unmodelled effect (lengths as the names say).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Unmodelled {
    CuspPileup {
        height_nm: f64,
        width_um: f64,
    },
    /// The same as a `vibration` with direction depth (see the module notes).
    Chatter {
        amplitude_nm: f64,
        per_revolution: f64,
        #[serde(default)]
        phase_deg: f64,
    },
    EdgeChip {
        depth_nm: f64,
        at_deg: f64,
        width_deg: f64,
    },
}

impl Unmodelled {
    pub fn name(&self) -> &'static str {
        match self {
            Unmodelled::CuspPileup { .. } => "cusp_pileup",
            Unmodelled::Chatter { .. } => "chatter",
            Unmodelled::EdgeChip { .. } => "edge_chip",
        }
    }

    /// Checks the values of entry `index` against their ranges (`half_span_deg`: the
    /// tool's edge spans ±this about its tip), naming the field.
    pub fn validate(&self, index: usize, half_span_deg: f64) -> Result<(), String> {
        let within = |field: &str, v: f64, lo: f64, hi: f64, lo_open: bool| {
            let low_ok = if lo_open { v > lo } else { v >= lo };
            if v.is_finite() && low_ok && v <= hi {
                Ok(())
            } else {
                let bracket = if lo_open { "(" } else { "[" };
                Err(format!(
                    "measurement.unmodelled[{index}].{field}: {v} is out of range; allowed: {bracket}{lo}, {hi}]"
                ))
            }
        };
        match *self {
            Unmodelled::CuspPileup {
                height_nm,
                width_um,
            } => {
                within("height_nm", height_nm, -1000.0, 1000.0, false)?;
                within("width_um", width_um, 0.0, 100.0, true)
            }
            Unmodelled::Chatter {
                amplitude_nm,
                per_revolution,
                phase_deg,
            } => {
                within("amplitude_nm", amplitude_nm, 0.0, 1000.0, false)?;
                within("per_revolution", per_revolution, 0.0, 1000.0, true)?;
                within("phase_deg", phase_deg, -360.0, 360.0, false)
            }
            Unmodelled::EdgeChip {
                depth_nm,
                at_deg,
                width_deg,
            } => {
                within("depth_nm", depth_nm, 0.0, 10_000.0, true)?;
                within("at_deg", at_deg, -half_span_deg, half_span_deg, false)?;
                within("width_deg", width_deg, 0.0, 30.0, true)
            }
        }
    }
}

/// A notch's radial depth at edge angle `psi_rad` (mm, ≥ 0): a raised cosine of full
/// width `width_rad` about `at_rad`.
pub fn notch_depth_mm(depth_mm: f64, at_rad: f64, width_rad: f64, psi_rad: f64) -> f64 {
    let off = psi_rad - at_rad;
    if off.abs() >= 0.5 * width_rad {
        0.0
    } else {
        0.5 * depth_mm * (1.0 + (std::f64::consts::TAU * off / width_rad).cos())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct Holder {
        unmodelled: Vec<Unmodelled>,
    }

    #[test]
    fn tables_parse_and_bad_values_name_their_field_and_range() {
        let text = r#"
[[unmodelled]]
kind = "chatter"
amplitude_nm = 3.0
per_revolution = 7.5

[[unmodelled]]
kind = "edge_chip"
depth_nm = 30.0
at_deg = 80.0
width_deg = 0.1
"#;
        let list = toml::from_str::<Holder>(text).unwrap().unmodelled;
        assert_eq!(
            list[0],
            Unmodelled::Chatter {
                amplitude_nm: 3.0,
                per_revolution: 7.5,
                phase_deg: 0.0
            }
        );
        assert!(list[0].validate(0, 70.0).is_ok());
        let err = list[1].validate(1, 70.0).unwrap_err();
        assert_eq!(
            err,
            "measurement.unmodelled[1].at_deg: 80 is out of range; allowed: [-70, 70]"
        );
        // An unknown field or kind is refused by the parser, naming it.
        let bad = "[[unmodelled]]\nkind = \"chatter\"\namplitude_nm = 1.0\nper_revolution = 2.0\nheight_nm = 1.0\n";
        let err = toml::from_str::<Holder>(bad).err().unwrap().to_string();
        assert!(err.contains("height_nm"), "{err}");
        let bad = "[[unmodelled]]\nkind = \"wobble\"\n";
        let err = toml::from_str::<Holder>(bad).err().unwrap().to_string();
        assert!(err.contains("wobble"), "{err}");
    }

    #[test]
    fn the_notch_is_its_depth_at_its_middle_and_nothing_beyond_its_width() {
        let (d, at, w) = (3e-5, 0.01, 0.004);
        assert_eq!(notch_depth_mm(d, at, w, at), d);
        // A quarter width off the middle: half the depth.
        assert!((notch_depth_mm(d, at, w, at + 0.001) - 0.5 * d).abs() < 1e-18);
        assert_eq!(notch_depth_mm(d, at, w, at - 0.002), 0.0);
        assert_eq!(notch_depth_mm(d, at, w, 0.0), 0.0);
    }
}

//! Writes turning pose tables as an NC program in the C-X-Z block form `formats::nc` reads
//! (and the UPM programs use): `G93` inverse-time blocks `C<deg> X<mm> Z<mm>`, C wrapping
//! in (0, 360], X/Z addressing the nose centre, 7 decimals (0.1 nm).

use crate::process::PoseTable;
use std::fmt::Write as _;

/// The program text for the tables (one cutting pass each). `feed` is the G93 F word
/// written with each pass; `title` goes into the header comment.
pub fn c_x_z_program(tables: &[PoseTable], feed: f64, title: &str) -> String {
    let clean = |s: &str| s.replace(['(', ')'], "");
    let mut program = format!(
        "( {} )\n( written by toolmark {}: X/Z address the nose centre, mm; C in degrees )\nG71 G90 G18\n",
        clean(title),
        env!("CARGO_PKG_VERSION")
    );
    for table in tables {
        let step = 360.0 / table.steps_per_rev as f64;
        let start = table.start_angle_rad.to_degrees();
        let _ = writeln!(program, "G94 Z5 F200\n( CUTTING BLOCK )\nG93 F{feed}");
        for (i, pose) in table.poses.iter().enumerate() {
            let c = (start + step * i as f64).rem_euclid(360.0);
            // Keep 0 for the very first block and 360 for later full turns, as the
            // controller's programs do; both wrap to the same spindle angle.
            let c = if c == 0.0 && i > 0 { 360.0 } else { c };
            let _ = writeln!(program, "C{c:.6} X{:.7} Z{:.7}", pose.x_mm, pose.z_mm);
        }
    }
    program.push_str("G94 Z20 F800\nM30\n");
    program
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::nc::parse_nc;
    use crate::process::ToolPose;

    #[test]
    fn a_written_program_reads_back_to_the_same_poses() {
        let table = PoseTable {
            start_angle_rad: 0.0,
            steps_per_rev: 720,
            poses: (0..2000)
                .map(|i| ToolPose {
                    x_mm: 1.0 - i as f64 * 1e-5,
                    z_mm: 0.05 - i as f64 * 3e-7,
                    b_rad: 0.0,
                })
                .collect(),
        };
        let text = c_x_z_program(std::slice::from_ref(&table), 0.001, "round trip (test)");
        let program = parse_nc(&text).unwrap();
        assert_eq!(program.passes.len(), 1);
        let blocks = &program.passes[0].blocks;
        assert_eq!(blocks.len(), table.poses.len());
        for (i, (block, pose)) in blocks.iter().zip(&table.poses).enumerate() {
            assert!((block.c_deg - 0.5 * i as f64).abs() < 1e-9);
            assert!((block.x_mm - pose.x_mm).abs() < 1e-7 && (block.z_mm - pose.z_mm).abs() < 1e-7);
        }
    }
}

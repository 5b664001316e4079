/// A base part: the public job and how it is measured.
pub struct Base {
    pub name: &'static str,
    pub process: &'static str,
    pub job: &'static str,
    pub measurement: &'static str,
    /// Measured file's extension.
    pub format: &'static str,
    /// A profile's mount: where along its line (instrument µm) the part's axis may sit,
    /// drawn per case within this range.
    pub axis_along_um: [f64; 2],
    /// Whether the case tells the diagnosis the line's azimuth on the part (a profile
    /// cut out of a map by hand does not).
    pub azimuth_stated: bool,
    /// Whether the case is diagnosed with power removed (`--remove-power`), as a user
    /// diagnoses a white-light line whose lateral calibration is uncertain.
    pub remove_power: bool,
    /// Files the job reads, written beside it: (name, text).
    pub files: fn() -> Vec<(&'static str, String)>,
}

/// A centred mount: the axis within ±15 µm of the instrument's zero.
const CENTRED: [f64; 2] = [-15.0, 15.0];

fn no_files() -> Vec<(&'static str, String)> {
    Vec::new()
}

pub const TURNING_SPHERE: Base = Base {
    name: "turned convex sphere R8, Ø3 mm, 10 µm/rev, 0.5 mm nose",
    process: "turning",
    job: r#"version = 1
name = "turned sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 8.0
aperture_diameter_mm = 3.0
[tool]
kind = "arc_nose"
nose_radius_mm = 0.5
included_angle_deg = 140.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = 0.01
stock_allowance_mm = 0.003
[grid]
pitch_um = 0.5
azimuths = 8
"#,
    measurement: r#"kind = "profile"
spacing_um = 1.0
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub const GENERATED_SPHERE: Base = Base {
    name: "generated concave sphere R53.5 (seed 000's wheel), Ø4 mm",
    process: "generating",
    job: r#"version = 1
name = "generated sphere"
[surface]
kind = "sphere"
form = "concave"
radius_mm = 53.5
aperture_diameter_mm = 4.0
[tool]
kind = "cup_wheel"
cutting_radius_mm = 10.0
edge_radius_mm = 3.5
[process]
kind = "generating"
plunge_axis = "z"
tool_rpm = 3000.0
workpiece_rpm = 10.0
spark_out_revolutions = 2.0
stock_allowance_mm = 0.01
[grid]
pitch_um = 2.0
azimuths = 8
"#,
    measurement: r#"kind = "profile"
spacing_um = 2.0
white_noise_nm = 1.0
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub(super) const BALL_MILLED_SPHERE: Base = Base {
    name: "ball-end raster (Ø1 mm, 20 µm step) over a convex sphere R3, Ø2 mm, profile across the passes",
    process: "milling",
    job: r#"version = 1
name = "milled sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 3.0
aperture_diameter_mm = 2.0
[tool]
kind = "ball_end"
diameter_mm = 1.0
teeth = 2
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.02
spindle_rpm = 20000.0
stock_allowance_mm = 0.005
[grid]
pitch_um = 1.0
azimuths = 8
"#,
    measurement: r#"kind = "profile"
azimuth_deg = 90.0
spacing_um = 1.0
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub(super) const BALL_SPIRAL_FLAT: Base = Base {
    name: "ball-end spiral (Ø1 mm, 20 µm step) over a flat, Ø2 mm, profile through the centre",
    process: "milling",
    job: r#"version = 1
name = "spiral-milled flat"
[surface]
kind = "plane"
aperture_diameter_mm = 2.0
[tool]
kind = "ball_end"
diameter_mm = 1.0
teeth = 2
[process]
kind = "milling"
path = "spiral"
stepover_mm = 0.02
spindle_rpm = 20000.0
stock_allowance_mm = 0.005
[grid]
pitch_um = 1.0
azimuths = 8
"#,
    measurement: r#"kind = "profile"
azimuth_deg = 90.0
spacing_um = 1.0
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub const BALL_FEED_MARKS_FLAT: Base = Base {
    name: "two-flute ball-end (Ø2 mm, 20 µm per tooth) raster over a flat, Ø1 mm, profile along the feed",
    process: "milling",
    job: r#"version = 1
name = "feed marks on a flat"
[surface]
kind = "plane"
aperture_diameter_mm = 1.0
[tool]
kind = "ball_end"
diameter_mm = 2.0
teeth = 2
flutes = "body"
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.1
feed_per_tooth_mm = 0.02
spindle_rpm = 20000.0
stock_allowance_mm = 0.005
[grid]
pitch_um = 0.5
azimuths = 8
"#,
    measurement: r#"kind = "profile"
spacing_um = 0.5
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub(super) const BALL_FEED_MARKS_SPHERE: Base = Base {
    name: "two-flute ball-end (Ø1 mm, 20 µm per tooth, 50 µm step) over a convex sphere R3, Ø1 mm, profile along the feed",
    process: "milling",
    job: r#"version = 1
name = "feed marks on a sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 3.0
aperture_diameter_mm = 1.0
[tool]
kind = "ball_end"
diameter_mm = 1.0
teeth = 2
flutes = "body"
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.05
feed_per_tooth_mm = 0.02
spindle_rpm = 20000.0
stock_allowance_mm = 0.005
[grid]
pitch_um = 0.5
azimuths = 8
"#,
    measurement: r#"kind = "profile"
spacing_um = 0.5
stylus_tip_um = 2.0
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

/// The turned sphere's centre as a white-light interferometer maps it: 81 × 81 pixels
/// of 1 µm, each the mean over its footprint.
pub const TURNING_CENTRE_MAP: Base = Base {
    name: "turned convex sphere R8 (as above), white-light map of the centre, 81 × 81 px of 1 µm",
    process: "turning",
    job: TURNING_SPHERE.job,
    measurement: r#"kind = "map"
pixels = [81, 81]
pixel_um = 1.0
pixel_averaging = true
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "x3p",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

/// The turned sphere's whole aperture as a Fizeau interferometer maps it: 61 × 61
/// pixels of 50 µm (the tool marks average out; the form stays).
pub(super) const TURNING_FORM_MAP: Base = Base {
    name: "turned convex sphere R8 (as above), interferometer map of the aperture, 61 × 61 px of 50 µm",
    process: "turning",
    job: TURNING_SPHERE.job,
    measurement: r#"kind = "map"
pixels = [61, 61]
pixel_um = 50.0
pixel_averaging = true
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "gsf",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

/// A bull-nose raster over a flat, mapped across five passes: the map sees a spindle's
/// tram both ways (a profile across the passes sees only its component across them).
pub(super) const BULL_NOSE_FLAT_MAP: Base = Base {
    name: "bull-nose (Ø3 mm, 0.5 mm corner, 0.1 mm step) raster over a flat, Ø2 mm, map of 21 × 21 px of 25 µm",
    process: "milling",
    job: r#"version = 1
name = "bull-nose raster over a flat"
[surface]
kind = "plane"
aperture_diameter_mm = 2.0
[tool]
kind = "bull_nose"
diameter_mm = 3.0
corner_radius_mm = 0.5
[process]
kind = "milling"
path = "raster"
stepover_mm = 0.1
stock_allowance_mm = 0.01
[grid]
pitch_um = 2.0
azimuths = 8
"#,
    measurement: r#"kind = "map"
pixels = [21, 21]
pixel_um = 25.0
pixel_averaging = true
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "exr",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

/// A planner's bare `C X Z` program like cut 1021's (mm, inverse-time feed, no header):
/// the nose centre on z = x²/(2 · 10.8 mm) from X = 1 mm to the axis, C in 2° steps
/// wrapping at 360°, the feed per revolution falling linearly from 26 µm at the rim to
/// 14 µm at the axis (a constant-residual plan on a curved part does the like).
fn varying_feed_program() -> Vec<(&'static str, String)> {
    let mut text = String::new();
    let (mut x_mm, mut c_deg) = (1.0_f64, 0.0_f64);
    loop {
        let z_mm = x_mm * x_mm / (2.0 * 10.8);
        text += &format!("C{c_deg:.3} X{x_mm:.6} Z{z_mm:.6}\n");
        if x_mm <= 0.0 {
            break;
        }
        let feed_mm = 0.014 + 0.012 * x_mm;
        x_mm = (x_mm - feed_mm * 2.0 / 360.0).max(0.0);
        c_deg = if c_deg >= 360.0 { 2.0 } else { c_deg + 2.0 };
    }
    vec![("program.nc", text)]
}

/// A part of cut 1021's family: the bare program above, a 0.191 mm arc, measured as a
/// white-light profile cut out of a map by hand: optical, 0.871 µm spacing, the file's
/// zero at the line's left end, the axis somewhere inside it, its azimuth not told.
pub const SPIRAL_VARYING_FEED: Base = Base {
    name: "turned part from a bare C X Z program (0.191 mm nose, feed 14–26 µm/rev over Ø2 mm), white-light line from the file's zero, axis 0.35–0.65 mm along it",
    process: "turning",
    job: r#"version = 1
name = "bare C X Z program, feed 14-26 um/rev"
[surface]
kind = "from_path"
[tool]
kind = "arc_nose"
nose_radius_mm = 0.191
included_angle_deg = 120.0
[process]
kind = "turning"
mode = "xz"
nc_program = "program.nc"
nc_feed_mode = "inverse_time"
nc_units = "mm"
stock_allowance_mm = 0.003
[grid]
pitch_um = 0.5
azimuths = 8
"#,
    measurement: r#"kind = "profile"
from_mm = 0.0
to_mm = 1.3
spacing_um = 0.871
white_noise_nm = 2.0
pink_noise_nm = 2.0
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: [350.0, 650.0],
    azimuth_stated: false,
    remove_power: true,
    files: varying_feed_program,
};

/// A convex sphere R5 turned at 2 µm/rev with a 0.2 mm nose: marks 2.5 nm high, which a
/// 2 µm stylus tip barely resolves, so the form and what lies at the centre place the
/// trace; a diameter whose axis sits up to 40 µm either side of the instrument's zero.
pub const FINE_FEED_SPHERE: Base = Base {
    name: "turned convex sphere R5, Ø1 mm, 2 µm/rev, 0.2 mm nose, stylus diameter (2 µm tip) with the axis up to 40 µm from its zero",
    process: "turning",
    job: r#"version = 1
name = "fine-feed sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 5.0
aperture_diameter_mm = 1.0
[tool]
kind = "arc_nose"
nose_radius_mm = 0.2
included_angle_deg = 120.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = 0.002
stock_allowance_mm = 0.003
[grid]
pitch_um = 0.25
azimuths = 8
"#,
    measurement: r#"kind = "profile"
from_mm = -0.45
to_mm = 0.45
spacing_um = 0.5
stylus_tip_um = 2.0
white_noise_nm = 1.0
pink_noise_nm = 1.0
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: [-40.0, 40.0],
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

/// A convex sphere R20 turned at 8 µm/rev with a 0.5 mm nose, measured as a white-light
/// line of 0.5 µm pixels across the axis, which lies up to 100 µm from the file's zero:
/// even marks that repeat every half feed (with the line half a turn round), so the
/// marks alone cannot say which of them the axis is at.
pub const WHITE_LIGHT_SPHERE: Base = Base {
    name: "turned convex sphere R20, Ø2 mm, 8 µm/rev, 0.5 mm nose, white-light diameter of 0.5 µm pixels, the axis 0–100 µm from its zero, azimuth not told",
    process: "turning",
    job: r#"version = 1
name = "white-light sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 20.0
aperture_diameter_mm = 2.0
[tool]
kind = "arc_nose"
nose_radius_mm = 0.5
included_angle_deg = 120.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = 0.008
stock_allowance_mm = 0.003
[grid]
pitch_um = 0.5
azimuths = 8
"#,
    measurement: r#"kind = "profile"
from_mm = -0.85
to_mm = 0.95
spacing_um = 0.5
white_noise_nm = 1.5
pink_noise_nm = 1.5
dropout_fraction = 0.01
"#,
    format: "csv",
    axis_along_um: [0.0, 100.0],
    azimuth_stated: false,
    remove_power: false,
    files: no_files,
};

/// Every base, for the suite's README.
pub(super) const BASES: [&Base; 12] = [
    &TURNING_SPHERE,
    &GENERATED_SPHERE,
    &BALL_MILLED_SPHERE,
    &BALL_SPIRAL_FLAT,
    &BALL_FEED_MARKS_FLAT,
    &BALL_FEED_MARKS_SPHERE,
    &TURNING_CENTRE_MAP,
    &TURNING_FORM_MAP,
    &BULL_NOSE_FLAT_MAP,
    &SPIRAL_VARYING_FEED,
    &FINE_FEED_SPHERE,
    &WHITE_LIGHT_SPHERE,
];

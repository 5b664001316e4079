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
    job: include_str!("bases/turning_sphere/job.toml"),
    measurement: include_str!("bases/turning_sphere/measurement.toml"),
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub const GENERATED_SPHERE: Base = Base {
    name: "generated concave sphere R53.5 (seed 000's wheel), Ø4 mm",
    process: "generating",
    job: include_str!("bases/generated_sphere/job.toml"),
    measurement: include_str!("bases/generated_sphere/measurement.toml"),
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub(super) const BALL_MILLED_SPHERE: Base = Base {
    name: "ball-end raster (Ø1 mm, 20 µm step) over a convex sphere R3, Ø2 mm, profile across the passes",
    process: "milling",
    job: include_str!("bases/ball_milled_sphere/job.toml"),
    measurement: include_str!("bases/ball_milled_sphere/measurement.toml"),
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub(super) const BALL_SPIRAL_FLAT: Base = Base {
    name: "ball-end spiral (Ø1 mm, 20 µm step) over a flat, Ø2 mm, profile through the centre",
    process: "milling",
    job: include_str!("bases/ball_spiral_flat/job.toml"),
    measurement: include_str!("bases/ball_spiral_flat/measurement.toml"),
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub const BALL_FEED_MARKS_FLAT: Base = Base {
    name: "two-flute ball-end (Ø2 mm, 20 µm per tooth) raster over a flat, Ø1 mm, profile along the feed",
    process: "milling",
    job: include_str!("bases/ball_feed_marks_flat/job.toml"),
    measurement: include_str!("bases/ball_feed_marks_flat/measurement.toml"),
    format: "csv",
    axis_along_um: CENTRED,
    azimuth_stated: true,
    remove_power: false,
    files: no_files,
};

pub(super) const BALL_FEED_MARKS_SPHERE: Base = Base {
    name: "two-flute ball-end (Ø1 mm, 20 µm per tooth, 50 µm step) over a convex sphere R3, Ø1 mm, profile along the feed",
    process: "milling",
    job: include_str!("bases/ball_feed_marks_sphere/job.toml"),
    measurement: include_str!("bases/ball_feed_marks_sphere/measurement.toml"),
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
    measurement: include_str!("bases/turning_centre_map/measurement.toml"),
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
    measurement: include_str!("bases/turning_form_map/measurement.toml"),
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
    job: include_str!("bases/bull_nose_flat_map/job.toml"),
    measurement: include_str!("bases/bull_nose_flat_map/measurement.toml"),
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
    job: include_str!("bases/spiral_varying_feed/job.toml"),
    measurement: include_str!("bases/spiral_varying_feed/measurement.toml"),
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
    job: include_str!("bases/fine_feed_sphere/job.toml"),
    measurement: include_str!("bases/fine_feed_sphere/measurement.toml"),
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
    job: include_str!("bases/white_light_sphere/job.toml"),
    measurement: include_str!("bases/white_light_sphere/measurement.toml"),
    format: "csv",
    axis_along_um: [0.0, 100.0],
    azimuth_stated: false,
    remove_power: false,
    files: no_files,
};

/// Every base by the name the suite's cases give it (its folder under `bases/`).
pub(super) const BASES: [(&str, &Base); 12] = [
    ("turning_sphere", &TURNING_SPHERE),
    ("generated_sphere", &GENERATED_SPHERE),
    ("ball_milled_sphere", &BALL_MILLED_SPHERE),
    ("ball_spiral_flat", &BALL_SPIRAL_FLAT),
    ("ball_feed_marks_flat", &BALL_FEED_MARKS_FLAT),
    ("ball_feed_marks_sphere", &BALL_FEED_MARKS_SPHERE),
    ("turning_centre_map", &TURNING_CENTRE_MAP),
    ("turning_form_map", &TURNING_FORM_MAP),
    ("bull_nose_flat_map", &BULL_NOSE_FLAT_MAP),
    ("spiral_varying_feed", &SPIRAL_VARYING_FEED),
    ("fine_feed_sphere", &FINE_FEED_SPHERE),
    ("white_light_sphere", &WHITE_LIGHT_SPHERE),
];

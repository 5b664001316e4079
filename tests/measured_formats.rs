//! Measured surface formats: the readers against fixtures written by independent code
//! (`tests/data/measured/make_fixtures.py`, Python standard library only), whose heights
//! follow formulas repeated here; round trips through every writer; the real
//! white-light-interferometer export; and the errors users will meet.

use std::io::{Cursor, Read};
use std::path::{Path, PathBuf};

use md5::{Digest, Md5};
use toolmark::formats::measured::{
    HeightMap, HeightProfile, LengthUnit, MeasuredSurface, ReadInfo, ReadOptions, UnitSource,
    read_measured, write_map, write_profile, write_profile_csv,
};

use LengthUnit::{Metre, Micrometre, Millimetre, Nanometre};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/measured")
        .join(name)
}

/// A fresh folder for files written by one test.
fn out_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("toolmark-measured-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn map(path: &Path, options: &ReadOptions) -> HeightMap {
    match read_measured(path, options) {
        Ok(MeasuredSurface::Map(m)) => m,
        Ok(MeasuredSurface::Profile(_)) => panic!("{}: read as a profile", path.display()),
        Err(e) => panic!("{e}"),
    }
}

fn profile(path: &Path, options: &ReadOptions) -> HeightProfile {
    match read_measured(path, options) {
        Ok(MeasuredSurface::Profile(p)) => p,
        Ok(MeasuredSurface::Map(_)) => panic!("{}: read as a map", path.display()),
        Err(e) => panic!("{e}"),
    }
}

fn error(path: &Path, options: &ReadOptions) -> String {
    match read_measured(path, options) {
        Ok(_) => panic!("{}: read without an error", path.display()),
        Err(e) => e.to_string(),
    }
}

fn none() -> ReadOptions {
    ReadOptions::default()
}

/// |a − b| ≤ tol, with NaN matching NaN only.
fn close(a: f64, b: f64, tol: f64) -> bool {
    (a.is_nan() && b.is_nan()) || (a - b).abs() <= tol
}

/// Every height of `m` against `expected(i, j)` (NaN = invalid) within `tol` mm.
fn assert_map(m: &HeightMap, expected: impl Fn(usize, usize) -> f64, tol: f64) {
    for j in 0..m.ny {
        for i in 0..m.nx {
            let (got, want) = (m.at(i, j), expected(i, j));
            assert!(
                close(got, want, tol),
                "({i}, {j}): {got} mm, expected {want} mm"
            );
        }
    }
}

fn assert_units(info: &ReadInfo, lateral: LengthUnit, height: LengthUnit, source: UnitSource) {
    assert_eq!(
        (info.lateral_unit, info.height_unit),
        (lateral, height),
        "{info:?}"
    );
    assert_eq!(
        (info.lateral_unit_source, info.height_unit_source),
        (source, source),
        "{info:?}"
    );
}

/// The f32 rounding of a value, for data stored as f32.
fn f32_tol(v: f64) -> f64 {
    v.abs() * 1e-7 + 1e-30
}

// ---------------------------------------------------------------------------------------
// Readers against the Python fixtures

#[test]
fn x3p_surface_map_with_nan() {
    let m = map(&fixture("sample.x3p"), &none());
    assert_eq!((m.nx, m.ny), (5, 4));
    // CX 2 µm from 10 µm, CY 3 µm from −20 µm, in metres in the file.
    let tol = 1e-15;
    assert!(
        close(m.dx_mm, 2e-3, tol) && close(m.dy_mm, 3e-3, tol),
        "{m:?}"
    );
    assert!(
        close(m.x0_mm, 0.01, tol) && close(m.y0_mm, -0.02, tol),
        "{m:?}"
    );
    // z = 1e-7 (i − 2 j) m, stored as f64: exact to the m → mm factor.
    let z = |i: usize, j: usize| {
        if (i, j) == (2, 1) {
            f64::NAN
        } else {
            1e-4 * (i as f64 - 2.0 * j as f64)
        }
    };
    assert_map(&m, z, 1e-18);
    assert_eq!((m.info.invalid_points, m.valid_count()), (1, 19));
    assert_eq!(m.info.format, "X3P (ISO 25178-72)");
    assert_units(&m.info, Metre, Metre, UnitSource::FromFile);
    // Checksums written by hashlib all match (a mismatch would be noted).
    assert!(m.info.notes.is_empty(), "{:?}", m.info.notes);
}

#[test]
fn x3p_profile_in_f32() {
    let p = profile(&fixture("sample_prf.x3p"), &none());
    assert_eq!(p.len(), 7);
    for k in 0..7 {
        let (x, z) = (0.5e-3 * k as f64, 2e-5 * (k * k) as f64 - 1e-4);
        assert!(close(p.x_mm[k], x, 1e-16), "x {k}: {}", p.x_mm[k]);
        assert!(
            close(p.height_mm[k], z, f32_tol(z)),
            "z {k}: {}",
            p.height_mm[k]
        );
    }
    assert_eq!(p.info.invalid_points, 0);
    assert_units(&p.info, Metre, Metre, UnitSource::FromFile);
}

#[test]
fn x3p_integers_are_scaled_and_masked() {
    let m = map(&fixture("sample_int.x3p"), &none());
    assert_eq!((m.nx, m.ny), (4, 3));
    // z = (10 i − 7 j) · 1e-9 + 5e-9 m; mask clears points 1 and 10.
    let z = |i: usize, j: usize| {
        if [1, 10].contains(&(j * 4 + i)) {
            f64::NAN
        } else {
            ((10 * i) as f64 - (7 * j) as f64) * 1e-6 + 5e-6
        }
    };
    assert_map(&m, z, 1e-18);
    assert_eq!(m.info.invalid_points, 2);
}

#[test]
fn x3p_inline_data_list() {
    let m = map(&fixture("sample_inline.x3p"), &none());
    assert_eq!((m.nx, m.ny), (3, 2));
    let z = |i: usize, j: usize| {
        if j * 3 + i == 4 {
            f64::NAN
        } else {
            1e-3 * (i + j) as f64
        }
    };
    assert_map(&m, z, 1e-18);
}

#[test]
fn gsf_map() {
    let m = map(&fixture("sample.gsf"), &none());
    assert_eq!((m.nx, m.ny), (6, 3));
    let tol = 1e-15;
    assert!(
        close(m.dx_mm, 1.5e-3, tol) && close(m.dy_mm, 2e-3, tol),
        "{m:?}"
    );
    // Corner (−4.5, 1) µm plus half a pixel.
    assert!(
        close(m.x0_mm, -3.75e-3, tol) && close(m.y0_mm, 2e-3, tol),
        "{m:?}"
    );
    let z = |i: usize, j: usize| {
        if (i, j) == (5, 2) {
            f64::NAN
        } else {
            1e-5 * (i + 10 * j) as f64
        }
    };
    for j in 0..3 {
        for i in 0..6 {
            assert!(close(m.at(i, j), z(i, j), f32_tol(z(i, j))), "({i}, {j})");
        }
    }
    assert_eq!(m.info.format, "GSF");
    assert_units(&m.info, Metre, Metre, UnitSource::FromFile);
}

#[test]
fn exr_map_written_by_hand() {
    let m = map(&fixture("sample.exr"), &none());
    assert_eq!((m.nx, m.ny), (4, 3));
    // Float attribute pixel_x_um, double pixel_y_um, string x0_mm, float y0_mm.
    assert_eq!(
        (m.dx_mm, m.dy_mm, m.x0_mm, m.y0_mm),
        (1.25e-3, 2.5e-3, 0.5, -0.25)
    );
    // height_um = 0.25 i − 0.5 j + 1 (exact in f32); channel `valid` is 0 at (3, 0).
    let z = |i: usize, j: usize| {
        if (i, j) == (3, 0) {
            f64::NAN
        } else {
            (0.25 * i as f64 - 0.5 * j as f64 + 1.0) * 1e-3
        }
    };
    assert_map(&m, z, 1e-18);
    assert_eq!(m.info.format, "EXR");
    assert_units(&m.info, Micrometre, Micrometre, UnitSource::FromFile);
}

#[test]
fn csv_grid_with_keys() {
    let m = map(&fixture("sample_grid.csv"), &none());
    assert_eq!((m.nx, m.ny), (5, 4));
    let tol = 1e-15;
    assert!(
        close(m.dx_mm, 2.5e-3, tol) && close(m.dy_mm, 4e-3, tol),
        "{m:?}"
    );
    assert!(
        close(m.x0_mm, 0.01, tol) && close(m.y0_mm, -0.02, tol),
        "{m:?}"
    );
    let z = |i: usize, j: usize| {
        if [(1, 2), (4, 3)].contains(&(i, j)) {
            f64::NAN
        } else {
            (3.0 * i as f64 - 2.0 * j as f64 + 0.5) * 1e-6
        }
    };
    assert_map(&m, z, 1e-18);
    assert_eq!(
        (m.info.format.as_str(), m.info.invalid_points),
        ("csv grid", 2)
    );
    assert_units(&m.info, Micrometre, Nanometre, UnitSource::FromFile);
}

#[test]
fn csv_profile_with_units_in_the_header() {
    let p = profile(&fixture("sample_profile.csv"), &none());
    assert_eq!(p.len(), 20);
    for k in 0..20 {
        let x = 0.5e-3 * k as f64;
        let z = if k == 7 {
            f64::NAN
        } else {
            (4.0 * k as f64 - 0.25 * (k * k) as f64) * 1e-6
        };
        assert!(
            close(p.x_mm[k], x, 1e-18) && close(p.height_mm[k], z, 1e-18),
            "{k}"
        );
    }
    assert_eq!(
        (p.info.format.as_str(), p.info.invalid_points),
        ("csv profile", 1)
    );
    assert_eq!(
        (p.info.lateral_unit, p.info.height_unit),
        (Micrometre, Nanometre)
    );
}

#[test]
fn xyz_points_on_a_slanted_line() {
    let p = profile(&fixture("sample_line.xyz"), &none());
    assert_eq!(p.len(), 16);
    for k in 0..16 {
        // x is the distance s = 0.1 k mm along the line; z = 0.5 s² µm.
        let s = 0.1 * k as f64;
        assert!(close(p.x_mm[k], s, 1e-12), "{k}: {}", p.x_mm[k]);
        assert!(close(p.height_mm[k], 0.5e-3 * s * s, 1e-15), "{k}");
    }
    assert_eq!(p.info.format, "xyz");
    assert_units(&p.info, Millimetre, Micrometre, UnitSource::FromFile);
    assert!(p.info.notes.iter().any(|n| n.contains("straight line")));
}

#[test]
fn xyz_points_on_a_partial_grid() {
    let m = map(&fixture("sample_grid.xyz"), &none());
    assert_eq!((m.nx, m.ny), (4, 3));
    assert_eq!(
        (m.x0_mm, m.y0_mm, m.dx_mm, m.dy_mm),
        (-1.0, 0.5, 0.25, 0.125)
    );
    let z = |i: usize, j: usize| {
        if (i, j) == (3, 2) {
            f64::NAN
        } else {
            (i * j + 1) as f64 * 1e-6
        }
    };
    assert_map(&m, z, 1e-18);
    assert!(
        m.info
            .notes
            .iter()
            .any(|n| n.contains("1 position missing"))
    );
}

/// The real export of cut 1021 (`X,Y,Slice`, µm, no units in the file). Counted
/// independently with Python's csv module: 1143 data rows, 999 with a height, 144
/// without; x from 0.871181614525112 to 995.760585402196 µm; median step
/// 0.8711816145249998 µm.
#[test]
fn real_wli_profile_with_declared_units() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/upm-spdt/1021-WLI-2D.csv");
    let e = error(&path, &none());
    assert!(e.contains("--lateral-unit"), "{e}");
    let um = ReadOptions {
        lateral_unit: Some(Micrometre),
        height_unit: Some(Micrometre),
        ..Default::default()
    };
    let p = profile(&path, &um);
    assert_eq!(
        (p.len(), p.valid_count(), p.info.invalid_points),
        (1143, 999, 144)
    );
    assert!(close(p.x_mm[0], 0.871181614525112e-3, 1e-15));
    assert!(close(p.x_mm[1142], 995.760585402196e-3, 1e-15));
    assert!(close(p.spacing_mm(), 0.8712e-3, 5e-8), "{}", p.spacing_mm());
    assert_units(&p.info, Micrometre, Micrometre, UnitSource::Declared);
    assert!(
        p.info.notes.iter().any(|n| n.contains("column `Y`")),
        "{:?}",
        p.info.notes
    );
    // The same points as the fixed-layout reader the CLI uses.
    let old =
        toolmark::formats::measured::read_wli_profile_csv(&path, Micrometre, Micrometre).unwrap();
    assert_eq!(p.valid_points(), (old.x_mm, old.height_mm));
}

// ---------------------------------------------------------------------------------------
// Writers: write, read back

/// A 7 × 5 map with awkward values and two invalid points.
fn test_map() -> HeightMap {
    let (nx, ny) = (7, 5);
    let height = (0..nx * ny)
        .map(|k| match k {
            3 | 17 => f64::NAN,
            _ => 1e-4 * ((k as f64 * 0.731).sin() + 0.1 * k as f64) - 3.3e-5,
        })
        .collect();
    HeightMap::new(
        (nx, ny),
        [-0.0125, 0.3],
        [1.3e-3, 0.7e-3],
        height,
        ReadInfo::in_mm("test"),
    )
    .unwrap()
}

fn assert_same_grid(back: &HeightMap, map: &HeightMap, tol: f64) {
    assert_eq!((back.nx, back.ny), (map.nx, map.ny));
    for (a, b) in [
        (back.dx_mm, map.dx_mm),
        (back.dy_mm, map.dy_mm),
        (back.x0_mm, map.x0_mm),
        (back.y0_mm, map.y0_mm),
    ] {
        assert!(close(a, b, tol), "{a} vs {b}");
    }
    assert_eq!(back.info.invalid_points, 2);
}

/// The entry `name` of a zip archive.
fn unzip(bytes: &[u8], name: &str) -> Vec<u8> {
    let mut archive = zip::ZipArchive::new(Cursor::new(bytes)).unwrap();
    let mut data = Vec::new();
    archive
        .by_name(name)
        .unwrap()
        .read_to_end(&mut data)
        .unwrap();
    data
}

#[test]
fn x3p_round_trip_is_exact_in_metres() {
    let dir = out_dir("x3p");
    let path = dir.join("map.x3p");
    let m = test_map();
    write_map(&path, &m).unwrap();
    // The payload holds each height / 1000 bit for bit (f64 metres).
    // Read with the `zip` crate directly, not through toolmark's reader.
    let bytes = std::fs::read(&path).unwrap();
    let data = unzip(&bytes, "bindata/data.bin");
    let stored: Vec<u64> = data
        .chunks_exact(8)
        .map(|b| u64::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let expected: Vec<u64> = m.height_mm.iter().map(|h| (h / 1e3).to_bits()).collect();
    assert_eq!(stored, expected);
    let main = unzip(&bytes, "main.xml");
    let sum = String::from_utf8(unzip(&bytes, "md5checksum.hex")).unwrap();
    let md5: String = Md5::digest(&main)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(sum, format!("{md5} *main.xml\n"));
    // Read back: within one ulp of the mm values (the m → mm product rounds once).
    let back = map(&path, &none());
    assert_same_grid(&back, &m, 1e-15);
    for (a, b) in back.height_mm.iter().zip(&m.height_mm) {
        assert!(close(*a, *b, b.abs() * f64::EPSILON), "{a} vs {b}");
    }
    assert!(back.info.notes.is_empty(), "{:?}", back.info.notes);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn gsf_exr_and_csv_round_trips() {
    let dir = out_dir("maps");
    let m = test_map();
    for (name, bit_exact) in [("map.gsf", false), ("map.exr", false), ("map.csv", true)] {
        let path = dir.join(name);
        write_map(&path, &m).unwrap();
        let back = map(&path, &none());
        // GSF stores positions in metres as decimal text; EXR and CSV store mm exactly.
        assert_same_grid(&back, &m, if name.ends_with("gsf") { 1e-15 } else { 0.0 });
        for (a, b) in back.height_mm.iter().zip(&m.height_mm) {
            let tol = if bit_exact { 0.0 } else { f32_tol(*b) };
            assert!(close(*a, *b, tol), "{name}: {a} vs {b}");
        }
        assert_eq!(back.info.height_unit_source, UnitSource::FromFile, "{name}");
    }
    let e = write_map(&dir.join("map.png"), &m).unwrap_err().to_string();
    assert!(
        e.contains("map.png") && e.contains(".x3p, .gsf, .exr or .csv"),
        "{e}"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn profile_round_trips_through_csv_and_x3p() {
    let dir = out_dir("profiles");
    let x: Vec<f64> = (0..50).map(|k| 0.125 + 2.5e-4 * k as f64).collect();
    let h: Vec<f64> = (0..50)
        .map(|k| {
            if k == 9 {
                f64::NAN
            } else {
                3e-5 * (0.37 * k as f64).cos()
            }
        })
        .collect();
    let p = HeightProfile::new(x, h, ReadInfo::in_mm("test")).unwrap();
    let csv = dir.join("profile.csv");
    write_profile_csv(&csv, &p, &["simulated part, azimuth 0".to_string()]).unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(
        text.starts_with("# simulated part, azimuth 0\nx_mm,height_mm\n"),
        "{text}"
    );
    let back = profile(&csv, &none());
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back.x_mm), bits(&p.x_mm));
    assert_eq!(bits(&back.height_mm), bits(&p.height_mm));
    assert_units(&back.info, Millimetre, Millimetre, UnitSource::FromFile);

    let x3p = dir.join("profile.x3p");
    write_profile(&x3p, &p).unwrap();
    let back = profile(&x3p, &none());
    for k in 0..50 {
        assert!(close(back.x_mm[k], p.x_mm[k], 1e-15), "x {k}");
        assert!(close(back.height_mm[k], p.height_mm[k], 1e-20), "z {k}");
    }
    let uneven = HeightProfile::new(vec![0.0, 1.0, 3.0], vec![0.0; 3], ReadInfo::in_mm("t"));
    let e = write_profile(&dir.join("uneven.x3p"), &uneven.unwrap()).unwrap_err();
    assert!(e.message.contains("evenly spaced"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_failed_write_keeps_the_old_file() {
    let dir = out_dir("atomic");
    for name in ["map.x3p", "map.gsf", "map.exr", "map.csv"] {
        let path = dir.join(name);
        write_map(&path, &test_map()).unwrap();
        let before = std::fs::read(&path).unwrap();
        // Block the temporary file `crate::formats::atomic` writes first (a folder in its
        // place), so the write fails midway.
        let temp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
        std::fs::create_dir(&temp).unwrap();
        let e = write_map(&path, &test_map()).unwrap_err();
        assert!(e.to_string().contains(name), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), before, "{name}");
        std::fs::remove_dir(&temp).unwrap();
    }
    std::fs::remove_dir_all(dir).unwrap();
}

// ---------------------------------------------------------------------------------------
// Errors

/// Writes `text` to a file called `name` in `dir` and reads it.
fn text_error(dir: &Path, name: &str, text: &[u8], options: &ReadOptions) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    let e = error(&path, options);
    assert!(
        e.starts_with(&path.display().to_string()),
        "no file name: {e}"
    );
    e
}

#[test]
fn unit_errors() {
    let dir = out_dir("unit-errors");
    let e = text_error(&dir, "a.csv", b"x,z\n1,2\n2,3\n", &none());
    assert!(e.contains("declare it with --lateral-unit"), "{e}");
    let um = ReadOptions {
        lateral_unit: Some(Micrometre),
        ..Default::default()
    };
    let e = text_error(&dir, "b.csv", b"x,z\n1,2\n2,3\n", &um);
    assert!(e.contains("--height-unit"), "{e}");
    let mm = ReadOptions {
        lateral_unit: Some(Millimetre),
        height_unit: Some(Nanometre),
        ..Default::default()
    };
    let e = text_error(&dir, "c.csv", b"x_um,z_nm\n1,2\n2,3\n", &mm);
    assert!(
        e.contains("µm") && e.contains("--lateral-unit mm") && e.contains("must agree"),
        "{e}"
    );
    let e = text_error(
        &dir,
        "d.csv",
        b"# height_unit = um\nx_um,z_nm\n1,2\n2,3\n",
        &none(),
    );
    assert!(e.contains("contradicts itself"), "{e}");
    let e = error(&fixture("sample.x3p"), &mm);
    assert!(e.contains("metres") && e.contains("--lateral-unit"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn empty_header_only_ragged_scattered_and_all_invalid() {
    let dir = out_dir("errors");
    let um = ReadOptions {
        lateral_unit: Some(Micrometre),
        height_unit: Some(Micrometre),
        pixel_mm: Some((1e-3, 1e-3)),
    };
    let cases: [(&str, &[u8], &str); 8] = [
        ("empty.csv", b"", "the file is empty"),
        ("blank.csv", b"\n# nothing\n\n", "no data rows"),
        (
            "header.csv",
            b"x_um,z_um\n",
            "no data rows after the header (line 1)",
        ),
        (
            "ragged.csv",
            b"1,2,3,4\n5,6,7,8\n9,10,11\n",
            "line 3: 3 cells, but the first row (line 1) has 4",
        ),
        (
            "scattered.xyz",
            b"0 0 1\n1 0.3 1\n0.37 1 1\n0.9 0.8 0\n",
            "scattered points are not supported",
        ),
        (
            "invalid.csv",
            b"x,z\n1,\n2,NaN\n3,***\n",
            "no valid heights in 3 points",
        ),
        (
            "invalid_grid.csv",
            b"-,-,-,-\nnan,,,\n",
            "no valid heights in 8 points",
        ),
        (
            "binary.dat",
            b"\x00\x01\x02\x03",
            "binary file of unknown format",
        ),
    ];
    for (name, text, why) in cases {
        let e = text_error(&dir, name, text, &um);
        assert!(e.contains(why), "{name}: {e} (wanted {why})");
    }
    let e = text_error(&dir, "text.x3p", b"x,z\n1,2\n", &um);
    assert!(e.contains("zip archive"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn broken_binary_files() {
    let dir = out_dir("binary-errors");
    let e = error(&fixture("sample_no_main.x3p"), &none());
    assert!(
        e.contains("no main.xml") && e.contains("bindata/data.bin"),
        "{e}"
    );
    let e = error(&fixture("sample_absolute.x3p"), &none());
    assert!(
        e.contains("CX has AxisType A") && e.contains("incremental"),
        "{e}"
    );

    // One byte of the stored main.xml changed: the CRC-32 check catches it.
    let mut x3p = std::fs::read(fixture("sample.x3p")).unwrap();
    let at = x3p
        .windows(15)
        .position(|w| w == b"FeatureType>SUR")
        .unwrap();
    x3p[at + 14] = b'S';
    let path = dir.join("corrupt.x3p");
    std::fs::write(&path, &x3p).unwrap();
    let e = error(&path, &none());
    assert!(
        e.contains("main.xml") && e.contains("CRC-32 mismatch"),
        "{e}"
    );

    // 6 × 3 f32 need 72 bytes; drop the last 4.
    let gsf = std::fs::read(fixture("sample.gsf")).unwrap();
    let path = dir.join("truncated.gsf");
    std::fs::write(&path, &gsf[..gsf.len() - 4]).unwrap();
    let e = error(&path, &none());
    assert!(e.contains("needs 72 bytes of f32 data, found 68"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

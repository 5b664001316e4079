//! `key = value` metadata: `#` comment lines of text files and EXR header attributes.
//!
//! Keys are matched without case, spaces read as `_`, and may end in a length unit that
//! applies to their value (`pixel_x_um = 2.5`, `x0 (mm) = 1`); a length key without one
//! takes the lateral unit (the `lateral_unit` key or `--lateral-unit`), else it is an
//! error. Known keys:
//!
//! | key | meaning |
//! |---|---|
//! | `pixel`, `pixel_size`, `pixel_pitch` + unit | square pixel pitch |
//! | `pixel_x`, `dx` / `pixel_y`, `dy` + unit | pitch along x / y |
//! | `x0`, `y0` + unit | centre of pixel (0, 0) (default 0, with a note) |
//! | `lateral_unit` (`xy_unit`, `x_unit`) | unit of positions and of unit-less keys |
//! | `height_unit` (`z_unit`) | unit of heights |
//!
//! A comment line that is just `# grid` marks a text file as a grid.

use super::text::split_name;
use super::{
    Axis, FileUnit, LengthUnit, MeasuredError, ReadOptions, UnitSource, fail, resolve_pixel,
    resolve_unit,
};

#[derive(Clone, Debug, Default)]
pub(super) struct Metadata {
    entries: Vec<Entry>,
    grid: bool,
}

#[derive(Clone, Debug)]
struct Entry {
    /// As written (for messages).
    key: String,
    value: String,
    line: Option<usize>,
}

const PIXEL: &[&str] = &["pixel", "pixel_size", "pixel_pitch"];
const PIXEL_X: &[&str] = &["pixel_x", "dx"];
const PIXEL_Y: &[&str] = &["pixel_y", "dy"];
const X0: &[&str] = &["x0"];
const Y0: &[&str] = &["y0"];

/// How a key is matched: lower case, spaces as `_`.
fn normalise(key: &str) -> String {
    key.trim().to_lowercase().replace(' ', "_")
}

impl Metadata {
    /// Takes the text after a `#`: `key = value`, `key: value`, or `grid`.
    pub(super) fn add_comment(&mut self, comment: &str, line: usize) {
        let comment = comment.trim();
        if comment.eq_ignore_ascii_case("grid") {
            self.grid = true;
            return;
        }
        let Some(at) = comment.find(['=', ':']) else {
            return;
        };
        let (key, value) = (comment[..at].trim(), comment[at + 1..].trim());
        // A key is a word (letters, digits, `_`, `-`), perhaps with a bracketed unit; a
        // sentence with a colon in it is a comment.
        let word = key.split(['(', '[']).next().unwrap_or("").trim_end();
        let plain = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-';
        if word.starts_with(|c: char| c.is_ascii_alphabetic()) && word.chars().all(plain) {
            self.entries.push(Entry {
                key: key.to_string(),
                value: value.to_string(),
                line: Some(line),
            });
        }
    }

    pub(super) fn from_pairs<'a>(pairs: impl IntoIterator<Item = (&'a str, &'a str)>) -> Self {
        let entries = pairs.into_iter().map(|(k, v)| Entry {
            key: k.to_string(),
            value: v.to_string(),
            line: None,
        });
        Metadata {
            entries: entries.collect(),
            grid: false,
        }
    }

    /// A `# grid` line, or any pixel size key.
    pub(super) fn marks_grid(&self) -> bool {
        let pixel_keys = [PIXEL, PIXEL_X, PIXEL_Y].concat();
        self.grid || self.find(&pixel_keys).is_some()
    }

    /// The first entry whose key (less any unit suffix) is one of `bases`.
    /// The unit is that of the key's suffix, if it is a length unit.
    fn find(&self, bases: &[&str]) -> Option<(&Entry, Option<LengthUnit>)> {
        self.entries.iter().find_map(|e| {
            let key = normalise(&e.key);
            let (base, unit) = split_name(&key);
            let unit = unit.and_then(LengthUnit::parse);
            bases.contains(&base.as_str()).then_some((e, unit))
        })
    }

    fn describe(e: &Entry) -> String {
        match e.line {
            Some(l) => format!("`{} = {}` (line {l})", e.key, e.value),
            None => format!("the attribute `{}`", e.key),
        }
    }

    /// The unit the file states for `axis`, checked to be a length unit.
    pub(super) fn unit(&self, axis: Axis) -> Result<Option<FileUnit>, MeasuredError> {
        let keys: &[&str] = match axis {
            Axis::Lateral => &["lateral_unit", "xy_unit", "x_unit"],
            Axis::Height => &["height_unit", "z_unit"],
        };
        let Some(e) = self
            .entries
            .iter()
            .find(|e| keys.contains(&normalise(&e.key).as_str()))
        else {
            return Ok(None);
        };
        match LengthUnit::parse(&e.value) {
            Some(unit) => Ok(Some(FileUnit {
                unit,
                source: Self::describe(e),
            })),
            None => fail(
                e.line,
                format!(
                    "{}: `{}` is not a length unit (allowed: m, mm, µm/um, nm)",
                    Self::describe(e),
                    e.value
                ),
            ),
        }
    }

    /// A length key's value. A key without a unit suffix takes `bare_unit` (the
    /// lateral unit, from the file or the user), or is an error.
    fn length(
        &self,
        bases: &[&str],
        bare_unit: Option<(LengthUnit, UnitSource)>,
    ) -> Result<Option<Length>, MeasuredError> {
        let Some((e, suffix)) = self.find(bases) else {
            return Ok(None);
        };
        let what = Self::describe(e);
        let Ok(value) = e.value.parse::<f64>() else {
            return fail(e.line, format!("{what}: `{}` is not a number", e.value));
        };
        if !value.is_finite() {
            return fail(e.line, format!("{what}: the value must be finite"));
        }
        let (unit, source) = match (suffix, bare_unit) {
            (Some(u), _) => (u, UnitSource::FromFile),
            (None, Some(bare)) => bare,
            (None, None) => {
                return fail(
                    e.line,
                    format!(
                        "{what} gives no unit: add one to the key (`{}_um`, `_mm`, `_nm`, `_m`) or declare --lateral-unit",
                        e.key
                    ),
                );
            }
        };
        Ok(Some(Length {
            mm: unit.to_mm(value),
            unit,
            source,
            what,
        }))
    }
}

/// A length read from a key.
#[derive(Clone, Debug)]
struct Length {
    mm: f64,
    unit: LengthUnit,
    source: UnitSource,
    /// The key and value, for messages.
    what: String,
}

/// A map's pitch, origin and lateral unit, from metadata or the user.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Sampling {
    pub pixel_mm: [f64; 2],
    pub origin_mm: [f64; 2],
    pub lateral_unit: LengthUnit,
    pub lateral_source: UnitSource,
    pub notes: Vec<String>,
}

/// The sampling of a grid or EXR map; `hint` tells how the file could give the pitch.
pub(super) fn sampling(
    meta: &Metadata,
    options: &ReadOptions,
    hint: &str,
) -> Result<Sampling, MeasuredError> {
    let file_lateral = meta.unit(Axis::Lateral)?;
    let bare_unit = match (&file_lateral, options.lateral_unit) {
        (None, None) => None,
        _ => Some(resolve_unit(Axis::Lateral, file_lateral, options, "")?),
    };
    let square = meta.length(PIXEL, bare_unit)?;
    let dx = meta.length(PIXEL_X, bare_unit)?.or(square.clone());
    let dy = meta.length(PIXEL_Y, bare_unit)?.or(square);
    let file_pixel = match (&dx, &dy) {
        (Some(x), Some(y)) => Some(([x.mm, y.mm], format!("{} and {}", x.what, y.what))),
        (None, None) => None,
        (Some(one), None) | (None, Some(one)) => {
            return fail(
                None,
                format!(
                    "{} needs its partner: give both pixel_x and pixel_y, or pixel for square pixels",
                    one.what
                ),
            );
        }
    };
    if let Some(x) = file_pixel
        .as_ref()
        .filter(|p| !(p.0[0] > 0.0 && p.0[1] > 0.0))
    {
        return fail(None, format!("{}: the pixel size must be > 0", x.1));
    }
    let (pixel_mm, pixel_source) = resolve_pixel(file_pixel, options, hint)?;
    let (lateral_unit, lateral_source) = match (&dx, pixel_source) {
        (Some(x), UnitSource::FromFile) => (x.unit, x.source),
        _ => (LengthUnit::Millimetre, UnitSource::Declared),
    };
    let mut notes = Vec::new();
    let mut origin_mm = [0.0; 2];
    for (k, (bases, name)) in [(X0, "x0"), (Y0, "y0")].into_iter().enumerate() {
        match meta.length(bases, bare_unit)? {
            Some(v) => origin_mm[k] = v.mm,
            None => notes.push(format!(
                "no {name} in the file: pixel (0, 0) taken at {name} = 0"
            )),
        }
    }
    if pixel_source == UnitSource::Declared {
        notes.push(format!(
            "pixel size declared: {} × {} µm",
            pixel_mm[0] * 1e3,
            pixel_mm[1] * 1e3
        ));
    }
    Ok(Sampling {
        pixel_mm,
        origin_mm,
        lateral_unit,
        lateral_source,
        notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta(lines: &[&str]) -> Metadata {
        let mut m = Metadata::default();
        for (i, l) in lines.iter().enumerate() {
            m.add_comment(l, i + 1);
        }
        m
    }

    #[test]
    fn pitch_and_origin_from_keys() {
        let m = meta(&[
            " pixel_x_um = 2.5",
            "pixel_y_um=4",
            "x0_mm = -1",
            "Y0 (µm): 3",
        ]);
        let s = sampling(&m, &ReadOptions::default(), "").unwrap();
        assert_eq!(s.pixel_mm, [2.5e-3, 4e-3]);
        assert_eq!(s.origin_mm, [-1.0, 3e-3]);
        assert_eq!(
            (s.lateral_unit, s.lateral_source),
            (LengthUnit::Micrometre, UnitSource::FromFile)
        );
        assert!(s.notes.is_empty(), "{:?}", s.notes);
        assert!(m.marks_grid());
    }

    #[test]
    fn bare_keys_need_a_lateral_unit() {
        let m = meta(&["pixel = 2"]);
        let e = sampling(&m, &ReadOptions::default(), "").unwrap_err();
        assert!(
            e.message.contains("--lateral-unit") && e.line == Some(1),
            "{e}"
        );
        let nm = ReadOptions {
            lateral_unit: Some(LengthUnit::Nanometre),
            ..Default::default()
        };
        let s = sampling(&m, &nm, "").unwrap();
        assert_eq!(s.pixel_mm, [2e-6, 2e-6]);
        assert_eq!(s.lateral_source, UnitSource::Declared);
        assert_eq!(s.notes.len(), 2, "origin notes: {:?}", s.notes);
        let m = meta(&["pixel = 2", "lateral_unit = um"]);
        let e = sampling(&m, &nm, "").unwrap_err();
        assert!(e.message.contains("must agree"), "{e}");
    }

    #[test]
    fn declared_pitch_and_conflicts() {
        let declared = ReadOptions {
            pixel_mm: Some((1e-3, 2e-3)),
            ..Default::default()
        };
        let s = sampling(&Metadata::default(), &declared, "").unwrap();
        assert_eq!(s.pixel_mm, [1e-3, 2e-3]);
        assert_eq!(s.lateral_source, UnitSource::Declared);
        let e = sampling(&meta(&["pixel_um = 1.5"]), &declared, "").unwrap_err();
        assert!(e.message.contains("--pixel-um"), "{e}");
        let e = sampling(&meta(&["pixel_x_um = 1.5"]), &declared, "").unwrap_err();
        assert!(e.message.contains("partner"), "{e}");
        let e = sampling(&Metadata::default(), &ReadOptions::default(), "a hint").unwrap_err();
        assert!(e.message.contains("a hint") && e.message.contains("--pixel-um"));
        let e = sampling(&meta(&["pixel_um = -1"]), &ReadOptions::default(), "").unwrap_err();
        assert!(e.message.contains("> 0"), "{e}");
        let e = sampling(&meta(&["pixel_um = abc"]), &ReadOptions::default(), "").unwrap_err();
        assert!(e.message.contains("not a number"), "{e}");
    }

    #[test]
    fn free_comments_are_not_keys() {
        let m = meta(&["measured 2024-05-01: white-light interferometer, 50x objective"]);
        assert!(m.entries.is_empty());
        let m = meta(&["grid"]);
        assert!(m.marks_grid());
    }
}

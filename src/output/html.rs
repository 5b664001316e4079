//! Self-contained HTML reports (`report.html`) for `run`, `diagnose`, `compensate` and
//! `correct`: one file, images inline as data URIs, styles inline, no script and no
//! network fetch, readable on a laptop screen. Each report opens with its verdict in one
//! sentence, then the figures and maps with their units.
//!
//! Reports are rendered from the JSON documents the commands write (`summary.json`,
//! `diagnosis.json`, `compensation.json`, `correction.json`) plus the PNGs beside them,
//! so a field a document lacks is simply not shown, and unknown fields of a block are
//! listed generically (tables for arrays of objects, key–value lists for objects).

use crate::formats::atomic::write_bytes_atomically;
use base64::Engine as _;
use serde_json::Value;
use std::fmt::Write as _;
use std::io;
use std::path::{Path, PathBuf};

/// Escapes text for HTML element content and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A JSON value as a short text: numbers to 4 significant digits, null as "—".
pub fn format_value(value: &Value) -> String {
    match value {
        Value::Null => "—".into(),
        Value::Bool(b) => b.to_string(),
        Value::Number(n) => match n.as_f64() {
            Some(v) if n.is_f64() => format_number(v),
            _ => n.to_string(),
        },
        Value::String(s) => s.clone(),
        Value::Array(items) if items.iter().all(|v| !v.is_object() && !v.is_array()) => items
            .iter()
            .map(format_value)
            .collect::<Vec<_>>()
            .join(", "),
        other => other.to_string(),
    }
}

fn format_number(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let magnitude = v.abs();
    if !(1e-3..1e6).contains(&magnitude) {
        return format!("{v:.3e}");
    }
    let decimals = (3 - magnitude.log10().floor() as i32).clamp(0, 6) as usize;
    format!("{v:.decimals$}")
}

/// One part of a report page.
pub struct Section {
    pub title: String,
    pub html: String,
}

impl Section {
    pub fn new(title: &str, html: String) -> Self {
        Section {
            title: title.to_string(),
            html,
        }
    }
}

const STYLE: &str = "body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;max-width:1100px;margin:0 auto;padding:16px 24px;color:#1b1b1b;line-height:1.45}\
h1{font-size:1.5em;margin:.2em 0}h2{font-size:1.2em;border-bottom:1px solid #ccc;padding-bottom:2px;margin-top:1.6em}\
.verdict{font-size:1.15em;background:#f3f6fa;border-left:5px solid #3b6fb6;padding:10px 14px;margin:12px 0}\
.status{font-family:monospace;color:#555}table{border-collapse:collapse;margin:8px 0;font-size:.92em}\
td,th{border:1px solid #ddd;padding:3px 8px;text-align:left;vertical-align:top}th{background:#f5f5f5}\
td.num{text-align:right;font-variant-numeric:tabular-nums}figure{margin:12px 0}figure img{max-width:100%;height:auto;border:1px solid #eee}\
figcaption{color:#555;font-size:.9em}dl{display:grid;grid-template-columns:max-content auto;gap:2px 16px}dt{color:#555}dd{margin:0}\
.warn{color:#8a4b00}footer{color:#777;font-size:.85em;margin-top:2em}";

/// A whole page: title, the verdict sentence, a status line, then the sections.
pub fn page(title: &str, verdict: &str, status: &str, sections: &[Section]) -> String {
    let mut html = String::new();
    let _ = write!(
        html,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>{}</title><style>{STYLE}</style></head><body>\n<h1>{}</h1>\n\
         <p class=\"verdict\">{}</p>\n<p class=\"status\">{}</p>\n",
        escape(title),
        escape(title),
        escape(verdict),
        escape(status)
    );
    for section in sections {
        let _ = write!(
            html,
            "<section><h2>{}</h2>\n{}</section>\n",
            escape(&section.title),
            section.html
        );
    }
    let _ = write!(
        html,
        "<footer>toolmark {} — a self-contained report: every image is inline.</footer>\n</body></html>\n",
        env!("CARGO_PKG_VERSION")
    );
    html
}

/// An inline PNG with its caption; `None` when the file is missing or unreadable.
pub fn figure(path: &Path, caption: &str) -> Option<String> {
    let bytes = std::fs::read(path).ok()?;
    if !bytes.starts_with(b"\x89PNG") {
        return None;
    }
    let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
    Some(format!(
        "<figure><img alt=\"{0}\" src=\"data:image/png;base64,{data}\"><figcaption>{0}</figcaption></figure>\n",
        escape(caption)
    ))
}

/// The figures among `images` (file name, caption) that exist in `dir`.
pub fn figures(dir: &Path, images: &[(&str, &str)]) -> String {
    images
        .iter()
        .filter_map(|(name, caption)| figure(&dir.join(name), caption))
        .collect()
}

/// An object's scalar fields as a definition list (nested objects flattened with dots,
/// arrays of scalars joined); arrays of objects are left to [`table`].
pub fn key_values(value: &Value) -> String {
    let mut rows = Vec::new();
    flatten("", value, &mut rows);
    if rows.is_empty() {
        return String::new();
    }
    let mut html = String::from("<dl>");
    for (key, text) in rows {
        let _ = write!(html, "<dt>{}</dt><dd>{}</dd>", escape(&key), escape(&text));
    }
    html.push_str("</dl>\n");
    html
}

fn flatten(prefix: &str, value: &Value, rows: &mut Vec<(String, String)>) {
    match value {
        Value::Object(map) => {
            for (key, item) in map {
                let name = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                flatten(&name, item, rows);
            }
        }
        Value::Array(items) if items.iter().any(|v| v.is_object() || v.is_array()) => {}
        other => rows.push((prefix.to_string(), format_value(other))),
    }
}

/// An array of objects as a table: one column per key (in first-seen order), nested
/// objects shown as compact `key value` lists. Empty for anything else.
pub fn table(value: &Value) -> String {
    let Some(items) = value.as_array().filter(|items| !items.is_empty()) else {
        return String::new();
    };
    let mut columns: Vec<String> = Vec::new();
    for item in items {
        if let Some(map) = item.as_object() {
            for key in map.keys() {
                if !columns.contains(key) {
                    columns.push(key.clone());
                }
            }
        }
    }
    if columns.is_empty() {
        return format!("<p>{}</p>\n", escape(&format_value(value)));
    }
    let mut html = String::from("<table><tr>");
    for column in &columns {
        let _ = write!(html, "<th>{}</th>", escape(column));
    }
    html.push_str("</tr>\n");
    for item in items {
        html.push_str("<tr>");
        for column in &columns {
            let cell = item.get(column).unwrap_or(&Value::Null);
            let class = if cell.is_number() {
                " class=\"num\""
            } else {
                ""
            };
            let text = match cell {
                Value::Object(_) => compact(cell),
                Value::Array(a) if a.iter().any(Value::is_object) => {
                    a.iter().map(compact).collect::<Vec<_>>().join("; ")
                }
                other => format_value(other),
            };
            let _ = write!(html, "<td{class}>{}</td>", escape(&text));
        }
        html.push_str("</tr>\n");
    }
    html.push_str("</table>\n");
    html
}

/// `key value, key value` for a small object.
fn compact(value: &Value) -> String {
    let mut rows = Vec::new();
    flatten("", value, &mut rows);
    rows.into_iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Writes `report.html` into `dir` (atomically) and returns its path.
fn write_page(dir: &Path, html: &str) -> io::Result<PathBuf> {
    let path = dir.join("report.html");
    write_bytes_atomically(&path, html.as_bytes())?;
    Ok(path)
}

fn get<'a>(value: &'a Value, pointer: &str) -> &'a Value {
    value.pointer(pointer).unwrap_or(&Value::Null)
}

fn number(value: &Value, pointer: &str) -> Option<f64> {
    value.pointer(pointer).and_then(Value::as_f64)
}

fn nm(value: Option<f64>) -> String {
    value.map_or("—".into(), |v| format!("{} nm", format_number(v)))
}

// ---------------------------------------------------------------------------------------
// run

/// The run report from `summary.json` (schema `toolmark.summary/1`) and the maps in `dir`.
pub fn write_run_html(dir: &Path, summary: &Value) -> io::Result<PathBuf> {
    let name = get(summary, "/job_name").as_str().unwrap_or("job");
    let verdict = run_verdict(summary);
    let status = format!(
        "{} · {} engine ({}) · job hash {}",
        get(summary, "/path/process").as_str().unwrap_or("?"),
        get(summary, "/engine/kind").as_str().unwrap_or("?"),
        get(summary, "/engine/adapter").as_str().unwrap_or(""),
        get(summary, "/job_hash").as_str().unwrap_or("")
    );
    let sections = run_sections(dir, summary);
    write_page(
        dir,
        &page(
            &format!("{name}: simulated surface"),
            &verdict,
            &status,
            &sections,
        ),
    )
}

/// One sentence: the form error, the texture and the central feature.
pub fn run_verdict(summary: &Value) -> String {
    let pv = nm(number(summary, "/deviation/pv_nm"));
    let rms = nm(number(summary, "/deviation/rms_nm"));
    let scallop = match number(summary, "/scallop/max_nm") {
        Some(max) => format!("tool marks up to {}", nm(Some(max))),
        None => "no tool marks resolved".to_string(),
    };
    let feature = match get(summary, "/protrusion/shape").as_str() {
        Some("none") | None => "no central feature".to_string(),
        Some(shape) => format!(
            "a central {shape} {} high, radius {} µm",
            nm(number(summary, "/protrusion/height_nm")),
            format_number(number(summary, "/protrusion/radius_um").unwrap_or(f64::NAN))
        ),
    };
    format!(
        "The simulated part deviates from nominal by {pv} PV ({rms} RMS), with {scallop} and {feature}."
    )
}

fn run_sections(dir: &Path, s: &Value) -> Vec<Section> {
    let mut sections = vec![Section::new(
        "Maps",
        figures(
            dir,
            &[
                (
                    "deviation_colour.png",
                    "Deviation along the outward normal (nm), top view from +Z",
                ),
                ("deviation_centre.png", "The central zone (nm)"),
                ("scallop_colour.png", "Scallop (cusp) height (nm)"),
                (
                    "cutting_diameter.png",
                    "Milling: effective cutting diameter (mm)",
                ),
                (
                    "centre_profile.png",
                    "Deviation across the central zone (nm against mm)",
                ),
            ],
        ),
    )];
    let figures_table = format!(
        "<table><tr><th>quantity</th><th>value</th></tr>\
         <tr><td>deviation PV / RMS / mean</td><td class=\"num\">{} / {} / {}</td></tr>\
         <tr><td>scallop max / mean (cusps)</td><td class=\"num\">{} / {} ({})</td></tr>\
         <tr><td>central feature</td><td>{} {} high, radius {} µm</td></tr></table>\n",
        nm(number(s, "/deviation/pv_nm")),
        nm(number(s, "/deviation/rms_nm")),
        nm(number(s, "/deviation/mean_nm")),
        nm(number(s, "/scallop/max_nm")),
        nm(number(s, "/scallop/mean_nm")),
        format_value(get(s, "/scallop/count")),
        format_value(get(s, "/protrusion/shape")),
        nm(number(s, "/protrusion/height_nm")),
        format_value(get(s, "/protrusion/radius_um")),
    );
    sections.push(Section::new("Figures", figures_table));
    sections.push(Section::new(
        "Surface texture (ISO 25178, ISO 4287), PSD and Zernike form",
        texture_html(get(s, "/texture")),
    ));
    let mut process = key_values(get(s, "/path"));
    process.push_str(&key_values(get(s, "/grid")));
    sections.push(Section::new("Process and grid", process));
    if let Some(warnings) = get(s, "/warnings").as_array().filter(|w| !w.is_empty()) {
        let list: String = warnings
            .iter()
            .map(|w| format!("<li class=\"warn\">{}</li>", escape(&format_value(w))))
            .collect();
        sections.push(Section::new("Warnings", format!("<ul>{list}</ul>")));
    }
    sections.push(Section::new("Engine and timings (s)", {
        let mut html = key_values(get(s, "/engine"));
        html.push_str(&key_values(get(s, "/timings_s")));
        html
    }));
    sections
}

/// The texture block: areal and profile parameters, a PSD plot (inline SVG) and the
/// Zernike table.
pub fn texture_html(texture: &Value) -> String {
    if texture.is_null() {
        return "<p>not computed</p>".into();
    }
    let mut html = String::new();
    let a = |k: &str| number(texture, &format!("/areal/{k}"));
    let _ = write!(
        html,
        "<table><tr><th>Sa</th><th>Sq</th><th>Sz</th><th>Ssk</th><th>Sku</th></tr>\
         <tr><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td></tr></table>\
         <p>Areal parameters of the deviation field (the nominal surface is the F-operator; area-weighted; no L-filter).</p>",
        nm(a("sa_nm")),
        nm(a("sq_nm")),
        nm(a("sz_nm")),
        format_value(get(texture, "/areal/ssk")),
        format_value(get(texture, "/areal/sku")),
    );
    let p = get(texture, "/profile");
    if p.is_object() {
        let _ = write!(
            html,
            "<table><tr><th>Ra</th><th>Rq</th><th>Rz</th><th>λc</th><th>λs</th><th>evaluation length</th></tr>\
             <tr><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{} mm</td><td class=\"num\">{} µm</td><td class=\"num\">{} mm ({} sampling lengths)</td></tr></table>\
             <p>Profile parameters of the radial profile at azimuth 0 (ISO 16610-21 Gaussian filters, λc by ISO 4288 from the mark spacing).</p>",
            nm(number(p, "/ra_nm")),
            nm(number(p, "/rq_nm")),
            nm(number(p, "/rz_nm")),
            format_value(get(p, "/lambda_c_mm")),
            format_value(get(p, "/lambda_s_um")),
            format_value(get(p, "/evaluation_length_mm")),
            format_value(get(p, "/sampling_lengths")),
        );
    }
    html.push_str(&psd_svg(get(texture, "/psd")));
    let zernike = get(texture, "/zernike");
    if zernike.as_array().is_some_and(|z| !z.is_empty()) {
        html.push_str("<p>Zernike form decomposition (Noll order, RMS-normalised coefficients in nm, ρ = r / outer radius):</p>");
        html.push_str(&table(zernike));
        let _ = write!(
            html,
            "<p>RMS left after the 15 terms: {}</p>",
            nm(number(texture, "/zernike_residual_rms_nm"))
        );
    }
    html
}

/// The PSD as a small log–log inline SVG (no script, no external file).
fn psd_svg(psd: &Value) -> String {
    let wavelengths: Vec<f64> = get(psd, "/wavelength_um")
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    let powers: Vec<f64> = get(psd, "/psd_nm2_mm")
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    let points: Vec<(f64, f64)> = wavelengths
        .iter()
        .zip(&powers)
        .filter(|(w, p)| **w > 0.0 && **p > 0.0)
        .map(|(w, p)| (w.log10(), p.log10()))
        .collect();
    if points.len() < 2 {
        return String::new();
    }
    let (x0, x1) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
    let (y0, y1) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.1), b.max(p.1))
        });
    let (w, h, left, bottom) = (640.0, 260.0, 70.0, 40.0);
    let sx = |x: f64| left + (x - x0) / (x1 - x0).max(1e-12) * (w - left - 10.0);
    let sy = |y: f64| 10.0 + (y1 - y) / (y1 - y0).max(1e-12) * (h - bottom - 10.0);
    let path: String = points
        .iter()
        .map(|(x, y)| format!("{:.1},{:.1}", sx(*x), sy(*y)))
        .collect::<Vec<_>>()
        .join(" ");
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" role=\"img\" aria-label=\"PSD\">\
         <rect x=\"{left}\" y=\"10\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#999\"/>\
         <polyline fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"1.5\" points=\"{path}\"/>",
        w - left - 10.0,
        h - bottom - 10.0
    );
    for decade in (x0.ceil() as i32)..=(x1.floor() as i32) {
        let x = sx(f64::from(decade));
        let _ = write!(
            svg,
            "<text x=\"{x:.0}\" y=\"{}\" font-size=\"11\" text-anchor=\"middle\">{}</text>",
            h - bottom + 14.0,
            format_number(10f64.powi(decade))
        );
    }
    for decade in (y0.ceil() as i32)..=(y1.floor() as i32) {
        let y = sy(f64::from(decade));
        let _ = write!(
            svg,
            "<text x=\"{}\" y=\"{y:.0}\" font-size=\"11\" text-anchor=\"end\">1e{decade}</text>",
            left - 4.0
        );
    }
    let _ = write!(
        svg,
        "<text x=\"{}\" y=\"{}\" font-size=\"12\" text-anchor=\"middle\">wavelength (µm)</text>\
         <text x=\"12\" y=\"{}\" font-size=\"12\" transform=\"rotate(-90 12 {})\" text-anchor=\"middle\">PSD (nm²·mm)</text></svg>",
        (w + left) / 2.0,
        h - 6.0,
        h / 2.0,
        h / 2.0
    );
    format!(
        "<figure>{svg}<figcaption>PSD of the radial profile (Hann window); dominant period below λc: {} µm</figcaption></figure>\n",
        format_value(get(psd, "/dominant_period_um"))
    )
}

// ---------------------------------------------------------------------------------------
// diagnose

/// The diagnosis report from `diagnosis.json` (schema `toolmark.diagnosis/1`, any fields
/// added since shown generically) and the images the diagnosis wrote into `out_dir`.
pub fn write_diagnosis_html(out_dir: &Path, diagnosis: &Value) -> io::Result<PathBuf> {
    let verdict = get(diagnosis, "/verdict/sentence")
        .as_str()
        .unwrap_or("The diagnosis gave no verdict sentence.");
    let status = format!(
        "status {} · job {} ({}) · measured {}",
        format_value(get(diagnosis, "/verdict/status")),
        format_value(get(diagnosis, "/job/name")),
        format_value(get(diagnosis, "/job/process")),
        format_value(get(diagnosis, "/measurement/file")),
    );
    let name = get(diagnosis, "/job/name").as_str().unwrap_or("job");
    let sections = diagnosis_sections(out_dir, diagnosis);
    write_page(
        out_dir,
        &page(&format!("{name}: diagnosis"), verdict, &status, &sections),
    )
}

/// The diagnosis report's sections in reading order, after its verdict.
fn diagnosis_sections(dir: &Path, d: &Value) -> Vec<Section> {
    let mut sections = Vec::new();
    sections.extend(advice_section(d));
    sections.push(gap_section(dir, d));
    sections.extend(comparison_section(d));
    sections.push(effects_section(d));
    sections.push(shrinkage_section(d));
    // Registration, fit check, measurement, run.
    sections.push(registration_section(d));
    sections.push(Section::new(
        "Does the data fit the job",
        key_values(&strip_arrays(get(d, "/fit_check"))),
    ));
    sections.push(Section::new(
        "Measurement",
        key_values(get(d, "/measurement")),
    ));
    sections.push(Section::new("Run", key_values(get(d, "/run"))));
    sections
}

/// "What to do": the verdict's advice as a list, when it has any.
fn advice_section(d: &Value) -> Option<Section> {
    let advice = get(d, "/verdict/advice")
        .as_array()
        .filter(|a| !a.is_empty())?;
    let list: String = advice
        .iter()
        .map(|a| format!("<li>{}</li>", escape(&format_value(a))))
        .collect();
    Some(Section::new("What to do", format!("<ul>{list}</ul>")))
}

/// Where the gap lies: overall, per zone, per band, per azimuthal order, before and after
/// the accepted effects, then the diagnosis's figures.
fn gap_section(dir: &Path, d: &Value) -> Section {
    let mut gap = String::new();
    for (key, label) in [
        ("residual_before", "against the job as given"),
        ("residual_after", "with the accepted effects"),
    ] {
        let block = get(d, &format!("/{key}"));
        if block.is_null() {
            continue;
        }
        let _ = write!(
            gap,
            "<h3>Residual {label}: PV {}, RMS {}</h3>",
            nm(number(block, "/pv_nm")),
            nm(number(block, "/rms_nm"))
        );
        for (part, title) in [
            ("zones", "zones"),
            ("bands", "bands"),
            ("azimuthal_orders", "azimuthal orders"),
        ] {
            let rows = get(block, &format!("/{part}"));
            if rows.as_array().is_some_and(|r| !r.is_empty()) {
                let _ = write!(gap, "<p>By {title}:</p>{}", table(rows));
            }
        }
    }
    gap.push_str(&figures(
        dir,
        &[
            (
                "profile.png",
                "Measured, nominal and fitted profiles (nm against mm)",
            ),
            (
                "residual.png",
                "Residual before and after the fitted effects (nm)",
            ),
            ("residual_zones.png", "Residual by zone (nm)"),
            (
                "residual_before.png",
                "Residual map against the job as given (nm)",
            ),
            (
                "residual_after.png",
                "Residual map with the fitted effects (nm)",
            ),
            ("zones.png", "Zones"),
        ],
    ));
    Section::new("Where the gap lies", gap)
}

/// Measured against simulated, when the document has the block (new blocks shown when
/// present).
fn comparison_section(d: &Value) -> Option<Section> {
    let comparison = get(d, "/comparison");
    if comparison.is_null() {
        return None;
    }
    let mut html = key_values(&strip_arrays(comparison));
    html.push_str(&table(get(comparison, "/mark_spacing")));
    Some(Section::new("Measured against simulated", html))
}

/// Which effects were accepted and tried, and those not diagnosable, indistinguishable
/// or tied (ambiguous).
fn effects_section(d: &Value) -> Section {
    let mut effects = String::new();
    for (key, title) in [("accepted", "Accepted"), ("candidates", "Tried")] {
        if let Some(list) = get(d, &format!("/{key}"))
            .as_array()
            .filter(|l| !l.is_empty())
        {
            let _ = write!(effects, "<h3>{title}</h3>{}", effect_table(list));
        }
    }
    for key in ["not_diagnosable", "indistinguishable", "ambiguous"] {
        let rows = get(d, &format!("/{key}"));
        if rows.as_array().is_some_and(|r| !r.is_empty()) {
            let _ = write!(effects, "<h3>{}</h3>{}", key.replace('_', " "), table(rows));
        }
    }
    Section::new("Effects tried and accepted (value ± σ)", effects)
}

/// How far the residual shrank, and the held-out check (an object's known fields in a
/// sentence, the rest listed; an array as a table).
fn shrinkage_section(d: &Value) -> Section {
    let mut shrink = table(get(d, "/shrinkage"));
    let held_out = get(d, "/held_out");
    if held_out.is_object() {
        let _ = write!(
            shrink,
            "<p>Held-out check ({} points, {}–{} mm): RMS {} → {}, PV {} → {}.</p>{}",
            format_value(get(held_out, "/points")),
            format_value(get(held_out, "/from_mm")),
            format_value(get(held_out, "/to_mm")),
            nm(number(held_out, "/before_rms_nm")),
            nm(number(held_out, "/after_rms_nm")),
            nm(number(held_out, "/before_pv_nm")),
            nm(number(held_out, "/after_pv_nm")),
            key_values(&strip_known(
                held_out,
                &[
                    "points",
                    "from_mm",
                    "to_mm",
                    "before_rms_nm",
                    "after_rms_nm",
                    "before_pv_nm",
                    "after_pv_nm"
                ]
            ))
        );
    } else if held_out.is_array() {
        shrink.push_str(&table(held_out));
    }
    Section::new("How far the residual shrank", shrink)
}

/// The registration found, then the fit check's findings as warnings.
fn registration_section(d: &Value) -> Section {
    let mut registration = key_values(get(d, "/registration"));
    for finding in get(d, "/fit_check/findings")
        .as_array()
        .into_iter()
        .flatten()
    {
        let _ = write!(
            registration,
            "<p class=\"warn\">{}: {}</p>",
            escape(&format_value(get(finding, "/severity"))),
            escape(&format_value(get(finding, "/message")))
        );
    }
    Section::new("Registration found", registration)
}

/// The effects list: label, the parameters as value ± σ with units, ΔBIC, explained.
fn effect_table(effects: &[Value]) -> String {
    let mut html = String::from(
        "<table><tr><th>effect</th><th>parameters</th><th>ΔBIC</th><th>explained</th><th>accepted</th><th>advice</th></tr>\n",
    );
    for effect in effects {
        let parameters: Vec<String> = get(effect, "/parameters")
            .as_array()
            .into_iter()
            .flatten()
            .map(|p| {
                let sigma = match get(p, "/sigma") {
                    Value::Null => " (not seen)".to_string(),
                    s => format!(" ± {}", format_value(s)),
                };
                format!(
                    "{} = {}{sigma} {}",
                    format_value(get(p, "/name")),
                    format_value(get(p, "/value")),
                    format_value(get(p, "/unit"))
                )
            })
            .collect();
        let label = match get(effect, "/label") {
            Value::Null => format_value(get(effect, "/effect")),
            l => format_value(l),
        };
        let _ = write!(
            html,
            "<tr><td>{}</td><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td>{}</td><td>{}</td></tr>",
            escape(&label),
            escape(&parameters.join("; ")),
            escape(&format_value(get(effect, "/delta_bic"))),
            escape(&format_value(get(effect, "/explained"))),
            escape(&format_value(get(effect, "/accepted"))),
            escape(&format_value(get(effect, "/advice"))),
        );
    }
    html.push_str("</table>\n");
    html
}

/// An object without its arrays (shown as tables elsewhere).
fn strip_arrays(value: &Value) -> Value {
    match value.as_object() {
        Some(map) => Value::Object(
            map.iter()
                .filter(|(_, v)| !v.is_array())
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect(),
        ),
        None => Value::Null,
    }
}

/// An object without the named keys.
fn strip_known(value: &Value, known: &[&str]) -> Value {
    match value.as_object() {
        Some(map) => Value::Object(
            map.iter()
                .filter(|(k, _)| !known.contains(&k.as_str()))
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect(),
        ),
        None => Value::Null,
    }
}

// ---------------------------------------------------------------------------------------
// compensate and correct

/// The compensation loop's report from `compensation.json` and `form_error.png`.
pub fn write_compensation_html(dir: &Path, compensation: &Value) -> io::Result<PathBuf> {
    let cycles = get(compensation, "/cycles")
        .as_array()
        .cloned()
        .unwrap_or_default();
    let first = cycles
        .first()
        .and_then(|c| c.get("form_pv_nm"))
        .and_then(Value::as_f64);
    let last = cycles
        .last()
        .and_then(|c| c.get("form_pv_nm"))
        .and_then(Value::as_f64);
    let verdict = format!(
        "Compensation took the form error from {} PV to {} PV in {} cycles.",
        nm(first),
        nm(last),
        cycles.len().saturating_sub(1)
    );
    let name = get(compensation, "/job_name").as_str().unwrap_or("job");
    let sections = vec![
        Section::new("Form error per cycle", table(get(compensation, "/cycles"))),
        Section::new(
            "Form error",
            figures(
                dir,
                &[("form_error.png", "Form error per cycle (nm against mm)")],
            ),
        ),
        Section::new("Settings", key_values(&strip_arrays(compensation))),
    ];
    write_page(
        dir,
        &page(
            &format!("{name}: compensation"),
            &verdict,
            "toolmark compensate",
            &sections,
        ),
    )
}

/// The generator correction's report from `correction.json` and the centre images.
pub fn write_correction_html(dir: &Path, correction: &Value) -> io::Result<PathBuf> {
    let verdict = get(correction, "/verdict")
        .as_str()
        .map(str::to_string)
        .unwrap_or_else(|| {
            let before = number(correction, "/before/central_pv_nm")
                .or_else(|| number(correction, "/central_pv_before_nm"));
            let after = number(correction, "/after/central_pv_nm")
                .or_else(|| number(correction, "/central_pv_after_nm"));
            format!(
                "The correction took the central zone from {} PV to {} PV.",
                nm(before),
                nm(after)
            )
        });
    let name = get(correction, "/job_name").as_str().unwrap_or("job");
    let mut sections = vec![Section::new(
        "Central zone before and after (one colour scale)",
        figures(
            dir,
            &[
                ("centre_before.png", "Before (nm)"),
                ("centre_after.png", "After (nm)"),
                (
                    "centre_profiles.png",
                    "Profiles across the central zone (nm against mm)",
                ),
            ],
        ),
    )];
    sections.push(Section::new(
        "Correction",
        key_values(&strip_arrays(correction)),
    ));
    if let Some(map) = correction.as_object() {
        for (key, value) in map.iter().filter(|(_, v)| v.is_array()) {
            sections.push(Section::new(&key.replace('_', " "), table(value)));
        }
    }
    write_page(
        dir,
        &page(
            &format!("{name}: generator correction"),
            &verdict,
            "toolmark correct",
            &sections,
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn text_is_escaped_and_numbers_are_short() {
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
        assert_eq!(format_value(&json!(12.345678)), "12.35");
        assert_eq!(format_value(&json!(0.000012)), "1.200e-5");
        assert_eq!(format_value(&json!(null)), "—");
        assert_eq!(format_value(&json!([1, 2])), "1, 2");
    }

    #[test]
    fn unknown_and_missing_diagnosis_fields_render_without_failing() {
        let dir = std::env::temp_dir().join(format!("toolmark-html-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // A document with only a verdict, plus blocks this module has never seen.
        let doc = json!({
            "verdict": {"status": "effects_found", "sentence": "Centre height <3 µm> explains it."},
            "registration": {"axis_x_mm": 0.0012, "novel": {"deep": [1, 2]}},
            "comparison": {"measured": {"pv_nm": 10.0, "rms_nm": 2.0},
                           "simulated": {"pv_nm": 9.0, "rms_nm": 1.5},
                           "mark_spacing": [{"radius_mm": 0.5, "measured_um": 40.9, "simulated_um": 40.3}]},
            "held_out": [{"from_mm": 0.0, "to_mm": 0.5, "rms_nm": 90.3}],
            "brand_new_block": 42
        });
        let path = write_diagnosis_html(&dir, &doc).unwrap();
        let html = std::fs::read_to_string(path).unwrap();
        assert!(html.contains("Centre height &lt;3 µm&gt; explains it."));
        assert!(html.contains("axis_x_mm") && html.contains("40.90"));
        assert!(!html.contains("<script"), "no script in a report");
        assert!(
            !html.contains("http://")
                || html.matches("http://").count()
                    == html.matches("xmlns=\"http://www.w3.org/2000/svg\"").count()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}

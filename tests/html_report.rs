//! The HTML reports of run, diagnose, compensate and correct, opened in a real headless
//! browser (Debian's `chromium`, installed by the test command): each page loads with
//! no console message (the reports have no script, so any message is an error: a
//! resource that failed), every image decodes (checked by the browser and again here
//! with the png crate), and a screenshot of each is kept under
//! `target/report-screenshots/`. Fails, never skips, when chromium is missing.

use std::path::{Path, PathBuf};
use std::process::Command;

fn toolmark(args: &[&str]) {
    let output = Command::new(env!("CARGO_BIN_EXE_toolmark"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("toolmark runs");
    assert!(
        output.status.success(),
        "toolmark {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("toolmark-html-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn chromium() -> &'static str {
    for candidate in ["/usr/bin/chromium", "/usr/bin/chromium-browser"] {
        if Path::new(candidate).exists() {
            return candidate;
        }
    }
    panic!("chromium is not installed: the README's test command installs Debian's chromium");
}

/// The browser's checks of one report: console messages, images decoded, screenshot.
fn check_in_browser(report: &Path, shot_name: &str) {
    let html = std::fs::read_to_string(report).unwrap();
    assert!(!html.contains("<script"), "reports carry no script");
    assert!(!html.contains("src=\"http"), "no network fetch");
    // Every inline image decodes as a PNG here too.
    let mut images = 0;
    for part in html.split("src=\"data:image/png;base64,").skip(1) {
        use base64::Engine as _;
        let data = &part[..part.find('"').unwrap()];
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(data)
            .unwrap();
        image::load_from_memory(&bytes).expect("an inline image decodes");
        images += 1;
    }
    assert!(images >= 1, "{}: no image", report.display());
    // A test-side copy with a probe script that writes the browser's own verdict on the
    // images into the title, which --dump-dom prints.
    let probe = report.with_file_name(format!("probe-{shot_name}.html"));
    let script = "<script>window.addEventListener('load',()=>{const i=[...document.images];\
        document.title='IMAGES '+i.filter(x=>x.complete&&x.naturalWidth>0).length+'/'+i.length;});</script>";
    std::fs::write(&probe, html.replace("</body>", &format!("{script}</body>"))).unwrap();
    let output = Command::new(chromium())
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=5000",
            "--dump-dom",
        ])
        .arg(format!("file://{}", probe.display()))
        .output()
        .expect("chromium runs");
    let dom = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let expected = format!("IMAGES {images}/{images}");
    assert!(
        dom.contains(&expected),
        "{shot_name}: the browser decoded fewer images than {expected}"
    );
    let console: Vec<&str> = stderr.lines().filter(|l| l.contains(":CONSOLE")).collect();
    assert!(
        console.is_empty(),
        "{shot_name}: console messages {console:?}"
    );
    // The screenshot of the report itself, kept as an artifact.
    let shots = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/report-screenshots");
    std::fs::create_dir_all(&shots).unwrap();
    let shot = shots.join(format!("{shot_name}.png"));
    let _ = std::fs::remove_file(&shot);
    let output = Command::new(chromium())
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--window-size=1280,2400",
        ])
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}", report.display()))
        .output()
        .expect("chromium runs");
    assert!(
        shot.is_file(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let picture = image::open(&shot).unwrap().to_rgb8();
    assert_eq!(picture.dimensions(), (1280, 2400));
    // Not a blank page: the screenshot holds ink and colour.
    let coloured = picture
        .pixels()
        .filter(|p| p.0.iter().max() != p.0.iter().min())
        .count();
    assert!(coloured > 10_000, "{shot_name}: screenshot looks empty");
}

#[test]
fn run_report_of_a_milling_job_opens_in_a_browser() {
    let dir = temp("run");
    toolmark(&[
        "run",
        "examples/milling_ball_feed_marks.toml",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    // The verdict first, then the texture figures every metrology package reports.
    let verdict = html.find("class=\"verdict\"").unwrap();
    assert!(verdict < html.find("<h2>").unwrap());
    for needle in ["Sa", "Sq", "Sz", "Ssk", "Sku", "Ra", "Rz", "Zernike", "PSD"] {
        assert!(html.contains(needle), "{needle} missing");
    }
    check_in_browser(&dir.join("report.html"), "run-milling-feed-marks");
}

#[test]
fn diagnosis_report_of_cut_1021_opens_in_a_browser() {
    let dir = temp("diagnose");
    toolmark(&[
        "diagnose",
        "--job",
        "examples/upm_1021_ideal.toml",
        "--measured",
        "data/upm-spdt/1021-WLI-2D.csv",
        "--lateral-unit",
        "um",
        "--height-unit",
        "um",
        "--remove-power",
        "--engine",
        "cpu",
        "--out",
        dir.to_str().unwrap(),
    ]);
    toolmark(&["report", dir.to_str().unwrap()]);
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    // The diagnosis's own sentence leads; the accepted effect carries its σ.
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("diagnosis.json")).unwrap())
            .unwrap();
    let sentence = doc["verdict"]["sentence"].as_str().unwrap();
    let escaped = toolmark::output::html::escape(sentence);
    assert!(html.find(&escaped).unwrap() < html.find("<h2>").unwrap());
    assert!(html.contains(" ± "), "σ of the fitted parameters");
    check_in_browser(&dir.join("report.html"), "diagnose-1021");
}

#[test]
fn compensate_and_correct_reports_open_in_a_browser() {
    let dir = temp("compensate");
    toolmark(&[
        "compensate",
        "examples/asphere_xz_with_errors.toml",
        "--cycles",
        "1",
        "--engine",
        "cpu",
        "--out",
        dir.to_str().unwrap(),
    ]);
    check_in_browser(&dir.join("report.html"), "compensate");
    let dir = temp("correct");
    toolmark(&[
        "correct",
        "examples/seed000_generator_before.toml",
        "--engine",
        "cpu",
        "--out",
        dir.to_str().unwrap(),
    ]);
    check_in_browser(&dir.join("report.html"), "correct");
}

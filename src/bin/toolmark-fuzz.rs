//! Mutation fuzzing of every reader on stable Rust: job TOML, effects files, NC programs,
//! CSV/XYZ profiles, CSV grids, X3P, GSF, EXR and measured tool edges.
//!
//! ```sh
//! cargo run --release --bin toolmark-fuzz -- --inputs 1000000            # every reader
//! cargo run --release --bin toolmark-fuzz -- --inputs 20000 --reader x3p
//! ```
//! Each reader starts from the repository's own corpus (examples, the invalid-job corpus,
//! the measured-data fixtures, cut 1021's files) and feeds it mutated inputs: bit flips,
//! byte insertions and deletions, duplicated and spliced chunks, numbers replaced by
//! extreme ones (0, −1, 1e308, NaN, 65536, …). Each input runs under `catch_unwind`, is
//! timed, and its peak heap is measured by a counting allocator. A panic, an input over
//! 1 s, or a peak over the declared bound (256 MiB, from inputs of at most a few hundred
//! kB) is a finding: the input is saved to `target/fuzz-findings/<reader>/` and the run
//! exits non-zero. Deterministic: the seed is fixed (`--seed`).

use std::alloc::{GlobalAlloc, Layout, System};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use toolmark::formats::measured::{
    LengthUnit, ReadOptions, read_edge_csv_str, read_measured_bytes,
};
use toolmark::model::{EffectsFragment, Job};

/// Heap bytes in use, and the peak since the last reset (per process: the harness runs
/// one input at a time per thread, and both threads' peaks count against the bound).
struct Counting;
static IN_USE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let now = IN_USE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        PEAK.fetch_max(now, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        IN_USE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            let grow = new_size - layout.size();
            let now = IN_USE.fetch_add(grow, Ordering::Relaxed) + grow;
            PEAK.fetch_max(now, Ordering::Relaxed);
        } else {
            IN_USE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
        }
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The declared bound on one input's peak heap (above what the harness itself holds).
const HEAP_BOUND: usize = 256 << 20;
/// An input slower than this is a hang (`--hang-ms`; 1 s by default).
const HANG_MS: u64 = 1000;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reader {
    Job,
    Effects,
    Nc,
    Profile,
    Grid,
    X3p,
    Gsf,
    Exr,
    Edge,
}

const READERS: [Reader; 9] = [
    Reader::Job,
    Reader::Effects,
    Reader::Nc,
    Reader::Profile,
    Reader::Grid,
    Reader::X3p,
    Reader::Gsf,
    Reader::Exr,
    Reader::Edge,
];

impl Reader {
    fn name(self) -> &'static str {
        match self {
            Reader::Job => "job",
            Reader::Effects => "effects",
            Reader::Nc => "nc",
            Reader::Profile => "profile",
            Reader::Grid => "grid",
            Reader::X3p => "x3p",
            Reader::Gsf => "gsf",
            Reader::Exr => "exr",
            Reader::Edge => "edge",
        }
    }

    /// Runs the reader on one input; the result is dropped (errors are the expected
    /// outcome of most mutations).
    fn read(self, bytes: &[u8], base_dir: &Path, declared: bool) {
        let text = || String::from_utf8_lossy(bytes);
        let options = if declared {
            ReadOptions {
                lateral_unit: Some(LengthUnit::Micrometre),
                height_unit: Some(LengthUnit::Nanometre),
                pixel_mm: Some((0.001, 0.001)),
            }
        } else {
            ReadOptions::default()
        };
        let measured = |extension: &str| {
            let name = PathBuf::from(format!("input.{extension}"));
            let _ = read_measured_bytes(&name, bytes, &options);
        };
        match self {
            Reader::Job => {
                let _ = Job::from_toml_in(&text(), "fuzz", base_dir);
            }
            Reader::Effects => {
                let _ = EffectsFragment::from_toml_str(&text());
            }
            Reader::Nc => {
                let _ = toolmark::formats::nc::parse_nc(&text());
            }
            Reader::Profile => measured("csv"),
            Reader::Grid => measured("csv"),
            Reader::X3p => measured("x3p"),
            Reader::Gsf => measured("gsf"),
            Reader::Exr => measured("exr"),
            Reader::Edge => {
                let _ = read_edge_csv_str(&text());
            }
        }
    }
}

/// A seed input and the folder its file names resolve against.
struct Seed {
    bytes: Vec<u8>,
    base_dir: PathBuf,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn files(dir: &str, extension: &str) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(root().join(dir))
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == extension))
                .collect()
        })
        .unwrap_or_default();
    found.sort();
    found
}

/// The first `lines` lines of a large text file (whole files of 0.6 MB would make each
/// input cost milliseconds); small files whole.
fn head(path: &Path, lines: usize) -> Vec<u8> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let mut out: String = text.lines().take(lines).collect::<Vec<_>>().join("\n");
    out.push('\n');
    out.into_bytes()
}

fn seeds(reader: Reader) -> Vec<Seed> {
    let whole = |path: PathBuf| Seed {
        bytes: std::fs::read(&path).unwrap_or_default(),
        base_dir: path.parent().unwrap_or(Path::new(".")).to_path_buf(),
    };
    let heads = |paths: Vec<PathBuf>, lines: usize| -> Vec<Seed> {
        paths
            .into_iter()
            .map(|p| Seed {
                bytes: head(&p, lines),
                base_dir: p.parent().unwrap_or(Path::new(".")).to_path_buf(),
            })
            .collect()
    };
    let measured = |names: &[&str]| -> Vec<Seed> {
        names
            .iter()
            .map(|n| whole(root().join("tests/data/measured").join(n)))
            .collect()
    };
    let mut seeds: Vec<Seed> = match reader {
        Reader::Job => files("examples", "toml")
            .into_iter()
            .chain(files("tests/invalid_jobs", "toml"))
            .map(whole)
            .collect(),
        Reader::Effects => files("examples", "toml")
            .into_iter()
            .chain(files("tests/invalid_jobs", "toml"))
            .filter_map(|p| {
                let text = std::fs::read_to_string(&p).ok()?;
                let at = text.find("[[effects]]")?;
                Some(Seed {
                    bytes: text.as_bytes()[at..].to_vec(),
                    base_dir: root(),
                })
            })
            .collect(),
        Reader::Nc => heads(files("data/upm-spdt", "nc"), 400)
            .into_iter()
            .chain(files("tests/invalid_jobs/nc", "nc").into_iter().map(whole))
            .collect(),
        Reader::Profile => {
            let mut s = measured(&["sample_profile.csv", "sample_line.xyz"]);
            s.extend(heads(
                vec![root().join("data/upm-spdt/1021-WLI-2D.csv")],
                300,
            ));
            s
        }
        Reader::Grid => measured(&["sample_grid.csv", "sample_grid.xyz"]),
        Reader::X3p => measured(&[
            "sample.x3p",
            "sample_absolute.x3p",
            "sample_inline.x3p",
            "sample_int.x3p",
            "sample_no_main.x3p",
            "sample_prf.x3p",
        ]),
        Reader::Gsf => measured(&["sample.gsf"]),
        Reader::Exr => measured(&["sample.exr"]),
        Reader::Edge => heads(files("data/upm-spdt", "csv"), 400)
            .into_iter()
            .filter(|s| !s.bytes.starts_with(b"X"))
            .collect(),
    };
    seeds.retain(|s| !s.bytes.is_empty());
    seeds
}

/// xorshift64*: small, deterministic, good enough to pick mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1e308",
    "-1e308",
    "1e-308",
    "NaN",
    "inf",
    "-inf",
    "65536",
    "4294967296",
    "18446744073709551616",
    "3.4028235e38",
    "1e37",
    "0.0000001",
    "999999999",
    "2",
    "1,5",
    "",
];

/// One to four stacked mutations of `seed`, sometimes spliced with `other`.
fn mutate(seed: &[u8], other: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut data = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = data.len();
        match rng.below(9) {
            0 if len > 0 => {
                let at = rng.below(len);
                data[at] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let at = rng.below(len);
                data[at] = rng.next() as u8;
            }
            2 => {
                let at = rng.below(len + 1);
                data.insert(at, rng.next() as u8);
            }
            3 if len > 0 => {
                let at = rng.below(len);
                let end = (at + 1 + rng.below(64)).min(len);
                data.drain(at..end);
            }
            4 if len > 0 => {
                let at = rng.below(len);
                let end = (at + 1 + rng.below(256)).min(len);
                let chunk = data[at..end].to_vec();
                let to = rng.below(len + 1);
                data.splice(to..to, chunk);
            }
            5 if !other.is_empty() => {
                let at = rng.below(len + 1);
                let from = rng.below(other.len());
                let end = (from + 1 + rng.below(512)).min(other.len());
                data.truncate(at);
                data.extend_from_slice(&other[from..end]);
            }
            6 => replace_number(&mut data, rng),
            7 if len > 0 => data.truncate(rng.below(len)),
            _ => {
                // Interesting binary values at a random offset (sizes, counts, offsets).
                let values: [u32; 6] = [0, 1, 0x7FFF_FFFF, 0xFFFF_FFFF, 0x8000_0000, 0x10000];
                let value = values[rng.below(values.len())].to_le_bytes();
                if len >= 4 {
                    let at = rng.below(len - 3);
                    data[at..at + 4].copy_from_slice(&value);
                }
            }
        }
    }
    data
}

/// Replaces one run of digits (with its sign, point and exponent) by an extreme number.
fn replace_number(data: &mut Vec<u8>, rng: &mut Rng) {
    let starts: Vec<usize> = (0..data.len())
        .filter(|&i| data[i].is_ascii_digit() && (i == 0 || !data[i - 1].is_ascii_digit()))
        .collect();
    if starts.is_empty() {
        return;
    }
    let start = starts[rng.below(starts.len())];
    let mut end = start;
    while end < data.len() && (data[end].is_ascii_digit() || b".eE+-".contains(&data[end])) {
        end += 1;
    }
    let number = NUMBERS[rng.below(NUMBERS.len())].as_bytes();
    data.splice(start..end, number.iter().copied());
}

#[derive(Default, Debug)]
struct Tally {
    inputs: u64,
    panics: u64,
    hangs: u64,
    over_bound: u64,
    slowest: Duration,
    peak_heap: usize,
}

fn save(reader: Reader, kind: &str, index: u64, bytes: &[u8]) -> PathBuf {
    let dir = root().join("target/fuzz-findings").join(reader.name());
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join(format!("{kind}-{index}.bin"));
    let _ = std::fs::write(&path, bytes);
    path
}

fn fuzz(reader: Reader, inputs: u64, seed: u64, threads: u64, hang: Duration) -> Tally {
    let corpus = seeds(reader);
    assert!(!corpus.is_empty(), "{}: no corpus", reader.name());
    let tallies: Vec<Tally> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let corpus = &corpus;
                scope.spawn(move || {
                    let mut rng = Rng(seed ^ (t + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
                    let mut tally = Tally::default();
                    let share = inputs / threads + u64::from(t < inputs % threads);
                    for index in 0..share {
                        let a = &corpus[rng.below(corpus.len())];
                        let b = &corpus[rng.below(corpus.len())];
                        let input = mutate(&a.bytes, &b.bytes, &mut rng);
                        let declared = rng.below(2) == 0;
                        let base = IN_USE.load(Ordering::Relaxed);
                        PEAK.store(base, Ordering::Relaxed);
                        let started = Instant::now();
                        let outcome = catch_unwind(AssertUnwindSafe(|| {
                            reader.read(&input, &a.base_dir, declared)
                        }));
                        let took = started.elapsed();
                        let heap = PEAK.load(Ordering::Relaxed).saturating_sub(base);
                        tally.inputs += 1;
                        tally.slowest = tally.slowest.max(took);
                        tally.peak_heap = tally.peak_heap.max(heap);
                        let index = t * inputs + index;
                        if outcome.is_err() {
                            tally.panics += 1;
                            let path = save(reader, "panic", index, &input);
                            eprintln!(
                                "{}: PANIC, input saved to {}",
                                reader.name(),
                                path.display()
                            );
                        }
                        if took > hang {
                            tally.hangs += 1;
                            let path = save(reader, "slow", index, &input);
                            eprintln!(
                                "{}: {took:?}, input saved to {}",
                                reader.name(),
                                path.display()
                            );
                        }
                        if heap > HEAP_BOUND {
                            tally.over_bound += 1;
                            let path = save(reader, "heap", index, &input);
                            eprintln!(
                                "{}: {heap} bytes, input saved to {}",
                                reader.name(),
                                path.display()
                            );
                        }
                    }
                    tally
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_default())
            .collect()
    });
    tallies.into_iter().fold(Tally::default(), |a, b| Tally {
        inputs: a.inputs + b.inputs,
        panics: a.panics + b.panics,
        hangs: a.hangs + b.hangs,
        over_bound: a.over_bound + b.over_bound,
        slowest: a.slowest.max(b.slowest),
        peak_heap: a.peak_heap.max(b.peak_heap),
    })
}

fn main() -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let inputs: u64 = value("--inputs")
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let seed: u64 = value("--seed").and_then(|v| v.parse().ok()).unwrap_or(15);
    let threads: u64 = value("--threads")
        .and_then(|v| v.parse().ok())
        .unwrap_or(2)
        .max(1);
    let only = value("--reader");
    let hang_ms: u64 = value("--hang-ms")
        .and_then(|v| v.parse().ok())
        .unwrap_or(HANG_MS);
    if let Some(file) = value("--replay") {
        // Re-run one saved input alone (a slow input found under load is re-timed here).
        let reader = READERS
            .into_iter()
            .find(|r| only.as_deref() == Some(r.name()))
            .expect("--replay needs --reader NAME");
        let bytes = std::fs::read(&file).expect("readable input");
        let base = root().join("examples");
        let started = Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(|| reader.read(&bytes, &base, false)));
        println!(
            "{file}: {:.1} ms{}",
            started.elapsed().as_secs_f64() * 1e3,
            if outcome.is_err() { ", PANIC" } else { "" }
        );
        return std::process::ExitCode::SUCCESS;
    }
    // Panics are counted and their inputs saved; their messages would flood the terminal.
    std::panic::set_hook(Box::new(|_| {}));
    println!(
        "| reader | inputs | panics | inputs over {hang_ms} ms | over {} MiB heap | slowest input | peak heap |",
        HEAP_BOUND >> 20
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    let mut clean = true;
    for reader in READERS {
        if only.as_deref().is_some_and(|o| o != reader.name()) {
            continue;
        }
        let started = Instant::now();
        let t = fuzz(
            reader,
            inputs,
            seed,
            threads,
            Duration::from_millis(hang_ms),
        );
        clean &= t.panics == 0 && t.hangs == 0 && t.over_bound == 0;
        println!(
            "| {} | {} | {} | {} | {} | {:.1} ms | {:.1} MiB | ({:.0} s)",
            reader.name(),
            t.inputs,
            t.panics,
            t.hangs,
            t.over_bound,
            t.slowest.as_secs_f64() * 1e3,
            t.peak_heap as f64 / (1 << 20) as f64,
            started.elapsed().as_secs_f64()
        );
    }
    if clean {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::FAILURE
    }
}

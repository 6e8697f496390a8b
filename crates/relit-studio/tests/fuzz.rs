//! Fuzzing of relit's text parsers on the stable toolchain, as ordinary tests.
//!
//! Harness: a small deterministic mutation fuzzer (no coverage feedback) instead of
//! cargo-fuzz (libFuzzer needs nightly) or cargo-afl (an extra toolchain to install):
//! it runs everywhere `cargo test` runs, replays its seeds in CI, and a long run is one
//! environment variable away. Each target starts from seeds — valid inputs made the way
//! relit makes them, plus the shared RealRTI `.lp` files read in place when
//! `../shared/data` is present — and feeds the parser mutants of them (bit flips, byte
//! changes, deletions, duplications, splices between seeds, and tokens that break
//! parsers: `nan`, `1e999`, `-0`, 2⁶⁴, deep nesting, quotes). A parser may return any
//! error; it must not panic. A panic fails the test and prints the input.
//!
//! Each target's committed corpus (`tests/corpus/<target>/`, written from the seeds with
//! `RELIT_FUZZ_WRITE_CORPUS=1`; shared-data files are read in place, never copied) is
//! replayed before the mutants, here and in `fuzz_files.rs`, so CI replays it on every
//! run; an input that ever breaks a parser goes there as a regression.
//!
//! `RELIT_FUZZ_EXECS=N` sets the mutants per target (default 3,000 in the test run) and
//! `RELIT_FUZZ_TARGETS=a,b` limits the run to those targets;
//! `RELIT_FUZZ_EXECS=10000000 cargo test --release -p relit-studio --test fuzz --
//! --nocapture` is the long run, and prints executions and seconds per target.
//!
//! Targets (10): `.lp` files, light-rig and animation JSON, `--light` specs, basis names
//! (parsed and, for analytic families, built), stored basis specs (JSON, rebuilt), light
//! plans (`grid:`/`fibonacci:`/`hemisphere:`), `list:` direction files, image sizes, and
//! the RTI tools' binary `.ptm` and `.rti` files (decoded from memory).

mod common;

use common::Rng;
use relit::basis::{BasisChoice, BasisSpec};
use relit::light::Light;
use relit::light::RigFile;
use relit_studio::plan::{parse_list, LightPlan};
use relit_studio::setup::parse_size;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::Instant;

const TOKENS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e999",
    "-1e999",
    "-0",
    "0",
    "18446744073709551616",
    "4294967296",
    "1073741824",
    "-1",
    "\"",
    "\\",
    "[",
    "]",
    "{",
    "}",
    ",",
    ":",
    "\n",
    " ",
    "\0",
    "é",
    "[[[[[[[[[[[[[[[[",
    "null",
    "true",
    "1e-320",
    "0x10",
    "+",
    ".",
];

fn mutate(seeds: &[Vec<u8>], rng: &mut Rng) -> Vec<u8> {
    let mut v = seeds[rng.below(seeds.len())].clone();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(v.len() + 1);
        match rng.below(7) {
            0 if !v.is_empty() => {
                let i = at.min(v.len() - 1);
                v[i] ^= 1 << rng.below(8);
            }
            1 if !v.is_empty() => {
                let i = at.min(v.len() - 1);
                v[i] = rng.next() as u8;
            }
            2 => {
                let end = (at + 1 + rng.below(16)).min(v.len());
                v.drain(at.min(end)..end);
            }
            3 => {
                let token = TOKENS[rng.below(TOKENS.len())].as_bytes();
                v.splice(at..at, token.iter().copied());
            }
            4 => {
                let end = (at + 1 + rng.below(32)).min(v.len());
                let part = v[at.min(end)..end].to_vec();
                v.splice(at..at, part);
            }
            5 => {
                let other = &seeds[rng.below(seeds.len())];
                let from = rng.below(other.len() + 1);
                v.truncate(at);
                v.extend_from_slice(&other[from..]);
            }
            _ => v.truncate(at),
        }
        if v.len() > 1 << 16 {
            v.truncate(1 << 16);
        }
    }
    v
}

fn execs() -> usize {
    std::env::var("RELIT_FUZZ_EXECS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3_000)
}

/// Feed `target` its seeds, then `execs()` mutants; returns the inputs that panicked.
fn fuzz(name: &str, seeds: Vec<Vec<u8>>, target: fn(&[u8])) -> Vec<String> {
    fuzz_with(name, seeds, Vec::new(), target)
}

/// [`fuzz`] with `read_in_place` seeds too: files read where they are (the shared
/// data), never stored in the committed corpus.
fn fuzz_with(
    name: &str,
    seeds: Vec<Vec<u8>>,
    read_in_place: Vec<Vec<u8>>,
    target: fn(&[u8]),
) -> Vec<String> {
    // `RELIT_FUZZ_TARGETS=ptm,rti` runs only those (a long run of new targets).
    if let Ok(only) = std::env::var("RELIT_FUZZ_TARGETS") {
        if !only.split(',').any(|t| t.trim() == name) {
            return Vec::new();
        }
    }
    common::store_corpus(name, &seeds);
    let mut seeds = seeds;
    seeds.extend(read_in_place);
    seeds.extend(common::corpus(name));
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ name.len() as u64);
    let mut crashes = Vec::new();
    let n = execs();
    let start = Instant::now();
    let inputs = seeds
        .clone()
        .into_iter()
        .chain((0..n).map(|_| mutate(&seeds, &mut rng)));
    for input in inputs {
        if catch_unwind(AssertUnwindSafe(|| target(&input))).is_err() {
            crashes.push(format!("{name}: {:?}", String::from_utf8_lossy(&input)));
            if crashes.len() >= 5 {
                break;
            }
        }
    }
    eprintln!(
        "fuzz {name}: {} seeds + {n} mutants in {:.1} s, {} panics",
        seeds.len(),
        start.elapsed().as_secs_f64(),
        crashes.len()
    );
    crashes
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The `.lp` files of the shared RealRTI items, read in place (never copied).
fn shared_lp_seeds() -> Vec<Vec<u8>> {
    let root =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/realrti");
    let mut seeds = Vec::new();
    for item in ["item1", "item7", "item9"] {
        if let Ok(bytes) = std::fs::read(root.join(item).join("dirs.lp")) {
            seeds.push(bytes);
        }
    }
    seeds
}

/// Small `.ptm` (LRGB, RGB and JPEG LRGB) and `.rti` files written by relit, as seeds.
fn rti_file_seeds() -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
    let image = |basis: &str| {
        let spec = BasisSpec::named(basis).unwrap();
        let k = spec.build().unwrap().len();
        let mut maps = CoefficientMaps::zeros(5, 4, k);
        for (i, v) in maps.data.iter_mut().enumerate() {
            *v = ((i * 37) % 101) as f32 / 200.0;
        }
        RelightableImage {
            meta: Metadata::new(spec, MapSpace::Srgb, Default::default()),
            maps,
            depth: None,
        }
    };
    let ptm = image("ptm:6");
    let ptm_seeds = [
        relit::codec::ptm::PtmFormat::Lrgb,
        relit::codec::ptm::PtmFormat::Rgb,
        relit::codec::ptm::PtmFormat::JpegLrgb(90),
    ]
    .map(|f| relit::codec::ptm::encode(&ptm, f).unwrap())
    .to_vec();
    let rti_seeds = ["hsh:4", "hsh:9"]
        .map(|b| relit::codec::rti::encode(&image(b)).unwrap())
        .to_vec();
    (ptm_seeds, rti_seeds)
}

#[test]
fn no_parser_panics_on_mutated_input() {
    // The harness reports panics itself; the default hook would print each one.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut crashes = Vec::new();

    let lp = vec![
        b"3\nlight 000.png 0.1 0.2 0.97\nlight 001.png -0.5 0 0.866\n\"a b.png\" 0 0 1\n".to_vec(),
        b"2\r\nx.jpg 0 0.6 0.8\r\ny.jpg 0.6 0 0.8\r\n".to_vec(),
    ];
    crashes.extend(fuzz_with("lp", lp, shared_lp_seeds(), |b| {
        let _ = relit::capture::lp::parse(&text(b), "fuzz.lp");
    }));

    crashes.extend(fuzz(
        "rig",
        vec![
            br#"{"lights":[{"type":"directional","direction":[0,0,1],"color":[1,0.9,0.8],"intensity":2}]}"#.to_vec(),
            br#"{"lights":[{"type":"point","position":[0,1,1]},{"type":"spot","position":[0,1,1],"direction":[0,-1,0],"cone_deg":30,"softness_deg":5},{"type":"area","shape":{"rect":{"center":[0,1,0],"u":[0.3,0,0],"v":[0,0,0.2]}},"samples":16},{"type":"environment","map":"sky.hdr","yaw_deg":30}]}"#.to_vec(),
            br#"{"keyframes":[{"time":0,"lights":[{"type":"point","position":[0,1,1]}]},{"time":1,"lights":[{"type":"point","position":[1,1,1]}]}]}"#.to_vec(),
        ],
        |b| {
            let _ = RigFile::parse(&text(b), "fuzz.json");
        },
    ));

    crashes.extend(fuzz(
        "light spec",
        vec![
            b"dir:0,0,1".to_vec(),
            b"point:0.1,1,2".to_vec(),
            b"spot:0,1,1/0,-1,0/30".to_vec(),
        ],
        |b| {
            let _ = Light::parse_spec(&text(b));
        },
    ));

    crashes.extend(fuzz(
        "basis name",
        vec![
            b"sh:25".to_vec(),
            b"sg:25:centres=hemisphere,width=0.75".to_vec(),
            b"hsh:16".to_vec(),
            b"ptm:6".to_vec(),
            b"rbf:18:centres=64".to_vec(),
            b"bilinear:9:grid=8".to_vec(),
        ],
        |b| {
            if let Ok(choice) = BasisChoice::parse(&text(b)) {
                // Analytic families build without a capture; data-driven ones must refuse.
                if choice.k <= 64 && !choice.needs_samples() {
                    let dirs = relit::sphere::hemisphere_fibonacci(48);
                    let _ = choice.build(&dirs, None);
                }
            }
        },
    ));

    let spec_seeds: Vec<Vec<u8>> = ["sh:9", "hsh:9", "sg:9", "ptm:6"]
        .iter()
        .map(|n| {
            let dirs = relit::sphere::hemisphere_fibonacci(48);
            let basis = BasisChoice::parse(n).unwrap().build(&dirs, None).unwrap();
            serde_json::to_vec(&basis.spec()).unwrap()
        })
        .collect();
    crashes.extend(fuzz("basis spec", spec_seeds, |b| {
        if let Ok(spec) = serde_json::from_slice::<BasisSpec>(b) {
            let _ = spec.build();
        }
    }));

    crashes.extend(fuzz(
        "light plan",
        vec![
            b"fibonacci:300".to_vec(),
            b"grid:8x16".to_vec(),
            b"hemisphere:48".to_vec(),
        ],
        |b| {
            let s = text(b);
            // `list:` reads a file named by the input: the list target covers its text.
            if !s.trim_start().to_ascii_lowercase().starts_with("list") {
                let _ = LightPlan::parse(&s);
            }
        },
    ));

    crashes.extend(fuzz(
        "direction list",
        vec![
            b"0 0 1\n0 1 1\n1 1 1\n".to_vec(),
            b"[[0,0,1],[0.5,0.5,0.7]]".to_vec(),
            b"# comment\n0.1, 0.2, 0.9\n".to_vec(),
        ],
        |b| {
            let _ = parse_list(&text(b), "fuzz.txt");
        },
    ));

    crashes.extend(fuzz(
        "image size",
        vec![b"1024x256".to_vec(), b"512X128".to_vec()],
        |b| {
            let _ = parse_size(&text(b));
        },
    ));

    // The RTI tools' binary files, decoded from memory (fast enough for long runs).
    let rti_seeds = rti_file_seeds();
    crashes.extend(fuzz("ptm", rti_seeds.0, |b| {
        let _ = relit::codec::ptm::decode(std::path::Path::new("fuzz.ptm"), b);
    }));
    crashes.extend(fuzz("rti", rti_seeds.1, |b| {
        let _ = relit::codec::rti::decode(std::path::Path::new("fuzz.rti"), b);
    }));

    std::panic::set_hook(hook);
    assert!(
        crashes.is_empty(),
        "parsers panicked on:\n{}",
        crashes.join("\n")
    );
}

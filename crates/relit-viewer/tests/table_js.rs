//! The viewer's JavaScript against the library: `assets/table.js` decodes the shipped
//! half-float table and samples it exactly as `WeightTable::sample`, `assets/vec.js` turns environments as
//! `EnvironmentMapLight::rotation`, and `assets/environment.js` sums a shipped
//! environment's quadrature as the documented formula says and close to the weights
//! the library gives (for SH, which the library projects and rotates exactly). Runs the
//! modules in Node; without `node` on the PATH it prints why it skipped and passes.

mod common;

use relit::basis::mat3_apply;
use relit::basis::{Basis, BasisSpec, WeightTable};
use relit::envmap::{EnvironmentLight, Window};
use relit::image::ImageRgb;
use relit::light::EnvironmentMapLight;
use relit::sphere::{fibonacci, Vec3};
use relit_viewer::bundle::{
    environment_quadrature, shipped_table, QUADRATURE_HEIGHT, QUADRATURE_WIDTH,
};
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;

/// |JavaScript − Rust| of a table's weights, relative to the table's largest weight:
/// the lookup is the same arithmetic, JavaScript in f64 where `corners` casts the
/// bilinear weights to f32 (relative error 6e-8).
const SAMPLE_TOLERANCE: f64 = 1e-6;

/// |JavaScript − Rust| of an environment's weights through the same quadrature and
/// table, relative to the largest weight: sums of thousands of f64 products of f32 data.
const QUADRATURE_TOLERANCE: f64 = 1e-6;

/// |quadrature − exact| of an environment's SH weights, relative to the largest weight.
/// Measured on the 512×256 sky below (a sun of 40 times the sky's radiance), 4 bands,
/// three rotations, through the shipped 128×64 quadrature: at most 9.1e-4 with the
/// basis itself (what the library's quadrature gives other bases), 5.4e-4 with the
/// table's weights as the viewer takes them (half floats).
const ENVIRONMENT_TOLERANCE: f64 = 2e-3;

/// Run `script` (an ES module; `ASSETS` is the URL of the viewer's assets, `INPUT` the
/// parsed input) in Node and parse what it prints, or `None` without Node.
fn node(script: &str, input: &Value) -> Option<Value> {
    let dir = tempfile::tempdir().unwrap();
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let input_file = dir.path().join("input.json");
    std::fs::write(&input_file, input.to_string()).unwrap();
    let module = dir.path().join("run.mjs");
    std::fs::write(
        &module,
        format!(
            "import fs from 'node:fs';\nconst ASSETS = {:?};\nconst INPUT = JSON.parse(fs.readFileSync({:?}, 'utf8'));\n{script}",
            format!("file://{}/", assets.display()),
            input_file.display().to_string()
        ),
    )
    .unwrap();
    let out = match Command::new("node").arg(&module).output() {
        Ok(out) => out,
        Err(e) => {
            relit::skip::skipping(&format!("the JavaScript checks: cannot run node ({e})"));
            return None;
        }
    };
    assert!(
        out.status.success(),
        "node failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(serde_json::from_slice(&out.stdout).expect("node prints JSON"))
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn sh(k: usize) -> Box<dyn Basis> {
    BasisSpec::named(&format!("sh:{k}"))
        .unwrap()
        .build()
        .unwrap()
}

/// The table as the viewer receives it: its half-float bits, which the JavaScript
/// decodes itself.
fn table_json(table: &WeightTable) -> Value {
    let bits: Vec<u16> = table
        .values
        .iter()
        .map(|&v| half::f16::from_f32(v).to_bits())
        .collect();
    json!({ "n": table.resolution, "k": table.k, "bits": bits })
}

#[test]
fn table_js_samples_as_the_rust_table() {
    // Directions everywhere, the poles, the axes, the octahedron's folds and edges.
    let mut dirs = fibonacci(300);
    let s = std::f64::consts::FRAC_1_SQRT_2;
    for d in [
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [s, -s, 0.0],
        [-s, 0.0, -s],
        [0.0, s, -s],
        [0.6, 0.0, -0.8],
    ] {
        dirs.push(Vec3::new(d[0], d[1], d[2]));
    }
    let bases: Vec<Box<dyn Basis>> = vec![sh(16), sh(25), Box::new(common::Lobes::new(7))];
    for basis in bases {
        let (table, _) = WeightTable::for_basis(basis.as_ref());
        let table = shipped_table(&table);
        let input = json!({
            "table": table_json(&table),
            "dirs": dirs.iter().map(|d| [d.x, d.y, d.z]).collect::<Vec<_>>(),
        });
        let Some(out) = node(
            "const { weightTable, halvesToFloats, sample } = await import(ASSETS + 'table.js');\n\
             const t = weightTable(INPUT.table.n, INPUT.table.k, halvesToFloats(Uint16Array.from(INPUT.table.bits)));\n\
             console.log(JSON.stringify(INPUT.dirs.map(d => Array.from(sample(t, d)))));",
            &input,
        ) else {
            return;
        };
        let largest = table.values.iter().fold(0f64, |m, v| m.max(v.abs() as f64));
        let mut want = vec![0f32; table.k];
        let mut worst = 0f64;
        for (d, got) in dirs.iter().zip(out.as_array().unwrap()) {
            table.sample(*d, &mut want);
            for (g, w) in floats(got).iter().zip(&want) {
                worst = worst.max((g - *w as f64).abs() / largest);
            }
        }
        eprintln!(
            "{}: |table.js − WeightTable::sample| ≤ {worst:.1e} of the largest weight",
            basis.name()
        );
        assert!(worst <= SAMPLE_TOLERANCE, "{}: {worst}", basis.name());
    }
}

/// An environment with a sky, a ground and a small bright sun: what the quadrature
/// must integrate sharply.
fn sky(w: usize, h: usize) -> ImageRgb {
    let mut map = ImageRgb::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = ((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
            let sun = (u - 0.65).hypot(v - 0.3) < 0.04;
            let rgb = if sun {
                [40.0, 35.0, 25.0]
            } else if v < 0.5 {
                [0.3 + 0.4 * u as f32, 0.45, 0.8]
            } else {
                [0.12, 0.1, 0.08]
            };
            let i = 3 * (y * w + x);
            map.data[i..i + 3].copy_from_slice(&rgb);
        }
    }
    map
}

#[test]
fn environment_js_gives_the_library_weights() {
    let map = sky(512, 256);
    let lights = environment_quadrature(&map, QUADRATURE_WIDTH, QUADRATURE_HEIGHT);
    let angles = [[0.0, 0.0, 0.0], [70.0, 25.0, -15.0], [-130.0, -40.0, 60.0]];
    let basis = sh(16);
    let (table, _) = WeightTable::for_basis(basis.as_ref());
    let table = shipped_table(&table);
    let flat: Vec<f32> = lights
        .iter()
        .flat_map(|(d, i)| [d.x, d.y, d.z, i[0], i[1], i[2]])
        .map(|v| v as f32)
        .collect();
    let input = json!({ "table": table_json(&table), "lights": flat, "angles": angles });
    let Some(out) = node(
        "const { weightTable, halvesToFloats } = await import(ASSETS + 'table.js');\n\
         const { environmentWeights } = await import(ASSETS + 'environment.js');\n\
         const { rotationYawPitchRoll } = await import(ASSETS + 'vec.js');\n\
         const t = weightTable(INPUT.table.n, INPUT.table.k, halvesToFloats(Uint16Array.from(INPUT.table.bits)));\n\
         const lights = Float32Array.from(INPUT.lights);\n\
         console.log(JSON.stringify(INPUT.angles.map(([y, p, r]) => {\n\
           const R = rotationYawPitchRoll(y, p, r);\n\
           return { R, weights: environmentWeights(t, lights, R).map(w => Array.from(w)) };\n\
         })));",
        &input,
    ) else {
        return;
    };
    let env = EnvironmentLight::from_image(map).unwrap();
    let k = basis.len();
    for ([yaw, pitch, roll], got) in angles.iter().zip(out.as_array().unwrap()) {
        let light: EnvironmentMapLight = serde_json::from_value(json!({
            "map": "sky.hdr", "yaw_deg": yaw, "pitch_deg": pitch, "roll_deg": roll
        }))
        .unwrap();
        let rotation = light.rotation().unwrap();
        for (r, row) in rotation.iter().zip(got["R"].as_array().unwrap()) {
            for (a, b) in r.iter().zip(floats(row)) {
                assert!(
                    (a - b).abs() < 1e-12,
                    "yaw {yaw} pitch {pitch} roll {roll}: R"
                );
            }
        }
        let got: Vec<Vec<f64>> = (0..3).map(|c| floats(&got["weights"][c])).collect();
        // The documented sum, Σ_t I_t b(R ω_t), in Rust: with the table (what the
        // JavaScript computes) and with the basis itself (the quadrature alone).
        let mut tabled = vec![vec![0.0; k]; 3];
        let mut exact = vec![vec![0.0; k]; 3];
        let (mut t, mut b) = (vec![0f32; k], vec![0.0; k]);
        for (d, i) in &flat_lights(&flat) {
            let turned = mat3_apply(&rotation, *d);
            table.sample(turned, &mut t);
            basis.eval(turned, &mut b);
            for c in 0..3 {
                for j in 0..k {
                    tabled[c][j] += i[c] * t[j] as f64;
                    exact[c][j] += i[c] * b[j];
                }
            }
        }
        let library = env
            .for_basis(basis.as_ref())
            .unwrap()
            .weights(basis.as_ref(), rotation, Window::None)
            .unwrap();
        let largest = library.iter().flatten().fold(0f64, |m, v| m.max(v.abs()));
        let off = |a: &[Vec<f64>], b: &[Vec<f64>]| {
            a.iter()
                .flatten()
                .zip(b.iter().flatten())
                .fold(0f64, |m, (a, b)| m.max((a - b).abs()))
                / largest
        };
        let (js, quadrature, viewer) = (
            off(&got, &tabled),
            off(&exact, &library),
            off(&got, &library),
        );
        eprintln!(
            "yaw {yaw} pitch {pitch} roll {roll}: |environment.js − its sum in Rust| ≤ {js:.1e}, \
             |quadrature − library| ≤ {quadrature:.1e} with the basis, {viewer:.1e} with the table"
        );
        assert!(js <= QUADRATURE_TOLERANCE, "{js}");
        assert!(viewer <= ENVIRONMENT_TOLERANCE, "{viewer}");
    }
}

/// The quadrature's lights as the viewer reads them (f32).
fn flat_lights(flat: &[f32]) -> Vec<(Vec3, [f64; 3])> {
    flat.chunks_exact(6)
        .map(|l| {
            (
                Vec3::new(l[0] as f64, l[1] as f64, l[2] as f64),
                [l[3] as f64, l[4] as f64, l[5] as f64],
            )
        })
        .collect()
}

//! Fuzzing of the readers that take a file: fitted EXR maps, the compressed `.rlz` file
//! (whole, and its header and tiles behind the checksums), the RTI tools' `.ptm` and
//! `.rti` files, JPEG photographs, environment maps (Radiance HDR), OBJ models and
//! capture manifests. Same harness as `fuzz.rs` (a deterministic
//! mutation fuzzer on stable), each mutant written to a file in a temporary folder and
//! read back; a reader may return any error but must not panic. The writes make these
//! targets slower, so the test run feeds each 300 mutants; `RELIT_FUZZ_FILE_EXECS=N`
//! sets the count for a long run (and `RELIT_FUZZ_FILE_TARGETS=a,b` its targets, by the
//! names the log prints; run it with `TMPDIR` on a tmpfs). A mutant that panics is kept in Cargo's
//! `CARGO_TARGET_TMPDIR` and named in the failure.

mod common;

use common::Rng;
use relit::sphere::hemisphere_fibonacci;
use relit::synth::BumpyPlane;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::Instant;

/// Binary-minded mutations: bit flips, bytes set to boundary values, 32-bit words set
/// to sizes a header might declare, deletions, duplications, truncation.
fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut v = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(v.len().max(1));
        match rng.below(6) {
            0 if !v.is_empty() => v[at] ^= 1 << rng.below(8),
            1 if !v.is_empty() => v[at] = [0u8, 1, 0x7f, 0x80, 0xff][rng.below(5)],
            2 if v.len() >= at + 4 => {
                let word: u32 =
                    [0, 1, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, 1 << 30, 65_536][rng.below(7)];
                v[at..at + 4].copy_from_slice(&word.to_le_bytes());
            }
            3 => {
                let end = (at + 1 + rng.below(64)).min(v.len());
                v.drain(at.min(end)..end);
            }
            4 => {
                let end = (at + 1 + rng.below(64)).min(v.len());
                let part = v[at.min(end)..end].to_vec();
                v.splice(at..at, part);
            }
            _ => v.truncate(at),
        }
    }
    v
}

fn execs() -> usize {
    std::env::var("RELIT_FUZZ_FILE_EXECS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300)
}

/// Whether `name` is among the targets `RELIT_FUZZ_FILE_TARGETS=a,b` picks (all when
/// unset): a long run can be split across processes.
fn picked(name: &str) -> bool {
    std::env::var("RELIT_FUZZ_FILE_TARGETS")
        .map(|list| list.split(',').any(|t| t.trim() == name))
        .unwrap_or(true)
}

/// Write each mutant of `seed` to `dir/name` and call `read` on it.
fn fuzz(dir: &Path, name: &str, seed: &[u8], read: fn(&Path)) -> Vec<String> {
    if !picked(name) {
        return Vec::new();
    }
    let mut rng = Rng(0xD1B5_4A32_D192_ED03 ^ name.len() as u64);
    let path = dir.join(name);
    let (n, start) = (execs(), Instant::now());
    let mut crashes = Vec::new();
    common::store_corpus(name, &[seed.to_vec()]);
    // The committed corpus first, then the seed and its mutants.
    let corpus = common::corpus(name);
    for i in 0..=n + corpus.len() {
        let input = if i < corpus.len() {
            corpus[i].clone()
        } else if i == corpus.len() {
            seed.to_vec()
        } else {
            mutate(seed, &mut rng)
        };
        std::fs::write(&path, &input).unwrap();
        if catch_unwind(AssertUnwindSafe(|| read(&path))).is_err() {
            // Kept past the temporary folder, to become a regression test.
            let kept =
                Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("fuzz-crash-{i}-{name}"));
            std::fs::write(&kept, &input).unwrap();
            crashes.push(format!(
                "{name}: mutant {i} ({} bytes), kept as {}",
                input.len(),
                kept.display()
            ));
            if crashes.len() >= 5 {
                break;
            }
        }
    }
    eprintln!(
        "fuzz {name}: 1 seed + {n} mutants in {:.1} s, {} panics",
        start.elapsed().as_secs_f64(),
        crashes.len()
    );
    crashes
}

#[test]
fn no_file_reader_panics_on_mutated_files() {
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();

    // Seeds, made the way relit makes them.
    let plane = BumpyPlane {
        width: 12,
        height: 8,
    };
    let dirs = hemisphere_fibonacci(8);
    plane.write_lp_capture(d, &dirs).unwrap();
    let options = relit::fit::FitOptions {
        basis: relit::fit::BasisRequest::parse("sh:4").unwrap(),
        lambda: relit::fit::Lambda::Fixed(1e-3),
        ..Default::default()
    };
    let fitted =
        relit::fit::fit(&plane.capture(&dirs), &options, &relit::progress::Silent).unwrap();
    let seed_exr = d.join("seed.exr");
    relit::codec::exr::write(&seed_exr, &fitted.image, relit::storage::Precision::F16).unwrap();
    let exr = std::fs::read(&seed_exr).unwrap();
    // A 4×2 Radiance HDR, flat (uncompressed) RGBE scanlines.
    let mut hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec();
    for p in 0..8u8 {
        hdr.extend_from_slice(&[100 + p, 120, 140, 128]);
    }
    let obj = b"v -0.5 0 0\nv 0.5 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\nf 1 3 4\n".to_vec();
    let lp = std::fs::read_to_string(d.join("dirs.lp")).unwrap();
    let manifest = serde_json::json!({
        "images": lp.lines().skip(1).map(|line| {
            let mut parts: Vec<&str> = line.rsplitn(4, ' ').collect();
            parts.reverse();
            serde_json::json!({ "file": parts[0].trim_matches('"'), "direction": [
                parts[1].parse::<f64>().unwrap(), parts[2].parse::<f64>().unwrap(), parts[3].parse::<f64>().unwrap()] })
        }).collect::<Vec<_>>()
    });
    let manifest = serde_json::to_vec_pretty(&manifest).unwrap();

    let mut crashes = Vec::new();
    crashes.extend(fuzz(d, "maps.exr", &exr, |p| {
        let _ = relit::codec::exr::read(p);
    }));
    // The compressed file: whole files (checksums stop most mutants early), and behind
    // the checksums its header JSON and a zstd tile, decoded as the reader would.
    let zstd_settings = relit::compress::Settings {
        components: Some(3),
        tile: 16,
        ..Default::default()
    };
    let jpeg_settings = relit::compress::Settings {
        layout: relit::compress::Layout::Ycc,
        codec: relit::compress::TileCodec::Jpeg { quality: 80 },
        ..zstd_settings.clone()
    };
    let packed = relit::compress::pack(&fitted.image, &zstd_settings).unwrap();
    let rlz = relit::codec::packed::to_bytes(&packed).unwrap();
    let rlz_jpeg = relit::codec::packed::to_bytes(
        &relit::compress::pack(&fitted.image, &jpeg_settings).unwrap(),
    )
    .unwrap();
    // Whole files, and a region read tile by tile (the sections it skips unread).
    crashes.extend(fuzz(d, "maps.rlz", &rlz, |p| {
        let _ = relit::codec::read(p);
        let _ = relit::codec::packed::read_region(p, (3, 2, 6, 5));
    }));
    crashes.extend(fuzz(d, "maps-jpeg.rlz", &rlz_jpeg, |p| {
        let _ = relit::codec::read(p);
        let _ = relit::codec::packed::read_region(p, (3, 2, 6, 5));
    }));
    // A file with mip levels: level 0 whole, and a region of level 1 with its depth.
    let mip_packed = relit::compress::pack(
        &fitted.image,
        &relit::compress::Settings {
            mip_levels: true,
            ..zstd_settings.clone()
        },
    )
    .unwrap();
    let rlz_mip = relit::codec::packed::to_bytes(&mip_packed).unwrap();
    crashes.extend(fuzz(d, "maps-mip.rlz", &rlz_mip, |p| {
        let _ = relit::codec::read(p);
        let _ = relit::codec::packed::read_level_region(p, 1, (1, 1, 4, 3), true);
    }));
    // A codebook file, read both ways: expanded into maps, and as entries and indices.
    let vq_settings = relit::compress::Settings {
        codebook: Some(12),
        ..zstd_settings.clone()
    };
    let rlz_vq = relit::codec::packed::to_bytes(
        &relit::compress::pack(&fitted.image, &vq_settings).unwrap(),
    )
    .unwrap();
    crashes.extend(fuzz(d, "maps-vq.rlz", &rlz_vq, |p| {
        let _ = relit::codec::read(p);
        if let Ok(packed) = relit::codec::packed::read_packed(p) {
            if let Ok(indexed) = relit::compress::indexed(&packed) {
                let _ = relit::engine::lookup::LookupRelighter::new(&indexed);
            }
        }
    }));
    // A codebook of the residual beside JPEG planes: planes, codebook and index tiles.
    let residual_settings = relit::compress::Settings {
        codebook: Some(12),
        residual: Some(1),
        ..jpeg_settings.clone()
    };
    let residual_packed = relit::compress::pack(&fitted.image, &residual_settings).unwrap();
    let rlz_residual = relit::codec::packed::to_bytes(&residual_packed).unwrap();
    crashes.extend(fuzz(d, "maps-residual.rlz", &rlz_residual, |p| {
        let _ = relit::codec::read(p);
        let _ = relit::codec::packed::read_region(p, (3, 2, 6, 5));
    }));
    // The RTI tools' files, written from the same maps.
    for (name, bytes) in [
        (
            "maps-lrgb.ptm",
            relit::codec::ptm::encode(&fitted.image, relit::codec::ptm::PtmFormat::Lrgb).unwrap(),
        ),
        (
            "maps-rgb.ptm",
            relit::codec::ptm::encode(&fitted.image, relit::codec::ptm::PtmFormat::Rgb).unwrap(),
        ),
        (
            "maps-jpeg-lrgb.ptm",
            relit::codec::ptm::encode(&fitted.image, relit::codec::ptm::PtmFormat::JpegLrgb(90))
                .unwrap(),
        ),
        (
            "maps.rti",
            relit::codec::rti::encode(&fitted.image).unwrap(),
        ),
    ] {
        crashes.extend(fuzz(d, name, &bytes, |p| {
            let _ = relit::codec::read(p);
        }));
    }
    for (name, seed) in [
        ("header.json", &packed),
        ("header-residual.json", &residual_packed),
        ("header-mip.json", &mip_packed),
    ] {
        let path = d.join(name).with_extension("sections");
        std::fs::write(path, seed.sections.concat()).unwrap();
        let header_json = serde_json::to_vec(&seed.header).unwrap();
        crashes.extend(fuzz(d, name, &header_json, |p| {
            let Ok(header) =
                serde_json::from_slice::<relit::compress::Header>(&std::fs::read(p).unwrap())
            else {
                return;
            };
            // The seed's sections, reused whatever the mutated header says they are.
            let all = std::fs::read(p.with_extension("sections")).unwrap();
            let count = header.sections().min(4096);
            let size = all.len() / count.max(1);
            let sections = (0..count)
                .map(|i| all[i * size..(i + 1) * size].to_vec())
                .collect();
            let packed = relit::compress::Packed { header, sections };
            let _ = relit::compress::unpack(&packed);
            let levels = packed.header.levels;
            for level in [1, levels.saturating_sub(1), levels, usize::MAX] {
                if let Ok(level) = packed.clone().level(level) {
                    let _ = relit::compress::unpack(&level);
                }
            }
        }));
    }
    let q = &packed.header.planes[0].quantizer;
    assert_eq!(
        (q.width(), packed.header.tile),
        (2, 16),
        "the tile seed's shape"
    );
    crashes.extend(fuzz(d, "tile.zst", &packed.sections[0], |p| {
        let bytes = std::fs::read(p).unwrap();
        let mut codes = vec![0u16; 12 * 8];
        let codec = relit::compress::TileCodec::Zstd { level: 3 };
        let _ = relit::compress::planes::decode_tile(&bytes, 12, 8, 2, 1 << 16, codec, &mut codes);
    }));
    // A capture's photograph: libjpeg (C) reports errors by unwinding, which the reader
    // must turn into errors, whole images and parts alike.
    let mut photo = relit::image::ImageRgb::new(24, 16);
    for (i, v) in photo.data.iter_mut().enumerate() {
        *v = ((i * 37) % 101) as f32 / 100.0;
    }
    let seed_jpg = d.join("seed.jpg");
    relit::image::save(&seed_jpg, &photo, 0.0).unwrap();
    crashes.extend(fuzz(
        d,
        "photo.jpg",
        &std::fs::read(&seed_jpg).unwrap(),
        |p| {
            let _ = relit::image::load_linear(p, None);
            let _ = relit::image::load_linear_parts(p, None, 3..9, &[5, 100, 2]);
        },
    ));
    crashes.extend(fuzz(d, "sky.hdr", &hdr, |p| {
        let _ = relit::envmap::EnvironmentLight::load(p);
    }));
    crashes.extend(fuzz(d, "model.obj", &obj, |p| {
        let _ = relit_studio::obj::load(p);
    }));
    crashes.extend(fuzz(d, "capture.json", &manifest, |p| {
        let _ = relit::capture::Capture::open(p);
    }));
    std::panic::set_hook(hook);
    assert!(
        crashes.is_empty(),
        "readers panicked on:\n{}",
        crashes.join("\n")
    );
}

//! Tiled bundles: every tile holds its level's pixels (level 0 cropped, coarser levels
//! the means of level 0's blocks), read by region from files with and without mip
//! levels; the server and the static export hand them out.

mod common;

use relit::maps::RelightableImage;
use relit::storage::Precision;
use relit_viewer::server::respond;
use relit_viewer::tiles::TileSource;
use relit_viewer::{export_web, BundleOptions, Tiling, WebBundle};
use serde_json::Value;
use std::path::{Path, PathBuf};

const SIDE: usize = 64;

/// A 300×100 image of k = 9 (sides that do not halve evenly) as a scan-line EXR
/// (level 0 alone) and as a tiled EXR with mip levels.
fn files(dir: &Path) -> (RelightableImage, PathBuf, PathBuf) {
    let image = common::sample_image(300, 100, 3);
    let plain = dir.join("plain.exr");
    let mips = dir.join("mips.exr");
    relit::codec::exr::write(&plain, &image, Precision::F32).unwrap();
    relit::codec::exr::write_tiled(&mips, &image, Precision::F32, SIDE).unwrap();
    (image, plain, mips)
}

/// The bytes under which the overview is level 2 (75×25 texels of 9 RGBA layers of
/// half floats: 135,000 bytes; level 1: 540,000).
const OVERVIEW: usize = 200_000;

/// Plane `j` (3i + c) of level `level` at (x, y): the mean of level 0's 2^l × 2^l block.
fn expected(image: &RelightableImage, level: usize, j: usize, x: usize, y: usize) -> f64 {
    let maps = &image.maps;
    let n = maps.pixels();
    let s = 1 << level;
    let mut sum = 0.0;
    for sy in y * s..(y + 1) * s {
        for sx in x * s..(x + 1) * s {
            sum += maps.data[j * n + sy * maps.width + sx] as f64;
        }
    }
    sum / (s * s) as f64
}

/// The depth of level `level` at (x, y): the mean of the hit depths (finite, positive)
/// of level 0's 2^l × 2^l block, 0 where none is hit; or, `stored`, as a file's levels
/// hold it, each level the mean of the hit ones of the 2×2 below.
fn expected_depth(image: &RelightableImage, level: usize, x: usize, y: usize, stored: bool) -> f32 {
    let depth = image.depth.as_deref().unwrap();
    let w = image.maps.width;
    if level == 0 {
        return depth[y * w + x];
    }
    let below = |sx: usize, sy: usize| {
        if stored {
            expected_depth(image, level - 1, sx, sy, true)
        } else {
            depth[sy * w + sx]
        }
    };
    let s = if stored { 2 } else { 1 << level };
    let (mut sum, mut n) = (0.0f64, 0);
    for sy in y * s..(y + 1) * s {
        for sx in x * s..(x + 1) * s {
            let d = below(sx, sy);
            if d.is_finite() && d > 0.0 {
                sum += d as f64;
                n += 1;
            }
        }
    }
    if n > 0 {
        (sum / n as f64) as f32
    } else {
        0.0
    }
}

fn halves(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(2)
        .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
        .collect()
}

/// Check every tile of `source` against `image`'s levels (half-float rounding), and
/// its depth, which follows the layers (`image` has depth).
fn check_tiles(source: &TileSource, image: &RelightableImage) {
    check_tiles_with(
        source,
        image.maps.k,
        |level, j, x, y| expected(image, level, j, x, y),
        // Levels 0 and 1: a file's own level 1 is the direct mean too.
        |level, x, y| expected_depth(image, level, x, y, false),
    );
}

/// Check every tile of `source` (`k` coefficients) against `want(level, plane, x, y)`
/// (half-float rounding), and its depth against `want_depth(level, x, y)`.
fn check_tiles_with(
    source: &TileSource,
    k: usize,
    want: impl Fn(usize, usize, usize, usize) -> f64,
    want_depth: impl Fn(usize, usize, usize) -> f32,
) {
    let layers = 3 * k.div_ceil(4);
    let mut count = 0;
    for (level, tx, ty) in source.tiles() {
        let bytes = source.tile(level, tx, ty).unwrap();
        assert_eq!(bytes.len(), source.tile_bytes(level, tx, ty));
        let (lw, lh) = source.sizes()[level];
        let (tw, th) = (SIDE.min(lw - tx * SIDE), SIDE.min(lh - ty * SIDE));
        let (coefficients, depth) = bytes.split_at(layers * tw * th * 8);
        assert_eq!(depth.len(), tw * th * 4);
        for (p, d) in depth.chunks_exact(4).enumerate() {
            let d = f32::from_le_bytes([d[0], d[1], d[2], d[3]]);
            let (x, y) = (tx * SIDE + p % tw, ty * SIDE + p / tw);
            let want = want_depth(level, x, y);
            assert!(
                (d - want).abs() <= 1e-6 * want,
                "level {level} tile {tx}_{ty} pixel ({x}, {y}) depth {d} vs {want}"
            );
        }
        let values = halves(coefficients);
        assert_eq!(values.len(), layers * tw * th * 4);
        for (l, layer) in values.chunks_exact(tw * th * 4).enumerate() {
            let (c, jl) = (l / k.div_ceil(4), l % k.div_ceil(4));
            for (p, texel) in layer.chunks_exact(4).enumerate() {
                let (x, y) = (tx * SIDE + p % tw, ty * SIDE + p / tw);
                for (q, &v) in texel.iter().enumerate() {
                    let i = 4 * jl + q;
                    if i >= k {
                        assert_eq!(v, 0.0);
                        continue;
                    }
                    let want = want(level, 3 * i + c, x, y);
                    assert!(
                        (v as f64 - want).abs() <= 1e-3 * want.abs().max(0.25),
                        "level {level} tile {tx}_{ty} pixel ({x}, {y}) coefficient {i} channel {c}: {v} vs {want}"
                    );
                }
            }
        }
        count += 1;
    }
    // Levels 0 and 1 of 64-pixel tiles: 5×2 and 3×1.
    assert_eq!(count, 13);
}

#[test]
fn tiles_hold_each_level_from_files_with_and_without_mip_levels() {
    let dir = tempfile::tempdir().unwrap();
    let (image, plain, mips) = files(dir.path());
    for path in [&plain, &mips] {
        let opened = TileSource::open(path, SIDE, OVERVIEW).unwrap();
        let source = &opened.source;
        assert_eq!(source.overview_level(), 2, "{}", path.display());
        assert_eq!(source.sizes(), &[(300, 100), (150, 50), (75, 25)]);
        // The overview: level 2's means, and its depth (no more: tiles carry the rest).
        let overview = &opened.overview.maps;
        assert_eq!((overview.width, overview.height), (75, 25));
        for j in 0..3 * image.maps.k {
            for y in 0..25 {
                for x in 0..75 {
                    let v = overview.data[j * 75 * 25 + y * 75 + x] as f64;
                    let want = expected(&image, 2, j, x, y);
                    assert!((v - want).abs() < 1e-5, "overview plane {j} ({x}, {y})");
                }
            }
        }
        check_overview_depth(&opened.overview, &image, path == &mips);
        check_tiles(source, &image);
        assert_eq!(source.counters().1, 13);
    }
    // A tile of level 0 of the tiled file reads its own block and little else.
    let opened = TileSource::open(&mips, SIDE, OVERVIEW).unwrap();
    let (before, _) = opened.source.counters();
    opened.source.tile(0, 2, 1).unwrap();
    let read = opened.source.counters().0 - before;
    let file = std::fs::metadata(&mips).unwrap().len();
    assert!(read * 8 < file, "{read} bytes read of {file}");
    // Tiles exist only below the overview and inside each level.
    for (level, x, y) in [(2, 0, 0), (0, 5, 0), (0, 0, 2), (1, 3, 0)] {
        assert!(opened.source.tile(level, x, y).is_err());
    }
}

/// The overview's depth is level 2's: the mean of the hit ones of each 4×4 block, or as
/// a file with levels holds it (`stored`).
fn check_overview_depth(overview: &RelightableImage, image: &RelightableImage, stored: bool) {
    let depth = overview.depth.as_deref().expect("the overview's depth");
    assert_eq!(depth.len(), 75 * 25);
    for y in 0..25 {
        for x in 0..75 {
            let want = expected_depth(image, 2, x, y, stored);
            let got = depth[y * 75 + x];
            assert!(
                (got - want).abs() <= 1e-6 * want,
                "overview depth ({x}, {y}): {got} vs {want}"
            );
        }
    }
}

#[test]
fn clients_asking_for_many_tiles_at_once_take_turns() {
    let dir = tempfile::tempdir().unwrap();
    let (image, plain, _) = files(dir.path());
    let opened = TileSource::open(&plain, SIDE, OVERVIEW).unwrap();
    let source = &opened.source;
    let tiles: Vec<_> = source.tiles().collect();
    let got: Vec<Vec<u8>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..4 * tiles.len())
            .map(|i| {
                let (l, x, y) = tiles[i % tiles.len()];
                s.spawn(move || source.tile(l, x, y).unwrap())
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert!(source.peak_readers() >= 1 && source.peak_readers() <= TileSource::readers());
    for (i, bytes) in got.iter().enumerate() {
        let (l, x, y) = tiles[i % tiles.len()];
        assert_eq!(bytes, &source.tile(l, x, y).unwrap());
    }
    check_tiles(source, &image);
}

fn options(tiling: Tiling) -> BundleOptions {
    BundleOptions {
        tiling,
        overview_bytes: OVERVIEW,
        ..Default::default()
    }
}

#[test]
fn the_server_hands_out_tiles_and_whole_layers_stay_the_default_for_small_files() {
    let dir = tempfile::tempdir().unwrap();
    let (image, plain, _) = files(dir.path());
    let bundle = WebBundle::read(&plain, &options(Tiling::Tiles(SIDE))).unwrap();
    let info: Value = serde_json::from_slice(bundle.info()).unwrap();
    assert_eq!(info["tiles"]["side"], 64);
    assert_eq!(info["tiles"]["overview"], 2);
    assert_eq!(
        (info["width"].as_u64(), info["height"].as_u64()),
        (Some(300), Some(100))
    );
    // The layers and the depth hold the overview; tiles carry the rest of both.
    let layer = &bundle.files["data/planes/L00.f16"];
    assert_eq!(layer.len(), 75 * 25 * 8);
    assert_eq!(bundle.files["data/depth.f32"].len(), 75 * 25 * 4);
    assert_eq!(
        (
            info["depth"]["width"].as_u64(),
            info["depth"]["height"].as_u64()
        ),
        (Some(75), Some(25))
    );
    let source = bundle.tiles.as_ref().unwrap();
    let got = respond(&bundle, "GET", "/data/tiles/1/2_0.f16");
    assert_eq!(got.status, 200);
    assert_eq!(&*got.body, &source.tile(1, 2, 0).unwrap()[..]);
    let head = respond(&bundle, "HEAD", "/data/tiles/0/4_1.f16");
    assert_eq!((head.status, head.body.len()), (200, 44 * 36 * (9 * 8 + 4)));
    for path in [
        "/data/tiles/2/0_0.f16",
        "/data/tiles/0/5_0.f16",
        "/data/tiles/0/0_0.png",
        "/data/tiles/0/-1_0.f16",
        "/data/tiles/0/0_0_0.f16",
        "/data/tiles/x/0_0.f16",
        "/data/tiles/0/99999999999999999999_0.f16",
    ] {
        assert_eq!(respond(&bundle, "GET", path).status, 404, "{path}");
    }
    // Auto: whole layers for a file this small; tiles are half floats, from EXR files.
    let whole = WebBundle::read(&plain, &options(Tiling::Auto)).unwrap();
    assert!(whole.tiles.is_none() && whole.files.contains_key("data/planes/L00.f16"));
    let u8 = BundleOptions {
        precision: Precision::U8,
        ..options(Tiling::Tiles(SIDE))
    };
    let err = WebBundle::read(&plain, &u8).unwrap_err().to_string();
    assert!(err.contains("tiled"), "{err}");
    // A codebook file is not tiled (its entries and indices are small already).
    let rlz = dir.path().join("book.rlz");
    let settings = relit::compress::Settings {
        codebook: Some(16),
        ..Default::default()
    };
    relit::codec::packed::write(&rlz, &image, &settings).unwrap();
    let err = WebBundle::read(&rlz, &options(Tiling::Tiles(SIDE)))
        .unwrap_err()
        .to_string();
    assert!(err.contains("codebook"), "{err}");
}

/// A compressed file of planes is tiled too: its level 0 read a tile of the file at a
/// time (its tiles of 40 pixels straddle the bundle's), the coarser levels the means of
/// level 0 as the file decodes it, and its depth from its own sections.
#[test]
fn a_compressed_files_tiles_hold_its_decoded_levels() {
    let dir = tempfile::tempdir().unwrap();
    let image = common::sample_image(300, 100, 3);
    let rlz = dir.path().join("scene.rlz");
    let settings = relit::compress::Settings {
        tile: 40,
        ..Default::default()
    };
    relit::codec::packed::write(&rlz, &image, &settings).unwrap();
    let decoded = relit::codec::packed::read(&rlz).unwrap();
    let opened = TileSource::open(&rlz, SIDE, OVERVIEW).unwrap();
    assert_eq!(opened.source.overview_level(), 2);
    check_overview_depth(&opened.overview, &decoded, false);
    assert_eq!(opened.overview.meta.basis, decoded.meta.basis);
    check_tiles(&opened.source, &decoded);
    let bundle = WebBundle::read(&rlz, &options(Tiling::Tiles(SIDE))).unwrap();
    let info: Value = serde_json::from_slice(bundle.info()).unwrap();
    assert_eq!(info["tiles"]["overview"], 2);
    assert_eq!(
        info["basis"]["name"],
        decoded.meta.basis.build().unwrap().name()
    );
}

/// A `.rlz` file with mip levels: each level's tiles and the overview are the file's
/// own levels as it decodes them, read from that level's sections (level 0 is not read
/// to open it or to serve a coarser tile).
#[test]
fn a_compressed_file_with_mip_levels_serves_its_own_levels() {
    let dir = tempfile::tempdir().unwrap();
    let image = common::sample_image(300, 100, 3);
    let rlz = dir.path().join("levels.rlz");
    let settings = relit::compress::Settings {
        tile: 40,
        mip_levels: true,
        ..Default::default()
    };
    relit::codec::packed::write(&rlz, &image, &settings).unwrap();
    let packed = relit::codec::packed::read_packed(&rlz).unwrap();
    let levels: Vec<RelightableImage> = (0..3)
        .map(|l| relit::compress::unpack(&packed.clone().level(l).unwrap()).unwrap())
        .collect();
    // Level 1 as stored is not level 0's means as decoded (each is quantised alone): the
    // last check tells them apart.
    let opened = TileSource::open(&rlz, SIDE, OVERVIEW).unwrap();
    assert_eq!(opened.source.overview_level(), 2);
    assert_eq!(opened.source.sizes(), &[(300, 100), (150, 50), (75, 25)]);
    let (opened_bytes, _) = opened.source.counters();
    let level_zero: usize = packed
        .clone()
        .level(0)
        .unwrap()
        .sections
        .iter()
        .map(Vec::len)
        .sum();
    assert!(
        (opened_bytes as usize) < level_zero / 8,
        "{opened_bytes} bytes read to open, level 0 is {level_zero}"
    );
    let overview = &levels[2];
    assert_eq!(opened.overview.maps, overview.maps);
    assert_eq!(opened.overview.depth, overview.depth);
    let at = |level: usize, j: usize, x: usize, y: usize| {
        let maps = &levels[level].maps;
        maps.data[j * maps.pixels() + y * maps.width + x] as f64
    };
    let depth_at = |level: usize, x: usize, y: usize| {
        levels[level].depth.as_ref().unwrap()[y * levels[level].maps.width + x]
    };
    check_tiles_with(&opened.source, image.maps.k, at, depth_at);
    let differs = (0..levels[1].maps.pixels()).any(|p| {
        let (x, y) = (p % 150, p / 150);
        (0..3 * image.maps.k)
            .any(|j| (at(1, j, x, y) - expected(&levels[0], 1, j, x, y)).abs() > 1e-5)
    });
    assert!(differs, "level 1 is the file's own, not level 0's means");
}

#[test]
fn a_static_export_holds_every_tile() {
    let dir = tempfile::tempdir().unwrap();
    let (image, _, mips) = files(dir.path());
    let site = dir.path().join("site");
    export_web(&mips, &site, &options(Tiling::Tiles(SIDE))).unwrap();
    let opened = TileSource::open(&mips, SIDE, OVERVIEW).unwrap();
    let mut n = 0;
    for (level, x, y) in opened.source.tiles() {
        let file = site.join(TileSource::tile_path(level, x, y));
        assert_eq!(
            std::fs::read(&file).unwrap(),
            opened.source.tile(level, x, y).unwrap()
        );
        n += 1;
    }
    assert_eq!(n, 13);
    check_tiles(&opened.source, &image);
}

//! Tiled OpenEXR files with mip levels: written, read whole as any relit file, and read
//! by region and level, against the maps and an independent 2×2 mean.

use relit::basis::BasisSpec;
use relit::codec::exr;
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::storage::Precision;

fn image(w: usize, h: usize) -> RelightableImage {
    image_of(w, h, 4)
}

/// An image of SH maps with `k` (a square) coefficients a channel.
fn image_of(w: usize, h: usize, k: usize) -> RelightableImage {
    let mut maps = CoefficientMaps::zeros(w, h, k);
    for (i, v) in maps.data.iter_mut().enumerate() {
        *v = ((i * 7919) % 1013) as f32 / 1013.0 - 0.3;
    }
    RelightableImage {
        meta: Metadata::new(
            BasisSpec::named(&format!("sh:{k}")).unwrap(),
            MapSpace::Linear,
            Default::default(),
        ),
        maps,
        depth: Some(
            (0..w * h)
                .map(|p| {
                    if p % 11 == 3 {
                        0.0
                    } else {
                        1.0 + (p % 17) as f32
                    }
                })
                .collect(),
        ),
    }
}

/// 2×2 means, rounding sizes down, written here independently of the library.
fn mean2(plane: &[f32], w: usize, h: usize) -> (Vec<f32>, usize, usize) {
    let (w2, h2) = ((w / 2).max(1), (h / 2).max(1));
    let mut out = vec![0.0; w2 * h2];
    for y in 0..h2 {
        for x in 0..w2 {
            let mut vals = Vec::new();
            for (sx, sy) in [
                (2 * x, 2 * y),
                (2 * x + 1, 2 * y),
                (2 * x, 2 * y + 1),
                (2 * x + 1, 2 * y + 1),
            ] {
                if sx < w && sy < h {
                    vals.push(plane[sy * w + sx] as f64);
                }
            }
            out[y * w2 + x] = (vals.iter().sum::<f64>() / vals.len() as f64) as f32;
        }
    }
    (out, w2, h2)
}

#[test]
fn tiled_files_read_whole_by_region_and_by_level() {
    let (w, h) = (70, 45);
    let original = image(w, h);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiled.exr");
    exr::write_tiled(&path, &original, Precision::F32, 16).unwrap();
    let sizes = exr::tiled_levels(&path).unwrap().unwrap();
    assert_eq!(
        sizes,
        vec![(70, 45), (35, 22), (17, 11), (8, 5), (4, 2), (2, 1), (1, 1)]
    );
    // Whole, as any relit file: level 0 exactly.
    let whole = relit::codec::read(&path).unwrap();
    assert_eq!(whole.maps.data, original.maps.data);
    assert_eq!(whole.depth, original.depth);
    // A region of level 0: that crop, from fewer bytes than the file.
    let (rx, ry, rw, rh) = (13, 7, 30, 20);
    let region = exr::read_region(&path, 0, (rx, ry, rw, rh)).unwrap();
    assert_crop(&region, &original, (rx, ry, rw, rh));
    // Level 1 whole and level 2 in part: the 2×2 means of the level above.
    let (m1, w1, h1) = mean2(original.maps.plane(2, 1), w, h);
    let level1 = exr::read_region(&path, 1, (0, 0, w1, h1)).unwrap();
    assert_eq!(level1.level_size, (w1, h1));
    for (a, b) in level1.image.maps.plane(2, 1).iter().zip(&m1) {
        assert!((a - b).abs() < 1e-6, "{a} {b}");
    }
    let (m2, w2, _) = mean2(&m1, w1, h1);
    let part = exr::read_region(&path, 2, (5, 3, 9, 6)).unwrap();
    for y in 0..6 {
        for x in 0..9 {
            let (a, b) = (
                part.image.maps.plane(2, 1)[y * 9 + x],
                m2[(3 + y) * w2 + 5 + x],
            );
            assert!((a - b).abs() < 1e-6, "({x}, {y}): {a} {b}");
        }
    }
    // Refusals: a level past the last, a region outside its level, a file of scan lines.
    assert!(exr::read_region(&path, 7, (0, 0, 1, 1))
        .unwrap_err()
        .to_string()
        .contains("levels 0 to 6"));
    assert!(exr::read_region(&path, 1, (30, 0, 10, 1))
        .unwrap_err()
        .to_string()
        .contains("not inside"));
    let plain = dir.path().join("plain.exr");
    exr::write(&plain, &original, Precision::F32).unwrap();
    assert!(exr::tiled_levels(&plain).unwrap().is_none());
    assert_eq!(exr::levels(&plain).unwrap(), vec![(w, h)]);
    assert!(exr::read_region(&plain, 1, (0, 0, 1, 1))
        .unwrap_err()
        .to_string()
        .contains("level 0 only"));
    assert!(exr::write_tiled(&plain, &original, Precision::F32, 8).is_err());
    // Half floats: level 0 reads back as the f16 rounding of the maps.
    let half = dir.path().join("half.exr");
    exr::write_tiled(&half, &original, Precision::F16, 32).unwrap();
    let back = relit::codec::read(&half).unwrap();
    for (a, b) in back.maps.data.iter().zip(&original.maps.data) {
        assert_eq!(*a, half::f16::from_f32(*b).to_f32());
    }
}

/// `region` holds the crop `rect` of `original`'s maps, read from fewer bytes than the
/// file.
fn assert_crop(
    region: &exr::RegionRead,
    original: &RelightableImage,
    (rx, ry, rw, rh): (usize, usize, usize, usize),
) {
    assert!(
        region.bytes_read < region.file_bytes,
        "{} of {}",
        region.bytes_read,
        region.file_bytes
    );
    let w = original.maps.width;
    for j in 0..3 * original.maps.k {
        let (i, c) = (j / 3, j % 3);
        let full = original.maps.plane(i, c);
        let got = region.image.maps.plane(i, c);
        for y in 0..rh {
            assert_eq!(
                &got[y * rw..(y + 1) * rw],
                &full[(ry + y) * w + rx..(ry + y) * w + rx + rw]
            );
        }
    }
}

#[test]
fn a_fits_files_read_by_region() {
    // Scan lines (blocks of 16 lines) and, 600 pixels wide at K = 25, tiles 16 lines
    // high: level 0 of either reads by region from the blocks it touches.
    let dir = tempfile::tempdir().unwrap();
    for (w, h, k, rect) in [
        (200, 160, 4, (13, 20, 30, 9)),
        (600, 40, 25, (300, 17, 100, 10)),
    ] {
        let original = image_of(w, h, k);
        let path = dir.path().join("fit.exr");
        exr::write(&path, &original, Precision::F32).unwrap();
        assert!(exr::tiled_levels(&path).unwrap().is_none());
        assert_eq!(exr::levels(&path).unwrap(), vec![(w, h)]);
        let region = exr::read_region(&path, 0, rect).unwrap();
        assert_crop(&region, &original, rect);
        assert!(
            region.bytes_read * 2 < region.file_bytes,
            "{w}: {} of {}",
            region.bytes_read,
            region.file_bytes
        );
    }
}

/// Two single-part EXR files the same but for the order of their header's attributes
/// (the exr crate keeps them in a hash map): equal headers, and every byte after them.
fn assert_same_file(a: &std::path::Path, b: &std::path::Path, what: &str) {
    let meta = |p: &std::path::Path| exr::read_metadata_summary(p).unwrap();
    let (mut ma, mut mb) = (meta(a), meta(b));
    ma.sort();
    mb.sort();
    assert_eq!(ma, mb, "{what}: headers");
    let (a, b) = (std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
    assert_eq!(a.len(), b.len(), "{what}: sizes");
    let end = header_end(&a);
    assert_eq!(end, header_end(&b), "{what}");
    let first = a[end..].iter().zip(&b[end..]).position(|(x, y)| x != y);
    assert!(
        first.is_none(),
        "{what}: the offsets and blocks differ from byte {first:?} after the header"
    );
}

/// Where a single-part EXR's header ends: after the magic number and version, the
/// attributes (name, type, size, value) up to an empty name.
fn header_end(bytes: &[u8]) -> usize {
    let mut at = 8;
    loop {
        let name = bytes[at..].iter().position(|&b| b == 0).unwrap();
        if name == 0 {
            return at + 1;
        }
        at += name + 1;
        at += bytes[at..].iter().position(|&b| b == 0).unwrap() + 1;
        let size = i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        at += 4 + size;
    }
}

/// The pyramid made a tile at a time from a relit EXR (`write_tiled_from`) is the file
/// `write_tiled` makes from the image read whole, byte for byte but for the order of
/// the header's attributes: odd sides (a last tile
/// column and row with no parent), a side that reaches 1 first, a wide fit-style file
/// in 16-line tiles as input, f16 and f32, with and without depth, and the file itself
/// as input.
#[test]
fn the_pyramid_made_a_tile_at_a_time_is_the_whole_images() {
    let dir = tempfile::tempdir().unwrap();
    for (w, h, k, tile, depth) in [
        (37, 21, 4, 16, true),
        (100, 3, 4, 16, false),
        (1200, 40, 9, 64, true),
    ] {
        let mut source = image_of(w, h, k);
        if !depth {
            source.depth = None;
        }
        for precision in [Precision::F16, Precision::F32] {
            let plain = dir.path().join(format!("plain-{w}-{precision:?}.exr"));
            exr::write(&plain, &source, precision).unwrap();
            let whole = dir.path().join("whole.exr");
            let streamed = dir.path().join("streamed.exr");
            exr::write_tiled(&whole, &exr::read(&plain).unwrap(), precision, tile).unwrap();
            exr::write_tiled_from(&plain, &streamed, precision, tile).unwrap();
            assert_same_file(
                &whole,
                &streamed,
                &format!("{w}×{h} k {k} tile {tile} {precision:?}"),
            );
            // A tiled file with levels as input: its level 0 again.
            let again = dir.path().join("again.exr");
            exr::write_tiled_from(&streamed, &again, precision, tile).unwrap();
            assert_same_file(&again, &streamed, "again");
        }
    }
    let plain = dir.path().join("plain-37-F16.exr");
    assert!(exr::write_tiled_from(&plain, &dir.path().join("x.exr"), Precision::F16, 8).is_err());
    assert!(exr::write_tiled_from(&plain, &dir.path().join("x.exr"), Precision::U8, 16).is_err());
}

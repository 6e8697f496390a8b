// Index loops over coefficients read more plainly than iterator chains here.
#![allow(clippy::needless_range_loop)]

use super::container as packed;
use super::*;
use crate::basis::BasisChoice;
use crate::camera::Projection;
use crate::engine::{RelightOptions, Relighter};
use crate::light::{Light, LightRig};
use crate::maps::MapSpace;

/// A relightable image whose pixels are mixtures of a few SH functions (as a real
/// capture's pixels crowd into few directions), with depth.
fn image(basis: &str, w: usize, h: usize) -> RelightableImage {
    let dirs = crate::sphere::hemisphere_fibonacci(48);
    let b = BasisChoice::parse(basis)
        .unwrap()
        .build(&dirs, None)
        .unwrap();
    let k = b.len();
    let mut maps = CoefficientMaps::zeros(w, h, k);
    let atoms: Vec<Vec<f32>> = (0..4)
        .map(|a| {
            (0..k)
                .map(|i| (((i + 3 * a) * 7919 % 23) as f32 / 23.0 - 0.3) / (1.0 + i as f32))
                .collect()
        })
        .collect();
    for p in 0..w * h {
        let (x, y) = ((p % w) as f32 / w as f32, (p / w) as f32 / h as f32);
        let mix = [1.0, x, y * y, (x * 6.0).sin() * 0.3];
        for c in 0..3 {
            let tint = [1.0, 0.8 + 0.2 * x, 0.6][c];
            for i in 0..k {
                let v: f32 = (0..4).map(|a| mix[a] * atoms[a][i]).sum();
                maps.plane_mut(i, c)[p] = tint * v;
            }
        }
    }
    let mut meta = Metadata::new(
        b.spec(),
        MapSpace::Linear,
        Projection::Cylindrical {
            fov_y_deg: Some(60.0),
        },
    );
    meta.fit = None;
    RelightableImage {
        meta,
        maps,
        depth: Some((0..w * h).map(|p| 1.0 + p as f32 * 0.01).collect()),
    }
}

/// Relit frames of both images under a few directional lights; the largest error
/// relative to the frame's peak.
fn relit_error(a: &RelightableImage, b: &RelightableImage) -> f32 {
    let ra = Relighter::new(a).unwrap();
    let rb = Relighter::new(b).unwrap();
    let options = RelightOptions::default();
    let mut worst = 0.0f32;
    for d in crate::sphere::hemisphere_fibonacci(5) {
        let rig = LightRig::new(vec![Light::directional(d, [1.0, 1.0, 1.0])]);
        let fa = ra.relight(&rig, &options).unwrap();
        let fb = rb.relight(&rig, &options).unwrap();
        let peak = fa.data.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-6);
        let err = fa
            .data
            .iter()
            .zip(&fb.data)
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        worst = worst.max(err / peak);
    }
    worst
}

fn round_trip(img: &RelightableImage, settings: &Settings) -> (RelightableImage, usize) {
    let packed = pack(img, settings).unwrap();
    let bytes = packed::to_bytes(&packed).unwrap();
    let again = packed::from_bytes(&bytes, "test").unwrap();
    assert!(again == packed, "the file reads back what was written");
    (unpack(&again).unwrap(), bytes.len())
}

#[test]
fn all_components_at_16_bits_relight_like_the_maps() {
    for basis in ["sh:16", "sg:9"] {
        let img = image(basis, 40, 23);
        let settings = Settings {
            bits: 16,
            tile: 16,
            ..Settings::default()
        };
        let (back, _) = round_trip(&img, &settings);
        assert_eq!(back.depth, img.depth, "depth is lossless");
        assert_eq!(back.maps.k, img.maps.k);
        let e = relit_error(&img, &back);
        assert!(e < 1e-3, "{basis}: {e}");
    }
}

#[test]
fn four_components_hold_pixels_of_four_atoms() {
    // Every pixel mixes four atoms per channel (tinted): rgb needs 4 components, and
    // so does lrgb's luminance when the tint is one scale per channel.
    for layout in Layout::ALL {
        let img = image("sh:25", 33, 17);
        let settings = Settings {
            layout,
            components: Some(4),
            chroma: Some(4),
            bits: 14,
            tile: 32,
            ..Settings::default()
        };
        let (back, bytes) = round_trip(&img, &settings);
        assert_eq!(back.maps.k, 4);
        let e = relit_error(&img, &back);
        assert!(e < 2e-3, "{layout:?}: {e}");
        assert!(bytes < img.maps.bytes() / 4, "{layout:?}: {bytes} bytes");
    }
}

#[test]
fn fewer_bits_and_jpeg_cost_accuracy_not_correctness() {
    let img = image("sh:16", 64, 48);
    let mut last = 0.0;
    for bits in [12, 8, 5] {
        let settings = Settings {
            components: Some(6),
            bits,
            ..Settings::default()
        };
        let e = relit_error(&img, &round_trip(&img, &settings).0);
        // About a step of the first plane's range per component (relative to the
        // frame's peak, not the plane's range: a little more).
        let bound = 6.0 / ((1u32 << bits) - 1) as f32;
        assert!(
            e >= last * 0.9 && e < bound,
            "{bits} bits: {e} (bound {bound})"
        );
        last = e;
    }
    let jpeg = Settings {
        layout: Layout::Ycc,
        components: Some(6),
        codec: TileCodec::Jpeg { quality: 95 },
        ..Settings::default()
    };
    let (shared, shared_bytes) = round_trip(&img, &jpeg);
    let per_plane = Settings {
        jpeg_range: JpegRange::PerPlane,
        ..jpeg
    };
    let (own, own_bytes) = round_trip(&img, &per_plane);
    let (e_shared, e_own) = (relit_error(&img, &shared), relit_error(&img, &own));
    // The shared step spends fewer bits on the minor components, and loses a little
    // more there.
    assert!(
        e_own < 0.05 && e_shared < 0.1,
        "jpeg: {e_own}, shared {e_shared}"
    );
    assert!(
        shared_bytes < own_bytes,
        "{shared_bytes} vs {own_bytes} bytes"
    );
}

#[test]
fn a_compressed_image_compresses_again_without_nesting() {
    let img = image("sh:16", 20, 20);
    let first = unpack(
        &pack(
            &img,
            &Settings {
                components: Some(8),
                bits: 16,
                ..Settings::default()
            },
        )
        .unwrap(),
    )
    .unwrap();
    let second = unpack(
        &pack(
            &first,
            &Settings {
                components: Some(5),
                bits: 16,
                ..Settings::default()
            },
        )
        .unwrap(),
    )
    .unwrap();
    assert_eq!(second.maps.k, 5);
    let basis = second.meta.basis.build().unwrap();
    let p = basis.as_any().downcast_ref::<Projected>().unwrap();
    assert_eq!(p.inner().name(), "sh:16");
    assert!(relit_error(&img, &second) < 2e-3);
}

#[test]
fn bad_settings_are_refused() {
    let img = image("sh:9", 8, 8);
    for s in [
        Settings {
            bits: 1,
            ..Settings::default()
        },
        Settings {
            bits: 17,
            ..Settings::default()
        },
        Settings {
            tile: 8,
            ..Settings::default()
        },
        Settings {
            components: Some(0),
            ..Settings::default()
        },
        Settings {
            components: Some(10),
            ..Settings::default()
        },
    ] {
        assert!(pack(&img, &s).is_err(), "{s:?}");
    }
}

#[test]
fn damaged_files_are_refused_not_misread() {
    let img = image("sh:9", 30, 20);
    let packed = pack(
        &img,
        &Settings {
            tile: 16,
            ..Settings::default()
        },
    )
    .unwrap();
    let bytes = packed::to_bytes(&packed).unwrap();
    // Every truncation, and a flipped bit anywhere, is an error.
    for len in [0, 7, 8, 15, 20, bytes.len() / 2, bytes.len() - 1] {
        assert!(
            packed::from_bytes(&bytes[..len], "t").is_err(),
            "truncated to {len}"
        );
    }
    for at in (0..bytes.len()).step_by(bytes.len() / 97 + 1) {
        let mut b = bytes.clone();
        b[at] ^= 0x10;
        assert!(packed::from_bytes(&b, "t").is_err(), "flip at {at}");
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(packed::from_bytes(&longer, "t").is_err());
}

#[test]
fn a_header_that_claims_a_huge_image_is_refused_before_allocating() {
    let img = image("sh:4", 16, 16);
    let mut packed = pack(
        &img,
        &Settings {
            tile: 16,
            ..Settings::default()
        },
    )
    .unwrap();
    packed.header.width = 1 << 16;
    packed.header.height = 1 << 16;
    let bytes = packed::to_bytes(&packed).unwrap();
    let err = packed::from_bytes(&bytes, "t").unwrap_err().to_string();
    assert!(err.contains("sections"), "{err}");
    // Sections consistent with the size but a header beyond the limits.
    packed.header.width = (1 << 16) + 1;
    packed.sections = vec![Vec::new(); packed.header.sections()];
    assert!(unpack(&packed).is_err());
}

#[test]
fn a_codebook_file_reads_back_and_relights_by_look_up() {
    for layout in Layout::ALL {
        let img = image("sh:16", 24, 16);
        let vq = |entries| Settings {
            layout,
            components: Some(6),
            chroma: Some(6),
            bits: 14,
            tile: 16,
            codebook: Some(entries),
            ..Settings::default()
        };
        // As many entries as pixels: every pixel its own entry, only quantisation lost.
        let packed = pack(&img, &vq(4096)).unwrap();
        assert_eq!(packed.header.codebook, Some(24 * 16), "{layout:?}");
        let bytes = packed::to_bytes(&packed).unwrap();
        assert_eq!(
            &bytes[8..12],
            &2u32.to_le_bytes(),
            "codebook files are version 2"
        );
        let again = packed::from_bytes(&bytes, "test").unwrap();
        assert!(again == packed);
        let back = unpack(&again).unwrap();
        assert_eq!(back.depth, img.depth, "depth is lossless");
        let exact = relit_error(&img, &back);
        let planes = unpack(
            &pack(
                &img,
                &Settings {
                    codebook: None,
                    ..vq(2)
                },
            )
            .unwrap(),
        )
        .unwrap();
        let reference = relit_error(&img, &planes);
        assert!(
            exact <= reference * 1.5 + 1e-4,
            "{layout:?}: {exact} vs {reference}"
        );

        // Fewer entries cost accuracy, gradually.
        let coarse = relit_error(&img, &unpack(&pack(&img, &vq(8)).unwrap()).unwrap());
        let finer = relit_error(&img, &unpack(&pack(&img, &vq(64)).unwrap()).unwrap());
        assert!(
            finer < coarse && coarse < 0.5,
            "{layout:?}: 8 → {coarse}, 64 → {finer}"
        );

        // Relighting the codebook and looking pixels up gives the expanded maps' frame.
        let small = pack(&img, &vq(64)).unwrap();
        let indexed = indexed(&small).unwrap();
        assert_eq!(indexed.entries.maps.pixels(), 64);
        let expanded = unpack(&small).unwrap();
        let lookup = crate::engine::lookup::LookupRelighter::new(&indexed).unwrap();
        let light = Light::directional([0.2, 0.5, 0.8], [1.0, 0.7, 0.4]);
        let relighter = Relighter::new(&expanded).unwrap();
        let prepared = relighter
            .prepare(&light, &RelightOptions::default())
            .unwrap();
        let want = relighter.relight_prepared(&prepared, 0.0).unwrap();
        let mut got = crate::image::ImageRgb::new(0, 0);
        lookup
            .relight_prepared_into(&prepared, 0.0, &mut got)
            .unwrap();
        for (a, b) in got.data.iter().zip(&want.data) {
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1.0), "{a} vs {b}");
        }
    }
}

#[test]
fn codebook_files_refuse_jpeg_and_version_1() {
    let img = image("sh:9", 20, 12);
    let settings = Settings {
        codebook: Some(16),
        codec: TileCodec::Jpeg { quality: 90 },
        ..Settings::default()
    };
    let err = pack(&img, &settings).unwrap_err().to_string();
    assert!(err.contains("lossless"), "{err}");
    let packed = pack(
        &img,
        &Settings {
            codebook: Some(16),
            ..Settings::default()
        },
    )
    .unwrap();
    assert!(indexed(&pack(&img, &Settings::default()).unwrap()).is_err());
    let mut bytes = packed::to_bytes(&packed).unwrap();
    bytes[8..12].copy_from_slice(&1u32.to_le_bytes());
    let err = packed::from_bytes(&bytes, "old.rlz")
        .unwrap_err()
        .to_string();
    assert!(err.contains("codebook"), "{err}");
    bytes[8..12].copy_from_slice(&(container::VERSION + 1).to_le_bytes());
    assert!(packed::from_bytes(&bytes, "new.rlz").is_err());
}

#[test]
fn webp_planes_relight_close_in_a_version_2_file() {
    let img = image("sh:16", 64, 48);
    let settings = Settings {
        layout: Layout::Ycc,
        components: Some(6),
        codec: TileCodec::Webp { quality: 95 },
        tile: 32,
        ..Settings::default()
    };
    let packed = pack(&img, &settings).unwrap();
    let bytes = packed::to_bytes(&packed).unwrap();
    assert_eq!(
        &bytes[8..12],
        &2u32.to_le_bytes(),
        "WebP files are version 2"
    );
    let (back, _) = round_trip(&img, &settings);
    let e = relit_error(&img, &back);
    assert!(e < 0.1, "webp: {e}");
}

#[test]
fn the_budget_keeps_the_best_candidate_that_fits_and_more_bits_never_score_less() {
    let plane = crate::synth::BumpyPlane {
        width: 128,
        height: 96,
    };
    let dirs = crate::sphere::hemisphere_fibonacci(40);
    let capture = plane.capture(&dirs);
    let options = crate::fit::FitOptions {
        basis: crate::fit::BasisRequest::parse("sh:16").unwrap(),
        ..Default::default()
    };
    let fitted = crate::fit::fit(&capture, &options, &crate::progress::Silent).unwrap();
    let pixels = (128 * 96) as f64;
    let mut last = f64::NEG_INFINITY;
    for budget in [12.0, 64.0] {
        let choice =
            budget::choose(&fitted.image, &capture, budget, &crate::progress::Silent).unwrap();
        let bytes = packed::to_bytes(&choice.packed).unwrap().len();
        assert_eq!(choice.bits_per_pixel, 8.0 * bytes as f64 / pixels);
        assert!(choice.bits_per_pixel <= budget, "{budget}: {choice:?}");
        assert!(choice.within > 0 && choice.score.is_finite());
        // Judged one at a time, the candidates give the same choice and count.
        let alone = budget::choose_judging(
            &fitted.image,
            &capture,
            budget,
            &crate::progress::Silent,
            false,
        )
        .unwrap();
        assert_eq!(alone.settings, choice.settings);
        assert_eq!(
            (alone.score, alone.within, alone.bits_per_pixel),
            (choice.score, choice.within, choice.bits_per_pixel)
        );
        assert!(
            choice.score >= last,
            "{budget} bits/px scored {} < {last}",
            choice.score
        );
        last = choice.score;
    }
    assert!(last > 30.0, "{last} dB at 64 bits/px");
    let err = budget::choose(&fitted.image, &capture, 0.01, &crate::progress::Silent).unwrap_err();
    assert!(err.to_string().contains("no compression fits"), "{err}");
}

/// A large image's sample: windows inside the image on the lattice of their side (or
/// against its far edge), spread over it, none twice, each pixel of the sample the
/// image's; small images have none.
// `fit --budget` packs a large image's file a band at a time from its fit's temporary
// file: every candidate of the grid must be one the band packer takes.
#[test]
fn every_budget_candidate_packs_in_bands() {
    for k in [4, 6, 9, 16, 25, 36, 49, 64] {
        let grid = budget::grid(k);
        // Blocks of principal components and codebooks among them, which the band
        // packer takes only within limits.
        assert!(grid.iter().any(|s| s.pca_block.is_some()));
        assert!(grid.iter().any(|s| s.codebook.is_some()));
        for settings in grid {
            assert!(
                bands::packs_in_bands(&settings),
                "k {k}: {}",
                settings.describe()
            );
        }
    }
}

#[test]
fn a_large_images_sample_is_windows_spread_over_it() {
    use budget::{Sample, SAMPLE_ABOVE_PIXELS, SAMPLE_WINDOWS};
    assert_eq!(Sample::of(700, 700), None);
    assert!(SAMPLE_ABOVE_PIXELS >= 512 * 1024 && Sample::of(1024, 512).is_none());
    for (w, h) in [
        (1030, 520),
        (8192, 2048),
        (16384, 300),
        (900, 900),
        (5000, 200),
    ] {
        let sample = Sample::of(w, h).unwrap();
        let (sw, sh) = sample.side;
        assert_eq!((sw, sh), (256.min(w), 256.min(h)));
        let n = sample.windows.len();
        assert!(n == SAMPLE_WINDOWS.min(w / sw * (h / sh)), "{w}×{h}: {n}");
        for (i, &(x, y)) in sample.windows.iter().enumerate() {
            assert!(x + sw <= w && y + sh <= h, "{w}×{h}: {x},{y}");
            assert!(x % 256 == 0 || x + sw == w, "{w}×{h}: x {x}");
            assert!(y % 256 == 0 || y + sh == h, "{w}×{h}: y {y}");
            assert!(!sample.windows[..i].contains(&(x, y)), "{w}×{h}: twice");
        }
        // Spread: the windows reach both halves of the image's longer side.
        let (lo, hi) = match w >= h {
            true => sample
                .windows
                .iter()
                .map(|&(x, _)| x + sw / 2)
                .fold((w, 0), |(a, b), v| (a.min(v), b.max(v))),
            false => sample
                .windows
                .iter()
                .map(|&(_, y)| y + sh / 2)
                .fold((h, 0), |(a, b), v| (a.min(v), b.max(v))),
        };
        let long = w.max(h);
        assert!(lo < long / 2 && hi > long / 2, "{w}×{h}: {lo}..{hi}");
    }
    let img = image("sh:4", 1030, 520);
    let sample = Sample::of(1030, 520).unwrap();
    let part = sample.image(&img);
    let (pw, ph) = sample.size();
    assert_eq!((part.width(), part.height()), (pw, ph));
    assert!(part.meta.camera.is_none() && part.depth.is_none());
    for (i, &(x0, y0)) in sample.windows.iter().enumerate() {
        let (ox, oy) = ((i % sample.across) * 256, (i / sample.across) * 256);
        for (x, y) in [(0, 0), (255, 0), (17, 200), (255, 255)] {
            for plane in 0..3 * 4 {
                assert_eq!(
                    part.maps.data[plane * pw * ph + (oy + y) * pw + ox + x],
                    img.maps.data[plane * 1030 * 520 + (y0 + y) * 1030 + x0 + x],
                );
            }
        }
    }
}

/// A large image chooses its file on its sample and writes it whole: the file is the
/// image's, within the budget by its own bytes, scored on the sample's pixels.
#[test]
fn a_large_image_chooses_its_file_on_a_sample_and_keeps_the_budget() {
    let plane = crate::synth::BumpyPlane {
        width: 1100,
        height: 560,
    };
    let capture = plane.capture(&crate::sphere::hemisphere_fibonacci(9));
    let options = crate::fit::FitOptions {
        basis: crate::fit::BasisRequest::parse("sh:4").unwrap(),
        ..Default::default()
    };
    let fitted = crate::fit::fit(&capture, &options, &crate::progress::Silent).unwrap();
    let sample = budget::Sample::of(1100, 560).unwrap();
    let budget = 6.0;
    let choice = budget::choose(&fitted.image, &capture, budget, &crate::progress::Silent).unwrap();
    assert_eq!(
        (choice.packed.header.width, choice.packed.header.height),
        (1100, 560)
    );
    let bytes = packed::to_bytes(&choice.packed).unwrap().len();
    assert_eq!(choice.bits_per_pixel, 8.0 * bytes as f64 / (1100.0 * 560.0));
    assert!(choice.bits_per_pixel <= budget, "{choice:?}");
    let (sw, sh) = sample.size();
    assert_eq!(choice.judged_pixels, sw * sh);
    assert!(
        choice.within > 0 && choice.score.is_finite() && choice.score > 25.0,
        "{}",
        choice.score
    );
    // The file holds the whole image's maps, as packing the settings chosen makes it.
    let direct = pack(&fitted.image, &choice.settings).unwrap();
    assert!(packed::to_bytes(&direct).unwrap() == packed::to_bytes(&choice.packed).unwrap());
}

#[test]
fn a_region_reads_only_its_tiles_and_equals_that_crop_of_the_whole_file() {
    let img = image("sh:9", 70, 45);
    let jpeg = TileCodec::parse("jpeg:90").unwrap();
    let zstd = TileCodec::Zstd { level: 12 };
    let layouts = [
        (Layout::Rgb, zstd, None, false, None),
        (Layout::Ycc, jpeg, None, false, None),
        (Layout::Lrgb, zstd, None, false, None),
        (Layout::Rgb, zstd, Some(32), false, None),
        (Layout::Ycc, jpeg, None, true, None),
        (Layout::Lrgb, jpeg, None, true, None),
        // Blocks that do not line up with the tiles.
        (Layout::Ycc, jpeg, None, false, Some(24)),
        (Layout::Lrgb, zstd, None, true, Some(16)),
    ];
    for (layout, codec, codebook, gain, pca_block) in layouts {
        let settings = Settings {
            layout,
            codec,
            codebook,
            gain,
            pca_block,
            components: Some(5),
            tile: 16,
            ..Settings::default()
        };
        let packed_image = pack(&img, &settings).unwrap();
        let bytes = packed::to_bytes(&packed_image).unwrap();
        let whole = unpack(&packed::from_bytes(&bytes, "test").unwrap()).unwrap();
        // A region read leaves the depth tiles unread.
        let (across, down) = packed_image.header.tiles();
        let base = packed_image.header.plane_sections();
        let depth_bytes: usize = packed_image.sections[base..base + across * down]
            .iter()
            .map(Vec::len)
            .sum();
        assert!((0..packed_image.sections.len())
            .all(|s| depth_section(&packed_image.header, s)
                == (base..base + across * down).contains(&s)));
        // Inside one tile, across tile borders, along the image's edges, the whole image.
        for region in [
            (3, 2, 5, 4),
            (10, 12, 30, 20),
            (60, 40, 10, 5),
            (0, 0, 70, 45),
        ] {
            let mut cursor = std::io::Cursor::new(&bytes[..]);
            let (sparse, read) =
                packed::read_from(&mut cursor, bytes.len() as u64, "test", &|h, s| {
                    section_needed(h, s, region)
                })
                .unwrap();
            let part = unpack_region(&sparse, region).unwrap();
            let (x, y, w, h) = region;
            assert_eq!(
                (part.width(), part.height(), part.maps.k),
                (w, h, whole.maps.k)
            );
            for plane in 0..3 * whole.maps.k {
                for r in 0..h {
                    let row = &whole.maps.data[plane * 70 * 45 + (y + r) * 70 + x..][..w];
                    let got = &part.maps.data[plane * w * h + r * w..][..w];
                    assert_eq!(row, got, "{layout:?} {codebook:?} {region:?} plane {plane}");
                }
            }
            // The region's depth, from the depth sections it touches alone.
            let mut cursor = std::io::Cursor::new(&bytes[..]);
            let (sparse_depth, depth_read) =
                packed::read_from(&mut cursor, bytes.len() as u64, "test", &|h, s| {
                    depth_section_in(h, s, region)
                })
                .unwrap();
            let depth = unpack_depth_region(&sparse_depth, region).unwrap().unwrap();
            let full = whole.depth.as_deref().expect("the test image has depth");
            for r in 0..h {
                assert_eq!(
                    &depth[r * w..(r + 1) * w],
                    &full[(y + r) * 70 + x..][..w],
                    "{layout:?} {region:?} depth row {r}"
                );
            }
            let all = region == (0, 0, 70, 45);
            let header_and_index =
                bytes.len() - packed_image.sections.iter().map(Vec::len).sum::<usize>();
            assert!(
                depth_read as usize <= header_and_index + depth_bytes,
                "{region:?}: {depth_read} bytes read for depth"
            );
            if !all {
                assert!(
                    (depth_read as usize) < header_and_index + depth_bytes,
                    "{region:?}"
                );
            }
            // A codebook's file reads its codebook and the index tiles the region
            // touches, as a file of planes reads their tiles: never the depth, and
            // never a tile the region leaves out.
            let untouched: usize = (0..packed_image.sections.len())
                .filter(|&s| !section_needed(&packed_image.header, s, region))
                .map(|s| packed_image.sections[s].len())
                .sum();
            assert_eq!(
                read,
                (bytes.len() - untouched) as u64,
                "{region:?}: the sections needed, no others"
            );
            if !all {
                // One tile of fifteen, or six; the header and index (a few KiB on this
                // small image) are read whole.
                let bound = match region {
                    (3, 2, 5, 4) => bytes.len() / 3,
                    _ => bytes.len() * 3 / 4,
                };
                assert!(
                    read < bound as u64,
                    "{codebook:?} {region:?}: {read} of {} bytes read",
                    bytes.len()
                );
            } else {
                assert_eq!(
                    read,
                    (bytes.len() - depth_bytes) as u64,
                    "{region:?}: every section is read but depth's"
                );
            }
        }
        let sparse = packed::from_bytes(&bytes, "test").unwrap();
        for outside in [(60, 40, 11, 5), (0, 0, 0, 1), (usize::MAX, 0, 2, 2)] {
            assert!(unpack_region(&sparse, outside).is_err(), "{outside:?}");
            assert!(
                unpack_depth_region(&sparse, outside).is_err(),
                "{outside:?}"
            );
        }
    }
}

#[test]
fn a_gain_file_relights_like_the_maps_in_every_layout() {
    let img = image("sh:16", 40, 23);
    for layout in Layout::ALL {
        let settings = Settings {
            layout,
            bits: 16,
            tile: 16,
            gain: true,
            ..Settings::default()
        };
        let packed_image = pack(&img, &settings).unwrap();
        let header = &packed_image.header;
        assert!(header.gain);
        assert_eq!(
            header.planes.last().unwrap().channel,
            gain::CHANNEL,
            "the gain is the last plane"
        );
        let bytes = packed::to_bytes(&packed_image).unwrap();
        assert_eq!(
            &bytes[8..12],
            &3u32.to_le_bytes(),
            "gain files are version 3"
        );
        let (back, _) = round_trip(&img, &settings);
        let e = relit_error(&img, &back);
        // lrgb is exact only for pixels whose channels are scaled copies of one function
        // (this image's tint varies across it: the same bound as without the gain).
        let bound = if layout == Layout::Lrgb { 2e-2 } else { 1e-3 };
        assert!(e < bound, "{layout:?}: {e}");
    }
    // The gain scales the planes, so a file without one reads as before.
    let (plain, _) = round_trip(&img, &Settings::default());
    assert!(relit_error(&img, &plain) < 1e-3);
}

#[test]
fn the_gain_spends_precision_where_the_screen_shows_it() {
    // Left half a hundred times darker than the right: one quantiser step for the
    // whole image is invisible on the right and coarse on screen on the left.
    // Every relit value positive (the constant term dominates), as a lit surface's.
    let mut img = image("sh:9", 48, 32);
    let (w, n) = (48, 48 * 32);
    for (plane, values) in img.maps.data.chunks_exact_mut(n).enumerate() {
        for (p, v) in values.iter_mut().enumerate() {
            let lit = if plane < 3 {
                2.0 + (p as f32 * 0.37).sin()
            } else {
                0.2 * *v
            };
            *v = lit * if p % w < w / 2 { 0.004 } else { 0.4 };
        }
    }
    let on_screen = |back: &RelightableImage, dark: bool| -> f64 {
        let (ra, rb) = (Relighter::new(&img).unwrap(), Relighter::new(back).unwrap());
        let mut sum = 0.0;
        let mut count = 0;
        for d in crate::sphere::hemisphere_fibonacci(6) {
            let rig = LightRig::new(vec![Light::directional(d, [1.0, 1.0, 1.0])]);
            let options = RelightOptions::default();
            let (fa, fb) = (
                ra.relight(&rig, &options).unwrap(),
                rb.relight(&rig, &options).unwrap(),
            );
            for (i, (a, b)) in fa.data.iter().zip(&fb.data).enumerate() {
                if ((i / 3) % w < w / 2) == dark {
                    let e = crate::color::linear_to_srgb(*a) - crate::color::linear_to_srgb(*b);
                    sum += (e as f64).powi(2);
                    count += 1;
                }
            }
        }
        (sum / count as f64).sqrt()
    };
    let settings = Settings {
        layout: Layout::Ycc,
        chroma: Some(9),
        bits: 8,
        tile: 16,
        ..Settings::default()
    };
    let (plain, plain_bytes) = round_trip(&img, &settings);
    let (gained, gained_bytes) = round_trip(
        &img,
        &Settings {
            gain: true,
            ..settings
        },
    );
    let (plain_dark, gained_dark) = (on_screen(&plain, true), on_screen(&gained, true));
    let (plain_bright, gained_bright) = (on_screen(&plain, false), on_screen(&gained, false));
    assert!(
        gained_dark < plain_dark / 4.0,
        "dark half on screen: {gained_dark} with the gain, {plain_dark} without"
    );
    // The bright half gives up some of the precision it could not show.
    assert!(
        gained_bright < 4.0 * plain_bright.max(1.0 / 255.0),
        "bright half: {gained_bright} against {plain_bright}"
    );
    assert!(
        gained_bytes < 2 * plain_bytes,
        "{gained_bytes} vs {plain_bytes} bytes"
    );
}

#[test]
fn a_gain_refuses_a_codebook_in_settings_and_in_a_file() {
    let img = image("sh:9", 20, 20);
    let both = Settings {
        codebook: Some(16),
        gain: true,
        ..Settings::default()
    };
    assert!(pack(&img, &both).is_err());
    let mut packed_image = pack(
        &img,
        &Settings {
            codebook: Some(16),
            ..Settings::default()
        },
    )
    .unwrap();
    packed_image.header.gain = true;
    assert!(
        unpack(&packed_image).is_err(),
        "a codebook file claiming a gain"
    );
    // A gain file whose gain plane is missing is refused by name.
    let mut no_plane = pack(
        &img,
        &Settings {
            gain: true,
            ..Settings::default()
        },
    )
    .unwrap();
    no_plane.header.planes.pop();
    let err = unpack(&no_plane).unwrap_err().to_string();
    assert!(err.contains("gain"), "{err}");
}

/// An image whose left half mixes two atoms and whose right half two others: two
/// components a block hold it, where one projection for the file needs four.
fn halves(basis: &str, w: usize, h: usize) -> RelightableImage {
    let mut img = image(basis, w, h);
    let k = img.maps.k;
    let atom =
        |a: usize, i: usize| (((i + 5 * a) * 7919 % 29) as f32 / 29.0 - 0.4) / (1.0 + i as f32);
    for p in 0..w * h {
        let (x, y) = (p % w, p / w);
        let base = if x < w / 2 { 0 } else { 2 };
        let (s, t) = (1.0 + 0.5 * (y as f32 / h as f32), (x as f32 * 0.7).sin());
        for c in 0..3 {
            let tint = [1.0, 0.7, 0.5][c];
            for i in 0..k {
                img.maps.plane_mut(i, c)[p] = tint * (s * atom(base, i) + t * atom(base + 1, i));
            }
        }
    }
    img
}

#[test]
fn principal_components_per_block_decode_into_the_input_basis() {
    for basis in ["sh:16", "sg:9"] {
        let img = halves(basis, 48, 20);
        for layout in Layout::ALL {
            let settings = |pca_block| Settings {
                layout,
                components: Some(2),
                chroma: Some(2),
                bits: 16,
                tile: 16,
                pca_block,
                ..Settings::default()
            };
            let packed_image = pack(&img, &settings(Some(24))).unwrap();
            let bytes = packed::to_bytes(&packed_image).unwrap();
            assert_eq!(&bytes[8..12], &4u32.to_le_bytes(), "a version 4 file");
            let back = unpack(&packed::from_bytes(&bytes, "test").unwrap()).unwrap();
            assert_eq!(
                back.meta.basis, img.meta.basis,
                "decoded into the input basis"
            );
            assert_eq!(back.maps.k, img.maps.k);
            assert_eq!(back.depth, img.depth);
            let blocks = relit_error(&img, &back);
            let (once, _) = round_trip(&img, &settings(None));
            assert_eq!(once.maps.k, 2);
            let file = relit_error(&img, &once);
            assert!(blocks < 1e-3, "{basis} {layout:?}: per block {blocks}");
            assert!(
                file > 20.0 * blocks,
                "{basis} {layout:?}: once {file}, per block {blocks}"
            );
        }
    }
}

#[test]
fn principal_components_per_block_refuse_a_codebook_and_damaged_maps() {
    let img = halves("sh:9", 40, 20);
    let with = |codebook| Settings {
        codebook,
        components: Some(3),
        pca_block: Some(16),
        ..Settings::default()
    };
    assert!(
        pack(&img, &with(Some(16))).is_err(),
        "a codebook and blocks"
    );
    assert!(
        pack(
            &img,
            &Settings {
                pca_block: Some(8),
                ..with(None)
            }
        )
        .is_err(),
        "a block of 8"
    );
    let good = pack(&img, &with(None)).unwrap();
    assert!(unpack(&good).is_ok());
    let mut claims_codebook = pack(
        &img,
        &Settings {
            codebook: Some(16),
            ..Settings::default()
        },
    )
    .unwrap();
    claims_codebook.header.pca_block = Some(16);
    assert!(
        unpack(&claims_codebook).is_err(),
        "a codebook file claiming blocks"
    );
    let last = good.sections.len() - 1;
    let mut short = good.clone();
    short.sections[last].truncate(12);
    let err = unpack(&short).unwrap_err().to_string();
    assert!(err.contains("projections"), "{err}");
    let mut nan = good.clone();
    nan.sections[last][..4].copy_from_slice(&f32::NAN.to_le_bytes());
    let err = unpack(&nan).unwrap_err().to_string();
    assert!(err.contains("not finite"), "{err}");
    let mut missing = good.clone();
    missing.sections.pop();
    assert!(unpack(&missing).is_err(), "no projections section");
    let mut more_planes_than_functions = good.clone();
    more_planes_than_functions.header.meta.basis = BasisChoice::parse("sh:1")
        .unwrap()
        .build(&[], None)
        .unwrap()
        .spec();
    assert!(unpack(&more_planes_than_functions).is_err(), "K′ > K");
    // A reader of version 3 files cannot hold blocks: the file says version 4.
    let mut bytes = packed::to_bytes(&good).unwrap();
    bytes[8..12].copy_from_slice(&3u32.to_le_bytes());
    assert!(
        packed::from_bytes(&bytes, "test").is_err(),
        "blocks in a version 3 file"
    );
}

/// A codebook of the PCA residual: the planes keep `K′` components, the codebook the
/// next `R`; every reader decodes `K′ + R` functions, region by region as a whole.
#[test]
fn a_codebook_of_the_residual_adds_its_components_to_the_planes() {
    let img = halves("sh:25", 40, 30);
    let jpeg = TileCodec::parse("jpeg:95").unwrap();
    for layout in Layout::ALL {
        let planes = |codec| Settings {
            layout,
            components: Some(3),
            chroma: Some(3),
            bits: 12,
            tile: 16,
            codec,
            ..Settings::default()
        };
        let residual = |codec, entries, r| Settings {
            codebook: Some(entries),
            residual: Some(r),
            ..planes(codec)
        };
        for codec in [TileCodec::Zstd { level: 12 }, jpeg] {
            let alone = relit_error(&img, &unpack(&pack(&img, &planes(codec)).unwrap()).unwrap());
            let packed_image = pack(&img, &residual(codec, 1200, 6)).unwrap();
            assert_eq!(
                packed_image.header.residual.len(),
                6 * layout.channels().0.len()
            );
            assert!(!packed_image.header.indexed_pixels());
            let bytes = packed::to_bytes(&packed_image).unwrap();
            assert_eq!(
                &bytes[8..12],
                &5u32.to_le_bytes(),
                "residual files are version 5"
            );
            let again = packed::from_bytes(&bytes, "test").unwrap();
            assert!(again == packed_image);
            let back = unpack(&again).unwrap();
            assert_eq!(
                back.maps.k, 9,
                "{layout:?}: 3 planes and 6 from the codebook"
            );
            assert_eq!(back.depth, img.depth);
            // As many entries as pixels: the residual's components are kept (to 16
            // bits), so the file is as good as 9 planes.
            let nine = relit_error(
                &img,
                &unpack(
                    &pack(
                        &img,
                        &Settings {
                            components: Some(9),
                            ..planes(codec)
                        },
                    )
                    .unwrap(),
                )
                .unwrap(),
            );
            let exact = relit_error(&img, &back);
            assert!(
                exact < alone * 0.8 && exact <= nine * 1.2 + 1e-4,
                "{layout:?} {codec:?}: 3 planes {alone}, +6 by codebook {exact}, 9 planes {nine}"
            );
            // A small codebook still helps; less where the planes are near exact (JPEG's
            // own error hides the difference).
            let small = relit_error(
                &img,
                &unpack(&pack(&img, &residual(codec, 8, 6)).unwrap()).unwrap(),
            );
            assert!(
                small < alone && (codec.is_image() || exact <= small),
                "{layout:?} {codec:?}: {alone} ≥ {small} ≥ {exact}"
            );
            // Regions read the planes' and the index's tiles they touch, and equal the
            // crop of the whole.
            let region = (17, 3, 9, 12);
            let mut cursor = std::io::Cursor::new(&bytes[..]);
            let (sparse, read) =
                packed::read_from(&mut cursor, bytes.len() as u64, "test", &|h, s| {
                    section_needed(h, s, region)
                })
                .unwrap();
            assert!(read < bytes.len() as u64, "{read} of {}", bytes.len());
            let part = unpack_region(&sparse, region).unwrap();
            let (x, y, w, h) = region;
            for plane in 0..3 * back.maps.k {
                for r in 0..h {
                    let row = &back.maps.data[plane * 40 * 30 + (y + r) * 40 + x..][..w];
                    assert_eq!(row, &part.maps.data[plane * w * h + r * w..][..w]);
                }
            }
            // Its pixels are not indices alone: no look-up relighting.
            assert!(indexed(&again).is_err());
        }
    }
    // Refused: residual components without a codebook, or more than the basis has.
    for bad in [
        Settings {
            residual: Some(4),
            components: Some(3),
            ..Settings::default()
        },
        Settings {
            codebook: Some(16),
            residual: Some(23),
            components: Some(3),
            ..Settings::default()
        },
    ] {
        assert!(pack(&img, &bad).is_err(), "{bad:?}");
    }
    // A header whose residual components are out of order is refused.
    let mut damaged = pack(
        &img,
        &Settings {
            codebook: Some(16),
            residual: Some(2),
            components: Some(3),
            tile: 16,
            ..Settings::default()
        },
    )
    .unwrap();
    damaged.header.residual.swap(0, 1);
    assert!(unpack(&damaged).is_err());
}

/// Level `level` of `img` computed directly: each pixel the mean of the block of level 0
/// under it, `2^level` a side until the side reached 1 (what repeated 2×2 means with
/// rounding down give), and the depth's mean of the same block.
fn block_means(img: &RelightableImage, level: usize) -> RelightableImage {
    let (w, h) = (img.width(), img.height());
    let (lw, lh) = ((w >> level).max(1), (h >> level).max(1));
    let side = |n: usize| 1usize << level.min(n.ilog2() as usize);
    let (bw, bh) = (side(w), side(h));
    let mean = |plane: &[f32], x: usize, y: usize| -> f32 {
        let mut sum = 0.0f64;
        for sy in y * bh..(y + 1) * bh {
            for sx in x * bw..(x + 1) * bw {
                sum += plane[sy * w + sx] as f64;
            }
        }
        (sum / (bw * bh) as f64) as f32
    };
    let mut maps = CoefficientMaps::zeros(lw, lh, img.maps.k);
    for j in 0..3 * img.maps.k {
        let plane = &img.maps.data[j * w * h..(j + 1) * w * h];
        for y in 0..lh {
            for x in 0..lw {
                maps.data[j * lw * lh + y * lw + x] = mean(plane, x, y);
            }
        }
    }
    let depth = img.depth.as_ref().map(|d| {
        (0..lw * lh)
            .map(|p| mean(d, p % lw, p / lw))
            .collect::<Vec<f32>>()
    });
    RelightableImage {
        meta: img.meta.clone(),
        maps,
        depth,
    }
}

#[test]
fn a_file_with_mip_levels_holds_each_level_in_level_zeros_planes_and_reads_it_by_region() {
    let img = image("sh:9", 70, 45);
    let jpeg = TileCodec::parse("jpeg:90").unwrap();
    let zstd = TileCodec::Zstd { level: 12 };
    for (layout, codec, gain) in [
        (Layout::Rgb, zstd, false),
        (Layout::Ycc, jpeg, false),
        (Layout::Lrgb, zstd, true),
    ] {
        let flat = Settings {
            layout,
            codec,
            gain,
            components: Some(5),
            tile: 16,
            ..Settings::default()
        };
        let settings = Settings {
            mip_levels: true,
            ..flat.clone()
        };
        let single = pack(&img, &flat).unwrap();
        let packed_image = pack(&img, &settings).unwrap();
        let header = &packed_image.header;
        let sizes = crate::maps::mip_sizes(70, 45);
        assert_eq!(header.levels, sizes.len());
        // Level 0 is the file without levels, to the byte.
        assert_eq!(header.at_level(0), single.header);
        let zero = packed_image.clone().level(0).unwrap();
        assert!(
            zero == single,
            "{layout:?}: level 0 is the single-level file"
        );
        let bytes = packed::to_bytes(&packed_image).unwrap();
        let again = packed::from_bytes(&bytes, "test").unwrap();
        assert!(
            again == packed_image,
            "the file reads back what was written"
        );
        // Every level relights like the block means of the maps, about as closely as
        // level 0 relights like the maps, or as the level packed alone (its own
        // projection and quantisers: lrgb's one colour a pixel holds a coarse level's
        // mixed colours less well) relights like them.
        let error_zero = relit_error(&unpack(&again).unwrap(), &img);
        for (level, &(lw, lh)) in sizes.iter().enumerate().skip(1) {
            assert_eq!(header.level_size(level), (lw, lh));
            let expected = block_means(&img, level);
            let got = unpack(&again.clone().level(level).unwrap()).unwrap();
            assert_eq!((got.width(), got.height()), (lw, lh));
            let error = relit_error(&got, &expected);
            let alone = relit_error(
                &unpack(&pack(&expected, &flat).unwrap()).unwrap(),
                &expected,
            );
            assert!(
                error < 2.0 * error_zero.max(alone) + 1e-3,
                "{layout:?} level {level}: {error} against {error_zero} at level 0, {alone} alone"
            );
            // Depth is lossless: the block means of level 0's.
            let (got_depth, want_depth) = (got.depth.unwrap(), expected.depth.unwrap());
            for (g, w) in got_depth.iter().zip(&want_depth) {
                assert!(
                    (g - w).abs() <= 1e-5 * w.abs(),
                    "level {level} depth {g} ≠ {w}"
                );
            }
        }
        // A region of level 1 reads that level's tiles it touches alone and equals that
        // crop of the whole level.
        let level = 1;
        let whole = unpack(&again.clone().level(level).unwrap()).unwrap();
        let (lw, _) = header.level_size(level);
        let at = header.at_level(level);
        let region = (20, 5, 10, 12);
        let mut cursor = std::io::Cursor::new(&bytes[..]);
        let (sparse, read) = packed::read_from(&mut cursor, bytes.len() as u64, "test", &|h, s| {
            let (l, own) = h.section_level(s);
            l == level && (section_needed(&at, own, region) || depth_section_in(&at, own, region))
        })
        .unwrap();
        let level_bytes: usize = packed_image.sections[header.level_sections(level)]
            .iter()
            .map(Vec::len)
            .sum();
        let header_and_index = bytes.len() - packed_image.payload_bytes();
        assert!(
            (read as usize) < header_and_index + level_bytes / 2,
            "{layout:?}: {read} bytes read of a level of {level_bytes}"
        );
        let sparse = sparse.level(level).unwrap();
        let part = unpack_region(&sparse, region).unwrap();
        let depth = unpack_depth_region(&sparse, region).unwrap().unwrap();
        let (x, y, w, h) = region;
        for r in 0..h {
            for plane in 0..3 * whole.maps.k {
                let (i, c) = (plane / 3, plane % 3);
                let want = &whole.maps.plane(i, c)[(y + r) * lw + x..][..w];
                assert_eq!(&part.maps.plane(i, c)[r * w..][..w], want);
            }
            let want = &whole.depth.as_ref().unwrap()[(y + r) * lw + x..][..w];
            assert_eq!(&depth[r * w..][..w], want);
        }
        assert!(again.clone().level(sizes.len()).is_err());
    }
    // Levels are coded with one projection and level 0's quantisers: no codebook, no
    // projection a block; a header that claims more levels than the image has is refused.
    for settings in [
        Settings {
            mip_levels: true,
            codebook: Some(16),
            ..Settings::default()
        },
        Settings {
            mip_levels: true,
            pca_block: Some(32),
            components: Some(4),
            ..Settings::default()
        },
    ] {
        assert!(pack(&img, &settings).is_err());
    }
    let mut packed_image = pack(
        &img,
        &Settings {
            mip_levels: true,
            tile: 16,
            ..Settings::default()
        },
    )
    .unwrap();
    packed_image.header.levels = 8;
    packed_image
        .sections
        .resize(packed_image.header.sections(), Vec::new());
    let err = unpack(&packed_image).unwrap_err().to_string();
    assert!(err.contains("mip levels"), "{err}");
}

/// Sections [`bands::pack_in_bands`] makes, by number.
#[derive(Default)]
struct Collected(std::collections::BTreeMap<usize, Vec<u8>>);

impl bands::SectionSink for Collected {
    fn put(&mut self, section: usize, bytes: Vec<u8>) -> Result<()> {
        assert!(
            self.0.insert(section, bytes).is_none(),
            "section {section} made twice"
        );
        Ok(())
    }
}

/// Packing a band of rows at a time makes the file `pack` makes from the whole image,
/// byte for byte: every layout, zstd and JPEG, all or fewer components, with and
/// without mip levels, depth and the perceptual gain (over the basis' domain or the
/// capture's lights), principal components a block (with and without the gain, blocks
/// cut by the image's edges), codebooks (of every pixel's planes, with `lrgb`'s weighed
/// albedo, and of the residual beside JPEG and zstd planes; trained on every few pixels
/// of a big image), sizes that are no multiple of the tile (odd ones, and a level of
/// one row or column).
#[test]
fn a_file_packed_band_by_band_is_the_file_packed_whole() {
    let odd = image("sh:9", 77, 41);
    let mut flat = image("hsh:9", 300, 1);
    flat.depth = None;
    let tall = image("sh:4", 17, 90);
    // More pixels than the principal components and the quantiles are found on: both
    // take every few pixels, across bands.
    let big = image("sh:4", 640, 640);
    let cases = [
        (
            &big,
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:80").unwrap(),
                tile: 256,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                tile: 16,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:85").unwrap(),
                components: Some(5),
                tile: 32,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                layout: Layout::Lrgb,
                bits: 10,
                tile: 24,
                ..Settings::default()
            },
        ),
        (
            &flat,
            Settings {
                layout: Layout::Ycc,
                chroma: Some(2),
                components: Some(6),
                tile: 16,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &tall,
            Settings {
                codec: TileCodec::parse("webp:80").unwrap(),
                jpeg_range: JpegRange::PerPlane,
                tile: 16,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &tall,
            Settings {
                layout: Layout::Lrgb,
                codec: TileCodec::parse("jpeg:90").unwrap(),
                tile: 64,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &big,
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:90").unwrap(),
                components: Some(3),
                tile: 128,
                gain: true,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                tile: 16,
                gain: true,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                layout: Layout::Lrgb,
                codec: TileCodec::parse("webp:75").unwrap(),
                jpeg_range: JpegRange::PerPlane,
                tile: 32,
                gain: true,
                directions: Some(crate::sphere::hemisphere_fibonacci(100)),
                ..Settings::default()
            },
        ),
        (
            &flat,
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:80").unwrap(),
                tile: 16,
                gain: true,
                mip_levels: true,
                ..Settings::default()
            },
        ),
        (
            &big,
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:85").unwrap(),
                components: Some(3),
                tile: 128,
                pca_block: Some(64),
                gain: true,
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                tile: 32,
                pca_block: Some(16),
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                layout: Layout::Lrgb,
                bits: 10,
                components: Some(5),
                tile: 32,
                pca_block: Some(32),
                ..Settings::default()
            },
        ),
        // Blocks across tile rows: smaller than a tile, larger than one, and with the
        // gain, whose decoded values divide the blocks' pixels.
        (
            &odd,
            Settings {
                tile: 32,
                pca_block: Some(24),
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                layout: Layout::Lrgb,
                components: Some(3),
                tile: 16,
                pca_block: Some(24),
                ..Settings::default()
            },
        ),
        (
            &big,
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:85").unwrap(),
                components: Some(3),
                tile: 128,
                pca_block: Some(96),
                gain: true,
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                components: Some(4),
                tile: 16,
                codebook: Some(64),
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                layout: Layout::Lrgb,
                components: Some(3),
                tile: 32,
                codebook: Some(300),
                ..Settings::default()
            },
        ),
        (
            &big,
            Settings {
                layout: Layout::Ycc,
                components: Some(2),
                tile: 128,
                codebook: Some(32),
                ..Settings::default()
            },
        ),
        (
            &odd,
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:85").unwrap(),
                components: Some(3),
                tile: 16,
                codebook: Some(48),
                residual: Some(2),
                ..Settings::default()
            },
        ),
        (
            &big,
            Settings {
                layout: Layout::Lrgb,
                components: Some(2),
                tile: 256,
                codebook: Some(16),
                residual: Some(1),
                ..Settings::default()
            },
        ),
    ];
    for (i, (img, settings)) in cases.into_iter().enumerate() {
        assert!(bands::packs_in_bands(&settings));
        let whole = pack(img, &settings).unwrap();
        let mut sink = Collected::default();
        let header =
            bands::pack_in_bands(img, &settings, &mut sink, &crate::progress::Silent).unwrap();
        assert_eq!(header, whole.header, "case {i}: header");
        assert_eq!(
            sink.0.keys().copied().collect::<Vec<_>>(),
            (0..header.sections()).collect::<Vec<_>>(),
            "case {i}: every section once"
        );
        for (s, bytes) in sink.0 {
            assert!(bytes == whole.sections[s], "case {i}: section {s}");
        }
    }
    // What is packed whole is refused, not packed differently.
    for settings in [
        // A codebook with mip levels (which `pack` refuses too).
        Settings {
            codebook: Some(16),
            mip_levels: true,
            ..Settings::default()
        },
        // Blocks with mip levels.
        Settings {
            tile: 32,
            pca_block: Some(16),
            mip_levels: true,
            ..Settings::default()
        },
    ] {
        assert!(!bands::packs_in_bands(&settings));
        let refused = bands::pack_in_bands(
            &odd,
            &settings,
            &mut Collected::default(),
            &crate::progress::Silent,
        );
        assert!(refused.is_err());
    }
}

/// A band source that gives other rows than it was asked for is refused with an error,
/// neither indexed out of bounds nor packed.
#[test]
fn a_band_source_that_gives_another_shape_is_refused() {
    struct Short(RelightableImage);
    impl bands::BandSource for Short {
        fn meta(&self) -> &Metadata {
            &self.0.meta
        }
        fn shape(&self) -> (usize, usize, usize) {
            (self.0.width(), self.0.height(), self.0.maps.k)
        }
        fn has_depth(&self) -> bool {
            self.0.depth.is_some()
        }
        fn band(&self, rows: std::ops::Range<usize>) -> Result<RelightableImage> {
            // One row short.
            bands::BandSource::band(&self.0, rows.start..rows.end - 1)
        }
    }
    let source = Short(image("sh:4", 40, 20));
    let settings = Settings {
        tile: 16,
        ..Settings::default()
    };
    let refused = bands::pack_in_bands(
        &source,
        &settings,
        &mut Collected::default(),
        &crate::progress::Silent,
    );
    let message = refused.unwrap_err().to_string();
    assert!(message.contains("another shape"), "{message}");
}

/// Every function channel's coefficients formed at once are each one's alone, bit for
/// bit, in every layout.
#[test]
fn a_pixels_functions_at_once_are_each_ones_alone() {
    let img = image("sh:9", 13, 7);
    for layout in [Layout::Rgb, Layout::Ycc, Layout::Lrgb] {
        let functions = layout.channels().0.len();
        let mut all = vec![f32::NAN; functions * 9];
        for p in [0, 5, 90] {
            undivided_all(layout, &img.maps, p, &mut all);
            for f in 0..functions {
                for i in 0..9 {
                    let alone = undivided(layout, &img.maps, i, f, p);
                    assert_eq!(all[f * 9 + i].to_bits(), alone.to_bits(), "{layout:?}");
                }
            }
        }
    }
}

/// A plane's quantiles, selected, are those of its sorted subsample: with repeated
/// values, signed zeros, one value and none.
#[test]
fn a_planes_quantiles_are_those_of_its_sorted_subsample() {
    let sorted_quantiles = |values: &[f32], q: f64| {
        let mut v = values.to_vec();
        v.sort_by(f32::total_cmp);
        let at = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
        (at(q), at(1.0 - q))
    };
    let jpeg = TileCodec::parse("jpeg:90").unwrap();
    let mut rng = 12345u64;
    let mut next = || {
        rng = rng
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((rng >> 40) % 1000) as f32 / 100.0 - 5.0
    };
    let noisy: Vec<f32> = (0..30_001).map(|_| next()).collect();
    for values in [
        noisy,
        vec![0.0, -0.0, 0.0, -0.0, 1.0],
        vec![3.0; 17],
        vec![2.5],
        vec![-1.0, 1.0],
    ] {
        let stats = PlaneStats::of(&values, jpeg);
        for q in [1e-4, 0.01, 0.25, 0.5] {
            let (lo, hi) = stats.percentiles(q);
            let (want_lo, want_hi) = sorted_quantiles(&values, q);
            assert_eq!(
                (lo.to_bits(), hi.to_bits()),
                (want_lo.to_bits(), want_hi.to_bits())
            );
        }
    }
    assert_eq!(PlaneStats::of(&[], jpeg).percentiles(1e-4), (0.0, 0.0));
}

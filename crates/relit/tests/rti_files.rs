//! The RTI tools' files (`.ptm`, HSH `.rti`): byte layout checked by hand (row order,
//! term order and signs against the viewers' own formulas), round trips on a real
//! capture scored against its photographs, and malformed files refused.

use relit::basis::{BasisChoice, BasisSpec};
use relit::capture::Capture;
use relit::codec::{ptm, rti};
use relit::engine::{RelightOptions, Relighter};
use relit::fit::{BasisRequest, FitOptions};
use relit::light::{Light, LightRig};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::sphere::Vec3;
use std::path::{Path, PathBuf};

/// A `width × height` image of `basis` whose coefficient `i`, channel `c` at pixel
/// `(x, y)` is `f(x, y, i, c)`.
fn image(
    basis: &str,
    width: usize,
    height: usize,
    f: impl Fn(usize, usize, usize, usize) -> f32,
) -> RelightableImage {
    let spec = BasisSpec::named(basis).unwrap();
    let k = spec.build().unwrap().len();
    let mut maps = CoefficientMaps::zeros(width, height, k);
    let n = width * height;
    for y in 0..height {
        for x in 0..width {
            for i in 0..k {
                for c in 0..3 {
                    maps.data[(3 * i + c) * n + y * width + x] = f(x, y, i, c);
                }
            }
        }
    }
    RelightableImage {
        meta: Metadata::new(spec, MapSpace::Srgb, Default::default()),
        maps,
        depth: None,
    }
}

/// Where the binary data starts: after `lines` line breaks.
fn data_offset(bytes: &[u8], lines: usize) -> usize {
    bytes
        .iter()
        .enumerate()
        .filter(|(_, &b)| b == b'\n')
        .nth(lines - 1)
        .unwrap()
        .0
        + 1
}

#[test]
fn ptm_rows_run_from_the_bottom_of_the_image_up() {
    // The constant term: 0.8 on the top row, 0.2 on the bottom one.
    let original = image(
        "ptm:6",
        3,
        2,
        |_, y, i, _| {
            if i == 5 {
                [0.8, 0.2][y]
            } else {
                0.0
            }
        },
    );
    let bytes = ptm::encode(&original, ptm::PtmFormat::Rgb).unwrap();
    let text = String::from_utf8_lossy(&bytes[..data_offset(&bytes, 6)]).to_string();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(&lines[..4], &["PTM_1.2", "PTM_FORMAT_RGB", "3", "2"]);
    let scale: Vec<f32> = lines[4].split(' ').map(|v| v.parse().unwrap()).collect();
    let bias: Vec<f32> = lines[5].split(' ').map(|v| v.parse().unwrap()).collect();
    // The first pixel of the red block is the bottom-left one: a5 = 0.2 · 255.
    let data = &bytes[data_offset(&bytes, 6)..];
    let a5 = (data[5] as f32 - bias[5]) * scale[5];
    assert!((a5 - 0.2 * 255.0).abs() < 1.0, "first stored a5 = {a5}");
    // Three blocks of 6 bytes per pixel.
    assert_eq!(data.len(), 3 * 6 * 6);
    let back = ptm::decode(Path::new("x.ptm"), &bytes).unwrap();
    let top = back.maps.plane(5, 0)[0];
    assert!((top - 0.8).abs() < 0.005, "top row read back as {top}");
    // LRGB: one coefficient block, then the colours.
    let lrgb = ptm::encode(&original, ptm::PtmFormat::Lrgb).unwrap();
    assert_eq!(lrgb.len() - data_offset(&lrgb, 6), 6 * (6 + 3));
    let back = ptm::decode(Path::new("x.ptm"), &lrgb).unwrap();
    assert!((back.maps.plane(5, 1)[0] - 0.8).abs() < 0.01);
    assert!((back.maps.plane(5, 1)[5] - 0.2).abs() < 0.01);
}

/// The nine functions RTIViewer, relight and OpenLIME evaluate for an HSH file, written
/// out from their definition (θ from +z, φ = atan2(y, x)).
fn viewer_hsh(d: Vec3) -> [f64; 9] {
    use std::f64::consts::PI;
    let phi = d.y.atan2(d.x);
    let r = d.z;
    let s = (r - r * r).sqrt();
    [
        1.0 / (2.0 * PI).sqrt(),
        (6.0 / PI).sqrt() * phi.cos() * s,
        (3.0 / (2.0 * PI)).sqrt() * (2.0 * r - 1.0),
        (6.0 / PI).sqrt() * s * phi.sin(),
        (30.0 / PI).sqrt() * (2.0 * phi).cos() * (r * r - r),
        (30.0 / PI).sqrt() * phi.cos() * (2.0 * r - 1.0) * s,
        (5.0 / (2.0 * PI)).sqrt() * (1.0 - 6.0 * r + 6.0 * r * r),
        (30.0 / PI).sqrt() * (2.0 * r - 1.0) * s * phi.sin(),
        (30.0 / PI).sqrt() * (r * r - r) * (2.0 * phi).sin(),
    ]
}

/// An HSH `.rti` of one pixel whose term `k` decodes to 1 and every other to 0.
fn one_term_rti(k: usize) -> Vec<u8> {
    let mut bytes = b"#HSH1.2\r\n3\r\n1 1 3\r\n9 2 1\r\n".to_vec();
    for _ in 0..9 {
        bytes.extend_from_slice(&1.0f32.to_le_bytes()); // scale
    }
    for _ in 0..9 {
        bytes.extend_from_slice(&0.0f32.to_le_bytes()); // bias
    }
    for _ in 0..3 {
        for t in 0..9 {
            bytes.push(if t == k { 255 } else { 0 });
        }
    }
    bytes
}

#[test]
fn rti_terms_are_the_viewers_functions() {
    let basis = BasisSpec::named("hsh:9").unwrap().build().unwrap();
    let directions = [
        Vec3::new(0.3, 0.2, 0.93),
        Vec3::new(-0.6, 0.1, 0.79),
        Vec3::new(0.2, -0.7, 0.68),
        Vec3::new(-0.5, -0.5, 0.71),
    ];
    for k in 0..9 {
        let image = rti::decode(Path::new("t.rti"), &one_term_rti(k)).unwrap();
        for &d in &directions {
            let d = d.normalized().unwrap();
            let weights = basis.values(d);
            let relit: f64 = (0..9)
                .map(|i| image.maps.plane(i, 1)[0] as f64 * weights[i])
                .sum();
            let viewer = viewer_hsh(d)[k];
            assert!(
                (relit - viewer).abs() < 1e-5,
                "term {k} at {d:?}: relit {relit}, viewers {viewer}"
            );
        }
    }
}

#[test]
fn rti_rows_run_from_the_top_of_the_image_down() {
    let original = image("hsh:9", 2, 3, |_, y, i, c| {
        if i == 0 {
            [0.9, 0.5, 0.1][y] * [1.0, 0.8, 0.6][c]
        } else {
            0.01 * i as f32
        }
    });
    let bytes = rti::encode(&original).unwrap();
    let offset = data_offset(&bytes, 4);
    assert_eq!(&bytes[..offset], b"#HSH1.2\n3\n2 3 3\n9 2 1\n");
    let float = |i: usize| {
        f32::from_le_bytes(
            bytes[offset + 4 * i..offset + 4 * i + 4]
                .try_into()
                .unwrap(),
        )
    };
    let (scale0, bias0) = (float(0), float(9));
    let data = &bytes[offset + 72..];
    // First pixel, red, term 0: the top row.
    let first = data[0] as f32 / 255.0 * scale0 + bias0;
    assert!((first - 0.9).abs() < 0.01, "first stored term = {first}");
    assert_eq!(data.len(), 2 * 3 * 27);
    let back = rti::decode(Path::new("x.rti"), &bytes).unwrap();
    for (p, want) in [(0, 0.9), (2, 0.5), (4, 0.1)] {
        assert!((back.maps.plane(0, 0)[p] - want).abs() < 0.005);
    }
}

fn shared_item(name: &str) -> Option<PathBuf> {
    relit::skip::shared(&format!("data/realrti/{name}/dirs.lp"))
}

/// Mean 8-bit sRGB PSNR of `image` relit at captured lights `lights` against the photos,
/// and the same with the relit frames upside down.
fn score(image: &RelightableImage, capture: &Capture, lights: &[usize]) -> (f64, f64) {
    let relighter = Relighter::new(image).unwrap();
    let directions = capture.directions();
    let (mut straight, mut flipped) = (0.0, 0.0);
    for &j in lights {
        let rig = LightRig::new(vec![Light::directional(directions[j], [1.0; 3])]);
        let relit = relighter.relight(&rig, &RelightOptions::default()).unwrap();
        let photo = capture.load(j).unwrap();
        straight += relit::metrics::psnr_srgb8(&relit.data, &photo.data);
        let row = 3 * relit.width;
        let upside_down: Vec<f32> = relit.data.chunks(row).rev().flatten().copied().collect();
        flipped += relit::metrics::psnr_srgb8(&upside_down, &photo.data);
    }
    (
        straight / lights.len() as f64,
        flipped / lights.len() as f64,
    )
}

/// item9 (48 lights, 279×289): display-space fits of the files' own bases, written,
/// read back and relit at three captured lights against the photographs. Measured:
/// ptm:6 fit 24.66 dB, RGB .ptm 24.66, LRGB .ptm 24.59, JPEG RGB (quality 90) 24.60,
/// JPEG LRGB 24.55; hsh:9 fit 25.04, .rti 25.04; upside down 17.5 and 16.9 dB.
#[test]
fn files_relight_like_their_fits_against_real_photographs() {
    let Some(lp) = shared_item("item9") else {
        return;
    };
    let capture = Capture::open(&lp).unwrap();
    let lights = [0, 20, 40];
    for basis in ["ptm:6", "hsh:9"] {
        let options = FitOptions {
            basis: BasisRequest::Fixed(BasisChoice::parse(basis).unwrap()),
            color_space: Some(MapSpace::Srgb),
            ..FitOptions::default()
        };
        let fitted = relit::fit::fit(&capture, &options, &relit::progress::Silent)
            .unwrap()
            .image;
        let (fit, _) = score(&fitted, &capture, &lights);
        let files: Vec<(&str, RelightableImage)> = if basis == "ptm:6" {
            [
                ptm::PtmFormat::Rgb,
                ptm::PtmFormat::Lrgb,
                ptm::PtmFormat::JpegRgb(90),
                ptm::PtmFormat::JpegLrgb(90),
            ]
            .into_iter()
            .map(|f| {
                let bytes = ptm::encode(&fitted, f).unwrap();
                ("ptm", ptm::decode(Path::new("x.ptm"), &bytes).unwrap())
            })
            .collect()
        } else {
            let bytes = rti::encode(&fitted).unwrap();
            vec![("rti", rti::decode(Path::new("x.rti"), &bytes).unwrap())]
        };
        for (kind, file) in files {
            let (read, upside_down) = score(&file, &capture, &lights);
            eprintln!(
                "{basis}: fit {fit:.2} dB, .{kind} {read:.2} dB, upside down {upside_down:.2} dB"
            );
            assert!(
                read > fit - 0.2,
                "{basis} .{kind}: {read:.2} dB against the fit's {fit:.2}"
            );
            assert!(
                upside_down < read - 5.0,
                "{basis} .{kind}: orientation barely matters?"
            );
        }
    }
}

#[test]
fn malformed_files_are_refused_with_the_file_and_field() {
    let good_ptm = ptm::encode(
        &image("ptm:6", 4, 3, |_, _, i, _| 0.1 * i as f32),
        ptm::PtmFormat::Lrgb,
    )
    .unwrap();
    let good_rti = rti::encode(&image("hsh:9", 4, 3, |_, _, i, _| 0.05 * i as f32)).unwrap();
    let replace = |bytes: &[u8], from: &str, to: &str| -> Vec<u8> {
        let at = bytes
            .windows(from.len())
            .position(|w| w == from.as_bytes())
            .unwrap();
        [&bytes[..at], to.as_bytes(), &bytes[at + from.len()..]].concat()
    };
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "x.ptm",
            good_ptm[..good_ptm.len() - 1].to_vec(),
            "truncated",
        ),
        ("x.ptm", Vec::new(), "PTM 1.2"),
        (
            "x.ptm",
            b"PTM_1.2\nPTM_FORMAT_LUM\n".to_vec(),
            "PTM_FORMAT_LUM",
        ),
        (
            "x.ptm",
            replace(&good_ptm, "\n4\n3\n", "\n1073741824\n1073741824\n"),
            "65536",
        ),
        (
            "x.ptm",
            replace(&good_ptm, "\n4\n3\n", "\nfour\n3\n"),
            "width",
        ),
        (
            "x.ptm",
            replace(&good_ptm, "PTM_FORMAT_LRGB\n", "PTM_FORMAT_LRGB\nNaN NaN\n"),
            "header",
        ),
        (
            "x.rti",
            good_rti[..good_rti.len() - 5].to_vec(),
            "truncated",
        ),
        (
            "x.rti",
            replace(&good_rti, "\n3\n4 3 3", "\n1\n4 3 3"),
            "file type 1",
        ),
        ("x.rti", replace(&good_rti, "9 2 1", "7 2 1"), "7 terms"),
        ("x.rti", replace(&good_rti, "4 3 3", "4 3 4"), "channels"),
        (
            "x.rti",
            replace(&good_rti, "4 3 3", "70000 70000 3"),
            "65536",
        ),
        ("x.rti", good_rti[..40].to_vec(), "scale and bias"),
    ];
    for (name, bytes, says) in cases {
        let path = Path::new(name);
        let result = if name.ends_with("ptm") {
            ptm::decode(path, &bytes)
        } else {
            rti::decode(path, &bytes)
        };
        let message = result.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(
            message.contains(name) && message.contains(says),
            "{name} ({says}): `{message}`"
        );
    }
    // Non-finite header values.
    let nan = replace(&good_ptm, "\n4\n3\n", "\n4\n3\nNaN ");
    assert!(ptm::decode(Path::new("x.ptm"), &nan).is_err());
}

#[test]
fn any_basis_is_re_expressed_for_the_rti_files() {
    // An SH image written as .ptm and .rti: the functions agree on the dome within what
    // a biquadratic / 9 HSH terms can hold of a smooth function.
    let sh = image("sh:4", 2, 2, |x, _, i, c| {
        [0.5, 0.1, 0.2, 0.05][i] * (1.0 + 0.1 * (x + c) as f32)
    });
    let basis = BasisSpec::named("sh:4").unwrap().build().unwrap();
    for (bytes, reader) in [
        (
            ptm::encode(&sh, ptm::PtmFormat::Rgb).unwrap(),
            ptm::decode as fn(&Path, &[u8]) -> relit::Result<RelightableImage>,
        ),
        (rti::encode(&sh).unwrap(), rti::decode),
    ] {
        let back = reader(Path::new("x"), &bytes).unwrap();
        let target = back.meta.basis.build().unwrap();
        for d in [Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.4, 0.3, 0.866)] {
            let d = d.normalized().unwrap();
            let (ws, wt) = (basis.values(d), target.values(d));
            let want: f64 = (0..4).map(|i| sh.maps.plane(i, 0)[0] as f64 * ws[i]).sum();
            let got: f64 = (0..target.len())
                .map(|i| back.maps.plane(i, 0)[0] as f64 * wt[i])
                .sum();
            assert!(
                (got - want).abs() < 0.01,
                "{} at {d:?}: {got} against {want}",
                target.name()
            );
        }
    }
}

/// An older `.hsh` file without the `#HSH1.2` comment reads as the same terms, by its
/// contents and by its name; a `.hsh` output is written as an HSH file.
#[test]
fn hsh_files_without_the_comment_read_like_rti_files() {
    let with = one_term_rti(4);
    let without = with[b"#HSH1.2\r\n".len()..].to_vec();
    assert!(without.starts_with(b"3\r\n"));
    let a = rti::decode(Path::new("t.rti"), &with).unwrap();
    let b = rti::decode(Path::new("t.hsh"), &without).unwrap();
    assert_eq!(a.maps.data, b.maps.data);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.hsh");
    std::fs::write(&path, &without).unwrap();
    assert!(relit::codec::FileForm::of(&path).unwrap() == relit::codec::FileForm::Rti);
    assert_eq!(relit::codec::read(&path).unwrap().maps.data, a.maps.data);
    assert!(
        relit::codec::FileForm::for_output(&dir.path().join("new.HSH"))
            == relit::codec::FileForm::Rti
    );
    // Text that only looks like a number is not taken for one.
    assert!(rti::decode(Path::new("t.hsh"), b"30\n1 1 3\n").is_err());
}

/// A `PTM_FORMAT_JPEG_LRGB` header and data of `w × h` pixels from its nine planes'
/// streams, with the given decoding order, references (transform bit 0: inverted) and
/// side information.
fn jpeg_lrgb_file(
    w: usize,
    h: usize,
    streams: &[Vec<u8>],
    transforms: &[i32; 9],
    order: &[i32; 9],
    references: &[i32; 9],
    side: &[Vec<u8>],
) -> Vec<u8> {
    let line = |v: Vec<String>| v.join(" ") + "\n";
    let mut text = format!("PTM_1.2\nPTM_FORMAT_JPEG_LRGB\n{w}\n{h}\n");
    text += "0.5 0.5 0.5 0.5 0.5 1.0 \n10 20 30 40 50 0 \n90\n";
    text += &line(transforms.iter().map(|t| t.to_string()).collect());
    text += &line(vec!["0".into(); 9]);
    text += &line(vec!["0".into(); 9]);
    text += &line(order.iter().map(|t| t.to_string()).collect());
    text += &line(references.iter().map(|t| t.to_string()).collect());
    text += &line(streams.iter().map(|s| s.len().to_string()).collect());
    text += &line(side.iter().map(|s| s.len().to_string()).collect());
    let mut bytes = text.into_bytes();
    for (stream, info) in streams.iter().zip(side) {
        bytes.extend_from_slice(stream);
        bytes.extend_from_slice(info);
    }
    bytes
}

/// A constant grayscale JPEG (exact at quality 100).
fn flat_jpeg(w: usize, h: usize, value: u8) -> Vec<u8> {
    let mut out = Vec::new();
    jpeg_encoder::Encoder::new(&mut out, 100)
        .encode(
            &vec![value; w * h],
            w as u16,
            h as u16,
            jpeg_encoder::ColorType::Luma,
        )
        .unwrap();
    out
}

/// The JPEG variants' prediction from a reference plane (plain and inverted), decoding
/// order and side-information corrections, against the raw LRGB file of the same codes;
/// then each malformed header refused by name.
#[test]
fn jpeg_ptm_predictions_and_corrections_decode_to_the_raw_codes() {
    let (w, h) = (16, 8);
    let n = w * h;
    // The codes each plane must decode to (pixel 5 of plane 1 and pixel 9 of plane 7
    // corrected by side information).
    let mut want: Vec<Vec<u8>> = [200u8, 90, 70, 60, 50, 40, 180, 120, 30]
        .iter()
        .map(|&v| vec![v; n])
        .collect();
    want[1][5] = 17;
    want[7][9] = 250;
    // Plane 0 predicts from plane 1 as completed, its correction included.
    want[0][5] = 200u8.wrapping_sub(90).wrapping_add(17);
    // Plane 1 is completed first and predicts plane 0; plane 6 predicts 7, inverted.
    let order = [1, 0, 2, 3, 4, 5, 6, 7, 8];
    let references = [1, -1, -1, -1, -1, -1, -1, 6, -1];
    let transforms = [0, 0, 0, 0, 0, 0, 0, 1, 0];
    let stored: Vec<u8> = (0..9)
        .map(|i| match i {
            0 => want[0][0].wrapping_sub(90).wrapping_add(128),
            7 => 120u8.wrapping_sub(255 - 180).wrapping_add(128),
            _ => want[i][0],
        })
        .collect();
    let streams: Vec<Vec<u8>> = stored.iter().map(|&v| flat_jpeg(w, h, v)).collect();
    let mut side = vec![Vec::new(); 9];
    side[1] = [0, 0, 0, 5, 17].to_vec();
    side[7] = [0, 0, 0, 9, 250, 0, 1, 0, 0, 3].to_vec(); // the second is past the plane
    let file = jpeg_lrgb_file(w, h, &streams, &transforms, &order, &references, &side);
    let jpeg = ptm::decode(Path::new("p.ptm"), &file).unwrap();
    let header = format!("PTM_1.2\nPTM_FORMAT_LRGB\n{w}\n{h}\n")
        + "0.5 0.5 0.5 0.5 0.5 1.0 \n10 20 30 40 50 0 \n";
    let mut raw = header.into_bytes();
    let want = &want;
    raw.extend((0..n).flat_map(|q| (0..6).map(move |i| want[i][q])));
    raw.extend((0..n).flat_map(|q| (6..9).map(move |i| want[i][q])));
    let plain = ptm::decode(Path::new("p.ptm"), &raw).unwrap();
    let differ: Vec<(usize, f32, f32)> = (0..jpeg.maps.data.len())
        .filter(|&i| jpeg.maps.data[i] != plain.maps.data[i])
        .map(|i| (i, jpeg.maps.data[i], plain.maps.data[i]))
        .take(5)
        .collect();
    assert!(
        differ.is_empty(),
        "first differences (index, jpeg, raw): {differ:?}"
    );

    let refused = |file: Vec<u8>, needle: &str| {
        let err = ptm::decode(Path::new("bad.ptm"), &file)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("bad.ptm") && err.contains(needle),
            "{needle}: {err}"
        );
    };
    let plain_refs = [-1; 9];
    let identity = [0, 1, 2, 3, 4, 5, 6, 7, 8];
    let none = vec![Vec::new(); 9];
    refused(
        jpeg_lrgb_file(
            w,
            h,
            &streams,
            &[0; 9],
            &[0, 0, 2, 3, 4, 5, 6, 7, 8],
            &plain_refs,
            &none,
        ),
        "decoding order",
    );
    refused(
        jpeg_lrgb_file(
            w,
            h,
            &streams,
            &[0; 9],
            &identity,
            &[3, -1, -1, -1, -1, -1, -1, -1, -1],
            &none,
        ),
        "reference plane 3",
    );
    refused(
        jpeg_lrgb_file(
            w,
            h,
            &streams,
            &[2, 0, 0, 0, 0, 0, 0, 0, 0],
            &identity,
            &plain_refs,
            &none,
        ),
        "motion-compensated",
    );
    let mut odd = none.clone();
    odd[2] = vec![0; 4];
    refused(
        jpeg_lrgb_file(w, h, &streams, &[0; 9], &identity, &plain_refs, &odd),
        "5-byte corrections",
    );
    // A stream claimed longer than the file, and a tiny stream claiming a huge image.
    let mut long = jpeg_lrgb_file(w, h, &streams, &[0; 9], &identity, &plain_refs, &none);
    long.truncate(long.len() - 10);
    refused(long, "truncated");
    refused(
        jpeg_lrgb_file(
            60000,
            60000,
            &streams,
            &[0; 9],
            &identity,
            &plain_refs,
            &none,
        ),
        "cannot hold",
    );
    // A stream of another size than the header's.
    let mut wrong = streams.clone();
    wrong[4] = flat_jpeg(8, 8, 1);
    refused(
        jpeg_lrgb_file(w, h, &wrong, &[0; 9], &identity, &plain_refs, &none),
        "not the header's",
    );
}

#[test]
fn other_bases_go_into_sixteen_hsh_terms_and_hsh_keeps_its_own() {
    let header_terms = |basis: &str| {
        let bytes = rti::encode(&image(basis, 4, 3, |x, y, i, c| {
            0.2 + 0.01 * (i + x + y + c) as f32
        }))
        .unwrap();
        let text = String::from_utf8_lossy(&bytes[..data_offset(&bytes, 4)]).to_string();
        text.lines().nth(3).unwrap().to_string()
    };
    assert_eq!(header_terms("sh:25"), "16 2 1");
    assert_eq!(header_terms("ptm:6"), "16 2 1");
    assert_eq!(header_terms("hsh:25"), "16 2 1");
    assert_eq!(header_terms("hsh:9"), "9 2 1");
    assert_eq!(header_terms("hsh:4"), "4 2 1");
}

//! How many median-cut lights an environment needs on display-referred maps
//! (`relit::engine::DISPLAY_ENVIRONMENT_LIGHTS`): a measurement, run by hand.

use relit::engine::{Relighter, Roi};
use relit::image::ImageRgb;
use relit::light::PreparedLight;
use relit::maps::MapSpace;
use relit::sphere::Vec3;

/// How many median-cut lights an environment needs on display-referred maps: the
/// frame of 4–64 lights, and of the map folded into one weight vector (what the
/// engine did before), against 4096 lights (the map's 64×64 quadrature, each decoded on
/// its own), 8-bit sRGB PSNR over a crop, for every shared environment map. Needs a
/// display-referred fit in `RELIT_MEASURE_FILE` (e.g. `relit fit item2/dirs.lp`).
/// `RELIT_MEASURE_FILE=… cargo test -p relit --release lumps_measurement -- --ignored --nocapture`
#[test]
#[ignore]
fn display_environment_lumps_measurement() {
    use relit::envmap::{environment_quadrature, median_cut};
    let Ok(file) = std::env::var("RELIT_MEASURE_FILE") else {
        return;
    };
    let img = relit::codec::read(std::path::Path::new(&file)).unwrap();
    assert_eq!(img.meta.color_space, MapSpace::Srgb);
    let r = Relighter::new(&img).unwrap();
    let (w, h) = (img.width(), img.height());
    let roi = Roi {
        x: w / 2 - 48,
        y: h / 2 - 48,
        width: 96,
        height: 96,
    };
    let envs =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/envmaps");
    let mut names: Vec<_> = std::fs::read_dir(&envs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    let rotation = relit::basis::rotation_from_yaw_pitch_roll(30.0, -10.0, 5.0).unwrap();
    for path in names {
        let map = relit::image::load_linear(&path, None).unwrap();
        let fine = environment_quadrature(&map, 64, 64);
        // Scaled so that the frame's mean is about mid-grey.
        let frame = |lights: &[(Vec3, [f64; 3])], scale: f64| {
            let prepared: Vec<PreparedLight> = lights
                .iter()
                .map(|(d, i)| PreparedLight::Directional {
                    direction: relit::basis::mat3_apply(&rotation, *d),
                    rgb: i.map(|v| v * scale),
                })
                .collect();
            let mut out = ImageRgb::new(0, 0);
            r.relight_prepared_into(&prepared, 0.0, roi, &mut out)
                .unwrap();
            out
        };
        let probe = frame(&fine, 1.0);
        let mean = probe.data.iter().map(|&v| v as f64).sum::<f64>() / probe.data.len() as f64;
        let scale = 0.18 / mean.max(1e-12);
        let reference = frame(&fine, scale);
        let mut line = format!("{}:", path.file_name().unwrap().to_string_lossy());
        for count in [4, 8, 16, 32, 64] {
            let got = frame(&median_cut(&fine, count), scale);
            line += &format!(" {count}: {:.1} dB", psnr8(&got, &reference));
        }
        let weights = relit::envmap::quadrature_weights(&fine, r.basis(), &rotation);
        let folded = PreparedLight::Weights(weights.map(|w| w.iter().map(|v| v * scale).collect()));
        let mut got = ImageRgb::new(0, 0);
        r.relight_prepared_into(&[folded], 0.0, roi, &mut got)
            .unwrap();
        line += &format!(" folded: {:.1} dB", psnr8(&got, &reference));
        println!("{line}");
    }
}

/// PSNR of `a` against `b` in sRGB display values (peak 1).
fn psnr8(a: &ImageRgb, b: &ImageRgb) -> f64 {
    let mse = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(&x, &y)| {
            let d = relit::color::linear_to_srgb(x) as f64 - relit::color::linear_to_srgb(y) as f64;
            d * d
        })
        .sum::<f64>()
        / a.data.len() as f64;
    relit::metrics::psnr(mse, 1.0)
}

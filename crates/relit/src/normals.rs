//! Surface normals by photometric stereo, from a capture or from a fitted file.
//!
//! A Lambertian pixel lit by a unit directional light toward `L` reads `ρ (n·L)` where
//! the light is in front of it. Stacking the lights gives `y = L g` with `g = ρ n`,
//! three unknowns per pixel (Woodham 1980), solved on the pixel's luma and then per
//! colour channel for the albedo.
//!
//! Real captures break the model in two ways: **shadows** (cast or attached) read darker
//! than `ρ (n·L)`, and **highlights** brighter. Plain least squares over every light
//! bends the normal toward the highlights and away from the shadows. The robust
//! estimator here ([`Method::Robust`]) starts from the lights between the 30th and 90th
//! percentile of the pixel's brightness (the darkest are the likeliest shadows, the
//! brightest the likeliest highlights), then reweights every light by Tukey's biweight
//! of its residual (scale: 1.4826 × the median absolute residual), dropping lights
//! behind the current normal (attached shadow) — iteratively reweighted least
//! squares, a few rounds.
//!
//! From a fitted file the observations are the file relit at a fixed set of directions
//! over the dome, as relight derives normals from its basis.
//!
//! Normals are in the `.lp` frame (x right, y up, z toward the camera); pictures encode
//! them as `(n + 1) / 2`.

use crate::capture::Capture;
use crate::engine::Relighter;
use crate::image::ImageRgb;
use crate::light::{Light, LightRig};
use crate::maps::RelightableImage;
use crate::progress::Progress;
use crate::sphere::Vec3;
use crate::{Error, Result};
use rayon::prelude::*;

/// How each pixel's normal is estimated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Least squares over every light.
    Ls,
    /// Trimmed start, then iteratively reweighted least squares (Tukey's biweight).
    Robust,
}

impl Method {
    /// Parse `ls` or `robust`.
    pub fn parse(name: &str) -> Result<Method> {
        match name {
            "ls" => Ok(Method::Ls),
            "robust" => Ok(Method::Robust),
            other => Err(Error::invalid(format!(
                "unknown photometric-stereo method `{other}`: use robust or ls"
            ))),
        }
    }
}

/// Normals and albedo per pixel.
#[derive(Clone, Debug)]
pub struct NormalMap {
    pub width: usize,
    pub height: usize,
    /// Unit normals, `[x, y, z]` per pixel; `[0, 0, 0]` where no light explains the pixel.
    pub normals: Vec<[f32; 3]>,
    /// Linear RGB albedo per pixel (the reflectance a unit light facing it shows).
    pub albedo: Vec<[f32; 3]>,
}

impl NormalMap {
    /// The normals as 8-bit codes `255 (n + 1) / 2` per component, no transfer curve
    /// (what normal-map tools expect).
    pub fn codes(&self) -> Vec<u8> {
        self.normals
            .iter()
            .flat_map(|n| n.map(|v| ((v + 1.0) * 0.5 * 255.0).round().clamp(0.0, 255.0) as u8))
            .collect()
    }

    /// The normals themselves as a float image (components in `[−1, 1]`).
    pub fn vectors(&self) -> ImageRgb {
        let mut image = ImageRgb::new(self.width, self.height);
        for (px, n) in image.data.chunks_exact_mut(3).zip(&self.normals) {
            px.copy_from_slice(n);
        }
        image
    }

    /// The albedo as a linear image.
    pub fn albedo_image(&self) -> ImageRgb {
        let mut image = ImageRgb::new(self.width, self.height);
        for (px, a) in image.data.chunks_exact_mut(3).zip(&self.albedo) {
            px.copy_from_slice(a);
        }
        image
    }
}

/// Observations per light: linear RGB images under unit lights toward `directions`.
struct Observations {
    directions: Vec<Vec3>,
    images: Vec<ImageRgb>,
}

/// Photometric stereo on a capture.
pub fn from_capture(
    capture: &Capture,
    method: Method,
    progress: &dyn Progress,
) -> Result<NormalMap> {
    if capture.len() < 3 {
        return Err(Error::invalid(format!(
            "photometric stereo needs at least 3 lights, the capture has {}",
            capture.len()
        )));
    }
    progress.begin("images", capture.len() as u64);
    let images = (0..capture.len())
        .map(|j| {
            let image = capture.load(j);
            progress.advance(1);
            image
        })
        .collect::<Result<Vec<_>>>()?;
    progress.end();
    solve(
        &Observations {
            directions: capture.directions(),
            images,
        },
        method,
    )
}

/// Photometric stereo on a fitted file: the file relit at directions over the dome.
pub fn from_maps(image: &RelightableImage, method: Method) -> Result<NormalMap> {
    let relighter = Relighter::new(image)?;
    let directions: Vec<Vec3> = crate::sphere::fibonacci(120)
        .into_iter()
        .filter(|d| d.z >= 0.17)
        .collect();
    let images = directions
        .iter()
        .map(|&d| {
            relighter.relight(
                &LightRig::new(vec![Light::directional(d, [1.0; 3])]),
                &Default::default(),
            )
        })
        .collect::<Result<Vec<_>>>()?;
    solve(&Observations { directions, images }, method)
}

fn solve(observations: &Observations, method: Method) -> Result<NormalMap> {
    let first = &observations.images[0];
    let (width, height) = (first.width, first.height);
    let lights = &observations.directions;
    let per_pixel: Vec<([f32; 3], [f32; 3])> = (0..width * height)
        .into_par_iter()
        .map(|p| {
            let rgb: Vec<[f32; 3]> = observations
                .images
                .iter()
                .map(|im| [im.data[3 * p], im.data[3 * p + 1], im.data[3 * p + 2]])
                .collect();
            pixel(lights, &rgb, method)
        })
        .collect();
    let (normals, albedo) = per_pixel.into_iter().unzip();
    Ok(NormalMap {
        width,
        height,
        normals,
        albedo,
    })
}

/// One pixel: its normal and albedo from its colour under each light.
fn pixel(lights: &[Vec3], rgb: &[[f32; 3]], method: Method) -> ([f32; 3], [f32; 3]) {
    let luma: Vec<f64> = rgb
        .iter()
        .map(|c| (0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]) as f64)
        .collect();
    let n = lights.len();
    let mut weights = vec![1.0f64; n];
    if method == Method::Robust && n >= 6 {
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| luma[a].total_cmp(&luma[b]));
        let (low, high) = ((n as f64 * 0.3) as usize, (n as f64 * 0.9).ceil() as usize);
        for (rank, &j) in order.iter().enumerate() {
            weights[j] = if (low..high).contains(&rank) {
                1.0
            } else {
                0.0
            };
        }
    }
    let Some(mut g) = weighted_solve(lights, &luma, &weights) else {
        return ([0.0; 3], [0.0; 3]);
    };
    if method == Method::Robust {
        for _ in 0..6 {
            let residuals: Vec<f64> = (0..n).map(|j| luma[j] - dot(lights[j], g)).collect();
            let mut front: Vec<f64> = (0..n)
                .filter(|&j| dot(lights[j], g) > 0.0)
                .map(|j| residuals[j].abs())
                .collect();
            if front.len() < 3 {
                break;
            }
            front.sort_by(f64::total_cmp);
            let scale = (1.4826 * front[front.len() / 2]).max(1e-6);
            let c = 4.685 * scale;
            for j in 0..n {
                weights[j] = if dot(lights[j], g) <= 0.0 {
                    0.0
                } else {
                    let u = residuals[j] / c;
                    if u.abs() < 1.0 {
                        (1.0 - u * u).powi(2)
                    } else {
                        0.0
                    }
                };
            }
            match weighted_solve(lights, &luma, &weights) {
                Some(next) => g = next,
                None => break,
            }
        }
    }
    let length = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if !(length > 1e-9 && length.is_finite()) {
        return ([0.0; 3], [0.0; 3]);
    }
    let normal = [g[0] / length, g[1] / length, g[2] / length];
    // Albedo per channel: ρ_c = Σ w y_c s / Σ w s² with s = n·L over the lights in front.
    let mut albedo = [0.0f32; 3];
    for (c, a) in albedo.iter_mut().enumerate() {
        let (mut num, mut den) = (0.0, 0.0);
        for j in 0..n {
            let s = dot(lights[j], normal);
            if s > 0.0 && weights[j] > 0.0 {
                num += weights[j] * rgb[j][c] as f64 * s;
                den += weights[j] * s * s;
            }
        }
        *a = if den > 0.0 { (num / den) as f32 } else { 0.0 };
    }
    (normal.map(|v| v as f32), albedo)
}

fn dot(l: Vec3, g: [f64; 3]) -> f64 {
    l.x * g[0] + l.y * g[1] + l.z * g[2]
}

/// The `g` minimising `Σ w_j (y_j − L_j·g)²`, if the weighted lights span 3 directions.
fn weighted_solve(lights: &[Vec3], y: &[f64], w: &[f64]) -> Option<[f64; 3]> {
    let mut normal = [0.0f64; 9];
    let mut rhs = [0.0f64; 3];
    for ((l, &y), &w) in lights.iter().zip(y).zip(w) {
        if w <= 0.0 {
            continue;
        }
        let v = [l.x, l.y, l.z];
        for i in 0..3 {
            rhs[i] += w * v[i] * y;
            for k in 0..3 {
                normal[i * 3 + k] += w * v[i] * v[k];
            }
        }
    }
    // A tiny ridge keeps near-planar light sets (a dome's ring) solvable.
    let trace = normal[0] + normal[4] + normal[8];
    for i in 0..3 {
        normal[i * 4] += 1e-9 * trace;
    }
    if !crate::linalg::cholesky(&mut normal, 3) {
        return None;
    }
    crate::linalg::cholesky_solve(&normal, 3, &mut rhs);
    rhs.iter().all(|v| v.is_finite()).then_some(rhs)
}

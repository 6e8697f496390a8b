//! The CPU relighting engine: coefficient maps + lights → linear images.
//!
//! A directional light has one light vector for the whole image, so its effect is a
//! weighted sum of the coefficient planes with the basis values `B_i(L)` as weights
//! (seed 000, figure 6). Several such lights on linear maps fold into one weight per
//! plane before any pixel is touched, so the cost is one pass over the planes whatever
//! their number. Lights with a position (point, spot, projector, area) have a light
//! vector per pixel, `L = S − P` with `P` the pixel's surface point from the camera
//! and depth (seed 004 eq. 3), and evaluate the basis per pixel (seed 000, figure 8).
//! Display-referred maps are evaluated per light and decoded to linear before adding.
//!
//! Known limitation (seed 004 §VI): the maps record shadows cast by *directional*
//! light. A non-directional light placed between an occluder and the surface seen
//! through a pixel still relights with the shadow the capture recorded, because the
//! pixel's function knows only directions, not distances.

use crate::basis::{Basis, BasisSpec};
use crate::camera::{Camera, CameraSpec};
use crate::color;
use crate::envmap::EnvironmentLight;
use crate::image::ImageRgb;
use crate::light::{Light, LightRig, PreparedLight};
use crate::maps::{MapSpace, RelightableImage};
use crate::sphere::Vec3;
use crate::{Error, Result};
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock};

/// Options of [`relight`].
#[derive(Clone, Debug, Default)]
pub struct RelightOptions {
    /// Exposure in stops applied to the result (each +1 doubles it).
    pub exposure: f64,
    /// Folder that relative paths in lights (projector slides) resolve against.
    pub resource_dir: PathBuf,
}

/// Pixels per task: small enough that a chunk of every plane stays in cache.
const CHUNK: usize = 4096;

/// Relight `image` with `rig` (a one-off; [`Relighter`] reuses work across frames).
pub fn relight(
    image: &RelightableImage,
    rig: &LightRig,
    options: &RelightOptions,
) -> Result<ImageRgb> {
    Relighter::new(image)?.relight(rig, options)
}

/// Relights one relightable image many times, keeping what does not depend on the lights
/// (the basis, the per-pixel surface points, loaded slides).
pub struct Relighter<'a> {
    image: &'a RelightableImage,
    basis: Box<dyn Basis>,
    points: OnceLock<Result<Vec<Option<Vec3>>, String>>,
    slides: Mutex<HashMap<PathBuf, Arc<ImageRgb>>>,
    /// Environment maps with their unrotated SH projection, by file.
    environments: Mutex<HashMap<PathBuf, Arc<(EnvironmentLight, [Vec<f64>; 3])>>>,
}

impl<'a> Relighter<'a> {
    pub fn new(image: &'a RelightableImage) -> Result<Self> {
        let basis = image.meta.basis.build()?;
        if basis.len() != image.maps.k {
            return Err(Error::invalid(format!(
                "the maps hold {} coefficients but the basis has {}",
                image.maps.k,
                basis.len()
            )));
        }
        Ok(Self {
            image,
            basis,
            points: OnceLock::new(),
            slides: Mutex::new(HashMap::new()),
            environments: Mutex::new(HashMap::new()),
        })
    }

    /// The camera the file was captured with (its stored camera, or its projection with
    /// the default pose).
    pub fn camera(&self) -> Result<Camera> {
        let meta = &self.image.meta;
        let spec = meta.camera.clone().unwrap_or(CameraSpec {
            projection: meta.projection.clone(),
            width: self.image.width(),
            height: self.image.height(),
            pose: Default::default(),
            orthographic_height: None,
        });
        spec.build()
    }

    /// Surface points of every pixel (`None` where nothing was hit), from camera and depth.
    pub fn surface_points(&self) -> Result<&[Option<Vec3>]> {
        let points = self.points.get_or_init(|| {
            let depth = self.image.depth.as_ref().ok_or_else(|| {
                "lights with a position need a depth map: fit a capture that has one (a manifest `depth`, or `relit capture`)".to_string()
            })?;
            let camera = self.camera().map_err(|e| e.to_string())?;
            camera.positions_from_depth(depth).map_err(|e| e.to_string())
        });
        points.as_deref().map_err(|e| Error::invalid(e.clone()))
    }

    /// The basis weights of an environment light for these maps: the map's SH projection
    /// (computed once per file) rotated and windowed, times the light's colour.
    pub fn environment_weights(
        &self,
        light: &crate::light::EnvironmentMapLight,
        resource_dir: &std::path::Path,
    ) -> Result<[Vec<f64>; 3]> {
        light.validate()?;
        let BasisSpec::Sh { bands } = self.image.meta.basis;
        let path = resource_dir.join(&light.map);
        let entry = {
            let mut cache = self.environments.lock().expect("environment cache");
            match cache.get(&path) {
                Some(e) => e.clone(),
                None => {
                    let env = EnvironmentLight::load(&path)?;
                    let projection = env.project(bands)?;
                    let e = Arc::new((env, projection));
                    cache.insert(path, e.clone());
                    e
                }
            }
        };
        let (env, projection) = &*entry;
        let env = env
            .clone()
            .with_rotation(light.rotation()?)?
            .with_window(light.window)?;
        let mut weights = env.weights_from_projection(projection)?;
        let rgb = Light::Environment(light.clone()).rgb();
        for (c, w) in weights.iter_mut().enumerate() {
            w.iter_mut().for_each(|v| *v *= rgb[c]);
        }
        Ok(weights)
    }

    fn prepare(&self, light: &Light, options: &RelightOptions) -> Result<PreparedLight> {
        if let Light::Environment(env) = light {
            return Ok(PreparedLight::Weights(
                self.environment_weights(env, &options.resource_dir)?,
            ));
        }
        if let Light::Projector(p) = light {
            p.validate()?;
            let path = options.resource_dir.join(&p.slide);
            let mut cache = self.slides.lock().expect("slide cache");
            let slide = match cache.get(&path) {
                Some(s) => s.clone(),
                None => {
                    let s = Arc::new(crate::image::load_linear(&path, None)?);
                    cache.insert(path, s.clone());
                    s
                }
            };
            return Ok(PreparedLight::Projector(
                Box::new(p.with_slide(slide)),
                light.rgb(),
            ));
        }
        light.prepare(&options.resource_dir)
    }

    /// Relight with `rig`.
    pub fn relight(&self, rig: &LightRig, options: &RelightOptions) -> Result<ImageRgb> {
        let lights: Vec<PreparedLight> = rig
            .lights
            .iter()
            .map(|l| self.prepare(l, options))
            .collect::<Result<_>>()?;
        self.relight_prepared(&lights, options.exposure)
    }

    /// Relight with lights already prepared.
    pub fn relight_prepared(&self, lights: &[PreparedLight], exposure: f64) -> Result<ImageRgb> {
        let image = self.image;
        let k = self.basis.len();
        let scale = 2f64.powf(exposure);
        let display = image.meta.color_space == MapSpace::Srgb;
        // Uniform lights: one weight vector per channel and pass. Linear maps fold every
        // such light into one pass; display-referred maps need one pass per light.
        let mut passes: Vec<([Vec<f32>; 3], [f32; 3])> = Vec::new();
        let mut folded: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; k]);
        let mut any_folded = false;
        for light in lights {
            let PreparedLight::Directional { direction, rgb } = light else {
                continue;
            };
            let y = self.basis.values(*direction);
            if display {
                let w: Vec<f32> = y.iter().map(|&v| v as f32).collect();
                passes.push(([w.clone(), w.clone(), w], rgb.map(|v| (v * scale) as f32)));
            } else {
                any_folded = true;
                for c in 0..3 {
                    for i in 0..k {
                        folded[c][i] += rgb[c] * scale * y[i];
                    }
                }
            }
        }
        if any_folded {
            passes.push((
                folded.map(|w| w.iter().map(|&v| v as f32).collect()),
                [1.0; 3],
            ));
        }
        let positional: Vec<&PreparedLight> = lights.iter().filter(|l| !l.is_uniform()).collect();
        let points = if positional.is_empty() {
            None
        } else {
            Some(self.surface_points()?)
        };

        let maps = &image.maps;
        let n = maps.pixels();
        let basis = self.basis.as_ref();
        let mut out = ImageRgb::new(maps.width, maps.height);
        out.data
            .par_chunks_mut(3 * CHUNK)
            .enumerate()
            .for_each(|(chunk, dst)| {
                let p0 = chunk * CHUNK;
                let len = dst.len() / 3;
                let mut acc = [vec![0f32; len], vec![0f32; len], vec![0f32; len]];
                for (weights, tint) in &passes {
                    for a in acc.iter_mut() {
                        a.iter_mut().for_each(|v| *v = 0.0);
                    }
                    for i in 0..k {
                        for c in 0..3 {
                            let w = weights[c][i];
                            let plane =
                                &maps.data[(3 * i + c) * n + p0..(3 * i + c) * n + p0 + len];
                            for (a, &v) in acc[c].iter_mut().zip(plane) {
                                *a += w * v;
                            }
                        }
                    }
                    for p in 0..len {
                        for c in 0..3 {
                            let v = if display {
                                color::srgb_to_linear(acc[c][p].clamp(0.0, 1.0))
                            } else {
                                acc[c][p]
                            };
                            dst[3 * p + c] += tint[c] * v;
                        }
                    }
                }
                if let Some(points) = points {
                    let mut y = vec![0.0f64; k];
                    let mut coef = vec![0.0f64; 3 * k];
                    for p in 0..len {
                        let pixel = p0 + p;
                        let Some(surface) = points[pixel] else {
                            continue;
                        };
                        for i in 0..k {
                            for c in 0..3 {
                                coef[3 * i + c] = maps.data[(3 * i + c) * n + pixel] as f64;
                            }
                        }
                        let mut sum = [0.0f64; 3];
                        for light in &positional {
                            light.illuminate(surface, pixel, &mut |l, rgb| {
                                basis.eval(l, &mut y);
                                for c in 0..3 {
                                    let mut v = 0.0;
                                    for i in 0..k {
                                        v += coef[3 * i + c] * y[i];
                                    }
                                    if display {
                                        v = color::srgb_to_linear(v.clamp(0.0, 1.0) as f32) as f64;
                                    }
                                    sum[c] += rgb[c] * v;
                                }
                            });
                        }
                        for c in 0..3 {
                            dst[3 * p + c] += (sum[c] * scale) as f32;
                        }
                    }
                }
            });
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisSpec;
    use crate::camera::Projection;
    use crate::maps::{CoefficientMaps, Metadata};
    use crate::sphere::Vec3;

    fn one_pixel(coef: &[f32], space: MapSpace) -> RelightableImage {
        let mut maps = CoefficientMaps::zeros(1, 1, coef.len());
        for (i, &v) in coef.iter().enumerate() {
            for c in 0..3 {
                maps.plane_mut(i, c)[0] = v;
            }
        }
        RelightableImage {
            meta: Metadata::new(BasisSpec::Sh { bands: 2 }, space, Projection::default()),
            maps,
            depth: None,
        }
    }

    #[test]
    fn lights_superpose_and_colours_scale() {
        let img = one_pixel(&[0.5, 0.1, 0.3, -0.2], MapSpace::Linear);
        let a = Light::directional([0.0, 1.0, 1.0], [1.0, 0.5, 0.0]);
        let b = Light::directional([1.0, 0.0, 0.2], [0.0, 0.5, 2.0]);
        let opts = RelightOptions::default();
        let ra = relight(&img, &LightRig::new(vec![a.clone()]), &opts).unwrap();
        let rb = relight(&img, &LightRig::new(vec![b.clone()]), &opts).unwrap();
        let both = relight(&img, &LightRig::new(vec![a, b]), &opts).unwrap();
        for c in 0..3 {
            assert!((both.data[c] - ra.data[c] - rb.data[c]).abs() < 1e-6);
        }
        // White light from the pole: Σ c_i Y_i(0,0,1).
        let sh = BasisSpec::Sh { bands: 2 }.build().unwrap();
        let y = sh.values(Vec3::new(0.0, 0.0, 1.0));
        let want = 0.5 * y[0] + 0.3 * y[2];
        let pole = relight(
            &img,
            &LightRig::new(vec![Light::directional([0.0, 0.0, 1.0], [1.0; 3])]),
            &opts,
        )
        .unwrap();
        assert!((pole.data[0] as f64 - want).abs() < 1e-6);
        let brighter = relight(
            &img,
            &LightRig::new(vec![Light::directional([0.0, 0.0, 1.0], [1.0; 3])]),
            &RelightOptions {
                exposure: 1.0,
                ..Default::default()
            },
        )
        .unwrap();
        assert!((brighter.data[0] - 2.0 * pole.data[0]).abs() < 1e-6);
    }

    #[test]
    fn display_maps_decode_each_light() {
        // Display value 0.5 from the constant term alone: Y_00 = 0.2821.
        let img = one_pixel(&[0.5 / 0.282_094_79, 0.0, 0.0, 0.0], MapSpace::Srgb);
        let rig = LightRig::new(vec![
            Light::directional([0.0, 0.0, 1.0], [1.0; 3]),
            Light::directional([1.0, 0.0, 0.0], [1.0; 3]),
        ]);
        let out = relight(&img, &rig, &RelightOptions::default()).unwrap();
        let want = 2.0 * color::srgb_to_linear(0.5);
        assert!(
            (out.data[0] - want).abs() < 1e-4,
            "{} vs {want}",
            out.data[0]
        );
    }

    /// A 6×4 image of pseudo-random 9-coefficient maps seen by a perspective camera,
    /// every pixel at depth 2.
    fn positioned_image() -> RelightableImage {
        let (w, h, k) = (6, 4, 9);
        let mut maps = CoefficientMaps::zeros(w, h, k);
        for (x, v) in maps.data.iter_mut().enumerate() {
            *v = if (x / (w * h)) < 3 {
                0.6
            } else {
                ((x * 7919 % 101) as f32 / 101.0 - 0.5) * 0.3
            };
        }
        let mut meta = Metadata::new(
            BasisSpec::Sh { bands: 3 },
            MapSpace::Linear,
            Projection::Planar {
                fov_y_deg: Some(50.0),
            },
        );
        meta.camera = Some(crate::camera::CameraSpec {
            projection: Projection::Planar {
                fov_y_deg: Some(50.0),
            },
            width: w,
            height: h,
            pose: Default::default(),
            orthographic_height: None,
        });
        RelightableImage {
            meta,
            maps,
            depth: Some(vec![2.0; w * h]),
        }
    }

    fn max_relative_difference(a: &ImageRgb, b: &ImageRgb) -> f64 {
        a.data
            .iter()
            .zip(&b.data)
            .map(|(x, y)| ((x - y).abs() / y.abs().max(1e-3)) as f64)
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_far_point_light_becomes_the_directional_light() {
        let img = positioned_image();
        let dir = Vec3::new(0.3, 0.5, 0.8).normalized().unwrap();
        let far = 1e5;
        let point = Light::Point(crate::light::PointLight {
            position: dir * far,
            color: [1.0; 3],
            intensity: far * far,
            attenuation: Default::default(),
        });
        let opts = RelightOptions::default();
        let a = relight(&img, &LightRig::new(vec![point]), &opts).unwrap();
        let b = relight(
            &img,
            &LightRig::new(vec![Light::directional(dir, [1.0; 3])]),
            &opts,
        )
        .unwrap();
        assert!(max_relative_difference(&a, &b) < 1e-3);
    }

    #[test]
    fn small_area_lights_and_wide_spots_become_point_lights() {
        let img = positioned_image();
        let s = Vec3::new(0.5, 1.0, -1.0);
        let opts = RelightOptions::default();
        let point = relight(&img, &LightRig::new(vec![Light::point(s, [1.0; 3])]), &opts).unwrap();
        // A disk of radius r facing every pixel roughly, radiance 1/(πr²): power of a unit point light.
        let r = 1e-3;
        let area = Light::Area(crate::light::AreaLight {
            shape: crate::light::AreaShape::Disk {
                center: s,
                normal: Vec3::new(-0.5, -1.0, -1.0),
                radius: r,
            },
            color: [1.0; 3],
            intensity: 1.0 / (std::f64::consts::PI * r * r),
            two_sided: true,
            samples: 4,
        });
        let a = relight(&img, &LightRig::new(vec![area]), &opts).unwrap();
        // A tiny disk is a point light whose intensity follows the emitter's cosine toward
        // each pixel's surface point: the ratio must be exactly that cosine.
        let points = Relighter::new(&img)
            .unwrap()
            .surface_points()
            .unwrap()
            .to_vec();
        let normal = Vec3::new(-0.5, -1.0, -1.0).normalized().unwrap();
        for (p, px) in points.iter().enumerate() {
            let cosine = (px.unwrap() - s).normalized().unwrap().dot(normal);
            for c in 0..3 {
                let ratio = (a.data[3 * p + c] / point.data[3 * p + c]) as f64;
                assert!(
                    (ratio - cosine).abs() < 2e-3,
                    "pixel {p}: {ratio} vs cos {cosine}"
                );
            }
        }
        let spot = Light::parse_spec("spot:0.5,1,-1/-0.3,-1,-1/89").unwrap();
        let sp = relight(&img, &LightRig::new(vec![spot]), &opts).unwrap();
        assert!(max_relative_difference(&sp, &point) < 1e-6);
    }

    #[test]
    fn positional_lights_without_depth_are_a_clear_error() {
        let mut img = positioned_image();
        img.depth = None;
        let err = relight(
            &img,
            &LightRig::new(vec![Light::point([0.0, 1.0, 0.0], [1.0; 3])]),
            &RelightOptions::default(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("depth"), "{err}");
    }
}

//! Environment lights: latitude–longitude HDR maps turned into the light vectors of a basis.
//!
//! # Directions
//!
//! A lat-long (equirectangular) map `width × height` covers the whole sphere. The texture
//! position `(u, v) ∈ [0, 1]²` (pixel `(x, y)` has its centre at
//! `u = (x + ½)/width`, `v = (y + ½)/height`, top-left origin) is the light vector
//!
//! ```text
//! θ = π·v              (polar angle from +y: the top row is up, the bottom row down)
//! α = 2π·(u − ½)       (azimuth from −z toward +x)
//! ω = (sin θ sin α,  cos θ,  −sin θ cos α)
//! ```
//!
//! in the light frame (x right, y up, z toward the camera): the centre column looks
//! along −z, straight ahead from the camera into the scene, u grows toward +x and the
//! left and right edges meet behind the camera at +z. This is the panorama convention of
//! the cameras (see the conventions): a lat-long photograph taken with relit's
//! equirectangular camera at the default pose is an environment map in this layout.
//! `ω` points from the scene toward the texel, so it is the light vector of the light
//! that texel sends: the part of the map seen behind the object lights it from behind.
//!
//! # Relighting is one dot product per pixel
//!
//! A coefficient map gives each pixel's response to a unit directional light whose light
//! vector is `L`: `f_p(L) = Σ_i c_i(p) b_i(L)` on the basis `b`. An environment sends radiance `E(ω)` from
//! every direction `ω` (the light vector of that texel); each solid-angle element acts as
//! a directional light of intensity `E(ω) dω`. By superposition the pixel's value is
//!
//! ```text
//! I_p = ∫ f_p(ω) E(ω) dω = Σ_i c_i(p) e_i,        e_i = ∫ E(ω) b_i(ω) dω.
//! ```
//!
//! The `e_i` are the same for every pixel, so relighting by an environment costs one dot
//! product per pixel and colour channel, exactly like a single directional light whose
//! weights are `b_i(L)`. [`BasisEnvironment::weights`] returns those `e_i` per channel,
//! rotated and windowed.
//!
//! # Rotation
//!
//! [`EnvironmentLight::with_rotation`] turns the environment by a rotation `R`:
//! `E'(ω) = E(Rᵀ ω)`, so what the map shows at `ω` arrives from `R ω`.
//! [`EnvironmentLight::with_yaw_degrees`] is a rotation about +y: positive yaw moves
//! what was straight ahead (the centre column) toward −x, i.e. the content of the map
//! slides toward smaller `u`.
//!
//! # One dispatch
//!
//! A basis may light its maps by an environment in its own way, finer than any sampling
//! of the map ([`Basis::environment`]: an exact projection that turns in closed form,
//! for instance). Every other basis is lit through the map's quadrature
//! ([`quadrature`]): a few thousand directional lights, `e_c = Σ_t I_{t,c} y(R ω_t)`
//! with the rotation applied to their directions. Band windows ([`Window`]) need a basis
//! whose coefficients come in bands ([`Basis::coefficient_bands`]) and are refused with
//! an error on any other. [`EnvironmentLight::for_basis`] makes that choice once per map
//! and basis ([`BasisEnvironment`]), and its [`BasisEnvironment::weights`] gives the
//! weights per frame: the engines never name a basis, and neither does this module.
//!
//! # Brute force
//!
//! To check a relit image against the captures themselves,
//! [`EnvironmentLight::weights_for_directions`] gives each captured light direction
//! `L_j` the radiance of its cell: every texel goes to the captured direction nearest
//! to it (largest `ω·L_j`), with weight `E_t · ΔΩ_t`. Then `Σ_j w_j I_j` (raw captured
//! images `I_j`) approximates `∫ f_p E dω`, exactly in the limit of fine captures and a
//! fine map. For a dome that only lights the upper hemisphere, the lower hemisphere's
//! light lands on the directions nearest the horizon.

pub use crate::basis::Window;
use crate::basis::{
    check_rotation, mat3_apply, rotation_about_axis, transpose, Basis, Mat3, PreparedEnvironment,
    MAT3_IDENTITY,
};
pub use crate::sphere::{latlong_direction, latlong_uv, texel_solid_angle};

pub mod quadrature;

use crate::image::{load_linear, ImageRgb};
use crate::sphere::Vec3;
use crate::{Error, Result};
pub use quadrature::{
    environment_quadrature, median_cut, quadrature_weights, QUADRATURE_HEIGHT, QUADRATURE_WIDTH,
};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::path::Path;

/// An environment light: a linear RGB lat-long radiance map, a rotation and a window.
#[derive(Clone)]
pub struct EnvironmentLight {
    map: ImageRgb,
    rotation: Mat3,
    window: Window,
}

impl std::fmt::Debug for EnvironmentLight {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EnvironmentLight")
            .field("width", &self.map.width)
            .field("height", &self.map.height)
            .field("rotation", &self.rotation)
            .field("window", &self.window)
            .finish()
    }
}

impl EnvironmentLight {
    /// Load a lat-long map (Radiance `.hdr`, OpenEXR or any format relit reads; float
    /// formats are linear radiance).
    pub fn load(path: &Path) -> Result<Self> {
        let map = load_linear(path, None)?;
        Self::from_image(map)
            .map_err(|e| Error::invalid(format!("environment map {}: {e}", path.display())))
    }

    /// An environment from a linear RGB lat-long image. Every sample must be finite.
    pub fn from_image(map: ImageRgb) -> Result<Self> {
        if map.width == 0 || map.height == 0 || map.data.len() != 3 * map.width * map.height {
            return Err(Error::invalid(format!(
                "an environment map needs at least one pixel and 3 samples per pixel ({}×{}, {} samples)",
                map.width,
                map.height,
                map.data.len()
            )));
        }
        if let Some(i) = map.data.iter().position(|v| !v.is_finite()) {
            let p = i / 3;
            return Err(Error::invalid(format!(
                "environment map pixel ({}, {}) is not finite",
                p % map.width,
                p / map.width
            )));
        }
        Ok(Self {
            map,
            rotation: MAT3_IDENTITY,
            window: Window::None,
        })
    }

    /// The radiance map.
    pub fn map(&self) -> &ImageRgb {
        &self.map
    }

    /// The rotation applied to the map (identity by default).
    pub fn rotation(&self) -> Mat3 {
        self.rotation
    }

    /// The window applied to the weights (none by default).
    pub fn window(&self) -> Window {
        self.window
    }

    /// Turn the environment by `rotation` (replacing any earlier one): `E'(ω) = E(Rᵀω)`.
    pub fn with_rotation(mut self, rotation: Mat3) -> Result<Self> {
        check_rotation(&rotation)?;
        self.rotation = rotation;
        Ok(self)
    }

    /// Turn the environment by `yaw_deg` degrees about +y (replacing any earlier
    /// rotation); positive yaw moves the map's centre from −z toward −x.
    pub fn with_yaw_degrees(self, yaw_deg: f64) -> Result<Self> {
        let rotation = rotation_about_axis(Vec3::new(0.0, 1.0, 0.0), yaw_deg.to_radians())?;
        self.with_rotation(rotation)
    }

    /// Window the weights (on a basis with bands).
    pub fn with_window(mut self, window: Window) -> Result<Self> {
        window.validate()?;
        self.window = window;
        Ok(self)
    }

    /// The radiance arriving from light vector `dir` (rotation applied, nearest texel).
    pub fn radiance(&self, dir: Vec3) -> [f64; 3] {
        let [u, v] = latlong_uv(mat3_apply(&transpose(&self.rotation), dir));
        let (w, h) = (self.map.width, self.map.height);
        // Float-to-int casts saturate (NaN gives 0), so any input lands on a texel.
        let x = ((u * w as f64) as usize).min(w - 1);
        let y = ((v * h as f64) as usize).min(h - 1);
        self.map.get(x, y).map(f64::from)
    }

    /// Brute-force weights for captured light directions `dirs` (module docs, *Brute
    /// force*): `w_j` is the radiance the rotated environment sends from the cell of
    /// directions nearer to `dirs[j]` than to any other, integrated over solid angle, so
    /// that `Σ_j w_j I_j` relights from the raw captures. `Σ_j w_j = ∫ E dω` exactly. The
    /// window does not apply. Cost: one dot product per texel and direction.
    pub fn weights_for_directions(&self, dirs: &[Vec3]) -> Result<Vec<[f64; 3]>> {
        if dirs.is_empty() {
            return Err(Error::invalid(
                "brute-force environment weights need at least one light direction",
            ));
        }
        // Compare unrotated texel directions d with Rᵀ L_j: (R d)·L_j = d·(Rᵀ L_j).
        let inverse = transpose(&self.rotation);
        let mut local = [
            Vec::with_capacity(dirs.len()),
            Vec::with_capacity(dirs.len()),
            Vec::with_capacity(dirs.len()),
        ];
        for (j, d) in dirs.iter().enumerate() {
            let unit = d.normalized().ok_or_else(|| {
                Error::invalid(format!(
                    "light direction {j} ({}, {}, {}) is zero or not finite",
                    d.x, d.y, d.z
                ))
            })?;
            let l = mat3_apply(&inverse, unit);
            local[0].push(l.x);
            local[1].push(l.y);
            local[2].push(l.z);
        }
        let (w, h) = (self.map.width, self.map.height);
        let columns: Vec<(f64, f64)> = (0..w)
            .map(|x| (2.0 * PI * ((x as f64 + 0.5) / w as f64 - 0.5)).sin_cos())
            .collect();
        let partials: Vec<Vec<[f64; 3]>> = (0..h)
            .collect::<Vec<_>>()
            .par_chunks(ROWS_PER_TASK)
            .map(|rows| {
                let mut acc = vec![[0.0; 3]; dirs.len()];
                for &y in rows {
                    let solid_angle = texel_solid_angle(w, h, y);
                    let (sin_t, cos_t) = (PI * (y as f64 + 0.5) / h as f64).sin_cos();
                    for (x, &(sin_a, cos_a)) in columns.iter().enumerate() {
                        let d = Vec3::new(sin_t * sin_a, cos_t, -sin_t * cos_a);
                        let nearest = nearest_direction(&local, d);
                        let e = self.map.get(x, y);
                        for c in 0..3 {
                            acc[nearest][c] += f64::from(e[c]) * solid_angle;
                        }
                    }
                }
                acc
            })
            .collect();
        let mut weights = vec![[0.0; 3]; dirs.len()];
        for part in &partials {
            for (wj, pj) in weights.iter_mut().zip(part) {
                for c in 0..3 {
                    wj[c] += pj[c];
                }
            }
        }
        Ok(weights)
    }

    /// The environment as relighting `basis`' maps sees it, for a basis with bands
    /// ([`Basis::coefficient_bands`], orthonormal): a `width × height` lat-long map
    /// (light frame, no further rotation) of `Σ_i e_i b_i(ω)` with the rotated, windowed
    /// weights `e` ([`BasisEnvironment::weights`]). Its brute-force weights
    /// ([`Self::weights_for_directions`]) relight the raw captures under exactly the
    /// band-limited lighting the coefficient maps are relit with, so comparing the two
    /// isolates the fit from the truncation of the environment. Ringing shows as
    /// negative radiance, which is kept.
    pub fn band_limited(&self, basis: &dyn Basis, width: usize, height: usize) -> Result<Self> {
        if width == 0 || height == 0 || width.saturating_mul(height) > 1 << 24 {
            return Err(Error::invalid(format!(
                "a band-limited environment map needs 1 to 2^24 texels, not {width}×{height}"
            )));
        }
        if basis.coefficient_bands().is_none() {
            return Err(Error::invalid(format!(
                "basis {} has no bands to limit an environment to",
                basis.name()
            )));
        }
        let weights = self
            .for_basis(basis)?
            .weights(basis, self.rotation, self.window)?;
        let k = basis.len();
        let mut map = ImageRgb::new(width, height);
        map.data
            .par_chunks_mut(3 * width)
            .enumerate()
            .for_each(|(y, row)| {
                let mut values = vec![0.0; k];
                for (x, px) in row.chunks_exact_mut(3).enumerate() {
                    let dir = latlong_direction(
                        (x as f64 + 0.5) / width as f64,
                        (y as f64 + 0.5) / height as f64,
                    );
                    basis.eval(dir, &mut values);
                    for (c, out) in px.iter_mut().enumerate() {
                        *out = values
                            .iter()
                            .zip(&weights[c])
                            .map(|(v, w)| v * w)
                            .sum::<f64>() as f32;
                    }
                }
            });
        Self::from_image(map)
    }
}

/// An environment map made ready for one basis (module docs, *One dispatch*): what
/// does not change when it turns.
#[derive(Debug)]
pub enum BasisEnvironment {
    /// The basis' own ([`Basis::environment`]).
    Own(Box<dyn PreparedEnvironment>),
    /// The map's quadrature ([`environment_quadrature`] at [`QUADRATURE_WIDTH`] ×
    /// [`QUADRATURE_HEIGHT`]), for every other basis.
    Quadrature(Vec<(Vec3, [f64; 3])>),
}

impl EnvironmentLight {
    /// This map (its rotation and window aside) made ready for `basis`: the basis' own
    /// environment where it has one, the quadrature otherwise.
    pub fn for_basis(&self, basis: &dyn Basis) -> Result<BasisEnvironment> {
        Ok(match basis.environment(&self.map) {
            Some(own) => BasisEnvironment::Own(own?),
            None => BasisEnvironment::Quadrature(environment_quadrature(
                &self.map,
                QUADRATURE_WIDTH,
                QUADRATURE_HEIGHT,
            )),
        })
    }
}

impl BasisEnvironment {
    /// The weights per colour channel that relight maps of `basis` (the basis this was
    /// made for) by one dot product per pixel, the environment turned by `rotation` and
    /// windowed. A window other than `none` on a basis without bands is an error.
    pub fn weights(
        &self,
        basis: &dyn Basis,
        rotation: Mat3,
        window: Window,
    ) -> Result<[Vec<f64>; 3]> {
        check_rotation(&rotation)?;
        window.validate()?;
        if window != Window::None && basis.coefficient_bands().is_none() {
            return Err(Error::invalid(format!(
                "band windows ({window:?}) are for bases with bands; basis {} has none: use no window",
                basis.name()
            )));
        }
        match self {
            BasisEnvironment::Own(own) => own.weights(&rotation, window),
            BasisEnvironment::Quadrature(lights) => {
                Ok(quadrature_weights(lights, basis, &rotation))
            }
        }
    }
}

/// Rows of the map one parallel task handles; fixed so that sums are reproducible.
const ROWS_PER_TASK: usize = 16;

/// The index of the direction (stored as x, y, z columns) with the largest dot with `d`.
fn nearest_direction(dirs: &[Vec<f64>; 3], d: Vec3) -> usize {
    let mut best = (f64::NEG_INFINITY, 0);
    for (j, ((x, y), z)) in dirs[0].iter().zip(&dirs[1]).zip(&dirs[2]).enumerate() {
        let dot = d.x * x + d.y * y + d.z * z;
        if dot > best.0 {
            best = (dot, j);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{rotation_from_yaw_pitch_roll, BasisSpec};
    use crate::image::test_maps::{sampled_map, smooth_sky};

    /// Rounding in sums over a few thousand texels, with f32 radiance stored exactly.
    const EXACT_TOLERANCE: f64 = 1e-9;

    #[test]
    fn texel_directions_follow_the_documented_convention() {
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-12;
        assert!(
            close(latlong_direction(0.5, 0.5), Vec3::new(0.0, 0.0, -1.0)),
            "centre looks along -z"
        );
        assert!(
            close(latlong_direction(0.75, 0.5), Vec3::new(1.0, 0.0, 0.0)),
            "u grows toward +x"
        );
        assert!(close(
            latlong_direction(0.25, 0.5),
            Vec3::new(-1.0, 0.0, 0.0)
        ));
        assert!(
            close(latlong_direction(0.0, 0.5), Vec3::new(0.0, 0.0, 1.0)),
            "the seam is behind the camera"
        );
        assert!(
            close(latlong_direction(0.3, 0.0), Vec3::new(0.0, 1.0, 0.0)),
            "top row is up"
        );
        assert!(close(
            latlong_direction(0.3, 1.0),
            Vec3::new(0.0, -1.0, 0.0)
        ));
        for d in crate::sphere::fibonacci(50) {
            let [u, v] = latlong_uv(d);
            assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v));
            assert!(close(latlong_direction(u, v), d));
        }
        // The same layout as relit's equirectangular camera at the default pose.
        let camera = crate::camera::Camera::new(
            &crate::camera::Projection::Equirectangular,
            16,
            8,
            crate::camera::Pose::identity(),
        )
        .unwrap();
        for y in 0..8 {
            for x in 0..16 {
                let d = latlong_direction((x as f64 + 0.5) / 16.0, (y as f64 + 0.5) / 8.0);
                assert!(
                    close(camera.pixel_ray(x, y).direction, d),
                    "pixel ({x}, {y})"
                );
            }
        }
    }

    #[test]
    fn texel_solid_angles_add_up_to_the_sphere() {
        for (w, h) in [(8, 4), (64, 32), (30, 13)] {
            let total: f64 = (0..h).map(|y| w as f64 * texel_solid_angle(w, h, y)).sum();
            assert!((total - 4.0 * PI).abs() < 1e-12, "{w}×{h}: {total}");
        }
    }

    #[test]
    fn the_radiance_lookup_turns_with_the_environment() {
        // What the map shows at d arrives from R d.
        for (yaw, pitch, roll) in [(37.0, 0.0, 0.0), (-20.0, 35.0, 10.0)] {
            let r = rotation_from_yaw_pitch_roll(yaw, pitch, roll).unwrap();
            let original = EnvironmentLight::from_image(sampled_map(256, 128, smooth_sky)).unwrap();
            let turned = original.clone().with_rotation(r).unwrap();
            let d = Vec3::new(0.3, 0.2, -0.9).normalized().unwrap();
            assert_eq!(turned.radiance(mat3_apply(&r, d)), original.radiance(d));
        }
    }

    #[test]
    fn brute_force_weights_agree_with_the_dot_product() {
        // A pixel whose response is band-limited (4 bands of spherical harmonics, whose
        // own environment is the exact projection) relit by a smooth sky: the dot
        // product is exact for the map; nearest-direction binning over 600
        // directions is a quadrature with cells ~0.15 rad across, off by 9e-5 of the
        // total light here (measured; 4e-4 with 150 directions, 5e-5 with 2400).
        let basis = BasisSpec::named("sh:16").unwrap().build().unwrap();
        let response: Vec<f64> = (0..16)
            .map(|i| [0.8, 0.3, 0.5, -0.2, 0.1, -0.15, 0.2, 0.05][i % 8] / (1 + i) as f64)
            .collect();
        let env = EnvironmentLight::from_image(sampled_map(128, 64, smooth_sky))
            .unwrap()
            .with_rotation(rotation_from_yaw_pitch_roll(50.0, 10.0, 0.0).unwrap())
            .unwrap();
        let e = env
            .for_basis(basis.as_ref())
            .unwrap()
            .weights(basis.as_ref(), env.rotation(), Window::None)
            .unwrap();
        let dirs = crate::sphere::fibonacci(600);
        let w = env.weights_for_directions(&dirs).unwrap();
        for c in 0..3 {
            let relit: f64 = response.iter().zip(&e[c]).map(|(a, b)| a * b).sum();
            let brute: f64 = dirs
                .iter()
                .zip(&w)
                .map(|(d, wj)| {
                    wj[c]
                        * basis
                            .values(*d)
                            .iter()
                            .zip(&response)
                            .map(|(y, r)| y * r)
                            .sum::<f64>()
                })
                .sum();
            let scale: f64 = w.iter().map(|wj| wj[c].abs()).sum::<f64>();
            assert!(
                (relit - brute).abs() < 5e-4 * scale,
                "channel {c}: dot product {relit} vs brute force {brute}"
            );
            // The weights hold all the light: Σ w_j = ∫E dω = √(4π) e_0.
            let total: f64 = w.iter().map(|wj| wj[c]).sum();
            assert!(
                (total - (4.0 * PI).sqrt() * e[c][0]).abs() < EXACT_TOLERANCE * total,
                "{total}"
            );
        }
        assert!(env.weights_for_directions(&[]).is_err());
        assert!(env
            .weights_for_directions(&[Vec3::new(0.0, 0.0, 0.0)])
            .is_err());
    }

    #[test]
    fn the_band_limited_map_reprojects_onto_the_windowed_weights() {
        // A rotated, windowed sun-and-sky map turned into its 5-band, windowed
        // reconstruction on spherical harmonics: projecting that map again gives the windowed weights (its
        // content is band-limited, so the exact texel projection recovers it up to the
        // texel discretisation), and it carries the same total light.
        let sun = Vec3::new(0.3, 0.8, -0.5).normalized().unwrap();
        let map = sampled_map(128, 64, |d| {
            let s = if d.dot(sun) > 0.99 { 40.0 } else { 0.0 };
            [0.2 + s, 0.25 + s, 0.3 + 0.9 * s]
        });
        let env = EnvironmentLight::from_image(map)
            .unwrap()
            .with_rotation(rotation_from_yaw_pitch_roll(30.0, -20.0, 10.0).unwrap())
            .unwrap()
            .with_window(Window::Hann)
            .unwrap();
        let basis = BasisSpec::named("sh:25").unwrap().build().unwrap();
        let weights = |env: &EnvironmentLight| {
            env.for_basis(basis.as_ref())
                .unwrap()
                .weights(basis.as_ref(), env.rotation(), env.window())
                .unwrap()
        };
        let expected = weights(&env);
        let limited = env.band_limited(basis.as_ref(), 256, 128).unwrap();
        assert_eq!(limited.rotation(), MAT3_IDENTITY);
        assert_eq!(limited.window(), Window::None);
        let again = weights(&limited);
        for c in 0..3 {
            let scale = expected[c][0].abs();
            for (i, (a, b)) in again[c].iter().zip(&expected[c]).enumerate() {
                assert!(
                    (a - b).abs() < 2e-3 * scale,
                    "channel {c} coefficient {i}: {a} vs {b}"
                );
            }
        }
        assert!(env.band_limited(basis.as_ref(), 0, 10).is_err());
        let without_bands = BasisSpec::named("ptm:6").unwrap().build().unwrap();
        assert!(env.band_limited(without_bands.as_ref(), 64, 32).is_err());
    }

    #[test]
    fn bad_input_is_refused_with_an_error() {
        let env = EnvironmentLight::from_image(sampled_map(8, 4, smooth_sky)).unwrap();
        assert!(env
            .clone()
            .with_window(Window::Laplacian {
                lambda: Some(f64::NAN)
            })
            .is_err());
        assert!(env
            .clone()
            .with_rotation([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
            .is_err());
        let mut bad = sampled_map(8, 4, smooth_sky);
        bad.data[7] = f32::INFINITY;
        assert!(EnvironmentLight::from_image(bad)
            .unwrap_err()
            .to_string()
            .contains("(2, 0)"));
        assert!(EnvironmentLight::from_image(ImageRgb::new(0, 0)).is_err());
        assert!(EnvironmentLight::load(Path::new("/nonexistent/sky.hdr")).is_err());
    }

    #[test]
    fn shared_envmaps_load() {
        let Some(paths) = crate::image::test_maps::shared_envmaps() else {
            println!("skipped: shared/data/envmaps is not present");
            return;
        };
        for (n, path) in paths.iter().enumerate() {
            let env = EnvironmentLight::load(path).unwrap();
            assert_eq!(
                (env.map().width, env.map().height),
                (1024, 512),
                "{}",
                path.display()
            );
            if n > 0 {
                continue;
            }
            // Timings on the first map only (the machine is shared).
            let turned = env
                .with_rotation(rotation_from_yaw_pitch_roll(30.0, 10.0, -5.0).unwrap())
                .unwrap();
            let dirs = crate::sphere::fibonacci(100);
            let start = std::time::Instant::now();
            turned.weights_for_directions(&dirs).unwrap();
            println!(
                "{}: brute-force weights for 100 directions {:.1} ms",
                path.file_name().unwrap().to_string_lossy(),
                start.elapsed().as_secs_f64() * 1e3
            );
        }
    }
}

//! Environment lights: latitude–longitude HDR maps turned into SH light vectors.
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
//! vector is `L`: `f_p(L) = Σ_i c_i(p) Y_i(L)`. An environment sends radiance `E(ω)` from
//! every direction `ω` (the light vector of that texel); each solid-angle element acts as
//! a directional light of intensity `E(ω) dω`. By superposition the pixel's value is
//!
//! ```text
//! I_p = ∫ f_p(ω) E(ω) dω = Σ_i c_i(p) e_i,        e_i = ∫ E(ω) Y_i(ω) dω,
//! ```
//!
//! the second form by the orthonormality of the `Y_i`. The `e_i` are the same for every
//! pixel, so relighting by an environment costs one dot product per pixel and colour
//! channel, exactly like a single directional light whose weights are `Y_i(L)`.
//! [`EnvironmentLight::light_weights`] returns those `e_i` per channel, rotated and
//! windowed. A map of constant radiance 1 gives `e_0 = √(4π)`, hence
//! `I_p = ∫ f_p(ω) dω`: the sum of the responses to a unit light from every direction.
//!
//! # Rotation
//!
//! [`EnvironmentLight::with_rotation`] turns the environment by a rotation `R`:
//! `E'(ω) = E(Rᵀ ω)`, so what the map shows at `ω` arrives from `R ω`. It is applied to
//! the coefficients with [`ShRotation`], exactly and at no cost per pixel.
//! [`EnvironmentLight::with_yaw_degrees`] is a rotation about +y: positive yaw moves
//! what was straight ahead (the centre column) toward −x, i.e. the content of the map
//! slides toward smaller `u`.
//!
//! # Projection
//!
//! The map is taken as constant radiance over each texel, and that piecewise-constant
//! function is projected exactly: `e_i = Σ_texels E_t ∫_t Y_i dω`. A texel spans
//! `Δα = 2π/width` in azimuth and `[θ_top, θ_bottom]` in polar angle, a solid angle of
//! `Δα·(cos θ_top − cos θ_bottom)` ([`texel_solid_angle`]); the solid angles of the
//! whole map add up to exactly 4π, so a constant map projects onto `Y_0` alone.
//!
//! In a frame whose polar axis is the map's (+y) the integral separates: `Y_{l,m}` is
//! `N_{l,|m|}(θ)` times `cos(mφ)` (m > 0), 1 or `sin(|m|φ)` (m < 0), so
//! `e_{l,m} = Σ_rows Θ_{l,|m|}(row) Σ_columns E Φ_m(column)` with the azimuth integrals
//! `Φ_m` in closed form and the polar ones `Θ_{l,m} = ∫ N_{l,m}(θ) sin θ dθ` by 8-point
//! Gauss–Legendre quadrature in θ (exact to rounding: the integrand is a trigonometric
//! polynomial of degree ≤ 8 over a short interval). The coefficients are then rotated
//! from that frame into the light frame (together with the user's rotation) by one
//! [`ShRotation`]. The cost is `3 (2·bands − 1)` multiply-adds per texel.
//!
//! # Windowing
//!
//! Truncating the SH series of a map with a bright sun rings (negative lobes). A window
//! scales band `l` of the `bands` kept by `h_l` ([`Window::factors`]):
//!
//! * `None`: `h_l = 1`;
//! * `Hann`: `h_l = ½ (1 + cos(π l / bands))`;
//! * `Lanczos`: `h_l = sinc(π l / bands) = sin(π l / bands) / (π l / bands)`;
//! * `Laplacian { lambda }`: `h_l = 1 / (1 + λ l² (l+1)²)`, the window that minimises
//!   the squared Laplacian of the windowed function plus `1/λ` times its squared
//!   distance from the original (seed 003 §4.1, Sloan's "Stupid SH tricks"). Without
//!   `lambda` the default strength is `λ = 1 / (L² (L+1)²)` with `L = bands − 1`, which
//!   halves the highest band (`h_L = ½`).
//!
//! All leave band 0 (the mean radiance) untouched and decrease with `l`.
//!
//! # One dispatch
//!
//! Everything above is for the real SH basis, whose projection is exact, rotates
//! analytically and has bands to window. Every other basis is lit through the map's
//! quadrature ([`quadrature`]): a few thousand directional lights, `e_c = Σ_t I_{t,c}
//! y(R ω_t)` with the rotation applied to their directions. Band windows need bands and
//! are refused there with an error. [`EnvironmentLight::for_basis`] makes that choice once
//! per map and basis ([`BasisEnvironment`]), and its [`BasisEnvironment::weights`] gives
//! the weights per frame: the engines never name a basis.
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

use crate::basis::{
    check_rotation, compose, mat3_apply, rotation_about_axis, sh_index, transpose, Basis, Mat3,
    ShRotation, SphericalHarmonics, MAT3_IDENTITY, MAX_BANDS,
};

pub mod quadrature;

use crate::image::{load_linear, ImageRgb};
use crate::sphere::Vec3;
use crate::{Error, Result};
pub use quadrature::{
    environment_quadrature, quadrature_weights, QUADRATURE_HEIGHT, QUADRATURE_WIDTH,
};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::Path;

/// The light vector of texture position `(u, v)` of a lat-long map (see the module docs).
pub fn latlong_direction(u: f64, v: f64) -> Vec3 {
    let (sin_t, cos_t) = (PI * v).sin_cos();
    let (sin_a, cos_a) = (2.0 * PI * (u - 0.5)).sin_cos();
    Vec3::new(sin_t * sin_a, cos_t, -sin_t * cos_a)
}

/// The texture position `[u, v]` of the non-zero direction `dir`: the inverse of
/// [`latlong_direction`], with `u ∈ [0, 1]` (both ends are the seam behind the camera)
/// and `v ∈ [0, 1]`.
pub fn latlong_uv(dir: Vec3) -> [f64; 2] {
    let u = dir.x.atan2(-dir.z) / (2.0 * PI) + 0.5;
    let v = dir.x.hypot(dir.z).atan2(dir.y) / PI;
    [u, v]
}

/// The solid angle of a texel in row `row` of a `width × height` lat-long map:
/// `(2π / width)·(cos θ_top − cos θ_bottom)`.
pub fn texel_solid_angle(width: usize, height: usize, row: usize) -> f64 {
    let theta = |r: usize| PI * r as f64 / height as f64;
    2.0 * PI / width as f64 * (theta(row).cos() - theta(row + 1).cos())
}

/// How the SH coefficients of an environment are attenuated by band (module docs,
/// *Windowing*).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Window {
    /// `h_l = 1`.
    #[default]
    None,
    /// `h_l = ½ (1 + cos(π l / bands))`.
    Hann,
    /// `h_l = sinc(π l / bands)`.
    Lanczos,
    /// `h_l = 1 / (1 + λ l²(l+1)²)`; `lambda` defaults to `1 / (L²(L+1)²)`, `L = bands − 1`.
    Laplacian {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        lambda: Option<f64>,
    },
}

impl Window {
    /// The window's name as users type it (`none`, `hann`, `lanczos`, `laplacian`).
    pub fn name(&self) -> &'static str {
        match self {
            Window::None => "none",
            Window::Hann => "hann",
            Window::Lanczos => "lanczos",
            Window::Laplacian { .. } => "laplacian",
        }
    }

    /// Parse `none`, `hann`, `lanczos`, `laplacian` or `laplacian:λ`.
    pub fn parse(spec: &str) -> Result<Window> {
        let window = match spec.split_once(':') {
            None => match spec {
                "none" => Window::None,
                "hann" => Window::Hann,
                "lanczos" => Window::Lanczos,
                "laplacian" => Window::Laplacian { lambda: None },
                other => {
                    return Err(Error::invalid(format!(
                        "unknown window `{other}`: use none, hann, lanczos or laplacian[:λ]"
                    )))
                }
            },
            Some(("laplacian", lambda)) => Window::Laplacian {
                lambda: Some(
                    lambda
                        .parse()
                        .map_err(|_| Error::invalid(format!("`{lambda}` is not a number")))?,
                ),
            },
            Some(_) => {
                return Err(Error::invalid(format!(
                    "only the laplacian window takes a value, not `{spec}`"
                )))
            }
        };
        window.validate()?;
        Ok(window)
    }

    /// Check the window's parameter.
    pub fn validate(&self) -> Result<()> {
        if let Window::Laplacian {
            lambda: Some(lambda),
        } = *self
        {
            if !(lambda.is_finite() && lambda >= 0.0) {
                return Err(Error::invalid(format!(
                    "a Laplacian window needs a finite λ ≥ 0, not {lambda}"
                )));
            }
        }
        Ok(())
    }

    /// The factors `h_0..h_{bands-1}` (1 ≤ bands ≤ 8).
    pub fn factors(&self, bands: usize) -> Result<Vec<f64>> {
        check_bands(bands)?;
        self.validate()?;
        let b = bands as f64;
        let h = |l: usize| -> f64 {
            let x = PI * l as f64 / b;
            match *self {
                Window::None => 1.0,
                Window::Hann => 0.5 * (1.0 + x.cos()),
                Window::Lanczos if l == 0 => 1.0,
                Window::Lanczos => x.sin() / x,
                Window::Laplacian { lambda } => {
                    let lambda = lambda.unwrap_or_else(|| default_laplacian_lambda(bands));
                    let ll = (l * (l + 1)) as f64;
                    1.0 / (1.0 + lambda * ll * ll)
                }
            }
        };
        Ok((0..bands).map(h).collect())
    }
}

/// The default strength of the Laplacian window: `h_{bands-1} = ½`.
fn default_laplacian_lambda(bands: usize) -> f64 {
    let top = (bands - 1) as f64;
    if bands > 1 {
        1.0 / (top * top * (top + 1.0) * (top + 1.0))
    } else {
        0.0
    }
}

fn check_bands(bands: usize) -> Result<()> {
    if !(1..=MAX_BANDS).contains(&bands) {
        return Err(Error::invalid(format!(
            "an environment light needs 1 to {MAX_BANDS} SH bands, got {bands}"
        )));
    }
    Ok(())
}

/// From the map frame (polar axis +y, azimuth φ = −α from −z toward −x; its axes are
/// −z, −x, +y of the light frame) to the light frame: the columns are those axes.
const MAP_TO_LIGHT: Mat3 = [[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]];

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

    /// The window applied to the SH weights (none by default).
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

    /// Window the SH weights.
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

    /// The SH projection `∫ E(ω) Y_i(ω) dω` of the map as stored (no rotation, no
    /// window), in the light frame: `bands²` coefficients per colour channel.
    pub fn project(&self, bands: usize) -> Result<[Vec<f64>; 3]> {
        let map_frame = project_map_frame(&self.map, bands)?;
        rotate_channels(&ShRotation::new(MAP_TO_LIGHT, bands)?, &map_frame)
    }

    /// The weights `e_i` per colour channel that relight a coefficient map by one dot
    /// product per pixel, `I_p = Σ_i c_i(p) e_i` (module docs): the projection of the
    /// map, rotated, then windowed.
    pub fn light_weights(&self, bands: usize) -> Result<[Vec<f64>; 3]> {
        let map_frame = project_map_frame(&self.map, bands)?;
        let rotation = ShRotation::new(compose(&self.rotation, &MAP_TO_LIGHT), bands)?;
        let mut weights = rotate_channels(&rotation, &map_frame)?;
        apply_window(&self.window, bands, &mut weights)?;
        Ok(weights)
    }

    /// [`Self::light_weights`] from a projection made earlier by [`Self::project`]: only
    /// the rotation and window are applied (microseconds), so an interactive viewer
    /// projects once and re-rotates freely.
    pub fn weights_from_projection(&self, projection: &[Vec<f64>; 3]) -> Result<[Vec<f64>; 3]> {
        Self::rotated_projection(projection, self.rotation, self.window)
    }

    /// An SH projection turned by `rotation` and windowed.
    fn rotated_projection(
        projection: &[Vec<f64>; 3],
        rotation: Mat3,
        window: Window,
    ) -> Result<[Vec<f64>; 3]> {
        let len = projection[0].len();
        let bands = (len as f64).sqrt().round() as usize;
        if bands * bands != len || projection.iter().any(|c| c.len() != len) {
            return Err(Error::invalid(format!(
                "an SH projection needs bands² coefficients in each of its 3 channels, got {}, {} and {}",
                projection[0].len(),
                projection[1].len(),
                projection[2].len()
            )));
        }
        check_bands(bands)?;
        let mut weights = rotate_channels(&ShRotation::new(rotation, bands)?, projection)?;
        apply_window(&window, bands, &mut weights)?;
        Ok(weights)
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

    /// The environment as SH relighting with `bands` bands sees it: a `width × height`
    /// lat-long map (light frame, no further rotation) of `Σ_i e_i Y_i(ω)` with the
    /// rotated, windowed [`Self::light_weights`]. Its brute-force weights
    /// ([`Self::weights_for_directions`]) relight the raw captures under exactly the
    /// band-limited lighting the coefficient maps are relit with, so comparing the two
    /// isolates the fit from the truncation of the environment. Ringing shows as
    /// negative radiance, which is kept.
    pub fn band_limited(&self, bands: usize, width: usize, height: usize) -> Result<Self> {
        if width == 0 || height == 0 || width.saturating_mul(height) > 1 << 24 {
            return Err(Error::invalid(format!(
                "a band-limited environment map needs 1 to 2^24 texels, not {width}×{height}"
            )));
        }
        let weights = self.light_weights(bands)?;
        let sh = SphericalHarmonics::new(bands)?;
        let k = bands * bands;
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
                    sh.eval(dir, &mut values);
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
#[derive(Clone, Debug)]
pub enum BasisEnvironment {
    /// The exact SH projection of the map, in the light frame, unrotated, unwindowed.
    Sh { projection: [Vec<f64>; 3] },
    /// The map's quadrature ([`environment_quadrature`] at [`QUADRATURE_WIDTH`] ×
    /// [`QUADRATURE_HEIGHT`]), for every other basis.
    Quadrature(Vec<(Vec3, [f64; 3])>),
}

impl EnvironmentLight {
    /// This map (its rotation and window aside) made ready for `basis`: SH's exact
    /// projection, or the quadrature for a basis without bands.
    pub fn for_basis(&self, basis: &dyn Basis) -> Result<BasisEnvironment> {
        Ok(match basis.band_limit() {
            Some(bands) => BasisEnvironment::Sh {
                projection: self.project(bands)?,
            },
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
    /// made for) by one dot product per pixel, the environment turned by `rotation` and,
    /// for SH, windowed. A window other than `none` on a basis without bands is an
    /// error.
    pub fn weights(
        &self,
        basis: &dyn Basis,
        rotation: Mat3,
        window: Window,
    ) -> Result<[Vec<f64>; 3]> {
        check_rotation(&rotation)?;
        window.validate()?;
        match self {
            BasisEnvironment::Sh { projection } => {
                EnvironmentLight::rotated_projection(projection, rotation, window)
            }
            BasisEnvironment::Quadrature(lights) => {
                if window != Window::None {
                    return Err(Error::invalid(format!(
                        "band windows ({window:?}) are for bases with bands (SH); basis {} has none: use no window",
                        basis.name()
                    )));
                }
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

fn rotate_channels(rotation: &ShRotation, coeffs: &[Vec<f64>; 3]) -> Result<[Vec<f64>; 3]> {
    Ok([
        rotation.rotate(&coeffs[0])?,
        rotation.rotate(&coeffs[1])?,
        rotation.rotate(&coeffs[2])?,
    ])
}

fn apply_window(window: &Window, bands: usize, coeffs: &mut [Vec<f64>; 3]) -> Result<()> {
    let h = window.factors(bands)?;
    for channel in coeffs.iter_mut() {
        for (l, &hl) in h.iter().enumerate() {
            channel[l * l..(l + 1) * (l + 1)]
                .iter_mut()
                .for_each(|c| *c *= hl);
        }
    }
    Ok(())
}

/// 8-point Gauss–Legendre nodes and weights on [−1, 1] (the nodes come in ± pairs).
const GAUSS_LEGENDRE_8: [(f64, f64); 4] = [
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
];

/// Rows are split into at least this many quadrature intervals in total, so that even a
/// map a few rows high is integrated exactly (each interval at most π/16 wide).
const MIN_POLAR_INTERVALS: usize = 16;

/// The exact projection of the piecewise-constant map onto SH of the map frame, whose
/// polar axis is +y and whose azimuth is `φ = −α` (module docs, *Projection*).
fn project_map_frame(map: &ImageRgb, bands: usize) -> Result<[Vec<f64>; 3]> {
    check_bands(bands)?;
    let sh = SphericalHarmonics::new(bands)?;
    let (w, h) = (map.width, map.height);
    let top = bands as isize - 1;
    let orders = 2 * bands - 1; // m = -top..=top, stored at m + top

    // Azimuth integrals Φ_m over each column. Column x spans α ∈ [α_x, α_x + Δ], so
    // φ = −α spans an interval of width Δ centred on φ_c = −2π((x + ½)/w − ½).
    let delta = 2.0 * PI / w as f64;
    let mut phi_integrals = vec![0.0; orders * w];
    for x in 0..w {
        let centre = -2.0 * PI * ((x as f64 + 0.5) / w as f64 - 0.5);
        for m in -top..=top {
            let k = m.unsigned_abs() as f64;
            // ∫ cos(kφ) = (2/k) cos(kφ_c) sin(kΔ/2); ∫ sin(kφ) = (2/k) sin(kφ_c) sin(kΔ/2).
            let value = match m.cmp(&0) {
                std::cmp::Ordering::Equal => delta,
                std::cmp::Ordering::Greater => {
                    2.0 / k * (k * centre).cos() * (k * delta / 2.0).sin()
                }
                std::cmp::Ordering::Less => 2.0 / k * (k * centre).sin() * (k * delta / 2.0).sin(),
            };
            phi_integrals[(m + top) as usize * w + x] = value;
        }
    }

    // Polar integrals Θ_{l,m}(row) = ∫ N_{l,m}(θ) sin θ dθ for m ≥ 0, where N_{l,m}(θ) is
    // Y_{l,m} at azimuth 0, by Gauss–Legendre over `pieces` sub-intervals of the row.
    let pieces = MIN_POLAR_INTERVALS.div_ceil(h);
    let polar_integrals = |y: usize| -> Vec<f64> {
        let mut theta_int = vec![0.0; bands * bands];
        let mut values = vec![0.0; bands * bands];
        let row_width = PI / h as f64;
        let piece_width = row_width / pieces as f64;
        for piece in 0..pieces {
            let mid = row_width * y as f64 + piece_width * (piece as f64 + 0.5);
            for &(node, weight) in &GAUSS_LEGENDRE_8 {
                for theta in [
                    mid - node * piece_width / 2.0,
                    mid + node * piece_width / 2.0,
                ] {
                    let (s, c) = theta.sin_cos();
                    sh.eval(Vec3::new(s, 0.0, c), &mut values);
                    let scale = weight * piece_width / 2.0 * s;
                    theta_int
                        .iter_mut()
                        .zip(&values)
                        .for_each(|(t, v)| *t += scale * v);
                }
            }
        }
        theta_int
    };

    let k = bands * bands;
    let partials: Vec<Vec<f64>> = (0..h)
        .collect::<Vec<_>>()
        .par_chunks(ROWS_PER_TASK)
        .map(|rows| {
            let mut acc = vec![0.0; 3 * k];
            let mut planar = vec![0.0f64; 3 * w];
            let mut sums = vec![0.0f64; 3 * orders];
            for &y in rows {
                let row = &map.data[3 * w * y..3 * w * (y + 1)];
                for (x, px) in row.chunks_exact(3).enumerate() {
                    for c in 0..3 {
                        planar[c * w + x] = f64::from(px[c]);
                    }
                }
                // Σ_columns E_c Φ_m for each channel and order.
                for (mi, phi) in phi_integrals.chunks_exact(w).enumerate() {
                    for c in 0..3 {
                        sums[c * orders + mi] = planar[c * w..(c + 1) * w]
                            .iter()
                            .zip(phi)
                            .map(|(e, p)| e * p)
                            .sum();
                    }
                }
                let theta_int = polar_integrals(y);
                for l in 0..bands {
                    for m in -(l as isize)..=(l as isize) {
                        let t = theta_int[sh_index(l, m.abs())];
                        let mi = (m + top) as usize;
                        for c in 0..3 {
                            acc[c * k + sh_index(l, m)] += t * sums[c * orders + mi];
                        }
                    }
                }
            }
            acc
        })
        .collect();
    let mut out = [vec![0.0; k], vec![0.0; k], vec![0.0; k]];
    for part in &partials {
        for (c, channel) in out.iter_mut().enumerate() {
            channel
                .iter_mut()
                .zip(&part[c * k..(c + 1) * k])
                .for_each(|(o, p)| *o += p);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::rotation_from_yaw_pitch_roll;

    /// A map whose texel centres sample `f` (RGB).
    fn sampled_map(width: usize, height: usize, f: impl Fn(Vec3) -> [f64; 3]) -> ImageRgb {
        let mut map = ImageRgb::new(width, height);
        for y in 0..height {
            for x in 0..width {
                let d = latlong_direction(
                    (x as f64 + 0.5) / width as f64,
                    (y as f64 + 0.5) / height as f64,
                );
                let i = 3 * (y * width + x);
                map.data[i..i + 3].copy_from_slice(&f(d).map(|v| v as f32));
            }
        }
        map
    }

    /// A smooth, positive, coloured environment: a soft "sky" lobe and a broad fill.
    fn smooth_sky(d: Vec3) -> [f64; 3] {
        let sun = Vec3::new(0.4, 0.7, -0.6).normalized().unwrap();
        let lobe = (3.0 * (d.dot(sun) - 1.0)).exp();
        [
            2.0 * lobe + 0.3,
            1.5 * lobe + 0.2 + 0.1 * d.y,
            lobe + 0.4 - 0.1 * d.x,
        ]
    }

    fn shared_envmaps() -> Option<Vec<std::path::PathBuf>> {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/envmaps");
        let mut paths: Vec<_> = std::fs::read_dir(&dir)
            .ok()?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "hdr"))
            .collect();
        paths.sort();
        (!paths.is_empty()).then_some(paths)
    }

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
    fn constant_map_projects_onto_the_constant_only() {
        let radiance = [1.5f32, 2.0, 0.25];
        for (w, h) in [(64, 32), (30, 13), (5, 3)] {
            let mut map = ImageRgb::new(w, h);
            map.data
                .chunks_exact_mut(3)
                .for_each(|p| p.copy_from_slice(&radiance));
            let env = EnvironmentLight::from_image(map).unwrap();
            let e = env.project(MAX_BANDS).unwrap();
            for c in 0..3 {
                let want = radiance[c] as f64 * (4.0 * PI).sqrt();
                assert!(
                    (e[c][0] - want).abs() < EXACT_TOLERANCE,
                    "{w}×{h} e_0: {} vs {want}",
                    e[c][0]
                );
                for (i, v) in e[c].iter().enumerate().skip(1) {
                    assert!(v.abs() < EXACT_TOLERANCE, "{w}×{h} channel {c} e_{i} = {v}");
                }
            }
        }
    }

    /// A map sampling `Y_i` at texel centres differs from `Y_i` within each texel by
    /// O(texel²): the worst coefficient error over all 64 harmonics is 5.1e-3 at
    /// 128×64, 1.3e-3 at 256×128 and 3.2e-4 at 512×256 (measured).
    const SAMPLED_TOLERANCE: f64 = 2e-3;

    #[test]
    fn a_map_of_one_harmonic_projects_onto_that_harmonic() {
        let bands = MAX_BANDS;
        let sh = SphericalHarmonics::new(bands).unwrap();
        for i in [0, 1, 2, 3, 6, 8, 13, 22, 30, 41, 48, 56, 63] {
            let map = sampled_map(256, 128, |d| {
                let y = sh.values(d)[i];
                [y, -0.5 * y, 2.0 * y]
            });
            let e = EnvironmentLight::from_image(map)
                .unwrap()
                .project(bands)
                .unwrap();
            for (c, scale) in [1.0, -0.5, 2.0].into_iter().enumerate() {
                for (j, v) in e[c].iter().enumerate() {
                    let want = if j == i { scale } else { 0.0 };
                    let error = (v - want).abs();
                    assert!(
                        error < SAMPLED_TOLERANCE * scale.abs(),
                        "Y_{i}, channel {c}: e_{j} = {v}"
                    );
                }
            }
        }
    }

    #[test]
    fn yaw_by_whole_columns_equals_shifting_the_map() {
        // Yaw ψ moves the content toward smaller u by ψ/2π of the width: 90° is 8 of 32
        // columns, and the projection of the shifted map is exact.
        let (w, h) = (32, 16);
        let map = sampled_map(w, h, smooth_sky);
        let mut shifted = ImageRgb::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let src = map.get((x + w / 4) % w, y);
                shifted.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&src);
            }
        }
        let yawed = EnvironmentLight::from_image(map)
            .unwrap()
            .with_yaw_degrees(90.0)
            .unwrap();
        let want = EnvironmentLight::from_image(shifted)
            .unwrap()
            .project(MAX_BANDS)
            .unwrap();
        let got = yawed.light_weights(MAX_BANDS).unwrap();
        for c in 0..3 {
            for (i, (g, w)) in got[c].iter().zip(&want[c]).enumerate() {
                assert!(
                    (g - w).abs() < EXACT_TOLERANCE,
                    "channel {c} e_{i}: {g} vs {w}"
                );
            }
        }
    }

    /// Both maps sample a smooth function at texel centres of a 256×128 grid; the
    /// rotated one samples different points, so they agree to the sampling error
    /// (measured: 1.4e-9 for a yaw, which only shifts azimuths; 5.4e-5 for a general
    /// rotation, against e_0 ≈ 2.2).
    const RESAMPLED_TOLERANCE: f64 = 3e-4;

    #[test]
    fn rotating_the_weights_equals_reprojecting_a_rotated_map() {
        for (yaw, pitch, roll) in [(37.0, 0.0, 0.0), (-20.0, 35.0, 10.0)] {
            let r = rotation_from_yaw_pitch_roll(yaw, pitch, roll).unwrap();
            let env = EnvironmentLight::from_image(sampled_map(256, 128, smooth_sky))
                .unwrap()
                .with_rotation(r)
                .unwrap();
            let inverse = transpose(&r);
            let rotated_map = sampled_map(256, 128, |d| smooth_sky(mat3_apply(&inverse, d)));
            let want = EnvironmentLight::from_image(rotated_map)
                .unwrap()
                .project(6)
                .unwrap();
            let got = env.light_weights(6).unwrap();
            // The rotated projection equals the projection made earlier, re-rotated.
            let again = env
                .weights_from_projection(&env.project(6).unwrap())
                .unwrap();
            for c in 0..3 {
                for i in 0..36 {
                    assert!(
                        (got[c][i] - want[c][i]).abs() < RESAMPLED_TOLERANCE,
                        "{yaw}/{pitch}/{roll} c{c} e_{i}"
                    );
                    assert!((got[c][i] - again[c][i]).abs() < 1e-12);
                }
            }
            // The radiance lookup turns the same way: what the map shows at d arrives from R d.
            let d = Vec3::new(0.3, 0.2, -0.9).normalized().unwrap();
            let turned = env.radiance(mat3_apply(&r, d));
            let original = EnvironmentLight::from_image(sampled_map(256, 128, smooth_sky))
                .unwrap()
                .radiance(d);
            assert_eq!(turned, original);
        }
    }

    #[test]
    fn windows_keep_band_zero_and_decrease() {
        let windows = [
            Window::Hann,
            Window::Lanczos,
            Window::Laplacian { lambda: None },
            Window::Laplacian { lambda: Some(1e-3) },
        ];
        for bands in 1..=MAX_BANDS {
            assert!(Window::None
                .factors(bands)
                .unwrap()
                .iter()
                .all(|&h| h == 1.0));
            for window in windows {
                let h = window.factors(bands).unwrap();
                assert_eq!(h.len(), bands);
                assert_eq!(h[0], 1.0, "{window:?}");
                for l in 1..bands {
                    assert!(
                        h[l] < h[l - 1] && h[l] > 0.0,
                        "{window:?} bands {bands}: {h:?}"
                    );
                }
            }
            if bands > 1 {
                let h = Window::Laplacian { lambda: None }.factors(bands).unwrap();
                assert!(
                    (h[bands - 1] - 0.5).abs() < 1e-15,
                    "the default strength halves the top band"
                );
            }
        }
        // The formulas at one point: bands 4, l 2.
        let at = |w: Window| w.factors(4).unwrap()[2];
        assert!((at(Window::Hann) - 0.5).abs() < 1e-15);
        assert!((at(Window::Lanczos) - 2.0 / PI).abs() < 1e-15);
        assert!((at(Window::Laplacian { lambda: Some(0.01) }) - 1.0 / 1.36).abs() < 1e-15);
        // The window scales the weights band by band.
        let env = EnvironmentLight::from_image(sampled_map(32, 16, smooth_sky)).unwrap();
        let plain = env.light_weights(4).unwrap();
        let hann = env
            .clone()
            .with_window(Window::Hann)
            .unwrap()
            .light_weights(4)
            .unwrap();
        let h = Window::Hann.factors(4).unwrap();
        for i in 0..16 {
            let l = (i as f64).sqrt() as usize;
            assert!((hann[1][i] - h[l] * plain[1][i]).abs() < 1e-15);
        }
        assert!(Window::Laplacian { lambda: Some(-1.0) }.validate().is_err());
        assert!(env
            .with_window(Window::Laplacian {
                lambda: Some(f64::NAN)
            })
            .is_err());
        let json = serde_json::to_string(&Window::Laplacian { lambda: None }).unwrap();
        assert_eq!(json, r#"{"type":"laplacian"}"#);
        assert_eq!(
            serde_json::from_str::<Window>(r#"{"type":"hann"}"#).unwrap(),
            Window::Hann
        );
    }

    #[test]
    fn brute_force_weights_agree_with_the_sh_dot_product() {
        // A pixel whose response is band-limited (4 bands) relit by a smooth sky: the SH
        // dot product is exact for the map; nearest-direction binning over 600
        // directions is a quadrature with cells ~0.15 rad across, off by 9e-5 of the
        // total light here (measured; 4e-4 with 150 directions, 5e-5 with 2400).
        let sh = SphericalHarmonics::new(4).unwrap();
        let response: Vec<f64> = (0..16)
            .map(|i| [0.8, 0.3, 0.5, -0.2, 0.1, -0.15, 0.2, 0.05][i % 8] / (1 + i) as f64)
            .collect();
        let env = EnvironmentLight::from_image(sampled_map(128, 64, smooth_sky))
            .unwrap()
            .with_rotation(rotation_from_yaw_pitch_roll(50.0, 10.0, 0.0).unwrap())
            .unwrap();
        let e = env.light_weights(4).unwrap();
        let dirs = crate::sphere::fibonacci(600);
        let w = env.weights_for_directions(&dirs).unwrap();
        for c in 0..3 {
            let sh_relit: f64 = response.iter().zip(&e[c]).map(|(a, b)| a * b).sum();
            let brute: f64 = dirs
                .iter()
                .zip(&w)
                .map(|(d, wj)| {
                    wj[c]
                        * sh.values(*d)
                            .iter()
                            .zip(&response)
                            .map(|(y, r)| y * r)
                            .sum::<f64>()
                })
                .sum();
            let scale: f64 = w.iter().map(|wj| wj[c].abs()).sum::<f64>();
            assert!(
                (sh_relit - brute).abs() < 5e-4 * scale,
                "channel {c}: SH {sh_relit} vs brute force {brute}"
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
        // A rotated, windowed sun-and-sky map turned into its 5-band, windowed SH
        // reconstruction: projecting that map again gives the windowed weights (its
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
        let expected = env.light_weights(5).unwrap();
        let limited = env.band_limited(5, 256, 128).unwrap();
        assert_eq!(limited.rotation(), MAT3_IDENTITY);
        let again = limited.project(5).unwrap();
        for c in 0..3 {
            let scale = expected[c][0].abs();
            for (i, (a, b)) in again[c].iter().zip(&expected[c]).enumerate() {
                assert!(
                    (a - b).abs() < 2e-3 * scale,
                    "channel {c} coefficient {i}: {a} vs {b}"
                );
            }
        }
        assert!(env.band_limited(5, 0, 10).is_err());
    }

    #[test]
    fn bad_input_is_refused_with_an_error() {
        let env = EnvironmentLight::from_image(sampled_map(8, 4, smooth_sky)).unwrap();
        assert!(env.light_weights(0).is_err());
        assert!(env.light_weights(9).is_err());
        assert!(env
            .weights_from_projection(&[vec![0.0; 4], vec![0.0; 4], vec![0.0; 3]])
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
    fn shared_envmaps_load_and_project() {
        let Some(paths) = shared_envmaps() else {
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
            let time = |f: &mut dyn FnMut()| {
                let start = std::time::Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            };
            let mut e5: [Vec<f64>; 3] = Default::default();
            let mut e8: [Vec<f64>; 3] = Default::default();
            let t5 = time(&mut || e5 = env.project(5).unwrap());
            let t8 = time(&mut || e8 = env.project(8).unwrap());
            let turned = env
                .clone()
                .with_rotation(rotation_from_yaw_pitch_roll(30.0, 10.0, -5.0).unwrap())
                .unwrap();
            let mut weights: [Vec<f64>; 3] = Default::default();
            let t_rot = time(&mut || weights = turned.weights_from_projection(&e8).unwrap());
            let dirs = crate::sphere::fibonacci(100);
            let t_brute = time(&mut || {
                turned.weights_for_directions(&dirs).unwrap();
            });
            println!(
                "{}: project 5 bands {t5:.1} ms, 8 bands {t8:.1} ms; rotate + window 8 bands {:.3} ms; \
                 brute-force weights for 100 directions {t_brute:.1} ms",
                path.file_name().unwrap().to_string_lossy(),
                t_rot
            );
            // Lower bands do not depend on how many are projected; rotation keeps each
            // band's energy; the mean radiance is positive.
            for c in 0..3 {
                assert!(e8[c][0] > 0.0);
                for i in 0..25 {
                    assert!((e5[c][i] - e8[c][i]).abs() <= 1e-9 * e8[c][0]);
                }
                for l in 0..8 {
                    let band = |v: &[f64]| {
                        v[l * l..(l + 1) * (l + 1)]
                            .iter()
                            .map(|x| x * x)
                            .sum::<f64>()
                    };
                    assert!(
                        (band(&weights[c]) - band(&e8[c])).abs() <= 1e-9 * band(&e8[c]).max(1e-300)
                    );
                }
            }
        }
    }
}

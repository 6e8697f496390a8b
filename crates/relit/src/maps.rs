//! Relightable images: coefficient maps plus what is needed to interpret them.

use crate::basis::BasisSpec;
use crate::camera::{CameraSpec, Projection};
use serde::{Deserialize, Serialize};

/// The version of the file layout written by this build (see the [conventions](crate)).
pub const FORMAT_VERSION: u32 = 1;

/// The light frame, stated in every file so that a reader never has to guess.
pub const LIGHT_FRAME: &str = "light vectors toward the light; x right, y up, z toward the camera";

/// Which space the maps' values are in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum MapSpace {
    /// Linear radiance for a unit white light: lights add up physically.
    #[default]
    Linear,
    /// Display-referred: the basis reproduces sRGB-encoded values (single-light RTI
    /// publishing). The engine decodes each light's contribution before adding.
    Srgb,
}

impl MapSpace {
    pub fn name(self) -> &'static str {
        match self {
            MapSpace::Linear => "linear",
            MapSpace::Srgb => "srgb",
        }
    }
}

/// How a set of maps was fitted, kept for `relit info` and provenance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitInfo {
    /// `perceptual` or `linear`.
    pub objective: String,
    /// The smoothness penalty's name (e.g. `roughness`).
    pub regularizer: String,
    /// The regularisation weight λ used (relative to the data weight).
    pub lambda: f64,
    /// How λ was chosen: `auto` (leave-one-out on a pixel subsample) or `fixed`.
    pub lambda_choice: String,
    /// Number of reference images fitted.
    pub images: usize,
    /// Root-mean-square training residual per channel in linear radiance (subsample).
    pub rmse_linear: [f64; 3],
    /// 8-bit sRGB PSNR of the training images (subsample).
    pub psnr_srgb8: f64,
    /// Wall time of the fit in seconds.
    pub seconds: f64,
    /// Present when the file holds one band of rows of a sharded fit (`relit fit
    /// --tile i/N`), which `relit merge` joins with the others.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardInfo>,
}

/// Which band of rows of a sharded fit a file holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardInfo {
    /// Part `index` (from 0) of `count`.
    pub index: usize,
    pub count: usize,
    /// The band's first row in the whole image.
    pub row0: usize,
    /// Rows of the whole image.
    pub full_height: usize,
}

impl ShardInfo {
    /// Part `index` of `count` equal bands of an image `height` rows tall, or why there
    /// is no such part.
    pub fn new(index: usize, count: usize, height: usize) -> std::result::Result<Self, String> {
        if count == 0 || index >= count {
            return Err(format!(
                "part {index} of {count} does not exist (parts are numbered 0 to N−1)"
            ));
        }
        if count > height {
            return Err(format!(
                "{count} parts of an image of {height} rows would leave some empty"
            ));
        }
        Ok(ShardInfo {
            index,
            count,
            row0: Self::first_row(index, count, height),
            full_height: height,
        })
    }

    fn first_row(index: usize, count: usize, height: usize) -> usize {
        // In u128: a file may claim any height, and `index · height` must not wrap.
        (index as u128 * height as u128 / count as u128) as usize
    }

    /// The rows of the whole image this part holds.
    pub fn rows(&self) -> std::ops::Range<usize> {
        self.row0..Self::first_row(self.index + 1, self.count, self.full_height)
    }
}

impl std::fmt::Display for ShardInfo {
    /// `part 1 of 3: rows 5..10 of 16`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let rows = self.rows();
        write!(
            f,
            "part {} of {}: rows {}..{} of {}",
            self.index, self.count, rows.start, rows.end, self.full_height
        )
    }
}

/// How a set of maps was baked from geometry (`relit bake`), kept for provenance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeInfo {
    /// `visibility`, `diffuse` or `bleeding`.
    pub transfer: String,
    /// Directions traced per camera sample.
    pub samples: u32,
    /// Bounce rays per camera sample (`bleeding`), 0 otherwise.
    pub indirect: u32,
    /// Directions traced per bounce point (`bleeding`), 0 otherwise.
    pub bounce_samples: u32,
    /// Camera samples per pixel along each axis.
    pub supersample: u32,
    /// The band window applied to the baked coefficients (`none`, `hann`, …).
    pub window: String,
    /// Whether glossy lobes were dropped (Lambertian transfer only).
    #[serde(default)]
    pub lambert: bool,
    /// Standard error of the white-sky image (the pixel lit by a uniform unit
    /// environment) from sampling, relative to its mean: an upper estimate.
    pub noise: f64,
    /// Wall time of the bake in seconds.
    pub seconds: f64,
}

/// Everything about a relightable image but its pixels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metadata {
    pub format_version: u32,
    pub basis: BasisSpec,
    pub color_space: MapSpace,
    pub light_frame: String,
    pub projection: Projection,
    /// The full camera (pose included), needed with depth by lights that have a position.
    pub camera: Option<CameraSpec>,
    pub fit: Option<FitInfo>,
    /// Present when the maps were baked from geometry instead of fitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bake: Option<BakeInfo>,
}

impl Metadata {
    /// Metadata for fresh maps of `basis`.
    pub fn new(basis: BasisSpec, color_space: MapSpace, projection: Projection) -> Self {
        Self {
            format_version: FORMAT_VERSION,
            basis,
            color_space,
            light_frame: LIGHT_FRAME.to_string(),
            projection,
            camera: None,
            fit: None,
            bake: None,
        }
    }
}

/// `k` coefficients × 3 colour channels of planar `f32` maps (plane `3 * i + c`).
#[derive(Clone, Debug, PartialEq)]
pub struct CoefficientMaps {
    pub width: usize,
    pub height: usize,
    pub k: usize,
    /// `3 * k` planes of `width * height` values, plane `3 * i + c` for coefficient `i`, channel `c`.
    pub data: Vec<f32>,
}

impl CoefficientMaps {
    /// Zeroed maps.
    pub fn zeros(width: usize, height: usize, k: usize) -> Self {
        Self {
            width,
            height,
            k,
            data: vec![0.0; 3 * k * width * height],
        }
    }

    /// Pixels per plane.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// The plane of coefficient `i`, channel `c`.
    pub fn plane(&self, i: usize, c: usize) -> &[f32] {
        let n = self.pixels();
        &self.data[(3 * i + c) * n..(3 * i + c + 1) * n]
    }

    /// The plane of coefficient `i`, channel `c`, mutably.
    pub fn plane_mut(&mut self, i: usize, c: usize) -> &mut [f32] {
        let n = self.pixels();
        &mut self.data[(3 * i + c) * n..(3 * i + c + 1) * n]
    }

    /// The coefficients of pixel `p` for channel `c`.
    pub fn coefficients(&self, p: usize, c: usize) -> Vec<f32> {
        (0..self.k).map(|i| self.plane(i, c)[p]).collect()
    }

    /// Bytes of the maps in memory.
    pub fn bytes(&self) -> usize {
        self.data.len() * 4
    }
}

/// Coefficient maps with their metadata and optional depth: what a `.exr` file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct RelightableImage {
    pub meta: Metadata,
    pub maps: CoefficientMaps,
    /// Distance from the eye along each pixel's view ray, if known.
    pub depth: Option<Vec<f32>>,
}

impl RelightableImage {
    pub fn width(&self) -> usize {
        self.maps.width
    }
    pub fn height(&self) -> usize {
        self.maps.height
    }
}

/// The sizes of a `w × h` image's mip levels, level 0 first: OpenEXR's MIPMAP_LEVELS
/// rounding down, each side halved until both are 1.
pub fn mip_sizes(w: usize, h: usize) -> Vec<(usize, usize)> {
    let count = (usize::BITS - w.max(h).max(1).leading_zeros()) as usize;
    (0..count)
        .map(|l| ((w >> l).max(1), (h >> l).max(1)))
        .collect()
}

/// The means of the 2×2 blocks of a `from`-sized plane at each pixel of a `to`-sized
/// one (rounded-down levels: an odd last row or column is left out; a side of 1 stays
/// 1), over the values `keep` accepts (0 where it accepts none).
pub(crate) fn halve(
    plane: &[f32],
    from: (usize, usize),
    to: (usize, usize),
    keep: fn(f32) -> bool,
) -> Vec<f32> {
    let (w, h) = from;
    let mut out = vec![0.0; to.0 * to.1];
    for y in 0..to.1 {
        for x in 0..to.0 {
            let (mut sum, mut n) = (0.0f64, 0u32);
            for sy in (2 * y..2 * y + 2).filter(|&v| v < h) {
                for sx in (2 * x..2 * x + 2).filter(|&v| v < w) {
                    let v = plane[sy * w + sx];
                    if keep(v) {
                        sum += v as f64;
                        n += 1;
                    }
                }
            }
            if n > 0 {
                out[y * to.0 + x] = (sum / n as f64) as f32;
            }
        }
    }
    out
}

/// The next mip level of `image`, of size `to` (one of [`mip_sizes`] after the
/// image's): the 2×2 means of every coefficient plane, and of the depth's hits.
pub fn halved(image: &RelightableImage, to: (usize, usize)) -> RelightableImage {
    use rayon::prelude::*;
    let maps = &image.maps;
    let from = (maps.width, maps.height);
    let data: Vec<f32> = (0..3 * maps.k)
        .into_par_iter()
        .flat_map_iter(|j| {
            halve(
                &maps.data[j * maps.pixels()..][..maps.pixels()],
                from,
                to,
                f32::is_finite,
            )
        })
        .collect();
    let hit: fn(f32) -> bool = |d| d.is_finite() && d > 0.0;
    RelightableImage {
        meta: image.meta.clone(),
        maps: CoefficientMaps {
            width: to.0,
            height: to.1,
            k: maps.k,
            data,
        },
        depth: image.depth.as_ref().map(|d| halve(d, from, to, hit)),
    }
}

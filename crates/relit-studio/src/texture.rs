//! Albedo textures: procedural patterns and images, looked up by texture coordinates.
//!
//! Texture coordinates of the built-in shapes are in metres along the surface, so a
//! pattern's scale reads as a physical size (a plank 0.2 m wide is `plank_width: 0.2`).
//! Every pattern is a pure function of its coordinates: renders are deterministic.

use crate::math::{v3, V3};
use relit::image::ImageRgb;
use std::sync::Arc;

/// An albedo pattern; each variant is a struct of its own and the enum only forwards.
#[derive(Clone, Debug)]
pub enum Texture {
    Constant(V3),
    Checker(Checker),
    Planks(Planks),
    Bricks(Bricks),
    Plaster(Plaster),
    Image(ImageTexture),
}

impl Texture {
    /// The albedo at texture coordinates `uv`.
    pub fn sample(&self, uv: [f32; 2]) -> V3 {
        match self {
            Texture::Constant(c) => *c,
            Texture::Checker(t) => t.sample(uv),
            Texture::Planks(t) => t.sample(uv),
            Texture::Bricks(t) => t.sample(uv),
            Texture::Plaster(t) => t.sample(uv),
            Texture::Image(t) => t.sample(uv),
        }
    }
}

/// Two colours in squares `size` wide.
#[derive(Clone, Debug)]
pub struct Checker {
    pub a: V3,
    pub b: V3,
    pub size: f32,
}

impl Checker {
    fn sample(&self, uv: [f32; 2]) -> V3 {
        let parity = ((uv[0] / self.size).floor() + (uv[1] / self.size).floor()) as i64 & 1;
        if parity == 0 {
            self.a
        } else {
            self.b
        }
    }
}

/// Wooden floor boards along u: per-board tint, staggered ends, grain and dark seams.
#[derive(Clone, Debug)]
pub struct Planks {
    pub light: V3,
    pub dark: V3,
    pub plank_width: f32,
    pub plank_length: f32,
}

impl Planks {
    fn sample(&self, uv: [f32; 2]) -> V3 {
        let row = (uv[1] / self.plank_width).floor();
        // Stagger the board ends from row to row.
        let along = uv[0] / self.plank_length + hash1(row as i32, 7) * 3.0;
        let board = along.floor();
        let id = hash2(row as i32, board as i32);
        let (fu, fv) = (along - board, uv[1] / self.plank_width - row);
        let seam = fu.min(1.0 - fu) * self.plank_length < 0.004
            || fv.min(1.0 - fv) * self.plank_width < 0.003;
        if seam {
            return self.dark * 0.35;
        }
        let grain_coord = uv[1] * 60.0 + 3.0 * fbm2(uv[0] * 1.5, uv[1] * 8.0 + id * 10.0, 3);
        let grain = 0.5 + 0.5 * (grain_coord * std::f32::consts::TAU).sin();
        let tint = 0.75 + 0.5 * id;
        self.dark
            .lerp(self.light, 0.35 + 0.45 * grain * tint.min(1.0))
            * (0.85 + 0.3 * id)
    }
}

/// A running-bond brick wall: bricks `brick` wide and high, mortar joints `mortar` thick.
#[derive(Clone, Debug)]
pub struct Bricks {
    pub brick: V3,
    pub mortar_color: V3,
    pub size: [f32; 2],
    pub mortar: f32,
}

impl Bricks {
    fn sample(&self, uv: [f32; 2]) -> V3 {
        let row = (uv[1] / self.size[1]).floor();
        let offset = if (row as i64) & 1 == 0 { 0.0 } else { 0.5 };
        let col = (uv[0] / self.size[0] + offset).floor();
        let fu = (uv[0] / self.size[0] + offset - col) * self.size[0];
        let fv = (uv[1] / self.size[1] - row) * self.size[1];
        if fu < self.mortar || fv < self.mortar {
            return self.mortar_color;
        }
        let id = hash2(row as i32, col as i32);
        let speckle = 0.9 + 0.2 * value_noise2(uv[0] * 40.0, uv[1] * 40.0);
        self.brick * ((0.75 + 0.45 * id) * speckle)
    }
}

/// A painted or plastered surface: a base colour with soft blotches.
#[derive(Clone, Debug)]
pub struct Plaster {
    pub color: V3,
    /// Relative strength of the blotches (0 = flat).
    pub variation: f32,
    pub scale: f32,
}

impl Plaster {
    fn sample(&self, uv: [f32; 2]) -> V3 {
        let n = fbm2(uv[0] / self.scale, uv[1] / self.scale, 4);
        self.color * (1.0 + self.variation * (2.0 * n - 1.0))
    }
}

/// A linear RGB image wrapped over `[0, 1)²` (v = 0 at the bottom row, as in OBJ files),
/// sampled bilinearly with repeat.
#[derive(Clone, Debug)]
pub struct ImageTexture {
    pub image: Arc<ImageRgb>,
}

impl ImageTexture {
    fn texel(&self, x: i64, y: i64) -> V3 {
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        let (x, y) = (x.rem_euclid(w) as usize, y.rem_euclid(h) as usize);
        V3::from(self.image.get(x, y))
    }

    fn sample(&self, uv: [f32; 2]) -> V3 {
        if self.image.width == 0
            || self.image.height == 0
            || !(uv[0].is_finite() && uv[1].is_finite())
        {
            return V3::splat(0.5);
        }
        let x = uv[0] * self.image.width as f32 - 0.5;
        let y = (1.0 - uv[1]) * self.image.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let bottom = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// A pseudo-random number in `[0, 1)` for an integer pair (a stable hash, not a PRNG).
pub fn hash2(a: i32, b: i32) -> f32 {
    let mut h = (a as u32).wrapping_mul(0x8da6_b343) ^ (b as u32).wrapping_mul(0xd816_3841);
    h ^= h >> 13;
    h = h.wrapping_mul(0x5bd1_e995);
    h ^= h >> 15;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// [`hash2`] of one integer and a salt.
pub fn hash1(a: i32, salt: i32) -> f32 {
    hash2(a, salt.wrapping_mul(977))
}

/// Smooth value noise in `[0, 1]`.
pub fn value_noise2(x: f32, y: f32) -> f32 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let (i, j) = (x0 as i32, y0 as i32);
    let top = hash2(i, j) + (hash2(i + 1, j) - hash2(i, j)) * sx;
    let bottom = hash2(i, j + 1) + (hash2(i + 1, j + 1) - hash2(i, j + 1)) * sx;
    top + (bottom - top) * sy
}

/// Fractal sum of `octaves` octaves of value noise, in `[0, 1]`.
pub fn fbm2(x: f32, y: f32, octaves: u32) -> f32 {
    let (mut sum, mut amplitude, mut norm, mut f) = (0.0, 1.0, 0.0, 1.0);
    for _ in 0..octaves {
        sum += amplitude * value_noise2(x * f, y * f);
        norm += amplitude;
        amplitude *= 0.5;
        f *= 2.03;
    }
    sum / norm
}

/// An sRGB-ish colour from 0–255 components, converted to linear albedo (for readable
/// scene code: `rgb8(180, 140, 100)` is the tan one sees in a colour picker).
pub fn rgb8(r: u8, g: u8, b: u8) -> V3 {
    let f = |c: u8| relit::color::srgb_to_linear(c as f32 / 255.0);
    v3(f(r), f(g), f(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_stay_in_range_and_are_deterministic() {
        let planks = Texture::Planks(Planks {
            light: v3(0.6, 0.4, 0.2),
            dark: v3(0.3, 0.2, 0.1),
            plank_width: 0.2,
            plank_length: 1.5,
        });
        let bricks = Texture::Bricks(Bricks {
            brick: v3(0.5, 0.2, 0.1),
            mortar_color: V3::splat(0.6),
            size: [0.25, 0.08],
            mortar: 0.01,
        });
        let plaster = Texture::Plaster(Plaster {
            color: V3::splat(0.7),
            variation: 0.1,
            scale: 0.5,
        });
        for t in [&planks, &bricks, &plaster] {
            for k in 0..500 {
                let uv = [k as f32 * 0.0137 - 3.0, k as f32 * 0.0291 - 2.0];
                let a = t.sample(uv);
                assert!(
                    a.is_finite() && a.x >= 0.0 && a.max_component() <= 1.0,
                    "{a:?}"
                );
                assert_eq!(a, t.sample(uv));
            }
        }
        let mut img = ImageRgb::new(2, 1);
        img.data = vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        let tex = Texture::Image(ImageTexture {
            image: Arc::new(img),
        });
        assert_eq!(tex.sample([0.25, 0.5]), v3(1.0, 0.0, 0.0));
        assert_eq!(tex.sample([1.75, 0.5]), v3(0.0, 0.0, 1.0), "repeats");
    }
}

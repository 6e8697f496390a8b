//! Materials: a Lambertian base with a texture and a normalised Blinn–Phong glossy lobe.
//!
//! Radiometric units follow relit's captures: a unit directional light makes a white
//! Lambertian surface facing it read exactly 1 (the light's irradiance is π in
//! physical units, so the 1/π of the BRDF cancels). The reflected radiance for unit
//! light from `wi` seen from `wo` is therefore
//!
//! ```text
//! L = cos θi · (albedo + specular · (s + 8)/8 · (n·h)^s),   h = (wi + wo)/|wi + wo|
//! ```
//!
//! where `(s + 8)/(8π)` normalises the Blinn–Phong lobe (Akenine-Möller et al., *Real-Time
//! Rendering*), so `specular` is roughly the fraction of light the lobe reflects and the
//! highlight sharpens without brightening as the exponent `s` grows.

use crate::math::V3;
use crate::texture::Texture;
use relit::{Error, ErrorKind, Result};

/// How a surface reflects light.
#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    /// Diffuse albedo (linear RGB, each component in [0, 1]).
    pub albedo: Texture,
    /// Strength of the glossy lobe, 0 for matte surfaces.
    pub specular: f32,
    /// Blinn–Phong exponent: 10 is a broad sheen, 200 a tight highlight.
    pub shininess: f32,
    /// Whether the surface blocks light. The shell of an interior scene (walls, roof)
    /// may let directional light through so that light from any direction reaches the
    /// room, as in the seed's attic renders, while the furniture still casts shadows.
    pub casts_shadows: bool,
}

impl Material {
    /// A matte material.
    pub fn matte(name: &str, albedo: Texture) -> Material {
        Material {
            name: name.into(),
            albedo,
            specular: 0.0,
            shininess: 1.0,
            casts_shadows: true,
        }
    }

    /// A material with a glossy lobe.
    pub fn glossy(name: &str, albedo: Texture, specular: f32, shininess: f32) -> Material {
        Material {
            name: name.into(),
            albedo,
            specular,
            shininess,
            casts_shadows: true,
        }
    }

    /// The same material, letting light through (see [`Material::casts_shadows`]).
    pub fn without_shadows(mut self) -> Material {
        self.casts_shadows = false;
        self
    }

    /// Check the parameters.
    pub fn validate(&self) -> Result<()> {
        if !(self.specular.is_finite() && (0.0..=1.0).contains(&self.specular)) {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!("material `{}`: specular must be in [0, 1]", self.name),
            ));
        }
        if !(self.shininess.is_finite() && self.shininess >= 0.0 && self.shininess <= 1e5) {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!("material `{}`: shininess must be in [0, 100000]", self.name),
            ));
        }
        if let Texture::Constant(c) = self.albedo {
            if !(c.is_finite() && c.x >= 0.0 && c.y >= 0.0 && c.z >= 0.0) {
                return Err(Error::new(
                    ErrorKind::InvalidInput,
                    format!(
                        "material `{}`: albedo must be finite and non-negative",
                        self.name
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// The reflectance of one shading point, with its texture already looked up.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reflectance {
    pub albedo: V3,
    pub specular: f32,
    pub shininess: f32,
}

impl Reflectance {
    /// Radiance toward `wo` for unit light from `wi` (unit vectors; `n` the unit
    /// shading normal on the viewer's side), cosine included; zero below the horizon.
    #[inline]
    pub fn reflect(&self, n: V3, wo: V3, wi: V3) -> V3 {
        let cos_i = n.dot(wi);
        if cos_i <= 0.0 {
            return V3::ZERO;
        }
        let mut value = self.albedo;
        if self.specular > 0.0 {
            let h = (wi + wo).normalized();
            let cos_h = n.dot(h).max(0.0);
            let lobe = self.specular * (self.shininess + 8.0) / 8.0 * cos_h.powf(self.shininess);
            value += V3::splat(lobe);
        }
        value * cos_i
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::v3;

    #[test]
    fn unit_light_on_white_lambert_reads_cosine() {
        let white = Reflectance {
            albedo: V3::splat(1.0),
            specular: 0.0,
            shininess: 1.0,
        };
        let n = v3(0.0, 0.0, 1.0);
        assert_eq!(white.reflect(n, n, n), V3::splat(1.0));
        let wi = v3(0.6, 0.0, 0.8);
        assert!((white.reflect(n, n, wi).x - 0.8).abs() < 1e-6);
        assert_eq!(white.reflect(n, n, v3(0.0, 0.6, -0.8)), V3::ZERO);
    }

    #[test]
    fn glossy_lobe_peaks_at_the_mirror_direction() {
        let gloss = Reflectance {
            albedo: V3::ZERO,
            specular: 0.5,
            shininess: 100.0,
        };
        let n = v3(0.0, 0.0, 1.0);
        let wo = v3(0.6, 0.0, 0.8);
        let mirror = v3(-0.6, 0.0, 0.8);
        let off = v3(-0.2, 0.0, 1.0).normalized();
        assert!(gloss.reflect(n, wo, mirror).x > 10.0 * gloss.reflect(n, wo, off).x);
        assert!(
            Material::glossy("x", Texture::Constant(V3::splat(0.5)), 1.5, 10.0)
                .validate()
                .is_err()
        );
    }
}

//! Spherical Gaussian kernels (SGKF): seed 002, Ho et al., "GPU-friendly rendering for
//! illumination adjustable images".
//!
//! The seed approximates a pixel's response by a weighted sum of spherical Gaussian
//! kernels with nodes spread uniformly over the sphere of light directions, and compares
//! it with SH at equal numbers of lightmaps (the text we hold gives the form, not a rule
//! for the kernels' width). Here a basis of K functions is a constant plus K−1 lobes
//!
//! ```text
//!   G_i(L) = exp(s·(μ_i·L − 1))
//! ```
//!
//! (1 at the centre `μ_i`, `exp(−2s)` opposite) with **one sharpness `s` for all lobes**:
//! equal lobes on an even layout leave no direction favoured. The constant carries the
//! mean level that overlapping lobes could only build as a bumpy sum.
//!
//! **Centres** are a Fibonacci lattice of K−1 points over the whole sphere, or over the
//! upper hemisphere when every captured light is above the horizon (an RTI dome,
//! [`BuildContext::hemisphere_only`]). Lobes where no light ever shone are set by the
//! regulariser alone and make the fit fragile: RealRTI item7 (a dome whose lowest light
//! is 0.07° below the horizon) scored 22.2 dB with whole-sphere centres at width 1.5,
//! 34.0 with hemisphere centres. Hemisphere bases declare [`Domain::UpperHemisphere`];
//! below the horizon the lobes simply decay, their own continuation.
//!
//! **Sharpness rule.** With `d̄` the mean angle from each centre to its nearest
//! neighbour, `s` makes every lobe fall to half its peak at `width·d̄`:
//! `exp(s·(cos(width·d̄) − 1)) = ½`, `width` = 1 by default. Neighbouring lobes then
//! cross at half height, the overlap that lets a sum of lobes follow a smooth response
//! between centres without a dip; wider lobes make the functions nearly dependent. On
//! the peer protocol (five hold-outs, sRGB PSNR) `sg:25` scored, for width 0.5 / 1 /
//! 1.5 / 2: item1 33.8 / 36.3 / 36.2 / 29.6, item2 29.1 / 36.3 / 36.5 / 25.4, item5
//! 22.1 / 26.1 / 26.2 / 22.3 (item1 36.4 and item7 32.4 at 0.75, item7 34.2 at 1).
//! For K = 9, 16, 25, 36, 49, 64 the rule gives
//! `s` = 2.1, 3.8, 6.1, 8.7, 11.8, 15.7 on the hemisphere (spacing 48° down to 17°) and
//! 1.2, 2.0, 3.1, 4.4, 6.1, 7.9 on the sphere.
//!
//! Options: `centres=sphere|hemisphere`, `sharpness=S` (replaces the rule),
//! `width=F` (the rule's factor), `constant=false` (K lobes, no constant). The spec
//! stores the centres, `s`, the constant flag and the domain, so a stored basis rebuilds
//! exactly whatever rule made it.
//!
//! The fit regularises with the basis' roughness (the numerical mean squared gradient,
//! sampled finely enough for the lobes' width); `--regularizer ridge` is the plain ridge
//! alternative.

use super::{Basis, BasisSpec, BuildContext, Domain, Family};
use crate::sphere::Vec3;
use crate::{Error, Result};

/// The `sg` family: `sg:K`, K a square from 4 to 64, to compare with SH at equal K.
pub(super) struct SgFamily;

pub(super) static FAMILY: SgFamily = SgFamily;

/// The most functions a basis may have, as for the other families.
const MAX_K: usize = 64;

/// A unit vector read back from a spec is a unit vector to this tolerance.
const UNIT_TOLERANCE: f64 = 1e-9;

/// The lobe value at `width` nearest-neighbour spacings.
const FALLOFF_AT_WIDTH: f64 = 0.5;

impl Family for SgFamily {
    fn name(&self) -> &'static str {
        "sg"
    }

    fn summary(&self) -> &'static str {
        "spherical Gaussian lobes with one sharpness, plus a constant (K = 4, 9, …, 64)"
    }

    fn sizes(&self, max: usize) -> Vec<usize> {
        (2..=8).map(|n| n * n).filter(|&k| k <= max).collect()
    }

    fn option_keys(&self) -> &'static [&'static str] {
        &["centres", "sharpness", "width", "constant"]
    }

    fn build(&self, k: usize, context: &BuildContext) -> Result<Box<dyn Basis>> {
        if !(1..=MAX_K).contains(&k) {
            return Err(Error::invalid(format!(
                "spherical Gaussians take 1 to {MAX_K} functions, not {k}"
            )));
        }
        let domain = match context.options.get("centres").map(String::as_str) {
            None if context.hemisphere_only() => Domain::UpperHemisphere,
            None | Some("sphere") => Domain::Sphere,
            Some("hemisphere") => Domain::UpperHemisphere,
            Some(other) => {
                return Err(Error::parse(format!(
                    "bad basis option `centres={other}`: sphere or hemisphere"
                )))
            }
        };
        let constant: bool = context.option("constant", true)?;
        let lobes = k - usize::from(constant);
        if lobes == 0 {
            return Err(Error::invalid("spherical Gaussians need at least one lobe"));
        }
        let lattice = match domain {
            Domain::Sphere => crate::sphere::fibonacci(lobes),
            Domain::UpperHemisphere => crate::sphere::hemisphere_fibonacci(lobes),
        };
        let centres: Vec<Vec3> = lattice
            .iter()
            .map(|c| Vec3::new(short(c.x), short(c.y), short(c.z)))
            .collect();
        let width = optional_number(context, "width")?;
        let sharpness = optional_number(context, "sharpness")?;
        let sharpness = match (sharpness, width) {
            (Some(_), Some(_)) => {
                return Err(Error::parse(
                    "give the spherical Gaussians a `sharpness` or a `width`, not both",
                ))
            }
            (Some(s), None) => short_relative(s),
            (None, w) => {
                let w = w.unwrap_or(1.0);
                if !(w.is_finite() && w > 0.0) {
                    return Err(Error::invalid(format!(
                        "the lobe width must be a positive number of spacings, not {w}"
                    )));
                }
                short_relative(sharpness_for_width(&centres, domain, w))
            }
        };
        Ok(Box::new(SphericalGaussians::new(
            centres, sharpness, constant, domain,
        )?))
    }

    fn rebuild(
        &self,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Box<dyn Basis>> {
        const KEYS: [&str; 4] = ["centres", "sharpness", "constant", "domain"];
        if let Some(key) = params.keys().find(|k| !KEYS.contains(&k.as_str())) {
            return Err(Error::parse(format!(
                "an `sg` basis has no parameter `{key}` (it has {KEYS:?})"
            )));
        }
        let list = params
            .get("centres")
            .and_then(|v| v.as_array())
            .ok_or_else(|| Error::parse("an `sg` basis needs `centres`, a list of [x, y, z]"))?;
        let mut centres = Vec::with_capacity(list.len());
        for (i, c) in list.iter().enumerate() {
            let xyz: Vec<f64> = c
                .as_array()
                .map(|a| a.iter().filter_map(|v| v.as_f64()).collect())
                .unwrap_or_default();
            if xyz.len() != 3 || c.as_array().map_or(0, |a| a.len()) != 3 {
                return Err(Error::parse(format!(
                    "`sg` centre {i} is not three numbers: {c}"
                )));
            }
            centres.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
        }
        let sharpness = params
            .get("sharpness")
            .and_then(|v| v.as_f64())
            .ok_or_else(|| Error::parse("an `sg` basis needs a number `sharpness`"))?;
        let constant = params
            .get("constant")
            .and_then(|v| v.as_bool())
            .ok_or_else(|| Error::parse("an `sg` basis needs a boolean `constant`"))?;
        let domain = match params.get("domain").and_then(|v| v.as_str()) {
            Some("sphere") => Domain::Sphere,
            Some("hemisphere") => Domain::UpperHemisphere,
            _ => {
                return Err(Error::parse(
                    "an `sg` basis needs `domain`: \"sphere\" or \"hemisphere\"",
                ))
            }
        };
        Ok(Box::new(SphericalGaussians::new(
            centres, sharpness, constant, domain,
        )?))
    }
}

/// `v` to 12 decimals: a number whose shortest decimal form every JSON reader turns back
/// into the same bits (a 12-digit integer over 10¹² is one correctly rounded division;
/// longer forms are not read exactly by every reader, serde_json's default among them).
/// The spec then rebuilds the very functions the maps were fitted with.
fn short(v: f64) -> f64 {
    const SCALE: f64 = 1e12;
    (v * SCALE).round() / SCALE
}

/// `v` to 12 significant digits, for the same reason as [`short`].
fn short_relative(v: f64) -> f64 {
    format!("{v:.11e}").parse().unwrap_or(v)
}

/// A number option that may be absent.
fn optional_number(context: &BuildContext, key: &str) -> Result<Option<f64>> {
    context
        .options
        .get(key)
        .map(|v| {
            v.parse()
                .map_err(|_| Error::parse(format!("bad basis option `{key}={v}`: a number")))
        })
        .transpose()
}

/// The mean angle (radians) from each centre to its nearest neighbour; for a single
/// centre, the spacing one point would have on `domain`.
pub fn mean_nearest_angle(centres: &[Vec3], domain: Domain) -> f64 {
    if centres.len() < 2 {
        return match domain {
            Domain::Sphere => std::f64::consts::PI,
            Domain::UpperHemisphere => std::f64::consts::FRAC_PI_2,
        };
    }
    let total: f64 = centres
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let nearest = centres
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, b)| a.dot(*b))
                .fold(-1.0f64, f64::max);
            nearest.clamp(-1.0, 1.0).acos()
        })
        .sum();
    total / centres.len() as f64
}

/// The sharpness at which a lobe falls to half its peak at `width` mean nearest-neighbour
/// spacings of `centres` (the rule in the module docs).
pub fn sharpness_for_width(centres: &[Vec3], domain: Domain, width: f64) -> f64 {
    let angle = (width * mean_nearest_angle(centres, domain)).min(std::f64::consts::PI);
    -FALLOFF_AT_WIDTH.ln() / (1.0 - angle.cos())
}

/// A constant (optionally) and one lobe per centre, all of one sharpness.
#[derive(Clone, Debug)]
pub struct SphericalGaussians {
    centres: Vec<Vec3>,
    sharpness: f64,
    constant: bool,
    domain: Domain,
}

impl SphericalGaussians {
    /// Lobes at the unit vectors `centres` (after the constant, if `constant`).
    pub fn new(centres: Vec<Vec3>, sharpness: f64, constant: bool, domain: Domain) -> Result<Self> {
        let k = centres.len() + usize::from(constant);
        if centres.is_empty() || k > MAX_K {
            return Err(Error::invalid(format!(
                "spherical Gaussians take 1 to {MAX_K} functions with at least one lobe, \
                 not {} lobes{}",
                centres.len(),
                if constant { " and a constant" } else { "" }
            )));
        }
        for (i, c) in centres.iter().enumerate() {
            if !c.is_finite() || (c.length() - 1.0).abs() > UNIT_TOLERANCE {
                return Err(Error::invalid(format!(
                    "spherical Gaussian centre {i} {:?} is not a unit vector",
                    [c.x, c.y, c.z]
                )));
            }
        }
        if !(sharpness.is_finite() && sharpness > 0.0) {
            return Err(Error::invalid(format!(
                "spherical Gaussians need a positive sharpness, not {sharpness}"
            )));
        }
        Ok(Self {
            centres,
            sharpness,
            constant,
            domain,
        })
    }

    /// The lobes' centres.
    pub fn centres(&self) -> &[Vec3] {
        &self.centres
    }

    /// The lobes' shared sharpness `s`.
    pub fn sharpness(&self) -> f64 {
        self.sharpness
    }
}

impl Basis for SphericalGaussians {
    fn spec(&self) -> BasisSpec {
        let centres: Vec<[f64; 3]> = self.centres.iter().map(|&c| c.into()).collect();
        let domain = match self.domain {
            Domain::Sphere => "sphere",
            Domain::UpperHemisphere => "hemisphere",
        };
        BasisSpec::new(
            "sg",
            serde_json::json!({
                "centres": centres,
                "sharpness": self.sharpness,
                "constant": self.constant,
                "domain": domain,
            }),
        )
    }

    fn family(&self) -> &'static str {
        "sg"
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn len(&self) -> usize {
        self.centres.len() + usize::from(self.constant)
    }

    fn domain(&self) -> Domain {
        self.domain
    }

    fn eval(&self, dir: Vec3, out: &mut [f64]) {
        let lobes = if self.constant {
            out[0] = 1.0;
            &mut out[1..self.len()]
        } else {
            &mut out[..self.len()]
        };
        for (o, c) in lobes.iter_mut().zip(&self.centres) {
            *o = (self.sharpness * (c.dot(dir) - 1.0)).exp();
        }
    }

    /// Ridge on the lobes (the constant is free), as seed 002 regularises its kernel
    /// weights: overlapping lobes trade weight among themselves freely, which a ridge
    /// stops, while the roughness penalty let them grow opposite and large. Measured on
    /// the RealRTI items at `sg:25`: ridge beats the roughness penalty on 7 of 8 items,
    /// by 0.5 dB on average (31.56 against 31.04 dB, peer protocol).
    fn penalty(&self) -> Vec<f64> {
        let k = self.len();
        let mut p = vec![0.0; k * k];
        let first_lobe = usize::from(self.constant);
        for i in first_lobe..k {
            p[i * k + i] = 1.0 / (4.0 * std::f64::consts::PI);
        }
        p
    }

    fn label(&self, i: usize) -> String {
        match (self.constant, i) {
            (true, 0) => "1".to_string(),
            (true, i) => format!("g{}", i - 1),
            (false, i) => format!("g{i}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn build(k: usize, directions: &[Vec3], options: &[(&str, &str)]) -> Result<Box<dyn Basis>> {
        let options: BTreeMap<String, String> = options
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        FAMILY.build(
            k,
            &BuildContext {
                directions,
                samples: None,
                options: &options,
            },
        )
    }

    /// Centres and sharpness are stored to 12 digits, so a lobe is 1 at its centre and
    /// ½ at the spacing to within a few times `s·1e-12`.
    const STORED_DIGITS: f64 = 1e-10;

    fn as_sg(b: &dyn Basis) -> &SphericalGaussians {
        b.as_any().downcast_ref().unwrap()
    }

    #[test]
    fn values_at_a_centre_and_opposite() {
        let b = build(16, &crate::sphere::fibonacci(40), &[]).unwrap();
        let sg = as_sg(&*b);
        assert_eq!(sg.centres().len(), 15);
        let s = sg.sharpness();
        for (i, &c) in sg.centres().iter().enumerate() {
            let v = b.values(c);
            assert_eq!(v[0], 1.0);
            assert!((v[i + 1] - 1.0).abs() < STORED_DIGITS);
            // Every other lobe is below its peak there.
            assert!(v[1..].iter().enumerate().all(|(j, &g)| j == i || g < 1.0));
            let far = b.values(-c);
            assert!((far[i + 1] - (-2.0 * s).exp()).abs() < STORED_DIGITS);
        }
    }

    #[test]
    fn the_rule_puts_half_height_at_the_mean_spacing() {
        for k in FAMILY.sizes(64) {
            for (dirs, domain) in [
                (crate::sphere::fibonacci(30), Domain::Sphere),
                (
                    crate::sphere::hemisphere_fibonacci(30),
                    Domain::UpperHemisphere,
                ),
            ] {
                let b = build(k, &dirs, &[]).unwrap();
                let sg = as_sg(&*b);
                assert_eq!(b.domain(), domain);
                assert_eq!(b.len(), k);
                let d = mean_nearest_angle(sg.centres(), domain);
                let g = (sg.sharpness() * (d.cos() - 1.0)).exp();
                assert!((g - 0.5).abs() < STORED_DIGITS, "k={k}: {g}");
                if domain == Domain::UpperHemisphere {
                    assert!(sg.centres().iter().all(|c| c.z > 0.0));
                }
            }
        }
        // More lobes are sharper.
        let dirs = crate::sphere::hemisphere_fibonacci(30);
        let s: Vec<f64> = FAMILY
            .sizes(64)
            .into_iter()
            .map(|k| as_sg(&*build(k, &dirs, &[]).unwrap()).sharpness())
            .collect();
        assert!(s.windows(2).all(|w| w[0] < w[1]), "{s:?}");
    }

    #[test]
    fn a_dome_with_a_light_just_below_the_horizon_is_still_a_dome() {
        let mut dome = crate::sphere::hemisphere_fibonacci(30);
        dome.push(Vec3::new(1.0, 0.0, -0.0012).normalized().unwrap());
        assert_eq!(
            build(25, &dome, &[]).unwrap().domain(),
            Domain::UpperHemisphere
        );
        dome.push(Vec3::new(0.0, 1.0, -0.5).normalized().unwrap());
        assert_eq!(build(25, &dome, &[]).unwrap().domain(), Domain::Sphere);
    }

    #[test]
    fn options_change_the_basis_and_are_checked() {
        let dome = crate::sphere::hemisphere_fibonacci(30);
        let b = build(25, &dome, &[("centres", "sphere"), ("sharpness", "8")]).unwrap();
        assert_eq!(b.domain(), Domain::Sphere);
        assert_eq!(as_sg(&*b).sharpness(), 8.0);
        let wide = build(25, &dome, &[("width", "2")]).unwrap();
        let default = build(25, &dome, &[]).unwrap();
        assert!(as_sg(&*wide).sharpness() < as_sg(&*default).sharpness());
        let lobes_only = build(25, &dome, &[("constant", "false")]).unwrap();
        assert_eq!(as_sg(&*lobes_only).centres().len(), 25);
        assert_eq!(lobes_only.label(0), "g0");
        for bad in [
            [("centres", "cube")],
            [("sharpness", "-1")],
            [("sharpness", "x")],
            [("width", "0")],
            [("constant", "maybe")],
        ] {
            assert!(build(25, &dome, &bad).is_err(), "{bad:?}");
        }
        assert!(build(25, &dome, &[("sharpness", "8"), ("width", "1")]).is_err());
        let parsed = crate::basis::BasisChoice::parse("sg:25:centres=hemisphere,sharpness=8")
            .unwrap()
            .build(&[], None)
            .unwrap();
        assert_eq!(parsed.domain(), Domain::UpperHemisphere);
    }

    #[test]
    fn weight_tables_of_at_most_256_reproduce_every_default_size() {
        use crate::basis::table::{WeightTable, TABLE_TOLERANCE};
        // Measured: 32 to 128 cells on the sphere, 64 to 256 on the hemisphere (sg:49
        // and sg:64, s ≈ 12 and 16). The cells needed grow like √s: a sharper lobe set
        // by `sharpness=` may need 512.
        for dirs in [
            crate::sphere::fibonacci(30),
            crate::sphere::hemisphere_fibonacci(30),
        ] {
            for k in FAMILY.sizes(64) {
                let b = build(k, &dirs, &[]).unwrap();
                let (table, accuracy) = WeightTable::for_basis(&*b);
                assert!(table.resolution <= 256, "sg:{k} {accuracy:?}");
                assert!(accuracy.relative_rms <= TABLE_TOLERANCE);
            }
        }
    }

    #[test]
    fn the_spec_round_trips_exactly_and_rebuild_is_strict() {
        let dome = crate::sphere::hemisphere_fibonacci(30);
        let b = build(36, &dome, &[("width", "1.3")]).unwrap();
        let json = serde_json::to_string(&b.spec()).unwrap();
        let spec: BasisSpec = serde_json::from_str(&json).unwrap();
        let again = spec.build().unwrap();
        assert_eq!(again.domain(), Domain::UpperHemisphere);
        assert_eq!(as_sg(&*again).centres(), as_sg(&*b).centres());
        assert_eq!(as_sg(&*again).sharpness(), as_sg(&*b).sharpness());
        for d in crate::sphere::fibonacci(50) {
            assert_eq!(again.values(d), b.values(d));
        }
        // A spec written by hand rebuilds as written, whatever the rule would say.
        let hand = serde_json::json!({
            "centres": [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]],
            "sharpness": 3.0, "constant": false, "domain": "sphere"
        });
        let b = BasisSpec::new("sg", hand.clone()).build().unwrap();
        assert_eq!(b.len(), 2);
        assert!((b.values(Vec3::new(0.0, 1.0, 0.0))[0] - (-3.0f64).exp()).abs() < 1e-15);
        let broken = |key: &str, value: serde_json::Value| {
            let mut v = hand.clone();
            v[key] = value;
            BasisSpec::new("sg", v).build().is_err()
        };
        assert!(broken("centres", serde_json::json!([[0.0, 0.0, 2.0]])));
        assert!(broken("centres", serde_json::json!([[0.0, 1.0]])));
        assert!(broken("centres", serde_json::json!([])));
        assert!(broken("centres", serde_json::json!("fibonacci")));
        assert!(broken("sharpness", serde_json::json!(0.0)));
        assert!(broken("constant", serde_json::json!(1)));
        assert!(broken("domain", serde_json::json!("cube")));
        assert!(broken("width", serde_json::json!(1.0)));
    }
}

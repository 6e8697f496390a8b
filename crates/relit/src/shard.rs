//! Sharded fits: the bands of rows that `fit` wrote part by part
//! ([`crate::fit::FitOptions::shard`]), joined back into one relightable image.
//!
//! Every part makes the whole image's choices (basis and its tables, objective, λ) on
//! the whole image's pixel subsample, and each pixel's coefficients depend only on that
//! pixel's samples, so the joined maps are the single fit's maps value for value. The
//! join therefore refuses parts that were fitted differently: a part of another capture
//! or of other options would otherwise leave a seam no one sees until it is relit.

use crate::error::{Error, Result};
use crate::maps::{CoefficientMaps, FitInfo, RelightableImage, ShardInfo};

/// The shard description of a part, or why it is not one.
fn shard_of(part: &RelightableImage, name: &str) -> Result<ShardInfo> {
    part.meta.fit.as_ref().and_then(|f| f.shard).ok_or_else(|| {
        Error::invalid(format!(
            "{name} is not a part of a sharded fit (no shard in its fit metadata; \
                 write parts with `relit fit --tile i/N`)"
        ))
    })
}

/// The metadata a part shares with every other part: its own timing, residual and
/// place left out.
fn shared_fit(fit: &FitInfo) -> FitInfo {
    FitInfo {
        rmse_linear: [0.0; 3],
        psnr_srgb8: 0.0,
        seconds: 0.0,
        shard: None,
        ..fit.clone()
    }
}

/// Joins the parts of one sharded fit as they arrive, one at a time: memory for the
/// whole image's maps and the part at hand, not for every part at once.
pub struct Merger {
    /// The first part's description, metadata and name: what every other part must share.
    head: ShardInfo,
    meta: crate::maps::Metadata,
    first: String,
    maps: CoefficientMaps,
    depth: Option<Vec<f32>>,
    /// Which file filled each part.
    slots: Vec<Option<String>>,
    /// Each part's rows and fit information, for the pooled residual and time.
    fits: Vec<(usize, FitInfo)>,
}

impl Merger {
    /// Start from `first` (named `name` in messages), of a fit in `expected` parts: the
    /// number of files given, which bounds what the parts' metadata may claim before
    /// anything is allocated from it.
    pub fn new(first: RelightableImage, name: &str, expected: usize) -> Result<Merger> {
        let head = shard_of(&first, name)?;
        if head.count != expected {
            return Err(Error::invalid(format!(
                "{name} is part {} of {}, but {expected} part{} given",
                head.index,
                head.count,
                if expected == 1 { " was" } else { "s were" }
            )));
        }
        check_place(&first, head, name)?;
        // full_height is now bounded by the part's real rows: ⌈H/N⌉ rows a part.
        let (width, k) = (first.width(), first.maps.k);
        let mut merger = Merger {
            head,
            meta: first.meta.clone(),
            first: name.to_string(),
            maps: CoefficientMaps::zeros(width, head.full_height, k),
            depth: first
                .depth
                .as_ref()
                .map(|_| vec![0.0; width * head.full_height]),
            slots: vec![None; head.count],
            fits: Vec::new(),
        };
        merger.place(first, head, name);
        Ok(merger)
    }

    /// Add another part (in any order).
    pub fn add(&mut self, part: RelightableImage, name: &str) -> Result<()> {
        let shard = shard_of(&part, name)?;
        let head = self.head;
        if shard.count != head.count || shard.full_height != head.full_height {
            return Err(Error::invalid(format!(
                "{name} is part {} of {} of an image {} rows tall, {} part {} of {} of {} rows: \
                 they are not parts of one fit",
                shard.index,
                shard.count,
                shard.full_height,
                self.first,
                head.index,
                head.count,
                head.full_height
            )));
        }
        check_place(&part, shard, name)?;
        if part.width() != self.maps.width || part.maps.k != self.maps.k {
            return Err(Error::invalid(format!(
                "{name} is {} pixels wide with {} coefficients, {} {} with {}",
                part.width(),
                part.maps.k,
                self.first,
                self.maps.width,
                self.maps.k
            )));
        }
        let differs = |what: &str| {
            Error::invalid(format!(
                "{name} was fitted with another {what} than {}: parts of one fit share every \
                 choice (re-fit the parts with the same capture and options)",
                self.first
            ))
        };
        if part.meta.basis != self.meta.basis {
            return Err(differs("basis"));
        }
        if part.meta.fit.as_ref().map(shared_fit) != self.meta.fit.as_ref().map(shared_fit) {
            return Err(differs("objective, λ or image count"));
        }
        let mut meta = part.meta.clone();
        meta.fit.clone_from(&self.meta.fit);
        if meta != self.meta {
            return Err(differs("colour space, projection or camera"));
        }
        if part.depth.is_some() != self.depth.is_some() {
            return Err(differs("depth map (one has it, the other not)"));
        }
        if let Some(other) = &self.slots[shard.index] {
            return Err(Error::invalid(format!(
                "{other} and {name} are both part {} of {}",
                shard.index, shard.count
            )));
        }
        self.place(part, shard, name);
        Ok(())
    }

    /// Copy a checked part into its rows.
    fn place(&mut self, part: RelightableImage, shard: ShardInfo, name: &str) {
        let rows = shard.rows();
        let width = self.maps.width;
        let plane_len = width * self.head.full_height;
        let n = part.maps.pixels();
        for (plane, out) in self.maps.data.chunks_exact_mut(plane_len).enumerate() {
            out[rows.start * width..rows.end * width]
                .copy_from_slice(&part.maps.data[plane * n..(plane + 1) * n]);
        }
        if let (Some(depth), Some(src)) = (self.depth.as_mut(), part.depth.as_ref()) {
            depth[rows.start * width..rows.end * width].copy_from_slice(src);
        }
        self.slots[shard.index] = Some(name.to_string());
        if let Some(fit) = part.meta.fit {
            self.fits.push((rows.len(), fit));
        }
    }

    /// The whole image, once every part is in.
    pub fn finish(self) -> Result<RelightableImage> {
        let missing: Vec<String> = (0..self.head.count)
            .filter(|&s| self.slots[s].is_none())
            .map(|s| s.to_string())
            .collect();
        if !missing.is_empty() {
            return Err(Error::invalid(format!(
                "part{} {} of {} missing",
                if missing.len() > 1 { "s" } else { "" },
                missing.join(", "),
                self.head.count
            )));
        }
        let mut meta = self.meta;
        if let Some(fit) = meta.fit.as_mut() {
            // The residual pooled over the parts that measured one (each measures the
            // subsample pixels in its rows), weighted by their rows; the time is the total.
            let measured: Vec<&(usize, FitInfo)> = self
                .fits
                .iter()
                .filter(|(_, f)| f.psnr_srgb8 > 0.0)
                .collect();
            let rows: f64 = measured.iter().map(|(r, _)| *r as f64).sum();
            if rows > 0.0 {
                for c in 0..3 {
                    let mse: f64 = measured
                        .iter()
                        .map(|(r, f)| *r as f64 * f.rmse_linear[c].powi(2))
                        .sum();
                    fit.rmse_linear[c] = (mse / rows).sqrt();
                }
                let mse8: f64 = measured
                    .iter()
                    .map(|(r, f)| *r as f64 * 10f64.powf(-f.psnr_srgb8 / 10.0))
                    .sum();
                fit.psnr_srgb8 = -10.0 * (mse8 / rows).log10();
            }
            fit.seconds = self.fits.iter().map(|(_, f)| f.seconds).sum();
            fit.shard = None;
        }
        Ok(RelightableImage {
            meta,
            maps: self.maps,
            depth: self.depth,
        })
    }
}

/// That `part` holds the rows its shard description gives it.
fn check_place(part: &RelightableImage, shard: ShardInfo, name: &str) -> Result<()> {
    let expected = ShardInfo::new(shard.index, shard.count, shard.full_height)
        .map_err(|e| Error::invalid(format!("{name}: {e}")))?;
    if shard != expected || part.height() != shard.rows().len() {
        return Err(Error::invalid(format!(
            "{name} claims rows {}..{} of part {} of {} but holds {} rows from row {}",
            expected.rows().start,
            expected.rows().end,
            shard.index,
            shard.count,
            part.height(),
            shard.row0
        )));
    }
    Ok(())
}

/// Join the parts of one sharded fit (in any order; `names` name them in messages)
/// into the whole image.
pub fn merge(parts: Vec<RelightableImage>, names: &[String]) -> Result<RelightableImage> {
    let name = |i: usize| names.get(i).cloned().unwrap_or_else(|| format!("part {i}"));
    let count = parts.len();
    let mut parts = parts.into_iter();
    let first = parts
        .next()
        .ok_or_else(|| Error::invalid("no parts to merge"))?;
    let mut merger = Merger::new(first, &name(0), count)?;
    for (i, part) in parts.enumerate() {
        merger.add(part, &name(i + 1))?;
    }
    merger.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::Capture;
    use crate::fit::{fit, BasisRequest, FitOptions, Objective};
    use crate::progress::Silent;
    use std::sync::Arc;

    fn capture() -> Capture {
        let dirs = crate::sphere::hemisphere_fibonacci(40);
        let mut capture = crate::synth::bumpy_plane(37, 23, &dirs);
        let pixels = capture.width * capture.height;
        capture.depth = Some(Arc::new((0..pixels).map(|p| 1.0 + p as f32).collect()));
        capture
    }

    fn parts(capture: &Capture, options: &FitOptions, count: usize) -> Vec<RelightableImage> {
        (0..count)
            .map(|i| {
                let options = FitOptions {
                    shard: Some((i, count)),
                    ..options.clone()
                };
                fit(capture, &options, &Silent).unwrap().image
            })
            .collect()
    }

    fn names(count: usize) -> Vec<String> {
        (0..count).map(|i| format!("part{i}.exr")).collect()
    }

    /// The joined parts hold the single fit's maps bit for bit, whatever the basis, the
    /// objective and the strips the perceptual fit streams in.
    #[test]
    fn merged_parts_equal_the_single_fit() {
        let capture = capture();
        // `auto` chooses on every part again, so it runs in fewer parts.
        let cases = [
            (
                FitOptions {
                    max_coefficients: 9,
                    ..Default::default()
                },
                &[3][..],
            ),
            (
                FitOptions {
                    basis: BasisRequest::parse("sh:9").unwrap(),
                    objective: Objective::Linear,
                    ..Default::default()
                },
                &[1, 2, 23],
            ),
            (
                FitOptions {
                    basis: BasisRequest::parse("rbf:9").unwrap(),
                    objective: Objective::Perceptual,
                    piece_bytes: 40 * 37 * 3 * 4 * 2, // two rows of all images per piece
                    ..Default::default()
                },
                &[4],
            ),
        ];
        for (options, counts) in cases {
            let whole = fit(&capture, &options, &Silent).unwrap().image;
            // The same parts fitted from a plan made once (through its JSON form).
            let plan = crate::fit::plan(&capture, &options, &Silent).unwrap();
            let json = serde_json::to_string(&plan).unwrap();
            let planned = FitOptions {
                plan: Some(serde_json::from_str(&json).unwrap()),
                ..options.clone()
            };
            for (count, options) in counts.iter().map(|&c| (c, &options)).chain([(3, &planned)]) {
                let mut pieces = parts(&capture, options, count);
                pieces.reverse(); // any order
                let merged = merge(pieces, &names(count)).unwrap();
                assert_eq!(merged.meta.basis, whole.meta.basis);
                assert!(merged.maps.data.len() == whole.maps.data.len());
                assert!(
                    merged
                        .maps
                        .data
                        .iter()
                        .zip(&whole.maps.data)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{:?} in {count} parts differs from the single fit",
                    options.basis
                );
                assert_eq!(merged.depth, whole.depth);
                let (m, w) = (merged.meta.fit.unwrap(), whole.meta.fit.clone().unwrap());
                assert_eq!(
                    (m.lambda, m.objective, m.shard),
                    (w.lambda, w.objective, None)
                );
                assert!((m.psnr_srgb8 - w.psnr_srgb8).abs() < 1.0, "pooled residual");
            }
        }
    }

    #[test]
    fn parts_that_do_not_make_one_fit_are_refused() {
        let capture = capture();
        let options = FitOptions {
            basis: BasisRequest::parse("sh:9").unwrap(),
            ..Default::default()
        };
        let three = parts(&capture, &options, 3);
        let message =
            |parts: Vec<RelightableImage>| merge(parts, &names(3)).unwrap_err().to_string();
        assert!(message(three[..2].to_vec()).contains("is part 0 of 3, but 2 parts were given"));
        assert!(
            message(vec![three[0].clone(), three[1].clone(), three[1].clone()])
                .contains("both part 1")
        );
        let mut other = three.clone();
        other[1].meta.fit.as_mut().unwrap().lambda *= 10.0;
        assert!(message(other).contains("part1.exr was fitted with another objective, λ"));
        let mut other = three.clone();
        other[2].meta.basis = crate::basis::BasisSpec::named("sh:16").unwrap();
        assert!(message(other).contains("another basis"));
        let whole = fit(&capture, &options, &Silent).unwrap().image;
        assert!(message(vec![whole]).contains("not a part of a sharded fit"));
        let mut wrong = three.clone();
        wrong[0].maps = CoefficientMaps::zeros(37, 5, 9);
        assert!(message(wrong).contains("holds 5 rows"));
        let two = parts(&capture, &options, 2);
        assert!(message(vec![two[0].clone(), three[1].clone()]).contains("not parts of one fit"));
        // Claims that would allocate more than the files hold are refused first.
        for (count, full_height) in [(1 << 40, 1 << 41), (3, 1 << 40)] {
            let mut bomb = three.clone();
            bomb[0].meta.fit.as_mut().unwrap().shard = Some(ShardInfo {
                index: 0,
                count,
                row0: 0,
                full_height,
            });
            assert!(merge(bomb, &names(3)).is_err(), "{count} {full_height}");
        }
        // The merger reports a part never added.
        let mut merger = Merger::new(three[0].clone(), "part0.exr", 3).unwrap();
        merger.add(three[2].clone(), "part2.exr").unwrap();
        let err = merger.finish().unwrap_err().to_string();
        assert!(err.contains("part 1 of 3 missing"), "{err}");
    }

    #[test]
    fn a_plan_for_another_capture_or_setting_is_refused() {
        let capture = capture();
        let options = FitOptions {
            basis: BasisRequest::parse("sh:4").unwrap(),
            ..Default::default()
        };
        let plan = crate::fit::plan(&capture, &options, &Silent).unwrap();
        let other = crate::synth::bumpy_plane(37, 22, &crate::sphere::hemisphere_fibonacci(40));
        let with = |plan: crate::fit::Plan, options: &FitOptions| FitOptions {
            plan: Some(plan),
            ..options.clone()
        };
        let err = fit(&other, &with(plan.clone(), &options), &Silent).unwrap_err();
        assert!(
            err.to_string().contains("made for 40 images of 37×23"),
            "{err}"
        );
        let srgb = FitOptions {
            color_space: crate::maps::MapSpace::Srgb,
            ..options.clone()
        };
        assert!(fit(&capture, &with(plan.clone(), &srgb), &Silent).is_err());
        let mut bad = plan.clone();
        bad.lambda = f64::NAN;
        assert!(fit(&capture, &with(bad, &options), &Silent).is_err());
        let mut bad = plan;
        bad.format = "something".into();
        assert!(fit(&capture, &with(bad, &options), &Silent).is_err());
    }

    #[test]
    fn a_part_that_does_not_exist_is_refused_by_the_fit() {
        let capture = capture();
        for shard in [(3, 3), (0, 0), (0, 24)] {
            let options = FitOptions {
                shard: Some(shard),
                ..Default::default()
            };
            assert!(fit(&capture, &options, &Silent).is_err(), "{shard:?}");
        }
    }
}

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
    /// The whole image's maps and depth, filled part by part; `None` when only the
    /// parts' headers are checked ([`Merger::headers`]).
    maps: Option<CoefficientMaps>,
    depth: Option<Vec<f32>>,
    /// Which file filled each part.
    slots: Vec<Option<String>>,
    /// Each part's index, rows and fit information, for the pooled residual and time
    /// (summed in the parts' order, so that the order they came in changes nothing).
    fits: Vec<(usize, usize, FitInfo)>,
    has_depth: bool,
    width: usize,
    k: usize,
}

impl Merger {
    /// Start from `first` (named `name` in messages), of a fit in `expected` parts: the
    /// number of files given, which bounds what the parts' metadata may claim before
    /// anything is allocated from it.
    pub fn new(first: RelightableImage, name: &str, expected: usize) -> Result<Merger> {
        Self::start(first, name, expected, true)
    }

    /// As [`Merger::new`], but for parts described by their headers alone (maps with
    /// their size and `k` but no values, depth empty when present): it checks that they
    /// make one fit and gives its metadata ([`Merger::finish_meta`]), holding no maps.
    pub fn headers(first: RelightableImage, name: &str, expected: usize) -> Result<Merger> {
        Self::start(first, name, expected, false)
    }

    fn start(first: RelightableImage, name: &str, expected: usize, hold: bool) -> Result<Merger> {
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
            maps: hold.then(|| CoefficientMaps::zeros(width, head.full_height, k)),
            depth: first
                .depth
                .as_ref()
                .filter(|_| hold)
                .map(|_| vec![0.0; width * head.full_height]),
            has_depth: first.depth.is_some(),
            width,
            k,
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
        if part.width() != self.width || part.maps.k != self.k {
            return Err(Error::invalid(format!(
                "{name} is {} pixels wide with {} coefficients, {} {} with {}",
                part.width(),
                part.maps.k,
                self.first,
                self.width,
                self.k
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
        if part.depth.is_some() != self.has_depth {
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
        let width = self.width;
        let plane_len = width * self.head.full_height;
        let n = part.maps.pixels();
        if let Some(maps) = self.maps.as_mut() {
            for (plane, out) in maps.data.chunks_exact_mut(plane_len).enumerate() {
                out[rows.start * width..rows.end * width]
                    .copy_from_slice(&part.maps.data[plane * n..(plane + 1) * n]);
            }
        }
        if let (Some(depth), Some(src)) = (self.depth.as_mut(), part.depth.as_ref()) {
            depth[rows.start * width..rows.end * width].copy_from_slice(src);
        }
        self.slots[shard.index] = Some(name.to_string());
        if let Some(fit) = part.meta.fit {
            self.fits.push((shard.index, rows.len(), fit));
        }
    }

    /// The whole image, once every part is in.
    pub fn finish(mut self) -> Result<RelightableImage> {
        let maps = self
            .maps
            .take()
            .ok_or_else(|| Error::invalid("the merger checked headers only: it holds no maps"))?;
        let depth = self.depth.take();
        Ok(RelightableImage {
            meta: self.finish_meta()?,
            maps,
            depth,
        })
    }

    /// The joined file's metadata, once every part is in: the fit's pooled residual
    /// and total time, no shard.
    pub fn finish_meta(self) -> Result<crate::maps::Metadata> {
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
        let mut fits = self.fits;
        fits.sort_by_key(|&(index, _, _)| index);
        let fits: Vec<(usize, FitInfo)> = fits.into_iter().map(|(_, r, f)| (r, f)).collect();
        if let Some(fit) = meta.fit.as_mut() {
            // The residual pooled over the parts that measured one (each measures the
            // subsample pixels in its rows), weighted by their rows; the time is the total.
            let measured: Vec<&(usize, FitInfo)> =
                fits.iter().filter(|(_, f)| f.psnr_srgb8 > 0.0).collect();
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
            fit.seconds = fits.iter().map(|(_, f)| f.seconds).sum();
            fit.shard = None;
        }
        Ok(meta)
    }
}

/// Join the parts of one sharded fit, relit EXR files in any order, into the EXR file
/// `output` in `precision`, a band of rows at a time: the file [`merge`] and
/// [`crate::codec::exr::write`] make of the same parts, holding a band of 16 rows (and
/// the depth map, when the parts have one) instead of the whole image's maps. Returns
/// the joined file's metadata and size.
pub fn merge_exr_files(
    parts: &[std::path::PathBuf],
    output: &std::path::Path,
    precision: crate::storage::Precision,
) -> Result<(crate::maps::Metadata, (usize, usize))> {
    use crate::codec::exr;
    use crate::fit::Piece;
    let name = |p: &std::path::Path| p.display().to_string();
    // Each part as its header describes it: metadata, size and k, no values.
    let heads: Vec<RelightableImage> = parts
        .iter()
        .map(|p| {
            let shape = exr::read_shape(p)?;
            Ok(RelightableImage {
                maps: CoefficientMaps {
                    width: shape.width,
                    height: shape.height,
                    k: shape.k,
                    data: Vec::new(),
                },
                depth: shape.depth.then(Vec::new),
                meta: shape.meta,
            })
        })
        .collect::<Result<_>>()?;
    let first = heads
        .first()
        .ok_or_else(|| Error::invalid("no parts to merge"))?;
    let mut merger = Merger::headers(first.clone(), &name(&parts[0]), parts.len())?;
    for (head, path) in heads.iter().zip(parts).skip(1) {
        merger.add(head.clone(), &name(path))?;
    }
    let meta = merger.finish_meta()?;
    let shards: Vec<ShardInfo> = heads
        .iter()
        .zip(parts)
        .map(|(h, p)| shard_of(h, &name(p)))
        .collect::<Result<_>>()?;
    let mut order: Vec<usize> = (0..parts.len()).collect();
    order.sort_by_key(|&i| shards[i].row0);
    let (width, k, height) = (first.maps.width, first.maps.k, shards[0].full_height);
    // Rows a band: a block of the file (16 scan lines, or a tile's height).
    let has_depth = first.depth.is_some();
    let tiles = exr::ExrStream::tiles(width, k, precision, has_depth);
    let band = tiles.map_or(16, |(_, h)| h);
    // The parts' rows overlapping [top, top + rows), in order: (first row, maps, depth).
    let segments = |top: usize, rows: usize, depth: bool| {
        order
            .iter()
            .filter_map(|&i| {
                let r = shards[i].rows();
                let (lo, hi) = (r.start.max(top), r.end.min(top + rows));
                (lo < hi).then(|| {
                    let read = exr::read_region_with(
                        &parts[i],
                        0,
                        (0, lo - r.start, width, hi - lo),
                        depth,
                    )?;
                    Ok((lo, read.image))
                })
            })
            .collect::<Result<Vec<_>>>()
    };
    let depth = if has_depth {
        let mut depth = vec![0.0f32; width * height];
        for top in (0..height).step_by(band) {
            for (y0, part) in segments(top, band.min(height - top), true)? {
                let d = part.depth.unwrap_or_default();
                depth[y0 * width..y0 * width + d.len()].copy_from_slice(&d);
            }
        }
        Some(depth)
    } else {
        None
    };
    let mut stream = exr::ExrStream::new(width, height, k, precision, depth)?;
    for top in (0..height).step_by(band) {
        let segments = segments(top, band.min(height - top), false)?;
        match tiles {
            None => {
                for (y0, part) in segments {
                    let piece = Piece {
                        x0: 0,
                        y0,
                        width,
                        height: part.maps.height,
                    };
                    stream.piece(piece, part.maps)?;
                }
            }
            Some((tile, _)) => {
                for x0 in (0..width).step_by(tile) {
                    let columns = tile.min(width - x0);
                    for (y0, part) in &segments {
                        let piece = Piece {
                            x0,
                            y0: *y0,
                            width: columns,
                            height: part.maps.height,
                        };
                        stream.piece(piece, columns_of(&part.maps, x0, columns))?;
                    }
                }
            }
        }
    }
    stream.finish(output, &meta)?;
    Ok((meta, (width, height)))
}

/// Columns `x0 .. x0 + width` of `maps`.
fn columns_of(maps: &CoefficientMaps, x0: usize, width: usize) -> CoefficientMaps {
    let mut out = CoefficientMaps::zeros(width, maps.height, maps.k);
    let (n, m) = (maps.pixels(), out.pixels());
    for plane in 0..3 * maps.k {
        for y in 0..maps.height {
            let from = plane * n + y * maps.width + x0;
            out.data[plane * m + y * width..plane * m + (y + 1) * width]
                .copy_from_slice(&maps.data[from..from + width]);
        }
    }
    out
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

    /// Parts joined from their files a band at a time make the file the merge in memory
    /// makes: the same maps bit for bit, depth and metadata, for a narrow image (scan
    /// lines) and a wide one (tiles 16 lines high), parts given in any order.
    #[test]
    fn parts_merged_from_files_a_band_at_a_time_equal_the_merge_in_memory() {
        use crate::codec::exr;
        use crate::storage::Precision;
        let dir = tempfile::tempdir().unwrap();
        let dirs = crate::sphere::hemisphere_fibonacci(40);
        let mut wide = crate::synth::bumpy_plane(1200, 5, &dirs);
        wide.depth = Some(Arc::new((0..6000).map(|p| 1.0 + p as f32).collect()));
        let options = FitOptions {
            basis: BasisRequest::parse("sh:9").unwrap(),
            objective: Objective::Linear,
            ..Default::default()
        };
        for (capture, count, tiled) in [(capture(), 3, false), (wide, 2, true)] {
            let pieces = parts(&capture, &options, count);
            assert_eq!(
                exr::ExrStream::tiles(capture.width, 9, Precision::F16, true).is_some(),
                tiled
            );
            let paths: Vec<std::path::PathBuf> = pieces
                .iter()
                .enumerate()
                .map(|(i, part)| {
                    let path = dir.path().join(format!("part{i}.exr"));
                    exr::write(&path, part, Precision::F32).unwrap();
                    path
                })
                .rev()
                .collect();
            let in_memory = dir.path().join("in_memory.exr");
            let banded = dir.path().join("banded.exr");
            let merged = merge(pieces, &names(count)).unwrap();
            exr::write(&in_memory, &merged, Precision::F16).unwrap();
            let (meta, size) = merge_exr_files(&paths, &banded, Precision::F16).unwrap();
            assert_eq!(size, (capture.width, capture.height));
            let (a, b) = (exr::read(&in_memory).unwrap(), exr::read(&banded).unwrap());
            assert_eq!(b.meta, meta);
            assert_eq!(a.meta, b.meta);
            assert_eq!(a.depth, b.depth);
            assert!(a
                .maps
                .data
                .iter()
                .zip(&b.maps.data)
                .all(|(x, y)| x.to_bits() == y.to_bits()));
            assert_eq!(a.maps.data.len(), b.maps.data.len());
        }
        // A missing part is named, and nothing is written.
        let two = [dir.path().join("part0.exr"), dir.path().join("part1.exr")];
        let out = dir.path().join("missing.exr");
        assert!(merge_exr_files(&two[..1], &out, Precision::F16).is_err());
        assert!(!out.exists());
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
            color_space: Some(crate::maps::MapSpace::Srgb),
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

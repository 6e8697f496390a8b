//! The native file: one OpenEXR part whose channels are the coefficient planes.
//!
//! Layout and attribute names are fixed in the [conventions](crate): channels
//! `cNN.R|G|B` (coefficient NN) and optional `Z` (depth); metadata in `relit.*`
//! attributes, structured values as ASCII JSON so any EXR tool can show them.

use super::Storage;
use crate::basis::BasisSpec;
use crate::fsutil::write_atomically;
use crate::image::ImageRgb;
use crate::maps::{CoefficientMaps, FitInfo, MapSpace, Metadata, RelightableImage, FORMAT_VERSION};
use crate::{Error, ErrorKind, Result};
use exr::prelude::*;
use std::path::Path;

const CHANNEL_NAMES: [&str; 3] = ["R", "G", "B"];

fn channel_name(i: usize, c: usize) -> String {
    format!("c{i:02}.{}", CHANNEL_NAMES[c])
}

fn exr_error(path: &Path, action: &str, e: exr::error::Error) -> Error {
    Error::new(
        ErrorKind::Io,
        format!("cannot {action} {}: {e}", path.display()),
    )
}

/// JSON with every non-ASCII character escaped, as EXR text attributes hold bytes.
fn ascii_json<T: serde::Serialize>(value: &T) -> String {
    let json = serde_json::to_string(value).expect("metadata serialises");
    let mut out = String::with_capacity(json.len());
    for ch in json.chars() {
        if ch.is_ascii() {
            out.push(ch);
        } else {
            let mut buf = [0u16; 2];
            for unit in ch.encode_utf16(&mut buf) {
                out.push_str(&format!("\\u{unit:04x}"));
            }
        }
    }
    out
}

fn text(s: &str) -> AttributeValue {
    AttributeValue::Text(Text::new_or_panic(s))
}

/// Write a relightable image. Maps are stored as `storage`; depth always as 32-bit float.
pub fn write(path: &Path, image: &RelightableImage, storage: Storage) -> Result<()> {
    let maps = &image.maps;
    let (w, h) = (maps.width, maps.height);
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::with_capacity(3 * maps.k + 1);
    for i in 0..maps.k {
        for c in 0..3 {
            let plane = maps.plane(i, c);
            let samples = match storage {
                Storage::Half => {
                    FlatSamples::F16(plane.iter().map(|&v| f16::from_f32(v)).collect())
                }
                Storage::Float => FlatSamples::F32(plane.to_vec()),
            };
            channels.push(AnyChannel::new(channel_name(i, c).as_str(), samples));
        }
    }
    if let Some(depth) = &image.depth {
        channels.push(AnyChannel::new("Z", FlatSamples::F32(depth.clone())));
    }
    let meta = &image.meta;
    let mut attrs = LayerAttributes::default();
    let other = &mut attrs.other;
    other.insert(
        Text::new_or_panic("relit.formatVersion"),
        AttributeValue::I32(meta.format_version as i32),
    );
    other.insert(
        Text::new_or_panic("relit.basis"),
        text(&ascii_json(&meta.basis)),
    );
    other.insert(
        Text::new_or_panic("relit.colorSpace"),
        text(meta.color_space.name()),
    );
    other.insert(
        Text::new_or_panic("relit.lightFrame"),
        text(&ascii_json(&meta.light_frame)),
    );
    other.insert(
        Text::new_or_panic("relit.projection"),
        text(&ascii_json(&meta.projection)),
    );
    other.insert(Text::new_or_panic("relit.storage"), text(storage.name()));
    if let Some(fit) = &meta.fit {
        other.insert(Text::new_or_panic("relit.fit"), text(&ascii_json(fit)));
    }
    if let Some(camera) = &meta.camera {
        other.insert(
            Text::new_or_panic("relit.camera"),
            text(&ascii_json(camera)),
        );
    }
    let encoding = Encoding {
        compression: Compression::ZIP16,
        ..Encoding::default()
    };
    let layer = Layer::new((w, h), attrs, encoding, AnyChannels::sort(channels.into()));
    let exr_image = Image::from_layer(layer);
    write_atomically(path, |out| {
        exr_image
            .write()
            .to_buffered(out)
            .map_err(|e| exr_error(path, "write", e))
    })
}

fn text_attr(attrs: &LayerAttributes, name: &str) -> Option<String> {
    match attrs.other.get(&Text::new_or_panic(name))? {
        AttributeValue::Text(t) => Some(t.to_string()),
        _ => None,
    }
}

fn parse_json<T: serde::de::DeserializeOwned>(path: &Path, name: &str, s: &str) -> Result<T> {
    serde_json::from_str(s)
        .map_err(|e| Error::parse(format!("{}: attribute {name}: {e}", path.display())))
}

/// Read a relightable image written by [`write`].
pub fn read(path: &Path) -> Result<RelightableImage> {
    if !path.is_file() {
        return Err(Error::new(
            ErrorKind::Io,
            format!("{} does not exist", path.display()),
        ));
    }
    // Block by block: each decompressed block goes straight into its planes, so reading
    // holds the maps once (plus the blocks in flight), not a second copy of every channel.
    use exr::block::reader::ChunksReader;
    let file = std::fs::File::open(path)
        .map_err(|e| Error::new(ErrorKind::Io, format!("{}: {e}", path.display())))?;
    let reader = exr::block::read(std::io::BufReader::new(file), false)
        .map_err(|e| exr_error(path, "read", e))?;
    let header =
        reader.headers().first().cloned().ok_or_else(|| {
            Error::parse(format!("{}: the EXR file has no layer", path.display()))
        })?;
    let attrs = &header.own_attributes;
    let bad = |what: &str| Error::parse(format!("{}: not a relit file ({what})", path.display()));
    let version = match attrs.other.get(&Text::new_or_panic("relit.formatVersion")) {
        Some(AttributeValue::I32(v)) => *v as u32,
        _ => return Err(bad("no relit.formatVersion attribute")),
    };
    if version > FORMAT_VERSION {
        return Err(Error::parse(format!(
            "{}: written by a newer relit (format {version}; this build reads up to {FORMAT_VERSION})",
            path.display()
        )));
    }
    let basis: BasisSpec = parse_json(
        path,
        "relit.basis",
        &text_attr(attrs, "relit.basis").ok_or_else(|| bad("no relit.basis"))?,
    )?;
    basis
        .build()
        .map_err(|e| Error::parse(format!("{}: relit.basis: {e}", path.display())))?;
    let color_space = match text_attr(attrs, "relit.colorSpace").as_deref() {
        Some("linear") | None => MapSpace::Linear,
        Some("srgb") => MapSpace::Srgb,
        Some(other) => {
            return Err(Error::parse(format!(
                "{}: unknown relit.colorSpace `{other}`",
                path.display()
            )))
        }
    };
    let light_frame = match text_attr(attrs, "relit.lightFrame") {
        Some(s) => parse_json(path, "relit.lightFrame", &s)?,
        None => crate::maps::LIGHT_FRAME.to_string(),
    };
    let projection = match text_attr(attrs, "relit.projection") {
        Some(s) => parse_json(path, "relit.projection", &s)?,
        None => Default::default(),
    };
    let camera = match text_attr(attrs, "relit.camera") {
        Some(s) => Some(parse_json(path, "relit.camera", &s)?),
        None => None,
    };
    let fit: Option<FitInfo> = match text_attr(attrs, "relit.fit") {
        Some(s) => Some(parse_json(path, "relit.fit", &s)?),
        None => None,
    };
    let (w, h) = (header.layer_size.width(), header.layer_size.height());
    let k = basis.len();
    let mut maps = CoefficientMaps::zeros(w, h, k);
    let mut found = vec![false; 3 * k];
    let mut depth: Option<Vec<f32>> = None;
    // Where each channel of the file goes: plane 3i + c, the depth map, or nowhere.
    #[derive(Clone, Copy)]
    enum Target {
        Plane(usize),
        Depth,
        Skip,
    }
    let mut targets = Vec::new();
    for channel in &header.channels.list {
        let name = channel.name.to_string();
        targets.push(if name == "Z" {
            depth = Some(vec![0f32; w * h]);
            Target::Depth
        } else if let Some((i, c)) = parse_channel_name(&name) {
            if i >= k {
                return Err(bad(&format!(
                    "channel {name} beyond the basis' {k} coefficients"
                )));
            }
            found[3 * i + c] = true;
            Target::Plane(3 * i + c)
        } else {
            Target::Skip
        });
    }
    let n = w * h;
    reader
        .all_chunks(false)
        .map_err(|e| exr_error(path, "read", e))?
        .decompress_parallel(false, |meta, block| {
            if block.index.layer != 0 || block.index.level != exr::math::Vec2(0, 0) {
                return Ok(());
            }
            let channels = &meta.headers[0].channels;
            for line in block.lines(channels) {
                let at = line.location.position;
                let start = at.y() * w + at.x();
                let count = line.location.sample_count;
                let dst = match targets[line.location.channel] {
                    Target::Plane(j) => &mut maps.data[j * n + start..j * n + start + count],
                    Target::Depth => match depth.as_mut() {
                        Some(d) => &mut d[start..start + count],
                        None => continue,
                    },
                    Target::Skip => continue,
                };
                match channels.list[line.location.channel].sample_type {
                    SampleType::F16 => {
                        for (d, v) in dst.iter_mut().zip(line.read_samples::<f16>()) {
                            *d = v?.to_f32();
                        }
                    }
                    SampleType::F32 => line.read_samples_into_slice(dst)?,
                    SampleType::U32 => {
                        for (d, v) in dst.iter_mut().zip(line.read_samples::<u32>()) {
                            *d = v? as f32;
                        }
                    }
                }
            }
            Ok(())
        })
        .map_err(|e| exr_error(path, "read", e))?;
    if let Some(missing) = found.iter().position(|f| !f) {
        return Err(bad(&format!(
            "channel {} is missing",
            channel_name(missing / 3, missing % 3)
        )));
    }
    let meta = Metadata {
        format_version: version,
        basis,
        color_space,
        light_frame,
        projection,
        camera,
        fit,
    };
    Ok(RelightableImage { meta, maps, depth })
}

fn read_all_data(path: &Path) -> Result<Image<Layers<AnyChannels<FlatSamples>>>> {
    exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .map_err(|e| exr_error(path, "read", e))
}

fn parse_channel_name(name: &str) -> Option<(usize, usize)> {
    let rest = name.strip_prefix('c')?;
    let (num, chan) = rest.split_once('.')?;
    let i: usize = num.parse().ok()?;
    let c = CHANNEL_NAMES.iter().position(|&n| n == chan)?;
    Some((i, c))
}

/// Read the header attributes only, for `relit info` on large files.
pub fn read_metadata_summary(path: &Path) -> Result<Vec<(String, String)>> {
    let meta =
        exr::meta::MetaData::read_from_file(path, false).map_err(|e| exr_error(path, "read", e))?;
    let mut out = Vec::new();
    for header in &meta.headers {
        out.push((
            "size".into(),
            format!(
                "{}×{}",
                header.layer_size.width(),
                header.layer_size.height()
            ),
        ));
        out.push(("channels".into(), header.channels.list.len().to_string()));
        out.push(("compression".into(), format!("{:?}", header.compression)));
        let mut names: Vec<_> = header.own_attributes.other.keys().collect();
        names.sort_by_key(|n| n.to_string());
        for name in names {
            let value = match &header.own_attributes.other[name] {
                AttributeValue::Text(t) => t.to_string(),
                other => format!("{other:?}"),
            };
            out.push((name.to_string(), value));
        }
    }
    Ok(out)
}

/// Write a linear RGB image as half-float EXR (relit frames).
pub fn write_rgb(path: &Path, image: &ImageRgb) -> Result<()> {
    let (w, h) = (image.width, image.height);
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let i = 3 * (pos.y() * w + pos.x());
        (
            f16::from_f32(image.data[i]),
            f16::from_f32(image.data[i + 1]),
            f16::from_f32(image.data[i + 2]),
        )
    });
    let encoding = Encoding {
        compression: Compression::ZIP16,
        ..Encoding::default()
    };
    let layer = Layer::new((w, h), LayerAttributes::default(), encoding, channels);
    let img = Image::from_layer(layer);
    write_atomically(path, |out| {
        img.write()
            .to_buffered(out)
            .map_err(|e| exr_error(path, "write", e))
    })
}

/// Read a single-valued plane (depth or mask) from the first of the channels `Z`, `Y`,
/// `R`, `A` that the file has.
pub fn read_scalar_channel(path: &Path) -> Result<(usize, usize, Vec<f32>)> {
    let image = read_all_data(path)?;
    let layer =
        image.layer_data.into_iter().next().ok_or_else(|| {
            Error::parse(format!("{}: the EXR file has no layer", path.display()))
        })?;
    let (w, h) = (layer.size.width(), layer.size.height());
    for wanted in ["Z", "Y", "R", "A"] {
        if let Some(ch) = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == wanted)
        {
            return Ok((w, h, ch.sample_data.values_as_f32().collect()));
        }
    }
    Err(Error::parse(format!(
        "{}: no Z, Y, R or A channel",
        path.display()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Projection;

    fn sample_image(k: usize) -> RelightableImage {
        let mut maps = CoefficientMaps::zeros(5, 3, k);
        for (i, v) in maps.data.iter_mut().enumerate() {
            *v = ((i * 7919) % 1000) as f32 / 137.0 - 3.0 + 1e-7 * i as f32;
        }
        let mut meta = Metadata::new(
            BasisSpec::Sh { bands: 2 },
            MapSpace::Linear,
            Projection::Cylindrical {
                fov_y_deg: Some(60.0),
            },
        );
        meta.fit = Some(FitInfo {
            objective: "perceptual".into(),
            regularizer: "roughness".into(),
            lambda: 1e-3,
            lambda_choice: "auto".into(),
            images: 60,
            rmse_linear: [0.01, 0.02, 0.03],
            psnr_srgb8: 35.5,
            seconds: 1.25,
        });
        meta.camera = Some(crate::camera::CameraSpec {
            projection: Projection::Cylindrical {
                fov_y_deg: Some(60.0),
            },
            width: 5,
            height: 3,
            pose: crate::camera::Pose::at(crate::sphere::Vec3::new(0.0, 1.5, 0.0)),
            orthographic_height: None,
        });
        RelightableImage {
            meta,
            maps,
            depth: Some((0..15).map(|i| i as f32 * 0.5).collect()),
        }
    }

    #[test]
    fn float_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.exr");
        let img = sample_image(4);
        write(&path, &img, Storage::Float).unwrap();
        let back = read(&path).unwrap();
        assert_eq!(back, img);
    }

    #[test]
    fn half_round_trip_equals_half_rounding() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.exr");
        let img = sample_image(4);
        write(&path, &img, Storage::Half).unwrap();
        let back = read(&path).unwrap();
        for (a, b) in back.maps.data.iter().zip(&img.maps.data) {
            assert_eq!(*a, Storage::Half.quantize(*b));
        }
        assert_eq!(back.meta, img.meta);
        assert_eq!(back.depth, img.depth, "depth is always stored as float");
    }

    #[test]
    fn foreign_and_broken_files_are_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain.exr");
        write_rgb(&plain, &ImageRgb::new(2, 2)).unwrap();
        assert!(read(&plain)
            .unwrap_err()
            .to_string()
            .contains("not a relit file"));
        let junk = dir.path().join("junk.exr");
        std::fs::write(&junk, b"v/1\x01 garbage").unwrap();
        assert!(read(&junk).is_err());
        assert!(read(&dir.path().join("absent.exr"))
            .unwrap_err()
            .to_string()
            .contains("does not exist"));
    }
}

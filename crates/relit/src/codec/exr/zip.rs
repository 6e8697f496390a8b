//! OpenEXR's ZIP compression of a block, made here rather than by the exr crate: the
//! same format (bytes split into even and odd halves, each byte replaced by its
//! difference from the one before plus 128, then a zlib stream), so every OpenEXR reader
//! reads it, with zlib-rs coding Huffman only in place of the crate's miniz_oxide at
//! level 4.
//!
//! Why: a `perf` profile of a 2048×512 fit (rbf:25, half floats) spent 19 % of its CPU
//! time in the crate's deflate. Coefficient maps are noisy half floats: after the byte
//! split and differences there are almost no repeated strings for deflate's matching to
//! find, only skewed byte frequencies, which Huffman coding alone takes. On that file's
//! 16-line blocks (157 MB), one run each:
//!
//! | deflate | speed | size (of raw) |
//! |---|---:|---:|
//! | miniz_oxide level 4 (the exr crate) | 31 MB/s | 0.827 |
//! | zlib-rs level 1 | 102 MB/s | 0.950 |
//! | zlib-rs level 2 (relit until 2026-12-05) | 59 MB/s | 0.816 |
//! | zlib-rs level 3 | 54 MB/s | 0.813 |
//! | zlib-rs Huffman only (now) | 158 MB/s | 0.799 |
//!
//! and on RealRTI item11's fit (rbf:25, 567×534): level 2 67 MB/s at 0.769, Huffman only
//! 160 MB/s at 0.749. PIZ made 0.939 and reads 4.6× slower.
//!
//! The split's first half holds the half floats' low bytes, whose differences are
//! nearly uniform: Huffman coding gains nothing there and one table for both halves
//! codes the high bytes worse. So the zlib stream holds the first half as *stored*
//! blocks and codes only the second half (raw deflate, Huffman only), then the Adler-32
//! of both, as any zlib stream may. On RealRTI item1's fit (sg:25, 487×439, 16-line
//! blocks): 0.7952 of the raw size with both halves coded, 0.7939 so, in 57 % of the
//! coding time (zlib, measured in Python); the fit's file 25.55 → 25.50 MB, its deflate
//! 23 % → 15 % of the fit's CPU samples, read back by OpenEXR's own library equal.

use exr::block::chunk::{
    Chunk, CompressedBlock, CompressedScanLineBlock, CompressedTileBlock, TileCoordinates,
};
use exr::block::{BlockIndex, UncompressedBlock};
use exr::meta::header::Header;
use exr::meta::BlockDescription;
use exr::prelude::{Compression, Vec2};

/// The zlib stream's settings: see the module docs.
fn config() -> zlib_rs::DeflateConfig {
    zlib_rs::DeflateConfig {
        level: 2, // unused by Huffman-only coding, which has no matching to tune
        strategy: zlib_rs::Strategy::HuffmanOnly,
        window_bits: -15, // raw deflate: `zip` writes the zlib wrapper itself
        ..zlib_rs::DeflateConfig::default()
    }
}

/// `block` compressed as `headers` say, as [`UncompressedBlock::compress_to_chunk`]
/// would make it: ZIP blocks (and only on a little-endian machine, where the block's
/// bytes are already the file's) by [`zip`], everything else by the exr crate.
pub(crate) fn compress(headers: &[Header], block: UncompressedBlock) -> exr::error::Result<Chunk> {
    let header = &headers[block.index.layer];
    let ours = matches!(header.compression, Compression::ZIP1 | Compression::ZIP16)
        && cfg!(target_endian = "little");
    if !ours {
        return block.compress_to_chunk(headers);
    }
    let UncompressedBlock { index, data } = block;
    let expected = header.channels.bytes_per_pixel * index.pixel_size.area();
    if data.len() != expected {
        return Err(exr::error::Error::Invalid(
            format!(
                "a block of {} bytes where its pixels take {expected}",
                data.len()
            )
            .into(),
        ));
    }
    // As OpenEXR stores a block: compressed only when that makes it smaller.
    let zipped = zip(&data);
    let pixels = if zipped.len() < data.len() {
        zipped
    } else {
        data
    };
    Ok(Chunk {
        layer_index: index.layer,
        compressed_block: chunk_block(header, &index, pixels)?,
    })
}

/// The chunk's block for `index`, holding `pixels`: its first line (scan lines) or its
/// tile coordinates, as the exr crate computes them.
fn chunk_block(
    header: &Header,
    index: &BlockIndex,
    pixels: Vec<u8>,
) -> exr::error::Result<CompressedBlock> {
    Ok(match header.blocks {
        BlockDescription::ScanLines => CompressedBlock::ScanLine(CompressedScanLineBlock {
            y_coordinate: i32::try_from(index.pixel_position.y())
                .map_err(|_| exr::error::Error::Invalid("a block beyond 2³¹ lines".into()))?
                + header.own_attributes.layer_position.y(),
            compressed_pixels_le: pixels,
        }),
        BlockDescription::Tiles(_) => {
            let size = header.max_block_pixel_size();
            CompressedBlock::Tile(CompressedTileBlock {
                coordinates: TileCoordinates {
                    tile_index: Vec2(
                        index.pixel_position.x() / size.width(),
                        index.pixel_position.y() / size.height(),
                    ),
                    level_index: index.level,
                },
                compressed_pixels_le: pixels,
            })
        }
    })
}

/// OpenEXR's ZIP of little-endian block bytes `raw`.
pub(crate) fn zip(raw: &[u8]) -> Vec<u8> {
    thread_local! {
        // The split bytes, reused block after block: a block is about a megabyte, which
        // the allocator would map and unmap (and the kernel zero) every time.
        static SPLIT: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    SPLIT.with_borrow_mut(|split| {
        let half = raw.len().div_ceil(2);
        split.clear();
        split.resize(raw.len(), 0);
        let (even, odd) = split.split_at_mut(half);
        for (i, pair) in raw.chunks(2).enumerate() {
            even[i] = pair[0];
            if let Some(&b) = pair.get(1) {
                odd[i] = b;
            }
        }
        let mut previous = split.first().copied().unwrap_or(0);
        for byte in split.iter_mut().skip(1) {
            let current = *byte;
            *byte = current.wrapping_sub(previous).wrapping_add(128);
            previous = current;
        }
        // One zlib stream: the low bytes' half as stored blocks, the high bytes' half
        // coded Huffman only (raw deflate, its last block final, straight into the
        // stream), the Adler-32 of both.
        let (low, high) = split.split_at(half);
        let bound = zlib_rs::compress_bound(high.len());
        let mut stream =
            Vec::with_capacity(2 + low.len() + 5 * low.len().div_ceil(0xffff) + bound + 4);
        stream.extend_from_slice(&[0x78, 0x01]);
        for block in low.chunks(u16::MAX as usize) {
            let len = block.len() as u16;
            stream.push(0); // not final, stored; the rest of the byte is padding
            stream.extend_from_slice(&len.to_le_bytes());
            stream.extend_from_slice(&(!len).to_le_bytes());
            stream.extend_from_slice(block);
        }
        let start = stream.len();
        stream.resize(start + bound, 0);
        let (written, code) = zlib_rs::compress_slice(&mut stream[start..], high, config());
        assert_eq!(
            code,
            zlib_rs::ReturnCode::Ok,
            "deflating into a buffer of the bound's size cannot fail"
        );
        let end = start + written.len();
        stream.truncate(end);
        stream.extend_from_slice(&zlib_rs::adler32::adler32(1, split).to_be_bytes());
        stream
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::*;

    /// A scan-line and a tiled header of three half-float channels, 40×37, ZIP16.
    fn headers(blocks: Blocks) -> exr::meta::Headers {
        let channels: Vec<AnyChannel<FlatSamples>> = ["A", "B", "C"]
            .iter()
            .map(|n| AnyChannel::new(*n, FlatSamples::F16(vec![f16::ZERO; 40 * 37])))
            .collect();
        let layer = Layer::new(
            (40, 37),
            LayerAttributes::default(),
            Encoding {
                compression: Compression::ZIP16,
                blocks,
                line_order: LineOrder::Increasing,
            },
            AnyChannels::sort(channels.into()),
        );
        Image::from_layer(layer).write().infer_meta_data()
    }

    /// What the exr crate needs to read a chunk of `headers`' file.
    fn meta(headers: &exr::meta::Headers) -> exr::meta::MetaData {
        exr::meta::MetaData {
            requirements: exr::meta::Requirements {
                file_format_version: 2,
                is_single_layer_and_tiled: matches!(headers[0].blocks, BlockDescription::Tiles(_)),
                has_long_names: false,
                has_deep_data: false,
                has_multiple_layers: false,
            },
            headers: headers.clone(),
        }
    }

    #[test]
    fn blocks_read_back_as_the_exr_crate_compresses_them() {
        for blocks in [Blocks::ScanLines, Blocks::Tiles(Vec2(16, 16))] {
            let headers = headers(blocks);
            let header = &headers[0];
            for index in exr::block::enumerate_ordered_header_block_indices(&headers) {
                let block = index.1;
                let bytes = header.channels.bytes_per_pixel * block.pixel_size.area();
                // Smooth half floats with noise in the low bits: compressible, not trivially.
                let data: Vec<u8> = (0..bytes / 2)
                    .flat_map(|i| {
                        let v = f16::from_f32(
                            0.3 + 0.001 * (i % 97) as f32 + 1e-4 * ((i * 7919) % 13) as f32,
                        );
                        v.to_bits().to_le_bytes()
                    })
                    .collect();
                let ours = compress(
                    &headers,
                    UncompressedBlock {
                        index: block,
                        data: data.clone(),
                    },
                )
                .unwrap();
                let theirs = UncompressedBlock {
                    index: block,
                    data: data.clone(),
                }
                .compress_to_chunk(&headers)
                .unwrap();
                // The same place in the file, and the same pixels when the crate reads it.
                let place = |c: &Chunk| match &c.compressed_block {
                    CompressedBlock::ScanLine(b) => (b.y_coordinate as usize, 0, 0),
                    CompressedBlock::Tile(t) => {
                        (t.coordinates.tile_index.0, t.coordinates.tile_index.1, 1)
                    }
                    _ => unreachable!(),
                };
                assert_eq!(place(&ours), place(&theirs));
                let size = |c: &Chunk| match &c.compressed_block {
                    CompressedBlock::ScanLine(b) => b.compressed_pixels_le.len(),
                    CompressedBlock::Tile(t) => t.compressed_pixels_le.len(),
                    _ => unreachable!(),
                };
                assert!(
                    size(&ours) < data.len(),
                    "{} of {}",
                    size(&ours),
                    data.len()
                );
                let back =
                    UncompressedBlock::decompress_chunk(ours, &meta(&headers), true).unwrap();
                assert_eq!(back.index, block);
                assert_eq!(back.data, data);
            }
        }
    }

    /// The stream is plain zlib: another inflater (zlib-rs's) gives back the split,
    /// differenced bytes exactly, at lengths of no bytes, one, odd ones and halves of
    /// more than one stored block (65 535 bytes).
    #[test]
    fn streams_inflate_with_any_zlib() {
        for len in [0usize, 1, 2, 3, 1001, 131_070, 131_071, 300_001] {
            let raw: Vec<u8> = (0..len)
                .map(|i| ((i * 31) % 251 + i / 1000) as u8)
                .collect();
            let stream = zip(&raw);
            let mut back = vec![0u8; len + 16];
            let (got, code) = zlib_rs::decompress_slice(
                &mut back,
                &stream,
                zlib_rs::InflateConfig { window_bits: 15 },
            );
            assert_eq!(code, zlib_rs::ReturnCode::Ok, "{len} bytes");
            // Undo the differences and the split.
            let mut split = got.to_vec();
            for i in 1..split.len() {
                split[i] = split[i].wrapping_add(split[i - 1]).wrapping_sub(128);
            }
            let half = len.div_ceil(2);
            let unsplit: Vec<u8> = (0..len)
                .map(|i| {
                    if i % 2 == 0 {
                        split[i / 2]
                    } else {
                        split[half + i / 2]
                    }
                })
                .collect();
            assert_eq!(unsplit, raw, "{len} bytes");
        }
    }

    #[test]
    fn incompressible_blocks_are_stored_raw() {
        let headers = headers(Blocks::ScanLines);
        let (_, block) = exr::block::enumerate_ordered_header_block_indices(&headers)
            .next()
            .unwrap();
        let bytes = headers[0].channels.bytes_per_pixel * block.pixel_size.area();
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let data: Vec<u8> = (0..bytes)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        let chunk = compress(
            &headers,
            UncompressedBlock {
                index: block,
                data: data.clone(),
            },
        )
        .unwrap();
        let CompressedBlock::ScanLine(lines) = &chunk.compressed_block else {
            panic!("a scan-line block")
        };
        assert_eq!(lines.compressed_pixels_le, data);
        let back = UncompressedBlock::decompress_chunk(chunk, &meta(&headers), true).unwrap();
        assert_eq!(back.data, data);
    }
}

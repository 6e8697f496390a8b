//! JPEG through MozJPEG (libjpeg-turbo with a better encoder): photographs decoded row
//! by row, and the web export's 8-bit planes encoded.
//!
//! A capture's photographs are read more than once: for the subsample the basis is
//! chosen on and the rows a fit (or one part of a sharded fit) solves — one pass where
//! the fit spills the photographs' codes, two otherwise — and by evaluations. Decoding a
//! whole image for either holds `3·W·H` bytes a thread; libjpeg hands rows out one at a
//! time and can stop anywhere, so a reader holds a few rows and never decodes below the
//! last one it needs. Every JPEG photograph relit reads comes through here, so that the
//! images a fit sees and the images an evaluation compares with are decoded alike.

use crate::{Error, ErrorKind, Result};
use mozjpeg_sys as ffi;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

/// Whether a file starts like a JPEG (SOI then a marker).
pub(super) fn is_jpeg(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 3];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head == [0xFF, 0xD8, 0xFF]
}

/// What [`stream_rows`] found: a JPEG libjpeg decodes to RGB, or one it leaves to the
/// general decoder (CMYK and YCCK photographs, which libjpeg does not convert to RGB).
pub(super) enum Streamed {
    Done { width: usize, height: usize },
    Unsupported,
}

/// Decode the JPEG at `path` from the top, handing each 8-bit RGB row (`3·width` bytes)
/// to `row` with its index. `rows_to_read(width, height)` says, once the header is read,
/// how many rows from the top are wanted: decoding stops there, so nothing below them is
/// decoded. A file that ends early is an error, not grey rows (libjpeg's default).
pub(super) fn stream_rows(
    path: &Path,
    rows_to_read: impl FnOnce(usize, usize) -> Result<usize>,
    mut row: impl FnMut(usize, &[u8]),
) -> Result<Streamed> {
    let file = File::open(path).map_err(|e| Error::io(path, "open image", e))?;
    let reader = BufReader::new(file);
    // libjpeg reports a fatal error by calling the error manager, which unwinds (the
    // only way out of C without longjmp); the unwind stops here and becomes an error.
    let outcome = catch_unwind(AssertUnwindSafe(|| decode(reader, rows_to_read, &mut row)));
    match outcome {
        Ok(result) => result,
        Err(payload) => {
            let message = payload
                .downcast_ref::<LibjpegFailure>()
                .map(|f| f.0.clone())
                .unwrap_or_else(|| "the JPEG decoder failed".into());
            Err(Error::new(
                ErrorKind::Image,
                format!("cannot decode {}: {message}", path.display()),
            ))
        }
    }
}

fn decode<R: BufRead>(
    reader: R,
    rows_to_read: impl FnOnce(usize, usize) -> Result<usize>,
    row: &mut impl FnMut(usize, &[u8]),
) -> Result<Streamed> {
    let decompress = mozjpeg::Decompress::builder()
        .with_err(error_manager())
        .from_reader(reader)
        .map_err(|e| Error::new(ErrorKind::Image, e.to_string()))?;
    if matches!(
        decompress.color_space(),
        ffi::J_COLOR_SPACE::JCS_CMYK | ffi::J_COLOR_SPACE::JCS_YCCK
    ) {
        return Ok(Streamed::Unsupported);
    }
    let (width, height) = (decompress.width(), decompress.height());
    let wanted = rows_to_read(width, height)?.min(height);
    let mut started = decompress
        .rgb()
        .map_err(|e| Error::new(ErrorKind::Image, e.to_string()))?;
    // A few rows a call: libjpeg decodes a whole row of 8×8 or 16×16 blocks at a time
    // and keeps it, so a small buffer costs no extra decoding.
    const ROWS_A_CALL: usize = 16;
    let mut buffer = vec![0u8; 3 * width * ROWS_A_CALL.min(wanted.max(1))];
    let mut y = 0;
    while y < wanted {
        let count = ROWS_A_CALL.min(wanted - y);
        let lines = started
            .read_scanlines_into(&mut buffer[..3 * width * count])
            .map_err(|e| Error::new(ErrorKind::Image, format!("rows {y}…: {e}")))?;
        for (i, line) in lines.chunks_exact(3 * width).enumerate() {
            row(y + i, line);
        }
        y += count;
    }
    // Rows below `wanted` are never decoded: dropping the decoder aborts it.
    Ok(Streamed::Done { width, height })
}

/// An 8-bit RGB image (`width × height` pixels of 3 samples, rows from the top) as a
/// JPEG at `quality` (1–100), with MozJPEG's defaults: its quantisation tables, trellis
/// quantisation and optimised progressive scans, and no chroma subsampling (each
/// channel is a plane of coefficients of its own). The web export's planes are written
/// so (item1's fit at quality 95: 6.6 % fewer bytes and +0.41 dB against a baseline
/// encoder; at 80, 4.8 % and +0.91 dB); the compressed file's stay baseline
/// (`compress::planes` says why).
pub(crate) fn encode_rgb(
    samples: &[u8],
    width: usize,
    height: usize,
    quality: u8,
) -> Result<Vec<u8>> {
    let channels = 3;
    if samples.len() != channels * width * height
        || width == 0
        || height == 0
        || width > 65_535
        || height > 65_535
    {
        return Err(Error::invalid(format!(
            "{} samples do not make a {width}×{height} JPEG of {channels} channels",
            samples.len()
        )));
    }
    let outcome = catch_unwind(AssertUnwindSafe(|| -> std::io::Result<Vec<u8>> {
        let mut compress =
            mozjpeg::Compress::new_err(Box::new(error_manager()), mozjpeg::ColorSpace::JCS_RGB);
        compress.set_size(width, height);
        compress.set_quality(quality.clamp(1, 100) as f32);
        compress.set_chroma_sampling_pixel_sizes((1, 1), (1, 1));
        let mut started = compress.start_compress(Vec::new())?;
        started.write_scanlines(samples)?;
        started.finish()
    }));
    match outcome {
        Ok(Ok(bytes)) => Ok(bytes),
        Ok(Err(e)) => Err(Error::new(ErrorKind::Image, format!("JPEG: {e}"))),
        Err(payload) => Err(Error::new(
            ErrorKind::Image,
            format!(
                "JPEG: {}",
                payload
                    .downcast_ref::<LibjpegFailure>()
                    .map_or("the encoder failed", |f| f.0.as_str())
            ),
        )),
    }
}

/// The payload an unwinding libjpeg error carries: its own message.
struct LibjpegFailure(String);

/// libjpeg's standard error manager with two changes: a fatal error unwinds (with
/// [`LibjpegFailure`]) instead of exiting the process, and a file that ends before its
/// last row is fatal instead of a warning, so a truncated photograph is never fitted
/// as grey. Other warnings (extraneous bytes, which some cameras write) stay silent,
/// as libjpeg leaves them.
fn error_manager() -> ffi::jpeg_error_mgr {
    // SAFETY: jpeg_std_error fills every field of the zeroed struct.
    let mut manager: ffi::jpeg_error_mgr = unsafe { std::mem::zeroed() };
    unsafe { ffi::jpeg_std_error(&mut manager) };
    manager.error_exit = Some(fail);
    manager.emit_message = Some(warn);
    manager
}

extern "C-unwind" fn fail(cinfo: &mut ffi::jpeg_common_struct) {
    let message = message(cinfo);
    std::panic::resume_unwind(Box::new(LibjpegFailure(message)));
}

extern "C-unwind" fn warn(cinfo: &mut ffi::jpeg_common_struct, level: std::os::raw::c_int) {
    // SAFETY: libjpeg calls this with its own struct, whose `err` is the manager above.
    let code = unsafe { cinfo.err.as_ref() }.map(|e| e.msg_code);
    if level < 0 && code == Some(ffi::JWRN_JPEG_EOF) {
        fail(cinfo);
    }
}

/// libjpeg's text for its current message.
fn message(cinfo: &mut ffi::jpeg_common_struct) -> String {
    type Format = unsafe extern "C-unwind" fn(&mut ffi::jpeg_common_struct, &mut [u8; 80]);
    let mut buffer = [0u8; 80];
    // SAFETY: `err` points to the manager libjpeg was given. format_message writes its
    // text, NUL-terminated, into the buffer (at most JMSG_LENGTH_MAX = 80 bytes): the
    // binding declares the buffer shared, so it is called through a type that says it
    // is written.
    let format = unsafe { cinfo.err.as_ref() }.and_then(|e| e.format_message);
    match format {
        Some(format) => {
            let format: Format = unsafe { std::mem::transmute(format) };
            unsafe { format(cinfo, &mut buffer) };
            let end = buffer.iter().position(|&b| b == 0).unwrap_or(buffer.len());
            String::from_utf8_lossy(&buffer[..end]).into_owned()
        }
        None => "unknown libjpeg error".into(),
    }
}

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
use std::io::BufReader;
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

/// Whether the decoder runs libjpeg-turbo's SIMD code (inverse DCT, upsampling and
/// colour conversion) rather than its portable C: a fifth less time for a fixed-basis
/// fit of 50 photographs of 1024×768. mozjpeg-sys assembles that code with `nasm` when
/// the crate is built, and builds without it, silently apart from a build warning,
/// where `nasm` is missing: a build made before `nasm` was installed stays portable
/// until mozjpeg-sys is rebuilt (`scripts/prepare.sh` does that).
pub fn decoder_simd() -> bool {
    extern "C" {
        // libjpeg-turbo's own check: jsimd.c asks the CPU; jsimd_none.c, compiled in
        // place of the SIMD code, answers 0.
        fn jsimd_can_idct_islow() -> std::os::raw::c_int;
    }
    // SAFETY: a C function of no arguments that reads CPU features once and keeps them.
    unsafe { jsimd_can_idct_islow() != 0 }
}

/// What to do where [`decoder_simd`] is false (`relit doctor`, `relit bench --fit`, the
/// tests' skip).
pub const DECODER_ADVICE: &str = "the JPEG decoder was built without its SIMD code (`nasm` \
     was missing when mozjpeg-sys was built): fits of photographs take about a quarter \
     longer (50 of 1024×768); install nasm (Debian/Ubuntu: `apt-get install nasm`), then \
     `cargo clean --release -p mozjpeg-sys` and rebuild (scripts/demo.sh and \
     scripts/test.sh do both)";

/// What [`stream_rows`] found: a JPEG libjpeg decodes to RGB, or one it leaves to the
/// general decoder (CMYK and YCCK photographs, which libjpeg does not convert to RGB).
pub(super) enum Streamed {
    Done { width: usize, height: usize },
    Unsupported,
}

/// Decode the JPEG at `path`, handing each 8-bit RGB row (`3·width` bytes) of the rows
/// wanted to `row` with its index. `rows_to_read(width, height)` says, once the header
/// is read, which rows are wanted: decoding stops after the last, so nothing below them
/// is decoded, and rows above the first are skipped — libjpeg reads their entropy-coded
/// data (a JPEG without restart markers must be read from its start) but does no
/// inverse DCT, upsampling or colour conversion for them. A file that ends early is an
/// error, not grey rows (libjpeg's default).
pub(super) fn stream_rows(
    path: &Path,
    rows_to_read: impl FnOnce(usize, usize) -> Result<std::ops::Range<usize>>,
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

fn decode(
    reader: BufReader<File>,
    rows_to_read: impl FnOnce(usize, usize) -> Result<std::ops::Range<usize>>,
    row: &mut impl FnMut(usize, &[u8]),
) -> Result<Streamed> {
    let mut decoder = Decoder::new(reader);
    let d = &mut *decoder.cinfo;
    // SAFETY: the decompressor was created with a source and an error manager that
    // outlive it (both are in `decoder`, which is neither moved nor dropped before it).
    unsafe { ffi::jpeg_read_header(d, 1) };
    if matches!(
        d.jpeg_color_space,
        ffi::J_COLOR_SPACE::JCS_CMYK | ffi::J_COLOR_SPACE::JCS_YCCK
    ) {
        return Ok(Streamed::Unsupported);
    }
    let (width, height) = (d.image_width as usize, d.image_height as usize);
    let wanted = rows_to_read(width, height)?;
    let (first, end) = (wanted.start.min(height), wanted.end.min(height));
    if first >= end {
        return Ok(Streamed::Done { width, height });
    }
    d.out_color_space = ffi::J_COLOR_SPACE::JCS_RGB;
    // SAFETY: as above; the header has been read.
    unsafe { ffi::jpeg_start_decompress(d) };
    if d.output_components != 3 || d.output_width as usize != width {
        return Err(Error::new(
            ErrorKind::Image,
            "libjpeg did not decode the JPEG to RGB",
        ));
    }
    // The rows above the first wanted: entropy-decoded only (libjpeg-turbo decodes the
    // rows it cannot skip, at the edges of a row of blocks, as it would anyway).
    let mut y = 0;
    while y < first {
        // SAFETY: decompression has started; `first - y` rows remain above `first`.
        let skipped = unsafe { ffi::jpeg_skip_scanlines(d, (first - y) as ffi::JDIMENSION) };
        if skipped == 0 {
            return Err(Error::new(
                ErrorKind::Image,
                format!("cannot skip to row {first}"),
            ));
        }
        y += skipped as usize;
    }
    // A few rows a call: libjpeg decodes a whole row of 8×8 or 16×16 blocks at a time
    // and keeps it, so a small buffer costs no extra decoding.
    const ROWS_A_CALL: usize = 16;
    let stride = 3 * width;
    let mut buffer = vec![0u8; stride * ROWS_A_CALL.min(end - first)];
    while y < end {
        let count = ROWS_A_CALL.min(end - y);
        let mut pointers: Vec<*mut u8> = buffer
            .chunks_exact_mut(stride)
            .take(count)
            .map(|r| r.as_mut_ptr())
            .collect();
        // SAFETY: `count` pointers to rows of `3·width` bytes, each the decoder's
        // output width × 3 components; decompression has started and `y < height`.
        let got =
            unsafe { ffi::jpeg_read_scanlines(d, pointers.as_mut_ptr(), count as ffi::JDIMENSION) }
                as usize;
        if got == 0 {
            return Err(Error::new(
                ErrorKind::Image,
                format!("no rows from row {y}"),
            ));
        }
        for (i, line) in buffer.chunks_exact(stride).take(got).enumerate() {
            row(y + i, line);
        }
        y += got;
    }
    // Rows below `end` are never decoded: the decoder is destroyed unfinished.
    Ok(Streamed::Done { width, height })
}

/// A libjpeg decompressor reading a file through its own buffer, with the error manager
/// of [`error_manager`]; destroyed when dropped (also while a libjpeg error unwinds).
/// Each part is boxed: libjpeg keeps pointers to the error and source managers.
struct Decoder {
    cinfo: Box<ffi::jpeg_decompress_struct>,
    _errors: Box<ffi::jpeg_error_mgr>,
    _source: Box<Source>,
}

impl Decoder {
    fn new(reader: BufReader<File>) -> Decoder {
        let mut errors = Box::new(error_manager());
        let mut source = Box::new(Source {
            manager: ffi::jpeg_source_mgr {
                next_input_byte: std::ptr::null(),
                bytes_in_buffer: 0,
                init_source: Some(Source::nothing),
                fill_input_buffer: Some(Source::fill),
                skip_input_data: Some(Source::skip),
                resync_to_restart: Some(ffi::jpeg_resync_to_restart),
                term_source: Some(Source::nothing),
            },
            reader,
            buffer: vec![0; 1 << 16].into_boxed_slice(),
        });
        // SAFETY: an all-zero decompress struct is what jpeg_create_decompress expects
        // (C callers clear it too); its error manager is set before it is created.
        let mut cinfo: Box<ffi::jpeg_decompress_struct> = Box::new(unsafe { std::mem::zeroed() });
        cinfo.common.err = &mut *errors;
        // SAFETY: `cinfo` is cleared and has its error manager.
        unsafe { ffi::jpeg_create_decompress(&mut *cinfo) };
        cinfo.src = &mut source.manager;
        Decoder {
            cinfo,
            _errors: errors,
            _source: source,
        }
    }
}

impl Drop for Decoder {
    fn drop(&mut self) {
        // SAFETY: created in `new`; destroying also aborts an unfinished decompression.
        unsafe { ffi::jpeg_destroy_decompress(&mut self.cinfo) };
    }
}

/// libjpeg's source manager over a file: `manager` first, so that libjpeg's pointer to
/// it is a pointer to the whole.
#[repr(C)]
struct Source {
    manager: ffi::jpeg_source_mgr,
    reader: BufReader<File>,
    buffer: Box<[u8]>,
}

impl Source {
    /// # Safety
    /// `cinfo.src` must be a [`Source`]'s manager.
    unsafe fn of(cinfo: &mut ffi::jpeg_decompress_struct) -> &mut Source {
        // SAFETY: the caller's promise.
        unsafe { &mut *(cinfo.src as *mut Source) }
    }

    extern "C-unwind" fn nothing(_: &mut ffi::jpeg_decompress_struct) {}

    /// The next bytes of the file. At its end, libjpeg's end-of-file warning (which
    /// [`error_manager`] makes fatal) and, were it to return, an end-of-image marker, as
    /// libjpeg's own sources do.
    extern "C-unwind" fn fill(cinfo: &mut ffi::jpeg_decompress_struct) -> ffi::boolean {
        use std::io::Read;
        // SAFETY: every decompressor made by `Decoder::new` has a `Source`.
        let source = unsafe { Source::of(cinfo) };
        let mut read = loop {
            match source.reader.read(&mut source.buffer) {
                Ok(n) => break n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => std::panic::resume_unwind(Box::new(LibjpegFailure(format!(
                    "cannot read the file: {e}"
                )))),
            }
        };
        let at_end = read == 0;
        if at_end {
            source.buffer[..2].copy_from_slice(&[0xFF, 0xD9]);
            read = 2;
        }
        source.manager.next_input_byte = source.buffer.as_ptr();
        source.manager.bytes_in_buffer = read;
        if at_end {
            // SAFETY: `err` is the manager `Decoder::new` set.
            if let Some(errors) = unsafe { cinfo.common.err.as_mut() } {
                errors.msg_code = ffi::JWRN_JPEG_EOF as std::os::raw::c_int;
                if let Some(emit) = errors.emit_message {
                    // SAFETY: libjpeg's own call, with its struct.
                    unsafe { emit(&mut cinfo.common, -1) };
                }
            }
        }
        1
    }

    extern "C-unwind" fn skip(
        cinfo: &mut ffi::jpeg_decompress_struct,
        bytes: std::os::raw::c_long,
    ) {
        let mut left = usize::try_from(bytes).unwrap_or(0);
        while left > 0 {
            // SAFETY: as in `fill`.
            let source = unsafe { Source::of(cinfo) };
            let here = source.manager.bytes_in_buffer.min(left);
            // SAFETY: `here` bytes remain in the buffer.
            source.manager.next_input_byte = unsafe { source.manager.next_input_byte.add(here) };
            source.manager.bytes_in_buffer -= here;
            left -= here;
            if left > 0 {
                Source::fill(cinfo);
            }
        }
    }
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

#[cfg(test)]
mod tests {
    /// On x86-64 (where relit's users and CI run) the decoder is libjpeg-turbo's SIMD
    /// build, as scripts/prepare.sh arranges by installing `nasm` and rebuilding a
    /// mozjpeg-sys built without it. A portable decoder is logged as a skip (a failure
    /// in CI): the fits are right, only slower.
    #[test]
    fn the_decoder_runs_libjpeg_turbos_simd_code() {
        if !cfg!(target_arch = "x86_64") {
            return;
        }
        if !super::decoder_simd() {
            crate::skip::skipping(super::DECODER_ADVICE);
        }
    }
}

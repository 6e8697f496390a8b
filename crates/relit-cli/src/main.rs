//! `relit`: the command-line face of the relit library.
//!
//! Exit codes: 0 success, 1 the work failed (bad input, I/O…), 2 bad command line.

mod cmd_bake;
mod cmd_bench;
mod cmd_capture;
mod cmd_compare;
mod cmd_convert;
mod cmd_demo;
mod cmd_doctor;
mod cmd_eval;
mod cmd_eval_rd;
mod cmd_export_web;
mod cmd_fit;
mod cmd_info;
mod cmd_merge;
mod cmd_normals;
mod cmd_plan;
mod cmd_relight;
mod cmd_render_truth;
mod cmd_view;
mod fit_bench;
mod rd_plot;
mod shared;

use clap::{Parser, Subcommand};

/// Image-based relighting: fit captures into coefficient maps and relight them.
#[derive(Parser)]
#[command(name = "relit", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fit a capture (.lp or manifest .json) into a relightable EXR of coefficient maps.
    Fit(cmd_fit::Args),
    /// Relight a fitted file with lights that were never photographed.
    Relight(cmd_relight::Args),
    /// Show what a relightable file holds.
    Info(cmd_info::Args),
    /// Surface normals (and albedo) by photometric stereo, robust to shadows and
    /// highlights, from a capture or a fitted file.
    Normals(cmd_normals::Args),
    /// Convert between the lossless EXR and the compressed .rlz file.
    Convert(cmd_convert::Args),
    /// Make a capture's fit choices (basis, objective, λ) once, for the parts of a
    /// sharded fit to reuse (`relit fit --plan PLAN --tile I/N`).
    Plan(cmd_plan::Args),
    /// Join the parts of a sharded fit (`relit fit --tile I/N`) into the single fit's file.
    Merge(cmd_merge::Args),
    /// Compare two images: PSNR (linear and 8-bit sRGB), SSIM, absolute errors, a
    /// difference picture.
    Compare(cmd_compare::Args),
    /// Measure fidelity: hold out captured lights, fit the rest, compare.
    // Boxed: eval has the most flags by far, and every other command would carry its size.
    Eval(Box<cmd_eval::Args>),
    /// Run the whole pipeline on a built-in scene: capture, fit, relight, compare.
    Demo(cmd_demo::Args),
    /// Render a synthetic capture (images, manifest, .lp, depth, mask) of a scene.
    Capture(cmd_capture::Args),
    /// Bake relightable maps from a scene's geometry (visibility, diffuse transfer or
    /// one-bounce colour bleeding projected onto SH), without a capture.
    Bake(cmd_bake::Args),
    /// Render a scene directly under lights: the ground truth relighting is compared with.
    RenderTruth(cmd_render_truth::Args),
    /// Measure relighting speed (CPU and GPU) against the machine's memory bandwidth.
    Bench(cmd_bench::Args),
    /// Serve the interactive relighting viewer (WebGL2) for a file on 127.0.0.1.
    View(cmd_view::Args),
    /// Write the viewer and a file's data as a static folder for any web server.
    ExportWeb(cmd_export_web::Args),
    /// Show what this machine can do (CPU kernels, GPU adapters, browser for the viewer
    /// test) and what to install for what it cannot.
    Doctor(cmd_doctor::Args),
}

/// Mesa's Vulkan drivers initialise Wayland support when wgpu asks for the
/// `VK_KHR_wayland_surface` extension, and libwayland prints "XDG_RUNTIME_DIR is
/// invalid or not set" once per adapter query on headless machines (CI, ssh). There is
/// no Wayland display to find either way, so point the variable at a private empty
/// folder, once, before any thread exists (setting the environment later would race
/// with readers in other threads).
fn quiet_headless_wayland() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
        // SAFETY: geteuid has no preconditions and cannot fail.
        let uid = unsafe { libc_geteuid() };
        let dir = std::env::temp_dir().join(format!("relit-runtime-{uid}"));
        let ok = std::fs::DirBuilder::new().mode(0o700).create(&dir).is_ok()
            || std::fs::metadata(&dir)
                .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.permissions().mode() & 0o077 == 0);
        if ok {
            std::env::set_var("XDG_RUNTIME_DIR", &dir);
        }
    }
}

#[cfg(unix)]
extern "C" {
    #[link_name = "geteuid"]
    fn libc_geteuid() -> u32;
    #[link_name = "signal"]
    fn libc_signal(signal: i32, handler: usize) -> usize;
}

/// Rust ignores SIGPIPE, so `relit info X | head` would panic on its next print once
/// `head` has gone; a command-line tool should end quietly as the others do.
fn default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: restoring the default action (SIG_DFL = 0) of SIGPIPE (13 on Linux and
    // the BSDs) before any thread exists has no preconditions.
    unsafe {
        libc_signal(13, 0);
    }
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
extern "C" {
    #[link_name = "mallopt"]
    fn glibc_mallopt(param: i32, value: i32) -> i32;
}

/// glibc raises its mmap threshold to the size of every large block freed, so that
/// later big buffers come from its heap and stay there once freed. A streamed fit
/// allocates and frees rows of a panorama part after part, and with the moving threshold
/// its peak grew with the panorama's width (40 MiB for a 2048-pixel-wide part, 49 MiB
/// for an 8192-wide one of the same pixels); with the threshold fixed, freed rows go
/// back to the system (34 and 36 MiB), in the same time.
///
/// The small blocks below it stay with the process once freed, though: glibc's default
/// gave the top of its heaps back whenever 128 KiB lay free there, and the basis
/// choice's many short-lived buffers were mapped, zeroed by the kernel and faulted in
/// again and again (a twelfth of RealRTI item3's samples were page faults). Keeping up
/// to 64 MiB free, and growing a heap 4 MiB at a time, took a tenth off the default
/// fit's time on the shared RTI items (`scripts/fit_releases.py`, same maps), for 0–3
/// MiB more peak memory.
///
/// The threshold is 2 MiB rather than 256 KiB: the compressed EXR blocks (about a
/// megabyte each) and the choice's larger buffers were otherwise mapped and faulted in
/// afresh each time (a twentieth of item3's samples). That took 5 % off the eight
/// items' summed time for 0.1–5.3 MiB more peak (item3 34.1 → 39.4, still 0.64× relight-cli's),
/// and the streamed fit's peak stays flat in the image's size (item1 repeated to
/// 2048×512, 4096×1024 and 8192×2048: 26.2–27.8, 27.0–28.6 and 28.2–29.2 MiB; 256 KiB:
/// 25.2–27.1, 26.6–27.1 and 26.4–28.3).
fn return_freed_buffers() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt(M_MMAP_THRESHOLD = -3 / M_TRIM_THRESHOLD = -1 / M_TOP_PAD = -2,
    // bytes) only sets glibc allocator parameters; called before any thread exists.
    unsafe {
        glibc_mallopt(-3, 2 << 20);
        glibc_mallopt(-1, 64 << 20);
        glibc_mallopt(-2, 4 << 20);
    }
}

fn main() {
    default_sigpipe();
    return_freed_buffers();
    quiet_headless_wayland();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Fit(args) => cmd_fit::run(args),
        Command::Relight(args) => cmd_relight::run(args),
        Command::Info(args) => cmd_info::run(args),
        Command::Normals(args) => cmd_normals::run(args),
        Command::Compare(args) => cmd_compare::run(args),
        Command::Convert(args) => cmd_convert::run(args),
        Command::Merge(args) => cmd_merge::run(args),
        Command::Plan(args) => cmd_plan::run(args),
        Command::Eval(args) => cmd_eval::run(*args),
        Command::Demo(args) => cmd_demo::run(args),
        Command::Capture(args) => cmd_capture::run(args),
        Command::RenderTruth(args) => cmd_render_truth::run(args),
        Command::Bake(args) => cmd_bake::run(args),
        Command::Bench(args) => cmd_bench::run(args),
        Command::View(args) => cmd_view::run(args),
        Command::ExportWeb(args) => cmd_export_web::run(args),
        Command::Doctor(args) => cmd_doctor::run(args),
    };
    if let Err(err) = result {
        eprintln!("relit: error: {err}");
        let mut source = err.source();
        while let Some(cause) = source {
            eprintln!("  caused by: {cause}");
            source = cause.source();
        }
        std::process::exit(1);
    }
}

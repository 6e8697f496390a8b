//! `relit bench --fit CAPTURE [--fit-args ARGS] [--peer BIN]`: the default fit (or the
//! fit `--fit-args` asks for) timed as a user meets it —
//! a fresh process, from start to file written — with its peak memory and the time of
//! each stage, beside another RTI fitter run on the same capture in the same run.
//!
//! Each fitter runs as a child process reaped with `wait4`, whose resource usage gives
//! that child's own peak resident memory (not the sum or maximum over earlier children).

use anyhow::Context;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

/// What one child process cost.
#[derive(Debug, serde::Serialize)]
struct Measured {
    command: String,
    wall_seconds: f64,
    peak_rss_bytes: u64,
    output_bytes: u64,
}

#[cfg(target_os = "linux")]
mod sys {
    #[repr(C)]
    pub struct Timeval {
        pub sec: i64,
        pub usec: i64,
    }

    /// `struct rusage` on 64-bit Linux: two timevals, then 14 longs.
    #[repr(C)]
    pub struct Rusage {
        pub utime: Timeval,
        pub stime: Timeval,
        pub maxrss_kib: i64,
        pub rest: [i64; 13],
    }

    extern "C" {
        pub fn wait4(pid: i32, status: *mut i32, options: i32, rusage: *mut Rusage) -> i32;
    }
}

/// Run `command` to its end: exit status (`Err` with its stderr where it failed), wall
/// seconds and the child's peak RSS.
fn run_measured(mut command: Command) -> anyhow::Result<(Result<(), String>, f64, u64)> {
    let start = Instant::now();
    let mut child = command
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .with_context(|| format!("starting {:?}", command.get_program()))?;
    #[cfg(target_os = "linux")]
    {
        let pid = child.id() as i32;
        // Drained while the child runs, so that a child writing more than a pipe holds
        // does not wait on us while we wait on it; shown where it fails.
        let stderr = child.stderr.take().map(|mut err| {
            std::thread::spawn(move || {
                let mut text = String::new();
                let _ = std::io::Read::read_to_string(&mut err, &mut text);
                text
            })
        });
        let mut status = 0i32;
        let mut usage: sys::Rusage = unsafe { std::mem::zeroed() };
        // SAFETY: `pid` is our own unreaped child; status and usage are valid pointers.
        let reaped = unsafe { sys::wait4(pid, &mut status, 0, &mut usage) };
        anyhow::ensure!(
            reaped == pid,
            "waiting for {:?} failed",
            command.get_program()
        );
        let wall = start.elapsed().as_secs_f64();
        let ok = status & 0x7f == 0 && (status >> 8) & 0xff == 0;
        let stderr = stderr
            .and_then(|reader| reader.join().ok())
            .unwrap_or_default();
        let outcome = if ok {
            Ok(())
        } else {
            Err(stderr.trim().to_string())
        };
        Ok((outcome, wall, usage.maxrss_kib.max(0) as u64 * 1024))
    }
    #[cfg(not(target_os = "linux"))]
    {
        let output = child.wait_with_output()?;
        let outcome = if output.status.success() {
            Ok(())
        } else {
            Err(String::from_utf8_lossy(&output.stderr).trim().to_string())
        };
        Ok((outcome, start.elapsed().as_secs_f64(), 0))
    }
}

/// Bytes under `path` (a file, or a folder's files).
fn bytes_under(path: &Path) -> u64 {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => m.len(),
        Ok(m) if m.is_dir() => std::fs::read_dir(path)
            .map(|entries| entries.flatten().map(|e| bytes_under(&e.path())).sum())
            .unwrap_or(0),
        _ => 0,
    }
}

/// Time `relit fit CAPTURE FIT_ARGS` (the default fit where `fit_args` is empty) and,
/// with `peer`, `PEER PEER_ARGS FOLDER OUT`, each in a fresh process.
pub fn run(
    capture: &Path,
    fit_args: &str,
    peer: Option<&Path>,
    peer_args: &str,
    json: bool,
) -> anyhow::Result<()> {
    anyhow::ensure!(
        capture.is_file(),
        "{} is not a capture file",
        capture.display()
    );
    let (_scratch, scratch) = relit_studio::scene_eval::scratch_dir()?;
    let exe = std::env::current_exe()?;
    let relit_out = scratch.join("relit.exr");
    let report_path = scratch.join("report.json");
    // The report goes to a file: the child's stdout is not read while it runs.
    let mut shell = Command::new("sh");
    shell.arg("-c").arg(
        "c=\"$1\" o=\"$2\" r=\"$3\"; shift 3; exec \"$0\" fit \"$c\" -o \"$o\" \"$@\" --json -q > \"$r\"",
    );
    shell
        .arg(&exe)
        .arg(capture)
        .arg(&relit_out)
        .arg(&report_path)
        .args(fit_args.split_whitespace());
    let (outcome, wall, rss) = run_measured(shell)?;
    let extra = if fit_args.trim().is_empty() {
        String::new()
    } else {
        format!(" {}", fit_args.trim())
    };
    if let Err(stderr) = outcome {
        anyhow::bail!("relit fit {}{extra} failed: {stderr}", capture.display());
    }
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&report_path)?)?;
    let relit = Measured {
        command: format!("relit fit {} -o OUT.exr{extra}", capture.display()),
        wall_seconds: wall,
        peak_rss_bytes: rss,
        output_bytes: bytes_under(&relit_out),
    };
    let peer = match peer {
        Some(bin) => {
            let folder = capture
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .unwrap_or(Path::new("."));
            let out = scratch.join("peer");
            let mut command = Command::new(bin);
            command
                .args(peer_args.split_whitespace())
                .arg(folder)
                .arg(&out);
            let description = format!("{} {peer_args} {} OUT", bin.display(), folder.display());
            let (outcome, wall, rss) = run_measured(command)?;
            if let Err(stderr) = outcome {
                anyhow::bail!("the peer failed: {description}: {stderr}");
            }
            Some(Measured {
                command: description,
                wall_seconds: wall,
                peak_rss_bytes: rss,
                output_bytes: bytes_under(&out),
            })
        }
        None => None,
    };
    let ratio = |f: fn(&Measured) -> f64| peer.as_ref().map(|p| f(&relit) / f(p).max(1e-9));
    let wall_ratio = ratio(|m| m.wall_seconds);
    let memory_ratio = ratio(|m| m.peak_rss_bytes as f64);
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "capture": capture.display().to_string(),
                "relit": relit,
                "relit_fit": {
                    "basis": report["basis"],
                    "seconds": report["seconds"],
                    "stages": report["stages"],
                },
                "peer": peer,
                "jpeg_decoder_simd": relit::image::jpeg_decoder_simd(),
                "wall_ratio": wall_ratio,
                "memory_ratio": memory_ratio,
            }))?
        );
        return Ok(());
    }
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    println!(
        "fit of {} (process start to file written)",
        capture.display()
    );
    println!(
        "{:<10} {:>9} {:>11} {:>11}  command",
        "", "wall s", "peak MiB", "output MiB"
    );
    for (name, m) in std::iter::once(("relit", &relit)).chain(peer.iter().map(|p| ("peer", p))) {
        println!(
            "{name:<10} {:>9.2} {:>11.1} {:>11.2}  {}",
            m.wall_seconds,
            mib(m.peak_rss_bytes),
            mib(m.output_bytes),
            m.command
        );
    }
    if let (Some(w), Some(m)) = (wall_ratio, memory_ratio) {
        println!("relit / peer: {w:.2}× the time, {m:.2}× the memory");
    }
    println!(
        "relit's stages ({}, {:.2} s inside the fit):",
        report["basis"].as_str().unwrap_or("?"),
        report["seconds"].as_f64().unwrap_or(0.0)
    );
    for stage in report["stages"].as_array().into_iter().flatten() {
        println!(
            "  {:<18} {:>7.2} s",
            stage["name"].as_str().unwrap_or(""),
            stage["seconds"].as_f64().unwrap_or(0.0)
        );
    }
    if !relit::image::jpeg_decoder_simd() {
        println!("note: {}", relit::image::JPEG_DECODER_ADVICE);
    }
    Ok(())
}

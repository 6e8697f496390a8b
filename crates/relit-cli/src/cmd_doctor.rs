//! `relit doctor`: what this machine can do with relit, and what to install for what it
//! cannot. Reads only: the CPU's features, the GPU adapters wgpu finds, and programs on
//! `PATH`; it changes nothing and always exits 0 (a report, not a check).

use serde_json::{json, Value};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Programs looked for, by what they serve: the viewer's browser test drives Chromium
/// with Node's Playwright (`scripts/test.sh`); `relit view` itself works in any browser
/// with WebGL2.
const BROWSERS: [&str; 4] = [
    "chromium",
    "chromium-browser",
    "google-chrome",
    "google-chrome-stable",
];

pub fn run(args: Args) -> anyhow::Result<()> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let jpeg_simd = relit::image::jpeg_decoder_simd();
    let cpu = json!({
        "model": proc_field("/proc/cpuinfo", "model name"),
        "threads": threads,
        "engine_threads": rayon::current_num_threads(),
        "kernels": relit::engine::cpu_kernels(),
        "jpeg_decoder_simd": jpeg_simd,
        "memory_bytes": proc_field("/proc/meminfo", "MemTotal")
            .and_then(|v| v.split_whitespace().next().and_then(|kb| kb.parse::<u64>().ok()))
            .map(|kb| kb * 1024),
    });
    let adapters = relit_gpu::adapters();
    let chosen = relit_gpu::probe();
    let gpu = json!({
        "adapters": adapters.iter().map(adapter_json).collect::<Vec<_>>(),
        "chosen": chosen.as_ref().ok().map(adapter_json),
        "error": chosen.as_ref().err().map(|e| e.to_string()),
    });
    let browser = BROWSERS.iter().find_map(|b| on_path(b));
    let node = on_path("node");
    let npm = on_path("npm");
    let tools = json!({
        "chromium": browser.as_ref().map(|p| p.display().to_string()),
        "node": node.as_ref().map(|p| p.display().to_string()),
        "npm": npm.as_ref().map(|p| p.display().to_string()),
    });

    let mut advice = Vec::new();
    if relit::engine::cpu_kernels() == "portable" {
        advice.push(
            "the CPU lacks AVX2/FMA/F16C (or is not x86-64): the engine runs its portable \
             loops, several times slower; nothing to install"
                .to_string(),
        );
    }
    if !jpeg_simd {
        advice.push(relit::image::JPEG_DECODER_ADVICE.to_string());
    }
    match &chosen {
        Err(_) => advice.push(
            "no GPU adapter: `relit relight --gpu` and the GPU benchmarks are unavailable; \
             install a Vulkan, Metal or DX12 driver (Debian/Ubuntu: `apt-get install \
             mesa-vulkan-drivers` gives a software Vulkan adapter, lavapipe)"
                .to_string(),
        ),
        Ok(a) if a.device_type == "Cpu" => advice.push(format!(
            "the GPU engine would run on a software adapter ({}): correct but slower than \
             the CPU engine; a hardware GPU's driver makes `--gpu` fast",
            a.name
        )),
        Ok(_) => {}
    }
    let viewer_test = browser.is_some() && node.is_some() && npm.is_some();
    if !viewer_test {
        let missing: Vec<&str> = [
            (browser.is_none(), "chromium"),
            (node.is_none(), "nodejs"),
            (npm.is_none(), "npm"),
        ]
        .iter()
        .filter(|(m, _)| *m)
        .map(|(_, name)| *name)
        .collect();
        advice.push(format!(
            "the viewer's browser test needs {} (Debian/Ubuntu: `apt-get install {}`; \
             scripts/test.sh installs them when it runs as root); `relit view` itself works \
             in any browser with WebGL2",
            missing.join(", "),
            missing.join(" ")
        ));
    }
    let can = json!({
        "fit_and_relight": true,
        "gpu_engine": chosen.is_ok(),
        "viewer_browser_test": viewer_test,
    });

    if args.json {
        let report = json!({
            "version": env!("CARGO_PKG_VERSION"),
            "cpu": cpu,
            "gpu": gpu,
            "tools": tools,
            "can": can,
            "advice": advice,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }

    println!("relit {}", env!("CARGO_PKG_VERSION"));
    println!(
        "CPU      {} — {threads} threads, engine kernels {}{}",
        cpu["model"].as_str().unwrap_or("unknown model"),
        relit::engine::cpu_kernels(),
        cpu["memory_bytes"]
            .as_u64()
            .map(|b| format!(", {:.1} GiB memory", b as f64 / (1u64 << 30) as f64))
            .unwrap_or_default()
    );
    println!(
        "JPEG     libjpeg-turbo {}",
        if jpeg_simd {
            "with SIMD"
        } else {
            "in portable C (no SIMD)"
        }
    );
    if adapters.is_empty() {
        println!("GPU      no adapter found");
    }
    for a in &adapters {
        let mark = match &chosen {
            Ok(c) if c.name == a.name && c.backend == a.backend => "  ← relit --gpu uses this",
            _ => "",
        };
        println!("GPU      {a}{mark}");
    }
    if let Err(e) = &chosen {
        println!("         {e}");
    }
    for (name, path) in [("chromium", &browser), ("node", &node), ("npm", &npm)] {
        println!(
            "{name:<8} {}",
            path.as_ref()
                .map_or("not found".to_string(), |p| p.display().to_string())
        );
    }
    println!(
        "can      fit and relight on the CPU: yes; GPU engine: {}; viewer browser test: {}",
        yes_no(chosen.is_ok()),
        yes_no(viewer_test)
    );
    for a in &advice {
        println!("advice   {a}");
    }
    Ok(())
}

fn yes_no(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

fn adapter_json(a: &relit_gpu::AdapterSummary) -> Value {
    json!({
        "name": a.name,
        "backend": a.backend,
        "device_type": a.device_type,
        "driver": a.driver,
    })
}

/// The value of the first `key: value` line of a `/proc` file (Linux), if any.
fn proc_field(file: &str, key: &str) -> Option<String> {
    let text = std::fs::read_to_string(file).ok()?;
    text.lines().find_map(|line| {
        let (k, v) = line.split_once(':')?;
        (k.trim() == key).then(|| v.trim().to_string())
    })
}

/// `program`'s path if an executable file of that name is on `PATH`.
fn on_path(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(program))
        .find(|p| is_executable(p))
}

fn is_executable(p: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        p.metadata()
            .map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
            .unwrap_or(false)
    }
    #[cfg(not(unix))]
    {
        p.is_file()
    }
}

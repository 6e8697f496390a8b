//! `relit normals`: surface normals (and albedo) by photometric stereo.

use crate::shared::{refuse_overwriting_inputs, Bars};
use anyhow::Context;
use relit::fsutil::Output;
use relit::normals::{self, Method};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A capture (`.lp` or manifest `.json`), or a relightable file (EXR, .rlz, .ptm,
    /// .rti) when the photographs are gone.
    pub input: PathBuf,
    /// The normal map: 8-bit PNG of (n + 1)/2 in the `.lp` frame (x right, y up, z toward
    /// the camera), or the vectors themselves as float OpenEXR when it ends in `.exr`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write the albedo (8-bit sRGB, or linear EXR).
    #[arg(long)]
    pub albedo: Option<PathBuf>,
    /// robust (trimmed start, then Tukey-reweighted least squares: shadows and
    /// highlights rejected) or ls (plain least squares over every light).
    #[arg(long, default_value = "robust", value_parser = |s: &str| Method::parse(s).map_err(|e| e.to_string()))]
    pub method: Method,
    /// Print a summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

fn is_capture(path: &Path) -> bool {
    matches!(
        path.extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref(),
        Some("lp") | Some("json")
    )
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut outputs = vec![Output::file(&args.output)];
    outputs.extend(args.albedo.iter().map(Output::file));
    refuse_overwriting_inputs(std::slice::from_ref(&args.input), &outputs)?;
    let start = std::time::Instant::now();
    let bars = Bars::new(args.quiet || args.json);
    let (map, source) = if is_capture(&args.input) {
        let capture = relit::capture::Capture::open(&args.input)?;
        refuse_overwriting_inputs(&capture.input_files(), &outputs)?;
        let map = normals::from_capture(&capture, args.method, &bars)?;
        (map, format!("{} photographs", capture.len()))
    } else {
        let image = relit::codec::read(&args.input)?;
        let basis = image.meta.basis.build()?.name();
        (
            normals::from_maps(&image, args.method)?,
            format!("the {basis} maps"),
        )
    };
    let write = |path: &Path, codes: Option<Vec<u8>>, float: relit::image::ImageRgb| {
        let is_exr = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        match codes {
            Some(codes) if !is_exr => {
                relit::image::save_srgb8_png(path, map.width, map.height, codes)
            }
            _ => relit::image::save(path, &float, 0.0),
        }
        .with_context(|| format!("writing {}", path.display()))
    };
    write(&args.output, Some(map.codes()), map.vectors())?;
    if let Some(albedo) = &args.albedo {
        write(albedo, None, map.albedo_image())?;
    }
    let seconds = start.elapsed().as_secs_f64();
    let solved = map
        .normals
        .iter()
        .filter(|n| n[2] != 0.0 || n[0] != 0.0)
        .count();
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "output": args.output.display().to_string(),
                "albedo": args.albedo.as_ref().map(|p| p.display().to_string()),
                "method": args.method,
                "width": map.width,
                "height": map.height,
                "solved_pixels": solved,
                "seconds": seconds,
            }))?
        );
    } else {
        println!(
            "wrote {} ({}×{}, {} photometric stereo on {source}, {solved} pixels solved) in {seconds:.2} s",
            args.output.display(),
            map.width,
            map.height,
            match args.method {
                Method::Robust => "robust",
                Method::Ls => "least-squares",
            }
        );
    }
    Ok(())
}

//! Pieces several subcommands share: fit flags, progress bars, formatting, and the
//! refusal to write over inputs.

use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use relit::fit::{BasisRequest, Criterion, FitOptions, Lambda, Objective, Regularizer};
use relit::fsutil::{check_outputs, Output, OutputKind};
use relit::light::RigFile;
use relit::maps::MapSpace;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// What the fit minimises (see the library docs of `relit::fit`).
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ObjectiveArg {
    /// Perceptual or linear, whichever predicts left-out images better on screen (validated
    /// with the basis; by exact leave-one-out for a fixed analytic basis on radiance
    /// captures).
    Auto,
    /// Squared residuals weighted by the sRGB curve's slope (display-space error).
    Perceptual,
    /// Plain least squares in linear radiance.
    Linear,
}

/// The space the stored maps are in.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SpaceArg {
    /// Linear radiance: lights add up physically (default).
    Linear,
    /// Display-referred sRGB values (single-light RTI publishing).
    Srgb,
}

/// The space a fit stores its maps in.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FitSpaceArg {
    /// For photographs with the automatic objective, linear radiance or display values,
    /// whichever validates better on the capture's own lights (with the basis); linear
    /// radiance otherwise.
    Auto,
    /// Linear radiance: lights add up physically.
    Linear,
    /// Display-referred sRGB values, fitted with plain least squares (each light's
    /// contribution is decoded to radiance before lights add up).
    Srgb,
}

/// The regulariser.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum RegularizerArg {
    /// Penalise the mean squared gradient over the sphere (constant term free).
    Roughness,
    /// Shrink every coefficient equally.
    Ridge,
}

/// What `--basis auto` judges its validation error in.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum CriterionArg {
    /// Linear radiance for radiance images (EXR, HDR), display values otherwise.
    Auto,
    /// sRGB display values clipped to white: the error a person sees on a screen.
    Display,
    /// Linear radiance, highlights above white included.
    Linear,
}

/// A `--basis` value, checked while parsing the command line (a bad one is a usage error).
pub fn parse_basis(s: &str) -> Result<BasisRequest, String> {
    BasisRequest::parse(s).map_err(|e| e.to_string())
}

/// The largest `--max-coefficients`.
const MOST_COEFFICIENTS: i64 = 64;

/// A `--candidate` value, `family:K` or a family, checked while parsing the command line
/// (a family is expanded once `--max-coefficients` is known).
pub fn parse_candidate(s: &str) -> Result<String, String> {
    relit::fit::parse_candidates(s, MOST_COEFFICIENTS as usize)
        .map(|_| s.trim().to_string())
        .map_err(|e| e.to_string())
}

/// Flags that shape a fit.
#[derive(Args, Debug, Clone)]
pub struct FitArgs {
    /// The basis: `auto` (chosen per capture by validation on its own lights) or
    /// `family:K` with K coefficients per colour channel (`sh:25`, `rbf:18`, …).
    #[arg(long, default_value = "auto", value_parser = parse_basis)]
    pub basis: BasisRequest,
    /// The most coefficients per colour channel `--basis auto` may choose.
    #[arg(long, default_value_t = relit::fit::DEFAULT_MAX_COEFFICIENTS as u16,
          value_parser = clap::value_parser!(u16).range(4..=MOST_COEFFICIENTS))]
    pub max_coefficients: u16,
    /// A basis `--basis auto` chooses among: `family:K`, or a family alone for its
    /// sizes of the ladder 4, 6, 9, 16, 25, 36, 49, 64 within `--max-coefficients`
    /// (`--candidate hsh --candidate ptm --max-coefficients 16`: what the RTI formats
    /// hold). Repeat the flag for more; default every family.
    #[arg(long = "candidate", value_parser = parse_candidate)]
    pub candidates: Vec<String>,
    /// Fit objective.
    #[arg(long, value_enum, default_value_t = ObjectiveArg::Auto)]
    pub objective: ObjectiveArg,
    /// Space of the stored maps (srgb fits display values with plain least squares).
    #[arg(long, value_enum, default_value_t = FitSpaceArg::Auto)]
    pub space: FitSpaceArg,
    /// Regulariser of the fit.
    #[arg(long, value_enum, default_value_t = RegularizerArg::Roughness)]
    pub regularizer: RegularizerArg,
    /// Regularisation weight λ, or `auto` to choose it per capture on its own lights
    /// (validated with the basis; by exact leave-one-out for a fixed analytic basis on
    /// radiance captures).
    #[arg(long, default_value = "auto")]
    pub lambda: String,
    /// Reweighting passes of the perceptual objective.
    #[arg(long, default_value_t = 1)]
    pub reweights: usize,
    /// What `--basis auto` judges candidates by: `auto` is linear radiance for captures
    /// of radiance images (EXR, HDR), the sRGB error on screen for photographs.
    #[arg(long, value_enum, default_value_t = CriterionArg::Auto)]
    pub criterion: CriterionArg,
    /// Pixels the fit reads first, to choose the basis, objective and λ on (a study's
    /// knob: `scripts/choice_stability.py`).
    #[arg(long, hide = true, default_value_t = relit::fit::FitOptions::default().subsample as u32,
          value_parser = clap::value_parser!(u32).range(16..=1 << 20))]
    pub subsample: u32,
    /// Pixels of that subsample `--basis auto` validates its finalists on.
    #[arg(long, hide = true, default_value_t = relit::fit::Halving::default().pixels as u32,
          value_parser = clap::value_parser!(u32).range(16..=1 << 20))]
    pub selection_pixels: u32,
    /// Pixels every candidate is screened on before the finalists are chosen.
    #[arg(long, hide = true, default_value_t = relit::fit::Halving::default().screening_pixels as u32,
          value_parser = clap::value_parser!(u32).range(8..=1 << 20))]
    pub screening_pixels: u32,
    /// (Candidate, variant) pairs the screening keeps for the full validation.
    #[arg(long, hide = true, default_value_t = relit::fit::Halving::default().finalists as u32,
          value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub finalists: u32,
}

impl FitArgs {
    /// The bases of `--candidate`, families expanded to their sizes, each once.
    fn candidate_bases(&self) -> anyhow::Result<Vec<relit::basis::BasisChoice>> {
        let mut out: Vec<relit::basis::BasisChoice> = Vec::new();
        for s in &self.candidates {
            for b in relit::fit::parse_candidates(s, self.max_coefficients as usize)? {
                if !out.contains(&b) {
                    out.push(b);
                }
            }
        }
        Ok(out)
    }

    pub fn to_options(&self) -> anyhow::Result<FitOptions> {
        anyhow::ensure!(
            self.candidates.is_empty() || matches!(self.basis, BasisRequest::Auto),
            "--candidate chooses among bases for --basis auto; --basis {} is one basis already",
            self.basis.name()
        );
        let lambda = if self.lambda.eq_ignore_ascii_case("auto") {
            Lambda::Auto
        } else {
            let v: f64 = self
                .lambda
                .parse()
                .map_err(|_| anyhow::anyhow!("--lambda must be `auto` or a number"))?;
            anyhow::ensure!(
                v.is_finite() && v >= 0.0,
                "--lambda must be a non-negative number"
            );
            Lambda::Fixed(v)
        };
        Ok(FitOptions {
            basis: self.basis.clone(),
            max_coefficients: self.max_coefficients as usize,
            candidates: self.candidate_bases()?,
            objective: match self.objective {
                ObjectiveArg::Auto => Objective::Auto,
                ObjectiveArg::Perceptual => Objective::Perceptual,
                ObjectiveArg::Linear => Objective::Linear,
            },
            color_space: match self.space {
                FitSpaceArg::Auto => None,
                FitSpaceArg::Linear => Some(MapSpace::Linear),
                FitSpaceArg::Srgb => Some(MapSpace::Srgb),
            },
            regularizer: match self.regularizer {
                RegularizerArg::Roughness => Regularizer::Roughness,
                RegularizerArg::Ridge => Regularizer::Ridge,
            },
            lambda,
            reweights: self.reweights,
            criterion: match self.criterion {
                CriterionArg::Auto => None,
                CriterionArg::Display => Some(Criterion::Display),
                CriterionArg::Linear => Some(Criterion::Linear),
            },
            subsample: self.subsample as usize,
            halving: relit::fit::Halving {
                screening_pixels: self.screening_pixels as usize,
                finalists: self.finalists as usize,
                pixels: self.selection_pixels as usize,
            },
            ..FitOptions::default()
        })
    }
}

/// How a compressed (`.rlz`) output is made (`relit::compress`).
#[derive(Args, Debug, Clone)]
pub struct CompressArgs {
    /// Colour layout of a compressed file: rgb, ycc (fewer chroma components) or lrgb
    /// (one luminance function × RGB albedo).
    #[arg(long, default_value = "rgb", value_parser = |s: &str| relit::compress::Layout::parse(s).map_err(|e| e.to_string()))]
    pub layout: relit::compress::Layout,
    /// Principal components per function (K′); default all K.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub components: Option<u16>,
    /// Components of ycc's chroma functions (default a third of K′).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub chroma: Option<u16>,
    /// Quantisation: the first plane's range in 2^bits − 1 steps (zstd planes; JPEG
    /// planes are 8-bit).
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u32).range(2..=16))]
    pub bits: u32,
    /// Plane codec: zstd[:level] (lossless codes), jpeg[:quality] or webp[:quality]
    /// (lossy 8-bit planes; WebP about a third smaller at equal error).
    #[arg(long, default_value = "zstd:12", value_parser = |s: &str| relit::compress::TileCodec::parse(s).map_err(|e| e.to_string()))]
    pub codec: relit::compress::TileCodec,
    /// Tile side in pixels of a compressed file (each tile is read and decoded alone).
    #[arg(long = "tile-size", default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub tile: u32,
    /// Vector quantisation (seed 004): every pixel an index into a codebook of this
    /// many entries (2–65536; zstd only). Directional and environment frames then
    /// relight the codebook and look pixels up.
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..=65536))]
    pub codebook: Option<u32>,
    /// With --codebook: keep the --components planes and vector-quantise only the next
    /// R principal components of each function (the PCA residual), one index a pixel
    /// beside the planes (any --codec; the indices are zstd).
    #[arg(long, requires = "codebook", value_parser = clap::value_parser!(u16).range(1..=64))]
    pub residual: Option<u16>,
    /// JPEG planes: `shared` (every plane with the first plane's step: few bits for the
    /// minor components) or `plane` (each over its own range: finer, many more bits).
    #[arg(long, default_value = "shared", value_parser = |s: &str| relit::compress::JpegRange::parse(s).map_err(|e| e.to_string()))]
    pub jpeg_range: relit::compress::JpegRange,
    /// Divide the function planes by a stored per-pixel perceptual gain, so that one
    /// quantiser step shows as the same error on screen in dark and bright pixels (not
    /// with --codebook).
    #[arg(long)]
    pub gain: bool,
    /// Find the principal components (--components) per block of N×N pixels instead of
    /// once for the file: each block keeps the K′ functions that suit it (and ycc's
    /// chroma its own), for (K′ + chroma) × K numbers a block (not with --codebook).
    #[arg(long = "pca-block", value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub pca_block: Option<u32>,
    /// Store mip levels too (each the 2×2 means of the one above, coded with level 0's
    /// planes and quantisers: about a third more bytes), so that the viewer and `relit
    /// relight --level` read a zoomed-out view's tiles from its level (not with
    /// --codebook or --pca-block).
    #[arg(long)]
    pub mip: bool,
}

impl CompressArgs {
    pub fn settings(&self) -> relit::compress::Settings {
        relit::compress::Settings {
            layout: self.layout,
            components: self.components.map(usize::from),
            chroma: self.chroma.map(usize::from),
            bits: self.bits,
            codec: self.codec,
            tile: self.tile as usize,
            codebook: self.codebook.map(|c| c as usize),
            residual: self.residual.map(usize::from),
            jpeg_range: self.jpeg_range,
            directions: None,
            gain: self.gain,
            pca_block: self.pca_block.map(|b| b as usize),
            mip_levels: self.mip,
        }
    }

    /// [`CompressArgs::settings`], with `--mip-tiles N` (of `relit fit` and `relit
    /// convert`): mip levels in tiles of N.
    pub fn settings_with_mip_tiles(&self, mip_tiles: Option<usize>) -> relit::compress::Settings {
        let mut settings = self.settings();
        if let Some(tile) = mip_tiles {
            settings.tile = tile;
            settings.mip_levels = true;
        }
        settings
    }
}

/// How a relight/OpenLIME web folder is written (`relit::codec::web`).
#[derive(Args, Debug, Clone)]
pub struct WebArgs {
    /// JPEG quality of a web folder's plane images.
    #[arg(long, default_value_t = 95, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub quality: u8,
    /// Planes of a web folder written as `bilinear` (bases other than display-referred
    /// ptm:6 and hsh:9): principal components, a multiple of 3.
    #[arg(long, default_value_t = 18)]
    pub planes: usize,
    /// Nodes per side of a `bilinear` web folder's light grid (2 to 12; relight writes
    /// 8). Default: a bilinear basis' own grid (at most 12), 12 for any other basis.
    #[arg(long)]
    pub grid: Option<usize>,
    /// How a web folder's plane images are laid out, by OpenLIME's layout names: single
    /// images, or tiled pyramids for big images (Deep Zoom files, or one tarzoom file
    /// per plane image, or one itarzoom file for all).
    #[arg(long, value_enum, default_value_t = WebLayoutArg::Image)]
    pub web_layout: WebLayoutArg,
    /// The same as `--web-layout deepzoom`.
    #[arg(long, conflicts_with = "web_layout")]
    pub deep_zoom: bool,
    /// Write display-referred ptm, hsh and sh maps in relight's `lrgb` colour space (one
    /// colour image times a luminance per function: about a third of the planes, the
    /// colour no longer varying with the light) instead of `rgb`.
    #[arg(long)]
    pub lrgb: bool,
    /// The functions a web folder holds: `auto` writes display-referred ptm:6, hsh:9 and
    /// sh:9 maps as those types and the rest as `bilinear`; `bilinear` and `rbf` write
    /// principal components on relight's light grid or at blended nodes.
    #[arg(long, value_enum, default_value_t = WebTypeArg::Auto)]
    pub web_type: WebTypeArg,
    /// Nodes of an `rbf` web folder, spread over the upper hemisphere.
    #[arg(long, default_value_t = relit::codec::web::DEFAULT_RBF_NODES)]
    pub rbf_nodes: usize,
    /// Write a `bilinear` or `rbf` web folder in relight's `mycc` colour space (luma and
    /// chroma, each with its own components) with this many planes per chroma channel
    /// (default: a third of `--planes`, the layout OpenLIME 1.2.6 reads as relight means
    /// it; fewer is relight's own, smaller layout).
    #[arg(long, num_args = 0..=1, default_missing_value = "0")]
    pub mycc: Option<usize>,
}

/// The functions of a web folder.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum WebTypeArg {
    Auto,
    Bilinear,
    Rbf,
}

/// OpenLIME's layouts that relit writes.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum WebLayoutArg {
    Image,
    Deepzoom,
    Tarzoom,
    Itarzoom,
}

impl WebArgs {
    pub fn layout(&self) -> relit::codec::web::Layout {
        use relit::codec::web::Layout;
        match (self.deep_zoom, self.web_layout) {
            (true, _) | (_, WebLayoutArg::Deepzoom) => Layout::DeepZoom,
            (_, WebLayoutArg::Image) => Layout::Image,
            (_, WebLayoutArg::Tarzoom) => Layout::Tarzoom,
            (_, WebLayoutArg::Itarzoom) => Layout::Itarzoom,
        }
    }

    pub fn options(&self) -> relit::codec::web::WriteOptions {
        use relit::codec::web::WebFunctions;
        relit::codec::web::WriteOptions {
            quality: self.quality,
            planes: self.planes,
            resolution: self.grid,
            layout: self.layout(),
            lrgb: self.lrgb,
            functions: match self.web_type {
                WebTypeArg::Auto => WebFunctions::Auto,
                WebTypeArg::Bilinear => WebFunctions::Bilinear,
                WebTypeArg::Rbf => WebFunctions::Rbf,
            },
            rbf_nodes: self.rbf_nodes,
            chroma_planes: self.mycc.map(|c| if c == 0 { self.planes / 3 } else { c }),
        }
    }
}

/// Whether to write a `.rlz` file of `shape` (width, height, most coefficients) a band of
/// rows at a time: [`relit::compress::bands::worth_packing_in_bands`], above
/// `RELIT_BANDS_ABOVE_MIB` MiB of maps where that is set (0: always where the settings
/// allow), [`relit::compress::bands::BANDS_ABOVE_BYTES`] otherwise.
pub fn pack_in_bands(settings: &relit::compress::Settings, shape: (usize, usize, usize)) -> bool {
    let above = std::env::var("RELIT_BANDS_ABOVE_MIB")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .map_or(relit::compress::bands::BANDS_ABOVE_BYTES, |mib| mib << 20);
    relit::compress::bands::worth_packing_in_bands(settings, shape, above)
}

/// A temporary file named `prefix…suffix` in `output`'s folder (where the output will
/// fit, unlike `/tmp`), removed when the returned path is dropped.
pub fn temporary_beside(
    output: &Path,
    prefix: &str,
    suffix: &str,
) -> anyhow::Result<tempfile::TempPath> {
    use anyhow::Context;
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    Ok(tempfile::Builder::new()
        .prefix(prefix)
        .suffix(suffix)
        .tempfile_in(&dir)
        .with_context(|| format!("creating a temporary file in {}", dir.display()))?
        .into_temp_path())
}

/// Bytes of a file, or of every file in a folder (one level deep and below).
pub fn size_on_disk(path: &Path) -> std::io::Result<u64> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_dir() {
        return Ok(meta.len());
    }
    let mut total = 0;
    for entry in std::fs::read_dir(path)? {
        total += size_on_disk(&entry?.path())?;
    }
    Ok(total)
}

/// Progress bars on standard error (hidden when it is not a terminal or when quiet).
pub struct Bars {
    bar: Mutex<Option<ProgressBar>>,
    quiet: bool,
}

impl Bars {
    pub fn new(quiet: bool) -> Self {
        Self {
            bar: Mutex::new(None),
            quiet,
        }
    }
}

impl relit::progress::Progress for Bars {
    fn begin(&self, stage: &str, total: u64) {
        if self.quiet {
            return;
        }
        let bar = ProgressBar::new(total);
        bar.set_style(
            ProgressStyle::with_template(
                "{msg:>16} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        bar.set_message(stage.to_string());
        *self.bar.lock().expect("progress lock") = Some(bar);
    }
    fn advance(&self, n: u64) {
        if let Some(bar) = self.bar.lock().expect("progress lock").as_ref() {
            bar.inc(n);
        }
    }
    fn end(&self) {
        if let Some(bar) = self.bar.lock().expect("progress lock").take() {
            bar.finish_and_clear();
        }
    }
}

/// Bytes for people.
pub fn mib(bytes: Option<u64>) -> String {
    bytes
        .map(relit::memory::mib)
        .unwrap_or_else(|| "n/a".into())
}

/// Refuse, before any work, outputs that would write over one of `inputs` (see
/// `relit::fsutil::check_outputs`). Commands call it as soon as they know their
/// inputs, again when the inputs have named further files.
pub fn refuse_overwriting_inputs(inputs: &[PathBuf], outputs: &[Output]) -> anyhow::Result<()> {
    check_outputs(inputs, outputs)?;
    // The running program is read too. Only a file output can replace it: folder
    // outputs hold files named by the command, never the program's name.
    if let Ok(program) = std::env::current_exe() {
        for output in outputs.iter().filter(|o| o.kind == OutputKind::File) {
            if check_outputs(std::slice::from_ref(&program), std::slice::from_ref(output)).is_err()
            {
                anyhow::bail!(
                    "refusing to write {}: it is the running relit program ({}); nothing was written",
                    output.path.display(),
                    program.display()
                );
            }
        }
    }
    Ok(())
}

/// A rig file and the files its lights read (slides, environment maps, resolved
/// against the rig's folder). A rig that does not parse is just itself: the command
/// reports why when it reads it.
pub fn rig_inputs(rig: &Path) -> Vec<PathBuf> {
    let base = rig.parent().unwrap_or(Path::new(""));
    let mut files = vec![rig.to_path_buf()];
    if let Ok(file) = RigFile::load(rig) {
        files.extend(file.referenced_files(base));
    }
    files
}

/// The files a studio scene spec and light plan name directly (a scene file, a
/// `list:` file); those the scene file names come from `Scene::files` once it is open.
pub fn scene_inputs(scene: &str, plan: Option<&str>) -> Vec<PathBuf> {
    relit_studio::scene_path(scene)
        .into_iter()
        .chain(plan.and_then(relit_studio::plan::LightPlan::list_file))
        .map(Path::to_path_buf)
        .collect()
}

/// What a `.ptm` or `.rti` file's values are, when told (`--file-space`): these files
/// carry no colour-space marker. relit reads them as display-referred sRGB codes, the
/// formats' convention (RTIViewer, PTMfitter, RTIBuilder, `relight-cli -I srgb`);
/// relight-cli's default writes linear-light values instead.
pub fn apply_file_space(
    path: &Path,
    image: &mut relit::maps::RelightableImage,
    space: Option<SpaceArg>,
) -> anyhow::Result<()> {
    let Some(space) = space else {
        return Ok(());
    };
    let form = relit::codec::FileForm::of(path)?;
    anyhow::ensure!(
        matches!(form, relit::codec::FileForm::Ptm | relit::codec::FileForm::Rti),
        "--file-space applies to .ptm and .rti files, which carry no colour space; {} states its own",
        path.display()
    );
    image.meta.color_space = match space {
        SpaceArg::Linear => relit::maps::MapSpace::Linear,
        SpaceArg::Srgb => relit::maps::MapSpace::Srgb,
    };
    Ok(())
}

/// A studio scene and the camera that sees it, as every command that renders one takes
/// them.
#[derive(clap::Args, Debug)]
pub struct SceneArgs {
    /// The scene: a built-in name (attic, city, box), an .obj file or a .json scene file.
    pub scene: String,
    /// Camera: cylindrical[:FOV], equirect, perspective[:FOV] or orthographic[:HEIGHT]
    /// (default: the scene's own). The scene's eye and orientation are kept.
    #[arg(long)]
    pub camera: Option<String>,
    /// Image size WIDTHxHEIGHT (default: the scene's, or the camera's usual size).
    #[arg(long)]
    pub size: Option<String>,
}

impl SceneArgs {
    /// Parse the camera options, open the scene (refusing `outputs` that would replace
    /// any file it reads), print its warnings as `command`, and build the camera.
    pub fn open(
        &self,
        command: &str,
        outputs: &[relit::fsutil::Output],
    ) -> anyhow::Result<(relit_studio::scene::Scene, relit::camera::Camera)> {
        use anyhow::Context;
        use relit_studio::setup;
        let projection = self
            .camera
            .as_deref()
            .map(setup::parse_projection)
            .transpose()?;
        let size = self.size.as_deref().map(setup::parse_size).transpose()?;
        let scene = relit_studio::open_scene(&self.scene)
            .with_context(|| format!("opening scene `{}`", self.scene))?;
        refuse_overwriting_inputs(&scene.files, outputs)?;
        for warning in &scene.warnings {
            eprintln!("relit {command}: warning: {warning}");
        }
        let camera = setup::scene_camera(&scene, projection.as_ref(), size)?;
        Ok((scene, camera))
    }
}

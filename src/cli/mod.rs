//! The command line's parts: each subcommand in its own file, and here
//! the arguments and helpers they share.

pub(crate) mod animate;
#[cfg(feature = "lab")]
pub(crate) mod bench;
#[cfg(feature = "farm")]
pub(crate) mod farm;
pub(crate) mod render;
#[cfg(feature = "lab")]
pub(crate) mod tradeoff;
#[cfg(feature = "lab")]
pub(crate) mod validate;
mod verify;
#[cfg(feature = "view")]
pub(crate) mod view;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;

use retrace::accel::{Accelerator, BackendKind};
use retrace::aov::{exr_picture, Aov, AovSet};
use retrace::camera::Projection;
use retrace::frame_loop::ViewOutput;
use retrace::output::{
    frame_format_for, read_exr, save_exr_pending, save_image_pending, FrameFormat, PendingFile,
};
use retrace::sampling::PixelSamples;
use retrace::scene::{load_scene, paper_scene, Scene, SceneOverrides};
use retrace::texture::TextureFilter;

#[derive(Args, Clone)]
struct SceneArgs {
    /// Scene file (.toml) or OBJ model; the built-in paper scene if omitted.
    scene: Option<PathBuf>,
    /// Image width in pixels: the camera's (RSVP viewports keep their own
    /// sizes).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels (as for --width).
    #[arg(long)]
    height: Option<u32>,
    /// Camera projection.
    #[arg(long, value_parser = projection_parser())]
    camera: Option<Projection>,
    /// Horizontal field of view in degrees.
    #[arg(long, allow_negative_numbers = true, value_parser = finite_number)]
    fov: Option<f64>,
    /// Samples per pixel, 1 to 256 (antialiasing: stratified sub-pixel
    /// positions, box-filtered) [default: the scene's `[render] spp`, or 1].
    #[arg(long)]
    spp: Option<u32>,
    /// Shadow rays each pixel sample casts to each area light, 1 to 256
    /// (stratified over the light; point lights take one)
    /// [default: the scene's `[render] light_samples`, or 4].
    #[arg(long, value_name = "N")]
    light_samples: Option<u32>,
    /// The most memory textures may take, in MB (texels and mip levels at
    /// 4 bytes a texel) [default: 1024].
    #[arg(long, value_name = "MB")]
    texture_memory: Option<u64>,
    /// How textures are filtered: trilinear (mip-mapped by each ray's
    /// footprint), bilinear or nearest (the full-size image only)
    /// [default: trilinear].
    #[arg(long, value_parser = str::parse::<TextureFilter>)]
    texture_filter: Option<TextureFilter>,
    /// A bare OBJ model's up axis: y (most tools) or z (CAD, 3ds Max),
    /// stood up as y [default: y]. A scene file turns its mesh objects
    /// with `rotate`.
    #[arg(long, value_parser = up_parser())]
    up: Option<retrace::scene::UpAxis>,
}

impl SceneArgs {
    /// What the flags change of the scene file's settings.
    fn overrides(&self) -> SceneOverrides {
        SceneOverrides {
            width: self.width,
            height: self.height,
            projection: self.camera,
            fov: self.fov,
            spp: self.spp,
            light_samples: self.light_samples,
            texture_memory_mb: self.texture_memory,
            texture_filter: self.texture_filter,
            up: self.up,
        }
    }
}

#[derive(Args)]
struct BackendArg {
    /// Intersection backend: embree, or grid (the pure-Rust reference).
    #[arg(long, default_value = "embree", value_parser = parse_backend)]
    backend: BackendKind,
    /// Grid backend: cells per axis of the world grid, N or XxYxZ (default:
    /// chosen from the primitive count).
    #[arg(long, value_parser = parse_resolution)]
    grid_resolution: Option<[u32; 3]>,
}

impl BackendArg {
    fn build(&self, scene: &Scene) -> Result<Accelerator> {
        Ok(Accelerator::build_with(
            self.backend,
            &scene.objects,
            self.grid_resolution()?,
        )?)
    }

    /// The grid's resolution asked for; refused with Embree, which would
    /// ignore it.
    fn grid_resolution(&self) -> Result<Option<[u32; 3]>> {
        if self.grid_resolution.is_some() && self.backend != BackendKind::Grid {
            anyhow::bail!(
                "--grid-resolution sets the grid backend's cells: add --backend grid \
                 (Embree builds its own hierarchy)"
            );
        }
        Ok(self.grid_resolution)
    }
}

fn parse_resolution(s: &str) -> Result<[u32; 3], String> {
    let parts: Vec<&str> = s.split('x').collect();
    let numbers: Vec<u32> = parts
        .iter()
        .map(|p| p.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}' is not N or XxYxZ"))?;
    let resolution = match numbers[..] {
        [n] => [n; 3],
        [x, y, z] => [x, y, z],
        _ => return Err(format!("'{s}' is not N or XxYxZ")),
    };
    if resolution.iter().any(|&n| n == 0 || n > 1024) {
        return Err(format!("'{s}': each axis needs 1 to 1024 cells"));
    }
    Ok(resolution)
}

/// The projections `--camera` takes, as `Projection` names them.
const PROJECTIONS: [&str; 3] = ["perspective", "equal-angle", "fisheye"];

/// `--camera`'s parser: `--help` and a wrong value list the projections.
fn projection_parser() -> impl clap::builder::TypedValueParser<Value = Projection> {
    use clap::builder::TypedValueParser as _;
    clap::builder::PossibleValuesParser::new(PROJECTIONS).try_map(|s| s.parse::<Projection>())
}

/// A number flag's parser: a value a 64-bit float cannot hold is refused
/// as the user wrote it, where the parsed infinity (`1e400`) would be
/// reported as `inf`. Each flag's own range is checked where its meaning
/// is, with the value printed short (`1e300`).
fn finite_number(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err("a finite number is needed (a 64-bit float holds at most ±1.8e308)".into()),
        Err(_) => Err("not a number".into()),
    }
}

/// Refuses a run whose `estimate` is more memory than the machine has
/// available, before any work, with the figure and what lowers it.
pub(crate) fn check_memory(estimate: &retrace::frame_loop::MemoryEstimate) -> Result<()> {
    use retrace::frame_loop::{available_bytes, bytes_text};
    match available_bytes() {
        Some(available) if estimate.total() > available => anyhow::bail!(
            "this run would need about {}, more than the {} this machine has available: \
             lower --width and --height, or --spp",
            estimate.describe(),
            bytes_text(available)
        ),
        _ => Ok(()),
    }
}

/// Says what the run held at its peak beside what was estimated before it.
pub(crate) fn say_memory(estimate: &retrace::frame_loop::MemoryEstimate) {
    use retrace::frame_loop::{bytes_text, peak_resident_bytes};
    if let Some(peak) = peak_resident_bytes() {
        say!(
            "memory: {} at the peak (estimated {} before the run)",
            bytes_text(peak),
            bytes_text(estimate.total())
        );
    }
}

/// `--up`'s parser: `--help` and a wrong value list the axes.
fn up_parser() -> impl clap::builder::TypedValueParser<Value = retrace::scene::UpAxis> {
    use clap::builder::TypedValueParser as _;
    clap::builder::PossibleValuesParser::new(["y", "z"]).try_map(|s| s.parse())
}

/// What `bench`'s shared arguments say of it alone, added to the command
/// line before it is parsed: its `--width` and `--height` size its
/// viewports too.
pub(crate) fn finish_command(command: clap::Command) -> clap::Command {
    let bench = command.get_name() == "bench";
    command
        .mut_args(|arg| match arg.get_id().as_str() {
            "width" if bench => {
                arg.help("Image width in pixels: the camera's, and each RSVP viewport's too")
            }
            "height" if bench => arg.help("Image height in pixels (as for --width)"),
            _ => arg,
        })
        .mut_subcommands(finish_command)
}

/// `--frames`'s value as given (every `--frames` takes one that starts
/// with `-`, so `--frames -3` gets `parse_frame_range`'s words rather than
/// clap's hint to write `-- -3`, which would not work either), unless it
/// is a flag (`--frames --gif a.gif`: a usage error).
fn frame_range_text(s: &str) -> Result<String, String> {
    let after_dash = s.strip_prefix('-').map(|rest| rest.trim_start());
    if after_dash.is_some_and(|rest| !rest.starts_with(|c: char| c.is_ascii_digit())) {
        return Err(format!(
            "'{s}' is a flag, not a frame range: give A-B (inclusive) or A, e.g. 0-49"
        ));
    }
    Ok(s.to_string())
}

fn parse_backend(s: &str) -> Result<BackendKind, String> {
    s.parse()
}

#[derive(Args)]
struct RsvpKnobArgs {
    /// RSVP reconstruction filter: nearest, bilinear, box or pixel-box
    /// (a box as wide as the pixel, blended in linear colour, one pass at
    /// any --spp) [default: bilinear; pixel-box at --spp 2 to 16; box
    /// above 16].
    #[arg(long)]
    filter: Option<retrace::reuse::rsvp::Filter>,
    /// RSVP: buffer samples per viewport pixel (per side) the pyramid level
    /// is chosen for, at least (0.01 to 8; with --spp N, per sub-pixel
    /// shift; the pixel box's per quarter of N) [default: 0.71; with the
    /// pixel box 1, 1.19 above --spp 4].
    #[arg(long, value_parser = finite_number)]
    oversample: Option<f64>,
    /// RSVP: pyramid levels added to the chosen one (negative: coarser;
    /// -4 to 4) [default: 0].
    #[arg(long, allow_negative_numbers = true)]
    level_bias: Option<i32>,
}

impl RsvpKnobArgs {
    /// The knobs asked for, the rest at their defaults for `samples` a
    /// pixel.
    fn knobs(&self, samples: PixelSamples) -> Result<retrace::reuse::rsvp::RsvpKnobs> {
        let filter = self
            .filter
            .unwrap_or(retrace::reuse::rsvp::RsvpKnobs::default_for(samples).filter);
        let default = retrace::reuse::rsvp::RsvpKnobs::with_filter(filter, samples);
        let oversample = self.oversample.unwrap_or(default.oversample);
        let level_bias = self.level_bias.unwrap_or(default.level_bias);
        // Finer than 8 samples a pixel, or 4 levels past the one chosen, a
        // pixel's reads land a tile of the store apart each: memory grows
        // with the spacing and bilinear reads gain nothing.
        if !(0.01..=8.0).contains(&oversample) {
            anyhow::bail!("--oversample {oversample}: must be within 0.01..8");
        }
        if !(-4..=4).contains(&level_bias) {
            anyhow::bail!("--level-bias {level_bias}: must be within -4..4");
        }
        Ok(retrace::reuse::rsvp::RsvpKnobs {
            filter,
            oversample,
            level_bias,
        })
    }

    /// The first knob given on the command line, if any.
    fn given(&self) -> Option<&'static str> {
        [
            ("--filter", self.filter.is_some()),
            ("--oversample", self.oversample.is_some()),
            ("--level-bias", self.level_bias.is_some()),
        ]
        .into_iter()
        .find_map(|(flag, given)| given.then_some(flag))
    }
}

#[derive(Args)]
struct OstcArgs {
    /// OSTC: the screen is cut into N x N regions, each a whole number of
    /// 4x2-pixel sample groups (the paper's 16: 40x30 pixels at 640x480);
    /// finer regions re-trace less but take more memory for their bits
    /// [default: one group a region for the camera's image (240 at
    /// 640x480); 160, 4x4 pixels at 640x480, with viewports].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    regions: Option<u32>,
    /// OSTC: about this many voxels in the grid over the moving objects'
    /// swept volume [default: 1].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16_777_216))]
    ostc_voxels: Option<u32>,
}

impl OstcArgs {
    fn settings(&self) -> retrace::frame_loop::OstcSettings {
        let default = retrace::frame_loop::OstcSettings::default();
        retrace::frame_loop::OstcSettings {
            regions: self
                .regions
                .map(retrace::reuse::regions::RegionGrid)
                .or(default.regions),
            voxels: self.ostc_voxels.unwrap_or(default.voxels),
        }
    }

    /// The first OSTC flag given on the command line, if any.
    fn given(&self) -> Option<&'static str> {
        [
            ("--regions", self.regions.is_some()),
            ("--ostc-voxels", self.ostc_voxels.is_some()),
        ]
        .into_iter()
        .find_map(|(flag, given)| given.then_some(flag))
    }
}

/// A flag that cannot act on this run, refused with the reason: every
/// command says it the same way.
fn idle_flag(flag: &str, reason: &str) -> anyhow::Error {
    anyhow::anyhow!("{flag} has nothing to act on in this run: {reason}")
}

fn load(args: &SceneArgs) -> Result<Scene> {
    let overrides = args.overrides();
    let scene = match &args.scene {
        Some(path) => load_scene(path, &overrides)?,
        None => paper_scene(&overrides)?,
    };
    for warning in &scene.warnings {
        eprintln!("warning: {warning}");
    }
    Ok(scene)
}

fn scene_name(args: &SceneArgs) -> String {
    args.scene
        .as_deref()
        .map_or("built-in paper scene".to_string(), |p| {
            p.display().to_string()
        })
}

/// Makes the folder `path` is written into.
fn ensure_parent(path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        make_folder(dir, path.file_name().map(Path::new))?;
    }
    Ok(())
}

/// Fails, before any work, if a file stands where a folder of `path`
/// would have to be made; makes nothing.
fn check_parent(path: &Path) -> Result<()> {
    match path.parent().and_then(file_in_the_way) {
        Some(blocker) => Err(in_the_way(blocker, path.file_name().map(Path::new))),
        None => Ok(()),
    }
}

/// Makes the folder `dir` and its parents, for the output `file` if one
/// is known. A file where a folder should be is named: the system's own
/// words ("File exists") name neither it nor the problem.
fn make_folder(dir: &Path, file: Option<&Path>) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|err| match file_in_the_way(dir) {
        Some(blocker) => in_the_way(blocker, file),
        None => anyhow::Error::new(err)
            .context(format!("cannot create output folder {}", dir.display())),
    })
}

/// The folder of `dir`, or of its parents, that is a file instead.
fn file_in_the_way(dir: &Path) -> Option<&Path> {
    dir.ancestors()
        .filter(|a| !a.as_os_str().is_empty())
        .find(|a| a.exists() && !a.is_dir())
}

fn in_the_way(blocker: &Path, file: Option<&Path>) -> anyhow::Error {
    let for_file = file.map_or(String::new(), |f| format!(" for {}", f.display()));
    anyhow::anyhow!(
        "cannot make the folder {}{for_file}: a file of that name is in the way",
        blocker.display()
    )
}

/// `A-B` or `A`, within `0..count`.
fn parse_frame_range(text: Option<&str>, count: u32) -> Result<std::ops::RangeInclusive<u32>> {
    let Some(text) = text else {
        return Ok(0..=count - 1);
    };
    let parse = |s: &str| -> Result<u32> {
        if s.trim().starts_with('-') {
            anyhow::bail!("--frames {text}: {NOT_NEGATIVE}: {FORM}");
        }
        s.trim()
            .parse()
            .with_context(|| format!("--frames {text}: '{s}' is not a frame number ({FORM})"))
    };
    const FORM: &str = "give A-B (inclusive) or A, e.g. 0-49";
    const NOT_NEGATIVE: &str = "frames are numbered from 0, never below";
    if text.trim_start().starts_with('-') {
        anyhow::bail!("--frames {text}: {NOT_NEGATIVE}: {FORM}");
    }
    let (first, last) = match text.split_once('-') {
        Some((a, b)) => (parse(a)?, parse(b)?),
        None => {
            let frame = parse(text)?;
            (frame, frame)
        }
    };
    if first > last {
        anyhow::bail!("--frames {text}: the first frame comes after the last");
    }
    if last >= count {
        anyhow::bail!("--frames {text}: the animation has frames 0-{}", count - 1);
    }
    Ok(first..=last)
}

/// A frame file pattern (`out/frame_####.png`): a run of `#` becomes the
/// zero-padded frame number, and a view's name (an RSVP viewport's) goes
/// before the extension (`out/frame_0007_zoomed.png`).
pub(crate) struct FramePattern {
    prefix: String,
    digits: usize,
    suffix: String,
}

impl FramePattern {
    /// `pattern` of rendered frames, checked: one run of `#` in the file
    /// name, and a frame format the extension names (PNG, TGA or EXR).
    pub(crate) fn parse(pattern: &str) -> Result<FramePattern> {
        let parsed = Self::split(pattern)?;
        frame_format_for(&parsed.path(0, ""))?;
        Ok(parsed)
    }

    /// `pattern` of 8-bit pictures (PNG or TGA), checked as
    /// [`FramePattern::parse`] checks frames.
    pub(crate) fn parse_picture(pattern: &str) -> Result<FramePattern> {
        let parsed = Self::split(pattern)?;
        retrace::output::format_for(&parsed.path(0, ""))?;
        Ok(parsed)
    }

    fn split(pattern: &str) -> Result<FramePattern> {
        let (prefix, digits, suffix) = frame_pattern(pattern)?;
        Ok(FramePattern {
            prefix,
            digits,
            suffix,
        })
    }

    /// What the files are written as.
    pub(crate) fn format(&self) -> FrameFormat {
        frame_format_for(&self.path(0, "")).expect("checked when parsed")
    }

    /// The file of view `view` (empty: the camera's image) at `frame`.
    pub(crate) fn path(&self, frame: u32, view: &str) -> PathBuf {
        let (prefix, digits, suffix) = (&self.prefix, self.digits, &self.suffix);
        if view.is_empty() {
            return PathBuf::from(format!("{prefix}{frame:0digits$}{suffix}"));
        }
        let (stem, ext) = match suffix.rfind('.') {
            Some(dot) if !suffix[dot..].contains('/') => suffix.split_at(dot),
            _ => (suffix.as_str(), ""),
        };
        PathBuf::from(format!("{prefix}{frame:0digits$}{stem}_{view}{ext}"))
    }
}

/// `--aov`, which `render` and `animate` share.
#[derive(Args)]
struct AovArgs {
    /// Arbitrary output variables, written as layers of an OpenEXR frame
    /// (-o NAME.exr): a comma list of depth, normal, albedo, object,
    /// traced (see the user's guide for what each holds).
    #[arg(long, value_name = "LIST", value_parser = AovSet::parse)]
    aov: Option<AovSet>,
}

impl AovArgs {
    /// The AOVs asked for; refused unless the frames are OpenEXR files.
    fn set(&self, output: &str, format: FrameFormat) -> Result<AovSet> {
        let Some(set) = self.aov else {
            return Ok(AovSet::NONE);
        };
        if format != FrameFormat::Exr {
            let names: Vec<&str> = Aov::ALL
                .into_iter()
                .filter(|&a| set.has(a))
                .map(Aov::name)
                .collect();
            anyhow::bail!(
                "--aov {}: AOVs are layers of an OpenEXR frame, and -o {output} is not one: \
                 name the output .exr (e.g. -o out/frame_####.exr)",
                names.join(",")
            );
        }
        Ok(set)
    }
}

/// Writes a rendered view for `path` in the format its extension names
/// (the 8-bit picture, or the linear colours, which the animator must
/// have been asked for, with the view's AOVs as OpenEXR) under a
/// temporary name: it appears at `path` only once committed, so a run
/// puts a frame's files in place together with counting it.
fn save_view_pending(path: &Path, view: &ViewOutput) -> Result<PendingFile> {
    Ok(match frame_format_for(path)? {
        FrameFormat::Picture(_) => save_image_pending(path, &view.image)?,
        FrameFormat::Exr => {
            let colours = view
                .frame
                .as_ref()
                .expect("OpenEXR frames are rendered in linear colour");
            save_exr_pending(path, &exr_picture(colours, view.aovs.as_ref()))?
        }
    })
}

/// A frame file written earlier (`--skip-existing`), read back as the
/// 8-bit picture a run shows (an OpenEXR frame's colours encoded as its
/// PNG would be, from its half floats).
fn read_frame_back(path: &Path) -> Result<image::RgbImage> {
    if frame_format_for(path)? == FrameFormat::Exr {
        let picture = read_exr(path)?;
        let colours = retrace::aov::colours_of(&picture)
            .with_context(|| format!("{}: no R, G and B channels", path.display()))?;
        return Ok(colours.to_rgb8());
    }
    Ok(image::open(path)
        .with_context(|| format!("cannot read {}", path.display()))?
        .to_rgb8())
}

/// Splits a frame pattern around its run of `#`.
fn frame_pattern(pattern: &str) -> Result<(String, usize, String)> {
    let start = pattern.find('#').with_context(|| {
        format!(
            "output pattern '{pattern}' has no # for the frame number (e.g. out/frame_####.png)"
        )
    })?;
    let width = pattern[start..].chars().take_while(|&c| c == '#').count();
    let (prefix, suffix) = (&pattern[..start], &pattern[start + width..]);
    if suffix.contains('#') {
        anyhow::bail!("output pattern '{pattern}' has more than one run of #");
    }
    if suffix.contains(std::path::is_separator) {
        anyhow::bail!(
            "output pattern '{pattern}': the # must be in the file name, not in a folder's"
        );
    }
    Ok((prefix.to_string(), width, suffix.to_string()))
}

/// The folder `path` is written into ("." for a bare file name).
fn folder_of(path: &Path) -> PathBuf {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .map_or(PathBuf::from("."), Path::to_path_buf)
}

/// Fails early, before any rendering, if `dir` cannot take new files
/// (making it if it is not there).
fn check_writable(dir: &Path) -> Result<()> {
    make_folder(dir, None)?;
    let probe = dir.join(format!(".retrace-probe-{}", std::process::id()));
    std::fs::write(&probe, b"")
        .with_context(|| format!("cannot write into output folder {}", dir.display()))?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}

/// Only the lab's reports (`bench`, `validate`) are written as JSON.
#[cfg(feature = "lab")]
fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    ensure_parent(path)?;
    let text = serde_json::to_string_pretty(value)?;
    retrace::output::write_atomically(path, |temp| {
        std::fs::write(temp, &text).map_err(|source| retrace::output::OutputError::Write {
            path: path.to_path_buf(),
            source,
        })
    })?;
    Ok(())
}

/// What the running command says, and saves, if it is interrupted.
type InterruptReport = Box<dyn FnMut() + Send>;

/// What an interrupt does to the running command.
enum OnInterrupt {
    /// Says what was kept and saves it; then the run stops at once.
    Report(InterruptReport),
    /// Asks the command to stop: it ends by itself, writing what it was
    /// asked for and saying why (a second interrupt stops it at once).
    #[cfg(feature = "view")]
    Stop(Box<dyn FnOnce() + Send>),
}

static ON_INTERRUPT: std::sync::Mutex<Option<OnInterrupt>> = std::sync::Mutex::new(None);

fn set_on_interrupt(action: Option<OnInterrupt>) {
    *ON_INTERRUPT
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = action;
}

/// Sets what an interrupt reports (the frames kept, how to resume) before
/// it stops the run.
fn on_interrupt(report: impl FnMut() + Send + 'static) {
    set_on_interrupt(Some(OnInterrupt::Report(Box::new(report))));
}

/// Sets how the next interrupt asks the running command to stop (None:
/// it stops the run at once again).
#[cfg(feature = "view")]
fn stop_on_interrupt(stop: Option<Box<dyn FnOnce() + Send>>) {
    set_on_interrupt(stop.map(OnInterrupt::Stop));
}

/// Ctrl-C, or a scheduler's SIGTERM or SIGHUP: asks a command that can
/// wind down to stop; else says what was kept, then stops at once,
/// leaving finished files and removing unfinished ones.
pub(crate) fn interrupted() {
    let action = ON_INTERRUPT
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .take();
    #[cfg(feature = "view")]
    if let Some(OnInterrupt::Stop(stop)) = action {
        return stop();
    }
    eprintln!("\ninterrupted");
    if let Some(OnInterrupt::Report(mut report)) = action {
        report();
    }
    retrace::output::remove_unfinished_and_exit(130)
}

/// Progress of a run of frames: a bar on a terminal; plain lines, at most
/// one every few seconds and the last, where stderr is a log (a render
/// farm's task, a pipe).
pub(crate) struct Progress {
    bar: Option<indicatif::ProgressBar>,
    total: u64,
    done: u64,
    last_line: std::time::Instant,
}

/// How often a log gets a progress line.
const PROGRESS_LINE_EVERY: std::time::Duration = std::time::Duration::from_secs(5);

impl Progress {
    pub(crate) fn new(total: u64) -> Progress {
        use std::io::IsTerminal as _;
        let bar = std::io::stderr().is_terminal().then(|| {
            indicatif::ProgressBar::new(total).with_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:30} {pos}/{len} frames {msg} [{elapsed} < {eta}]",
                )
                .expect("static template"),
            )
        });
        Progress {
            bar,
            total,
            done: 0,
            last_line: std::time::Instant::now(),
        }
    }

    /// A frame done: `what` says what it did (its time, its samples).
    pub(crate) fn frame_done(&mut self, frame: u32, what: &str) {
        self.done += 1;
        match &self.bar {
            Some(bar) => {
                bar.set_message(what.to_string());
                bar.inc(1);
            }
            None => {
                let last = self.done == self.total;
                if last || self.last_line.elapsed() >= PROGRESS_LINE_EVERY {
                    eprintln!(
                        "frame {frame}: {} of {} done, {what}",
                        self.done, self.total
                    );
                    self.last_line = std::time::Instant::now();
                }
            }
        }
    }

    pub(crate) fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_projection_listed_for_camera_parses_to_itself() {
        for name in PROJECTIONS {
            let projection: Projection = name.parse().unwrap();
            assert_eq!(projection.to_string(), name);
        }
    }

    #[test]
    fn a_frame_range_may_start_with_a_dash_but_a_flag_may_not() {
        assert_eq!(frame_range_text("-3").unwrap(), "-3");
        assert_eq!(frame_range_text("2-5").unwrap(), "2-5");
        assert!(frame_range_text("--gif").unwrap_err().contains("is a flag"));
        let err = parse_frame_range(Some("-3"), 10).unwrap_err().to_string();
        assert!(err.contains("numbered from 0"), "{err}");
        let err = parse_frame_range(Some("2--1"), 10).unwrap_err().to_string();
        assert!(err.contains("numbered from 0"), "{err}");
    }
}

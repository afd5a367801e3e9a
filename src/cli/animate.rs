//! `retrace animate`: an animation's frames, re-tracing only what changed,
//! and what a run writes besides them (GIF, statistics, chunks).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;

use retrace::clock;
use retrace::frame_loop::{
    stats_csv, stats_json, stats_rows, Animator, FrameStats, Options, Techniques,
};
use retrace::output::{csv_records, save_image_pending, FrameFormat, PendingFile};

use super::verify::RunCheck;
use super::{
    check_writable, ensure_parent, folder_of, frame_pattern, idle_flag, load, on_interrupt,
    parse_frame_range, read_frame_back, save_view_pending, scene_name, AovArgs, BackendArg,
    FramePattern, OstcArgs, Progress, RsvpKnobArgs, SceneArgs,
};

#[derive(Args)]
pub(crate) struct AnimateArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Frames to render: A-B (inclusive) or A; default: the whole animation.
    #[arg(long, allow_hyphen_values = true, value_parser = super::frame_range_text)]
    frames: Option<String>,
    /// Frame files (.png, .tga, or .exr: linear half floats, with --aov's
    /// layers); a run of # becomes the zero-padded frame number. A scene with RSVP viewports writes one file per viewport,
    /// its name added before the extension: out/frame_0007_zoomed.png.
    #[arg(short, long, default_value = "out/frame_####.png")]
    output: String,
    #[command(flatten)]
    aov: AovArgs,
    /// RSVP: also write the camera's sample buffer per frame (e.g.
    /// out/buffer_####.png), never-traced samples black (paper, figure 5a).
    #[arg(long)]
    buffer_image: Option<String>,
    #[command(flatten)]
    rsvp: RsvpKnobArgs,
    /// Also write the frames as an animated GIF here (with RSVP viewports:
    /// the first viewport's frames).
    #[arg(long)]
    gif: Option<PathBuf>,
    /// Per-frame statistics: .csv or .json.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Also write each frame with the samples it re-traced painted black
    /// (like the paper's figure 4), e.g. out/dirty_####.png.
    #[arg(long)]
    dirty_image: Option<String>,
    /// full (no reuse), auto (every technique the timeline allows), or a
    /// comma list of techniques: pan (camera pans shift the image), ostc
    /// (moving objects and lights re-trace only their regions), rsvp
    /// (viewports resample the camera's lazily traced sample buffer; with
    /// viewports, full traces each viewport's own rays).
    #[arg(long, default_value = "auto", value_parser = Techniques::parse)]
    mode: Techniques,
    #[command(flatten)]
    ostc: OstcArgs,
    /// How a pan by a fraction of a sample is shown: snap (to the nearest
    /// stratum of the pixel's samples at --spp 4, 9, 16...; to whole samples
    /// at --spp 1: exact, the angle off by at most half a stratum),
    /// snap-samples (to whole samples whatever the --spp: exact, off by up
    /// to half a pixel) or resample (the true angle, bilinear from the
    /// buffer: slightly blurred). [default: snap]
    #[arg(long)]
    fractional_pan: Option<retrace::reuse::pan::FractionalPan>,
    /// Also render every frame in full: exact (snapped) frames must equal
    /// it bit for bit; resampled frames (and RSVP viewports) report their
    /// error against it.
    #[arg(long)]
    verify: bool,
    /// Leave frames whose file already exists (to resume a run).
    #[arg(long)]
    skip_existing: bool,
    /// For array jobs on a render farm: cut the frames into N contiguous
    /// chunks and render one, starting from a full frame. Which one:
    /// --chunk-index, else the scheduler's task index (SLURM_ARRAY_TASK_ID
    /// from SLURM_ARRAY_TASK_MIN, JOB_COMPLETION_INDEX of a Kubernetes
    /// indexed Job, AWS_BATCH_JOB_ARRAY_INDEX). The frames equal those of
    /// one run; --stats files get the chunk's number (stats.chunk03.csv).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    chunks: Option<u32>,
    /// With --chunks: this task's chunk, from 0.
    #[arg(long, requires = "chunks")]
    chunk_index: Option<u32>,
}

pub(crate) struct GifWriter {
    /// None once finished. Declared first: dropped (closing the file)
    /// before `file` removes an unfinished one.
    encoder: Option<image::codecs::gif::GifEncoder<std::io::BufWriter<std::fs::File>>>,
    file: PendingFile,
    delay: image::Delay,
}

impl GifWriter {
    pub(crate) fn create(path: &Path, fps: f64) -> Result<GifWriter> {
        ensure_parent(path)?;
        let file = PendingFile::beside(path);
        let out = std::fs::File::create(file.temp())
            .with_context(|| format!("cannot write {}", path.display()))?;
        // Speed 20 of 30: quantization good enough for previews, several times faster than the default.
        let mut encoder =
            image::codecs::gif::GifEncoder::new_with_speed(std::io::BufWriter::new(out), 20);
        encoder.set_repeat(image::codecs::gif::Repeat::Infinite)?;
        Ok(GifWriter {
            encoder: Some(encoder),
            file,
            // 1000/fps ms, to a thousandth of a frame per second (0.5 fps:
            // 2 s a frame; GIF itself keeps hundredths of a second).
            delay: image::Delay::from_numer_denom_ms(
                1_000_000,
                (fps * 1000.0).round().max(1.0) as u32,
            ),
        })
    }

    fn add(&mut self, image: &image::RgbImage) -> Result<()> {
        let rgba = image::DynamicImage::ImageRgb8(image.clone()).to_rgba8();
        self.encoder
            .as_mut()
            .expect("frames are added before finish")
            .encode_frame(image::Frame::from_parts(rgba, 0, 0, self.delay))
            .with_context(|| format!("cannot encode {}", self.file.path().display()))
    }

    /// A frame written by an earlier run (`--skip-existing`), read back so
    /// that the GIF still shows every frame.
    pub(crate) fn add_file(&mut self, path: &Path) -> Result<()> {
        let image = read_frame_back(path)
            .with_context(|| format!("cannot read {} back for the GIF", path.display()))?;
        self.add(&image)
    }

    pub(crate) fn finish(mut self) -> Result<()> {
        // Dropping the encoder writes the trailer and flushes the file.
        drop(self.encoder.take());
        Ok(self.file.commit()?)
    }
}

fn write_stats(
    path: &Path,
    stats: &[retrace::frame_loop::FrameStats],
    earlier: &EarlierRows,
) -> Result<()> {
    let frames: std::collections::HashSet<u32> = stats.iter().map(|s| s.frame).collect();
    let text = match earlier {
        EarlierRows::Json(earlier) => {
            let rows = stats_rows(stats);
            let kept = earlier
                .iter()
                .filter(|row| {
                    row.get("frame")
                        .and_then(serde_json::Value::as_u64)
                        .is_some_and(|f| !u32::try_from(f).is_ok_and(|f| frames.contains(&f)))
                })
                .cloned()
                .collect();
            let rows = retrace::chunk::merge_stats(vec![kept, rows]).map_err(anyhow::Error::msg)?;
            stats_json(&rows)
        }
        EarlierRows::Csv(earlier) => {
            let text = stats_csv(&stats_rows(stats))?;
            let records = csv_records(&text);
            // One record a row, after the header.
            let mut rows: Vec<(u32, &str)> = stats
                .iter()
                .map(|s| s.frame)
                .zip(records[1..].iter().copied())
                .collect();
            rows.extend(
                earlier
                    .iter()
                    .filter(|(frame, _)| !frames.contains(frame))
                    .map(|(frame, record)| (*frame, record.as_str())),
            );
            // Stable: a frame's views keep their order.
            rows.sort_by_key(|(frame, _)| *frame);
            let mut merged = format!("{}\n", records[0]);
            for (_, record) in rows {
                merged.push_str(record);
                merged.push('\n');
            }
            merged
        }
    };
    ensure_parent(path)?;
    retrace::output::save_text(path, &text)?;
    Ok(())
}

fn is_json(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// The rows of the statistics file an earlier run of the same frames
/// wrote: a resumed run (`--skip-existing`, a requeued farm task) keeps
/// those of the frames it skips, so the file still covers every frame.
enum EarlierRows {
    Json(Vec<serde_json::Value>),
    /// Each row's frame and its record as written.
    Csv(Vec<(u32, String)>),
}

fn earlier_stats(args: &AnimateArgs, path: Option<&Path>) -> Result<EarlierRows> {
    let json = path.is_some_and(is_json);
    let none = if json {
        EarlierRows::Json(Vec::new())
    } else {
        EarlierRows::Csv(Vec::new())
    };
    let Some(path) = path.filter(|p| args.skip_existing && p.is_file()) else {
        return Ok(none);
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read {} to keep its rows", path.display()))?;
    let not_stats = || {
        format!(
            "{}: not a statistics file of an earlier run (--skip-existing keeps its rows)",
            path.display()
        )
    };
    if json {
        return Ok(EarlierRows::Json(
            serde_json::from_str(&text).with_context(not_stats)?,
        ));
    }
    let header = stats_csv(&[])?;
    let records = csv_records(&text);
    if records.first() != csv_records(&header).first() {
        anyhow::bail!("{}: its columns are not this version's", not_stats());
    }
    let rows = records[1..].iter().map(|record| {
        let frame = record.split(',').next().and_then(|f| f.parse().ok());
        frame
            .map(|frame| (frame, record.to_string()))
            .with_context(not_stats)
    });
    Ok(EarlierRows::Csv(rows.collect::<Result<_>>()?))
}

/// The frames this task renders and where its statistics go: all of
/// `range`, or with `--chunks` this task's chunk of it (None: the chunk is
/// empty, nothing to do).
fn chunk_of(
    args: &AnimateArgs,
    range: std::ops::RangeInclusive<u32>,
) -> Result<Option<(std::ops::RangeInclusive<u32>, Option<PathBuf>)>> {
    use retrace::chunk::{chunk_frames, chunk_path, index_from_env, IndexSource};
    let Some(count) = args.chunks else {
        return Ok(Some((range, args.stats.clone())));
    };
    let (index, source) = match args.chunk_index {
        Some(index) => (index, IndexSource::Flag),
        None => index_from_env(|name| std::env::var(name).ok())
            .map_err(|err| anyhow::anyhow!("--chunks {count}: {err}"))?
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "--chunks {count}: which chunk is this task's? Give --chunk-index, or run it as \
                     a Slurm array task, a Kubernetes indexed Job or an AWS Batch array job"
                )
            })?,
    };
    if index >= count {
        anyhow::bail!(
            "--chunks {count}: chunk {index} (from {source}) is not one of 0-{}",
            count - 1
        );
    }
    if count > 1 && args.gif.is_some() {
        anyhow::bail!(
            "--gif with --chunks {count}: each task has only its chunk's frames; make the GIF \
             from all the frame files once the tasks are done"
        );
    }
    let stats = args
        .stats
        .as_deref()
        .map(|path| chunk_path(path, count, index));
    let what = format!(
        "chunk {index} of {count} (from {source}) of frames {}-{}",
        range.start(),
        range.end()
    );
    match chunk_frames(&range, count, index) {
        Some(frames) => {
            eprintln!("{what}: frames {}-{}", frames.start(), frames.end());
            Ok(Some((frames, stats)))
        }
        None => {
            eprintln!("{what}: no frames (more chunks than frames)");
            Ok(None)
        }
    }
}

/// Fails before any rendering if two outputs share a pattern (one would
/// overwrite the other) or an output's folder cannot take files: a run
/// should not end, after its last frame, on a folder it could not write.
fn check_outputs(args: &AnimateArgs, stats: Option<&Path>) -> Result<()> {
    let patterns = [
        ("-o", Some(&args.output)),
        ("--dirty-image", args.dirty_image.as_ref()),
        ("--buffer-image", args.buffer_image.as_ref()),
    ];
    let patterns: Vec<(&str, &String)> = patterns
        .into_iter()
        .filter_map(|(flag, p)| p.map(|p| (flag, p)))
        .collect();
    for (i, (flag, pattern)) in patterns.iter().enumerate() {
        if let Some((other, _)) = patterns[..i].iter().find(|(_, p)| p == pattern) {
            anyhow::bail!("{other} and {flag} both write '{pattern}': give each its own name");
        }
        let (prefix, digits, suffix) = frame_pattern(pattern)?;
        check_writable(&folder_of(Path::new(&format!(
            "{prefix}{:0digits$}{suffix}",
            0
        ))))?;
    }
    for path in [stats, args.gif.as_deref()].into_iter().flatten() {
        check_writable(&folder_of(path))?;
    }
    Ok(())
}

pub(crate) fn animate(args: AnimateArgs) -> Result<()> {
    let mut files = OutputFiles::parse(&args)?;
    let exr = files.frames.format() == FrameFormat::Exr;
    let aovs = args.aov.set(&args.output, files.frames.format())?;
    let scene = load(&args.scene)?;
    if scene.animation.is_none() {
        eprintln!(
            "note: {} has no [animation]: it is one frame (`retrace render` makes single images)",
            scene_name(&args.scene)
        );
    }
    let (count, fps) = scene
        .animation
        .as_ref()
        .map_or((1, 25.0), |a| (a.frames, a.fps));
    let range = parse_frame_range(args.frames.as_deref(), count)?;
    let Some((range, stats_path)) = chunk_of(&args, range)? else {
        return Ok(());
    };
    let options = Options {
        techniques: args.mode,
        frames: *range.start()..*range.end() + 1,
        linear: args.verify || exr,
        fractional_pan: args.fractional_pan.unwrap_or_default(),
        ostc: args.ostc.settings(),
        rsvp: args.rsvp.knobs(scene.samples)?,
        traced_images: files.traced.is_some(),
        aovs,
        sample_memory: None,
    };
    refuse_idle_flags(&args, &scene, &options, files.store.is_some())?;
    check_outputs(&args, stats_path.as_deref())?;
    if let Some(path) = &args.gif {
        files.gif = Some(GifWriter::create(path, fps)?);
    }
    let mut accel = args.backend.build(&scene)?;
    let mut animator = Animator::new(&scene, &mut accel, options);
    let memory = animator.memory_estimate();
    super::check_memory(&memory)?;
    // What an interrupt says and saves: the frames finished so far, their
    // statistics, and how to resume.
    let finished = Arc::new(Mutex::new(Finished::default()));
    let earlier = Arc::new(earlier_stats(&args, stats_path.as_deref())?);
    save_on_interrupt(&finished, &earlier, stats_path.clone(), *range.start());
    // The camera image's regions, where the frames truly changed.
    let region_size = retrace::reuse::lattice_buffer::lattice_region_size(
        args.ostc.settings().regions,
        (scene.camera.width, scene.camera.height),
        1,
    );
    let mut run_check = RunCheck::new(scene.samples, (*range.start(), *range.end()), region_size);
    run_check.exr = exr;
    let rendered = render_frames(
        &args,
        &mut animator,
        &range,
        &mut files,
        &finished,
        &mut run_check,
    )?;
    // A copy: an interrupt from here on still counts (and saves) every
    // frame, which are all on disk.
    let all_stats = finished
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .stats
        .clone();
    if let Some(gif) = files.gif {
        gif.finish()?;
    }
    if let Some(path) = &stats_path {
        write_stats(path, &all_stats, &earlier)?;
    }
    // Reuse that was asked for but could not apply is worth a word.
    let mut refusals: Vec<String> = all_stats
        .iter()
        .filter_map(|s| s.refusal().map(|r| r.to_string()))
        .collect();
    refusals.dedup();
    for reason in refusals {
        eprintln!("warning: rendered in full: {reason}");
    }
    warn_ostc_refused(&animator);
    run_check.say_store()?;
    say_run(&args, &animator, &rendered, &all_stats);
    super::say_memory(&memory);
    if args.verify && !all_stats.is_empty() {
        run_check.say(&animator, &rendered.names, &all_stats)?;
    }
    Ok(())
}

/// Where a run's pictures go: its frames, and as asked the traced-sample
/// images, the store's pictures and a GIF.
struct OutputFiles {
    frames: FramePattern,
    traced: Option<FramePattern>,
    store: Option<FramePattern>,
    gif: Option<GifWriter>,
}

impl OutputFiles {
    /// The file patterns the flags name, checked before any work (the GIF
    /// is created once the run is known to go ahead).
    fn parse(args: &AnimateArgs) -> Result<OutputFiles> {
        let pattern =
            |flag: &Option<String>| flag.as_deref().map(FramePattern::parse_picture).transpose();
        let extension = |path: &Path| path.extension().map(|e| e.to_string_lossy().to_lowercase());
        if let Some(path) = &args.stats {
            if !matches!(extension(path).as_deref(), Some("csv" | "json")) {
                anyhow::bail!("--stats {}: use a .csv or .json file", path.display());
            }
        }
        if let Some(path) = &args.gif {
            if extension(path).as_deref() != Some("gif") {
                anyhow::bail!("--gif {}: use a .gif file", path.display());
            }
        }
        Ok(OutputFiles {
            frames: FramePattern::parse(&args.output)?,
            traced: pattern(&args.dirty_image)?,
            store: pattern(&args.buffer_image)?,
            gif: None,
        })
    }
}

/// The frames of a run whose files are all in place, with their
/// statistics: what an interrupt counts and saves. The interrupt closes it,
/// and no frame's files are put in place after that, so that the count,
/// the statistics and the files agree.
#[derive(Default)]
struct Finished {
    stats: Vec<FrameStats>,
    /// Counted by an interrupt, which is ending the process.
    closed: bool,
}

/// Puts a frame's `files` in place and adds its `stats` to `finished`, as
/// one step for an interrupt: before it, neither; after it, both. Once an
/// interrupt has counted the frames, the files are never put in place and
/// the thread waits for the process to end.
fn keep_frame(
    finished: &Mutex<Finished>,
    files: Vec<PendingFile>,
    stats: Vec<FrameStats>,
) -> Result<()> {
    let mut finished = finished.lock().unwrap_or_else(PoisonError::into_inner);
    if finished.closed {
        drop(finished);
        drop(files);
        loop {
            std::thread::park();
        }
    }
    for file in files {
        file.commit()?;
    }
    finished.stats.extend(stats);
    Ok(())
}

/// On an interrupt, says which frames were kept and how to resume, and
/// writes the statistics of the `finished` frames.
fn save_on_interrupt(
    finished: &Arc<Mutex<Finished>>,
    earlier: &Arc<EarlierRows>,
    stats_path: Option<PathBuf>,
    first: u32,
) {
    let (finished, earlier) = (Arc::clone(finished), Arc::clone(earlier));
    on_interrupt(move || {
        let mut finished = finished.lock().unwrap_or_else(PoisonError::into_inner);
        finished.closed = true;
        let stats = &finished.stats;
        let mut frames: Vec<u32> = stats.iter().map(|s| s.frame).collect();
        frames.dedup();
        eprintln!(
            "{} of this run kept ({}); resume with:\n  {}",
            counted(frames.len() as u64, "finished frame"),
            match (frames.first(), frames.last()) {
                (Some(a), Some(b)) => format!("frames {a}-{b}"),
                _ => format!("none from frame {first} on"),
            },
            resume_command()
        );
        if let Some(path) = &stats_path {
            if !stats.is_empty() {
                match write_stats(path, stats, &earlier) {
                    Ok(()) => eprintln!("statistics of those frames: {}", path.display()),
                    Err(err) => eprintln!("cannot write {}: {err}", path.display()),
                }
            }
        }
    });
}

/// What a run rendered: its views' names, the frames `--skip-existing`
/// left, and the time spent writing files.
struct Rendered {
    names: Vec<String>,
    frames: u32,
    skipped: u32,
    write_ms: f64,
}

/// Renders the frames of `range`, writes their files, checks them with
/// `--verify`, and keeps each frame's statistics in `finished` as its
/// files are put in place.
fn render_frames(
    args: &AnimateArgs,
    animator: &mut Animator,
    range: &std::ops::RangeInclusive<u32>,
    files: &mut OutputFiles,
    finished: &Mutex<Finished>,
    run_check: &mut RunCheck,
) -> Result<Rendered> {
    let names: Vec<String> = animator
        .views(*range.start())
        .into_iter()
        .map(|view| view.name)
        .collect();
    let mut progress = Progress::new(u64::from(range.end() - range.start() + 1));
    let (mut write_ms, mut skipped) = (0.0, 0);
    for frame in range.clone() {
        if args.skip_existing && names.iter().all(|n| files.frames.path(frame, n).exists()) {
            if let Some(gif) = &mut files.gif {
                gif.add_file(&files.frames.path(frame, &names[0]))?;
            }
            skipped += 1;
            progress.frame_done(frame, "skipped: its files exist");
            continue;
        }
        let outputs = animator.render(frame);
        let (mut frame_ms, mut frame_samples) = (0.0, 0);
        // Written whole, put in place at once when the frame is counted.
        let (mut written, mut frame_stats) = (Vec::new(), Vec::new());
        for (index, mut output) in outputs.into_iter().enumerate() {
            if args.verify {
                run_check.check_view(animator, frame, index, &mut output)?;
            }
            let write_start = Instant::now();
            let path = files.frames.path(frame, &output.name);
            written.push(save_view_pending(&path, &output)?);
            if let (Some(traced_files), Some(traced)) = (&files.traced, &output.traced_image) {
                written.push(save_image_pending(
                    &traced_files.path(frame, &output.name),
                    traced,
                )?);
            }
            if index == 0 {
                if let Some(gif) = &mut files.gif {
                    gif.add(&output.image)?;
                }
            }
            write_ms += clock::ms(write_start.elapsed());
            frame_ms += output.stats.total_ms();
            frame_samples += output.stats.work.samples_traced;
            frame_stats.push(output.stats);
        }
        if let Some(store_files) = &files.store {
            if let Some(picture) = animator.store_picture(frame) {
                let write_start = Instant::now();
                written.push(save_image_pending(&store_files.path(frame, ""), &picture)?);
                write_ms += clock::ms(write_start.elapsed());
            }
        }
        keep_frame(finished, written, frame_stats)?;
        if args.verify {
            run_check.check_store(animator);
        }
        progress.frame_done(
            frame,
            &format!(
                "{frame_ms:.1} ms, {} traced",
                counted(frame_samples, "sample")
            ),
        );
    }
    progress.finish();
    Ok(Rendered {
        names,
        frames: range.end() - range.start() + 1 - skipped,
        skipped,
        write_ms,
    })
}

/// Refuses, with the reason, every flag that cannot act on this run: a
/// technique `--mode` names that has nothing to do, and the knobs of a
/// technique that does not run.
fn refuse_idle_flags(
    args: &AnimateArgs,
    scene: &retrace::scene::Scene,
    options: &Options,
    store_image: bool,
) -> Result<()> {
    use retrace::frame_loop::Technique;
    use retrace::reuse::{idle_reason, Run};
    let run = Run {
        scene,
        options,
        interactive: false,
    };
    let mode = args.mode;
    let explicit = mode != Techniques::AUTO && mode != Techniques::FULL;
    // Why `technique` does not run: not asked for, or idle on this scene.
    let off = |technique: Technique| -> Option<String> {
        if !mode.has(technique) {
            return Some(format!("--mode leaves {} off", technique.name()));
        }
        idle_reason(&run, technique).map(|idle| idle.to_string())
    };
    for technique in Technique::ALL {
        if explicit && mode.has(technique) {
            if let Some(reason) = idle_reason(&run, technique) {
                let reason = reason.to_string();
                return Err(idle_flag(&format!("--mode {}", technique.name()), &reason));
            }
        }
    }
    let knobs = [
        (Technique::Rsvp, args.rsvp.given()),
        (
            Technique::Pan,
            args.fractional_pan.map(|_| "--fractional-pan"),
        ),
        (Technique::Ostc, args.ostc.given()),
        (Technique::Rsvp, store_image.then_some("--buffer-image")),
    ];
    for (technique, flag) in knobs {
        if let (Some(flag), Some(reason)) = (flag, off(technique)) {
            return Err(idle_flag(flag, &reason));
        }
    }
    Ok(())
}

/// OSTC asked for but refused is worth a word: buffers restarted on every
/// change instead.
fn warn_ostc_refused(animator: &Animator) {
    if let Some(why) = animator.ostc_refusal() {
        eprintln!("warning: OSTC is off: {why}; buffers restart whenever something moves");
    }
}

/// The run's last lines: what was rendered, in what time, and with
/// `--verify` the time of the full (or direct) renders it was checked
/// against.
fn say_run(args: &AnimateArgs, animator: &Animator, rendered: &Rendered, stats: &[FrameStats]) {
    let frames = counted(u64::from(rendered.frames), "frame");
    let skipped = skipped_note(rendered.skipped);
    let (what, references) = if animator.has_viewports() {
        let names = &rendered.names;
        (
            format!(
                "{frames} x {} ({}){skipped}",
                counted(names.len() as u64, "viewport"),
                names.join(", "),
            ),
            "direct renders",
        )
    } else {
        (format!("{frames}{skipped}"), "full renders")
    };
    say!(
        "{}: {what} {}",
        scene_name(&args.scene),
        run_summary(stats, rendered.write_ms)
    );
    if args.verify && stats.is_empty() {
        say!("verify: no frame rendered, nothing to check");
    } else if args.verify {
        say!("verify: {references} {}", verify_timing(stats));
    }
}

/// Says how many frames `--skip-existing` left as they were, if any.
fn skipped_note(skipped: u32) -> String {
    if skipped == 0 {
        String::new()
    } else {
        let files = if skipped == 1 {
            "its file exists"
        } else {
            "their files exist"
        };
        format!(" ({skipped} more skipped: {files})")
    }
}

/// Milliseconds added up from +0.0: `Iterator::sum` starts floats at -0.0,
/// which prints as "-0.0 ms" when nothing was rendered.
fn sum_ms(values: impl Iterator<Item = f64>) -> f64 {
    values.fold(0.0, |total, ms| total + ms)
}

/// Time spent, and samples traced against pixels shown, over a run.
fn run_summary(stats: &[retrace::frame_loop::FrameStats], write_ms: f64) -> String {
    let total = sum_ms(stats.iter().map(|s| s.total_ms()));
    let traced: u64 = stats.iter().map(|s| s.work.samples_traced).sum();
    let pixels: u64 = stats.iter().map(|s| s.pixels).sum();
    let per_pixel = traced as f64 / pixels.max(1) as f64;
    // RSVP traces the pyramid level a viewport's pixels need, a whole
    // level at a time: zoomed in or at a wide view's edges, finer than the
    // pixels themselves.
    let why = if per_pixel > 1.0 && stats.iter().any(|s| !s.view.is_empty()) {
        " (RSVP traces whole pyramid levels about as fine as the viewports' pixels, finer where a view is squeezed)"
    } else {
        ""
    };
    format!(
        "in {total:.1} ms rendering ({write_ms:.1} ms writing); traced {} for {}: {per_pixel:.2} a pixel{why}",
        counted(traced, "sample"),
        counted(pixels, "pixel"),
    )
}

/// `count` and `word`, plural as the count asks: "1 frame", "2 frames".
fn counted(count: u64, word: &str) -> String {
    if count == 1 {
        format!("1 {word}")
    } else {
        format!("{count} {word}s")
    }
}

/// The reference renders' time and the speedup against them.
fn verify_timing(stats: &[retrace::frame_loop::FrameStats]) -> String {
    let total = sum_ms(stats.iter().map(|s| s.total_ms()));
    let full = sum_ms(stats.iter().filter_map(|s| s.check.map(|c| c.full_ms)));
    format!("{full:.1} ms, speedup {:.2}x", full / total.max(1e-9))
}

/// This run's command line with `--skip-existing`: it renders the frames
/// whose files are missing.
fn resume_command() -> String {
    let mut args: Vec<String> = std::env::args().collect();
    if !args.iter().any(|a| a == "--skip-existing") {
        args.push("--skip-existing".to_string());
    }
    args.iter()
        .map(|a| {
            if a.is_empty() || a.contains(|c: char| c.is_whitespace() || "'\"$#*?".contains(c)) {
                format!("'{}'", a.replace('\'', "'\\''"))
            } else {
                a.clone()
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

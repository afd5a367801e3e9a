//! `retrace farm`: an animation rendered by a Slurm job array (one chunk
//! of frames a task), the job that assembles the result once every task
//! has succeeded, and the tasks' states.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};

use retrace::chunk::{chunk_frames, chunk_path, merge_stats, ACCEPTED_REUSE_LOSS};
use retrace::farm::{
    parse_sacct, parse_scontrol, reused_share, sort_records, task_indices, RestartCost,
};
use retrace::scene::SceneOverrides;

use super::animate::GifWriter;
use super::{folder_of, frame_pattern, make_folder, parse_frame_range, FramePattern};
use retrace::frame_loop::{stats_csv, stats_json};
use retrace::output::{frame_format_for, FrameFormat};

/// The batch scripts, carried in the binary so that an installed retrace
/// submits the same scripts as the repository's `farm/slurm/`.
const RENDER_SCRIPT: &str = include_str!("../../farm/slurm/render.sbatch");
const ASSEMBLE_SCRIPT: &str = include_str!("../../farm/slurm/assemble.sbatch");

#[derive(Args)]
pub(crate) struct FarmArgs {
    #[command(subcommand)]
    command: FarmCommand,
}

#[derive(Subcommand)]
enum FarmCommand {
    /// Submit an animation to Slurm: a job array of N tasks (one chunk of
    /// frames each, resuming if requeued) and a job that assembles the
    /// result once every task has succeeded (--dependency=afterok).
    /// Prints both job ids.
    Submit(SubmitArgs),
    /// What the assembly job runs: the GIF of all frames (and an MP4 where
    /// ffmpeg is installed), the chunks' statistics merged into stats.csv
    /// and stats.json, and report.md with the per-frame savings plot.
    Assemble(AssembleArgs),
    /// Each task of Slurm jobs: state, exit code, restarts, reason.
    Status(StatusArgs),
    /// Run tasks of a render array again (cancelled, failed or running
    /// ones) within seconds rather than after Slurm's requeue delay; they resume
    /// from the frames already written. With --assembly, the assembly job
    /// waits for every task again: a failed or cancelled task had made its
    /// dependency one that could never be met.
    Requeue(RequeueArgs),
}

/// What says which frames a farm run renders, and where: `submit` and
/// `assemble` share it so that they agree.
#[derive(Args, Clone)]
struct RunArgs {
    /// Scene file (.toml) with an [animation].
    scene: PathBuf,
    /// Tasks in the array, one contiguous chunk of frames each.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    chunks: u32,
    /// Frame files; a run of # becomes the frame number.
    #[arg(short, long, default_value = "out/frame_####.png")]
    output: String,
    /// Frames to render: A-B (inclusive) or A; default: all.
    #[arg(long, allow_hyphen_values = true, value_parser = super::frame_range_text)]
    frames: Option<String>,
    /// Folder of the run's statistics, logs and assembled results
    /// [default: the frames' folder].
    #[arg(long)]
    out: Option<PathBuf>,
}

impl RunArgs {
    fn out_dir(&self) -> PathBuf {
        self.out.clone().unwrap_or_else(|| {
            let (prefix, digits, suffix) =
                frame_pattern(&self.output).unwrap_or_else(|_| (self.output.clone(), 0, "".into()));
            folder_of(Path::new(&format!(
                "{prefix}{}{suffix}",
                "0".repeat(digits)
            )))
        })
    }

    /// Each chunk's statistics file is this with its number added.
    fn stats_base(&self) -> PathBuf {
        self.out_dir().join("stats.json")
    }

    /// The run's frames, the scene's frame rate and the name of the view
    /// the GIF shows (empty: the camera's image).
    fn frames(&self) -> Result<(std::ops::RangeInclusive<u32>, f64, String)> {
        let scene = retrace::scene::load_scene(&self.scene, &SceneOverrides::default())?;
        let animation = scene.animation.as_ref().with_context(|| {
            format!(
                "{} has no [animation]: nothing for a farm to share out",
                self.scene.display()
            )
        })?;
        let range = parse_frame_range(self.frames.as_deref(), animation.frames)?;
        let view = scene
            .viewports
            .first()
            .map_or(String::new(), |track| track.viewport.name.clone());
        Ok((range, animation.fps, view))
    }

    /// The arguments that name the same run again.
    fn to_args(&self) -> Vec<String> {
        let mut args = vec![
            self.scene.display().to_string(),
            "--chunks".into(),
            self.chunks.to_string(),
            "-o".into(),
            self.output.clone(),
        ];
        if let Some(frames) = &self.frames {
            args.extend(["--frames".into(), frames.clone()]);
        }
        args
    }
}

#[derive(Args)]
struct SubmitArgs {
    #[command(flatten)]
    run: RunArgs,
    /// Image width in pixels.
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels.
    #[arg(long)]
    height: Option<u32>,
    /// Samples per pixel.
    #[arg(long)]
    spp: Option<u32>,
    /// An sbatch option for both jobs (e.g. --sbatch=--partition=render);
    /// repeat for more.
    #[arg(long = "sbatch", allow_hyphen_values = true)]
    sbatch_options: Vec<String>,
    /// Print the sbatch commands instead of running them.
    #[arg(long)]
    dry_run: bool,
    /// More `retrace animate` flags for every task, after `--`
    /// (e.g. -- --mode full --dirty-image out/traced_####.png).
    #[arg(last = true)]
    animate_args: Vec<String>,
}

#[derive(Args)]
struct AssembleArgs {
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Args)]
struct StatusArgs {
    /// Job ids (an array's id covers all its tasks).
    #[arg(required = true)]
    jobs: Vec<String>,
}

#[derive(Args)]
struct RequeueArgs {
    /// The render array's job id.
    array: String,
    /// The tasks to run again (their indices in the array).
    #[arg(required = true)]
    tasks: Vec<u32>,
    /// The array's assembly job, to wait for the tasks again.
    #[arg(long)]
    assembly: Option<String>,
}

pub(crate) fn farm(args: FarmArgs) -> Result<()> {
    match args.command {
        FarmCommand::Submit(args) => submit(args),
        FarmCommand::Assemble(args) => assemble(args),
        FarmCommand::Status(args) => status(args),
        FarmCommand::Requeue(args) => requeue(args),
    }
}

fn requeue(args: RequeueArgs) -> Result<()> {
    for task in &args.tasks {
        let id = format!("{}_{task}", args.array);
        scontrol(&["requeue", &id])?;
        // Slurm holds a requeued task about two minutes (its BeginTime);
        // one second is the least that is safe. slurmd refuses to launch a
        // job whose credential dates from the second the job was killed in
        // (it compares whole seconds) and the task then fails with exit 1
        // without running, so `now` loses the race whenever a scheduling
        // pass comes within that second.
        scontrol(&["update", &format!("jobid={id}"), "StartTime=now+1"])?;
        say!("requeued task {task} of {}", args.array);
    }
    if let Some(assembly) = &args.assembly {
        // Named task by task: Slurm remembers an array's worst exit code,
        // so `afterok:ARRAY` stays unmet after a failed task succeeds on
        // its requeue (measured on 22.05), while each task's own state is
        // its latest.
        let mut tasks: Vec<u32> = job_records(&args.array)?
            .iter()
            .filter_map(|r| r.task.as_deref())
            .flat_map(task_indices)
            .collect();
        tasks.sort_unstable();
        tasks.dedup();
        let dependency: Vec<String> = tasks
            .iter()
            .map(|t| format!("{}_{t}", args.array))
            .collect();
        scontrol(&[
            "update",
            &format!("jobid={assembly}"),
            &format!("Dependency=afterok:{}", dependency.join(":")),
        ])?;
        say!(
            "assembly job {assembly} waits for every task of {} again",
            args.array
        );
    }
    Ok(())
}

fn scontrol(args: &[&str]) -> Result<()> {
    let output = Command::new("scontrol")
        .args(args)
        .output()
        .context("cannot run scontrol (is Slurm's client installed and on PATH?)")?;
    if !output.status.success() {
        anyhow::bail!(
            "scontrol {} failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&output.stderr).trim()
        );
    }
    Ok(())
}

fn submit(args: SubmitArgs) -> Result<()> {
    let run = &args.run;
    FramePattern::parse(&run.output)?;
    let overrides = SceneOverrides {
        width: args.width,
        height: args.height,
        spp: args.spp,
        ..Default::default()
    };
    // Refused here, not in every task's log: a scene that does not load.
    let scene = retrace::scene::load_scene(&run.scene, &overrides)?;
    let (range, _, _) = run.frames()?;
    let dir = run.out_dir();
    let logs = dir.join("logs");
    make_folder(&logs, None)?;
    let render_script = dir.join("render.sbatch");
    let assemble_script = dir.join("assemble.sbatch");
    retrace::output::save_text(&render_script, RENDER_SCRIPT)?;
    retrace::output::save_text(&assemble_script, ASSEMBLE_SCRIPT)?;
    let binary = std::env::current_exe().context("cannot find the retrace binary to run")?;
    let here = std::env::current_dir()?;
    let common = |name: &str, log: &str| -> Vec<String> {
        let mut options = vec![
            "--parsable".to_string(),
            format!("--job-name={name}"),
            format!("--chdir={}", here.display()),
            format!("--output={}", logs.join(log).display()),
            format!("--export=ALL,RETRACE={}", binary.display()),
        ];
        options.extend(args.sbatch_options.iter().cloned());
        options
    };

    let mut render = common("retrace-render", "render-%A_%a.log");
    render.extend([
        format!("--array=0-{}", run.chunks - 1),
        "--requeue".to_string(),
        render_script.display().to_string(),
    ]);
    render.extend(run.to_args());
    render.extend(["--stats".into(), run.stats_base().display().to_string()]);
    for (flag, value) in [
        ("--width", args.width),
        ("--height", args.height),
        ("--spp", args.spp),
    ] {
        if let Some(value) = value {
            render.extend([flag.to_string(), value.to_string()]);
        }
    }
    render.extend(args.animate_args.iter().cloned());

    let sizes: Vec<u32> = (0..run.chunks)
        .filter_map(|i| chunk_frames(&range, run.chunks, i))
        .map(|c| c.end() - c.start() + 1)
        .collect();
    let (smallest, largest) = (
        sizes.iter().min().copied().unwrap_or(0),
        sizes.iter().max().copied().unwrap_or(0),
    );
    eprintln!(
        "frames {}-{} in {} chunks of {}{} frames",
        range.start(),
        range.end(),
        run.chunks,
        smallest,
        if largest > smallest {
            format!("-{largest}")
        } else {
            String::new()
        }
    );
    let frame_count = range.end() - range.start() + 1;
    let (restart, restarted) = if scene.viewports.is_empty() {
        (RestartCost::EXACT, "")
    } else {
        (RestartCost::VIEWPORTS, " and refills its viewport buffer")
    };
    eprintln!(
        "each chunk restarts from a full frame{restarted}: {} chunks lose about {:.0}% of the \
         reuse one run has; keep at least {} frames a chunk to lose < {:.0}% \
         (measured by `retrace bench --only chunking`)",
        run.chunks,
        100.0 * restart.reuse_lost(run.chunks, frame_count),
        restart.min_frames_per_chunk(ACCEPTED_REUSE_LOSS),
        100.0 * ACCEPTED_REUSE_LOSS
    );
    if args.dry_run {
        say!("sbatch {}", shell_words(&render));
        let mut assemble = assemble_command(&common, run, &assemble_script, "ARRAY_JOB");
        assemble.insert(0, "sbatch".into());
        say!("{}", shell_words(&assemble));
        return Ok(());
    }
    let array = sbatch(&render)?;
    let assemble = assemble_command(&common, run, &assemble_script, &array);
    let assembly = match sbatch(&assemble) {
        Ok(id) => id,
        Err(err) => {
            return Err(err.context(format!(
                "render array {array} is submitted, but not its assembly job: run \
                 `retrace farm assemble {}` once it is done",
                shell_words(&run.to_args())
            )))
        }
    };
    say!("render array job: {array} (tasks 0-{})", run.chunks - 1);
    say!("assembly job: {assembly} (runs once every task has succeeded)");
    say!("logs: {}", logs.display());
    Ok(())
}

fn assemble_command(
    common: &dyn Fn(&str, &str) -> Vec<String>,
    run: &RunArgs,
    script: &Path,
    array: &str,
) -> Vec<String> {
    let mut command = common("retrace-assemble", "assemble-%j.log");
    command.extend([
        format!("--dependency=afterok:{array}"),
        script.display().to_string(),
        "--out".into(),
        run.out_dir().display().to_string(),
    ]);
    command.extend(run.to_args());
    command
}

/// Runs sbatch with `args` (`--parsable` among them) and returns the job
/// id it prints.
fn sbatch(args: &[String]) -> Result<String> {
    let output = Command::new("sbatch")
        .args(args)
        .output()
        .context("cannot run sbatch (is Slurm's client installed and on PATH?)")?;
    if !output.status.success() {
        anyhow::bail!(
            "sbatch failed ({}): {}",
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        );
    }
    // --parsable prints "id" or "id;cluster".
    let text = String::from_utf8_lossy(&output.stdout);
    let id = text.trim().split(';').next().unwrap_or_default();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        anyhow::bail!("sbatch printed no job id: '{}'", text.trim());
    }
    Ok(id.to_string())
}

/// `args` as a line a shell would split back into them.
fn shell_words(args: &[String]) -> String {
    args.iter()
        .map(|a| {
            if !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./=:,%@+#".contains(c))
            {
                a.clone()
            } else {
                format!("'{}'", a.replace('\'', "'\\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn assemble(args: AssembleArgs) -> Result<()> {
    let run = &args.run;
    let pattern = FramePattern::parse(&run.output)?;
    let (range, fps, view) = run.frames()?;
    let dir = run.out_dir();
    make_folder(&dir, None)?;
    let missing: Vec<u32> = range
        .clone()
        .filter(|&f| !pattern.path(f, &view).is_file())
        .collect();
    if !missing.is_empty() {
        anyhow::bail!(
            "{} of {} frames are missing (first: {}): have all tasks succeeded?",
            missing.len(),
            range.clone().count(),
            pattern.path(missing[0], &view).display()
        );
    }

    let gif_path = dir.join("animation.gif");
    let mut gif = GifWriter::create(&gif_path, fps)?;
    for frame in range.clone() {
        gif.add_file(&pattern.path(frame, &view))?;
    }
    gif.finish()?;
    say!("wrote {}", gif_path.display());
    match mp4(run, &range, fps, &view, &dir)? {
        Some(path) => say!("wrote {}", path.display()),
        None => eprintln!("note: no MP4: ffmpeg is not on PATH"),
    }

    let mut chunks = Vec::new();
    for index in 0..run.chunks {
        let Some(frames) = chunk_frames(&range, run.chunks, index) else {
            continue;
        };
        let path = chunk_path(&run.stats_base(), run.chunks, index);
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read chunk {index}'s statistics"))?;
        let rows: Vec<serde_json::Value> = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a statistics file", path.display()))?;
        chunks.push((index, frames, rows));
    }
    let merged = merge_stats(chunks.iter().map(|(_, _, rows)| rows.clone()).collect())
        .map_err(anyhow::Error::msg)?;
    let csv_path = dir.join("stats.csv");
    let json_path = dir.join("stats.json");
    retrace::output::save_text(&csv_path, &stats_csv(&merged)?)?;
    retrace::output::save_text(&json_path, &stats_json(&merged))?;
    say!("wrote {} and {}", csv_path.display(), json_path.display());

    let plot_path = dir.join("savings.png");
    let series: Vec<retrace::lab::plot::Series> = chunks
        .iter()
        .map(|(index, _, rows)| retrace::lab::plot::Series {
            label: format!("chunk {index}"),
            points: rows
                .iter()
                .filter(|row| row["viewport"].as_str().unwrap_or_default() == view)
                .filter_map(|row| Some((row["frame"].as_f64()?, reused_share(row)? * 100.0)))
                .collect(),
        })
        .collect();
    retrace::lab::plot::line_chart(
        &plot_path,
        "Pixels reused per frame (each chunk starts with a full frame)",
        "frame",
        "pixels reused (%)",
        &series,
    )?;
    let report_path = dir.join("report.md");
    retrace::output::save_text(&report_path, &report(run, &range, &view, &chunks))?;
    say!(
        "wrote {} and {}",
        report_path.display(),
        plot_path.display()
    );
    Ok(())
}

/// An MP4 of the frames if ffmpeg is on PATH (None if it is not).
fn mp4(
    run: &RunArgs,
    range: &std::ops::RangeInclusive<u32>,
    fps: f64,
    view: &str,
    dir: &Path,
) -> Result<Option<PathBuf>> {
    let on_path = std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|p| p.join("ffmpeg").is_file()));
    if !on_path {
        return Ok(None);
    }
    let (prefix, digits, suffix) = frame_pattern(&run.output)?;
    let suffix = if view.is_empty() {
        suffix
    } else {
        match suffix.rfind('.') {
            Some(dot) => format!("{}_{view}{}", &suffix[..dot], &suffix[dot..]),
            None => format!("{suffix}_{view}"),
        }
    };
    // ffmpeg's own numbering: %04d for ####, a literal % doubled.
    let input = format!(
        "{}%0{digits}d{}",
        prefix.replace('%', "%%"),
        suffix.replace('%', "%%")
    );
    let path = dir.join("animation.mp4");
    let pending = retrace::output::PendingFile::beside(&path);
    let temp = pending.temp().with_extension("mp4");
    // OpenEXR frames hold linear light: ffmpeg encodes it to sRGB, as the
    // PNG frames are.
    let linear = frame_format_for(Path::new(&input))? == FrameFormat::Exr;
    let status = Command::new("ffmpeg")
        .args(["-loglevel", "error", "-y", "-framerate", &fps.to_string()])
        .args(if linear {
            &["-apply_trc", "iec61966_2_1"][..]
        } else {
            &[]
        })
        .args(["-start_number", &range.start().to_string(), "-i", &input])
        .args(["-frames:v", &(range.end() - range.start() + 1).to_string()])
        // H.264 in yuv420p (what players expect) needs even sides.
        .args([
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            "-pix_fmt",
            "yuv420p",
        ])
        .arg(&temp)
        .status()
        .context("cannot run ffmpeg")?;
    if !status.success() {
        let _ = std::fs::remove_file(&temp);
        anyhow::bail!("ffmpeg failed ({status}) making {}", path.display());
    }
    std::fs::rename(&temp, pending.temp())?;
    pending.commit()?;
    Ok(Some(path))
}

type Chunk = (u32, std::ops::RangeInclusive<u32>, Vec<serde_json::Value>);

/// report.md: what each chunk rendered and saved, and the plot.
fn report(
    run: &RunArgs,
    range: &std::ops::RangeInclusive<u32>,
    view: &str,
    chunks: &[Chunk],
) -> String {
    let number = |row: &serde_json::Value, key: &str| row[key].as_f64().unwrap_or(0.0);
    let mut text = format!(
        "# {}: frames {}-{} in {} chunks\n\n\
         Each chunk is one task of a Slurm job array; it starts from a full frame, so the \
         first frame of every chunk traces everything and reuse starts again from there.\n\n\
         | chunk | frames | rendering ms | ms a frame | samples traced | pixels reused |\n\
         |---:|---|---:|---:|---:|---:|\n",
        run.scene.display(),
        range.start(),
        range.end(),
        run.chunks
    );
    let (mut all_ms, mut all_traced, mut all_pixels, mut all_reused) = (0.0, 0.0, 0.0, 0.0);
    for (index, frames, rows) in chunks {
        let rows: Vec<_> = rows
            .iter()
            .filter(|r| r["viewport"].as_str().unwrap_or_default() == view)
            .collect();
        let ms: f64 = rows.iter().map(|r| number(r, "total_ms")).sum();
        let traced: f64 = rows.iter().map(|r| number(r, "samples_traced")).sum();
        let pixels: f64 = rows.iter().map(|r| number(r, "pixels")).sum();
        let reused: f64 = rows.iter().map(|r| number(r, "pixels_reused")).sum();
        text.push_str(&format!(
            "| {index} | {}-{} | {ms:.1} | {:.1} | {traced:.0} | {:.1}% |\n",
            frames.start(),
            frames.end(),
            ms / rows.len().max(1) as f64,
            100.0 * reused / pixels.max(1.0)
        ));
        all_ms += ms;
        all_traced += traced;
        all_pixels += pixels;
        all_reused += reused;
    }
    let count = (range.end() - range.start() + 1) as f64;
    text.push_str(&format!(
        "| all | {}-{} | {all_ms:.1} | {:.1} | {all_traced:.0} | {:.1}% |\n\n",
        range.start(),
        range.end(),
        all_ms / count,
        100.0 * all_reused / all_pixels.max(1.0)
    ));
    text.push_str(&restart_cost(chunks, view, all_ms));
    text.push_str(
        "![pixels reused per frame](savings.png)\n\n\
         Files: `animation.gif` (and `animation.mp4` where ffmpeg is installed), \
         `stats.csv` and `stats.json` (every frame's statistics, all chunks), \
         `stats.chunkN.json` (each task's own), `logs/` (each task's log).\n",
    );
    text
}

/// What the run's own restarts cost: each chunk's first frame against its
/// other frames (a paragraph, empty with one chunk or one frame a chunk).
fn restart_cost(chunks: &[Chunk], view: &str, all_ms: f64) -> String {
    let (mut first, mut rest) = (Vec::new(), Vec::new());
    for (_, _, rows) in chunks {
        let ms: Vec<f64> = rows
            .iter()
            .filter(|r| r["viewport"].as_str().unwrap_or_default() == view)
            .map(|r| r["total_ms"].as_f64().unwrap_or(0.0))
            .collect();
        if let Some((head, tail)) = ms.split_first() {
            first.push(*head);
            rest.extend_from_slice(tail);
        }
    }
    if first.len() < 2 || rest.is_empty() {
        return String::new();
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (first_ms, rest_ms) = (mean(&first), mean(&rest));
    let restarts = (first.len() - 1) as f64;
    let lost = restarts * (first_ms - rest_ms);
    format!(
        "Restarts: a chunk's first frame took {first_ms:.1} ms on average, its other frames \
         {rest_ms:.1} ms; the {restarts:.0} restarts beyond one run's cost about {lost:.0} ms, \
         {:.1}% of the rendering time (`retrace bench --only chunking` measures the whole \
         curve, and `retrace farm submit` prints the chunk size it recommends).\n\n",
        100.0 * lost / all_ms.max(f64::MIN_POSITIVE)
    )
}

fn status(args: StatusArgs) -> Result<()> {
    let mut records = Vec::new();
    for job in &args.jobs {
        records.extend(job_records(job)?);
    }
    sort_records(&mut records);
    say!(
        "{:<12} {:<18} {:<12} {:<10} {:<9} reason",
        "job",
        "name",
        "state",
        "exit",
        "restarts"
    );
    for r in &records {
        let id = match &r.task {
            Some(task) => format!("{}_{task}", r.job),
            None => r.job.clone(),
        };
        say!(
            "{:<12} {:<18} {:<12} {:<10} {:<9} {}",
            id,
            r.name,
            r.state,
            r.exit_text(),
            r.restarts.map_or("?".to_string(), |n| n.to_string()),
            r.reason
        );
    }
    let failed: Vec<String> = records
        .iter()
        .filter(|r| r.failed())
        .map(|r| {
            let id = match &r.task {
                Some(task) => format!("task {task} of {}", r.job),
                None => format!("job {}", r.job),
            };
            format!("{id} {} ({})", r.state, r.exit_text())
        })
        .collect();
    let done = records.iter().filter(|r| r.state == "COMPLETED").count();
    let ended = records.iter().filter(|r| r.ended()).count();
    say!(
        "{done} completed, {} failed, {} not ended{}",
        failed.len(),
        records.len() - ended,
        if failed.is_empty() {
            String::new()
        } else {
            format!(": {}", failed.join("; "))
        }
    );
    Ok(())
}

/// The job's records from slurmctld's memory (scontrol, which counts
/// restarts), or from accounting once slurmctld has forgotten the job.
fn job_records(job: &str) -> Result<Vec<retrace::farm::TaskRecord>> {
    let scontrol = Command::new("scontrol")
        .args(["-o", "show", "job", job])
        .output()
        .context("cannot run scontrol (is Slurm's client installed and on PATH?)")?;
    if scontrol.status.success() {
        let records = parse_scontrol(&String::from_utf8_lossy(&scontrol.stdout));
        if !records.is_empty() {
            return Ok(records);
        }
    }
    let sacct = Command::new("sacct")
        .args(["-n", "-P", "-X", "-j", job])
        .args(["-o", "JobID,JobName,State,ExitCode,Reason"])
        .output();
    if let Ok(sacct) = sacct {
        let records = parse_sacct(&String::from_utf8_lossy(&sacct.stdout));
        if sacct.status.success() && !records.is_empty() {
            return Ok(records);
        }
    }
    anyhow::bail!(
        "job {job}: slurmctld does not know it ({}) and accounting has no record of it",
        String::from_utf8_lossy(&scontrol.stderr).trim()
    )
}

//! `retrace view`: a scene in a window (drag, zoom, play), or the same
//! input from a script without a display.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use anyhow::{Context, Result};
use clap::Args;

use retrace::output::{save_image, save_text};
use retrace::sampling::MAX_SAMPLES_PER_PIXEL;
use retrace::view::help::key_list;
use retrace::view::refine::DEFAULT_REFINE_SPP;
use retrace::view::script::{parse_script, run_script, stats_csv, EventStats};
use retrace::view::window::{run_window, Ending, Hooks, LastWords, Shown, Stop};
use retrace::view::worker::{Abandoned, Stage};
use retrace::view::{next_save_path, Picture, RenderThread, ViewState, Viewer};

use super::{check_writable, ensure_parent, load, scene_name, BackendArg, SceneArgs};

#[derive(Args)]
pub(crate) struct ViewArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Run the input of this script instead of opening a window (drag DX
    /// DY, wheel N [X Y], key K, play N, wait, wait-converged, sleep MS,
    /// save PATH; see the guide), through the same render thread, without
    /// a display.
    #[arg(long)]
    script: Option<PathBuf>,
    /// Statistics as CSV: with --script one row per command (ms from the
    /// command to its picture, samples traced), in a window one per
    /// picture shown.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Where `s` saves pictures (view_0001.png, view_0002.png, ...).
    #[arg(long, default_value = "out")]
    save_dir: PathBuf,
    /// Print a line for every picture the window shows (its request, state
    /// and times): for tests and scripts that drive the window.
    #[arg(long)]
    print_pictures: bool,
    /// In idle time, refine the picture to this many samples a pixel (the
    /// scene's samples times 4, times 16, ... up to it); the scene's
    /// samples a pixel or fewer: no refinement.
    #[arg(long, default_value_t = DEFAULT_REFINE_SPP,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_SAMPLES_PER_PIXEL)))]
    refine_spp: u32,
    /// The most memory, in MB, the samples kept for zoomed and turned views
    /// may take; past it, those read least recently are dropped and traced
    /// again when needed [default: 1024, or a quarter of the machine's
    /// memory if that is less].
    #[arg(long, value_name = "MB",
          value_parser = clap::value_parser!(u64).range(1..=MAX_SAMPLE_MEMORY_MB))]
    sample_memory: Option<u64>,
}

/// The largest `--sample-memory`: 16 TB, which no byte count overflows.
const MAX_SAMPLE_MEMORY_MB: u64 = 1 << 24;

/// The cap on the kept samples unless `--sample-memory` says otherwise:
/// 1024 MB, or a quarter of the machine's memory if that is less (1024 MB
/// where /proc/meminfo does not say).
fn default_sample_memory() -> u64 {
    const DEFAULT: u64 = 1 << 30;
    let total = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| mem_total_bytes(&text));
    total.map_or(DEFAULT, |total| DEFAULT.min(total / 4))
}

/// The `MemTotal:` line of /proc/meminfo, in bytes.
fn mem_total_bytes(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find_map(|l| l.strip_prefix("MemTotal:"))?;
    let kb = line.trim().strip_suffix("kB")?.trim().parse::<u64>().ok()?;
    kb.checked_mul(1024).filter(|&bytes| bytes > 0)
}

pub(crate) fn view(args: ViewArgs) -> Result<()> {
    if let Some(path) = &args.stats {
        if path.extension().map(|e| e.to_ascii_lowercase()) != Some("csv".into()) {
            anyhow::bail!("--stats {}: use a .csv file", path.display());
        }
        check_writable(&super::folder_of(path))?;
    }
    // A script is read and checked before the scene is loaded or traced.
    let script = match &args.script {
        Some(path) => Some((
            path,
            std::fs::read_to_string(path)
                .with_context(|| format!("cannot read the script {}", path.display()))?,
        )),
        None => None,
    };
    let scene = load(&args.scene)?;
    if !scene.viewports.is_empty() {
        let names: Vec<&str> = scene
            .viewports
            .iter()
            .map(|t| t.viewport.name.as_str())
            .collect();
        let then = match &names[1..] {
            [] => "`v` shows the camera's image, and the viewport again".to_string(),
            others => format!(
                "`v` shows the next ({}), then the camera's image",
                others.join(", ")
            ),
        };
        eprintln!(
            "note: the view opens on the scene's viewport {} as `retrace animate` renders it; \
             {then}",
            names[0]
        );
    }
    let name = scene_name(&args.scene);
    let grid = args.backend.grid_resolution()?;
    let sample_memory = Some(
        args.sample_memory
            .map_or_else(default_sample_memory, |mb| mb << 20),
    );
    match script {
        Some((path, text)) => {
            let viewer = Viewer::new(&scene);
            let lines = parse_script(&text, path, viewer.size())?;
            let thread = RenderThread::spawn(
                scene,
                args.backend.backend,
                grid,
                true,
                args.refine_spp,
                sample_memory,
                Box::new(|| {}),
            )
            .map_err(anyhow::Error::msg)?;
            let save_dir = args.save_dir.clone();
            let mut next_save = move || next_save_path(&save_dir);
            let mut save = |path: &Path, image: &image::RgbImage| -> Result<(), String> {
                ensure_parent(path).map_err(|e| e.to_string())?;
                save_image(path, image).map_err(|e| e.to_string())?;
                say!("saved {}", path.display());
                Ok(())
            };
            // An interrupt ends the script after the picture under way,
            // with the statistics of the commands run written.
            super::stop_on_interrupt(Some(thread.interrupter()));
            let ran = run_script(&thread, &viewer, &lines, &mut next_save, &mut save);
            super::stop_on_interrupt(None);
            let rows = ran.map_err(anyhow::Error::msg)?;
            say_script(&name, &rows, &thread.abandoned());
            if let Some(path) = &args.stats {
                save_text(path, &stats_csv(&rows)?)?;
            }
            if thread.interrupted() {
                eprintln!("\ninterrupted");
                retrace::output::remove_unfinished_and_exit(130)
            }
            Ok(())
        }
        None => {
            let rows = Arc::new(Mutex::new(Vec::new()));
            let mut hooks = WindowHooks {
                viewer: Viewer::new(&scene),
                print: args.print_pictures,
                save_dir: args.save_dir.clone(),
                rows: Arc::clone(&rows),
                stats: args.stats.clone(),
            };
            eprintln!("{}", key_list());
            let ran = run_window(
                scene,
                &name,
                args.backend.backend,
                grid,
                args.refine_spp,
                sample_memory,
                &mut hooks,
            );
            super::stop_on_interrupt(None);
            let ending = ran.map_err(anyhow::Error::msg)?;
            // Whatever ended the window, the statistics asked for are
            // written.
            let written = write_window_stats(args.stats.as_deref(), &rows);
            match ending {
                Ending::Failed(err) => {
                    if let Err(stats_err) = written {
                        eprintln!("error: {}", crate::error_text(&stats_err));
                    }
                    Err(anyhow::Error::msg(err))
                }
                Ending::Interrupted => {
                    written?;
                    eprintln!("\ninterrupted");
                    retrace::output::remove_unfinished_and_exit(130)
                }
                other => {
                    written?;
                    eprintln!("view ended: {}", other.why());
                    Ok(())
                }
            }
        }
    }
}

/// The window's statistics, a row per picture, if asked for; says where
/// they went.
fn write_window_stats(path: Option<&Path>, rows: &Mutex<Vec<EventStats>>) -> Result<()> {
    let Some(path) = path else {
        return Ok(());
    };
    let rows = rows.lock().unwrap_or_else(PoisonError::into_inner);
    save_text(path, &stats_csv(&rows)?)?;
    let plural = if rows.len() == 1 { "" } else { "s" };
    say!(
        "statistics of {} picture{plural} written to {}",
        rows.len(),
        path.display()
    );
    Ok(())
}

/// A script's run in a few lines: the pictures' times, and the pictures
/// given up for newer input.
fn say_script(name: &str, rows: &[EventStats], abandoned: &[Abandoned]) {
    let times: Vec<f64> = rows.iter().filter_map(|r| r.ms_to_picture).collect();
    let traced: u64 = rows
        .iter()
        .filter_map(|r| r.picture.as_ref())
        .map(|p| p.work.samples_traced)
        .sum();
    say!(
        "{name}: {} commands with a picture, ms to picture: median {:.1}, max {:.1}; {} samples traced",
        times.len(),
        median(&times),
        times.iter().copied().fold(0.0, f64::max),
        traced
    );
    let converged: Vec<f64> = rows.iter().filter_map(|r| r.ms_to_converged).collect();
    // For each kind of picture given up: how many, and ms from the newer
    // input to giving up.
    let given_up = |frame_loop: bool| {
        let waited: Vec<f64> = abandoned
            .iter()
            .filter(|a| a.frame_loop == frame_loop)
            .map(|a| a.waited_ms)
            .collect();
        match waited.len() {
            0 => "none abandoned".to_string(),
            n => format!(
                "{n} abandoned for newer input, which waited for them ms: median {:.1}, max {:.1}",
                median(&waited),
                waited.iter().copied().fold(0.0, f64::max)
            ),
        }
    };
    say!(
        "refinement: {} commands with a converged picture, ms to converged: median {:.1}; {}",
        converged.len(),
        median(&converged),
        given_up(false)
    );
    if abandoned.iter().any(|a| a.frame_loop) {
        say!("pictures traced from nothing: {}", given_up(true));
    }
}

fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    match sorted.len() {
        0 => 0.0,
        n => sorted[n / 2],
    }
}

struct WindowHooks {
    viewer: Viewer,
    print: bool,
    save_dir: PathBuf,
    /// Shared with the last words on a lost X server, which write them.
    rows: Arc<Mutex<Vec<EventStats>>>,
    stats: Option<PathBuf>,
}

impl Hooks for WindowHooks {
    fn presented(&mut self, picture: &Picture, latency_ms: f64, first_ms: f64, title: &str) {
        let state = &picture.state;
        let shown = self.viewer.shown_name(state);
        let (width, height) = (picture.image.width(), picture.image.height());
        if self.print {
            say!(
                "{}picture {}: size {width}x{height} shows {} frame {} yaw {:.6} pitch {:.6} zoom notches {} reuse {} mode {} \
                 spp {} render {:.2} ms latency {:.2} ms traced {} | {title}",
                if picture.complete { "" } else { "coarse " },
                picture.generation,
                shown.replace(' ', "_"),
                state.frame,
                state.yaw.to_degrees(),
                state.pitch.to_degrees(),
                state.notches,
                if state.reuse { "on" } else { "off" },
                picture.mode(),
                picture.samples,
                picture.stats.total_ms(),
                latency_ms,
                picture.stats.work.samples_traced
            );
        }
        if !picture.complete {
            return;
        }
        let mut rows = self.rows.lock().unwrap_or_else(PoisonError::into_inner);
        if picture.stage == Stage::Refined {
            // The row of the request it refines.
            if let Some(row) = rows
                .last_mut()
                .filter(|r| r.event == format!("picture {}", picture.generation))
            {
                if picture.converged {
                    row.ms_to_converged = Some(latency_ms);
                }
            }
            return;
        }
        rows.push(EventStats {
            line: 0,
            event: format!("picture {}", picture.generation),
            frame: state.frame,
            reuse: state.reuse,
            mode: Some(picture.mode()),
            ms_to_first_picture: Some(first_ms),
            ms_to_picture: Some(latency_ms),
            ms_to_converged: picture.converged.then_some(latency_ms),
            pixels: u64::from(picture.image.width()) * u64::from(picture.image.height()),
            picture: Some(picture.stats.clone()),
        });
    }

    fn redrawn(&mut self, picture: &Picture, asked: &ViewState, shown: Shown) {
        if self.print {
            let on = |on: bool| if on { "on" } else { "off" };
            say!(
                "shown picture {}: help {} overlay {} asking frame {} yaw {:.6} pitch {:.6} zoom notches {}",
                picture.generation,
                on(shown.help),
                on(shown.overlay),
                asked.frame,
                asked.yaw.to_degrees(),
                asked.pitch.to_degrees(),
                asked.notches
            );
        }
    }

    fn opened(&mut self, stop: Stop) {
        super::stop_on_interrupt(Some(stop));
    }

    fn when_display_lost(&mut self) -> LastWords {
        let rows = Arc::clone(&self.rows);
        let stats = self.stats.clone();
        Box::new(move |why| {
            eprintln!("error: {why}");
            if let Err(err) = write_window_stats(stats.as_deref(), &rows) {
                eprintln!("error: {}", crate::error_text(&err));
            }
        })
    }

    fn save(&mut self, image: &image::RgbImage) -> Result<String, String> {
        let path = next_save_path(&self.save_dir);
        ensure_parent(&path).map_err(|e| e.to_string())?;
        save_image(&path, image).map_err(|e| e.to_string())?;
        say!("saved {}", path.display());
        Ok(path.display().to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_machine_s_memory_is_read_from_meminfo() {
        let meminfo = "MemTotal:       24731184 kB\nMemFree:          190632 kB\n";
        assert_eq!(mem_total_bytes(meminfo), Some(24_731_184 * 1024));
        for bad in [
            "",
            "MemFree: 10 kB\n",
            "MemTotal: lots kB\n",
            "MemTotal: 0 kB\n",
        ] {
            assert_eq!(mem_total_bytes(bad), None, "{bad:?}");
        }
        let default = default_sample_memory();
        assert!(default > 0 && default <= 1 << 30, "{default}");
    }
}

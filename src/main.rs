//! The `retrace` command line: parses arguments, calls the library, reports.

#![deny(unsafe_code)]

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

use cli::animate::{animate, AnimateArgs};
#[cfg(feature = "lab")]
use cli::bench::{bench, BenchArgs};
#[cfg(feature = "farm")]
use cli::farm::{farm, FarmArgs};
use cli::render::{render, RenderArgs};
#[cfg(feature = "lab")]
use cli::tradeoff::{tradeoff, TradeoffArgs};
#[cfg(feature = "lab")]
use cli::validate::{validate, ValidateArgs};
#[cfg(feature = "view")]
use cli::view::{view, ViewArgs};

/// Prints a line to stdout; a closed stdout (`retrace ... | head -1`) is
/// not an error worth a panic: the work is done, only the report is cut.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

mod cli;

#[derive(Parser)]
#[command(
    name = "retrace",
    version,
    about = "A ray tracer for animation that re-traces only what changed"
)]
struct Cli {
    /// Worker threads, at most 4 a core or 256, whichever is more; 0 is
    /// taken as 1 [default: one per core].
    #[arg(long, global = true, allow_negative_numbers = true, value_parser = parse_threads)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

// A subcommand whose feature is off is left out rather than refused at
// run time: `--help` lists only what this build can do.
#[derive(Subcommand)]
enum Command {
    /// Render one image of a scene file (.toml) or a bare model (.obj).
    Render(RenderArgs),
    /// Render an animation's frames, re-tracing only what changed.
    Animate(AnimateArgs),
    #[cfg(feature = "lab")]
    /// Measure rendering costs (release builds only make sense here).
    Bench(BenchArgs),
    #[cfg(feature = "lab")]
    /// Check Embree against the pure-Rust grid: ray by ray (camera rays and
    /// seeded random rays) and image by image. Exits with status 1 when
    /// agreement falls below the limits: hit/miss agreement 99.95%, same
    /// primitive on 99.9% of common hits; on those, the two hit points at
    /// most gamma(32) M apart across the surface (f32 rounding: gamma(n) =
    /// n u / (1 - n u), u = 2^-24, M = the largest coordinates of the ray
    /// origin, of t times the direction and of the primitive, added; about
    /// 6e-5 for coordinates near 10); at most 0.5% of pixels differing by
    /// more than 1/255, mean colour difference 1e-3.
    Validate(ValidateArgs),
    #[cfg(feature = "lab")]
    /// Sweep each approximation knob (pan snap vs resample; RSVP filter,
    /// oversampling and level bias; OSTC region and voxel grids) and report
    /// its speedup against its error versus the exact reference (direct
    /// tracing of the output's own rays). Writes tradeoff.csv and
    /// tradeoff.png (error against speedup). All 100 frames take about 5
    /// CPU-minutes (roughly 3 minutes on a quiet 2-core machine, release
    /// build); `--frames 0-49` takes half that, with frame 0's full trace
    /// weighing more in each speedup.
    Tradeoff(TradeoffArgs),
    #[cfg(feature = "farm")]
    /// Render an animation on a Slurm cluster: submit a job array (one
    /// chunk of frames a task) and the job that assembles the result, and
    /// report each task's state.
    Farm(FarmArgs),
    #[cfg(feature = "view")]
    /// Open a scene in a window: drag pans, the wheel zooms about the
    /// cursor, space plays the timeline, `t` shows the samples each picture
    /// traced, `m` turns reuse off and on, `s` saves, `q` quits. With
    /// --script, the same input from a file, without a display.
    View(ViewArgs),
}

/// `err` and its causes, each said once: an error that prints its source
/// itself (`path: cannot write: No such file`) would otherwise repeat it.
fn error_text(err: &anyhow::Error) -> String {
    let mut text = err.to_string();
    for cause in err.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text = format!("{text}: {cause}");
        }
    }
    text
}

/// `--threads`'s value: a count, said so when it is not one (`-1` too,
/// rather than clap's hint to write `-- -1`).
fn parse_threads(s: &str) -> Result<usize, String> {
    s.trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number of threads (0 or more)"))
}

/// The most worker threads `--threads` may ask for: four for each core
/// this process may use, and never fewer than 256.
///
/// Rendering is CPU-bound: past one thread a core, threads only share the
/// same cores, and the frame loop keeps every worker looking for work
/// through a frame (`retrace::pool`), so each extra one costs. Four a core
/// leaves room to measure oversubscription; the floor lets a count fixed in
/// a script (a farm task's, a benchmark's) run on a small machine or in a
/// container whose CPU quota makes it look like one or two cores. Beyond
/// that, `--threads 100000` ran for minutes what takes a second, and a
/// few thousand threads (each reserves a stack) can exhaust the process's
/// memory or thread limits, which made the threads that failed to start
/// panic.
fn max_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    cores.saturating_mul(4).max(256)
}

/// Sets up the global pool with `threads` workers (0 is taken as 1), or
/// says why not: too many asked for, or the system refused them.
fn set_up_threads(threads: usize) -> Result<(), String> {
    let limit = max_threads();
    if threads > limit {
        return Err(format!(
            "--threads {threads}: at most {limit} worker threads here (4 for each of the \
             {} cores this process may use, and at least 256)",
            std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
        ));
    }
    // A thread the system starts but cannot give a signal stack panics as
    // it starts, before rayon sees the failure: its report would bury the
    // error below. The pool's own error says what went wrong.
    let report_panic = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let built = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build_global();
    match built {
        Ok(()) => {
            std::panic::set_hook(report_panic);
            Ok(())
        }
        // The hook stays quiet: the run stops here, and a thread that fails
        // to start while the others are let go would still report.
        Err(err) => Err(format!(
            "--threads {threads}: the system would not start that many worker threads \
             ({err}); ask for fewer"
        )),
    }
}

fn main() -> ExitCode {
    let mut command = cli::finish_command(Cli::command());
    let matches = command.clone().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|err| err.format(&mut command).exit());
    // Before any work: a count of threads the machine cannot run is
    // refused, not left to spin for minutes.
    if let Some(threads) = cli.threads {
        if let Err(err) = set_up_threads(threads) {
            eprintln!("error: {err}");
            return ExitCode::FAILURE;
        }
    }
    // Ctrl-C, or a scheduler's SIGTERM (or SIGHUP), stops at once, leaving
    // finished files and no unfinished ones (frames, GIFs, reports are
    // written under temporary names); the window winds down first.
    let interrupted = ctrlc::set_handler(cli::interrupted);
    if let Err(err) = interrupted {
        eprintln!("warning: an interrupt will not clean up unfinished files: {err}");
    }
    let result = match cli.command {
        // The window's thread waits for input: run on one of the pool's
        // workers it would leave the frame loop one thread short. The
        // viewer runs its frame loop on the pool itself.
        #[cfg(feature = "view")]
        Command::View(args) => view(args),
        command => run_in_pool(command),
    };
    say_removed_temporaries();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", error_text(&err));
            ExitCode::FAILURE
        }
    }
}

/// Says which temporary files killed runs had left in the folders this
/// run wrote into (and it removed).
fn say_removed_temporaries() {
    let removed = retrace::output::take_removed_temporaries();
    if let Some(first) = removed.first() {
        let more = match removed.len() {
            1 => String::new(),
            n => format!(" and {} more", n - 1),
        };
        eprintln!(
            "note: removed {}{more}, left by a run that was killed before it could clean up",
            first.display()
        );
    }
}

/// Runs `command` on a worker thread of the pool, so each parallel step
/// starts at once on this thread while the other workers wake. Called from
/// outside the pool, every step first waited for a sleeping worker, ~0.2
/// ms here (2 vCPUs); an RSVP frame has five steps of 0.2-2 ms each, so it
/// paid that wait five times a frame.
fn run_in_pool(command: Command) -> anyhow::Result<()> {
    rayon::scope(|_| match command {
        Command::Render(args) => render(args),
        Command::Animate(args) => animate(args),
        #[cfg(feature = "lab")]
        Command::Bench(args) => bench(args),
        #[cfg(feature = "lab")]
        Command::Validate(args) => validate(args),
        #[cfg(feature = "lab")]
        Command::Tradeoff(args) => tradeoff(args),
        #[cfg(feature = "farm")]
        Command::Farm(args) => farm(args),
        #[cfg(feature = "view")]
        Command::View(args) => view(args),
    })
}

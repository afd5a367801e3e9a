//! `report.md`: the run, the table, what each column and experiment
//! means, the oracle, and each experiment's plots.

use super::table::{cells, numeric, TABLE_HEADER};
use super::{
    accuracy_plot_file, has_reference, profile_file, rays_plot_file, time_plot_file, BenchRow,
    ErrorSummary, ExperimentResult,
};

/// What the run was: printed at the top of report.md.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RunInfo {
    pub command: String,
    pub backend: String,
    pub threads: usize,
    /// `uptime`'s load average when the run started and ended, if known.
    pub load: Option<(f64, f64)>,
    pub release: bool,
}

/// A markdown table of `rows` (the same cells as the terminal's).
fn markdown_table(rows: &[BenchRow]) -> String {
    let mut out = format!("| {} |\n", TABLE_HEADER.join(" | "));
    let rule: Vec<&str> = (0..TABLE_HEADER.len())
        .map(|c| if numeric(c) { "---:" } else { "---" })
        .collect();
    out.push_str(&format!("| {} |\n", rule.join(" | ")));
    for row in rows {
        let cells = cells(row).map(|c| c.replace('|', "\\|"));
        out.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    out
}

/// report.md: the run, the table, what each column and experiment means,
/// the oracle, and each experiment's plots (relative links).
pub fn report_markdown(run: &RunInfo, results: &[ExperimentResult]) -> String {
    let rows: Vec<BenchRow> = results.iter().map(|r| r.row.clone()).collect();
    let mut md = String::new();
    md.push_str("# retrace bench\n\n");
    md.push_str(&format!(
        "`{}` — backend {}, {} threads, {} build{}.\n\n",
        run.command,
        run.backend,
        run.threads,
        if run.release {
            "release"
        } else {
            "DEBUG (timings mean little)"
        },
        run.load.map_or_else(String::new, |(start, end)| format!(
            ", load average {start:.2} at the start and {end:.2} at the end"
        )),
    ));
    md.push_str(
        "Both sides of every ratio were measured in this one run, on the same backend, \
         threads and packet width. Absolute times depend on the machine and its load; \
         the ratios are the result.\n\n",
    );
    md.push_str(&markdown_table(&rows));
    md.push_str(
        "\nThe same rows with full precision: [bench.csv](bench.csv), [bench.json](bench.json).\n",
    );
    md.push_str(COLUMNS_EXPLAINED);
    md.push_str(EXPERIMENTS_EXPLAINED);
    md.push_str(ORACLE_EXPLAINED);
    md.push_str("\n## Per frame\n\n");
    md.push_str(
        "Left: each frame's time, full render against the accelerated sequence. Right: \
         rays traced per frame by kind on the accelerated side, against all rays of the full \
         render and the oracle's samples (the least any reuse must trace). Frame 0 has \
         nothing to reuse and costs a full frame or more.\n",
    );
    for result in results {
        let info = &result.row.info;
        let accuracy = if has_reference(&result.profile) {
            format!(
                " ![{} PSNR against the reference]({})",
                info.id,
                accuracy_plot_file(&info.id)
            )
        } else {
            String::new()
        };
        md.push_str(&format!(
            "\n### {} — {} ({}, {}x{})\n\n{}\n\n![{} time per frame]({}) ![{} rays per frame]({}){}\n\n\
             Per-frame numbers: [{}]({}).\n",
            info.id,
            info.what,
            info.scene,
            info.width,
            info.height,
            summary(&result.row),
            info.id,
            time_plot_file(&info.id),
            info.id,
            rays_plot_file(&info.id),
            accuracy,
            profile_file(&info.id),
            profile_file(&info.id),
        ));
    }
    md
}

/// One sentence about a row, for report.md.
pub(super) fn summary(row: &BenchRow) -> String {
    let oracle = match (row.oracle_speedup, row.efficiency) {
        (Some(o), Some(e)) => format!(
            "; the oracle allows {o:.1}x, so the reuse gets {:.0}% of the way",
            e * 100.0
        ),
        _ => "; no oracle was measured".to_string(),
    };
    format!(
        "{:.2} ms per frame in full against {:.2} ms accelerated over {} frames: {:.2}x (paper: {}){}. {}. {}{}",
        row.full_ms_per_frame,
        row.accelerated_ms_per_frame,
        row.frames,
        row.speedup,
        row.info.paper_speedup,
        oracle,
        capitalise(&row.exactness),
        time_split(row),
        reference_errors(row),
    )
}

/// Both sides against the converged reference, every figure, for report.md.
fn reference_errors(row: &BenchRow) -> String {
    let (Some(samples), Some(full), Some(fast)) = (
        row.reference_samples,
        row.full_vs_reference,
        row.accelerated_vs_reference,
    ) else {
        return String::new();
    };
    let frames: Vec<String> = row.reference_frames.iter().map(u32::to_string).collect();
    let figures = |e: ErrorSummary| {
        format!(
            "PSNR {:.2} dB worst, {:.2} mean; max abs {:.3}; mean abs {:.5}; {:.2}% of pixels differ by more than one 8-bit step",
            e.worst_psnr_db,
            e.mean_psnr_db,
            e.max_abs,
            e.mean_abs,
            e.differing_share * 100.0
        )
    };
    let shown = if row.accelerated_vs_keyed_reference.is_some() {
        " (against the reference of the snapped view it shows)"
    } else {
        ""
    };
    let keyed = row
        .accelerated_vs_keyed_reference
        .map_or_else(String::new, |k| {
            format!(
                " Against the keyed camera's reference, the snapped output scores {}.",
                figures(k)
            )
        });
    format!(
        " Against a {samples}-spp reference of frames {}: the full render at {} spp: {}; \
         the accelerated output{shown}: {}.{keyed}",
        frames.join(", "),
        row.samples_per_pixel,
        figures(full),
        figures(fast),
    )
}

/// Where the accelerated time went, and what the speedup would be if the
/// copying cost nothing: the bound that tracing less cannot lift.
fn time_split(row: &BenchRow) -> String {
    let bookkeeping = (1.0 - row.tracing_share - row.copying_share).max(0.0);
    let mut text = format!(
        "The accelerated side spent {:.0}% of its time tracing and {:.0}% copying{}",
        row.tracing_share * 100.0,
        row.copying_share * 100.0,
        if row.info.uses_rsvp() {
            " (mapping and resampling the buffer)"
        } else {
            ""
        },
    );
    if bookkeeping >= 0.005 {
        text.push_str(&format!(
            ", {:.0}% on OSTC bookkeeping",
            bookkeeping * 100.0
        ));
    }
    if row.copying_share < 1.0 {
        text.push_str(&format!(
            "; with copying free it would run {:.1}x faster than in full",
            row.speedup / (1.0 - row.copying_share)
        ));
    }
    text.push('.');
    text
}

fn capitalise(text: &str) -> String {
    let mut chars = text.chars();
    match chars.next() {
        Some(first) => first.to_uppercase().chain(chars).collect(),
        None => String::new(),
    }
}

const COLUMNS_EXPLAINED: &str = "
## Columns

- **experiment**: the paper's experiment and the reuse that accelerates it.
- **scene**: the scene and its triangle count (spheres and planes stay analytic and add none).
- **size**: the output frame (or viewport) in pixels.
- **spp (ref)**: samples a pixel both sides traced (`--spp`), and in brackets those of the \
converged reference both are measured against (64, or 256 for runs of 64 or more: a 64-spp \
frame is 52-55 dB from a 256-spp one, well under the errors measured against it).
- **paper**: the speedup Gage & Semwal report for it.
- **full ms/frame**: mean time of a full render of each output frame (tracing every pixel \
through its own ray, in place; conversion to 8 bits included, file writing excluded): the \
fastest plain render of the same frames.
- **vs plain**: the full side's time over plain renders of the same views made outside the \
frame loop (as `retrace bench --only frame` makes them), on every tenth frame: near 1.00, or \
the full side is slower than it should be and the speedup reads high.
- **accel ms/frame**: the same for the accelerated sequence; it pays for everything it does: \
frame 0, buffers, recording, merging, copies, resampling, scene updates.
- **speedup**: full time over accelerated time, whole sequences. With `--repeats`, the \
medians' ratio, and in brackets the lowest and highest of the rounds' own speedups (each \
round's full sequence over the accelerated one right after it): how far the machine's own \
noise moves the figure.
- **oracle (sample / region)**: the speedup of the least tracing any reuse could get away \
with (below). For camera sequences: the rays full renders of all frames trace over the rays of \
the samples that had to be traced; the second figure traces every OSTC region holding such a \
sample whole: the best a method working in whole regions (as OSTC does) could do. The third \
(timed) is that region oracle run for real: after each full render, the groups of the regions \
that had to be traced are traced again and timed; full renders over frame 0 in full plus those \
times. It prices each ray at what it costs: rays near a moving object hit it, reflect and \
cast shadows more than the average ray, which counting rays cannot see. For viewports: \
output pixels over needed samples. `n/a` where it was not measured.
- **efficiency**: speedup / oracle (per sample / per region / per region timed): how close the reuse comes to the \
limit, its overheads included. It can pass 100% where the oracle counts only tracing and the \
full side pays for more than tracing, or where the region oracle is coarser than the reuse.
- **bookkeeping**: OSTC's recording of rays into voxels and merging of dirty regions, per frame, \
as a share of a full frame's time; `none` where the experiment runs no OSTC.
- **full vs ref dB** and **accel vs ref dB**: PSNR, worst / mean over the frames and views \
measured, of the full render at the run's samples and of the accelerated output against the \
converged reference of the same views, rendered on an untimed pass for every 20th frame and \
the last. The first is what the run's samples a pixel cost in accuracy, the second that plus \
what reuse adds. A snapped pan's frames are exact renders of the camera moved onto the \
pan lattice (by at most half a sample in yaw and pitch), so they are measured against the \
reference of that view; the exactness column gives the largest snap and the output's \
PSNR against the keyed camera's reference besides. Exact output equals its full render, \
so the two columns differ only where the output is resampled or snapped. Mean and largest absolute error and the share of \
pixels differing by more than one 8-bit step are in bench.csv and below.
- **exactness / error**: `bit-exact`: every accelerated frame equals its full render bit for \
bit (checked on an untimed pass). Viewports are resampled from the sample buffer, so their \
error against direct renders is given instead (worst PSNR over frames and viewports); with \
OSTC the kept buffer samples are also re-traced at checkpoints and compared bit for bit.
";

const EXPERIMENTS_EXPLAINED: &str = "
## Experiments

- **E1** (Panimation): the paper scene's equal-angle camera yaws 3.6 degrees a frame, a \
whole turn in 100 frames. A pan is a shift of the sample buffer; only the newly exposed \
columns are traced. Frames are snapped to the pan lattice; on the untimed pass each is \
compared bit for bit with a full render on the same lattice.
- **E2 in / E2 out** (RSVP): one perspective viewport of the frame's size zooms between a \
100 and a 50 degree field of view over 100 frames, in and out. The viewport resamples the \
lazily traced sample pyramid around the eye and traces only the null samples it reads.
- **E3** (OSTC): a small ball bounces before the still camera. Each frame re-traces only \
the screen regions whose recorded rays (primary, shadow, reflection) crossed the voxels the \
ball left or entered.
- **E4** (all): E1's pan, E2's zoom in and E3's ball at once, seen through a perspective \
viewport: OSTC erases dirty regions of the sample buffer, the viewport resamples it and \
traces the nulls it reads.
- Rows on other scenes or sizes (scaling) run the same experiments there.
";

const ORACLE_EXPLAINED: &str = "
## The oracle

The least tracing any reuse could get away with, counted per sample from full renders on an \
untimed pass:

- **Camera sequences (E1, E3)**: a sample is a point of the pan lattice (equal-angle cameras; \
a whole turn, so a sample keeps its identity as the view moves). A frame must trace the \
samples it shows that were never shown before (newly exposed by the pan) and those whose \
colour differs from the colour last shown there (what changed). The per-region variant \
traces every OSTC region holding such a sample whole: the best OSTC can do at its region size. \
Samples are weighted by the rays their full render traced (primary, shadow and reflection, \
counted per pixel on the untimed pass): a sample on a mirror costs several times one on the \
sky, and the samples that change (a moving ball, its shadows and reflections) cost more than \
the average.
- **Viewport sequences (E2, E4)**: each viewport pixel needs one buffer sample: the nearest \
sample of the coarsest pyramid level whose spacing is no wider than the pixel's footprint (one \
sample per pixel, the least that keeps the output's detail). A frame must trace the needed \
samples never traced before (exposed by the pan, or by zooming into a finer level) and, when \
objects move, those whose colour truly changed since they were last traced (every needed \
sample is traced again on the untimed pass to find out). RSVP itself reads four samples per \
pixel (bilinear), picks levels per 16x16-pixel patch and traces whole groups of eight \
samples; that gap is part of what the efficiency shows.

Oracle speedup = rays of full renders of all frames / rays of the oracle's samples (camera \
sequences), or output pixels over all frames / oracle samples (viewports): it counts tracing \
only, as if everything else were free.
";

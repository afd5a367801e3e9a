//! What `retrace bench` reports: one row per experiment (the paper's
//! table), the rows as CSV and JSON, each experiment's per-frame profile as
//! CSV, and `report.md`, which puts the table and the plots together for a
//! reader.
//!
//! Every figure that could not be measured honestly is `None` here, "n/a"
//! in the table and an empty cell in CSV; nothing is made up to fill a
//! column.

use crate::lab::bench::{FrameProfile, SequenceBench};

/// What an experiment is, before it is measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ExperimentInfo {
    /// `E1`, `E2 in`, ...; also names its files (see [`file_stem`]).
    pub id: String,
    /// What changes from frame to frame.
    pub what: String,
    /// The reuse that accelerates it (Panimation, RSVP, OSTC, ...).
    pub technique: String,
    /// The speedup the paper reports, as it says it ("~10x"; "-" if none).
    pub paper_speedup: String,
    /// The scene's name and size.
    pub scene: String,
    pub triangles: u64,
    pub width: u32,
    pub height: u32,
}

impl ExperimentInfo {
    /// Whether the experiment resamples viewports from an RSVP buffer.
    pub fn uses_rsvp(&self) -> bool {
        self.technique.contains("RSVP")
    }
}

/// One line of the table.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BenchRow {
    #[serde(flatten)]
    pub info: ExperimentInfo,
    pub frames: u32,
    pub full_ms_per_frame: f64,
    /// The full side over plain renders of the same views made outside the
    /// frame loop: near 1 when the full side is the fastest plain render.
    pub full_vs_plain: f64,
    pub accelerated_ms_per_frame: f64,
    /// full / accelerated, for the whole sequence.
    pub speedup: f64,
    /// All output pixels over the samples the oracle must trace.
    pub oracle_speedup: Option<f64>,
    /// The same when whole OSTC regions are traced.
    pub region_oracle_speedup: Option<f64>,
    /// The region oracle timed: its regions' groups traced, not counted.
    pub timed_region_oracle_speedup: Option<f64>,
    /// speedup / oracle_speedup.
    pub efficiency: Option<f64>,
    /// OSTC recording and merging per frame over a full frame's time; None
    /// when the experiment has no OSTC.
    pub bookkeeping_share: Option<f64>,
    /// Of the accelerated time, the share spent tracing, and the share
    /// spent copying reused pixels (RSVP: mapping and resampling) and
    /// converting to 8 bits; the rest is OSTC bookkeeping.
    pub tracing_share: f64,
    pub copying_share: f64,
    pub samples_traced: u64,
    pub oracle_samples: Option<u64>,
    /// Every output frame (or kept buffer sample) bit-identical to a full
    /// render; None where the output is resampled and only an error applies.
    pub exact: Option<bool>,
    /// Worst PSNR of a resampled frame against its direct render.
    pub worst_psnr_db: Option<f64>,
    /// The exactness or error result, in words.
    pub exactness: String,
}

impl BenchRow {
    /// speedup / region_oracle_speedup: how close OSTC comes to the best
    /// any method tracing whole regions could do.
    pub fn region_efficiency(&self) -> Option<f64> {
        self.region_oracle_speedup.map(|r| self.speedup / r)
    }

    /// speedup / timed_region_oracle_speedup.
    pub fn timed_region_efficiency(&self) -> Option<f64> {
        self.timed_region_oracle_speedup.map(|r| self.speedup / r)
    }
}

/// An experiment's row and its per-frame profile.
#[derive(Clone, Debug, PartialEq)]
pub struct ExperimentResult {
    pub row: BenchRow,
    pub profile: Vec<FrameProfile>,
}

/// `E2 in` -> `e2-in`: the stem of the experiment's files.
pub fn file_stem(id: &str) -> String {
    id.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect()
}

impl ExperimentResult {
    /// A measured sequence: for the camera's image, the oracle and the
    /// exactness from the frames; for viewports, the oracle counts per
    /// frame `viewport_oracle` gives (None: not measured), the error of the
    /// resampled frames, and with OSTC the buffer's bit-for-bit check.
    pub fn from_bench(
        info: ExperimentInfo,
        mut bench: SequenceBench,
        viewport_oracle: Option<Vec<u64>>,
    ) -> Self {
        let frames = f64::from(bench.frames.max(1));
        let full_ms_per_frame = bench.full_ms / frames;
        if let Some(counts) = &viewport_oracle {
            for (row, &count) in bench.profile.iter_mut().zip(counts) {
                row.oracle_samples = Some(count);
            }
        }
        let oracle_samples: Option<u64> = bench
            .profile
            .iter()
            .any(|p| p.oracle_samples.is_some())
            .then(|| bench.profile.iter().filter_map(|p| p.oracle_samples).sum());
        let oracle_speedup = match (&bench.oracle, oracle_samples) {
            (Some(oracle), _) => Some(oracle.samples),
            (None, Some(samples)) => {
                let all_pixels = bench.pixels_per_frame as f64 * frames;
                Some(all_pixels / samples.max(1) as f64)
            }
            (None, None) => None,
        };
        let worst_psnr_db = bench
            .profile
            .iter()
            .any(|p| p.psnr_db.is_some())
            .then(|| bench.error.map_or(f64::NAN, |e| e.worst_psnr_db));
        // The mean beside the worst: a knob that trades accuracy for speed
        // (oversampling, level bias) may leave the worst frame as it was.
        let mean = bench.error.map_or(f64::NAN, |e| e.mean_psnr_db);
        let psnr = match worst_psnr_db {
            Some(db) if db.is_infinite() => "identical to direct".to_string(),
            Some(db) if mean.is_finite() => format!("PSNR {db:.1} dB worst, {mean:.1} mean"),
            Some(db) => format!("PSNR {db:.1} dB worst"),
            None => "error not measured".to_string(),
        };
        let (exact, exactness) = match (bench.exact, bench.buffer_check) {
            (Some(true), _) => (Some(true), "bit-exact".to_string()),
            (Some(false), _) => {
                let differing = bench
                    .profile
                    .iter()
                    .filter(|p| p.exact == Some(false))
                    .count();
                (
                    Some(false),
                    format!("{differing} of {} frames DIFFER", bench.frames),
                )
            }
            (None, Some((compared, 0))) => (
                Some(true),
                format!("buffer bit-exact ({compared} samples); {psnr}"),
            ),
            (None, Some((compared, differing))) => (
                Some(false),
                format!("buffer: {differing} of {compared} samples DIFFER; {psnr}"),
            ),
            (None, None) => (None, psnr),
        };
        let ostc = bench.buffer_check.is_some() || bench.bookkeeping_ms > 0.0;
        let split = TimeSplit::of(&bench.profile);
        let row = BenchRow {
            info,
            frames: bench.frames,
            full_ms_per_frame,
            full_vs_plain: bench.full_vs_plain,
            accelerated_ms_per_frame: bench.accelerated_ms / frames,
            speedup: bench.speedup,
            oracle_speedup,
            region_oracle_speedup: bench.oracle.map(|o| o.regions),
            timed_region_oracle_speedup: bench.oracle.map(|o| o.timed_regions),
            efficiency: oracle_speedup.map(|o| bench.speedup / o),
            bookkeeping_share: ostc
                .then(|| bench.bookkeeping_ms / frames / full_ms_per_frame.max(f64::MIN_POSITIVE)),
            tracing_share: split.tracing,
            copying_share: split.copying,
            samples_traced: bench.samples_traced,
            oracle_samples,
            exact,
            worst_psnr_db,
            exactness,
        };
        ExperimentResult {
            row,
            profile: bench.profile,
        }
    }
}

/// Where the accelerated side's time went, as shares of its tracing,
/// copying and bookkeeping together.
struct TimeSplit {
    tracing: f64,
    copying: f64,
}

impl TimeSplit {
    fn of(profile: &[FrameProfile]) -> TimeSplit {
        let sum = |part: fn(&FrameProfile) -> f64| profile.iter().map(part).sum::<f64>();
        let tracing = sum(|p| p.accelerated_trace_ms);
        let copying = sum(|p| p.accelerated_copy_ms);
        let total = (tracing + copying + sum(|p| p.bookkeeping_ms)).max(f64::MIN_POSITIVE);
        TimeSplit {
            tracing: tracing / total,
            copying: copying / total,
        }
    }
}

/// The figures measured, joined by " / ": the per-sample oracle, then the
/// region ones where there are regions; `n/a` if none was.
fn figures(values: [Option<f64>; 3], show: impl Fn(f64) -> String) -> String {
    let shown: Vec<String> = values.into_iter().flatten().map(show).collect();
    if shown.is_empty() {
        "n/a".to_string()
    } else {
        shown.join(" / ")
    }
}

const TABLE_HEADER: [&str; 12] = [
    "experiment",
    "scene",
    "size",
    "paper",
    "full ms/frame",
    "vs plain",
    "accel ms/frame",
    "speedup",
    "oracle (sample / region / timed)",
    "efficiency",
    "bookkeeping",
    "exactness / error",
];

/// The cells of a row, as the terminal table and report.md show them.
fn cells(row: &BenchRow) -> [String; 12] {
    let info = &row.info;
    [
        format!("{} ({})", info.id, info.technique),
        format!("{} ({} tris)", info.scene, thousands(info.triangles)),
        format!("{}x{}", info.width, info.height),
        info.paper_speedup.clone(),
        format!("{:.2}", row.full_ms_per_frame),
        format!("{:.2}", row.full_vs_plain),
        format!("{:.2}", row.accelerated_ms_per_frame),
        format!("{:.2}x", row.speedup),
        figures(
            [
                row.oracle_speedup,
                row.region_oracle_speedup,
                row.timed_region_oracle_speedup,
            ],
            |o| format!("{o:.2}x"),
        ),
        figures(
            [
                row.efficiency,
                row.region_efficiency(),
                row.timed_region_efficiency(),
            ],
            |e| format!("{:.0}%", e * 100.0),
        ),
        row.bookkeeping_share
            .map_or_else(|| "none".to_string(), |b| format!("{:.1}%", b * 100.0)),
        row.exactness.clone(),
    ]
}

/// 1234567 -> "1,234,567".
fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// The table for the terminal: columns padded to their widest cell,
/// numbers right-aligned.
pub fn table(rows: &[BenchRow]) -> String {
    let body: Vec<[String; 12]> = rows.iter().map(cells).collect();
    let mut widths = TABLE_HEADER.map(str::len);
    for row in &body {
        for (width, cell) in widths.iter_mut().zip(row) {
            *width = (*width).max(cell.chars().count());
        }
    }
    let numeric = |column: usize| (4..=10).contains(&column);
    let line = |cells: &[String]| {
        let mut out = String::new();
        for (column, (cell, &width)) in cells.iter().zip(&widths).enumerate() {
            if column > 0 {
                out.push_str("  ");
            }
            let pad = " ".repeat(width - cell.chars().count());
            let last = column + 1 == cells.len();
            if numeric(column) {
                out.push_str(&pad);
                out.push_str(cell);
            } else {
                out.push_str(cell);
                if !last {
                    out.push_str(&pad);
                }
            }
        }
        out.push('\n');
        out
    };
    let mut out = line(&TABLE_HEADER.map(String::from));
    out.push_str(&line(&widths.map(|w| "-".repeat(w))));
    for row in &body {
        out.push_str(&line(row));
    }
    out
}

/// A CSV field: quoted when it holds a comma, quote or line break.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn opt<T: ToString>(value: Option<T>) -> String {
    value.map_or_else(String::new, |v| v.to_string())
}

/// The columns of `bench.csv`.
pub const ROW_COLUMNS: [&str; 28] = [
    "experiment",
    "what",
    "technique",
    "paper_speedup",
    "scene",
    "triangles",
    "width",
    "height",
    "frames",
    "full_ms_per_frame",
    "full_vs_plain",
    "accelerated_ms_per_frame",
    "speedup",
    "oracle_speedup",
    "region_oracle_speedup",
    "efficiency",
    "region_efficiency",
    "timed_region_oracle_speedup",
    "timed_region_efficiency",
    "bookkeeping_share",
    "tracing_share",
    "copying_share",
    "samples_traced",
    "oracle_samples",
    "exact",
    "worst_psnr_db",
    "exactness",
    "profile",
];

/// The table as CSV (full precision; empty cells where not measured).
pub fn rows_csv(rows: &[BenchRow]) -> String {
    let mut out = ROW_COLUMNS.join(",");
    out.push('\n');
    for row in rows {
        let info = &row.info;
        let fields = [
            info.id.clone(),
            info.what.clone(),
            info.technique.clone(),
            info.paper_speedup.clone(),
            info.scene.clone(),
            info.triangles.to_string(),
            info.width.to_string(),
            info.height.to_string(),
            row.frames.to_string(),
            row.full_ms_per_frame.to_string(),
            row.full_vs_plain.to_string(),
            row.accelerated_ms_per_frame.to_string(),
            row.speedup.to_string(),
            opt(row.oracle_speedup),
            opt(row.region_oracle_speedup),
            opt(row.efficiency),
            opt(row.region_efficiency()),
            opt(row.timed_region_oracle_speedup),
            opt(row.timed_region_efficiency()),
            opt(row.bookkeeping_share),
            row.tracing_share.to_string(),
            row.copying_share.to_string(),
            row.samples_traced.to_string(),
            opt(row.oracle_samples),
            opt(row.exact),
            // Identical frames have an infinite PSNR: JSON has no word for
            // it, CSV says inf.
            opt(row.worst_psnr_db),
            row.exactness.clone(),
            profile_file(&info.id),
        ];
        let fields: Vec<String> = fields.iter().map(|f| csv_field(f)).collect();
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// The table as JSON: the rows, with infinite PSNRs as null.
pub fn rows_json(rows: &[BenchRow]) -> String {
    serde_json::to_string_pretty(rows).expect("rows serialize")
}

/// The columns of each experiment's per-frame CSV.
pub const PROFILE_COLUMNS: [&str; 20] = [
    "frame",
    "full_ms",
    "accelerated_ms",
    "full_primary",
    "full_shadow",
    "full_reflection",
    "accelerated_primary",
    "accelerated_shadow",
    "accelerated_reflection",
    "samples_traced",
    "dirty_regions",
    "samples_nulled",
    "bookkeeping_ms",
    "accelerated_trace_ms",
    "accelerated_copy_ms",
    "oracle_samples",
    "oracle_region_samples",
    "psnr_db",
    "exact",
    "speedup",
];

/// The per-frame CSV of one experiment.
pub fn profile_csv(profile: &[FrameProfile]) -> String {
    let mut out = PROFILE_COLUMNS.join(",");
    out.push('\n');
    for p in profile {
        let fields = [
            p.frame.to_string(),
            format!("{:.4}", p.full_ms),
            format!("{:.4}", p.accelerated_ms),
            p.full_rays.primary.to_string(),
            p.full_rays.shadow.to_string(),
            p.full_rays.reflection.to_string(),
            p.accelerated_rays.primary.to_string(),
            p.accelerated_rays.shadow.to_string(),
            p.accelerated_rays.reflection.to_string(),
            p.samples_traced.to_string(),
            p.dirty_regions.to_string(),
            p.samples_nulled.to_string(),
            format!("{:.4}", p.bookkeeping_ms),
            format!("{:.4}", p.accelerated_trace_ms),
            format!("{:.4}", p.accelerated_copy_ms),
            opt(p.oracle_samples),
            opt(p.oracle_region_samples),
            opt(p.psnr_db.map(|db| format!("{db:.3}"))),
            opt(p.exact),
            format!("{:.3}", p.full_ms / p.accelerated_ms),
        ];
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// The file names of an experiment's outputs, relative to the bench folder.
pub fn profile_file(id: &str) -> String {
    format!("{}-frames.csv", file_stem(id))
}

pub fn time_plot_file(id: &str) -> String {
    format!("{}-time.png", file_stem(id))
}

pub fn rays_plot_file(id: &str) -> String {
    format!("{}-rays.png", file_stem(id))
}

/// Triangles in `scene`'s meshes (spheres and planes are analytic).
pub fn triangles(scene: &crate::scene::Scene) -> u64 {
    scene
        .objects
        .iter()
        .map(|object| match &object.shape {
            crate::geometry::Shape::Mesh(mesh) => mesh.triangles.len() as u64,
            _ => 0,
        })
        .sum()
}

/// A chart to draw: named lines over the frames.
#[derive(Clone, Debug, PartialEq)]
pub struct ChartSpec {
    pub file: String,
    pub title: String,
    pub y_label: String,
    pub lines: Vec<(String, Vec<(f64, f64)>)>,
}

/// An experiment's two charts: time per frame, both sides; rays per frame
/// by kind on the accelerated side against all rays of the full render,
/// with the oracle's samples (what had to be traced at the least).
pub fn charts(result: &ExperimentResult) -> [ChartSpec; 2] {
    let info = &result.row.info;
    let line = |label: &str, value: &dyn Fn(&FrameProfile) -> Option<f64>| {
        (
            label.to_string(),
            result
                .profile
                .iter()
                .filter_map(|p| value(p).map(|v| (f64::from(p.frame), v)))
                .collect::<Vec<_>>(),
        )
    };
    let time = ChartSpec {
        file: time_plot_file(&info.id),
        title: format!(
            "{}: time per frame ({}, {}x{})",
            info.id, info.scene, info.width, info.height
        ),
        y_label: "ms".to_string(),
        lines: vec![
            line("full render", &|p| Some(p.full_ms)),
            line(&format!("accelerated ({})", info.technique), &|p| {
                Some(p.accelerated_ms)
            }),
        ],
    };
    let mut ray_lines = vec![
        line("full: all rays", &|p| Some(p.full_rays.total() as f64)),
        line("accelerated: primary", &|p| {
            Some(p.accelerated_rays.primary as f64)
        }),
        line("accelerated: shadow", &|p| {
            Some(p.accelerated_rays.shadow as f64)
        }),
        line("accelerated: reflection", &|p| {
            Some(p.accelerated_rays.reflection as f64)
        }),
    ];
    if result.profile.iter().any(|p| p.oracle_samples.is_some()) {
        ray_lines.push(line("oracle: samples", &|p| {
            p.oracle_samples.map(|n| n as f64)
        }));
    }
    let rays = ChartSpec {
        file: rays_plot_file(&info.id),
        title: format!("{}: rays traced per frame", info.id),
        y_label: "rays".to_string(),
        lines: ray_lines,
    };
    [time, rays]
}

/// Writes the bench folder: bench.csv, bench.json, each experiment's
/// per-frame CSV, its charts (through `draw`) and report.md, each file
/// whole or not at all. Returns the files written.
pub fn write_bench<E>(
    dir: &std::path::Path,
    run: &RunInfo,
    results: &[ExperimentResult],
    mut draw: impl FnMut(&std::path::Path, &ChartSpec) -> Result<(), E>,
) -> Result<Vec<std::path::PathBuf>, E>
where
    E: From<crate::output::OutputError>,
{
    let rows: Vec<BenchRow> = results.iter().map(|r| r.row.clone()).collect();
    let mut written = Vec::new();
    let mut text = |name: &str, content: &str| -> Result<(), E> {
        let path = dir.join(name);
        crate::output::save_text(&path, content)?;
        written.push(path);
        Ok(())
    };
    text("bench.csv", &rows_csv(&rows))?;
    text("bench.json", &rows_json(&rows))?;
    for result in results {
        text(
            &profile_file(&result.row.info.id),
            &profile_csv(&result.profile),
        )?;
    }
    text("report.md", &report_markdown(run, results))?;
    for result in results {
        for chart in charts(result) {
            let path = dir.join(&chart.file);
            draw(&path, &chart)?;
            written.push(path);
        }
    }
    Ok(written)
}

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
        .map(|c| if (4..=9).contains(&c) { "---:" } else { "---" })
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
        md.push_str(&format!(
            "\n### {} — {} ({}, {}x{})\n\n{}\n\n![{} time per frame]({}) ![{} rays per frame]({})\n\n\
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
            profile_file(&info.id),
            profile_file(&info.id),
        ));
    }
    md
}

/// One sentence about a row, for report.md.
fn summary(row: &BenchRow) -> String {
    let oracle = match (row.oracle_speedup, row.efficiency) {
        (Some(o), Some(e)) => format!(
            "; the oracle allows {o:.1}x, so the reuse gets {:.0}% of the way",
            e * 100.0
        ),
        _ => "; no oracle was measured".to_string(),
    };
    format!(
        "{:.2} ms per frame in full against {:.2} ms accelerated over {} frames: {:.2}x (paper: {}){}. {}. {}",
        row.full_ms_per_frame,
        row.accelerated_ms_per_frame,
        row.frames,
        row.speedup,
        row.info.paper_speedup,
        oracle,
        capitalise(&row.exactness),
        time_split(row),
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
- **paper**: the speedup Gage & Semwal report for it.
- **full ms/frame**: mean time of a full render of each output frame (tracing every pixel \
through its own ray, in place; conversion to 8 bits included, file writing excluded): the \
fastest plain render of the same frames.
- **vs plain**: the full side's time over plain renders of the same views made outside the \
frame loop (as `retrace bench --only frame` makes them), on every tenth frame: near 1.00, or \
the full side is slower than it should be and the speedup reads high.
- **accel ms/frame**: the same for the accelerated sequence; it pays for everything it does: \
frame 0, buffers, recording, merging, copies, resampling, scene updates.
- **speedup**: full time over accelerated time, whole sequences.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shade::RayCounts;

    fn info(id: &str) -> ExperimentInfo {
        ExperimentInfo {
            id: id.to_string(),
            what: "pan, 3.6 deg/frame".to_string(),
            technique: "Panimation".to_string(),
            paper_speedup: "~10x".to_string(),
            scene: "paper".to_string(),
            triangles: 1234567,
            width: 640,
            height: 480,
        }
    }

    fn row(id: &str, oracle: Option<f64>) -> BenchRow {
        BenchRow {
            info: info(id),
            frames: 100,
            full_ms_per_frame: 30.0,
            full_vs_plain: 1.0,
            accelerated_ms_per_frame: 1.5,
            speedup: 20.0,
            oracle_speedup: oracle,
            region_oracle_speedup: None,
            timed_region_oracle_speedup: None,
            efficiency: oracle.map(|o| 20.0 / o),
            bookkeeping_share: None,
            tracing_share: 0.4,
            copying_share: 0.6,
            samples_traced: 1000,
            oracle_samples: oracle.map(|_| 900),
            exact: Some(true),
            worst_psnr_db: None,
            exactness: "bit-exact".to_string(),
        }
    }

    #[test]
    fn the_summary_says_where_the_accelerated_time_went() {
        let mut e2 = row("E2 in", Some(40.0));
        e2.info.technique = "RSVP".to_string();
        let text = summary(&e2);
        assert!(
            text.contains("spent 40% of its time tracing and 60% copying (mapping and resampling"),
            "{text}"
        );
        // 20x with 60% of the time copying: 50x if copying were free.
        assert!(
            text.contains("with copying free it would run 50.0x faster"),
            "{text}"
        );
        assert!(!text.contains("bookkeeping"), "{text}");
        let mut e4 = row("E4", Some(12.0));
        (e4.tracing_share, e4.copying_share) = (0.5, 0.3);
        let text = summary(&e4);
        assert!(
            text.contains("30% copying, 20% on OSTC bookkeeping"),
            "{text}"
        );
        assert!(!text.contains("resampling"), "{text}");
    }

    #[test]
    fn table_aligns_columns_and_says_na_for_what_was_not_measured() {
        let text = table(&[row("E1", Some(25.0)), row("E2 in", None)]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4);
        assert!(lines[0].starts_with("experiment"));
        // Right-aligned numbers end in the same column on every line.
        let end_of = |line: &str, needle: &str| line.find(needle).unwrap() + needle.len();
        assert_eq!(end_of(lines[2], "20.00x"), end_of(lines[3], "20.00x"));
        assert_eq!(end_of(lines[0], "speedup"), end_of(lines[2], "20.00x"));
        assert!(lines[2].contains("25.00x") && lines[2].contains("80%"));
        let mut with_regions = row("E3", Some(40.0));
        with_regions.region_oracle_speedup = Some(8.0);
        let text = table(&[with_regions]);
        assert!(text.contains("40.00x / 8.00x"), "{text}");
        assert!(text.contains("50% / 250%"), "{text}");
        assert!(lines[3].contains("n/a"));
        assert!(lines[2].contains("paper (1,234,567 tris)"));
        assert!(lines[2].contains("none"), "no OSTC: no bookkeeping");
    }

    #[test]
    fn csv_has_one_line_per_row_and_quotes_commas() {
        let csv = rows_csv(&[row("E1", Some(25.0)), row("E2 in", None)]);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[0].split(',').count(), ROW_COLUMNS.len());
        // "pan, 3.6 deg/frame" holds a comma: quoted, so the column count holds.
        assert!(lines[1].contains("\"pan, 3.6 deg/frame\""));
        assert!(lines[1].starts_with("E1,"));
        assert!(
            lines[1].contains(",25,"),
            "oracle speedup in full: {}",
            lines[1]
        );
        assert!(lines[1].ends_with(",e1-frames.csv"));
        // Not measured: an empty cell, not a made-up number.
        assert!(lines[2].contains(",20,,,,,"), "{}", lines[2]);
        assert!(lines[2].ends_with(",e2-in-frames.csv"));
    }

    #[test]
    fn csv_fields_escape_quotes() {
        assert_eq!(csv_field("plain"), "plain");
        assert_eq!(csv_field("a \"b\", c"), "\"a \"\"b\"\", c\"");
    }

    #[test]
    fn json_rows_flatten_the_experiment() {
        let json: serde_json::Value = serde_json::from_str(&rows_json(&[row("E1", None)])).unwrap();
        assert_eq!(json[0]["id"], "E1");
        assert_eq!(json[0]["speedup"], 20.0);
        assert!(json[0]["oracle_speedup"].is_null());
    }

    #[test]
    fn profile_csv_has_a_line_per_frame() {
        let frame = FrameProfile {
            frame: 7,
            full_ms: 10.0,
            accelerated_ms: 2.5,
            full_rays: RayCounts {
                primary: 100,
                shadow: 150,
                reflection: 20,
            },
            oracle_samples: Some(5),
            accelerated_trace_ms: 1.5,
            accelerated_copy_ms: 0.75,
            ..FrameProfile::default()
        };
        let csv = profile_csv(&[frame]);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].split(',').count(), PROFILE_COLUMNS.len());
        let cells: Vec<&str> = lines[1].split(',').collect();
        assert_eq!(cells.len(), PROFILE_COLUMNS.len());
        assert_eq!(cells[0], "7");
        assert_eq!(cells[3..6], ["100", "150", "20"]);
        assert_eq!(cells[13..15], ["1.5000", "0.7500"]);
        assert_eq!(cells[15], "5");
        assert_eq!(cells[16], "", "no region oracle: empty");
        assert_eq!(cells[19], "4.000");
    }

    #[test]
    fn file_names_come_from_the_experiment() {
        assert_eq!(file_stem("E2 in"), "e2-in");
        assert_eq!(profile_file("E4"), "e4-frames.csv");
        assert_eq!(time_plot_file("E1 1280x960"), "e1-1280x960-time.png");
    }

    #[test]
    fn thousands_separates_groups() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(1000), "1,000");
        assert_eq!(thousands(940_544), "940,544");
    }

    #[test]
    fn report_links_every_plot_and_the_table() {
        let result = ExperimentResult {
            row: row("E1", Some(25.0)),
            profile: Vec::new(),
        };
        let md = report_markdown(&RunInfo::default(), &[result]);
        assert!(md.contains("](e1-time.png)"));
        assert!(md.contains("](e1-rays.png)"));
        assert!(md.contains("](e1-frames.csv)"));
        assert!(md.contains("| E1 (Panimation) |"));
        assert!(md.contains("## The oracle"));
    }
}

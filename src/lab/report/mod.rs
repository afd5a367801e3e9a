//! What `retrace bench` reports: one row per experiment (the paper's
//! table), the rows as CSV and JSON, each experiment's per-frame profile as
//! CSV, and `report.md`, which puts the table and the plots together for a
//! reader.
//!
//! Every figure that could not be measured honestly is `None` here, "n/a"
//! in the table and an empty cell in CSV; nothing is made up to fill a
//! column.

mod markdown;
mod table;

pub use markdown::{report_markdown, RunInfo};
pub use table::{profile_csv, rows_csv, rows_json, table};

use crate::lab::bench::{ErrorSummary, FrameProfile, SequenceBench};
use crate::output::OutputError;

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
    /// Each round's own speedup (`--repeats`; one round, one figure).
    pub round_speedups: Vec<f64>,
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
    /// The samples a pixel both sides traced.
    pub samples_per_pixel: u32,
    /// The converged reference's samples a pixel; None where no reference
    /// was rendered.
    pub reference_samples: Option<u32>,
    /// The frames the reference was rendered for.
    pub reference_frames: Vec<u32>,
    /// The full render at `samples_per_pixel` against the reference.
    pub full_vs_reference: Option<ErrorSummary>,
    /// The accelerated output against the reference of the view it shows
    /// (for a snapped pan, the camera moved onto the lattice).
    pub accelerated_vs_reference: Option<ErrorSummary>,
    /// Snapped pans: the accelerated output against the keyed camera's
    /// reference.
    pub accelerated_vs_keyed_reference: Option<ErrorSummary>,
    /// Snapped pans: the largest yaw or pitch between a frame's view and
    /// its keyed camera, in samples.
    pub largest_snap_samples: f64,
    /// The exactness or error result, in words.
    pub exactness: String,
}

impl BenchRow {
    /// The lowest and the highest round's speedup, with more than one
    /// round.
    pub fn speedup_range(&self) -> Option<(f64, f64)> {
        let rounds = &self.round_speedups;
        (rounds.len() > 1).then(|| {
            let lowest = rounds.iter().copied().fold(f64::INFINITY, f64::min);
            let highest = rounds.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (lowest, highest)
        })
    }

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
        let keyed = bench
            .reference
            .as_ref()
            .and_then(|r| r.accelerated_vs_keyed);
        let (exact, exactness) = match (bench.exact, bench.buffer_check) {
            (Some(true), _) if bench.largest_snap_samples > 0.0 => (
                Some(true),
                snapped_exactness(bench.largest_snap_samples, keyed.as_ref()),
            ),
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
            round_speedups: bench.round_speedups.clone(),
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
            samples_per_pixel: bench.samples_per_pixel,
            reference_samples: bench.reference.as_ref().map(|r| r.samples),
            reference_frames: bench
                .reference
                .as_ref()
                .map_or_else(Vec::new, |r| r.frames.clone()),
            full_vs_reference: bench.reference.as_ref().map(|r| r.full),
            accelerated_vs_reference: bench.reference.as_ref().map(|r| r.accelerated),
            accelerated_vs_keyed_reference: keyed,
            largest_snap_samples: bench.largest_snap_samples,
            exactness,
        };
        ExperimentResult {
            row,
            profile: bench.profile,
        }
    }
}

/// A snapped pan's exactness: bit-exact renders of views up to
/// `largest_snap` samples off the keyed camera, and what that shift costs
/// against the keyed camera's reference where one was rendered.
fn snapped_exactness(largest_snap: f64, keyed: Option<&ErrorSummary>) -> String {
    let keyed = keyed.map_or_else(String::new, |k| {
        format!(
            "; {:.1} / {:.1} dB vs the keyed camera's ref",
            k.worst_psnr_db, k.mean_psnr_db
        )
    });
    format!("bit-exact of views snapped by <= {largest_snap:.2} samples{keyed}")
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
        let tracing = sum(|p| p.accelerated.trace_ms());
        let copying = sum(|p| p.accelerated.copy_ms());
        let total =
            (tracing + copying + sum(|p| p.accelerated.bookkeeping_ms())).max(f64::MIN_POSITIVE);
        TimeSplit {
            tracing: tracing / total,
            copying: copying / total,
        }
    }
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

pub fn accuracy_plot_file(id: &str) -> String {
    format!("{}-accuracy.png", file_stem(id))
}

/// Whether the experiment was measured against a converged reference
/// (then it has an accuracy chart).
pub fn has_reference(profile: &[FrameProfile]) -> bool {
    profile.iter().any(|p| p.full_reference_psnr_db.is_some())
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

/// An experiment's charts: time per frame, both sides; rays per frame by
/// kind on the accelerated side against all rays of the full render, with
/// the oracle's samples (what had to be traced at the least); and, where
/// measured, both sides' PSNR against the converged reference.
pub fn charts(result: &ExperimentResult) -> Vec<ChartSpec> {
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
            Some(p.accelerated.work.rays.primary as f64)
        }),
        line("accelerated: shadow", &|p| {
            Some(p.accelerated.work.rays.shadow as f64)
        }),
        line("accelerated: reflection", &|p| {
            Some(p.accelerated.work.rays.reflection as f64)
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
    let mut charts = vec![time, rays];
    if has_reference(&result.profile) {
        charts.push(ChartSpec {
            file: accuracy_plot_file(&info.id),
            title: format!(
                "{}: worst view's PSNR against the converged reference",
                info.id
            ),
            y_label: "dB".to_string(),
            lines: vec![
                line("full render", &|p| p.full_reference_psnr_db),
                line(&format!("accelerated ({})", info.technique), &|p| {
                    p.accelerated_reference_psnr_db
                }),
            ],
        });
    }
    charts
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
    E: From<OutputError>,
{
    let rows: Vec<BenchRow> = results.iter().map(|r| r.row.clone()).collect();
    let mut written = Vec::new();
    let mut text = |name: &str, content: &str| -> Result<(), E> {
        let path = dir.join(name);
        crate::output::save_text(&path, content)?;
        written.push(path);
        Ok(())
    };
    let csv = |text: Result<String, crate::output::CsvError>| text.map_err(OutputError::from);
    text("bench.csv", &csv(rows_csv(&rows))?)?;
    text("bench.json", &rows_json(&rows))?;
    for result in results {
        text(
            &profile_file(&result.row.info.id),
            &csv(profile_csv(&result.profile))?,
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

#[cfg(test)]
mod tests {
    use super::markdown::summary;
    use super::table::thousands;
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
            round_speedups: Vec::new(),
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
            samples_per_pixel: 1,
            reference_samples: None,
            reference_frames: Vec::new(),
            full_vs_reference: None,
            accelerated_vs_reference: None,
            accelerated_vs_keyed_reference: None,
            largest_snap_samples: 0.0,
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

    /// A CSV's cells by column name, for rows without quoted commas.
    fn cells(csv: &str, line: usize) -> std::collections::HashMap<String, String> {
        let header = csv.lines().next().unwrap().split(',').map(str::to_owned);
        let row = csv.lines().nth(line).unwrap().split(',').map(str::to_owned);
        header.zip(row).collect()
    }

    #[test]
    fn csv_has_one_line_per_row_and_quotes_commas() {
        let mut e2 = row("E2 in", None);
        // No quoted commas in this row: its fields split where the columns do.
        e2.info.what = "zoom in".to_string();
        let csv = rows_csv(&[row("E1", Some(25.0)), e2]).unwrap();
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 3);
        // "pan, 3.6 deg/frame" holds a comma: quoted, so the column count holds.
        assert!(lines[1].contains("\"pan, 3.6 deg/frame\""));
        assert!(lines[1].starts_with("E1,"));
        assert!(
            lines[1].contains(",25,"),
            "oracle speedup in full: {}",
            lines[1]
        );
        assert!(lines[1].ends_with(",e1-frames.csv"));
        assert!(lines[2].ends_with(",e2-in-frames.csv"));
        let header: Vec<&str> = lines[0].split(',').collect();
        let column = |name: &str| header.iter().position(|c| *c == name).unwrap();
        // Not measured: an empty cell, not a made-up number; an error
        // summary's fields each in their own column.
        let e2: Vec<&str> = lines[2].split(',').collect();
        assert_eq!(e2[column("oracle_speedup")], "");
        assert_eq!(e2[column("full_vs_reference.worst_psnr_db")], "");
        assert_eq!(header.len(), e2.len());
        // bench.json has the same fields.
        let json: serde_json::Value =
            serde_json::from_str(&rows_json(&[row("E1", Some(25.0))])).unwrap();
        assert_eq!(json[0]["oracle_speedup"], 25.0);
        assert_eq!(json[0]["profile"], "e1-frames.csv");
    }

    /// With several rounds the table and the CSV show how far they spread;
    /// with one there is no spread to show.
    #[test]
    fn rounds_show_the_spread_of_their_speedups() {
        let mut repeated = row("E4", None);
        repeated.speedup = 4.05;
        repeated.round_speedups = vec![4.2, 3.9, 4.05];
        let mut once = row("E1", None);
        // No quoted commas: the fields split where the columns do.
        for row in [&mut repeated, &mut once] {
            row.info.what = "all at once".to_string();
        }
        let shown = table(&[repeated.clone(), once.clone()]);
        assert!(shown.contains("4.05x (3.90-4.20)"), "{shown}");
        assert!(
            shown.contains("20.00x") && !shown.contains("20.00x ("),
            "{shown}"
        );
        let csv = rows_csv(&[repeated, once]).unwrap();
        let (first, second) = (cells(&csv, 1), cells(&csv, 2));
        let spread = |row: &std::collections::HashMap<String, String>| {
            (
                row["speedup_lowest_round"].clone(),
                row["speedup_highest_round"].clone(),
            )
        };
        assert_eq!(spread(&first), ("3.9".into(), "4.2".into()));
        assert_eq!(first["round_speedups"], "4.2 3.9 4.05");
        assert_eq!(spread(&second), (String::new(), String::new()));
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
                refraction: 0,
            },
            oracle_samples: Some(5),
            accelerated: crate::frame_loop::FrameStats {
                work: crate::reuse::ViewWork {
                    trace_ms: 1.5,
                    assembly_ms: 0.75,
                    ..Default::default()
                },
                ..Default::default()
            },
            ..FrameProfile::default()
        };
        let csv = profile_csv(&[frame]).unwrap();
        assert_eq!(csv.lines().count(), 2);
        let row = cells(&csv, 1);
        assert_eq!(row["frame"], "7");
        let rays =
            ["primary", "shadow", "reflection"].map(|k| row[&format!("full_rays.{k}")].clone());
        assert_eq!(rays, ["100", "150", "20"]);
        // The accelerated side as the frame loop's statistics.
        assert_eq!(row["accelerated.trace_ms"], "1.5000");
        assert_eq!(row["accelerated.copy_ms"], "0.7500");
        assert_eq!(row["accelerated.total_ms"], "2.2500");
        assert_eq!(row["oracle_samples"], "5");
        assert_eq!(row["oracle_region_samples"], "", "no region oracle: empty");
        assert_eq!(row["accelerated.error.psnr_db"], "");
    }

    #[test]
    fn file_names_come_from_the_experiment() {
        assert_eq!(file_stem("E2 in"), "e2-in");
        assert_eq!(profile_file("E4"), "e4-frames.csv");
        assert_eq!(time_plot_file("E1 1280x960"), "e1-1280x960-time.png");
    }

    #[test]
    fn a_run_against_the_reference_charts_both_sides_psnr() {
        let profile: Vec<FrameProfile> = (0..41)
            .map(|frame| FrameProfile {
                frame,
                full_reference_psnr_db: (frame % 20 == 0).then_some(27.0),
                accelerated_reference_psnr_db: (frame % 20 == 0).then_some(29.5),
                ..FrameProfile::default()
            })
            .collect();
        let result = ExperimentResult {
            row: row("E2 in", None),
            profile,
        };
        let charts = charts(&result);
        let accuracy = charts
            .iter()
            .find(|c| c.file == "e2-in-accuracy.png")
            .expect("an accuracy chart");
        let points: Vec<&Vec<(f64, f64)>> = accuracy.lines.iter().map(|(_, p)| p).collect();
        assert_eq!(*points[0], vec![(0.0, 27.0), (20.0, 27.0), (40.0, 27.0)]);
        assert_eq!(*points[1], vec![(0.0, 29.5), (20.0, 29.5), (40.0, 29.5)]);
        let md = report_markdown(&RunInfo::default(), &[result]);
        assert!(md.contains("](e2-in-accuracy.png)"), "{md}");
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
        assert!(!md.contains("accuracy.png"), "no reference measured");
        assert!(md.contains("| E1 (Panimation) |"));
        assert!(md.contains("## The oracle"));
    }
}

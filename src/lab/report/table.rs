//! The bench's table as the terminal shows it, and as CSV and JSON; each
//! experiment's per-frame CSV.

use super::{profile_file, BenchRow, ErrorSummary, FrameProfile};
use crate::frame_loop::FrameStats;
use crate::output::{csv_text, CsvError, Floats};

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

pub(super) const TABLE_HEADER: [&str; 15] = [
    "experiment",
    "scene",
    "size",
    "spp (ref)",
    "paper",
    "full ms/frame",
    "vs plain",
    "accel ms/frame",
    "speedup",
    "oracle (sample / region / timed)",
    "efficiency",
    "bookkeeping",
    "full vs ref dB",
    "accel vs ref dB",
    "exactness / error",
];

/// The columns whose cells are numbers, right-aligned.
pub(super) fn numeric(column: usize) -> bool {
    (5..=13).contains(&column)
}

/// PSNR against the reference, worst and mean over the frames measured;
/// `n/a` where no reference was rendered.
fn reference_cell(summary: Option<&ErrorSummary>) -> String {
    let db = |db: f64| {
        if db.is_infinite() {
            "inf".to_string()
        } else {
            format!("{db:.1}")
        }
    };
    summary.map_or_else(
        || "n/a".to_string(),
        |s| format!("{} / {}", db(s.worst_psnr_db), db(s.mean_psnr_db)),
    )
}

/// The cells of a row, as the terminal table and report.md show them.
pub(super) fn cells(row: &BenchRow) -> [String; 15] {
    let info = &row.info;
    [
        format!("{} ({})", info.id, info.technique),
        format!("{} ({} tris)", info.scene, thousands(info.triangles)),
        format!("{}x{}", info.width, info.height),
        match row.reference_samples {
            Some(reference) => format!("{} ({reference})", row.samples_per_pixel),
            None => row.samples_per_pixel.to_string(),
        },
        info.paper_speedup.clone(),
        format!("{:.2}", row.full_ms_per_frame),
        format!("{:.2}", row.full_vs_plain),
        format!("{:.2}", row.accelerated_ms_per_frame),
        match row.speedup_range() {
            Some((lowest, highest)) => {
                format!("{:.2}x ({lowest:.2}-{highest:.2})", row.speedup)
            }
            None => format!("{:.2}x", row.speedup),
        },
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
        reference_cell(row.full_vs_reference.as_ref()),
        reference_cell(row.accelerated_vs_reference.as_ref()),
        row.exactness.clone(),
    ]
}

/// 1234567 -> "1,234,567".
pub(super) fn thousands(n: u64) -> String {
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
    let body: Vec<[String; 15]> = rows.iter().map(cells).collect();
    let mut widths = TABLE_HEADER.map(str::len);
    for row in &body {
        for (width, cell) in widths.iter_mut().zip(row) {
            *width = (*width).max(cell.chars().count());
        }
    }
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

/// A row as `bench.csv` and `bench.json` hold it: what was measured and
/// what follows from it, so both files have the same fields.
#[derive(serde::Serialize)]
struct WrittenRow<'a> {
    #[serde(flatten)]
    row: &'a BenchRow,
    speedup_lowest_round: Option<f64>,
    speedup_highest_round: Option<f64>,
    region_efficiency: Option<f64>,
    timed_region_efficiency: Option<f64>,
    /// The experiment's per-frame CSV.
    profile: String,
}

impl WrittenRow<'_> {
    fn of(row: &BenchRow) -> WrittenRow<'_> {
        let range = row.speedup_range();
        WrittenRow {
            row,
            speedup_lowest_round: range.map(|(lowest, _)| lowest),
            speedup_highest_round: range.map(|(_, highest)| highest),
            region_efficiency: row.region_efficiency(),
            timed_region_efficiency: row.timed_region_efficiency(),
            profile: profile_file(&row.info.id),
        }
    }
}

/// The table as CSV: every field at full precision (an error summary's
/// as `full_vs_reference.worst_psnr_db`, ...; the rounds' speedups split
/// by spaces), an empty cell where not measured, `inf` for the PSNR of
/// identical frames.
pub fn rows_csv(rows: &[BenchRow]) -> Result<String, CsvError> {
    let written: Vec<WrittenRow> = rows.iter().map(WrittenRow::of).collect();
    let summary = Some(ErrorSummary {
        worst_psnr_db: 0.0,
        mean_psnr_db: 0.0,
        max_abs: 0.0,
        mean_abs: 0.0,
        differing_share: 0.0,
        identical: false,
    });
    let Some(first) = rows.first() else {
        return Ok(String::new());
    };
    let every_column = BenchRow {
        full_vs_reference: summary,
        accelerated_vs_reference: summary,
        accelerated_vs_keyed_reference: summary,
        ..first.clone()
    };
    csv_text(&written, &WrittenRow::of(&every_column), Floats::Shortest)
}

/// The table as JSON: the rows, with infinite PSNRs as null.
pub fn rows_json(rows: &[BenchRow]) -> String {
    let written: Vec<WrittenRow> = rows.iter().map(WrittenRow::of).collect();
    serde_json::to_string_pretty(&written).expect("rows serialize")
}

/// The per-frame CSV of one experiment: [`FrameProfile`]'s fields, the
/// accelerated side's as the frame loop's statistics
/// (`accelerated.samples_traced`, `accelerated.trace_ms`, ...), times to
/// four places.
pub fn profile_csv(profile: &[FrameProfile]) -> Result<String, CsvError> {
    let every_column = FrameProfile {
        accelerated: FrameStats::every_column(),
        oracle_samples: Some(0),
        oracle_region_samples: Some(0),
        psnr_db: Some(0.0),
        full_reference_psnr_db: Some(0.0),
        accelerated_reference_psnr_db: Some(0.0),
        exact: Some(true),
        ..FrameProfile::default()
    };
    csv_text(profile, &every_column, Floats::Fixed(4))
}

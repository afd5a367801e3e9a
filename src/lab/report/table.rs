//! The bench's table as the terminal shows it, and as CSV and JSON; each
//! experiment's per-frame CSV.

use super::{profile_file, BenchRow, ErrorSummary, FrameProfile};

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

/// A CSV field: quoted when it holds a comma, quote or line break.
pub(super) fn csv_field(text: &str) -> String {
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
pub const ROW_COLUMNS: [&str; 49] = [
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
    "speedup_lowest_round",
    "speedup_highest_round",
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
    "spp",
    "reference_spp",
    "reference_frames",
    "full_ref_worst_psnr_db",
    "full_ref_mean_psnr_db",
    "full_ref_max_abs",
    "full_ref_mean_abs",
    "full_ref_differing_share",
    "accelerated_ref_worst_psnr_db",
    "accelerated_ref_mean_psnr_db",
    "accelerated_ref_max_abs",
    "accelerated_ref_mean_abs",
    "accelerated_ref_differing_share",
    "largest_snap_samples",
    "accelerated_keyed_ref_worst_psnr_db",
    "accelerated_keyed_ref_mean_psnr_db",
    "accelerated_keyed_ref_max_abs",
    "accelerated_keyed_ref_mean_abs",
    "accelerated_keyed_ref_differing_share",
    "exactness",
    "profile",
];

/// An error summary's columns in `bench.csv`; empty where not measured.
fn summary_fields(summary: Option<&ErrorSummary>) -> [String; 5] {
    [
        opt(summary.map(|s| s.worst_psnr_db)),
        opt(summary.map(|s| s.mean_psnr_db)),
        opt(summary.map(|s| s.max_abs)),
        opt(summary.map(|s| s.mean_abs)),
        opt(summary.map(|s| s.differing_share)),
    ]
}

/// The table as CSV (full precision; empty cells where not measured).
pub fn rows_csv(rows: &[BenchRow]) -> String {
    let mut out = ROW_COLUMNS.join(",");
    out.push('\n');
    for row in rows {
        let info = &row.info;
        let speedup_range = row.speedup_range();
        let reference_frames: Vec<String> =
            row.reference_frames.iter().map(u32::to_string).collect();
        let mut fields = vec![
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
            opt(speedup_range.map(|(lowest, _)| lowest)),
            opt(speedup_range.map(|(_, highest)| highest)),
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
            row.samples_per_pixel.to_string(),
            opt(row.reference_samples),
            // Frames split by spaces: one cell whatever the count.
            reference_frames.join(" "),
        ];
        fields.extend(summary_fields(row.full_vs_reference.as_ref()));
        fields.extend(summary_fields(row.accelerated_vs_reference.as_ref()));
        fields.push(row.largest_snap_samples.to_string());
        fields.extend(summary_fields(row.accelerated_vs_keyed_reference.as_ref()));
        fields.extend([row.exactness.clone(), profile_file(&info.id)]);
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
pub const PROFILE_COLUMNS: [&str; 22] = [
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
    "full_ref_psnr_db",
    "accelerated_ref_psnr_db",
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
            opt(p.full_reference_psnr_db.map(|db| format!("{db:.3}"))),
            opt(p.accelerated_reference_psnr_db.map(|db| format!("{db:.3}"))),
        ];
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

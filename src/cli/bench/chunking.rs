//! `retrace bench --only chunking`: what cutting E1, E3 and E4 (or the
//! scene given) into 1, 2, 4, 8 and 16 farm chunks costs.

use std::fmt::Write as _;

use anyhow::Result;

use retrace::chunk::ACCEPTED_REUSE_LOSS;
use retrace::frame_loop::{Options, Techniques};
use retrace::lab::bench::{bench_chunking, ChunkingBench, ChunkingRow};
use retrace::lab::plot::{line_chart, Series};
use retrace::output::{csv_text, Floats};

use super::{check_writable, load, parse_frame_range, BenchArgs, Experiment};

/// One line of `chunking.csv`: a chunk count's cost on one experiment.
#[derive(serde::Serialize)]
struct ChunkingLine<'a> {
    experiment: &'a str,
    #[serde(flatten)]
    row: &'a ChunkingRow,
    /// A plain full render of the same frames.
    full_cpu_s: f64,
    /// The share of the reuse the chunking loses.
    reuse_lost: Option<f64>,
}

pub(super) fn bench_chunking_cli(args: &BenchArgs, bar: indicatif::ProgressBar) -> Result<()> {
    let counts = args.chunk_counts.clone();
    if counts.contains(&0) {
        anyhow::bail!("--chunk-counts: a count of chunks is at least 1");
    }
    let mut counts = counts;
    if !counts.contains(&1) {
        // The long run everything is measured against.
        counts.insert(0, 1);
    }
    let overrides = args.scene.overrides();
    let scenes = match &args.scene.scene {
        Some(path) => {
            let scene = load(&args.scene)?;
            if scene.animation.is_none() {
                anyhow::bail!("--only chunking: {} has no [animation]", path.display());
            }
            let label = path
                .file_stem()
                .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
            vec![(label, scene)]
        }
        None => [Experiment::E1, Experiment::E3, Experiment::E4]
            .iter()
            .map(|e| {
                let scene = retrace::scene::builtin_scene(e.scene_file(), &overrides)?;
                Ok((e.heading().0.to_string(), scene))
            })
            .collect::<Result<Vec<_>>>()?,
    };
    let out = args.out();
    check_writable(&out)?;
    let rounds = args.repeats.unwrap_or(1) as usize;
    let mut planned = Vec::new();
    for (label, scene) in scenes {
        let count = scene.animation.as_ref().map_or(1, |a| a.frames);
        let frames = parse_frame_range(args.frames.as_deref(), count)
            .map_err(|err| anyhow::anyhow!("{label}: {err}"))?;
        planned.push((label, scene, *frames.start()..*frames.end() + 1));
    }
    let steps: u64 = planned
        .iter()
        .map(|(_, _, f)| (rounds * f.len() * (counts.len() + 1)) as u64)
        .sum();
    bar.set_length(steps);
    bar.set_position(0);
    let mut results = Vec::new();
    for (label, scene, frames) in planned {
        bar.set_message(format!("{label}: chunks"));
        let mut accel = args.backend.build(&scene)?;
        let options = Options {
            ostc: args.ostc.settings(),
            rsvp: args.rsvp.knobs(scene.samples)?,
            ..Options::new(Techniques::AUTO, frames)
        };
        let bench = bench_chunking(&scene, &mut accel, &options, &counts, rounds, || bar.inc(1));
        results.push((label, bench));
    }
    bar.finish_and_clear();
    let table = chunking_table(&results);
    say!(
        "retrace bench --only chunking: {} backend, {} threads, {}",
        args.backend.backend,
        rayon::current_num_threads(),
        match rounds {
            1 => "one run of each".to_string(),
            n => format!("median of {n} runs"),
        }
    );
    say!("{table}");
    let plots = [
        (
            "chunking-cpu.png",
            "CPU time of all chunks, against one long run",
            "CPU time / one long run",
        ),
        (
            "chunking-wall.png",
            "Wall time with one node a chunk (the longest chunk)",
            "seconds",
        ),
    ];
    for (index, (file, title, y_label)) in plots.iter().enumerate() {
        let series: Vec<Series> = results
            .iter()
            .map(|(label, bench)| {
                let one = bench.rows.iter().find(|r| r.chunks == 1).map(|r| r.cpu_s);
                Series {
                    label: label.clone(),
                    points: bench
                        .rows
                        .iter()
                        .map(|row| {
                            let y = match index {
                                0 => row.cpu_s / one.unwrap_or(f64::NAN),
                                _ => row.longest_chunk_s,
                            };
                            (f64::from(row.chunks), y)
                        })
                        .collect(),
                }
            })
            .collect();
        line_chart(&out.join(file), title, "chunks", y_label, &series)?;
    }
    let lines: Vec<ChunkingLine> = results
        .iter()
        .flat_map(|(experiment, bench)| {
            bench.rows.iter().map(move |row| ChunkingLine {
                experiment,
                row,
                full_cpu_s: bench.full_cpu_s,
                reuse_lost: bench.reuse_lost(row),
            })
        })
        .collect();
    let csv = match lines.first() {
        Some(first) => csv_text(&lines, first, Floats::Shortest)?,
        None => String::new(),
    };
    retrace::output::save_text(&out.join("chunking.csv"), &csv)?;
    let report = format!(
        "# What farm chunks cost\n\n`{}`\n\n{}\n\nEach chunk is rendered as its own run, one after another, as a farm \
         task renders it; CPU time is all chunks' together (what a farm bills), the \
         longest chunk is the wall time with one node a chunk. \"Reuse lost\" is the CPU \
         time chunking added over what one long run saves against a plain full render.\n\n\
         ![CPU time](chunking-cpu.png)\n\n![Wall time](chunking-wall.png)\n",
        std::env::args().collect::<Vec<_>>().join(" "),
        table
    );
    retrace::output::save_text(&out.join("report.md"), &report)?;
    say!(
        "wrote chunking.csv, the plots and {}",
        out.join("report.md").display()
    );
    Ok(())
}

/// The table printed and written: per experiment and count, CPU and wall
/// time, reuse lost, and the recommendation.
fn chunking_table(results: &[(String, ChunkingBench)]) -> String {
    let mut out = String::from(
        "| experiment | chunks | frames a chunk | CPU s | CPU vs one run | reuse lost | longest chunk s |\n|---|---:|---:|---:|---:|---:|---:|\n",
    );
    let mut notes = String::new();
    for (label, bench) in results {
        let one = bench.rows.iter().find(|r| r.chunks == 1).map(|r| r.cpu_s);
        for row in &bench.rows {
            let (small, large) = (row.fewest_frames, row.most_frames);
            let _ = writeln!(
                out,
                "| {label} | {} | {} | {:.2} | {} | {} | {:.2} |",
                row.chunks,
                if small == large {
                    small.to_string()
                } else {
                    format!("{small}-{large}")
                },
                row.cpu_s,
                one.map_or("-".into(), |one| format!("{:.2}x", row.cpu_s / one)),
                bench
                    .reuse_lost(row)
                    .map_or("-".into(), |l| format!("{:.0}%", l * 100.0)),
                row.longest_chunk_s,
            );
        }
        let _ = writeln!(
            notes,
            "- {label}: a full render of the {} frames took {:.2} CPU s; {}",
            bench.frames,
            bench.full_cpu_s,
            match (
                bench.restart_cost_frames(),
                bench.min_frames_per_chunk(ACCEPTED_REUSE_LOSS)
            ) {
                (Some(cost), Some(k)) => format!(
                    "a restart costs {cost:.1} frames' worth of reuse: keep at least {k} frames a chunk to lose < {:.0}% of the reuse",
                    ACCEPTED_REUSE_LOSS * 100.0
                ),
                _ => "nothing was reused, so chunking loses nothing".into(),
            }
        );
    }
    format!("{out}\n{notes}")
}

//! Splitting an animation's frames among the tasks of a render farm's array
//! job: each task renders one contiguous chunk, starting from a full frame.
//!
//! A task learns its index from `--chunk-index` or from the environment its
//! scheduler sets: a Slurm job array (`SLURM_ARRAY_TASK_ID`, counted from
//! `SLURM_ARRAY_TASK_MIN`), a Kubernetes indexed Job
//! (`JOB_COMPLETION_INDEX`) or an AWS Batch array job
//! (`AWS_BATCH_JOB_ARRAY_INDEX`).
//!
//! Every technique's output is independent of which frame a run started
//! from (exact frames equal their full renders; RSVP viewports resample
//! buffer samples that equal a fresh trace), so the frames of a chunked
//! run are the frames of one long run, bit for bit, and their statistics
//! merge into one run's ([`merge_stats`]).

use std::ops::RangeInclusive;

use serde_json::Value;

/// Where a task's chunk index came from, for messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum IndexSource {
    Flag,
    Environment(&'static str),
}

impl std::fmt::Display for IndexSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            IndexSource::Flag => write!(f, "--chunk-index"),
            IndexSource::Environment(name @ "SLURM_ARRAY_TASK_ID") => {
                write!(f, "{name}, counted from SLURM_ARRAY_TASK_MIN")
            }
            IndexSource::Environment(name) => write!(f, "{name}"),
        }
    }
}

/// The array-job index variables this understands, in the order tried.
const INDEX_VARIABLES: [&str; 3] = [
    "SLURM_ARRAY_TASK_ID",
    "JOB_COMPLETION_INDEX",
    "AWS_BATCH_JOB_ARRAY_INDEX",
];

/// This task's 0-based chunk index from the environment (`var` reads a
/// variable), or None when no scheduler set one.
pub fn index_from_env(
    var: impl Fn(&str) -> Option<String>,
) -> Result<Option<(u32, IndexSource)>, String> {
    let number = |name: &str, text: &str| {
        text.trim()
            .parse::<u32>()
            .map_err(|_| format!("{name}={text}: not a task index (a whole number from 0)"))
    };
    for name in INDEX_VARIABLES {
        let Some(text) = var(name) else { continue };
        let mut index = number(name, &text)?;
        // Slurm numbers a job array's tasks as its --array asked (1-8, say).
        if name == "SLURM_ARRAY_TASK_ID" {
            if let Some(min) = var("SLURM_ARRAY_TASK_MIN") {
                let min = number("SLURM_ARRAY_TASK_MIN", &min)?;
                index = index.checked_sub(min).ok_or_else(|| {
                    format!("SLURM_ARRAY_TASK_ID={text} is below SLURM_ARRAY_TASK_MIN={min}")
                })?;
            }
        }
        return Ok(Some((index, IndexSource::Environment(name))));
    }
    Ok(None)
}

/// The frames of chunk `index` when `frames` is cut into `count`
/// contiguous chunks whose sizes differ by at most one (None: the chunk is
/// empty, when there are more chunks than frames).
pub fn chunk_frames(
    frames: &RangeInclusive<u32>,
    count: u32,
    index: u32,
) -> Option<RangeInclusive<u32>> {
    assert!(index < count, "chunk {index} of {count}");
    let (start, len) = (
        u64::from(*frames.start()),
        u64::from(frames.end() - frames.start()) + 1,
    );
    let edge = |k: u64| start + k * len / u64::from(count);
    let (first, end) = (edge(u64::from(index)), edge(u64::from(index) + 1));
    // Within the range, whose bounds are u32.
    (first < end).then(|| first as u32..=(end - 1) as u32)
}

/// `path` with `.chunkNN` before its extension, NN the index padded to the
/// width of the last index: each task's own statistics file.
pub fn chunk_path(path: &std::path::Path, count: u32, index: u32) -> std::path::PathBuf {
    let width = (count - 1).max(1).to_string().len();
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match path.extension() {
        Some(ext) => format!("{stem}.chunk{index:0width$}.{}", ext.to_string_lossy()),
        None => format!("{stem}.chunk{index:0width$}"),
    };
    path.with_file_name(name)
}

/// The statistics of a whole run from its chunks' (each a JSON array of
/// per-frame rows, as `animate --stats x.json` writes): the rows in frame
/// order. Fails if a frame appears twice.
pub fn merge_stats(chunks: Vec<Vec<Value>>) -> Result<Vec<Value>, String> {
    let mut rows: Vec<Value> = chunks.into_iter().flatten().collect();
    let key = |row: &Value| {
        (
            row.get("frame").and_then(Value::as_u64).unwrap_or(u64::MAX),
            row.get("viewport")
                .and_then(Value::as_str)
                .unwrap_or_default()
                .to_string(),
        )
    };
    // Stable: a frame's views keep the order the run wrote them in.
    rows.sort_by_key(|row| key(row).0);
    for pair in rows.windows(2) {
        if key(&pair[0]) == key(&pair[1]) {
            let (frame, view) = key(&pair[0]);
            let view = if view.is_empty() {
                String::new()
            } else {
                format!(" (viewport {view})")
            };
            return Err(format!("frame {frame}{view} is in two chunks' statistics"));
        }
    }
    Ok(rows)
}

/// The share of the reuse the recommended chunk size may lose: what `farm
/// submit` advises and `bench --only chunking` reports.
pub const ACCEPTED_REUSE_LOSS: f64 = 0.1;

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    #[test]
    fn chunks_cover_the_frames_once_in_order_and_evenly() {
        for (frames, count) in [
            (0..=99, 8),
            (10..=12, 3),
            (5..=5, 1),
            (0..=4, 7),
            (3..=102, 100),
        ] {
            let chunks: Vec<_> = (0..count)
                .filter_map(|i| chunk_frames(&frames, count, i))
                .collect();
            let all: Vec<u32> = chunks.iter().flat_map(|c| c.clone()).collect();
            assert_eq!(
                all,
                frames.clone().collect::<Vec<_>>(),
                "{frames:?} / {count}"
            );
            let sizes: Vec<usize> = chunks.iter().map(|c| c.clone().count()).collect();
            let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
            assert!(hi - lo <= 1, "{frames:?} / {count}: {sizes:?}");
        }
        assert_eq!(chunk_frames(&(0..=99), 8, 0), Some(0..=11));
        assert_eq!(chunk_frames(&(0..=99), 8, 7), Some(87..=99));
        // More chunks than frames: some get none.
        assert_eq!(chunk_frames(&(0..=1), 4, 0), None);
        assert_eq!(
            chunk_frames(&(0..=u32::MAX), 2, 1),
            Some(1 << 31..=u32::MAX)
        );
    }

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: HashMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |name| map.get(name).cloned()
    }

    #[test]
    fn the_index_comes_from_the_scheduler() {
        assert_eq!(index_from_env(env(&[])), Ok(None));
        assert_eq!(
            index_from_env(env(&[("JOB_COMPLETION_INDEX", "3")])),
            Ok(Some((3, IndexSource::Environment("JOB_COMPLETION_INDEX"))))
        );
        // A Slurm array --array=1-8: task 1 renders chunk 0.
        assert_eq!(
            index_from_env(env(&[
                ("SLURM_ARRAY_TASK_ID", "1"),
                ("SLURM_ARRAY_TASK_MIN", "1")
            ])),
            Ok(Some((0, IndexSource::Environment("SLURM_ARRAY_TASK_ID"))))
        );
        assert_eq!(
            index_from_env(env(&[("AWS_BATCH_JOB_ARRAY_INDEX", " 12 ")])),
            Ok(Some((
                12,
                IndexSource::Environment("AWS_BATCH_JOB_ARRAY_INDEX")
            )))
        );
        let err = index_from_env(env(&[("JOB_COMPLETION_INDEX", "-1")])).unwrap_err();
        assert!(err.contains("JOB_COMPLETION_INDEX=-1"), "{err}");
        let err = index_from_env(env(&[
            ("SLURM_ARRAY_TASK_ID", "0"),
            ("SLURM_ARRAY_TASK_MIN", "2"),
        ]))
        .unwrap_err();
        assert!(err.contains("below"), "{err}");
    }

    #[test]
    fn each_chunk_gets_its_own_statistics_file() {
        use std::path::Path;
        assert_eq!(
            chunk_path(Path::new("out/stats.csv"), 16, 3),
            Path::new("out/stats.chunk03.csv")
        );
        assert_eq!(
            chunk_path(Path::new("s.json"), 2, 1),
            Path::new("s.chunk1.json")
        );
        assert_eq!(
            chunk_path(Path::new("stats"), 1, 0),
            Path::new("stats.chunk0")
        );
    }

    #[test]
    fn chunk_statistics_merge_in_frame_order() {
        let row = |frame: u32| serde_json::json!({"frame": frame, "viewport": ""});
        let merged = merge_stats(vec![vec![row(2), row(3)], vec![row(0), row(1)]]).unwrap();
        let frames: Vec<_> = merged
            .iter()
            .map(|r| r["frame"].as_u64().unwrap())
            .collect();
        assert_eq!(frames, [0, 1, 2, 3]);
        let err = merge_stats(vec![vec![row(1)], vec![row(1)]]).unwrap_err();
        assert!(err.contains("frame 1"), "{err}");
        // Two viewports of one frame are two rows, not a repeat.
        let view = |name: &str| serde_json::json!({"frame": 5, "viewport": name});
        assert_eq!(
            merge_stats(vec![vec![view("a"), view("b")]]).unwrap().len(),
            2
        );
    }
}

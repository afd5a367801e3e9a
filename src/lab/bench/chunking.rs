//! What cutting an animation into farm chunks costs: every chunk restarts
//! from a full frame (and from an empty RSVP buffer and OSTC grid), so the
//! reuse a long run gets between chunks is lost.
//!
//! Each chunk of a count is rendered as its own run, one after another in
//! this process, exactly as a farm task renders it. Measured per count: the
//! CPU time of all chunks (what a farm bills), the sum of their wall times,
//! and the longest chunk's wall time (the farm's wall time with one node
//! per chunk, scheduling left out). A plain full render of every frame
//! gives the scale: the reuse a run has is the full render's time less its
//! own, and chunking loses a share of that.

use std::time::Instant;

use cpu_time::ProcessTime;

use crate::accel::Accelerator;
use crate::chunk::chunk_frames;
use crate::frame_loop::{Animator, Options, Techniques};
use crate::scene::Scene;

/// One chunk count's cost, medians over the rounds.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ChunkingRow {
    pub chunks: u32,
    /// The fewest and most frames a chunk has.
    pub fewest_frames: u32,
    pub most_frames: u32,
    /// CPU seconds of all chunks together.
    pub cpu_s: f64,
    /// Wall seconds of all chunks, one after another.
    pub wall_s: f64,
    /// Wall seconds of the longest chunk.
    pub longest_chunk_s: f64,
}

/// The chunk counts measured, and a plain full render of the same frames.
#[derive(Clone, Debug, PartialEq)]
pub struct ChunkingBench {
    pub frames: u32,
    /// CPU and wall seconds of a plain full render of every frame.
    pub full_cpu_s: f64,
    pub full_wall_s: f64,
    pub rows: Vec<ChunkingRow>,
}

impl ChunkingBench {
    /// The share of the reuse (full render's CPU time less one long run's)
    /// that `row`'s chunking loses; None without a one-chunk row or without
    /// any reuse to lose.
    pub fn reuse_lost(&self, row: &ChunkingRow) -> Option<f64> {
        let one = self.rows.iter().find(|r| r.chunks == 1)?;
        let reuse = self.full_cpu_s - one.cpu_s;
        (reuse > 0.0).then(|| (row.cpu_s - one.cpu_s) / reuse)
    }

    /// What one chunk restart costs, in frames' worth of reuse: the CPU time
    /// chunking added, per restart, over the reuse one frame of a long run
    /// has (least squares through the origin over every count; None when
    /// nothing was reused or only one count was measured).
    pub fn restart_cost_frames(&self) -> Option<f64> {
        let one = self.rows.iter().find(|r| r.chunks == 1)?;
        let reuse_per_frame = (self.full_cpu_s - one.cpu_s) / f64::from(self.frames);
        let (mut xy, mut xx) = (0.0, 0.0);
        for row in &self.rows {
            let restarts = f64::from(row.chunks - 1);
            xy += restarts * (row.cpu_s - one.cpu_s);
            xx += restarts * restarts;
        }
        (reuse_per_frame > 0.0 && xx > 0.0).then(|| xy / xx / reuse_per_frame)
    }

    /// The fewest frames a chunk should have for chunking to lose less than
    /// `share` of the reuse: a chunk of K frames loses about one restart's
    /// cost out of K frames' reuse.
    pub fn min_frames_per_chunk(&self, share: f64) -> Option<u32> {
        let cost = self.restart_cost_frames()?;
        Some((cost.max(0.0) / share).ceil().max(1.0) as u32)
    }
}

/// Renders `options.frames` as 1 and every count of `counts` chunks,
/// `rounds` times (alternating the counts within a round), and a plain full
/// render of the same frames once a round.
pub fn bench_chunking(
    scene: &Scene,
    accel: &mut Accelerator,
    options: &Options,
    counts: &[u32],
    rounds: usize,
    mut progress: impl FnMut(),
) -> ChunkingBench {
    let frames = options.frames.clone();
    let range = frames.start..=frames.end.saturating_sub(1).max(frames.start);
    let frame_count = frames.end - frames.start;
    let rounds = rounds.max(1);
    // Untimed: the first render of a process pays for page faults and
    // rayon's threads.
    std::hint::black_box(
        Animator::new(scene, accel, Options::new(Techniques::FULL, frames.clone())).render_full(
            frames.start,
            0,
            None,
        ),
    );
    let mut full = Vec::new();
    let mut per_count: Vec<Vec<(f64, f64, f64)>> = vec![Vec::new(); counts.len()];
    for _ in 0..rounds {
        full.push(timed(|| {
            let mut animator =
                Animator::new(scene, accel, Options::new(Techniques::FULL, frames.clone()));
            let views = animator.views(frames.start).len();
            for frame in frames.clone() {
                for index in 0..views {
                    let (image, _) = animator.render_own_rays(frame, index, None);
                    std::hint::black_box(image.to_rgb8());
                }
                progress();
            }
        }));
        for (count, measured) in counts.iter().zip(&mut per_count) {
            let (mut cpu, mut wall, mut longest) = (0.0, 0.0, 0.0_f64);
            for index in 0..*count {
                let Some(chunk) = chunk_frames(&range, *count, index) else {
                    continue;
                };
                let chunk = *chunk.start()..*chunk.end() + 1;
                let (chunk_cpu, chunk_wall) = timed(|| {
                    let mut animator = Animator::new(
                        scene,
                        accel,
                        Options {
                            frames: chunk.clone(),
                            linear: false,
                            ..options.clone()
                        },
                    );
                    for frame in chunk.clone() {
                        std::hint::black_box(animator.render(frame));
                        progress();
                    }
                });
                cpu += chunk_cpu;
                wall += chunk_wall;
                longest = longest.max(chunk_wall);
            }
            measured.push((cpu, wall, longest));
        }
    }
    let rows = counts
        .iter()
        .zip(per_count)
        .map(|(&chunks, measured)| {
            let sizes: Vec<u32> = (0..chunks)
                .filter_map(|i| chunk_frames(&range, chunks, i))
                .map(|c| c.end() - c.start() + 1)
                .collect();
            ChunkingRow {
                chunks,
                fewest_frames: sizes.iter().copied().min().unwrap_or(0),
                most_frames: sizes.iter().copied().max().unwrap_or(0),
                cpu_s: median(measured.iter().map(|m| m.0).collect()),
                wall_s: median(measured.iter().map(|m| m.1).collect()),
                longest_chunk_s: median(measured.iter().map(|m| m.2).collect()),
            }
        })
        .collect();
    ChunkingBench {
        frames: frame_count,
        full_cpu_s: median(full.iter().map(|f| f.0).collect()),
        full_wall_s: median(full.iter().map(|f| f.1).collect()),
        rows,
    }
}

/// The process's CPU seconds (all threads) and the wall seconds `work`
/// took.
fn timed(work: impl FnOnce()) -> (f64, f64) {
    let (cpu, wall) = (ProcessTime::now(), Instant::now());
    work();
    (cpu.elapsed().as_secs_f64(), wall.elapsed().as_secs_f64())
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(chunks: u32, cpu_s: f64) -> ChunkingRow {
        ChunkingRow {
            chunks,
            fewest_frames: 100 / chunks,
            most_frames: 100 / chunks,
            cpu_s,
            wall_s: cpu_s,
            longest_chunk_s: cpu_s / f64::from(chunks),
        }
    }

    /// Full frames of 1 s, reused ones of 0.1 s: a long run of 100 frames
    /// is 1 + 99 * 0.1 s, and each restart trades a reused frame for a
    /// full one (0.9 s, one frame's reuse).
    fn one_frame_per_restart() -> ChunkingBench {
        let long = 1.0 + 99.0 * 0.1;
        ChunkingBench {
            frames: 100,
            full_cpu_s: 100.0,
            full_wall_s: 100.0,
            rows: [1, 2, 4, 10]
                .map(|n| row(n, long + f64::from(n - 1) * 0.9))
                .to_vec(),
        }
    }

    #[test]
    fn a_restart_that_retraces_one_frame_costs_about_one_frame_of_reuse() {
        let bench = one_frame_per_restart();
        let cost = bench.restart_cost_frames().unwrap();
        // One frame's reuse is (100 - 10.9) / 100 = 0.891 s a frame.
        assert!((cost - 0.9 / 0.891).abs() < 1e-9, "{cost}");
        assert_eq!(bench.min_frames_per_chunk(0.1), Some(11));
        let ten = bench.rows.iter().find(|r| r.chunks == 10).unwrap();
        let lost = bench.reuse_lost(ten).unwrap();
        assert!((lost - 9.0 * 0.9 / 89.1).abs() < 1e-9, "{lost}");
    }

    #[test]
    fn nothing_reused_means_no_recommendation() {
        let bench = ChunkingBench {
            full_cpu_s: 5.0,
            ..one_frame_per_restart()
        };
        assert_eq!(bench.restart_cost_frames(), None);
        assert_eq!(bench.min_frames_per_chunk(0.1), None);
        assert_eq!(bench.reuse_lost(&bench.rows[1]), None);
    }
}

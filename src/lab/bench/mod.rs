//! Measurements behind `retrace bench`.
//!
//! `frame`: how much a full frame costs beyond Embree itself. The frame is
//! rendered once through a recording intersector that keeps every packet
//! call (primary, shadow, reflection: rays and lane masks); then full
//! renders and replays of exactly those packets through bare Embree (no ray
//! generation, no shading, no plane tests) alternate, and the medians are
//! compared. Both sides run on the same rayon pool.
//!
//! `backends`: the grid against Embree on the packet calls of one frame
//! (planes included on both sides, as the renderer traces them).
//!
//! Experiments (E1-E4): a sequence rendered in full and accelerated in one
//! run, with a per-frame profile of both sides and the oracle (the least
//! tracing any reuse could do); [`crate::lab::report`] turns them into the table.

mod chunking;
mod oracle;
mod sequence;
mod viewport_oracle;

pub use chunking::{bench_chunking, ChunkingBench, ChunkingRow};
pub use oracle::{rays_per_pixel, OracleRays};
pub use sequence::{
    bench_sequence, ErrorSummary, FrameProfile, Measure, OracleSpeedups, ReferenceErrors,
    SequenceBench,
};
pub use viewport_oracle::viewport_oracle;

use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;

use crate::accel::embree::{EmbreeError, EmbreeIntersector};
use crate::accel::{AccelError, Accelerator, BackendKind, Intersector};
use crate::clock;
use crate::ray::{Hit, HitPacket, LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::render::render_frame;
use crate::scene::Scene;
use crate::shade::RayCounts;

#[derive(Clone, Copy)]
enum Call {
    Intersect,
    Occluded,
}

struct Recorded {
    call: Call,
    rays: RayPacket,
    mask: LaneMask,
}

/// Forwards to an intersector and keeps a copy of every packet call.
struct Recorder<'a> {
    inner: &'a dyn Intersector,
    log: Mutex<Vec<Recorded>>,
}

impl Recorder<'_> {
    fn record(&self, call: Call, rays: &RayPacket, mask: LaneMask) {
        self.log
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(Recorded {
                call,
                rays: *rays,
                mask,
            });
    }
}

impl Intersector for Recorder<'_> {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
        rays[0] = *ray;
        self.record(Call::Intersect, &rays, 1);
        self.inner.intersect(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
        rays[0] = *ray;
        self.record(Call::Occluded, &rays, 1);
        self.inner.occluded(ray)
    }

    fn intersect8(&self, rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
        self.record(Call::Intersect, rays, mask);
        self.inner.intersect8(rays, mask, hits)
    }

    fn occluded8(&self, rays: &RayPacket, mask: LaneMask) -> LaneMask {
        self.record(Call::Occluded, rays, mask);
        self.inner.occluded8(rays, mask)
    }
}

/// What a packet-replay measurement ran on.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PacketRun {
    pub width: u32,
    pub height: u32,
    pub repeats: usize,
    /// Packet calls in one frame.
    pub packets: usize,
    pub rays: RayCounts,
    pub threads: usize,
}

impl PacketRun {
    fn new(scene: &Scene, repeats: usize, packets: usize, rays: RayCounts) -> PacketRun {
        PacketRun {
            width: scene.camera.width,
            height: scene.camera.height,
            repeats,
            packets,
            rays,
            threads: rayon::current_num_threads(),
        }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct FrameBench {
    #[serde(flatten)]
    pub run: PacketRun,
    /// Median of the full renders (ray generation, Embree, planes, shading).
    pub full_ms: f64,
    /// Median of the bare Embree replays of the same packets.
    pub embree_ms: f64,
    /// full / embree.
    pub ratio: f64,
}

/// The packet calls a full frame of `scene` makes, recorded once.
fn record_frame(scene: &Scene, accel: &Accelerator) -> (Vec<Recorded>, RayCounts) {
    let recorder = Recorder {
        inner: accel,
        log: Mutex::new(Vec::new()),
    };
    let (_, rays) = render_frame(scene, &recorder);
    (
        recorder.log.into_inner().unwrap_or_else(|e| e.into_inner()),
        rays,
    )
}

/// Replays recorded packet calls through `intersector`, in parallel.
fn replay(log: &[Recorded], intersector: &dyn Intersector) {
    log.par_iter()
        .with_min_len(16)
        .for_each(|packet| match packet.call {
            Call::Intersect => {
                let mut hits = [None; PACKET_WIDTH];
                intersector.intersect8(&packet.rays, packet.mask, &mut hits);
                std::hint::black_box(&hits);
            }
            Call::Occluded => {
                std::hint::black_box(intersector.occluded8(&packet.rays, packet.mask));
            }
        })
}

/// Each frame's times: the medians of its rounds, full and accelerated.
fn set_frame_medians(profile: &mut [FrameProfile], full: Vec<Vec<f64>>, fast: Vec<Vec<f64>>) {
    for ((row, full), fast) in profile.iter_mut().zip(full).zip(fast) {
        row.full_ms = median(full);
        row.accelerated_ms = median(fast);
    }
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Measures a full frame of `scene` against bare Embree on the same packets.
pub fn bench_frame(
    scene: &Scene,
    accel: &Accelerator,
    repeats: usize,
    mut progress: impl FnMut(),
) -> Result<FrameBench, EmbreeError> {
    let bare = EmbreeIntersector::build(&scene.objects)?;
    let recorder = Recorder {
        inner: accel,
        log: Mutex::new(Vec::new()),
    };
    let (_, rays) = render_frame(scene, &recorder);
    let log = recorder.log.into_inner().unwrap_or_else(|e| e.into_inner());

    let replay = || {
        log.par_iter()
            .with_min_len(16)
            .for_each(|packet| match packet.call {
                Call::Intersect => {
                    let mut hits = [None; PACKET_WIDTH];
                    bare.intersect8(&packet.rays, packet.mask, &mut hits);
                    std::hint::black_box(&hits);
                }
                Call::Occluded => {
                    std::hint::black_box(bare.occluded8(&packet.rays, packet.mask));
                }
            })
    };
    // Warm both paths (page faults, caches, rayon's threads).
    replay();
    std::hint::black_box(render_frame(scene, accel));

    let repeats = repeats.max(1);
    let mut full = Vec::with_capacity(repeats);
    let mut embree = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let start = Instant::now();
        std::hint::black_box(render_frame(scene, accel));
        full.push(clock::ms(start.elapsed()));
        let start = Instant::now();
        replay();
        embree.push(clock::ms(start.elapsed()));
        progress();
    }
    let (full_ms, embree_ms) = (median(full), median(embree));
    Ok(FrameBench {
        run: PacketRun::new(scene, repeats, log.len(), rays),
        full_ms,
        embree_ms,
        ratio: full_ms / embree_ms,
    })
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct BackendBench {
    #[serde(flatten)]
    pub run: PacketRun,
    /// Median time of Embree on the recorded packets (planes included).
    pub embree_ms: f64,
    /// Median time of the grid on the same packets.
    pub grid_ms: f64,
    /// grid / embree.
    pub ratio: f64,
}

/// Times both backends on the packet calls of one full frame (recorded
/// through Embree), alternating, medians compared.
pub fn bench_backends(
    scene: &Scene,
    repeats: usize,
    mut progress: impl FnMut(),
) -> Result<BackendBench, AccelError> {
    let embree = Accelerator::build(BackendKind::Embree, &scene.objects)?;
    let grid = Accelerator::build(BackendKind::Grid, &scene.objects)?;
    let (log, rays) = record_frame(scene, &embree);
    replay(&log, &embree);
    replay(&log, &grid);
    let repeats = repeats.max(1);
    let (mut embree_times, mut grid_times) = (Vec::new(), Vec::new());
    for _ in 0..repeats {
        let start = Instant::now();
        replay(&log, &embree);
        embree_times.push(clock::ms(start.elapsed()));
        let start = Instant::now();
        replay(&log, &grid);
        grid_times.push(clock::ms(start.elapsed()));
        progress();
    }
    let (embree_ms, grid_ms) = (median(embree_times), median(grid_times));
    Ok(BackendBench {
        run: PacketRun::new(scene, repeats, log.len(), rays),
        embree_ms,
        grid_ms,
        ratio: grid_ms / embree_ms,
    })
}

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

mod viewport_oracle;

pub use viewport_oracle::viewport_oracle;

use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;

use crate::accel::embree::{EmbreeError, EmbreeIntersector};
use crate::accel::{AccelError, Accelerator, BackendKind, Intersector};
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
        full.push(start.elapsed().as_secs_f64() * 1e3);
        let start = Instant::now();
        replay();
        embree.push(start.elapsed().as_secs_f64() * 1e3);
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
        embree_times.push(start.elapsed().as_secs_f64() * 1e3);
        let start = Instant::now();
        replay(&log, &grid);
        grid_times.push(start.elapsed().as_secs_f64() * 1e3);
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

/// One frame of an experiment, both sides: where the time and the rays go.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameProfile {
    pub frame: u32,
    /// The full render (every viewport, for RSVP), 8-bit conversion included.
    pub full_ms: f64,
    pub accelerated_ms: f64,
    pub full_rays: RayCounts,
    pub accelerated_rays: RayCounts,
    /// Samples (primary rays) the accelerated side traced.
    pub samples_traced: u64,
    /// OSTC: regions found dirty and samples erased for them.
    pub dirty_regions: u64,
    pub samples_nulled: u64,
    /// OSTC: recording and merging.
    pub bookkeeping_ms: f64,
    /// The accelerated side's tracing: the samples it could not reuse, with
    /// their shadow and reflection rays.
    pub accelerated_trace_ms: f64,
    /// The accelerated side's everything else but bookkeeping: copying
    /// reused pixels, RSVP's mapping and resampling, 8-bit conversion.
    pub accelerated_copy_ms: f64,
    /// Samples the oracle says this frame could not avoid tracing.
    pub oracle_samples: Option<u64>,
    /// The same with every region that holds one traced whole.
    pub oracle_region_samples: Option<u64>,
    /// RSVP: the worst viewport's PSNR against its direct render.
    pub psnr_db: Option<f64>,
    /// Camera sequences: the accelerated frame equals the full one bit for bit.
    pub exact: Option<bool>,
}

impl FrameProfile {
    /// One empty profile per frame of `frames`.
    fn empty(frames: std::ops::Range<u32>) -> Vec<FrameProfile> {
        frames
            .map(|frame| FrameProfile {
                frame,
                ..FrameProfile::default()
            })
            .collect()
    }
}

/// One experiment's sequence, rendered in full and with reuse in one run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SequenceBench {
    pub frames: u32,
    pub pixels_per_frame: u64,
    /// Median over rounds of the whole full sequence (frames converted to
    /// 8 bits, not written).
    pub full_ms: f64,
    /// The same for the accelerated sequence (frame 0, buffers and copies included).
    pub accelerated_ms: f64,
    pub speedup: f64,
    pub samples_traced: u64,
    /// The rays of full renders of every frame over the rays of the
    /// samples no reuse could avoid tracing: the lattice samples the windows
    /// expose, each once, and the samples whose colour changed.
    pub oracle_speedup: f64,
    /// The same, with every region that holds such a sample traced whole
    /// (the best OSTC can do at its region size).
    pub region_oracle_speedup: f64,
    /// The oracle's ray totals behind both speedups.
    pub oracle_rays: OracleRays,
    /// The region oracle timed rather than counted: full renders over
    /// frame 0 in full plus, for each later frame, the time of tracing just
    /// the groups of its regions that had to be traced (first round). Rays
    /// differ in cost (those near a moving object hit more and reflect
    /// more), which counting rays cannot see.
    pub timed_region_oracle_speedup: f64,
    /// speedup / oracle_speedup.
    pub efficiency: f64,
    /// OSTC's recording and merging per frame, as a share of a full
    /// frame's time (last round).
    pub bookkeeping_share: f64,
    /// Every accelerated frame equal, bit for bit, to its full render.
    pub exact: bool,
    pub max_yaw_error_deg: f64,
    pub rounds: usize,
    pub threads: usize,
    /// Why accelerated frames were rendered in full, where reuse could not
    /// apply (a pan on a camera that is not equal-angle, say), each once.
    pub full_reasons: Vec<String>,
    /// Per frame: times are medians over the rounds.
    pub profile: Vec<FrameProfile>,
}

/// FNV-1a over a frame's bits: full and accelerated frames compare without
/// keeping a hundred frames in memory.
fn frame_hash(frame: &crate::render::Frame) -> u64 {
    frame
        .pixels
        .iter()
        .flat_map(|p| p.to_array())
        .fold(0xcbf2_9ce4_8422_2325u64, |h, x| {
            (h ^ u64::from(x.to_bits())).wrapping_mul(0x0100_0000_01b3)
        })
}

/// The least tracing any reuse could get away with, counted from the full
/// renders of a sequence: samples never traced before (newly exposed by a
/// pan) plus samples whose value truly changed since they were last shown,
/// per sample and per region (a region counts whole when any of its
/// samples needs tracing: what OSTC at that granularity could at best do).
///
/// Equal-angle views are placed on their pan lattice, so a sample keeps its
/// identity as the window moves; other views (and views too narrow for a
/// whole-turn lattice) keep the camera's own pixels while it stands still,
/// and count every pixel when it moves (no reuse keeps them then).
struct Oracle {
    /// Per lattice sample (row-major within a whole turn), or per pixel of
    /// `image_camera`: a hash of the colour last shown, 0 for never.
    shown: Vec<u64>,
    lattice: Option<crate::reuse::pan::EqualAngleLattice>,
    /// The camera whose own pixels `shown` holds, off the lattice.
    image_camera: Option<crate::camera::Camera>,
    region_size: (i64, i64),
    samples: u64,
    region_samples: u64,
    /// Per pixel of the last frame added: does its region need tracing?
    region_pixels: Vec<bool>,
    /// Rays a full render of every frame traced, and the rays of the
    /// oracle's samples and regions: what tracing them costs, since pixels
    /// differ a lot in cost (a mirror's samples trace several rays).
    rays: OracleRays,
}

/// Ray totals of the oracle (see `Oracle::rays`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct OracleRays {
    pub all: u64,
    pub samples: u64,
    pub regions: u64,
}

impl Oracle {
    fn new(region_size: (i64, i64)) -> Oracle {
        Oracle {
            shown: Vec::new(),
            lattice: None,
            image_camera: None,
            region_size,
            samples: 0,
            region_samples: 0,
            region_pixels: Vec::new(),
            rays: OracleRays::default(),
        }
    }

    /// Counts what `frame` (seen by `camera`, whose full render traced
    /// `rays[pixel]` rays for each pixel) must trace: (samples, samples of
    /// whole regions).
    fn add(
        &mut self,
        camera: &crate::camera::Camera,
        frame: &crate::render::Frame,
        rays: &[u32],
    ) -> (u64, u64) {
        use crate::reuse::pan::EqualAngleLattice;
        let all_rays: u64 = rays.iter().map(|&r| u64::from(r)).sum();
        self.rays.all += all_rays;
        let before = (self.samples, self.region_samples);
        // One hash per sample of a whole lattice: past the pan buffer's
        // limit (a narrow view) no pan runs either.
        let columns = EqualAngleLattice::columns_per_turn_for(camera) as f64;
        let on_lattice = camera.projection == crate::camera::Projection::EqualAngle
            && 8.0 * columns * columns / 2.0 <= crate::anim::PAN_BUFFER_LIMIT_BYTES;
        let (rw, rh) = self.region_size;
        let width = i64::from(frame.width);
        // Where each pixel's sample lives (a slot of `shown`, None for none)
        // and its region.
        let place: Box<dyn Fn(i64, i64) -> (Option<usize>, i64)> = if on_lattice {
            if !self.lattice.as_ref().is_some_and(|l| l.fits(camera)) {
                let lattice = EqualAngleLattice::for_camera(camera);
                self.shown = vec![0; (lattice.columns_per_turn * lattice.rows) as usize];
                self.lattice = Some(lattice);
            }
            let lattice = self.lattice.as_ref().expect("lattice just ensured");
            let window = lattice.window(camera);
            let regions_across = (lattice.columns_per_turn + rw - 1) / rw;
            Box::new(move |x, y| {
                let (col, row) = (lattice.wrap_column(window.col + x), window.row + y);
                let slot = usize::try_from(row)
                    .ok()
                    .filter(|&r| (r as i64) < lattice.rows)
                    .map(|r| r * lattice.columns_per_turn as usize + col as usize);
                (slot, row.div_euclid(rh) * regions_across + col / rw)
            })
        } else {
            // Off the lattice a sample is the camera's own pixel, kept while
            // the camera stands still (as OSTC keeps it).
            if self.image_camera.as_ref() != Some(camera) {
                self.shown = vec![0; frame.pixels.len()];
                self.image_camera = Some(camera.clone());
                self.lattice = None;
            }
            let regions_across = (width + rw - 1) / rw;
            Box::new(move |x, y| {
                let slot = (y * width + x) as usize;
                (Some(slot), (y / rh) * regions_across + x / rw)
            })
        };
        if on_lattice {
            self.image_camera = None;
        }
        let mut dirty_regions = std::collections::HashSet::new();
        let mut region_of_pixel = Vec::with_capacity(frame.pixels.len());
        for (i, color) in frame.pixels.iter().enumerate() {
            let (slot, region) = place(i as i64 % width, i as i64 / width);
            region_of_pixel.push(region);
            let hash = color
                .to_array()
                .iter()
                .fold(0xcbf2_9ce4_8422_2325u64, |h, c| {
                    (h ^ u64::from(c.to_bits())).wrapping_mul(0x0100_0000_01b3)
                })
                | 1;
            let Some(slot) = slot else {
                continue;
            };
            if self.shown[slot] != hash {
                self.shown[slot] = hash;
                self.samples += 1;
                self.rays.samples += u64::from(rays[i]);
                dirty_regions.insert(region);
            }
        }
        self.region_pixels.clear();
        for (region, &pixel_rays) in region_of_pixel.iter().zip(rays) {
            let dirty = dirty_regions.contains(region);
            if dirty {
                self.region_samples += 1;
                self.rays.regions += u64::from(pixel_rays);
            }
            self.region_pixels.push(dirty);
        }
        (self.samples - before.0, self.region_samples - before.1)
    }

    /// The sample groups (of a `width` pixels wide frame) holding a pixel
    /// of the last frame's regions that had to be traced: what the region
    /// oracle traces when timed.
    fn region_groups(&self, width: u32) -> Vec<crate::render::SampleGroup> {
        let width = i64::from(width.max(1));
        let mut groups: Vec<_> = self
            .region_pixels
            .iter()
            .enumerate()
            .filter(|&(_, &dirty)| dirty)
            .map(|(i, _)| {
                crate::render::SampleGroup::containing(i as i64 % width, i as i64 / width)
            })
            .collect();
        groups.sort_unstable_by_key(|g| (g.row, g.col));
        groups.dedup();
        groups
    }
}

/// Rays traced for each pixel of a full render through `camera` (primary,
/// shadow and reflection rays of its sample), counted on an untimed pass:
/// what each pixel costs to trace.
pub fn rays_per_pixel(shader: &crate::shade::Shader, camera: &crate::camera::Camera) -> Vec<u32> {
    use crate::render::{trace_groups_observed, SampleGroup};
    use crate::shade::{RayKind, RayObserver};
    use std::sync::atomic::{AtomicU32, Ordering};

    struct Counter<'a> {
        counts: [u32; PACKET_WIDTH],
        group: SampleGroup,
        width: i64,
        height: i64,
        sink: &'a [AtomicU32],
    }
    impl RayObserver for Counter<'_> {
        fn traced(&mut self, _: RayKind, _: &RayPacket, mask: LaneMask, _: &[f32; PACKET_WIDTH]) {
            for lane in crate::ray::lanes(mask) {
                self.counts[lane] += 1;
            }
        }
    }
    impl Drop for Counter<'_> {
        fn drop(&mut self) {
            for (lane, (x, y)) in self.group.lane_samples().into_iter().enumerate() {
                if x < self.width && y < self.height {
                    self.sink[(y * self.width + x) as usize]
                        .fetch_add(self.counts[lane], Ordering::Relaxed);
                }
            }
        }
    }

    let (width, height) = (i64::from(camera.width), i64::from(camera.height));
    let sink: Vec<AtomicU32> = (0..width * height).map(|_| AtomicU32::new(0)).collect();
    let table = crate::camera::RayTable::new(camera);
    let groups = SampleGroup::covering(0..width, 0..height);
    trace_groups_observed(shader, &table, &groups, |group| {
        Some(Counter {
            counts: [0; PACKET_WIDTH],
            group,
            width,
            height,
            sink: &sink,
        })
    });
    sink.into_iter().map(AtomicU32::into_inner).collect()
}

/// Renders `frames` in full and with `techniques`, alternating `rounds`
/// times; compares the medians of the sequence totals.
pub fn bench_sequence(
    scene: &Scene,
    accel: &mut Accelerator,
    techniques: crate::anim::Techniques,
    ostc: crate::anim::OstcSettings,
    frames: std::ops::Range<u32>,
    rounds: usize,
    mut progress: impl FnMut(),
) -> SequenceBench {
    let region_size = ostc
        .regions
        .region_size(scene.camera.width, scene.camera.height);
    use crate::anim::{Animator, Techniques};
    let rounds = rounds.max(1);
    let (mut full_times, mut fast_times) = (Vec::new(), Vec::new());
    let mut exact = true;
    let mut samples_traced = 0;
    let mut max_yaw_error: f64 = 0.0;
    let mut full_reasons: Vec<String> = Vec::new();
    let mut pixels_per_frame = 0;
    let mut bookkeeping_ms = 0.0;
    let mut oracle = Oracle::new(region_size);
    let mut oracle_traced_ms = 0.0;
    let mut profile = FrameProfile::empty(frames.clone());
    // Per frame and round, for per-frame medians.
    let mut full_frame_ms = vec![Vec::new(); profile.len()];
    let mut fast_frame_ms = vec![Vec::new(); profile.len()];
    // Untimed: the first render of a process pays for page faults and
    // rayon's threads, which neither side should.
    std::hint::black_box(
        Animator::new(scene, accel, Techniques::FULL, frames.clone()).render_full(frames.start),
    );
    for round in 0..rounds {
        let mut full = Animator::new(scene, accel, Techniques::FULL, frames.clone());
        let mut hashes = Vec::new();
        let mut elapsed = 0.0;
        for (row, frame) in profile.iter_mut().zip(frames.clone()) {
            let start = Instant::now();
            let (image, rays) = full.render_full(frame);
            std::hint::black_box(image.to_rgb8());
            let ms = start.elapsed().as_secs_f64() * 1e3;
            elapsed += ms;
            full_frame_ms[(frame - frames.start) as usize].push(ms);
            hashes.push(frame_hash(&image));
            if round == 0 {
                let (shader, camera) = full.posed_shader(frame);
                let pixel_rays = rays_per_pixel(&shader, &camera);
                let (samples, region_samples) = oracle.add(&camera, &image, &pixel_rays);
                row.oracle_samples = Some(samples);
                row.oracle_region_samples = Some(region_samples);
                row.full_rays = rays;
                let table = crate::camera::RayTable::new(&camera);
                let groups = oracle.region_groups(camera.width);
                let start = Instant::now();
                std::hint::black_box(crate::render::trace_groups(&shader, &table, &groups));
                oracle_traced_ms += start.elapsed().as_secs_f64() * 1e3;
            }
            progress();
        }
        full_times.push(elapsed);

        let mut fast = Animator::new(scene, accel, techniques, frames.clone());
        fast.set_linear_output(false);
        fast.set_ostc(ostc);
        samples_traced = 0;
        bookkeeping_ms = 0.0;
        let mut elapsed = 0.0;
        for (row, frame) in profile.iter_mut().zip(frames.clone()) {
            let start = Instant::now();
            let (_, rgb, stats) = fast.render(frame);
            std::hint::black_box(rgb);
            let ms = start.elapsed().as_secs_f64() * 1e3;
            elapsed += ms;
            fast_frame_ms[(frame - frames.start) as usize].push(ms);
            samples_traced += stats.samples_traced;
            bookkeeping_ms += stats.bookkeeping_ms;
            max_yaw_error = max_yaw_error.max(stats.yaw_error_deg.abs());
            pixels_per_frame = stats.pixels;
            // The last round's counts (they are the same every round).
            row.accelerated_rays = RayCounts {
                primary: stats.primary_rays,
                shadow: stats.shadow_rays,
                reflection: stats.reflection_rays,
            };
            row.samples_traced = stats.samples_traced;
            row.dirty_regions = stats.dirty_regions;
            row.samples_nulled = stats.samples_nulled;
            row.bookkeeping_ms = stats.bookkeeping_ms;
            row.accelerated_trace_ms = stats.trace_ms;
            row.accelerated_copy_ms = stats.copy_ms;
            if let Some(reason) = stats.refusal() {
                if !full_reasons.iter().any(|r| r == reason) {
                    full_reasons.push(reason.to_string());
                }
            }
            progress();
        }
        fast_times.push(elapsed);
        // Exactness on a separate, untimed pass that keeps linear colour.
        let mut check = Animator::new(scene, accel, techniques, frames.clone());
        check.set_ostc(ostc);
        for ((row, frame), full_hash) in profile.iter_mut().zip(frames.clone()).zip(&hashes) {
            let same =
                frame_hash(&check.render(frame).0.expect("linear output is on")) == *full_hash;
            row.exact = Some(row.exact.unwrap_or(true) && same);
            exact &= same;
        }
    }
    set_frame_medians(&mut profile, full_frame_ms, fast_frame_ms);
    let frame_count = frames.end - frames.start;
    // The oracle was timed in the first round, next to its full renders.
    let timed_region_oracle_speedup = full_times[0] / oracle_traced_ms.max(1e-9);
    let (full_ms, accelerated_ms) = (median(full_times), median(fast_times));
    let speedup = full_ms / accelerated_ms;
    // Weighted by the rays each sample costs (see `Oracle::rays`).
    let oracle_speedup = oracle.rays.all as f64 / oracle.rays.samples.max(1) as f64;
    let region_oracle_speedup = oracle.rays.all as f64 / oracle.rays.regions.max(1) as f64;
    SequenceBench {
        frames: frame_count,
        pixels_per_frame,
        full_ms,
        accelerated_ms,
        speedup,
        samples_traced,
        oracle_speedup,
        region_oracle_speedup,
        oracle_rays: oracle.rays,
        timed_region_oracle_speedup,
        efficiency: speedup / oracle_speedup,
        bookkeeping_share: bookkeeping_ms
            / (full_ms / f64::from(frame_count.max(1)))
            / f64::from(frame_count.max(1)),
        exact,
        max_yaw_error_deg: max_yaw_error,
        rounds,
        threads: rayon::current_num_threads(),
        full_reasons,
        profile,
    }
}

/// Experiment E1 of the paper: the paper scene (as given), yawing 3.6
/// degrees per frame for 100 frames, a whole turn.
pub fn e1_scene(mut scene: Scene) -> Scene {
    use crate::timeline::{Animation, CameraKey, Ease};
    let camera = &scene.camera;
    let key = |frame: u32, yaw_deg: f64| CameraKey {
        frame,
        yaw: camera.yaw + yaw_deg.to_radians(),
        pitch: camera.pitch,
        fov: camera.fov,
        position: camera.position,
        ease: Ease::Linear,
    };
    scene.animation = Some(Animation::camera_only(
        100,
        25.0,
        vec![key(0, 0.0), key(100, 360.0)],
    ));
    scene
}

/// A viewport sequence (RSVP) against direct renders of the same viewport
/// frames, with the resampling error measured on an untimed pass.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ViewportSequenceBench {
    pub frames: u32,
    pub viewports: usize,
    pub pixels_per_frame: u64,
    /// The whole sequence of direct renders (each viewport's own rays),
    /// converted to 8 bits, not written.
    pub full_ms: f64,
    /// The RSVP sequence: frame 0, mapping, tracing, resampling, 8 bits.
    pub rsvp_ms: f64,
    pub speedup: f64,
    pub samples_traced: u64,
    pub knobs: crate::reuse::rsvp::RsvpKnobs,
    /// Against the direct renders, over every frame and viewport.
    pub worst_psnr_db: f64,
    pub mean_psnr_db: f64,
    pub max_abs: f32,
    pub mean_abs: f64,
    pub differing_share: f64,
    pub threads: usize,
    /// With OSTC and the error measured: the kept buffer samples re-traced
    /// and compared bit for bit at checkpoints (samples compared, differing).
    pub buffer_check: Option<(u64, u64)>,
    /// Bookkeeping (OSTC recording and merging) over the whole sequence.
    pub bookkeeping_ms: f64,
    pub profile: Vec<FrameProfile>,
}

/// How often (in frames) the E4 check re-traces the whole sample buffer:
/// a stale sample shows up at the next checkpoint unless erased again
/// before it, and every checkpoint costs a retrace of all kept samples.
const BUFFER_CHECK_EVERY: u32 = 20;

/// Renders the viewports of `frames` directly and with RSVP, alternating
/// `rounds` timed runs of each (medians reported, per sequence and per
/// frame), then measures the RSVP frames' error against the direct ones
/// (untimed; skipped with `measure_error` off).
#[allow(clippy::too_many_arguments)]
pub fn bench_viewport_sequence(
    scene: &Scene,
    accel: &mut Accelerator,
    frames: std::ops::Range<u32>,
    rounds: usize,
    knobs: crate::reuse::rsvp::RsvpKnobs,
    measure_error: bool,
    ostc: Option<crate::anim::OstcSettings>,
    mut progress: impl FnMut(),
) -> ViewportSequenceBench {
    use crate::anim::{Animator, Techniques};
    use crate::metrics::image_error;
    let rsvp_only = Techniques {
        rsvp: true,
        ostc: ostc.is_some(),
        ..Techniques::FULL
    };
    let views = scene.viewports.len();
    let mut pixels_per_frame = 0;
    let mut profile = FrameProfile::empty(frames.clone());
    // Untimed: see bench_sequence.
    if views > 0 {
        let mut warm = Animator::new(scene, accel, Techniques::FULL, frames.clone());
        std::hint::black_box(warm.render_viewport_direct(frames.start, 0));
    }
    let rounds = rounds.max(1);
    let (mut full_times, mut fast_times) = (Vec::new(), Vec::new());
    // Per frame and round, for per-frame medians.
    let mut full_frame_ms = vec![Vec::new(); profile.len()];
    let mut fast_frame_ms = vec![Vec::new(); profile.len()];
    // Counts are the same every round: the last round's are kept.
    let mut samples_traced = 0;
    let mut bookkeeping_ms = 0.0;
    for _ in 0..rounds {
        let mut full = Animator::new(scene, accel, Techniques::FULL, frames.clone());
        let mut elapsed = 0.0;
        for (row, frame) in profile.iter_mut().zip(frames.clone()) {
            let start = Instant::now();
            let mut frame_rays = RayCounts::default();
            for index in 0..views {
                let (image, rays) = full.render_viewport_direct(frame, index);
                std::hint::black_box(image.to_rgb8());
                frame_rays += rays;
            }
            let ms = start.elapsed().as_secs_f64() * 1e3;
            full_frame_ms[(frame - frames.start) as usize].push(ms);
            elapsed += ms;
            row.full_rays = frame_rays;
            progress();
        }
        full_times.push(elapsed);
        drop(full);
        let mut fast = Animator::new(scene, accel, rsvp_only, frames.clone());
        fast.set_linear_output(false);
        fast.set_rsvp_knobs(knobs);
        if let Some(settings) = ostc {
            fast.set_ostc(settings);
        }
        let mut elapsed = 0.0;
        (samples_traced, bookkeeping_ms) = (0, 0.0);
        for (row, frame) in profile.iter_mut().zip(frames.clone()) {
            let start = Instant::now();
            let outputs = fast.render_viewports(frame);
            let ms = start.elapsed().as_secs_f64() * 1e3;
            fast_frame_ms[(frame - frames.start) as usize].push(ms);
            elapsed += ms;
            pixels_per_frame = outputs.iter().map(|o| o.stats.pixels).sum();
            (row.accelerated_rays, row.samples_traced, row.bookkeeping_ms) =
                (RayCounts::default(), 0, 0.0);
            (row.accelerated_trace_ms, row.accelerated_copy_ms) = (0.0, 0.0);
            for output in &outputs {
                let stats = &output.stats;
                row.accelerated_rays += RayCounts {
                    primary: stats.primary_rays,
                    shadow: stats.shadow_rays,
                    reflection: stats.reflection_rays,
                };
                row.samples_traced += stats.samples_traced;
                row.bookkeeping_ms += stats.bookkeeping_ms;
                row.accelerated_trace_ms += stats.trace_ms;
                row.accelerated_copy_ms += stats.copy_ms;
            }
            // Frame-wide OSTC figures repeat on every viewport's stats.
            if let Some(first) = outputs.first() {
                row.dirty_regions = first.stats.dirty_regions;
                row.samples_nulled = first.stats.samples_nulled;
            }
            samples_traced += row.samples_traced;
            bookkeeping_ms += row.bookkeeping_ms;
            std::hint::black_box(outputs);
            progress();
        }
        fast_times.push(elapsed);
    }
    set_frame_medians(&mut profile, full_frame_ms, fast_frame_ms);
    let (full_ms, rsvp_ms) = (median(full_times), median(fast_times));
    let mut errors = Vec::new();
    let mut buffer_check = None;
    if measure_error {
        let mut check = Animator::new(scene, accel, rsvp_only, frames.clone());
        check.set_rsvp_knobs(knobs);
        if let Some(settings) = ostc {
            check.set_ostc(settings);
        }
        for (row, frame) in profile.iter_mut().zip(frames.clone()) {
            let mut worst = f64::INFINITY;
            for (index, output) in check.render_viewports(frame).into_iter().enumerate() {
                let (reference, _) = check.render_viewport_direct(frame, index);
                let image = output.frame.expect("linear output is on");
                let error = image_error(&image, &reference);
                worst = worst.min(error.psnr_db);
                errors.push(error);
            }
            row.psnr_db = Some(worst);
            let last = frame + 1 == frames.end;
            if ostc.is_some() && (last || (frame - frames.start + 1) % BUFFER_CHECK_EVERY == 0) {
                if let Some((compared, differing)) = check.verify_sample_buffer() {
                    let (c, d) = buffer_check.unwrap_or((0, 0));
                    buffer_check = Some((c + compared, d + differing));
                }
            }
            progress();
        }
    }
    let count = errors.len().max(1) as f64;
    ViewportSequenceBench {
        frames: frames.end - frames.start,
        viewports: views,
        pixels_per_frame,
        full_ms,
        rsvp_ms,
        speedup: full_ms / rsvp_ms,
        samples_traced,
        knobs,
        worst_psnr_db: errors
            .iter()
            .map(|e| e.psnr_db)
            .fold(f64::INFINITY, f64::min),
        mean_psnr_db: errors.iter().map(|e| e.psnr_db.min(100.0)).sum::<f64>() / count,
        max_abs: errors.iter().map(|e| e.max_abs).fold(0.0, f32::max),
        mean_abs: errors.iter().map(|e| e.mean_abs).sum::<f64>() / count,
        differing_share: errors.iter().map(|e| e.differing_share).sum::<f64>() / count,
        threads: rayon::current_num_threads(),
        buffer_check,
        bookkeeping_ms,
        profile,
    }
}

/// Which way experiment E2 zooms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ZoomDirection {
    /// 100 -> 50 degrees.
    In,
    /// 50 -> 100 degrees.
    Out,
}

/// Zoom that narrows a 100-degree perspective view to 50 degrees (the
/// paper's 2:1 in angle).
pub const E2_ZOOM: f64 = 2.555_723_8;

/// Experiment E2 of the paper: one perspective viewport of the camera's
/// size (640x480 in the paper scene), 100 deg
/// wide at zoom 1, zooming between 100 and 50 degrees over 100 frames (a
/// steady rate) on the paper scene's camera buffer; with `pan_deg_per_frame`
/// the camera also yaws (E4 without the moving ball).
pub fn e2_scene(mut scene: Scene, direction: ZoomDirection, pan_deg_per_frame: f64) -> Scene {
    use crate::camera::{ViewTransform, Viewport};
    use crate::timeline::{Animation, CameraKey, Ease, ViewportKey, ViewportTrack};
    let (from, to) = match direction {
        ZoomDirection::In => (1.0, E2_ZOOM),
        ZoomDirection::Out => (E2_ZOOM, 1.0),
    };
    let key = |frame: u32, zoom: f64| ViewportKey {
        frame,
        transform: ViewTransform {
            zoom,
            ..ViewTransform::default()
        },
        ease: Ease::Linear,
    };
    scene.viewports = vec![ViewportTrack {
        viewport: Viewport {
            name: "zoom".into(),
            width: scene.camera.width,
            height: scene.camera.height,
            projection: crate::camera::Projection::Perspective,
            fov: 100f64.to_radians(),
            yaw: 0.0,
            pitch: 0.0,
            transform: ViewTransform::default(),
        },
        keys: vec![key(0, from), key(99, to)],
    }];
    let camera = &scene.camera;
    let camera_key = |frame: u32| CameraKey {
        frame,
        yaw: camera.yaw + (pan_deg_per_frame * f64::from(frame)).to_radians(),
        pitch: camera.pitch,
        fov: camera.fov,
        position: camera.position,
        ease: Ease::Linear,
    };
    scene.animation = Some(Animation {
        frames: 100,
        fps: 25.0,
        camera_keys: vec![camera_key(0), camera_key(100)],
        objects: Vec::new(),
        lights: Vec::new(),
    });
    scene
}

/// Camera yaw per frame in E4 (E1's pan: a whole turn in 100 frames).
pub const E4_PAN_DEG_PER_FRAME: f64 = 3.6;

/// Experiment E4 on a scene whose own timeline moves objects or lights:
/// E2's viewport zooming in while the camera pans as in E1, the scene's
/// motion kept (`scenes/paper-all.toml` is this on the paper scene with a
/// bouncing ball).
pub fn e4_scene(mut scene: Scene) -> Scene {
    let motion = scene.animation.take();
    let mut scene = e2_scene(scene, ZoomDirection::In, E4_PAN_DEG_PER_FRAME);
    if let (Some(animation), Some(motion)) = (scene.animation.as_mut(), motion) {
        animation.objects = motion.objects;
        animation.lights = motion.lights;
    }
    scene
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::render_view;
    use crate::scene::{paper_scene, SceneOverrides};
    use crate::shade::Shader;

    /// The paper scene at 64x48: a full render, its ray counts, and the
    /// rays of each pixel.
    fn small_paper_traced() -> (Scene, crate::render::Frame, RayCounts, Vec<u32>) {
        let scene = paper_scene(&SceneOverrides {
            width: Some(64),
            height: Some(48),
            ..SceneOverrides::default()
        })
        .unwrap();
        let accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
        let (frame, counts) = render_view(&scene, &scene.camera, &accel);
        let rays = rays_per_pixel(&Shader::new(&scene, &accel), &scene.camera);
        (scene, frame, counts, rays)
    }

    /// E4 built on the bouncing-ball scene is `scenes/paper-all.toml`'s
    /// timeline: the same camera and viewport at every frame, the scene's
    /// own bounce kept (so `bench --scaling` runs the same E4 on bunnies).
    #[test]
    fn e4_on_a_moving_scene_is_paper_all_s_pan_and_zoom_over_its_motion() {
        let overrides = SceneOverrides::default();
        let bouncing = crate::lab::tradeoff::bouncing_ball_scene(&overrides).unwrap();
        let bounce = bouncing.animation.clone().unwrap().objects;
        assert!(!bounce.is_empty());
        let built = e4_scene(bouncing);
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper-all.toml");
        let paper_all = crate::scene::load_scene(&path, &overrides).unwrap();
        let (ours, theirs) = (
            built.animation.as_ref().unwrap(),
            paper_all.animation.as_ref().unwrap(),
        );
        assert_eq!(ours.objects, bounce);
        assert!(ours.moves_scene());
        assert_eq!((ours.frames, built.viewports.len()), (theirs.frames, 1));
        for frame in 0..ours.frames {
            let (a, b) = (
                ours.camera_at(&built.camera, frame),
                theirs.camera_at(&paper_all.camera, frame),
            );
            assert!((a.yaw - b.yaw).abs() < 1e-9, "frame {frame}: yaw");
            assert_eq!((a.pitch, a.fov, a.position), (b.pitch, b.fov, b.position));
            let (a, b) = (&built.viewports[0], &paper_all.viewports[0]);
            assert_eq!(
                (a.viewport.width, a.viewport.height, a.viewport.fov),
                (b.viewport.width, b.viewport.height, b.viewport.fov)
            );
            let (za, zb) = (a.transform_at(frame).zoom, b.transform_at(frame).zoom);
            assert!((za - zb).abs() < 1e-9, "frame {frame}: zoom {za} {zb}");
        }
    }

    #[test]
    fn rays_per_pixel_add_up_to_the_full_render() {
        let (_, _, counts, rays) = small_paper_traced();
        assert_eq!(rays.len(), 64 * 48);
        assert!(
            rays.iter().all(|&r| r >= 1),
            "every pixel traces its primary ray"
        );
        let sum: u64 = rays.iter().map(|&r| u64::from(r)).sum();
        assert_eq!(sum, counts.total());
        // Mirrors and lit surfaces cost more than the sky: the weights vary.
        assert!(rays.iter().max() > rays.iter().min());
    }

    #[test]
    fn the_oracle_weighs_changed_samples_by_their_rays() {
        let (scene, frame, _, rays) = small_paper_traced();
        let all: u64 = rays.iter().map(|&r| u64::from(r)).sum();
        let mut oracle = Oracle::new((16, 8));
        // The first frame shows every sample for the first time.
        assert_eq!(oracle.add(&scene.camera, &frame, &rays), (64 * 48, 64 * 48));
        assert_eq!(
            oracle.rays,
            OracleRays {
                all,
                samples: all,
                regions: all
            }
        );
        // The same frame again: nothing to trace.
        assert_eq!(oracle.add(&scene.camera, &frame, &rays), (0, 0));
        // One changed pixel: its rays, and its whole region's.
        let mut changed = frame.clone();
        let pixel = 20 * 64 + 37;
        changed.pixels[pixel] += glam::Vec3::splat(0.25);
        assert_eq!(oracle.add(&scene.camera, &changed, &rays), (1, 16 * 8));
        assert_eq!(oracle.rays.all, 3 * all);
        assert_eq!(oracle.rays.samples, all + u64::from(rays[pixel]));
        let region_rays = oracle.rays.regions - all;
        assert!(region_rays >= 16 * 8 && region_rays > u64::from(rays[pixel]));
    }

    #[test]
    fn off_the_lattice_the_oracle_keeps_a_still_cameras_pixels() {
        let (scene, frame, _, rays) = small_paper_traced();
        let perspective = crate::camera::Camera {
            projection: crate::camera::Projection::Perspective,
            ..scene.camera.clone()
        };
        let mut oracle = Oracle::new((16, 8));
        assert_eq!(oracle.add(&perspective, &frame, &rays), (64 * 48, 64 * 48));
        assert_eq!(oracle.add(&perspective, &frame, &rays), (0, 0));
        // Pixel (37, 20): its region is columns 32..48, rows 16..24.
        let mut changed = frame.clone();
        changed.pixels[20 * 64 + 37] += glam::Vec3::splat(0.25);
        assert_eq!(oracle.add(&perspective, &changed, &rays), (1, 16 * 8));
        // A moved camera shows every pixel anew.
        let turned = crate::camera::Camera {
            yaw: perspective.yaw + 0.1,
            ..perspective
        };
        assert_eq!(oracle.add(&turned, &changed, &rays), (64 * 48, 64 * 48));
    }

    #[test]
    fn the_timed_region_oracle_traces_exactly_the_changed_regions_groups() {
        use crate::render::SampleGroup;
        let (scene, frame, _, rays) = small_paper_traced();
        let mut oracle = Oracle::new((16, 8));
        oracle.add(&scene.camera, &frame, &rays);
        // Frame 0: the whole frame.
        assert_eq!(
            oracle.region_groups(64),
            SampleGroup::covering(0..64, 0..48)
        );
        oracle.add(&scene.camera, &frame, &rays);
        assert!(oracle.region_groups(64).is_empty());
        // Pixel (37, 20) lies in the region of columns 32..48, rows 16..24
        // (the window starts on the lattice's region grid here).
        let mut changed = frame.clone();
        changed.pixels[20 * 64 + 37] += glam::Vec3::splat(0.25);
        oracle.add(&scene.camera, &changed, &rays);
        let groups = oracle.region_groups(64);
        let region: Vec<(i64, i64)> = groups.iter().map(|g| (g.col, g.row)).collect();
        let lattice = crate::reuse::pan::EqualAngleLattice::for_camera(&scene.camera);
        let window = lattice.window(&scene.camera);
        let (c0, r0) = (window.col.rem_euclid(16), window.row.rem_euclid(8));
        let expected: Vec<(i64, i64)> = SampleGroup::covering(
            (37 - (37 + c0) % 16)..(37 - (37 + c0) % 16 + 16),
            (20 - (20 + r0) % 8)..(20 - (20 + r0) % 8 + 8),
        )
        .iter()
        .map(|g| (g.col, g.row))
        .collect();
        assert_eq!(region, expected);
    }
}

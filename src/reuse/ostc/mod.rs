//! OSTC: Jevans' object space temporal coherence, as Gage & Semwal use it.
//!
//! The sample buffer is cut into rectangular *regions* (by default a
//! 160x160 screen grid: 4x4 samples at 640x480; the paper's 16x16 grid of 40x30
//! is `RegionGrid::PAPER`), fixed in buffer coordinates so a pan does not
//! invalidate them. A uniform voxel grid over the volume the
//! animated objects sweep through keeps, per voxel, one bit per region: set
//! when a ray traced for a sample of that region (primary, reflection or
//! shadow) crossed the voxel. When an object moves, the union of the bits
//! of the voxels under its old and its new bounds names every region whose
//! samples could change ("dirty"); those are erased to null and re-traced.
//!
//! The voxel bits only name candidates: each region also keeps the
//! segments of its recorded rays that enter the grid, and a candidate is
//! dirty only if one of those segments meets the object's old or new
//! footprint itself. Voxels round every footprint out to whole voxels (on
//! E3, a ring of regions around the ball, its shadows and reflections that
//! never changed); the segment test does not.
//!
//! Each segment also names the sample group whose ray it is, so a buffer
//! whose regions hold many groups (RSVP's pyramid: a region of level-0
//! samples holds 4^k times as many on level k) erases just the groups
//! whose own rays meet a moving object ([`Ostc::dirty_groups_for`]): far
//! fewer samples are nulled than whole regions hold, and the images are
//! bit for bit the same.
//!
//! Promises:
//! - Conservative: every sample whose colour can change lies in a dirty
//!   region. Bounds are rounded outward, walks are supercover walks that
//!   end a little past the hit, shadow rays count to the light (an
//!   occlusion query finds *a* blocker, not the nearest), misses count to
//!   the grid's exit. A segment counts as meeting a footprint within a
//!   slack well above the rounding of the hit and of the posed object.
//! - Bits are never lost early: a region's bits are cleared only when the
//!   region is erased (all its samples nulled) or its last recorded ray is
//!   forgotten with its group, and the re-traced samples set them again.
//!   A region that keeps some groups keeps all its voxel and light bits, a
//!   superset of what its rays crossed (they only pick candidates).
//! - Nothing is built that the timeline does not need: no voxel grid when
//!   no object moves, no per-region light bookkeeping when no light moves.
//!
//! A light that moves dirties every region with a sample whose primary ray
//! hit a surface: without attenuation any lit or unlit surface may change
//! when a point light moves (N.L <= 0 included, since a surface can turn
//! toward it), so only the background is safe. A light that only changes
//! colour or intensity dirties just the regions where one of its shadow
//! rays got through (kept per animated light): a sample it did not light
//! before, it does not light now.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

use crate::geometry::Aabb;
use crate::voxel::{GridSpec, GridWalker};
use glam::Vec3;
use rayon::prelude::*;

use crate::ray::{lanes, LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::render::SampleGroup;
use crate::reuse::regions::{RegionLayout, RegionSet};
use crate::reuse::{Idle, Run};

/// Why OSTC cannot act on `run`, whether asked for or not.
pub fn idle_reason(run: &Run) -> Option<Idle> {
    if !run
        .scene
        .animation
        .as_ref()
        .is_some_and(|a| a.moves_scene())
    {
        Some(Idle::NothingMoves)
    } else if run.has_viewports() && !run.options.techniques.rsvp {
        Some(Idle::ViewportsWithoutRsvp)
    } else {
        None
    }
}

mod footprint;

use crate::rng::SplitMix64;
use crate::shade::{RayKind, RayObserver};
pub use footprint::Footprint;
use footprint::Reach;

/// The voxel grid and its per-voxel region bits.
struct VoxelBits {
    spec: GridSpec,
    walker: GridWalker,
    /// `words` planes of one u64 per voxel, plane-major: a walk marks one
    /// plane (its region's), whose voxels lie side by side in memory.
    bits: Vec<AtomicU64>,
    voxel_count: usize,
    /// Per region, the recorded rays that enter the grid, as walked (`tmin`
    /// to the walk's end): what refines the voxels' candidates. Filled by
    /// the markers of the region's groups (one lock per group), emptied
    /// with the region's bits.
    segments: Vec<Mutex<Vec<RecordedSegment>>>,
}

/// One recorded ray inside the grid: `tmin` to the walk's end (its hit or
/// `tmax`, plus [`WALK_END_SLACK`]).
#[derive(Clone, Copy, Debug)]
struct RecordedSegment {
    ray: Ray,
    /// A shadow ray: only whether something blocks it matters.
    shadow: bool,
    /// The sample group whose rays it is (a key of the buffer's choosing:
    /// see [`Ostc::marker_in`]).
    group: PackedKey,
}

/// The most bits a group's key may have.
pub const GROUP_KEY_BITS: u32 = 96;

/// A group key in three words: a segment stays 48 bytes, where a u128
/// would align it to 64, and recording is bound by memory traffic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PackedKey([u32; 3]);

impl PackedKey {
    fn new(key: u128) -> PackedKey {
        assert!(key >> GROUP_KEY_BITS == 0, "group key {key:#x} too wide");
        PackedKey([key as u32, (key >> 32) as u32, (key >> 64) as u32])
    }

    fn key(self) -> u128 {
        let [low, mid, high] = self.0.map(u128::from);
        low | mid << 32 | high << 64
    }
}

impl RecordedSegment {
    /// Whether moving an object from and to `volumes` (its places, each a
    /// bound of it) can change what this ray found.
    ///
    /// A ray that meets none of them found what it found before (see
    /// [`Ostc::dirty_for`]). A shadow ray's one result is whether anything
    /// blocks it: if the object surely blocks it at every place (the
    /// footprint is the object's own exact shape and the segment runs
    /// through it well inside), it was blocked and still is, whatever else
    /// lies on it. On E3 that spares the core of the ball's shadows, where
    /// both the old and the new ball block the way to the light.
    fn may_change(&self, volumes: &[Footprint], reach: &Reach) -> bool {
        reach.may_meet(&self.ray)
            && volumes.iter().any(|volume| volume.meets_segment(&self.ray))
            && !(self.shadow && volumes.iter().all(|volume| volume.surely_blocks(&self.ray)))
    }
}

/// A walk ends this far (relative to its length) past the hit, so the voxel
/// the hit lies in always counts whatever the rounding of `t`.
const WALK_END_SLACK: f32 = 1e-4;

/// The OSTC bookkeeping of one sample buffer.
pub struct Ostc {
    layout: RegionLayout,
    voxels: Option<VoxelBits>,
    /// Regions with a sample whose primary ray hit something; kept only
    /// when a light is animated.
    hit: Option<Vec<AtomicU64>>,
    /// Per light, for animated lights only: regions with a sample one of
    /// whose shadow rays to that light got through.
    lit_by: Vec<Option<Vec<AtomicU64>>>,
    counters: RecordCounters,
}

/// What recording cost, summed by every marker as it finishes. On a cache
/// line of its own: beside the fields every traced packet reads, each add
/// would take that line away from the other workers.
#[repr(align(128))]
#[derive(Default)]
struct RecordCounters {
    voxels_walked: AtomicU64,
    record_nanos: AtomicU64,
}

/// Default voxel count of the OSTC grid. The dirty regions do not depend
/// on it: the recorded segments decide, the voxels only pick the candidate
/// regions, and testing every recorded segment of a frame's candidates
/// costs less than walking rays through finer voxels. One voxel needs no
/// walk at all.
pub const DEFAULT_VOXELS: u32 = 1;

impl Ostc {
    /// The bytes [`Ostc::new`] would allocate for `regions` regions and a
    /// grid of about `voxels` voxels (when an object moves), before the
    /// rays recorded into it: known before allocating them.
    pub fn bytes_for(regions: usize, voxels: u32, objects_move: bool) -> f64 {
        let words = regions.div_ceil(64) as f64;
        let light_sets = 2.0 * words * 8.0;
        if !objects_move {
            return light_sets;
        }
        let per_region = std::mem::size_of::<Mutex<Vec<RecordedSegment>>>() as f64;
        // A grid asked for N voxels rounds each axis, up to about twice N.
        let grid = 2.0 * f64::from(voxels.max(1)) * words * 8.0;
        light_sets + regions as f64 * per_region + grid
    }

    /// The bytes of the segments recorded for `samples` samples traced:
    /// only rays that cross a moving object's swept bounds are recorded,
    /// about one in four samples' on the paper's bouncing ball (a scene
    /// whose moving objects fill the screen records more).
    pub fn recorded_bytes(samples: f64) -> f64 {
        samples / 4.0 * std::mem::size_of::<RecordedSegment>() as f64
    }

    /// Bookkeeping for a buffer tiled by `layout`: a grid of about `voxels`
    /// voxels over `swept` (the bounds every animated object passes through
    /// over the whole animation; None when no object moves), and the light
    /// bookkeeping for the lights flagged in `animated_lights` (one flag
    /// per scene light).
    pub fn new(
        layout: RegionLayout,
        swept: Option<Aabb>,
        voxels: u32,
        animated_lights: &[bool],
    ) -> Ostc {
        let words = layout.count().div_ceil(64);
        let voxels = swept
            .filter(|b| !b.is_empty() && b.is_finite())
            .map(|bounds| {
                let mut spec = GridSpec::with_cell_budget(bounds, f64::from(voxels.max(1)));
                // The budget rounds per axis (1 asked over a tall box gives
                // 1x2x1): one voxel asked for is one voxel, whose marking
                // needs no walk.
                if voxels <= 1 {
                    spec.resolution = [1, 1, 1];
                }
                VoxelBits {
                    bits: (0..spec.voxel_count() * words)
                        .map(|_| AtomicU64::new(0))
                        .collect(),
                    voxel_count: spec.voxel_count(),
                    walker: spec.walker(),
                    segments: (0..layout.count()).map(|_| Mutex::default()).collect(),
                    spec,
                }
            });
        Ostc {
            layout,
            voxels,
            hit: animated_lights.contains(&true).then(|| atomic_words(words)),
            lit_by: animated_lights
                .iter()
                .map(|&animated| animated.then(|| atomic_words(words)))
                .collect(),
            counters: RecordCounters::default(),
        }
    }

    pub fn layout(&self) -> &RegionLayout {
        &self.layout
    }

    pub fn grid(&self) -> Option<&GridSpec> {
        self.voxels.as_ref().map(|v| &v.spec)
    }

    /// What a group's rays are recorded through, for a buffer that erases
    /// whole regions (every group under one key: the pan buffer's regions
    /// are a few groups each, two at the default size).
    pub fn marker(&self, group: SampleGroup) -> RegionMarker<'_> {
        self.marker_in(self.layout.region_of(group.col, group.row), 0)
    }

    /// What the rays of the sample group named `group` (a key the buffer
    /// chooses, unique among its groups and at most [`GROUP_KEY_BITS`]
    /// wide, for [`Ostc::dirty_groups_for`]), lying in `region`, are
    /// recorded through.
    pub fn marker_in(&self, region: usize, group: u128) -> RegionMarker<'_> {
        assert!(
            region < self.layout.count(),
            "region {region} outside the layout"
        );
        RegionMarker {
            ostc: self,
            region,
            group: PackedKey::new(group),
            walked: 0,
            nanos: 0,
            recent: [0; RECENT_SLOTS],
            segments: SPARE_SEGMENTS.with(|spare| spare.take()),
        }
    }

    /// Regions with a recorded ray that meets one of `volumes` (an
    /// object's old and new place), rounded outward.
    ///
    /// Why this is enough: a ray's result depends only on the geometry
    /// along the segment it was walked over (to its hit and a little past
    /// it; to the light for shadow rays, since an occlusion query may stop
    /// at any blocker; to the grid's exit for misses). An object that
    /// neither was nor is on that segment leaves the ray's hit, and so its
    /// shading and the rays it spawns, exactly as they were; by induction
    /// over the sample's rays, a sample none of whose rays meets `volumes`
    /// keeps its colour bit for bit. The voxels only pick the regions worth
    /// testing: a segment that meets a footprint crosses a voxel the
    /// footprint overlaps (the walk is a supercover, the voxel range and
    /// the footprints are rounded outward).
    pub fn dirty_for(&self, volumes: &[Footprint]) -> RegionSet {
        let candidates: Vec<usize> = self.candidates_for(volumes).iter().collect();
        let reach = Reach::around(volumes);
        // Testing the segments is most of the bookkeeping, and regions are
        // independent: they are tested in parallel.
        let found: Vec<usize> = candidates
            .into_par_iter()
            .filter(|&region| {
                self.with_segments(region, |all| {
                    all.iter().any(|s| s.may_change(volumes, &reach))
                })
            })
            .collect();
        let mut dirty = RegionSet::empty(self.layout.count());
        for region in found {
            dirty.insert(region);
        }
        dirty
    }

    /// The groups (by the keys their markers were given) with a recorded
    /// ray that meets one of `volumes`, sorted, and the regions they lie
    /// in: the same test as [`Ostc::dirty_for`], one group at a time. A
    /// region of a pyramid's level-0 samples holds 4^k times as many
    /// samples on level k, nearly all of them untouched.
    pub fn dirty_groups_for(&self, volumes: &[Footprint]) -> (RegionSet, Vec<u128>) {
        let candidates: Vec<usize> = self.candidates_for(volumes).iter().collect();
        let reach = Reach::around(volumes);
        // Every segment of a dirty region is tested, the bulk of the work:
        // one region per task.
        let found: Vec<(usize, Vec<u128>)> = candidates
            .into_par_iter()
            .filter_map(|region| {
                let mut groups = Vec::new();
                self.with_segments(region, |all| {
                    // A group's segments come in one run (its marker adds
                    // them at once): once one may change, skip the rest.
                    for run in all.chunk_by(|a, b| a.group == b.group) {
                        if run.iter().any(|s| s.may_change(volumes, &reach)) {
                            groups.push(run[0].group.key());
                        }
                    }
                });
                (!groups.is_empty()).then_some((region, groups))
            })
            .collect();
        let mut regions = RegionSet::empty(self.layout.count());
        let mut groups = Vec::new();
        for (region, mine) in found {
            regions.insert(region);
            groups.extend(mine);
        }
        groups.sort_unstable();
        groups.dedup();
        (regions, groups)
    }

    /// `f` of the recorded segments of `region` (none without a grid).
    fn with_segments<R>(&self, region: usize, f: impl FnOnce(&[RecordedSegment]) -> R) -> R {
        match &self.voxels {
            Some(voxels) => f(&voxels.segments[region]
                .lock()
                .unwrap_or_else(PoisonError::into_inner)),
            None => f(&[]),
        }
    }

    /// The regions whose voxel bits say a recorded ray may meet `volumes`
    /// (rounded outward).
    fn candidates_for(&self, volumes: &[Footprint]) -> RegionSet {
        let mut candidates = RegionSet::empty(self.layout.count());
        let Some(voxels) = &self.voxels else {
            return candidates;
        };
        for volume in volumes {
            let bounds = padded_outward(volume.bounds());
            let Some([first, last]) = voxels.spec.voxel_range(&bounds) else {
                continue;
            };
            for k in first[2]..=last[2] {
                for j in first[1]..=last[1] {
                    for i in first[0]..=last[0] {
                        if !volume.may_touch(&voxels.spec.voxel_bounds([i, j, k])) {
                            continue;
                        }
                        let voxel = voxels.spec.linear_index([i, j, k]);
                        for (word, bits) in candidates.words_mut().iter_mut().enumerate() {
                            *bits |= voxels.bits[word * voxels.voxel_count + voxel]
                                .load(Ordering::Relaxed);
                        }
                    }
                }
            }
        }
        candidates
    }

    /// Regions light number `light` can change: if it `moved`, every
    /// region with a surface hit, else (a new colour or intensity) the
    /// regions it lit (see the module notes).
    pub fn dirty_for_light(&self, light: usize, moved: bool) -> RegionSet {
        let mut dirty = RegionSet::empty(self.layout.count());
        let tracked = if moved {
            self.hit.as_ref()
        } else {
            self.lit_by.get(light).and_then(Option::as_ref)
        };
        match tracked {
            Some(words) => dirty.union_atomic(words),
            // Not tracked: every region may change.
            None => (0..self.layout.count()).for_each(|r| dirty.insert(r)),
        }
        dirty
    }

    /// Clears the bits of `regions`, whose samples have all been nulled.
    pub fn forget(&mut self, regions: &RegionSet) {
        if regions.is_empty() {
            return;
        }
        let keep: Vec<u64> = regions.words().iter().map(|w| !w).collect();
        if let Some(voxels) = &mut self.voxels {
            let planes = voxels.bits.chunks_mut(voxels.voxel_count);
            for (plane, keep) in planes.zip(&keep).filter(|(_, &keep)| keep != u64::MAX) {
                for bits in plane {
                    *bits.get_mut() &= keep;
                }
            }
            for region in regions.iter() {
                voxels.segments[region]
                    .get_mut()
                    .unwrap_or_else(PoisonError::into_inner)
                    .clear();
            }
        }
        let light_sets = self.lit_by.iter_mut().flatten();
        for set in self.hit.iter_mut().chain(light_sets) {
            for (bits, keep) in set.iter_mut().zip(&keep) {
                *bits.get_mut() &= keep;
            }
        }
    }

    /// Drops the recorded rays of `groups` (sorted keys), whose samples
    /// have all been nulled, from `regions` (where they lie). A region left
    /// without recorded rays loses its voxel bits too; one that keeps some
    /// keeps all its bits, a superset of its rays' voxels (they only pick
    /// candidates), as it keeps its light bits (a superset too).
    pub fn forget_groups(&mut self, regions: &RegionSet, groups: &[u128]) {
        let Some(voxels) = &mut self.voxels else {
            return;
        };
        let mut emptied = RegionSet::empty(self.layout.count());
        for region in regions.iter() {
            let segments = voxels.segments[region]
                .get_mut()
                .unwrap_or_else(PoisonError::into_inner);
            // A group's segments come in one run: one search per run.
            let mut run: Option<(PackedKey, bool)> = None;
            segments.retain(|s| match run {
                Some((group, keep)) if group == s.group => keep,
                _ => {
                    let keep = groups.binary_search(&s.group.key()).is_err();
                    run = Some((s.group, keep));
                    keep
                }
            });
            if segments.is_empty() {
                emptied.insert(region);
            }
        }
        let planes = voxels.bits.chunks_mut(voxels.voxel_count);
        for (plane, &gone) in planes.zip(emptied.words()).filter(|(_, &gone)| gone != 0) {
            for bits in plane {
                *bits.get_mut() &= !gone;
            }
        }
    }

    /// Voxel visits and recording time (estimated from one packet in
    /// `TIMED_EVERY`) since the last call, then zeroes them.
    pub fn take_counters(&self) -> (u64, f64) {
        (
            self.counters.voxels_walked.swap(0, Ordering::Relaxed),
            self.counters.record_nanos.swap(0, Ordering::Relaxed) as f64 * 1e-6,
        )
    }
}

fn atomic_words(count: usize) -> Vec<AtomicU64> {
    (0..count).map(|_| AtomicU64::new(0)).collect()
}

/// Grows a box by a little relative to its size and position: covers the
/// rounding of transformed bounds.
fn padded_outward(b: Aabb) -> Aabb {
    let magnitude = b.min.abs().max(b.max.abs()).max_element();
    let pad = (b.extent().max_element() * 1e-4).max(magnitude * 1e-5);
    Aabb {
        min: b.min - Vec3::splat(pad),
        max: b.max + Vec3::splat(pad),
    }
}

/// Records the rays of one sample group into its region's bits.
pub struct RegionMarker<'a> {
    ostc: &'a Ostc,
    region: usize,
    group: PackedKey,
    walked: u64,
    nanos: u64,
    /// Voxels (index + 1) this group marked lately, direct-mapped: the
    /// rays of one group cross mostly the same voxels, and a hit here
    /// skips the shared bit array.
    recent: [u32; RECENT_SLOTS],
    /// The group's rays that entered the grid, as walked: added to the
    /// region's list once, when the marker is done.
    segments: Vec<RecordedSegment>,
}

const RECENT_SLOTS: usize = 64;

/// Recording is timed on one crossing packet in this many (see
/// [`RegionMarker::traced`]).
const TIMED_EVERY: u64 = 8;

thread_local! {
    /// An empty list with room, for this thread's next marker: a group's
    /// rays record dozens of segments, and growing a fresh list for each
    /// group would reallocate it several times.
    static SPARE_SEGMENTS: std::cell::Cell<Vec<RecordedSegment>> = const { std::cell::Cell::new(Vec::new()) };
    /// This thread's draws of which recorded packet to time.
    static TIMING_DRAW: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

impl RayObserver for RegionMarker<'_> {
    fn traced(
        &mut self,
        kind: RayKind,
        rays: &RayPacket,
        mask: LaneMask,
        ends: &[f32; PACKET_WIDTH],
    ) {
        let word = self.region / 64;
        let bit = 1u64 << (self.region % 64);
        match kind {
            RayKind::Primary => {
                if let Some(hit) = &self.ostc.hit {
                    if lanes(mask).any(|lane| ends[lane] < rays[lane].tmax) {
                        hit[word].fetch_or(bit, Ordering::Relaxed);
                    }
                }
            }
            RayKind::Shadow { light, blocked } => {
                if let Some(Some(lit)) = self.ostc.lit_by.get(light) {
                    if mask & !blocked != 0 {
                        lit[word].fetch_or(bit, Ordering::Relaxed);
                    }
                }
            }
            RayKind::Reflection | RayKind::Refraction => {}
        }
        let Some(voxels) = &self.ostc.voxels else {
            return;
        };
        // The box test alone decides most rays (those nowhere near the
        // moving objects): it is not timed, the walks and marks are.
        let ends: [f32; PACKET_WIDTH] =
            std::array::from_fn(|lane| ends[lane] + ends[lane].abs() * WALK_END_SLACK);
        let crossing = voxels.spec.bounds.crossing_lanes(rays, mask, &ends);
        if crossing == 0 {
            return;
        }
        // One crossing packet in TIMED_EVERY, picked at random (a fixed
        // period could keep landing on one kind of ray), is timed and the
        // sum scaled: two clock reads on every packet would be a visible
        // share of a steady frame.
        let start = TIMING_DRAW.with(|state| {
            let mut draw = SplitMix64(state.get());
            let timed = draw.next_u64() % TIMED_EVERY == 0;
            state.set(draw.0);
            timed.then(Instant::now)
        });
        let shadow = matches!(kind, RayKind::Shadow { .. });
        let plane = &voxels.bits[word * voxels.voxel_count..(word + 1) * voxels.voxel_count];
        if voxels.voxel_count == 1 {
            // One voxel, the whole grid: every lane the box test lets
            // through may cross it (a superset of what the walk would
            // find, so still conservative), and no walk is needed.
            self.walked += u64::from(crossing.count_ones());
            if plane[0].load(Ordering::Relaxed) & bit == 0 {
                plane[0].fetch_or(bit, Ordering::Relaxed);
            }
        }
        for lane in lanes(crossing) {
            let ray = &rays[lane];
            let (origin, dir, t0, t1) = (ray.origin, ray.dir, ray.tmin, ends[lane]);
            self.segments.push(RecordedSegment {
                ray: Ray {
                    origin,
                    dir,
                    tmin: t0,
                    tmax: t1,
                    time: ray.time,
                },
                shadow,
                group: self.group,
            });
            if voxels.voxel_count == 1 {
                continue;
            }
            voxels.walker.for_each_index(origin, dir, t0, t1, |index| {
                self.walked += 1;
                let slot = index % RECENT_SLOTS;
                if self.recent[slot] == index as u32 + 1 {
                    return;
                }
                self.recent[slot] = index as u32 + 1;
                // Most voxels are marked already: a load is cheaper than a
                // read-modify-write on a shared cache line.
                if plane[index].load(Ordering::Relaxed) & bit == 0 {
                    plane[index].fetch_or(bit, Ordering::Relaxed);
                }
            });
        }
        if let Some(start) = start {
            self.nanos += start.elapsed().as_nanos() as u64 * TIMED_EVERY;
        }
    }
}

impl Drop for RegionMarker<'_> {
    fn drop(&mut self) {
        if !self.segments.is_empty() {
            if let Some(voxels) = &self.ostc.voxels {
                voxels.segments[self.region]
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .append(&mut self.segments);
            }
            SPARE_SEGMENTS.with(|spare| spare.set(std::mem::take(&mut self.segments)));
        }
        // Most groups' rays pass nowhere near the grid: nothing to add.
        if self.walked == 0 && self.nanos == 0 {
            return;
        }
        self.ostc
            .counters
            .voxels_walked
            .fetch_add(self.walked, Ordering::Relaxed);
        self.ostc
            .counters
            .record_nanos
            .fetch_add(self.nanos, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::Ray;
    use proptest::prelude::{prop_oneof, Just};

    fn layout() -> RegionLayout {
        RegionLayout::new(
            crate::reuse::regions::RegionGrid(16).region_size(640, 480),
            2304,
            10,
            482,
        )
    }

    #[test]
    fn rays_mark_the_voxels_they_cross_and_moves_dirty_their_regions() {
        let swept = Aabb {
            min: Vec3::new(-1.0, 0.0, -1.0),
            max: Vec3::new(1.0, 2.0, 1.0),
        };
        let mut ostc = Ostc::new(layout(), Some(swept), 4096, &[false]);
        let group = SampleGroup { col: 44, row: 40 };
        let region = ostc.layout().region_of(44, 40);
        {
            let mut marker = ostc.marker(group);
            let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
            // Through the middle of the box along x, stopping at x = 0.
            rays[0] = Ray::new(Vec3::new(-5.0, 1.0, 0.0), Vec3::X);
            let mut ends = [0.0; PACKET_WIDTH];
            ends[0] = 5.0;
            marker.traced(RayKind::Primary, &rays, 1, &ends);
        }
        let (walked, _) = ostc.take_counters();
        assert!(walked > 0);
        let near = |x: f32| {
            Footprint::Box(Aabb {
                min: Vec3::new(x - 0.05, 0.95, -0.05),
                max: Vec3::new(x + 0.05, 1.05, 0.05),
            })
        };
        assert!(ostc.dirty_for(&[near(-0.5)]).contains(region));
        // Past the hit: the ray never got there.
        assert!(ostc.dirty_for(&[near(0.6)]).is_empty());
        // Off the ray's line.
        let aside = Footprint::Box(Aabb {
            min: Vec3::new(-0.5, 0.1, 0.6),
            max: Vec3::new(-0.4, 0.2, 0.7),
        });
        assert!(ostc.dirty_for(&[aside]).is_empty());
        // A ball whose bounding box reaches the voxels the ray marked (y and
        // z within 1 +- 0.125 and 0 +- 0.125: 16 voxels a side), but neither
        // the ball nor its box reaches the ray: the voxels name the region
        // a candidate, its recorded segment clears it.
        let ball = |center: Vec3| Footprint::Ball {
            center,
            radius: 0.3,
        };
        let corner = Vec3::new(-0.5, 1.125 + 0.23, 0.125 + 0.23);
        assert!(ostc
            .dirty_for(&[Footprint::Box(ball(corner).bounds())])
            .is_empty());
        assert!(ostc.dirty_for(&[ball(corner)]).is_empty());
        // Within the slack of the ray's line, a ball and a box count.
        let grazing = Vec3::new(-0.5, 1.3, 0.0);
        assert!(ostc.dirty_for(&[ball(grazing)]).contains(region));
        assert!(ostc
            .dirty_for(&[Footprint::Box(ball(grazing).bounds())])
            .contains(region));
        assert!(ostc
            .dirty_for(&[ball(Vec3::new(-0.5, 1.2, 0.0))])
            .contains(region));
        // Forgetting the region clears it everywhere.
        let mut dirty = RegionSet::empty(ostc.layout().count());
        dirty.insert(region);
        ostc.forget(&dirty);
        assert!(ostc.dirty_for(&[near(-0.5)]).is_empty());
    }

    /// Two groups of one region, one ray each, at different heights: a
    /// move across one ray dirties that group alone; forgetting it leaves
    /// the other's ray recorded, and forgetting both clears the region's
    /// voxel bits.
    #[test]
    fn moves_dirty_just_the_groups_whose_rays_they_meet() {
        let swept = Aabb {
            min: Vec3::new(-1.0, 0.0, -1.0),
            max: Vec3::new(1.0, 2.0, 1.0),
        };
        for voxels in [1, 512] {
            let mut ostc = Ostc::new(layout(), Some(swept), voxels, &[false]);
            let region = ostc.layout().region_of(44, 40);
            for (key, y) in [(7u128, 0.5f32), (9, 1.5)] {
                let mut marker = ostc.marker_in(region, key);
                let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
                rays[0] = Ray::new(Vec3::new(-5.0, y, 0.0), Vec3::X);
                let mut ends = [0.0; PACKET_WIDTH];
                ends[0] = 10.0;
                marker.traced(RayKind::Primary, &rays, 1, &ends);
            }
            let across = |y: f32| {
                [Footprint::Box(Aabb {
                    min: Vec3::new(-0.1, y - 0.05, -0.1),
                    max: Vec3::new(0.1, y + 0.05, 0.1),
                })]
            };
            let (regions, groups) = ostc.dirty_groups_for(&across(0.5));
            assert_eq!(
                (regions.iter().collect::<Vec<_>>(), groups.clone()),
                (vec![region], vec![7])
            );
            assert_eq!(ostc.dirty_groups_for(&across(1.5)).1, vec![9]);
            assert!(ostc.dirty_groups_for(&across(1.0)).1.is_empty());
            // Both at once, sorted.
            let both = [across(0.5)[0], across(1.5)[0]];
            assert_eq!(ostc.dirty_groups_for(&both).1, vec![7, 9]);
            // Whole regions, as before.
            assert!(ostc.dirty_for(&across(0.5)).contains(region));

            ostc.forget_groups(&regions, &groups);
            assert!(ostc.dirty_groups_for(&across(0.5)).1.is_empty());
            assert_eq!(ostc.dirty_groups_for(&across(1.5)).1, vec![9]);
            ostc.forget_groups(&regions, &[9]);
            assert!(ostc.dirty_groups_for(&across(1.5)).1.is_empty());
            // No recorded ray left: no voxel names the region any more.
            assert!(ostc.candidates_for(&both).is_empty(), "{voxels} voxels");
        }
    }

    #[test]
    fn shadow_rays_blocked_by_both_places_of_a_ball_stay_clean() {
        let swept = Aabb {
            min: Vec3::new(-1.0, 0.0, -1.0),
            max: Vec3::new(1.0, 2.0, 1.0),
        };
        let ostc = Ostc::new(layout(), Some(swept), 64, &[]);
        let region = ostc.layout().region_of(44, 40);
        let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
        // Toward a light at x = 5, through the middle of the box.
        rays[0] = Ray::segment(Vec3::new(-5.0, 1.0, 0.0), Vec3::new(10.0, 0.0, 0.0), 1.0);
        let ends = [1.0; PACKET_WIDTH];
        let shadow = RayKind::Shadow {
            light: 0,
            blocked: 1,
        };
        ostc.marker(SampleGroup { col: 44, row: 40 })
            .traced(shadow, &rays, 1, &ends);
        let ball = |x: f32, y: f32| Footprint::Ball {
            center: Vec3::new(x, y, 0.0),
            radius: 0.3,
        };
        // Blocked before and after: nothing to re-trace.
        assert!(ostc
            .dirty_for(&[ball(-0.5, 1.0), ball(0.5, 1.1)])
            .is_empty());
        // Off the ray at one of its places (or only grazing it): dirty.
        assert!(ostc
            .dirty_for(&[ball(-0.5, 1.0), ball(0.5, 1.5)])
            .contains(region));
        assert!(ostc
            .dirty_for(&[ball(-0.5, 1.0), ball(0.5, 1.3)])
            .contains(region));
        // A box is only a bound of its object: it never surely blocks.
        let boxed = |x: f32| Footprint::Box(ball(x, 1.0).bounds());
        assert!(ostc.dirty_for(&[boxed(-0.5), boxed(0.5)]).contains(region));
        // A primary or reflected ray through both places still changes.
        let ostc = Ostc::new(layout(), Some(swept), 64, &[]);
        ostc.marker(SampleGroup { col: 44, row: 40 })
            .traced(RayKind::Reflection, &rays, 1, &ends);
        assert!(ostc
            .dirty_for(&[ball(-0.5, 1.0), ball(0.5, 1.1)])
            .contains(region));
    }

    proptest::proptest! {
        /// The cheap box test never rejects a segment the walk would mark
        /// a voxel for.
        #[test]
        fn box_test_rejects_only_segments_that_miss(
            origin in proptest::array::uniform3(-6.0f32..6.0),
            target in proptest::array::uniform3(-3.0f32..3.0),
            axis_zero in 0usize..4,
            t1 in prop_oneof![0.1f32..3.0, Just(f32::INFINITY)],
        ) {
            let bounds = Aabb { min: Vec3::new(-1.0, 0.0, -1.0), max: Vec3::new(1.0, 2.0, 1.0) };
            let ostc = Ostc::new(layout(), Some(bounds), 512, &[]);
            let voxels = ostc.voxels.as_ref().unwrap();
            let origin = Vec3::from(origin);
            let mut dir = Vec3::from(target) - origin;
            if axis_zero < 3 {
                dir[axis_zero] = 0.0;
            }
            let walked = voxels.spec.walk(origin, dir, 0.0, t1).next().is_some();
            let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
            rays[3] = Ray { origin, dir, tmin: 0.0, tmax: t1, time: 0.0 };
            let crossing = voxels.spec.bounds.crossing_lanes(&rays, 1 << 3, &[t1; PACKET_WIDTH]);
            proptest::prop_assert!(!walked || crossing == 1 << 3);
        }
    }

    #[test]
    fn lights_dirty_hit_regions_when_moved_and_lit_regions_when_recoloured() {
        // Two lights, the second animated.
        let ostc = Ostc::new(layout(), None, 4096, &[false, true]);
        assert!(ostc.grid().is_none(), "no moving object: no voxel grid");
        let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
        rays[0] = Ray::new(Vec3::ZERO, Vec3::X);
        rays[1] = Ray::new(Vec3::ZERO, Vec3::Y);
        let mut hit = [f32::INFINITY; PACKET_WIDTH];
        hit[0] = 3.0;
        let to_light = [1.0; PACKET_WIDTH];
        let region = |col| ostc.layout().region_of(col, 10);
        // Region of column 0: a hit, its shadow ray to light 1 gets through.
        let mut marker = ostc.marker(SampleGroup { col: 0, row: 10 });
        marker.traced(RayKind::Primary, &rays, 1, &hit);
        let shadow = |blocked| RayKind::Shadow { light: 1, blocked };
        marker.traced(shadow(0b10), &rays, 0b11, &to_light);
        // Column 40: a hit whose shadow rays are all blocked.
        let mut marker = ostc.marker(SampleGroup { col: 40, row: 10 });
        marker.traced(RayKind::Primary, &rays, 1, &hit);
        marker.traced(shadow(0b01), &rays, 0b01, &to_light);
        // Column 80: nothing hit (sky).
        ostc.marker(SampleGroup { col: 80, row: 10 }).traced(
            RayKind::Primary,
            &rays,
            1,
            &[f32::INFINITY; PACKET_WIDTH],
        );
        let moved = ostc.dirty_for_light(1, true);
        assert_eq!(
            moved.iter().collect::<Vec<_>>(),
            vec![region(0), region(40)]
        );
        let recoloured = ostc.dirty_for_light(1, false);
        assert_eq!(recoloured.iter().collect::<Vec<_>>(), vec![region(0)]);
        // Light 0 is not tracked: a change to it dirties everything.
        assert_eq!(ostc.dirty_for_light(0, false).len(), ostc.layout().count());
    }
}

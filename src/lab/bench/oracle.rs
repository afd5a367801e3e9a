//! The least tracing any reuse of a camera's image could get away with,
//! counted from full renders: the oracle E1 and E3 are measured against.

use crate::ray::{LaneMask, RayPacket, PACKET_WIDTH};

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
pub(super) struct Oracle {
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
    pub(super) rays: OracleRays,
}

/// Ray totals of the oracle (see `Oracle::rays`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct OracleRays {
    pub all: u64,
    pub samples: u64,
    pub regions: u64,
}

impl Oracle {
    pub(super) fn new(region_size: (i64, i64)) -> Oracle {
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
    pub(super) fn add(
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
            && 8.0 * columns * columns / 2.0 <= crate::reuse::pan::PAN_BUFFER_LIMIT_BYTES;
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

    /// The sample groups (of a `width` pixels wide frame, of its strata
    /// `side` to a pixel's side when above one) holding a pixel of the last
    /// frame's regions that had to be traced: what the region oracle traces
    /// when timed.
    pub(super) fn region_groups(&self, width: u32, side: u32) -> Vec<crate::render::SampleGroup> {
        let width = i64::from(width.max(1));
        let side = i64::from(side.max(1));
        let mut groups: Vec<_> = self
            .region_pixels
            .iter()
            .enumerate()
            .filter(|&(_, &dirty)| dirty)
            .flat_map(|(i, _)| {
                let (x, y) = (i as i64 % width * side, i as i64 / width * side);
                (0..side * side).map(move |stratum| {
                    crate::render::SampleGroup::containing(x + stratum % side, y + stratum / side)
                })
            })
            .collect();
        groups.sort_unstable_by_key(|g| (g.row, g.col));
        groups.dedup();
        groups
    }
}

/// `trace` given `table`'s rays as groups address them: its strata (a
/// lattice `side` times as dense) when `side` is above one, its cells
/// otherwise.
pub(super) fn traced_as_groups<R>(
    table: &crate::camera::RayTable,
    side: i64,
    trace: impl FnOnce(&dyn crate::render::PrimaryRays) -> R,
) -> R {
    if side > 1 {
        trace(&crate::render::Strata::new(table))
    } else {
        trace(table)
    }
}

/// Rays traced for each pixel of a full render through `camera` at
/// `samples` a pixel (primary, shadow and reflection rays of all its
/// sub-samples), counted on an untimed pass: what each pixel costs to trace.
pub fn rays_per_pixel(
    shader: &crate::shade::Shader,
    camera: &crate::camera::Camera,
    samples: crate::sampling::PixelSamples,
) -> Vec<u32> {
    use crate::render::{trace_groups_observed, SampleGroup};
    use crate::shade::{RayKind, RayObserver};
    use std::sync::atomic::{AtomicU32, Ordering};

    struct Counter<'a> {
        counts: [u32; PACKET_WIDTH],
        group: SampleGroup,
        /// Lanes are strata, `side` to a pixel's side (1: pixels).
        side: i64,
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
                let (x, y) = (x / self.side, y / self.side);
                if x < self.width && y < self.height {
                    self.sink[(y * self.width + x) as usize]
                        .fetch_add(self.counts[lane], Ordering::Relaxed);
                }
            }
        }
    }

    let (width, height) = (i64::from(camera.width), i64::from(camera.height));
    let sink: Vec<AtomicU32> = (0..width * height).map(|_| AtomicU32::new(0)).collect();
    let table = crate::camera::RayTable::with_samples(camera, samples);
    // A packet's lanes are one cell's each only with one sample a cell, or
    // counts that are not squares; with square counts they are strata.
    let side = i64::from(samples.grid_side()).max(1);
    let counter = |group| {
        Some(Counter {
            counts: [0; PACKET_WIDTH],
            group,
            side,
            width,
            height,
            sink: &sink,
        })
    };
    let groups = SampleGroup::covering(0..width * side, 0..height * side);
    traced_as_groups(&table, side, |source| {
        trace_groups_observed(shader, source, &groups, counter)
    });
    sink.into_iter().map(AtomicU32::into_inner).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{Accelerator, BackendKind};
    use crate::render::render_view;
    use crate::scene::{paper_scene, Scene, SceneOverrides};
    use crate::shade::{RayCounts, Shader};

    /// The paper scene at 64x48: a full render, its ray counts, and the
    /// rays of each pixel.
    fn small_paper_traced(samples: u32) -> (Scene, crate::render::Frame, RayCounts, Vec<u32>) {
        let scene = paper_scene(&SceneOverrides {
            width: Some(64),
            height: Some(48),
            spp: Some(samples),
            ..SceneOverrides::default()
        })
        .unwrap();
        let accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
        let (frame, counts) = render_view(&scene, &scene.camera, &accel);
        let shader = Shader::new(&scene, &accel);
        let rays = rays_per_pixel(&shader, &scene.camera, scene.samples);
        (scene, frame, counts, rays)
    }

    #[test]
    fn rays_per_pixel_add_up_to_the_full_render() {
        for samples in [1, 4] {
            let (_, _, counts, rays) = small_paper_traced(samples);
            assert_eq!(rays.len(), 64 * 48);
            assert!(
                rays.iter().all(|&r| r >= samples),
                "every pixel traces its primary rays"
            );
            let sum: u64 = rays.iter().map(|&r| u64::from(r)).sum();
            assert_eq!(sum, counts.total(), "at {samples} samples a pixel");
            // Mirrors and lit surfaces cost more than the sky: the weights vary.
            assert!(rays.iter().max() > rays.iter().min());
        }
    }

    #[test]
    fn the_oracle_weighs_changed_samples_by_their_rays() {
        let (scene, frame, _, rays) = small_paper_traced(1);
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
        let (scene, frame, _, rays) = small_paper_traced(1);
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
        let (scene, frame, _, rays) = small_paper_traced(1);
        let mut oracle = Oracle::new((16, 8));
        oracle.add(&scene.camera, &frame, &rays);
        // Frame 0: the whole frame.
        assert_eq!(
            oracle.region_groups(64, 1),
            SampleGroup::covering(0..64, 0..48)
        );
        oracle.add(&scene.camera, &frame, &rays);
        assert!(oracle.region_groups(64, 1).is_empty());
        // Pixel (37, 20) lies in the region of columns 32..48, rows 16..24
        // (the window starts on the lattice's region grid here).
        let mut changed = frame.clone();
        changed.pixels[20 * 64 + 37] += glam::Vec3::splat(0.25);
        oracle.add(&scene.camera, &changed, &rays);
        let groups = oracle.region_groups(64, 1);
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

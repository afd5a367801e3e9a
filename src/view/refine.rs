//! Refinement in idle time: once the frame loop's picture is shown and
//! nothing new is asked, the same view is traced again at more samples a
//! pixel, in bands of sample groups, so that new input stops it within a
//! band.
//!
//! Promises: a refined picture at N samples a pixel is the render of the
//! view at N samples a pixel (the camera's image as `retrace render
//! --spp N` traces it, a viewport through its own rays as the frame loop's
//! direct render does), whatever the bands: each sample group is traced by
//! the one shared [`trace_groups`], whose colours are a pure function of
//! the group. Refinement never touches the frame loop's kept samples.

use std::time::Instant;

use crate::clock;
use crate::render::{image_groups, trace_groups, Frame, PrimaryRays};
use crate::shade::{RayCounts, Shader};

/// The samples a pixel refinement climbs to by default.
pub const DEFAULT_REFINE_SPP: u32 = 16;

/// Each rung of the ladder traces this many times the samples of the one
/// before: a picture visibly better at each step, and each step about as
/// long as all the steps before it together.
pub const LADDER_STEP: u32 = 4;

/// A band is sized to take about this long, so that input waits at most
/// about this long for the render thread.
pub const BAND_MS: f64 = 3.0;

/// The samples a pixel of each refined picture after one at `scene_spp`,
/// climbing by [`LADDER_STEP`] to `top` (empty when `top` is no more than
/// `scene_spp`: refinement off).
pub fn ladder(scene_spp: u32, top: u32) -> Vec<u32> {
    let mut rungs = Vec::new();
    let mut spp = scene_spp.saturating_mul(LADDER_STEP);
    while spp < top {
        rungs.push(spp);
        spp = spp.saturating_mul(LADDER_STEP);
    }
    if top > scene_spp {
        rungs.push(top);
    }
    rungs
}

/// Traces every pixel of a `width` x `height` image from `source` (pixel
/// (x, y) from its cell (x, y), as [`crate::render::render_image`] does),
/// a band of sample groups at a time (in rows, left to right), asking
/// `stop` before each band: None as soon as it says so.
pub fn trace_in_bands(
    shader: &Shader,
    source: &dyn PrimaryRays,
    width: u32,
    height: u32,
    stop: &dyn Fn() -> bool,
) -> Option<(Frame, RayCounts)> {
    let mut frame = Frame::new(width, height);
    let mut counts = RayCounts::default();
    let groups = image_groups(width, height);
    // Bands of whole groups, sized by the pace of the bands before (at 16
    // samples a pixel one row of groups of a 640-wide image takes longer
    // than a band should).
    let mut size = MIN_BAND_GROUPS;
    let mut pace: Option<f64> = None;
    let mut done = 0;
    while done < groups.len() {
        if stop() {
            return None;
        }
        let band = &groups[done..(done + size).min(groups.len())];
        let start = Instant::now();
        let (colors, band_counts) = trace_groups(shader, source, band);
        counts += band_counts;
        for (group, lanes) in band.iter().zip(&colors) {
            for ((col, row), color) in group.lane_samples().into_iter().zip(lanes) {
                if col < i64::from(width) && row < i64::from(height) {
                    frame.pixels[row as usize * width as usize + col as usize] = *color;
                }
            }
        }
        // The pace of the bands so far, smoothed (a band slowed by other
        // work on the machine should not halve the next one), and bands
        // growing at most twofold, so one fast band cannot make a long one.
        let ms_per_group = clock::ms(start.elapsed()) / band.len() as f64;
        pace = match pace {
            None => ms_per_group,
            Some(pace) => 0.75 * pace + 0.25 * ms_per_group,
        }
        .into();
        let fit = (BAND_MS / pace.unwrap_or(ms_per_group).max(1e-6)) as usize;
        size = fit.min(2 * size).max(MIN_BAND_GROUPS);
        done += band.len();
    }
    Some((frame, counts))
}

/// A band has at least this many groups: enough to share among threads.
const MIN_BAND_GROUPS: usize = 64;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{Accelerator, BackendKind};
    use crate::camera::RayTable;
    use crate::render::render_image;
    use crate::sampling::PixelSamples;
    use crate::scene::{paper_scene, SceneOverrides};
    use std::cell::Cell;

    #[test]
    fn the_ladder_climbs_by_four_to_the_top() {
        assert_eq!(ladder(1, 16), [4, 16]);
        assert_eq!(ladder(1, 64), [4, 16, 64]);
        assert_eq!(ladder(1, 10), [4, 10]);
        assert_eq!(ladder(1, 2), [2]);
        assert_eq!(ladder(4, 16), [16]);
        assert_eq!(ladder(4, 100), [16, 64, 100]);
        assert!(ladder(1, 1).is_empty());
        assert!(ladder(16, 16).is_empty());
        assert!(ladder(16, 4).is_empty());
    }

    #[test]
    fn bands_give_the_render_of_the_whole_image_and_stop_when_told() {
        // 122 x 90: groups cut by the image's right and bottom edges.
        let overrides = SceneOverrides {
            width: Some(122),
            height: Some(90),
            ..SceneOverrides::default()
        };
        let scene = paper_scene(&overrides).unwrap();
        let accel = Accelerator::build_with(BackendKind::default(), &scene.objects, None).unwrap();
        let shader = Shader::new(&scene, &accel);
        let table = RayTable::with_samples(&scene.camera, PixelSamples::new(4).unwrap());
        let (whole, whole_counts) = render_image(&shader, &table, 122, 90);
        let (banded, counts) = trace_in_bands(&shader, &table, 122, 90, &|| false).unwrap();
        assert!(banded == whole);
        assert_eq!(counts.primary, whole_counts.primary);
        let asked = Cell::new(0);
        let stopped = trace_in_bands(&shader, &table, 122, 90, &|| {
            asked.set(asked.get() + 1);
            asked.get() > 1
        });
        assert!(stopped.is_none());
        assert_eq!(asked.get(), 2, "stopped before the second band");
    }
}

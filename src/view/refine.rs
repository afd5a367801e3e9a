//! Refinement in idle time: once the frame loop's picture is shown and
//! nothing new is asked, the same view is traced again at more samples a
//! pixel, in bands of rows, so that new input stops it within a band.
//!
//! Promises: a refined picture at N samples a pixel is the render of the
//! view at N samples a pixel (the camera's image as `retrace render
//! --spp N` traces it, a viewport through its own rays as the frame loop's
//! direct render does), whatever the bands: each sample group is traced by
//! the one shared [`trace_groups`], whose colours are a pure function of
//! the group. Refinement never touches the frame loop's kept samples.

use std::time::Instant;

use crate::render::{trace_groups, Frame, PrimaryRays, SampleGroup, GROUP_HEIGHT};
use crate::shade::{RayCounts, Shader};

/// The samples a pixel refinement climbs to by default.
pub const DEFAULT_REFINE_SPP: u32 = 16;

/// Each rung of the ladder traces this many times the samples of the one
/// before: a picture visibly better at each step, and each step about as
/// long as all the steps before it together.
pub const LADDER_STEP: u32 = 4;

/// A band of rows is sized to take about this long, so that input waits
/// at most about this long for the render thread.
pub const BAND_MS: f64 = 4.0;

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
/// a band of whole group rows at a time, asking `stop` before each band:
/// None as soon as it says so.
pub fn trace_in_bands(
    shader: &Shader,
    source: &dyn PrimaryRays,
    width: u32,
    height: u32,
    stop: &dyn Fn() -> bool,
) -> Option<(Frame, RayCounts)> {
    let mut frame = Frame::new(width, height);
    let mut counts = RayCounts::default();
    let mut rows = GROUP_HEIGHT;
    let mut row = 0;
    while row < height {
        if stop() {
            return None;
        }
        let end = (row + rows).min(height);
        let start = Instant::now();
        let groups = SampleGroup::covering(0..i64::from(width), i64::from(row)..i64::from(end));
        let (colors, band_counts) = trace_groups(shader, source, &groups);
        counts += band_counts;
        for (group, lanes) in groups.iter().zip(&colors) {
            for ((col, y), color) in group.lane_samples().into_iter().zip(lanes) {
                if col < i64::from(width) && y < i64::from(height) {
                    frame.pixels[y as usize * width as usize + col as usize] = *color;
                }
            }
        }
        // The next band as long as the last rows' pace allows, in whole
        // group rows.
        let ms_per_row = start.elapsed().as_secs_f64() * 1e3 / f64::from(end - row);
        let fit = (BAND_MS / ms_per_row.max(1e-6)) as u32;
        rows = (fit / GROUP_HEIGHT * GROUP_HEIGHT).clamp(GROUP_HEIGHT, height.max(GROUP_HEIGHT));
        row = end;
    }
    Some((frame, counts))
}

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
        // 90 rows: the last band is cut by the image's edge.
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
        assert_eq!(asked.get(), 2, "stopped at the second band");
    }
}

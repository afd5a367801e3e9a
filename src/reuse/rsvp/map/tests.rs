use super::*;
use crate::camera::ViewTransform;
use crate::camera::{Camera, Projection};
use crate::reuse::rsvp::fixtures::*;
use crate::reuse::rsvp::Filter;

#[test]
fn trace_order_keys_keep_every_level_and_sort_by_it() {
    // Levels past index 255 (level 15 in azimuth and finer) need a
    // ninth bit: a key without it sends them to a coarser level's tiles.
    let far = SampleGroup {
        col: (1 << ORDER_COORD_BITS) - 4,
        row: (1 << ORDER_COORD_BITS) - 2,
    };
    let mut keys = Vec::new();
    for index in 0..Level::COUNT {
        let level = Level::from_index(index);
        for group in [SampleGroup { col: 0, row: 0 }, far] {
            let key = trace_order(level, group);
            assert_eq!(from_trace_order(key), (level, group), "level {index}");
            keys.push(key);
        }
    }
    assert!(keys.windows(2).all(|w| w[0] < w[1]));
}

#[test]
fn interpolated_patches_stay_within_their_tolerance() {
    let buffer = SampleBuffer::new(lattice());
    let knobs = RsvpKnobs::default();
    let base = tilted_camera();
    let transform = off_centre;
    let cases = [
        // E2's ends, then rotation and shear, a view straight down
        // (the pole), a view wider than a turn (the back seam) and an
        // equal-angle viewport.
        (base.clone(), transform(1.0, 0.0, [0.0, 0.0])),
        (base.clone(), transform(2.5557, 0.0, [0.0, 0.0])),
        (base.clone(), transform(1.7, 0.5, [0.2, -0.1])),
        (
            Camera {
                pitch: -89f64.to_radians(),
                ..base.clone()
            },
            transform(1.0, 0.0, [0.0, 0.0]),
        ),
        (base.clone(), transform(0.01, 0.0, [0.0, 0.0])),
        (
            Camera {
                projection: Projection::EqualAngle,
                ..base.clone()
            },
            transform(3.0, 0.2, [0.0, 0.0]),
        ),
    ];
    let mut interpolated = [0usize; 6];
    // Patches whose grid level equals patch_level's.
    let mut levels = [0usize; 6];
    for (case, (camera, transform)) in cases.into_iter().enumerate() {
        let pose = ViewportPose::new(camera, transform);
        let map = PixelMap::new(&pose);
        let (mut exact, mut fast) = (Vec::new(), Vec::new());
        for y0 in (0..pose.camera.height).step_by(PATCH as usize) {
            for x0 in (0..pose.camera.width).step_by(PATCH as usize) {
                let Some((level, _, grid)) = buffer.patch_grid(&pose, &map, &knobs, x0, y0) else {
                    continue;
                };
                let (chosen, _) = buffer.patch_level(&pose, &map, &knobs, x0, y0);
                levels[case] += usize::from(level == chosen);
                interpolated[case] += 1;
                let size = (
                    (pose.camera.width - x0).min(PATCH) as usize,
                    (pose.camera.height - y0).min(PATCH) as usize,
                );
                let at = (x0, y0);
                let n = size.0 * size.1;
                let exact_out = nan_filled(&mut exact, n);
                buffer.patch_coords(&pose, &map, level, None, at, size.0, exact_out);
                let fast_out = nan_filled(&mut fast, n);
                buffer.patch_coords(&pose, &map, level, Some(&grid), at, size.0, fast_out);
                for (e, f) in exact.iter().zip(&fast) {
                    let miss = (*e - *f).abs().max_element();
                    assert!(
                        miss <= 1.25 * GRID_TOLERANCE,
                        "case {case}, patch ({x0}, {y0}) at level {level}: {e} vs {f}"
                    );
                }
            }
        }
    }
    // 40 x 30 patches: the smooth views interpolate nearly everywhere.
    assert_eq!(interpolated[0], 1200, "{interpolated:?}");
    assert_eq!(interpolated[1], 1200, "{interpolated:?}");
    // Near the pole some patches bend too much; zoomed far out (a patch
    // spans many degrees) nearly none fit: only a few where azimuth
    // saturates at +-90 degrees and elevation keeps a coarse level.
    assert!((1..1200).contains(&interpolated[3]), "{interpolated:?}");
    assert!(interpolated[4] <= 12, "{interpolated:?}");
    assert_eq!(interpolated[5], 1200, "{interpolated:?}");
    // The grid's cells measure the footprint a few pixels from where
    // patch_level does: a level may differ only where the footprint
    // sits on a threshold.
    for (case, (&same, &all)) in levels.iter().zip(&interpolated).enumerate() {
        assert!(
            same * 100 >= all * 97,
            "case {case}: {levels:?} of {interpolated:?}"
        );
    }
}

#[test]
fn the_groups_asked_for_are_exactly_those_the_pixels_read() {
    // An empty buffer: every group a pixel's filter reads must be asked
    // for, and no other, whichever way a patch collects them (marks in
    // its box, or pixel by pixel when sparse).
    let buffer = SampleBuffer::new(lattice());
    let base = camera(Projection::Perspective);
    let poses = [
        (base.clone(), 2.5557, 0.0, [0.0, 0.0]),
        (base.clone(), 1.7, 0.5, [0.2, -0.1]),
        (
            Camera {
                pitch: -89f64.to_radians(),
                ..base.clone()
            },
            1.0,
            0.3,
            [0.0, 0.0],
        ),
        (base.clone(), 0.01, 0.0, [0.0, 0.0]),
        // Zoomed out: levels coarser than 0, some mixed with finer ones.
        (base.clone(), 0.3, 0.4, [0.0, 0.0]),
        (
            Camera {
                projection: Projection::EqualAngle,
                width: 96,
                height: 80,
                ..base.clone()
            },
            3.0,
            0.2,
            [0.0, 0.0],
        ),
    ];
    let knobs = [
        RsvpKnobs::default(),
        RsvpKnobs {
            filter: Filter::Nearest,
            ..RsvpKnobs::default()
        },
        // Pixels sparser than samples: gaps between their reads.
        RsvpKnobs {
            oversample: 0.5,
            ..RsvpKnobs::default()
        },
        // Up to 5x5 reads a pixel, as many as its box covers.
        RsvpKnobs {
            filter: Filter::PixelBox,
            ..RsvpKnobs::default()
        },
        RsvpKnobs {
            filter: Filter::PixelBox,
            oversample: 1.0,
            ..RsvpKnobs::default()
        },
    ];
    for (case, (camera, zoom, rotate, shear)) in poses.into_iter().enumerate() {
        let transform = ViewTransform {
            zoom,
            rotate,
            shear,
            translate: [3.0, 1.0],
        };
        let pose = ViewportPose::new(camera, transform);
        let map = PixelMap::new(&pose);
        for knobs in &knobs {
            let mapped = buffer.map(&pose, knobs);
            let mut read = std::collections::BTreeSet::new();
            let mut coords = Vec::new();
            for (index, patch) in mapped.patches.iter().enumerate() {
                let x0 = (index % mapped.patches_x) as u32 * PATCH;
                let y0 = (index / mapped.patches_x) as u32 * PATCH;
                let cols = (pose.camera.width - x0).min(PATCH) as usize;
                let rows = (pose.camera.height - y0).min(PATCH) as usize;
                let out = nan_filled(&mut coords, cols * rows);
                let grid = patch.grid.as_ref();
                buffer.patch_coords(&pose, &map, patch.level, grid, (x0, y0), cols, out);
                let last_row = buffer.lattice.last_row(patch.level.y);
                for c in coords.iter().filter(|c| !c.x.is_nan()) {
                    let (cols, rows) = if knobs.filter == Filter::PixelBox {
                        // Every sample whose cell the pixel's box covers.
                        let (wx, wy) = patch.filter.width();
                        (covered(c.x, wx.into()), covered(c.y, wy.into()))
                    } else {
                        let (cx, ry) = patch.filter.origin(c.x, c.y);
                        let side = knobs.filter.side();
                        (cx..cx + side, ry..ry + side)
                    };
                    for row in rows {
                        let row = row.clamp(0, last_row);
                        for col in cols.clone() {
                            let (owner, c, r) = buffer.lattice.owner(patch.level, col, row);
                            let group = SampleGroup::containing(c, r);
                            read.insert((owner, group.row, group.col));
                        }
                    }
                }
            }
            let asked: Vec<_> = mapped
                .missing
                .iter()
                .map(|&(level, g)| (level, g.row, g.col))
                .collect();
            assert!(!asked.is_empty(), "case {case}, {knobs:?}");
            assert_eq!(
                asked,
                read.into_iter().collect::<Vec<_>>(),
                "case {case}, {knobs:?}"
            );
        }
    }
}

/// The samples whose cells (each a sample wide, centred on it) a box
/// `width` wide centred on `x` covers; `x` first rounded to the filters'
/// grid of 2^-16 of a sample.
fn covered(x: f64, width: f64) -> std::ops::Range<i64> {
    let x = (x * 65536.0).round() / 65536.0;
    let (start, end) = (x - 0.5 * width, x + 0.5 * width);
    (start + 0.5).floor() as i64..(end + 0.5).ceil() as i64
}

#[test]
fn the_pixel_box_is_as_wide_as_the_patch_s_densest_pixel() {
    let buffer = SampleBuffer::new(lattice());
    // The oversampling at four samples a pixel and at sixteen, where the
    // box needs the wide taps.
    for oversample in [1.19, 2.38] {
        let knobs = RsvpKnobs {
            filter: Filter::PixelBox,
            oversample,
            ..RsvpKnobs::default()
        };
        for zoom in [1.0, 1.3, 1.9, 2.6, 7.7] {
            let pose = ViewportPose::new(
                camera(Projection::EqualAngle),
                off_centre(zoom, 0.0, [0.0, 0.0]),
            );
            let mapped = buffer.map(&pose, &knobs);
            let map = PixelMap::new(&pose);
            let (x0, y0) = (5 * PATCH, 4 * PATCH);
            let patch =
                &mapped.patches[(y0 / PATCH) as usize * mapped.patches_x + (x0 / PATCH) as usize];
            // Pixel spacing along each lattice axis, at the patch's level,
            // from neighbours mapped exactly.
            let mut spacing = DVec2::INFINITY;
            for y in y0..y0 + PATCH {
                for x in x0..x0 + PATCH {
                    let at = |x: u32, y: u32| {
                        let (az, el) = map.angles(&pose, x, y).unwrap();
                        DVec2::new(az, -el) / buffer.lattice.step * level_scale(patch.level)
                    };
                    let (p, right, down) = (at(x, y), at(x + 1, y), at(x, y + 1));
                    spacing = spacing.min(DVec2::new((right - p).x.abs(), (down - p).y.abs()));
                }
            }
            let (wx, wy) = patch.filter.width();
            for (width, spacing) in [(wx, spacing.x), (wy, spacing.y)] {
                // 2 to 4 times the oversampling a pixel side (a level
                // finer than the footprint), and the box that wide.
                let (least, most) = (2.0 * oversample, 4.0 * oversample);
                assert!(
                    (least - 1e-3..most + 1e-3).contains(&spacing),
                    "oversample {oversample}, zoom {zoom}: {spacing}"
                );
                assert!(
                    (f64::from(width) - spacing).abs() < 0.02 * spacing,
                    "oversample {oversample}, zoom {zoom}: {width} for {spacing}"
                );
            }
        }
    }
}

#[test]
fn a_wide_perspective_viewport_needs_finer_levels_at_its_edges() {
    let lattice = lattice();
    let buffer = SampleBuffer::new(lattice);
    let pose = ViewportPose::new(camera(Projection::Perspective), ViewTransform::default());
    // At least a sample a pixel everywhere, so the levels follow the
    // lens's squeeze alone.
    let knobs = RsvpKnobs {
        oversample: 1.0,
        ..RsvpKnobs::default()
    };
    let map = PixelMap::new(&pose);
    let level = |x0| buffer.patch_level(&pose, &map, &knobs, x0, 232).0;
    assert_eq!(level(312), Level::new(0, 0));
    // Perspective squeezes azimuth first: a third of the way out only
    // columns need the finer level, at the edge rows too.
    assert_eq!(level(112), Level::new(1, 0));
    assert_eq!(level(0), Level::new(1, 1));
    let zoomed = ViewportPose::new(
        pose.camera.clone(),
        ViewTransform {
            zoom: 1000.0,
            ..ViewTransform::default()
        },
    );
    let (level, _) = buffer.patch_level(&zoomed, &PixelMap::new(&zoomed), &knobs, 312, 232);
    assert!((10..=11).contains(&level.x), "{level}");
    assert!((10..=11).contains(&level.y), "{level}");
}

#[test]
fn a_zoomed_out_view_reads_coarser_levels_about_a_sample_a_pixel() {
    // Zoomed out fourfold, the middle's pixels are four level-0 samples
    // apart: read from level 0, each would trace groups of its own.
    let buffer = SampleBuffer::new(lattice());
    let pose = ViewportPose::new(
        camera(Projection::Perspective),
        ViewTransform {
            zoom: 0.25,
            ..ViewTransform::default()
        },
    );
    let mapped = buffer.map(&pose, &RsvpKnobs::default());
    let centre = &mapped.patches[mapped.patches.len() / 2 + mapped.patches_x / 2];
    assert_eq!(centre.level, Level::new(-2, -2));
    let coarsest = mapped.patches.iter().map(|p| p.level.finest()).min();
    assert_eq!(coarsest, Some(-2));
    let pixels = u64::from(pose.camera.width * pose.camera.height);
    let samples = mapped.missing.len() as u64 * u64::from(GROUP_WIDTH * GROUP_HEIGHT);
    // Measured 2.1 samples a pixel (the wide lens's edges need finer
    // levels); with level 0 the coarsest, 3.3.
    assert!(
        samples * 2 < 5 * pixels,
        "{samples} samples for {pixels} pixels"
    );
}

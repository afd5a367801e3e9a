//! Pass 2 of a viewport frame: each pixel's colour from the samples its
//! filter reads, through the assembled blocks of its patch's level,
//! converted to 8 bits.

use glam::{DVec2, Vec3, Vec3A};
use rayon::prelude::*;

use super::{
    blocks::SampleView,
    filter::{
        bilinear, decode, decode_simd, encode, is_narrow, mean, pixel_box, pixel_box_of, rgb8,
        split_from, PatchFilter, SampleCode, PIXEL_BOX_NARROW_TAPS, PIXEL_BOX_TAPS,
    },
    map::{nan_filled, Mapped, SampleBox, GRID_SPACING},
    tiles::{tile_key, TileCache},
    viewport::PixelMap,
    Filter, Level, SampleBuffer, PATCH,
};
use crate::camera::ViewportPose;
use crate::color::{srgb_table, SrgbTable};
use crate::render::Frame;

impl SampleBuffer {
    /// A traced (or null: black) sample, with the tile cache.
    #[inline(always)]
    fn read(&self, cache: &mut TileCache, level: Level, col: i64, row: i64) -> Vec3 {
        let row = row.clamp(0, self.lattice.last_row(level.y));
        let (owner, col, row) = self.lattice.owner(level, col, row);
        let (key, sample, _) = tile_key(col, row);
        let samples = &self.levels[owner.index()];
        match cache.tile(samples, owner, key) {
            u32::MAX => Vec3::ZERO,
            tile => samples.tile_colors(tile)[sample],
        }
    }

    /// Pass 2: each pixel's colour from its samples, read from the
    /// assembled blocks of its patch's level (see [`super::blocks`]).
    pub(super) fn gather(
        &self,
        pose: &ViewportPose,
        mapped: &Mapped,
        linear: bool,
    ) -> (Option<Frame>, image::RgbImage) {
        let (w, h) = (pose.camera.width as usize, pose.camera.height as usize);
        let map = PixelMap::new(pose);
        let band = w * PATCH as usize;
        let mut bytes = vec![0u8; w * h * 3];
        let mut pixels = if linear {
            vec![Vec3::ZERO; w * h]
        } else {
            Vec::new()
        };
        let mut pixel_bands: Vec<&mut [Vec3]> = if linear {
            pixels.chunks_mut(band).collect()
        } else {
            Vec::new()
        };
        pixel_bands.resize_with(h.div_ceil(PATCH as usize), || &mut []);
        bytes
            .par_chunks_mut(band * 3)
            .zip(pixel_bands.into_par_iter())
            .enumerate()
            .for_each_init(
                BandScratch::default,
                |scratch, (band_index, (out, linear_out))| {
                    let BandScratch {
                        view_samples,
                        coords,
                        reads,
                    } = scratch;
                    let mut cache = TileCache::new();
                    let mut colors: [SampleCode; (PATCH * PATCH) as usize] = [0; _];
                    let srgb = srgb_table();
                    let y0 = band_index * PATCH as usize;
                    let rows = (h - y0).min(PATCH as usize);
                    let patches =
                        &mapped.patches[band_index * mapped.patches_x..][..mapped.patches_x];
                    for (patch_x, patch) in patches.iter().enumerate() {
                        let x0 = patch_x * PATCH as usize;
                        let cols = (w - x0).min(PATCH as usize);
                        let (level, filter) = (patch.level, &patch.filter);
                        let grid = patch.grid.as_ref();
                        // A grid writes every pixel; exact mapping leaves
                        // pixels without a ray as they were.
                        let coords = if grid.is_some() {
                            coords.resize(cols * rows, DVec2::NAN);
                            &mut coords[..cols * rows]
                        } else {
                            nan_filled(coords, cols * rows)
                        };
                        let origin = (x0 as u32, y0 as u32);
                        self.patch_coords(pose, &map, level, grid, origin, cols, coords);
                        let colors = &mut colors[..cols * rows];
                        // The pixels' own box: a grid's points bound its
                        // pixels', so it is often smaller than pass 1's, and
                        // copies fewer samples.
                        let bounds = match grid {
                            // Within pass 1's box, whose blocks are the
                            // ones assembled, whatever its slack adds.
                            Some(_) => patch.blocks.and_then(|assembled| {
                                grid_pixels_box(filter, coords, cols)
                                    .map(|b| b.intersection(&assembled))
                            }),
                            None => patch.blocks.and(pixels_box(filter, coords)),
                        };
                        match bounds {
                            Some(bounds) => {
                                let view = self.view(level, &bounds, view_samples);
                                gather_patch(srgb, &view, filter, coords, reads, colors);
                            }
                            None => {
                                for (slot, c) in colors.iter_mut().zip(coords.iter()) {
                                    *slot = if c.x.is_nan() {
                                        0
                                    } else {
                                        self.filter(&mut cache, srgb, level, filter, c.x, c.y)
                                    };
                                }
                            }
                        }
                        // Whole patch rows at once: no per-pixel index checks.
                        for (j, line) in colors.chunks_exact(cols).enumerate() {
                            let p = j * w + x0;
                            for (byte, c) in
                                out[p * 3..(p + cols) * 3].chunks_exact_mut(3).zip(line)
                            {
                                byte.copy_from_slice(&rgb8(*c));
                            }
                            if let Some(slots) = linear_out.get_mut(p..p + cols) {
                                for (slot, c) in slots.iter_mut().zip(line) {
                                    *slot = decode(srgb, *c);
                                }
                            }
                        }
                    }
                },
            );
        let image =
            image::RgbImage::from_raw(w as u32, h as u32, bytes).expect("three bytes per pixel");
        let frame = linear.then_some(Frame {
            width: w as u32,
            height: h as u32,
            pixels,
        });
        (frame, image)
    }

    /// A pixel's code at lattice coordinates (x, y), from the tiles: as
    /// [`gather_patch`] makes it from the blocks.
    #[inline(always)]
    fn filter(
        &self,
        cache: &mut TileCache,
        srgb: &SrgbTable,
        level: Level,
        filter: &PatchFilter,
        x: f64,
        y: f64,
    ) -> SampleCode {
        let ((c, fx), (r, fy)) = filter.split(x, y);
        let (c, r) = (c as i64, r as i64);
        let mut code = |c, r| encode(srgb, self.read(cache, level, c, r));
        match filter.filter {
            Filter::Nearest => code(c, r),
            Filter::Box => mean([
                code(c, r),
                code(c + 1, r),
                code(c, r + 1),
                code(c + 1, r + 1),
            ]),
            Filter::PixelBox => pixel_box(
                srgb,
                |i, j| code(c + i as i64, r + j as i64),
                (fx as f32, fy as f32),
                filter.width(),
            ),
            Filter::Bilinear => bilinear(
                [
                    code(c, r),
                    code(c + 1, r),
                    code(c, r + 1),
                    code(c + 1, r + 1),
                ],
                fx as f32,
                fy as f32,
            ),
        }
    }
}

/// What pass 2 reuses from patch to patch.
#[derive(Default)]
struct BandScratch {
    /// A patch's samples, copied out of the blocks: what its
    /// [`SampleView`] reads.
    view_samples: Vec<SampleCode>,
    /// A patch's pixels' lattice coordinates.
    coords: Vec<DVec2>,
    /// What [`gather_patch`] works out for a patch's pixels.
    reads: Box<PatchReads>,
}

/// Pixels a patch holds at most.
const PATCH_PIXELS: usize = (PATCH * PATCH) as usize;

/// Each pixel's reads in a patch: kept from patch to patch, as zeroing
/// them afresh for every patch costs more than some filters' blends.
struct PatchReads {
    /// Where the pixel's filter starts in the view.
    index: [u32; PATCH_PIXELS],
    /// The pixel's bilinear weights across and down.
    wx: [f32; PATCH_PIXELS],
    wy: [f32; PATCH_PIXELS],
    /// Bilinear: every pixel's two top and two bottom samples.
    pairs: [[SampleCode; 2 * PATCH_PIXELS]; 2],
    /// Pixel box: the view's samples in linear colour.
    linear: Vec<Vec3A>,
}

impl Default for PatchReads {
    fn default() -> Self {
        PatchReads {
            index: [0; PATCH_PIXELS],
            wx: [0.0; PATCH_PIXELS],
            wy: [0.0; PATCH_PIXELS],
            pairs: [[0; 2 * PATCH_PIXELS]; 2],
            linear: Vec::new(),
        }
    }
}

/// The box of the samples `filter` reads for the pixels at `coords`
/// (lattice coordinates, NaN for no ray); None when no pixel has a ray.
fn pixels_box(filter: &PatchFilter, coords: &[DVec2]) -> Option<SampleBox> {
    // min and max skip NaN.
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for c in coords {
        lo = lo.min(*c);
        hi = hi.max(*c);
    }
    (lo.x <= hi.x).then(|| SampleBox::read_by(filter, lo, hi))
}

/// [`pixels_box`] of a grid-mapped patch's pixels (`coords`, `cols`
/// wide, none NaN) from a few of them: within each grid cell a pixel's
/// coordinates interpolate the cell's corners, so the pixels on grid
/// points and on the patch's last column and row bound the rest, up to
/// the interpolation's rounding, which the box is grown by (a sample more
/// at most, and that rarely).
fn grid_pixels_box(filter: &PatchFilter, coords: &[DVec2], cols: usize) -> Option<SampleBox> {
    let rows = coords.len() / cols;
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    let mut take = |c: DVec2| {
        lo = lo.min(c);
        hi = hi.max(c);
    };
    let s = GRID_SPACING as usize;
    for j in (0..rows).step_by(s).chain([rows - 1]) {
        let line = &coords[j * cols..(j + 1) * cols];
        for i in (0..cols).step_by(s).chain([cols - 1]) {
            take(line[i]);
        }
    }
    for j in 0..rows {
        take(coords[j * cols + cols - 1]);
    }
    for i in 0..cols {
        take(coords[(rows - 1) * cols + i]);
    }
    let slack = (lo.abs().max(hi.abs()) * 1e-12).max(DVec2::splat(1e-12));
    (lo.x <= hi.x).then(|| SampleBox::read_by(filter, lo - slack, hi + slack))
}

/// Filters one patch's pixels (`coords`: their lattice coordinates at the
/// view's level, NaN for no ray) from `view`, which holds every sample
/// they read, into `out` (`coords`' length), working in `reads`.
fn gather_patch(
    srgb: &SrgbTable,
    view: &SampleView,
    filter: &PatchFilter,
    coords: &[DVec2],
    reads: &mut PatchReads,
    out: &mut [SampleCode],
) {
    let wd = view.width;
    let samples = view.samples;
    // View index and weights of every pixel first, in straight-line f64
    // code (exact: whole numbers and multiples of 2^-16) that vectorises;
    // NaN pixels get index 0 and are blacked out last.
    let PatchReads {
        index,
        wx,
        wy,
        pairs,
        linear,
    } = reads;
    let (c0f, r0f, wdf) = (view.col as f64, view.row as f64, wd as f64);
    let mut has_nan = false;
    let (shift_x, shift_y) = filter.shift();
    for (((c, k), fx), fy) in coords
        .iter()
        .zip(index.iter_mut())
        .zip(wx.iter_mut())
        .zip(wy.iter_mut())
    {
        has_nan |= c.x.is_nan();
        let (ox, x) = split_from(shift_x, c.x);
        let (oy, y) = split_from(shift_y, c.y);
        // A whole number in 0..2^32 (NaN: 0), read from the mantissa of
        // itself plus 2^52: `as u32` saturates one lane at a time.
        let k_exact = ((oy - r0f) * wdf + (ox - c0f)).max(0.0);
        *k = (k_exact + 4_503_599_627_370_496.0).to_bits() as u32;
        *fx = x as f32;
        *fy = y as f32;
    }
    let n = coords.len();
    let (index, wx, wy) = (&index[..n], &wx[..n], &wy[..n]);
    // One loop per filter, without branches inside.
    match filter.filter {
        Filter::Nearest => {
            for (slot, &k) in out.iter_mut().zip(index) {
                *slot = samples[k as usize];
            }
        }
        Filter::Box => {
            for (slot, &k) in out.iter_mut().zip(index) {
                let k = k as usize;
                let (top, bottom) = (&samples[k..k + 2], &samples[k + wd..k + wd + 2]);
                *slot = mean([top[0], top[1], bottom[0], bottom[1]]);
            }
        }
        Filter::PixelBox => {
            // Each sample decoded once, not once for each pixel reading it.
            linear.clear();
            linear.extend(samples.iter().map(|&code| decode_simd(srgb, code)));
            // The box's taps chosen once a patch, out of the loop.
            fn blend_all<const TAPS: usize>(
                srgb: &SrgbTable,
                out: &mut [SampleCode],
                index: &[u32],
                (wx, wy): (&[f32], &[f32]),
                linear: &[Vec3A],
                wd: usize,
                width: (f32, f32),
            ) {
                for ((slot, &k), (&fx, &fy)) in out.iter_mut().zip(index).zip(wx.iter().zip(wy)) {
                    let k = k as usize;
                    let blend =
                        pixel_box_of::<TAPS>(|i, j| linear[k + j * wd + i], (fx, fy), width);
                    *slot = encode(srgb, blend.into());
                }
            }
            let width = filter.width();
            if is_narrow(width) {
                blend_all::<PIXEL_BOX_NARROW_TAPS>(srgb, out, index, (wx, wy), linear, wd, width);
            } else {
                blend_all::<PIXEL_BOX_TAPS>(srgb, out, index, (wx, wy), linear, wd, width);
            }
        }
        Filter::Bilinear => {
            // Every pixel's pairs of samples first, each pair one copy,
            // then the blends, which so vectorise.
            for (i, &k) in index.iter().enumerate() {
                let k = k as usize;
                pairs[0][2 * i..2 * i + 2].copy_from_slice(&samples[k..k + 2]);
                pairs[1][2 * i..2 * i + 2].copy_from_slice(&samples[k + wd..k + wd + 2]);
            }
            let [top, bottom] = &*pairs;
            let (top, bottom) = (&top[..2 * n], &bottom[..2 * n]);
            let out = &mut out[..n];
            for i in 0..n {
                let s = [top[2 * i], top[2 * i + 1], bottom[2 * i], bottom[2 * i + 1]];
                out[i] = bilinear(s, wx[i], wy[i]);
            }
        }
    }
    if has_nan {
        for (slot, c) in out.iter_mut().zip(coords) {
            if c.x.is_nan() {
                *slot = 0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reuse::rsvp::fixtures::*;
    use crate::reuse::rsvp::{RsvpKnobs, RsvpStore};

    #[test]
    fn a_grid_patch_box_from_its_corners_and_edges_holds_every_pixel() {
        let buffer = SampleBuffer::new(lattice());
        let knobs = RsvpKnobs::default();
        let transforms = [
            (1.0, 0.0, [0.0, 0.0]),
            (2.5557, 0.0, [0.0, 0.0]),
            (1.7, 0.5, [0.2, -0.1]),
            (40.0, -2.0, [0.0, 0.3]),
        ];
        let mut checked = 0;
        for (zoom, rotate, shear) in transforms {
            let pose = ViewportPose::new(tilted_camera(), off_centre(zoom, rotate, shear));
            let mapped = buffer.map(&pose, &knobs);
            let map = PixelMap::new(&pose);
            let mut coords = Vec::new();
            for (index, patch) in mapped.patches.iter().enumerate() {
                let Some(grid) = patch.grid.as_ref() else {
                    continue;
                };
                let x0 = (index % mapped.patches_x) as u32 * PATCH;
                let y0 = (index / mapped.patches_x) as u32 * PATCH;
                let cols = (pose.camera.width - x0).min(PATCH) as usize;
                let rows = (pose.camera.height - y0).min(PATCH) as usize;
                let out = nan_filled(&mut coords, cols * rows);
                let level = patch.level;
                buffer.patch_coords(&pose, &map, level, Some(grid), (x0, y0), cols, out);
                for filter in [
                    Filter::Nearest,
                    Filter::Bilinear,
                    Filter::Box,
                    Filter::PixelBox,
                ]
                .map(PatchFilter::fixed)
                .into_iter()
                .chain([PatchFilter::new(Filter::PixelBox, DVec2::new(2.3, 3.1))])
                {
                    let filter = &filter;
                    let every = pixels_box(filter, &coords).expect("a grid maps every pixel");
                    let quick = grid_pixels_box(filter, &coords, cols).expect("likewise");
                    assert!(
                        quick.c0 <= every.c0
                            && quick.r0 <= every.r0
                            && quick.c1 >= every.c1
                            && quick.r1 >= every.r1,
                        "patch ({x0}, {y0}), {filter:?}: {quick:?} misses some of {every:?}"
                    );
                    // Grown only by the interpolation's rounding.
                    assert!(quick.c1 - quick.c0 <= every.c1 - every.c0 + 2);
                    assert!(quick.r1 - quick.r0 <= every.r1 - every.r0 + 2);
                }
                checked += 1;
            }
        }
        assert!(checked > 3000, "{checked} patches");
    }

    /// At four samples a pixel the default box filter reads a level finer,
    /// at twice the oversampling: boxes of 10-30 samples a pixel, which are
    /// as dense as those knobs make them, and are read through assembled
    /// blocks, not sample by sample.
    #[test]
    fn antialiased_defaults_read_through_assembled_blocks() {
        let samples = crate::sampling::PixelSamples::new(4).unwrap();
        let store = RsvpStore::new(lattice(), RsvpKnobs::default_for(samples), samples);
        for zoom in [1.0, 1.7, 3.1] {
            let pose = ViewportPose::new(tilted_camera(), off_centre(zoom, 0.2, [0.0, 0.0]));
            let mapped = store.buffer.map(&pose, &store.knobs);
            let read_one_by_one = mapped.patches.iter().filter(|p| p.blocks.is_none()).count();
            assert_eq!(
                read_one_by_one,
                0,
                "zoom {zoom}: {read_one_by_one} of {} patches",
                mapped.patches.len()
            );
        }
    }

    /// At four samples a pixel the pixel box resamples in one pass, where
    /// the box filter takes four, and reads on each axis the level the
    /// shifted boxes read or the next coarser one (2-4 samples a pixel
    /// side against their 2.8-5.7): never a level finer, but where a shift
    /// moves a patch's densest pixel across a level's threshold.
    #[test]
    fn the_pixel_box_reads_in_one_pass_at_most_a_level_coarser_than_four_shifted_boxes() {
        let samples = crate::sampling::PixelSamples::new(4).unwrap();
        let knobs = RsvpKnobs::default_for(samples);
        let shifted = RsvpStore::new(
            lattice(),
            RsvpKnobs {
                filter: Filter::Box,
                ..RsvpKnobs::default()
            },
            samples,
        );
        let pixel_box = RsvpStore::new(lattice(), knobs, samples);
        let levels = |store: &RsvpStore, pose: &ViewportPose| -> Vec<Level> {
            let mapped = store.buffer.map(pose, &store.knobs);
            mapped.patches.iter().map(|p| p.level).collect()
        };
        for zoom in [1.0, 1.7, 3.1] {
            let pose = ViewportPose::new(tilted_camera(), off_centre(zoom, 0.2, [0.0, 0.0]));
            let shifts = shifted.shifted(&pose);
            assert_eq!((pixel_box.shifted(&pose).len(), shifts.len()), (1, 4));
            let (one, first) = (levels(&pixel_box, &pose), levels(&shifted, &shifts[0]));
            let mut finer = 0;
            for (a, b) in one.iter().zip(&first) {
                assert!(
                    b.x - a.x <= 1 && b.y - a.y <= 1,
                    "zoom {zoom}: level {a} against the boxes' {b}"
                );
                finer += usize::from(a.x > b.x || a.y > b.y);
            }
            assert!(
                finer * 20 <= one.len(),
                "zoom {zoom}: {finer} of {} patches read a finer level",
                one.len()
            );
        }
    }

    /// A still viewport at four samples a pixel traces at most 3 times
    /// its samples: the pixel box's level holds 2-4 samples a pixel side.
    /// At an oversampling of 1.19 (2.4-4.8 a side) it traced up to 4.4
    /// times them.
    #[test]
    fn a_still_viewport_at_four_samples_traces_at_most_three_times_them() {
        let samples = crate::sampling::PixelSamples::new(4).unwrap();
        let store = RsvpStore::new(lattice(), RsvpKnobs::default_for(samples), samples);
        let per_sample: Vec<(f64, f64)> = [1.0, 1.3, 1.7, 2.4, 3.1, 6.5]
            .into_iter()
            .map(|zoom| {
                let pose = ViewportPose::new(tilted_camera(), off_centre(zoom, 0.0, [0.0, 0.0]));
                let mapped = store.buffer.map(&pose, &store.knobs);
                let traced = (mapped.missing.len() as u64 * super::super::GROUP_SAMPLES) as f64;
                let pixels = f64::from(pose.camera.width * pose.camera.height);
                (zoom, traced / pixels / f64::from(samples.count()))
            })
            .collect();
        assert!(
            per_sample.iter().all(|&(_, n)| (1.0..=3.0).contains(&n)),
            "traced samples per pixel sample, by zoom: {per_sample:.2?}"
        );
    }
}

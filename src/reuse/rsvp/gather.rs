//! Pass 2 of a viewport frame: each pixel's colour from the samples its
//! filter reads, through dense windows of one level's samples, converted
//! to 8 bits.

use glam::{DVec2, Vec3};
use rayon::prelude::*;

use super::{
    filter::{bilinear, filter_origin, filter_split},
    lattice::{owned_positions, wrap},
    map::Mapped,
    store::{tile_key, TileCache, TILE_COLS, TILE_SAMPLES},
    viewport::PixelMap,
    Filter, Level, SampleBuffer, ViewportPose, REGION,
};
use crate::render::{srgb_table, Frame};

impl SampleBuffer {
    /// A traced (or null: black) sample, with the tile cache.
    #[inline(always)]
    fn read(&self, cache: &mut TileCache, level: Level, col: i64, row: i64) -> Vec3 {
        let row = row.clamp(0, self.lattice.last_row(level.y));
        let (owner, col, row) = self.lattice.owner(level, col, row);
        let (key, sample, _) = tile_key(col, row);
        let store = &self.levels[owner.index()];
        match cache.tile(store, owner, key) {
            u32::MAX => Vec3::ZERO,
            tile => store.colors[tile as usize * TILE_SAMPLES + sample],
        }
    }

    /// Pass 2: each pixel's colour from its samples. The samples under a
    /// run of neighbouring regions of one level are first copied into one
    /// dense window, so the filter reads plain arrays. A window per run
    /// rather than per region copies each row as one long run per owner
    /// instead of many runs of a few cache lines (about 18% off E2's
    /// gather). Filling windows is still about half of the gather: the
    /// loads of the owners' samples stall.
    pub(super) fn gather(
        &self,
        pose: &ViewportPose,
        mapped: &Mapped,
        filter: Filter,
        linear: bool,
    ) -> (Option<Frame>, image::RgbImage) {
        let (w, h) = (pose.camera.width as usize, pose.camera.height as usize);
        let map = PixelMap::new(pose);
        let band = w * REGION as usize;
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
        pixel_bands.resize_with(h.div_ceil(REGION as usize), || &mut []);
        bytes
            .par_chunks_mut(band * 3)
            .zip(pixel_bands.into_par_iter())
            .enumerate()
            // Scratch per rayon job rather than per band: a band's window
            // is up to about a megabyte, which a fresh allocation would
            // zero (and fault in) again for each of the 30 bands.
            .for_each_init(
                BandScratch::default,
                |scratch, (band_index, (out, linear_out))| {
                    let BandScratch { window, coords } = scratch;
                    let mut cache = TileCache::new();
                    let mut colors = [Vec3::ZERO; (REGION * REGION) as usize];
                    let srgb = srgb_table();
                    let y0 = band_index * REGION as usize;
                    let rows = (h - y0).min(REGION as usize);
                    let regions =
                        &mapped.regions[band_index * mapped.regions_x..][..mapped.regions_x];
                    // Every region's coordinates first (region after region,
                    // each row-major), for the boxes that decide the runs.
                    coords.resize(w * rows, DVec2::NAN);
                    let spans: Vec<RegionSpan> = regions
                        .iter()
                        .enumerate()
                        .map(|(rx, region)| {
                            let x0 = rx * REGION as usize;
                            let cols = (w - x0).min(REGION as usize);
                            let coords = &mut coords[x0 * rows..(x0 + cols) * rows];
                            // A grid writes every pixel; exact mapping leaves
                            // pixels without a ray as they were.
                            if region.grid.is_none() {
                                coords.fill(DVec2::NAN);
                            }
                            self.region_coords(
                                pose,
                                &map,
                                region.level,
                                region.grid.as_ref(),
                                (x0 as u32, y0 as u32),
                                cols,
                                coords,
                            );
                            RegionSpan::new(filter, region.level, cols, rows, coords)
                        })
                        .collect();
                    let mut rx = 0;
                    while rx < spans.len() {
                        let first = &spans[rx];
                        let mut end = rx + 1;
                        if let Some(mut joined) = first.window.filter(|_| !first.direct) {
                            let mut area = joined.area();
                            while let Some(next) = spans.get(end).filter(|n| n.level == first.level)
                            {
                                let Some(b) = next.window.filter(|_| !next.direct) else {
                                    break;
                                };
                                let union = joined.union(&b);
                                // A rotated view's band runs diagonally: its
                                // box would copy far more than its regions read.
                                if union.area() * 4 > (area + b.area()) * 5 {
                                    break;
                                }
                                (joined, area) = (union, area + b.area());
                                end += 1;
                            }
                            self.fill_window(&mut cache, first.level, &joined, window);
                        }
                        for (rx, span) in spans.iter().enumerate().take(end).skip(rx) {
                            let x0 = rx * REGION as usize;
                            let cols = span.cols;
                            let region_coords = &coords[x0 * rows..(x0 + cols) * rows];
                            let colors = &mut colors[..cols * rows];
                            match span.window {
                                None => colors.fill(Vec3::ZERO),
                                Some(_) if span.direct => {
                                    for (slot, c) in colors.iter_mut().zip(region_coords) {
                                        *slot = if c.x.is_nan() {
                                            Vec3::ZERO
                                        } else {
                                            self.filter(&mut cache, span.level, filter, c.x, c.y)
                                        };
                                    }
                                }
                                Some(_) => gather_region(window, filter, region_coords, colors),
                            }
                            // Whole region rows at once: no per-pixel index checks.
                            for (j, line) in colors.chunks_exact(cols).enumerate() {
                                let p = j * w + x0;
                                for (byte, c) in
                                    out[p * 3..(p + cols) * 3].chunks_exact_mut(3).zip(line)
                                {
                                    byte[0] = srgb.encode(c.x);
                                    byte[1] = srgb.encode(c.y);
                                    byte[2] = srgb.encode(c.z);
                                }
                                if let Some(slots) = linear_out.get_mut(p..p + cols) {
                                    slots.copy_from_slice(line);
                                }
                            }
                        }
                        rx = end;
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

    /// Copies the samples of `level` in `bounds` (rows clamped to the
    /// lattice) into `window`.
    fn fill_window(
        &self,
        cache: &mut TileCache,
        level: Level,
        bounds: &SampleBox,
        window: &mut Window,
    ) {
        let (wd, ht) = (bounds.width(), bounds.height());
        window.col = bounds.c0;
        window.row = bounds.r0;
        window.width = wd;
        // No clearing: copy_row writes every entry of a row (the owners'
        // positions tile it), and a band's windows are up to ~1 MB.
        window.samples.resize(wd * ht, Vec3::ZERO);
        let last_row = self.lattice.last_row(level.y);
        for (j, line) in window.samples.chunks_mut(wd).enumerate() {
            let row = (bounds.r0 + j as i64).clamp(0, last_row);
            self.copy_row(cache, level, bounds.c0, row, line);
        }
    }

    /// Samples (col.., row) of `level` whichever level owns them (black
    /// where nothing was traced). The row belongs to one elevation level;
    /// along it, each coarser azimuth level owns every 2^k-th sample, so
    /// each owner's slots go straight into `out` at their stride.
    fn copy_row(&self, cache: &mut TileCache, level: Level, col: i64, row: i64, out: &mut [Vec3]) {
        let sy = row.trailing_zeros().min(level.y);
        let oy = level.y - sy;
        let slot_row = (row >> sy) >> u32::from(oy > 0);
        let n = out.len() as i64;
        for ox in 0..=level.x {
            let sx = level.x - ox;
            let (period, offset) = owned_positions(level.x, ox);
            let first = col + (offset - col).rem_euclid(period);
            if first - col >= n {
                continue;
            }
            let slot = (first >> sx) >> u32::from(ox > 0);
            let owner = Level::new(ox, oy);
            let out = &mut out[(first - col) as usize..];
            self.copy_run(cache, owner, slot, slot_row, out, period as usize);
        }
    }

    /// The slots (col.., row) of `level` as its tiles hold them, into every
    /// `stride`th entry of `out` (black where no tile is), in runs. A
    /// window's rows come in pairs per tile row and span a tile or two:
    /// `cache` saves most of the hash map lookups.
    fn copy_run(
        &self,
        cache: &mut TileCache,
        level: Level,
        col: i64,
        row: i64,
        out: &mut [Vec3],
        stride: usize,
    ) {
        let store = &self.levels[level.index()];
        let columns = self.lattice.slot_columns(level);
        let count = out.len().div_ceil(stride);
        let mut i = 0;
        while i < count {
            let wc = wrap(col + i as i64, columns);
            let (key, sample, _) = tile_key(wc, row);
            let run = (count - i)
                .min((TILE_COLS - (wc & (TILE_COLS - 1))) as usize)
                .min((columns - wc) as usize);
            let tile = cache.tile(store, level, key);
            let source = (tile != u32::MAX).then(|| {
                let start = tile as usize * TILE_SAMPLES + sample;
                &store.colors[start..start + run]
            });
            match (source, stride) {
                (None, 1) => out[i..i + run].fill(Vec3::ZERO),
                (Some(source), 1) => out[i..i + run].copy_from_slice(source),
                (None, _) => scatter(&mut out[i * stride..], &BLACK[..run], stride),
                (Some(source), _) => scatter(&mut out[i * stride..], source, stride),
            }
            i += run;
        }
    }

    #[inline(always)]
    fn filter(&self, cache: &mut TileCache, level: Level, filter: Filter, x: f64, y: f64) -> Vec3 {
        let ((c, fx), (r, fy)) = (filter_split(filter, x), filter_split(filter, y));
        let (c, r) = (c as i64, r as i64);
        match filter {
            Filter::Nearest => self.read(cache, level, c, r),
            Filter::Box => {
                (self.read(cache, level, c, r)
                    + self.read(cache, level, c + 1, r)
                    + self.read(cache, level, c, r + 1)
                    + self.read(cache, level, c + 1, r + 1))
                    * 0.25
            }
            Filter::Bilinear => bilinear(
                [
                    self.read(cache, level, c, r),
                    self.read(cache, level, c + 1, r),
                    self.read(cache, level, c, r + 1),
                    self.read(cache, level, c + 1, r + 1),
                ],
                fx as f32,
                fy as f32,
            ),
        }
    }
}

/// A run's worth of black, for the samples of a tile never allocated.
static BLACK: [Vec3; TILE_COLS as usize] = [Vec3::ZERO; TILE_COLS as usize];

/// Writes `source` into every `stride`th entry of `out` from its first
/// (`out` reaches the last). The window's usual strides (2, 4, 8: a coarser
/// owner's samples among a finer level's) get loops of fixed step, 8% fewer
/// instructions in filling E2's windows than chunks of a variable length.
#[inline]
fn scatter(out: &mut [Vec3], source: &[Vec3], stride: usize) {
    match stride {
        2 => scatter_by::<2>(out, source),
        4 => scatter_by::<4>(out, source),
        8 => scatter_by::<8>(out, source),
        _ => {
            for (chunk, &sample) in out.chunks_mut(stride).zip(source) {
                chunk[0] = sample;
            }
        }
    }
}

#[inline(always)]
fn scatter_by<const STRIDE: usize>(out: &mut [Vec3], source: &[Vec3]) {
    for (slot, &sample) in out.iter_mut().step_by(STRIDE).zip(source) {
        *slot = sample;
    }
}

/// What pass 2 reuses from band to band.
#[derive(Default)]
struct BandScratch {
    window: Window,
    /// The band's pixels' lattice coordinates.
    coords: Vec<DVec2>,
}

/// Samples of one level copied into a dense row-major array, `width`
/// wide, its first entry the sample (col, row).
#[derive(Default)]
struct Window {
    pub(super) col: i64,
    pub(super) row: i64,
    pub(super) width: usize,
    pub(super) samples: Vec<Vec3>,
}

/// The samples (c0..=c1, r0..=r1) of a level.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SampleBox {
    c0: i64,
    r0: i64,
    c1: i64,
    r1: i64,
}

impl SampleBox {
    fn width(&self) -> usize {
        (self.c1 - self.c0 + 1) as usize
    }

    fn height(&self) -> usize {
        (self.r1 - self.r0 + 1) as usize
    }

    fn area(&self) -> usize {
        self.width() * self.height()
    }

    fn union(&self, other: &SampleBox) -> SampleBox {
        SampleBox {
            c0: self.c0.min(other.c0),
            r0: self.r0.min(other.r0),
            c1: self.c1.max(other.c1),
            r1: self.r1.max(other.r1),
        }
    }
}

/// What pass 2 needs to know of a region before reading its samples.
struct RegionSpan {
    pub(super) level: Level,
    pub(super) cols: usize,
    /// The samples its filter reads; None: no pixel has a ray.
    pub(super) window: Option<SampleBox>,
    /// Zoomed far out: a window would copy far more samples than the
    /// region's pixels read, so each pixel reads its own.
    pub(super) direct: bool,
}

impl RegionSpan {
    fn new(filter: Filter, level: Level, cols: usize, rows: usize, coords: &[DVec2]) -> Self {
        // Filter origins grow with the coordinates: the window spans the
        // origins of the coordinates' box (min and max skip NaN).
        let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for c in coords {
            lo = lo.min(*c);
            hi = hi.max(*c);
        }
        let window = (lo.x <= hi.x).then(|| {
            let (c0, r0) = filter_origin(filter, lo.x, lo.y);
            let (c1, r1) = filter_origin(filter, hi.x, hi.y);
            SampleBox {
                c0,
                r0,
                c1: c1 + 1,
                r1: r1 + 1,
            }
        });
        let direct = window.is_some_and(|b| b.area() > 16 * cols * rows);
        RegionSpan {
            level,
            cols,
            window,
            direct,
        }
    }
}

/// Filters one region's pixels (`coords`: their lattice coordinates at the
/// window's level, NaN for no ray) from `window`, which holds every sample
/// they read, into `out` (`coords`' length).
fn gather_region(window: &Window, filter: Filter, coords: &[DVec2], out: &mut [Vec3]) {
    let wd = window.width;
    let samples = &window.samples;
    // Window index and weights of every pixel first, in straight-line f64
    // code (exact: whole numbers and multiples of 2^-16) that vectorises;
    // NaN pixels get index 0 and are blacked out last.
    const N: usize = (REGION * REGION) as usize;
    let (mut index, mut wx, mut wy) = ([0u32; N], [0f32; N], [0f32; N]);
    let (c0f, r0f, wdf) = (window.col as f64, window.row as f64, wd as f64);
    let mut has_nan = false;
    for (((c, k), fx), fy) in coords.iter().zip(&mut index).zip(&mut wx).zip(&mut wy) {
        has_nan |= c.x.is_nan();
        let (ox, x) = filter_split(filter, c.x);
        let (oy, y) = filter_split(filter, c.y);
        *k = ((oy - r0f) * wdf + (ox - c0f)) as u32;
        *fx = x as f32;
        *fy = y as f32;
    }
    let n = coords.len();
    let (index, wx, wy) = (&index[..n], &wx[..n], &wy[..n]);
    // One loop per filter, without branches inside.
    match filter {
        Filter::Nearest => {
            for (slot, &k) in out.iter_mut().zip(index) {
                *slot = samples[k as usize];
            }
        }
        Filter::Box => {
            for (slot, &k) in out.iter_mut().zip(index) {
                let k = k as usize;
                let (top, bottom) = (&samples[k..k + 2], &samples[k + wd..k + wd + 2]);
                *slot = (top[0] + top[1] + bottom[0] + bottom[1]) * 0.25;
            }
        }
        Filter::Bilinear => {
            for (((slot, &k), &fx), &fy) in out.iter_mut().zip(index).zip(wx).zip(wy) {
                let k = k as usize;
                let (top, bottom) = (&samples[k..k + 2], &samples[k + wd..k + wd + 2]);
                *slot = bilinear([top[0], top[1], bottom[0], bottom[1]], fx, fy);
            }
        }
    }
    if has_nan {
        for (slot, c) in out.iter_mut().zip(coords) {
            if c.x.is_nan() {
                *slot = Vec3::ZERO;
            }
        }
    }
}

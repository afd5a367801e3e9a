//! Reconstruction: the filters a viewport pixel is made with, the knobs
//! of the level choice, the exact sub-sample grid both passes share, and
//! the sample codes pass 2 blends.

use glam::{DVec2, Vec3, Vec3A};

use crate::color::SrgbTable;
use crate::sampling::PixelSamples;

/// How a viewport pixel's colour is made from buffer samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Filter {
    /// The nearest sample.
    Nearest,
    /// The four samples around the pixel centre, weighted by distance.
    #[default]
    Bilinear,
    /// The mean of the 2x2 samples around the pixel centre one level finer
    /// than the pixel's footprint needs: a box over the pixel, four samples.
    Box,
    /// A box exactly as wide as the pixel on each axis, centred on it, one
    /// level finer than the pixel's footprint needs (at least 2.4 samples a
    /// side at its default oversampling): every sample whose cell it
    /// covers, weighted by how much of the cell it covers. One resampling
    /// pass antialiases where `box` needs a pass per sub-pixel shift.
    PixelBox,
}

impl Filter {
    /// Samples the filter reads along each axis (the most, for the pixel
    /// box: see [`PatchFilter::sides`]).
    pub(super) fn side(self) -> i64 {
        match self {
            Filter::Nearest => 1,
            Filter::Bilinear | Filter::Box => 2,
            Filter::PixelBox => PIXEL_BOX_TAPS as i64,
        }
    }

    /// Levels finer than the pixel's footprint needs that the filter reads.
    pub(super) fn finer_levels(self) -> i32 {
        match self {
            Filter::Nearest | Filter::Bilinear => 0,
            Filter::Box | Filter::PixelBox => 1,
        }
    }
}

impl std::str::FromStr for Filter {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "nearest" => Ok(Filter::Nearest),
            "bilinear" => Ok(Filter::Bilinear),
            "box" => Ok(Filter::Box),
            "pixel-box" => Ok(Filter::PixelBox),
            other => Err(format!(
                "unknown filter '{other}' (expected nearest, bilinear, box or pixel-box)"
            )),
        }
    }
}

impl std::fmt::Display for Filter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Filter::Nearest => "nearest",
            Filter::Bilinear => "bilinear",
            Filter::Box => "box",
            Filter::PixelBox => "pixel-box",
        })
    }
}

/// The resampling knobs; each one's cost and error is measured by `retrace
/// bench --only knobs`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RsvpKnobs {
    pub filter: Filter,
    /// Buffer samples per viewport pixel (per side) the level choice aims
    /// for at least.
    pub oversample: f64,
    /// Levels added to the chosen one (negative: coarser, cheaper).
    pub level_bias: i32,
}

impl Default for RsvpKnobs {
    /// The defaults at one sample a pixel; [`RsvpKnobs::default_for`] gives
    /// them at any count.
    fn default() -> Self {
        RsvpKnobs {
            filter: Filter::Bilinear,
            oversample: DEFAULT_OVERSAMPLE,
            level_bias: 0,
        }
    }
}

/// Buffer samples a viewport pixel (or shifted pixel, antialiased), per
/// side, that the levels are chosen for by default. Below 1 some pixels
/// read fewer than one sample each, and the filter spreads them: against a
/// converged reference that still measured closer to the truth than direct
/// renders at the same samples a pixel, on every viewport scene shipped
/// (E2, E4, the bunnies; 0.8-1.7 dB better at one sample a pixel, 0.2-1.2
/// at four), at about twice the speed of oversampling 1 (docs/RESULTS.md).
const DEFAULT_OVERSAMPLE: f64 = 0.71;

/// The pixel box's oversampling up to four samples a pixel: its level
/// then holds 2-4 samples a pixel side at four, 4-16 a pixel. Blending in
/// linear colour, as the direct render does, E2 and E4 beat the direct
/// render there; at 0.85 E4's worst frame fell 0.6 dB short
/// (docs/RESULTS.md).
const PIXEL_BOX_OVERSAMPLE: f64 = 1.0;

/// The pixel box's oversampling above four samples a pixel (times the
/// square root of a quarter of them: 4.8-9.5 samples a pixel side at
/// sixteen). At 1 E2 at sixteen fell 0.7 dB short of the direct render,
/// whose sixteen strata resolve the horizon better than the regular
/// lattice at 4-8 a side (docs/RESULTS.md).
const PIXEL_BOX_OVERSAMPLE_ABOVE_FOUR: f64 = 1.19;

impl RsvpKnobs {
    /// The default knobs at `samples` a pixel: bilinear at one sample a
    /// pixel; from two to sixteen the pixel box, over 2-4 samples a
    /// pixel side at four and 4.8-9.5 at sixteen, in one pass more
    /// accurate than the direct render and than shifted boxes, and
    /// faster; above sixteen, where the pixel would be wider than the
    /// box's taps, the box filter (over one level finer) at each shift
    /// (docs/RESULTS.md).
    pub fn default_for(samples: PixelSamples) -> RsvpKnobs {
        let filter = match samples.count() {
            1 => Filter::Bilinear,
            2..=16 => Filter::PixelBox,
            _ => Filter::Box,
        };
        RsvpKnobs::with_filter(filter, samples)
    }

    /// The default knobs with `filter` at `samples` a pixel: the pixel
    /// box at its own oversampling, which sets the box's density
    /// directly.
    pub fn with_filter(filter: Filter, samples: PixelSamples) -> RsvpKnobs {
        let oversample = match filter {
            Filter::PixelBox if samples.count() > 4 => PIXEL_BOX_OVERSAMPLE_ABOVE_FOUR,
            Filter::PixelBox => PIXEL_BOX_OVERSAMPLE,
            _ => DEFAULT_OVERSAMPLE,
        };
        RsvpKnobs {
            filter,
            oversample,
            level_bias: 0,
        }
    }

    /// The sub-pixel shifts a viewport is resampled at, with `samples` a
    /// pixel: one per sample, or one for the pixel box, which reads every
    /// sample its pixel covers at once.
    pub(crate) fn shifts(&self, samples: PixelSamples) -> PixelSamples {
        if self.filter == Filter::PixelBox {
            PixelSamples::ONE
        } else {
            samples
        }
    }

    /// What the oversampling is multiplied by on each axis with `samples`
    /// a pixel: the square root of the shifts (each shift's pixel reads
    /// at the oversampling), and for the pixel box the square root of a
    /// quarter of the samples, at least 1 (its oversampling is set at
    /// four).
    pub fn density_scale(&self, samples: PixelSamples) -> f64 {
        if self.filter == Filter::PixelBox {
            (f64::from(samples.count()) / 4.0).max(1.0).sqrt()
        } else {
            f64::from(samples.count()).sqrt()
        }
    }

    /// Buffer samples a viewport pixel covers at the levels these knobs
    /// choose, give or take the rounding up to a level (a factor of up to
    /// four): the oversampling squared, at least one, times four for each
    /// level the box filter and a positive bias add. What a patch's box of
    /// samples is weighed against when choosing how to work on it.
    pub(crate) fn samples_per_pixel(&self) -> f64 {
        let finer = self.level_bias.max(0) + self.filter.finer_levels();
        self.oversample.max(1.0).powi(2) * 4f64.powi(finer)
    }

    /// The knobs set away from their defaults at `samples` a pixel, in
    /// words ("oversample 0.9, level bias -1"); None at the defaults.
    pub fn changes(&self, samples: PixelSamples) -> Option<String> {
        let default = RsvpKnobs::default_for(samples);
        let mut changed = Vec::new();
        if self.filter != default.filter {
            changed.push(format!("{} filter", self.filter));
        }
        if self.oversample != RsvpKnobs::with_filter(self.filter, samples).oversample {
            changed.push(format!("oversample {}", self.oversample));
        }
        if self.level_bias != default.level_bias {
            changed.push(format!("level bias {:+}", self.level_bias));
        }
        (!changed.is_empty()).then(|| changed.join(", "))
    }
}

/// A sample as pass 2 keeps and blends it: each channel's sRGB quarter
/// code ([`SrgbTable::encode_quarters`], 10 bits), red lowest, in one
/// word: a third of three f32's bytes to copy, blended a channel at a
/// time over whole lanes, and a shift from the 8-bit output, where three
/// f32 would each take a table lookup.
///
/// Filters so blend in sRGB, not linear, space, which on its own barely
/// changes the error against the direct render. The codes' quarter steps
/// round a blend a little (by one step, where a gradient's exact value
/// lies near a byte's edge), far less than whole bytes would. Exact where
/// blending in linear colour is: a pixel on a sample, or amid equal ones,
/// shows that sample's own byte.
pub(super) type SampleCode = u32;

const CODE_BITS: u32 = 10;
const CODE_MASK: u32 = (1 << CODE_BITS) - 1;
/// Where each channel's code starts.
const CODE_SHIFTS: [u32; 3] = [0, CODE_BITS, 2 * CODE_BITS];

/// A linear colour's code.
#[inline(always)]
pub(super) fn encode(srgb: &SrgbTable, c: Vec3) -> SampleCode {
    srgb.encode_quarters(c.x)
        | srgb.encode_quarters(c.y) << CODE_SHIFTS[1]
        | srgb.encode_quarters(c.z) << CODE_SHIFTS[2]
}

/// The 8-bit sRGB pixel a code (a sample's, or a blend's) shows.
#[inline(always)]
pub(super) fn rgb8(code: SampleCode) -> [u8; 3] {
    CODE_SHIFTS.map(|shift| ((code >> shift & CODE_MASK) >> 2) as u8)
}

/// The linear colour a code stands for.
#[inline(always)]
pub(super) fn decode(srgb: &SrgbTable, code: SampleCode) -> Vec3 {
    Vec3::from_array(CODE_SHIFTS.map(|shift| srgb.decode_quarters(code >> shift & CODE_MASK)))
}

/// One channel of a code, as a float (exact).
#[inline(always)]
fn channel(code: SampleCode, shift: u32) -> f32 {
    (code >> shift & CODE_MASK) as i32 as f32
}

/// A channel's bilinear blend of codes `a b` (top) and `c d` (bottom),
/// rounded to a code. A zero weight and equal samples both give a sample's
/// code exactly, so a pixel on a sample, or amid equal ones, shows the
/// sample's byte. Straight-line float code, so loops of it vectorise.
#[inline(always)]
fn bilinear_channel(a: f32, b: f32, c: f32, d: f32, fx: f32, fy: f32) -> SampleCode {
    let top = a + (b - a) * fx;
    let bottom = c + (d - c) * fx;
    let v = top + (bottom - top) * fy;
    // Round to nearest: v (0..1024) plus 2^23 holds it in its low bits,
    // where `as` would saturate one lane at a time.
    (v + 8_388_608.0).to_bits() & CODE_MASK
}

/// The bilinear blend of four codes (top left, top right, bottom left,
/// bottom right).
#[inline(always)]
pub(super) fn bilinear(s: [SampleCode; 4], fx: f32, fy: f32) -> SampleCode {
    let mut blend = 0;
    for shift in CODE_SHIFTS {
        let [a, b, c, d] = s.map(|code| channel(code, shift));
        blend |= bilinear_channel(a, b, c, d, fx, fy) << shift;
    }
    blend
}

/// The mean of four codes, rounded (exact in integers).
#[inline(always)]
pub(super) fn mean(s: [SampleCode; 4]) -> SampleCode {
    let mut blend = 0;
    for shift in CODE_SHIFTS {
        let sum: u32 = s.iter().map(|code| code >> shift & CODE_MASK).sum();
        blend |= (sum + 2) >> 2 << shift;
    }
    blend
}

/// Samples [`Filter::PixelBox`] reads along each axis at most: a box up to
/// 11 samples wide, as the pixel at sixteen samples a pixel (4.8-9.5 a
/// side at the default oversampling).
pub(super) const PIXEL_BOX_TAPS: usize = 12;

/// Taps of the narrow pixel box, up to 5 samples wide: enough at four
/// samples a pixel (2-4 a side), and a quarter of the wide box's
/// blending work.
pub(super) const PIXEL_BOX_NARROW_TAPS: usize = 6;

/// Whether a pixel box `width` samples wide fits the narrow box's taps.
#[inline(always)]
pub(super) fn is_narrow((wx, wy): (f32, f32)) -> bool {
    wx.max(wy) <= (PIXEL_BOX_NARROW_TAPS - 1) as f32
}

/// The pixel box's blend of its codes (`read(i, j)`: column i, row j),
/// its start `fx`, `fy` past the first tap's cell's start and its width
/// `wx`, `wy` in samples: each tap's linear colour weighted by how much
/// of its cell the box covers, as the direct render's samples average in
/// linear colour. Reads only the taps the box covers ([`box_taps`]).
#[inline(always)]
pub(super) fn pixel_box(
    srgb: &SrgbTable,
    mut read: impl FnMut(usize, usize) -> SampleCode,
    start: (f32, f32),
    width: (f32, f32),
) -> SampleCode {
    let read = |i, j| decode_simd(srgb, read(i, j));
    let blend = if is_narrow(width) {
        pixel_box_of::<PIXEL_BOX_NARROW_TAPS>(read, start, width)
    } else {
        pixel_box_of::<PIXEL_BOX_TAPS>(read, start, width)
    };
    encode(srgb, blend.into())
}

/// A code's linear colour, in a SIMD register.
#[inline(always)]
pub(super) fn decode_simd(srgb: &SrgbTable, code: SampleCode) -> Vec3A {
    decode(srgb, code).into()
}

/// [`pixel_box`] over linear colours (`read(i, j)`), with room for `TAPS`
/// taps a side (the box at most `TAPS - 1` samples wide).
#[inline(always)]
pub(super) fn pixel_box_of<const TAPS: usize>(
    mut read: impl FnMut(usize, usize) -> Vec3A,
    (fx, fy): (f32, f32),
    (wx, wy): (f32, f32),
) -> Vec3A {
    let weights = |f: f32, w: f32| -> [f32; TAPS] {
        let (end, scale) = (f + w, 1.0 / w);
        std::array::from_fn(|i| {
            let i = i as f32;
            (end.min(i + 1.0) - f.max(i)).max(0.0) * scale
        })
    };
    let (nx, ny) = (box_taps(fx, wx), box_taps(fy, wy));
    let (wx, wy) = (weights(fx, wx), weights(fy, wy));
    let mut sum = Vec3A::ZERO;
    for (j, wy) in wy.iter().enumerate().take(ny) {
        let mut across = Vec3A::ZERO;
        for (i, wx) in wx.iter().enumerate().take(nx) {
            across += *wx * read(i, j);
        }
        sum += *wy * across;
    }
    sum
}

/// Taps a pixel box `w` samples wide covers, starting `f` into its first
/// tap's cell (both exact: multiples of 2^-16 below 16).
#[inline(always)]
pub(super) fn box_taps(f: f32, w: f32) -> usize {
    (f + w).ceil() as usize
}

/// Sub-sample steps per sample on the filter's grid.
const FRACTION_ONE: f64 = 65536.0;

/// A lattice coordinate on the filter's grid (rounded to 2^-16 of a
/// sample), its first read `origin_shift` grid steps away: the sample the
/// filter starts from (the one below for bilinear and box, the nearest for
/// nearest, the one whose cell holds the start for the pixel box) and the
/// fraction past the sample below (for the pixel box, past that cell's
/// start). Every step is exact in f64, so pass 1 (which samples to trace)
/// and pass 2 (which to read) always agree; a pixel within 2^-17 of a
/// sample shows that sample bit for bit. The shift is looked up once a
/// patch, out of the loop, which so stays straight-line code and
/// vectorises.
#[inline(always)]
pub(super) fn split_from(origin_shift: f64, x: f64) -> (f64, f64) {
    let q = (x * FRACTION_ONE + 0.5).floor() + origin_shift;
    let origin = (q * (1.0 / FRACTION_ONE)).floor();
    (origin, (q - origin * FRACTION_ONE) * (1.0 / FRACTION_ONE))
}

/// A filter as one patch applies it: the pixel box as wide as the
/// patch's pixels on each axis, at whatever density its level gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PatchFilter {
    pub(super) filter: Filter,
    /// Per axis, where the first read lies from a pixel's coordinate, in
    /// steps of the filter's grid.
    shift: [f64; 2],
    /// Per axis, the pixel box's width in samples (a multiple of 2^-15).
    width: [f32; 2],
}

impl PatchFilter {
    /// `filter` over pixels `footprint` samples of the patch's level wide
    /// on each axis. The pixel box's width is rounded to the filter's
    /// grid, so both passes find the same taps, and kept to
    /// 1..=[`PIXEL_BOX_TAPS`] - 1 samples.
    pub(super) fn new(filter: Filter, footprint: DVec2) -> PatchFilter {
        let max = (PIXEL_BOX_TAPS - 1) as f64;
        let axis = |w: f64| -> (f64, f32) {
            let w = if w.is_finite() {
                w.clamp(1.0, max)
            } else {
                max
            };
            let half = (0.5 * w * FRACTION_ONE).round();
            (
                0.5 * FRACTION_ONE - half,
                (2.0 * half / FRACTION_ONE) as f32,
            )
        };
        match filter {
            Filter::PixelBox => {
                let ((sx, wx), (sy, wy)) = (axis(footprint.x), axis(footprint.y));
                PatchFilter {
                    filter,
                    shift: [sx, sy],
                    width: [wx, wy],
                }
            }
            _ => PatchFilter::fixed(filter),
        }
    }

    /// `filter` at its fixed width (the pixel box as wide as it reads at
    /// most).
    pub(super) fn fixed(filter: Filter) -> PatchFilter {
        // Where the first read lies from the coordinate, in steps of the
        // filter's grid.
        let shift = match filter {
            Filter::Nearest => 0.5 * FRACTION_ONE,
            Filter::Bilinear | Filter::Box => 0.0,
            Filter::PixelBox => {
                return PatchFilter::new(filter, DVec2::splat((PIXEL_BOX_TAPS - 1) as f64))
            }
        };
        PatchFilter {
            filter,
            shift: [shift; 2],
            // Unread: only the pixel box weighs its taps by width.
            width: [1.0; 2],
        }
    }

    /// The pixel box's width in samples across and down.
    #[inline(always)]
    pub(super) fn width(&self) -> (f32, f32) {
        (self.width[0], self.width[1])
    }

    /// Where the filter's first read lies from the coordinate across and
    /// down, in steps of the filter's grid (see [`split_from`]).
    #[inline(always)]
    pub(super) fn shift(&self) -> (f64, f64) {
        (self.shift[0], self.shift[1])
    }

    /// The sample the filter starts from (top-left for bilinear and box)
    /// and the fractions past it, across and down.
    #[inline(always)]
    pub(super) fn split(&self, x: f64, y: f64) -> ((f64, f64), (f64, f64)) {
        (split_from(self.shift[0], x), split_from(self.shift[1], y))
    }

    /// The sample the filter starts from.
    #[inline]
    pub(super) fn origin(&self, x: f64, y: f64) -> (i64, i64) {
        let ((c, _), (r, _)) = self.split(x, y);
        (c as i64, r as i64)
    }

    /// The most samples the filter reads along each axis.
    pub(super) fn sides(&self) -> (i64, i64) {
        match self.filter {
            // The start lies at most 1 - 2^-16 into the first tap's cell.
            Filter::PixelBox => {
                let most = |w: f32| box_taps(1.0 - 1.0 / FRACTION_ONE as f32, w) as i64;
                (most(self.width[0]), most(self.width[1]))
            }
            filter => (filter.side(), filter.side()),
        }
    }
}

/// Calls `each(column, row)` for every sample a pixel at lattice
/// coordinates (x, y) reads: [`for_each_read_run`]'s runs, sample by
/// sample.
#[inline(always)]
pub(super) fn for_each_read(
    filter: &PatchFilter,
    pixel: (f64, f64),
    last_row: i64,
    mut each: impl FnMut(i64, i64),
) {
    for_each_read_run(filter, pixel, last_row, |col, row, run| {
        for i in 0..run {
            each(col + i, row);
        }
    });
}

/// Calls `each(column, row, run)` for every row of samples a pixel at
/// lattice coordinates (x, y) reads, `run` samples from `column`: the
/// filter's square of samples from its origin (for the pixel box, the
/// taps it covers), row by row; rows clamped to the lattice
/// (`0..=last_row`), as reads are. The filter is matched once a pixel,
/// so the 2x2 filters keep a fixed two-run body.
#[inline(always)]
pub(super) fn for_each_read_run(
    filter: &PatchFilter,
    (x, y): (f64, f64),
    last_row: i64,
    mut each: impl FnMut(i64, i64, i64),
) {
    let ((col, fx), (row, fy)) = filter.split(x, y);
    let (col, row) = (col as i64, row as i64);
    match filter.filter {
        Filter::Nearest => each(col, row.clamp(0, last_row), 1),
        Filter::Bilinear | Filter::Box => {
            each(col, row.clamp(0, last_row), 2);
            each(col, (row + 1).clamp(0, last_row), 2);
        }
        Filter::PixelBox => {
            let (wx, wy) = filter.width();
            let nx = box_taps(fx as f32, wx) as i64;
            let ny = box_taps(fy as f32, wy) as i64;
            for j in 0..ny {
                each(col, (row + j).clamp(0, last_row), nx);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::{encode_srgb, srgb_table};

    #[test]
    fn blends_show_a_sample_s_own_byte_where_it_alone_counts() {
        let srgb = srgb_table();
        let mut rng = crate::rng::SplitMix64(17);
        let colour = |rng: &mut crate::rng::SplitMix64| {
            Vec3::new(rng.unit(), rng.unit(), rng.unit()).powf(2.2)
        };
        for _ in 0..2000 {
            let c = colour(&mut rng);
            let others = [colour(&mut rng), colour(&mut rng), colour(&mut rng)];
            let code = encode(srgb, c);
            assert_eq!(rgb8(code), c.to_array().map(encode_srgb), "{c}");
            assert_eq!(rgb8(encode(srgb, decode(srgb, code))), rgb8(code));
            let [x, y, z] = others.map(|o| encode(srgb, o));
            // A zero weight, or four equal samples: the sample's code.
            assert_eq!(bilinear([code, x, y, z], 0.0, 0.0), code);
            assert_eq!(bilinear([x, code, y, z], 1.0, 0.0), code);
            assert_eq!(bilinear([x, y, z, code], 1.0, 1.0), code);
            let (fx, fy) = (rng.unit(), rng.unit());
            assert_eq!(bilinear([code; 4], fx, fy), code);
            assert_eq!(mean([code; 4]), code);
            // Box widths on the filter's grid, 1 to 11 samples (the
            // narrow box's and the wide one's); starts on it too.
            let on_grid = |v: f32, step: f32| (v * step).round() / step;
            let max = (PIXEL_BOX_TAPS - 1) as f32;
            let width = (
                on_grid(1.0 + (max - 1.0) * rng.unit(), 32768.0),
                on_grid(1.0 + (max - 1.0) * rng.unit(), 32768.0),
            );
            let start = (on_grid(fx, 65536.0) % 1.0, on_grid(fy, 65536.0) % 1.0);
            assert_eq!(pixel_box(srgb, |_, _| code, start, width), code);
            // Otherwise each channel lies between its samples'.
            let blend = bilinear([code, x, y, z], fx, fy);
            for shift in CODE_SHIFTS {
                let all = [code, x, y, z].map(|s| s >> shift & CODE_MASK);
                let one = blend >> shift & CODE_MASK;
                let (lo, hi) = (all.iter().min().unwrap(), all.iter().max().unwrap());
                assert!((*lo..=*hi).contains(&one), "{one} outside {all:?}");
            }
            // The pixel box: each channel the linear mean of its taps
            // weighted by how much of each one's cell it covers; it reads
            // no other.
            let taps = [code, x, y, z];
            let mut read_past = false;
            let (nx, ny) = (box_taps(start.0, width.0), box_taps(start.1, width.1));
            let blend = pixel_box(
                srgb,
                |i, j| {
                    read_past |= i >= nx || j >= ny;
                    taps[(i + 2 * j) % 4]
                },
                start,
                width,
            );
            assert!(!read_past, "read a tap the box misses");
            for shift in CODE_SHIFTS {
                // Tap i's cell spans [i, i + 1) from the first cell's start.
                let weight = |f: f32, w: f32, i: usize| {
                    let i = i as f32;
                    ((f + w).min(i + 1.0) - f.max(i)).max(0.0) / w
                };
                let mut want = 0.0;
                for j in 0..ny {
                    for i in 0..nx {
                        let c = srgb.decode_quarters(taps[(i + 2 * j) % 4] >> shift & CODE_MASK);
                        want += weight(start.0, width.0, i) * weight(start.1, width.1, j) * c;
                    }
                }
                let got = (blend >> shift & CODE_MASK) as i64;
                let want = srgb.encode_quarters(want) as i64;
                // Summed in another order, a mean on a code's edge may
                // round to its neighbour.
                assert!((got - want).abs() <= 1, "{got} against {want}");
            }
        }
    }

    #[test]
    fn changes_name_only_the_knobs_moved_from_their_defaults() {
        let one = PixelSamples::ONE;
        assert_eq!(RsvpKnobs::default().changes(one), None);
        let cheap = RsvpKnobs {
            oversample: 0.9,
            ..RsvpKnobs::default()
        };
        assert_eq!(cheap.changes(one).as_deref(), Some("oversample 0.9"));
        let all = RsvpKnobs {
            filter: Filter::Box,
            oversample: 2.0,
            level_bias: -1,
        };
        assert_eq!(
            all.changes(one).as_deref(),
            Some("box filter, oversample 2, level bias -1")
        );
        // The pixel box is the default from two to sixteen samples a
        // pixel, the box above.
        let pixel_box = RsvpKnobs {
            filter: Filter::PixelBox,
            ..all
        };
        let (four, sixteen, many) = (
            PixelSamples::new(4).unwrap(),
            PixelSamples::new(16).unwrap(),
            PixelSamples::new(25).unwrap(),
        );
        for count in [four, sixteen] {
            assert_eq!(
                pixel_box.changes(count).as_deref(),
                Some("oversample 2, level bias -1")
            );
        }
        assert_eq!(
            all.changes(many).as_deref(),
            Some("oversample 2, level bias -1")
        );
        assert_eq!(
            all.changes(four).as_deref(),
            Some("box filter, oversample 2, level bias -1")
        );
        // Each filter's own oversampling is its default, whatever the
        // count: the pixel box at one sample a pixel names the filter
        // alone, the box at four likewise.
        assert_eq!(
            RsvpKnobs::with_filter(Filter::PixelBox, one)
                .changes(one)
                .as_deref(),
            Some("pixel-box filter")
        );
        assert_eq!(
            RsvpKnobs::with_filter(Filter::Box, four)
                .changes(four)
                .as_deref(),
            Some("box filter")
        );
        assert_eq!(
            RsvpKnobs::default_for(four),
            RsvpKnobs::with_filter(Filter::PixelBox, four)
        );
        // Above four samples a pixel the pixel box's own oversampling is
        // higher: it is the default there, and the one at four a change.
        let denser = RsvpKnobs::default_for(sixteen);
        assert!(denser.oversample > RsvpKnobs::default_for(four).oversample);
        assert_eq!(denser.changes(sixteen), None);
        assert_eq!(
            RsvpKnobs::default_for(four).changes(sixteen).as_deref(),
            Some("oversample 1")
        );
    }
}

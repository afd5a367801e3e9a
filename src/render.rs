//! Turning samples into colours: full frames, and "trace just these sample
//! groups" for the reuse algorithms. The one way samples get traced.
//!
//! Samples are traced in fixed groups of 4x2 (one 8-wide packet), aligned to
//! multiples of 4 columns and 2 rows of the sample lattice. Embree does not
//! promise that a ray gives bit-identical results in a different packet, so
//! a sample is always traced with the same seven neighbours: a partial
//! re-trace then equals a full render bit for bit.

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::Intersector;
use crate::camera::{Camera, RayTable};
use crate::ray::{LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::scene::Scene;
use crate::shade::{RayCounts, RayObserver, Shader};

pub const GROUP_WIDTH: u32 = 4;
pub const GROUP_HEIGHT: u32 = 2;
const _: () = assert!((GROUP_WIDTH * GROUP_HEIGHT) as usize == PACKET_WIDTH);

/// The aligned group holding a sample: column and row of its top-left sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SampleGroup {
    pub col: i64,
    pub row: i64,
}

impl SampleGroup {
    pub fn containing(col: i64, row: i64) -> SampleGroup {
        SampleGroup {
            col: col.div_euclid(i64::from(GROUP_WIDTH)) * i64::from(GROUP_WIDTH),
            row: row.div_euclid(i64::from(GROUP_HEIGHT)) * i64::from(GROUP_HEIGHT),
        }
    }

    /// (column, row) of each lane.
    pub fn lane_samples(self) -> [(i64, i64); PACKET_WIDTH] {
        std::array::from_fn(|lane| {
            (
                self.col + (lane as i64 % i64::from(GROUP_WIDTH)),
                self.row + (lane as i64 / i64::from(GROUP_WIDTH)),
            )
        })
    }

    /// The groups covering columns `cols` and rows `rows` (half-open).
    pub fn covering(cols: std::ops::Range<i64>, rows: std::ops::Range<i64>) -> Vec<SampleGroup> {
        if cols.is_empty() || rows.is_empty() {
            return Vec::new();
        }
        let first = SampleGroup::containing(cols.start, rows.start);
        let (gw, gh) = (i64::from(GROUP_WIDTH), i64::from(GROUP_HEIGHT));
        let mut groups = Vec::new();
        let mut row = first.row;
        while row < rows.end {
            let mut col = first.col;
            while col < cols.end {
                groups.push(SampleGroup { col, row });
                col += gw;
            }
            row += gh;
        }
        groups
    }
}

/// Where primary rays come from: a sample lattice addressed by integer
/// column and row. None = no ray there (outside the image, or outside
/// what the projection covers).
pub trait PrimaryRays: Sync {
    fn primary(&self, col: i64, row: i64) -> Option<Ray>;

    /// The rays of a whole group and the mask of lanes that have one. One
    /// dynamic call per packet: inside, `primary` is called on the concrete
    /// type and inlines (eight dynamic calls per packet cost more than the
    /// ray arithmetic).
    fn primary_group(&self, group: SampleGroup) -> (RayPacket, LaneMask) {
        gather_group(self, group)
    }
}

/// The rays of `group`, one [`PrimaryRays::primary`] call per lane.
#[inline(always)]
fn gather_group<P: PrimaryRays + ?Sized>(source: &P, group: SampleGroup) -> (RayPacket, LaneMask) {
    let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
    let mut mask: LaneMask = 0;
    for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
        if let Some(ray) = source.primary(col, row) {
            rays[lane] = ray;
            mask |= 1 << lane;
        }
    }
    (rays, mask)
}

/// A camera's lattice is its image: one sample per pixel centre.
impl PrimaryRays for RayTable {
    #[inline(always)]
    fn primary(&self, col: i64, row: i64) -> Option<Ray> {
        let (width, height) = self.size();
        let inside = (0..i64::from(width)).contains(&col) && (0..i64::from(height)).contains(&row);
        if !inside {
            return None;
        }
        self.primary_ray(col as u32, row as u32)
    }

    /// A group inside the image (every group of a frame whose size is a
    /// multiple of the group's) is checked against the image once, not
    /// lane by lane.
    fn primary_group(&self, group: SampleGroup) -> (RayPacket, LaneMask) {
        let (width, height) = self.size();
        let inside = group.col >= 0
            && group.row >= 0
            && group.col + i64::from(GROUP_WIDTH) <= i64::from(width)
            && group.row + i64::from(GROUP_HEIGHT) <= i64::from(height);
        if !inside {
            return gather_group(self, group);
        }
        let (col, row) = (group.col as u32, group.row as u32);
        let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
        let mut mask: LaneMask = 0;
        for (lane, ray) in rays.iter_mut().enumerate() {
            let lane_u32 = lane as u32;
            let sample =
                self.primary_ray(col + lane_u32 % GROUP_WIDTH, row + lane_u32 / GROUP_WIDTH);
            if let Some(sample) = sample {
                *ray = sample;
                mask |= 1 << lane;
            }
        }
        (rays, mask)
    }
}

/// Traces one group; lanes without a ray come back black.
pub fn trace_group(
    shader: &Shader,
    source: &dyn PrimaryRays,
    group: SampleGroup,
    counts: &mut RayCounts,
    observer: Option<&mut dyn RayObserver>,
) -> [Vec3; PACKET_WIDTH] {
    let (rays, mask) = source.primary_group(group);
    shader.shade(&rays, mask, 0, counts, observer)
}

/// Traces `groups` in parallel; colours come back in the order given.
pub fn trace_groups(
    shader: &Shader,
    source: &dyn PrimaryRays,
    groups: &[SampleGroup],
) -> (Vec<[Vec3; PACKET_WIDTH]>, RayCounts) {
    trace_groups_observed(shader, source, groups, |_| None::<NoObserver>)
}

/// Never used as an observer: lets [`trace_groups`] share the observed path.
pub enum NoObserver {}

impl RayObserver for NoObserver {
    fn traced(
        &mut self,
        _: crate::shade::RayKind,
        _: &crate::ray::RayPacket,
        _: LaneMask,
        _: &[f32; PACKET_WIDTH],
    ) {
        match *self {}
    }
}

/// As [`trace_groups`], showing each group's rays to the observer
/// `observer_for(group)` makes (None: not observed).
pub fn trace_groups_observed<O: RayObserver>(
    shader: &Shader,
    source: &dyn PrimaryRays,
    groups: &[SampleGroup],
    observer_for: impl Fn(SampleGroup) -> Option<O> + Sync,
) -> (Vec<[Vec3; PACKET_WIDTH]>, RayCounts) {
    let (colors, counts) = trace_each(shader, groups, |&group| {
        (source, group, observer_for(group))
    });
    (
        colors,
        counts.into_iter().fold(RayCounts::default(), |a, b| a + b),
    )
}

/// Traces one group per item in parallel, each from the ray source, group
/// and observer `setup(item)` gives (one batch over groups of different
/// sources, such as several pyramid levels); each item's colours and rays
/// come back in the order given.
pub fn trace_each<'s, T: Sync, O: RayObserver>(
    shader: &Shader,
    items: &[T],
    setup: impl Fn(&T) -> (&'s dyn PrimaryRays, SampleGroup, Option<O>) + Sync,
) -> (Vec<[Vec3; PACKET_WIDTH]>, Vec<RayCounts>) {
    items
        .par_iter()
        .with_min_len(16)
        .map(|item| {
            let (source, group, mut observer) = setup(item);
            let mut counts = RayCounts::default();
            let colors = trace_group(
                shader,
                source,
                group,
                &mut counts,
                observer.as_mut().map(|o| o as &mut dyn RayObserver),
            );
            (colors, counts)
        })
        .unzip()
}

/// A linear-light RGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Frame {
    pub fn new(width: u32, height: u32) -> Frame {
        Frame {
            width,
            height,
            pixels: vec![Vec3::ZERO; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// 8-bit sRGB, clamped.
    pub fn to_rgb8(&self) -> image::RgbImage {
        let table = srgb_table();
        let mut out = image::RgbImage::new(self.width, self.height);
        for (dst, src) in out.pixels_mut().zip(&self.pixels) {
            *dst = image::Rgb(src.to_array().map(|c| table.encode(c)));
        }
        out
    }
}

/// sRGB encoding without a powf per channel: for each byte, the least
/// linear value that encodes to it, found from [`encode_srgb`] itself, so
/// the table gives exactly the same bytes.
pub struct SrgbTable {
    /// `thresholds[b]`: least f32 (as bits; positive floats order like
    /// their bits) that encodes to byte b or more; `thresholds[256]` is
    /// out of reach.
    thresholds: [u32; 257],
    /// For each bucket of the f32 bit pattern, the byte at its low end.
    buckets: Vec<u8>,
    /// As `thresholds` and `buckets`, for quarter codes (see
    /// [`SrgbTable::encode_quarters`]).
    quarter_thresholds: Vec<u32>,
    quarter_buckets: Vec<u16>,
    /// Per quarter code, the linear value at the middle of its span.
    quarter_linear: Vec<f32>,
}

/// Quarter codes: an sRGB byte in steps of a quarter (0..1024).
pub const QUARTER_CODES: u32 = 1024;

/// Bits of the f32 pattern that select a bucket; at the steepest part of
/// the curve a bucket then spans far less than one byte step.
const SRGB_BUCKET_SHIFT: u32 = 13;

/// For each bucket of the f32 bit patterns of [0, 1], the step (byte or
/// quarter code) its low end falls in, given each step's least pattern.
fn bucket_starts(thresholds: &[u32]) -> impl Iterator<Item = usize> + '_ {
    let count = (1.0f32.to_bits() >> SRGB_BUCKET_SHIFT) + 1;
    (0..count).map(move |bucket| {
        let low = bucket << SRGB_BUCKET_SHIFT;
        thresholds.partition_point(|&t| t <= low) - 1
    })
}

impl SrgbTable {
    fn new() -> SrgbTable {
        let mut thresholds = [u32::MAX; 257];
        thresholds[0] = 0;
        for (byte, threshold) in thresholds.iter_mut().enumerate().take(256).skip(1) {
            // Bisect on the bit pattern of [0, 1].
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if usize::from(encode_srgb(f32::from_bits(mid))) >= byte {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *threshold = lo;
        }
        let buckets = bucket_starts(&thresholds).map(|b| b as u8).collect();
        // A byte's span of linear values, thresholds[b]..thresholds[b + 1],
        // cut in four equal parts; 255's reaches past 1.0, where encoding
        // stops, as far again as from its threshold (1.0 is then at its
        // middle, as 255 * s + 0.5 = 255.5 puts it).
        let mut quarter_thresholds = vec![u32::MAX; QUARTER_CODES as usize + 1];
        for (byte, &low) in thresholds.iter().enumerate().take(256) {
            let lo = f32::from_bits(low);
            let hi = match thresholds[byte + 1] {
                u32::MAX => 2.0 - lo,
                high => f32::from_bits(high),
            };
            for quarter in 0..4 {
                quarter_thresholds[4 * byte + quarter] =
                    (lo + quarter as f32 * 0.25 * (hi - lo)).to_bits();
            }
        }
        let quarter_buckets = bucket_starts(&quarter_thresholds)
            .map(|code| code as u16)
            .collect();
        let quarter_linear = quarter_thresholds
            .windows(2)
            .map(|span| {
                let lo = f32::from_bits(span[0]);
                let hi = f32::from_bits(span[1]).min(1.0);
                (lo + 0.5 * (hi - lo)).min(1.0)
            })
            .collect();
        SrgbTable {
            thresholds,
            buckets,
            quarter_thresholds,
            quarter_buckets,
            quarter_linear,
        }
    }

    /// A linear value as an sRGB byte in quarter steps: `4 * encode(linear)`
    /// plus the quarter of that byte's span of linear values the value lies
    /// in (the curve is nearly straight across one byte). `code >> 2` is
    /// exactly `encode(linear)`: blending the codes of equal values gives
    /// their byte back, and the extra bits keep a blend of different ones
    /// within an eighth of a byte step instead of half of one.
    pub fn encode_quarters(&self, linear: f32) -> u32 {
        let c = if linear > 0.0 { linear.min(1.0) } else { 0.0 };
        let bits = c.to_bits();
        // As in `encode`: a bucket spans less than one quarter (tested).
        let code = u32::from(self.quarter_buckets[(bits >> SRGB_BUCKET_SHIFT) as usize]);
        code + u32::from(bits >= self.quarter_thresholds[code as usize + 1])
    }

    /// The linear value a quarter code stands for: the middle of its span.
    pub fn decode_quarters(&self, code: u32) -> f32 {
        self.quarter_linear[code as usize]
    }

    pub fn encode(&self, linear: f32) -> u8 {
        // NaN and negatives to 0, above 1 to 255.
        let c = if linear > 0.0 { linear.min(1.0) } else { 0.0 };
        let bits = c.to_bits();
        // A bucket spans less than one byte step (tested), so one compare
        // settles it, without a loop in the per-pixel path.
        let byte = self.buckets[(bits >> SRGB_BUCKET_SHIFT) as usize];
        byte + u8::from(bits >= self.thresholds[usize::from(byte) + 1])
    }
}

/// The shared table, built on first use.
pub fn srgb_table() -> &'static SrgbTable {
    static TABLE: std::sync::OnceLock<SrgbTable> = std::sync::OnceLock::new();
    TABLE.get_or_init(SrgbTable::new)
}

/// Linear [0, 1] to an sRGB byte.
pub fn encode_srgb(linear: f32) -> u8 {
    let c = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// The groups covering a whole `width` x `height` image.
pub fn image_groups(width: u32, height: u32) -> Vec<SampleGroup> {
    SampleGroup::covering(0..i64::from(width), 0..i64::from(height))
}

/// Renders the scene's camera view in full.
pub fn render_frame(scene: &Scene, intersector: &dyn Intersector) -> (Frame, RayCounts) {
    render_view(scene, &scene.camera, intersector)
}

/// Renders the scene through `camera` (which may differ from the scene's
/// own, e.g. posed by a timeline) in full.
pub fn render_view(
    scene: &Scene,
    camera: &Camera,
    intersector: &dyn Intersector,
) -> (Frame, RayCounts) {
    let shader = Shader::new(scene, intersector);
    render_image(&shader, &RayTable::new(camera), camera.width, camera.height)
}

/// Traces every pixel of a `width` x `height` image, pixel (x, y) from
/// `source`'s ray (x, y).
pub fn render_image(
    shader: &Shader,
    source: &dyn PrimaryRays,
    width: u32,
    height: u32,
) -> (Frame, RayCounts) {
    let mut frame = Frame::new(width, height);
    let width = width as usize;
    // Each band of GROUP_HEIGHT rows is written in place by the worker that
    // traces it: no per-frame list of groups or of their colours (at 640x480
    // those were megabytes, fresh pages to fault in on every frame).
    let band = width * GROUP_HEIGHT as usize;
    let counts = frame
        .pixels
        .par_chunks_mut(band)
        .enumerate()
        .map(|(index, pixels)| {
            let row = (index * GROUP_HEIGHT as usize) as i64;
            let mut counts = RayCounts::default();
            let group_width = GROUP_WIDTH as usize;
            for x in (0..width).step_by(group_width) {
                let group = SampleGroup { col: x as i64, row };
                let colors = trace_group(shader, source, group, &mut counts, None);
                // Lanes run along rows of the group (`lane_samples`): each
                // row is one slice copy, cut at the image's right edge; the
                // band's last rows may be missing at its bottom edge.
                let n = group_width.min(width - x);
                for (y, lanes) in colors.chunks_exact(group_width).enumerate() {
                    let start = y * width + x;
                    if let Some(dst) = pixels.get_mut(start..start + n) {
                        dst.copy_from_slice(&lanes[..n]);
                    }
                }
            }
            counts
        })
        .reduce(RayCounts::default, |a, b| a + b);
    (frame, counts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_align_and_cover() {
        assert_eq!(
            SampleGroup::containing(5, 3),
            SampleGroup { col: 4, row: 2 }
        );
        assert_eq!(
            SampleGroup::containing(-1, -1),
            SampleGroup { col: -4, row: -2 }
        );
        let groups = SampleGroup::covering(3..9, 1..4);
        let mut covered = std::collections::HashSet::new();
        for g in &groups {
            assert_eq!(g.col % 4, 0);
            assert_eq!(g.row % 2, 0);
            covered.extend(g.lane_samples());
        }
        for col in 3..9 {
            for row in 1..4 {
                assert!(covered.contains(&(col, row)));
            }
        }
        assert_eq!(groups.len(), 3 * 2);
        assert_eq!(image_groups(640, 480).len(), 160 * 240);
    }

    /// Each bucket's step at its low end (`starts`) against the step of
    /// its last bit pattern (`step_of`): one compare settles a lookup only
    /// if they are at most one step apart.
    fn assert_buckets_span_one_step(
        starts: impl Iterator<Item = usize>,
        step_of: impl Fn(u32) -> usize,
    ) {
        for (bucket, first) in starts.enumerate() {
            let high = (((bucket as u32 + 1) << SRGB_BUCKET_SHIFT) - 1).min(1.0f32.to_bits());
            let last = step_of(high);
            assert!(last <= first + 1, "bucket {bucket}: {first}..{last}");
        }
    }

    #[test]
    fn srgb_buckets_span_at_most_one_byte_step() {
        let table = srgb_table();
        assert_buckets_span_one_step(table.buckets.iter().map(|&b| usize::from(b)), |bits| {
            usize::from(encode_srgb(f32::from_bits(bits)))
        });
    }

    #[test]
    fn srgb_table_matches_the_formula_everywhere() {
        let table = srgb_table();
        // Every 97th bit pattern in [0, 1] plus values around each threshold.
        let mut values: Vec<f32> = (0..=1.0f32.to_bits())
            .step_by(97)
            .map(f32::from_bits)
            .collect();
        for &t in &table.thresholds[..256] {
            values.extend([
                f32::from_bits(t.saturating_sub(1)),
                f32::from_bits(t),
                f32::from_bits(t + 1),
            ]);
        }
        values.extend([-1.0, 2.0, f32::NAN, f32::INFINITY, -0.0]);
        for v in values {
            assert_eq!(table.encode(v), encode_srgb(v), "{v}");
        }
    }

    #[test]
    fn srgb_buckets_span_at_most_one_quarter_step() {
        let table = srgb_table();
        // A pattern's code by search of the quarter thresholds.
        let thresholds = &table.quarter_thresholds;
        assert_buckets_span_one_step(
            table.quarter_buckets.iter().map(|&c| usize::from(c)),
            |bits| thresholds.partition_point(|&t| t <= bits) - 1,
        );
    }

    #[test]
    fn quarter_codes_refine_the_byte_and_round_trip() {
        let table = srgb_table();
        let mut values: Vec<f32> = (0..=1.0f32.to_bits())
            .step_by(997)
            .map(f32::from_bits)
            .collect();
        for &t in &table.thresholds[..256] {
            values.extend([f32::from_bits(t.saturating_sub(1)), f32::from_bits(t)]);
        }
        values.extend([-1.0, 2.0, f32::NAN, f32::INFINITY, -0.0, 1.0]);
        values.sort_by(f32::total_cmp);
        let mut last = 0;
        for v in values {
            let code = table.encode_quarters(v);
            assert_eq!(code >> 2, u32::from(table.encode(v)), "{v}");
            if !v.is_nan() && v >= 0.0 {
                assert!(code >= last, "{v}: {code} after {last}");
                last = code;
            }
        }
        // Every code is reached, and its middle encodes back to it; but
        // the last, past 1.0, which no value or blend of values reaches.
        for code in 0..QUARTER_CODES - 1 {
            let middle = table.decode_quarters(code);
            assert_eq!(table.encode_quarters(middle), code, "{code}: {middle}");
        }
        assert_eq!(table.encode_quarters(1.0), 4 * 255 + 2);
    }

    #[test]
    fn srgb_encoding_endpoints() {
        assert_eq!(encode_srgb(0.0), 0);
        assert_eq!(encode_srgb(1.0), 255);
        assert_eq!(encode_srgb(2.0), 255);
        assert_eq!(encode_srgb(f32::NAN), 0);
        assert_eq!(encode_srgb(-1.0), 0);
        assert!(encode_srgb(0.5) > 180);
    }
}

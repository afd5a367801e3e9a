//! Image textures: a mip-map pyramid per image, sampled with wrapping
//! (repeat) at a level of detail chosen from a ray's footprint.
//!
//! Promises:
//! - Texels are kept as 8-bit sRGB (alpha linear), as GPUs keep sRGB
//!   textures, and decoded to linear light through an exact 256-entry
//!   table before any filtering: blends happen in linear light. A texture
//!   of data (heights, normals: [`TextureEncoding::Linear`]) keeps its
//!   bytes as values over 255 instead, never through the sRGB curve, and
//!   blends so that equal texels give their own value exactly (a flat
//!   stretch of a height map has no slope, not one of rounding).
//! - Level k is level k-1 halved (at least 1 texel a side), each texel the
//!   mean in linear light of the 2x2 texels under it (the last row or
//!   column of an odd size left out), re-encoded as the texture is.
//! - A lookup is a pure function of the texture, the texture coordinates
//!   and the level of detail: no state, so a sample traced again gives the
//!   same bits.
//! - Coordinates wrap (repeat) on both axes; any finite value is valid.
//!
//! `load` reads image files (PNG, JPEG, TGA, BMP) within a memory budget;
//! `path` finds the file an MTL or scene names as its author wrote it.

pub mod load;
pub mod path;

use std::path::{Path, PathBuf};
use std::sync::{Arc, LazyLock};

use glam::{Vec2, Vec4};

use crate::color::encode_srgb;

/// How a texture is filtered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TextureFilter {
    /// The nearest texel of the full-size image: no filtering (aliases at
    /// a distance).
    Nearest,
    /// Bilinear on the full-size image.
    Bilinear,
    /// Bilinear on the two mip levels around the footprint's level of
    /// detail, blended (trilinear).
    #[default]
    Trilinear,
}

impl std::str::FromStr for TextureFilter {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "nearest" => Ok(TextureFilter::Nearest),
            "bilinear" => Ok(TextureFilter::Bilinear),
            "trilinear" => Ok(TextureFilter::Trilinear),
            _ => Err(format!(
                "'{s}' is not a texture filter (nearest, bilinear or trilinear)"
            )),
        }
    }
}

/// The linear value of each sRGB byte.
static SRGB_TO_LINEAR: LazyLock<[f32; 256]> = LazyLock::new(|| {
    std::array::from_fn(|byte| {
        let c = byte as f64 / 255.0;
        let linear = if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        };
        linear as f32
    })
});

/// The linear value of an sRGB byte.
pub fn srgb_to_linear(byte: u8) -> f32 {
    SRGB_TO_LINEAR[usize::from(byte)]
}

/// Each byte over 255: the values of a data texture.
static BYTE_TO_UNIT: LazyLock<[f32; 256]> =
    LazyLock::new(|| std::array::from_fn(|byte| byte as f32 / 255.0));

/// What a texture's RGB bytes stand for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TextureEncoding {
    /// Colours: sRGB-encoded light, decoded before filtering.
    #[default]
    Srgb,
    /// Data (a height or normal map): each byte is its value times 255.
    Linear,
}

impl TextureEncoding {
    /// The value of each byte of RGB.
    fn table(self) -> &'static [f32; 256] {
        match self {
            TextureEncoding::Srgb => &SRGB_TO_LINEAR,
            TextureEncoding::Linear => &BYTE_TO_UNIT,
        }
    }

    /// The byte of an RGB value.
    fn encode(self, value: f32) -> u8 {
        match self {
            TextureEncoding::Srgb => encode_srgb(value),
            TextureEncoding::Linear => (value.clamp(0.0, 1.0) * 255.0).round() as u8,
        }
    }
}

/// How bilinear and trilinear filtering blend two values. Colours blend
/// as they always have; data blends as `a + (b - a) t`, which gives `a`
/// itself, bit for bit, where `b` equals it (`a (1 - t) + b t` can miss by
/// a rounding, and a height map's slope is a difference of such blends).
trait Blend {
    fn blend(a: Vec4, b: Vec4, t: f32) -> Vec4;
}

struct ColourBlend;
struct DataBlend;

impl Blend for ColourBlend {
    #[inline(always)]
    fn blend(a: Vec4, b: Vec4, t: f32) -> Vec4 {
        a.lerp(b, t)
    }
}

impl Blend for DataBlend {
    #[inline(always)]
    fn blend(a: Vec4, b: Vec4, t: f32) -> Vec4 {
        a + (b - a) * t
    }
}

/// One level of the pyramid: RGB as its texture's encoding says and
/// linear alpha, row-major, top row first.
#[derive(Clone)]
pub struct MipLevel {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[u8; 4]>,
}

impl MipLevel {
    /// The texel at (`x`, `y`) (wrapped into range), its RGB bytes
    /// decoded through `table`.
    #[inline]
    fn linear(&self, x: i64, y: i64, table: &[f32; 256]) -> Vec4 {
        let x = x.rem_euclid(i64::from(self.width)) as usize;
        let y = y.rem_euclid(i64::from(self.height)) as usize;
        let [r, g, b, a] = self.texels[y * self.width as usize + x];
        Vec4::new(
            table[usize::from(r)],
            table[usize::from(g)],
            table[usize::from(b)],
            f32::from(a) / 255.0,
        )
    }

    /// Bilinear at `uv` (texel centres at half-integers, wrapped).
    #[inline]
    fn bilinear<B: Blend>(&self, uv: Vec2, table: &[f32; 256]) -> Vec4 {
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let texel = |x, y| self.linear(x, y, table);
        let top = B::blend(texel(x0, y0), texel(x0 + 1, y0), fx);
        let bottom = B::blend(texel(x0, y0 + 1), texel(x0 + 1, y0 + 1), fx);
        B::blend(top, bottom, fy)
    }

    #[inline]
    fn nearest(&self, uv: Vec2, table: &[f32; 256]) -> Vec4 {
        let x = (uv.x * self.width as f32).floor() as i64;
        let y = (uv.y * self.height as f32).floor() as i64;
        self.linear(x, y, table)
    }

    /// The next level down: half the size, each texel the linear mean of
    /// the 2x2 under it, encoded as `encoding` says.
    fn halved(&self, encoding: TextureEncoding) -> MipLevel {
        let table = encoding.table();
        let width = (self.width / 2).max(1);
        let height = (self.height / 2).max(1);
        let mut texels = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                let (sx, sy) = (i64::from(x) * 2, i64::from(y) * 2);
                // A side of 1 texel averages that texel with itself.
                let (dx, dy) = (i64::from(self.width > 1), i64::from(self.height > 1));
                let mean = (self.linear(sx, sy, table)
                    + self.linear(sx + dx, sy, table)
                    + self.linear(sx, sy + dy, table)
                    + self.linear(sx + dx, sy + dy, table))
                    * 0.25;
                texels.push([
                    encoding.encode(mean.x),
                    encoding.encode(mean.y),
                    encoding.encode(mean.z),
                    (mean.w * 255.0).round() as u8,
                ]);
            }
        }
        MipLevel {
            width,
            height,
            texels,
        }
    }
}

/// An image as a mip-map pyramid, with where it came from.
pub struct Texture {
    /// Level 0 is the image itself; the last level is 1x1.
    levels: Vec<MipLevel>,
    source: PathBuf,
    filter: TextureFilter,
    encoding: TextureEncoding,
}

/// Bytes a pyramid over a `width` x `height` image takes (4 per texel, all
/// levels).
pub fn pyramid_bytes(width: u32, height: u32) -> u64 {
    let (mut w, mut h) = (u64::from(width.max(1)), u64::from(height.max(1)));
    let mut total = 0;
    loop {
        total += w * h * 4;
        if w == 1 && h == 1 {
            return total;
        }
        (w, h) = ((w / 2).max(1), (h / 2).max(1));
    }
}

impl Texture {
    /// The pyramid of an sRGB image (`rgba`: 4 bytes a texel, row-major,
    /// top row first) of at least one texel.
    pub fn from_srgba8(
        width: u32,
        height: u32,
        rgba: Vec<[u8; 4]>,
        source: &Path,
        filter: TextureFilter,
    ) -> Texture {
        Texture::from_rgba8(width, height, rgba, source, filter, TextureEncoding::Srgb)
    }

    /// [`Texture::from_srgba8`] for an image whose RGB is `encoding`.
    pub fn from_rgba8(
        width: u32,
        height: u32,
        rgba: Vec<[u8; 4]>,
        source: &Path,
        filter: TextureFilter,
        encoding: TextureEncoding,
    ) -> Texture {
        assert!(width > 0 && height > 0 && rgba.len() == width as usize * height as usize);
        let mut levels = vec![MipLevel {
            width,
            height,
            texels: rgba,
        }];
        while let Some(last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
            let next = last.halved(encoding);
            levels.push(next);
        }
        Texture {
            levels,
            source: source.to_path_buf(),
            filter,
            encoding,
        }
    }

    pub fn levels(&self) -> &[MipLevel] {
        &self.levels
    }

    pub fn source(&self) -> &Path {
        &self.source
    }

    pub fn filter(&self) -> TextureFilter {
        self.filter
    }

    pub fn encoding(&self) -> TextureEncoding {
        self.encoding
    }

    /// Width and height of the full-size image.
    pub fn size(&self) -> (u32, u32) {
        (self.levels[0].width, self.levels[0].height)
    }

    /// Bytes the pyramid holds.
    pub fn bytes(&self) -> u64 {
        self.levels.iter().map(|l| l.texels.len() as u64 * 4).sum()
    }

    /// The linear RGBA at `uv` (wrapped), filtered at level of detail
    /// `lod` (0: the full-size image; each step halves it) as the
    /// texture's filter says. A NaN `lod` reads level 0.
    #[inline]
    pub fn sample(&self, uv: Vec2, lod: f32) -> Vec4 {
        match self.encoding {
            TextureEncoding::Srgb => self.sample_blending::<ColourBlend>(uv, lod),
            TextureEncoding::Linear => self.sample_blending::<DataBlend>(uv, lod),
        }
    }

    #[inline]
    fn sample_blending<B: Blend>(&self, uv: Vec2, lod: f32) -> Vec4 {
        let table = self.encoding.table();
        // Wrapping first keeps huge coordinates' texel arithmetic exact.
        let uv = uv - uv.floor();
        match self.filter {
            TextureFilter::Nearest => self.levels[0].nearest(uv, table),
            TextureFilter::Bilinear => self.levels[0].bilinear::<B>(uv, table),
            TextureFilter::Trilinear => {
                let lod = self.level_read(lod);
                let below = lod.floor();
                let blend = lod - below;
                let fine = self.levels[below as usize].bilinear::<B>(uv, table);
                if blend == 0.0 {
                    return fine;
                }
                let coarse = self.levels[below as usize + 1].bilinear::<B>(uv, table);
                B::blend(fine, coarse, blend)
            }
        }
    }

    /// The (fractional) level a trilinear lookup at `lod` reads: `lod`
    /// within the pyramid, level 0 for NaN.
    #[inline]
    fn level_read(&self, lod: f32) -> f32 {
        let top = (self.levels.len() - 1) as f32;
        if lod > 0.0 {
            lod.min(top)
        } else {
            0.0
        }
    }

    /// The width and height, in texture coordinates, of a texel of the
    /// level a lookup at `lod` reads (of level 0 where the filter reads
    /// only that): the step a finite difference of lookups takes.
    pub fn texel_span(&self, lod: f32) -> Vec2 {
        let level = match self.filter {
            TextureFilter::Trilinear => self.level_read(lod),
            TextureFilter::Nearest | TextureFilter::Bilinear => 0.0,
        };
        let (w, h) = self.size();
        Vec2::new(w as f32, h as f32).recip() * level.exp2()
    }
}

/// A texture shared by the materials that use it. Two are equal when they
/// are the same loaded image (one file loads once per scene).
#[derive(Clone)]
pub struct TextureRef(pub Arc<Texture>);

impl std::ops::Deref for TextureRef {
    type Target = Texture;
    fn deref(&self) -> &Texture {
        &self.0
    }
}

impl PartialEq for TextureRef {
    fn eq(&self, other: &TextureRef) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl std::fmt::Debug for TextureRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = self.size();
        let data = match self.encoding {
            TextureEncoding::Srgb => "",
            TextureEncoding::Linear => ", linear",
        };
        write!(f, "Texture({}, {w}x{h}{data})", self.source.display())
    }
}

/// The level of detail of a ray cone's footprint (Akenine-Möller et al.,
/// "Texture Level of Detail Strategies for Real-Time Ray Tracing", Ray
/// Tracing Gems ch. 20, eq. 34): `width` is the cone's width at the hit,
/// `cos` the cosine between the ray and the surface normal; `texel_area`
/// the triangle's area in texels (its texture-space area times the
/// texture's size) and `world_area` its area in the world.
#[inline]
pub fn cone_level_of_detail(width: f32, cos: f32, texel_area: f32, world_area: f32) -> f32 {
    0.5 * (texel_area / world_area).log2() + width.abs().log2() - cos.abs().log2()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texture(width: u32, height: u32, texels: Vec<[u8; 4]>) -> Texture {
        Texture::from_srgba8(
            width,
            height,
            texels,
            Path::new("t.png"),
            TextureFilter::Trilinear,
        )
    }

    #[test]
    fn srgb_bytes_decode_to_linear_light() {
        assert_eq!(srgb_to_linear(0), 0.0);
        assert_eq!(srgb_to_linear(255), 1.0);
        // sRGB 188 is linear 0.5 (to 3 digits), 128 is 0.2158.
        assert!((srgb_to_linear(188) - 0.5029).abs() < 1e-4);
        assert!((srgb_to_linear(128) - 0.21586).abs() < 1e-4);
        // The linear segment at the bottom.
        assert!((srgb_to_linear(10) - 10.0 / 255.0 / 12.92).abs() < 1e-7);
        for byte in 0..=255u8 {
            assert_eq!(encode_srgb(srgb_to_linear(byte)), byte);
        }
    }

    #[test]
    fn mip_levels_of_a_known_image_average_in_linear_light() {
        // A 4x2 image: black and white columns.
        let (b, w) = ([0, 0, 0, 255], [255, 255, 255, 255]);
        let t = texture(4, 2, vec![b, w, b, w, b, w, b, w]);
        let sizes: Vec<(u32, u32)> = t.levels().iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(4, 2), (2, 1), (1, 1)]);
        // Half black, half white is linear 0.5: sRGB 188, not 128.
        assert_eq!(t.levels()[1].texels, vec![[188, 188, 188, 255]; 2]);
        assert_eq!(t.levels()[2].texels, vec![[188, 188, 188, 255]]);
        assert_eq!(t.bytes(), pyramid_bytes(4, 2));
        assert_eq!(pyramid_bytes(4, 2), (8 + 2 + 1) * 4);
        // A 1x1 image is its own pyramid.
        let one = texture(1, 1, vec![[10, 20, 30, 40]]);
        assert_eq!(one.levels().len(), 1);
        let c = one.sample(Vec2::new(0.3, 0.7), 5.0);
        assert_eq!(c.x, srgb_to_linear(10));
        assert_eq!(c.w, 40.0 / 255.0);
    }

    #[test]
    fn coordinates_wrap_and_levels_blend() {
        let (r, g, bl, w) = (
            [255, 0, 0, 255],
            [0, 255, 0, 255],
            [0, 0, 255, 255],
            [255, 255, 255, 255],
        );
        let mut t = texture(2, 2, vec![r, g, bl, w]);
        t.filter = TextureFilter::Nearest;
        let at = |u: f32, v: f32| t.sample(Vec2::new(u, v), 0.0);
        assert_eq!(at(0.25, 0.25), Vec4::new(1.0, 0.0, 0.0, 1.0));
        assert_eq!(at(0.75, 0.25), Vec4::new(0.0, 1.0, 0.0, 1.0));
        // Out of [0, 1] repeats, negative coordinates too.
        for (u, v) in [
            (1.25, 0.25),
            (-0.75, 0.25),
            (7.25, -2.75),
            (-1e4 + 0.25, 3.25),
        ] {
            assert_eq!(at(u, v), at(0.25, 0.25), "{u} {v}");
        }
        assert_eq!(at(0.75, -0.25), Vec4::new(1.0, 1.0, 1.0, 1.0));
        // Bilinear between texel centres wraps around the edge: u = 0 lies
        // halfway between column 1 (wrapped) and column 0.
        t.filter = TextureFilter::Trilinear;
        let edge = t.sample(Vec2::new(0.0, 0.25), 0.0);
        assert!(
            (edge - Vec4::new(0.5, 0.5, 0.0, 1.0)).length() < 1e-6,
            "{edge}"
        );
        // The coarsest level is the mean; half-way blends the two.
        let mean = t.sample(Vec2::new(0.25, 0.25), 1.0);
        let half = t.sample(Vec2::new(0.25, 0.25), 0.5);
        let fine = t.sample(Vec2::new(0.25, 0.25), 0.0);
        assert!((half - (fine + mean) * 0.5).length() < 1e-6);
        // Past the top level, the top level; below 0 or NaN, level 0.
        assert_eq!(t.sample(Vec2::new(0.25, 0.25), 9.0), mean);
        assert_eq!(t.sample(Vec2::new(0.25, 0.25), -3.0), fine);
        assert_eq!(t.sample(Vec2::new(0.25, 0.25), f32::NAN), fine);
    }

    #[test]
    fn data_textures_skip_the_srgb_curve_and_keep_flat_stretches_exact() {
        let (b, w, g) = ([0, 0, 0, 255], [255, 255, 255, 255], [77, 77, 77, 255]);
        let t = Texture::from_rgba8(
            4,
            2,
            vec![b, w, b, w, g, g, g, g],
            Path::new("h.png"),
            TextureFilter::Trilinear,
            TextureEncoding::Linear,
        );
        // A level down, the mean of the bytes (0 + 255 + 77 + 77) / 4, not
        // of the light they would encode as sRGB.
        assert_eq!(t.levels()[1].texels, vec![[102, 102, 102, 255]; 2]);
        // Between equal texels a lookup is their value, bit for bit,
        // wherever it lands (a colour blend can miss it by a rounding).
        let grey = 77.0 / 255.0;
        for i in 0..1000 {
            let u = i as f32 * 0.000_999_7;
            assert_eq!(t.sample(Vec2::new(u, 0.75), 0.0).x, grey, "{u}");
        }
        assert_eq!(t.sample(Vec2::new(0.125, 0.25), 0.0).x, 0.0);
        assert_eq!(t.sample(Vec2::new(0.25, 0.25), 0.0).x, 0.5);
        // A texel of the level read, in texture coordinates.
        assert_eq!(t.texel_span(0.0), Vec2::new(0.25, 0.5));
        assert_eq!(t.texel_span(1.0), Vec2::new(0.5, 1.0));
        assert_eq!(t.texel_span(f32::NAN), Vec2::new(0.25, 0.5));
        assert_eq!(t.texel_span(7.0), Vec2::new(1.0, 2.0));
    }

    #[test]
    fn a_wider_footprint_reads_a_coarser_level() {
        // A 1x1 world triangle mapped onto 256x256 texels: one texel is
        // 1/256 wide, so a cone 1/256 wide head-on reads level 0, and each
        // doubling of the width or halving of the cosine one level up.
        let (texels, world) = (256.0 * 256.0 * 0.5, 0.5);
        let lod = |width: f32, cos: f32| cone_level_of_detail(width, cos, texels, world);
        assert!(lod(1.0 / 256.0, 1.0).abs() < 1e-5);
        assert!((lod(1.0 / 64.0, 1.0) - 2.0).abs() < 1e-5);
        assert!((lod(1.0 / 256.0, 0.5) - 1.0).abs() < 1e-5);
    }
}

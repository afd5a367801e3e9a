//! Reading image files into textures, each file once per scene, within a
//! memory budget.
//!
//! Promises: a file that is missing, unreadable or not an image is a
//! [`TextureProblem`] its caller reports as a warning (the material then
//! renders without the texture); only a texture past the budget is an
//! error, and it is known from the image's header, before any decoding.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::{pyramid_bytes, Texture, TextureEncoding, TextureFilter, TextureRef};

/// The texture memory a scene may use unless told otherwise, in MB
/// (2^20 bytes): 1024, some 180 images of 1024 x 1024 with their mip
/// levels, or one of 16384 x 16384 refused.
pub const DEFAULT_TEXTURE_MEMORY_MB: u64 = 1024;

/// Why a texture did not load.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TextureProblem {
    /// Not loaded; the material renders without it.
    #[error("{0}")]
    Skipped(String),
    /// Past the budget: the scene should not load.
    #[error("{0}")]
    OverBudget(String),
}

/// The textures one scene loaded, by file and encoding (a file read as
/// colours and as data is two textures), and the memory they hold.
pub struct TextureCache {
    limit_bytes: u64,
    used_bytes: u64,
    filter: TextureFilter,
    loaded: HashMap<(PathBuf, TextureEncoding), TextureRef>,
}

impl Default for TextureCache {
    fn default() -> Self {
        TextureCache::new(DEFAULT_TEXTURE_MEMORY_MB, TextureFilter::default())
    }
}

impl TextureCache {
    /// A cache that holds at most `limit_mb` MB of texture, sampled with
    /// `filter`.
    pub fn new(limit_mb: u64, filter: TextureFilter) -> TextureCache {
        TextureCache {
            limit_bytes: limit_mb.saturating_mul(1 << 20),
            used_bytes: 0,
            filter,
            loaded: HashMap::new(),
        }
    }

    /// Bytes the loaded textures hold.
    pub fn used_bytes(&self) -> u64 {
        self.used_bytes
    }

    /// The texture of the image file at `path` (loaded on first use), its
    /// colours sRGB.
    pub fn load(&mut self, path: &Path) -> Result<TextureRef, TextureProblem> {
        self.load_as(path, TextureEncoding::Srgb)
    }

    /// [`TextureCache::load`] with the image's RGB read as `encoding` says.
    pub fn load_as(
        &mut self,
        path: &Path,
        encoding: TextureEncoding,
    ) -> Result<TextureRef, TextureProblem> {
        let key = (
            path.canonicalize().unwrap_or_else(|_| path.to_path_buf()),
            encoding,
        );
        if let Some(texture) = self.loaded.get(&key) {
            return Ok(texture.clone());
        }
        let skipped = |why: String| TextureProblem::Skipped(format!("{}: {why}", path.display()));
        let reader = image::ImageReader::open(path)
            .map_err(|err| skipped(format!("cannot open: {err}")))?
            .with_guessed_format()
            .map_err(|err| skipped(format!("cannot read: {err}")))?;
        if reader.format().is_none() {
            return Err(skipped(
                "not an image this program reads (PNG, JPEG, TGA, BMP)".into(),
            ));
        }
        let (width, height) = reader
            .into_dimensions()
            .map_err(|err| skipped(format!("not a readable image: {err}")))?;
        let needed = pyramid_bytes(width, height);
        if self.used_bytes + needed > self.limit_bytes {
            let mb = |bytes: u64| bytes as f64 / f64::from(1 << 20);
            return Err(TextureProblem::OverBudget(format!(
                "{}: a {width} x {height} texture needs {:.0} MB with its mip levels; with the \
                 {:.0} MB already loaded that passes the texture memory limit of {:.0} MB \
                 (raise it with --texture-memory MB, or use a smaller image)",
                path.display(),
                mb(needed),
                mb(self.used_bytes),
                mb(self.limit_bytes)
            )));
        }
        // Headers were read; decoding may still find the data broken.
        let mut reader = image::ImageReader::open(path)
            .map_err(|err| skipped(format!("cannot open: {err}")))?
            .with_guessed_format()
            .map_err(|err| skipped(format!("cannot read: {err}")))?;
        let mut limits = image::Limits::default();
        limits.max_alloc = Some(needed.saturating_mul(4).max(1 << 20));
        reader.limits(limits);
        let image = reader
            .decode()
            .map_err(|err| skipped(format!("not a readable image: {err}")))?;
        let rgba = image.into_rgba8();
        let (width, height) = rgba.dimensions();
        if width == 0 || height == 0 {
            return Err(skipped("the image has no pixels".into()));
        }
        let texels: Vec<[u8; 4]> = bytemuck::cast_vec(rgba.into_raw());
        let texture = TextureRef(Arc::new(Texture::from_rgba8(
            width,
            height,
            texels,
            path,
            self.filter,
            encoding,
        )));
        self.used_bytes += texture.bytes();
        self.loaded.insert(key, texture.clone());
        Ok(texture)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(path: &Path, width: u32, height: u32) {
        image::RgbaImage::from_fn(width, height, |x, y| {
            image::Rgba([(x * 40) as u8, (y * 40) as u8, 128, 255])
        })
        .save(path)
        .unwrap();
    }

    #[test]
    fn each_file_loads_once_and_is_counted() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        png(&path, 4, 4);
        let mut cache = TextureCache::default();
        let a = cache.load(&path).unwrap();
        let again = cache.load(&dir.path().join(".").join("a.png")).unwrap();
        assert!(a == again);
        assert_eq!(cache.used_bytes(), pyramid_bytes(4, 4));
        assert_eq!(a.levels()[0].texels[4 + 1], [40, 40, 128, 255]);
        // Read as data it is another texture, counted too.
        let data = cache.load_as(&path, TextureEncoding::Linear).unwrap();
        assert!(data != a && data.encoding() == TextureEncoding::Linear);
        assert!(data == cache.load_as(&path, TextureEncoding::Linear).unwrap());
        assert_eq!(cache.used_bytes(), 2 * pyramid_bytes(4, 4));
    }

    #[test]
    fn formats_other_than_png_decode() {
        let dir = tempfile::tempdir().unwrap();
        let source = image::RgbImage::from_pixel(8, 8, image::Rgb([200, 100, 50]));
        for ext in ["jpg", "tga", "bmp"] {
            let path = dir.path().join(format!("t.{ext}"));
            source.save(&path).unwrap();
            let texture = TextureCache::default().load(&path).unwrap();
            let [r, g, b, a] = texture.levels()[0].texels[0];
            // JPEG is lossy: within a few steps.
            assert!(
                r.abs_diff(200) < 4 && g.abs_diff(100) < 4 && b.abs_diff(50) < 4,
                "{ext}"
            );
            assert_eq!(a, 255);
        }
    }

    #[test]
    fn missing_corrupt_and_truncated_files_are_skipped() {
        let dir = tempfile::tempdir().unwrap();
        let mut cache = TextureCache::default();
        let missing = cache.load(&dir.path().join("none.png")).unwrap_err();
        assert!(
            matches!(&missing, TextureProblem::Skipped(m) if m.contains("none.png: cannot open")),
            "{missing}"
        );
        let garbage = dir.path().join("garbage.png");
        std::fs::write(&garbage, b"this is not an image at all").unwrap();
        let err = cache.load(&garbage).unwrap_err();
        assert!(matches!(err, TextureProblem::Skipped(_)), "{err}");
        // A PNG cut short: the header reads, the pixels do not.
        let whole = dir.path().join("whole.png");
        png(&whole, 64, 64);
        let bytes = std::fs::read(&whole).unwrap();
        let cut = dir.path().join("cut.png");
        std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
        let err = cache.load(&cut).unwrap_err();
        assert!(
            matches!(&err, TextureProblem::Skipped(m) if m.contains("not a readable image")),
            "{err}"
        );
        assert_eq!(cache.used_bytes(), 0);
    }

    /// A PNG whose header says `width` x `height` and whose data is a
    /// stub: enough to test what the header alone decides.
    fn png_header(path: &Path, width: u32, height: u32) {
        let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut ihdr = b"IHDR".to_vec();
        ihdr.extend(width.to_be_bytes());
        ihdr.extend(height.to_be_bytes());
        ihdr.extend([8, 6, 0, 0, 0]);
        bytes.extend(13u32.to_be_bytes());
        bytes.extend(&ihdr);
        bytes.extend(crc32(&ihdr).to_be_bytes());
        // The start of the pixel data: a zlib header, and no more.
        let idat = b"IDAT\x78\x9c";
        bytes.extend(2u32.to_be_bytes());
        bytes.extend(idat);
        bytes.extend(crc32(idat).to_be_bytes());
        std::fs::write(path, bytes).unwrap();
    }

    fn crc32(data: &[u8]) -> u32 {
        let mut crc = 0xffff_ffffu32;
        for &byte in data {
            crc ^= u32::from(byte);
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xedb8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    #[test]
    fn a_huge_texture_is_refused_from_its_header_and_the_limit_can_be_raised() {
        let dir = tempfile::tempdir().unwrap();
        let huge = dir.path().join("huge.png");
        png_header(&huge, 16384, 16384);
        let err = TextureCache::default().load(&huge).unwrap_err();
        let TextureProblem::OverBudget(message) = &err else {
            panic!("{err:?}")
        };
        assert!(
            message.contains("huge.png: a 16384 x 16384 texture needs 1365 MB"),
            "{message}"
        );
        assert!(message.contains("limit of 1024 MB") && message.contains("--texture-memory"));
        // Raised past it, the header passes and the stub data is what fails.
        let err = TextureCache::new(2048, TextureFilter::Trilinear)
            .load(&huge)
            .unwrap_err();
        assert!(matches!(err, TextureProblem::Skipped(_)), "{err}");
        // The budget counts what is already loaded.
        let small = dir.path().join("small.png");
        png(&small, 512, 256);
        let mut cache = TextureCache::new(1, TextureFilter::Trilinear);
        cache.load(&small).unwrap();
        let other = dir.path().join("other.png");
        png(&other, 512, 256);
        let err = cache.load(&other).unwrap_err();
        assert!(
            matches!(&err, TextureProblem::OverBudget(m) if m.contains("with the 1 MB already loaded")),
            "{err}"
        );
    }
}

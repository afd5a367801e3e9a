//! Writing images: the format comes from the extension (PNG or TGA; a
//! frame may be an OpenEXR file too, [`exr`]), and the file appears only
//! when complete (written to a temporary name beside it,
//! then renamed), so an interrupted run leaves no half-written frame.
//!
//! TGA files are run-length encoded with every packet inside one row, as
//! the TGA 2.0 specification requires: decoders that work row by row
//! (Pillow's) refuse packets that run on into the next row.
//!
//! Every CSV file is written from serializable rows by [`csv_text`].
//! Temporary files a killed run left are removed by the next run writing
//! into the same folder ([`take_removed_temporaries`] says which).

mod csv;
pub mod exr;
mod stale;

pub use csv::{csv_records, csv_text, CsvError, Floats};
pub use exr::{
    read_exr, save_exr, save_exr_pending, ExrChannel, ExrMismatch, ExrPicture, ExrSamples,
};
pub use stale::take_removed_temporaries;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};

use image::ImageFormat;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error(transparent)]
    Csv(#[from] CsvError),
    #[error("{path}: unsupported image format (use {allowed})")]
    UnsupportedFormat {
        path: PathBuf,
        allowed: &'static str,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: a TGA image is at most 65535 pixels wide and high, not {width}x{height}")]
    TooLargeForTga {
        path: PathBuf,
        width: u32,
        height: u32,
    },
    #[error("{path}: cannot encode or decode OpenEXR: {message}")]
    Exr { path: PathBuf, message: String },
    #[error("{path}: cannot encode image: {source}")]
    Encode {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
}

/// The image format for an 8-bit picture at `path`, from its extension.
pub fn format_for(path: &Path) -> Result<ImageFormat, OutputError> {
    match ImageFormat::from_path(path) {
        Ok(format @ (ImageFormat::Png | ImageFormat::Tga)) => Ok(format),
        _ => Err(OutputError::UnsupportedFormat {
            path: path.to_path_buf(),
            allowed: if is_exr(path) {
                ".png or .tga: this picture is 8-bit; only rendered frames are written as .exr"
            } else {
                ".png or .tga"
            },
        }),
    }
}

/// What a rendered frame is written as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameFormat {
    /// 8-bit sRGB.
    Picture(ImageFormat),
    /// Linear half floats, with the arbitrary output variables asked for.
    Exr,
}

/// The format of a rendered frame at `path`, from its extension.
pub fn frame_format_for(path: &Path) -> Result<FrameFormat, OutputError> {
    if is_exr(path) {
        return Ok(FrameFormat::Exr);
    }
    format_for(path)
        .map(FrameFormat::Picture)
        .map_err(|_| OutputError::UnsupportedFormat {
            path: path.to_path_buf(),
            allowed: ".png, .tga or .exr",
        })
}

fn is_exr(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// The temporary files being written now, so that an interrupt can remove
/// them ([`remove_unfinished_and_exit`]).
static UNFINISHED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn unfinished() -> MutexGuard<'static, Vec<PathBuf>> {
    UNFINISHED.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A file being written under a temporary name beside `path`: renamed into
/// place by [`PendingFile::commit`], removed if dropped before that or if
/// the run is interrupted.
pub struct PendingFile {
    temp: PathBuf,
    path: PathBuf,
    /// Renamed into place (or failed to be and removed): nothing to undo.
    settled: bool,
}

impl PendingFile {
    pub fn beside(path: &Path) -> PendingFile {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let dir = match path.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        stale::sweep_once(&dir);
        let temp = dir.join(format!(
            ".{name}.{}-{}.{}.tmp",
            stale::host(),
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        unfinished().push(temp.clone());
        PendingFile {
            temp,
            path: path.to_path_buf(),
            settled: false,
        }
    }

    /// Where to write.
    pub fn temp(&self) -> &Path {
        &self.temp
    }

    /// Where the file goes once committed.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Moves the written file into place.
    pub fn commit(mut self) -> Result<(), OutputError> {
        // Under the lock, so an interrupt either removes the temporary
        // file first or finds it renamed: never half of each.
        let mut list = unfinished();
        let renamed = std::fs::rename(&self.temp, &self.path);
        if renamed.is_err() {
            let _ = std::fs::remove_file(&self.temp);
        }
        list.retain(|p| *p != self.temp);
        self.settled = true;
        renamed.map_err(|source| OutputError::Write {
            path: self.path.clone(),
            source,
        })
    }
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        if self.settled {
            return;
        }
        let mut list = unfinished();
        let _ = std::fs::remove_file(&self.temp);
        list.retain(|p| *p != self.temp);
    }
}

/// Removes every file still being written and exits with `code`, for an
/// interrupt (Ctrl-C): no half-written file stays behind. Holds the list's
/// lock to the end, so no write finishes meanwhile.
pub fn remove_unfinished_and_exit(code: i32) -> ! {
    let list = unfinished();
    for temp in list.iter() {
        let _ = std::fs::remove_file(temp);
    }
    std::process::exit(code)
}

/// Runs `write` against a temporary file next to `path`, then renames it
/// into place; on any error the temporary file is removed.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), OutputError>,
) -> Result<(), OutputError> {
    write_pending(path, write)?.commit()
}

/// Runs `write` against a temporary file next to `path`, to be renamed into
/// place by [`PendingFile::commit`]; on any error the temporary file is
/// removed.
pub fn write_pending(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), OutputError>,
) -> Result<PendingFile, OutputError> {
    let pending = PendingFile::beside(path);
    write(pending.temp())?;
    Ok(pending)
}

/// Writes `text` to `path` atomically.
pub fn save_text(path: &Path, text: &str) -> Result<(), OutputError> {
    write_atomically(path, |temp| {
        std::fs::write(temp, text).map_err(|source| OutputError::Write {
            path: path.to_path_buf(),
            source,
        })
    })
}

pub fn save_image(path: &Path, image: &image::RgbImage) -> Result<(), OutputError> {
    save_image_pending(path, image)?.commit()
}

/// [`save_image`] but for the rename: the image whole under a temporary
/// name, appearing at `path` only once committed (so a run can put a
/// frame's files in place together with counting it).
pub fn save_image_pending(
    path: &Path,
    image: &image::RgbImage,
) -> Result<PendingFile, OutputError> {
    let format = format_for(path)?;
    if format == ImageFormat::Tga {
        let bytes = encode_tga(image).ok_or_else(|| OutputError::TooLargeForTga {
            path: path.to_path_buf(),
            width: image.width(),
            height: image.height(),
        })?;
        return write_pending(path, |temp| {
            std::fs::write(temp, bytes).map_err(|source| OutputError::Write {
                path: path.to_path_buf(),
                source,
            })
        });
    }
    write_pending(path, |temp| {
        image
            .save_with_format(temp, format)
            .map_err(|source| match source {
                image::ImageError::IoError(source) => OutputError::Write {
                    path: path.to_path_buf(),
                    source,
                },
                source => OutputError::Encode {
                    path: path.to_path_buf(),
                    source,
                },
            })
    })
}

/// Pixels a TGA packet holds at most (its count is 7 bits, stored minus 1).
const TGA_MAX_PACKET: usize = 128;

/// `image` as a run-length encoded, 24-bit, top-left-origin TGA file (image
/// type 10), every packet inside one row; `None` when a side exceeds the
/// format's 16 bits.
fn encode_tga(image: &image::RgbImage) -> Option<Vec<u8>> {
    let width = u16::try_from(image.width()).ok()?;
    let height = u16::try_from(image.height()).ok()?;
    let mut out = Vec::with_capacity(18 + image.as_raw().len() / 2);
    out.extend_from_slice(&[0, 0, 10, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    out.extend_from_slice(&width.to_le_bytes());
    out.extend_from_slice(&height.to_le_bytes());
    // 24 bits a pixel; descriptor: no alpha bits, origin at the top left.
    out.extend_from_slice(&[24, 0x20]);
    if width > 0 {
        for row in image.as_raw().chunks_exact(usize::from(width) * 3) {
            let pixels: Vec<[u8; 3]> = row.chunks_exact(3).map(|p| [p[2], p[1], p[0]]).collect();
            encode_tga_row(&pixels, &mut out);
        }
    }
    Some(out)
}

/// One row's packets (pixels already in the file's BGR order): a run of two
/// or more equal pixels becomes a run-length packet, anything else raw
/// packets that stop where the next run starts.
fn encode_tga_row(pixels: &[[u8; 3]], out: &mut Vec<u8>) {
    let mut start = 0;
    while start < pixels.len() {
        let first = pixels[start];
        let run = pixels[start..]
            .iter()
            .take(TGA_MAX_PACKET)
            .take_while(|&&p| p == first)
            .count();
        if run >= 2 {
            out.push(0x80 | (run - 1) as u8);
            out.extend_from_slice(&first);
            start += run;
            continue;
        }
        let mut end = start + 1;
        while end < pixels.len()
            && end - start < TGA_MAX_PACKET
            && pixels.get(end + 1) != Some(&pixels[end])
        {
            end += 1;
        }
        out.push((end - start - 1) as u8);
        for pixel in &pixels[start..end] {
            out.extend_from_slice(pixel);
        }
        start = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_png_and_tga_and_rejects_others() {
        let dir = tempfile::tempdir().unwrap();
        let image = image::RgbImage::from_pixel(3, 2, image::Rgb([10, 20, 30]));
        for name in ["a.png", "b.tga"] {
            let path = dir.path().join(name);
            save_image(&path, &image).unwrap();
            let back = image::open(&path).unwrap().to_rgb8();
            assert_eq!(back, image);
        }
        let err = save_image(&dir.path().join("c.jpg"), &image).unwrap_err();
        assert!(matches!(err, OutputError::UnsupportedFormat { .. }));
        // Only the two images: no temporary files left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    /// The rows of pixels in a TGA file of ours, each row's decoded from
    /// its own packets, failing if a packet runs past the end of a row.
    fn tga_rows_packet_by_packet(bytes: &[u8]) -> Vec<Vec<[u8; 3]>> {
        assert_eq!(
            &bytes[..3],
            &[0, 0, 10],
            "no id, no colour map, RLE true colour"
        );
        let width = usize::from(u16::from_le_bytes([bytes[12], bytes[13]]));
        let height = usize::from(u16::from_le_bytes([bytes[14], bytes[15]]));
        assert_eq!(
            (bytes[16], bytes[17]),
            (24, 0x20),
            "24 bits, top-left origin"
        );
        let mut at = 18;
        let mut rows = Vec::new();
        for y in 0..height {
            let mut row = Vec::new();
            while row.len() < width {
                let header = bytes[at];
                let count = usize::from(header & 0x7f) + 1;
                at += 1;
                assert!(
                    row.len() + count <= width,
                    "row {y}: a packet of {count} at x = {} crosses into the next row",
                    row.len()
                );
                let pixel = |i: usize| [bytes[i + 2], bytes[i + 1], bytes[i]];
                if header & 0x80 != 0 {
                    row.extend(std::iter::repeat(pixel(at)).take(count));
                    at += 3;
                } else {
                    row.extend((0..count).map(|k| pixel(at + 3 * k)));
                    at += 3 * count;
                }
            }
            rows.push(row);
        }
        assert_eq!(at, bytes.len(), "bytes after the last row");
        rows
    }

    #[test]
    fn tga_packets_end_at_each_row_end() {
        // Rows that end and start with the same colour (runs would carry
        // on across them), runs longer than a packet, and noise (raw
        // packets) that ends a row.
        let (width, height) = (300, 5);
        let image = image::RgbImage::from_fn(width, height, |x, y| match y {
            0 | 1 => image::Rgb([7, 8, 9]),
            2 if x < 150 => image::Rgb([7, 8, 9]),
            _ => image::Rgb([(x * 7 + y) as u8, (x * 13) as u8, (x / 3) as u8]),
        });
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.tga");
        save_image(&path, &image).unwrap();
        let rows = tga_rows_packet_by_packet(&std::fs::read(&path).unwrap());
        for (y, row) in rows.iter().enumerate() {
            for (x, pixel) in row.iter().enumerate() {
                assert_eq!(
                    pixel,
                    &image.get_pixel(x as u32, y as u32).0,
                    "pixel ({x}, {y})"
                );
            }
        }
        // Still run-length encoded: the flat rows (a packet per 128 pixels)
        // make the file far smaller than its pixels.
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(
            size < 18 + u64::from(width * height) * 3 * 2 / 3,
            "{size} bytes"
        );
    }

    #[test]
    fn a_tga_too_large_for_the_format_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("wide.tga");
        let err = save_image(&path, &image::RgbImage::new(70_000, 1)).unwrap_err();
        assert!(err.to_string().contains("at most 65535"), "{err}");
        assert!(!path.exists());
    }

    #[test]
    fn a_pending_file_appears_only_when_committed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        let pending = PendingFile::beside(&path);
        std::fs::write(pending.temp(), "half").unwrap();
        drop(pending);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        let pending = PendingFile::beside(&path);
        let other = PendingFile::beside(&path);
        assert_ne!(pending.temp(), other.temp(), "two writers, two names");
        std::fs::write(pending.temp(), "whole").unwrap();
        pending.commit().unwrap();
        drop(other);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "whole");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert!(!unfinished().iter().any(|p| p.starts_with(dir.path())));
    }

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing-dir").join("x.png");
        let image = image::RgbImage::new(2, 2);
        assert!(save_image(&path, &image).is_err());
        assert!(!path.exists());
    }
}

//! Writing images: the format comes from the extension (PNG or TGA), and the
//! file appears only when complete (written to a temporary name beside it,
//! then renamed), so an interrupted run leaves no half-written frame.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};

use image::ImageFormat;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: unsupported image format (use .png or .tga)")]
    UnsupportedFormat { path: PathBuf },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot encode image: {source}")]
    Encode {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
}

/// The image format for `path`, from its extension.
pub fn format_for(path: &Path) -> Result<ImageFormat, OutputError> {
    match ImageFormat::from_path(path) {
        Ok(format @ (ImageFormat::Png | ImageFormat::Tga)) => Ok(format),
        _ => Err(OutputError::UnsupportedFormat {
            path: path.to_path_buf(),
        }),
    }
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
        let temp = dir.join(format!(
            ".{name}.{}.{}.tmp",
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
    let pending = PendingFile::beside(path);
    write(pending.temp())?;
    pending.commit()
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
    let format = format_for(path)?;
    write_atomically(path, |temp| {
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

//! Writing images: the format comes from the extension (PNG or TGA), and the
//! file appears only when complete (written to a temporary name beside it,
//! then renamed), so an interrupted run leaves no half-written frame.

use std::path::{Path, PathBuf};

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

/// Runs `write` against a temporary file next to `path`, then renames it
/// into place; on any error the temporary file is removed.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), OutputError>,
) -> Result<(), OutputError> {
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let temp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = write(&temp).and_then(|()| {
        std::fs::rename(&temp, path).map_err(|source| OutputError::Write {
            path: path.to_path_buf(),
            source,
        })
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&temp);
    }
    result
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
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing-dir").join("x.png");
        let image = image::RgbImage::new(2, 2);
        assert!(save_image(&path, &image).is_err());
        assert!(!path.exists());
    }
}

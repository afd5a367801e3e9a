//! OpenEXR pictures: named channels of half floats, floats or unsigned
//! integers, one part, scan lines compressed losslessly (ZIP, 16 lines a
//! block), written whole or not at all like every other file.
//!
//! A channel name with a dot is a layer's channel (`depth.Z`,
//! `albedo.R`), the convention compositors read layers by.

use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, Text,
    WritableImage,
};

pub use exr::prelude::f16;

use super::{write_pending, OutputError, PendingFile};

/// One channel's samples, row by row from the top left.
#[derive(Clone, Debug, PartialEq)]
pub enum ExrSamples {
    Half(Vec<f16>),
    Float(Vec<f32>),
    Uint(Vec<u32>),
}

impl ExrSamples {
    fn len(&self) -> usize {
        match self {
            ExrSamples::Half(v) => v.len(),
            ExrSamples::Float(v) => v.len(),
            ExrSamples::Uint(v) => v.len(),
        }
    }

    /// Sample `index`'s bits: equal bits, equal values written.
    fn bits(&self, index: usize) -> u32 {
        match self {
            ExrSamples::Half(v) => u32::from(v[index].to_bits()),
            ExrSamples::Float(v) => v[index].to_bits(),
            ExrSamples::Uint(v) => v[index],
        }
    }

    fn kind(&self) -> &'static str {
        match self {
            ExrSamples::Half(_) => "half",
            ExrSamples::Float(_) => "float",
            ExrSamples::Uint(_) => "uint",
        }
    }
}

/// A named channel.
#[derive(Clone, Debug, PartialEq)]
pub struct ExrChannel {
    pub name: String,
    pub samples: ExrSamples,
}

/// A picture as an EXR file holds it.
#[derive(Clone, Debug, PartialEq)]
pub struct ExrPicture {
    pub width: u32,
    pub height: u32,
    pub channels: Vec<ExrChannel>,
}

/// Two EXR pictures that cannot be compared sample by sample.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ExrMismatch {
    #[error("EXR pictures of different sizes: {a:?} against {b:?}")]
    Size { a: (u32, u32), b: (u32, u32) },
    #[error("EXR pictures with other channels: {a} against {b}")]
    Channels { a: String, b: String },
}

impl ExrPicture {
    /// The channel named `name`.
    pub fn channel(&self, name: &str) -> Option<&ExrSamples> {
        self.channels
            .iter()
            .find(|c| c.name == name)
            .map(|c| &c.samples)
    }

    /// The pixels where some channel's bits differ from `other`'s, leaving
    /// out the channels named in `ignored`; both must have the same size
    /// and, `ignored` aside, the same channels of the same kinds.
    pub fn differing_pixels(
        &self,
        other: &ExrPicture,
        ignored: &[&str],
    ) -> Result<u64, ExrMismatch> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(ExrMismatch::Size {
                a: (self.width, self.height),
                b: (other.width, other.height),
            });
        }
        let compared = |picture: &ExrPicture| -> Vec<(String, &'static str)> {
            let mut list: Vec<_> = picture
                .channels
                .iter()
                .filter(|c| !ignored.contains(&c.name.as_str()))
                .map(|c| (c.name.clone(), c.samples.kind()))
                .collect();
            list.sort();
            list
        };
        let (mine, theirs) = (compared(self), compared(other));
        if mine != theirs {
            let describe = |list: &[(String, &str)]| {
                list.iter()
                    .map(|(name, kind)| format!("{name} ({kind})"))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            return Err(ExrMismatch::Channels {
                a: describe(&mine),
                b: describe(&theirs),
            });
        }
        let pixels = self.width as usize * self.height as usize;
        let mut differs = vec![false; pixels];
        for channel in &self.channels {
            if ignored.contains(&channel.name.as_str()) {
                continue;
            }
            let theirs = other
                .channel(&channel.name)
                .expect("the channel lists are equal");
            for (pixel, differs) in differs.iter_mut().enumerate() {
                *differs |= channel.samples.bits(pixel) != theirs.bits(pixel);
            }
        }
        Ok(differs.into_iter().filter(|&d| d).count() as u64)
    }
}

/// Writes `picture` to `path` atomically.
pub fn save_exr(path: &Path, picture: &ExrPicture) -> Result<(), OutputError> {
    save_exr_pending(path, picture)?.commit()
}

/// [`save_exr`] but for the rename: the file whole under a temporary
/// name, appearing at `path` only once committed.
pub fn save_exr_pending(path: &Path, picture: &ExrPicture) -> Result<PendingFile, OutputError> {
    let pixels = picture.width as usize * picture.height as usize;
    if let Some(channel) = picture.channels.iter().find(|c| c.samples.len() != pixels) {
        panic!(
            "EXR channel {} has {} samples for {pixels} pixels",
            channel.name,
            channel.samples.len()
        );
    }
    let channels = picture
        .channels
        .iter()
        .map(|channel| {
            let samples = match &channel.samples {
                ExrSamples::Half(v) => FlatSamples::F16(v.clone()),
                ExrSamples::Float(v) => FlatSamples::F32(v.clone()),
                ExrSamples::Uint(v) => FlatSamples::U32(v.clone()),
            };
            AnyChannel::new(Text::from(channel.name.as_str()), samples)
        })
        .collect();
    let layer = Layer::new(
        (picture.width as usize, picture.height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels),
    );
    let image = Image::from_layer(layer);
    write_pending(path, |temp| {
        image
            .write()
            .to_file(temp)
            .map_err(|err| exr_error(path, err))
    })
}

/// Reads the first layer of the EXR file at `path`, every channel.
pub fn read_exr(path: &Path) -> Result<ExrPicture, OutputError> {
    let image =
        exr::prelude::read_first_flat_layer_from_file(path).map_err(|err| exr_error(path, err))?;
    let layer = image.layer_data;
    let channels = layer
        .channel_data
        .list
        .into_iter()
        .map(|channel| ExrChannel {
            name: channel.name.to_string(),
            samples: match channel.sample_data {
                FlatSamples::F16(v) => ExrSamples::Half(v),
                FlatSamples::F32(v) => ExrSamples::Float(v),
                FlatSamples::U32(v) => ExrSamples::Uint(v),
            },
        })
        .collect();
    Ok(ExrPicture {
        width: layer.size.0 as u32,
        height: layer.size.1 as u32,
        channels,
    })
}

fn exr_error(path: &Path, err: exr::error::Error) -> OutputError {
    match err {
        exr::error::Error::Io(source) => OutputError::Write {
            path: path.to_path_buf(),
            source,
        },
        other => OutputError::Exr {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn picture(red: f32, depth: f32) -> ExrPicture {
        ExrPicture {
            width: 2,
            height: 1,
            channels: vec![
                ExrChannel {
                    name: "R".into(),
                    samples: ExrSamples::Half(vec![f16::from_f32(red), f16::ZERO]),
                },
                ExrChannel {
                    name: "depth.Z".into(),
                    samples: ExrSamples::Float(vec![depth, f32::INFINITY]),
                },
                ExrChannel {
                    name: "object.id".into(),
                    samples: ExrSamples::Uint(vec![3, 0]),
                },
            ],
        }
    }

    #[test]
    fn a_written_picture_reads_back_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let written = picture(0.25, 7.5);
        save_exr(&path, &written).unwrap();
        let mut back = read_exr(&path).unwrap();
        back.channels.sort_by(|a, b| a.name.cmp(&b.name));
        assert_eq!(back, written);
        assert_eq!(written.differing_pixels(&back, &[]), Ok(0));
        // Only the file: no temporary left beside it.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn differing_pixels_counts_any_channel_but_the_ignored() {
        let a = picture(0.25, 7.5);
        assert_eq!(a.differing_pixels(&picture(0.5, 7.5), &[]), Ok(1));
        assert_eq!(a.differing_pixels(&picture(0.25, 7.25), &[]), Ok(1));
        assert_eq!(
            a.differing_pixels(&picture(0.25, 7.25), &["depth.Z"]),
            Ok(0)
        );
        // A change within half precision is no change in what is written.
        assert_eq!(a.differing_pixels(&picture(0.25 + 1e-6, 7.5), &[]), Ok(0));
        let mut fewer = picture(0.25, 7.5);
        fewer.channels.pop();
        assert!(matches!(
            a.differing_pixels(&fewer, &[]),
            Err(ExrMismatch::Channels { .. })
        ));
    }
}

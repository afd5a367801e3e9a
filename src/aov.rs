//! Arbitrary output variables (AOVs): what each pixel's primary ray met,
//! written beside a frame's colours as layers of an OpenEXR frame for
//! compositing, and the frame's reuse mask.
//!
//! Every AOV but `traced` is a pure function of the pixel and the scene
//! as posed: whatever the samples a pixel, one ray through the pixel's
//! centre (the picture's own centre rays, [`crate::reuse::StorePlan::centre_rays`])
//! is cast afresh for every frame, in the same packets each time. A frame
//! made from reused samples therefore writes the AOVs its full render
//! writes, bit for bit, with no store keeping them; `traced` is the one
//! AOV that tells the two apart. Depth and object ids would mean nothing
//! averaged over a pixel's samples, so none of them is.
//!
//! Nothing here runs unless AOVs are asked for: colours are traced as
//! they always are.

use glam::Vec3;
use rayon::prelude::*;

use crate::output::exr::f16;
use crate::output::{ExrChannel, ExrPicture, ExrSamples};
use crate::render::{Frame, PrimaryRays, SampleGroup, GROUP_HEIGHT, GROUP_WIDTH};
use crate::shade::{FirstHit, Shader};

/// One arbitrary output variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aov {
    /// Distance from the eye to the primary hit, along the ray.
    Depth,
    /// The primary hit's world-space shading normal.
    Normal,
    /// The primary hit's diffuse surface colour (checker and texture).
    Albedo,
    /// Which object the primary ray hit.
    Object,
    /// Whether the frame traced the pixel afresh (1) or reused it (0).
    Traced,
}

impl Aov {
    pub const ALL: [Aov; 5] = [
        Aov::Depth,
        Aov::Normal,
        Aov::Albedo,
        Aov::Object,
        Aov::Traced,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Aov::Depth => "depth",
            Aov::Normal => "normal",
            Aov::Albedo => "albedo",
            Aov::Object => "object",
            Aov::Traced => "traced",
        }
    }

    /// The EXR channels it is written as.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            Aov::Depth => &["depth.Z"],
            Aov::Normal => &["N.x", "N.y", "N.z"],
            Aov::Albedo => &["albedo.R", "albedo.G", "albedo.B"],
            Aov::Object => &["object.id"],
            Aov::Traced => &[TRACED_CHANNEL],
        }
    }

    fn bit(self) -> u8 {
        1 << self as u8
    }
}

/// The channel of the reuse mask: the one AOV a reused frame and its full
/// render differ in.
pub const TRACED_CHANNEL: &str = "traced.mask";

/// Which AOVs a run writes (`--aov`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AovSet(u8);

impl AovSet {
    pub const NONE: AovSet = AovSet(0);

    /// A comma list of AOV names.
    pub fn parse(text: &str) -> Result<AovSet, String> {
        let mut set = AovSet::NONE;
        for word in text.split(',').map(str::trim) {
            let Some(aov) = Aov::ALL.into_iter().find(|a| a.name() == word) else {
                let names: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
                return Err(format!(
                    "unknown AOV '{word}' (expected a comma list of: {})",
                    names.join(", ")
                ));
            };
            set = set.with(aov);
        }
        Ok(set)
    }

    pub fn with(self, aov: Aov) -> AovSet {
        AovSet(self.0 | aov.bit())
    }

    pub fn has(self, aov: Aov) -> bool {
        self.0 & aov.bit() != 0
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Whether any AOV asks for what the primary rays met.
    pub fn needs_first_hits(self) -> bool {
        Aov::ALL
            .into_iter()
            .any(|aov| aov != Aov::Traced && self.has(aov))
    }
}

/// One view's AOVs.
#[derive(Clone, Debug, PartialEq)]
pub struct Aovs {
    pub set: AovSet,
    pub width: u32,
    pub height: u32,
    /// Per pixel, row by row, what its centre ray met first (None: it
    /// met nothing); empty unless [`AovSet::needs_first_hits`].
    pub first_hits: Vec<Option<FirstHit>>,
    /// Per pixel, whether the frame traced it afresh; empty unless
    /// `traced` is asked for.
    pub traced: Vec<bool>,
}

impl Aovs {
    /// The AOVs of `set` for a `width` x `height` picture whose pixel
    /// (x, y) is `centre_rays`' cell (x, y); `traced` gives the reuse mask
    /// (called only if `traced` is asked for).
    pub fn trace(
        shader: &Shader,
        centre_rays: &dyn PrimaryRays,
        (width, height): (u32, u32),
        set: AovSet,
        traced: impl FnOnce() -> Vec<bool>,
    ) -> Aovs {
        let first_hits = if set.needs_first_hits() {
            trace_first_hits(shader, centre_rays, width, height)
        } else {
            Vec::new()
        };
        let traced = if set.has(Aov::Traced) {
            traced()
        } else {
            Vec::new()
        };
        Aovs {
            set,
            width,
            height,
            first_hits,
            traced,
        }
    }

    /// The pixels a picture has.
    fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// What each pixel's centre ray met first: pixel (x, y) is `source`'s
/// cell (x, y), traced in the 4x2 groups of the image, so the same
/// picture's AOVs are cast in the same packets every time.
fn trace_first_hits(
    shader: &Shader,
    source: &dyn PrimaryRays,
    width: u32,
    height: u32,
) -> Vec<Option<FirstHit>> {
    let width = width as usize;
    let mut hits = vec![None; width * height as usize];
    let band = width * GROUP_HEIGHT as usize;
    if band == 0 {
        return hits;
    }
    hits.par_chunks_mut(band)
        .enumerate()
        .for_each(|(index, pixels)| {
            let row = (index * GROUP_HEIGHT as usize) as i64;
            let group_width = GROUP_WIDTH as usize;
            for x in (0..width).step_by(group_width) {
                let group = SampleGroup { col: x as i64, row };
                let (rays, mask) = source.primary_group(group);
                let found = shader.first_hits(&rays, mask);
                let n = group_width.min(width - x);
                for (y, lanes) in found.chunks_exact(group_width).enumerate() {
                    let start = y * width + x;
                    if let Some(dst) = pixels.get_mut(start..start + n) {
                        dst.copy_from_slice(&lanes[..n]);
                    }
                }
            }
        });
    hits
}

/// `frame` as an EXR picture: linear R, G, B as half floats with alpha 1
/// (the renderer covers every pixel: a miss shows the background), and
/// `aovs`' layers.
///
/// Depth and object ids are 32-bit floats, the rest half floats. Where a
/// pixel's centre ray met nothing, depth is +infinity, the normal and
/// albedo are 0 and the object id is 0; ids count the scene's objects
/// from 1.
pub fn exr_picture(frame: &Frame, aovs: Option<&Aovs>) -> ExrPicture {
    let half = |value: f32| f16::from_f32(value);
    let colour =
        |axis: usize| ExrSamples::Half(frame.pixels.iter().map(|p| half(p[axis])).collect());
    let mut channels = vec![
        channel("R", colour(0)),
        channel("G", colour(1)),
        channel("B", colour(2)),
        channel("A", ExrSamples::Half(vec![f16::ONE; frame.pixels.len()])),
    ];
    let Some(aovs) = aovs else {
        return picture(frame, channels);
    };
    assert_eq!(
        (aovs.width, aovs.height),
        (frame.width, frame.height),
        "AOVs of another picture"
    );
    let hits = &aovs.first_hits;
    let vector = |name: &str, axis: usize, of: fn(&FirstHit) -> Vec3| {
        let samples = hits
            .iter()
            .map(|hit| half(hit.as_ref().map_or(0.0, |h| of(h)[axis])))
            .collect();
        channel(name, ExrSamples::Half(samples))
    };
    for aov in Aov::ALL.into_iter().filter(|&aov| aovs.set.has(aov)) {
        let names = aov.channels();
        match aov {
            Aov::Depth => {
                let depth = hits
                    .iter()
                    .map(|hit| hit.as_ref().map_or(f32::INFINITY, |h| h.distance))
                    .collect();
                channels.push(channel(names[0], ExrSamples::Float(depth)));
            }
            Aov::Normal => {
                for (axis, name) in names.iter().enumerate() {
                    channels.push(vector(name, axis, |h| h.normal));
                }
            }
            Aov::Albedo => {
                for (axis, name) in names.iter().enumerate() {
                    channels.push(vector(name, axis, |h| h.albedo));
                }
            }
            Aov::Object => {
                // Floats, exact to 2^24 objects: readers show unsigned
                // integer channels scaled to 0..1 (OpenImageIO does).
                let ids = hits
                    .iter()
                    .map(|hit| hit.as_ref().map_or(0.0, |h| (h.object + 1) as f32))
                    .collect();
                channels.push(channel(names[0], ExrSamples::Float(ids)));
            }
            Aov::Traced => {
                debug_assert_eq!(aovs.traced.len(), aovs.pixels());
                let mask = aovs
                    .traced
                    .iter()
                    .map(|&t| if t { f16::ONE } else { f16::ZERO })
                    .collect();
                channels.push(channel(names[0], ExrSamples::Half(mask)));
            }
        }
    }
    picture(frame, channels)
}

/// The linear colours of an EXR picture's R, G and B channels, as any
/// kind of sample; None if one is missing.
pub fn colours_of(picture: &ExrPicture) -> Option<Frame> {
    let values = |name: &str| -> Option<Vec<f32>> {
        Some(match picture.channel(name)? {
            ExrSamples::Half(v) => v.iter().map(|h| h.to_f32()).collect(),
            ExrSamples::Float(v) => v.clone(),
            ExrSamples::Uint(v) => v.iter().map(|&u| u as f32).collect(),
        })
    };
    let (r, g, b) = (values("R")?, values("G")?, values("B")?);
    let pixels = r
        .into_iter()
        .zip(g)
        .zip(b)
        .map(|((r, g), b)| Vec3::new(r, g, b))
        .collect();
    Some(Frame {
        width: picture.width,
        height: picture.height,
        pixels,
    })
}

fn channel(name: &str, samples: ExrSamples) -> ExrChannel {
    ExrChannel {
        name: name.to_string(),
        samples,
    }
}

fn picture(frame: &Frame, channels: Vec<ExrChannel>) -> ExrPicture {
    ExrPicture {
        width: frame.width,
        height: frame.height,
        channels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aov_lists_parse_and_unknown_names_are_refused_with_the_known_ones() {
        let set = AovSet::parse("depth, traced").unwrap();
        assert!(set.has(Aov::Depth) && set.has(Aov::Traced));
        assert!(!set.has(Aov::Normal));
        assert!(set.needs_first_hits());
        assert!(!AovSet::parse("traced").unwrap().needs_first_hits());
        let err = AovSet::parse("depth,colour").unwrap_err();
        assert!(err.contains("'colour'"), "{err}");
        assert!(
            err.contains("depth, normal, albedo, object, traced"),
            "{err}"
        );
        assert!(AovSet::parse("").is_err());
    }

    #[test]
    fn misses_are_infinitely_far_of_no_object_and_a_hit_counts_objects_from_one() {
        let mut frame = Frame::new(2, 1);
        frame.pixels[0] = Vec3::new(0.5, 2.0, 1e-3);
        let hit = FirstHit {
            distance: 4.25,
            normal: Vec3::Y,
            albedo: Vec3::new(0.25, 0.5, 1.0),
            object: 0,
        };
        let aovs = Aovs {
            set: AovSet::parse("depth,normal,albedo,object,traced").unwrap(),
            width: 2,
            height: 1,
            first_hits: vec![Some(hit), None],
            traced: vec![false, true],
        };
        let picture = exr_picture(&frame, Some(&aovs));
        let get = |name: &str| picture.channel(name).unwrap().clone();
        assert_eq!(
            get("R"),
            ExrSamples::Half(vec![f16::from_f32(0.5), f16::ZERO])
        );
        assert_eq!(get("A"), ExrSamples::Half(vec![f16::ONE; 2]));
        assert_eq!(get("depth.Z"), ExrSamples::Float(vec![4.25, f32::INFINITY]));
        assert_eq!(get("N.y"), ExrSamples::Half(vec![f16::ONE, f16::ZERO]));
        assert_eq!(
            get("albedo.R"),
            ExrSamples::Half(vec![f16::from_f32(0.25), f16::ZERO])
        );
        assert_eq!(get("object.id"), ExrSamples::Float(vec![1.0, 0.0]));
        assert_eq!(
            get(TRACED_CHANNEL),
            ExrSamples::Half(vec![f16::ZERO, f16::ONE])
        );
        assert_eq!(picture.channels.len(), 4 + 1 + 3 + 3 + 1 + 1);
    }
}

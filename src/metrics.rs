//! How far one image is from another: the error figures every accuracy
//! report uses, the converged reference they are measured against, and the
//! bit-for-bit comparisons behind the exactness checks.

use crate::render::Frame;
use crate::sampling::{PixelSamples, REFERENCE_SAMPLES_PER_PIXEL};

/// Two images of different sizes: nothing to compare pixel by pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("images of different sizes: {a:?} against {b:?}")]
pub struct SizeMismatch {
    pub a: (u32, u32),
    pub b: (u32, u32),
}

/// Fails unless `a` and `b` have the same size.
fn same_size(a: (u32, u32), b: (u32, u32)) -> Result<(), SizeMismatch> {
    if a == b {
        Ok(())
    } else {
        Err(SizeMismatch { a, b })
    }
}

fn frame_size(frame: &Frame) -> (u32, u32) {
    (frame.width, frame.height)
}

/// How far an approximate frame is from its reference, on colours clamped
/// to [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ImageError {
    pub max_abs: f32,
    pub mean_abs: f64,
    /// Peak signal-to-noise ratio in dB (infinite for identical frames).
    pub psnr_db: f64,
    /// Share of pixels whose 8-bit sRGB value differs by more than one
    /// step in some channel (a step is rounding; two are a difference).
    pub differing_share: f64,
}

pub fn image_error(frame: &Frame, reference: &Frame) -> Result<ImageError, SizeMismatch> {
    same_size(frame_size(frame), frame_size(reference))?;
    let srgb = crate::color::srgb_table();
    let (mut max_abs, mut sum_abs, mut sum_sq, mut differing) = (0.0f32, 0.0f64, 0.0f64, 0u64);
    for (a, b) in frame.pixels.iter().zip(&reference.pixels) {
        let (a, b) = (
            a.clamp(glam::Vec3::ZERO, glam::Vec3::ONE),
            b.clamp(glam::Vec3::ZERO, glam::Vec3::ONE),
        );
        let d = (a - b).abs();
        max_abs = max_abs.max(d.max_element());
        sum_abs += f64::from(d.element_sum()) / 3.0;
        sum_sq += f64::from(d.dot(d)) / 3.0;
        let (a8, b8) = (
            a.to_array().map(|c| srgb.encode(c)),
            b.to_array().map(|c| srgb.encode(c)),
        );
        differing += u64::from(a8.iter().zip(&b8).any(|(x, y)| x.abs_diff(*y) > 1));
    }
    let n = frame.pixels.len().max(1) as f64;
    let mse = sum_sq / n;
    Ok(ImageError {
        max_abs,
        mean_abs: sum_abs / n,
        psnr_db: if mse == 0.0 {
            f64::INFINITY
        } else {
            -10.0 * mse.log10()
        },
        differing_share: differing as f64 / n,
    })
}

/// PSNR in dB of one 8-bit picture against another, over every channel
/// (infinite for identical pictures): for pictures known only as shown.
pub fn psnr_8bit(a: &image::RgbImage, b: &image::RgbImage) -> Result<f64, SizeMismatch> {
    same_size(a.dimensions(), b.dimensions())?;
    let sum: f64 = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2))
        .sum();
    let mse = sum / a.as_raw().len().max(1) as f64;
    Ok(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0 * 255.0 / mse).log10()
    })
}

/// Regions of `size` pixels (tiling the image from its top-left corner) in
/// which some pixel differs in any bit: OSTC's oracle, the fewest regions
/// any region-based reuse must re-trace.
pub fn changed_regions(a: &Frame, b: &Frame, size: (i64, i64)) -> Result<u64, SizeMismatch> {
    same_size(frame_size(a), frame_size(b))?;
    let (w, h) = (size.0.max(1) as usize, size.1.max(1) as usize);
    let across = (a.width as usize).div_ceil(w);
    let mut changed = std::collections::HashSet::new();
    for (i, (x, y)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if x.to_array().map(f32::to_bits) != y.to_array().map(f32::to_bits) {
            let (col, row) = (i % a.width as usize, i / a.width as usize);
            changed.insert(row / h * across + col / w);
        }
    }
    Ok(changed.len() as u64)
}

/// Pixels whose colours differ in any bit.
pub fn count_differences(a: &Frame, b: &Frame) -> Result<u64, SizeMismatch> {
    same_size(frame_size(a), frame_size(b))?;
    Ok(a.pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| x.to_array().map(f32::to_bits) != y.to_array().map(f32::to_bits))
        .count() as u64)
}

/// Pixels whose bytes differ between two 8-bit images (what is written).
pub fn count_byte_differences(
    a: &image::RgbImage,
    b: &image::RgbImage,
) -> Result<u64, SizeMismatch> {
    same_size(a.dimensions(), b.dimensions())?;
    Ok(a.pixels().zip(b.pixels()).filter(|(x, y)| x != y).count() as u64)
}

/// How an output differs from its reference: pixels differing in linear
/// colour, and in the 8-bit image written (which comes from its own store
/// and is checked as such).
pub fn output_differences(
    frame: &Frame,
    written: &image::RgbImage,
    reference: &Frame,
) -> Result<(u64, u64), SizeMismatch> {
    Ok((
        count_differences(frame, reference)?,
        count_byte_differences(written, &reference.to_rgb8())?,
    ))
}

/// Samples a pixel of the converged reference the bench and `animate
/// --verify` measure both sides against. At 640x480 a 64-spp render of an
/// E1 or E2 frame is 52.7-54.3 dB from a 256-spp one, and 4 spp is
/// 35.6-36.3 dB from it, so the reference's own error is under 2% of the
/// squared error it helps measure at 4 spp (under 0.1 dB), at a quarter of
/// 256 spp's time.
pub const BENCH_REFERENCE_SAMPLES: u32 = 64;

/// Frames between two that get a reference (the last frame always does):
/// a reference frame costs as much as 64 frames at 1 spp.
pub const REFERENCE_EVERY: u32 = 20;

/// The reference a run at `run` samples a pixel is measured against: the
/// bench's count up to 4 samples a pixel, and from there on the converged
/// count, so that the reference has at least sixteen times the run's
/// samples where it can (its own error then stays under about a tenth of
/// the run's squared error).
pub fn reference_samples(run: PixelSamples) -> PixelSamples {
    let count = if run.count() * 16 <= BENCH_REFERENCE_SAMPLES {
        BENCH_REFERENCE_SAMPLES
    } else {
        REFERENCE_SAMPLES_PER_PIXEL
    };
    PixelSamples::new(count).expect("the reference counts are within the limits")
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn comparisons_refuse_images_of_different_sizes() {
        let (a, b) = (Frame::new(4, 2), Frame::new(2, 4));
        let mismatch = SizeMismatch {
            a: (4, 2),
            b: (2, 4),
        };
        assert_eq!(count_differences(&a, &b), Err(mismatch));
        assert_eq!(image_error(&a, &b).unwrap_err(), mismatch);
        assert_eq!(changed_regions(&a, &b, (2, 2)), Err(mismatch));
        // A prefix of the same pixels is not the same picture.
        let short = Frame::new(4, 1);
        assert!(count_differences(&a, &short).is_err());
        let (x, y) = (image::RgbImage::new(4, 2), image::RgbImage::new(4, 1));
        assert!(count_byte_differences(&x, &y).is_err());
    }

    #[test]
    fn the_differing_share_counts_pixels_more_than_one_8_bit_step_apart() {
        // The linear value that sRGB-encodes to `code`.
        let step = |code: u8| {
            let linear = ((f32::from(code) / 255.0 + 0.055) / 1.055).powf(2.4);
            assert_eq!(crate::color::encode_srgb(linear), code);
            linear
        };
        let mut reference = Frame::new(3, 1);
        reference.pixels.fill(Vec3::splat(step(100)));
        let mut frame = reference.clone();
        frame.pixels[1].x = step(101);
        frame.pixels[2].y = step(102);
        let error = image_error(&frame, &reference).unwrap();
        assert_eq!(error.differing_share, 1.0 / 3.0);
    }

    #[test]
    fn differences_count_pixels_in_bits_and_in_bytes() {
        let a = Frame::new(3, 2);
        let mut b = a.clone();
        // Two bits apart in linear colour; the same byte once encoded.
        b.pixels[4] = Vec3::splat(f32::from_bits(2));
        assert_eq!(count_differences(&a, &b), Ok(1));
        assert_eq!(count_byte_differences(&a.to_rgb8(), &b.to_rgb8()), Ok(0));
        b.pixels[1] = Vec3::ONE;
        assert_eq!(count_differences(&a, &b), Ok(2));
        assert_eq!(count_byte_differences(&a.to_rgb8(), &b.to_rgb8()), Ok(1));
    }

    #[test]
    fn an_output_is_checked_in_what_is_written_too() {
        let reference = Frame::new(3, 2);
        let mut written = reference.to_rgb8();
        assert_eq!(
            output_differences(&reference, &written, &reference),
            Ok((0, 0))
        );
        // Linear colour right, the written bytes wrong.
        written.put_pixel(2, 1, image::Rgb([0, 0, 1]));
        assert_eq!(
            output_differences(&reference, &written, &reference),
            Ok((0, 1))
        );
    }

    #[test]
    fn the_reference_is_finer_than_the_run() {
        let count = |spp| reference_samples(PixelSamples::new(spp).unwrap()).count();
        assert_eq!(count(1), BENCH_REFERENCE_SAMPLES);
        assert_eq!(count(4), BENCH_REFERENCE_SAMPLES);
        assert_eq!(count(9), REFERENCE_SAMPLES_PER_PIXEL);
        assert_eq!(count(16), REFERENCE_SAMPLES_PER_PIXEL);
        assert_eq!(count(BENCH_REFERENCE_SAMPLES), REFERENCE_SAMPLES_PER_PIXEL);
    }
}

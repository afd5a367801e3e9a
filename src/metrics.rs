//! How far one image is from another: the error figures every accuracy
//! report uses, and the bit-for-bit comparisons behind the exactness
//! checks.

use crate::render::Frame;

/// How far an approximate frame is from its reference, on colours clamped
/// to [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ImageError {
    pub max_abs: f32,
    pub mean_abs: f64,
    /// Peak signal-to-noise ratio in dB (infinite for identical frames).
    pub psnr_db: f64,
    /// Share of pixels whose 8-bit sRGB value differs.
    pub differing_share: f64,
}

pub fn image_error(frame: &Frame, reference: &Frame) -> ImageError {
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
        differing +=
            u64::from(a.to_array().map(|c| srgb.encode(c)) != b.to_array().map(|c| srgb.encode(c)));
    }
    let n = frame.pixels.len().max(1) as f64;
    let mse = sum_sq / n;
    ImageError {
        max_abs,
        mean_abs: sum_abs / n,
        psnr_db: if mse == 0.0 {
            f64::INFINITY
        } else {
            -10.0 * mse.log10()
        },
        differing_share: differing as f64 / n,
    }
}

/// Regions of `size` pixels (tiling the image from its top-left corner) in
/// which some pixel differs in any bit: OSTC's oracle, the fewest regions
/// any region-based reuse must re-trace.
pub fn changed_regions(a: &Frame, b: &Frame, size: (i64, i64)) -> u64 {
    let (w, h) = (size.0.max(1) as usize, size.1.max(1) as usize);
    let across = (a.width as usize).div_ceil(w);
    let mut changed = std::collections::HashSet::new();
    for (i, (x, y)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if x.to_array().map(f32::to_bits) != y.to_array().map(f32::to_bits) {
            let (col, row) = (i % a.width as usize, i / a.width as usize);
            changed.insert(row / h * across + col / w);
        }
    }
    changed.len() as u64
}

/// Pixels whose colours differ in any bit.
pub fn count_differences(a: &Frame, b: &Frame) -> u64 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| x.to_array().map(f32::to_bits) != y.to_array().map(f32::to_bits))
        .count() as u64
}

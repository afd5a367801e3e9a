//! Cut-out maps: where an image lets rays through a surface.
//!
//! Promises:
//! - A map's coverage is the image's alpha when any of its texels is not
//!   opaque, else its grey level (the mean of a texel's three bytes, read
//!   as data, not as sRGB light): exporters write cut-outs both ways, an
//!   RGBA image shared with the diffuse map or a black-and-white mask.
//! - [`Cutout::lets_through`] is a pure function of the triangle, the
//!   barycentrics and the map: the texture coordinates there looked up in
//!   the full-size image, bilinear (texel centres at half-integers,
//!   wrapped like every texture), clear below half. Both backends ask it
//!   about every hit on a cut-out mesh, so a hit depends only on the ray,
//!   never on which level of detail a shader would pick.

use std::sync::Arc;

use glam::Vec2;

use super::TriangleMesh;

/// A cut-out map: one coverage byte (255 opaque) per texel of the image.
pub struct Coverage {
    width: u32,
    height: u32,
    values: Vec<u8>,
}

/// Coverage at or above this (of 255) keeps a hit. Bilinear weights sum to
/// one, so comparing the blend of bytes with it is the same as comparing
/// the blend of coverages in 0..1 with one half.
const KEEP_FROM: f32 = 127.5;

impl Coverage {
    /// The coverage of a `width` x `height` image of RGBA bytes (row-major,
    /// top row first, at least one texel).
    pub fn from_rgba8(width: u32, height: u32, texels: &[[u8; 4]]) -> Coverage {
        assert!(width > 0 && height > 0 && texels.len() == width as usize * height as usize);
        let has_alpha = texels.iter().any(|t| t[3] < 255);
        let values = texels
            .iter()
            .map(|&[r, g, b, a]| {
                if has_alpha {
                    a
                } else {
                    ((u16::from(r) + u16::from(g) + u16::from(b) + 1) / 3) as u8
                }
            })
            .collect();
        Coverage {
            width,
            height,
            values,
        }
    }

    /// Whether the surface is clear at texture coordinates `uv`.
    #[inline]
    pub fn lets_through(&self, uv: Vec2) -> bool {
        let uv = uv - uv.floor();
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let at = |x: i64, y: i64| {
            let x = x.rem_euclid(i64::from(self.width)) as usize;
            let y = y.rem_euclid(i64::from(self.height)) as usize;
            f32::from(self.values[y * self.width as usize + x])
        };
        let top = at(x0, y0) + (at(x0 + 1, y0) - at(x0, y0)) * fx;
        let bottom = at(x0, y0 + 1) + (at(x0 + 1, y0 + 1) - at(x0, y0 + 1)) * fx;
        top + (bottom - top) * fy < KEEP_FROM
    }

    /// Share of the image's texels that let rays through.
    pub fn clear_share(&self) -> f64 {
        let clear = self
            .values
            .iter()
            .filter(|&&v| f32::from(v) < KEEP_FROM)
            .count();
        clear as f64 / self.values.len() as f64
    }
}

/// A cut-out map shared by the materials and meshes that use it. Two are
/// equal when they are the same map.
#[derive(Clone)]
pub struct CoverageRef(pub Arc<Coverage>);

impl std::ops::Deref for CoverageRef {
    type Target = Coverage;
    fn deref(&self) -> &Coverage {
        &self.0
    }
}

impl PartialEq for CoverageRef {
    fn eq(&self, other: &CoverageRef) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl std::fmt::Debug for CoverageRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Coverage({}x{})", self.width, self.height)
    }
}

/// A mesh's cut-out: its triangles' texture coordinates, and the map
/// that says where they let rays through.
#[derive(Clone, Debug)]
pub struct Cutout {
    /// Per triangle, its corners' texture coordinates.
    corners: Arc<[[Vec2; 3]]>,
    coverage: CoverageRef,
}

impl Cutout {
    /// `mesh`'s cut-out by `coverage`; `None` for a mesh without texture
    /// coordinates, which the map cannot be placed on.
    pub fn new(mesh: &TriangleMesh, coverage: CoverageRef) -> Option<Cutout> {
        if mesh.texcoords.is_empty() {
            return None;
        }
        let corners = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| mesh.texcoords[i as usize]))
            .collect();
        Some(Cutout { corners, coverage })
    }

    /// Whether triangle `prim` is clear at barycentrics (`u`, `v`) (p =
    /// (1-u-v) v0 + u v1 + v v2, both backends' convention): a ray
    /// meeting it there goes on.
    #[inline]
    pub fn lets_through(&self, prim: u32, u: f32, v: f32) -> bool {
        let [a, b, c] = self.corners[prim as usize];
        self.coverage
            .lets_through(a * (1.0 - u - v) + b * u + c * v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coverage(width: u32, height: u32, texels: Vec<[u8; 4]>) -> Coverage {
        Coverage::from_rgba8(width, height, &texels)
    }

    #[test]
    fn alpha_decides_when_present_else_the_grey_level() {
        // Left texel clear by alpha, right opaque; colours do not matter.
        let alpha = coverage(2, 1, vec![[255, 255, 255, 0], [0, 0, 0, 255]]);
        assert!(alpha.lets_through(Vec2::new(0.25, 0.5)));
        assert!(!alpha.lets_through(Vec2::new(0.75, 0.5)));
        // No alpha: black is clear, white opaque.
        let mask = coverage(2, 1, vec![[0, 0, 0, 255], [255, 255, 255, 255]]);
        assert!(mask.lets_through(Vec2::new(0.25, 0.5)));
        assert!(!mask.lets_through(Vec2::new(0.75, 0.5)));
        assert_eq!(mask.clear_share(), 0.5);
    }

    #[test]
    fn the_edge_lies_half_way_between_texel_centres_and_wraps() {
        let mask = coverage(2, 1, vec![[0, 0, 0, 255], [255, 255, 255, 255]]);
        // Centres at u = 0.25 (clear) and 0.75 (opaque): the blend crosses
        // one half at u = 0.5, and, wrapping, at u = 0 (= 1).
        assert!(mask.lets_through(Vec2::new(0.49, 0.5)));
        assert!(!mask.lets_through(Vec2::new(0.51, 0.5)));
        assert!(!mask.lets_through(Vec2::new(0.99, 0.5)));
        assert!(mask.lets_through(Vec2::new(1.01, 0.5)));
        assert!(mask.lets_through(Vec2::new(-0.75, 3.5)));
    }
}

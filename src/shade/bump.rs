//! Bump and normal maps: a material's relief bends the shading normal of
//! meshes with texture coordinates, in the frame the texture lies in on
//! each triangle.
//!
//! Promises: the bent normal is a pure function of the hit, the ray and
//! the width of its cone (a sample traced again bends the same way);
//! relief that is flat where the lookups land (a constant height map, a
//! normal map of (128, 128, 255)) leaves the shading normal's bits as
//! they were; a bent normal never turns away from the eye
//! ([`facing_the_eye`]). Where a mesh has no texture coordinates, or a
//! triangle's are degenerate, and on other shapes, the normal is left as
//! it was (loading warns of the first two).

use glam::{Vec2, Vec3};

use super::WorldShape;
use crate::ray::{Hit, Ray};
use crate::scene::BumpMap;
use crate::texture::{cone_level_of_detail, Texture};

/// The least cosine a bent normal keeps with the direction to the eye
/// (about 87 degrees): see [`facing_the_eye`].
const MIN_FACING: f32 = 0.05;

/// A normal map's byte 128, decoded: no tilt. 127.5, the middle of 0 to
/// 255, is not a byte, so flat normal maps store 128; reading it as the
/// middle makes them flat exactly (255 is still 1, and 0 reads as -1).
const NORMAL_MAP_MIDDLE: f32 = 128.0 / 255.0;

/// Where a hit lies in a texture, with the triangle's texture frame.
struct TexturePoint {
    uv: Vec2,
    /// Level of detail of the ray cone's footprint.
    lod: f32,
    /// How the world point moves with each texture coordinate (v as
    /// stored: down the image).
    dpdu: Vec3,
    dpdv: Vec3,
}

impl WorldShape<'_> {
    /// `shading` (unit, facing the ray) bent by `bump` at `hit`, the map
    /// filtered over the footprint of a ray cone `width` wide there.
    #[inline(never)]
    pub(super) fn bumped_normal(
        &self,
        bump: &BumpMap,
        ray: &Ray,
        hit: &Hit,
        width: f32,
        shading: Vec3,
    ) -> Vec3 {
        let map = match bump {
            BumpMap::Height { map, .. } | BumpMap::Normal { map } => map,
        };
        let Some(at) = self.texture_point(map, ray, hit, width) else {
            return shading;
        };
        let bent = match bump {
            BumpMap::Height { map, scale } => height_normal(map, *scale, &at, shading),
            BumpMap::Normal { map } => mapped_normal(map, &at, shading),
        };
        match bent {
            Some(bent) => facing_the_eye(bent, shading, ray.dir),
            None => shading,
        }
    }

    /// Where `hit` lies in `map` on a mesh with texture coordinates, at the
    /// level of detail [`WorldShape::texel`] reads, with the triangle's
    /// dP/du and dP/dv; `None` elsewhere and where the triangle's texture
    /// coordinates span no area.
    fn texture_point(
        &self,
        map: &Texture,
        ray: &Ray,
        hit: &Hit,
        width: f32,
    ) -> Option<TexturePoint> {
        let WorldShape::Mesh {
            mesh, transform, ..
        } = self
        else {
            return None;
        };
        let uv = mesh.texcoord(hit.prim, hit.u, hit.v)?;
        let [a, b, c] = mesh
            .vertices(hit.prim)
            .map(|p| transform.map_or(p, |xf| xf.transform_point3(p)));
        let [ta, tb, tc] = mesh.triangles[hit.prim as usize].map(|i| mesh.texcoords[i as usize]);
        let (e1, e2) = (b - a, c - a);
        let (d1, d2) = (tb - ta, tc - ta);
        let det = d1.perp_dot(d2);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let dpdu = (e1 * d2.y - e2 * d1.y) / det;
        let dpdv = (e2 * d1.x - e1 * d2.x) / det;
        let (w, h) = map.size();
        let cross = e1.cross(e2);
        let world_area = cross.length();
        let texel_area = det.abs() * w as f32 * h as f32;
        let cos = ray.dir.dot(cross) / (ray.dir.length() * world_area);
        let lod = cone_level_of_detail(width, cos, texel_area, world_area);
        (dpdu.is_finite() && dpdv.is_finite()).then_some(TexturePoint {
            uv,
            lod,
            dpdu,
            dpdv,
        })
    }
}

/// The normal of the surface raised along `shading` by `scale` times the
/// height map (Blinn's bump mapping, as pbrt's `BumpMap`): with the
/// tangents Tu, Tv (dP/du, dP/dv in the plane normal to `shading`, N) and
/// the height's slopes hu, hv, the normal of P + h N is
/// (Tu + hu N) x (Tv + hv N). The slopes are central differences of the
/// filtered lookup, a texel of the level read apart, so a footprint
/// spanning many texels sees their mean slope rather than one texel's
/// edge. `None`: no slope there.
fn height_normal(map: &Texture, scale: f32, at: &TexturePoint, shading: Vec3) -> Option<Vec3> {
    let span = map.texel_span(at.lod);
    let height = |du: f32, dv: f32| {
        let c = map.sample(at.uv + Vec2::new(du, dv), at.lod);
        (c.x + c.y + c.z) / 3.0
    };
    let rise_u = height(0.5 * span.x, 0.0) - height(-0.5 * span.x, 0.0);
    let rise_v = height(0.0, 0.5 * span.y) - height(0.0, -0.5 * span.y);
    if rise_u == 0.0 && rise_v == 0.0 {
        return None;
    }
    let (hu, hv) = (scale * rise_u / span.x, scale * rise_v / span.y);
    let tu = at.dpdu - shading * shading.dot(at.dpdu);
    let tv = at.dpdv - shading * shading.dot(at.dpdv);
    let flat = tu.cross(tv);
    // Tu x Tv points along N or against it, as the texture is mirrored on
    // the triangle or not; the bent normal stays on N's side.
    let side = if flat.dot(shading) < 0.0 { -1.0 } else { 1.0 };
    let bent = (flat + tu.cross(shading) * hv + shading.cross(tv) * hu) * side;
    let bent = bent.normalize_or_zero();
    (bent != Vec3::ZERO && bent.is_finite()).then_some(bent)
}

/// The normal a tangent-space normal map gives: its texel `c` decoded as
/// 2c - 1 (about byte 128, [`NORMAL_MAP_MIDDLE`]) in the frame of T (dP/du
/// made normal to `shading` by Gram-Schmidt), B (N x T, turned up the
/// image: green is up, as Blender, glTF and OpenGL have it) and N
/// (`shading`). `None`: no tilt there.
fn mapped_normal(map: &Texture, at: &TexturePoint, shading: Vec3) -> Option<Vec3> {
    let c = map.sample(at.uv, at.lod);
    let decode = |c: f32| ((c - NORMAL_MAP_MIDDLE) * (255.0 / 127.0)).clamp(-1.0, 1.0);
    let (x, y) = (decode(c.x), decode(c.y));
    if x == 0.0 && y == 0.0 {
        return None;
    }
    // A normal pointing into the surface is no relief one can see.
    let z = decode(c.z).max(0.0);
    let t = (at.dpdu - shading * shading.dot(at.dpdu)).normalize_or_zero();
    if t == Vec3::ZERO {
        return None;
    }
    let b = shading.cross(t);
    // Stored v runs down the image.
    let b = if b.dot(at.dpdv) > 0.0 { -b } else { b };
    let bent = (t * x + b * y + shading * z).normalize_or_zero();
    (bent != Vec3::ZERO && bent.is_finite()).then_some(bent)
}

/// `bent` turned toward the eye (against `dir`, the ray's direction)
/// where it faces it less than `shading` does and less than
/// [`MIN_FACING`]. A normal facing away from the eye stands for a slope
/// the eye cannot see: real relief would hide it behind its own crest, a
/// map has no crest. Shaded as it is, lights on the eye's side count as
/// behind it (the point goes black but for ambient) and its mirror
/// reflection heads into the surface. Turned in the plane of itself and
/// the eye until it faces the eye at a grazing angle, the slope still
/// shows as steep. (Renderers do likewise: Cycles bends bump-mapped
/// normals so their reflection stays above the surface.)
fn facing_the_eye(bent: Vec3, shading: Vec3, dir: Vec3) -> Vec3 {
    let view = -dir.normalize();
    let least = MIN_FACING.min(shading.dot(view));
    let facing = bent.dot(view);
    if facing >= least {
        return bent;
    }
    let across = (bent - view * facing).normalize_or_zero();
    if across == Vec3::ZERO {
        return shading;
    }
    across * (1.0 - least * least).max(0.0).sqrt() + view * least
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::accel::{Accelerator, BackendKind, Intersector};
    use crate::geometry::{Object, Placement, Shape, TriangleMesh};
    use crate::texture::{TextureEncoding, TextureFilter, TextureRef};

    /// A 2 x 2 quad about the origin, facing +z, tilted by `tilt` (z =
    /// -tilt (x + y)), its texture once over it (u along +x, the image's
    /// top at +y).
    fn quad(tilt: f32) -> Object {
        let corner = |x: f32, y: f32| Vec3::new(x, y, -tilt * (x + y));
        Object {
            name: "quad".into(),
            shape: Shape::Mesh(TriangleMesh {
                positions: vec![
                    corner(-1.0, -1.0),
                    corner(1.0, -1.0),
                    corner(1.0, 1.0),
                    corner(-1.0, 1.0),
                ],
                triangles: vec![[0, 1, 2], [0, 2, 3]],
                normals: Vec::new(),
                texcoords: vec![
                    Vec2::new(0.0, 1.0),
                    Vec2::new(1.0, 1.0),
                    Vec2::new(1.0, 0.0),
                    Vec2::new(0.0, 0.0),
                ],
                cutout: None,
            }),
            material: 0,
            placement: Placement::World,
        }
    }

    fn data(width: u32, height: u32, texel: impl Fn(u32, u32) -> [u8; 4]) -> TextureRef {
        let texels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| texel(x, y))
            .collect();
        TextureRef(std::sync::Arc::new(Texture::from_rgba8(
            width,
            height,
            texels,
            Path::new("t.png"),
            TextureFilter::Trilinear,
            TextureEncoding::Linear,
        )))
    }

    /// The normal `bump` gives the flat quad where a ray from (x, y, 2)
    /// straight down meets it (a cone of no width: level 0).
    fn bent_at(bump: &BumpMap, x: f32, y: f32) -> Vec3 {
        bent_and_unbent(bump, 0.0, x, y).0
    }

    /// The normal `bump` gives the quad tilted by `tilt` where a ray from
    /// (x, y, 2) straight down meets it, and the normal without it.
    fn bent_and_unbent(bump: &BumpMap, tilt: f32, x: f32, y: f32) -> (Vec3, Vec3) {
        let object = quad(tilt);
        let ray = Ray::new(Vec3::new(x, y, 2.0), Vec3::NEG_Z);
        let objects = [object];
        let accel = Accelerator::build(BackendKind::Grid, &objects).unwrap();
        let hit = accel.intersect(&ray).expect("the ray meets the quad");
        let shape = WorldShape::new(&objects[0]);
        let surface = shape.surface(&ray, &hit, 0);
        let bent = shape.bumped_normal(bump, &ray, &hit, 0.0, surface.shading_normal);
        (bent, surface.shading_normal)
    }

    #[test]
    fn flat_relief_leaves_the_normal_exactly() {
        let grey = BumpMap::Height {
            map: data(8, 8, |_, _| [90, 90, 90, 255]),
            scale: 3.0,
        };
        let flat = BumpMap::Normal {
            map: data(4, 4, |_, _| [128, 128, 255, 255]),
        };
        // On a tilted quad, whose normal is no axis, at many points: a
        // normal worked out again, or a height blended as a colour, misses
        // the bits at some of them.
        for i in 0..400 {
            let (x, y) = (
                (i % 20) as f32 * 0.0947 - 0.93,
                (i / 20) as f32 * 0.0931 - 0.91,
            );
            for bump in [&grey, &flat] {
                let (bent, unbent) = bent_and_unbent(bump, 0.3, x, y);
                assert_eq!(bent, unbent, "{x} {y} {bump:?}");
            }
        }
    }

    #[test]
    fn a_height_ramp_tilts_the_normal_down_its_slope() {
        // Heights rising along u (+x), 1/8 a texel: over the quad's 2
        // units, 8 texels rise by 8/8 = 1 times `scale`, 0.5: a slope of
        // 1/4 up +x, whose normal leans toward -x.
        let ramp = BumpMap::Height {
            map: data(8, 8, |x, _| {
                let v = (x * 32) as u8;
                [v, v, v, 255]
            }),
            scale: 0.5,
        };
        let n = bent_at(&ramp, 0.1, 0.3);
        // 32/255 a texel, 8 texels a unit of u, 2 world units a unit of u.
        let slope = 0.5 * (32.0 / 255.0) * 8.0 / 2.0;
        let expected = Vec3::new(-slope, 0.0, 1.0).normalize();
        assert!((n - expected).length() < 1e-4, "{n} vs {expected}");
        // Heights rising up the image (+y) lean it toward -y.
        let up = BumpMap::Height {
            map: data(8, 8, |_, y| {
                let v = 255 - (y * 32) as u8;
                [v, v, v, 255]
            }),
            scale: 0.5,
        };
        let n = bent_at(&up, 0.1, 0.3);
        assert!(n.y < -0.1 && n.x.abs() < 1e-6 && n.z > 0.9, "{n}");
    }

    #[test]
    fn a_normal_map_tilts_toward_red_along_u_and_green_up_the_image() {
        let tilted = |c: [u8; 4]| {
            bent_at(
                &BumpMap::Normal {
                    map: data(2, 2, |_, _| c),
                },
                0.2,
                0.2,
            )
        };
        let n = tilted([255, 128, 255, 255]);
        assert!(
            (n - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-6,
            "{n}"
        );
        let n = tilted([128, 255, 255, 255]);
        assert!(
            (n - Vec3::new(0.0, 1.0, 1.0).normalize()).length() < 1e-6,
            "{n}"
        );
        let n = tilted([128, 1, 255, 255]);
        assert!(
            (n - Vec3::new(0.0, -1.0, 1.0).normalize()).length() < 1e-6,
            "{n}"
        );
    }

    #[test]
    fn a_normal_facing_away_from_the_eye_is_turned_to_graze_it() {
        // Looking down at 45 degrees along +x, a normal leaning far toward
        // +x faces away from the eye.
        let dir = Vec3::new(1.0, 0.0, -1.0);
        let view = -dir.normalize();
        let away = Vec3::new(1.0, 0.0, 0.2).normalize();
        assert!(away.dot(view) < 0.0);
        let turned = facing_the_eye(away, Vec3::Z, dir);
        assert!((turned.dot(view) - MIN_FACING).abs() < 1e-6, "{turned}");
        assert!((turned.length() - 1.0).abs() < 1e-6);
        assert!(turned.y.abs() < 1e-6 && turned.x > 0.0);
        // One that faces the eye is kept as it is.
        let toward = Vec3::new(-0.5, 0.0, 1.0).normalize();
        assert_eq!(facing_the_eye(toward, Vec3::Z, dir), toward);
    }
}

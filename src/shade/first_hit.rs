//! What a primary ray meets first, without lighting it: the geometry and
//! surface colour the arbitrary output variables (`crate::aov`) write
//! beside a frame's colours.

use glam::Vec3;

use super::{albedo, Shader};
use crate::ray::{LaneMask, RayPacket, PACKET_WIDTH};

/// The first surface a ray met, as a compositor wants it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FirstHit {
    /// From the ray's origin (the eye) to the hit, along the ray: a range,
    /// not a distance along the camera's axis.
    pub distance: f32,
    /// Unit world-space shading normal (interpolated on smooth meshes,
    /// bent by a bump or normal map), turned toward the ray, as lighting
    /// uses it.
    pub normal: Vec3,
    /// The material's diffuse colour there: its checker, times its diffuse
    /// texture filtered over the primary ray's footprint, as shading uses.
    pub albedo: Vec3,
    /// Index of the object in `Scene::objects`.
    pub object: u32,
}

impl Shader<'_> {
    /// What each ray of `mask` met first (None: nothing, or not in the
    /// mask). One packet call, as shading makes for primary rays; nothing
    /// is lit and no other ray is cast.
    pub fn first_hits(&self, rays: &RayPacket, mask: LaneMask) -> [Option<FirstHit>; PACKET_WIDTH] {
        let mut hits = [None; PACKET_WIDTH];
        self.intersector.intersect8(rays, mask, &mut hits);
        std::array::from_fn(|lane| {
            let hit = hits[lane].filter(|_| mask & (1 << lane) != 0)?;
            let ray = &rays[lane];
            let object = &self.objects[hit.object as usize];
            let (surface, colour) = object.with_shape_at(ray.time, |shape| {
                let mut surface = shape.surface(ray, &hit, object.material_index);
                let mut colour = albedo(object.material, surface.point, surface.plane_uv);
                // A primary ray's cone starts as a point at the eye.
                let width = self.primary_spread * hit.t * ray.dir.length();
                if let Some(map) = &object.material.diffuse_map {
                    if let Some(texel) = shape.texel(map, ray, &hit, width) {
                        colour *= texel;
                    }
                }
                if let Some(bump) = &object.material.bump_map {
                    let normal = surface.shading_normal;
                    surface.shading_normal = shape.bumped_normal(bump, ray, &hit, width, normal);
                }
                (surface, colour)
            });
            Some(FirstHit {
                distance: hit.t * ray.dir.length(),
                normal: surface.shading_normal,
                albedo: colour,
                object: hit.object,
            })
        })
    }
}

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
    /// is lit and no other ray is cast. With motion blur the rays look at
    /// the scene as it stands at the frame's instant.
    pub fn first_hits(&self, rays: &RayPacket, mask: LaneMask) -> [Option<FirstHit>; PACKET_WIDTH] {
        let instant: RayPacket;
        let rays = match self.motion_blur {
            true => {
                instant = rays.map(|ray| ray.at_time(self.instant_time));
                &instant
            }
            false => rays,
        };
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

#[cfg(test)]
mod tests {
    use std::path::Path;

    use glam::Vec3;

    use crate::accel::{Accelerator, BackendKind};
    use crate::ray::{Ray, PACKET_WIDTH};
    use crate::scene::{parse_scene_str, SceneOverrides};
    use crate::shade::Shader;

    /// A ball moving from x = -1 to 1 while a shutter `[-0.5, 0.5]` is
    /// open around frame 1's instant, when it stands straight ahead.
    #[test]
    fn with_motion_blur_the_aovs_see_the_scene_at_the_frames_instant() {
        let text = "[camera]\nprojection = \"perspective\"\nposition = [0, 0, 0]\nfov = 90\n\
                    [[object]]\nname = \"ball\"\ntype = \"sphere\"\ncenter = [0, 0, -10]\nradius = 0.3\n\
                    [animation]\nframes = 3\nshutter = [-0.5, 0.5]\n\
                    [[animation.object]]\nobject = \"ball\"\nframe = 0\ntranslate = [-2, 0, 0]\n\
                    [[animation.object]]\nobject = \"ball\"\nframe = 2\ntranslate = [2, 0, 0]\n";
        let mut scene =
            parse_scene_str(text, Path::new("aov.toml"), &SceneOverrides::default()).unwrap();
        let animation = scene.animation.clone().unwrap();
        animation.pose(&mut scene.objects, &mut scene.lights, 1);
        let accel = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        let ahead = [Ray::new(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0)); PACKET_WIDTH];
        let hit = shader.first_hits(&ahead, 1)[0].expect("the ball straight ahead");
        assert!((hit.distance - 9.7).abs() < 1e-3, "{hit:?}");
        // Where the shutter opens, the ball is a unit to the left.
        let left = [Ray::new(Vec3::ZERO, Vec3::new(-0.1, 0.0, -1.0)); PACKET_WIDTH];
        assert_eq!(shader.first_hits(&left, 1)[0], None);
    }
}

//! Whitted shading, one 8-ray packet at a time: ambient, Lambert and Phong
//! per point light with shadow rays, and mirror reflection to a set depth.
//!
//! Every Embree call here is a packet call (primary, shadow and reflection
//! rays of the same 8 samples travel together). A sample's colour depends
//! only on the packet it was traced in, so callers that need bit-exact
//! repeats (the reuse algorithms) always trace the same groups of samples.

use glam::Vec3;

use crate::accel::Intersector;
use crate::geometry::{plane_axes, transform_normal, Placement, Shape};
use crate::ray::{lanes, offset_origin, Hit, LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::scene::{Material, Scene};

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RayCounts {
    pub primary: u64,
    pub shadow: u64,
    pub reflection: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflection
    }
}

impl std::ops::AddAssign for RayCounts {
    fn add_assign(&mut self, other: RayCounts) {
        self.primary += other.primary;
        self.shadow += other.shadow;
        self.reflection += other.reflection;
    }
}

impl std::ops::Add for RayCounts {
    type Output = RayCounts;
    fn add(mut self, other: RayCounts) -> RayCounts {
        self += other;
        self
    }
}

/// Sees every ray shading traces, with where it stopped: OSTC records the
/// voxels each ray crossed (primary, reflection and shadow rays alike).
pub trait RayObserver {
    /// `kind` says which rays these are; `ends[lane]` is the `t` at which lane's ray stopped: its hit, or its
    /// `tmax` on a miss. Shadow rays always report their `tmax` (the light):
    /// an occlusion query finds *a* blocker, not the nearest, so the whole
    /// segment must count.
    fn traced(
        &mut self,
        kind: RayKind,
        rays: &RayPacket,
        mask: LaneMask,
        ends: &[f32; PACKET_WIDTH],
    );
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayKind {
    Primary,
    Shadow,
    Reflection,
}

/// Where a ray met a surface, refined for shading and for spawning rays.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// On the surface, reconstructed from the primitive (not `o + t d`,
    /// whose error grows with the distance travelled).
    pub point: Vec3,
    /// Unit geometric normal, facing the incoming ray.
    pub geometric_normal: Vec3,
    /// Unit shading normal (interpolated for smooth meshes), same side.
    pub shading_normal: Vec3,
    /// Where rays leaving the surface start: `point` moved off the surface
    /// to the side the incoming ray came from. Every ray shading spawns
    /// leaves from that side (lights behind the surface are skipped, and
    /// reflections are kept above it).
    pub spawn_point: Vec3,
    pub material: usize,
    /// In-plane coordinates for plane checkers; None elsewhere.
    pub plane_uv: Option<(f32, f32)>,
}

impl Surface {
    pub fn from_hit(scene: &Scene, ray: &Ray, hit: &Hit) -> Surface {
        let object = &scene.objects[hit.object as usize];
        let transform = match object.placement {
            Placement::World => None,
            Placement::Instance(xf) => Some(xf),
        };
        let to_world = |p: Vec3| transform.map_or(p, |xf| xf.transform_point3(p));
        let (point, normal, shading, scale, plane_uv) = match &object.shape {
            Shape::Mesh(mesh) => {
                let [a, b, c] = mesh.vertices(hit.prim).map(to_world);
                let (u, v) = (hit.u, hit.v);
                let point = a * (1.0 - u - v) + b * u + c * v;
                let normal = (b - a).cross(c - a).normalize();
                let shading = if mesh.normals.is_empty() {
                    normal
                } else {
                    let [i, j, k] = mesh.triangles[hit.prim as usize];
                    let n = mesh.normals[i as usize] * (1.0 - u - v)
                        + mesh.normals[j as usize] * u
                        + mesh.normals[k as usize] * v;
                    let n = match transform {
                        Some(xf) => transform_normal(&xf, n),
                        None => n,
                    };
                    let n = n.normalize_or_zero();
                    if n == Vec3::ZERO {
                        normal
                    } else if n.dot(normal) < 0.0 {
                        -n
                    } else {
                        n
                    }
                };
                let scale = a.abs().max(b.abs()).max(c.abs()).max_element();
                (point, normal, shading, scale, None)
            }
            Shape::Sphere(sphere) => {
                let center = to_world(sphere.center);
                let radius = match transform {
                    Some(xf) => sphere.radius * xf.matrix3.x_axis.length(),
                    None => sphere.radius,
                };
                let outward = (ray.at(hit.t) - center).normalize();
                let point = center + outward * radius;
                let scale = center.abs().max_element() + radius;
                (point, outward, outward, scale, None)
            }
            Shape::Plane(plane) => {
                let (origin, normal) = match transform {
                    Some(xf) => (
                        xf.transform_point3(plane.point),
                        transform_normal(&xf, plane.normal),
                    ),
                    None => (plane.point, plane.normal),
                };
                let rough = ray.at(hit.t);
                let point = rough - normal * normal.dot(rough - origin);
                let (u_axis, v_axis) = plane_axes(normal);
                let local = point - origin;
                let scale = origin
                    .abs()
                    .max_element()
                    .max(ray.origin.abs().max_element());
                (
                    point,
                    normal,
                    normal,
                    scale,
                    Some((local.dot(u_axis), local.dot(v_axis))),
                )
            }
        };
        let facing = if normal.dot(ray.dir) > 0.0 { -1.0 } else { 1.0 };
        let geometric_normal = normal * facing;
        Surface {
            point,
            geometric_normal,
            shading_normal: shading * facing,
            spawn_point: offset_origin(point, geometric_normal, scale),
            material: object.material,
            plane_uv,
        }
    }
}

fn albedo(material: &Material, surface: &Surface) -> Vec3 {
    let Some(checker) = &material.checker else {
        return material.diffuse;
    };
    let parity = match surface.plane_uv {
        Some((u, v)) => (u / checker.scale).floor() as i64 + (v / checker.scale).floor() as i64,
        None => {
            let p = surface.point / checker.scale;
            p.x.floor() as i64 + p.y.floor() as i64 + p.z.floor() as i64
        }
    };
    checker.colors[(parity & 1) as usize]
}

fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - n * (2.0 * d.dot(n))
}

/// Traces and shades packets for one scene through one intersector.
pub struct Shader<'a> {
    scene: &'a Scene,
    intersector: &'a dyn Intersector,
    /// Per material: R.V below which its highlight is negligible.
    highlight_cutoffs: Vec<f32>,
    /// Per material: the Phong exponent when it is a whole number, so the
    /// highlight is a few multiplications (powi) instead of a powf.
    whole_exponents: Vec<Option<i32>>,
}

fn phong(r_dot_v: f32, shininess: f32, whole: Option<i32>) -> f32 {
    match whole {
        Some(n) => r_dot_v.powi(n),
        None => r_dot_v.powf(shininess),
    }
}

impl<'a> Shader<'a> {
    pub fn new(scene: &'a Scene, intersector: &'a dyn Intersector) -> Shader<'a> {
        Shader {
            scene,
            intersector,
            highlight_cutoffs: scene
                .materials
                .iter()
                .map(Material::highlight_cutoff)
                .collect(),
            whole_exponents: scene
                .materials
                .iter()
                .map(|m| {
                    (m.shininess.fract() == 0.0 && m.shininess <= 65_536.0)
                        .then_some(m.shininess as i32)
                })
                .collect(),
        }
    }

    /// Colours of the rays in `mask`; other lanes come back black. `depth`
    /// is the number of reflections so far (0 for primary rays).
    pub fn shade(
        &self,
        rays: &RayPacket,
        mask: LaneMask,
        depth: u32,
        counts: &mut RayCounts,
        mut observer: Option<&mut dyn RayObserver>,
    ) -> [Vec3; PACKET_WIDTH] {
        let scene = self.scene;
        let mut colors = [Vec3::ZERO; PACKET_WIDTH];
        if mask == 0 {
            return colors;
        }
        let traced = u64::from(mask.count_ones());
        if depth == 0 {
            counts.primary += traced;
        } else {
            counts.reflection += traced;
        }
        let mut hits = [None; PACKET_WIDTH];
        self.intersector.intersect8(rays, mask, &mut hits);
        if let Some(observer) = observer.as_deref_mut() {
            let ends = std::array::from_fn(|lane| hits[lane].map_or(rays[lane].tmax, |h| h.t));
            let kind = if depth == 0 {
                RayKind::Primary
            } else {
                RayKind::Reflection
            };
            observer.traced(kind, rays, mask, &ends);
        }

        let mut surfaces: [Option<Surface>; PACKET_WIDTH] = [None; PACKET_WIDTH];
        let mut hit_mask: LaneMask = 0;
        for lane in lanes(mask) {
            match &hits[lane] {
                None => colors[lane] = scene.background,
                Some(hit) => {
                    let surface = Surface::from_hit(scene, &rays[lane], hit);
                    let material = &scene.materials[surface.material];
                    colors[lane] = scene.ambient * albedo(material, &surface);
                    surfaces[lane] = Some(surface);
                    hit_mask |= 1 << lane;
                }
            }
        }
        if hit_mask == 0 {
            return colors;
        }

        for light in &scene.lights {
            let mut shadow_rays = [Ray::INACTIVE; PACKET_WIDTH];
            let mut lit_mask: LaneMask = 0;
            for lane in lanes(hit_mask) {
                let surface = surfaces[lane].as_ref().expect("hit lanes have surfaces");
                let to_light = light.position - surface.point;
                // A light behind the surface cannot light it: no ray needed.
                if to_light.dot(surface.geometric_normal) <= 0.0 {
                    continue;
                }
                let origin = surface.spawn_point;
                // The segment ends at the light: dir spans it, so t < 1.
                shadow_rays[lane] = Ray::segment(origin, light.position - origin, 1.0);
                lit_mask |= 1 << lane;
            }
            if lit_mask == 0 {
                continue;
            }
            counts.shadow += u64::from(lit_mask.count_ones());
            let blocked = self.intersector.occluded8(&shadow_rays, lit_mask);
            if let Some(observer) = observer.as_deref_mut() {
                let ends = std::array::from_fn(|lane| shadow_rays[lane].tmax);
                observer.traced(RayKind::Shadow, &shadow_rays, lit_mask, &ends);
            }
            for lane in lanes(lit_mask & !blocked) {
                let surface = surfaces[lane].as_ref().expect("lit lanes have surfaces");
                let material = &scene.materials[surface.material];
                let n = surface.shading_normal;
                let l = shadow_rays[lane].dir.normalize();
                let n_dot_l = n.dot(l).max(0.0);
                let view = -rays[lane].dir.normalize();
                let r_dot_v = reflect(-l, n).dot(view);
                // Below the cutoff the highlight is under 1e-5: skip the powf.
                let specular = if r_dot_v > self.highlight_cutoffs[surface.material] {
                    material.specular
                        * phong(
                            r_dot_v,
                            material.shininess,
                            self.whole_exponents[surface.material],
                        )
                } else {
                    Vec3::ZERO
                };
                colors[lane] += light.power * (albedo(material, surface) * n_dot_l + specular);
            }
        }

        if depth < scene.max_depth {
            let mut reflected = [Ray::INACTIVE; PACKET_WIDTH];
            let mut mirror_mask: LaneMask = 0;
            for lane in lanes(hit_mask) {
                let surface = surfaces[lane].as_ref().expect("hit lanes have surfaces");
                if scene.materials[surface.material].reflectivity <= 0.0 {
                    continue;
                }
                let d = rays[lane].dir.normalize();
                let mut r = reflect(d, surface.shading_normal);
                // Interpolated normals can bend a reflection into the surface.
                if r.dot(surface.geometric_normal) <= 0.0 {
                    r = reflect(d, surface.geometric_normal);
                }
                reflected[lane] = Ray::new(surface.spawn_point, r);
                mirror_mask |= 1 << lane;
            }
            if mirror_mask != 0 {
                let mirrored = self.shade(&reflected, mirror_mask, depth + 1, counts, observer);
                for lane in lanes(mirror_mask) {
                    let surface = surfaces[lane].as_ref().expect("mirror lanes have surfaces");
                    let k = scene.materials[surface.material].reflectivity;
                    colors[lane] = colors[lane] * (1.0 - k) + mirrored[lane] * k;
                }
            }
        }
        colors
    }
}

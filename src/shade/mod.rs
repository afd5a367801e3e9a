//! Whitted shading, one 8-ray packet at a time: ambient, Lambert and Phong
//! per point light with shadow rays, and mirror reflection to a set depth.
//!
//! Every Embree call here is a packet call (primary, shadow and reflection
//! rays of the same 8 samples travel together). A sample's colour depends
//! only on the packet it was traced in, so callers that need bit-exact
//! repeats (the reuse algorithms) always trace the same groups of samples.

mod area;
mod bump;
mod cones;
mod draws;
mod first_hit;
mod glossy;
mod lanes;
mod lens;
mod lighting;
mod shutter;
mod strata;
mod surface;

use glam::Vec3;

use crate::accel::Intersector;
use crate::geometry::{Light, Placement};
use crate::ray::{lanes, Hit, LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::scene::{Material, Scene};
pub use first_hit::FirstHit;
pub use strata::PixelStrata;
pub use surface::Surface;
use surface::{albedo, ShapeMotion, WorldShape};

use cones::{reflected_spread, refracted_spread, sample_spread, RayCones};
use lanes::{lane_flags, lanes_where, AnalyticHits, HitLanes, Lanes, RayColumns, Vec3Lanes};

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RayCounts {
    pub primary: u64,
    pub shadow: u64,
    pub reflection: u64,
    pub refraction: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflection + self.refraction
    }
}

impl std::ops::AddAssign for RayCounts {
    fn add_assign(&mut self, other: RayCounts) {
        self.primary += other.primary;
        self.shadow += other.shadow;
        self.reflection += other.reflection;
        self.refraction += other.refraction;
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
    /// Toward light number `light`; `blocked` lanes found an occluder.
    Shadow {
        light: usize,
        blocked: LaneMask,
    },
    Reflection,
    /// Through a transparent surface (glass).
    Refraction,
}

/// One object as shading sees it, looked up once per hit: its shape in
/// world space and its material, with what lighting derives from it.
struct ObjectShading<'a> {
    shape: WorldShape<'a>,
    /// How the shape moves while the shutter is open, for objects that do.
    motion: Option<ShapeMotion<'a>>,
    material_index: usize,
    material: &'a Material,
    /// R.V below which the material's highlight is negligible.
    highlight_cutoff: f32,
}

/// What a hit reads off its object's maps where ray cones are followed
/// (scenes with textures), and passes on to its children.
struct MapsRead {
    /// The cone leaving the hit: its width there and its spread.
    cone_width: f32,
    cone_spread: f32,
    /// Mirrors and glass: the surface's radius of curvature, which bends
    /// refracted cones; infinite elsewhere.
    curvature_radius: f32,
    /// The specular map's texel; white (a multiplication that changes no
    /// bits) without one.
    specular_texel: Vec3,
}

impl<'a> ObjectShading<'a> {
    /// Calls `f` with the object's shape where a ray cast at shutter time
    /// `time` meets it.
    #[inline(always)]
    fn with_shape_at<R>(&self, time: f32, f: impl FnOnce(&WorldShape<'a>) -> R) -> R {
        match &self.motion {
            None => f(&self.shape),
            Some(motion) => f(&motion.at(time)),
        }
    }

    /// Reads the object's diffuse, specular and relief maps at `hit`
    /// through the ray's cone, arriving as (width at the ray's origin,
    /// spread): the diffuse texel multiplies `albedo` and the relief bends
    /// `surface`'s shading normal.
    #[inline(always)]
    fn read_maps(
        &self,
        shape: &WorldShape<'_>,
        ray: &Ray,
        hit: &Hit,
        (width_at_origin, spread): (f32, f32),
        surface: &mut Surface,
        albedo: &mut Vec3,
    ) -> MapsRead {
        let width = width_at_origin + spread * hit.t * ray.dir.length();
        let material = self.material;
        // Only mirrors and glass pass cones on: the curvature of other
        // surfaces is never needed.
        let (curvature_radius, cone_spread) =
            if material.reflectivity > 0.0 || material.glass.is_some() {
                let radius = shape.curvature_radius(hit, surface);
                (radius, reflected_spread(spread, width, radius))
            } else {
                (f32::INFINITY, spread)
            };
        if let Some(map) = &material.diffuse_map {
            if let Some(texel) = shape.texel(map, ray, hit, width) {
                *albedo *= texel;
            }
        }
        let specular_texel = material
            .specular_map
            .as_ref()
            .and_then(|map| shape.texel(map, ray, hit, width))
            .unwrap_or(Vec3::ONE);
        if let Some(bump) = &material.bump_map {
            let normal = surface.shading_normal;
            surface.shading_normal = shape.bumped_normal(bump, ray, hit, width, normal);
        }
        MapsRead {
            cone_width: width,
            cone_spread,
            curvature_radius,
            specular_texel,
        }
    }
}

/// Traces and shades packets for one scene through one intersector.
pub struct Shader<'a> {
    scene: &'a Scene,
    intersector: &'a dyn Intersector,
    /// Per object: what reconstructing and lighting its hits needs.
    objects: Vec<ObjectShading<'a>>,
    /// Per material: the Phong exponent when it is a whole number, so the
    /// highlight is a few multiplications instead of a powf.
    whole_exponents: Vec<Option<u32>>,
    /// Whether any material has a texture: only then are ray cones
    /// followed.
    textured: bool,
    /// The spread of the cone around a primary ray.
    primary_spread: f32,
    /// Whether any object is transparent: scenes without glass skip all
    /// of refraction's work.
    any_glass: bool,
    /// Whether any object reflects glossily: scenes without rough mirrors
    /// keep every reflection on the mirror direction, untouched.
    any_glossy: bool,
    /// Whether any light or surface draws samples (area lights, glossy
    /// surfaces): only then are rays' path keys worked out.
    draws: bool,
    /// Whether any object glows (mesh lights): only then is a hit's glow
    /// added.
    any_emission: bool,
    /// Whether any object, light or the camera moves while the shutter is
    /// open: only then are camera rays cast at times across it.
    motion_blur: bool,
    /// The shutter time of the frame's instant (0 without a shutter):
    /// when the AOVs see the scene.
    instant_time: f32,
}

/// `x` to the power `n` by repeated squaring, the same multiplications in
/// the same order as `f32::powi` (compiler-rt's `__powisf2`), so results
/// are bit for bit those of `powi`; inlined here, where `powi` with an
/// exponent only known at run time is an out-of-line call per highlight.
#[inline]
fn powi(mut x: f32, mut n: u32) -> f32 {
    let mut result = if n & 1 != 0 { x } else { 1.0 };
    n >>= 1;
    while n != 0 {
        x *= x;
        if n & 1 != 0 {
            result *= x;
        }
        n >>= 1;
    }
    result
}

#[inline]
fn phong(r_dot_v: f32, shininess: f32, whole: Option<u32>) -> f32 {
    match whole {
        Some(n) => powi(r_dot_v, n),
        None => r_dot_v.powf(shininess),
    }
}

impl<'a> Shader<'a> {
    /// The scene this shades.
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    pub fn new(scene: &'a Scene, intersector: &'a dyn Intersector) -> Shader<'a> {
        Shader {
            scene,
            intersector,
            objects: scene
                .objects
                .iter()
                .map(|object| {
                    let material = &scene.materials[object.material];
                    ObjectShading {
                        shape: WorldShape::new(object),
                        motion: ShapeMotion::new(object),
                        material_index: object.material,
                        material,
                        highlight_cutoff: material.highlight_cutoff(),
                    }
                })
                .collect(),
            whole_exponents: scene
                .materials
                .iter()
                .map(|m| {
                    (m.shininess.fract() == 0.0 && (0.0..=65_536.0).contains(&m.shininess))
                        .then_some(m.shininess as u32)
                })
                .collect(),
            textured: scene.materials.iter().any(Material::textured),
            primary_spread: sample_spread(scene),
            any_glass: scene
                .objects
                .iter()
                .any(|o| scene.materials[o.material].glass.is_some()),
            any_glossy: scene
                .objects
                .iter()
                .any(|o| scene.materials[o.material].roughness > 0.0),
            draws: scene.lights.iter().any(Light::draws_samples)
                || scene.materials.iter().any(|m| m.roughness > 0.0),
            any_emission: scene
                .objects
                .iter()
                .any(|o| scene.materials[o.material].emission != Vec3::ZERO),
            motion_blur: scene
                .objects
                .iter()
                .any(|o| matches!(o.placement, Placement::Moving(_)))
                || scene.lights.iter().any(|light| light.motion.is_some())
                || scene.camera_motion.is_some(),
            instant_time: scene
                .animation
                .as_ref()
                .and_then(|a| a.shutter)
                .map_or(0.0, |s| shutter::time_of_instant(&s)),
        }
    }

    /// Colours of the rays in `mask`; other lanes come back black. `depth`
    /// is the number of reflections so far (0 for primary rays).
    ///
    /// Surfaces are reconstructed lane by lane (each lane may hit a
    /// different kind of object); lighting and reflection directions then
    /// run on all eight lanes at once, by coordinate (`Vec3Lanes`), with
    /// the lane masks choosing which results are kept. Per lane that is the
    /// same arithmetic, in the same order, as shading one ray at a time.
    pub fn shade(
        &self,
        rays: &RayPacket,
        mask: LaneMask,
        depth: u32,
        counts: &mut RayCounts,
        observer: Option<&mut dyn RayObserver>,
    ) -> [Vec3; PACKET_WIDTH] {
        self.shade_generation(rays, mask, depth, None, counts, observer)
    }

    /// [`Shader::shade`] for camera rays (depth 0) that are sub-samples of
    /// square counts, `strata` saying which cell of its pixel's grid each
    /// is: their first glossy bounces are then stratified across the
    /// pixel's sub-samples (see [`glossy`]) rather than drawn at random.
    /// The rest of their shading is [`Shader::shade`]'s, bit for bit.
    pub fn shade_strata(
        &self,
        rays: &RayPacket,
        mask: LaneMask,
        strata: &PixelStrata,
        counts: &mut RayCounts,
        observer: Option<&mut dyn RayObserver>,
    ) -> [Vec3; PACKET_WIDTH] {
        self.shade_generation(rays, mask, 0, Some(strata), counts, observer)
    }

    /// A packet entering the recursion at `depth`, its lanes' cells of
    /// their pixels given where they are camera sub-samples.
    fn shade_generation(
        &self,
        rays: &RayPacket,
        mask: LaneMask,
        depth: u32,
        strata: Option<&PixelStrata>,
        counts: &mut RayCounts,
        observer: Option<&mut dyn RayObserver>,
    ) -> [Vec3; PACKET_WIDTH] {
        let cones = RayCones {
            width: [0.0; PACKET_WIDTH],
            spread: [self.primary_spread; PACKET_WIDTH],
        };
        let kind = if depth == 0 {
            RayKind::Primary
        } else {
            RayKind::Reflection
        };
        // Camera rays come as a pinhole's at the frame's instant: with
        // motion blur each is cast at its own time (drawn from the pinhole
        // ray) by the camera as it stands then, and a lens moves them onto
        // itself.
        let timed = (self.motion_blur && depth == 0)
            .then(|| shutter::timed_rays(rays, mask, strata, self.scene.camera_motion.as_ref()));
        let rays = timed.as_ref().unwrap_or(rays);
        let through_lens = match &self.scene.lens {
            Some(lens) if depth == 0 => Some(lens::lens_rays(lens, rays, mask, strata)),
            _ => None,
        };
        let rays = through_lens.as_ref().unwrap_or(rays);
        let paths = if self.draws {
            draws::ray_keys(rays, depth)
        } else {
            [0; PACKET_WIDTH]
        };
        let generation = Generation {
            depth,
            kind,
            cones: &cones,
            paths: &paths,
            strata,
        };
        self.shade_lanes(rays, mask, generation, counts, observer)
            .vectors()
    }

    /// [`Shader::shade`] with the colours by coordinate, as the recursion
    /// mixes them: reflections blend into their parents lane-parallel, and
    /// the colours change layout once per primary packet, not per bounce.
    fn shade_lanes(
        &self,
        rays: &RayPacket,
        mask: LaneMask,
        generation: Generation<'_>,
        counts: &mut RayCounts,
        mut observer: Option<&mut dyn RayObserver>,
    ) -> Vec3Lanes {
        let Generation {
            depth,
            kind,
            cones,
            paths,
            strata,
        } = generation;
        let scene = self.scene;
        if mask == 0 {
            return Vec3Lanes::default();
        }
        let traced = u64::from(mask.count_ones());
        match kind {
            RayKind::Primary => counts.primary += traced,
            RayKind::Refraction => counts.refraction += traced,
            _ => counts.reflection += traced,
        }
        let mut hits = [None; PACKET_WIDTH];
        self.intersector.intersect8(rays, mask, &mut hits);
        if let Some(observer) = observer.as_deref_mut() {
            let ends = std::array::from_fn(|lane| hits[lane].map_or(rays[lane].tmax, |h| h.t));
            observer.traced(kind, rays, mask, &ends);
        }

        let hit_mask = mask & lanes_where(|lane| hits[lane].is_some());
        if hit_mask == 0 {
            // All misses (common for reflections): no per-lane work, and
            // no hit lanes to clear.
            return Vec3Lanes::splat(scene.background)
                .select(&lane_flags(mask), &Vec3Lanes::default());
        }
        let mut lanes_hit = HitLanes {
            path: *paths,
            time: rays.map(|ray| ray.time),
            ..HitLanes::default()
        };
        // The cones leaving each hit, followed only where textures are.
        let mut next_cones = RayCones::default();
        // Where they are followed: each mirror or glass lane's radius of
        // curvature, for the refracted cones.
        let mut curvature_radii = [f32::INFINITY; PACKET_WIDTH];
        // What each lane's specular map gives; white (a multiplication
        // that changes no bits) without one.
        let mut specular_texels = [Vec3::ONE; PACKET_WIDTH];
        let columns = RayColumns::new(rays);
        lanes_hit.direction = columns.direction;
        // Hits on spheres and planes are reconstructed all lanes at once
        // after this loop; those on meshes, and every hit where cones are
        // followed, one by one here.
        let mut analytic = AnalyticHits::default();
        let mut analytic_mask: LaneMask = 0;
        for lane in lanes(hit_mask) {
            let Some(hit) = &hits[lane] else { continue };
            let object = &self.objects[hit.object as usize];
            lanes_hit.material[lane] = object.material_index as u32;
            lanes_hit.cutoff[lane] = object.highlight_cutoff;
            lanes_hit.reflectivity[lane] = object.material.reflectivity;
            if self.any_glass {
                lanes_hit.glass[lane] = object.material.glass;
            }
            let ray = &rays[lane];
            object.with_shape_at(ray.time, |shape| {
                if !self.textured && analytic.add(lane, shape, hit.t) {
                    analytic_mask |= 1 << lane;
                    return;
                }
                let mut surface = shape.surface(ray, hit, object.material_index);
                let mut albedo = albedo(object.material, surface.point, surface.plane_uv);
                if self.textured {
                    let cone = (cones.width[lane], cones.spread[lane]);
                    let read = object.read_maps(shape, ray, hit, cone, &mut surface, &mut albedo);
                    next_cones.width[lane] = read.cone_width;
                    next_cones.spread[lane] = read.cone_spread;
                    curvature_radii[lane] = read.curvature_radius;
                    specular_texels[lane] = read.specular_texel;
                }
                lanes_hit.set(lane, &surface, albedo);
            });
        }
        if analytic_mask != 0 {
            analytic.reconstruct(&columns, &lane_flags(analytic_mask), &mut lanes_hit);
            for lane in lanes(analytic_mask) {
                let Some(hit) = &hits[lane] else { continue };
                let object = &self.objects[hit.object as usize];
                let point = lanes_hit.point.get(lane);
                let uv = object.shape.plane_uv(point);
                let albedo = albedo(object.material, point, uv);
                lanes_hit.albedo.set(lane, albedo);
            }
        }
        lanes_hit.normalize_directions();
        let mut colors = first_colors(
            scene.ambient,
            &lanes_hit.albedo,
            &lane_flags(hit_mask),
            scene.background,
            &lane_flags(mask & !hit_mask),
        );

        self.add_lights(
            &lanes_hit,
            hit_mask,
            &specular_texels,
            &mut colors,
            counts,
            reborrow(&mut observer),
        );
        if depth < scene.max_depth {
            let secondary = Secondary {
                depth,
                cones,
                next_cones: &next_cones,
                curvature_radii: &curvature_radii,
                strata,
            };
            self.add_secondary(
                &lanes_hit,
                hit_mask,
                secondary,
                &mut colors,
                counts,
                observer,
            );
        }
        if self.any_emission {
            self.add_glow(&lanes_hit, hit_mask, &mut colors);
        }
        colors
    }

    /// Adds each hit lane's glow (mesh lights) to `colors`: the surface's
    /// own light, not dimmed by its mirror.
    fn add_glow(&self, lanes_hit: &HitLanes, hit_mask: LaneMask, colors: &mut Vec3Lanes) {
        for lane in lanes(hit_mask) {
            let glow = self.scene.materials[lanes_hit.material[lane] as usize].emission;
            if glow != Vec3::ZERO {
                colors.set(lane, colors.get(lane) + glow);
            }
        }
    }

    /// Adds to `colors` what the mirror and glass lanes reflect and
    /// refract, traced one generation deeper.
    #[inline(always)]
    fn add_secondary(
        &self,
        lanes_hit: &HitLanes,
        hit_mask: LaneMask,
        secondary: Secondary<'_>,
        colors: &mut Vec3Lanes,
        counts: &mut RayCounts,
        mut observer: Option<&mut dyn RayObserver>,
    ) {
        let Secondary {
            depth,
            cones,
            next_cones,
            curvature_radii,
            strata,
        } = secondary;
        let h = lanes_hit;
        // Scene numbers are finite (a `Scene` promise), so no NaN to exclude.
        let mirror_mask = hit_mask & lanes_where(|lane| h.reflectivity[lane] > 0.0);
        // Built only where there is glass: it is a packet of rays and
        // more, which scenes without glass would fill for nothing.
        let glass = self
            .any_glass
            .then(|| h.glass_lanes(hit_mask))
            .filter(|glass| glass.lanes != 0);
        let reflect_mask = mirror_mask | glass.as_ref().map_or(0, |glass| glass.reflecting);
        let mut mirrored = Vec3Lanes::default();
        if reflect_mask != 0 {
            let mut directions = h.mirror_directions();
            if self.any_glossy {
                for lane in lanes(reflect_mask) {
                    let roughness = self.scene.materials[h.material[lane] as usize].roughness;
                    if roughness > 0.0 {
                        let mirror = directions.get(lane);
                        let facing = h.geometric_normal.get(lane);
                        let stratum = strata.map(|strata| strata.lane(lane));
                        let lobe = glossy::lobe_position(h.path[lane], stratum);
                        let glossy = glossy::glossy_direction(mirror, facing, roughness, lobe);
                        directions.set(lane, glossy);
                    }
                }
            }
            // As for shadow rays: all lanes, then reset the others.
            let mut reflected: RayPacket = std::array::from_fn(|lane| {
                Ray::new(h.spawn_point.get(lane), directions.get(lane)).at_time(h.time[lane])
            });
            for lane in lanes(!reflect_mask) {
                reflected[lane] = Ray::INACTIVE;
            }
            mirrored = self.shade_lanes(
                &reflected,
                reflect_mask,
                Generation {
                    depth: depth + 1,
                    kind: RayKind::Reflection,
                    cones: next_cones,
                    paths: &child_paths(h, 1),
                    strata: None,
                },
                counts,
                reborrow(&mut observer),
            );
        }
        if mirror_mask != 0 {
            mix_reflection(colors, &mirrored, &h.reflectivity, &lane_flags(mirror_mask));
        }
        if let Some(glass) = glass {
            let mut refracted_cones = *next_cones;
            if self.textured {
                for lane in lanes(glass.refracting) {
                    refracted_cones.spread[lane] = refracted_spread(
                        cones.spread[lane],
                        next_cones.width[lane],
                        curvature_radii[lane],
                        glass.eta[lane],
                    );
                }
            }
            let refracted = self.shade_lanes(
                &glass.rays,
                glass.refracting,
                Generation {
                    depth: depth + 1,
                    kind: RayKind::Refraction,
                    cones: &refracted_cones,
                    paths: &child_paths(h, 2),
                    strata: None,
                },
                counts,
                observer,
            );
            glass.mix(colors, &mirrored, &refracted);
        }
    }
}

/// What the reflected and refracted rays of a packet's hits carry on.
struct Secondary<'a> {
    /// The packet's own depth.
    depth: u32,
    /// The cones the packet's rays arrived in.
    cones: &'a RayCones,
    /// The cones leaving each hit.
    next_cones: &'a RayCones,
    /// Each mirror or glass lane's radius of curvature.
    curvature_radii: &'a [f32; PACKET_WIDTH],
    /// The packet's cells of their pixels, where it is a packet of camera
    /// sub-samples of a square count.
    strata: Option<&'a PixelStrata>,
}

/// What a packet of rays is in the recursion: its depth (0 for primary
/// rays), its kind (primary, reflection or refraction), the ray cones it
/// carries and what its lanes' draws are keyed by.
#[derive(Clone, Copy)]
struct Generation<'c> {
    depth: u32,
    kind: RayKind,
    cones: &'c RayCones,
    /// Each lane's path key (zeros in scenes that draw no samples).
    paths: &'c [u64; PACKET_WIDTH],
    /// Each lane's cell of its pixel: camera sub-samples of a square
    /// count only, so the bounces they spawn draw without.
    strata: Option<&'c PixelStrata>,
}

/// The path keys of the rays a bounce of kind `bounce` (1 reflection, 2
/// refraction) sends on from `h`'s hits.
fn child_paths(h: &HitLanes, bounce: u64) -> [u64; PACKET_WIDTH] {
    std::array::from_fn(|lane| draws::child_key(h.path[lane], bounce))
}

/// The transparent lanes of a packet's hits, worked out lane by lane (only
/// scenes with glass get here): how much each reflects (exact Fresnel), the
/// refracted rays, and what the light coming through is filtered by.
struct GlassLanes {
    /// Lanes on a transparent surface.
    lanes: LaneMask,
    /// Of those, the ones whose Fresnel reflection is traced (all but
    /// those of index 1, which reflect nothing).
    reflecting: LaneMask,
    /// The ones a refracted ray leaves (all but total internal reflection).
    refracting: LaneMask,
    rays: RayPacket,
    transparency: Lanes,
    reflectance: Lanes,
    /// The index ratio each refracted ray crosses (the index it leaves
    /// over the one it enters).
    eta: Lanes,
    /// The glass's filter where the ray goes in, white where it comes out.
    filter: [Vec3; PACKET_WIDTH],
}

impl Default for GlassLanes {
    fn default() -> GlassLanes {
        GlassLanes {
            lanes: 0,
            reflecting: 0,
            refracting: 0,
            rays: [Ray::INACTIVE; PACKET_WIDTH],
            transparency: [0.0; PACKET_WIDTH],
            reflectance: [0.0; PACKET_WIDTH],
            eta: [1.0; PACKET_WIDTH],
            filter: [Vec3::ONE; PACKET_WIDTH],
        }
    }
}

impl GlassLanes {
    /// `colors` in the glass lanes: the surface's own colour kept by
    /// `1 - transparency`, the rest the Fresnel blend of what the reflected
    /// and the (filtered) refracted rays see.
    fn mix(&self, colors: &mut Vec3Lanes, mirrored: &Vec3Lanes, refracted: &Vec3Lanes) {
        for lane in lanes(self.lanes) {
            let (t, f) = (self.transparency[lane], self.reflectance[lane]);
            let behind =
                mirrored.get(lane) * f + self.filter[lane] * refracted.get(lane) * (1.0 - f);
            colors.set(lane, colors.get(lane) * (1.0 - t) + behind * t);
        }
    }
}

/// `observer` lent for one call, its trait object's lifetime shortened to
/// the loan (which `as_deref_mut` does not do).
#[inline]
fn reborrow<'s>(observer: &'s mut Option<&mut dyn RayObserver>) -> Option<&'s mut dyn RayObserver> {
    match observer {
        Some(observer) => Some(&mut **observer),
        None => None,
    }
}

/// Colours before any light: `ambient * albedo` in the `hit` lanes, the
/// background in the `missed` ones, black elsewhere. All lanes at once,
/// out of line for the reason given at [`HitLanes::toward`].
#[inline(never)]
fn first_colors(
    ambient: Vec3,
    albedo: &Vec3Lanes,
    hit: &[bool; PACKET_WIDTH],
    background: Vec3,
    missed: &[bool; PACKET_WIDTH],
) -> Vec3Lanes {
    let sky = Vec3Lanes::splat(background).select(missed, &Vec3Lanes::default());
    Vec3Lanes::splat(ambient).mul(albedo).select(hit, &sky)
}

/// `colors` blended in the `keep` lanes with what their mirrors see,
/// `mirrored`, by each lane's reflectivity `k`. Out of line for the reason
/// given at [`HitLanes::toward`].
#[inline(never)]
fn mix_reflection(
    colors: &mut Vec3Lanes,
    mirrored: &Vec3Lanes,
    k: &Lanes,
    keep: &[bool; PACKET_WIDTH],
) {
    let rest = k.map(|k| 1.0 - k);
    let mixed = colors.scale(&rest).add(&mirrored.scale(k));
    *colors = mixed.select(keep, colors);
}

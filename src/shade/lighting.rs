//! Direct lighting of a packet's hits: one packet of shadow rays per
//! point light, `light_samples` per area light, each sample's diffuse and
//! Phong terms added lane-parallel.

use glam::Vec3;

use super::lanes::{lane_flags, lanes_where, HitLanes, Lanes, Vec3Lanes};
use super::{area, phong, reborrow, RayCounts, RayKind, RayObserver, Shader};
use crate::geometry::Light;
use crate::ray::{lanes, LaneMask, Ray, RayPacket, PACKET_WIDTH};

impl Shader<'_> {
    /// Adds to `colors` each light's diffuse and Phong terms on the hit
    /// lanes it reaches, casting the shadow rays: one packet for a point
    /// light, `light_samples` for an area light.
    #[inline(always)]
    pub(super) fn add_lights(
        &self,
        lanes_hit: &HitLanes,
        hit_mask: LaneMask,
        specular_texels: &[Vec3; PACKET_WIDTH],
        colors: &mut Vec3Lanes,
        counts: &mut RayCounts,
        mut observer: Option<&mut dyn RayObserver>,
    ) {
        let scene = self.scene;
        for (light_index, light) in scene.lights.iter().enumerate() {
            // A light moving while the shutter is open stands, for each
            // lane, where it is at that lane's ray's time.
            let timed: Option<[Light; PACKET_WIDTH]> = light
                .motion
                .is_some()
                .then(|| std::array::from_fn(|lane| light.at_time(lanes_hit.time[lane])));
            let power = match &timed {
                None => LightPower::Same(light.power),
                Some(timed) => LightPower::ByLane(lane_vectors(timed.map(|l| l.power))),
            };
            let shade = LightSample {
                light: light_index,
                power,
                hit_mask,
                specular_texels,
            };
            if !light.draws_samples() {
                let target = match &timed {
                    None => Vec3Lanes::splat(light.position),
                    Some(timed) => lane_vectors(timed.map(|l| l.position)),
                };
                let ray = (&target, 1.0);
                self.add_light_sample(
                    lanes_hit,
                    &shade,
                    ray,
                    None,
                    colors,
                    counts,
                    reborrow(&mut observer),
                );
                continue;
            }
            let (count, reach) = if light.is_area() {
                (scene.light_samples, area::AREA_SHADOW_REACH)
            } else {
                (1, 1.0)
            };
            let share = 1.0 / count as f32;
            for index in 0..count {
                let mut target = Vec3Lanes::default();
                let mut weight: Lanes = [0.0; PACKET_WIDTH];
                let mut mask = 0;
                for lane in lanes(hit_mask) {
                    let point = lanes_hit.point.get(lane);
                    // A point light has one position: nothing to place.
                    let uv = if light.is_area() {
                        area::stratum_position(lanes_hit.path[lane], light_index, index, count)
                    } else {
                        (0.0, 0.0)
                    };
                    let light = timed.as_ref().map_or(light, |timed| &timed[lane]);
                    if let Some((at, w)) = area::sample_toward(light, point, uv) {
                        target.set(lane, at);
                        weight[lane] = w * share;
                        mask |= 1 << lane;
                    }
                }
                if mask == 0 {
                    continue;
                }
                let shade = LightSample {
                    hit_mask: mask,
                    ..shade
                };
                self.add_light_sample(
                    lanes_hit,
                    &shade,
                    (&target, reach),
                    Some(&weight),
                    colors,
                    counts,
                    reborrow(&mut observer),
                );
            }
        }
    }

    /// Adds one light sample's diffuse and Phong terms (each lane's power
    /// times its `weight`, or the power itself) on the lanes it reaches
    /// from `target`, casting one packet of shadow rays toward it, each
    /// looking for blockers up to `reach` of the way.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn add_light_sample(
        &self,
        h: &HitLanes,
        sample: &LightSample,
        (target, reach): (&Vec3Lanes, f32),
        weight: Option<&Lanes>,
        colors: &mut Vec3Lanes,
        counts: &mut RayCounts,
        observer: Option<&mut dyn RayObserver>,
    ) {
        let scene = self.scene;
        let (facing, lit_from, to_light) = h.toward(target);
        // A light behind the surface cannot light it: no ray needed.
        let lit_mask = sample.hit_mask & lanes_where(|lane| facing[lane] > 0.0);
        if lit_mask == 0 {
            return;
        }
        // Nearly every lane is lit: filling all of them and resetting
        // the few others beats picking lanes out one by one.
        let mut shadow_rays: RayPacket = std::array::from_fn(|lane| {
            Ray::segment(h.shadow_point.get(lane), to_light.get(lane), reach).at_time(h.time[lane])
        });
        for lane in lanes(!lit_mask) {
            shadow_rays[lane] = Ray::INACTIVE;
        }
        counts.shadow += u64::from(lit_mask.count_ones());
        let blocked = self.intersector.occluded8(&shadow_rays, lit_mask);
        if let Some(observer) = observer {
            let ends = std::array::from_fn(|lane| shadow_rays[lane].tmax);
            let kind = RayKind::Shadow {
                light: sample.light,
                blocked,
            };
            observer.traced(kind, &shadow_rays, lit_mask, &ends);
        }
        let shaded = lit_mask & !blocked;
        if shaded == 0 {
            return;
        }
        let (mut n_dot_l, r_dot_v) = h.cosines(&lit_from);
        // Below the cutoff the highlight is under 1e-5: skip the powf.
        let mut specular = Vec3Lanes::default();
        for lane in lanes(shaded & lanes_where(|lane| r_dot_v[lane] > h.cutoff[lane])) {
            let material = h.material[lane] as usize;
            specular.set(
                lane,
                scene.materials[material].specular
                    * sample.specular_texels[lane]
                    * phong(
                        r_dot_v[lane],
                        scene.materials[material].shininess,
                        self.whole_exponents[material],
                    ),
            );
        }
        if let Some(weight) = weight {
            for lane in 0..PACKET_WIDTH {
                n_dot_l[lane] *= weight[lane];
                specular.set(lane, specular.get(lane) * weight[lane]);
            }
        }
        let keep = lane_flags(shaded);
        match &sample.power {
            LightPower::Same(power) => {
                add_light(colors, *power, &h.albedo, &n_dot_l, &specular, &keep);
            }
            LightPower::ByLane(power) => {
                add_light_by_lane(colors, power, &h.albedo, &n_dot_l, &specular, &keep);
            }
        }
    }
}

/// One light as a packet's hits take a sample of it.
#[derive(Clone, Copy)]
struct LightSample<'a> {
    /// The light's number in the scene.
    light: usize,
    power: LightPower,
    /// The lanes the sample may light.
    hit_mask: LaneMask,
    specular_texels: &'a [Vec3; PACKET_WIDTH],
}

/// A light's colour times intensity, as each lane's ray meets it.
#[derive(Clone, Copy)]
enum LightPower {
    /// The light's all through the shutter.
    Same(Vec3),
    /// Each lane's, at its ray's time (a light whose power changes while
    /// the shutter is open).
    ByLane(Vec3Lanes),
}

/// Per-lane `vectors` as lanes.
fn lane_vectors(vectors: [Vec3; PACKET_WIDTH]) -> Vec3Lanes {
    let mut lanes = Vec3Lanes::default();
    for (lane, v) in vectors.into_iter().enumerate() {
        lanes.set(lane, v);
    }
    lanes
}

/// As [`add_light`], each lane with its own power: the same sum, channel
/// by channel, so a power every lane shares adds as it does there.
#[inline(never)]
fn add_light_by_lane(
    colors: &mut Vec3Lanes,
    power: &Vec3Lanes,
    albedo: &Vec3Lanes,
    n_dot_l: &Lanes,
    specular: &Vec3Lanes,
    keep: &[bool; PACKET_WIDTH],
) {
    for lane in (0..PACKET_WIDTH).filter(|&lane| keep[lane]) {
        let term = power.get(lane) * (albedo.get(lane) * n_dot_l[lane] + specular.get(lane));
        colors.set(lane, colors.get(lane) + term);
    }
}

/// One light's contribution to every channel, added in the `keep` lanes.
/// Out of line for the reason given at [`HitLanes::toward`].
#[inline(never)]
fn add_light(
    colors: &mut Vec3Lanes,
    power: Vec3,
    albedo: &Vec3Lanes,
    n_dot_l: &Lanes,
    specular: &Vec3Lanes,
    keep: &[bool; PACKET_WIDTH],
) {
    accumulate(
        &mut colors.x,
        power.x,
        &albedo.x,
        n_dot_l,
        &specular.x,
        keep,
    );
    accumulate(
        &mut colors.y,
        power.y,
        &albedo.y,
        n_dot_l,
        &specular.y,
        keep,
    );
    accumulate(
        &mut colors.z,
        power.z,
        &albedo.z,
        n_dot_l,
        &specular.z,
        keep,
    );
}

/// One light's contribution to one colour channel, added in the `keep`
/// lanes: `color + power * (albedo * n_dot_l + specular)`. Computed in every
/// lane and then selected, so the loop is a few vector instructions instead
/// of eight branches.
#[inline]
fn accumulate(
    color: &mut Lanes,
    power: f32,
    albedo: &Lanes,
    n_dot_l: &Lanes,
    specular: &Lanes,
    keep: &[bool; PACKET_WIDTH],
) {
    for lane in 0..PACKET_WIDTH {
        let term = power * (albedo[lane] * n_dot_l[lane] + specular[lane]);
        let sum = color[lane] + term;
        color[lane] = if keep[lane] { sum } else { color[lane] };
    }
}

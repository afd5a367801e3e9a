//! The timeline: keyframes of the camera, objects, lights and viewports,
//! and what they give at a frame.
//!
//! Promises: every value at a frame is computed from the frame number and
//! the keys alone, never accumulated from the previous frame, so frame
//! 10,000 is as exact as frame 1 and a chunk of frames equals the same
//! frames of one long run.

use glam::{Affine3A, DVec3, EulerRot, Quat, Vec3};

use crate::camera::{
    Camera, CameraMotion, Lens, Projection, ViewTransform, Viewport, ViewportPose,
};
use crate::geometry::{Light, LightMotion, LightShape, Motion, Object, Placement, MOTION_STEPS};

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ease {
    /// Constant speed.
    #[default]
    Linear,
    /// Smoothstep: starts and ends at rest.
    EaseInOut,
}

impl Ease {
    pub fn apply(self, t: f64) -> f64 {
        match self {
            Ease::Linear => t,
            Ease::EaseInOut => t * t * (3.0 - 2.0 * t),
        }
    }
}

/// A camera keyframe, fully resolved (unset values carried over).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraKey {
    pub frame: u32,
    /// Radians.
    pub yaw: f64,
    pub pitch: f64,
    pub fov: f64,
    pub position: DVec3,
    /// The lens's radius (0: a pinhole) and the distance in focus (NaN
    /// while no key or camera has given one).
    pub aperture: f64,
    pub focus_distance: f64,
    /// How the segment from this key to the next is eased.
    pub ease: Ease,
}

impl CameraKey {
    /// `base` posed as this key says.
    pub fn apply(&self, base: &Camera) -> Camera {
        Camera {
            yaw: self.yaw,
            pitch: self.pitch,
            fov: self.fov,
            position: self.position,
            ..base.clone()
        }
    }
}

/// Where `frame` falls among `keys` (in increasing frame order): the key at
/// or before it (the first key before the first), and, strictly between two
/// keys, the next key with the eased fraction of the way to it.
fn key_segment<K>(
    keys: &[K],
    time: f64,
    frame_of: impl Fn(&K) -> u32,
    ease_of: impl Fn(&K) -> Ease,
) -> Option<(&K, Option<(&K, f64)>)> {
    let first = keys.first()?;
    let next = keys.partition_point(|k| f64::from(frame_of(k)) <= time);
    if next == 0 {
        return Some((first, None));
    }
    let a = &keys[next - 1];
    let Some(b) = keys.get(next) else {
        return Some((a, None));
    };
    let (fa, fb) = (frame_of(a), frame_of(b));
    let t = ease_of(a).apply((time - f64::from(fa)) / f64::from(fb - fa));
    Some((a, Some((b, t))))
}

fn lerp3(a: Vec3, b: Vec3, t: f64) -> Vec3 {
    (a.as_dvec3() + (b.as_dvec3() - a.as_dvec3()) * t).as_vec3()
}

/// An object keyframe, resolved (unset values carried over): the motion
/// relative to where the scene file puts the object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectKey {
    pub frame: u32,
    pub translate: Vec3,
    /// Degrees about x, then y, then z, around the object's centre.
    pub rotate: Vec3,
    pub ease: Ease,
}

/// A ball's bounce: a parabola of `height` above the keyed position, one
/// hop every `period` frames, touching down at whole periods (after
/// `phase` periods' shift).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounce {
    pub height: f32,
    pub period: f64,
    pub phase: f64,
}

impl Bounce {
    /// The height at `time` (in frames, not necessarily whole).
    pub fn lift(&self, time: f64) -> f32 {
        let p = (time / self.period + self.phase).rem_euclid(1.0);
        (f64::from(self.height) * 4.0 * p * (1.0 - p)) as f32
    }
}

/// The motion of one named scene object (all its parts).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectTrack {
    pub name: String,
    /// Indices into `Scene::objects`.
    pub objects: Vec<usize>,
    /// Centre of the object at rest: rotations turn about it.
    pub pivot: Vec3,
    /// In increasing frame order; may be empty (a bounce alone).
    pub keys: Vec<ObjectKey>,
    pub bounce: Option<Bounce>,
}

impl ObjectTrack {
    /// Object-to-world transform at `frame`, from the rest placement.
    pub fn transform_at(&self, frame: u32) -> Affine3A {
        self.transform_at_time(f64::from(frame))
    }

    /// Object-to-world transform at `time`, in frames (between frames
    /// while a shutter is open).
    pub fn transform_at_time(&self, time: f64) -> Affine3A {
        let (translate, rotate) = match key_segment(&self.keys, time, |k| k.frame, |k| k.ease) {
            None => (Vec3::ZERO, Vec3::ZERO),
            Some((a, None)) => (a.translate, a.rotate),
            Some((a, Some((b, t)))) => (
                lerp3(a.translate, b.translate, t),
                lerp3(a.rotate, b.rotate, t),
            ),
        };
        let lift = self.bounce.map_or(0.0, |b| b.lift(time));
        let rotation = Quat::from_euler(
            EulerRot::ZYX,
            rotate.z.to_radians(),
            rotate.y.to_radians(),
            rotate.x.to_radians(),
        );
        Affine3A::from_translation(self.pivot + translate + Vec3::Y * lift)
            * Affine3A::from_quat(rotation)
            * Affine3A::from_translation(-self.pivot)
    }
}

/// A light keyframe, resolved (unset values carried over).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightKey {
    pub frame: u32,
    pub position: Vec3,
    pub color: Vec3,
    pub intensity: f32,
    pub ease: Ease,
}

#[derive(Clone, Debug, PartialEq)]
pub struct LightTrack {
    /// Index into `Scene::lights`.
    pub light: usize,
    /// In increasing frame order, at least one.
    pub keys: Vec<LightKey>,
}

impl LightTrack {
    /// The light at `frame`: its keyed position and power, with the
    /// `shape` its table gave (keys do not change a light's shape).
    pub fn light_at(&self, frame: u32, shape: LightShape) -> Light {
        self.light_at_time(f64::from(frame), shape)
    }

    /// As [`LightTrack::light_at`], at any time of the timeline (in frames).
    pub fn light_at_time(&self, time: f64, shape: LightShape) -> Light {
        let key = |k: &LightKey| Light {
            position: k.position,
            power: k.color * k.intensity,
            shape,
            motion: None,
        };
        match key_segment(&self.keys, time, |k| k.frame, |k| k.ease) {
            None => unreachable!("a light track has keys"),
            Some((a, None)) => key(a),
            Some((a, Some((b, t)))) => {
                let intensity =
                    f64::from(a.intensity) + (f64::from(b.intensity) - f64::from(a.intensity)) * t;
                Light {
                    position: lerp3(a.position, b.position, t),
                    power: lerp3(a.color, b.color, t) * intensity as f32,
                    shape,
                    motion: None,
                }
            }
        }
    }

    /// The light over `frame`'s `shutter`: as it stands at the opening,
    /// with its motion while the shutter is open if it changes then.
    pub fn light_over(&self, frame: u32, shutter: &Shutter, shape: LightShape) -> Light {
        let steps: [Light; MOTION_STEPS] = std::array::from_fn(|step| {
            let time = step as f64 / (MOTION_STEPS - 1) as f64;
            self.light_at_time(shutter.instant(frame, time), shape)
        });
        let still = steps.iter().all(|light| *light == steps[0]);
        Light {
            motion: (!still).then(|| LightMotion {
                positions: steps.map(|light| light.position),
                powers: steps.map(|light| light.power),
            }),
            ..steps[0]
        }
    }
}

/// When the camera's shutter is open around each frame's instant, in
/// frames: a ray's shutter time 0 is `open`, 1 is `close` (motion blur).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shutter {
    pub open: f64,
    pub close: f64,
}

impl Shutter {
    /// The timeline's time at shutter time `time` of `frame`.
    pub fn instant(&self, frame: u32, time: f64) -> f64 {
        f64::from(frame) + self.open + (self.close - self.open) * time
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    pub frames: u32,
    pub fps: f64,
    /// Motion blur: objects move while it is open. `None`: every frame
    /// is an instant.
    pub shutter: Option<Shutter>,
    /// In increasing frame order.
    pub camera_keys: Vec<CameraKey>,
    pub objects: Vec<ObjectTrack>,
    pub lights: Vec<LightTrack>,
}

impl Animation {
    /// A timeline of camera keys alone.
    pub fn camera_only(frames: u32, fps: f64, camera_keys: Vec<CameraKey>) -> Animation {
        Animation {
            frames,
            fps,
            shutter: None,
            camera_keys,
            objects: Vec::new(),
            lights: Vec::new(),
        }
    }

    /// The camera at `frame`: before the first key and after the last, the
    /// nearest key; between two keys, interpolated (with the first key's ease).
    pub fn camera_at(&self, base: &Camera, frame: u32) -> Camera {
        self.camera_at_time(base, f64::from(frame))
    }

    /// As [`Animation::camera_at`], at any time of the timeline (in frames).
    pub fn camera_at_time(&self, base: &Camera, time: f64) -> Camera {
        match key_segment(&self.camera_keys, time, |k| k.frame, |k| k.ease) {
            None => base.clone(),
            Some((a, None)) => a.apply(base),
            Some((a, Some((b, t)))) => {
                let lerp = |x: f64, y: f64| x + (y - x) * t;
                Camera {
                    yaw: lerp(a.yaw, b.yaw),
                    pitch: lerp(a.pitch, b.pitch),
                    fov: lerp(a.fov, b.fov),
                    position: a.position + (b.position - a.position) * t,
                    ..base.clone()
                }
            }
        }
    }

    /// How the camera moves while `frame`'s shutter is open: None without
    /// a shutter or when it stands still then.
    pub fn camera_motion(&self, base: &Camera, frame: u32) -> Option<CameraMotion> {
        let shutter = self.shutter.as_ref()?;
        if base.projection == Projection::EqualAngle {
            if let Some(steady) = self.steady_camera(frame, shutter) {
                return steady;
            }
        }
        let poses = std::array::from_fn(|step| {
            let time = step as f64 / (MOTION_STEPS - 1) as f64;
            self.camera_at_time(base, shutter.instant(frame, time))
        });
        CameraMotion::posed(self.camera_at(base, frame), poses)
    }

    /// When `frame`'s whole shutter lies in one constant-speed segment of
    /// the camera keys at one field of view: the camera's steady motion
    /// there (None inside: it stands still), the same for every frame of
    /// the segment bit for bit.
    fn steady_camera(&self, frame: u32, shutter: &Shutter) -> Option<Option<CameraMotion>> {
        let (open, close) = (shutter.instant(frame, 0.0), shutter.instant(frame, 1.0));
        let keys = &self.camera_keys;
        let next = keys.partition_point(|k| f64::from(k.frame) <= open);
        let (a, b) = (keys.get(next.checked_sub(1)?)?, keys.get(next)?);
        let fits = f64::from(b.frame) >= close && a.ease == Ease::Linear && a.fov == b.fov;
        if !fits {
            return None;
        }
        let frames = f64::from(b.frame - a.frame);
        let (yaw, pitch) = ((b.yaw - a.yaw) / frames, (b.pitch - a.pitch) / frames);
        let position = (b.position - a.position) / frames;
        let still = yaw == 0.0 && pitch == 0.0 && position == DVec3::ZERO;
        Some((!still).then_some(CameraMotion::Steady {
            yaw,
            pitch,
            position,
            open: shutter.open,
            close: shutter.close,
        }))
    }

    /// The lens at `frame` (None: a pinhole), from the camera keys as
    /// [`Animation::camera_at`] finds them; `base` without keys. A lens
    /// two keys share is theirs bit for bit between them.
    pub fn lens_at(&self, base: Option<Lens>, frame: u32) -> Option<Lens> {
        let lens = |aperture: f64, focus_distance: f64| {
            (aperture > 0.0).then_some(Lens {
                aperture,
                focus_distance,
            })
        };
        match key_segment(&self.camera_keys, f64::from(frame), |k| k.frame, |k| k.ease) {
            None => base,
            Some((a, None)) => lens(a.aperture, a.focus_distance),
            Some((a, Some((b, t)))) => {
                // A key before the lens first opens has no focus yet: the
                // other key's holds.
                let focus = match (a.focus_distance, b.focus_distance) {
                    (x, y) if x.is_nan() => y,
                    (x, y) if y.is_nan() => x,
                    (x, y) => x + (y - x) * t,
                };
                lens(a.aperture + (b.aperture - a.aperture) * t, focus)
            }
        }
    }

    /// Whether anything but the camera moves.
    pub fn moves_scene(&self) -> bool {
        !self.objects.is_empty() || !self.lights.is_empty()
    }

    /// Puts a scene's animated `objects` and `lights` where they are at
    /// `frame`: with a shutter, each as it moves while the shutter is
    /// open.
    /// Returns the objects whose placement changed.
    pub fn pose(&self, objects: &mut [Object], lights: &mut [Light], frame: u32) -> Vec<usize> {
        let mut moved = Vec::new();
        for track in &self.objects {
            let placement = match &self.shutter {
                None => Placement::Instance(track.transform_at(frame)),
                Some(shutter) => Placement::Moving(Motion {
                    poses: std::array::from_fn(|step| {
                        let time = step as f64 / (MOTION_STEPS - 1) as f64;
                        track.transform_at_time(shutter.instant(frame, time))
                    }),
                }),
            };
            for &object in &track.objects {
                if objects[object].placement != placement {
                    objects[object].placement = placement;
                    moved.push(object);
                }
            }
        }
        for track in &self.lights {
            let shape = lights[track.light].shape;
            lights[track.light] = match &self.shutter {
                None => track.light_at(frame, shape),
                Some(shutter) => track.light_over(frame, shutter, shape),
            };
        }
        moved
    }
}

/// A viewport transform keyframe, fully resolved (unset values carried
/// over from the previous key of the same viewport).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewportKey {
    pub frame: u32,
    pub transform: ViewTransform,
    /// How the segment from this key to the next is eased.
    pub ease: Ease,
}

/// A viewport and its keyframes (in increasing frame order).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewportTrack {
    pub viewport: Viewport,
    pub keys: Vec<ViewportKey>,
}

impl ViewportTrack {
    /// The transform at `frame`, from the frame number alone: the nearest
    /// key outside the keyed range, interpolated between keys.
    pub fn transform_at(&self, frame: u32) -> ViewTransform {
        let keys = &self.keys;
        let Some(first) = keys.first() else {
            return self.viewport.transform;
        };
        let next = keys.partition_point(|k| k.frame <= frame);
        if next == 0 {
            return first.transform;
        }
        let a = &keys[next - 1];
        let Some(b) = keys.get(next) else {
            return a.transform;
        };
        let t = a
            .ease
            .apply(f64::from(frame - a.frame) / f64::from(b.frame - a.frame));
        a.transform.lerp(&b.transform, t)
    }

    /// The viewport at `frame` when the scene camera is `base`.
    pub fn pose_at(&self, base: &Camera, frame: u32) -> ViewportPose {
        self.viewport.pose(base, self.transform_at(frame))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Projection;

    fn base() -> Camera {
        Camera {
            projection: Projection::EqualAngle,
            position: DVec3::ZERO,
            yaw: 0.0,
            pitch: 0.0,
            fov: 1.0,
            width: 8,
            height: 8,
        }
    }

    fn key(frame: u32, yaw_deg: f64, ease: Ease) -> CameraKey {
        CameraKey {
            frame,
            yaw: yaw_deg.to_radians(),
            pitch: 0.0,
            fov: 1.0,
            position: DVec3::ZERO,
            aperture: 0.0,
            focus_distance: f64::NAN,
            ease,
        }
    }

    #[test]
    fn interpolates_from_the_frame_number() {
        let animation = Animation::camera_only(
            100,
            25.0,
            vec![
                key(10, 0.0, Ease::Linear),
                key(110, 360.0, Ease::EaseInOut),
                key(210, 0.0, Ease::Linear),
            ],
        );
        let yaw = |f| animation.camera_at(&base(), f).yaw.to_degrees();
        assert_eq!(yaw(0), 0.0);
        assert!((yaw(60) - 180.0).abs() < 1e-9);
        assert!((yaw(11) - 3.6).abs() < 1e-9);
        // Eased segment: slow at both ends, halfway in the middle.
        assert!((yaw(160) - 180.0).abs() < 1e-9);
        assert!(360.0 - yaw(111) < 3.6 * 0.1);
        assert_eq!(yaw(10_000), 0.0);
    }
}

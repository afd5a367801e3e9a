//! The `[animation]` table as an [`Animation`]: the timeline's length and
//! rate, the camera's keys, and the tracks of the objects and lights that
//! move (keyframes and bounces).
//!
//! Promises: a timeline of 1 to [`MAX_FRAMES`] frames at a rate above 0;
//! each track's keyframes in increasing frame order, a value a key leaves
//! unset carried over from the key before (or the scene); every pose of
//! the camera a key gives valid, every position within the scene's extent;
//! every track moves something that exists and can move.

use glam::{DVec3, Vec3};
use toml::Spanned;

use super::defs::{
    AnimationDef, CameraKeyDef, LightDef, LightKeyDef, ObjectKeyDef, ViewportKeyDef, DEFAULT_FPS,
};
use super::lights::check_intensity;
use super::values::{colour, world3};
use super::Ctx;
use crate::camera::{Camera, Lens};
use crate::geometry::{Object, Shape, WORLD_LIMIT};
use crate::scene::{Material, SceneError};
use crate::timeline::{
    Animation, Bounce, CameraKey, Ease, LightKey, LightTrack, ObjectKey, ObjectTrack, Shutter,
};

/// The longest animation accepted, in frames.
pub const MAX_FRAMES: u32 = 1_000_000;

/// The `[animation]` table: the timeline, the camera's keys (from the
/// scene's `camera`), and the tracks of the `objects` and `lights` (their
/// tables, already checked) that move.
///
/// `lens` is the camera's, the keys' starting point: its aperture 0 for a
/// pinhole, its focus distance NaN when the camera gives none.
pub(super) fn convert_animation(
    ctx: &Ctx,
    def: &AnimationDef,
    camera: &Camera,
    lens: Lens,
    objects: &[Object],
    materials: &[Material],
    lights: &[Spanned<LightDef>],
) -> Result<Animation, SceneError> {
    let mut animation = convert_timeline(ctx, def, camera, lens)?;
    animation.shutter = def
        .shutter
        .as_ref()
        .map(|shutter| convert_shutter(ctx, shutter))
        .transpose()?;
    animation.objects = convert_object_tracks(ctx, def, objects, materials)?;
    animation.lights = convert_light_tracks(ctx, def, lights)?;
    Ok(animation)
}

/// The shutter's opening and closing around each frame: in order, at most
/// a frame apart and within a frame of the frame's instant.
fn convert_shutter(ctx: &Ctx, shutter: &Spanned<[f64; 2]>) -> Result<Shutter, SceneError> {
    let [open, close] = *shutter.get_ref();
    let problem = if !(open.is_finite() && close.is_finite()) {
        Some("must be finite".to_string())
    } else if open >= close {
        Some(format!(
            "opens before it closes: [open, close] in frames, as [-0.25, 0.25]; got [{open}, {close}]"
        ))
    } else if close - open > 1.0 {
        Some(format!(
            "stays open at most a frame (close - open <= 1), got {}",
            close - open
        ))
    } else if open < -1.0 || close > 1.0 {
        Some(format!(
            "opens and closes within a frame of the frame's instant (-1 to 1), got [{open}, {close}]"
        ))
    } else {
        None
    };
    match problem {
        Some(problem) => Err(ctx.error(shutter.span(), "animation.shutter", problem)),
        None => Ok(Shutter { open, close }),
    }
}

/// The timeline of `def`: its length and rate, and the camera's keys,
/// which start from the scene's camera, `base`, and its lens.
fn convert_timeline(
    ctx: &Ctx,
    def: &AnimationDef,
    base: &Camera,
    lens: Lens,
) -> Result<Animation, SceneError> {
    let frames = *def.frames.get_ref();
    let fps = def.fps.as_ref().map_or(DEFAULT_FPS, |fps| *fps.get_ref());
    if frames == 0 {
        return Err(ctx.error(def.frames.span(), "animation.frames", "must be at least 1"));
    }
    // A run walks the timeline once up front (the camera's path, the
    // moving objects' swept bounds): bounded, as a run's length is.
    if frames > MAX_FRAMES {
        return Err(ctx.error(
            def.frames.span(),
            "animation.frames",
            format!("at most {MAX_FRAMES} (11 hours at 25 fps), got {frames}"),
        ));
    }
    if !(fps.is_finite() && fps > 0.0) {
        let span = def.fps.as_ref().map_or(0..0, Spanned::span);
        return Err(ctx.error(span, "animation.fps", format!("must be above 0, got {fps}")));
    }
    let mut keys: Vec<CameraKey> = Vec::with_capacity(def.camera.len());
    for (i, key) in def.camera.iter().enumerate() {
        let k = key.get_ref();
        let field = |f: &str| format!("animation.camera[{i}].{f}");
        check_key_order(ctx, key, field("frame"), "", keys.last().map(|p| p.frame))?;
        // Unset values carry over from the previous key (or the camera).
        let previous = keys.last().copied().unwrap_or(CameraKey {
            frame: 0,
            yaw: base.yaw,
            pitch: base.pitch,
            fov: base.fov,
            position: base.position,
            aperture: lens.aperture,
            focus_distance: lens.focus_distance,
            ease: Ease::Linear,
        });
        let mut resolved = CameraKey {
            frame: k.frame,
            yaw: k.yaw.map_or(previous.yaw, f64::to_radians),
            pitch: k.pitch.map_or(previous.pitch, f64::to_radians),
            fov: k.fov.map_or(previous.fov, f64::to_radians),
            position: k.position.map_or(previous.position, DVec3::from_array),
            aperture: k.aperture.unwrap_or(previous.aperture),
            focus_distance: k.focus_distance.unwrap_or(previous.focus_distance),
            ease: k.ease,
        };
        check_key_lens(ctx, key, &resolved, &field)?;
        for (name, value) in [
            ("yaw", resolved.yaw),
            ("pitch", resolved.pitch),
            ("fov", resolved.fov),
        ] {
            if !value.is_finite() {
                return Err(ctx.error(key.span(), field(name), "must be finite"));
            }
        }
        if !resolved.position.is_finite() {
            return Err(ctx.error(key.span(), field("position"), "must be finite"));
        }
        let posed = resolved.apply(base);
        posed.validate().map_err(|err| {
            use crate::camera::CameraError;
            let name = match &err {
                CameraError::ElevationOutOfRange { .. } => "pitch",
                CameraError::NotFinite { field, .. } | CameraError::TooFar { field, .. } => {
                    field.trim_start_matches("camera.")
                }
                _ => "fov",
            };
            ctx.error(key.span(), field(name), err.to_string())
        })?;
        resolved.frame = k.frame;
        keys.push(resolved);
    }
    Ok(Animation::camera_only(frames, fps, keys))
}

/// A key's lens: an aperture of 0 or more, and a distance in focus above
/// 0 once the lens is open.
fn check_key_lens(
    ctx: &Ctx,
    key: &Spanned<CameraKeyDef>,
    resolved: &CameraKey,
    field: &dyn Fn(&str) -> String,
) -> Result<(), SceneError> {
    let (aperture, focus) = (resolved.aperture, resolved.focus_distance);
    if !(aperture.is_finite() && aperture >= 0.0) {
        return Err(ctx.error(
            key.span(),
            field("aperture"),
            format!("the lens's radius: finite and at least 0, got {aperture}"),
        ));
    }
    // NaN: no distance given yet; anything else must be one.
    let usable = focus.is_nan() || (focus.is_finite() && focus > 0.0);
    if !usable {
        return Err(ctx.error(
            key.span(),
            field("focus_distance"),
            format!("finite and above 0, got {focus}"),
        ));
    }
    if aperture > 0.0 && focus.is_nan() {
        return Err(ctx.error(
            key.span(),
            field("focus_distance"),
            format!(
                "a lens (aperture {aperture}) needs a distance to focus at: give focus_distance \
                 here, on an earlier key, or on the camera (or a look_at to focus there)"
            ),
        ));
    }
    Ok(())
}

/// Keys with a `frame`, for [`check_key_order`].
pub(super) trait Keyed {
    fn frame(&self) -> u32;
}

impl Keyed for CameraKeyDef {
    fn frame(&self) -> u32 {
        self.frame
    }
}

impl Keyed for ObjectKeyDef {
    fn frame(&self) -> u32 {
        self.frame
    }
}

impl Keyed for LightKeyDef {
    fn frame(&self) -> u32 {
        self.frame
    }
}

impl Keyed for ViewportKeyDef {
    fn frame(&self) -> u32 {
        self.frame
    }
}

/// Keyframes of one track must come in increasing frame order.
pub(super) fn check_key_order<K: Keyed>(
    ctx: &Ctx,
    key: &Spanned<K>,
    field: String,
    of: &str,
    previous: Option<u32>,
) -> Result<(), SceneError> {
    let frame = key.get_ref().frame();
    match previous {
        Some(previous) if frame <= previous => Err(ctx.error(
            key.span(),
            field,
            format!(
                "keyframes {of}must be in increasing frame order: frame {frame} follows frame {previous}"
            ),
        )),
        _ => Ok(()),
    }
}

/// The objects a track's name moves: the object of that name and, for a
/// multi-part mesh, its parts.
fn objects_named(objects: &[Object], name: &str) -> Vec<usize> {
    let part_prefix = format!("{name} part ");
    (0..objects.len())
        .filter(|&i| objects[i].name == name || objects[i].name.starts_with(&part_prefix))
        .collect()
}

/// The tracks of the objects that `def`'s object keys and bounces move,
/// one per name, in the order the names first appear.
fn convert_object_tracks(
    ctx: &Ctx,
    def: &AnimationDef,
    objects: &[Object],
    materials: &[Material],
) -> Result<Vec<ObjectTrack>, SceneError> {
    let mut tracks: Vec<ObjectTrack> = Vec::new();
    let track_for = |tracks: &mut Vec<ObjectTrack>,
                     name: &str,
                     span: std::ops::Range<usize>,
                     field: String| {
        if let Some(index) = tracks.iter().position(|t| t.name == name) {
            return Ok(index);
        }
        let members = objects_named(objects, name);
        if members.is_empty() {
            let known: Vec<&str> = objects.iter().map(|o| o.name.as_str()).collect();
            return Err(ctx.error(
                span,
                field,
                format!("no object named '{name}' (objects: {})", known.join(", ")),
            ));
        }
        if let Some(&plane) = members
            .iter()
            .find(|&&i| matches!(objects[i].shape, Shape::Plane(_)))
        {
            return Err(ctx.error(
                span,
                field,
                format!(
                    "'{}' is an infinite plane, which cannot move (give it a size to make it finite)",
                    objects[plane].name
                ),
            ));
        }
        // Its triangle lights are made once, where the model stands.
        if let Some(&glowing) = members
            .iter()
            .find(|&&i| materials[objects[i].material].emission != Vec3::ZERO)
        {
            return Err(ctx.error(
                span,
                field,
                format!(
                    "'{}' glows as mesh lights, which cannot move yet (light it with a \
                     [[light]] the animation moves, or leave mesh_lights off)",
                    objects[glowing].name
                ),
            ));
        }
        let rest = members
            .iter()
            .map(|&i| objects[i].world_bounds())
            .fold(crate::geometry::Aabb::EMPTY, |a, b| a.union(b));
        tracks.push(ObjectTrack {
            name: name.to_string(),
            objects: members,
            pivot: if rest.is_empty() {
                Vec3::ZERO
            } else {
                rest.center()
            },
            keys: Vec::new(),
            bounce: None,
        });
        Ok(tracks.len() - 1)
    };
    for (i, key) in def.object.iter().enumerate() {
        let k = key.get_ref();
        let field = |f: &str| format!("animation.object[{i}].{f}");
        let index = track_for(&mut tracks, &k.object, key.span(), field("object"))?;
        let track = &mut tracks[index];
        let previous = track.keys.last().copied();
        let of = format!("of '{}' ", k.object);
        check_key_order(ctx, key, field("frame"), &of, previous.map(|p| p.frame))?;
        let carried = previous.unwrap_or(ObjectKey {
            frame: 0,
            translate: Vec3::ZERO,
            rotate: Vec3::ZERO,
            ease: Ease::Linear,
        });
        let value = |v: Option<[f32; 3]>, old: Vec3, name: &str| match v {
            None => Ok(old),
            Some(v) => world3(v).map_err(|m| ctx.error(key.span(), field(name), m)),
        };
        track.keys.push(ObjectKey {
            frame: k.frame,
            translate: value(k.translate, carried.translate, "translate")?,
            rotate: value(k.rotate, carried.rotate, "rotate")?,
            ease: k.ease,
        });
    }
    for (i, bounce) in def.bounce.iter().enumerate() {
        let b = bounce.get_ref();
        let field = |f: &str| format!("animation.bounce[{i}].{f}");
        let index = track_for(&mut tracks, &b.object, bounce.span(), field("object"))?;
        if !(b.height.is_finite() && b.height >= 0.0 && b.height <= WORLD_LIMIT) {
            return Err(ctx.error(
                bounce.span(),
                field("height"),
                format!(
                    "must be a finite number from 0 to {WORLD_LIMIT:e}, got {}",
                    b.height
                ),
            ));
        }
        if !(b.period.is_finite() && b.period > 0.0) {
            return Err(ctx.error(
                bounce.span(),
                field("period"),
                format!("must be above 0 frames, got {}", b.period),
            ));
        }
        if !b.phase.is_finite() {
            return Err(ctx.error(bounce.span(), field("phase"), "must be finite"));
        }
        if tracks[index].bounce.is_some() {
            return Err(ctx.error(
                bounce.span(),
                field("object"),
                format!("'{}' already bounces", b.object),
            ));
        }
        tracks[index].bounce = Some(Bounce {
            height: b.height,
            period: b.period,
            phase: b.phase,
        });
    }
    Ok(tracks)
}

/// The keys of `def` for the scene's `lights` (their tables, already
/// checked).
fn convert_light_tracks(
    ctx: &Ctx,
    def: &AnimationDef,
    lights: &[Spanned<LightDef>],
) -> Result<Vec<LightTrack>, SceneError> {
    let mut tracks: Vec<LightTrack> = Vec::new();
    for (i, key) in def.light.iter().enumerate() {
        let k = key.get_ref();
        let field = |f: &str| format!("animation.light[{i}].{f}");
        let Some(base) = lights.get(k.light).map(Spanned::get_ref) else {
            return Err(ctx.error(
                key.span(),
                field("light"),
                format!(
                    "no light {} (the scene has {} [[light]] table(s), numbered from 0)",
                    k.light,
                    lights.len()
                ),
            ));
        };
        let index = match tracks.iter().position(|t| t.light == k.light) {
            Some(index) => index,
            None => {
                tracks.push(LightTrack {
                    light: k.light,
                    keys: Vec::new(),
                });
                tracks.len() - 1
            }
        };
        let track = &mut tracks[index];
        let previous = track.keys.last().copied();
        let of = format!("of light {} ", k.light);
        check_key_order(ctx, key, field("frame"), &of, previous.map(|p| p.frame))?;
        // The scene's light is the starting point: a key that leaves its
        // colour or its intensity unset keeps the earlier one.
        let carried = previous.unwrap_or(LightKey {
            frame: 0,
            position: Vec3::from(base.position),
            color: Vec3::from(base.color),
            intensity: base.intensity,
            ease: Ease::Linear,
        });
        let position = match k.position {
            None => carried.position,
            Some(p) => world3(p).map_err(|m| ctx.error(key.span(), field("position"), m))?,
        };
        let color = match k.color {
            None => carried.color,
            Some(c) => colour(c).map_err(|m| ctx.error(key.span(), field("color"), m))?,
        };
        let intensity = k.intensity.unwrap_or(carried.intensity);
        check_intensity(intensity).map_err(|m| ctx.error(key.span(), field("intensity"), m))?;
        track.keys.push(LightKey {
            frame: k.frame,
            position,
            color,
            intensity,
            ease: k.ease,
        });
    }
    Ok(tracks)
}

#[cfg(test)]
mod tests {
    use crate::scene::file::testing::{parse, CAMERA};

    #[test]
    fn light_keys_carry_the_unset_colour_and_intensity_over() {
        // Keys that restate the light, each part on its own, leave it as
        // it was.
        let scene = parse(&format!(
            "{CAMERA}[[light]]\nposition = [0, 5, 0]\ncolor = [1, 0.5, 0.25]\nintensity = 0.5\n\
             [animation]\nframes = 5\n\
             [[animation.light]]\nlight = 0\nframe = 0\n\
             [[animation.light]]\nlight = 0\nframe = 2\nintensity = 0.5\n\
             [[animation.light]]\nlight = 0\nframe = 4\ncolor = [1, 0.5, 0.25]\n"
        ))
        .unwrap();
        let track = &scene.animation.as_ref().unwrap().lights[0];
        for frame in 0..5 {
            assert_eq!(
                track.light_at(frame, scene.lights[0].shape),
                scene.lights[0],
                "frame {frame}"
            );
        }
    }
}

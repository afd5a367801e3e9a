//! The `[[viewport]]` tables (RSVP viewports onto the camera's sample
//! buffer) and their `[[animation.viewport]]` keys, as [`ViewportTrack`]s.
//!
//! Promises: every viewport has a name of its own that can go into file
//! names, a size of at least 1x1, and a view (its own and at every key)
//! that [`Viewport::validate`] accepts for the camera; the keys of each
//! viewport in increasing frame order, a transform value a key leaves unset
//! carried over from the key before (or the viewport).

use super::animation::check_key_order;
use super::defs::SceneFile;
use super::{names_or_none, Ctx};
use crate::camera::{Camera, ViewTransform, Viewport};
use crate::scene::SceneError;
use crate::timeline::{ViewportKey, ViewportTrack};

/// A viewport transform's error, at `span`, its field under `prefix`.
fn transform_error(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    prefix: &str,
    err: crate::camera::TransformError,
) -> SceneError {
    ctx.error(span, format!("{prefix}.{}", err.field), err.message)
}

/// The `[[viewport]]` tables onto `camera`'s samples, each with the keys
/// of its `[[animation.viewport]]` tables.
pub(super) fn convert_viewports(
    ctx: &Ctx,
    file: &SceneFile,
    camera: &Camera,
) -> Result<Vec<ViewportTrack>, SceneError> {
    let mut tracks: Vec<ViewportTrack> = Vec::with_capacity(file.viewport.len());
    for (i, def) in file.viewport.iter().enumerate() {
        let v = def.get_ref();
        let field = format!("viewport[{i}]");
        let name = v.name.clone().unwrap_or_else(|| format!("view{i}"));
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(ctx.error(
                def.span(),
                format!("{field}.name"),
                format!("'{name}': use letters, digits, - and _ (it goes into file names)"),
            ));
        }
        if tracks.iter().any(|t| t.viewport.name == name) {
            return Err(ctx.error(
                def.span(),
                format!("{field}.name"),
                format!("'{name}' names two viewports"),
            ));
        }
        let size = |value: i64, which: &str| {
            u32::try_from(value).ok().filter(|&s| s > 0).ok_or_else(|| {
                ctx.error(
                    def.span(),
                    format!("{field}.{which}"),
                    format!("must be at least 1, got {value}"),
                )
            })
        };
        let t = v;
        let viewport = Viewport {
            name,
            width: size(v.width, "width")?,
            height: size(v.height, "height")?,
            projection: v.projection,
            fov: v.fov.map_or(camera.fov, f64::to_radians),
            yaw: v.yaw.to_radians(),
            pitch: v.pitch.to_radians(),
            transform: ViewTransform {
                zoom: t.zoom.unwrap_or(1.0),
                rotate: t.rotate.unwrap_or(0.0).to_radians(),
                shear: t.shear.unwrap_or([0.0; 2]),
                translate: t.translate.unwrap_or([0.0; 2]),
            },
        };
        viewport
            .validate(camera)
            .map_err(|err| transform_error(ctx, def.span(), &field, err))?;
        tracks.push(ViewportTrack {
            viewport,
            keys: Vec::new(),
        });
    }
    let keys = file.animation.as_ref().map_or(&[][..], |a| &a.viewport[..]);
    for (i, key) in keys.iter().enumerate() {
        let k = key.get_ref();
        let field = format!("animation.viewport[{i}]");
        let index = match &k.viewport {
            None => 0,
            Some(toml::Value::Integer(n)) => usize::try_from(*n).unwrap_or(usize::MAX),
            Some(toml::Value::String(name)) => tracks
                .iter()
                .position(|t| t.viewport.name == *name)
                .unwrap_or(usize::MAX),
            Some(other) => {
                return Err(ctx.error(
                    key.span(),
                    format!("{field}.viewport"),
                    format!("expected a viewport name or index, got {other}"),
                ))
            }
        };
        let Some(track) = tracks.get_mut(index) else {
            return Err(ctx.error(
                key.span(),
                format!("{field}.viewport"),
                format!(
                    "no such viewport{} (defined: {})",
                    k.viewport
                        .as_ref()
                        .map_or(String::new(), |v| format!(" {v}")),
                    names_or_none(tracks.iter().map(|t| t.viewport.name.as_str()))
                ),
            ));
        };
        let previous = track.keys.last();
        let of = format!("of viewport '{}' ", track.viewport.name);
        check_key_order(
            ctx,
            key,
            format!("{field}.frame"),
            &of,
            previous.map(|p| p.frame),
        )?;
        let carried = previous.map_or(track.viewport.transform, |p| p.transform);
        let transform = ViewTransform {
            zoom: k.zoom.unwrap_or(carried.zoom),
            rotate: k.rotate.map_or(carried.rotate, f64::to_radians),
            shear: k.shear.unwrap_or(carried.shear),
            translate: k.translate.unwrap_or(carried.translate),
        };
        track
            .viewport
            .validate_transform(camera, &transform)
            .map_err(|err| {
                transform_error(
                    ctx,
                    key.span(),
                    &format!("{field} (viewport '{}')", track.viewport.name),
                    err,
                )
            })?;
        track.keys.push(ViewportKey {
            frame: k.frame,
            transform,
            ease: k.ease,
        });
    }
    Ok(tracks)
}

#[cfg(test)]
mod tests {
    use crate::scene::file::testing::{parse, CAMERA};

    #[test]
    fn viewport_keys_name_their_viewport_in_errors() {
        let views = "[[viewport]]\nname = \"left\"\nwidth = 32\nheight = 24\n\
                     [[viewport]]\nname = \"right\"\nwidth = 32\nheight = 24\n\
                     [animation]\nframes = 4\n";
        let key = |viewport: &str, frame: u32| {
            format!("[[animation.viewport]]\nviewport = {viewport}\nframe = {frame}\nzoom = 2\n")
        };
        let cases = [
            (
                format!("{CAMERA}{views}{}{}", key("\"right\"", 2), key("1", 1)),
                20,
                "animation.viewport[1].frame",
                "keyframes of viewport 'right' must be in increasing frame order: \
                 frame 1 follows frame 2",
            ),
            (
                format!("{CAMERA}{views}{}", key("\"up\"", 1)),
                15,
                "animation.viewport[0].viewport",
                "no such viewport \"up\" (defined: left, right)",
            ),
            (
                format!("{CAMERA}[animation]\nframes = 4\n{}", key("0", 1)),
                7,
                "animation.viewport[0].viewport",
                "no such viewport 0 (defined: none)",
            ),
        ];
        for (text, line, field, message) in cases {
            let err = parse(&text).unwrap_err();
            assert_eq!(
                (err.line, err.field.as_deref(), err.message.as_str()),
                (Some(line), Some(field), message),
                "{err}"
            );
        }
    }
}

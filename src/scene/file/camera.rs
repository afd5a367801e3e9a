//! The `[camera]` table, and the image size of `[render]`, as a validated
//! [`Camera`], with the command line's overrides applied.
//!
//! Promises: the camera returned passed [`Camera::validate`]; a value the
//! command line gave is blamed on its flag, a value of the file on the
//! line of `[camera]` (the image size on `[render]`'s, when the file has
//! one).

use glam::DVec3;
use toml::Spanned;

use super::defs::{CameraDef, RenderDef};
use super::{Ctx, SceneOverrides};
use crate::camera::{yaw_pitch_toward, Camera};
use crate::scene::SceneError;

/// The camera of `def`, its image sized by `render` (the [render] table at
/// `render_span`, when the file has one) or the command line.
pub(super) fn convert_camera(
    ctx: &Ctx,
    def: &Spanned<CameraDef>,
    render: &RenderDef,
    render_span: Option<std::ops::Range<usize>>,
    overrides: &SceneOverrides,
) -> Result<Camera, SceneError> {
    let c = def.get_ref();
    let position = DVec3::from_array(c.position);
    let (yaw, pitch) = match (c.look_at, c.yaw, c.pitch) {
        (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
            return Err(ctx.error(
                def.span(),
                "camera.look_at",
                "give either look_at or yaw/pitch, not both",
            ))
        }
        (Some(target), None, None) => {
            let target = DVec3::from_array(target);
            if !target.is_finite() {
                return Err(ctx.error(
                    def.span(),
                    "camera.look_at",
                    format!("must be finite, got {target}"),
                ));
            }
            if (target - position).length() == 0.0 {
                return Err(ctx.error(
                    def.span(),
                    "camera.look_at",
                    "must differ from camera.position",
                ));
            }
            yaw_pitch_toward(position, target)
        }
        (None, yaw, pitch) => (
            yaw.unwrap_or(0.0).to_radians(),
            pitch.unwrap_or(0.0).to_radians(),
        ),
    };
    let camera = Camera {
        projection: overrides.projection.unwrap_or(c.projection),
        position,
        yaw,
        pitch,
        fov: overrides.fov.unwrap_or(c.fov).to_radians(),
        width: overrides.width.unwrap_or(render.width),
        height: overrides.height.unwrap_or(render.height),
    };
    camera.validate().map_err(|err| {
        use crate::camera::CameraError;
        // A value from the command line is named by its flag: the file's
        // line did not cause it.
        let (field, flag) = match err {
            CameraError::EmptyImage { .. } | CameraError::ImageTooLarge { .. } => (
                "render.width/height",
                (overrides.width.is_some() || overrides.height.is_some())
                    .then(|| "--width/--height".to_string()),
            ),
            CameraError::FieldOfView { .. } => (
                "camera.fov",
                overrides.fov.is_some().then(|| "--fov".to_string()),
            ),
            // The field of view over the width.
            CameraError::TooFine { .. } => (
                "camera.fov",
                (overrides.fov.is_some() || overrides.width.is_some())
                    .then(|| "--fov/--width".to_string()),
            ),
            // The pitch, field of view, projection and height together.
            CameraError::ElevationOutOfRange { .. } => {
                let given: Vec<&str> = [
                    (overrides.projection.is_some(), "--camera"),
                    (overrides.fov.is_some(), "--fov"),
                    (overrides.height.is_some(), "--height"),
                ]
                .into_iter()
                .filter_map(|(given, flag)| given.then_some(flag))
                .collect();
                (
                    "camera.pitch",
                    (!given.is_empty()).then(|| format!("camera.pitch with {}", given.join(", "))),
                )
            }
            CameraError::NotFinite { field, .. } | CameraError::TooFar { field, .. } => {
                (field, None)
            }
        };
        // The image size is the [render] table's, if there is one.
        let span = match (&err, &render_span) {
            (CameraError::EmptyImage { .. } | CameraError::ImageTooLarge { .. }, Some(span)) => {
                span.clone()
            }
            _ => def.span(),
        };
        match flag {
            Some(flag) => SceneError::new(ctx.file_of(def.span()), err.to_string()).field(flag),
            None => ctx.error(span, field, err.to_string()),
        }
    })?;
    Ok(camera)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::camera::Projection;
    use crate::scene::file::testing::{parse, CAMERA};
    use crate::scene::{parse_scene_str, SceneOverrides};

    #[test]
    fn a_pixel_finer_than_the_lattices_count_is_refused() {
        // 1e-14 degrees wrapped the lattices' column counts (a black image).
        let err = parse("[camera]\nposition = [0, 1, 5]\nfov = 1e-14\n").unwrap_err();
        assert_eq!(
            (err.line, err.field.as_deref()),
            (Some(3), Some("camera.fov")),
            "{err}"
        );
        assert!(
            err.message.contains("finer than the sample lattices count"),
            "{err}"
        );
        let overrides = SceneOverrides {
            fov: Some(1e-5),
            ..SceneOverrides::default()
        };
        let err = parse_scene_str(CAMERA, Path::new("t.toml"), &overrides).unwrap_err();
        assert_eq!(err.field.as_deref(), Some("--fov/--width"), "{err}");
        // DESIGN's extreme: 0.01 degrees over 640 pixels.
        parse("[camera]\nposition = [0, 1, 5]\nfov = 0.01\n").unwrap();
    }

    #[test]
    fn bad_command_line_overrides_name_their_flag() {
        let text = CAMERA;
        let overrides = SceneOverrides {
            fov: Some(500.0),
            ..SceneOverrides::default()
        };
        let err = parse_scene_str(text, Path::new("t.toml"), &overrides).unwrap_err();
        assert_eq!(
            (err.field.as_deref(), err.line),
            (Some("--fov"), None),
            "{err}"
        );
        assert!(err.message.contains("field of view 500 degrees"), "{err}");
        let overrides = SceneOverrides {
            width: Some(0),
            ..SceneOverrides::default()
        };
        let err = parse_scene_str(text, Path::new("t.toml"), &overrides).unwrap_err();
        assert_eq!(err.field.as_deref(), Some("--width/--height"), "{err}");
        let overrides = SceneOverrides {
            projection: Some(Projection::EqualAngle),
            fov: Some(360.0),
            ..SceneOverrides::default()
        };
        let err = parse_scene_str(text, Path::new("t.toml"), &overrides).unwrap_err();
        assert_eq!(
            err.field.as_deref(),
            Some("camera.pitch with --camera, --fov"),
            "{err}"
        );
        // The file's own bad value keeps its line.
        let err = parse("[camera]\nposition = [0, 1, 5]\nfov = 500\n").unwrap_err();
        assert_eq!(
            (err.field.as_deref(), err.line),
            (Some("camera.fov"), Some(3)),
            "{err}"
        );
    }
}

//! The `[camera]` table, and the image size of `[render]`, as a validated
//! [`Camera`], with the command line's overrides applied.
//!
//! Promises: the camera returned passed [`Camera::validate`]; an error is
//! blamed on the command line's flags, named with their values, when they
//! alone gave the values at fault, else on the file's field at fault, at
//! the line it was written on (a value left out: the line of its table,
//! `[render]` for the image size, or `[camera]`).

use glam::DVec3;
use toml::Spanned;

use super::defs::{CameraDef, RenderDef};
use super::{Ctx, SceneOverrides};
use crate::camera::{yaw_pitch_toward, Camera, CameraError, Lens, MAX_IMAGE_SIDE};
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
    camera
        .validate()
        .map_err(|err| camera_error(ctx, def, render_span, overrides, err))?;
    Ok(camera)
}

/// The lens of `def`: none without an aperture (or at 0), else focused at
/// `focus_distance`, or where `look_at` is when that is left out.
pub(super) fn convert_lens(
    ctx: &Ctx,
    def: &Spanned<CameraDef>,
) -> Result<Option<Lens>, SceneError> {
    let c = def.get_ref();
    let error = |field: &str, message: String| ctx.error(def.span(), field, message);
    let aperture = c.aperture.unwrap_or(0.0);
    if !(aperture.is_finite() && aperture >= 0.0) {
        return Err(error(
            "camera.aperture",
            format!("the lens's radius: finite and at least 0, got {aperture}"),
        ));
    }
    if let Some(focus) = c.focus_distance {
        if !(focus.is_finite() && focus > 0.0) {
            return Err(error(
                "camera.focus_distance",
                format!("finite and above 0, got {focus}"),
            ));
        }
    }
    if aperture == 0.0 {
        return Ok(None);
    }
    let Some(focus_distance) = focus_default(def) else {
        return Err(error(
            "camera.focus_distance",
            format!(
                "a lens (aperture {aperture}) needs a distance to focus at: give \
                 focus_distance, or look_at to focus there"
            ),
        ));
    };
    Ok(Some(Lens {
        aperture,
        focus_distance,
    }))
}

/// The lens the camera keys start from: the camera's `lens`, or a closed
/// one (aperture 0) focused where an opened one would be (NaN: nowhere
/// given).
pub(super) fn keys_start_lens(def: &Spanned<CameraDef>, lens: Option<Lens>) -> Lens {
    lens.unwrap_or(Lens {
        aperture: 0.0,
        focus_distance: focus_default(def).unwrap_or(f64::NAN),
    })
}

/// Where the camera of `def` focuses when its lens is open: its
/// `focus_distance`, else the distance to `look_at`.
fn focus_default(def: &Spanned<CameraDef>) -> Option<f64> {
    let c = def.get_ref();
    let to_target = c
        .look_at
        .map(|target| (DVec3::from_array(target) - DVec3::from_array(c.position)).length());
    c.focus_distance.or(to_target)
}

/// `err` of the camera of `def`, blamed on what gave the values at fault:
/// the command line's flags, named with their values (`--width 0`), when
/// they alone did; else the file, at the line of the field (with the flags
/// that played a part: `camera.pitch with --fov 170`).
fn camera_error(
    ctx: &Ctx,
    def: &Spanned<CameraDef>,
    render_span: Option<std::ops::Range<usize>>,
    overrides: &SceneOverrides,
    err: CameraError,
) -> SceneError {
    let flag_of = |name: &str| -> Option<String> {
        let value = match name {
            "--width" => overrides.width.map(|v| v.to_string()),
            "--height" => overrides.height.map(|v| v.to_string()),
            "--camera" => overrides.projection.map(|v| v.to_string()),
            "--fov" => overrides.fov.map(crate::camera::readable_number),
            // A value only the file gives.
            _ => None,
        };
        value.map(|value| format!("{name} {value}"))
    };
    // The values at fault: (the file's field, the flag that replaces it).
    let culprits: Vec<(&str, &str)> = match &err {
        CameraError::EmptyImage { width, height }
        | CameraError::ImageTooLarge { width, height, .. } => {
            let bad = |side: u32| match err {
                CameraError::EmptyImage { .. } => side == 0,
                _ => side > MAX_IMAGE_SIDE,
            };
            let sides = [
                (bad(*width), ("render.width", "--width")),
                (bad(*height), ("render.height", "--height")),
            ];
            let mut at_fault: Vec<_> = sides.iter().filter(|s| s.0).map(|s| s.1).collect();
            // Sides each within the limit, too many pixels together.
            if at_fault.is_empty() {
                at_fault = sides.iter().map(|s| s.1).collect();
            }
            at_fault
        }
        CameraError::FieldOfView { .. } => vec![("camera.fov", "--fov")],
        // The field of view; the width only takes part (below).
        CameraError::TooFine { .. } => vec![("camera.fov", "--fov")],
        // The pitch with the projection, field of view and height.
        CameraError::ElevationOutOfRange { .. } => vec![
            ("camera.pitch", ""),
            ("camera.projection", "--camera"),
            ("camera.fov", "--fov"),
            ("render.height", "--height"),
        ],
        CameraError::NotFinite { field, .. } | CameraError::TooFar { field, .. } => {
            vec![(*field, "")]
        }
    };
    let mut flags: Vec<String> = culprits.iter().filter_map(|(_, f)| flag_of(f)).collect();
    // A wider image makes a field of view too fine sooner, but no width
    // makes a field of view of 1e-14 degrees right: a width flag is named
    // beside the field of view, never blamed in its place.
    if matches!(err, CameraError::TooFine { .. }) {
        flags.extend(flag_of("--width"));
    }
    let from_file: Vec<&str> = culprits
        .iter()
        .filter(|(_, f)| flag_of(f).is_none())
        .map(|(field, _)| *field)
        .collect();
    let message = err.to_string();
    if from_file.is_empty() {
        return SceneError::of_flags(flags.join(" "), message);
    }
    // The file's part, at the line of its first value at fault (found
    // from the table it sits in: the image size's is [render], when the
    // file has one).
    let at = from_file[0];
    let table = match render_span {
        Some(span) if at.starts_with("render.") => span,
        _ => def.span(),
    };
    let mut named = if from_file.len() > 1 && at.starts_with("render.") {
        "render.width/height".to_string()
    } else {
        at.to_string()
    };
    if !flags.is_empty() {
        named = format!("{named} with {}", flags.join(", "));
    }
    ctx.error_at(table, at, named, message)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::camera::Projection;
    use crate::scene::file::testing::{parse, CAMERA};
    use crate::scene::{parse_scene_str, SceneError, SceneOverrides};

    fn with(text: &str, overrides: SceneOverrides) -> SceneError {
        parse_scene_str(text, Path::new("t.toml"), &overrides).unwrap_err()
    }

    #[test]
    fn a_pixel_finer_than_the_lattices_count_is_refused() {
        // 1e-14 degrees would wrap the lattices' column counts (a black
        // image).
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
        assert_eq!(
            with(CAMERA, overrides).field.as_deref(),
            Some("--fov 0.00001")
        );
        // The file's field of view is at fault whatever the width: the
        // flag that took part is named beside it, not in its place.
        let overrides = SceneOverrides {
            width: Some(32),
            ..SceneOverrides::default()
        };
        let err = with("[camera]\nposition = [0, 1, 5]\nfov = 1e-14\n", overrides);
        assert_eq!(
            (err.line, err.field.as_deref()),
            (Some(3), Some("camera.fov with --width 32")),
            "{err}"
        );
        // DESIGN's extreme: 0.01 degrees over 640 pixels.
        parse("[camera]\nposition = [0, 1, 5]\nfov = 0.01\n").unwrap();
    }

    #[test]
    fn bad_command_line_overrides_name_their_flags_and_values_not_the_file() {
        let err = with(
            CAMERA,
            SceneOverrides {
                fov: Some(500.0),
                ..SceneOverrides::default()
            },
        );
        assert_eq!(
            err.to_string(),
            "--fov 500: field of view 500 degrees: must be a number above 0 and below 180 \
             for perspective"
        );
        assert_eq!(err.line, None);
        let err = with(
            CAMERA,
            SceneOverrides {
                width: Some(100_000),
                height: Some(100_000),
                ..SceneOverrides::default()
            },
        );
        assert_eq!(
            err.to_string(),
            "--width 100000 --height 100000: image size 100000x100000 is too large \
             (at most 32768 pixels per side and 268435456 pixels in all)"
        );
        // Only the flag at fault: the height of 10 is fine.
        let overrides = SceneOverrides {
            width: Some(0),
            height: Some(10),
            ..SceneOverrides::default()
        };
        assert_eq!(with(CAMERA, overrides).field.as_deref(), Some("--width 0"));
        // A width of 0 in the file is the file's, whatever the flags say.
        let sized = format!("[render]\nwidth = 0\n{CAMERA}");
        let overrides = SceneOverrides {
            height: Some(10),
            ..SceneOverrides::default()
        };
        let err = with(&sized, overrides);
        assert_eq!(
            (err.line, err.field.as_deref()),
            (Some(2), Some("render.width")),
            "{err}"
        );
        // The file's pitch with the flags' projection and field of view.
        let overrides = SceneOverrides {
            projection: Some(Projection::EqualAngle),
            fov: Some(360.0),
            ..SceneOverrides::default()
        };
        let err = with(text_with_pitch(), overrides);
        assert_eq!(
            (err.line, err.field.as_deref()),
            (
                Some(4),
                Some("camera.pitch with --camera equal-angle, --fov 360")
            ),
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

    fn text_with_pitch() -> &'static str {
        "[camera]\nposition = [0, 1, 5]\nfov = 60\npitch = 10\n"
    }
}

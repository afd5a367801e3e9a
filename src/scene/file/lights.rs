//! The `[[light]]` tables as point [`Light`]s.
//!
//! Promises: every light lies within the scene's extent, its colour is
//! finite and not negative, its intensity finite and not negative (as
//! [`check_intensity`] checks for the animation's light keys too).

use toml::Spanned;

use super::defs::LightDef;
use super::values::{colour, world3};
use super::Ctx;
use crate::geometry::Light;
use crate::scene::SceneError;

/// The scene's lights, in the order of their tables.
pub(super) fn convert_lights(
    ctx: &Ctx,
    defs: &[Spanned<LightDef>],
) -> Result<Vec<Light>, SceneError> {
    defs.iter()
        .enumerate()
        .map(|(i, def)| {
            let field = |f: &str| format!("light[{i}].{f}");
            let l = def.get_ref();
            let position =
                world3(l.position).map_err(|m| ctx.error(def.span(), field("position"), m))?;
            let color = colour(l.color).map_err(|m| ctx.error(def.span(), field("color"), m))?;
            check_intensity(l.intensity)
                .map_err(|m| ctx.error(def.span(), field("intensity"), m))?;
            Ok(Light {
                position,
                power: color * l.intensity,
            })
        })
        .collect()
}

/// A light's intensity: finite and not negative.
pub(super) fn check_intensity(intensity: f32) -> Result<(), String> {
    if intensity.is_finite() && intensity >= 0.0 {
        Ok(())
    } else {
        Err(format!("must be a finite number >= 0, got {intensity}"))
    }
}

#[cfg(test)]
mod tests {
    use crate::scene::file::testing::{parse, CAMERA};

    #[test]
    fn a_negative_intensity_is_refused_in_the_table_and_in_its_keys() {
        let light = "[[light]]\nposition = [0, 5, 0]\n";
        for (text, line, field) in [
            (format!("{CAMERA}{light}intensity = -1\n"), 6, "light[0].intensity"),
            (
                format!("{CAMERA}{light}[animation]\nframes = 2\n[[animation.light]]\nlight = 0\nframe = 1\nintensity = -1\n"),
                11,
                "animation.light[0].intensity",
            ),
        ] {
            let err = parse(&text).unwrap_err();
            assert_eq!(
                (err.line, err.field.as_deref(), err.message.as_str()),
                (Some(line), Some(field), "must be a finite number >= 0, got -1"),
                "{err}"
            );
        }
    }
}

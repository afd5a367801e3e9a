//! The `[[light]]` tables as [`Light`]s: points, and spheres, rectangles
//! and discs (area lights).
//!
//! Promises: every light lies within the scene's extent, its colour is
//! finite and not negative, its intensity finite and not negative (as
//! [`check_intensity`] checks for the animation's light keys too); each
//! shape takes exactly the fields that describe it (a field another shape
//! uses is refused, naming the shapes it is for), with sizes finite and
//! above 0 and directions finite and not zero; `falloff` is a point
//! light's alone (area lights fall off physically).

use glam::Vec3;
use toml::Spanned;

use super::defs::{FalloffName, LightDef, LightShapeName};
use super::values::{colour, finite3, world3};
use super::Ctx;
use crate::geometry::{plane_axes, Falloff, Light, LightShape};
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
            let fail = |f: &str, m: String| ctx.error(def.span(), field(f), m);
            let l = def.get_ref();
            let position = world3(l.position).map_err(|m| fail("position", m))?;
            let color = colour(l.color).map_err(|m| fail("color", m))?;
            check_intensity(l.intensity).map_err(|m| fail("intensity", m))?;
            check_fields(l).map_err(|(f, m)| fail(f, m))?;
            let shape = shape(l).map_err(|(f, m)| fail(f, m))?;
            Ok(Light {
                position,
                power: color * l.intensity,
                shape,
                motion: None,
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

/// The shape-specific fields `def` gives, each with the shapes it is for.
fn given_fields(def: &LightDef) -> [(&'static str, bool, &'static [LightShapeName]); 5] {
    use LightShapeName::*;
    [
        ("falloff", def.falloff.is_some(), &[Point]),
        ("radius", def.radius.is_some(), &[Sphere, Disc]),
        ("size", def.size.is_some(), &[Rectangle]),
        ("normal", def.normal.is_some(), &[Rectangle, Disc]),
        ("width_axis", def.width_axis.is_some(), &[Rectangle]),
    ]
}

fn shape_name(shape: LightShapeName) -> &'static str {
    match shape {
        LightShapeName::Point => "point",
        LightShapeName::Sphere => "sphere",
        LightShapeName::Rectangle => "rectangle",
        LightShapeName::Disc => "disc",
    }
}

/// Refuses a field the light's shape does not use.
fn check_fields(def: &LightDef) -> Result<(), (&'static str, String)> {
    for (name, given, shapes) in given_fields(def) {
        if given && !shapes.contains(&def.shape) {
            let for_shapes: Vec<_> = shapes.iter().map(|&s| shape_name(s)).collect();
            let why = if name == "falloff" {
                " (area lights always fall off as the inverse square of the distance)"
            } else {
                ""
            };
            return Err((
                name,
                format!(
                    "is for {} lights only, and this light's shape is \"{}\"{why}",
                    for_shapes.join(" and "),
                    shape_name(def.shape)
                ),
            ));
        }
    }
    Ok(())
}

/// The light's shape from its checked fields.
fn shape(def: &LightDef) -> Result<LightShape, (&'static str, String)> {
    let missing = |f: &'static str| (f, format!("a {} light needs it", shape_name(def.shape)));
    let radius = || -> Result<f32, (&'static str, String)> {
        let r = def.radius.ok_or_else(|| missing("radius"))?;
        positive(r).map_err(|m| ("radius", m))
    };
    let normal = || -> Result<Vec3, (&'static str, String)> {
        let n = def.normal.ok_or_else(|| missing("normal"))?;
        direction(n).map_err(|m| ("normal", m))
    };
    Ok(match def.shape {
        LightShapeName::Point => LightShape::Point {
            falloff: match def.falloff {
                None | Some(FalloffName::None) => Falloff::None,
                Some(FalloffName::InverseSquare) => Falloff::InverseSquare,
            },
        },
        LightShapeName::Sphere => LightShape::Sphere { radius: radius()? },
        LightShapeName::Disc => LightShape::Disc {
            radius: radius()?,
            normal: normal()?,
        },
        LightShapeName::Rectangle => {
            let [width, height] = def.size.ok_or_else(|| missing("size"))?;
            let width = positive(width).map_err(|m| ("size", m))?;
            let height = positive(height).map_err(|m| ("size", m))?;
            let normal = normal()?;
            let along = match def.width_axis {
                Some(axis) => {
                    let axis = direction(axis).map_err(|m| ("width_axis", m))?;
                    let along = axis - normal * axis.dot(normal);
                    if along.length() < 1e-3 {
                        return Err((
                            "width_axis",
                            format!(
                                "{:?} runs along the normal {:?}: it must lie across it",
                                axis.to_array(),
                                normal.to_array()
                            ),
                        ));
                    }
                    along.normalize()
                }
                None => default_width_axis(normal),
            };
            LightShape::Rectangle {
                half_width: along * (0.5 * width),
                half_height: normal.cross(along) * (0.5 * height),
                normal,
            }
        }
    })
}

/// Where a rectangle's width runs unless `width_axis` says: along the
/// first axis a finite plane with this normal has (`[[object]]`'s
/// `size`), so a light and a plane of the same `size` and `normal`
/// coincide.
fn default_width_axis(normal: Vec3) -> Vec3 {
    plane_axes(normal).0
}

/// A size: finite and above 0.
fn positive(value: f32) -> Result<f32, String> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(format!("must be a finite number above 0, got {value}"))
    }
}

/// A direction: finite and not zero, made unit length.
fn direction(values: [f32; 3]) -> Result<Vec3, String> {
    let v = finite3(values)?;
    let length = v.length();
    if length > 0.0 && length.is_finite() {
        Ok(v / length)
    } else {
        Err(format!("must be a direction (not zero), got {values:?}"))
    }
}
#[cfg(test)]
mod tests {
    use glam::Vec3;

    use crate::geometry::{Falloff, LightShape};
    use crate::scene::file::testing::{parse, CAMERA};

    #[test]
    fn each_shape_reads_its_own_fields() {
        let text = format!(
            "{CAMERA}[[light]]\nposition = [0, 5, 0]\nfalloff = \"inverse-square\"\n\
             [[light]]\nshape = \"sphere\"\nposition = [0, 5, 0]\nradius = 0.5\n\
             [[light]]\nshape = \"disc\"\nposition = [0, 5, 0]\nradius = 2\nnormal = [0, -3, 0]\n\
             [[light]]\nshape = \"rectangle\"\nposition = [0, 5, 0]\nsize = [2, 4]\nnormal = [0, -1, 0]\n\
             [[light]]\nshape = \"rectangle\"\nposition = [0, 5, 0]\nsize = [2, 4]\nnormal = [0, -1, 0]\nwidth_axis = [1, 1, 0]\n"
        );
        let scene = parse(&text).unwrap();
        let shapes: Vec<_> = scene.lights.iter().map(|l| l.shape).collect();
        assert_eq!(
            shapes[..3],
            [
                LightShape::Point {
                    falloff: Falloff::InverseSquare
                },
                LightShape::Sphere { radius: 0.5 },
                LightShape::Disc {
                    radius: 2.0,
                    normal: Vec3::NEG_Y
                },
            ]
        );
        // As a floor-facing plane of the same size: `a` along z, `b` along x.
        let LightShape::Rectangle {
            half_width,
            half_height,
            normal,
        } = shapes[3]
        else {
            panic!("{:?}", shapes[3]);
        };
        let (u, v) = crate::geometry::plane_axes(Vec3::NEG_Y);
        assert_eq!((half_width, half_height, normal), (u, v * 2.0, Vec3::NEG_Y));
        let LightShape::Rectangle { half_width, .. } = shapes[4] else {
            panic!("{:?}", shapes[4]);
        };
        assert!(half_width.abs_diff_eq(Vec3::X, 1e-6), "{half_width}");
    }

    #[test]
    fn fields_of_other_shapes_missing_ones_and_bad_sizes_are_refused() {
        let light = "[[light]]\nposition = [0, 5, 0]\n";
        for (extra, field, message) in [
            (
                "shape = \"sphere\"\nradius = 1\nfalloff = \"none\"\n",
                "light[0].falloff",
                "is for point lights only, and this light's shape is \"sphere\" (area lights always fall off as the inverse square of the distance)",
            ),
            (
                "radius = 1\n",
                "light[0].radius",
                "is for sphere and disc lights only, and this light's shape is \"point\"",
            ),
            ("shape = \"disc\"\nradius = 1\n", "light[0].normal", "a disc light needs it"),
            (
                "shape = \"rectangle\"\nsize = [1, 0]\nnormal = [0, -1, 0]\n",
                "light[0].size",
                "must be a finite number above 0, got 0",
            ),
            (
                "shape = \"disc\"\nradius = 1\nnormal = [0, 0, 0]\n",
                "light[0].normal",
                "must be a direction (not zero), got [0.0, 0.0, 0.0]",
            ),
            (
                "shape = \"rectangle\"\nsize = [1, 1]\nnormal = [0, -1, 0]\nwidth_axis = [0, 2, 0]\n",
                "light[0].width_axis",
                "[0.0, 1.0, 0.0] runs along the normal [0.0, -1.0, 0.0]: it must lie across it",
            ),
        ] {
            let text = format!("{CAMERA}{light}{extra}");
            let err = parse(&text).unwrap_err();
            // The line that gives the field, or the table's for one missing.
            let name = field.trim_start_matches("light[0].");
            let line_of = |start: &str| text.lines().position(|l| l.starts_with(start));
            let line = line_of(name).or(line_of("[[light]]")).map(|i| i + 1);
            assert_eq!(
                (err.line, err.field.as_deref(), err.message.as_str()),
                (line, Some(field), message),
                "{err}"
            );
        }
        let err = parse(&format!("{CAMERA}[render]\nlight_samples = 0\n")).unwrap_err();
        assert_eq!(err.field.as_deref(), Some("render.light_samples"), "{err}");
    }

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

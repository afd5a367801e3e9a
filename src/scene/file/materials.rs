//! The `[material.NAME]` tables as [`Material`]s.
//!
//! Promises: every colour is finite and not negative, a checker's scale
//! above 0, the shininess finite and not negative, the reflectivity and
//! the roughness within 0..1; a bump scale finite; a transparent
//! material's values as [`Glass`] promises.

use std::path::Path;

use toml::Spanned;

use super::defs::MaterialDef;
use super::values::colour;
use super::Ctx;
use crate::scene::glass::{Glass, DEFAULT_IOR};
use crate::scene::{BumpMap, Checker, Material, SceneError};
use crate::texture::load::TextureProblem;
use crate::texture::path::{resolve, shown};
use crate::texture::{TextureEncoding, TextureRef};

/// The texture `written` names in field `field` (`texture`,
/// `specular_texture`, `cutout_texture`, ...) of material `name`, relative to the file that
/// names it, its RGB read as `encoding`. A file that is missing or not a
/// readable image is a warning (the material renders untextured); one
/// past the texture memory limit an error.
fn texture(
    ctx: &Ctx,
    name: &str,
    field: &str,
    written: &Spanned<String>,
    encoding: TextureEncoding,
) -> Result<Option<TextureRef>, SceneError> {
    let field = format!("material.{name}.{field}");
    let here = || {
        let (file, line) = ctx
            .source
            .locate(super::line_of(&ctx.source.text, written.span().start));
        format!("{}:{line}: {field}", file.display())
    };
    let folder = ctx
        .file_of(written.span())
        .parent()
        .unwrap_or(Path::new(""));
    let Some(found) = resolve(folder, written.get_ref()) else {
        ctx.texture_warnings.borrow_mut().push(format!(
            "{}: no file '{}' (looked in {}); the material renders without it",
            here(),
            written.get_ref(),
            shown(folder)
        ));
        return Ok(None);
    };
    if found.case_differs {
        ctx.texture_warnings.borrow_mut().push(format!(
            "{}: '{}' found as {} (the case differs)",
            here(),
            written.get_ref(),
            found.path.display()
        ));
    }
    let loaded = ctx.textures.borrow_mut().load_as(&found.path, encoding);
    match loaded {
        Ok(texture) => Ok(Some(texture)),
        Err(TextureProblem::Skipped(why)) => {
            ctx.texture_warnings.borrow_mut().push(format!(
                "{}: {why}; the material renders without it",
                here()
            ));
            Ok(None)
        }
        Err(TextureProblem::OverBudget(why)) => Err(ctx.error(written.span(), field, why)),
    }
}

/// The material `name` of a `[material.name]` table.
pub(super) fn convert_material(
    ctx: &Ctx,
    name: &str,
    def: &Spanned<MaterialDef>,
) -> Result<Material, SceneError> {
    let m = def.get_ref();
    let field = |f: &str| format!("material.{name}.{f}");
    let err = |f: &str| {
        let f = field(f);
        move |message: String| ctx.error(def.span(), f.clone(), message)
    };
    let checker = match &m.checker {
        None => None,
        Some(c) => {
            if !(c.scale.is_finite() && c.scale > 0.0) {
                return Err(err("checker.scale")(format!(
                    "must be above 0, got {}",
                    c.scale
                )));
            }
            Some(Checker {
                colors: [
                    colour(c.colors[0]).map_err(err("checker.colors"))?,
                    colour(c.colors[1]).map_err(err("checker.colors"))?,
                ],
                scale: c.scale,
            })
        }
    };
    if !(m.shininess.is_finite() && m.shininess >= 0.0) {
        return Err(err("shininess")(format!(
            "must be >= 0, got {}",
            m.shininess
        )));
    }
    if !(0.0..=1.0).contains(&m.reflectivity) {
        return Err(err("reflectivity")(format!(
            "must be within 0..1, got {}",
            m.reflectivity
        )));
    }
    if !(0.0..=1.0).contains(&m.roughness) {
        return Err(err("roughness")(format!(
            "must be within 0..1, got {}",
            m.roughness
        )));
    }
    let diffuse_map = match &m.texture {
        None => None,
        Some(written) => texture(ctx, name, "texture", written, TextureEncoding::Srgb)?,
    };
    let specular_map = match &m.specular_texture {
        None => None,
        Some(written) => texture(
            ctx,
            name,
            "specular_texture",
            written,
            TextureEncoding::Srgb,
        )?,
    };
    let cutout = match &m.cutout_texture {
        None => None,
        Some(written) => texture(ctx, name, "cutout_texture", written, TextureEncoding::Srgb)?
            .map(|map| crate::scene::coverage_of(&map)),
    };
    let bump_map = bump_map(ctx, name, m, err)?;
    let untextured_grey = if diffuse_map.is_some() { 1.0 } else { 0.7 };
    let unmapped_specular = if specular_map.is_some() { 1.0 } else { 0.0 };
    let filter = match m.transmission_filter {
        Some(filter) => colour(filter).map_err(err("transmission_filter"))?,
        None => glam::Vec3::ONE,
    };
    let glass = Glass::new(m.transparency, m.ior.unwrap_or(DEFAULT_IOR), filter)
        .map_err(|(f, message)| err(f)(message))?;
    Ok(Material {
        name: name.to_string(),
        diffuse: colour(m.diffuse.unwrap_or([untextured_grey; 3])).map_err(err("diffuse"))?,
        diffuse_map,
        checker,
        specular: colour(m.specular.unwrap_or([unmapped_specular; 3])).map_err(err("specular"))?,
        specular_map,
        bump_map,
        shininess: m.shininess,
        reflectivity: m.reflectivity,
        roughness: m.roughness,
        glass,
        cutout,
        emission: glam::Vec3::ZERO,
    })
}

/// The height or normal map of material `name`, if it has one that
/// loaded; `err(field)` makes an error about one of its fields.
fn bump_map<E: Fn(String) -> SceneError>(
    ctx: &Ctx,
    name: &str,
    m: &MaterialDef,
    err: impl Fn(&str) -> E,
) -> Result<Option<BumpMap>, SceneError> {
    if let Some(scale) = m.bump_scale {
        if !scale.is_finite() {
            return Err(err("bump_scale")(format!("must be finite, got {scale}")));
        }
        if m.bump_texture.is_none() {
            return Err(err("bump_scale")(
                "scales a height map: give the material a `bump_texture`".into(),
            ));
        }
    }
    match (&m.bump_texture, &m.normal_texture) {
        (Some(_), Some(_)) => Err(err("normal_texture")(
            "a material takes a height map (`bump_texture`) or a normal map \
             (`normal_texture`), not both"
                .into(),
        )),
        (Some(written), None) => {
            let map = texture(ctx, name, "bump_texture", written, TextureEncoding::Linear)?;
            Ok(map.map(|map| BumpMap::Height {
                map,
                scale: m.bump_scale.unwrap_or(1.0),
            }))
        }
        (None, Some(written)) => {
            let map = texture(
                ctx,
                name,
                "normal_texture",
                written,
                TextureEncoding::Linear,
            )?;
            Ok(map.map(|map| BumpMap::Normal { map }))
        }
        (None, None) => Ok(None),
    }
}

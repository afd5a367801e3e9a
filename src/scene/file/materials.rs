//! The `[material.NAME]` tables as [`Material`]s.
//!
//! Promises: every colour is finite and not negative, a checker's scale
//! above 0, the shininess finite and not negative, the reflectivity and
//! the roughness within 0..1; a transparent material's values as
//! [`Glass`] promises.

use std::path::Path;
use std::sync::Arc;

use toml::Spanned;

use super::defs::MaterialDef;
use super::values::colour;
use super::Ctx;
use crate::geometry::CoverageRef;
use crate::scene::glass::{Glass, DEFAULT_IOR};
use crate::scene::{Checker, Material, SceneError};
use crate::texture::load::TextureProblem;
use crate::texture::path::{resolve, shown};
use crate::texture::TextureRef;

/// The texture `written` names in field `field` (`texture`,
/// `specular_texture`, `cutout_texture`) of material `name`, relative to the file that
/// names it. A file that is missing or not a readable image is a
/// warning (the material renders untextured); one past the texture memory
/// limit an error.
fn texture(
    ctx: &Ctx,
    name: &str,
    field: &str,
    written: &Spanned<String>,
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
    let loaded = ctx.textures.borrow_mut().load(&found.path);
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
        Some(written) => texture(ctx, name, "texture", written)?,
    };
    let specular_map = match &m.specular_texture {
        None => None,
        Some(written) => texture(ctx, name, "specular_texture", written)?,
    };
    let cutout = match &m.cutout_texture {
        None => None,
        Some(written) => texture(ctx, name, "cutout_texture", written)?
            .map(|map| CoverageRef(Arc::new(map.coverage()))),
    };
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
        shininess: m.shininess,
        reflectivity: m.reflectivity,
        roughness: m.roughness,
        glass,
        cutout,
    })
}

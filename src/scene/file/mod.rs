//! The TOML scene file: parsing, checking, and conversion to a [`Scene`].
//!
//! [`parse_scene_str`] splices in the file's includes (`include`), reads
//! its tables with serde (`defs`), then converts them in the order a scene
//! needs them: `[render]` (here), `[camera]` (`camera`), `[material.NAME]`
//! (`materials`), `[[light]]` (`lights`), `[[object]]` (`objects`),
//! `[animation]` (`animation`) and `[[viewport]]` (`viewports`); `values`
//! holds the checks they share.
//!
//! Promises: a scene that loads keeps the promises of [`Scene`]; a scene
//! that does not gets one error, which names the file, the line (of the
//! offending value or of the table it sits in) and the field path, e.g.
//! `scenes/x.toml:14: object[2].radius: must be above 0, got -1`.

mod animation;
mod camera;
mod defs;
mod include;
mod lights;
mod materials;
mod objects;
mod spans;
mod values;
mod viewports;
mod wording;

use std::path::Path;

use glam::{Affine3A, Vec3};
use toml::Spanned;

use super::{Material, Scene, SceneError, MAX_LIGHT_SAMPLES};
use crate::camera::Projection;
use crate::geometry::Placement;
use crate::sampling::PixelSamples;
use crate::texture::load::{TextureCache, DEFAULT_TEXTURE_MEMORY_MB};
use crate::texture::TextureFilter;
use animation::convert_animation;
use camera::{convert_camera, convert_lens, keys_start_lens};
use defs::{RenderDef, SceneFile};
use include::{line_of, splice, Source};
pub(crate) use include::{read_text, Files, MAX_SCENE_TEXT};
use lights::convert_lights;
use materials::convert_material;
use objects::convert_objects;
use values::colour;
use viewports::convert_viewports;

/// Settings from the command line that replace the file's.
#[derive(Clone, Debug, Default)]
pub struct SceneOverrides {
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub projection: Option<Projection>,
    /// Degrees.
    pub fov: Option<f64>,
    /// Samples per pixel (`--spp`).
    pub spp: Option<u32>,
    /// Shadow rays a pixel sample casts to an area light
    /// (`--light-samples`).
    pub light_samples: Option<u32>,
    /// The most memory textures may take, in MB (`--texture-memory`).
    pub texture_memory_mb: Option<u64>,
    /// How textures are filtered (`--texture-filter`).
    pub texture_filter: Option<TextureFilter>,
    /// Which axis a bare OBJ model's up is (`--up`): most tools write Y
    /// up, CAD and 3ds Max exports Z.
    pub up: Option<UpAxis>,
}

/// The axis a model's author meant as up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UpAxis {
    #[default]
    Y,
    Z,
}

impl std::str::FromStr for UpAxis {
    type Err = String;

    fn from_str(s: &str) -> Result<UpAxis, String> {
        match s {
            "y" | "Y" => Ok(UpAxis::Y),
            "z" | "Z" => Ok(UpAxis::Z),
            _ => Err(format!("'{s}' is not an axis: give y or z")),
        }
    }
}

impl SceneOverrides {
    /// The samples per pixel `--spp` asks for, if it does.
    pub(crate) fn samples(&self) -> Result<Option<PixelSamples>, SceneError> {
        self.spp
            .map(|spp| {
                PixelSamples::new(spp).map_err(|m| SceneError::of_flags(format!("--spp {spp}"), m))
            })
            .transpose()
    }

    /// The light samples `--light-samples` asks for, if it does.
    pub(crate) fn light_samples(&self) -> Result<Option<u32>, SceneError> {
        self.light_samples
            .map(|count| {
                check_light_samples(count)
                    .map_err(|m| SceneError::of_flags(format!("--light-samples {count}"), m))
            })
            .transpose()
    }

    /// Where the scene's textures load, within the memory asked for.
    pub(crate) fn texture_cache(&self) -> TextureCache {
        TextureCache::new(
            self.texture_memory_mb.unwrap_or(DEFAULT_TEXTURE_MEMORY_MB),
            self.texture_filter.unwrap_or_default(),
        )
    }
}

/// Deepest reflection recursion accepted (each level can double the rays).
pub const MAX_DEPTH_LIMIT: u32 = 16;

/// What every table's conversion needs: the spliced source, to name the
/// file and line of a span.
struct Ctx<'a> {
    source: &'a Source,
    /// The scene's textures (materials' and models' alike), and what
    /// loading them went past.
    textures: std::cell::RefCell<TextureCache>,
    texture_warnings: std::cell::RefCell<Vec<String>>,
}

impl Ctx<'_> {
    /// The error `message` about `field`, at the line of the value the
    /// field path names, else (a field left out) where `table`, the span
    /// of the table it belongs in, starts.
    fn error(
        &self,
        table: std::ops::Range<usize>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> SceneError {
        let field = field.into();
        let at = self.locate(&field, table);
        let (file, line) = self.source.locate(line_of(&self.source.text, at));
        SceneError::new(file, message).at_line(line).field(field)
    }

    /// [`Ctx::error`], at the value of the field path `at`, the error
    /// naming `field` (which says more: `camera.pitch with --fov 170`).
    fn error_at(
        &self,
        table: std::ops::Range<usize>,
        at: &str,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> SceneError {
        let at = self.locate(at, table);
        let (file, line) = self.source.locate(line_of(&self.source.text, at));
        SceneError::new(file, message).at_line(line).field(field)
    }

    /// Where the value of the field path `field` starts in the spliced
    /// text; `table`'s start when the file did not write it.
    fn locate(&self, field: &str, table: std::ops::Range<usize>) -> usize {
        spans::value_span(&self.source.text, field).map_or(table.start, |span| span.start)
    }

    /// The file a span was written in (relative paths in it start there).
    fn file_of(&self, span: std::ops::Range<usize>) -> &Path {
        self.source.locate(line_of(&self.source.text, span.start)).0
    }
}

/// What a scene defines, for an error message: the names, comma-separated,
/// or `none`.
fn names_or_none<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let names: Vec<&str> = names.collect();
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}

/// `path` as the user wrote it: `Spanned<T>` shows up in serde's path as a
/// private key (anywhere, last too, when the spanned table itself lacks a
/// field), which no scene file has.
fn user_path(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut out = String::new();
    for segment in path.iter() {
        match segment {
            Segment::Seq { index } => out.push_str(&format!("[{index}]")),
            Segment::Map { key } if key.starts_with("$__serde_spanned") => {}
            Segment::Map { key } | Segment::Enum { variant: key } => {
                if !out.is_empty() {
                    out.push('.');
                }
                out.push_str(key);
            }
            Segment::Unknown => {
                if !out.is_empty() {
                    out.push('.');
                }
                out.push('?');
            }
        }
    }
    out
}

/// The scene of a scene file's `text`, read from `path` (which names it
/// in errors, and where its includes and models are found), with the
/// command line's `overrides`.
pub fn parse_scene_str(
    text: &str,
    path: &Path,
    overrides: &SceneOverrides,
) -> Result<Scene, SceneError> {
    parse_scene(text, path, Files::Disk, overrides)
}

/// As [`parse_scene_str`], its includes read from `files`.
pub(crate) fn parse_scene(
    text: &str,
    path: &Path,
    files: Files,
    overrides: &SceneOverrides,
) -> Result<Scene, SceneError> {
    let source = splice(text, path, files)?;
    let text = source.text.as_str();
    if let Some(number) = spans::first_unfit_number(text) {
        let (file, line) = source.locate(line_of(text, number.span.start));
        return Err(SceneError::new(file, number.message(text))
            .at_line(line)
            .field(number.path));
    }
    let deserializer = toml::Deserializer::new(text);
    let file: SceneFile = serde_path_to_error::deserialize(deserializer).map_err(|err| {
        let field = user_path(err.path());
        let inner = err.into_inner();
        let span = inner.span();
        // What the file wrote there, for a message that does not say.
        let written = span
            .as_ref()
            .and_then(|span| text.get(span.clone()))
            .and_then(|value| value.lines().next())
            .filter(|value| value.len() <= 40);
        let message = wording::reworded(inner.message(), &field, written);
        let mut e = SceneError::new(path, message.clone());
        if let Some(span) = span {
            let (file, line) = source.locate(line_of(text, span.start));
            e = SceneError::new(file, message).at_line(line);
        }
        if !field.is_empty() {
            e = e.field(field);
        }
        e
    })?;
    let ctx = Ctx {
        source: &source,
        textures: std::cell::RefCell::new(overrides.texture_cache()),
        texture_warnings: std::cell::RefCell::new(Vec::new()),
    };

    let default_render = RenderDef::default();
    let render_span = file.render.as_ref().map(Spanned::span);
    let render = file
        .render
        .as_ref()
        .map_or(&default_render, Spanned::get_ref);
    // A [render] table's errors name its line (in whichever file holds it).
    let render_error = |field: &str, message: String| match &render_span {
        Some(span) => ctx.error(span.clone(), field, message),
        None => SceneError::new(path, message).field(field),
    };
    let background = colour(render.background).map_err(|m| render_error("render.background", m))?;
    let ambient = colour(render.ambient).map_err(|m| render_error("render.ambient", m))?;
    if render.max_depth > MAX_DEPTH_LIMIT {
        return Err(render_error(
            "render.max_depth",
            format!("at most {MAX_DEPTH_LIMIT}, got {}", render.max_depth),
        ));
    }

    let samples = match overrides.samples()? {
        Some(samples) => samples,
        None => PixelSamples::new(render.spp).map_err(|m| render_error("render.spp", m))?,
    };
    let light_samples = match overrides.light_samples()? {
        Some(count) => count,
        None => check_light_samples(render.light_samples)
            .map_err(|m| render_error("render.light_samples", m))?,
    };
    let camera = convert_camera(&ctx, &file.camera, render, render_span, overrides)?;
    let mut lens = convert_lens(&ctx, &file.camera)?;

    let mut materials = Vec::with_capacity(file.material.len() + 1);
    for (name, def) in &file.material {
        materials.push(convert_material(&ctx, name, def)?);
    }
    let default_material = materials.len();
    materials.push(Material::matte("default", Vec3::splat(0.7)));

    let mut lights = convert_lights(&ctx, &file.light)?;

    let mut warnings = Vec::new();
    let mut objects =
        convert_objects(&ctx, &file, &mut materials, default_material, &mut warnings)?;
    warnings.extend(ctx.texture_warnings.take());
    // After the tables' lights: the animation's light keys number those.
    lights.extend(crate::scene::mesh_lights(&objects, &materials));
    // Legal (an all-mirror or a flat-lit scene), but more often a light
    // forgotten: the picture comes out dim, flat and shadowless.
    if lights.is_empty() {
        warnings.push(format!(
            "{}: no [[light]]: surfaces show only the ambient term (render.ambient = {:?}), \
             without highlights or shadows",
            path.display(),
            ambient.to_array()
        ));
    }

    let animation = file
        .animation
        .as_ref()
        .map(|def| {
            let keys_lens = keys_start_lens(&file.camera, lens);
            convert_animation(
                &ctx,
                def,
                &camera,
                keys_lens,
                &objects,
                &materials,
                &file.light,
            )
        })
        .transpose()?;
    if let Some(animation) = &animation {
        // Animated objects become instances, so a move updates a transform
        // instead of rebuilding geometry; the scene shows frame 0.
        for track in &animation.objects {
            for &object in &track.objects {
                objects[object].placement = Placement::Instance(Affine3A::IDENTITY);
            }
        }
        animation.pose(&mut objects, &mut lights, 0);
        lens = animation.lens_at(lens, 0);
    }

    let viewports = convert_viewports(&ctx, &file, &camera)?;
    crate::scene::cut_out_meshes(&mut objects, &materials);

    Ok(Scene {
        camera,
        lens,
        camera_motion: None,
        viewports,
        objects,
        materials,
        lights,
        background,
        ambient,
        max_depth: render.max_depth,
        samples,
        light_samples,
        warnings,
        animation,
    })
}

/// A count of light samples within 1..=[`MAX_LIGHT_SAMPLES`].
fn check_light_samples(count: u32) -> Result<u32, String> {
    if (1..=MAX_LIGHT_SAMPLES).contains(&count) {
        Ok(count)
    } else {
        Err(format!(
            "must be within 1..={MAX_LIGHT_SAMPLES}, got {count}"
        ))
    }
}

/// What the tests of every table share.
#[cfg(test)]
mod testing {
    use std::path::Path;

    use super::{parse_scene_str, SceneOverrides};
    use crate::scene::{Scene, SceneError};

    /// The scene of `text`, read as if from `t.toml`, without overrides.
    pub(super) fn parse(text: &str) -> Result<Scene, SceneError> {
        parse_scene_str(text, Path::new("t.toml"), &SceneOverrides::default())
    }

    /// A camera table (lines 1 to 3) to put before the table under test.
    pub(super) const CAMERA: &str = "[camera]\nposition = [0, 1, 5]\nfov = 60\n";
}

#[cfg(test)]
mod tests {
    use super::testing::{parse, CAMERA};

    #[test]
    fn minimal_scene_parses() {
        let scene = parse(&format!(
            "{CAMERA}[material.red]\ndiffuse = [1, 0, 0]\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"red\"\n"
        ))
        .unwrap();
        assert_eq!(scene.objects.len(), 1);
        assert_eq!(scene.materials[scene.objects[0].material].name, "red");
        assert_eq!(scene.camera.width, 640);
    }

    #[test]
    fn a_scene_without_lights_warns_that_only_the_ambient_term_lights_it() {
        let sphere = "[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n";
        let scene = parse(&format!(
            "{CAMERA}[render]\nambient = [0.2, 0.2, 0.2]\n{sphere}"
        ))
        .unwrap();
        assert_eq!(
            scene.warnings,
            ["t.toml: no [[light]]: surfaces show only the ambient term \
              (render.ambient = [0.2, 0.2, 0.2]), without highlights or shadows"]
        );
        let lit = parse(&format!(
            "{CAMERA}[[light]]\nposition = [0, 5, 0]\n{sphere}"
        ))
        .unwrap();
        assert_eq!(lit.warnings, Vec::<String>::new());
    }

    #[test]
    fn a_scene_beyond_the_world_extent_is_refused_by_line_and_field() {
        // Embree aborts on rays from or toward such points: each is named.
        let sphere = "[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n";
        let cases = [
            (
                format!("[camera]\nposition = [0, 1e13, 5]\nfov = 60\n{sphere}"),
                2,
                "camera.position.y",
            ),
            (
                format!("{CAMERA}[[light]]\nposition = [1e19, 0, 0]\n{sphere}"),
                5,
                "light[0].position",
            ),
            (
                format!("{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1e13\n"),
                4,
                "object[0]",
            ),
            (
                format!("{CAMERA}{sphere}[animation]\nframes = 2\n[[animation.camera]]\nframe = 1\nposition = [2e12, 0, 0]\n"),
                12,
                "animation.camera[0].position.x",
            ),
            (
                format!("[camera]\nprojection = \"equal-angle\"\nposition = [0, 1, 5]\nfov = 100\n{sphere}[animation]\nframes = 2\n[[animation.camera]]\nframe = 1\npitch = 80\n"),
                13,
                "animation.camera[0].pitch",
            ),
        ];
        for (text, line, field) in cases {
            let err = parse(&text).unwrap_err();
            assert_eq!(
                (err.line, err.field.as_deref()),
                (Some(line), Some(field)),
                "{err}"
            );
        }
        // At the extent's edge, a scene is fine.
        parse(&format!(
            "[camera]\nposition = [0, 1e12, 5]\nfov = 60\n{sphere}"
        ))
        .unwrap();
    }

    #[test]
    fn type_errors_name_line_and_field() {
        let err = parse(&format!(
            "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = \"big\"\n"
        ))
        .unwrap_err();
        assert_eq!(err.line, Some(7), "{err}");
        assert_eq!(err.field.as_deref(), Some("object[0].radius"), "{err}");
        let err = parse("[camera]\nposition = [0, 1, 5\nfov = 60\n").unwrap_err();
        assert!(err.line.is_some(), "{err}");
        let err = parse(&format!(
            "{CAMERA}[[object]]\ntype = \"sphere\"\ncentre = [0, 0, 0]\n"
        ))
        .unwrap_err();
        assert!(err.message.contains("centre"), "{err}");
    }

    #[test]
    fn missing_fields_name_their_table_not_serde_internals() {
        let err = parse("[camera]\nfov = 60\n").unwrap_err();
        assert_eq!(err.field.as_deref(), Some("camera"), "{err}");
        assert!(err.message.contains("missing field `position`"), "{err}");
        assert!(!err.to_string().contains("serde"), "{err}");
        let err = parse(&format!("{CAMERA}[[light]]\ncolor = [1, 1, 1]\n")).unwrap_err();
        assert_eq!(err.field.as_deref(), Some("light[0]"), "{err}");
        assert!(err.message.contains("missing field `position`"), "{err}");
    }

    #[test]
    fn render_and_camera_errors_name_the_line_of_their_field() {
        // [render] on line 4, its field on line 6.
        let camera = "[camera]\nposition = [0, 1, 5]\nfov = 60\n";
        for (render, field) in [
            ("background = [nan, 0, 0]", "render.background"),
            ("ambient = [-1, 0, 0]", "render.ambient"),
            ("max_depth = 1000", "render.max_depth"),
            ("width = 0", "render.width"),
        ] {
            let err = parse(&format!("{camera}[render]\nheight = 10\n{render}\n")).unwrap_err();
            assert_eq!(
                (err.line, err.field.as_deref()),
                (Some(6), Some(field)),
                "{err}"
            );
        }
        let err =
            parse("[camera]\nposition = [0, 1, 5]\nfov = 60\nlook_at = [0, nan, 0]\n").unwrap_err();
        assert_eq!(
            (err.line, err.field.as_deref()),
            (Some(4), Some("camera.look_at")),
            "{err}"
        );
    }

    #[test]
    fn bad_values_are_rejected() {
        for (body, field) in [
            (
                "[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = -1\n",
                "object[0].radius",
            ),
            (
                "[[object]]\ntype = \"sphere\"\ncenter = [0, nan, 0]\nradius = 1\n",
                "object[0].center",
            ),
            (
                "[[object]]\ntype = \"sphere\"\ncenter = [0, inf, 0]\nradius = 1\n",
                "object[0].center",
            ),
            (
                "[[object]]\ntype = \"quad\"\nvertices = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\n",
                "object[0].vertices",
            ),
            ("[[light]]\nposition = [0, nan, 0]\n", "light[0].position"),
            ("[animation]\nframes = 0\n", "animation.frames"),
            ("[animation]\nframes = 4000000000\n", "animation.frames"),
            ("[animation]\nframes = 2\nfps = 0\n", "animation.fps"),
        ] {
            let err = parse(&format!("{CAMERA}{body}")).unwrap_err();
            assert_eq!(err.field.as_deref(), Some(field), "{err}");
            assert!(err.line.is_some());
        }
        for (camera, field) in [
            ("[camera]\nposition = [0, 1, 5]\nfov = 0\n", "camera.fov"),
            ("[camera]\nposition = [0, 1, 5]\nfov = 180\n", "camera.fov"),
            ("[render]\nwidth = 0\n[camera]\nposition = [0, 1, 5]\nfov = 60\n", "render.width"),
            ("[render]\nwidth = 4000000\nheight = 4000000\n[camera]\nposition = [0, 1, 5]\nfov = 60\n", "render.width/height"),
        ] {
            let err = parse(camera).unwrap_err();
            assert_eq!(err.field.as_deref(), Some(field), "{err}");
        }
    }
}

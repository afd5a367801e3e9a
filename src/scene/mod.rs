//! Render-ready scenes: what a scene file (TOML), a bare OBJ, or the built-in
//! paper scene turn into.
//!
//! Promises: every number in a [`Scene`] is finite, every material index is
//! valid, every mesh triangle has non-zero area, and the camera validated.

mod file;
pub mod glass;
mod obj;

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::camera::Camera;
use crate::geometry::{Coverage, CoverageRef, Cutout, Light, LightShape, Object, Shape};
use crate::texture::TextureRef;
use crate::timeline::{Animation, ViewportTrack};

pub use file::{parse_scene_str, SceneOverrides, UpAxis};
pub use glass::Glass;
pub use obj::{load_obj_mesh, load_obj_mesh_with, ObjMesh, ObjPart};

/// The scene files of `scenes/` built into the binary, so `retrace render`
/// and the lab work with no files at all: the paper's scene (checkerboard
/// plane, 12 polygons, 19 spheres, 2 lights) and its experiments, which
/// include it. By file name.
pub const BUILTIN_SCENES: &[(&str, &str)] = &[
    ("paper.toml", include_str!("../../scenes/paper.toml")),
    (
        "paper-pan.toml",
        include_str!("../../scenes/paper-pan.toml"),
    ),
    (
        "paper-zoom-in.toml",
        include_str!("../../scenes/paper-zoom-in.toml"),
    ),
    (
        "paper-zoom-out.toml",
        include_str!("../../scenes/paper-zoom-out.toml"),
    ),
    (
        "paper-bounce.toml",
        include_str!("../../scenes/paper-bounce.toml"),
    ),
    (
        "paper-all.toml",
        include_str!("../../scenes/paper-all.toml"),
    ),
    (
        "paper-bounce-blur.toml",
        include_str!("../../scenes/paper-bounce-blur.toml"),
    ),
    (
        "paper-all-blur.toml",
        include_str!("../../scenes/paper-all-blur.toml"),
    ),
    (
        "paper-pan-blur.toml",
        include_str!("../../scenes/paper-pan-blur.toml"),
    ),
    (
        "paper-pan-lens.toml",
        include_str!("../../scenes/paper-pan-lens.toml"),
    ),
    (
        "paper-pan-zoom.toml",
        include_str!("../../scenes/paper-pan-zoom.toml"),
    ),
    (
        "paper-viewports.toml",
        include_str!("../../scenes/paper-viewports.toml"),
    ),
];

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Checker {
    pub colors: [Vec3; 2],
    /// Edge length of one square, in world units.
    pub scale: f32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub diffuse: Vec3,
    pub checker: Option<Checker>,
    pub specular: Vec3,
    pub shininess: f32,
    /// Share of the mirror reflection added to the colour (0 = none).
    pub reflectivity: f32,
    /// How rough the reflecting surface is, 0 to 1: 0 a perfect mirror;
    /// above, each reflection ray leaves through a lobe about the mirror
    /// direction, wider as it grows (glossy reflection).
    pub roughness: f32,
    /// An image the diffuse colour is multiplied by, on meshes with
    /// texture coordinates (MTL `map_Kd`, a scene's `texture`).
    pub diffuse_map: Option<TextureRef>,
    /// An image the specular colour is multiplied by, likewise (MTL
    /// `map_Ks`, a scene's `specular_texture`).
    pub specular_map: Option<TextureRef>,
    /// Relief that bends the shading normal, likewise.
    pub bump_map: Option<BumpMap>,
    /// Transparent materials only: how light goes through.
    pub glass: Option<Glass>,
    /// Where the surface is cut away, letting rays through (MTL `map_d`, a
    /// scene's `cutout_texture`): on meshes with texture coordinates.
    pub cutout: Option<CoverageRef>,
    /// The light the surface gives off itself, seen where it is hit (MTL
    /// `Ke`, on the faces of a model whose object asks for mesh lights;
    /// zero elsewhere). The faces light the scene as triangle lights.
    pub emission: Vec3,
}

/// `map`'s full-size image as a cut-out map.
pub(crate) fn coverage_of(map: &TextureRef) -> CoverageRef {
    let level = &map.levels()[0];
    CoverageRef(std::sync::Arc::new(Coverage::from_rgba8(
        level.width,
        level.height,
        &level.texels,
    )))
}

/// Gives each mesh with texture coordinates its material's cut-out, where
/// the material has one: the backends read it from the mesh.
pub fn cut_out_meshes(objects: &mut [Object], materials: &[Material]) {
    for object in objects {
        if let (Shape::Mesh(mesh), Some(coverage)) =
            (&mut object.shape, &materials[object.material].cutout)
        {
            mesh.cutout = Cutout::new(mesh, coverage.clone());
        }
    }
}

/// A triangle light for each face of a mesh whose material glows (see
/// [`Material::emission`]), in the order of the objects and their faces.
/// Its power makes the light agree with the glow seen on the face: a
/// white matte surface under a glowing ceiling that fills its sky looks
/// as bright as the ceiling (the face's area over pi, times the glow,
/// since a light's power is its intensity straight in front).
pub fn mesh_lights(objects: &[Object], materials: &[Material]) -> Vec<Light> {
    let mut lights = Vec::new();
    for object in objects {
        let emission = materials[object.material].emission;
        let Shape::Mesh(mesh) = &object.shape else {
            continue;
        };
        if emission == Vec3::ZERO {
            continue;
        }
        // Glowing objects do not move (the scene file refuses it).
        let transform = object.placement.transform_at(0.0);
        let to_world = |p| transform.map_or(p, |xf: glam::Affine3A| xf.transform_point3(p));
        for triangle in &mesh.triangles {
            let [a, b, c] = triangle.map(|i| to_world(mesh.positions[i as usize]));
            let edges = [b - a, c - a];
            let cross = edges[0].cross(edges[1]);
            let area = 0.5 * cross.length();
            lights.push(Light {
                position: a,
                power: emission * (area / std::f32::consts::PI),
                shape: LightShape::Triangle {
                    edges,
                    normal: cross.normalize(),
                },
                motion: None,
            });
        }
    }
    lights
}

/// An image of a surface's relief, which bends its shading normal (the
/// surface itself stays where it is: shadows and silhouettes are the
/// mesh's). Its texture is read as data, not through the sRGB curve.
#[derive(Clone, Debug, PartialEq)]
pub enum BumpMap {
    /// A height map (MTL `map_Bump` or `bump`, a scene's `bump_texture`):
    /// the surface raised along its normal by the mean of the texel's RGB
    /// (0 to 1) times `scale`, in world units (MTL `-bm`, a scene's
    /// `bump_scale`; 1 unless given).
    Height { map: TextureRef, scale: f32 },
    /// A tangent-space normal map (MTL `norm`, a scene's
    /// `normal_texture`): red along the texture's u, green up its v, blue
    /// out of the surface.
    Normal { map: TextureRef },
}

/// Highlights dimmer than this are not computed (an sRGB byte changes only
/// above about 3e-4 near black).
pub const NEGLIGIBLE_HIGHLIGHT: f32 = 1e-5;

impl Material {
    /// The value of R.V below which the Phong highlight (R.V)^shininess is
    /// negligible; above 1 when the material has no highlight at all.
    pub fn highlight_cutoff(&self) -> f32 {
        if self.specular == Vec3::ZERO {
            return 2.0;
        }
        NEGLIGIBLE_HIGHLIGHT.powf(1.0 / self.shininess.max(1e-3))
    }

    /// Whether any image maps onto the material.
    pub fn textured(&self) -> bool {
        self.diffuse_map.is_some() || self.specular_map.is_some() || self.bump_map.is_some()
    }

    /// Whether the material needs texture coordinates: an image maps onto
    /// it, or cuts it out.
    pub fn needs_texcoords(&self) -> bool {
        self.textured() || self.cutout.is_some()
    }

    pub fn matte(name: &str, diffuse: Vec3) -> Material {
        Material {
            name: name.to_string(),
            diffuse,
            checker: None,
            specular: Vec3::ZERO,
            shininess: 1.0,
            reflectivity: 0.0,
            roughness: 0.0,
            diffuse_map: None,
            specular_map: None,
            bump_map: None,
            glass: None,
            cutout: None,
            emission: Vec3::ZERO,
        }
    }
}

/// Shadow rays a pixel sample casts to an area light unless
/// `render.light_samples` says otherwise.
pub const DEFAULT_LIGHT_SAMPLES: u32 = 4;

/// The most shadow rays a pixel sample may cast to one area light.
pub const MAX_LIGHT_SAMPLES: u32 = 256;

#[derive(Clone, Debug)]
pub struct Scene {
    pub camera: Camera,
    /// A thin lens at the eye (depth of field); none: a pinhole.
    pub lens: Option<crate::camera::Lens>,
    /// The camera moving while the shutter is open (motion blur), posed
    /// with the frame; none while it stands still or the shutter is shut.
    pub camera_motion: Option<crate::camera::CameraMotion>,
    pub objects: Vec<Object>,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    pub background: Vec3,
    pub ambient: Vec3,
    /// Reflection bounces after the primary hit.
    pub max_depth: u32,
    /// Sub-samples a pixel of the camera's image and of the viewports
    /// (antialiasing: the mean of stratified sub-samples).
    pub samples: crate::sampling::PixelSamples,
    /// Shadow rays each pixel sample casts to each area light (stratified
    /// over the light); point lights take one.
    pub light_samples: u32,
    /// Things the user should know that did not stop loading (e.g. dropped
    /// degenerate triangles).
    pub warnings: Vec<String>,
    /// The timeline, for scenes that animate.
    pub animation: Option<Animation>,
    /// RSVP viewports onto the camera's sample buffer (none: the camera's
    /// own image is the output).
    pub viewports: Vec<ViewportTrack>,
}

impl Scene {
    pub fn triangle_count(&self) -> usize {
        self.objects
            .iter()
            .map(|o| match &o.shape {
                Shape::Mesh(m) => m.triangles.len(),
                _ => 0,
            })
            .sum()
    }

    pub fn count_shapes(&self) -> (usize, usize, usize) {
        let mut counts = (0, 0, 0);
        for object in &self.objects {
            match object.shape {
                Shape::Mesh(_) => counts.0 += 1,
                Shape::Sphere(_) => counts.1 += 1,
                Shape::Plane(_) => counts.2 += 1,
            }
        }
        counts
    }
}

/// A scene problem a user can act on: the file, the line when known, the
/// field when known.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct SceneError {
    /// Empty when only values the command line gave are at fault: then
    /// `field` names those flags (see [`SceneError::of_flags`]).
    pub file: PathBuf,
    pub line: Option<usize>,
    pub field: Option<String>,
    pub message: String,
}

impl std::fmt::Display for SceneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut parts = Vec::new();
        if !self.file.as_os_str().is_empty() {
            match self.line {
                Some(line) => parts.push(format!("{}:{line}", self.file.display())),
                None => parts.push(self.file.display().to_string()),
            }
        }
        parts.extend(self.field.clone());
        parts.push(self.message.clone());
        write!(f, "{}", parts.join(": "))
    }
}

impl SceneError {
    pub fn new(file: &Path, message: impl Into<String>) -> SceneError {
        SceneError {
            file: file.to_path_buf(),
            line: None,
            field: None,
            message: message.into(),
        }
    }

    /// An error of the command line's values alone, `flags` as given
    /// (`--width 0`): no file is to blame.
    pub fn of_flags(flags: impl Into<String>, message: impl Into<String>) -> SceneError {
        SceneError {
            file: PathBuf::new(),
            line: None,
            field: Some(flags.into()),
            message: message.into(),
        }
    }

    pub fn at_line(mut self, line: usize) -> SceneError {
        self.line = Some(line);
        self
    }

    pub fn field(mut self, field: impl Into<String>) -> SceneError {
        self.field = Some(field.into());
        self
    }
}

/// Loads a scene from a `.toml` scene file or a bare `.obj` model (framed by
/// a default camera, light and ground plane).
pub fn load_scene(path: &Path, overrides: &SceneOverrides) -> Result<Scene, SceneError> {
    let is_obj = path
        .extension()
        .is_some_and(|ext| ext.eq_ignore_ascii_case("obj"));
    if is_obj {
        return obj::scene_around_obj(path, overrides);
    }
    if let Some(up) = overrides.up {
        return Err(SceneError::of_flags(
            format!("--up {}", if up == UpAxis::Z { "z" } else { "y" }),
            "turns a bare OBJ model; in a scene file, turn the mesh object itself \
             (a Z-up model stands up with `rotate = [-90, 0, 0]`)",
        ));
    }
    let is_mtl = path
        .extension()
        .is_some_and(|ext| ext.eq_ignore_ascii_case("mtl"));
    if is_mtl {
        return Err(material_library_given(path));
    }
    let text = file::read_text(path, file::MAX_SCENE_TEXT).map_err(|err| err.of_scene(path))?;
    parse_scene_str(&text, path, overrides)
}

/// The error for an `.mtl` given where a scene belongs: read as TOML it
/// fails on its first line, which blames the wrong thing. Names the model
/// beside it that uses the library, when there is one.
fn material_library_given(path: &Path) -> SceneError {
    let user = models_using(path);
    let what = if user.is_empty() {
        "the .obj model that names it in a `mtllib` line".to_string()
    } else {
        user.iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(" or ")
    };
    SceneError::new(
        path,
        format!("this is a material library (MTL), not a scene: render {what}, which uses it"),
    )
}

/// The `.obj` files in `mtl`'s folder whose `mtllib` lines name it, as
/// paths beside `mtl`'s own.
fn models_using(mtl: &Path) -> Vec<PathBuf> {
    use std::io::BufRead;
    let Some(name) = mtl.file_name() else {
        return Vec::new();
    };
    let folder = mtl.parent().unwrap_or(Path::new(""));
    let listed = if folder.as_os_str().is_empty() {
        Path::new(".")
    } else {
        folder
    };
    let Ok(entries) = std::fs::read_dir(listed) else {
        return Vec::new();
    };
    let mut models: Vec<PathBuf> = entries
        .filter_map(|entry| Some(folder.join(entry.ok()?.file_name())))
        .filter(|p| {
            p.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"))
                && std::fs::File::open(p).is_ok_and(|file| {
                    std::io::BufReader::new(file)
                        .lines()
                        .map_while(Result::ok)
                        .filter_map(|line| line.trim().strip_prefix("mtllib ").map(str::to_owned))
                        .any(|libs| {
                            libs.split_whitespace()
                                .any(|lib| Path::new(lib).file_name() == Some(name))
                        })
                })
        })
        .collect();
    models.sort();
    models
}

/// The built-in paper scene.
pub fn paper_scene(overrides: &SceneOverrides) -> Result<Scene, SceneError> {
    builtin_scene("paper.toml", overrides)
}

/// The built-in scene file `name` (one of [`BUILTIN_SCENES`]), loaded as
/// `scenes/<name>` would be, its includes read from the built-in files.
pub fn builtin_scene(name: &str, overrides: &SceneOverrides) -> Result<Scene, SceneError> {
    let path = Path::new("scenes").join(name);
    let text = BUILTIN_SCENES
        .iter()
        .find(|(file, _)| *file == name)
        .map(|(_, text)| *text)
        .ok_or_else(|| SceneError::new(&path, "not one of the scene files built into retrace"))?;
    file::parse_scene(text, &path, file::Files::BuiltIn, overrides)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_built_in_scene_is_its_file_in_scenes() {
        let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let overrides = SceneOverrides::default();
        for (name, text) in BUILTIN_SCENES {
            let path = scenes.join(name);
            assert_eq!(
                std::fs::read_to_string(&path).unwrap(),
                *text,
                "{name}: stale copy"
            );
            let from_disk = load_scene(&path, &overrides).unwrap();
            let built_in = builtin_scene(name, &overrides).unwrap();
            assert_eq!(format!("{from_disk:?}"), format!("{built_in:?}"), "{name}");
        }
        // Every experiment file there is built in.
        for entry in std::fs::read_dir(&scenes).unwrap() {
            let name = entry.unwrap().file_name().into_string().unwrap();
            if name.starts_with("paper") {
                assert!(
                    BUILTIN_SCENES.iter().any(|(file, _)| *file == name),
                    "{name} is not built in"
                );
            }
        }
        let err = builtin_scene("bunnies.toml", &overrides).unwrap_err();
        assert!(err.message.contains("built into"), "{err}");
    }
}

//! The scene file's tables as serde reads them: one struct per TOML table,
//! with the defaults of the fields a file may leave out.
//!
//! Promises: an unknown key anywhere is an error (`deny_unknown_fields`),
//! and a value of the wrong type is serde's error. Ranges, finiteness and
//! references between tables are not checked here but where each table is
//! converted.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

use crate::camera::Projection;
use crate::timeline::Ease;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneFile {
    pub(super) render: Option<Spanned<RenderDef>>,
    pub(super) camera: Spanned<CameraDef>,
    #[serde(default)]
    pub(super) light: Vec<Spanned<LightDef>>,
    #[serde(default)]
    pub(super) material: BTreeMap<String, Spanned<MaterialDef>>,
    #[serde(default)]
    pub(super) object: Vec<Spanned<ObjectDef>>,
    pub(super) animation: Option<AnimationDef>,
    #[serde(default)]
    pub(super) viewport: Vec<Spanned<ViewportDef>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AnimationDef {
    pub(super) frames: Spanned<u32>,
    /// Frames per second, 25 when not given.
    #[serde(default)]
    pub(super) fps: Option<Spanned<f64>>,
    /// When the shutter opens and closes around each frame, in frames
    /// (motion blur); none when not given.
    #[serde(default)]
    pub(super) shutter: Option<Spanned<[f64; 2]>>,
    #[serde(default)]
    pub(super) camera: Vec<Spanned<CameraKeyDef>>,
    #[serde(default)]
    pub(super) object: Vec<Spanned<ObjectKeyDef>>,
    #[serde(default)]
    pub(super) bounce: Vec<Spanned<BounceDef>>,
    #[serde(default)]
    pub(super) light: Vec<Spanned<LightKeyDef>>,
    #[serde(default)]
    pub(super) viewport: Vec<Spanned<ViewportKeyDef>>,
}

/// An RSVP viewport onto the camera's sample buffer.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ViewportDef {
    pub(super) name: Option<String>,
    pub(super) width: i64,
    pub(super) height: i64,
    #[serde(default = "default_projection")]
    pub(super) projection: Projection,
    /// Degrees; the camera's if unset.
    pub(super) fov: Option<f64>,
    /// Degrees, added to the camera's.
    #[serde(default)]
    pub(super) yaw: f64,
    #[serde(default)]
    pub(super) pitch: f64,
    pub(super) zoom: Option<f64>,
    /// Degrees, counter-clockwise.
    pub(super) rotate: Option<f64>,
    pub(super) shear: Option<[f64; 2]>,
    pub(super) translate: Option<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ViewportKeyDef {
    pub(super) frame: u32,
    /// Name or index of the viewport; the first if unset.
    pub(super) viewport: Option<toml::Value>,
    pub(super) zoom: Option<f64>,
    pub(super) rotate: Option<f64>,
    pub(super) shear: Option<[f64; 2]>,
    pub(super) translate: Option<[f64; 2]>,
    #[serde(default)]
    pub(super) ease: Ease,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObjectKeyDef {
    /// The object's `name` (all parts of a multi-part mesh move together).
    pub(super) object: String,
    pub(super) frame: u32,
    pub(super) translate: Option<[f32; 3]>,
    /// Degrees about x, then y, then z, around the object's centre.
    pub(super) rotate: Option<[f32; 3]>,
    #[serde(default)]
    pub(super) ease: Ease,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BounceDef {
    pub(super) object: String,
    pub(super) height: f32,
    /// Frames per hop.
    pub(super) period: f64,
    /// Fraction of a hop to start at.
    #[serde(default)]
    pub(super) phase: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightKeyDef {
    /// Index of the `[[light]]` (0 = the first).
    pub(super) light: usize,
    pub(super) frame: u32,
    pub(super) position: Option<[f32; 3]>,
    pub(super) color: Option<[f32; 3]>,
    pub(super) intensity: Option<f32>,
    #[serde(default)]
    pub(super) ease: Ease,
}

pub(super) const DEFAULT_FPS: f64 = 25.0;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraKeyDef {
    pub(super) frame: u32,
    /// Degrees.
    pub(super) yaw: Option<f64>,
    /// Degrees.
    pub(super) pitch: Option<f64>,
    /// Degrees.
    pub(super) fov: Option<f64>,
    pub(super) position: Option<[f64; 3]>,
    /// The lens's radius, scene units.
    pub(super) aperture: Option<f64>,
    pub(super) focus_distance: Option<f64>,
    #[serde(default)]
    pub(super) ease: Ease,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RenderDef {
    #[serde(default = "default_width")]
    pub(super) width: u32,
    #[serde(default = "default_height")]
    pub(super) height: u32,
    #[serde(default = "default_depth")]
    pub(super) max_depth: u32,
    #[serde(default)]
    pub(super) background: [f32; 3],
    #[serde(default = "default_ambient")]
    pub(super) ambient: [f32; 3],
    #[serde(default = "default_spp")]
    pub(super) spp: u32,
    /// Shadow rays to each area light a pixel sample casts.
    #[serde(default = "default_light_samples")]
    pub(super) light_samples: u32,
}

impl Default for RenderDef {
    fn default() -> Self {
        RenderDef {
            width: default_width(),
            height: default_height(),
            max_depth: default_depth(),
            background: [0.0; 3],
            ambient: default_ambient(),
            spp: default_spp(),
            light_samples: default_light_samples(),
        }
    }
}

fn default_spp() -> u32 {
    1
}
fn default_light_samples() -> u32 {
    crate::scene::DEFAULT_LIGHT_SAMPLES
}
fn default_width() -> u32 {
    640
}
fn default_height() -> u32 {
    480
}
fn default_depth() -> u32 {
    4
}
fn default_ambient() -> [f32; 3] {
    [0.1; 3]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraDef {
    #[serde(default = "default_projection")]
    pub(super) projection: Projection,
    pub(super) position: [f64; 3],
    /// Degrees.
    pub(super) yaw: Option<f64>,
    /// Degrees.
    pub(super) pitch: Option<f64>,
    pub(super) look_at: Option<[f64; 3]>,
    /// Horizontal field of view, degrees.
    pub(super) fov: f64,
    /// The lens's radius (depth of field), scene units; 0: a pinhole.
    pub(super) aperture: Option<f64>,
    /// The distance in focus, along each ray (default: to `look_at`).
    pub(super) focus_distance: Option<f64>,
}

fn default_projection() -> Projection {
    Projection::Perspective
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightDef {
    /// A point light's position; an area light's centre.
    pub(super) position: [f32; 3],
    #[serde(default = "white")]
    pub(super) color: [f32; 3],
    #[serde(default = "one")]
    pub(super) intensity: f32,
    #[serde(default)]
    pub(super) shape: LightShapeName,
    /// Point lights only.
    pub(super) falloff: Option<FalloffName>,
    /// Sphere and disc lights.
    pub(super) radius: Option<f32>,
    /// Rectangle lights: width and height.
    pub(super) size: Option<[f32; 2]>,
    /// Rectangle and disc lights: the side they shine to.
    pub(super) normal: Option<[f32; 3]>,
    /// Rectangle lights: the direction their width runs along.
    pub(super) width_axis: Option<[f32; 3]>,
}

#[derive(Deserialize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub(super) enum LightShapeName {
    #[default]
    Point,
    Sphere,
    Rectangle,
    Disc,
}

#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub(super) enum FalloffName {
    None,
    InverseSquare,
}

fn white() -> [f32; 3] {
    [1.0; 3]
}
fn one() -> f32 {
    1.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MaterialDef {
    /// Grey 0.7 when not given; white under a `texture`.
    #[serde(default)]
    pub(super) diffuse: Option<[f32; 3]>,
    /// An image file, relative to the scene file, the diffuse colour is
    /// multiplied by.
    #[serde(default)]
    pub(super) texture: Option<Spanned<String>>,
    pub(super) checker: Option<CheckerDef>,
    /// Black when not given; white under a `specular_texture`.
    #[serde(default)]
    pub(super) specular: Option<[f32; 3]>,
    /// An image file, relative to the scene file, the specular colour is
    /// multiplied by.
    #[serde(default)]
    pub(super) specular_texture: Option<Spanned<String>>,
    /// An image file, relative to the scene file, whose clear texels cut
    /// the surface away.
    #[serde(default)]
    pub(super) cutout_texture: Option<Spanned<String>>,
    /// A height map, relative to the scene file, that bends the shading
    /// normal.
    #[serde(default)]
    pub(super) bump_texture: Option<Spanned<String>>,
    /// World units a white texel of the height map stands above a black
    /// one: 1 when not given.
    #[serde(default)]
    pub(super) bump_scale: Option<f32>,
    /// A tangent-space normal map, relative to the scene file.
    #[serde(default)]
    pub(super) normal_texture: Option<Spanned<String>>,
    #[serde(default = "default_shininess")]
    pub(super) shininess: f32,
    #[serde(default)]
    pub(super) reflectivity: f32,
    /// Glossy reflection: 0 a perfect mirror, up to 1.
    #[serde(default)]
    pub(super) roughness: f32,
    /// Glass: share of the colour that is what lies behind (0 = opaque).
    #[serde(default)]
    pub(super) transparency: f32,
    pub(super) ior: Option<f32>,
    pub(super) transmission_filter: Option<[f32; 3]>,
}

fn default_shininess() -> f32 {
    32.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CheckerDef {
    pub(super) colors: [[f32; 3]; 2],
    #[serde(default = "one")]
    pub(super) scale: f32,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub(super) enum ObjectKind {
    Sphere,
    Plane,
    Quad,
    Polygon,
    Mesh,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObjectDef {
    #[serde(rename = "type")]
    pub(super) kind: ObjectKind,
    pub(super) name: Option<String>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) center: Option<[f32; 3]>,
    pub(super) radius: Option<f32>,
    pub(super) point: Option<[f32; 3]>,
    pub(super) normal: Option<[f32; 3]>,
    /// Finite plane: side lengths along the plane's two in-plane axes.
    pub(super) size: Option<[f32; 2]>,
    pub(super) vertices: Option<Vec<[f32; 3]>>,
    pub(super) file: Option<String>,
    #[serde(default)]
    pub(super) translate: [f32; 3],
    /// Degrees about x, then y, then z.
    #[serde(default)]
    pub(super) rotate: [f32; 3],
    #[serde(default = "one")]
    pub(super) scale: f32,
    /// Meshes without normals in the file: smooth across every edge (a
    /// crease angle of 180 degrees).
    #[serde(default)]
    pub(super) smooth: bool,
    /// Meshes without normals in the file: degrees between two faces'
    /// normals below which their shared edge is smoothed.
    pub(super) crease_angle: Option<f32>,
    /// Meshes: faces whose MTL material gives off light (`Ke`) glow and
    /// light the scene, each a triangle light.
    #[serde(default)]
    pub(super) mesh_lights: bool,
}

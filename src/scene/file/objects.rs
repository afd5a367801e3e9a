//! The `[[object]]` tables as [`Object`]s: spheres, planes (infinite, or
//! finite as a quad), quads and polygons, and OBJ meshes.
//!
//! Promises: each object has a name no other has (the table's `name`, else
//! `object[i]`; a mesh's later parts `NAME part k`), a valid material index,
//! and lies within the scene's extent (an infinite plane: its point does);
//! a field another type uses is an error, not ignored.

use std::collections::HashMap;
use std::path::Path;

use glam::{Affine3A, EulerRot, Quat, Vec3};
use toml::Spanned;

use super::defs::{ObjectDef, ObjectKind, SceneFile};
use super::values::{finite3, world3};
use super::{names_or_none, Ctx};
use crate::geometry::normals::{apply_crease_normals, DEFAULT_CREASE_ANGLE_DEG};
use crate::geometry::{
    within_world, Object, Placement, Plane, Shape, Sphere, TriangleMesh, WORLD_LIMIT,
};
use crate::scene::{Material, SceneError};

/// The objects of the `[[object]]` tables, in order (a mesh of several
/// parts as one object per part), each with its material: the one it
/// names, else `default_material`. Meshes that name none bring their MTL
/// materials, added to `materials`; what loading them noticed goes into
/// `warnings`.
pub(super) fn convert_objects(
    ctx: &Ctx,
    file: &SceneFile,
    materials: &mut Vec<Material>,
    default_material: usize,
    warnings: &mut Vec<String>,
) -> Result<Vec<Object>, SceneError> {
    let mut objects = Vec::with_capacity(file.object.len());
    let mut names: HashMap<String, usize> = HashMap::new();
    for (i, def) in file.object.iter().enumerate() {
        let material = match &def.get_ref().material {
            None => default_material,
            Some(name) => materials
                .iter()
                .position(|m| m.name == *name.get_ref())
                .ok_or_else(|| {
                    ctx.error(
                        name.span(),
                        format!("object[{i}].material"),
                        format!(
                            "unknown material '{}' (defined: {})",
                            name.get_ref(),
                            names_or_none(file.material.keys().map(String::as_str))
                        ),
                    )
                })?,
        };
        let converted = convert_object(ctx, i, def, material, materials, warnings)?;
        for object in &converted {
            let untextured = match &object.shape {
                Shape::Mesh(mesh) => mesh.texcoords.is_empty(),
                _ => true,
            };
            if untextured && materials[object.material].needs_texcoords() {
                let at = ctx.error(def.span(), format!("object[{i}]"), "");
                warnings.push(format!(
                    "{}:{}: object[{i}]: '{}' has no texture coordinates: material '{}' \
                     shows its colours without its textures",
                    at.file.display(),
                    at.line.unwrap_or(0),
                    object.name,
                    materials[object.material].name
                ));
            }
            // Keys find objects by name (a mesh's parts by "name part k"):
            // one name, one object.
            if let Some(other) = names.insert(object.name.clone(), i) {
                return Err(ctx.error(
                    def.span(),
                    format!("object[{i}].name"),
                    format!(
                        "'{}' already names object[{other}]: each object needs its own name",
                        object.name
                    ),
                ));
            }
            // A plane is unbounded: its point is checked where it is read.
            if matches!(object.shape, Shape::Plane(_)) {
                continue;
            }
            let bounds = object.shape.bounds();
            // An empty mesh is nowhere (and only a warning).
            let inside = within_world(bounds.min) && within_world(bounds.max);
            if !(bounds.is_empty() || inside) {
                let reach = bounds.min.abs().max(bounds.max.abs()).max_element();
                return Err(ctx.error(
                    def.span(),
                    format!("object[{i}]"),
                    format!(
                        "reaches {reach:e} from the origin, beyond the scene's extent \
                         (within ±{WORLD_LIMIT:e})"
                    ),
                ));
            }
        }
        objects.extend(converted);
    }
    Ok(objects)
}

/// The object of table `index` (a mesh: one object per part), its
/// transform applied to its geometry.
fn convert_object(
    ctx: &Ctx,
    index: usize,
    def: &Spanned<ObjectDef>,
    material: usize,
    materials: &mut Vec<Material>,
    warnings: &mut Vec<String>,
) -> Result<Vec<Object>, SceneError> {
    let o = def.get_ref();
    let field = |f: &str| format!("object[{index}].{f}");
    let err = |f: &str, message: String| ctx.error(def.span(), field(f), message);
    let require = |value: Option<[f32; 3]>, f: &str| -> Result<Vec3, SceneError> {
        let v = value.ok_or_else(|| {
            err(
                f,
                format!("required for type = \"{:?}\"", o.kind).to_lowercase(),
            )
        })?;
        finite3(v).map_err(|m| err(f, m))
    };

    // A field another type uses would be silently ignored: say so.
    let given = [
        ("center", o.center.is_some()),
        ("radius", o.radius.is_some()),
        ("point", o.point.is_some()),
        ("normal", o.normal.is_some()),
        ("size", o.size.is_some()),
        ("vertices", o.vertices.is_some()),
        ("file", o.file.is_some()),
        ("smooth", o.smooth),
        ("crease_angle", o.crease_angle.is_some()),
        ("mesh_lights", o.mesh_lights),
    ];
    let used: &[&str] = match o.kind {
        ObjectKind::Sphere => &["center", "radius"],
        ObjectKind::Plane => &["point", "normal", "size"],
        ObjectKind::Quad | ObjectKind::Polygon => &["vertices"],
        ObjectKind::Mesh => &["file", "smooth", "crease_angle", "mesh_lights"],
    };
    if let Some((unused, _)) = given.iter().find(|(f, given)| *given && !used.contains(f)) {
        return Err(err(
            unused,
            format!(
                "not used by type = \"{}\" (it takes {})",
                format!("{:?}", o.kind).to_lowercase(),
                used.join(", ")
            ),
        ));
    }
    let translate = world3(o.translate).map_err(|m| err("translate", m))?;
    let rotate = finite3(o.rotate).map_err(|m| err("rotate", m))?;
    if !(o.scale.is_finite() && o.scale > 0.0) {
        return Err(err("scale", format!("must be above 0, got {}", o.scale)));
    }
    let transform = Affine3A::from_scale_rotation_translation(
        Vec3::splat(o.scale),
        Quat::from_euler(
            EulerRot::ZYX,
            rotate.z.to_radians(),
            rotate.y.to_radians(),
            rotate.x.to_radians(),
        ),
        translate,
    );

    let shape = match o.kind {
        ObjectKind::Sphere => {
            let center = require(o.center, "center")?;
            let radius = o
                .radius
                .ok_or_else(|| err("radius", "required for type = \"sphere\"".into()))?;
            if !(radius.is_finite() && radius > 0.0) {
                return Err(err("radius", format!("must be above 0, got {radius}")));
            }
            Shape::Sphere(Sphere {
                center: transform.transform_point3(center),
                radius: radius * o.scale,
            })
        }
        ObjectKind::Plane => plane_shape(o, &transform, &require, &err)?,
        ObjectKind::Quad | ObjectKind::Polygon => {
            let vertices = o
                .vertices
                .as_ref()
                .ok_or_else(|| err("vertices", "required for quads and polygons".into()))?;
            if o.kind == ObjectKind::Quad && vertices.len() != 4 {
                return Err(err(
                    "vertices",
                    format!("a quad needs 4 vertices, got {}", vertices.len()),
                ));
            }
            let points = vertices
                .iter()
                .map(|&v| finite3(v).map(|p| transform.transform_point3(p)))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|m| err("vertices", m))?;
            polygon_mesh(points).map_err(|m| err("vertices", m))?
        }
        ObjectKind::Mesh => {
            let parts = MeshParts {
                index,
                material,
                transform,
            };
            return mesh_objects(ctx, def, parts, materials, warnings, &err);
        }
    };
    Ok(vec![Object {
        name: o.name.clone().unwrap_or_else(|| format!("object[{index}]")),
        shape,
        material,
        placement: Placement::World,
    }])
}

/// A table's required vector field, checked: the value given, or the
/// error naming the field.
type RequireVec3<'a> = dyn Fn(Option<[f32; 3]>, &str) -> Result<Vec3, SceneError> + 'a;

/// A plane object's shape: infinite, or with `size` a rectangle of two
/// triangles.
fn plane_shape(
    o: &ObjectDef,
    transform: &Affine3A,
    require: &RequireVec3,
    err: &dyn Fn(&str, String) -> SceneError,
) -> Result<Shape, SceneError> {
    let point = transform.transform_point3(require(o.point, "point")?);
    if !within_world(point) {
        return Err(err(
            "point",
            format!("{point} lies beyond the scene's extent (within ±{WORLD_LIMIT:e})"),
        ));
    }
    let normal = transform.transform_vector3(require(o.normal, "normal")?);
    if normal.length_squared() == 0.0 {
        return Err(err("normal", "must not be zero".into()));
    }
    let normal = normal.normalize();
    Ok(match o.size {
        None => Shape::Plane(Plane { point, normal }),
        Some(size) => {
            if !(size[0].is_finite() && size[1].is_finite() && size[0] > 0.0 && size[1] > 0.0) {
                return Err(err(
                    "size",
                    format!("both sides must be above 0, got {size:?}"),
                ));
            }
            let (u, v) = crate::geometry::plane_axes(normal);
            let (hu, hv) = (u * size[0] * 0.5, v * size[1] * 0.5);
            let corners = vec![
                point - hu - hv,
                point + hu - hv,
                point + hu + hv,
                point - hu + hv,
            ];
            polygon_mesh(corners).map_err(|m| err("size", m))?
        }
    })
}

/// Where a mesh table's parts go: its table index, the scene's material
/// for it and its transform.
struct MeshParts {
    index: usize,
    material: usize,
    transform: Affine3A,
}

/// A mesh table's model, one object per part, its transform applied.
fn mesh_objects(
    ctx: &Ctx,
    def: &Spanned<ObjectDef>,
    parts: MeshParts,
    materials: &mut Vec<Material>,
    warnings: &mut Vec<String>,
    err: &dyn Fn(&str, String) -> SceneError,
) -> Result<Vec<Object>, SceneError> {
    let o = def.get_ref();
    let MeshParts {
        index,
        material,
        transform,
    } = parts;
    let file = o
        .file
        .as_ref()
        .ok_or_else(|| err("file", "required for type = \"mesh\"".into()))?;
    let obj_path = ctx
        .file_of(def.span())
        .parent()
        .unwrap_or(Path::new("."))
        .join(file);
    // A model that is not there is the scene's mistake: name its
    // line. (Errors inside the model name the model's own line.)
    if obj_path.is_dir() {
        return Err(err(
            "file",
            format!("{}: a folder, not a model file", obj_path.display()),
        ));
    }
    if !obj_path.is_file() {
        return Err(err(
            "file",
            format!("{}: no such model file", obj_path.display()),
        ));
    }
    let crease_deg = mesh_crease_angle(o).map_err(|(f, m)| err(f, m))?;
    if o.mesh_lights && o.material.is_some() {
        return Err(err(
            "mesh_lights",
            "reads the glow (Ke) of the model's MTL materials, which `material` replaces: \
             give one or the other"
                .into(),
        ));
    }
    let mut loaded = crate::scene::load_obj_mesh_with(&obj_path, &mut ctx.textures.borrow_mut())?;
    warnings.extend(loaded.warnings(&obj_path));
    if loaded.triangle_count() == 0 {
        warnings.push(format!("{}: mesh has no triangles", obj_path.display()));
    }
    loaded
        .keep_glow(o.mesh_lights, &obj_path, warnings)
        .map_err(|m| err("mesh_lights", m))?;
    let name = o.name.clone().unwrap_or_else(|| format!("object[{index}]"));
    let mut objects = Vec::new();
    for (part_index, part) in loaded.parts.into_iter().enumerate() {
        let mut mesh = part.mesh;
        for p in &mut mesh.positions {
            *p = transform.transform_point3(*p);
        }
        for n in &mut mesh.normals {
            *n = crate::geometry::transform_normal(&transform, *n);
        }
        if mesh.normals.is_empty() {
            apply_crease_normals(&mut mesh, crease_deg);
        }
        // The scene's material wins; without one, the MTL's.
        let part_material = match (&o.material, part.material) {
            (None, Some(mtl)) => {
                materials.push(mtl);
                materials.len() - 1
            }
            _ => material,
        };
        objects.push(Object {
            name: if part_index == 0 {
                name.clone()
            } else {
                format!("{name} part {part_index}")
            },
            shape: Shape::Mesh(mesh),
            material: part_material,
            placement: Placement::World,
        });
    }
    Ok(objects)
}

/// The crease angle of a mesh's table, in degrees: `crease_angle`, 180 for
/// `smooth = true`, else the default. On error, the field and the message.
fn mesh_crease_angle(o: &ObjectDef) -> Result<f32, (&'static str, String)> {
    match (o.crease_angle, o.smooth) {
        (Some(_), true) => Err((
            "crease_angle",
            "give either crease_angle or smooth = true (a crease angle of 180), not both".into(),
        )),
        (Some(angle), false) if !(0.0..=180.0).contains(&angle) => Err((
            "crease_angle",
            format!("must be within 0..180 degrees, got {angle}"),
        )),
        (Some(angle), false) => Ok(angle),
        (None, true) => Ok(180.0),
        (None, false) => Ok(DEFAULT_CREASE_ANGLE_DEG),
    }
}

/// Fan-triangulates a planar convex polygon, rejecting degenerate ones.
fn polygon_mesh(points: Vec<Vec3>) -> Result<Shape, String> {
    if points.len() < 3 {
        return Err(format!(
            "a polygon needs at least 3 vertices, got {}",
            points.len()
        ));
    }
    let triangles: Vec<[u32; 3]> = (1..points.len() as u32 - 1)
        .map(|i| [0, i, i + 1])
        .collect();
    let mesh = TriangleMesh {
        positions: points,
        triangles,
        normals: Vec::new(),
        texcoords: Vec::new(),
        cutout: None,
    };
    let area: f32 = (0..mesh.triangles.len() as u32)
        .map(|t| {
            let [a, b, c] = mesh.vertices(t);
            (b - a).cross(c - a).length()
        })
        .sum();
    if area == 0.0 {
        return Err("polygon has zero area".into());
    }
    Ok(Shape::Mesh(mesh))
}

#[cfg(test)]
mod tests {
    use crate::scene::file::testing::{parse, CAMERA};

    #[test]
    fn fields_of_another_object_type_are_refused() {
        let err = parse(&format!(
            "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nvertices = [[0, 0, 0]]\n"
        ))
        .unwrap_err();
        assert_eq!(err.field.as_deref(), Some("object[0].vertices"), "{err}");
        assert!(
            err.message.contains("not used by type = \"sphere\""),
            "{err}"
        );
    }

    #[test]
    fn placement_scales_then_turns_about_x_y_z_about_the_origin_then_moves() {
        // What SCENE-FORMAT.md promises: (0, 1, 0) scaled by 2 is (0, 2, 0);
        // 90 degrees about x takes it to (0, 0, 2), about y then to
        // (2, 0, 0), about z then to (0, 2, 0); the move adds (0, 0, 10).
        let scene = parse(&format!(
            "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\n\
             scale = 2\nrotate = [90, 90, 90]\ntranslate = [0, 0, 10]\n"
        ))
        .unwrap();
        let crate::geometry::Shape::Sphere(sphere) = &scene.objects[0].shape else {
            panic!("not a sphere");
        };
        assert!(
            (sphere.center - glam::Vec3::new(0.0, 2.0, 10.0)).length() < 1e-5,
            "{}",
            sphere.center
        );
        // Uniform: the radius scales too.
        assert_eq!(sphere.radius, 2.0);
    }

    #[test]
    fn object_names_are_unique() {
        let ball = |name: &str| {
            format!("[[object]]\ntype = \"sphere\"\nname = \"{name}\"\ncenter = [0, 0, 0]\nradius = 1\n")
        };
        let err = parse(&format!("{CAMERA}{}{}", ball("ball"), ball("ball"))).unwrap_err();
        assert_eq!(err.line, Some(11), "{err}");
        assert_eq!(err.field.as_deref(), Some("object[1].name"), "{err}");
        assert!(err.message.contains("already names object[0]"), "{err}");
        parse(&format!("{CAMERA}{}{}", ball("ball"), ball("ball 2"))).unwrap();
    }

    #[test]
    fn unknown_material_names_line_and_field() {
        let err = parse(&format!(
            "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"nope\"\n"
        ))
        .unwrap_err();
        assert_eq!(err.line, Some(8));
        assert_eq!(err.field.as_deref(), Some("object[0].material"));
        assert!(err.message.contains("unknown material 'nope'"), "{err}");
    }

    #[test]
    fn an_unknown_material_lists_the_defined_ones() {
        let ball =
            "[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"nope\"\n";
        for (materials, defined) in [
            ("", "none"),
            ("[material.red]\n[material.blue]\n", "blue, red"),
        ] {
            let err = parse(&format!("{CAMERA}{materials}{ball}")).unwrap_err();
            assert_eq!(
                err.message,
                format!("unknown material 'nope' (defined: {defined})"),
                "{err}"
            );
        }
    }
}

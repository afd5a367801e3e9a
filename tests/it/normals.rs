//! Shading normals as the model's author made them: flat faces for a box
//! without normals, smooth only below the crease angle, the file's own
//! normals kept, and shadow rays of smooth triangles leaving from the
//! curved surface the normals describe (the shadow terminator).

use std::path::Path;

use glam::Vec3;
use retrace::geometry::Shape;
use retrace::ray::{Hit, Ray};
use retrace::scene::{load_scene, parse_scene_str, Scene, SceneOverrides};
use retrace::shade::Surface;

/// A unit cube as quads, no normals.
const CUBE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                    f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 1 5 8 4\nf 2 3 7 6\n";

/// An octahedron with its vertex normals pointing out from the centre, as
/// a low-poly sphere's file gives them.
const OCTAHEDRON: &str = "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n\
                          vn 1 0 0\nvn -1 0 0\nvn 0 1 0\nvn 0 -1 0\nvn 0 0 1\nvn 0 0 -1\n\
                          f 1//1 3//3 5//5\nf 3//3 2//2 5//5\nf 2//2 4//4 5//5\nf 4//4 1//1 5//5\n\
                          f 3//3 1//1 6//6\nf 2//2 3//3 6//6\nf 4//4 2//2 6//6\nf 1//1 4//4 6//6\n";

fn meshes(scene: &Scene) -> Vec<&retrace::geometry::TriangleMesh> {
    scene
        .objects
        .iter()
        .filter_map(|o| match &o.shape {
            Shape::Mesh(m) => Some(m),
            _ => None,
        })
        .collect()
}

fn mesh_scene(dir: &Path, model: &str, object_fields: &str) -> Result<Scene, String> {
    let text = format!(
        "[camera]\nposition = [3, 2, 4]\nlook_at = [0, 0, 0]\nfov = 40\n\
         [[light]]\nposition = [5, 5, 5]\n\
         [[object]]\ntype = \"mesh\"\nfile = \"{model}\"\n{object_fields}"
    );
    parse_scene_str(&text, &dir.join("scene.toml"), &SceneOverrides::default())
        .map_err(|e| e.to_string())
}

#[test]
fn a_box_without_normals_has_flat_faces() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("box.obj"), CUBE).unwrap();
    // The bare model, as `retrace render box.obj` frames it.
    let scene = load_scene(&dir.path().join("box.obj"), &SceneOverrides::default()).unwrap();
    let mesh = meshes(&scene)[0];
    assert_eq!(mesh.triangles.len(), 12);
    // No edge is smooth: shaded by each triangle's own normal.
    assert!(mesh.normals.is_empty());
    assert_eq!(mesh.positions.len(), 8);
}

#[test]
fn the_crease_angle_is_set_per_object() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("box.obj"), CUBE).unwrap();
    // 0 degrees: flat shading, no vertex normals.
    let scene = mesh_scene(dir.path(), "box.obj", "crease_angle = 0\n").unwrap();
    assert!(meshes(&scene)[0].normals.is_empty());
    // Above the cube's 90 degrees: one smooth normal per corner vertex.
    let scene = mesh_scene(dir.path(), "box.obj", "crease_angle = 91\n").unwrap();
    let mesh = meshes(&scene)[0];
    assert_eq!(mesh.positions.len(), 8);
    let corner = mesh.normals[6];
    assert!((corner - Vec3::ONE.normalize()).length() < 1e-6, "{corner}");
    // `smooth = true` is a crease angle of 180.
    let smooth = mesh_scene(dir.path(), "box.obj", "smooth = true\n").unwrap();
    assert_eq!(meshes(&smooth)[0].normals, mesh.normals);
    // The default (30 degrees): flat faces, as the bare model.
    let scene = mesh_scene(dir.path(), "box.obj", "").unwrap();
    assert!(meshes(&scene)[0].normals.is_empty());
    for (fields, needle) in [
        (
            "crease_angle = 200\n",
            "must be within 0..180 degrees, got 200",
        ),
        (
            "crease_angle = -1\n",
            "must be within 0..180 degrees, got -1",
        ),
        ("crease_angle = 20\nsmooth = true\n", "not both"),
    ] {
        let err = mesh_scene(dir.path(), "box.obj", fields).unwrap_err();
        assert!(err.contains("scene.toml:"), "{err}");
        assert!(err.contains("object[0].crease_angle"), "{err}");
        assert!(err.contains(needle), "{fields}: {err}");
    }
}

#[test]
fn normals_from_the_file_are_kept_as_given() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("octa.obj"), OCTAHEDRON).unwrap();
    for fields in ["", "crease_angle = 0\n", "crease_angle = 180\n"] {
        let scene = mesh_scene(dir.path(), "octa.obj", fields).unwrap();
        let mesh = meshes(&scene)[0];
        assert_eq!(mesh.positions.len(), 6, "{fields}");
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            // Each vertex's own direction from the centre, not a face's.
            assert_eq!(*n, *p, "{fields}");
        }
    }
}

/// The surface a ray from above the centre of `mesh`'s triangle 0 meets,
/// in `scene` (whose object 0 that mesh is).
fn surface_of_first_triangle(scene: &Scene) -> Surface {
    let mesh = meshes(scene)[0];
    let [a, b, c] = mesh.vertices(0);
    let (u, v) = (0.3, 0.3);
    let point = a * (1.0 - u - v) + b * u + c * v;
    let normal = (b - a).cross(c - a).normalize();
    let origin = point + normal * 2.0;
    let ray = Ray::new(origin, -normal);
    let hit = Hit {
        t: 2.0,
        object: 0,
        prim: 0,
        u,
        v,
    };
    Surface::from_hit(scene, &ray, &hit)
}

#[test]
fn shadow_rays_leave_curved_triangles_from_the_surface_their_normals_describe() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("octa.obj"), OCTAHEDRON).unwrap();
    // Without its normals, the octahedron is flat: shadow rays start where
    // every other ray does, bit for bit.
    let flat_file = OCTAHEDRON
        .lines()
        .filter(|l| !l.starts_with("vn"))
        .map(|l| l.replace("//1", "").replace("//2", "").replace("//3", ""))
        .map(|l| l.replace("//4", "").replace("//5", "").replace("//6", ""))
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(dir.path().join("flat.obj"), flat_file).unwrap();
    let flat = mesh_scene(dir.path(), "flat.obj", "").unwrap();
    assert!(meshes(&flat)[0].normals.is_empty());
    let s = surface_of_first_triangle(&flat);
    assert_eq!(s.shadow_point, s.spawn_point);

    // With them, it stands for a sphere of radius 1: the shadow point is
    // lifted off the facet (at the centre of a face, 0.577 from the
    // centre) toward the sphere, outward, and stays inside it.
    let curved = mesh_scene(dir.path(), "octa.obj", "").unwrap();
    let s = surface_of_first_triangle(&curved);
    let lift = (s.shadow_point - s.point).dot(s.geometric_normal);
    assert!(lift > 0.05, "lift {lift}");
    let radius = s.shadow_point.length();
    assert!(
        radius > s.point.length() && radius < 1.0,
        "{radius} from {}",
        s.point.length()
    );
    // Other rays still leave from the facet.
    assert!((s.spawn_point - s.point).length() < 1e-5);
}

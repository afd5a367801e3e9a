use super::*;

fn check(text: &str) -> Result<(), SceneError> {
    check_obj_text(Path::new("m.obj"), text)
}

#[test]
fn reports_the_line_of_bad_numbers_and_indices() {
    let err = check("v 0 0 0\nv 1 0 0\nv 0 x 0\n").unwrap_err();
    assert_eq!(err.line, Some(3));
    let err = check("v 0 0 0\nv 1 nan 0\n").unwrap_err();
    assert_eq!(err.line, Some(2));
    assert!(err.message.contains("not finite"));
    let err = check("v 0 0 0\nv 1 0 0\nv 0 0 -3e13\n").unwrap_err();
    assert_eq!(err.line, Some(3));
    assert!(err.message.contains("beyond the scene's extent"), "{err}");
    // Texture coordinates and normals are not places.
    check("v 0 0 0\nvn 0 2e13 0\n").unwrap();
    // Texture coordinate and normal indices, each against its own count.
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n";
    check(&format!("{tri}f 1/1/1 2/1/1 3//1\n")).unwrap();
    for (face, needle) in [
        ("f 1/2 2/1 3/1", "texture coordinate index 2"),
        ("f 1//1 2//1 3//-2", "normal index -2"),
        ("f 1/a 2 3", "'a' is not a texture coordinate index"),
    ] {
        let err = check(&format!("{tri}{face}\n")).unwrap_err();
        assert_eq!(err.line, Some(6), "{err}");
        assert!(err.message.contains(needle), "{face}: {err}");
    }
    let err = check("v 0 0 0\nv 1 0 0 0\n").unwrap_err();
    assert_eq!(err.line, Some(2), "{err}");
    assert!(err.message.contains("weight"), "{err}");
    let err = check("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err();
    assert_eq!(err.line, Some(4));
    assert!(err.message.contains("out of range"));
    let err = check("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n").unwrap_err();
    assert_eq!(err.line, Some(4));
    let err = check("v 0 0 inf\n").unwrap_err();
    assert_eq!(err.field.as_deref(), Some("v"));
    // A nameless `usemtl` (Blender's) is left to `faces_only`.
    check("v 0 0 0\nusemtl  \n").unwrap();
    assert!(check("# c\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nf 1/1/1 2//2 3\n").is_ok());
}

#[test]
fn texture_coordinates_are_carried_per_vertex_and_nan_ones_refused() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("quad.obj");
    let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                vt 0 0\nvt 2 0\nvt 2 2\nvt 0 2\nf 1/1 2/2 3/3 4/4\n";
    std::fs::write(&obj, quad).unwrap();
    let mesh = &load_obj_mesh(&obj).unwrap().parts[0].mesh;
    assert_eq!(mesh.texcoords.len(), mesh.positions.len());
    // The image's top row is v = 1 in OBJ, row 0 in the texture.
    for (p, t) in mesh.positions.iter().zip(&mesh.texcoords) {
        assert_eq!(*t, Vec2::new(p.x * 2.0, 1.0 - p.y * 2.0));
    }
    // Interpolated at a hit's barycentrics.
    let [a, b, c] = mesh.triangles[0].map(|i| mesh.texcoords[i as usize]);
    let at = mesh.texcoord(0, 0.25, 0.5).unwrap();
    assert!((at - (a * 0.25 + b * 0.25 + c * 0.5)).length() < 1e-6);
    for bad in ["nan", "inf"] {
        let text = quad.replace("vt 2 2", &format!("vt 2 {bad}"));
        std::fs::write(&obj, text).unwrap();
        let err = load_obj_mesh(&obj).unwrap_err();
        assert_eq!(
            (err.line, err.field.as_deref()),
            (Some(7), Some("vt")),
            "{err}"
        );
        assert!(err.message.contains("not finite"), "{err}");
    }
}

#[test]
fn a_material_value_that_is_not_a_number_falls_back_to_the_default() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("m.obj");
    std::fs::write(
        &obj,
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl shiny\nf 1 2 3\n",
    )
    .unwrap();
    let mtl = |ns: &str| format!("newmtl shiny\nKd 0.5 0.5 0.5\nNs {ns}\n");
    std::fs::write(dir.path().join("m.mtl"), mtl("nan")).unwrap();
    let mesh = load_obj_mesh(&obj).unwrap();
    assert!(mesh.parts[0].material.is_none());
    let warnings = mesh.warnings(&obj).join("\n");
    assert!(
        warnings.contains("m.mtl:3: Ns: 'nan' is not finite; material 'shiny' uses the default"),
        "{warnings}"
    );
    std::fs::write(dir.path().join("m.mtl"), mtl("20")).unwrap();
    let mesh = load_obj_mesh(&obj).unwrap();
    assert_eq!(mesh.parts[0].material.as_ref().unwrap().shininess, 20.0);
}

/// Every model the project ships (all of convex faces) is cut into the
/// triangles, and vertices, tobj's fan gave: their pictures do not change.
#[test]
fn shipped_models_are_cut_as_tobj_fanned_them() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut models = vec![scenes.join("bunny.obj"), scenes.join("prism/prism.obj")];
    for name in ["floor", "sphere", "crate"] {
        models.push(scenes.join(format!("textured/{name}.obj")));
    }
    for path in models {
        let load = |triangulate| {
            let options = tobj::LoadOptions {
                triangulate,
                single_index: true,
                ..Default::default()
            };
            tobj::load_obj(&path, &options).unwrap().0
        };
        let (fanned, faces) = (load(true), load(false));
        let text = std::fs::read_to_string(&path).unwrap();
        let mut cutter = FaceCutter::new(&text);
        assert_eq!(fanned.len(), faces.len());
        for (fanned, faces) in fanned.iter().zip(&faces) {
            let (fanned, faces) = (&fanned.mesh, &faces.mesh);
            assert_eq!(fanned.positions, faces.positions, "{}", path.display());
            let positions: Vec<Vec3> = faces
                .positions
                .chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect();
            let cut = cutter.cut(&positions, &faces.indices, &faces.face_arities);
            let fan: Vec<[u32; 3]> = fanned
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect();
            assert_eq!(cut, fan, "{}", path.display());
        }
        assert!(cutter.warnings(&path).is_empty());
    }
}

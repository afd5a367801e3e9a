//! OBJ/MTL models through tobj, after a line-by-line check of our own so that
//! a broken file is reported with its line (tobj reports no positions), and
//! the scene made around a bare `.obj` given on the command line.
//!
//! Promises: a model loads or fails whole, naming the file and line of the
//! first problem; what can be rendered around is a warning naming its file
//! and line instead: bytes that are not UTF-8 (read with U+FFFD in their
//! place; UTF-16 with a byte-order mark is read as such), point and line
//! elements (not surfaces: left out), vertex colours (ignored), a material
//! library entry that does not parse (that material falls back to the
//! default), an `Ns` out of range, a `usemtl` naming no material or none,
//! a face whose edges cross (filled as a fan; concave faces are cut in
//! their plane, in `triangulate`).
//! tobj only ever sees text that has passed these checks.

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec2, Vec3};

use super::file::{SceneOverrides, UpAxis};
use super::{Checker, Material, Scene, SceneError};
use crate::camera::{yaw_pitch_toward, Camera, Projection};
use crate::geometry::normals::{apply_crease_normals, DEFAULT_CREASE_ANGLE_DEG};
use crate::geometry::Light;
use crate::geometry::{Aabb, Object, Placement, Plane, Shape, TriangleMesh, WORLD_LIMIT};
use crate::texture::load::TextureCache;
use crate::texture::TextureEncoding;
use triangulate::FaceCutter;

mod mtl;
mod triangulate;

use mtl::{
    checked_mtl_text, load_mtl_texture, material_from_mtl, mtl_bump_map, shadowed_height_map,
};

/// The most triangle lights one model may bring: each is sampled at every
/// shaded point, so a finely cut glowing surface would multiply the
/// shadow rays of every pixel.
pub const MAX_MESH_LIGHT_TRIANGLES: usize = 64;

/// One material's worth of an OBJ file.
#[derive(Clone, Debug)]
pub struct ObjPart {
    pub mesh: TriangleMesh,
    /// From the MTL file, when the model names one that loaded.
    pub material: Option<Material>,
}

#[derive(Clone, Debug)]
pub struct ObjMesh {
    pub parts: Vec<ObjPart>,
    /// Zero-area triangles (repeated vertices, collinear points) left out.
    pub dropped_degenerate: usize,
    /// Why the material library the model names did not load, if it did
    /// not: the model then renders with the scene's material.
    pub material_problem: Option<String>,
    /// Other problems loading went past, each naming its file and line.
    pub problems: Vec<String>,
}

impl ObjMesh {
    /// What a user should hear about loading `path` (this model).
    pub fn warnings(&self, path: &Path) -> Vec<String> {
        let mut warnings = Vec::new();
        if self.dropped_degenerate > 0 {
            warnings.push(format!(
                "{}: dropped {} degenerate triangle(s) (zero area or repeated vertices)",
                path.display(),
                self.dropped_degenerate
            ));
        }
        if let Some(problem) = &self.material_problem {
            warnings.push(format!(
                "{}: material library not loaded ({problem}); the model uses the default material",
                path.display()
            ));
        }
        warnings.extend(self.problems.iter().cloned());
        warnings
    }

    /// Keeps the glow of the MTL materials where mesh lights are
    /// `wanted` (refusing more glowing triangles than
    /// [`MAX_MESH_LIGHT_TRIANGLES`]), and clears it, with a warning, where
    /// they are not: a model's `Ke` changes nothing unless asked for.
    pub fn keep_glow(
        &mut self,
        wanted: bool,
        obj_path: &Path,
        warnings: &mut Vec<String>,
    ) -> Result<(), String> {
        let glowing = |part: &ObjPart| {
            part.material
                .as_ref()
                .is_some_and(|m| m.emission != Vec3::ZERO)
        };
        let triangles: usize = self
            .parts
            .iter()
            .filter(|p| glowing(p))
            .map(|p| p.mesh.triangles.len())
            .sum();
        let mut names: Vec<String> = self
            .parts
            .iter()
            .filter(|p| glowing(p))
            .filter_map(|p| p.material.as_ref().map(|m| format!("'{}'", m.name)))
            .collect();
        names.dedup();
        if !wanted {
            if triangles > 0 {
                warnings.push(format!(
                    "{}: material {} gives off light (Ke), which is left out: give the \
                     model's object mesh_lights = true in a scene file for its faces to glow \
                     and light the scene",
                    obj_path.display(),
                    names.join(", ")
                ));
            }
            for part in &mut self.parts {
                if let Some(m) = &mut part.material {
                    m.emission = Vec3::ZERO;
                }
            }
            return Ok(());
        }
        if triangles == 0 {
            warnings.push(format!(
                "{}: mesh_lights = true, but no material of the model gives off light (Ke)",
                obj_path.display()
            ));
        }
        if triangles > MAX_MESH_LIGHT_TRIANGLES {
            return Err(format!(
                "{}: {triangles} glowing triangles (material {}), and at most \
                 {MAX_MESH_LIGHT_TRIANGLES} can be lights, each sampled at every shaded point: \
                 light a large glowing surface with a sphere, rectangle or disc [[light]]",
                obj_path.display(),
                names.join(", ")
            ));
        }
        Ok(())
    }

    pub fn triangle_count(&self) -> usize {
        self.parts.iter().map(|p| p.mesh.triangles.len()).sum()
    }

    pub fn bounds(&self) -> Aabb {
        self.parts
            .iter()
            .fold(Aabb::EMPTY, |b, p| b.union(p.mesh.bounds()))
    }
}

/// Checks what tobj would accept silently or report without a line: numbers
/// that do not parse, NaN/Inf coordinates, a vertex weight of 0, and face
/// indices (of positions, texture coordinates and normals) out of range.
fn check_obj_text(path: &Path, text: &str) -> Result<(), SceneError> {
    let keyword_anywhere = |wanted: &str| {
        text.lines()
            .any(|line| line.split_whitespace().next() == Some(wanted))
    };
    let defined_anywhere = [keyword_anywhere("vt"), keyword_anywhere("vn")];
    // Positions, texture coordinates, normals defined so far.
    let (mut vertex_count, mut texcoord_count, mut normal_count): (i64, i64, i64) = (0, 0, 0);
    for (number, line) in text.lines().enumerate() {
        let line_no = number + 1;
        let fail = |field: &str, message: String| {
            Err(SceneError::new(path, message).at_line(line_no).field(field))
        };
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "v" | "vn" | "vt" => {
                let wanted = if keyword == "vt" { 2 } else { 3 };
                let values: Vec<&str> = words.collect();
                if values.len() < wanted {
                    return fail(
                        keyword,
                        format!("expected {wanted} numbers, got {}", values.len()),
                    );
                }
                // `v x y z`, `v x y z w` or `v x y z r g b`: tobj refuses
                // other counts without a line.
                if keyword == "v" && !matches!(values.len(), 3 | 4 | 6) {
                    return fail(
                        "v",
                        format!(
                            "expected 3 numbers (x y z), 4 (x y z w) or 6 (x y z r g b), \
                             got {}",
                            values.len()
                        ),
                    );
                }
                for word in &values {
                    match word.parse::<f32>() {
                        Ok(x) if x.is_finite() && (keyword != "v" || x.abs() <= WORLD_LIMIT) => {}
                        Ok(x) if x.is_finite() => {
                            return fail(
                                keyword,
                                format!(
                                    "coordinate '{word}' lies beyond the scene's extent \
                                     (within ±{WORLD_LIMIT:e} of the origin)"
                                ),
                            )
                        }
                        Ok(_) => {
                            return fail(keyword, format!("coordinate '{word}' is not finite"))
                        }
                        Err(_) => return fail(keyword, format!("'{word}' is not a number")),
                    }
                }
                // `v x y z w`: tobj divides by w.
                if keyword == "v" && values.len() == 4 && values[3].parse::<f32>() == Ok(0.0) {
                    return fail("v", "a vertex weight (w) of 0 puts it at infinity".into());
                }
                match keyword {
                    "v" => vertex_count += 1,
                    "vt" => texcoord_count += 1,
                    _ => normal_count += 1,
                }
            }
            "f" => {
                let refs: Vec<&str> = words.collect();
                if refs.len() < 3 {
                    return fail(
                        "f",
                        format!("a face needs at least 3 vertices, got {}", refs.len()),
                    );
                }
                for r in refs {
                    // v, v/vt, v//vn or v/vt/vn; only the position is needed.
                    if r.split('/').count() > 3 {
                        return fail("f", format!("'{r}' is not v, v/vt, v//vn or v/vt/vn"));
                    }
                    let kinds = [
                        ("vertex", vertex_count),
                        ("texture coordinate", texcoord_count),
                        ("normal", normal_count),
                    ];
                    for (position, (index, (what, count))) in r.split('/').zip(kinds).enumerate() {
                        if position > 0 && index.is_empty() {
                            continue;
                        }
                        let Ok(index) = index.parse::<i64>() else {
                            return fail("f", format!("'{r}': '{index}' is not a {what} index"));
                        };
                        // tobj ignores texture coordinates and normals a
                        // file never defines.
                        if position > 0 && !defined_anywhere[position - 1] {
                            continue;
                        }
                        let resolved = if index < 0 { count + index + 1 } else { index };
                        if index == 0 || resolved < 1 || resolved > count {
                            return fail(
                                "f",
                                format!("{what} index {index} is out of range (1..={count} defined so far)"),
                            );
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// The name a `usemtl` line selects: everything after the keyword, trimmed
/// (tobj is handed `usemtl NAME` lines rewritten so that it reads the same).
fn usemtl_name(line: &str) -> &str {
    line.trim_start()
        .strip_prefix("usemtl")
        .map_or("", str::trim)
}

/// A nameless `usemtl` (Blender's) for tobj, which refuses the file for one:
/// a name that always selects the default material.
const NAMELESS_USEMTL: &str = "\u{0}retrace: nameless usemtl";

/// `bytes` as text: UTF-16 after its byte-order mark (FF FE, FE FF), else
/// UTF-8 (after its mark, if any). Bytes that are not UTF-8 (or UTF-16)
/// become U+FFFD, with a warning naming the first line that has any (so a
/// Latin-1 material name still matches itself between the OBJ and the MTL).
fn decode_lossily(path: &Path, bytes: &[u8], problems: &mut Vec<String>) -> String {
    let (bytes, unit): (_, fn([u8; 2]) -> u16) = match bytes {
        [0xFF, 0xFE, rest @ ..] => (rest, u16::from_le_bytes),
        [0xFE, 0xFF, rest @ ..] => (rest, u16::from_be_bytes),
        [0xEF, 0xBB, 0xBF, rest @ ..] | rest => return decode_utf8(path, rest, problems),
    };
    // An odd last byte reads as an unpaired surrogate.
    let units = bytes.chunks(2).map(|pair| match *pair {
        [a, b] => unit([a, b]),
        _ => 0xDC00,
    });
    let (mut text, mut line, mut first_bad) = (String::with_capacity(bytes.len() / 2), 1, None);
    for c in char::decode_utf16(units) {
        let c = c.unwrap_or_else(|_| {
            first_bad.get_or_insert(line);
            '\u{FFFD}'
        });
        line += usize::from(c == '\n');
        text.push(c);
    }
    if let Some(line) = first_bad {
        problems.push(format!(
            "{}:{line}: not valid UTF-16: read with U+FFFD in place of the units that are not",
            path.display()
        ));
    }
    text
}

fn decode_utf8(path: &Path, bytes: &[u8], problems: &mut Vec<String>) -> String {
    match std::str::from_utf8(bytes) {
        Ok(text) => text.to_string(),
        Err(err) => {
            let line = bytes[..err.valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count()
                + 1;
            problems.push(format!(
                "{}:{line}: not valid UTF-8 (Latin-1?): read with U+FFFD in place of the bytes \
                 that are not; save the file as UTF-8 to keep them",
                path.display()
            ));
            String::from_utf8_lossy(bytes).into_owned()
        }
    }
}

/// The OBJ's text for tobj with point (`p`) and line (`l`) elements left out
/// (they are not surfaces, and tobj would turn a `p` or `l` of three or more
/// vertices into a face), vertex colours dropped and `usemtl` lines as
/// [`usemtl_name`] reads them. Warns at the first of each; fails if no face
/// remains.
fn faces_only(path: &Path, text: &str, problems: &mut Vec<String>) -> Result<String, SceneError> {
    let mut kept = String::with_capacity(text.len());
    let mut left_out = 0;
    let mut first_left_out = None;
    let mut faces = 0;
    let (mut first_coloured, mut nameless, mut first_nameless) = (None, 0, None);
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some(keyword @ ("p" | "l")) => {
                left_out += 1;
                first_left_out.get_or_insert((number + 1, keyword));
            }
            // Vertex colours are not used (a mesh has no colour attribute:
            // colour is the material's), and tobj refuses a model in
            // which only some vertices have one.
            Some("v") if words.clone().count() == 6 => {
                first_coloured.get_or_insert(number + 1);
                kept.push('v');
                for word in words.take(3) {
                    kept.push(' ');
                    kept.push_str(word);
                }
            }
            Some("usemtl") => {
                let mut name = usemtl_name(line);
                if name.is_empty() {
                    nameless += 1;
                    first_nameless.get_or_insert(number + 1);
                    name = NAMELESS_USEMTL;
                }
                kept.push_str(&format!("usemtl {name}"));
            }
            keyword => {
                faces += usize::from(keyword == Some("f"));
                kept.push_str(line);
            }
        }
        kept.push('\n');
    }
    if let Some(line) = first_coloured {
        problems.push(format!(
            "{}:{line}: v: vertex colours (v x y z r g b) are not supported: ignored; \
             the faces take their materials' colours",
            path.display()
        ));
    }
    if let Some(line) = first_nameless {
        problems.push(format!(
            "{}:{line}: usemtl: no material name ({nameless} in the file): \
             the faces after it use the default material",
            path.display()
        ));
    }
    if let Some((line, keyword)) = first_left_out {
        problems.push(format!(
            "{}:{line}: {keyword}: point (p) and line (l) elements are not surfaces: \
             left out ({left_out} in the file)",
            path.display()
        ));
    }
    if faces == 0 {
        let only = if left_out > 0 {
            ", only points and lines"
        } else {
            ""
        };
        return Err(SceneError::new(
            path,
            format!("the model has no faces (f elements){only}: no triangles to render"),
        ));
    }
    Ok(kept)
}

/// Loads an OBJ (and its MTL, when present) as triangle meshes, one part per
/// material, dropping degenerate triangles; textures within the default
/// memory limit.
pub fn load_obj_mesh(path: &Path) -> Result<ObjMesh, SceneError> {
    load_obj_mesh_with(path, &mut TextureCache::default())
}

/// [`load_obj_mesh`], its textures loaded through `textures` (shared with
/// the rest of a scene, and bounded by its limit).
pub fn load_obj_mesh_with(path: &Path, textures: &mut TextureCache) -> Result<ObjMesh, SceneError> {
    let bytes = std::fs::read(path)
        .map_err(|err| SceneError::new(path, format!("cannot read OBJ file: {err}")))?;
    let mut problems = Vec::new();
    let text = decode_lossily(path, &bytes, &mut problems);
    check_obj_text(path, &text)?;
    let faces = faces_only(path, &text, &mut problems)?;
    // Faces as the file gives them: tobj would fan them, filling concave
    // ones past their edges.
    let options = tobj::LoadOptions {
        triangulate: false,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    // tobj calls back for each `mtllib`; what the libraries say goes here.
    let mtl_problems = RefCell::new(Vec::new());
    let broken_materials = RefCell::new(HashSet::new());
    let texture_lines = RefCell::new(HashMap::new());
    let folder = path.parent().unwrap_or(Path::new(""));
    let load_mtl = |name: &Path| -> tobj::MTLLoadResult {
        let mtl_path: PathBuf = folder.join(name);
        let bytes = std::fs::read(&mtl_path).map_err(|_| tobj::LoadError::OpenFileFailed)?;
        let (text, broken) = checked_mtl_text(
            &mtl_path,
            &bytes,
            &mut mtl_problems.borrow_mut(),
            &mut texture_lines.borrow_mut(),
        );
        broken_materials.borrow_mut().extend(broken);
        tobj::load_mtl_buf(&mut text.as_bytes())
    };
    let (models, materials) = tobj::load_obj_buf(&mut faces.as_bytes(), &options, load_mtl)
        .map_err(|err| SceneError::new(path, format!("cannot parse OBJ: {err}")))?;
    problems.extend(mtl_problems.into_inner());
    let broken_materials = broken_materials.into_inner();
    let texture_lines = texture_lines.into_inner();
    // A missing MTL is not fatal: the model renders with the scene's
    // material instead (and the user is told).
    let (materials, material_problem) = match materials {
        Ok(materials) => (materials, None),
        Err(err) => {
            let named: Vec<&str> = text
                .lines()
                .filter_map(|line| line.trim().strip_prefix("mtllib "))
                .map(str::trim)
                .collect();
            (Vec::new(), Some(format!("{}: {err}", named.join(" "))))
        }
    };
    if material_problem.is_none() {
        warn_undefined_materials(path, &text, &materials, &mut problems);
    }

    // Each material once (its texture loads once), by index.
    let mut converted: Vec<Option<Material>> = Vec::with_capacity(materials.len());
    for m in &materials {
        if broken_materials.contains(&m.name) || m.name == NAMELESS_USEMTL {
            converted.push(None);
            continue;
        }
        problems.extend(shadowed_height_map(m, &texture_lines));
        let mut map = |arguments: Option<&String>, keyword: &str, encoding| {
            let at = texture_lines.get(&(m.name.clone(), keyword.to_string()));
            match (arguments, at) {
                (Some(arguments), Some(at)) => {
                    load_mtl_texture(&m.name, arguments, at, encoding, textures, &mut problems)
                }
                _ => Ok(None),
            }
        };
        let diffuse_map = map(m.diffuse_texture.as_ref(), "map_Kd", TextureEncoding::Srgb)?;
        let specular_map = map(m.specular_texture.as_ref(), "map_Ks", TextureEncoding::Srgb)?;
        let bump_map = mtl_bump_map(m, &mut map)?;
        let mut material = material_from_mtl(m, diffuse_map, specular_map);
        material.bump_map = bump_map;
        material.cutout = map(m.dissolve_texture.as_ref(), "map_d", TextureEncoding::Srgb)?
            .map(|map| crate::scene::coverage_of(&map));
        converted.push(Some(material));
    }

    let mut dropped_degenerate = 0;
    let mut untextured: HashSet<String> = HashSet::new();
    let mut parts: Vec<ObjPart> = Vec::new();
    // tobj keeps the file's order of faces, model after model.
    let mut faces = FaceCutter::new(&text);
    for model in models {
        let m = &model.mesh;
        let mesh = model_mesh(m, &mut faces, &mut dropped_degenerate);
        let texcoords_missing = mesh.texcoords.is_empty();
        let material = m
            .material_id
            .and_then(|id| converted.get(id).cloned().flatten());
        if let Some(textured) = material.as_ref().filter(|m| m.needs_texcoords()) {
            if texcoords_missing && untextured.insert(textured.name.clone()) {
                problems.push(format!(
                    "{}: faces with material '{}' have no texture coordinates (vt): its \
                     textures are not shown on them",
                    path.display(),
                    textured.name
                ));
            }
        }
        // Parts with the same material merge: fewer objects, same picture.
        // Not a part with normals and one without: the file's normals stay
        // as given, and only the other gets normals of its own.
        let same_kind = |p: &ObjPart| {
            p.material == material && p.mesh.normals.is_empty() == mesh.normals.is_empty()
        };
        match parts.iter_mut().find(|p| same_kind(p)) {
            Some(part) => append_mesh(&mut part.mesh, mesh),
            None => parts.push(ObjPart { mesh, material }),
        }
    }
    problems.extend(faces.warnings(path));
    Ok(ObjMesh {
        parts,
        dropped_degenerate,
        material_problem,
        problems,
    })
}

/// Warns of each `usemtl` (once a name) naming a material no library
/// defines: its faces use the default material.
fn warn_undefined_materials(
    path: &Path,
    text: &str,
    materials: &[tobj::Material],
    problems: &mut Vec<String>,
) {
    let defined: HashSet<&str> = materials.iter().map(|m| m.name.as_str()).collect();
    let mut told = HashSet::new();
    for (number, line) in text.lines().enumerate() {
        if line.split_whitespace().next() != Some("usemtl") {
            continue;
        }
        let name = usemtl_name(line);
        if !name.is_empty() && !defined.contains(name) && told.insert(name) {
            problems.push(format!(
                "{}:{}: usemtl: material '{name}' is not defined in any material library; \
                 its faces use the default material",
                path.display(),
                number + 1
            ));
        }
    }
}

/// One model of tobj's as a triangle mesh: its faces cut by `faces`,
/// zero-area triangles dropped (counted in `dropped_degenerate`), normals
/// and texture coordinates kept only where every vertex has them.
fn model_mesh(
    m: &tobj::Mesh,
    faces: &mut FaceCutter,
    dropped_degenerate: &mut usize,
) -> TriangleMesh {
    let positions: Vec<Vec3> = m
        .positions
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect();
    let mut normals: Vec<Vec3> = m
        .normals
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect();
    if normals.len() != positions.len() {
        normals.clear();
    }
    // OBJ's v runs up the image; textures are stored top row first.
    let mut texcoords: Vec<Vec2> = m
        .texcoords
        .chunks_exact(2)
        .map(|c| Vec2::new(c[0], 1.0 - c[1]))
        .collect();
    if texcoords.len() != positions.len() {
        texcoords.clear();
    }
    let cut = faces.cut(&positions, &m.indices, &m.face_arities);
    let mut triangles = Vec::with_capacity(cut.len());
    for t in cut {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        if (b - a).cross(c - a).length_squared() > 0.0 {
            triangles.push(t);
        } else {
            *dropped_degenerate += 1;
        }
    }
    TriangleMesh {
        positions,
        triangles,
        normals,
        texcoords,
        cutout: None,
    }
}

fn append_mesh(into: &mut TriangleMesh, mesh: TriangleMesh) {
    let base = into.positions.len() as u32;
    let keep_normals = !into.normals.is_empty() && !mesh.normals.is_empty()
        || into.positions.is_empty() && !mesh.normals.is_empty();
    // Faces without texture coordinates beside faces with them (under one
    // material) read the texture at (0, 0), as other OBJ readers do.
    if !into.texcoords.is_empty() || !mesh.texcoords.is_empty() {
        into.texcoords.resize(into.positions.len(), Vec2::ZERO);
        into.texcoords.extend(mesh.texcoords);
        into.texcoords
            .resize(into.positions.len() + mesh.positions.len(), Vec2::ZERO);
    }
    into.positions.extend(mesh.positions);
    into.triangles
        .extend(mesh.triangles.into_iter().map(|t| t.map(|i| i + base)));
    if keep_normals {
        into.normals.extend(mesh.normals);
    } else {
        into.normals.clear();
    }
}

/// A scene for a bare model: the model (where the file has no normals,
/// smooth only across edges below the default crease angle), a checkered ground plane under it, a key light, and a camera
/// that frames its bounds.
/// A Z-up model turned Y-up: -90 degrees about x, `(x, y, z)` to
/// `(x, z, -y)`, as a scene file's `rotate = [-90, 0, 0]` turns it.
fn stand_up_z(mesh: &mut TriangleMesh) {
    let turn = |v: &mut Vec3| *v = Vec3::new(v.x, v.z, -v.y);
    mesh.positions.iter_mut().for_each(turn);
    mesh.normals.iter_mut().for_each(turn);
}

pub(super) fn scene_around_obj(
    path: &Path,
    overrides: &SceneOverrides,
) -> Result<Scene, SceneError> {
    let mut loaded = load_obj_mesh_with(path, &mut overrides.texture_cache())?;
    if overrides.up == Some(UpAxis::Z) {
        for part in &mut loaded.parts {
            stand_up_z(&mut part.mesh);
        }
    }
    let mut warnings = loaded.warnings(path);
    loaded
        .keep_glow(false, path, &mut warnings)
        .map_err(|m| SceneError::new(path, m))?;
    let bounds = loaded.bounds();
    if loaded.triangle_count() == 0 || !bounds.is_finite() {
        return Err(SceneError::new(
            path,
            "the model has no triangles to render",
        ));
    }
    let center = bounds.center();
    let radius = (bounds.extent().length() * 0.5).max(f32::MIN_POSITIVE);

    let mut materials = vec![
        Material {
            specular: Vec3::splat(0.25),
            shininess: 48.0,
            ..Material::matte("model", Vec3::new(0.75, 0.72, 0.68))
        },
        Material {
            checker: Some(Checker {
                colors: [Vec3::splat(0.85), Vec3::splat(0.35)],
                scale: radius * 0.25,
            }),
            reflectivity: 0.15,
            ..Material::matte("ground", Vec3::splat(0.7))
        },
    ];
    let mut objects = Vec::new();
    for (i, part) in loaded.parts.into_iter().enumerate() {
        let material = match part.material {
            Some(m) => {
                materials.push(m);
                materials.len() - 1
            }
            None => 0,
        };
        let mut mesh = part.mesh;
        if mesh.normals.is_empty() {
            apply_crease_normals(&mut mesh, DEFAULT_CREASE_ANGLE_DEG);
        }
        objects.push(Object {
            name: format!("model part {i}"),
            shape: Shape::Mesh(mesh),
            material,
            placement: Placement::World,
        });
    }
    objects.push(Object {
        name: "ground".into(),
        shape: Shape::Plane(Plane {
            point: Vec3::new(center.x, bounds.min.y, center.z),
            normal: Vec3::Y,
        }),
        material: 1,
        placement: Placement::World,
    });

    let width = overrides.width.unwrap_or(640);
    let height = overrides.height.unwrap_or(480);
    let projection = overrides.projection.unwrap_or(Projection::Perspective);
    let fov = overrides.fov.unwrap_or(45.0).to_radians();
    // Fit the bounding sphere into the narrower of the two fields of view.
    let aspect = f64::from(height) / f64::from(width);
    let narrow = match projection {
        Projection::Perspective => 2.0 * ((0.5 * fov).tan() * aspect).atan(),
        _ => fov * aspect,
    }
    .clamp(1e-6, std::f64::consts::PI * 0.9);
    let distance = f64::from(radius) / (0.5 * narrow).sin() * 1.05;
    let view_dir = DVec3::new(0.45, 0.35, 1.0).normalize();
    let target = center.as_dvec3();
    let position = target + view_dir * distance;
    let (yaw, pitch) = yaw_pitch_toward(position, target);
    let camera = Camera {
        projection,
        position,
        yaw,
        pitch,
        fov,
        width,
        height,
    };
    camera
        .validate()
        .map_err(|err| SceneError::new(path, err.to_string()).field("camera"))?;
    let key = center + Vec3::new(-1.5, 3.0, 2.0) * radius;
    crate::scene::cut_out_meshes(&mut objects, &materials);
    Ok(Scene {
        camera,
        lens: None,
        camera_motion: None,
        objects,
        materials,
        lights: vec![Light::point(key, Vec3::splat(1.0))],
        background: Vec3::new(0.08, 0.09, 0.12),
        ambient: Vec3::splat(0.12),
        max_depth: 3,
        samples: overrides.samples()?.unwrap_or_default(),
        light_samples: overrides
            .light_samples()?
            .unwrap_or(crate::scene::DEFAULT_LIGHT_SAMPLES),
        warnings,
        animation: None,
        viewports: Vec::new(),
    })
}

#[cfg(test)]
mod tests;

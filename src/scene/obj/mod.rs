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
use super::{BumpMap, Checker, Material, Scene, SceneError};
use crate::camera::{yaw_pitch_toward, Camera, Projection};
use crate::geometry::normals::{apply_crease_normals, DEFAULT_CREASE_ANGLE_DEG};
use crate::geometry::Light;
use crate::geometry::{Aabb, Object, Placement, Plane, Shape, TriangleMesh, WORLD_LIMIT};
use crate::texture::load::{TextureCache, TextureProblem};
use crate::texture::path::{mtl_file_name, resolve, shown};
use crate::texture::{TextureEncoding, TextureRef};
use triangulate::FaceCutter;

mod triangulate;

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

/// The material library at `path` as tobj should see it: text, with every
/// line tobj would refuse (or read as a value that is not a number) blanked
/// out and warned about; and the names of the materials those lines belong
/// to, which fall back to the default material.
fn checked_mtl_text(
    path: &Path,
    bytes: &[u8],
    problems: &mut Vec<String>,
    texture_lines: &mut HashMap<(String, String), TextureLine>,
) -> (String, HashSet<String>) {
    let text = decode_lossily(path, bytes, problems);
    let mut kept = String::with_capacity(text.len());
    let mut broken = HashSet::new();
    // The material the lines belong to; `None` before the first `newmtl`
    // and after a nameless one (whose lines are all left out).
    let mut current: Option<String> = None;
    let mut nameless = false;
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let keyword = words.next().unwrap_or("");
        let values: Vec<&str> = words.collect();
        let numbers = |wanted: usize| -> Option<String> {
            if values.len() < wanted {
                return Some(format!("expected {wanted} number(s), got {}", values.len()));
            }
            values[..wanted]
                .iter()
                .find_map(|word| match word.parse::<f32>() {
                    Ok(x) if x.is_finite() => None,
                    Ok(_) => Some(format!("'{word}' is not finite")),
                    Err(_) => Some(format!("'{word}' is not a number")),
                })
        };
        let problem = match keyword {
            "newmtl" => {
                let name = line.trim()[6..].trim();
                nameless = name.is_empty();
                current = (!nameless).then(|| name.to_string());
                nameless.then(|| "expected a material name".to_string())
            }
            _ if nameless => {
                kept.push('\n');
                continue;
            }
            "Ka" | "Kd" | "Ks" | "Ke" => numbers(3),
            "Ns" | "Pr" => numbers(1),
            "Ni" | "d" | "Tr" | "Tf" => {
                numbers(1).or_else(|| super::glass::mtl_value_problem(keyword, &values))
            }
            "illum" => match values.first().map(|w| w.parse::<u8>()) {
                Some(Ok(_)) => None,
                Some(Err(_)) => Some(format!(
                    "'{}' is not an illumination model (0-10)",
                    values[0]
                )),
                None => Some("expected an illumination model (0-10)".into()),
            },
            "map_Ka" | "map_Kd" | "map_Ks" | "map_Bump" | "map_bump" | "map_Ns" | "map_ns"
            | "map_NS" | "bump" | "map_d" | "norm"
                if values.is_empty() =>
            {
                Some("expected a texture file name".into())
            }
            "map_Bump" | "map_bump" | "bump" => bump_scale(&values.join(" ")).err(),
            _ => None,
        };
        match problem {
            Some(problem) => {
                let whose = match &current {
                    Some(name) => {
                        broken.insert(name.clone());
                        format!("material '{name}' uses the default material")
                    }
                    None if nameless => "its lines are left out".to_string(),
                    None => "the line is left out".to_string(),
                };
                problems.push(format!(
                    "{}:{}: {keyword}: {problem}; {whose}",
                    path.display(),
                    number + 1
                ));
            }
            None => {
                if let (Some(name), "Ns", Some(why)) = (&current, keyword, ns_problem(&values)) {
                    problems.push(format!(
                        "{}:{}: Ns {}: material '{name}': {why}",
                        path.display(),
                        number + 1,
                        values[0]
                    ));
                }
                if let (Some(name), "map_Kd" | "map_Ks" | "map_d" | "norm") = (&current, keyword) {
                    texture_lines.insert(
                        (name.clone(), keyword.to_string()),
                        TextureLine {
                            mtl: path.to_path_buf(),
                            line: number + 1,
                            keyword: keyword.to_string(),
                        },
                    );
                }
                // tobj keeps the last of the three spellings of a height map.
                if let (Some(name), "map_Bump" | "map_bump" | "bump") = (&current, keyword) {
                    texture_lines.insert(
                        (name.clone(), "bump".to_string()),
                        TextureLine {
                            mtl: path.to_path_buf(),
                            line: number + 1,
                            keyword: keyword.to_string(),
                        },
                    );
                }
                kept.push_str(line)
            }
        }
        kept.push('\n');
    }
    (kept, broken)
}

/// The largest `Ns` used as written: beyond it the highlight is narrower
/// than any pixel.
const MAX_NS: f32 = 10_000.0;

/// How an MTL `Ns` (`values`, a finite number) is read when not as the
/// Phong exponent it gives; `None` for 0 < Ns <= [`MAX_NS`].
fn ns_problem(values: &[&str]) -> Option<&'static str> {
    match values.first()?.parse::<f32>().ok()? {
        ns if ns <= 0.0 => Some(
            "an exponent of 0 or below lights the whole lit side at full Ks ((R.V)^Ns = 1), \
             not a highlight: read as no highlight",
        ),
        ns if ns > MAX_NS => Some("an exponent above 10000 is clamped to 10000"),
        _ => None,
    }
}

/// The `-bm` (bump multiplier) of a height map's `arguments` (what
/// follows `map_Bump`): 1 without one; an error when its value is not a
/// finite number.
fn bump_scale(arguments: &str) -> Result<f32, String> {
    let (_, options) = mtl_file_name(arguments);
    let Some(option) = options.iter().find(|o| o.starts_with("-bm")) else {
        return Ok(1.0);
    };
    let value = option["-bm".len()..].trim();
    match value.parse::<f32>() {
        Ok(scale) if scale.is_finite() => Ok(scale),
        Ok(_) => Err(format!("-bm '{value}' is not finite")),
        Err(_) if value.is_empty() => Err("-bm needs a number".into()),
        Err(_) => Err(format!("-bm '{value}' is not a number")),
    }
}

/// Where a material's texture map (`map_Kd`, `map_Ks`) was written.
#[derive(Clone, Debug)]
struct TextureLine {
    mtl: PathBuf,
    line: usize,
    keyword: String,
}

/// The texture of a material's `map_Kd`, `map_Ks`, `map_d`, height map
/// or `norm` (`arguments`, written at `at`), its RGB read as `encoding`:
/// `None`, with a warning naming the MTL file and line, when the file is
/// missing or not a readable image (the material keeps its `Kd`, or `Ks`,
/// or is drawn whole, or keeps its smooth normals); an error past the
/// texture memory limit.
fn load_mtl_texture(
    material: &str,
    arguments: &str,
    at: &TextureLine,
    encoding: TextureEncoding,
    textures: &mut TextureCache,
    problems: &mut Vec<String>,
) -> Result<Option<TextureRef>, SceneError> {
    let here = format!("{}:{}: {}", at.mtl.display(), at.line, at.keyword);
    let fallback = match at.keyword.as_str() {
        "map_Kd" => format!("material '{material}' uses its Kd"),
        "map_Ks" => format!("material '{material}' uses its Ks"),
        "map_d" => format!("material '{material}' is drawn whole"),
        _ => format!("material '{material}' is shaded without it"),
    };
    let (name, mut options) = mtl_file_name(arguments);
    // A height map's `-bm` is read (by `bump_scale`); nothing else's is.
    if matches!(at.keyword.as_str(), "map_Bump" | "map_bump" | "bump") {
        options.retain(|option| !option.starts_with("-bm"));
    }
    if !options.is_empty() {
        problems.push(format!(
            "{here}: options {} are not supported: left out",
            options.join(" ")
        ));
    }
    let folder = at.mtl.parent().unwrap_or(Path::new(""));
    let Some(found) = resolve(folder, &name) else {
        problems.push(format!(
            "{here}: no file '{name}' (looked in {}); {fallback}",
            shown(folder)
        ));
        return Ok(None);
    };
    if found.case_differs {
        problems.push(format!(
            "{here}: '{name}' found as {} (the case differs)",
            found.path.display()
        ));
    }
    match textures.load_as(&found.path, encoding) {
        Ok(texture) => Ok(Some(texture)),
        Err(TextureProblem::Skipped(why)) => {
            problems.push(format!("{here}: {why}; {fallback}"));
            Ok(None)
        }
        Err(TextureProblem::OverBudget(why)) => Err(SceneError::new(&at.mtl, why)
            .at_line(at.line)
            .field(at.keyword.clone())),
    }
}

/// The material of an MTL entry (whose numbers [`checked_mtl_text`] has
/// made sure are finite), with its diffuse and specular textures.
fn material_from_mtl(
    m: &tobj::Material,
    diffuse_map: Option<TextureRef>,
    specular_map: Option<TextureRef>,
) -> Material {
    let rgb =
        |c: Option<[f32; 3]>, default: f32| c.map(Vec3::from_array).unwrap_or(Vec3::splat(default));
    let specular = rgb(m.specular, 0.0);
    // `Ns 0` (3ds Max and others write it for no highlight) or below makes
    // the Phong term (R.V)^Ns 1 at every lit point: Ks over the whole lit
    // side, a wash-out. Read as no highlight, as meant (Blender's importer
    // reads it as fully rough); an exponent of 1 would still spread Ks over
    // the lit side. The mirror of illum 3, 5 and 7 keeps its Ks.
    let highlight = m.shininess.map_or(true, |ns| ns > 0.0);
    // A specular map with no `Ks` shows the image's own colours.
    let mapped_specular = match (&specular_map, m.specular) {
        _ if !highlight => Vec3::ZERO,
        (Some(_), None) => Vec3::ONE,
        _ => specular,
    };
    // illum 3, 5 and 7 are the MTL modes with ray-traced reflection.
    let reflective = matches!(m.illumination_model, Some(3 | 5 | 7));
    Material {
        name: m.name.clone(),
        diffuse: rgb(m.diffuse, 0.7).clamp(Vec3::ZERO, Vec3::ONE),
        checker: None,
        specular: mapped_specular.clamp(Vec3::ZERO, Vec3::ONE),
        shininess: m.shininess.unwrap_or(32.0).clamp(0.0, MAX_NS),
        reflectivity: if reflective {
            specular.max_element().clamp(0.0, 1.0)
        } else {
            0.0
        },
        roughness: mtl_roughness(m),
        diffuse_map,
        specular_map: specular_map.filter(|_| highlight),
        bump_map: None,
        glass: super::glass::glass_from_mtl(m),
        cutout: None,
        emission: rgb(m.emissive, 0.0).max(Vec3::ZERO),
    }
}

/// The PBR extension's `Pr` (roughness, 0 to 1), where the MTL gives it;
/// else 0: `Ns` already shapes the Phong highlight, and a reflective
/// `illum` with `Ks` is how exporters write a mirror, so without `Pr` a
/// reflection stays mirror-sharp.
fn mtl_roughness(m: &tobj::Material) -> f32 {
    m.unknown_param
        .get("Pr")
        .and_then(|v| v.split_whitespace().next()?.parse::<f32>().ok())
        .filter(|r| r.is_finite())
        .map_or(0.0, |r| r.clamp(0.0, 1.0))
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

/// The relief of MTL material `m`: its `norm` normal map, else its height
/// map (`map_Bump`, `bump`) with its `-bm`; `map` loads a texture line's
/// file.
fn mtl_bump_map(
    m: &tobj::Material,
    map: &mut impl FnMut(
        Option<&String>,
        &str,
        TextureEncoding,
    ) -> Result<Option<TextureRef>, SceneError>,
) -> Result<Option<BumpMap>, SceneError> {
    if let Some(normal) = m.unknown_param.get("norm") {
        let loaded = map(Some(normal), "norm", TextureEncoding::Linear)?;
        return Ok(loaded.map(|map| BumpMap::Normal { map }));
    }
    let loaded = map(m.normal_texture.as_ref(), "bump", TextureEncoding::Linear)?;
    Ok(loaded.map(|map| BumpMap::Height {
        map,
        // Checked when the line was read.
        scale: m
            .normal_texture
            .as_deref()
            .map_or(1.0, |a| bump_scale(a).unwrap_or(1.0)),
    }))
}

/// The warning for MTL material `m` when it has a normal map (`norm`) and
/// a height map both: it shows the normal map.
fn shadowed_height_map(
    m: &tobj::Material,
    texture_lines: &HashMap<(String, String), TextureLine>,
) -> Option<String> {
    m.unknown_param.get("norm")?;
    m.normal_texture.as_ref()?;
    let at = texture_lines.get(&(m.name.clone(), "bump".to_string()))?;
    Some(format!(
        "{}:{}: {}: material '{}' has a normal map (norm) too, which it shows: \
         its height map is left out",
        at.mtl.display(),
        at.line,
        at.keyword,
        m.name
    ))
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

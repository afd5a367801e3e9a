//! MTL material libraries: their text checked line by line before tobj
//! reads it (what tobj would take silently or report without a line), and
//! each entry turned into a [`Material`] with its texture, relief and
//! cut-out maps.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::Vec3;

use super::decode_lossily;
use crate::scene::{BumpMap, Material, SceneError};
use crate::texture::load::{TextureCache, TextureProblem};
use crate::texture::path::{mtl_file_name, resolve, shown};
use crate::texture::{TextureEncoding, TextureRef};

/// The material library at `path` as tobj should see it: text, with every
/// line tobj would refuse (or read as a value that is not a number) blanked
/// out and warned about; and the names of the materials those lines belong
/// to, which fall back to the default material.
pub(super) fn checked_mtl_text(
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
                numbers(1).or_else(|| crate::scene::glass::mtl_value_problem(keyword, &values))
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
pub(super) const MAX_NS: f32 = 10_000.0;

/// How an MTL `Ns` (`values`, a finite number) is read when not as the
/// Phong exponent it gives; `None` for 0 < Ns <= [`MAX_NS`].
pub(super) fn ns_problem(values: &[&str]) -> Option<&'static str> {
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
pub(super) fn bump_scale(arguments: &str) -> Result<f32, String> {
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
pub(super) struct TextureLine {
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
pub(super) fn load_mtl_texture(
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
pub(super) fn material_from_mtl(
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
        glass: crate::scene::glass::glass_from_mtl(m),
        cutout: None,
        emission: rgb(m.emissive, 0.0).max(Vec3::ZERO),
    }
}

/// The PBR extension's `Pr` (roughness, 0 to 1), where the MTL gives it;
/// else 0: `Ns` already shapes the Phong highlight, and a reflective
/// `illum` with `Ks` is how exporters write a mirror, so without `Pr` a
/// reflection stays mirror-sharp.
pub(super) fn mtl_roughness(m: &tobj::Material) -> f32 {
    m.unknown_param
        .get("Pr")
        .and_then(|v| v.split_whitespace().next()?.parse::<f32>().ok())
        .filter(|r| r.is_finite())
        .map_or(0.0, |r| r.clamp(0.0, 1.0))
}

/// The relief of MTL material `m`: its `norm` normal map, else its height
/// map (`map_Bump`, `bump`) with its `-bm`; `map` loads a texture line's
/// file.
pub(super) fn mtl_bump_map(
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
pub(super) fn shadowed_height_map(
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

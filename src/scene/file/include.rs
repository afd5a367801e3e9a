//! `include = "other.toml"`: splicing included scene files into one text,
//! and mapping each line of that text back to the file and line it was
//! written on.
//!
//! Promises: the spliced text parses as the scene the user meant (the
//! including file's tables replace the included ones of the same name, its
//! arrays of tables add to them), and [`Source::locate`] names the file and
//! line a user can open, whichever file a value came from.

use std::path::Path;

use crate::scene::{SceneError, BUILTIN_SCENES};

/// Where a scene file's includes are read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Files {
    /// The file system, relative to the including file.
    Disk,
    /// The scene files built into the binary ([`BUILTIN_SCENES`]), by
    /// file name.
    BuiltIn,
}

impl Files {
    fn read(self, path: &Path) -> std::io::Result<String> {
        match self {
            Files::Disk => std::fs::read_to_string(path),
            Files::BuiltIn => {
                let name = path.file_name().and_then(|n| n.to_str());
                BUILTIN_SCENES
                    .iter()
                    .find(|(file, _)| Some(*file) == name)
                    .map(|(_, text)| text.to_string())
                    .ok_or_else(|| {
                        std::io::Error::new(
                            std::io::ErrorKind::NotFound,
                            "not one of the scene files built into retrace",
                        )
                    })
            }
        }
    }
}

/// Line (1-based) of a byte offset.
pub(super) fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

/// How deep `include` may nest (a cycle hits this).
const MAX_INCLUDE_DEPTH: usize = 8;

/// A scene's text with its includes spliced in before it, and where each
/// line came from, so errors name the file and line the user wrote.
pub(super) struct Source {
    pub(super) text: String,
    /// Runs of lines, in order: (file, first line in `text`, number of
    /// lines, the file's line number of the first).
    pieces: Vec<(std::path::PathBuf, usize, usize, usize)>,
}

impl Source {
    /// The file and line within it of a line of the spliced text.
    pub(super) fn locate(&self, line: usize) -> (&Path, usize) {
        for (file, first, count, first_line) in &self.pieces {
            if line >= *first && line < first + count {
                return (file, line - first + first_line);
            }
        }
        let (file, first, _, first_line) = self.pieces.last().expect("a source has a piece");
        (file, line.saturating_sub(*first) + first_line)
    }

    /// Appends `text`, lines `first_line..` of `file`.
    fn push(&mut self, file: &Path, text: &str, first_line: usize) {
        let first = line_of(&self.text, self.text.len());
        self.text.push_str(text);
        self.pieces
            .push((file.to_path_buf(), first, text.lines().count(), first_line));
    }

    /// Appends another source, its lines mapped as they were.
    fn append(&mut self, other: Source) {
        let offset = line_of(&self.text, self.text.len()) - 1;
        self.text.push_str(&other.text);
        self.pieces.extend(
            other
                .pieces
                .into_iter()
                .map(|(file, first, count, line)| (file, first + offset, count, line)),
        );
    }
}

/// Splices `include = "other.toml"` lines (top-level, before any table):
/// this file's own top-level keys come first, then the included scene, then
/// this file's tables, which add to it (or replace its tables of the same
/// name). The keys stay top-level: after the included text they would
/// fall into its last table.
pub(super) fn assemble(
    text: &str,
    path: &Path,
    files: Files,
    depth: usize,
) -> Result<Source, SceneError> {
    let mut included = Source {
        text: String::new(),
        pieces: Vec::new(),
    };
    let (mut preamble, mut tables) = (String::new(), String::with_capacity(text.len()));
    let mut preamble_lines = 0;
    let mut in_tables = false;
    for (number, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        in_tables |= trimmed.starts_with('[');
        let own = if in_tables {
            &mut tables
        } else {
            preamble_lines += 1;
            &mut preamble
        };
        let include = (!in_tables)
            .then(|| trimmed.strip_prefix("include"))
            .flatten()
            .and_then(|rest| rest.trim_start().strip_prefix('='))
            .map(str::trim);
        let Some(value) = include else {
            own.push_str(line);
            own.push('\n');
            continue;
        };
        let located = |message: String| {
            SceneError::new(path, message)
                .at_line(number + 1)
                .field("include")
        };
        let name: String = toml::from_str::<toml::Value>(&format!("v = {value}"))
            .ok()
            .and_then(|v| v.get("v").and_then(|v| v.as_str()).map(str::to_string))
            .ok_or_else(|| located(format!("expected a quoted file name, got {value}")))?;
        if depth >= MAX_INCLUDE_DEPTH {
            return Err(located(format!(
                "includes nest deeper than {MAX_INCLUDE_DEPTH} (a cycle?)"
            )));
        }
        let other = path.parent().unwrap_or(Path::new(".")).join(&name);
        let other_text = files.read(&other).map_err(|err| {
            located(format!(
                "cannot read included file {}: {err}",
                other.display()
            ))
        })?;
        included.append(assemble(&other_text, &other, files, depth + 1)?);
        // Keeps this file's line numbers.
        own.push_str("# (include)\n");
    }
    // The tables this file defines again, by header or by a top-level key
    // (`render = { width = 32 }`), replace the included ones.
    let mut overridden: Vec<String> = tables
        .lines()
        .filter_map(table_header)
        .filter(|(_, array)| !array)
        .map(|(name, _)| name)
        .collect();
    overridden.extend(preamble.lines().filter_map(top_level_key));
    included.text = without_overridden(&included.text, &overridden);
    let mut source = Source {
        text: String::new(),
        pieces: Vec::new(),
    };
    source.push(path, &preamble, 1);
    source.append(included);
    source.push(path, &tables, preamble_lines + 1);
    Ok(source)
}

/// The table name of a TOML header line (`[a.b]` or `[[a.b]]`), and
/// whether it is an array of tables; None for other lines (including rows
/// of a multi-line array value, whose first character is not a letter).
fn table_header(line: &str) -> Option<(String, bool)> {
    let line = line.split('#').next()?.trim();
    let (inner, array) = match line.strip_prefix("[[") {
        Some(rest) => (rest.strip_suffix("]]")?, true),
        None => (line.strip_prefix('[')?.strip_suffix(']')?, false),
    };
    let name: String = inner
        .split('.')
        .map(str::trim)
        .collect::<Vec<_>>()
        .join(".");
    let starts_like_a_key = name
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '"' || c == '_');
    starts_like_a_key.then_some((name, array))
}

/// The key a top-level `key = value` line sets (a bare key; not a dotted
/// one, which sets part of a table).
fn top_level_key(line: &str) -> Option<String> {
    let (key, _) = line.split_once('=')?;
    let key = key.trim();
    let bare = !key.is_empty()
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    (bare && key != "include").then(|| key.to_string())
}

/// `included` with every table named in `overridden` taken out, with its
/// sub-tables, so the including file overrides it. Removed lines become
/// comments: line numbers stay where they were.
fn without_overridden(included: &str, overridden: &[String]) -> String {
    if overridden.is_empty() {
        return included.to_string();
    }
    let mut out = String::with_capacity(included.len());
    let mut skipping = false;
    for line in included.lines() {
        if let Some((name, _)) = table_header(line) {
            skipping = overridden
                .iter()
                .any(|o| name == *o || name.starts_with(&format!("{o}.")));
        }
        out.push_str(if skipping { "# (overridden)" } else { line });
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use crate::camera::Projection;
    use crate::scene::{load_scene, SceneOverrides};

    #[test]
    fn an_including_file_overrides_whole_tables() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("base.toml"),
            "[render]\nwidth = 320\nheight = 200\n[camera]\nposition = [0, 1, 5]\nfov = 60\n[material.red]\ndiffuse = [1, 0, 0]\nvertices = [\n  [0, 0, 0],\n]\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"red\"\n",
        )
        .unwrap();
        let top = dir.path().join("top.toml");
        let text = "include = \"base.toml\"\n[camera]\nprojection = \"equal-angle\"\nposition = [0, 2, 5]\nfov = 90\n[material.red]\ndiffuse = [0.5, 0, 0]\n[[object]]\ntype = \"sphere\"\ncenter = [3, 0, 0]\nradius = 1\nmaterial = \"red\"\n";
        std::fs::write(&top, text).unwrap();
        let scene = load_scene(&top, &SceneOverrides::default()).unwrap();
        assert_eq!(scene.camera.projection, Projection::EqualAngle);
        assert_eq!(scene.camera.position.y, 2.0);
        // Untouched tables stay; arrays of tables add up.
        assert_eq!(scene.camera.width, 320);
        assert_eq!(scene.objects.len(), 2);
        let red = scene.materials.iter().find(|m| m.name == "red").unwrap();
        assert_eq!(red.diffuse.x, 0.5);
        // Errors still name the file and line they come from.
        std::fs::write(&top, text.replace("fov = 90", "fov = 400")).unwrap();
        let err = load_scene(&top, &SceneOverrides::default()).unwrap_err();
        assert_eq!(
            (err.file.clone(), err.line),
            (top.clone(), Some(5)),
            "{err}"
        );
    }

    #[test]
    fn paths_in_a_file_are_relative_to_its_own_folder() {
        // top.toml includes sub/base.toml, which includes deeper/lights.toml
        // and names the model m.obj: both beside base.toml, not top.toml.
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("sub");
        std::fs::create_dir_all(sub.join("deeper")).unwrap();
        std::fs::write(
            sub.join("base.toml"),
            "include = \"deeper/lights.toml\"\n[camera]\nposition = [0, 1, 5]\nfov = 60\n\
             [[object]]\ntype = \"mesh\"\nfile = \"m.obj\"\n",
        )
        .unwrap();
        std::fs::write(
            sub.join("deeper/lights.toml"),
            "[[light]]\nposition = [0, 5, 0]\n",
        )
        .unwrap();
        std::fs::write(sub.join("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let top = dir.path().join("top.toml");
        std::fs::write(&top, "include = \"sub/base.toml\"\n").unwrap();
        let scene = load_scene(&top, &SceneOverrides::default()).unwrap();
        assert_eq!((scene.lights.len(), scene.triangle_count()), (1, 1));
    }

    #[test]
    fn top_level_keys_after_an_include_stay_top_level() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("base.toml"),
            "[render]\nwidth = 320\nheight = 200\n[camera]\nposition = [0, 1, 5]\nfov = 60\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n",
        )
        .unwrap();
        let top = dir.path().join("top.toml");
        // An inline table replaces the included [render] as a [render]
        // header would; it used to fall into the base's last table.
        let text = "include = \"base.toml\"\nrender = { width = 32, height = 24 }\n\n[[light]]\nposition = [0, 5, 5]\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = -1\n";
        std::fs::write(&top, text).unwrap();
        let err = load_scene(&top, &SceneOverrides::default()).unwrap_err();
        // Lines after the top-level keys still map to this file.
        assert_eq!(
            (err.file.clone(), err.line),
            (top.clone(), Some(9)),
            "{err}"
        );
        assert_eq!(err.field.as_deref(), Some("object[1].radius"), "{err}");
        std::fs::write(&top, text.replace("radius = -1", "radius = 1")).unwrap();
        let scene = load_scene(&top, &SceneOverrides::default()).unwrap();
        assert_eq!((scene.camera.width, scene.camera.height), (32, 24));
        assert_eq!((scene.objects.len(), scene.lights.len()), (2, 1));
    }
}

//! `include = "other.toml"`: splicing included scene files into one text,
//! and mapping each line of that text back to the file and line it was
//! written on.
//!
//! Promises: the spliced text parses as the scene the user meant (the
//! including file's tables replace the included ones of the same name, its
//! arrays of tables add to them), and [`Source::locate`] names the file and
//! line a user can open, whichever file a value came from. A scene holds
//! each file once (a cycle or a repeat is refused at its `include` line)
//! and at most [`MAX_SCENE_TEXT`] bytes of text in all, so what splicing
//! reads and keeps is bounded by the files themselves.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::scene::{SceneError, BUILTIN_SCENES};

/// Most text a scene may hold, with everything it includes. toml keeps
/// every value with its text and spacing, up to some 150 bytes for each
/// byte of a file (a megabyte of dotted keys took 150 MB), so this bounds
/// what a scene file makes the loader hold to some 600 MB. Geometry that
/// would need more belongs in OBJ files.
pub const MAX_SCENE_TEXT: usize = 4 << 20;

/// Most dotted parts a key may have. A scene's deepest is three
/// (`animation.camera.frame`); toml builds a nested table for each part, some
/// 200 bytes a byte of a key like `[a.a.a...]`, past what the text limit
/// allows for.
const MAX_KEY_PARTS: usize = 32;

/// The dotted parts of the key `line` names, a table header's or a key's
/// before its `=`; 0 for other lines (values, array rows).
fn key_parts(line: &str) -> usize {
    let trimmed = line.trim();
    let key = match trimmed.strip_prefix('[') {
        Some(header) => header
            .trim_start_matches('[')
            .split(']')
            .next()
            .unwrap_or(""),
        None => trimmed.split('=').next().unwrap_or(""),
    };
    let key_like = key.chars().all(|c| {
        c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '"' | '\'' | ' ' | '\t')
    });
    if key_like {
        key.matches('.').count() + 1
    } else {
        0
    }
}

/// Why a scene file could not be read as text.
pub(crate) enum ReadError {
    Io(std::io::Error),
    /// Longer than the bytes the scene had left of [`MAX_SCENE_TEXT`].
    TooLong,
    /// This line holds a byte that is not UTF-8.
    NotText {
        line: usize,
    },
}

impl ReadError {
    /// The error of the scene file `path` that could not be read.
    pub(crate) fn of_scene(self, path: &Path) -> SceneError {
        match self {
            ReadError::Io(err) => SceneError::new(path, format!("cannot read scene file: {err}")),
            ReadError::TooLong => SceneError::new(path, too_long()),
            ReadError::NotText { line } => SceneError::new(path, NOT_TEXT).at_line(line),
        }
    }
}

fn too_long() -> String {
    format!(
        "the scene, with its includes, holds more than {} MiB of text \
         (put large geometry in OBJ files)",
        MAX_SCENE_TEXT >> 20
    )
}

const NOT_TEXT: &str = "not text: this line holds a byte that is not UTF-8";

/// The text of the file `path`, if it holds at most `limit` bytes (a
/// special file such as `/dev/zero` is cut off there, not read forever).
pub(crate) fn read_text(path: &Path, limit: usize) -> Result<String, ReadError> {
    use std::io::Read;
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|file| file.take(limit as u64 + 1).read_to_end(&mut bytes))
        .map_err(ReadError::Io)?;
    if bytes.len() > limit {
        return Err(ReadError::TooLong);
    }
    String::from_utf8(bytes).map_err(|err| {
        let valid = &err.as_bytes()[..err.utf8_error().valid_up_to()];
        ReadError::NotText {
            line: valid.iter().filter(|&&b| b == b'\n').count() + 1,
        }
    })
}

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
    /// The text of `path`, at most `limit` bytes.
    fn read(self, path: &Path, limit: usize) -> Result<String, ReadError> {
        match self {
            Files::Disk => read_text(path, limit),
            Files::BuiltIn => {
                let name = path.file_name().and_then(|n| n.to_str());
                let text = BUILTIN_SCENES
                    .iter()
                    .find(|(file, _)| Some(*file) == name)
                    .map(|(_, text)| text.to_string())
                    .ok_or_else(|| {
                        ReadError::Io(std::io::Error::new(
                            std::io::ErrorKind::NotFound,
                            "not one of the scene files built into retrace",
                        ))
                    })?;
                if text.len() > limit {
                    return Err(ReadError::TooLong);
                }
                Ok(text)
            }
        }
    }

    /// What names the file `path` whatever the path says: two paths to one
    /// file on disk (`a.toml`, `./a.toml`, a link) are one file.
    fn identity(self, path: &Path) -> PathBuf {
        match self {
            Files::Disk => std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()),
            Files::BuiltIn => path.file_name().map_or_else(PathBuf::new, PathBuf::from),
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

/// How deep `include` may nest.
const MAX_INCLUDE_DEPTH: usize = 8;

/// A scene's text with its includes spliced in before it, and where each
/// line came from, so errors name the file and line the user wrote.
pub(super) struct Source {
    pub(super) text: String,
    /// Lines `text` holds, as [`line_of`] counts them at its end, less one.
    lines: usize,
    /// Runs of lines, in order: (file, first line in `text`, number of
    /// lines, the file's line number of the first).
    pieces: Vec<(PathBuf, usize, usize, usize)>,
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

    fn new() -> Source {
        Source {
            text: String::new(),
            lines: 0,
            pieces: Vec::new(),
        }
    }

    /// Appends `text`, lines `first_line..` of `file`.
    fn push(&mut self, file: &Path, text: &str, first_line: usize) {
        let first = self.lines + 1;
        self.text.push_str(text);
        self.lines += text.bytes().filter(|&b| b == b'\n').count();
        self.pieces
            .push((file.to_path_buf(), first, text.lines().count(), first_line));
    }

    /// Appends another source, its lines mapped as they were.
    fn append(&mut self, other: Source) {
        let offset = self.lines;
        self.text.push_str(&other.text);
        self.lines += other.lines;
        self.pieces.extend(
            other
                .pieces
                .into_iter()
                .map(|(file, first, count, line)| (file, first + offset, count, line)),
        );
    }
}

/// What splicing one scene's files shares.
pub(super) struct Splice {
    files: Files,
    /// The files being read, outermost first: one included again is a
    /// cycle.
    chain: Vec<PathBuf>,
    /// Every file spliced so far, to the file and line that included it.
    seen: HashMap<PathBuf, (PathBuf, usize)>,
    /// Bytes the scene may still read of [`MAX_SCENE_TEXT`].
    left: usize,
}

/// The scene file `path`, of `text`, with its includes spliced in.
pub(super) fn splice(text: &str, path: &Path, files: Files) -> Result<Source, SceneError> {
    let left = MAX_SCENE_TEXT
        .checked_sub(text.len())
        .ok_or_else(|| SceneError::new(path, too_long()))?;
    let mut splice = Splice {
        files,
        chain: vec![files.identity(path)],
        seen: HashMap::new(),
        left,
    };
    assemble(text, path, &mut splice)
}

/// Splices `include = "other.toml"` lines (top-level, before any table):
/// this file's own top-level keys come first, then the included scene, then
/// this file's tables, which add to it (or replace its tables of the same
/// name). The keys stay top-level: after the included text they would
/// fall into its last table.
fn assemble(text: &str, path: &Path, splice: &mut Splice) -> Result<Source, SceneError> {
    let mut included = Source::new();
    let (mut preamble, mut tables) = (String::new(), String::with_capacity(text.len()));
    let mut preamble_lines = 0;
    let mut in_tables = false;
    for (number, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if key_parts(line) > MAX_KEY_PARTS {
            return Err(SceneError::new(
                path,
                format!(
                    "a key of more than {MAX_KEY_PARTS} dotted parts: no scene key is that deep"
                ),
            )
            .at_line(number + 1));
        }
        in_tables |= trimmed.starts_with('[');
        let own = if in_tables {
            &mut tables
        } else {
            preamble_lines += 1;
            &mut preamble
        };
        let include_line = trimmed
            .strip_prefix("include")
            .and_then(|rest| rest.trim_start().strip_prefix('='))
            .map(str::trim);
        if in_tables && include_line.is_some() {
            return Err(SceneError::new(
                path,
                "an include must come before the first table ([...]): it splices a \
                 whole scene in, and after a table it would be read as that table's key",
            )
            .at_line(number + 1)
            .field("include"));
        }
        let include = include_line.filter(|_| !in_tables);
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
        let other = path.parent().unwrap_or(Path::new(".")).join(&name);
        let identity = splice.files.identity(&other);
        if splice.chain.last() == Some(&identity) {
            return Err(located("a file cannot include itself".into()));
        }
        if splice.chain.contains(&identity) {
            return Err(located(format!(
                "{name} includes this file: an include cycle"
            )));
        }
        if let Some((by, line)) = splice.seen.get(&identity) {
            return Err(located(format!(
                "{name} is included already, at {}:{line} (a scene holds each file once)",
                by.display()
            )));
        }
        if splice.chain.len() > MAX_INCLUDE_DEPTH {
            return Err(located(format!(
                "includes nest deeper than {MAX_INCLUDE_DEPTH}"
            )));
        }
        let other_text = splice
            .files
            .read(&other, splice.left)
            .map_err(|err| match err {
                ReadError::Io(err) => located(format!(
                    "cannot read included file {}: {err}",
                    other.display()
                )),
                ReadError::TooLong => located(too_long()),
                ReadError::NotText { line } => SceneError::new(&other, NOT_TEXT).at_line(line),
            })?;
        splice.left -= other_text.len();
        splice
            .seen
            .insert(identity.clone(), (path.to_path_buf(), number + 1));
        splice.chain.push(identity);
        included.append(assemble(&other_text, &other, splice)?);
        splice.chain.pop();
        // Keeps this file's line numbers.
        own.push_str("# (include)\n");
    }
    // The tables this file defines again, by header or by a top-level key
    // (`render = { width = 32 }`), replace the included ones.
    let mut overridden = TableNames::default();
    let redefined = tables
        .lines()
        .filter_map(table_header)
        .filter(|(_, array)| !array)
        .map(|(name, _)| name);
    for name in redefined.chain(preamble.lines().filter_map(top_level_key)) {
        overridden.insert(&name);
    }
    included.text = without_overridden(&included.text, &overridden);
    let mut source = Source::new();
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

/// Table names (`a.b.c`) as a tree of their dotted parts, flat so that
/// neither a name of a million parts nor its removal recurses, and a look
/// up walks a name's parts once.
#[derive(Default)]
struct TableNames {
    /// (parent node, part) to node; node 0 is the root.
    children: HashMap<(usize, String), usize>,
    /// The nodes that are a name given.
    named: Vec<bool>,
}

impl TableNames {
    fn insert(&mut self, name: &str) {
        let mut node = 0;
        for part in name.split('.') {
            let next = self.children.len() + 1;
            node = *self
                .children
                .entry((node, part.to_string()))
                .or_insert(next);
        }
        if self.named.len() <= node {
            self.named.resize(node + 1, false);
        }
        self.named[node] = true;
    }

    fn is_empty(&self) -> bool {
        self.children.is_empty()
    }

    /// Whether `name` is a name given, or a table within one.
    fn covers(&self, name: &str) -> bool {
        let mut node = 0;
        for part in name.split('.') {
            // A borrowed key would need a second map: the owned key costs
            // one allocation a part.
            match self.children.get(&(node, part.to_string())) {
                Some(&child) => node = child,
                None => return false,
            }
            if self.named.get(node) == Some(&true) {
                return true;
            }
        }
        false
    }
}

/// `included` with every table named in `overridden` taken out, with its
/// sub-tables, so the including file overrides it. Removed lines become
/// comments: line numbers stay where they were.
fn without_overridden(included: &str, overridden: &TableNames) -> String {
    if overridden.is_empty() {
        return included.to_string();
    }
    let mut out = String::with_capacity(included.len());
    let mut skipping = false;
    for line in included.lines() {
        if let Some((name, _)) = table_header(line) {
            skipping = overridden.covers(&name);
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

    const CAMERA: &str = "[camera]\nposition = [0, 1, 5]\nfov = 60\n";

    #[test]
    fn keys_deeper_than_any_scene_key_are_refused_at_their_line() {
        let deep = vec!["a"; super::MAX_KEY_PARTS + 1].join(".");
        for line in [
            format!("[{deep}]"),
            format!("{deep} = 1"),
            format!("[[{deep}]]"),
        ] {
            let text = format!("{CAMERA}\n{line}\n");
            let (_, at, message) = refusal(&[("s.toml".into(), text.into_bytes())]);
            assert_eq!(at, Some(5), "{line}");
            assert!(message.contains("dotted parts"), "{message}");
        }
        // Values and rows of numbers are not keys.
        assert_eq!(super::key_parts("  [1.5, 2.5, 3.5],"), 0);
        assert_eq!(super::key_parts("position = [0.5, 1.5]"), 1);
        assert_eq!(super::key_parts("[[animation.camera]]"), 2);
    }

    /// (file, line, message) of loading the first of `files` from a folder
    /// of them, paths within the folder.
    fn refusal(files: &[(String, Vec<u8>)]) -> (String, Option<usize>, String) {
        let dir = tempfile::tempdir().unwrap();
        for (name, bytes) in files {
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
        let err = load_scene(&dir.path().join(&files[0].0), &SceneOverrides::default())
            .expect_err("loaded");
        let folder = format!("{}/", dir.path().display());
        (
            err.file.display().to_string().replace(&folder, ""),
            err.line,
            err.message.replace(&folder, ""),
        )
    }

    fn texts(files: &[(&str, &str)]) -> Vec<(String, Vec<u8>)> {
        files
            .iter()
            .map(|(name, text)| (name.to_string(), text.as_bytes().to_vec()))
            .collect()
    }

    #[test]
    fn a_file_is_included_once_so_cycles_and_fans_are_refused_at_their_line() {
        let said =
            |file: &str, line, message: &str| (file.to_string(), Some(line), message.to_string());
        assert_eq!(
            refusal(&texts(&[("top.toml", "include = \"./top.toml\"\n")])),
            said("top.toml", 1, "a file cannot include itself")
        );
        assert_eq!(
            refusal(&texts(&[
                ("top.toml", "# a\ninclude = \"b.toml\"\n"),
                ("b.toml", "include = \"top.toml\"\n"),
            ])),
            said("b.toml", 1, "top.toml includes this file: an include cycle")
        );
        // A fan: each file including the next twice spliced 2^8 copies.
        let mut fan: Vec<(String, String)> = (0..8)
            .map(|i| {
                let next = format!("f{}.toml", i + 1);
                let text = format!("include = \"{next}\"\ninclude = \"{next}\"\n");
                (format!("f{i}.toml"), text)
            })
            .collect();
        fan.push(("f8.toml".into(), CAMERA.into()));
        let fan: Vec<(&str, &str)> = fan.iter().map(|(a, b)| (a.as_str(), b.as_str())).collect();
        assert_eq!(
            refusal(&texts(&fan)),
            said(
                "f7.toml",
                2,
                "f8.toml is included already, at f7.toml:1 (a scene holds each file once)"
            )
        );
        // Nine deep: one more than the limit; eight is allowed.
        let mut chain: Vec<(String, String)> = (0..9)
            .map(|i| {
                (
                    format!("f{i}.toml"),
                    format!("include = \"f{}.toml\"\n", i + 1),
                )
            })
            .collect();
        chain.push(("f9.toml".into(), CAMERA.into()));
        let chain: Vec<(&str, &str)> = chain
            .iter()
            .map(|(a, b)| (a.as_str(), b.as_str()))
            .collect();
        assert_eq!(
            refusal(&texts(&chain)),
            said("f8.toml", 1, "includes nest deeper than 8")
        );
        let dir = tempfile::tempdir().unwrap();
        for (name, text) in &chain[1..] {
            std::fs::write(dir.path().join(name), text).unwrap();
        }
        load_scene(&dir.path().join("f1.toml"), &SceneOverrides::default()).unwrap();
    }

    #[test]
    fn scene_text_is_read_up_to_its_limit_and_must_be_utf8() {
        let mut not_text = format!("{CAMERA}# caf").into_bytes();
        not_text.extend([0xe9, b'\n']);
        let not_text_message = "not text: this line holds a byte that is not UTF-8";
        assert_eq!(
            refusal(&[("top.toml".into(), not_text.clone())]),
            ("top.toml".into(), Some(4), not_text_message.into())
        );
        assert_eq!(
            refusal(&[
                ("top.toml".into(), b"include = \"b.toml\"\n".to_vec()),
                ("b.toml".into(), not_text),
            ]),
            ("b.toml".into(), Some(4), not_text_message.into())
        );
        let too_long = "the scene, with its includes, holds more than 4 MiB of text \
                        (put large geometry in OBJ files)";
        // A special file is read only as far as a scene may be long.
        assert_eq!(
            refusal(&texts(&[("top.toml", "include = \"/dev/zero\"\n")])),
            ("top.toml".into(), Some(1), too_long.into())
        );
        let long = format!("{CAMERA}# {}\n", "x".repeat(4 << 20));
        assert_eq!(
            refusal(&texts(&[("top.toml", &long)])),
            ("top.toml".into(), None, too_long.into())
        );
        // Together with what it includes: the second include is too much.
        let half = format!("# {}\n", "x".repeat(5 << 19));
        assert_eq!(
            refusal(&texts(&[
                (
                    "top.toml",
                    &format!("include = \"a.toml\"\ninclude = \"b.toml\"\n{CAMERA}")
                ),
                ("a.toml", &half),
                ("b.toml", &half),
            ])),
            ("top.toml".into(), Some(2), too_long.into())
        );
    }

    #[test]
    fn an_including_file_that_redefines_many_tables_splices_in_linear_time() {
        // Comparing each header of the including file with each line of
        // the included one is quadratic: 20,000 of each take over 15 s in
        // a test build, a fraction of a second in linear time.
        let headers: String = (0..20_000).map(|i| format!("[material.m{i}]\n")).collect();
        let start = std::time::Instant::now();
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("base.toml"), format!("{CAMERA}{headers}")).unwrap();
        let top = dir.path().join("top.toml");
        std::fs::write(&top, format!("include = \"base.toml\"\n{headers}")).unwrap();
        load_scene(&top, &SceneOverrides::default()).unwrap();
        assert!(start.elapsed().as_secs() < 5, "{:?}", start.elapsed());
        // A header of half a million parts: looking each of its prefixes
        // up whole is quadratic too (50 s).
        let header = format!("[{}a]", "a.".repeat(1 << 19));
        let start = std::time::Instant::now();
        assert_eq!(
            refusal(&texts(&[
                ("top.toml", "include = \"base.toml\"\n[render]\n"),
                ("base.toml", &format!("{CAMERA}{header}\n")),
            ]))
            .1,
            Some(4)
        );
        assert!(start.elapsed().as_secs() < 5, "{:?}", start.elapsed());
    }

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
        // header would, rather than falling into the base's last table.
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

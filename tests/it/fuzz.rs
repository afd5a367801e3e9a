//! Fuzzing the scene and model loaders (issue 34): structured mutations of
//! the shipped scene files, of OBJ models and of MTL libraries (truncation,
//! byte flips, numbers swapped for huge, tiny and non-finite ones, lines
//! dropped, repeated, swapped, inserted, and lines of a megabyte), and the
//! hazards a mutation is unlikely to hit by chance (include cycles and
//! fans, enormous face indices, special files).
//!
//! Every input must load, or be refused with an error that names the file
//! and the line (see [`why_no_line`] for the refusals that cannot); no
//! input may panic (caught, the input printed and saved) or make the
//! loader allocate far beyond its size (counted by this binary's
//! allocator, on the loading thread; see [`memory_budget`]).
//!
//! `make test` runs a fixed seed; `make fuzz` sets `RETRACE_FUZZ=N` for N
//! times the cases from a fresh seed.

use std::alloc::System;
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};

use tracking_allocator::{
    AllocationGroupId, AllocationGroupToken, AllocationRegistry, AllocationTracker, Allocator,
};

use retrace::scene::{load_scene, parse_scene_str, Scene, SceneError, SceneOverrides};

// ---------------------------------------------------------------------------
// Memory: the live bytes of the loading thread, and their peak.

/// The live bytes and their peak of each allocation group a load runs in,
/// by group id (the loaders run on one thread, and a group follows the
/// thread that entered it, so tests running beside it are not counted).
static GROUPS: Mutex<BTreeMap<usize, (isize, isize)>> = Mutex::new(BTreeMap::new());

struct PeakTracker;

impl AllocationTracker for PeakTracker {
    fn allocated(&self, _addr: usize, size: usize, _wrapped: usize, group: AllocationGroupId) {
        if group != AllocationGroupId::ROOT {
            let mut groups = GROUPS.lock().unwrap_or_else(|e| e.into_inner());
            let (live, peak) = groups.entry(group.as_usize().get()).or_default();
            *live += size as isize;
            *peak = (*peak).max(*live);
        }
    }

    fn deallocated(
        &self,
        _addr: usize,
        size: usize,
        _wrapped: usize,
        source: AllocationGroupId,
        _current: AllocationGroupId,
    ) {
        if source != AllocationGroupId::ROOT {
            let mut groups = GROUPS.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((live, _)) = groups.get_mut(&source.as_usize().get()) {
                *live -= size as isize;
            }
        }
    }
}

#[global_allocator]
static ALLOCATOR: Allocator<System> = Allocator::system();

/// `f`'s result and the most bytes it held at once.
fn measured<T>(f: impl FnOnce() -> T) -> (T, usize) {
    static TRACKING: OnceLock<()> = OnceLock::new();
    TRACKING.get_or_init(|| {
        AllocationRegistry::set_global_tracker(PeakTracker).expect("one tracker");
        AllocationRegistry::enable_tracking();
    });
    // Registering races between threads (tracking-allocator 0.4 refuses an
    // id when a later one was handed out first); a refused call only used
    // up an id, so asking again is safe.
    let mut token = std::iter::repeat_with(AllocationGroupToken::register)
        .flatten()
        .next()
        .expect("an allocation group");
    let id = token.id().as_usize().get();
    let guard = token.enter();
    let out = f();
    drop(guard);
    let peak = GROUPS
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .remove(&id)
        .map_or(0, |(_, peak)| peak);
    (out, peak.max(0) as usize)
}

/// The most a load may hold at once for `toml` bytes of scene files and
/// `other` bytes of models and material libraries. The shipped scenes
/// (the paper's 32 objects, a 3,674-triangle bunny) stay well within the
/// constant. toml keeps every value with its text and spacing: up to 150
/// bytes a byte (a megabyte of dotted keys, measured), which the loader's
/// 4 MiB limit on a scene's text bounds. A model's triangles, vertices,
/// normals and tobj's copies of them take some 20 bytes a byte of its
/// text (a megabyte-long face).
fn memory_budget(toml: usize, other: usize) -> usize {
    (64 << 20) + toml.saturating_mul(160) + other.saturating_mul(32)
}

// ---------------------------------------------------------------------------
// Cases.

/// Cases for a family: `base`, times `RETRACE_FUZZ` (an integer) when set.
fn cases(base: u32) -> u32 {
    base * fuzz_factor()
}

fn fuzz_factor() -> u32 {
    std::env::var("RETRACE_FUZZ")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1)
        .max(1)
}

/// A runner of `cases`: a fixed seed under `make test`, so a failure
/// there repeats; a fresh one under `make fuzz`, so each run explores.
fn runner(cases: u32) -> TestRunner {
    let config = Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    };
    if std::env::var_os("RETRACE_FUZZ").is_some() {
        TestRunner::new(config)
    } else {
        TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[34; 32]))
    }
}

/// The files of one case; `top` is the one loaded.
#[derive(Clone, Debug)]
struct Files {
    files: Vec<(String, Vec<u8>)>,
    top: String,
}

impl Files {
    fn bytes(&self) -> usize {
        self.files.iter().map(|(_, b)| b.len()).sum()
    }

    fn budget(&self) -> usize {
        let toml: usize = self
            .files
            .iter()
            .filter(|(name, _)| name.ends_with(".toml"))
            .map(|(_, b)| b.len())
            .sum();
        memory_budget(toml, self.bytes() - toml)
    }

    /// The files, each cut to its first and last KB (a case may hold a
    /// line of megabytes).
    fn shown(&self) -> String {
        let mut out = String::new();
        for (name, bytes) in &self.files {
            let text = String::from_utf8_lossy(bytes);
            let text = if text.len() > 2048 {
                let head: String = text.chars().take(1024).collect();
                let tail: String = {
                    let v: Vec<char> = text.chars().rev().take(1024).collect();
                    v.into_iter().rev().collect()
                };
                format!("{head}\n... ({} bytes) ...\n{tail}", bytes.len())
            } else {
                text.into_owned()
            };
            out.push_str(&format!("----- {name}\n{text}\n"));
        }
        out
    }
}

/// Why a refusal names no line: `Some(reason)` for the kinds that cannot
/// or, for the OBJ reader, do not yet; None for every other (which must).
fn why_no_line(err: &SceneError) -> Option<&'static str> {
    let m = err.message.as_str();
    if m.starts_with("the scene, with its includes, holds more than") {
        return Some("the length of the whole file");
    }
    if m == "the model has no triangles to render" || m.starts_with("the model has no faces") {
        return Some("a property of the whole model");
    }
    if err.field.as_deref() == Some("camera") && m.starts_with("camera.") {
        // The camera that src/scene/obj.rs makes around a bare model: a
        // model reaching near the scene's extent puts it beyond (a
        // property of the whole model, though the words are the camera's).
        return Some("the camera made to frame a bare model");
    }
    None
}

/// Loads `files` (through `load`, given the top file's path) from this
/// thread's folder for cases, and checks the outcome: loaded, or refused
/// naming its file and line; no panic; memory within the budget.
fn check(
    files: &Files,
    load: impl FnOnce(&Path) -> Result<Scene, SceneError>,
) -> Result<(), TestCaseError> {
    let top = in_workspace(files);
    let (outcome, peak) = measured(|| catch_unwind(AssertUnwindSafe(|| load(&top))));
    let problem = match &outcome {
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("(no message)");
            Some(format!("panicked: {what}"))
        }
        Ok(Err(err)) if err.file.as_os_str().is_empty() => {
            Some(format!("refused without naming a file: {err}"))
        }
        Ok(Err(err)) if err.line.is_none() && why_no_line(err).is_none() => {
            Some(format!("refused without a line: {err}"))
        }
        _ => None,
    };
    let budget = files.budget();
    let problem = problem.or_else(|| {
        (peak > budget).then(|| {
            format!(
                "held {peak} bytes at once for {} bytes of input (budget {budget})",
                files.bytes()
            )
        })
    });
    match problem {
        None => Ok(()),
        Some(problem) => Err(TestCaseError::fail(format!(
            "{problem}\nsaved in {}\n{}",
            save_failure(files).display(),
            files.shown()
        ))),
    }
}

/// The path of `files`' top file, the files written into this thread's
/// folder for cases: only those that differ from what it holds (writing
/// every file of every case took ten times the loading).
fn in_workspace(files: &Files) -> PathBuf {
    /// A folder and the files it holds.
    struct Workspace {
        dir: tempfile::TempDir,
        held: Vec<(String, Vec<u8>)>,
    }
    thread_local! {
        static WORKSPACE: std::cell::RefCell<Option<Workspace>> =
            const { std::cell::RefCell::new(None) };
    }
    WORKSPACE.with(|workspace| {
        let mut workspace = workspace.borrow_mut();
        let Workspace { dir, held } = workspace.get_or_insert_with(|| Workspace {
            dir: tempfile::tempdir().unwrap(),
            held: Vec::new(),
        });
        for (name, _) in held.iter() {
            if !files.files.iter().any(|(n, _)| n == name) {
                let _ = std::fs::remove_file(dir.path().join(name));
            }
        }
        for (name, bytes) in &files.files {
            if !held.iter().any(|(n, b)| n == name && b == bytes) {
                let path = dir.path().join(name);
                std::fs::create_dir_all(path.parent().unwrap()).unwrap();
                std::fs::write(path, bytes).unwrap();
            }
        }
        *held = files.files.clone();
        dir.path().join(&files.top)
    })
}

/// `files` in a folder of their own.
fn written(files: &Files) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in &files.files {
        let path = dir.path().join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, bytes).unwrap();
    }
    dir
}

/// Keeps a failing case's files for a rerun by hand: `target/fuzz-failure`.
fn save_failure(files: &Files) -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fuzz-failure");
    let _ = std::fs::remove_dir_all(&dir);
    for (name, bytes) in &files.files {
        let path = dir.join(name);
        let _ = std::fs::create_dir_all(path.parent().unwrap());
        let _ = std::fs::write(path, bytes);
    }
    dir
}

/// Loads the top file as the command line does.
fn by_path(path: &Path) -> Result<Scene, SceneError> {
    load_scene(path, &SceneOverrides::default())
}

/// Loads the top file's text, when it is text, as [`parse_scene_str`]
/// (what `load_scene` does after reading it); else as [`by_path`].
fn by_text(path: &Path) -> Result<Scene, SceneError> {
    match std::fs::read(path).map(String::from_utf8) {
        Ok(Ok(text)) => parse_scene_str(&text, path, &SceneOverrides::default()),
        _ => by_path(path),
    }
}

// ---------------------------------------------------------------------------
// Mutations.

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Toml,
    Obj,
    Mtl,
}

/// One change to a file's bytes.
#[derive(Clone, Debug)]
enum Edit {
    /// Cut the file here.
    Truncate(Index),
    /// XOR a byte with a non-zero value.
    Flip(Index, u8),
    /// Replace a number with one of [`NUMBERS`].
    Number(Index, Index),
    /// Replace a face's vertex index with one of [`FACE_INDICES`].
    FaceIndex(Index, Index),
    DropLine(Index),
    RepeatLine(Index),
    SwapLines(Index, Index),
    /// Insert one of the kind's snippets before a line.
    Insert(Index, Index),
    /// Insert a line of about [`huge_len`] bytes before a line.
    Huge(Index, Index),
}

const NUMBERS: &[&str] = &[
    "1e308",
    "-1e308",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "1e-320",
    "-1e-320",
    "1e400",
    "1e39",
    "3.4028235e38",
    "0",
    "-0",
    "-1",
    "4294967296",
    "99999999999",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
];

const FACE_INDICES: &[&str] = &[
    "99999999999",
    "-99999999999",
    "0",
    "2147483648",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "-1",
];

/// Lines a scene file may meet, valid or not where they land.
const TOML_SNIPPETS: &[&str] = &[
    "include = \"paper.toml\"",
    "include = \"case.toml\"",
    "include = \"missing.toml\"",
    "include = \".\"",
    "[render]",
    "max_depth = 16",
    "width = 32768",
    "height = 32768",
    "[camera]",
    "projection = \"equal-angle\"",
    "projection = \"fisheye\"",
    "fov = 1e-5",
    "fov = 360",
    "pitch = 90",
    "yaw = 1e300",
    "look_at = [0, 1, 5]",
    "[[light]]",
    "position = [0, 5, 0]",
    "intensity = 1e38",
    "[material.x]",
    "checker = { colors = [[0, 0, 0], [1, 1, 1]], scale = 1e-30 }",
    "reflectivity = 1",
    "shininess = 1e38",
    "[[object]]",
    "type = \"sphere\"",
    "type = \"mesh\"",
    "type = \"polygon\"",
    "file = \"bunny.obj\"",
    "file = \"/dev/zero\"",
    "vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]",
    "radius = 1e-30",
    "scale = 1e30",
    "scale = 1e-30",
    "rotate = [1e30, 0, 0]",
    "name = \"ball\"",
    "smooth = true",
    "[animation]",
    "frames = 1000000",
    "fps = 1e-300",
    "[[animation.camera]]",
    "frame = 0",
    "frame = 4294967295",
    "[[animation.object]]",
    "object = \"ball\"",
    "[[animation.bounce]]",
    "period = 1e-300",
    "height = 1e12",
    "[[animation.light]]",
    "light = 18446744073709551615",
    "[[viewport]]",
    "zoom = 1000",
    "shear = [1, 1]",
    "translate = [1e30, 0]",
    "[[animation.viewport]]",
    "viewport = -1",
    "viewport = \"view\"",
    "when = 1979-05-27T07:32:00Z",
    "[a.b.c.d]",
    "x = { y = { z = 1 } }",
];

const OBJ_SNIPPETS: &[&str] = &[
    "mtllib m.mtl",
    "mtllib missing.mtl",
    "mtllib .",
    "usemtl red",
    "usemtl missing",
    "o part",
    "g group",
    "s 1",
    "s off",
    "f 1 2 3",
    "f -1 -2 -3",
    "f 1/1/1 2/2/2 3/3/3",
    "f 1//1 2//1 3//1",
    "f 1/1 2/1 3/1",
    "f 1 2 3 4 5 6 7 8",
    "vt 0 0",
    "vt 0.5 1e38 0",
    "vn 0 0 1",
    "vn 0 0 0",
    "v 0 0 0 0",
    "v 1e12 0 0",
    "v 1 2 3 0.5 0.5 0.5",
    "l 1 2",
    "p 1",
    "f",
    "v",
];

const MTL_SNIPPETS: &[&str] = &[
    "newmtl red",
    "newmtl",
    "Kd 1 0 0",
    "Kd nan 0 0",
    "Kd 1",
    "Ks 1e400 0 0",
    "Ks 0.9 0.9 0.9",
    "Ns -1",
    "Ns 1e38",
    "illum 3",
    "illum 99999999999",
    "illum -1",
    "d 0.5",
    "Tr 2",
    "map_Kd texture.png",
    "Ka 0.1 0.1 0.1",
];

fn snippets(kind: Kind) -> &'static [&'static str] {
    match kind {
        Kind::Toml => TOML_SNIPPETS,
        Kind::Obj => OBJ_SNIPPETS,
        Kind::Mtl => MTL_SNIPPETS,
    }
}

/// The length of a huge line: a megabyte, four under `make fuzz`.
fn huge_len() -> usize {
    if fuzz_factor() > 1 {
        4 << 20
    } else {
        1 << 20
    }
}

/// A line of about `n` bytes of kind `which` (modulo the kinds there are).
fn huge_line(kind: Kind, which: usize, n: usize) -> String {
    let repeat = |unit: &str| unit.repeat(n / unit.len().max(1));
    let lines: Vec<String> = match kind {
        Kind::Toml => vec![
            format!("# {}", repeat("x")),
            format!("name = \"{}\"", repeat("a")),
            format!("vertices = [{}[0, 1, 0]]", repeat("[0, 0, 0], [1, 0, 0], ")),
            format!("radius = {}", repeat("9")),
            format!(
                "x = {}1{}",
                repeat("[").get(..n / 2).unwrap_or(""),
                "]".repeat(n / 2)
            ),
            format!("x = {}1{}", "{ a = ".repeat(n / 12), " }".repeat(n / 12)),
            format!("[{}a]", repeat("a.")),
            repeat("a"),
            format!("radius = 1{}", repeat("0")),
        ],
        Kind::Obj => vec![
            format!("f{}", repeat(" 1 2 3")),
            format!("f{}", repeat(" 1/1/1 2/2/2 3/3/3")),
            format!("v{}", repeat(" 1")),
            format!("vt{}", repeat(" 0.5")),
            format!("# {}", repeat("x")),
            format!("o {}", repeat("n")),
            format!("usemtl {}", repeat("n")),
            format!(
                "mtllib{}",
                repeat(" m.mtl").get(..n.min(64 << 10)).unwrap_or("")
            ),
            format!("v 1 2 {}", repeat("3")),
        ],
        Kind::Mtl => vec![
            format!("newmtl {}", repeat("n")),
            format!("Kd{}", repeat(" 0.5")),
            format!("# {}", repeat("x")),
            format!("map_Kd {}", repeat("t")),
            format!("Ns {}", repeat("9")),
        ],
    };
    lines[which % lines.len()].clone()
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        3 => any::<Index>().prop_map(Edit::Truncate),
        4 => (any::<Index>(), 1u8..=255).prop_map(|(at, x)| Edit::Flip(at, x)),
        6 => (any::<Index>(), any::<Index>()).prop_map(|(at, n)| Edit::Number(at, n)),
        3 => (any::<Index>(), any::<Index>()).prop_map(|(at, n)| Edit::FaceIndex(at, n)),
        2 => any::<Index>().prop_map(Edit::DropLine),
        2 => any::<Index>().prop_map(Edit::RepeatLine),
        2 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Edit::SwapLines(a, b)),
        4 => (any::<Index>(), any::<Index>()).prop_map(|(at, s)| Edit::Insert(at, s)),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(at, k)| Edit::Huge(at, k)),
    ]
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    prop::collection::vec(edit(), 1..4)
}

/// Where the numbers of `text` are: runs that start with a digit (or a
/// sign, or `nan`/`inf`) not inside a word.
fn number_spans(text: &[u8]) -> Vec<std::ops::Range<usize>> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let word_before =
            i > 0 && (text[i - 1].is_ascii_alphanumeric() || b"_.-".contains(&text[i - 1]));
        let starts = text[i].is_ascii_digit()
            || (b"+-".contains(&text[i]) && text.get(i + 1).is_some_and(u8::is_ascii_digit));
        if starts && !word_before {
            let end = (i + 1..text.len())
                .find(|&j| !(text[j].is_ascii_digit() || b".eE+-_".contains(&text[j])))
                .unwrap_or(text.len());
            spans.push(i..end);
            i = end;
        } else {
            i += 1;
        }
    }
    spans
}

/// Where the vertex indices of the `f` lines of `text` are.
fn face_index_spans(text: &[u8]) -> Vec<std::ops::Range<usize>> {
    let mut spans = Vec::new();
    let mut start = 0;
    for line in text.split(|&b| b == b'\n') {
        if line.starts_with(b"f ") {
            spans.extend(
                number_spans(line)
                    .into_iter()
                    .map(|s| s.start + start..s.end + start),
            );
        }
        start += line.len() + 1;
    }
    spans
}

fn lines(bytes: &[u8]) -> Vec<Vec<u8>> {
    bytes.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect()
}

fn unlines(lines: Vec<Vec<u8>>) -> Vec<u8> {
    lines.join(&b'\n')
}

/// `bytes` (a file of `kind`) with `edit` made.
fn apply(kind: Kind, bytes: Vec<u8>, edit: &Edit) -> Vec<u8> {
    let mut bytes = bytes;
    let replace =
        |bytes: &mut Vec<u8>, spans: Vec<std::ops::Range<usize>>, at: &Index, with: &str| {
            if !spans.is_empty() {
                let span = spans[at.index(spans.len())].clone();
                bytes.splice(span, with.bytes());
            }
        };
    match edit {
        Edit::Truncate(at) => bytes.truncate(at.index(bytes.len() + 1)),
        Edit::Flip(at, x) => {
            if !bytes.is_empty() {
                let i = at.index(bytes.len());
                bytes[i] ^= x;
            }
        }
        Edit::Number(at, n) => {
            let spans = number_spans(&bytes);
            replace(&mut bytes, spans, at, NUMBERS[n.index(NUMBERS.len())]);
        }
        Edit::FaceIndex(at, n) => {
            let spans = face_index_spans(&bytes);
            replace(
                &mut bytes,
                spans,
                at,
                FACE_INDICES[n.index(FACE_INDICES.len())],
            );
        }
        Edit::DropLine(at) => {
            let mut l = lines(&bytes);
            l.remove(at.index(l.len()));
            bytes = unlines(l);
        }
        Edit::RepeatLine(at) => {
            let mut l = lines(&bytes);
            let i = at.index(l.len());
            l.insert(i, l[i].clone());
            bytes = unlines(l);
        }
        Edit::SwapLines(a, b) => {
            let mut l = lines(&bytes);
            let (a, b) = (a.index(l.len()), b.index(l.len()));
            l.swap(a, b);
            bytes = unlines(l);
        }
        Edit::Insert(at, s) => {
            let mut l = lines(&bytes);
            let snippets = snippets(kind);
            l.insert(
                at.index(l.len() + 1),
                snippets[s.index(snippets.len())].into(),
            );
            bytes = unlines(l);
        }
        Edit::Huge(at, which) => {
            let mut l = lines(&bytes);
            let line = huge_line(kind, which.index(64), huge_len());
            l.insert(at.index(l.len() + 1), line.into_bytes());
            bytes = unlines(l);
        }
    }
    bytes
}

fn mutated(kind: Kind, bytes: &[u8], edits: &[Edit]) -> Vec<u8> {
    edits
        .iter()
        .fold(bytes.to_vec(), |bytes, edit| apply(kind, bytes, edit))
}

// ---------------------------------------------------------------------------
// The corpus.

fn shipped(name: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name),
    )
    .unwrap()
}

/// The shipped scene files, by name, with `bunnies.toml` cut to its first
/// two bunnies (its 256 cost a load 256 bunny models; the experiment files
/// that include it need only its names and tables).
fn scene_corpus() -> &'static [(String, Vec<u8>)] {
    static CORPUS: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
    CORPUS.get_or_init(|| {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|name| name.ends_with(".toml") || name.ends_with(".obj"))
            .map(|name| {
                let mut bytes = shipped(&name);
                if name == "bunnies.toml" {
                    let text = String::from_utf8(bytes).unwrap();
                    let cut = text.find("[[object]]\nname = \"bunny-002\"").unwrap();
                    bytes = text.into_bytes();
                    bytes.truncate(cut);
                }
                (name, bytes)
            })
            .collect();
        files.sort();
        files
    })
}

/// The scene files a case loads: every shipped one but `bunnies.toml`
/// itself, which its experiments load.
fn scene_tops() -> Vec<&'static str> {
    scene_corpus()
        .iter()
        .map(|(name, _)| name.as_str())
        .filter(|name| name.ends_with(".toml") && *name != "bunnies.toml")
        .collect()
}

/// The files `name` includes, directly or not, and the models they name:
/// what its folder must hold.
fn needs(name: &str) -> Vec<&'static str> {
    let corpus = scene_corpus();
    let mut needed: Vec<&'static str> = Vec::new();
    let mut todo = vec![name.to_string()];
    while let Some(file) = todo.pop() {
        let Some((own, bytes)) = corpus.iter().find(|(n, _)| *n == file) else {
            continue;
        };
        if needed.contains(&own.as_str()) {
            continue;
        }
        needed.push(own);
        for line in String::from_utf8_lossy(bytes).lines() {
            for key in ["include", "file"] {
                if let Some(rest) = line.trim().strip_prefix(key) {
                    if let Some(value) = rest.trim().strip_prefix('=') {
                        todo.push(value.trim().trim_matches('"').to_string());
                    }
                }
            }
        }
    }
    needed
}

/// A triangle, a quad and a pentagon with texture coordinates, normals
/// and two materials; a model in parts with negative indices; a
/// smoothing-group model; a bare triangle.
const SMALL_OBJS: &[&str] = &[
    "mtllib m.mtl\no tri\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 0 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
     vn 0 0 1\nusemtl red\nf 1/1/1 2/2/1 3/3/1\nusemtl shiny\nf 2/2/1 4/3/1 3/1/1\n\
     f 1/1/1 5/2/1 4/3/1 3/1/1 2/2/1\n",
    "mtllib m.mtl\ng a\nv -1 0 0\nv 1 0 0\nv 0 2 0\nf -3 -2 -1\ng b\nv -1 0 1\nv 1 0 1\n\
     v 0 2 1\nusemtl red\nf -3 -2 -1\nl 1 2\np 3\n",
    "s 1\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\nvn 0 0 -1\nvn 0 0 1\n\
     f 1//1 2//1 3//1 4//1\nf 1//2 2//2 5//2\nf 2//2 3//2 5//2\n",
    "v -1 0 0\nv 1 0 0\nv 0 2 0\nf 1 2 3\n",
];

const SMALL_MTL: &str = "newmtl red\nKd 1 0 0\nKs 0.2 0.2 0.2\nNs 30\n\
                         newmtl shiny\nKd 0.1 0.1 0.1\nKs 0.9 0.9 0.9\nNs 300\nillum 3\n";

/// A scene that shows the model `m.obj`.
const MESH_SCENE: &str = "[camera]\nposition = [0, 1, 5]\nfov = 60\n[[light]]\n\
                          position = [0, 5, 0]\n[[object]]\ntype = \"mesh\"\nfile = \"m.obj\"\n\
                          smooth = true\n";

// ---------------------------------------------------------------------------
// The families.

/// The shipped scenes, the file loaded or one it includes mutated.
#[test]
fn shipped_scenes_survive_mutation() {
    let tops = scene_tops();
    let strategy = (any::<Index>(), any::<Index>(), edits());
    runner(cases(2000))
        .run(&strategy, |(top, victim, edits)| {
            let top = tops[top.index(tops.len())];
            let needed = needs(top);
            let victim = needed
                .iter()
                .filter(|n| n.ends_with(".toml"))
                .nth(victim.index(needed.iter().filter(|n| n.ends_with(".toml")).count()))
                .copied()
                .unwrap_or(top);
            let files = Files {
                files: scene_corpus()
                    .iter()
                    .filter(|(name, _)| needed.contains(&name.as_str()))
                    .map(|(name, bytes)| {
                        let bytes = if name == victim {
                            mutated(Kind::Toml, bytes, &edits)
                        } else {
                            bytes.clone()
                        };
                        (name.clone(), bytes)
                    })
                    .collect(),
                top: top.to_string(),
            };
            check(&files, if victim == top { by_text } else { by_path })
        })
        .unwrap();
}

/// OBJ models: the bunny and small hand-written ones, loaded bare or
/// through a scene.
#[test]
fn models_survive_mutation() {
    let bunny = shipped("bunny.obj");
    let strategy = (0..SMALL_OBJS.len() + 1, any::<bool>(), edits());
    runner(cases(2000))
        .run(&strategy, |(model, in_scene, edits)| {
            // The bunny (110 KB) is a fifth of the cases' models.
            let obj = match SMALL_OBJS.get(model) {
                Some(text) => text.as_bytes(),
                None => &bunny,
            };
            let mut files = vec![
                ("m.obj".to_string(), mutated(Kind::Obj, obj, &edits)),
                ("m.mtl".to_string(), SMALL_MTL.as_bytes().to_vec()),
            ];
            if in_scene {
                files.push(("s.toml".into(), MESH_SCENE.as_bytes().to_vec()));
            }
            let top = if in_scene { "s.toml" } else { "m.obj" };
            check(
                &Files {
                    files,
                    top: top.into(),
                },
                by_path,
            )
        })
        .unwrap();
}

/// MTL libraries, through the models that use them.
#[test]
fn material_libraries_survive_mutation() {
    let strategy = (0..2usize, edits());
    runner(cases(1000))
        .run(&strategy, |(model, edits)| {
            let files = vec![
                ("m.obj".to_string(), SMALL_OBJS[model].as_bytes().to_vec()),
                (
                    "m.mtl".to_string(),
                    mutated(Kind::Mtl, SMALL_MTL.as_bytes(), &edits),
                ),
            ];
            check(
                &Files {
                    files,
                    top: "m.obj".into(),
                },
                by_path,
            )
        })
        .unwrap();
}

// ---------------------------------------------------------------------------
// Hazards chance rarely finds, and what the fuzzing found.

/// A case of the files `files`, the first loaded.
fn case(files: &[(&str, &str)]) -> Files {
    Files {
        files: files
            .iter()
            .map(|(name, text)| (name.to_string(), text.as_bytes().to_vec()))
            .collect(),
        top: files[0].0.to_string(),
    }
}

const CAMERA: &str = "[camera]\nposition = [0, 1, 5]\nfov = 60\n";

/// Checks `files` as every case is; a failure fails the test.
fn must_hold(files: &Files) {
    check(files, by_path).unwrap_or_else(|e| panic!("{e}"));
}

/// The refusal of `files`, checked as every case is, its file named
/// within the case's folder.
fn refusal(files: &Files) -> SceneError {
    must_hold(files);
    let dir = written(files);
    let err = by_path(&dir.path().join(&files.top)).expect_err("loaded");
    let file = err.file.strip_prefix(dir.path()).unwrap().to_path_buf();
    let folder = format!("{}/", dir.path().display());
    let message = err.message.replace(&folder, "");
    SceneError {
        file,
        message,
        ..err
    }
}

#[test]
fn include_hazards_are_refused_by_line_within_memory() {
    // A fan (each file including the next twice: 2^8 copies), a cycle,
    // a chain one deeper than allowed, a special file, a folder.
    let fan: Vec<(String, String)> = (0..9)
        .map(|i| {
            let text = if i == 8 {
                CAMERA.to_string()
            } else {
                format!("include = \"f{0}.toml\"\ninclude = \"f{0}.toml\"\n", i + 1)
            };
            (format!("f{i}.toml"), text)
        })
        .collect();
    let chain: Vec<(String, String)> = (0..10)
        .map(|i| {
            let text = if i == 9 {
                CAMERA.to_string()
            } else {
                format!("include = \"f{}.toml\"\n", i + 1)
            };
            (format!("f{i}.toml"), text)
        })
        .collect();
    let cycle: Vec<(String, String)> = vec![
        ("f0.toml".into(), "include = \"f1.toml\"\n".into()),
        ("f1.toml".into(), "include = \"./f0.toml\"\n".into()),
    ];
    let special = vec![(
        "f0.toml".to_string(),
        "include = \"/dev/zero\"\n".to_string(),
    )];
    let folder = vec![("f0.toml".to_string(), "include = \".\"\n".to_string())];
    for files in [fan, chain, cycle, special, folder] {
        let files: Vec<(&str, &str)> = files
            .iter()
            .map(|(a, b)| (a.as_str(), b.as_str()))
            .collect();
        let err = refusal(&case(&files));
        assert_eq!(err.field.as_deref(), Some("include"), "{err}");
    }
}

#[test]
fn enormous_face_indices_are_refused_by_line() {
    for index in FACE_INDICES.iter().filter(|i| **i != "-1") {
        let obj = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 {index}\n");
        let err = refusal(&case(&[("m.obj", &obj)]));
        assert_eq!(
            (err.line, err.field.as_deref()),
            (Some(4), Some("f")),
            "{err}"
        );
    }
}

#[test]
fn lines_of_a_megabyte_hold() {
    for which in 0..9 {
        let line = huge_line(Kind::Toml, which, 1 << 20);
        must_hold(&case(&[(
            "top.toml",
            &format!("{CAMERA}[[object]]\ntype = \"polygon\"\n{line}\n"),
        )]));
        let line = huge_line(Kind::Obj, which, 1 << 20);
        let obj = case(&[
            (
                "m.obj",
                &format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n{line}\nf 1 2 3\n"),
            ),
            ("m.mtl", SMALL_MTL),
        ]);
        must_hold(&obj);
        let line = huge_line(Kind::Mtl, which, 1 << 20);
        must_hold(&case(&[
            ("m.obj", SMALL_OBJS[0]),
            ("m.mtl", &format!("{SMALL_MTL}{line}\n")),
        ]));
    }
}

/// What tobj would panic on, or refuse without a line, is caught first by
/// src/scene/obj.rs: refused at its line in an OBJ, warned about at its
/// line in an MTL (that material falls back to the default).
mod obj_reader_hazards {
    use super::*;

    fn warnings_of(files: &Files) -> String {
        let dir = written(files);
        let outcome = catch_unwind(|| by_path(&dir.path().join(&files.top)));
        let scene = outcome.expect("panicked").expect("refused");
        scene.warnings.join("\n")
    }

    #[test]
    fn an_mtl_colour_of_fewer_than_three_numbers_is_warned_by_line() {
        for colour in ["Kd", "Kd 1", "Ks 1 0", "Ka 0.5", "Ke"] {
            let files = case(&[
                ("m.obj", SMALL_OBJS[0]),
                ("m.mtl", &format!("newmtl red\n{colour}\n")),
            ]);
            let warnings = warnings_of(&files);
            assert!(
                warnings.contains("m.mtl:2: ")
                    && warnings.contains("material 'red' uses the default material"),
                "{colour}: {warnings}"
            );
        }
    }

    #[test]
    fn lines_tobj_refuses_are_refused_by_line() {
        let triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        for refused in [
            // `v` of 5, or of 7 and more, numbers: tobj's "color parse error".
            "v 1 0 0 1 1",
            "v 1 0 0 1 1 1 1",
            // Texture coordinates a file never defines are skipped by tobj
            // only when they are numbers.
            "f 1/x 2/x 3/x",
            "f 1/1/1/1 2 3",
        ] {
            let obj = format!("{triangle}f 1 2 3\n{refused}\n");
            let err = refusal(&case(&[("m.obj", &obj)]));
            assert_eq!(err.line, Some(5), "{refused}: {err}");
        }
    }

    #[test]
    fn colours_on_some_vertices_only_load() {
        let obj = "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        warnings_of(&case(&[("m.obj", obj)]));
    }

    #[test]
    fn normals_used_before_they_are_defined_are_refused_by_line() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\nvn 0 0 1\n";
        let err = refusal(&case(&[("m.obj", obj)]));
        assert_eq!(err.line, Some(4), "{err}");
    }

    #[test]
    fn an_obj_that_is_not_utf8_is_read_with_a_warning_by_line() {
        let mut obj = b"v 0 0 0\nv 1 0 0\n# caf".to_vec();
        obj.extend([0xe9, b'\n']);
        obj.extend(b"v 0 1 0\nf 1 2 3\n");
        let warnings = warnings_of(&Files {
            files: vec![("m.obj".into(), obj)],
            top: "m.obj".into(),
        });
        assert!(warnings.contains("m.obj:3: not valid UTF-8"), "{warnings}");
    }
}

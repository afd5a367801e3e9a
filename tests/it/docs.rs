//! The maps of the source in the docs name every module that is there:
//! docs/ARCHITECTURE.md's Layers section every module down to a top-level
//! folder's children, the README's map every top-level module. Read from
//! the files and from `src/` itself, so a module added without its line in
//! the docs fails here by name.

use std::path::Path;

/// A module of the library or binary, as its files lay it out.
struct Module {
    /// Below `src/`, without an extension: `texture`, `cli/farm`.
    path: String,
    /// `src/<path>.rs` exists.
    file: bool,
    /// `src/<path>/` exists and holds Rust code.
    folder: bool,
}

impl Module {
    /// How a failure names it: its file, else its folder.
    fn shown(&self) -> String {
        if self.file {
            format!("src/{}.rs", self.path)
        } else {
            format!("src/{}/", self.path)
        }
    }

    /// Whether path `named` (with `src/` or without, ending in `.rs` or
    /// `/`) is this module's file or folder, whole or by its trailing
    /// components. A path with `src/` must be whole.
    fn is_named_by(&self, named: &str) -> bool {
        let (named, whole) = match named.strip_prefix("src/") {
            Some(rest) => (rest, true),
            None => (named, false),
        };
        let stem = if let Some(stem) = named.strip_suffix("/mod.rs") {
            self.folder.then_some(stem)
        } else if let Some(stem) = named.strip_suffix(".rs") {
            self.file.then_some(stem)
        } else if let Some(stem) = named.strip_suffix('/') {
            self.folder.then_some(stem)
        } else {
            None
        };
        stem.is_some_and(|stem| {
            !stem.is_empty()
                && if whole {
                    self.path == stem
                } else {
                    self.path == stem || self.path.ends_with(&format!("/{stem}"))
                }
        })
    }

    /// Whether this module lies within one of `scopes` (module paths).
    fn is_within(&self, scopes: &[String]) -> bool {
        scopes
            .iter()
            .any(|scope| self.path == *scope || self.path.starts_with(&format!("{scope}/")))
    }
}

/// Whether a name is code rather than tests alone.
fn is_code(name: &str) -> bool {
    name.ends_with(".rs") && !matches!(name, "main.rs" | "lib.rs" | "tests.rs" | "mod.rs")
}

/// Whether `folder` holds Rust code outside tests, at any depth.
fn holds_code(folder: &Path) -> bool {
    std::fs::read_dir(folder).unwrap().any(|entry| {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if path.is_dir() {
            name != "tests" && holds_code(&path)
        } else {
            name.ends_with(".rs") && name != "tests.rs"
        }
    })
}

/// The modules in `folder` (module path `prefix`), by name.
fn modules_in(folder: &Path, prefix: &str) -> Vec<Module> {
    let mut modules: Vec<Module> = Vec::new();
    for entry in std::fs::read_dir(folder).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let (stem, file) = if path.is_dir() {
            if name == "tests" || !holds_code(&path) {
                continue;
            }
            (name, false)
        } else if is_code(&name) {
            (name.trim_end_matches(".rs").to_string(), true)
        } else {
            continue;
        };
        let path = format!("{prefix}{stem}");
        match modules.iter_mut().find(|m| m.path == path) {
            Some(module) if file => module.file = true,
            Some(module) => module.folder = true,
            None => modules.push(Module {
                path,
                file,
                folder: !file,
            }),
        }
    }
    modules.sort_by(|a, b| a.path.cmp(&b.path));
    modules
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Every module under `src/`, at any depth, each folder before its
/// modules.
fn every_module() -> Vec<Module> {
    fn within(src: &Path, prefix: &str, modules: &mut Vec<Module>) {
        for module in modules_in(&src.join(prefix), prefix) {
            let folder = module.folder.then(|| format!("{}/", module.path));
            modules.push(module);
            if let Some(folder) = folder {
                within(src, &folder, modules);
            }
        }
    }
    let mut modules = Vec::new();
    within(&root().join("src"), "", &mut modules);
    modules
}

/// The text of `file` from the line `heading` to the next heading of the
/// same or a higher level (a `#` comment in a code block is none).
fn section(file: &str, heading: &str) -> String {
    let text = std::fs::read_to_string(root().join(file)).unwrap();
    let level = heading.len() - heading.trim_start_matches('#').len();
    let mut lines = text.lines().skip_while(|line| *line != heading);
    assert!(lines.next().is_some(), "{file} has no line `{heading}`");
    let mut in_code = false;
    lines
        .take_while(|line| {
            in_code ^= line.starts_with("```");
            let hashes = line.len() - line.trim_start_matches('#').len();
            in_code || !(hashes > 0 && hashes <= level && line[hashes..].starts_with(' '))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The paths a line names: words of path characters that end in `.rs` or
/// `/` (a sentence's full stop left off).
fn paths_in(line: &str) -> Vec<&str> {
    line.split(|c: char| !(c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '/')))
        .map(|word| word.trim_end_matches('.'))
        .filter(|word| word.ends_with(".rs") || word.ends_with('/'))
        .collect()
}

/// The module paths of a layer's `src/` paths (its table row's second
/// column): `src/cli/`, `src/main.rs` give `cli`, `main`.
fn scopes_of(paths: &str) -> Vec<String> {
    paths_in(paths)
        .into_iter()
        .filter_map(|path| path.strip_prefix("src/"))
        .map(|path| {
            path.trim_end_matches('/')
                .trim_end_matches(".rs")
                .to_string()
        })
        .collect()
}

/// The Layers section names a module by a path: in full from `src/`
/// anywhere in it, or by its trailing components (`texture/`,
/// `cli/farm.rs`, `farm.rs`) in its own layer's table row or in that
/// layer's bullet under "What each layer promises". A file is named with
/// `.rs`, a folder with `/` (or `/mod.rs`).
#[test]
fn the_architecture_layers_name_every_module() {
    let text = section("docs/ARCHITECTURE.md", "## Layers");
    let mut layers: Vec<(String, Vec<String>)> = Vec::new();
    // Per line, the modules its shorter paths may name.
    let mut named: Vec<(Vec<String>, Vec<&str>)> = Vec::new();
    let mut scopes: Vec<String> = Vec::new();
    for line in text.lines() {
        if let Some(row) = line.strip_prefix('|') {
            let cells: Vec<&str> = row.split('|').collect();
            let layer = cells[0].trim().trim_matches('`').to_string();
            scopes = cells.get(1).map_or(Vec::new(), |paths| scopes_of(paths));
            layers.push((layer, scopes.clone()));
        } else if let Some(bullet) = line.strip_prefix("- **") {
            let layer = bullet.split(".**").next().unwrap();
            scopes = layers
                .iter()
                .find(|(name, _)| name == layer)
                .map_or(Vec::new(), |(_, scopes)| scopes.clone());
        } else if !line.starts_with(' ') {
            // A paragraph or heading of its own: no layer's.
            scopes = Vec::new();
        }
        named.push((scopes.clone(), paths_in(line)));
    }
    let missing: Vec<String> = every_module()
        .into_iter()
        .filter(|module| {
            !named.iter().any(|(scopes, paths)| {
                paths.iter().any(|path| {
                    module.is_named_by(path)
                        && (path.starts_with("src/") || module.is_within(scopes))
                })
            })
        })
        .map(|module| module.shown())
        .collect();
    assert!(
        missing.is_empty(),
        "docs/ARCHITECTURE.md's Layers section does not name {} module(s) \
         (in full from src/, or by the end of its path in its layer's row or bullet): {}",
        missing.len(),
        missing.join(", ")
    );
}

/// The README's map names every top-level module in its first column: as
/// `src/X.rs` or `src/X/`, or as `X.rs` or `X/` after a `src/` path in the
/// same list (`src/ray.rs, geometry.rs`). Parenthesised parts (a module's
/// own parts) and indented lines (a folder's modules) name none.
#[test]
fn the_readme_map_names_every_top_level_module() {
    let text = section("README.md", "## Where things live");
    let mut named = Vec::new();
    for line in text.lines().filter(|line| line.starts_with("src/")) {
        let mut column = String::new();
        let mut depth = 0;
        for c in line.chars() {
            match c {
                '(' => depth += 1,
                ')' => depth -= 1,
                _ if depth == 0 => column.push(c),
                _ => {}
            }
        }
        let column = column.split("  ").next().unwrap();
        let mut folder = "";
        for item in column.split(',').map(str::trim) {
            if item.starts_with("src/") {
                folder = &item[..item.trim_end_matches('/').rfind('/').unwrap() + 1];
                named.push(item.to_string());
            } else if !folder.is_empty() {
                named.push(format!("{folder}{item}"));
            }
        }
    }
    let missing: Vec<String> = modules_in(&root().join("src"), "")
        .into_iter()
        .filter(|module| !named.iter().any(|path| module.is_named_by(path)))
        .map(|module| module.shown())
        .collect();
    assert!(
        missing.is_empty(),
        "README.md's map (\"Where things live\") does not name {} top-level module(s): {}",
        missing.len(),
        missing.join(", ")
    );
}

/// The guide's `retrace tradeoff` table lists the oversampling settings the
/// sweep runs, no more and no fewer.
#[test]
fn the_guides_tradeoff_table_lists_the_oversampling_swept() {
    let guide = std::fs::read_to_string(root().join("docs/GUIDE.md")).unwrap();
    let row = guide
        .lines()
        .find(|l| l.starts_with("| RSVP oversampling |"))
        .expect("the tradeoff table has an oversampling row");
    let listed: Vec<String> = row
        .split('|')
        .nth(3)
        .unwrap()
        .split(',')
        .map(|s| s.replace("(default)", "").trim().to_string())
        .collect();
    let mut swept: Vec<String> = retrace::lab::tradeoff::rsvp_knob_settings()
        .iter()
        .map(|k| format!("{}x", k.oversample))
        .collect();
    swept.sort_by(|a, b| {
        a.trim_end_matches('x')
            .parse::<f64>()
            .unwrap()
            .total_cmp(&b.trim_end_matches('x').parse().unwrap())
    });
    swept.dedup();
    assert_eq!(listed, swept, "{row}");
}

//! The library's module graph runs one way: each top-level module uses
//! only modules of the layers below it, and the modules of one folder
//! (the reuse algorithms, the lab, ...) import each other without a cycle.
//! Read from the source, test code left out.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Top-level modules, lowest layer first.
const LAYERS: &[&[&str]] = &[
    &[
        "ray", "rng", "color", "sampling", "output", "chunk", "farm", "pool", "clock",
    ],
    &["geometry", "texture"],
    &["voxel", "camera"],
    &["timeline"],
    &["scene"],
    &["accel"],
    &["shade"],
    &["render"],
    &["aov"],
    &["metrics"],
    &["reuse"],
    &["frame_loop"],
    &["verify"],
    &["lab"],
    &["view"],
];

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|layer| layer.contains(&module))
}

/// The library's source files (the binary's `main.rs` and `cli/` are
/// above every layer, test-only files below none) with their module path.
fn library_files(src: &Path) -> Vec<(PathBuf, Vec<String>)> {
    let mut files = Vec::new();
    let mut folders = vec![src.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                if path != src.join("cli") {
                    folders.push(path);
                }
                continue;
            }
            let relative = path.strip_prefix(src).unwrap().with_extension("");
            let mut module: Vec<String> = relative
                .iter()
                .map(|part| part.to_string_lossy().into_owned())
                .collect();
            let name = module.last().cloned().unwrap_or_default();
            if path.extension().map_or(true, |e| e != "rs")
                || matches!(name.as_str(), "main" | "lib" | "tests")
            {
                continue;
            }
            if name == "mod" {
                module.pop();
            }
            files.push((path, module));
        }
    }
    files.sort();
    files
}

/// `text` without comments and without `#[cfg(test)]` items.
fn library_code(text: &str) -> String {
    let code: String = text
        .lines()
        .map(|line| match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = String::new();
    let mut rest = code.as_str();
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let item = &rest[at..];
        // The item (or field, or statement) ends at the brace closing its
        // body, at its `;` or `,`, or where the block around it closes.
        let (mut depth, mut end) = (0usize, item.len());
        for (i, c) in item.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    end = i;
                    break;
                }
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = i + 1;
                        break;
                    }
                }
                ';' | ',' if depth == 0 => {
                    end = i + 1;
                    break;
                }
                _ => {}
            }
        }
        rest = &item[end..];
    }
    out.push_str(rest);
    out
}

/// The module paths `code` (of module `module`) names: `crate::a::b` and
/// `super::x` (with `use crate::{a, b}` lists), as far as they go.
fn references(module: &[String], code: &str) -> BTreeSet<Vec<String>> {
    let mut found = BTreeSet::new();
    // The path's segments up to the first that does not go on with `::`.
    let words = |text: &str| -> Vec<String> {
        let mut path = Vec::new();
        for segment in text.split("::") {
            let word: String = segment
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let whole = word.len() == segment.len();
            if !word.is_empty() {
                path.push(word);
            }
            if !whole || path.is_empty() {
                break;
            }
        }
        path
    };
    for (at, _) in code.match_indices("crate::") {
        let after = &code[at + "crate::".len()..];
        if let Some(list) = after.strip_prefix('{') {
            let list = &list[..list.find('}').unwrap_or(list.len())];
            for item in list.split(',') {
                found.insert(words(item.trim()));
            }
        } else {
            found.insert(words(after));
        }
    }
    // `super::` is the parent module (a folder's `mod.rs` is the folder).
    let parent = module[..module.len().saturating_sub(1)].to_vec();
    for (at, _) in code.match_indices("super::") {
        let before = code[..at].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
            continue;
        }
        let mut path = parent.clone();
        path.extend(words(&code[at + "super::".len()..]));
        found.insert(path);
    }
    found.retain(|path| !path.is_empty());
    found
}

#[test]
fn each_module_uses_only_the_layers_below_it_and_no_folder_has_a_cycle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut upward = Vec::new();
    // Per folder, its child modules' imports of each other.
    let mut siblings: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (path, module) in library_files(&src) {
        let text = std::fs::read_to_string(&path).unwrap();
        let top = &module[0];
        let Some(layer) = layer_of(top) else {
            panic!("{}: module {top} is in no layer of LAYERS", path.display());
        };
        for used in references(&module, &library_code(&text)) {
            let other = &used[0];
            if other != top {
                match layer_of(other) {
                    Some(l) if l < layer => {}
                    _ => upward.push(format!(
                        "{} ({top}) uses crate::{}",
                        path.display(),
                        used.join("::")
                    )),
                }
                continue;
            }
            // Within one folder: which child uses which.
            let common = module.iter().zip(&used).take_while(|(a, b)| a == b).count();
            if common < module.len() && common < used.len() {
                siblings
                    .entry(module[..common].to_vec())
                    .or_default()
                    .entry(module[common].clone())
                    .or_default()
                    .insert(used[common].clone());
            }
        }
    }
    assert!(
        upward.is_empty(),
        "imports from a layer above or beside:\n{}",
        upward.join("\n")
    );
    for (folder, graph) in &siblings {
        // Depth-first search for a cycle.
        fn visit(
            node: &str,
            graph: &BTreeMap<String, BTreeSet<String>>,
            path: &mut Vec<String>,
            done: &mut BTreeSet<String>,
        ) -> Option<Vec<String>> {
            if let Some(at) = path.iter().position(|p| p == node) {
                let mut cycle = path[at..].to_vec();
                cycle.push(node.to_string());
                return Some(cycle);
            }
            if done.contains(node) {
                return None;
            }
            path.push(node.to_string());
            for next in graph.get(node).into_iter().flatten() {
                if let Some(cycle) = visit(next, graph, path, done) {
                    return Some(cycle);
                }
            }
            path.pop();
            done.insert(node.to_string());
            None
        }
        let mut done = BTreeSet::new();
        for node in graph.keys() {
            if let Some(cycle) = visit(node, graph, &mut Vec::new(), &mut done) {
                panic!(
                    "an import cycle in src/{}: {}",
                    folder.join("/"),
                    cycle.join(" -> ")
                );
            }
        }
    }
}

#[test]
fn the_checker_sees_crate_paths_lists_and_super() {
    let module = vec!["reuse".to_string(), "pan".to_string()];
    let code = library_code(
        "use crate::render::Frame;\nuse crate::{camera::Camera, ray};\nuse super::ostc::Ostc; // crate::lab\n#[cfg(test)]\nmod tests { use crate::lab::bench; }\n",
    );
    let found = references(&module, &code);
    let names: Vec<String> = found.iter().map(|p| p.join("::")).collect();
    assert_eq!(
        names,
        [
            "camera::Camera",
            "ray",
            "render::Frame",
            "reuse::ostc::Ostc"
        ]
    );
}

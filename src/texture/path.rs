//! Finding the image an MTL or scene file names, as its author wrote it:
//! relative to the naming file's folder, with Windows separators
//! (`.\wal67ar_small.jpg`), spaces in names, MTL options before the name
//! (`-s 2 2 1 tiles.png`), and, failing an exact match, a file whose name
//! differs only in case (files made on Windows or macOS, where case does
//! not matter).

use std::path::{Component, Path, PathBuf};

/// Options `map_Kd` and its kin may put before the file name, with how
/// many values each takes (`-o`, `-s` and `-t` take one to three numbers).
const MTL_OPTIONS: &[(&str, usize)] = &[
    ("-blendu", 1),
    ("-blendv", 1),
    ("-bm", 1),
    ("-boost", 1),
    ("-cc", 1),
    ("-clamp", 1),
    ("-imfchan", 1),
    ("-mm", 2),
    ("-texres", 1),
    ("-type", 1),
    ("-o", 3),
    ("-s", 3),
    ("-t", 3),
];

/// The file name of an MTL texture statement's arguments (what follows
/// `map_Kd`), its options left out, and the options it had.
pub fn mtl_file_name(arguments: &str) -> (String, Vec<String>) {
    let arguments = arguments.trim();
    // Each word with where it starts, so the name keeps its own spaces.
    let words: Vec<(usize, &str)> = arguments
        .split_whitespace()
        .map(|word| (word.as_ptr() as usize - arguments.as_ptr() as usize, word))
        .collect();
    let mut options = Vec::new();
    let mut next = 0;
    while let Some(&(start, word)) = words.get(next) {
        let Some(&(_, takes)) = MTL_OPTIONS.iter().find(|(o, _)| *o == word) else {
            break;
        };
        let variable = matches!(word, "-o" | "-s" | "-t");
        let mut end = next + 1;
        while end < words.len() && end - next <= takes {
            if variable && end > next + 1 && words[end].1.parse::<f32>().is_err() {
                break;
            }
            end += 1;
        }
        let (last_start, last) = words[end - 1];
        options.push(arguments[start..last_start + last.len()].to_string());
        next = end;
    }
    let name = words
        .get(next)
        .map_or("", |&(start, _)| &arguments[start..])
        .trim_matches('"')
        .to_string();
    (name, options)
}

/// Where a named texture was found.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    pub path: PathBuf,
    /// Found only by ignoring case (worth a warning: the file is not named
    /// as written, and a case-sensitive system elsewhere may not find it).
    pub case_differs: bool,
}

/// `folder` as a message shows where it looked: `.` for the current
/// folder (a file named without a folder), which would show as nothing.
pub fn shown(folder: &Path) -> std::path::Display<'_> {
    if folder.as_os_str().is_empty() {
        Path::new(".").display()
    } else {
        folder.display()
    }
}

/// The file `written` names, relative to `folder` unless absolute; `None`
/// when there is none, even ignoring case.
pub fn resolve(folder: &Path, written: &str) -> Option<Resolved> {
    // A backslash is a separator only on Windows, but a file name holding
    // one is far rarer than an MTL written there.
    let written = written.replace('\\', "/");
    let relative = Path::new(&written);
    let exact = folder.join(relative);
    if exact.is_file() {
        return Some(Resolved {
            path: exact,
            case_differs: false,
        });
    }
    let mut found = if relative.is_absolute() {
        PathBuf::from("/")
    } else {
        folder.to_path_buf()
    };
    for component in relative.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => found.push(".."),
            Component::Normal(name) => {
                let direct = found.join(name);
                if direct.exists() {
                    found = direct;
                    continue;
                }
                let wanted = name.to_string_lossy().to_lowercase();
                let listed = if found.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    &found
                };
                let mut matches: Vec<PathBuf> = std::fs::read_dir(listed)
                    .ok()?
                    .filter_map(|entry| entry.ok())
                    .filter(|entry| entry.file_name().to_string_lossy().to_lowercase() == wanted)
                    .map(|entry| found.join(entry.file_name()))
                    .collect();
                // Several names differing only in case: take the first in
                // order, so the choice does not depend on the directory.
                matches.sort();
                found = matches.into_iter().next()?;
            }
            Component::RootDir | Component::Prefix(_) => {}
        }
    }
    found.is_file().then_some(Resolved {
        path: found,
        case_differs: true,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_before_the_name_are_left_out_and_spaces_kept() {
        assert_eq!(
            mtl_file_name(".\\wal67ar_small.jpg"),
            (".\\wal67ar_small.jpg".to_string(), vec![])
        );
        assert_eq!(
            mtl_file_name("my old tiles.png"),
            ("my old tiles.png".to_string(), vec![])
        );
        let (name, options) = mtl_file_name("-s 2 2 -bm 0.5 -clamp on  textures/brick wall.tga");
        assert_eq!(name, "textures/brick wall.tga");
        assert_eq!(options, ["-s 2 2", "-bm 0.5", "-clamp on"]);
        let (name, options) = mtl_file_name("-o 0.5 tex.png");
        assert_eq!((name.as_str(), options.len()), ("tex.png", 1));
    }

    #[test]
    fn backslashes_folders_and_case_differences_resolve() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path();
        std::fs::create_dir(folder.join("Maps")).unwrap();
        std::fs::write(folder.join("wal67ar_small.jpg"), b"x").unwrap();
        std::fs::write(folder.join("Maps").join("Brick Wall.PNG"), b"x").unwrap();
        let exact = resolve(folder, ".\\wal67ar_small.jpg").unwrap();
        assert_eq!(exact.path, folder.join("./wal67ar_small.jpg"));
        assert!(!exact.case_differs);
        let spaced = resolve(folder, "Maps\\Brick Wall.PNG").unwrap();
        assert!(!spaced.case_differs && spaced.path.is_file());
        let folded = resolve(folder, "maps/brick wall.png").unwrap();
        assert_eq!(folded.path, folder.join("Maps").join("Brick Wall.PNG"));
        assert!(folded.case_differs);
        assert_eq!(resolve(folder, "maps/stone wall.png"), None);
        assert_eq!(resolve(folder, "nowhere/brick wall.png"), None);
        // Absolute paths resolve on their own.
        let absolute = folder.join("wal67ar_small.jpg");
        let found = resolve(Path::new("elsewhere"), absolute.to_str().unwrap()).unwrap();
        assert_eq!(found.path, absolute);
    }
}

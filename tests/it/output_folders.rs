//! An output whose folder cannot be made because a file has its name:
//! every command names the folder and the problem, before any work, and
//! writes nothing (issue 34).

use std::path::Path;
use std::process::Output;

use crate::common::retrace;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

const SCENE: &str = "[render]\nwidth = 16\nheight = 12\n\
                     [camera]\nposition = [0, 1, 5]\nfov = 60\n\
                     [[light]]\nposition = [0, 5, 0]\n\
                     [[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n\
                     [animation]\nframes = 2\n";

/// Runs `args` in a folder holding `s.toml` and a file `some_file.png`,
/// and checks the failure: exit 1, `message` alone, nothing new written.
fn assert_refused(args: &[&str], message: &str) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("s.toml"), SCENE).unwrap();
    std::fs::write(dir.path().join("some_file.png"), "not a folder").unwrap();
    let out = retrace(args, dir.path());
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    // The lab's commands warn first in a debug build.
    let said: String = stderr(&out)
        .lines()
        .filter(|l| !l.starts_with("warning: this is a debug build"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert_eq!(said, format!("error: {message}\n"), "{args:?}");
    let mut left: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["s.toml", "some_file.png"], "{args:?}");
    assert_eq!(
        std::fs::read_to_string(dir.path().join("some_file.png")).unwrap(),
        "not a folder"
    );
}

#[test]
fn a_file_in_the_way_of_an_output_folder_is_named() {
    let blocked =
        "cannot make the folder some_file.png for x.png: a file of that name is in the way";
    assert_refused(&["render", "s.toml", "-o", "some_file.png/x.png"], blocked);
    // Deeper: the file is still what is named.
    assert_refused(
        &["render", "s.toml", "-o", "some_file.png/a/b/x.png"],
        blocked,
    );
    assert_refused(
        &["animate", "s.toml", "-o", "some_file.png/f_##.png"],
        "cannot make the folder some_file.png: a file of that name is in the way",
    );
    assert_refused(
        &[
            "animate",
            "s.toml",
            "-o",
            "f_##.png",
            "--stats",
            "some_file.png/stats.csv",
        ],
        "cannot make the folder some_file.png: a file of that name is in the way",
    );
    assert_refused(
        &["tradeoff", "--frames", "0-1", "--out", "some_file.png"],
        "cannot make the folder some_file.png: a file of that name is in the way",
    );
}

#[test]
fn an_output_folder_that_is_not_there_is_made() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("s.toml"), SCENE).unwrap();
    let out = retrace(&["render", "s.toml", "-o", "a/b/x.png"], dir.path());
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(Path::new(&dir.path().join("a/b/x.png")).is_file());
}

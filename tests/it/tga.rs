//! TGA frames as another program reads them: Pillow (Python's imaging
//! library, a decoder of its own, strict about packets that cross rows)
//! must decode every TGA that `render` and `animate` write, to the pixels of
//! the PNG written of the same frame.

use std::path::Path;
use std::process::Command;

use crate::common::retrace_ok;

/// A Python that can import Pillow: Debian's python3-pil goes with
/// /usr/bin/python3, which another python3 (a pyenv one) may hide on PATH.
fn python_with_pillow() -> Option<String> {
    ["python3", "/usr/bin/python3"]
        .into_iter()
        .find(|python| {
            Command::new(python)
                .args(["-c", "import PIL.Image"])
                .output()
                .is_ok_and(|out| out.status.success())
        })
        .map(str::to_string)
}

/// Decodes `tga` with Pillow into (width, height, RGB bytes).
fn pillow_decode(python: &str, tga: &Path) -> (u32, u32, Vec<u8>) {
    let script = "import sys\nfrom PIL import Image\n\
                  im = Image.open(sys.argv[1])\nim.load()\n\
                  sys.stdout.write('%d %d\\n' % im.size)\nsys.stdout.flush()\n\
                  sys.stdout.buffer.write(im.convert('RGB').tobytes())\n";
    let out = Command::new(python)
        .args(["-c", script])
        .arg(tga)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "Pillow cannot read {}: {}",
        tga.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let newline = out.stdout.iter().position(|&b| b == b'\n').unwrap();
    let size = String::from_utf8_lossy(&out.stdout[..newline]).into_owned();
    let (width, height) = size.split_once(' ').unwrap();
    (
        width.parse().unwrap(),
        height.parse().unwrap(),
        out.stdout[newline + 1..].to_vec(),
    )
}

/// Checks that Pillow reads `name.tga` in `dir` as the pixels of `name.png`.
fn assert_pillow_reads_as_png(python: &str, dir: &Path, name: &str) {
    let tga = dir.join(format!("{name}.tga"));
    let png = image::open(dir.join(format!("{name}.png")))
        .unwrap()
        .to_rgb8();
    let (width, height, pixels) = pillow_decode(python, &tga);
    assert_eq!((width, height), png.dimensions(), "{name}.tga: size");
    let differing = pixels
        .chunks_exact(3)
        .zip(png.pixels())
        .filter(|(a, b)| *a != b.0)
        .count();
    assert_eq!(pixels.len(), png.as_raw().len(), "{name}.tga: pixel bytes");
    assert_eq!(differing, 0, "{name}.tga: pixels differ from {name}.png");
}

#[test]
fn pillow_reads_every_tga_the_program_writes() {
    let Some(python) = python_with_pillow() else {
        let message = "Python 3 with Pillow is needed to check TGA output against \
                       another decoder (Debian package python3-pil; `make deps` installs it)";
        crate::common::skip_unless_ci(message);
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let size = ["--width", "64", "--height", "48"];
    for ext in ["tga", "png"] {
        let output = format!("still.{ext}");
        retrace_ok(
            &[&["render", "-o", &output][..], &size].concat(),
            dir.path(),
        );
    }
    assert_pillow_reads_as_png(&python, dir.path(), "still");

    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper-bounce.toml");
    let scene = scene.to_str().unwrap();
    for ext in ["tga", "png"] {
        let output = format!("frame_##.{ext}");
        let args = [
            &["animate", scene, "--frames", "0-3", "-o", &output][..],
            &size,
        ]
        .concat();
        retrace_ok(&args, dir.path());
    }
    for frame in 0..4 {
        assert_pillow_reads_as_png(&python, dir.path(), &format!("frame_{frame:02}"));
    }
}

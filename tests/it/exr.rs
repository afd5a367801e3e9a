//! OpenEXR frames as other programs read them: the `exr` crate reads back
//! what `render` and `animate` write (linear half floats equal to the full
//! render's, AOV layers that say what the primary rays met, the reuse
//! mask), and OpenImageIO's `iinfo` and `oiiotool`, programs written
//! elsewhere, list the layers and read the pixels.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use exr::prelude::{f16, FlatSamples};
use retrace::accel::{Accelerator, BackendKind};
use retrace::reuse::pan::EqualAngleLattice;
use retrace::scene::{load_scene, Scene, SceneOverrides};

use crate::common::{retrace, retrace_ok};

const ALL_AOVS: &str = "depth,normal,albedo,object,traced";

/// Every channel an EXR frame with all AOVs has.
const ALL_CHANNELS: [&str; 13] = [
    "A",
    "B",
    "G",
    "N.x",
    "N.y",
    "N.z",
    "R",
    "albedo.B",
    "albedo.G",
    "albedo.R",
    "depth.Z",
    "object.id",
    "traced.mask",
];

fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

fn load(name: &str, width: u32, height: u32) -> Scene {
    let overrides = SceneOverrides {
        width: Some(width),
        height: Some(height),
        ..SceneOverrides::default()
    };
    load_scene(&scene_path(name), &overrides).unwrap()
}

/// An EXR file as the `exr` crate reads it: its size and its channels by
/// name.
struct Read {
    width: usize,
    height: usize,
    channels: HashMap<String, FlatSamples>,
}

impl Read {
    fn of(path: &Path) -> Read {
        let image = exr::prelude::read_first_flat_layer_from_file(path)
            .unwrap_or_else(|err| panic!("{}: {err}", path.display()));
        let layer = image.layer_data;
        Read {
            width: layer.size.0,
            height: layer.size.1,
            channels: layer
                .channel_data
                .list
                .into_iter()
                .map(|c| (c.name.to_string(), c.sample_data))
                .collect(),
        }
    }

    fn names(&self) -> Vec<&str> {
        let mut names: Vec<&str> = self.channels.keys().map(String::as_str).collect();
        names.sort_unstable();
        names
    }

    fn half(&self, name: &str) -> &[f16] {
        match &self.channels[name] {
            FlatSamples::F16(v) => v,
            other => panic!("{name}: not half floats: {other:?}"),
        }
    }

    fn float(&self, name: &str) -> &[f32] {
        match &self.channels[name] {
            FlatSamples::F32(v) => v,
            other => panic!("{name}: not 32-bit floats: {other:?}"),
        }
    }

    /// The channels' samples at pixel `index`, as bits: equal bits, equal
    /// values.
    fn bits(&self, name: &str, index: usize) -> u32 {
        match &self.channels[name] {
            FlatSamples::F16(v) => u32::from(v[index].to_bits()),
            FlatSamples::F32(v) => v[index].to_bits(),
            FlatSamples::U32(v) => v[index],
        }
    }
}

#[test]
fn render_writes_linear_half_rgba_equal_to_the_full_render_with_every_aov() {
    let dir = tempfile::tempdir().unwrap();
    let (width, height) = (96, 72);
    let scene = scene_path("paper.toml");
    retrace_ok(
        &[
            "render",
            scene.to_str().unwrap(),
            "--width",
            "96",
            "--height",
            "72",
            "-o",
            "still.exr",
            "--aov",
            ALL_AOVS,
        ],
        dir.path(),
    );
    let read = Read::of(&dir.path().join("still.exr"));
    assert_eq!((read.width, read.height), (96, 72));
    assert_eq!(read.names(), ALL_CHANNELS);

    // The colours are the full render's, each f32 turned into the same
    // half float.
    let scene = load("paper.toml", width, height);
    let accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
    let (frame, _) = retrace::render::render_frame(&scene, &accel);
    for (axis, name) in ["R", "G", "B"].into_iter().enumerate() {
        let written = read.half(name);
        let differing = frame
            .pixels
            .iter()
            .zip(written)
            .filter(|(p, w)| f16::from_f32(p[axis]).to_bits() != w.to_bits())
            .count();
        assert_eq!(
            differing, 0,
            "{name}: pixels differing from the full render"
        );
    }
    assert!(read.half("A").iter().all(|&a| a == f16::ONE));
    // A still render traces every pixel.
    assert!(read.half("traced.mask").iter().all(|&t| t == f16::ONE));
}

#[test]
fn depth_normal_albedo_and_object_say_what_the_centre_ray_met() {
    let dir = tempfile::tempdir().unwrap();
    let (width, height) = (128u32, 96u32);
    let scene_file = scene_path("paper.toml");
    retrace_ok(
        &[
            "render",
            scene_file.to_str().unwrap(),
            "--width",
            "128",
            "--height",
            "96",
            "-o",
            "still.exr",
            "--aov",
            "depth,normal,albedo,object",
        ],
        dir.path(),
    );
    let read = Read::of(&dir.path().join("still.exr"));
    assert!(!read.channels.contains_key("traced.mask"), "not asked for");
    let scene = load("paper.toml", width, height);
    let camera = &scene.camera;
    let ball = scene
        .objects
        .iter()
        .position(|o| o.name == "mirror ball")
        .unwrap();
    let retrace::geometry::Shape::Sphere(sphere) = &scene.objects[ball].shape else {
        panic!("the mirror ball is a sphere");
    };
    let (centre, radius) = (sphere.center.as_dvec3(), f64::from(sphere.radius));
    let eye = camera.position;
    let mirror = scene.materials[scene.objects[ball].material].diffuse;

    let (depth, ids) = (read.float("depth.Z"), read.float("object.id"));
    let normal = ["N.x", "N.y", "N.z"].map(|n| read.half(n));
    let albedo = ["albedo.R", "albedo.G", "albedo.B"].map(|n| read.half(n));
    let mut ball_pixels = 0;
    // The pixel looking most nearly at the ball's centre.
    let mut centre_pixel = (f64::NEG_INFINITY, 0);
    for y in 0..height {
        for x in 0..width {
            let index = (y * width + x) as usize;
            let ray = camera.primary_ray(x, y).unwrap();
            let dir = ray.dir.as_dvec3().normalize();
            if ids[index] == 0.0 {
                assert_eq!(
                    depth[index],
                    f32::INFINITY,
                    "({x}, {y}): a miss is infinitely far"
                );
                continue;
            }
            assert!(depth[index].is_finite() && depth[index] > 0.0);
            let object = ids[index] as usize - 1;
            assert!(
                object < scene.objects.len(),
                "({x}, {y}): id {}",
                ids[index]
            );
            if object != ball {
                continue;
            }
            ball_pixels += 1;
            // The ray meets the sphere where |eye + t dir - centre| = r.
            let to_eye = eye - centre;
            let b = to_eye.dot(dir);
            let t = -b - (b * b - to_eye.length_squared() + radius * radius).sqrt();
            assert!(
                (f64::from(depth[index]) - t).abs() < 1e-4 * t,
                "({x}, {y}): depth {} against {t}",
                depth[index]
            );
            let outward = (eye + dir * t - centre) / radius;
            for axis in 0..3 {
                let written = f64::from(normal[axis][index].to_f32());
                assert!(
                    (written - outward[axis]).abs() < 2e-3,
                    "({x}, {y}): normal {axis} {written} against {}",
                    outward[axis]
                );
                assert_eq!(albedo[axis][index], f16::from_f32(mirror[axis]));
            }
            let facing = dir.dot((centre - eye).normalize());
            if facing > centre_pixel.0 {
                centre_pixel = (facing, index);
            }
        }
    }
    assert!(ball_pixels > 50, "{ball_pixels} pixels show the ball");
    // At its centre pixel the ball is its radius nearer than its centre.
    let expected = (centre - eye).length() - radius;
    let at_centre = f64::from(depth[centre_pixel.1]);
    assert!(
        (at_centre - expected).abs() < 1e-3 * expected,
        "centre pixel depth {at_centre}, distance to the surface {expected}"
    );
}

/// The columns of `read`'s traced mask that are 1, checking that each is
/// 1 (or 0) in every row.
fn traced_columns(read: &Read) -> Vec<usize> {
    let mask = read.half("traced.mask");
    (0..read.width)
        .filter(|&x| {
            let column: Vec<f16> = (0..read.height).map(|y| mask[y * read.width + x]).collect();
            assert!(
                column.iter().all(|&t| t == column[0]),
                "column {x} is traced in some rows only"
            );
            assert!(column[0] == f16::ONE || column[0] == f16::ZERO);
            column[0] == f16::ONE
        })
        .collect()
}

#[test]
fn a_pan_frames_traced_channel_is_the_newly_exposed_columns() {
    let dir = tempfile::tempdir().unwrap();
    let (width, height) = (320u32, 240u32);
    let scene_file = scene_path("paper-pan.toml");
    retrace_ok(
        &[
            "animate",
            scene_file.to_str().unwrap(),
            "--width",
            "320",
            "--height",
            "240",
            "--frames",
            "0-3",
            "-o",
            "pan_#.exr",
            "--aov",
            "depth,traced",
            "--dirty-image",
            "dirty_#.png",
        ],
        dir.path(),
    );
    let scene = load("paper-pan.toml", width, height);
    let animation = scene.animation.as_ref().unwrap();
    let column_of = |frame: u32| {
        let camera = animation.camera_at(&scene.camera, frame);
        EqualAngleLattice::for_camera(&camera).window(&camera).col
    };
    let first = Read::of(&dir.path().join("pan_0.exr"));
    assert_eq!(
        first.names(),
        ["A", "B", "G", "R", "depth.Z", "traced.mask"]
    );
    assert_eq!(
        traced_columns(&first).len(),
        width as usize,
        "frame 0 traces all"
    );
    for frame in 1..=3 {
        let read = Read::of(&dir.path().join(format!("pan_{frame}.exr")));
        let columns = traced_columns(&read);
        // The pan turns right: the new columns come in at the right edge.
        let exposed = (column_of(frame) - column_of(frame - 1)) as usize;
        assert!(exposed > 5, "{exposed} columns a frame");
        let traced = columns.len();
        assert_eq!(
            columns,
            (width as usize - traced..width as usize).collect::<Vec<_>>(),
            "frame {frame}: the traced columns are the rightmost ones"
        );
        // The previous frame traced whole groups of 4 columns, so up to
        // 3 of the exposed columns may already have been traced.
        assert!(
            (exposed - 3..=exposed).contains(&traced),
            "frame {frame}: {traced} columns traced, {exposed} exposed"
        );
        // A snapped pan's pixels are lattice samples: the depth a column
        // shows is the one it showed `exposed` columns further right, to
        // the bit.
        let earlier = Read::of(&dir.path().join(format!("pan_{}.exr", frame - 1)));
        let (now, before) = (read.float("depth.Z"), earlier.float("depth.Z"));
        for y in 0..height as usize {
            for x in 0..width as usize - exposed {
                let at = y * width as usize;
                assert_eq!(
                    now[at + x].to_bits(),
                    before[at + x + exposed].to_bits(),
                    "frame {frame}: depth at ({x}, {y})"
                );
            }
        }
        // The same mask the paper's figure 4 picture shows in black.
        let dirty = image::open(dir.path().join(format!("dirty_{frame}.png")))
            .unwrap()
            .to_rgb8();
        let mask = read.half("traced.mask");
        for (index, pixel) in dirty.pixels().enumerate() {
            assert_eq!(
                pixel.0 == [0; 3],
                mask[index] == f16::ONE,
                "frame {frame}, pixel {index}"
            );
        }
    }
}

/// Runs `animate` on `scene` writing `pattern` with every AOV.
fn animate_exr(dir: &Path, scene: &str, frames: &str, pattern: &str, extra: &[&str]) -> String {
    let scene = scene_path(scene);
    let args = [
        &[
            "animate",
            scene.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
            "--frames",
            frames,
            "-o",
            pattern,
            "--aov",
            ALL_AOVS,
        ][..],
        extra,
    ]
    .concat();
    let out = retrace_ok(&args, dir);
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn reused_exr_frames_verify_and_equal_full_renders_but_for_the_traced_mask() {
    let dir = tempfile::tempdir().unwrap();
    // A pan (the pan lattice's store) and a bouncing ball (OSTC).
    for scene in ["paper-pan.toml", "paper-bounce.toml"] {
        let said = animate_exr(dir.path(), scene, "0-3", "reused_#.exr", &["--verify"]);
        assert!(
            said.contains("every frame equals its full render bit for bit"),
            "{scene}: {said}"
        );
        animate_exr(dir.path(), scene, "0-3", "full_#.exr", &["--mode", "full"]);
        let mut reused_somewhere = false;
        for frame in 0..=3 {
            let reused = Read::of(&dir.path().join(format!("reused_{frame}.exr")));
            let full = Read::of(&dir.path().join(format!("full_{frame}.exr")));
            assert_eq!(reused.names(), ALL_CHANNELS);
            assert_eq!(full.names(), ALL_CHANNELS);
            for name in ALL_CHANNELS.iter().filter(|&&n| n != "traced.mask") {
                let differing = (0..64 * 48)
                    .filter(|&i| reused.bits(name, i) != full.bits(name, i))
                    .count();
                assert_eq!(differing, 0, "{scene} frame {frame}: {name} differs");
            }
            assert!(full.half("traced.mask").iter().all(|&t| t == f16::ONE));
            reused_somewhere |= reused.half("traced.mask").contains(&f16::ZERO);
        }
        assert!(reused_somewhere, "{scene}: no pixel was reused");
    }
}

#[test]
fn bad_aov_names_and_aovs_without_exr_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // What the command says, failing, at a small size.
    let refused = |command: &[&str]| {
        let out = retrace(
            &[command, &["--width", "16", "--height", "8"]].concat(),
            dir.path(),
        );
        assert!(!out.status.success(), "{command:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = refused(&["render", "-o", "a.exr", "--aov", "depth,colour"]);
    assert!(err.contains("unknown AOV 'colour'"), "{err}");
    assert!(
        err.contains("depth, normal, albedo, object, traced"),
        "{err}"
    );
    for command in [
        &["render", "-o", "a.png", "--aov", "depth"][..],
        &[
            "animate", "-o", "f_#.png", "--aov", "traced", "--frames", "0",
        ][..],
    ] {
        let err = refused(command);
        assert!(err.contains("--aov") && err.contains(".exr"), "{err}");
    }
    // An 8-bit picture of the run is not a frame: no EXR for it.
    let err = refused(&["animate", "-o", "f_#.exr", "--dirty-image", "d_#.exr"]);
    assert!(err.contains("use .png or .tga"), "{err}");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "nothing written"
    );
}

/// Runs an OpenImageIO tool, None if it is not installed.
fn oiio(tool: &str, args: &[&str], dir: &Path) -> Option<String> {
    let out = Command::new(tool)
        .args(args)
        .current_dir(dir)
        .output()
        .ok()?;
    assert!(
        out.status.success(),
        "{tool} {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The figures of one `Stats NAME:` line of `oiiotool --printstats`, one
/// per channel.
fn stats_line(stats: &str, name: &str) -> Vec<f64> {
    let line = stats
        .lines()
        .find_map(|l| l.trim().strip_prefix(&format!("Stats {name}:")))
        .unwrap_or_else(|| panic!("no Stats {name} in:\n{stats}"));
    line.split_whitespace()
        .filter_map(|word| word.parse().ok())
        .collect()
}

#[test]
fn openimageio_lists_the_layers_and_reads_the_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_path("paper-pan.toml");
    retrace_ok(
        &[
            "animate",
            scene.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
            "--frames",
            "0-1",
            "-o",
            "f_#.exr",
            "--aov",
            ALL_AOVS,
        ],
        dir.path(),
    );
    let Some(info) = oiio("iinfo", &["-v", "f_1.exr"], dir.path()) else {
        crate::common::skip_unless_ci(
            "OpenImageIO's iinfo and oiiotool are needed to read EXR frames with another \
             program (Debian package openimageio-tools; `make test-deps` installs it)",
        );
        return;
    };
    let list = info
        .lines()
        .find_map(|l| l.trim().strip_prefix("channel list:"))
        .unwrap_or_else(|| panic!("no channel list in:\n{info}"));
    let listed: Vec<String> = list
        .split(',')
        .map(|c| c.split_whitespace().next().unwrap().to_string())
        .collect();
    let mut sorted = listed.clone();
    sorted.sort();
    assert_eq!(sorted, ALL_CHANNELS, "iinfo -v lists {listed:?}");
    let words: Vec<&str> = info.split_whitespace().collect();
    assert!(words.windows(3).any(|w| w == ["64", "x", "48,"]), "{info}");

    // oiiotool reads the pixels: its figures, channel by channel in the
    // order iinfo lists them, are ours.
    let stats = oiio("oiiotool", &["f_1.exr", "--printstats"], dir.path()).unwrap();
    let read = Read::of(&dir.path().join("f_1.exr"));
    let (min, max, infinite) = (
        stats_line(&stats, "Min"),
        stats_line(&stats, "Max"),
        stats_line(&stats, "InfCount"),
    );
    assert_eq!(min.len(), listed.len(), "{stats}");
    for (channel, name) in listed.iter().enumerate() {
        let values: Vec<f64> = (0..64 * 48)
            .map(|i| match &read.channels[name] {
                FlatSamples::F16(v) => f64::from(v[i].to_f32()),
                FlatSamples::F32(v) => f64::from(v[i]),
                FlatSamples::U32(v) => f64::from(v[i]),
            })
            .collect();
        let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        let ours_min = finite.iter().copied().fold(f64::INFINITY, f64::min);
        let ours_max = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        // oiiotool prints six significant digits.
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-5 * b.abs().max(1.0);
        assert!(
            close(min[channel], ours_min),
            "{name}: min {} against {ours_min}",
            min[channel]
        );
        assert!(
            close(max[channel], ours_max),
            "{name}: max {} against {ours_max}",
            max[channel]
        );
        let ours_infinite = values.len() - finite.len();
        assert_eq!(
            infinite[channel], ours_infinite as f64,
            "{name}: infinities"
        );
    }
    // The sky is infinitely far, and the pan's frame 1 reused pixels.
    let depth = listed.iter().position(|n| n == "depth.Z").unwrap();
    assert!(infinite[depth] > 0.0);
    let traced = listed.iter().position(|n| n == "traced.mask").unwrap();
    assert_eq!((min[traced], max[traced]), (0.0, 1.0));
}

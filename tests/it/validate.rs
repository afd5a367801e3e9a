//! `retrace validate`: Embree against the pure-Rust grid, from the command
//! line.

use crate::common::retrace;

#[test]
fn validate_passes_on_the_paper_scene_and_writes_its_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &[
            "validate", "--width", "64", "--height", "48", "--rays", "2000", "--json", "v.json",
        ],
        dir.path(),
    );
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(said.contains("camera") && said.contains("random"), "{said}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("v.json")).unwrap()).unwrap();
    assert_eq!(report["failures"], serde_json::json!([]), "{report}");
    assert_eq!(report["camera_rays"]["rays"], 64 * 48, "{report}");
    assert_eq!(report["random_rays"]["rays"], 2000, "{report}");
}

#[test]
fn rays_that_hit_nothing_in_both_backends_agree() {
    // No random rays, and a camera looking up at the empty sky: no ray
    // hits in either backend, which is agreement, not a failure.
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &[
            "validate", "--width", "32", "--height", "24", "--rays", "0", "--json", "v.json",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let scene = "[camera]\nposition = [0, 1, 5]\npitch = 80\nfov = 20\n\n\
                 [[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n";
    std::fs::write(dir.path().join("sky.toml"), scene).unwrap();
    let out = retrace(
        &[
            "validate", "sky.toml", "--width", "32", "--height", "24", "--rays", "0", "--json",
            "v.json",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("v.json")).unwrap()).unwrap();
    assert_eq!(report["camera_rays"]["both_hit"], 0, "{report}");
    assert_eq!(report["failures"], serde_json::json!([]), "{report}");
}

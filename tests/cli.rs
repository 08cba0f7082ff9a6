//! The `assetfield` binary end to end: help, the main job on a small scale, and bad input
//! (clear message naming the place, non-zero exit, nothing half-written).

use assetfield_tests::{repo, run_cli, scratch};

#[test]
fn help_explains_every_command() {
    let dir = scratch("help");
    let (code, out, _) = run_cli(&dir, &["--help"]);
    assert_eq!(code, 0);
    for cmd in ["synth", "inspect", "layout"] {
        assert!(out.contains(cmd), "{out}");
    }
    let (code, out, _) = run_cli(&dir, &["synth", "--help"]);
    assert_eq!(code, 0);
    assert!(
        out.contains("--views")
            && out.contains("--res")
            && out.contains("--edited")
            && out.contains("gt_layout.json"),
        "{out}"
    );
    let (code, _, err) = run_cli(&dir, &["synth"]);
    assert_eq!(code, 2, "missing argument is a usage error: {err}");
}

#[test]
fn synth_then_inspect_then_layout() {
    let dir = scratch("main-job");
    let scene = repo().join("scenes/cafe.ron");
    let (code, out, err) = run_cli(
        &dir,
        &[
            "synth",
            scene.to_str().unwrap(),
            "--out",
            "cafe",
            "--views",
            "5",
            "--test-views",
            "1",
            "--res",
            "32",
            "--aa",
            "1",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("cafe") && out.contains("4 train + 1 test"), "{out}");
    let (code, out, err) = run_cli(&dir, &["inspect", "cafe", "--picture", "cams.png"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("32") && dir.join("cams.png").exists(), "{out}");
    let (code, out, err) =
        run_cli(&dir, &["layout", scene.to_str().unwrap(), "--picture", "top.png"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("tables[0]/stools[2]") && dir.join("top.png").exists(), "{out}");
    // without --force an existing output is refused and left as it was
    let before = std::fs::read(dir.join("cafe/gt_layout.json")).unwrap();
    let (code, _, err) = run_cli(
        &dir,
        &[
            "synth",
            scene.to_str().unwrap(),
            "--out",
            "cafe",
            "--views",
            "3",
            "--test-views",
            "1",
            "--res",
            "16",
        ],
    );
    assert_eq!(code, 1);
    assert!(err.contains("already exists") && err.contains("--force"), "{err}");
    assert_eq!(std::fs::read(dir.join("cafe/gt_layout.json")).unwrap(), before);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn expect_failure(dir: &std::path::Path, args: &[&str], needles: &[&str]) {
    let (code, _, err) = run_cli(dir, args);
    assert_eq!(code, 1, "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: expected {n:?} in: {err}");
    }
}

#[test]
fn bad_scripts_fail_with_file_line_and_column() {
    let dir = scratch("bad-scripts");
    let assets = repo().join("scenes/assets/furniture.ron");
    let inc = assets.to_str().unwrap();
    std::fs::write(
        dir.join("typo.ron"),
        "Scene(\n  layout: [\n    Instance(asset: \"chair\" at: (0, 0)),\n  ],\n)\n",
    )
    .unwrap();
    expect_failure(&dir, &["synth", "typo.ron", "--res", "16"], &["typo.ron:3:", "syntax error"]);
    std::fs::write(dir.join("unknown.ron"), format!("Scene(\n  include: [{inc:?}],\n  layout: [\n    Instance(asset: \"chiar\", at: (0, 0)),\n  ],\n)\n")).unwrap();
    expect_failure(
        &dir,
        &["synth", "unknown.ron", "--res", "16"],
        &["unknown.ron:4:21", "unknown asset \"chiar\"", "did you mean \"chair\""],
    );
    std::fs::write(
        dir.join("crowded.ron"),
        format!("Scene(\n  include: [{inc:?}],\n  layout: [\n    Scatter(asset: \"sofa\", region: Rect(min: (0, 0), max: (2, 2)), count: 9, min_distance: 1),\n  ],\n)\n"),
    )
    .unwrap();
    expect_failure(
        &dir,
        &["synth", "crowded.ron", "--res", "16"],
        &["crowded.ron:4:5", "could place only"],
    );
    expect_failure(&dir, &["synth", "missing.ron"], &["missing.ron", "cannot read script"]);
    expect_failure(&dir, &["layout", "unknown.ron"], &["unknown.ron:4:21"]);
    // nothing was written for any of them
    assert!(!dir.join("runs").exists(), "failed runs must not leave output");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_datasets_name_the_file_and_frame() {
    let dir = scratch("bad-data");
    expect_failure(&dir, &["inspect", "."], &["transforms"]);
    // a dataset whose second frame lost its image
    let scene = repo().join("scenes/plaza.ron");
    let (code, _, err) = run_cli(
        &dir,
        &[
            "synth",
            scene.to_str().unwrap(),
            "--out",
            "d",
            "--views",
            "4",
            "--test-views",
            "1",
            "--res",
            "16",
            "--aa",
            "1",
        ],
    );
    assert_eq!(code, 0, "{err}");
    std::fs::remove_file(dir.join("d/train/r_1.png")).unwrap();
    expect_failure(&dir, &["inspect", "d", "--picture", "x.png"], &["frame 1", "r_1"]);
    // a non-rigid pose
    std::fs::copy(dir.join("d/test/r_0.png"), dir.join("d/train/r_1.png")).unwrap();
    let p = dir.join("d/transforms_test.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["frames"][0]["transform_matrix"][0][0] = serde_json::json!(3.0);
    std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
    expect_failure(
        &dir,
        &["inspect", "d", "--picture", "x.png"],
        &["transforms_test.json", "frame 0", "rigid"],
    );
    // malformed JSON
    std::fs::write(&p, "{\n  \"camera_angle_x\": 0.7,\n  \"frames\": [\n    {\"file_path\": \"./test/r_0\",, }\n  ]\n}").unwrap();
    expect_failure(
        &dir,
        &["inspect", "d", "--picture", "x.png"],
        &["transforms_test.json", "line 4"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

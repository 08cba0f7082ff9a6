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

/// `synth --random`: the drawn script lands in the dataset and in `--write-script`, and
/// rendering that file again gives the same ground truth and images.
#[test]
fn a_random_scene_renders_again_from_its_script() {
    let sh3f = assetfield_synth::sh3f::catalog_dir();
    if !assetfield_synth::sh3f::ALLOWED_CATALOGS
        .iter()
        .all(|c| sh3f.join(format!("{c}.sh3f")).is_file())
    {
        let why =
            format!("{} lacks the catalogs; apt-get install sweethome3d-furniture", sh3f.display());
        assert!(
            std::env::var("ASSETFIELD_STRICT_TESTS").as_deref() != Ok("1"),
            "sweethome3d-furniture not installed ({why}) and ASSETFIELD_STRICT_TESTS=1"
        );
        eprintln!(
            "SKIPPED: sweethome3d-furniture not installed ({why}); synth --random did not run"
        );
        return;
    }
    let dir = scratch("random");
    let small = ["--views", "3", "--test-views", "1", "--res", "16", "--aa", "1"];
    let mut args = vec!["synth", "--random", "3", "--out", "r3", "--write-script", "r3.ron"];
    args.extend(small);
    let (code, out, err) = run_cli(&dir, &args);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("random scene 3") && out.contains("units per metre"), "{out}");
    let script = std::fs::read_to_string(dir.join("r3.ron")).unwrap();
    assert_eq!(std::fs::read_to_string(dir.join("r3/scene.ron")).unwrap(), script);
    let mut again = vec!["synth", "r3.ron", "--out", "again"];
    again.extend(small);
    let (code, _, err) = run_cli(&dir, &again);
    assert_eq!(code, 0, "{err}");
    for f in ["gt_layout.json", "test/r_0.png", "train/r_1.png"] {
        assert_eq!(
            std::fs::read(dir.join("r3").join(f)).unwrap(),
            std::fs::read(dir.join("again").join(f)).unwrap(),
            "{f}"
        );
    }
    let synth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("r3/synth.json")).unwrap()).unwrap();
    let u = synth["units_per_metre"].as_f64().unwrap();
    assert!((0.5..2.0).contains(&u), "{u}");
    // --write-script without --random is a usage error
    let (code, _, err) = run_cli(&dir, &["synth", "r3.ron", "--write-script", "x.ron"]);
    assert!(code != 0 && err.contains("--random"), "{err}");
}

/// Dataset values found by fuzzing that `inspect` and `train` used to accept: each is
/// refused naming the file and the frame (index and file_path) or the top-level key.
#[test]
fn dataset_values_out_of_range_name_file_and_place() {
    use assetfield_data::{FrameEntry, TransformsFile, write_transforms};
    let dir = scratch("bad-values");
    let d = dir.join("d");
    std::fs::create_dir_all(d.join("train")).unwrap();
    let mut frames = Vec::new();
    for i in 0..3 {
        image::RgbImage::from_pixel(8, 6, image::Rgb([40 * i as u8, 90, 200]))
            .save(d.join(format!("train/r_{i}.png")))
            .unwrap();
        let eye = glam::Vec3::new(3.0 * (i as f32).cos(), 3.0 * (i as f32).sin(), 1.0);
        let k = assetfield_core::Intrinsics::from_fov_x(8, 6, 0.7);
        let c2w =
            assetfield_core::Camera::look_at(k, eye, glam::Vec3::ZERO, glam::Vec3::Z).c2w_matrix();
        frames.push(FrameEntry::new(format!("./train/r_{i}"), c2w));
    }
    let json = d.join("transforms_train.json");
    write_transforms(&json, &TransformsFile::nerf_synthetic(0.7, frames)).unwrap();
    let good = std::fs::read_to_string(&json).unwrap();
    let out = run_cli(&dir, &["inspect", "d"]);
    assert_eq!(out.0, 0, "the valid dataset inspects: {}", out.2);
    type Edit<'a> = &'a dyn Fn(&mut serde_json::Value);
    let cases: [(&str, Edit, &[&str]); 6] = [
        (
            "fov",
            &|v| v["camera_angle_x"] = serde_json::json!(6.3),
            &["transforms_train.json: \"camera_angle_x\" is 6.3", "(0, pi)"],
        ),
        (
            "w0",
            &|v| v["frames"][1]["w"] = serde_json::json!(0),
            &["transforms_train.json: frame 1 (./train/r_1): \"w\" is 0"],
        ),
        (
            "far",
            &|v| v["frames"][2]["transform_matrix"][1][3] = serde_json::json!(1e30),
            &["frame 2 (./train/r_2): \"transform_matrix translation\""],
        ),
        (
            "inf",
            &|v| v["frames"][0]["transform_matrix"][0][0] = serde_json::json!(1e39),
            &["frame 0 (./train/r_0): \"transform_matrix[0][0]\" is inf"],
        ),
        (
            "null",
            &|v| v["frames"][0]["transform_matrix"][0][0] = serde_json::Value::Null,
            &["transforms_train.json:", "null"],
        ),
        (
            "aabb_scale",
            &|v| v["aabb_scale"] = serde_json::json!(-4),
            &["transforms_train.json: \"aabb_scale\" is -4.0"],
        ),
    ];
    for (what, edit, needles) in cases {
        let mut v: serde_json::Value = serde_json::from_str(&good).unwrap();
        edit(&mut v);
        std::fs::write(&json, serde_json::to_string(&v).unwrap()).unwrap();
        for args in
            [&["inspect", "d"][..], &["train", "d", "--out", "f.safetensors", "--iters", "1"]]
        {
            let (code, _, err) = run_cli(&dir, args);
            assert_eq!(code, 1, "{what}: {args:?}: {err}");
            for n in needles {
                assert!(err.contains(n), "{what}: {args:?}: expected {n:?} in: {err}");
            }
        }
    }
    std::fs::write(&json, &good).unwrap();
    std::fs::write(d.join("synth.json"), r#"{"scene_aabb": [[1, 0, 0], [-1, 1, 1]]}"#).unwrap();
    expect_failure(
        &dir,
        &["inspect", "d"],
        &["synth.json: \"scene_aabb\"", "xmin (1) below xmax (-1)"],
    );
    assert!(!dir.join("f.safetensors").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

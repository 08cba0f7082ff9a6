//! `assetfield mine` and `assetfield library` end to end: a small synthesised scene (two
//! categories at several yaws on a floor) trained briefly, mined against its ground truth;
//! the library, layout and pictures it writes; bad input (exit 1, a clear message, nothing
//! written).

use assetfield_layout::{GtLayout, PartsCatalog, resolve};
use assetfield_library::open_library;
use assetfield_tests::{SCENE, fail, ok, run_cli, scratch};
use assetfield_tests::{Similarity, moved_gt, repose_as_nerfstudio};
use glam::{Mat3, Vec3};
use std::path::Path;

/// The small scene (`SCENE`) synthesised into `dir/d`: 24 training views at 48 x 48.
fn synth_tiny(dir: &Path) {
    std::fs::write(dir.join("tiny.ron"), SCENE).unwrap();
    let args = ["synth", "tiny.ron", "--out", "d", "--views", "24", "--test-views", "2"];
    ok(dir, &[&args[..], &["--res", "48", "--aa", "1"]].concat());
}

#[test]
fn mine_a_small_scene_into_a_library_and_layout() {
    let dir = scratch("mining");
    synth_tiny(&dir);
    ok(
        &dir,
        &[
            "train",
            "d",
            "--out",
            "f.safetensors",
            "--iters",
            "1500",
            "--res",
            "64",
            "--batch",
            "2048",
        ],
    );

    let out = ok(&dir, &["mine", "f.safetensors", "--out", "lib", "--gt", "d/gt_layout.json"]);
    assert!(out.contains("mined 5 objects") && out.contains("F1"), "{out}");
    let lib = dir.join("lib");
    for f in [
        "index.ron",
        "patches.safetensors",
        "shared.safetensors",
        "layout.ron",
        "boxes.png",
        "categories.png",
        "metrics.json",
        "mining.json",
    ] {
        assert!(lib.join(f).is_file(), "lib/{f} missing");
    }
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(lib.join("metrics.json")).unwrap()).unwrap();
    let num = |k: &str| m[k].as_f64().unwrap_or_else(|| panic!("metrics.json lacks {k}: {m}"));
    assert!(num("f1") >= 0.85, "F1 {}: {m}", num("f1"));
    assert!(num("ari") >= 0.6, "ARI {}: {m}", num("ari"));
    assert!(num("yaw_median_deg") <= 8.0, "yaw {}: {m}", num("yaw_median_deg"));
    assert!(num("position_median") <= 0.1, "position {}", num("position_median"));
    for key in ["precision", "recall", "yaw_max_deg", "per_category", "per_instance"] {
        assert!(m.get(key).is_some(), "metrics.json lacks {key}");
    }

    // the library checks out, and its layout loads and resolves with the library assets
    let l = open_library(&lib).unwrap();
    assert_eq!(l.index.format, "assetfield-library/1");
    assert_eq!(l.index.entries.len(), 5);
    assert!(l.index.categories.iter().all(|c| l.index.entry(&c.template).is_some()));
    assert!(l.shared.tensors.contains_key("density.axis"));
    assert!(l.shared.tensors.keys().all(|k| !k.ends_with(".plane")), "planes are not shared");
    assert!(l.patches.tensors.contains_key("container.density"));
    let loaded = assetfield_layout::load(&lib.join("layout.ron")).unwrap();
    let resolved = resolve(&loaded, &PartsCatalog::from_script(&loaded)).unwrap();
    assert_eq!(resolved.instances.len(), 5);
    let out = ok(&dir, &["library", "check", "lib"]);
    assert!(out.contains("5 entries") && out.contains("ok"), "{out}");

    // a second mining run of the same field shares its tensors: the libraries merge
    ok(
        &dir,
        &["mine", "f.safetensors", "--out", "lib2", "--categories", "2", "--template", "cat0=0"],
    );
    let out = ok(&dir, &["library", "merge", "lib", "lib2", "--out", "both"]);
    assert!(out.contains("10 entries"), "{out}");
    assert!(open_library(&dir.join("both")).unwrap().index.entry("lib2/obj000").is_some());

    // grouping on the objects' own voxel colours instead of the colour plane, and yaws
    // matched on the objects' own voxel slabs for every category
    let out = ok(
        &dir,
        &[
            "mine",
            "f.safetensors",
            "--out",
            "lib3",
            "--group-on",
            "voxels",
            "--yaw-on",
            "voxels",
            "--gt",
            "d/gt_layout.json",
        ],
    );
    assert!(out.contains("mined 5 objects"), "{out}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("lib3/metrics.json")).unwrap())
            .unwrap();
    assert!(m["ari"].as_f64().unwrap() >= 0.6, "ARI on voxels: {m}");
    let report = std::fs::read_to_string(dir.join("lib3/mining.json")).unwrap();
    assert!(report.contains("\"group_on\": \"Voxels\""), "{report}");
    assert!(report.contains("\"yaw_on\": \"Voxels\""), "{report}");
    assert!(m["yaw_median_deg"].as_f64().unwrap() <= 8.0, "yaw on voxels: {m}");
    // slab poses are judged on the density plane, which is what the layout places
    let index = std::fs::read_to_string(dir.join("lib3/index.ron")).unwrap();
    assert!(index.contains("matched_on: \"density\""), "{index}");

    // the paper's steps alone, and a filter switched off: both mine, and say so
    let out = ok(
        &dir,
        &[
            "mine",
            "f.safetensors",
            "--out",
            "paper",
            "--preset",
            "paper",
            "--gt",
            "d/gt_layout.json",
        ],
    );
    assert!(out.contains("F1"), "{out}");
    let report = std::fs::read_to_string(dir.join("paper/mining.json")).unwrap();
    assert!(report.contains("\"detect_preset\": \"paper\""), "{report}");
    assert!(report.contains("\"yaw_on\": \"Density\""), "{report}");
    ok(&dir, &["mine", "f.safetensors", "--out", "nofilter", "--no-filter", "walls"]);
    let report = std::fs::read_to_string(dir.join("nofilter/mining.json")).unwrap();
    assert!(report.contains("\"walls\": false"), "{report}");
    assert!(!report.contains("filter walls"), "{report}");

    // refusals: an existing output, bad flags, a template outside its category
    fail(&dir, &["mine", "f.safetensors", "--out", "lib"], &["already exists", "--force"]);
    fail(&dir, &["mine", "f.safetensors", "--out", "x", "--k", "1"], &["--k"]);
    let (code, _, err) =
        run_cli(&dir, &["mine", "f.safetensors", "--out", "x", "--no-filter", "lamps"]);
    assert!(code == 2 && err.contains("lamps") && err.contains("duplicates"), "{err}");
    fail(&dir, &["mine", "f.safetensors", "--out", "x", "--k", "100000"], &["clusters"]);
    fail(&dir, &["mine", "f.safetensors", "--out", "x", "--template", "cat9=0"], &["cat9"]);
    fail(&dir, &["mine", "nope.safetensors", "--out", "x"], &["nope.safetensors"]);
    fail(&dir, &["library", "check", "d"], &["index.ron"]);
    assert!(!dir.join("x").exists(), "a failed run must not leave its output");

    // the TensoRF-VM baseline has no ground plane representation
    ok(
        &dir,
        &["train", "d", "--out", "vm.safetensors", "--model", "vm", "--iters", "20", "--res", "32"],
    );
    fail(&dir, &["mine", "vm.safetensors", "--out", "x"], &["ground plane representation"]);
    assert!(!dir.join("x").exists());
    let leftovers: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "staging folders left behind: {leftovers:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Train `data` (a nerfstudio capture) briefly, levelled with `--align-ground pca`, and mine
/// it against its ground truth moved by `s` and the field's own alignment; the metrics.
fn train_levelled_and_mine(dir: &Path, data: &str, s: &Similarity) -> serde_json::Value {
    let field = format!("{data}.safetensors");
    let args =
        ["train", data, "--out", &field, "--iters", "1500", "--res", "96", "--batch", "2048"];
    ok(dir, &[&args[..], &["--align-ground", "pca"]].concat());
    let loaded = assetfield_field::eval::load_field(&dir.join(&field)).unwrap();
    let align = loaded.info.ground_transform.expect("the field records its alignment");
    let gt = GtLayout::read(&dir.join("d/gt_layout.json")).unwrap();
    let gt_path = dir.join(format!("{data}_gt.json"));
    std::fs::write(&gt_path, serde_json::to_string(&moved_gt(&gt, s, &align)).unwrap()).unwrap();
    let lib = format!("{data}_lib");
    let out = ok(dir, &["mine", &field, "--out", &lib, "--gt", gt_path.to_str().unwrap()]);
    assert!(out.contains("F1"), "{out}");
    serde_json::from_str(&std::fs::read_to_string(dir.join(lib).join("metrics.json")).unwrap())
        .unwrap()
}

/// Issue 16, section 2: the same photos posed in another frame and unit (scale 0.37, turned
/// 90 degrees and tilted 30, offset), levelled with `--align-ground pca`, mine the same
/// objects as the capture in its own frame: no length of the detector is in world units.
#[test]
fn a_capture_in_another_frame_and_unit_mines_the_same_objects() {
    let dir = scratch("mining-reposed");
    synth_tiny(&dir);
    let same = Similarity { scale: 1.0, rotation: Mat3::IDENTITY, offset: Vec3::ZERO };
    let moved = Similarity {
        scale: 0.37,
        rotation: Mat3::from_rotation_x(30f32.to_radians())
            * Mat3::from_rotation_z(90f32.to_radians()),
        offset: Vec3::new(1.3, -0.7, 2.1),
    };
    repose_as_nerfstudio(&dir.join("d"), &dir.join("a"), &same);
    repose_as_nerfstudio(&dir.join("d"), &dir.join("b"), &moved);
    let a = train_levelled_and_mine(&dir, "a", &same);
    let b = train_levelled_and_mine(&dir, "b", &moved);
    let num = |m: &serde_json::Value, k: &str| m[k].as_f64().unwrap_or(f64::NAN);
    assert!(num(&a, "f1") >= 0.8, "in its own frame: {a}");
    assert!(
        (num(&a, "f1") - num(&b, "f1")).abs() <= 0.02,
        "F1 {} vs {}",
        num(&a, "f1"),
        num(&b, "f1")
    );
    assert!(
        (num(&a, "ari") - num(&b, "ari")).abs() <= 0.02,
        "ARI {} vs {}",
        num(&a, "ari"),
        num(&b, "ari")
    );
    // positions are in each capture's units
    assert!(
        num(&b, "position_median") <= 0.37 * num(&a, "position_median").max(0.02) * 2.0,
        "{a} {b}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Issue 16, section 4: a small field trained by `assetfield train` and frozen in
/// `tests/data` (see its README), mined end to end with the defaults and with the paper's
/// steps alone; the detector must find what it found when the field was frozen and beat the
/// paper's baseline.
#[test]
fn a_frozen_trained_field_mines_with_the_defaults_and_the_paper_preset() {
    let dir = scratch("mining-frozen");
    let data = assetfield_tests::repo().join("tests/data");
    let field = data.join("living_room_s128.safetensors");
    let gt = data.join("living_room_gt_layout.json");
    let (field, gt) = (field.to_str().unwrap(), gt.to_str().unwrap());
    let metrics = |lib: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join(lib).join("metrics.json")).unwrap())
            .unwrap()
    };
    ok(&dir, &["mine", field, "--out", "default", "--gt", gt]);
    ok(&dir, &["mine", field, "--out", "paper", "--gt", gt, "--preset", "paper"]);
    let (d, p) = (metrics("default"), metrics("paper"));
    let num = |m: &serde_json::Value, k: &str| m[k].as_f64().unwrap_or(f64::NAN);
    // (its two lamps on their side tables are at the smallest object's area on this
    // 128-texel plane: 22 and 25 texels; one is found, and its side table then differs from
    // the other: ARI 0.916 with 13 of 15 found, where 12 of 15 with ARI 1.000 were before)
    assert!(num(&d, "f1") >= 0.85 && num(&d, "ari") >= 0.9, "default: {d}");
    assert!(num(&d, "yaw_median_deg") <= 3.0, "default: {d}");
    assert!(num(&p, "f1") < num(&d, "f1"), "the paper's steps alone: {p}");
    // the detector's decisions on stderr when asked for, nothing otherwise
    let logged = std::process::Command::new(assetfield_tests::assetfield_bin())
        .args(["mine", field, "--out", "logged"])
        .env("ASSETFIELD_LOG", "assetfield_mining=debug")
        .current_dir(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&logged.stderr);
    assert!(logged.status.success() && err.contains("final") && err.contains("part"), "{err}");
    let quiet = std::process::Command::new(assetfield_tests::assetfield_bin())
        .args(["mine", field, "--out", "quiet"])
        .env_remove("ASSETFIELD_LOG")
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(!String::from_utf8_lossy(&quiet.stderr).contains("final"));
    // nothing left: a clear message, nothing written
    fail(
        &dir,
        &["mine", field, "--out", "none", "--min-area", "100000"],
        &["no object found", "--min-area"],
    );
    assert!(!dir.join("none").exists());
    // every removal names its filter
    let report = std::fs::read_to_string(dir.join("default/mining.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&report).unwrap();
    for r in v["removed_as_background"].as_array().unwrap() {
        assert!(r.as_str().unwrap().contains("(filter "), "{r}");
    }
    // the detection values a run used, read back from its report, mine the same library
    let values = serde_json::to_string(&v["options"]["detect"]).unwrap();
    std::fs::write(dir.join("detect.json"), &values).unwrap();
    ok(&dir, &["mine", field, "--out", "again", "--gt", gt, "--detect-params", "detect.json"]);
    let again = metrics("again");
    assert_eq!((num(&again, "f1"), num(&again, "ari")), (num(&d, "f1"), num(&d, "ari")));
    std::fs::write(dir.join("bad.json"), values.replace("\"min_area_texels\"", "\"min_area\""))
        .unwrap();
    fail(&dir, &["mine", field, "--out", "bad", "--detect-params", "bad.json"], &["bad.json"]);
    assert!(!dir.join("bad").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn mine_help_explains_the_flags() {
    let dir = scratch("mining-help");
    let out = ok(&dir, &["mine", "--help"]);
    for flag in [
        "--out",
        "--gt",
        "--detect-on",
        "--preset",
        "--no-filter",
        "--min-area",
        "--k",
        "--labels",
        "--categories",
        "--distance",
        "--template",
        "--shape-weight",
        "--profile-weight",
        "--auto-cut",
        "--no-copies",
        "--detect-params",
        "--force",
        "metrics.json",
        "layout.ron",
    ] {
        assert!(out.contains(flag), "mine --help lacks {flag}: {out}");
    }
    let out = ok(&dir, &["library", "--help"]);
    assert!(out.contains("merge") && out.contains("check"), "{out}");
    let (code, _, _) = run_cli(&dir, &["mine"]);
    assert_eq!(code, 2, "a missing argument is a usage error");
    std::fs::remove_dir_all(&dir).unwrap();
}

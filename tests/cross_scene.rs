//! The cross-scene library end to end (paper Sec. 3.4): two small scenes that share their
//! objects trained together (`train A B --out DIR`), each field's shared tensors bit-identical;
//! both mined, merged with `--regroup` against both ground truths (one category spans the
//! scenes); a third scene fitted against the frozen shared tensors (`--share`) joins the
//! library; libraries of separately trained fields are refused, naming the tensor and files;
//! bad flags are refused before anything is written.

use assetfield_core::TensorFile;
use assetfield_field::FieldConfig;
use assetfield_library::open_library;
use assetfield_tests::{SCENE, fail, ok, scratch};
use std::path::Path;

/// `SCENE`'s assets on a smaller floor (another box, so other plane sizes), placed and
/// turned otherwise.
fn scene_b() -> String {
    let assets = &SCENE[..SCENE.find("    layout: [").expect("SCENE has a layout")];
    let assets =
        assets.replace("\"tiny\"", "\"tiny_b\"").replace("(4.6, 3.6, 0.02)", "(4.0, 3.2, 0.02)");
    assert!(assets.contains("(4.0, 3.2, 0.02)"), "SCENE's floor changed: update scene_b");
    format!(
        r#"{assets}    layout: [
        Instance(asset: "floor", at: (0, 0)),
        Instance(asset: "wedge", at: (-1.0, -0.7), yaw: 45, name: "w0"),
        Instance(asset: "wedge", at: (0.9, 0.8), yaw: 160, name: "w1"),
        Instance(asset: "block", at: (-0.9, 0.7), yaw: 10, name: "b0"),
        Instance(asset: "block", at: (0.9, -0.7), yaw: 75, name: "b1"),
    ],
)"#
    )
}

fn synth(dir: &Path, name: &str, script: &str) {
    std::fs::write(dir.join(format!("{name}.ron")), script).unwrap();
    let args =
        ["synth", &format!("{name}.ron"), "--out", name, "--views", "24", "--test-views", "2"];
    ok(dir, &[&args[..], &["--res", "48", "--aa", "1"]].concat());
}

fn shared_of(path: &Path) -> TensorFile {
    let mut f = TensorFile::load(path).unwrap();
    f.tensors.retain(|name, _| !FieldConfig::is_plane_tensor(name) && name != "occupancy");
    f
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn scenes_trained_together_form_one_library_that_a_new_scene_joins() {
    let dir = scratch("cross-scene");
    synth(&dir, "alpha", SCENE);
    synth(&dir, "beta", &scene_b());
    let train = ["--iters", "1500", "--res", "64", "--batch", "2048"];
    let out = ok(&dir, &[&["train", "alpha", "beta", "--out", "joint"][..], &train].concat());
    assert!(
        out.contains("trained 2 scenes together") && out.contains("shared tensors fnv1a64:"),
        "{out}"
    );
    let (a, b) = (dir.join("joint/alpha.safetensors"), dir.join("joint/beta.safetensors"));
    assert!(dir.join("joint/alpha.ckpt.safetensors").is_file());
    // the shared tensors are one set, bit for bit; the planes are each scene's own
    let (sa, sb) = (shared_of(&a), shared_of(&b));
    assert!(sa.tensors.contains_key("density.axis") && sa.tensors.contains_key("decoder.0.weight"));
    assert_eq!(sa.tensors, sb.tensors);
    let (fa, fb) = (TensorFile::load(&a).unwrap(), TensorFile::load(&b).unwrap());
    assert_ne!(fa.tensors["density.plane"].shape, fb.tensors["density.plane"].shape);

    // both mined, merged with one grouping across the scenes
    for s in ["alpha", "beta"] {
        let gt = format!("{s}/gt_layout.json");
        ok(
            &dir,
            &["mine", &format!("joint/{s}.safetensors"), "--out", &format!("lib_{s}"), "--gt", &gt],
        );
    }
    let out = ok(
        &dir,
        &[
            "library",
            "merge",
            "lib_alpha",
            "lib_beta",
            "--out",
            "merged",
            "--regroup",
            "--gt",
            "alpha/gt_layout.json",
            "beta/gt_layout.json",
        ],
    );
    assert!(out.contains("cross-scene ARI") && out.contains("grouped across scenes"), "{out}");
    let m = json(&dir.join("merged/metrics.json"));
    let ari = m["cross_scene_ari"].as_f64().unwrap();
    assert!(ari >= 0.6, "cross-scene ARI {ari}: {m}");
    assert!(m["categories_spanning_scenes"].as_u64().unwrap() >= 1, "{m}");
    assert_eq!(m["per_scene"].as_array().unwrap().len(), 2);
    let lib = open_library(&dir.join("merged")).unwrap();
    assert_eq!(lib.index.entries.len(), 9 - count_missed(&m));
    let spanning = lib.index.categories.iter().filter(|c| {
        c.members.iter().any(|n| n.starts_with("lib_alpha/"))
            && c.members.iter().any(|n| n.starts_with("lib_beta/"))
    });
    assert!(spanning.count() >= 1);
    // every category's template is one of its members, posed at yaw 0
    for c in &lib.index.categories {
        assert!(c.members.contains(&c.template));
        assert_eq!(lib.index.entry(&c.template).unwrap().yaw_deg, 0.0);
    }
    // the merged library composes: its check passes
    let out = ok(&dir, &["library", "check", "merged"]);
    assert!(out.contains("ok"), "{out}");

    // a third scene fitted against the frozen shared tensors joins the library
    let out = ok(
        &dir,
        &[
            "train",
            "beta",
            "--share",
            "merged",
            "--out",
            "gamma.safetensors",
            "--iters",
            "600",
            "--batch",
            "2048",
        ],
    );
    assert!(out.contains("frozen"), "{out}");
    assert_eq!(shared_of(&dir.join("gamma.safetensors")).tensors, sa.tensors);
    ok(&dir, &["mine", "gamma.safetensors", "--out", "lib_gamma"]);
    ok(&dir, &["library", "merge", "merged", "lib_gamma", "--out", "grown"]);

    // a field trained alone (the frozen living room) has other shared tensors: its library
    // is refused, naming them
    let alone = assetfield_tests::repo().join("tests/data/living_room_s128.safetensors");
    ok(&dir, &["mine", alone.to_str().unwrap(), "--out", "lib_alone"]);
    fail(
        &dir,
        &["library", "merge", "lib_alpha", "lib_alone", "--out", "bad"],
        &["lib_alpha", "lib_alone", "differ"],
    );
    assert!(!dir.join("bad").exists());
}

fn count_missed(m: &serde_json::Value) -> usize {
    // entries are the mined objects: the test counts what mining found in both scenes
    let per = m["per_scene"].as_array().unwrap();
    9 - per.iter().map(|s| s["entries"].as_u64().unwrap() as usize).sum::<usize>()
}

#[test]
fn bad_cross_scene_flags_are_refused_before_anything_is_written() {
    let dir = scratch("cross-scene-bad");
    synth(&dir, "alpha", SCENE);
    let t = ["--iters", "20", "--res", "16", "--batch", "256"];
    // two datasets of one name would write one file
    fail(
        &dir,
        &[&["train", "alpha", "./alpha", "--out", "j"][..], &t].concat(),
        &["both named", "alpha"],
    );
    // per-scene flags with several datasets, VM, a file as the folder
    fail(&dir, &["train", "alpha", "alpha", "--aabb", "0,0,0,1,1,1", "--out", "j"], &["--aabb"]);
    std::fs::write(dir.join("afile"), "x").unwrap();
    fail(&dir, &["train", "alpha", "alpha2", "--out", "afile"], &["is a file"]);
    ok(&dir, &[&["train", "alpha", "--out", "f.safetensors"][..], &t].concat());
    // --share: another model, --res, several datasets, a path that is neither
    fail(
        &dir,
        &["train", "alpha", "--share", "f.safetensors", "--model", "i", "--out", "g.safetensors"],
        &["--model i", "differs", "(s)"],
    );
    fail(
        &dir,
        &["train", "alpha", "--share", "f.safetensors", "--res", "32", "--out", "g.safetensors"],
        &["--res", "texel size"],
    );
    fail(
        &dir,
        &["train", "alpha", "alpha", "--share", "f.safetensors", "--out", "g"],
        &["--share", "one new scene"],
    );
    fail(
        &dir,
        &["train", "alpha", "--share", "nothing.safetensors", "--out", "g.safetensors"],
        &["--share", "nothing.safetensors"],
    );
    assert!(!dir.join("g.safetensors").exists() && !dir.join("j").exists());
    // a merge with ground truths that do not pair with the libraries
    fail(
        &dir,
        &["library", "merge", "a", "b", "--out", "m", "--gt", "alpha/gt_layout.json"],
        &["one ground truth per library"],
    );
}

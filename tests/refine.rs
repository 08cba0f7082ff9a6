//! `assetfield refine` end to end: the templates of a library mined from a real trained field
//! (the frozen living room) refined against its scene's views; the templates-only layout it
//! writes composes to what it measured and beats the templates before refinement; a dataset
//! of another place is refused before anything is written.

use assetfield_tests::{fail, ok, repo, scratch};

fn json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn refined_templates_compose_closer_to_the_scene() {
    let dir = scratch("refine");
    let field = repo().join("tests/data/living_room_s128.safetensors");
    let scene = repo().join("scenes/living_room.ron");
    let args = ["synth", scene.to_str().unwrap(), "--out", "data", "--views", "30"];
    ok(&dir, &[&args[..], &["--test-views", "4", "--res", "64"]].concat());
    ok(
        &dir,
        &[
            "mine",
            field.to_str().unwrap(),
            "--out",
            "lib",
            "--gt",
            "data/gt_layout.json",
            "--gt-names",
        ],
    );
    let out = ok(
        &dir,
        &[
            "refine", "lib", "--data", "data", "--out", "refined", "--iters", "150", "--batch",
            "2048",
        ],
    );
    assert!(out.contains("templates only") && out.contains("->"), "{out}");
    let r = json(&dir.join("refined/refine.json"));
    let (before, after) = (
        r["test_psnr_templates_before"].as_f64().unwrap(),
        r["test_psnr_templates_after"].as_f64().unwrap(),
    );
    assert!(after > before + 0.1, "templates only: {before} -> {after} dB");
    assert_eq!(r["iterations"].as_u64(), Some(150));
    // the written library checks out, and its templates-only layout composes to the figure
    ok(&dir, &["library", "check", "refined"]);
    // its instances keep the names the mined layout gave them (edit scripts find them)
    let names = |p: &str| -> std::collections::BTreeSet<String> {
        let text = std::fs::read_to_string(dir.join(p)).unwrap();
        text.lines().filter(|l| l.starts_with("            name: ")).map(str::to_string).collect()
    };
    let (mined, refined) = (names("lib/layout.ron"), names("refined/layout.ron"));
    assert!(mined.len() >= 10 && mined == refined, "{mined:?} vs {refined:?}");
    let out = ok(
        &dir,
        &[
            "compose",
            "refined/layout.ron",
            "--library",
            "refined",
            "--views",
            "data",
            "--metrics",
            "--out",
            "c",
            "--backend",
            "cpu",
        ],
    );
    let composed = json(&dir.join("c/metrics.json"))["psnr"].as_f64().unwrap();
    assert!((composed - after).abs() < 0.05, "compose {composed} vs refine {after}: {out}");

    // a dataset of another place: its cameras look elsewhere
    let far = r#"Scene(
        assets: { "block": Asset(parts: [Box(center: (0, 0, 0.15), size: (0.6, 0.6, 0.3), color: (0.2, 0.7, 0.3))]) },
        layout: [Instance(asset: "block", at: (40, 40)), Instance(asset: "block", at: (41, 40.5))],
    )"#;
    std::fs::write(dir.join("far.ron"), far).unwrap();
    ok(
        &dir,
        &[
            "synth",
            "far.ron",
            "--out",
            "far",
            "--views",
            "8",
            "--test-views",
            "1",
            "--res",
            "16",
            "--aa",
            "1",
        ],
    );
    fail(
        &dir,
        &["refine", "lib", "--data", "far", "--out", "bad"],
        &["does not look like the scene", "lib"],
    );
    assert!(!dir.join("bad").exists());
    // the output exists
    fail(
        &dir,
        &["refine", "lib", "--data", "data", "--out", "refined"],
        &["already exists", "--force"],
    );
}

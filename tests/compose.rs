//! `assetfield compose` end to end (issue 5): a small scene is synthesised with an edited
//! version, trained briefly, mined with ground-truth names, and composed again:
//! - every entry placed back where it was mined restores the trained planes exactly (the
//!   mine -> compose round trip);
//! - the mined layout renders the test views nearly as well as the field itself;
//! - the edit (two moves, a quarter turn, a deletion, a duplication) applied to the mined
//!   layout renders within 2 dB of the unedited test PSNR against `synth --edited`;
//! - an empty canvas and a turntable work; bad scripts fail naming the script line.

use assetfield_core::TensorFile;
use assetfield_field::eval::load_field;
use assetfield_layout::resolve;
use assetfield_library::{content_hash, index_to_ron};
use assetfield_scene::{AssetLibrary, Composer, ScriptAssets};
use assetfield_tests::{SCENE, fail, ok, run_cli, scratch};
use std::path::Path;

const EDIT: &str = r#"Scene(
    base: "tiny.ron",
    edits: [
        Move(target: "w0", by: (0.3, 0.2)),
        Move(target: "b1", by: (0.5, 0.3)),
        Rotate(target: "w1", by: 90),
        Remove("w2"),
        Duplicate(target: "b0", by: (0.0, 1.2)),
    ],
)
"#;

fn psnr_of(path: &Path) -> f64 {
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    m["psnr"].as_f64().unwrap_or_else(|| panic!("{} lacks psnr: {m}", path.display()))
}

#[test]
fn mine_compose_round_trip_and_edit_fidelity() {
    let dir = scratch("compose");
    std::fs::write(dir.join("tiny.ron"), SCENE).unwrap();
    std::fs::write(dir.join("edit.ron"), EDIT).unwrap();
    let synth = [
        "synth",
        "tiny.ron",
        "--out",
        "d",
        "--views",
        "24",
        "--test-views",
        "2",
        "--res",
        "48",
        "--aa",
        "1",
        "--edited",
        "edit.ron",
    ];
    ok(&dir, &synth);
    let train = [
        "train",
        "d",
        "--out",
        "f.safetensors",
        "--iters",
        "1500",
        "--res",
        "96",
        "--batch",
        "2048",
    ];
    ok(&dir, &train);
    ok(&dir, &["eval", "f.safetensors", "--data", "d", "--out", "e"]);
    let field_psnr = psnr_of(&dir.join("e/metrics.json"));
    assert!(field_psnr > 20.0, "the field itself must be usable: {field_psnr}");
    ok(&dir, &["mine", "f.safetensors", "--out", "lib", "--gt", "d/gt_layout.json", "--gt-names"]);
    let layout = std::fs::read_to_string(dir.join("lib/layout.ron")).unwrap();
    for key in ["\"w0\"", "\"w1\"", "\"w2\"", "\"b0\"", "\"b1\""] {
        assert!(layout.contains(key), "--gt-names: {key} missing from\n{layout}");
    }

    // round trip: every entry's own patch placed back where it was mined (its pivot)
    // restores the trained planes (the container holds the rest)
    let lib = AssetLibrary::open(&dir.join("lib")).unwrap();
    let mut items = String::new();
    for e in &lib.index.entries {
        let (x, y) = e.pivot_world().into();
        items += &format!("Instance(asset: \"{}\", at: ({x}, {y})),\n", e.name);
    }
    let own = dir.join("own.ron");
    std::fs::write(&own, format!("Scene(layout: [\n{items}])\n")).unwrap();
    let script = assetfield_layout::load(&own).unwrap();
    let assets = ScriptAssets::resolve(&script, &lib, None).unwrap();
    let layout = resolve(&script, &assets).unwrap();
    let mut composer = Composer::new(lib.composition(&lib.default_canvas()).unwrap());
    assets.install(&mut composer).unwrap();
    composer.apply_layout(&layout).unwrap();
    composer.update();
    let trained = load_field(&dir.join("f.safetensors")).unwrap().field;
    let composed = &composer.composition().field;
    for name in ["density.plane", "color.plane"] {
        let (a, b) = (trained.params.spec(name).unwrap(), composed.params.spec(name).unwrap());
        assert_eq!(a.shape, b.shape, "{name}");
        let (pa, pb) =
            (&trained.params.data[a.offset..][..a.len], &composed.params.data[b.offset..][..b.len]);
        let scale = pa.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let worst = pa.iter().zip(pb).fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        assert!(
            worst <= 1e-4 * scale.max(1.0),
            "{name}: composed differs by {worst} (scale {scale})"
        );
    }

    // the mined layout (every instance its own patch, the default) re-renders the test views,
    // and the edit holds up
    let out = ok(
        &dir,
        &[
            "compose",
            "lib/layout.ron",
            "--library",
            "lib",
            "--out",
            "c",
            "--views",
            "d",
            "--metrics",
        ],
    );
    let count = |out: &str| -> usize {
        let n = out.split("composed ").nth(1).and_then(|t| t.split(' ').next());
        n.and_then(|n| n.parse().ok()).unwrap_or_else(|| panic!("no instance count in {out}"))
    };
    let mined = count(&out);
    assert!(mined >= 5, "{out}");
    let same = psnr_of(&dir.join("c/metrics.json"));
    assert!(same >= field_psnr - 2.0, "recomposed {same:.2} dB vs field {field_psnr:.2} dB");
    let args = [
        "compose",
        "lib/layout.ron",
        "--library",
        "lib",
        "--edits",
        "edit.ron",
        "--out",
        "ce",
        "--views",
        "d/edited",
        "--metrics",
        "--planes",
    ];
    let out = ok(&dir, &args);
    assert_eq!(count(&out), mined, "2 moved, 1 turned, 1 removed, 1 added: {out}");
    let edited = psnr_of(&dir.join("ce/metrics.json"));
    assert!(
        edited >= field_psnr - 2.0,
        "edited {edited:.2} dB must be within 2 dB of the unedited {field_psnr:.2} dB"
    );
    for f in [
        "r_0.png",
        "error/r_0.png",
        "planes/density.png",
        "planes/color_pca.png",
        "layout.png",
        "compose.json",
    ] {
        assert!(dir.join("ce").join(f).is_file(), "ce/{f} missing");
    }
    eprintln!("field {field_psnr:.2} dB, recomposed {same:.2} dB, edited {edited:.2} dB");

    // category-level edits from a script: recolour a category through its template, warp
    // one instance's density, remove a whole category
    let cats = &lib.index.categories;
    assert!(cats.len() >= 2, "two categories: {cats:?}");
    let (c0, c1) = (&cats[0], &cats[1]);
    let mined_script = assetfield_layout::load(&dir.join("lib/layout.ron")).unwrap();
    let mined_assets = ScriptAssets::resolve(&mined_script, &lib, None).unwrap();
    let mined_layout = resolve(&mined_script, &mined_assets).unwrap();
    let first = mined_layout.objects().find(|i| i.category == c0.name).unwrap().key.clone();
    let gone = mined_layout.objects().filter(|i| i.category == c1.name).count();
    let lib_asset = |extra: &str| {
        format!(
            "Library(path: \"lib\", entry: \"{}\", size: (0.6, 0.6, 0.5), {extra})",
            c0.template
        )
    };
    let text = format!(
        "Scene(\n  base: \"lib/layout.ron\",\n  assets: {{\n    \"recoloured\": Asset(category: \"{}\", library: {}),\n    \"warped\": Asset(library: {}),\n  }},\n  edits: [\n    ReplaceAsset(category: \"{}\", with: \"recoloured\"),\n    Override(target: \"{first}\", asset: \"warped\"),\n    RemoveCategory(\"{}\"),\n  ],\n)\n",
        c0.name,
        lib_asset(&format!("color_from: \"{}\"", c1.template)),
        lib_asset(&format!("density_from: \"{}\"", c1.template)),
        c0.name,
        c1.name,
    );
    std::fs::write(dir.join("category.ron"), text).unwrap();
    let out = ok(
        &dir,
        &[
            "compose",
            "category.ron",
            "--library",
            "lib",
            "--out",
            "cat",
            "--orbit",
            "1",
            "--res",
            "24",
        ],
    );
    assert_eq!(count(&out), mined - gone, "RemoveCategory drops {gone}: {out}");
    let bad = format!(
        "Scene(\n  base: \"lib/layout.ron\",\n  assets: {{\n    \"x\": Asset(library: {}),\n  }},\n)\n",
        lib_asset("color_from: \"nope\"")
    );
    std::fs::write(dir.join("nope.ron"), bad).unwrap();
    fail(
        &dir,
        &["compose", "nope.ron", "--library", "lib", "--out", "x"],
        &["nope.ron:4:", "color_from names \"nope\""],
    );

    // an empty canvas and a turntable
    let args = [
        "compose",
        "lib/layout.ron",
        "--library",
        "lib",
        "--out",
        "orbit",
        "--orbit",
        "2",
        "--res",
        "24",
        "--canvas",
        "empty",
    ];
    let out = ok(&dir, &args);
    assert!(out.contains("empty"), "{out}");
    assert!(dir.join("orbit/orbit_001.png").is_file());

    // the same composed scene rendered by wgpu (lavapipe without a GPU) and by the CPU
    let cpu = [
        "compose",
        "lib/layout.ron",
        "--library",
        "lib",
        "--out",
        "o_cpu",
        "--orbit",
        "1",
        "--res",
        "32",
        "--backend",
        "cpu",
    ];
    ok(&dir, &cpu);
    let (code, out, err) = run_cli(
        &dir,
        &[
            "compose",
            "lib/layout.ron",
            "--library",
            "lib",
            "--out",
            "o_gpu",
            "--orbit",
            "1",
            "--res",
            "32",
            "--backend",
            "gpu",
        ],
    );
    if code == 0 {
        assert!(out.contains("on the GPU"), "{out}");
        let a = image::open(dir.join("o_cpu/orbit_000.png")).unwrap().to_rgb8();
        let b = image::open(dir.join("o_gpu/orbit_000.png")).unwrap().to_rgb8();
        let worst = a
            .pixels()
            .zip(b.pixels())
            .flat_map(|(p, q)| (0..3).map(move |k| (p[k] as i32 - q[k] as i32).abs()))
            .max()
            .unwrap();
        assert!(worst <= 2, "CPU and GPU renders differ by {worst} levels");
    } else {
        assert!(err.contains("adapter"), "a GPU failure must say why: {err}");
        eprintln!("SKIPPED: compose --backend gpu: no wgpu adapter ({})", err.trim());
    }

    // bad scripts: errors name the line
    let bad = |name: &str, body: &str| {
        std::fs::write(dir.join(name), format!("Scene(\n  base: \"lib/layout.ron\",\n{body})\n"))
            .unwrap();
    };
    bad("unknown.ron", "  layout: [\n    Instance(asset: \"cat7\", at: (0, 0)),\n  ],\n");
    fail(
        &dir,
        &["compose", "unknown.ron", "--library", "lib", "--out", "x"],
        &["unknown.ron:4:", "unknown asset \"cat7\""],
    );
    bad("scale.ron", "  edits: [\n    Scale(target: \"w0\", to: 0.0),\n  ],\n");
    fail(
        &dir,
        &["compose", "scale.ron", "--library", "lib", "--out", "x"],
        &["scale.ron:4:", "scale must be positive"],
    );
    bad("far.ron", "  edits: [\n    Move(target: \"b0\", to: (40.0, 0.0)),\n  ],\n");
    fail(
        &dir,
        &["compose", "far.ron", "--library", "lib", "--out", "x"],
        &["far.ron:4:", "outside the canvas"],
    );
    std::fs::write(
        dir.join("prim.ron"),
        "Scene(\n  assets: {\n    \"box\": Asset(parts: [Box(center: (0, 0, 0.1), size: (0.2, 0.2, 0.2), color: (1, 0, 0))]),\n  },\n  layout: [Instance(asset: \"box\", at: (0, 0))],\n)\n",
    )
    .unwrap();
    fail(
        &dir,
        &["compose", "prim.ron", "--library", "lib", "--out", "x"],
        &["prim.ron:3:", "library assets"],
    );
    // a patch from a library trained separately (other axes and decoders)
    // (a copy of the library whose shared tensors differ, with a consistent index)
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::copy(dir.join("lib/patches.safetensors"), other.join("patches.safetensors")).unwrap();
    let mut shared = TensorFile::load(&dir.join("lib/shared.safetensors")).unwrap();
    let shape = shared.shape_of("density.axis").unwrap().to_vec();
    let mut axis = shared.get_f32("density.axis", &shape).unwrap().to_vec();
    axis[0] += 0.5;
    shared.insert_f32("density.axis", &shape, axis);
    shared.save(&other.join("shared.safetensors")).unwrap();
    let mut index = lib.index.clone();
    index.shared.hash = content_hash(&shared);
    std::fs::write(other.join("index.ron"), index_to_ron(&index).unwrap()).unwrap();
    std::fs::write(
        dir.join("foreign.ron"),
        "Scene(\n  assets: {\n    \"alien\": Asset(library: Library(path: \"other\", entry: \"obj000\", size: (0.5, 0.5, 0.5))),\n  },\n  layout: [Instance(asset: \"alien\", at: (0, 0))],\n)\n",
    )
    .unwrap();
    fail(
        &dir,
        &["compose", "foreign.ron", "--library", "lib", "--out", "x"],
        &["foreign.ron:3:", "axes and decoders"],
    );
    fail(
        &dir,
        &["compose", "lib/layout.ron", "--library", "lib", "--out", "x", "--canvas", "attic"],
        &["no container \"attic\""],
    );
    assert!(!dir.join("x").exists(), "a failed run must not leave its output");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `library check` says ok only for libraries `compose` composes: on each broken library
/// found by fuzzing both fail, naming the file and the entry or tensor (compose's error used
/// to name no file).
#[test]
fn library_check_fails_wherever_compose_would() {
    use assetfield_library::{INDEX_FILE, index_from_ron, write_sample_library};
    let dir = scratch("library-check");
    std::fs::write(
        dir.join("one.ron"),
        "Scene(layout: [Instance(asset: \"obj000\", at: (0.2, 0.15))])\n",
    )
    .unwrap();
    let compose = |lib: &str, out: &str| -> Vec<String> {
        ["compose", "one.ron", "--library", lib, "--out", out, "--orbit", "1", "--res", "8"]
            .iter()
            .map(|s| s.to_string())
            .chain(["--backend".into(), "cpu".into()])
            .collect()
    };
    fn args(v: &[String]) -> Vec<&str> {
        v.iter().map(String::as_str).collect()
    }
    write_sample_library(&dir.join("good"), 0.25).unwrap();
    let out = ok(&dir, &["library", "check", "good"]);
    assert!(out.contains("2 entries") && out.contains("ok"), "{out}");
    ok(&dir, &args(&compose("good", "composed")));

    let index_edit = |lib: &Path, edit: &dyn Fn(&mut assetfield_library::LibraryIndex)| {
        let p = lib.join(INDEX_FILE);
        let mut ix = index_from_ron(&p, &std::fs::read_to_string(&p).unwrap()).unwrap();
        edit(&mut ix);
        std::fs::write(&p, index_to_ron(&ix).unwrap()).unwrap();
    };
    type Break = Box<dyn Fn(&Path)>;
    let cases: Vec<(&str, Break, &str, &str)> = vec![
        (
            "texel",
            Box::new(move |l| index_edit(l, &|ix| ix.texel_size = (0.0, 0.0))),
            "index.ron",
            "\"texel_size\" is (0.0, 0.0)",
        ),
        (
            "listed",
            Box::new(move |l| index_edit(l, &|ix| ix.shared.tensors.push("decoder.5.bias".into()))),
            "shared.safetensors",
            "missing tensor \"decoder.5.bias\"",
        ),
        (
            "config",
            Box::new(|l| {
                let p = l.join("shared.safetensors");
                let mut f = TensorFile::load(&p).unwrap();
                let c = f.meta("config").unwrap().replace("\"basis_dim\":3", "\"basis_dim\":6");
                f.set_meta("config", c);
                f.save(&p).unwrap();
            }),
            "shared.safetensors",
            "tensor \"color.basis.weight\" has shape [3, 4], expected [6, 4]",
        ),
        (
            "nan-patch",
            Box::new(|l| {
                let p = l.join("patches.safetensors");
                let mut f = TensorFile::load(&p).unwrap();
                f.insert_f32("obj000.density", &[2, 3, 2], vec![f32::NAN; 12]);
                f.save(&p).unwrap();
            }),
            "patches.safetensors",
            "tensor \"obj000.density\" has a non-finite value (NaN) at index 0",
        ),
        (
            "nan-yaw",
            Box::new(move |l| index_edit(l, &|ix| ix.entries[1].yaw_deg = f32::NAN)),
            "index.ron",
            "entry \"obj001\": \"yaw_deg\" is NaN",
        ),
    ];
    for (name, breaks, file, needle) in &cases {
        write_sample_library(&dir.join(name), 0.25).unwrap();
        breaks(&dir.join(name));
        let path = Path::new(name).join(file).display().to_string();
        fail(&dir, &["library", "check", name], &[&path, needle]);
        let out = format!("out-{name}");
        fail(&dir, &args(&compose(name, &out)), &[&path, needle]);
        assert!(!dir.join(&out).exists(), "{name}: compose wrote {out}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

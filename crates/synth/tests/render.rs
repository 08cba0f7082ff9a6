//! The ground-truth renderer and dataset writer.

use assetfield_core::{Camera, Intrinsics};
use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_layout::{GtLayout, PartsCatalog, load_str, resolve};
use assetfield_synth::synth::{RigView, SynthConfig};
use assetfield_synth::{AssetSet, Light, Scene, SynthOptions, camera_rig, synthesize};
use glam::Vec3;
use std::path::{Path, PathBuf};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("assetfield-synth-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn one_box_scene() -> (Scene, assetfield_layout::ResolvedLayout) {
    let text = r#"Scene(
        assets: { "b": Asset(parts: [Box(center: (0, 0, 0.5), size: (1, 1, 1), color: (0.8, 0.2, 0.1))]) },
        layout: [Instance(asset: "b", at: (0, 0))],
    )"#;
    let loaded = load_str(Path::new("box.ron"), text).unwrap();
    let assets = AssetSet::from_script(&loaded).unwrap();
    let layout = resolve(&loaded, &assets).unwrap();
    // the synthesiser's catalog agrees with the primitive-only one
    assert_eq!(
        resolve(&loaded, &PartsCatalog::from_script(&loaded)).unwrap().instances[0].bev_aabb,
        layout.instances[0].bev_aabb
    );
    (Scene::new(&layout, &assets, Light::default()), layout)
}

#[test]
fn top_face_is_lambert_shaded_and_background_is_transparent() {
    let (scene, _) = one_box_scene();
    let k = Intrinsics::from_fov_x(64, 64, 0.5);
    let cam = Camera::look_at(k, Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, Vec3::Y);
    let img = scene.render(&cam, 2);
    let l = Light::default();
    let shade = l.ambient + (1.0 - l.ambient) * l.direction.z;
    let centre = img.get_pixel(32, 32);
    let expect = [0.8 * shade, 0.2 * shade, 0.1 * shade].map(|v| (v * 255.0).round() as i32);
    for c in 0..3 {
        assert!((centre[c] as i32 - expect[c]).abs() <= 1, "{centre:?} vs {expect:?}");
    }
    assert_eq!(centre[3], 255);
    assert_eq!(img.get_pixel(0, 0)[3], 0, "background is transparent");
    // along the box's silhouette some pixels are partly covered (anti-aliasing)
    let partial = img.pixels().filter(|p| p[3] > 0 && p[3] < 255).count();
    assert!(partial > 10, "expected anti-aliased edges, found {partial} partial pixels");
    let no_aa = scene.render(&cam, 1);
    assert!(no_aa.pixels().all(|p| p[3] == 0 || p[3] == 255));
}

#[test]
fn obj_meshes_load_with_textures_and_levelling() {
    let text = r#"Scene(assets: {
        "crate": Asset(obj: Obj(path: "assets/meshes/crate.obj", scale: 0.8)),
        "vase": Asset(obj: Obj(path: "assets/meshes/vase.obj", up: Y)),
    })"#;
    let loaded = load_str(&scenes_dir().join("virtual.ron"), text).unwrap();
    let assets = AssetSet::from_script(&loaded).unwrap();
    let crate_g = &assets.geometry["crate"];
    let b = crate_g.bounds();
    assert!((b.extent() - Vec3::splat(0.8)).abs().max_element() < 1e-3, "{b:?}");
    assert!(
        b.min.z.abs() < 1e-3 && b.center().truncate().length() < 1e-3,
        "recentred on the floor: {b:?}"
    );
    assert_eq!(crate_g.textures.len(), 1);
    // the texture shows through: the crate's top face is not one flat colour
    let mut colours = Vec::new();
    for x in [-0.35f32, -0.1, 0.05, 0.2, 0.37] {
        let h = crate_g.intersect(Vec3::new(x, 0.02, 2.0), -Vec3::Z, f32::INFINITY).unwrap();
        assert!((h.t - 1.2).abs() < 1e-3);
        colours.push(h.color);
    }
    let spread = colours.iter().map(|c| (*c - colours[0]).length()).fold(0.0, f32::max);
    assert!(spread > 0.1, "texture lookups vary across the face: {colours:?}");
    // the Y-up vase stands up along +Z after levelling, with its MTL colours
    let vb = assets.geometry["vase"].bounds();
    assert!((vb.extent().z - 0.36).abs() < 1e-3 && vb.extent().x < 0.25, "{vb:?}");
    let mats: Vec<Vec3> = assets.geometry["vase"].materials.iter().map(|m| m.color).collect();
    assert!(mats.iter().any(|c| (*c - Vec3::new(0.1, 0.5, 0.55)).length() < 1e-4), "{mats:?}");
}

#[test]
fn a_missing_obj_names_the_asset_and_place() {
    let text = "Scene(assets: {\n  \"ghost\": Asset(obj: Obj(path: \"nowhere.obj\")),\n})";
    let loaded = load_str(Path::new("/tmp/x.ron"), text).unwrap();
    let e = AssetSet::from_script(&loaded).unwrap_err().to_string();
    assert!(
        e.starts_with("/tmp/x.ron:2:3") && e.contains("ghost") && e.contains("nowhere.obj"),
        "{e}"
    );
}

#[test]
fn camera_rig_covers_the_upper_half_sphere() {
    let bounds = assetfield_core::Aabb3::new(Vec3::new(-2.0, -1.0, 0.0), Vec3::new(2.0, 1.0, 1.0));
    let cfg = SynthConfig::DEFAULT;
    let rig: Vec<RigView> = camera_rig(&bounds, &cfg);
    assert_eq!(rig.len(), 50);
    assert_eq!(rig.iter().filter(|v| v.test).count(), 10);
    let c = bounds.center();
    let r0 = (rig[0].camera.position() - c).length();
    for v in &rig {
        let to = v.camera.position() - c;
        assert!((to.length() - r0).abs() < 1e-3);
        let elev = (to.z / to.length()).asin().to_degrees();
        assert!((14.9..=75.1).contains(&elev), "{elev}");
        assert!((v.camera.forward() - (-to).normalize()).length() < 1e-4);
    }
    // azimuths spread all around
    let mut quadrants = [0; 4];
    for v in &rig {
        let p = v.camera.position() - c;
        quadrants[(usize::from(p.x > 0.0)) * 2 + usize::from(p.y > 0.0)] += 1;
    }
    assert!(quadrants.iter().all(|q| *q >= 8), "{quadrants:?}");
    // the whole scene is in view from every camera
    for v in &rig {
        for corner in bounds.corners() {
            let uv = v.camera.project(corner).unwrap();
            assert!(uv.min_element() >= 0.0 && uv.max_element() <= cfg.resolution as f32, "{uv:?}");
        }
    }
}

#[test]
fn synth_writes_a_loadable_dataset_with_ground_truth_and_edits() {
    let root = scratch("roundtrip");
    let out = root.join("data");
    let scene = scenes_dir().join("dining_hall.ron");
    let edited = root.join("edited.ron");
    std::fs::write(
        &edited,
        format!(
            "Scene(base: {:?}, edits: [Move(target: \"tables[0]\", by: (0.5, 0)), Rotate(target: \"tables[1]/chairs[0]\", by: 90), Remove(\"plants[0]\"), Duplicate(target: \"plants[1]\", by: (1, 0))])",
            scene.display().to_string()
        ),
    )
    .unwrap();
    let opts = SynthOptions {
        views: Some(6),
        test_views: Some(2),
        resolution: Some(40),
        samples_per_side: Some(1),
        ..Default::default()
    };
    let mut calls = 0;
    let report =
        synthesize(&scene, &opts, &out, false, Some(&edited), &mut |_, _| calls += 1).unwrap();
    assert_eq!((report.train_views, report.test_views, report.edited_views), (4, 2, 2));
    assert_eq!(calls, 8);
    for f in [
        "transforms_train.json",
        "transforms_test.json",
        "gt_layout.json",
        "layout.png",
        "synth.json",
        "train/r_3.png",
        "test/r_1.png",
        "edited/test/r_0.png",
        "edited/gt_layout.json",
    ] {
        assert!(out.join(f).exists(), "missing {f}");
    }
    let train = Dataset::load(&out, Split::Train, &LoadOptions::default()).unwrap();
    let test = Dataset::load(&out, Split::Test, &LoadOptions::default()).unwrap();
    assert_eq!((train.frames.len(), test.frames.len()), (4, 2));
    assert_eq!(train.resolution(), (40, 40));
    let rig = camera_rig(
        &assetfield_core::Aabb3::new(
            Vec3::from(report.scene_aabb[0]),
            Vec3::from(report.scene_aabb[1]),
        ),
        &report.config,
    );
    let test_rig: Vec<_> = rig.iter().filter(|v| v.test).collect();
    for (f, v) in test.frames.iter().zip(&test_rig) {
        assert!((f.camera.position() - v.camera.position()).length() < 1e-4);
        assert!((f.camera.intrinsics.fx - v.camera.intrinsics.fx).abs() < 1e-3);
    }
    let gt = GtLayout::read(&out.join("gt_layout.json")).unwrap();
    assert_eq!(gt.instances.len(), report.instances);
    let egt = GtLayout::read(&out.join("edited/gt_layout.json")).unwrap();
    assert_eq!(egt.instances.len(), gt.instances.len(), "one removed, one duplicated");
    let moved = egt.instances.iter().find(|i| i.key == "tables[0]").unwrap();
    let orig = gt.instances.iter().find(|i| i.key == "tables[0]").unwrap();
    assert!((moved.position[0] - orig.position[0] - 0.5).abs() < 1e-5);
    // the edited test views are rendered from the same cameras but differ in content
    let a = image::open(out.join("test/r_0.png")).unwrap().to_rgba8();
    let b = image::open(out.join("edited/test/r_0.png")).unwrap().to_rgba8();
    assert_eq!(a.dimensions(), b.dimensions());
    assert_ne!(a.as_raw(), b.as_raw());
    // an existing output is never replaced without --force, and stays intact
    let again = synthesize(&scene, &opts, &out, false, None, &mut |_, _| {});
    assert!(again.unwrap_err().to_string().contains("already exists"));
    assert!(out.join("edited/gt_layout.json").exists());
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn bad_settings_are_refused_before_anything_is_written() {
    let root = scratch("settings");
    let out = root.join("data");
    let scene = scenes_dir().join("plaza.ron");
    for opts in [
        SynthOptions { views: Some(1), ..Default::default() },
        SynthOptions { views: Some(10), test_views: Some(10), ..Default::default() },
        SynthOptions { resolution: Some(2), ..Default::default() },
        SynthOptions { elevation_deg: Some((60.0, 30.0)), ..Default::default() },
    ] {
        let e = synthesize(&scene, &opts, &out, false, None, &mut |_, _| {}).unwrap_err();
        assert!(e.to_string().contains("invalid synthesis settings"), "{e}");
        assert!(!out.exists());
    }
    assert_eq!(std::fs::read_dir(&root).unwrap().count(), 0, "no staging folder left behind");
    std::fs::remove_dir_all(&root).unwrap();
}

/// Synthesise the script `text` (written to `scene.ron` in a scratch folder) and return
/// the error's message; nothing may be written.
fn synth_error(name: &str, text: &str, opts: &SynthOptions) -> String {
    let root = scratch(name);
    let (scene, out) = (root.join("scene.ron"), root.join("data"));
    std::fs::write(&scene, text).unwrap();
    let e = synthesize(&scene, opts, &out, false, None, &mut |_, _| {}).unwrap_err();
    assert!(!out.exists(), "nothing written");
    std::fs::remove_dir_all(&root).unwrap();
    e.to_string().replace(&format!("{}", scene.display()), "scene.ron")
}

#[test]
fn an_empty_scene_is_refused_with_its_place() {
    let floor = r#""floor": Asset(container: true, parts: [Box(center: (0, 0, -0.01), size: (4, 4, 0.02), color: (0.5, 0.5, 0.5))])"#;
    let opts = SynthOptions::default();
    let e = synth_error(
        "empty",
        &format!("Scene(\n    assets: {{ {floor} }},\n    layout: [],\n)\n"),
        &opts,
    );
    assert_eq!(
        e,
        "scene.ron:3:5: nothing to render: the resolved layout has no instances; add objects to `layout`"
    );
    let containers = format!(
        "Scene(\n    assets: {{ {floor} }},\n    layout: [Instance(asset: \"floor\", at: (0, 0))],\n)\n"
    );
    let e = synth_error("containers", &containers, &opts);
    assert!(e.contains("containers only (1 instances, no object)"), "{e}");
}

#[test]
fn non_finite_positions_are_refused_before_rendering() {
    let text = "Scene(\n    assets: { \"b\": Asset(parts: [Box(center: (0, 0, 0.5), size: (1, 1, 1), color: (1, 0, 0))]) },\n    layout: [\n        Instance(asset: \"b\", at: (NaN, 0)),\n    ],\n)\n";
    let e = synth_error("nan", text, &SynthOptions::default());
    assert_eq!(e, "scene.ron:4:9: Instance: at must be a point of finite numbers, got (NaN, 0)");
}

#[test]
fn bad_views_of_a_script_name_the_script_line() {
    let scene = |views: &str| {
        format!(
            "Scene(\n    assets: {{ \"b\": Asset(parts: [Box(center: (0, 0, 0.5), size: (1, 1, 1), color: (1, 0, 0))]) }},\n    views: {views},\n    layout: [Instance(asset: \"b\", at: (0, 0))],\n)\n"
        )
    };
    // out of range on its own: refused when the script is loaded
    let e = synth_error("res", &scene("(resolution: 0)"), &SynthOptions::default());
    assert_eq!(e, "scene.ron:3:5: views: resolution must be 8..=8192 pixels, got 0");
    // the script's test views against the views of the command line
    let opts = SynthOptions { views: Some(20), ..Default::default() };
    let e = synth_error("test", &scene("(test: 40)"), &opts);
    assert_eq!(
        e,
        "scene.ron:3:5: views: test must be between 1 and 19 (one less than the 20 views from --views), got 40"
    );
    // the script's views against the default test views
    let e = synth_error("count", &scene("(count: 5)"), &SynthOptions::default());
    assert_eq!(
        e,
        "scene.ron:3:5: views: count must be more than the 10 test views by default, got 5"
    );
    // a bad flag is still reported as a flag
    let opts = SynthOptions { test_views: Some(30), ..Default::default() };
    let e = synth_error("flag", &scene("(count: 20)"), &opts);
    assert!(
        e.starts_with(
            "scene.ron:3:5: views: count must be more than the 30 test views from --test-views"
        ),
        "{e}"
    );
    let opts = SynthOptions { views: Some(20), test_views: Some(30), ..Default::default() };
    let e = synth_error("flags", &scene("(resolution: 64)"), &opts);
    assert_eq!(
        e,
        "invalid synthesis settings: --test-views must be between 1 and views - 1 (19), got 30"
    );
}

#[test]
fn the_ground_truth_box_of_a_turned_round_object_is_its_own_size() {
    // a round stool (radius 0.25) and a square crate (0.5), both turned by 45 degrees
    let text = r#"Scene(
        assets: {
            "stool": Asset(parts: [Cylinder(base: (0, 0, 0), radius: 0.25, height: 0.7, color: (0.5, 0.5, 0.5))]),
            "crate": Asset(parts: [Box(center: (0, 0, 0.25), size: (0.5, 0.5, 0.5), color: (0.6, 0.4, 0.2))]),
        },
        layout: [
            Instance(asset: "stool", at: (0, 0), yaw: 45),
            Instance(asset: "crate", at: (2, 0), yaw: 45),
        ],
    )"#;
    let loaded = load_str(Path::new("round.ron"), text).unwrap();
    let assets = AssetSet::from_script(&loaded).unwrap();
    let layout = resolve(&loaded, &assets).unwrap();
    let size = |i: usize| layout.instances[i].bev_aabb.size();
    // the stool's box is its disc's (0.5), not its turned square footprint's (0.71)
    assert!((size(0) - glam::Vec2::splat(0.5)).abs().max_element() < 0.005, "{}", size(0));
    // the crate's turned corners do reach 0.71
    let d = 0.5 * std::f32::consts::SQRT_2;
    assert!((size(1) - glam::Vec2::splat(d)).abs().max_element() < 1e-3, "{}", size(1));
}

#[test]
fn a_mesh_path_that_is_no_regular_file_is_refused_without_reading_it() {
    // as `base:` and `include:` are: /dev/zero would be read for ever, a folder is no mesh
    let dir = scratch("mesh-device");
    for (name, path) in [("zero", "/dev/zero"), ("folder", "/tmp")] {
        let text = format!(
            "Scene(\n    assets: {{ \"m\": Asset(obj: Obj(path: \"{path}\")) }},\n    layout: [Instance(asset: \"m\", at: (0, 0))],\n)\n"
        );
        let script = dir.join(format!("{name}.ron"));
        std::fs::write(&script, text).unwrap();
        let e = assetfield_synth::load_scene(&script).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{name}: {e}");
        assert!(e.contains(&format!("{name}.ron:2:")), "{name}: {e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

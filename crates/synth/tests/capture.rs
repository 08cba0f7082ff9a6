//! Hand-held captures (`synth --capture`): the room drawn for one, and the photos written.

use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_layout::{load_str, resolve};
use assetfield_synth::random::{Style, random_scene_styled};
use assetfield_synth::{AssetSet, LoadedScene, SynthOptions, synthesize_loaded};
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("assetfield-capture-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// A primitive room (no catalog needed): two objects, a floor, walls all round, 8 x 6 units.
const ROOM: &str = r#"Scene(
    extent: ((-4, -3), (4, 3)),
    views: (count: 8, test: 2, resolution: 24, capture: (seed: 5)),
    assets: {
        "room": Asset(container: true, parts: [
            Box(center: (0, 0, -0.01), size: (8, 6, 0.02), color: (0.5, 0.45, 0.4)),
            Box(center: (0, -3.05, 1.25), size: (8.2, 0.1, 2.5), color: (0.8, 0.8, 0.7)),
            Box(center: (0, 3.05, 1.25), size: (8.2, 0.1, 2.5), color: (0.7, 0.8, 0.8)),
            Box(center: (-4.05, 0, 1.25), size: (0.1, 6.2, 2.5), color: (0.8, 0.7, 0.8)),
            Box(center: (4.05, 0, 1.25), size: (0.1, 6.2, 2.5), color: (0.7, 0.7, 0.9)),
        ]),
        "crate": Asset(parts: [Box(center: (0, 0, 0.4), size: (0.8, 0.8, 0.8), color: (0.8, 0.3, 0.1))]),
    },
    layout: [
        Instance(asset: "room", at: (0, 0)),
        Instance(asset: "crate", at: (-1, 0.5)),
        Instance(asset: "crate", at: (1.2, -0.5), yaw: 30),
    ],
)"#;

fn synth_room(out: &Path, text: &str) -> assetfield_synth::SynthReport {
    let path = PathBuf::from("room.ron");
    let loaded = load_str(&path, text).unwrap();
    let mut progress = |_: usize, _: usize| {};
    let source = LoadedScene { script: &loaded, path: &path, text: None };
    let opts = SynthOptions { samples_per_side: Some(1), ..Default::default() };
    synthesize_loaded(source, &opts, out, true, None, &mut progress).unwrap()
}

#[test]
fn a_capture_writes_opaque_photos_taken_from_inside_the_room() {
    let out = scratch("room");
    let report = synth_room(&out, ROOM);
    let cap = report.capture.as_ref().expect("the script asks for a capture");
    assert_eq!((cap.train_gains.len(), cap.test_gains.len()), (6, 2));
    assert_eq!(report.config.fov_deg, assetfield_synth::capture::FOV_DEG);
    let synth_json = std::fs::read_to_string(out.join("synth.json")).unwrap();
    assert!(synth_json.contains("\"train_gains\""), "synth.json records the gains");
    // photos are RGB, no alpha channel
    let img = image::open(out.join("train/r_0.png")).unwrap();
    assert_eq!(img.color(), image::ColorType::Rgb8);
    // the dataset reads back; every camera stands on the path at eye height, looking into
    // the room; every pixel is opaque
    let ds = Dataset::load(&out, Split::All, &LoadOptions::default()).unwrap();
    assert_eq!(ds.frames.len(), 8);
    for f in &ds.frames {
        let p = f.camera.position();
        assert!(p.x.abs() <= 3.5 + 1e-3 && p.y.abs() <= 2.5 + 1e-3, "{p}");
        assert!((p.x.abs() - 3.5).abs() < 1e-3 || (p.y.abs() - 2.5).abs() < 1e-3, "{p}");
        assert!((p.z - 1.6).abs() < 0.3, "{p}");
        assert!(f.camera.forward().z < 0.0);
        assert!(f.image.alpha.is_none(), "{} has an alpha channel", f.file_path);
    }
    // the same script gives the same photos, byte for byte
    let again = scratch("room-again");
    synth_room(&again, ROOM);
    for name in ["train/r_0.png", "test/r_1.png"] {
        assert_eq!(
            std::fs::read(out.join(name)).unwrap(),
            std::fs::read(again.join(name)).unwrap()
        );
    }
    // where the walls are low, the sky shows over them: the top rows are bluer than red
    let low = ROOM
        .replace("1.25), size: (8.2, 0.1, 2.5)", "0.1), size: (8.2, 0.1, 0.2)")
        .replace("1.25), size: (0.1, 6.2, 2.5)", "0.1), size: (0.1, 6.2, 0.2)");
    let sky = scratch("sky");
    synth_room(&sky, &low);
    let blue = (0..6)
        .map(|k| {
            let img = image::open(sky.join(format!("train/r_{k}.png"))).unwrap().to_rgb8();
            img.pixels().filter(|p| p[2] as i32 > p[0] as i32 + 20).count()
        })
        .sum::<usize>();
    assert!(blue > 20, "the sky over low walls: {blue} blue pixels");
    for d in [out, again, sky] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn bad_capture_settings_name_the_script_line() {
    let bad = ROOM.replace("capture: (seed: 5)", "capture: (noise: 2)");
    let e = load_str(Path::new("room.ron"), &bad).unwrap_err().to_string();
    assert!(e.contains("room.ron:3:") && e.contains("noise"), "{e}");
    let unknown = ROOM.replace("capture: (seed: 5)", "capture: (iso: 100)");
    let e = load_str(Path::new("room.ron"), &unknown).unwrap_err().to_string();
    assert!(e.contains("room.ron:3:") && e.contains("iso"), "{e}");
    // a path that does not fit in the room
    let tight = ROOM.replace("capture: (seed: 5)", "capture: (path_inset: 3.5)");
    let path = PathBuf::from("room.ron");
    let loaded = load_str(&path, &tight).unwrap();
    let mut progress = |_: usize, _: usize| {};
    let source = LoadedScene { script: &loaded, path: &path, text: None };
    let out = scratch("tight");
    let e = synthesize_loaded(source, &SynthOptions::default(), &out, true, None, &mut progress)
        .unwrap_err()
        .to_string();
    assert!(e.contains("too small for a walking path"), "{e}");
    assert!(!out.exists(), "nothing written");
}

#[test]
fn a_drawn_capture_room_is_closed_textured_and_leaves_a_path_clear() {
    for seed in [1, 2, 3, 1001] {
        let r = random_scene_styled(seed, Style::Capture).unwrap();
        assert_eq!(r.text, random_scene_styled(seed, Style::Capture).unwrap().text);
        let back = assetfield_layout::source::parse_script(Path::new("r.ron"), &r.text).unwrap();
        assert_eq!(back, r.script);
        assert!(r.text.contains("--capture"));
        let views = r.script.views.as_ref().unwrap();
        assert!(views.capture.is_some());
        let ((x0, y0), (x1, y1)) = r.script.extent.unwrap();
        let u = r.units_per_metre;
        // a tiled floor
        assert!(
            r.floor.contains("checker")
                || r.floor.contains("planks")
                || r.floor.contains("carpet")
                || r.floor.contains("asphalt"),
            "{}",
            r.floor
        );
        let loaded = load_str(Path::new("r.ron"), &r.text).unwrap();
        let layout = resolve(&loaded, &r.catalog().unwrap()).unwrap();
        // the container covers the extent and stands above eye height all round
        let room = layout.instances.iter().find(|i| i.container).expect("a room container");
        let def = &r.script.assets[&room.asset];
        let b = def.parts_bounds();
        assert!(b.min.x <= x0 && b.max.x >= x1 && b.min.y <= y0 && b.max.y >= y1, "{b:?}");
        assert!(b.max.z >= 2.4 * u * 0.999, "walls {} high", b.max.z);
        assert!(def.parts.len() > 40, "wallpaper, pictures and tiles: {} parts", def.parts.len());
        // every object clear of the walking path (0.5 m inside the extent) by a step
        let margin = 0.5 * u + 0.3 * u;
        for i in layout.objects() {
            let f = i.bev_aabb;
            assert!(
                f.min.x >= x0 + margin
                    && f.max.x <= x1 - margin
                    && f.min.y >= y0 + margin
                    && f.max.y <= y1 - margin,
                "seed {seed}: {} at {f:?} is in the walk (extent {x0}..{x1} x {y0}..{y1})",
                i.key
            );
        }
        // the orbit draw of the same seed is untouched by the capture's
        assert!(!assetfield_synth::random::random_scene(seed).unwrap().text.contains("capture"));
    }
    // synthesising needs the catalogs: one tiny capture through the same path as the CLI
    if !assetfield_synth::sh3f::catalogs_installed(&assetfield_synth::sh3f::catalog_dir()) {
        if std::env::var("ASSETFIELD_STRICT_TESTS").as_deref() == Ok("1") {
            panic!(
                "capture synthesis: sweethome3d-furniture not installed and ASSETFIELD_STRICT_TESTS=1"
            );
        }
        eprintln!("SKIPPED: sweethome3d-furniture not installed; capture synthesis did not run");
        return;
    }
    let r = random_scene_styled(2, Style::Capture).unwrap();
    let path = PathBuf::from("capture_2.ron");
    let loaded = load_str(&path, &r.text).unwrap();
    let assets = AssetSet::from_script(&loaded).unwrap();
    assert!(resolve(&loaded, &assets).is_ok());
    let out = scratch("drawn");
    let opts = SynthOptions {
        views: Some(6),
        test_views: Some(1),
        resolution: Some(16),
        samples_per_side: Some(1),
        ..Default::default()
    };
    let mut progress = |_: usize, _: usize| {};
    let source = LoadedScene { script: &loaded, path: &path, text: Some(&r.text) };
    let report = synthesize_loaded(source, &opts, &out, false, None, &mut progress).unwrap();
    assert_eq!(report.capture.unwrap().train_gains.len(), 5);
    let _ = std::fs::remove_dir_all(out);
}

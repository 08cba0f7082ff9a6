//! Real furniture from Sweet Home 3D catalogs (Debian's `sweethome3d-furniture`): indexes,
//! sizes and orientation of loaded models, the curated list, errors with locations.
//!
//! Tests that need the installed package print `SKIPPED: sweethome3d-furniture not
//! installed (...)` when the catalog folder is missing, and fail instead when
//! `ASSETFIELD_STRICT_TESTS=1`.

use assetfield_core::{Camera, Intrinsics};
use assetfield_layout::{load_str, resolve};
use assetfield_synth::curated::{CURATED, Placement};
use assetfield_synth::sh3f::{ALLOWED_CATALOGS, Catalog, DIR_ENV, catalog_dir, catalogs_installed};
use assetfield_synth::{AssetSet, Light, Scene};
use glam::Vec3;
use std::path::Path;

/// The catalog folder, or `None` after saying loudly why the test does not run.
fn catalogs_or_skip(test: &str) -> Option<std::path::PathBuf> {
    let dir = catalog_dir();
    if catalogs_installed(&dir) {
        return Some(dir);
    }
    let why = format!(
        "{} lacks {} (apt-get install sweethome3d-furniture, or set {DIR_ENV})",
        dir.display(),
        ALLOWED_CATALOGS.map(|c| format!("{c}.sh3f")).join(", ")
    );
    if std::env::var("ASSETFIELD_STRICT_TESTS").as_deref() == Ok("1") {
        panic!("{test}: sweethome3d-furniture not installed ({why}) and ASSETFIELD_STRICT_TESTS=1");
    }
    eprintln!("SKIPPED: sweethome3d-furniture not installed ({why}); {test} did not run");
    None
}

#[test]
fn both_indexes_parse_and_the_curated_models_follow_the_rules() {
    let Some(dir) = catalogs_or_skip("indexes") else { return };
    let bs = Catalog::open_in(&dir, "BlendSwap-CC-BY").unwrap();
    let kl = Catalog::open_in(&dir, "KatorLegaz").unwrap();
    assert_eq!(bs.models.len(), 135);
    assert_eq!(kl.models.len(), 90);
    let chair = kl.model("Kator Legaz#mid-century-chair").unwrap();
    assert_eq!((chair.width_cm, chair.depth_cm, chair.height_cm), (73.5, 84.4, 80.0));
    assert_eq!(chair.model, "katorlegaz/mid-century-chair/mid-century-chair.obj");
    assert_eq!(chair.creator, "Kator Legaz");
    // the catalog licence is Latin-1 (a copyright sign) and reaches every model
    assert!(chair.license.contains("Creative Commons") && chair.license.contains('\u{a9}'));
    let flashlight = kl.model("Kator Legaz#flashlight").unwrap();
    assert_eq!(flashlight.model_rotation, Some([1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0]));
    assert!(bs.models.iter().all(|m| m.license.starts_with("Creative Commons Attribution")));
    assert!(
        kl.models.iter().any(|m| m.door_or_window)
            && kl.models.iter().any(|m| m.elevation_cm > 0.0)
    );

    for c in CURATED {
        let cat = if c.catalog == "KatorLegaz" { &kl } else { &bs };
        let m = cat.model(c.id).unwrap();
        assert_eq!((m.width_cm, m.depth_cm, m.height_cm), c.size_cm, "{}", c.id);
        assert!(!m.door_or_window && m.elevation_cm == 0.0 && m.movable, "{}", c.id);
        assert!(!["Doors and windows", "Vehicles", "Characters"].contains(&m.category.as_str()));
        let (w, d, h) = c.size_cm;
        match c.placement {
            Placement::TableTop => {
                assert!(w >= 8.0 && d >= 8.0 && (5.0..80.0).contains(&h), "{}", c.id)
            }
            _ => assert!((30.0..=230.0).contains(&h) && w.max(d) < 220.0, "{}", c.id),
        }
    }
    // an unknown id gets a hint
    let e = kl.model("Kator Legaz#mid-century-chiar").unwrap_err().to_string();
    assert!(e.contains("did you mean \"Kator Legaz#mid-century-chair\""), "{e}");
}

const MODELS: [(&str, &str); 4] = [
    ("KatorLegaz", "Kator Legaz#mid-century-chair"),
    ("KatorLegaz", "Kator Legaz#flashlight"),
    ("BlendSwap-CC-BY", "Blend Swap CC-BY#chair3"),
    ("BlendSwap-CC-BY", "Blend Swap CC-BY#lamp"),
];

#[test]
fn models_are_sized_as_the_catalog_says_and_stand_on_the_ground() {
    let Some(dir) = catalogs_or_skip("model sizes") else { return };
    for (catalog, id) in MODELS {
        let c = Catalog::open_in(&dir, catalog).unwrap();
        let m = c.model(id).unwrap();
        let g = c.load_geometry(m).unwrap();
        let b = g.bounds();
        let want = Vec3::new(m.depth_cm, m.width_cm, m.height_cm) / 100.0;
        let got = b.extent();
        assert!(((got - want) / want).abs().max_element() < 0.01, "{id}: {got} vs {want}");
        let centre = b.center();
        assert!(centre.x.abs() < 0.01 * want.x && centre.y.abs() < 0.01 * want.y, "{id}: {centre}");
        assert!(b.min.z.abs() < 1e-3, "{id} floats or sinks: {}", b.min.z);
    }
}

/// A chair seen from the front and from above: it stands upright (more of it is covered near
/// the ground than at the top, nothing below the floor) and its front faces +X (its back
/// rest, the tallest part, is on the -X side).
#[test]
fn a_catalog_chair_renders_upright_facing_plus_x() {
    let Some(_) = catalogs_or_skip("chair render") else { return };
    let text = r#"Scene(
        assets: { "chair": Asset(obj: Catalog(name: "KatorLegaz", id: "Kator Legaz#dining-chair")) },
        layout: [Instance(asset: "chair", at: (0, 0))],
    )"#;
    let loaded = load_str(Path::new("chair.ron"), text).unwrap();
    let assets = AssetSet::from_script(&loaded).unwrap();
    assert_eq!(assets.sources["chair"].creator, "Kator Legaz");
    let layout = resolve(&loaded, &assets).unwrap();
    let inst = &layout.instances[0];
    // depth 57.3 cm along x, width 42.3 cm along y, height 1 m
    assert!((inst.footprint.size().x - 0.573).abs() < 0.006, "{:?}", inst.footprint);
    assert!((inst.footprint.size().y - 0.423).abs() < 0.005, "{:?}", inst.footprint);
    assert!((inst.top - 1.0).abs() < 0.01, "{}", inst.top);
    let scene = Scene::new(&layout, &assets, Light::default());
    let k = Intrinsics::from_fov_x(48, 48, 0.6);
    // from the side (+Y), looking along -Y: x to the right of the picture is +X
    let side = Camera::look_at(k, Vec3::new(0.0, 2.0, 0.5), Vec3::new(0.0, 0.0, 0.5), Vec3::Z);
    let img = scene.render(&side, 2);
    if let Ok(d) = std::env::var("ASSETFIELD_TEST_PICTURES") {
        // bigger pictures for a human: the side view and one from the front-left, above
        let k = Intrinsics::from_fov_x(256, 256, 0.6);
        let side = Camera::look_at(k, Vec3::new(0.0, 2.0, 0.5), Vec3::new(0.0, 0.0, 0.5), Vec3::Z);
        scene.render(&side, 2).save(Path::new(&d).join("catalog_chair_side.png")).unwrap();
        let front =
            Camera::look_at(k, Vec3::new(1.6, 1.0, 1.4), Vec3::new(0.0, 0.0, 0.45), Vec3::Z);
        scene.render(&front, 2).save(Path::new(&d).join("catalog_chair_front.png")).unwrap();
    }
    let covered = |x0: u32, x1: u32, y0: u32, y1: u32| {
        let mut n = 0;
        for y in y0..y1 {
            for x in x0..x1 {
                n += (img.get_pixel(x, y)[3] > 128) as u32;
            }
        }
        n
    };
    // camera at +Y looking at -Y with Z up: picture right = -X
    let (top_minus_x, top_plus_x) = (covered(24, 48, 0, 16), covered(0, 24, 0, 16));
    assert!(top_minus_x > 2 * top_plus_x.max(1), "back rest on -X: {top_minus_x} vs {top_plus_x}");
    let (upper, lower) = (covered(0, 48, 0, 24), covered(0, 48, 24, 48));
    assert!(lower > 0 && upper > 0);
}

#[test]
fn catalog_errors_name_the_script_line() {
    let Some(_) = catalogs_or_skip("catalog errors") else { return };
    let cases = [
        (
            r#"Asset(obj: Catalog(name: "Scopia", id: "x"))"#,
            "allowed catalogs: BlendSwap-CC-BY, KatorLegaz",
        ),
        (
            r#"Asset(obj: Catalog(name: "KatorLegaz", id: "Kator Legaz#dinning-chair"))"#,
            "did you mean \"Kator Legaz#dining-chair\"",
        ),
    ];
    for (asset, want) in cases {
        let text = format!("Scene(\n  assets: {{\n    \"a\": {asset},\n  }},\n)");
        let loaded = load_str(Path::new("/tmp/c.ron"), &text).unwrap();
        let e = AssetSet::from_script(&loaded).unwrap_err().to_string();
        assert!(e.starts_with("/tmp/c.ron:3:5") && e.contains(want), "{e}");
    }
}

#[test]
fn a_missing_package_is_named() {
    // independent of the installed package: a folder without catalogs
    let dir = std::env::temp_dir().join(format!("assetfield-nosh3f-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let e = Catalog::open_in(&dir, "KatorLegaz").unwrap_err().to_string();
    assert!(e.contains("apt-get install sweethome3d-furniture") && e.contains(DIR_ENV), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_broken_mesh_is_an_error_naming_the_model() {
    use std::io::Write;
    let dir = std::env::temp_dir().join(format!("assetfield-badsh3f-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let index = "id=test\nlicense=CC-BY\nid#1=Kator Legaz#broken\nname#1=Broken\nmodel#1=/b/broken.obj\nwidth#1=10\ndepth#1=10\nheight#1=10\nid#2=Kator Legaz#flat\nmodel#2=/b/flat.obj\nwidth#2=10\ndepth#2=10\nheight#2=10\n";
    let f = std::fs::File::create(dir.join("KatorLegaz.sh3f")).unwrap();
    let mut z = zip::ZipWriter::new(f);
    let opts =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, body) in [
        ("PluginFurnitureCatalog.properties", index),
        ("b/broken.obj", "v 0 0 0\nv 1 0 0\nf 1 2 x\n"),
        ("b/flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
    ] {
        z.start_file(name, opts).unwrap();
        z.write_all(body.as_bytes()).unwrap();
    }
    z.finish().unwrap();
    let c = Catalog::open_in(&dir, "KatorLegaz").unwrap();
    assert_eq!(c.license, "CC-BY");
    for (id, want) in
        [("Kator Legaz#broken", "broken mesh b/broken.obj"), ("Kator Legaz#flat", "flat")]
    {
        let e = c.load_geometry(c.model(id).unwrap()).unwrap_err().to_string();
        assert!(e.contains(id) && e.contains(want), "{e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every curated model loads (mesh, materials, textures) at the catalog's size.
#[test]
fn every_curated_model_loads_at_its_catalog_size() {
    let Some(dir) = catalogs_or_skip("curated models") else { return };
    let cats: Vec<Catalog> =
        ALLOWED_CATALOGS.iter().map(|c| Catalog::open_in(&dir, c).unwrap()).collect();
    for c in CURATED {
        let cat = cats.iter().find(|k| k.name == c.catalog).unwrap();
        let m = cat.model(c.id).unwrap();
        let g = cat.load_geometry(m).unwrap_or_else(|e| panic!("{}: {e}", c.id));
        let (w, d, h) = c.size_cm;
        let want = Vec3::new(d, w, h) / 100.0;
        let got = g.bounds().extent();
        assert!(((got - want) / want).abs().max_element() < 0.01, "{}: {got} vs {want}", c.id);
    }
}

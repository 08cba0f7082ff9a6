//! The scene as meshes (`synth --mesh`): what the OBJ holds is where the ray tracer sees the
//! scene, triangles face outwards, and textured materials keep their textures.

use assetfield_layout::{load_str, resolve};
use assetfield_synth::export::export_obj;
use assetfield_synth::{AssetSet, Light, Scene};
use glam::Vec3;
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("assetfield-export-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// One primitive per asset, each placed turned and scaled.
const PRIMITIVES: &str = r#"Scene(
    assets: {
        "box": Asset(parts: [Box(center: (0.1, 0, 0.4), size: (0.8, 0.5, 0.8), yaw: 20, color: (0.8, 0.2, 0.1))]),
        "drum": Asset(parts: [Cylinder(base: (0, 0, 0.3), radius: 0.3, height: 0.6, axis: X, color: (0.1, 0.5, 0.2))]),
        "cone": Asset(parts: [Cone(base: (0, 0, 0), radius: 0.4, top_radius: 0.1, height: 0.9, color: (0.2, 0.2, 0.9))]),
        "ball": Asset(parts: [Sphere(center: (0, 0, 0.35), radius: 0.35, color: (0.9, 0.9, 0.2))]),
    },
    layout: [
        Instance(asset: "box", at: (0, 0), yaw: 30, scale: 1.5),
        Instance(asset: "drum", at: (3, 0), yaw: 75),
        Instance(asset: "cone", at: (0, 3), scale: 0.7),
        Instance(asset: "ball", at: (3, 3)),
    ],
)"#;

/// Triangulated, one index for position, normal and texture coordinate.
const LOAD: tobj::LoadOptions = tobj::LoadOptions {
    single_index: true,
    triangulate: true,
    ignore_points: true,
    ignore_lines: true,
};

fn triangles(models: &[tobj::Model]) -> Vec<([Vec3; 3], Vec3)> {
    let mut out = Vec::new();
    for m in models {
        let v = |i: u32| {
            let i = 3 * i as usize;
            Vec3::new(m.mesh.positions[i], m.mesh.positions[i + 1], m.mesh.positions[i + 2])
        };
        let n = |i: u32| {
            let i = 3 * i as usize;
            Vec3::new(m.mesh.normals[i], m.mesh.normals[i + 1], m.mesh.normals[i + 2])
        };
        for t in m.mesh.indices.chunks(3) {
            out.push(([v(t[0]), v(t[1]), v(t[2])], (n(t[0]) + n(t[1]) + n(t[2])).normalize()));
        }
    }
    out
}

#[test]
fn primitives_export_where_the_tracer_sees_them_facing_outwards() {
    let dir = scratch("primitives");
    let loaded = load_str(Path::new("prims.ron"), PRIMITIVES).unwrap();
    let assets = AssetSet::from_script(&loaded).unwrap();
    let layout = resolve(&loaded, &assets).unwrap();
    let report = export_obj(&layout, &assets, &dir).unwrap();
    assert_eq!((report.materials, report.textures), (4, 0));
    let (models, materials) = tobj::load_obj(dir.join("scene.obj"), &LOAD).unwrap();
    let materials = materials.unwrap();
    assert_eq!(materials.len(), 4);
    let tris = triangles(&models);
    assert_eq!(tris.len(), report.triangles);
    // every triangle lies on the surface the tracer hits, facing out: a ray from a little
    // outside its centre, against its normal, hits the scene right there (a tessellated
    // round is inscribed, a chord's middle within 0.5% of its radius inside)
    let scene = Scene::new(&layout, &assets, Light::default());
    let size = (scene.bounds().max - scene.bounds().min).max_element();
    let (out, tol) = (0.02 * size, 0.005 * size);
    for (p, n) in &tris {
        let winding = (p[1] - p[0]).cross(p[2] - p[0]);
        if winding.length() < 1e-9 {
            continue; // a sphere's pole
        }
        assert!(winding.dot(*n) > 0.0, "winding against the normal at {p:?}");
        let c = (p[0] + p[1] + p[2]) / 3.0;
        let hit = scene.trace(c + *n * out, -*n, 2.0 * out).map(|h| h.t);
        assert!(
            hit.is_some_and(|t| (t - out).abs() <= tol),
            "triangle at {c} (normal {n}): traced hit at {hit:?}, expected {out}"
        );
    }
    // colours go out linear: the box's sRGB (0.8, 0.2, 0.1) is (0.604, 0.033, 0.010)
    let linear = [0.6038, 0.0331, 0.0100];
    assert!(
        materials
            .iter()
            .filter_map(|m| m.diffuse)
            .any(|d| (0..3).all(|i| (d[i] - linear[i]).abs() < 1e-3)),
        "{:?}",
        materials.iter().map(|m| m.diffuse).collect::<Vec<_>>()
    );
}

#[test]
fn textured_meshes_keep_their_textures() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let text = r#"Scene(
        assets: { "crate": Asset(obj: Obj(path: "assets/meshes/crate.obj", scale: 0.8)) },
        layout: [Instance(asset: "crate", at: (0, 0)), Instance(asset: "crate", at: (2, 0), yaw: 45)],
    )"#;
    let loaded = load_str(&scenes.join("export_test.ron"), text).unwrap();
    let assets = AssetSet::from_script(&loaded).unwrap();
    let layout = resolve(&loaded, &assets).unwrap();
    let dir = scratch("textured");
    let report = export_obj(&layout, &assets, &dir).unwrap();
    assert!(report.textures >= 1, "{report:?}");
    let (models, materials) = tobj::load_obj(dir.join("scene.obj"), &LOAD).unwrap();
    let materials = materials.unwrap();
    let textured: Vec<_> = materials.iter().filter_map(|m| m.diffuse_texture.clone()).collect();
    assert_eq!(textured.len(), report.textures);
    for t in &textured {
        let img = image::open(dir.join(t)).unwrap();
        assert!(img.width() > 1 && img.height() > 1, "{t}");
    }
    // both instances are there, with texture coordinates
    assert_eq!(models.iter().map(|m| m.mesh.indices.len() / 3).sum::<usize>(), report.triangles);
    assert!(models.iter().all(|m| !m.mesh.texcoords.is_empty()));
}

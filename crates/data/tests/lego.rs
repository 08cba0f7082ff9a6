//! The real NeRF-synthetic "lego" scene at 400x400 (read from ../shared/data).

mod common;

use assetfield_data::{Dataset, DatasetSummary, Format, LoadOptions, Split, camera_map};
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};

const NAME: &str = "nerf_synthetic_lego_400";

fn lego() -> Option<PathBuf> {
    common::shared_dataset(NAME)
}

/// `camera_angle_x` and the matrices straight from the JSON, independently of the loader.
fn raw(dir: &Path, split: &str) -> (f32, Vec<[[f32; 4]; 4]>) {
    let text = std::fs::read_to_string(dir.join(format!("transforms_{split}.json"))).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let angle = v["camera_angle_x"].as_f64().unwrap() as f32;
    let mats = v["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            let mut m = [[0.0f32; 4]; 4];
            for (r, row) in f["transform_matrix"].as_array().unwrap().iter().enumerate() {
                for (c, x) in row.as_array().unwrap().iter().enumerate() {
                    m[r][c] = x.as_f64().unwrap() as f32;
                }
            }
            m
        })
        .collect();
    (angle, mats)
}

#[test]
fn all_splits_load_with_images() {
    let Some(dir) = lego() else { return };
    let opts = LoadOptions::default();
    for (split, n) in [(Split::Train, 100), (Split::Val, 100), (Split::Test, 200)] {
        let ds = Dataset::load(&dir, split, &opts).unwrap();
        assert_eq!(ds.format, Format::NerfSynthetic);
        assert_eq!(ds.len(), n, "{split}");
        assert_eq!(ds.resolution(), (400, 400));
        assert!(ds.frames.iter().all(|f| f.split == split && f.image.alpha.is_some()));
        let (angle, _) = raw(&dir, split.name());
        let focal = 0.5 * 400.0 / (0.5 * angle).tan();
        for f in &ds.frames {
            let k = f.camera.intrinsics;
            assert!((k.fx - focal).abs() < 1e-3 && (k.fy - focal).abs() < 1e-3);
            assert_eq!((k.cx, k.cy, k.distortion), (200.0, 200.0, None));
            // Corners are transparent background: white.
            assert_eq!(f.image.pixel(0, 0), [1.0, 1.0, 1.0], "{}", f.file_path);
            assert_eq!(f.image.alpha_at(0, 0), 0.0);
        }
        // The object is opaque somewhere in the middle of the first view.
        let first = &ds.frames[0];
        assert!(first.image.alpha_at(200, 200) > 0.5);
        assert_eq!(first.file_path, format!("./{}/r_0", split.name()));
        assert!(first.image_path.ends_with(format!("{}/r_0.png", split.name())));
    }
}

#[test]
fn background_is_composited() {
    let Some(dir) = lego() else { return };
    let one = LoadOptions { max_frames: Some(1), ..LoadOptions::default() };
    let white = Dataset::load(&dir, Split::Train, &one).unwrap();
    let black =
        Dataset::load(&dir, Split::Train, &LoadOptions { background: [0.0; 3], ..one.clone() })
            .unwrap();
    assert_eq!(white.len(), 1);
    assert_eq!(white.frames[0].image.pixel(0, 0), [1.0; 3]);
    assert_eq!(black.frames[0].image.pixel(0, 399), [0.0; 3]);
    // Opaque pixels do not depend on the background; others move by (1 - alpha).
    let (w, b) = (&white.frames[0].image, &black.frames[0].image);
    let a = w.alpha.as_ref().unwrap();
    for k in (0..a.len()).step_by(97) {
        for c in 0..3 {
            let d = w.rgb[3 * k + c] - b.rgb[3 * k + c];
            assert!((d - (1.0 - a[k])).abs() < 1e-5);
        }
    }
}

#[test]
fn poses_are_rigid_and_on_a_sphere() {
    let Some(dir) = lego() else { return };
    let cams = Dataset::load_cameras_only(&dir, Split::All, &LoadOptions::default()).unwrap();
    assert_eq!(cams.views.len(), 400);
    assert_eq!(
        cams.split_counts(),
        vec![(Split::Train, 100), (Split::Val, 100), (Split::Test, 200)]
    );
    assert_eq!(cams.source_size, (400, 400));
    for v in &cams.views {
        assert!(assetfield_core::camera::check_rigid(&v.camera.c2w_matrix()).is_ok());
        let d = v.camera.position().length();
        assert!((d - 4.031).abs() < 0.01, "{} {}: distance {d}", v.split, v.file_path);
    }
    let s = DatasetSummary::of(&cams);
    assert_eq!(s.views, 400);
    assert!((s.distance_mean - 4.031).abs() < 0.01);
    assert!(s.look_at.unwrap().length() < 0.1, "{s}");
    assert!(s.z_up && s.up_axis == "+Z", "{s}");
    assert!(s.distortion.is_none());
    assert!((s.fov_x_deg - 39.6).abs() < 0.1, "{s}");
    let text = s.to_string();
    assert!(text.contains("train 100, val 100, test 200"), "{text}");
    eprintln!("{text}");
}

#[test]
fn rays_match_the_matrices_and_projection() {
    let Some(dir) = lego() else { return };
    let opts = LoadOptions { max_frames: Some(3), ..LoadOptions::default() };
    let ds = Dataset::load(&dir, Split::Test, &opts).unwrap();
    let (_, mats) = raw(&dir, "test");
    for (n, f) in ds.frames.iter().enumerate() {
        let m = mats[f.index];
        let minus_z = -Vec3::new(m[0][2], m[1][2], m[2][2]).normalize();
        let origin = Vec3::new(m[0][3], m[1][3], m[2][3]);
        // Exactly through the principal point, and half a pixel off through pixel (200, 200).
        let r = f.camera.ray(200.0, 200.0);
        assert!((r.dir - minus_z).length() < 1e-5);
        assert!((r.origin - origin).length() < 1e-5);
        let r = ds.ray(n, 200, 200);
        assert!((r.dir - minus_z).length() < 2e-3);
        for (i, j) in [(0, 0), (399, 0), (17, 311), (200, 200), (399, 399)] {
            let r = f.ray(i, j);
            assert!((r.dir.length() - 1.0).abs() < 1e-5);
            let uv = f.camera.project(r.at(3.7)).unwrap();
            assert!(
                (uv - Vec2::new(i as f32 + 0.5, j as f32 + 0.5)).length() < 1e-2,
                "{uv} vs ({i}, {j})"
            );
        }
    }
    let test = Dataset::load_cameras_only(&dir, Split::Test, &LoadOptions::default()).unwrap();
    assert_eq!(test.views.len(), 200);
    for v in &test.views {
        let uv = v.camera.project(Vec3::ZERO).expect("origin in front of every test camera");
        assert!(uv.x > 0.0 && uv.x < 400.0 && uv.y > 0.0 && uv.y < 400.0, "{}: {uv}", v.file_path);
    }
}

#[test]
fn downscale_and_camera_map() {
    let Some(dir) = lego() else { return };
    let opts = LoadOptions { downscale: 4, max_frames: Some(4), ..LoadOptions::default() };
    let ds = Dataset::load(&dir, Split::Val, &opts).unwrap();
    assert_eq!(ds.resolution(), (100, 100));
    let full = Dataset::load_cameras_only(&dir, Split::Val, &LoadOptions::default()).unwrap();
    let (k4, k1) = (ds.frames[0].camera.intrinsics, full.views[0].camera.intrinsics);
    assert!((k4.fx * 4.0 - k1.fx).abs() < 1e-3 && (k4.cx - 50.0).abs() < 1e-6);
    // The object still projects to the same place, scaled.
    let p = ds.frames[0].camera.project(Vec3::ZERO).unwrap();
    let q = full.views[0].camera.project(Vec3::ZERO).unwrap();
    assert!((p * 4.0 - q).length() < 1e-2);

    let out = common::Scratch::new("lego-map");
    let png = out.0.join("lego_cameras.png");
    camera_map(&full.cameras(), &png, "lego val cameras").unwrap();
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (800, 800));
}

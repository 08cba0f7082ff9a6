//! The real instant-ngp "fox" capture (read from ../shared/data): one transforms.json with
//! OpenCV distortion, JPEG photos, a hand-held (varying) camera up vector.

mod common;

use assetfield_data::{Dataset, DatasetSummary, Format, LoadOptions, Split, fill_rays};

fn fox() -> Option<std::path::PathBuf> {
    common::shared_dataset("instant_ngp_fox")
}

#[test]
fn cameras_with_distortion_and_holdout() {
    let Some(dir) = fox() else { return };
    let opts = LoadOptions::default();
    let all = Dataset::load_cameras_only(&dir, Split::All, &opts).unwrap();
    assert_eq!(all.format, Format::Nerfstudio);
    assert_eq!(all.views.len(), 67);
    assert_eq!(all.source_size, (1080, 1920));
    assert_eq!(all.aabb_scale, Some(4.0));
    // Every 8th frame (0, 8, ..., 64) is held out for testing.
    assert_eq!(all.split_counts(), vec![(Split::Train, 58), (Split::Test, 9)]);
    assert!(all.views.iter().all(|v| (v.split == Split::Test) == (v.index % 8 == 0)));
    let k = all.views[0].camera.intrinsics;
    assert_eq!((k.width, k.height), (1080, 1920));
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (1375.52, 1374.49, 554.558, 965.268));
    let d = k.distortion.expect("OpenCV distortion is applied");
    assert_eq!(
        (d.k1, d.k2, d.p1, d.p2, d.k3),
        (0.0578421, -0.0805099, -0.000980296, 0.00015575, 0.0)
    );
    assert_eq!(all.views[0].file_path, "images/0001.jpg");

    let train = Dataset::load_cameras_only(&dir, Split::Train, &opts).unwrap();
    let test = Dataset::load_cameras_only(&dir, Split::Test, &opts).unwrap();
    assert_eq!((train.views.len(), test.views.len()), (58, 9));
    assert!(test.views.iter().all(|v| v.split == Split::Test));

    let s = DatasetSummary::of(&all);
    assert!(s.distortion.is_some());
    // colmap2nerf re-orients captures so that the mean camera up is +Z and the cameras look
    // at the origin; the file keeps that, although the photos were taken hand-held.
    assert!(s.z_up && s.mean_up.z > 0.999, "{s}");
    assert!(s.look_at.unwrap().length() < 0.2, "{s}");
    eprintln!("{s}");
}

#[test]
fn downscaled_images_and_unit_rays() {
    let Some(dir) = fox() else { return };
    let opts = LoadOptions { downscale: 4, ..LoadOptions::default() };
    let ds = Dataset::load(&dir, Split::All, &opts).unwrap();
    assert_eq!(ds.len(), 67);
    assert_eq!(ds.resolution(), (270, 480));
    let k = ds.frames[0].camera.intrinsics;
    assert!((k.fx - 1375.52 / 4.0).abs() < 1e-3 && (k.fy - 1374.49 / 4.0).abs() < 1e-3);
    assert!((k.cx - 554.558 / 4.0).abs() < 1e-3 && (k.cy - 965.268 / 4.0).abs() < 1e-3);
    assert!(k.distortion.is_some());
    let f = &ds.frames[5];
    assert!(f.image.alpha.is_none());
    let mean: f32 = f.image.rgb.iter().sum::<f32>() / f.image.rgb.len() as f32;
    assert!(mean > 0.05 && mean < 0.95, "a real photo, mean {mean}");

    let n = 3 * 270 * 480;
    let (mut o, mut d) = (vec![0.0; n], vec![0.0; n]);
    fill_rays(&f.camera, &mut o, &mut d);
    for dir in d.chunks_exact(3) {
        let len = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5);
    }
    let pos = f.camera.position().to_array();
    assert!(o.chunks_exact(3).all(|p| p == pos));
    // Rays through the corners still project back onto their pixels with distortion.
    for (i, j) in [(0u32, 0u32), (269, 479), (135, 240)] {
        let r = f.ray(i, j);
        let uv = f.camera.project(r.at(2.0)).unwrap();
        assert!(
            (uv.x - (i as f32 + 0.5)).abs() < 0.05 && (uv.y - (j as f32 + 0.5)).abs() < 0.05,
            "{uv}"
        );
    }
}

//! Small datasets written into a scratch folder: round trips and error messages.

mod common;

use assetfield_core::{Camera, Intrinsics};
use assetfield_data::{
    DataError, Dataset, DatasetSummary, Format, FrameEntry, LoadOptions, Split, TransformsFile,
    camera_map, write_transforms,
};
use common::Scratch;
use glam::{Mat4, Vec3};
use std::path::Path;

const ANGLE: f32 = 0.7;

fn ring_camera(i: usize, n: usize) -> Camera {
    let a = i as f32 / n as f32 * std::f32::consts::TAU;
    let eye = Vec3::new(3.0 * a.cos(), 3.0 * a.sin(), 1.0 + 0.1 * i as f32);
    Camera::look_at(Intrinsics::from_fov_x(8, 6, ANGLE), eye, Vec3::ZERO, Vec3::Z)
}

/// A w x h RGBA image whose pixels depend on `seed`, with some transparency.
fn rgba(w: u32, h: u32, seed: u32) -> image::RgbaImage {
    image::RgbaImage::from_fn(w, h, |x, y| {
        let v = (x * 31 + y * 17 + seed * 7) % 256;
        image::Rgba([
            v as u8,
            (255 - v) as u8,
            (seed * 40 % 256) as u8,
            if x == 0 { 0 } else { 255 - (y * 20) as u8 },
        ])
    })
}

/// Write `transforms_{split}.json` with `n` frames and their PNGs (`sizes` per frame).
fn write_split(
    dir: &Path,
    split: &str,
    n: usize,
    size: impl Fn(usize) -> (u32, u32),
) -> TransformsFile {
    let mut frames = Vec::new();
    for i in 0..n {
        let file_path = format!("./{split}/r_{i}");
        let (w, h) = size(i);
        let png = dir.join(format!("{split}/r_{i}.png"));
        std::fs::create_dir_all(png.parent().unwrap()).unwrap();
        rgba(w, h, i as u32).save(&png).unwrap();
        frames.push(FrameEntry::new(file_path, ring_camera(i, n).c2w_matrix()));
    }
    let file = TransformsFile::nerf_synthetic(ANGLE, frames);
    write_transforms(&dir.join(format!("transforms_{split}.json")), &file).unwrap();
    file
}

fn load_err(dir: &Path, split: Split) -> String {
    let e = Dataset::load(dir, split, &LoadOptions::default()).unwrap_err();
    e.to_string()
}

#[test]
fn nerf_synthetic_round_trip() {
    let s = Scratch::new("roundtrip");
    let dir = &s.0;
    let train = write_split(dir, "train", 4, |_| (8, 6));
    write_split(dir, "test", 2, |_| (8, 6));

    // The written file reads back identically and is plain NeRF-synthetic.
    let json = dir.join("transforms_train.json");
    assert_eq!(TransformsFile::read(&json).unwrap(), train);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v.as_object().unwrap().len(), 2, "only camera_angle_x and frames: {v}");
    assert_eq!(v["frames"][1]["file_path"], "./train/r_1");

    let ds = Dataset::load(dir, Split::Train, &LoadOptions::default()).unwrap();
    assert_eq!(ds.format, Format::NerfSynthetic);
    assert_eq!(ds.len(), 4);
    assert_eq!(ds.root, dir.canonicalize().unwrap());
    for (i, f) in ds.frames.iter().enumerate() {
        let want = ring_camera(i, 4);
        assert_eq!(f.index, i);
        assert!(f.camera.c2w_matrix().abs_diff_eq(want.c2w_matrix(), 1e-6));
        let k = f.camera.intrinsics;
        assert_eq!((k.width, k.height), (8, 6));
        assert!((k.fx - want.intrinsics.fx).abs() < 1e-4 && k.cx == 4.0 && k.cy == 3.0);
        // Pixels: straight alpha onto white, alpha kept.
        let src = rgba(8, 6, i as u32);
        for (x, y) in [(0, 0), (3, 2), (7, 5)] {
            let p = src.get_pixel(x, y).0;
            let a = p[3] as f32 / 255.0;
            let got = f.image.pixel(x, y);
            for c in 0..3 {
                let want = p[c] as f32 / 255.0 * a + (1.0 - a);
                assert!((got[c] - want).abs() < 1e-5, "frame {i} pixel ({x}, {y})");
            }
            assert!((f.image.alpha_at(x, y) - a).abs() < 1e-6);
        }
        // Back to 8 bits: the composited colour, the original alpha.
        let back = f.image.to_rgba8();
        assert!(back.pixels().zip(src.pixels()).all(|(b, s)| b.0[3] == s.0[3]));
        assert_eq!(back.get_pixel(0, 0).0, [255, 255, 255, 0]);
    }

    let all = Dataset::load(dir, Split::All, &LoadOptions::default()).unwrap();
    assert_eq!(all.split_counts(), vec![(Split::Train, 4), (Split::Test, 2)]);
    let cams = Dataset::load_cameras_only(dir, Split::All, &LoadOptions::default()).unwrap();
    assert_eq!(cams.cameras(), all.cameras());
    let summary = DatasetSummary::of(&all);
    assert_eq!(summary, DatasetSummary::of(&cams));
    assert!(summary.to_string().contains("train 4, test 2"));
    let capped =
        Dataset::load(dir, Split::All, &LoadOptions { max_frames: Some(5), ..Default::default() })
            .unwrap();
    assert_eq!(capped.split_counts(), vec![(Split::Train, 4), (Split::Test, 1)]);
}

#[test]
fn downscale_averages_and_scales_intrinsics() {
    let s = Scratch::new("downscale");
    write_split(&s.0, "train", 1, |_| (8, 6));
    let full = Dataset::load(&s.0, Split::Train, &LoadOptions::default()).unwrap();
    let half =
        Dataset::load(&s.0, Split::Train, &LoadOptions { downscale: 2, ..Default::default() })
            .unwrap();
    let (a, b) = (&full.frames[0], &half.frames[0]);
    assert_eq!((b.image.width, b.image.height), (4, 3));
    let by_hand = a.image.downscaled(2);
    for (x, y) in b.image.rgb.iter().zip(&by_hand.rgb) {
        assert!((x - y).abs() < 1e-6);
    }
    let (ka, kb) = (a.camera.intrinsics, b.camera.intrinsics);
    assert_eq!((kb.fx, kb.cx, kb.cy), (ka.fx / 2.0, 2.0, 1.5));
    // Downscale 3 drops the incomplete trailing column: 8x6 -> 2x2.
    let third =
        Dataset::load(&s.0, Split::Train, &LoadOptions { downscale: 3, ..Default::default() })
            .unwrap();
    assert_eq!(third.resolution(), (2, 2));
    assert!((third.frames[0].camera.intrinsics.cx - 4.0 / 3.0).abs() < 1e-6);
    let e = Dataset::load(&s.0, Split::Train, &LoadOptions { downscale: 0, ..Default::default() })
        .unwrap_err();
    assert!(e.to_string().contains("downscale"), "{e}");
    let e = Dataset::load(&s.0, Split::Train, &LoadOptions { downscale: 7, ..Default::default() })
        .unwrap_err();
    assert!(e.to_string().contains("downscale 7 leaves nothing of the 8x6 images"), "{e}");
}

/// A nerfstudio-style folder: one transforms.json, JPEG images with extensions.
fn write_nerfstudio(dir: &Path, n: usize, edit: impl FnOnce(&mut TransformsFile)) {
    std::fs::create_dir_all(dir.join("images")).unwrap();
    let mut frames = Vec::new();
    for i in 0..n {
        let img = image::RgbImage::from_fn(12, 8, |x, y| {
            image::Rgb([(x * 20) as u8, (y * 30) as u8, i as u8])
        });
        img.save(dir.join(format!("images/{i:04}.jpg"))).unwrap();
        frames.push(FrameEntry::new(format!("images/{i:04}.jpg"), ring_camera(i, n).c2w_matrix()));
    }
    let mut file = TransformsFile {
        fl_x: Some(10.0),
        fl_y: Some(11.0),
        cx: Some(6.5),
        cy: Some(3.5),
        w: Some(12),
        h: Some(8),
        k1: Some(0.01),
        k2: Some(-0.002),
        p1: Some(0.0005),
        p2: Some(-0.0003),
        camera_model: Some("OPENCV".into()),
        aabb_scale: Some(2.0),
        frames,
        ..Default::default()
    };
    edit(&mut file);
    write_transforms(&dir.join("transforms.json"), &file).unwrap();
}

#[test]
fn nerfstudio_holdout_intrinsics_and_distortion() {
    let s = Scratch::new("nerfstudio");
    write_nerfstudio(&s.0, 10, |_| {});
    let opts = LoadOptions { holdout_every: 4, ..Default::default() };
    let all = Dataset::load(&s.0, Split::All, &opts).unwrap();
    assert_eq!(all.format, Format::Nerfstudio);
    assert_eq!(all.aabb_scale, Some(2.0));
    assert_eq!(all.split_counts(), vec![(Split::Train, 7), (Split::Test, 3)]);
    let test = Dataset::load(&s.0, Split::Test, &opts).unwrap();
    assert_eq!(test.frames.iter().map(|f| f.index).collect::<Vec<_>>(), [0, 4, 8]);
    let val = Dataset::load_cameras_only(&s.0, Split::Val, &opts).unwrap();
    assert_eq!(val.views.len(), 3, "single-file datasets validate on the held-out views");
    let train = Dataset::load(&s.0, Split::Train, &opts).unwrap();
    assert_eq!(train.len(), 7);
    let f = &train.frames[0];
    assert_eq!(f.file_path, "images/0001.jpg");
    assert!(f.image.alpha.is_none());
    let k = f.camera.intrinsics;
    assert_eq!((k.width, k.height, k.fx, k.fy, k.cx, k.cy), (12, 8, 10.0, 11.0, 6.5, 3.5));
    let d = k.distortion.unwrap();
    assert_eq!((d.k1, d.k2, d.p1, d.p2, d.k3), (0.01, -0.002, 0.0005, -0.0003, 0.0));
    // holdout_every = 0: everything trains, the test split is empty.
    let none = LoadOptions { holdout_every: 0, ..Default::default() };
    assert_eq!(Dataset::load_cameras_only(&s.0, Split::Train, &none).unwrap().views.len(), 10);
    let e = Dataset::load_cameras_only(&s.0, Split::Test, &none).unwrap_err().to_string();
    assert!(e.contains("holdout_every is 0"), "{e}");
}

#[test]
fn declared_size_rescales_or_rejects() {
    // Intrinsics for 24x16 while the images are 12x8: scaled down by two.
    let s = Scratch::new("declared");
    write_nerfstudio(&s.0, 2, |f| {
        (f.w, f.h, f.fl_x, f.fl_y, f.cx, f.cy) = (Some(24), Some(16), Some(20.0), None, None, None);
    });
    let ds = Dataset::load_cameras_only(&s.0, Split::All, &LoadOptions::default()).unwrap();
    let k = ds.views[0].camera.intrinsics;
    assert_eq!((k.width, k.height, k.fx, k.fy, k.cx, k.cy), (12, 8, 10.0, 10.0, 6.0, 4.0));
    // Per-frame overrides win over the file's values.
    let s = Scratch::new("perframe");
    write_nerfstudio(&s.0, 2, |f| {
        f.frames[1].fl_x = Some(30.0);
        f.frames[1].cx = Some(5.0);
    });
    let ds = Dataset::load_cameras_only(&s.0, Split::All, &LoadOptions::default()).unwrap();
    assert_eq!(ds.views[0].camera.intrinsics.fx, 10.0);
    assert_eq!((ds.views[1].camera.intrinsics.fx, ds.views[1].camera.intrinsics.cx), (30.0, 5.0));
    assert!(DatasetSummary::of(&ds).intrinsics_vary);
    // Another aspect ratio cannot be rescaled.
    let s = Scratch::new("aspect");
    write_nerfstudio(&s.0, 2, |f| f.h = Some(12));
    let e = load_err(&s.0, Split::All);
    assert!(
        e.contains("frame 0 (images/0000.jpg)") && e.contains("12x12") && e.contains("12x8"),
        "{e}"
    );
}

#[test]
fn missing_image_names_frame_and_path() {
    let s = Scratch::new("missing");
    write_split(&s.0, "train", 3, |_| (8, 6));
    std::fs::remove_file(s.0.join("train/r_1.png")).unwrap();
    let e = load_err(&s.0, Split::Train);
    let json = s.0.canonicalize().unwrap().join("transforms_train.json");
    let png = s.0.canonicalize().unwrap().join("train/r_1.png");
    assert!(
        e.starts_with(&format!(
            "{}: frame 1 (./train/r_1): cannot open {}",
            json.display(),
            png.display()
        )),
        "{e}"
    );
    assert!(e.contains("no such file") && e.contains("r_1.jpg"), "{e}");
    // Header-only loading reports it too.
    let e = Dataset::load_cameras_only(&s.0, Split::Train, &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, DataError::ImageNotFound { ref frame, .. } if frame.index == 1), "{e}");
}

#[test]
fn corrupt_image_names_frame_and_path() {
    let s = Scratch::new("corrupt");
    write_split(&s.0, "train", 2, |_| (8, 6));
    std::fs::write(s.0.join("train/r_1.png"), b"not a png at all").unwrap();
    let e = load_err(&s.0, Split::Train);
    assert!(e.contains("frame 1 (./train/r_1): cannot open") && e.contains("r_1.png"), "{e}");
}

#[test]
fn extension_is_found_when_omitted() {
    let s = Scratch::new("jpgext");
    write_split(&s.0, "train", 1, |_| (8, 6));
    let png = s.0.join("train/r_0.png");
    image::open(&png).unwrap().to_rgb8().save(s.0.join("train/r_0.jpg")).unwrap();
    std::fs::remove_file(&png).unwrap();
    let ds = Dataset::load(&s.0, Split::Train, &LoadOptions::default()).unwrap();
    assert!(ds.frames[0].image_path.ends_with("train/r_0.jpg"));
    assert!(ds.frames[0].image.alpha.is_none());
}

#[test]
fn malformed_json_names_line_and_column() {
    let s = Scratch::new("badjson");
    let json = s.0.join("transforms_train.json");
    std::fs::write(&json, "{\n  \"camera_angle_x\": 0.7,\n  \"frames\": [,]\n}\n").unwrap();
    let e = load_err(&s.0, Split::Train);
    assert!(e.contains("transforms_train.json:3:"), "{e}");
    assert!(e.contains("line 3, column 14"), "{e}");
    // Schema errors (wrong type) are located too.
    std::fs::write(&json, "{\"camera_angle_x\": 0.7,\n\"frames\": [{\"file_path\": 3}]}").unwrap();
    let e = load_err(&s.0, Split::Train);
    assert!(e.contains("line 2") && e.contains("expected a string"), "{e}");
}

#[test]
fn non_rigid_pose_names_the_frame() {
    let s = Scratch::new("nonrigid");
    let mut file = write_split(&s.0, "train", 3, |_| (8, 6));
    let scaled = file.frames[2].matrix() * Mat4::from_scale(Vec3::splat(1.5));
    file.frames[2] = FrameEntry::new("./train/r_2", scaled);
    write_transforms(&s.0.join("transforms_train.json"), &file).unwrap();
    let e = load_err(&s.0, Split::Train);
    assert!(e.contains("frame 2 (./train/r_2): transform_matrix is not rigid"), "{e}");
    assert!(e.contains("not orthonormal"), "{e}");
    let e = Dataset::load_cameras_only(&s.0, Split::Train, &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, DataError::NotRigid { .. }));
}

#[test]
fn different_image_sizes_name_frame_and_sizes() {
    let s = Scratch::new("sizes");
    write_split(&s.0, "train", 3, |i| if i == 2 { (4, 3) } else { (8, 6) });
    let e = load_err(&s.0, Split::Train);
    assert!(e.contains("frame 2 (./train/r_2)"), "{e}");
    assert!(e.contains("is 4x3, expected 8x6 like") && e.contains("frame 0 (./train/r_0)"), "{e}");
}

#[test]
fn fisheye_is_rejected() {
    let s = Scratch::new("fisheye");
    write_nerfstudio(&s.0, 2, |f| f.camera_model = Some("OPENCV_FISHEYE".into()));
    let e = load_err(&s.0, Split::All);
    assert!(
        e.contains("transforms.json") && e.contains("\"OPENCV_FISHEYE\" is not supported"),
        "{e}"
    );
    assert!(e.contains("OPENCV, PINHOLE"), "{e}");
}

#[test]
fn missing_focal_is_reported() {
    let s = Scratch::new("nofocal");
    write_nerfstudio(&s.0, 2, |f| f.fl_x = None);
    let e = load_err(&s.0, Split::All);
    assert!(
        e.contains("missing required key") && e.contains("camera_angle_x") && e.contains("fl_x"),
        "{e}"
    );
    assert!(e.contains("frame 0 (images/0000.jpg)"), "{e}");
}

#[test]
fn folders_without_datasets_or_splits() {
    let s = Scratch::new("empty");
    let e = load_err(&s.0, Split::Train);
    assert!(e.contains("no dataset found"), "{e}");
    assert!(
        e.contains(
            "transforms_train.json, transforms_val.json, transforms_test.json, transforms.json"
        ),
        "{e}"
    );
    write_split(&s.0, "train", 1, |_| (8, 6));
    let e = load_err(&s.0, Split::Val);
    assert!(
        e.contains("no transforms_val.json") && e.contains("found transforms_train.json"),
        "{e}"
    );
    let e = load_err(&s.0.join("nope"), Split::Train);
    assert!(e.starts_with("cannot open dataset folder") && e.contains("nope"), "{e}");
    let e = Dataset::load(
        &s.0,
        Split::Train,
        &LoadOptions { max_frames: Some(0), ..Default::default() },
    )
    .unwrap_err();
    assert!(e.to_string().contains("max_frames is 0"), "{e}");
}

#[test]
fn camera_map_writes_a_png() {
    let s = Scratch::new("map");
    let cams: Vec<Camera> = (0..12).map(|i| ring_camera(i, 12)).collect();
    let path = s.0.join("maps/cameras.png");
    camera_map(&cams, &path, "twelve cameras").unwrap();
    let img = image::open(&path).unwrap();
    assert_eq!((img.width(), img.height()), (800, 800));
    // Nothing else is left in the folder (atomic write).
    assert_eq!(std::fs::read_dir(s.0.join("maps")).unwrap().count(), 1);
    camera_map(&[], &s.0.join("empty.png"), "no cameras").unwrap();
}

/// Rewrite a JSON file through `edit` of its parsed value.
fn edit_json(path: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

/// Both loaders refuse the dataset with an error containing every needle.
fn refused(dir: &Path, split: Split, needles: &[&str]) -> DataError {
    let e = Dataset::load(dir, split, &LoadOptions::default()).unwrap_err();
    let msg = e.to_string();
    for n in needles {
        assert!(msg.contains(n), "expected {n:?} in: {msg}");
    }
    let again = Dataset::load_cameras_only(dir, split, &LoadOptions::default()).unwrap_err();
    assert_eq!(again.to_string(), msg, "both loaders run the same checks");
    e
}

#[test]
fn field_of_view_outside_zero_to_pi_is_refused() {
    let s = Scratch::new("fov");
    write_split(&s.0, "train", 3, |_| (8, 6));
    let json = s.0.join("transforms_train.json");
    for bad in [6.3, 0.0, -0.5, 3.2] {
        edit_json(&json, |v| v["camera_angle_x"] = serde_json::json!(bad));
        let e = refused(
            &s.0,
            Split::Train,
            &[
                "transforms_train.json: \"camera_angle_x\" is ",
                "expected a horizontal field of view in radians, in (0, pi)",
            ],
        );
        assert!(
            matches!(&e, DataError::Invalid(v) if v.key == "camera_angle_x" && v.place == assetfield_data::Place::File),
            "{e}"
        );
    }
}

#[test]
fn zero_or_huge_image_sizes_are_refused() {
    // a top-level w of 0 next to focal lengths
    let s = Scratch::new("w0");
    write_nerfstudio(&s.0, 3, |f| f.w = Some(0));
    refused(
        &s.0,
        Split::All,
        &["transforms.json: \"w\" is 0, expected an image size in pixels, 1 to 32768"],
    );
    // a per-frame w of 0 where the field of view fixes the intrinsics (the size was ignored)
    let s = Scratch::new("framew0");
    write_split(&s.0, "train", 3, |_| (8, 6));
    edit_json(&s.0.join("transforms_train.json"), |v| v["frames"][1]["w"] = serde_json::json!(0));
    refused(&s.0, Split::Train, &["transforms_train.json: frame 1 (./train/r_1): \"w\" is 0"]);
    let s = Scratch::new("h-huge");
    write_nerfstudio(&s.0, 3, |f| f.h = Some(1_000_000));
    refused(&s.0, Split::All, &["\"h\" is 1000000"]);
    // an image on disk larger than any camera takes is refused before it is decoded
    let s = Scratch::new("wide-image");
    write_split(&s.0, "train", 2, |_| (8, 6));
    image::RgbaImage::new(40_000, 1).save(s.0.join("train/r_1.png")).unwrap();
    refused(
        &s.0,
        Split::Train,
        &[
            "transforms_train.json: frame 1 (./train/r_1): \"the size of image ",
            "r_1.png\" is 40000x1, expected 1 to 32768 pixels per side",
        ],
    );
}

#[test]
fn far_away_cameras_are_refused() {
    let s = Scratch::new("far");
    write_split(&s.0, "train", 3, |_| (8, 6));
    edit_json(&s.0.join("transforms_train.json"), |v| {
        v["frames"][2]["transform_matrix"][0][3] = serde_json::json!(1e30)
    });
    refused(
        &s.0,
        Split::Train,
        &[
            "transforms_train.json: frame 2 (./train/r_2): \"transform_matrix translation\" is [1e30",
            "expected a camera position within 1e6 scene units of the origin",
        ],
    );
}

#[test]
fn non_finite_and_null_matrix_entries_are_refused() {
    let s = Scratch::new("nonfinite");
    write_split(&s.0, "train", 3, |_| (8, 6));
    let json = s.0.join("transforms_train.json");
    // 1e39 is a valid JSON number that becomes infinity as an f32
    let good = std::fs::read_to_string(&json).unwrap();
    edit_json(&json, |v| v["frames"][1]["transform_matrix"][2][1] = serde_json::json!(1e39));
    refused(
        &s.0,
        Split::Train,
        &["transforms_train.json: frame 1 (./train/r_1): \"transform_matrix[2][1]\" is inf"],
    );
    std::fs::write(&json, &good).unwrap();
    edit_json(&json, |v| v["frames"][1]["transform_matrix"][2][1] = serde_json::Value::Null);
    refused(&s.0, Split::Train, &["transforms_train.json:", "null"]);
    std::fs::write(&json, &good).unwrap();
    edit_json(&json, |v| v["camera_angle_x"] = serde_json::json!(1e39));
    refused(&s.0, Split::Train, &["\"camera_angle_x\" is inf"]);
}

#[test]
fn every_frame_is_checked_not_only_the_selected_ones() {
    // frame 0 is a held-out view: loading the training split used to skip its pose
    let s = Scratch::new("unselected");
    write_nerfstudio(&s.0, 6, |f| f.frames[0].transform_matrix[1][1] = 2.0);
    refused(
        &s.0,
        Split::Train,
        &["transforms.json: frame 0 (images/0000.jpg): transform_matrix is not rigid"],
    );
}

#[test]
fn every_split_file_is_checked_not_only_the_requested_one() {
    let s = Scratch::new("other-split");
    write_split(&s.0, "train", 2, |_| (8, 6));
    write_split(&s.0, "test", 2, |_| (8, 6));
    assert!(Dataset::load_cameras_only(&s.0, Split::Train, &LoadOptions::default()).is_ok());
    edit_json(&s.0.join("transforms_test.json"), |v| {
        v["frames"][1]["transform_matrix"][1][3] = serde_json::json!(4294967296.0)
    });
    for split in [Split::Train, Split::Test, Split::All] {
        refused(
            &s.0,
            split,
            &["transforms_test.json: frame 1 (./test/r_1): \"transform_matrix translation\""],
        );
    }
}

#[test]
fn non_positive_aabb_scale_is_refused() {
    for bad in [-4.0, 0.0] {
        let s = Scratch::new("aabb-scale");
        write_nerfstudio(&s.0, 2, |f| f.aabb_scale = Some(bad));
        refused(&s.0, Split::All, &["transforms.json: \"aabb_scale\" is ", "positive"]);
    }
}

#[test]
fn inverted_or_empty_scene_boxes_are_refused() {
    let s = Scratch::new("scene-box");
    write_split(&s.0, "train", 2, |_| (8, 6));
    let synth = s.0.join("synth.json");
    std::fs::write(&synth, r#"{"scene_aabb": [[-1, -2, 0], [1, 2, 0.5]]}"#).unwrap();
    let cams = Dataset::load_cameras_only(&s.0, Split::Train, &LoadOptions::default()).unwrap();
    let b = cams.scene_box.unwrap();
    assert_eq!((b.min, b.max), (Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 2.0, 0.5)));
    for (text, needle) in [
        (r#"{"scene_aabb": [[1, -2, 0], [-1, 2, 0.5]]}"#, "xmin (1) below xmax (-1)"),
        (r#"{"scene_aabb": [[-1, -2, 0.5], [1, 2, 0.5]]}"#, "zmin (0.5) below zmax (0.5)"),
        (r#"{"scene_aabb": [[-1, -2, 0], [1, 2, 1e39]]}"#, "finite coordinates"),
        (r#"{"scene_aabb": [[-1, -2, 0], [1, 2]]}"#, "six numbers"),
    ] {
        std::fs::write(&synth, text).unwrap();
        refused(&s.0, Split::Train, &["synth.json: \"scene_aabb\" is ", needle]);
    }
    std::fs::write(&synth, r#"{"scene": "x"}"#).unwrap();
    refused(&s.0, Split::Train, &["synth.json: missing required key: \"scene_aabb\""]);
}

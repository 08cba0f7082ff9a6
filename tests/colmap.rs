//! COLMAP projects: the committed sparse model of one of the project's own renders
//! (`tests/data/colmap_random_3`, COLMAP 3.8's own poses, see tests/data/README.md) reads the
//! same in its binary and text forms, levels on its floor and matches the poses the scene was
//! rendered with up to the scale, heading and place COLMAP cannot know; the CLI inspects and
//! trains it; a broken project is refused with the file and the image id.

use assetfield_data::{
    AlignMethod, ColmapModel, Dataset, DatasetCameras, GroundAlignment, LoadOptions, Split,
};
use assetfield_tests::{fail, ok, render_poses, repo, scratch};
use glam::{DVec3, Mat3, Vec3};
use std::path::{Path, PathBuf};

fn fixture(form: &str) -> PathBuf {
    repo().join("tests/data/colmap_random_3").join(form)
}

/// The walked capture's model (text form only).
fn capture_fixture() -> PathBuf {
    repo().join("tests/data/colmap_capture_1/txt")
}

/// `synth --random 3 --res 256`, the render the fixture's model was made from.
fn render(dir: &Path) -> PathBuf {
    let out = dir.join("render");
    ok(dir, &["synth", "--random", "3", "--res", "256", "--out", out.to_str().unwrap()]);
    out
}

/// `synth --random 1 --capture --views 50 --test-views 10 --res 512`, the photos the capture
/// fixture's model was made from (a capture's default was 50 photos then).
fn render_capture(dir: &Path) -> PathBuf {
    let out = dir.join("capture");
    let out_arg = out.to_str().unwrap();
    let args = ["synth", "--random", "1", "--capture", "--views", "50", "--test-views", "10"];
    ok(dir, &[&args[..], &["--res", "512", "--out", out_arg]].concat());
    out
}

/// A COLMAP project in `dir/NAME`: the render's views as `images/SPLIT_r_K.png` (the names
/// COLMAP was given) and the fixture's model of `form` in `sparse/0/`.
fn project(dir: &Path, name: &str, render: &Path, form: &str) -> PathBuf {
    project_from(dir, name, render, &fixture(form))
}

/// [`project`] with the model in `model`.
fn project_from(dir: &Path, name: &str, render: &Path, model: &Path) -> PathBuf {
    let p = dir.join(name);
    std::fs::create_dir_all(p.join("images")).unwrap();
    std::fs::create_dir_all(p.join("sparse/0")).unwrap();
    for split in ["train", "test"] {
        for e in std::fs::read_dir(render.join(split)).unwrap() {
            let e = e.unwrap().path();
            let file = e.file_name().unwrap().to_string_lossy().into_owned();
            std::fs::copy(&e, p.join("images").join(format!("{split}_{file}"))).unwrap();
        }
    }
    for e in std::fs::read_dir(model).unwrap() {
        let e = e.unwrap().path();
        std::fs::copy(&e, p.join("sparse/0").join(e.file_name().unwrap())).unwrap();
    }
    p
}

fn cameras(dir: &Path) -> DatasetCameras {
    Dataset::load_cameras_only(dir, Split::All, &LoadOptions::default()).unwrap()
}

#[test]
fn binary_and_text_forms_read_to_the_same_cameras() {
    let (b, t) =
        (ColmapModel::read(&fixture("bin")).unwrap(), ColmapModel::read(&fixture("txt")).unwrap());
    assert!(b.binary && !t.binary);
    assert_eq!(b.cameras, t.cameras);
    assert_eq!((b.images.len(), b.points.len()), (42, 835));
    assert_eq!((t.images.len(), t.points.len()), (42, 835));
    for (x, y) in b.images.iter().zip(&t.images) {
        assert_eq!(x, y);
    }
    for (x, y) in b.points.iter().zip(&t.points) {
        assert_eq!(x, y);
    }
    let dir = scratch("colmap-forms");
    let r = render(&dir);
    let (cb, ct) =
        (cameras(&project(&dir, "b", &r, "bin")), cameras(&project(&dir, "t", &r, "txt")));
    assert_eq!(cb.format, assetfield_data::Format::Colmap);
    assert_eq!(cb.views.len(), 42);
    for (x, y) in cb.views.iter().zip(&ct.views) {
        assert_eq!((x.split, &x.file_path), (y.split, &y.file_path));
        assert_eq!(x.camera, y.camera);
    }
    // every 8th image by name is a test view, as for a nerfstudio capture
    assert_eq!(cb.split_counts(), vec![(Split::Train, 36), (Split::Test, 6)]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// COLMAP's poses, levelled on the floor of its sparse points, against the poses the scene was
/// rendered with: after the scale, heading and offset that no capture can know (fitted here),
/// camera centres agree within 3% of their spread and orientations within 1.5 degrees (the
/// floor's tilt included, which nothing here fits).
/// How COLMAP's poses, levelled on the floor, agree with the poses `render` was made with,
/// after the scale, heading and offset that no capture can know (fitted here): camera
/// centres as a share of their spread, orientations in degrees (mean and largest); the floor
/// alignment used.
struct PoseAgreement {
    cameras: usize,
    centres: f64,
    mean_deg: f32,
    max_deg: f32,
    floor: GroundAlignment,
    points: usize,
    lowest_camera: f64,
}

fn pose_agreement(project: &Path, render: &Path) -> PoseAgreement {
    let mut cams = cameras(project);
    let g = GroundAlignment::fit_floor(&cams.points, &cams.cameras()).unwrap();
    assert_eq!(g.method, AlignMethod::Floor);
    g.apply_to_cameras(&mut cams);
    let truth = render_poses(render);
    let pairs: Vec<(glam::Affine3A, glam::Mat4)> = cams
        .views
        .iter()
        .map(|v| (v.camera.c2w, truth[v.file_path.trim_start_matches("images/")]))
        .collect();
    // scale from the spreads, heading about +Z and offset by least squares (2-D Procrustes)
    let c: Vec<DVec3> = pairs.iter().map(|(a, _)| Vec3::from(a.translation).as_dvec3()).collect();
    let t: Vec<DVec3> = pairs.iter().map(|(_, m)| m.w_axis.truncate().as_dvec3()).collect();
    let n = c.len() as f64;
    let (cm, tm) = (c.iter().sum::<DVec3>() / n, t.iter().sum::<DVec3>() / n);
    let spread = |v: &[DVec3], m: DVec3| {
        (v.iter().map(|p| (*p - m).length_squared()).sum::<f64>() / n).sqrt()
    };
    let scale = spread(&t, tm) / spread(&c, cm);
    let (mut sxy, mut cross) = (0.0, 0.0);
    for (p, q) in c.iter().zip(&t) {
        let (p, q) = (*p - cm, *q - tm);
        sxy += p.x * q.x + p.y * q.y;
        cross += p.x * q.y - p.y * q.x;
    }
    let yaw = cross.atan2(sxy);
    let turn = glam::DMat3::from_rotation_z(yaw);
    let rms = (c
        .iter()
        .zip(&t)
        .map(|(p, q)| (scale * (turn * (*p - cm)) - (*q - tm)).length_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    let turn32 = Mat3::from_rotation_z(yaw as f32);
    let angles: Vec<f32> = pairs
        .iter()
        .map(|(a, m)| {
            let mine = glam::Quat::from_mat3(&(turn32 * Mat3::from(a.matrix3)));
            let theirs = glam::Quat::from_mat3(&Mat3::from_mat4(*m));
            mine.angle_between(theirs).to_degrees()
        })
        .collect();
    let agreement = PoseAgreement {
        cameras: pairs.len(),
        centres: rms / spread(&t, tm),
        mean_deg: angles.iter().sum::<f32>() / angles.len() as f32,
        max_deg: angles.iter().cloned().fold(0.0, f32::max),
        floor: g,
        points: cams.points.len(),
        lowest_camera: c.iter().map(|p| p.z).fold(f64::INFINITY, f64::min),
    };
    println!(
        "COLMAP vs render ({}): {} cameras, centres {:.2}% of their spread, orientation mean {:.2} deg (max {:.2}); floor holds {:.0}% of {} points",
        project.display(),
        agreement.cameras,
        100.0 * agreement.centres,
        agreement.mean_deg,
        agreement.max_deg,
        100.0 * agreement.floor.floor_share.unwrap(),
        agreement.points
    );
    agreement
}

/// COLMAP's poses, levelled on the floor of its sparse points, against the poses the scene was
/// rendered with: after the scale, heading and offset that no capture can know (fitted here),
/// camera centres agree within 3% of their spread and orientations within 1.5 degrees (the
/// floor's tilt included, which nothing here fits).
#[test]
fn colmap_poses_levelled_on_the_floor_match_the_render() {
    let dir = scratch("colmap-poses");
    let r = render(&dir);
    let a = pose_agreement(&project(&dir, "p", &r, "txt"), &r);
    assert!(a.centres < 0.03, "camera centres {:.2}% of their spread off", 100.0 * a.centres);
    assert!(a.mean_deg < 1.5, "orientations {:.2} degrees off on average", a.mean_deg);
    // the levelled cameras stand above the floor, as the render's do above its ground
    assert!(a.lowest_camera > 0.0, "a camera below the floor");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A capture walked at eye height through a closed room (`synth --random 1 --capture`, the
/// model COLMAP made of its 512-pixel photos): every camera stands at about the same height,
/// so the plane of the cameras says nothing of the floor; the floor of the sparse points
/// does. Levelled on it, the poses match the walk's.
#[test]
fn a_walked_capture_levels_on_its_floor_and_matches_the_walk() {
    let dir = scratch("colmap-capture");
    let r = render_capture(&dir);
    let p = project_from(&dir, "p", &r, &capture_fixture());
    let a = pose_agreement(&p, &r);
    assert_eq!(a.cameras, 50);
    assert!(a.centres < 0.03, "camera centres {:.2}% of their spread off", 100.0 * a.centres);
    assert!(a.mean_deg < 1.0, "orientations {:.2} degrees off on average", a.mean_deg);
    // cameras at eye height above the floor
    assert!(a.lowest_camera > 0.0, "a camera below the floor");
    // the photos are opaque and their exposures vary: the reader takes them as they are
    let ds = Dataset::load(&p, Split::Test, &LoadOptions::default()).unwrap();
    assert!(ds.frames.iter().all(|f| f.image.alpha.is_none()));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_cli_inspects_and_trains_a_colmap_project() {
    let dir = scratch("colmap-cli");
    let r = render(&dir);
    let p = project(&dir, "p", &r, "bin");
    let out = ok(
        &dir,
        &["inspect", p.to_str().unwrap(), "--picture", dir.join("c.png").to_str().unwrap()],
    );
    for needle in [
        "COLMAP",
        "views            42 (train 36, test 6)",
        "sparse points    835",
        "floor            holds",
    ] {
        assert!(out.contains(needle), "{needle:?} in {out}");
    }
    let field = dir.join("f.safetensors");
    let (code, _, err) = assetfield_tests::run_cli(
        &dir,
        &[
            "train",
            p.to_str().unwrap(),
            "--out",
            field.to_str().unwrap(),
            "--iters",
            "30",
            "--res",
            "32",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("ground alignment (floor)")
            && err.contains("the sparse points' 2%-98% percentiles"),
        "{err}"
    );
    let info = assetfield_field::eval::FieldInfo::read(
        &assetfield_core::TensorFile::load(&field).unwrap(),
    )
    .unwrap();
    assert_eq!(info.ground_transform.unwrap().method, AlignMethod::Floor);
    // a capture learns its photos' colour maps and what lies beyond its box by default, and
    // eval renders over that background
    assert!(
        err.contains("colour transform per training photo") && err.contains("background map"),
        "{err}"
    );
    let file = assetfield_core::TensorFile::load(&field).unwrap();
    assert_eq!(file.shape_of("background.map"), Some(&[32usize, 64, 3][..]));
    let ev = dir.join("ev");
    let out =
        ok(&dir, &["eval", field.to_str().unwrap(), "--out", ev.to_str().unwrap(), "--views", "1"]);
    assert!(out.contains("right halves after a colour map"), "{out}");
    // an image the model names is missing: the file, the image id and the name
    let name = "train_r_5.png";
    std::fs::remove_file(p.join("images").join(name)).unwrap();
    fail(&dir, &["inspect", p.to_str().unwrap()], &["images.bin: image id", name, "no such file"]);
    // a model of another camera model is refused by name
    let q = project(&dir, "q", &r, "txt");
    let cams = std::fs::read_to_string(q.join("sparse/0/cameras.txt")).unwrap();
    std::fs::write(
        q.join("sparse/0/cameras.txt"),
        cams.replace("SIMPLE_RADIAL 256 256", "SIMPLE_RADIAL_FISHEYE 256 256"),
    )
    .unwrap();
    fail(
        &dir,
        &[
            "train",
            q.to_str().unwrap(),
            "--iters",
            "1",
            "--out",
            dir.join("g.safetensors").to_str().unwrap(),
        ],
        &["cameras.txt", "camera id 1", "SIMPLE_RADIAL_FISHEYE", "not supported"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

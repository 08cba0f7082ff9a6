//! Shared helpers of the workspace-level integration tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ sits in the repository")
        .to_path_buf()
}

/// Every scene script of the suite (`scenes/*.ron`, not the shared asset files).
pub fn scene_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join("scenes"))
        .expect("scenes/ exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    v.sort();
    v
}

/// The shared real data folder, or `None` (with a message) when it is absent.
pub fn shared_data(name: &str) -> Option<PathBuf> {
    let p = repo().join("../shared/data").join(name);
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("skipping: {} not found (real data lives in ../shared/data)", p.display());
        None
    }
}

/// A fresh scratch folder unique to this process and `name`.
pub fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("assetfield-it-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir is writable");
    d
}

/// The `assetfield` binary next to the test executable, brought up to date once per test
/// process.
pub fn assetfield_bin() -> PathBuf {
    static BUILT: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    BUILT
        .get_or_init(|| {
            let exe = std::env::current_exe().expect("test executable path");
            let dir = exe.parent().and_then(Path::parent).expect("target/<profile>/deps");
            let bin = dir.join(format!("assetfield{}", std::env::consts::EXE_SUFFIX));
            // always (re)build once per test process: a stale binary from an earlier build
            // would test old code (cheap when it is up to date)
            let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
            // the profile the tests were built with (`cargo test --release` tests the
            // release binary, which is the one next to them)
            let release = dir.file_name().is_some_and(|n| n == "release");
            let mut args = vec!["build", "-p", "assetfield-cli", "--bin", "assetfield"];
            if release {
                args.push("--release");
            }
            let status =
                Command::new(cargo).args(&args).current_dir(repo()).status().expect("cargo runs");
            assert!(status.success(), "building the assetfield binary failed");
            bin
        })
        .clone()
}

/// Run `assetfield ARGS...` in `cwd`; returns (exit code, stdout, stderr).
pub fn run_cli(cwd: &Path, args: &[&str]) -> (i32, String, String) {
    let Output { status, stdout, stderr } = Command::new(assetfield_bin())
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("assetfield runs");
    (
        status.code().unwrap_or(-1),
        String::from_utf8_lossy(&stdout).into_owned(),
        String::from_utf8_lossy(&stderr).into_owned(),
    )
}

/// The footprint of an instance as a convex polygon in world coordinates, shrunk by `margin`:
/// its rectangle, or a 24-gon for rotationally symmetric (round) assets.
pub fn footprint_polygon(i: &assetfield_layout::ResolvedInstance, margin: f32) -> Vec<glam::Vec2> {
    let (a, b) = (i.footprint.min + margin, i.footprint.max - margin);
    let local: Vec<glam::Vec2> = if i.yaw_symmetry_deg == 0.0 {
        let (c, r) = ((a + b) * 0.5, (b - a).min_element() * 0.5);
        (0..24)
            .map(|k| c + glam::Vec2::from_angle(k as f32 * std::f32::consts::TAU / 24.0) * r)
            .collect()
    } else {
        vec![a, glam::Vec2::new(b.x, a.y), b, glam::Vec2::new(a.x, b.y)]
    };
    local.into_iter().map(|p| i.transform.transform_point2(p)).collect()
}

/// Separating-axis test for convex polygons.
pub fn convex_overlap(p: &[glam::Vec2], q: &[glam::Vec2]) -> bool {
    for poly in [p, q] {
        for k in 0..poly.len() {
            let e = poly[(k + 1) % poly.len()] - poly[k];
            let n = glam::Vec2::new(-e.y, e.x);
            let range = |s: &[glam::Vec2]| {
                s.iter()
                    .fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(v.dot(n)), hi.max(v.dot(n))))
            };
            let ((a0, a1), (b0, b1)) = (range(p), range(q));
            if a1 <= b0 || b1 <= a0 {
                return false;
            }
        }
    }
    true
}

/// A small scene for the mining and composing tests: two asymmetric categories (three red and
/// blue wedges, two green blocks with a yellow corner post) at different yaws, on a floor.
pub const SCENE: &str = r#"Scene(
    name: "tiny",
    assets: {
        "floor": Asset(container: true, parts: [
            Box(center: (0.0, 0.0, -0.01), size: (4.6, 3.6, 0.02), color: (0.55, 0.5, 0.45)),
        ]),
        "wedge": Asset(parts: [
            Box(center: (0.0, 0.0, 0.2), size: (0.8, 0.5, 0.4), color: (0.8, 0.15, 0.1)),
            Box(center: (-0.35, 0.0, 0.5), size: (0.1, 0.5, 0.2), color: (0.1, 0.2, 0.8)),
        ]),
        "block": Asset(parts: [
            Box(center: (0.0, 0.0, 0.15), size: (0.6, 0.6, 0.3), color: (0.2, 0.7, 0.3)),
            Box(center: (0.2, 0.2, 0.4), size: (0.2, 0.2, 0.2), color: (0.95, 0.85, 0.2)),
        ]),
    },
    layout: [
        Instance(asset: "floor", at: (0, 0)),
        Instance(asset: "wedge", at: (-1.2, 0.8), yaw: 0, name: "w0"),
        Instance(asset: "wedge", at: (0.4, 0.9), yaw: 90, name: "w1"),
        Instance(asset: "wedge", at: (1.5, -0.3), yaw: 200, name: "w2"),
        Instance(asset: "block", at: (-1.0, -0.9), yaw: 30, name: "b0"),
        Instance(asset: "block", at: (0.4, -1.0), yaw: 135, name: "b1"),
    ],
)
"#;

/// Run `assetfield ARGS` in `dir` and expect success; returns stdout.
pub fn ok(dir: &Path, args: &[&str]) -> String {
    let (code, out, err) = run_cli(dir, args);
    assert_eq!(code, 0, "{args:?}\nstdout: {out}\nstderr: {err}");
    out
}

/// Run `assetfield ARGS` in `dir` and expect exit 1 with every needle in stderr.
pub fn fail(dir: &Path, args: &[&str], needles: &[&str]) {
    let (code, out, err) = run_cli(dir, args);
    assert_eq!(code, 1, "{args:?}\nstdout: {out}\nstderr: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: expected {n:?} in: {err}");
    }
}

/// A similarity of world coordinates, `p' = scale * rotation * p + offset`: a capture of the
/// same scene in another frame and unit.
#[derive(Debug, Clone, Copy)]
pub struct Similarity {
    pub scale: f32,
    pub rotation: glam::Mat3,
    pub offset: glam::Vec3,
}

impl Similarity {
    pub fn point(&self, p: glam::Vec3) -> glam::Vec3 {
        self.scale * (self.rotation * p) + self.offset
    }
}

/// The camera-to-world poses a `synth` render was made with (`transforms_{train,test}.json`),
/// by the name its photo takes in a COLMAP project of it: `SPLIT_r_K.png`.
pub fn render_poses(render: &Path) -> std::collections::BTreeMap<String, glam::Mat4> {
    let mut poses = std::collections::BTreeMap::new();
    for split in ["train", "test"] {
        let f = assetfield_data::schema::TransformsFile::read(
            &render.join(format!("transforms_{split}.json")),
        )
        .unwrap();
        for e in &f.frames {
            let stem =
                e.file_path.trim_start_matches("./").trim_start_matches(&format!("{split}/"));
            poses.insert(format!("{split}_{stem}.png"), e.matrix());
        }
    }
    poses
}

/// Write the NeRF-synthetic dataset `src` (`transforms_{train,test}.json`, `camera_angle_x`)
/// as a nerfstudio capture `dst/transforms.json` (`fl_x fl_y cx cy w h`, one file, split by
/// holdout) whose cameras are moved by `s`: the same photos of the same scene, posed in
/// another frame and unit. No `synth.json` is written, so nothing tells the tools the
/// scene's box, its up axis or its unit.
pub fn repose_as_nerfstudio(src: &Path, dst: &Path, s: &Similarity) {
    use assetfield_data::schema::{FrameEntry, TransformsFile, write_transforms};
    std::fs::create_dir_all(dst.join("images")).unwrap();
    let mut out = TransformsFile { camera_model: Some("OPENCV".into()), ..Default::default() };
    for split in ["train", "test"] {
        let file = TransformsFile::read(&src.join(format!("transforms_{split}.json"))).unwrap();
        let fov = file.camera_angle_x.expect("a NeRF-synthetic file");
        for (i, f) in file.frames.iter().enumerate() {
            let from = src.join(format!("{}.png", f.file_path.trim_start_matches("./")));
            let name = format!("images/{split}_{i:03}.png");
            std::fs::copy(&from, dst.join(&name)).unwrap();
            if out.w.is_none() {
                let (w, h) = image::image_dimensions(&from).unwrap();
                let focal = 0.5 * w as f32 / (0.5 * fov).tan();
                (out.w, out.h, out.fl_x, out.fl_y) = (Some(w), Some(h), Some(focal), Some(focal));
                (out.cx, out.cy) = (Some(w as f32 / 2.0), Some(h as f32 / 2.0));
            }
            let m = f.matrix();
            let rotation = s.rotation * glam::Mat3::from_mat4(m);
            let position = s.point(m.w_axis.truncate());
            let c2w = glam::Mat4::from_mat3_translation(rotation, position);
            out.frames.push(FrameEntry::new(name, c2w));
        }
    }
    write_transforms(&dst.join("transforms.json"), &out).unwrap();
}

/// The ground truth of a scene moved by `s` and then by a field's ground alignment `align`
/// (`p -> align(s(p))`): positions, boxes (the box of the moved corners; exact when the two
/// turn the ground by a multiple of 90 degrees about the vertical), yaws and scales.
pub fn moved_gt(
    gt: &assetfield_layout::GtLayout,
    s: &Similarity,
    align: &assetfield_data::GroundAlignment,
) -> assetfield_layout::GtLayout {
    let total = |p: glam::Vec3| align.transform_point(s.point(p));
    let turn = align.rotation_matrix() * s.rotation;
    let yaw = turn.x_axis.y.atan2(turn.x_axis.x).to_degrees();
    let mut out = gt.clone();
    for i in out.instances.iter_mut().chain(out.containers.iter_mut()) {
        let p = total(glam::Vec3::from(i.position));
        let top = total(glam::Vec3::new(i.position[0], i.position[1], i.top)).z;
        let b = i.bev_aabb;
        let corners = [(b[0], b[1]), (b[2], b[1]), (b[0], b[3]), (b[2], b[3])]
            .map(|(x, y)| total(glam::Vec3::new(x, y, i.position[2])));
        let lo = corners.iter().fold(glam::Vec3::splat(f32::INFINITY), |a, c| a.min(*c));
        let hi = corners.iter().fold(glam::Vec3::splat(f32::NEG_INFINITY), |a, c| a.max(*c));
        i.position = p.to_array();
        i.bev_aabb = [lo.x, lo.y, hi.x, hi.y];
        i.yaw_deg += yaw;
        i.scale *= s.scale;
        i.top = top;
    }
    out
}

/// Per texel node of `field`'s ground grid (row-major, `res[1]` rows of `res[0]`), the sum
/// of the march's step opacities over the whole height of its column: haze above an opaque
/// floor adds to it, where the largest step opacity would not see it. What the residue
/// measures compare (a vacated footprint against the ground around it).
pub fn column_opacity(field: &assetfield_field::Field) -> Vec<f32> {
    let cfg = &field.config;
    let [cols, rows, nz] = cfg.res;
    let (a0, v) = (cfg.aabb().min, cfg.voxel_size());
    let zs: Vec<f32> = (0..nz).map(|k| a0.z + k as f32 * v.z).collect();
    let delta = cfg.step_size() * cfg.distance_scale;
    let (mut scratch, mut sigma) = (Vec::new(), vec![0.0f32; nz]);
    let mut opacity = vec![0.0f32; cols * rows];
    for r in 0..rows {
        for c in 0..cols {
            let (x, y) = (a0.x + c as f32 * v.x, a0.y + r as f32 * v.y);
            field.density_column(x, y, &zs, &mut scratch, &mut sigma);
            opacity[r * cols + c] = sigma.iter().map(|s| 1.0 - (-s * delta).exp()).sum();
        }
    }
    opacity
}

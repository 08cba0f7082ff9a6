//! The field commands end to end on a tiny synthesised scene: train, eval, render, planes;
//! resume and Ctrl-C; ground alignment; bad input (exit 1, a clear message, nothing
//! written).

use assetfield_core::TensorFile;
use assetfield_tests::{repo, run_cli, scratch};
use glam::{Mat4, Vec3};
use std::path::Path;

/// Synthesise the small plaza dataset into `dir/d` (12 views, 2 of them test, 32 px).
fn synth_tiny(dir: &Path) {
    let scene = repo().join("scenes/plaza.ron");
    let (code, _, err) = run_cli(
        dir,
        &[
            "synth",
            scene.to_str().unwrap(),
            "--out",
            "d",
            "--views",
            "12",
            "--test-views",
            "2",
            "--res",
            "32",
            "--aa",
            "1",
        ],
    );
    assert_eq!(code, 0, "{err}");
}

fn ok(dir: &Path, args: &[&str]) -> String {
    let (code, out, err) = run_cli(dir, args);
    assert_eq!(code, 0, "{args:?}\nstdout: {out}\nstderr: {err}");
    out
}

fn fail(dir: &Path, args: &[&str], needles: &[&str]) {
    let (code, _, err) = run_cli(dir, args);
    assert_eq!(code, 1, "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: expected {n:?} in: {err}");
    }
}

fn meta_u64(path: &Path, key: &str) -> u64 {
    let f = TensorFile::load(path).unwrap();
    f.meta_json(key).unwrap()
}

fn png_size(path: &Path) -> (u32, u32) {
    image::image_dimensions(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

const TINY: [&str; 6] = ["--iters", "60", "--res", "32", "--batch", "512"];

#[test]
fn help_explains_the_field_commands() {
    let dir = scratch("field-help");
    let out = ok(&dir, &["--help"]);
    for cmd in ["train", "eval", "render", "planes"] {
        assert!(out.contains(cmd), "{out}");
    }
    let out = ok(&dir, &["train", "--help"]);
    for flag in [
        "--model",
        "--minutes",
        "--iters",
        "--res",
        "--batch",
        "--decoder",
        "--aabb",
        "--align-ground",
        "--background",
        "--seed",
        "--checkpoint-every-minutes",
        "--resume",
        "--val-every",
        "--downscale",
        "synth.json",
        "ckpt.safetensors",
    ] {
        assert!(out.contains(flag), "train --help lacks {flag}: {out}");
    }
    let out = ok(&dir, &["eval", "--help"]);
    assert!(out.contains("metrics.json") && out.contains("--views") && out.contains("--every"));
    let out = ok(&dir, &["render", "--help"]);
    assert!(out.contains("--orbit") && out.contains("--elevation") && out.contains("--fov"));
    let out = ok(&dir, &["planes", "--help"]);
    assert!(
        out.contains("density.png") && out.contains("color_pca.png") && out.contains("curve.png")
    );
    let (code, _, _) = run_cli(&dir, &["train"]);
    assert_eq!(code, 2, "a missing argument is a usage error");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn train_eval_render_planes() {
    let dir = scratch("field-main");
    synth_tiny(&dir);
    let mut args = vec!["train", "d", "--out", "runs/f.safetensors", "--val-every", "30"];
    args.extend(TINY);
    let out = ok(&dir, &args);
    assert!(out.contains("60 iterations") && out.contains("runs/f.safetensors"), "{out}");
    assert!(out.contains("PSNR") && out.contains("rays/s"), "{out}");
    let field = dir.join("runs/f.safetensors");
    assert_eq!(meta_u64(&field, "iterations"), 60);
    let f = TensorFile::load(&field).unwrap();
    for key in ["history", "dataset", "aabb", "background", "val_history", "config"] {
        assert!(f.meta(key).is_some(), "field file lacks metadata {key:?}");
    }
    assert!(f.meta("ground_transform").is_none(), "no alignment was asked for");
    let history: Vec<(f64, u64, f32)> = f.meta_json("history").unwrap();
    assert_eq!(history.last().unwrap().1, 60);
    let val: Vec<(f64, u64, f32)> = f.meta_json("val_history").unwrap();
    assert_eq!(val.iter().map(|v| v.1).collect::<Vec<_>>(), vec![30, 60]);
    // the box is synth.json's scene_aabb padded by 2%
    let synth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("d/synth.json")).unwrap()).unwrap();
    let aabb: [[f32; 3]; 2] = f.meta_json("aabb").unwrap();
    let lo = synth["scene_aabb"][0][0].as_f64().unwrap() as f32;
    let hi = synth["scene_aabb"][1][0].as_f64().unwrap() as f32;
    assert!((aabb[0][0] - (lo - 0.02 * (hi - lo))).abs() < 1e-4, "{aabb:?}");

    // eval
    let out = ok(&dir, &["eval", "runs/f.safetensors", "--data", "d", "--out", "ev"]);
    assert!(out.contains("PSNR") && out.contains("SSIM"), "{out}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("ev/metrics.json")).unwrap())
            .unwrap();
    for key in ["psnr", "ssim", "views", "seconds_per_view", "model", "resolution"] {
        assert!(m.get(key).is_some(), "metrics.json lacks {key}: {m}");
    }
    let psnr = m["psnr"].as_f64().unwrap();
    assert!(psnr.is_finite() && psnr > 10.0, "psnr {psnr}");
    assert!(m["ssim"].as_f64().unwrap().is_finite());
    assert_eq!(m["model"], "s");
    assert_eq!(m["resolution"], serde_json::json!([32, 32]));
    let views = m["views"].as_array().unwrap();
    assert_eq!(views.len(), 2);
    for v in views {
        let k = v["index"].as_u64().unwrap();
        assert!(v["file_path"].as_str().unwrap().contains("test"));
        assert!(v["psnr"].as_f64().unwrap().is_finite());
        assert_eq!(png_size(&dir.join(format!("ev/render/r_{k}.png"))), (32, 32));
        assert_eq!(png_size(&dir.join(format!("ev/error/r_{k}.png"))), (32, 32));
    }
    // the dataset stored in the field is the default; --views limits, existing output is kept
    let before = std::fs::read(dir.join("ev/metrics.json")).unwrap();
    fail(&dir, &["eval", "runs/f.safetensors", "--out", "ev"], &["already exists", "--force"]);
    assert_eq!(std::fs::read(dir.join("ev/metrics.json")).unwrap(), before);
    ok(&dir, &["eval", "runs/f.safetensors", "--out", "ev", "--views", "1", "--force"]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("ev/metrics.json")).unwrap())
            .unwrap();
    assert_eq!(m["views"].as_array().unwrap().len(), 1);

    // render: a turntable and the test cameras
    ok(&dir, &["render", "runs/f.safetensors", "--out", "orbit", "--orbit", "3", "--res", "24"]);
    for k in 0..3 {
        assert_eq!(png_size(&dir.join(format!("orbit/orbit_{k:03}.png"))), (24, 24));
    }
    assert_eq!(std::fs::read_dir(dir.join("orbit")).unwrap().count(), 3);
    ok(&dir, &["render", "runs/f.safetensors", "--out", "cams", "--data", "d"]);
    assert_eq!(png_size(&dir.join("cams/r_1.png")), (32, 32));

    // planes: seen from above, scaled up to at least 512 px
    let out = ok(&dir, &["planes", "runs/f.safetensors", "--out", "planes"]);
    assert!(out.contains("density.png"), "{out}");
    for name in ["density.png", "density_pca.png", "color_pca.png", "curve.png"] {
        let (w, h) = png_size(&dir.join("planes").join(name));
        assert!(w >= 512 && h >= 300, "{name}: {w}x{h}");
    }
    assert!(dir.join("planes/planes.json").exists());
    // no staging folders left behind
    for e in std::fs::read_dir(&dir).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.contains(".tmp-"), "left behind: {name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn resume_continues_the_run() {
    let dir = scratch("field-resume");
    synth_tiny(&dir);
    let base = ["train", "d", "--out", "f.safetensors", "--res", "32", "--batch", "512"];
    let mut first = base.to_vec();
    first.extend(["--iters", "30", "--model", "i", "--decoder", "sh"]);
    ok(&dir, &first);
    assert!(dir.join("f.ckpt.safetensors").exists(), "the checkpoint is kept for --resume");
    assert_eq!(meta_u64(&dir.join("f.safetensors"), "iterations"), 30);
    // a second run on the same output must say how to go on
    fail(&dir, &first, &["already exists", "--resume", "--force"]);
    let mut more = base.to_vec();
    more.extend(["--resume", "--iters", "50"]);
    let out = ok(&dir, &more);
    assert!(out.contains("50 iterations") && out.contains("20 new"), "{out}");
    let field = dir.join("f.safetensors");
    assert_eq!(meta_u64(&field, "iterations"), 50);
    let f = TensorFile::load(&field).unwrap();
    assert_eq!(f.meta("model"), Some("i"), "model comes from the checkpoint");
    let history: Vec<(f64, u64, f32)> = f.meta_json("history").unwrap();
    assert_eq!(history.first().unwrap().1, 1);
    assert_eq!(history.last().unwrap().1, 50);
    assert!(history.windows(2).all(|w| w[0].1 < w[1].1 && w[0].0 <= w[1].0));
    // --resume without a checkpoint names where it looked
    fail(
        &dir,
        &["train", "d", "--out", "other.safetensors", "--resume"],
        &["no checkpoint", "other.ckpt.safetensors"],
    );
    // --discard-checkpoint removes it at the end
    let mut fresh = base.to_vec();
    fresh.extend(["--iters", "10", "--force", "--discard-checkpoint"]);
    ok(&dir, &fresh);
    assert!(!dir.join("f.ckpt.safetensors").exists());
    assert_eq!(meta_u64(&field, "iterations"), 10);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Start an endless `train` in `dir` (dataset `d`), send it `signal` once it runs, and check
/// that it stops with status 130, a checkpoint and no field file. `closed`: the reader of its
/// standard output and error has gone (both pipes closed) before the signal.
#[cfg(unix)]
fn signal_stops_training_with_a_checkpoint(dir: &Path, signal: &str, closed: bool) {
    use std::process::{Command, Stdio};
    let _ = std::fs::remove_file(dir.join("f.ckpt.safetensors"));
    let mut child = Command::new(assetfield_tests::assetfield_bin())
        .args(["train", "d", "--out", "f.safetensors", "--iters", "1000000", "--res", "32"])
        .args(["--batch", "256", "--force"])
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    if closed {
        drop(child.stdout.take());
        drop(child.stderr.take());
    }
    // wait until training runs (the box is printed just before the first step)
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let status =
        Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status();
    assert!(status.unwrap().success());
    if closed {
        let start = std::time::Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if start.elapsed() > std::time::Duration::from_secs(60) {
                let _ = child.kill();
                panic!("SIG{signal} with closed output pipes did not stop train in 60 s");
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        };
        assert_eq!(status.code(), Some(130), "SIG{signal}, closed pipes");
        assert!(
            dir.join("f.ckpt.safetensors").exists(),
            "SIG{signal}, closed pipes: no checkpoint"
        );
        assert!(!dir.join("f.safetensors").exists(), "SIG{signal}, closed pipes: a field file");
        return;
    }
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "SIG{signal}: {err}");
    assert!(err.contains("f.ckpt.safetensors") && err.contains("--resume"), "SIG{signal}: {err}");
    assert!(dir.join("f.ckpt.safetensors").exists(), "SIG{signal}: no checkpoint");
    assert!(!dir.join("f.safetensors").exists(), "SIG{signal}: a half-trained field file");
}

#[cfg(unix)]
#[test]
fn ctrl_c_term_and_hup_save_a_checkpoint_and_no_field() {
    let dir = scratch("field-ctrlc");
    synth_tiny(&dir);
    // SIGTERM (kill, a batch system's time limit) and SIGHUP (the terminal closing) stop a
    // run as Ctrl-C does
    for signal in ["TERM", "HUP", "INT"] {
        signal_stops_training_with_a_checkpoint(&dir, signal, false);
    }
    // whatever has become of standard output and error (`train ... 2>&1 | head -1`)
    for signal in ["TERM", "INT"] {
        signal_stops_training_with_a_checkpoint(&dir, signal, true);
    }
    signal_stops_training_with_a_checkpoint(&dir, "INT", false);
    // and the run goes on from there
    let state: serde_json::Value =
        TensorFile::load(&dir.join("f.ckpt.safetensors")).unwrap().meta_json("train").unwrap();
    assert!(state["iter"].as_u64().is_some(), "{state}");
    let out = ok(&dir, &["train", "d", "--out", "f.safetensors", "--resume", "--iters", "5"]);
    assert!(out.contains("wrote f.safetensors"), "{out}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_run_killed_while_writing_its_field_finishes_from_its_checkpoint() {
    let dir = scratch("field-killed-write");
    synth_tiny(&dir);
    let args = ["train", "d", "--out", "f.safetensors", "--iters", "12", "--res", "32"];
    let small = ["--batch", "512", "--checkpoint-every-minutes", "0"];
    ok(&dir, &[&args[..], &small[..]].concat());
    // train saves its final checkpoint before the field file, so a kill -9 during the field
    // write leaves that checkpoint and the field as a hidden temporary: made here by hand
    assert!(dir.join("f.ckpt.safetensors").exists());
    std::fs::rename(dir.join("f.safetensors"), dir.join(".f.safetensors.tmp-4194305")).unwrap();
    let resume = ["--resume", "--discard-checkpoint"];
    let out = ok(&dir, &[&args[..], &small[..], &resume[..]].concat());
    assert!(out.contains("wrote f.safetensors"), "{out}");
    assert_eq!(meta_u64(&dir.join("f.safetensors"), "iterations"), 12, "no iteration lost");
    let hidden: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(hidden.is_empty(), "the killed run's temporary must be gone: {hidden:?}");
    assert!(!dir.join("f.ckpt.safetensors").exists(), "--discard-checkpoint removes it");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ground_alignment_levels_tilted_poses() {
    let dir = scratch("field-align");
    synth_tiny(&dir);
    // tilt the whole capture by 25 degrees about an oblique horizontal axis and shift it
    let tilt = Mat4::from_translation(Vec3::new(3.0, -1.0, 2.0))
        * Mat4::from_axis_angle(Vec3::new(1.0, 0.5, 0.0).normalize(), 25f32.to_radians());
    for split in ["train", "test"] {
        let p = dir.join(format!("d/transforms_{split}.json"));
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        for f in v["frames"].as_array_mut().unwrap() {
            let m: [[f32; 4]; 4] = serde_json::from_value(f["transform_matrix"].clone()).unwrap();
            let c2w = Mat4::from_cols_array_2d(&m).transpose();
            let t = (tilt * c2w).transpose().to_cols_array_2d();
            f["transform_matrix"] = serde_json::json!(t);
        }
        std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
    }
    std::fs::remove_file(dir.join("d/synth.json")).unwrap();
    let mut args = vec![
        "train",
        "d",
        "--out",
        "f.safetensors",
        "--align-ground",
        "pca",
        "--aabb",
        "-7,-7,-2,7,7,4",
    ];
    args.extend(TINY);
    ok(&dir, &args);
    let f = TensorFile::load(&dir.join("f.safetensors")).unwrap();
    let g: serde_json::Value = f.meta_json("ground_transform").unwrap();
    let n: [f32; 3] = serde_json::from_value(g["normal"].clone()).unwrap();
    let expect = tilt.transform_vector3(Vec3::Z);
    assert!(Vec3::from(n).dot(expect) > 0.99, "normal {n:?}, expected {expect}");
    // eval re-applies the stored alignment to the tilted test poses
    ok(&dir, &["eval", "f.safetensors", "--out", "ev"]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("ev/metrics.json")).unwrap())
            .unwrap();
    assert!(m["psnr"].as_f64().unwrap() > 10.0, "{m}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_ground_under_the_box_only_where_there_is_one() {
    // a render of this project stands on z = 0: rays below its box meet the ground; the same
    // photos without synth.json (a capture posed with no floor found) let the map take them
    let dir = scratch("field-ground");
    synth_tiny(&dir);
    let ground = |out: &str| {
        let f = TensorFile::load(&dir.join(out)).unwrap();
        f.get_u8(assetfield_field::background::GROUND_TENSOR, &[1]).unwrap()[0]
    };
    let mut args = vec!["train", "d", "--out", "rendered.safetensors", "--background-map", "on"];
    args.extend(TINY);
    let (code, _, err) = run_cli(&dir, &args);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("no floor under the box"), "{err}");
    assert_eq!(ground("rendered.safetensors"), 1);
    std::fs::remove_file(dir.join("d/synth.json")).unwrap();
    args[3] = "posed.safetensors";
    let (code, _, err) = run_cli(&dir, &args);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("no floor under the box"), "{err}");
    assert_eq!(ground("posed.safetensors"), 0);
    // the user who knows the box stands on the ground says so
    args[3] = "told.safetensors";
    args.extend(["--ground-under-box", "on"]);
    let (code, _, err) = run_cli(&dir, &args);
    assert_eq!(code, 0, "{err}");
    assert_eq!(ground("told.safetensors"), 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_fails_clearly() {
    let dir = scratch("field-bad");
    synth_tiny(&dir);
    fail(
        &dir,
        &["train", "missing", "--out", "f.safetensors"],
        &["missing", "cannot open dataset"],
    );
    for (aabb, needle) in [("1,2,3", "six"), ("0,0,0,1,1,x", "\"x\""), ("-1,-1,2,1,1,1", "zmin")] {
        fail(&dir, &["train", "d", "--out", "f.safetensors", "--aabb", aabb], &["--aabb", needle]);
    }
    fail(&dir, &["train", "d", "--out", "f.safetensors", "--background", "pink"], &["colour"]);
    // feature maps: only I-AssetField has a semantic field; every training image needs one
    std::fs::create_dir_all(dir.join("feats")).unwrap();
    fail(
        &dir,
        &["train", "d", "--out", "f.safetensors", "--features", "feats"],
        &["--features", "--model i"],
    );
    fail(
        &dir,
        &["train", "d", "--out", "f.safetensors", "--model", "i", "--features", "feats"],
        &["no feature map for image", "r_0.png", "r_0.npy"],
    );
    std::fs::write(dir.join("feats/r_0.npy"), "not numpy").unwrap();
    fail(
        &dir,
        &["train", "d", "--out", "f.safetensors", "--model", "i", "--features", "feats"],
        &["feature map", "r_0.npy", "magic"],
    );
    // not a field file
    std::fs::write(dir.join("notes.safetensors"), "hello").unwrap();
    for file in ["d/synth.json", "d/train/r_0.png", "notes.safetensors", "absent.safetensors"] {
        fail(&dir, &["eval", file, "--data", "d", "--out", "ev"], &[file, "cannot read field"]);
        fail(&dir, &["planes", file, "--out", "pl"], &[file, "cannot read field"]);
        fail(&dir, &["render", file, "--out", "rd"], &[file, "cannot read field"]);
    }
    for out in ["f.safetensors", "f.ckpt.safetensors", "ev", "pl", "rd"] {
        assert!(!dir.join(out).exists(), "{out} written by a failed command");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Field files found by fuzzing (a NaN in a plane evaluated to "PSNR NaN dB" with exit 0; a
/// resolution of 100000 aborted on a 640 GB allocation; a zero march step rendered blank
/// images): every command that opens a field refuses them, naming the file and the tensor
/// or config key, and writes nothing.
#[test]
fn broken_field_files_are_refused_by_every_command() {
    let dir = scratch("field-broken");
    let real = TensorFile::load(&repo().join("tests/data/living_room_s128.safetensors")).unwrap();
    let config = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut f = real.clone();
        let mut c: serde_json::Value = serde_json::from_str(f.meta("config").unwrap()).unwrap();
        edit(&mut c);
        f.set_meta("config", c.to_string());
        f
    };
    let mut nan = real.clone();
    let shape = nan.shape_of("density.plane").unwrap().to_vec();
    let mut v = nan.get_f32("density.plane", &shape).unwrap().to_vec();
    v[4242] = f32::NAN;
    nan.insert_f32("density.plane", &shape, v);
    let cases = [
        (
            "nan.safetensors",
            nan,
            "tensor \"density.plane\" has a non-finite value (NaN) at index 4242",
        ),
        (
            "huge.safetensors",
            config(&|c| c["res"] = serde_json::json!([100_000, 100_000, 34])),
            "config \"res[0]\" is 100000, expected 2 to 4096",
        ),
        (
            "step0.safetensors",
            config(&|c| c["step_ratio"] = serde_json::json!(0.0)),
            "config \"step_ratio\" is 0.0",
        ),
        (
            "shape.safetensors",
            config(&|c| c["res"] = serde_json::json!([64, 64, 34])),
            "tensor \"density.plane\" has shape [110, 128, 16], expected [64, 64, 16]",
        ),
    ];
    for (name, file, needle) in &cases {
        file.save(&dir.join(name)).unwrap();
        fail(&dir, &["eval", name, "--data", "nowhere", "--out", "ev"], &[name, needle]);
        fail(&dir, &["render", name, "--out", "rd"], &[name, needle]);
        fail(&dir, &["planes", name, "--out", "pl"], &[name, needle]);
        fail(&dir, &["mine", name, "--out", "lib"], &[name, needle]);
    }
    for out in ["ev", "rd", "pl", "lib"] {
        assert!(!dir.join(out).exists(), "{out} written by a failed command");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

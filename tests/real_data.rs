//! The real benchmark data in ../shared/data through the command line (the data crate's own
//! tests check loading in depth). Skips with a message when the data is absent.

use assetfield_tests::{run_cli, scratch, shared_data};

#[test]
fn inspect_describes_lego_and_draws_its_cameras() {
    let Some(lego) = shared_data("nerf_synthetic_lego_400") else { return };
    let dir = scratch("inspect-lego");
    let (code, out, err) =
        run_cli(&dir, &["inspect", lego.to_str().unwrap(), "--picture", "cams.png"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("400") && out.contains("train") && out.contains("test"), "{out}");
    let img = image::open(dir.join("cams.png")).unwrap();
    assert!(img.width() >= 400);
    let (code, json, _) =
        run_cli(&dir, &["inspect", lego.to_str().unwrap(), "--json", "--picture", "cams.png"]);
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["views"], 400);
    assert!((v["fx"].as_f64().unwrap() - 555.555).abs() < 0.01, "{v}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn inspect_reads_a_real_capture_with_distortion() {
    let Some(fox) = shared_data("instant_ngp_fox") else { return };
    let dir = scratch("inspect-fox");
    let (code, out, err) =
        run_cli(&dir, &["inspect", fox.to_str().unwrap(), "--picture", "cams.png"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("67") && out.to_lowercase().contains("distortion"), "{out}");
    std::fs::remove_dir_all(&dir).unwrap();
}

//! Field files that must be refused when loaded (found by fuzzing `eval`, `render`, `planes`
//! and `mine`): non-finite parameters, configurations out of bounds or not matching the
//! tensors, and render settings that give blank images. Each starts from the small real
//! field of `tests/data` and changes one thing; the error names the file and the place.

use assetfield_core::TensorFile;
use assetfield_field::{Field, FieldError};
use std::path::{Path, PathBuf};

fn real_field() -> TensorFile {
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/living_room_s128.safetensors");
    TensorFile::load(&p).unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let d =
        std::env::temp_dir().join(format!("assetfield-field-files-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Save `f` as `dir/name` and load it as a field: the error.
fn load_err(f: &TensorFile, dir: &Path, name: &str) -> (FieldError, String) {
    let path = dir.join(name);
    f.save(&path).unwrap();
    let e = Field::load(&path).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains(&path.display().to_string()), "the error names the file: {msg}");
    // the other loader (with the training metadata) refuses it the same way
    let again = assetfield_field::eval::load_field(&path).unwrap_err().to_string();
    assert_eq!(again, msg);
    (e, msg)
}

/// `f` with the JSON config edited by `edit`.
fn with_config(f: &TensorFile, edit: impl FnOnce(&mut serde_json::Value)) -> TensorFile {
    let mut g = f.clone();
    let mut v: serde_json::Value = serde_json::from_str(g.meta("config").unwrap()).unwrap();
    edit(&mut v);
    g.set_meta("config", v.to_string());
    g
}

#[test]
fn the_real_field_loads() {
    let dir = scratch("ok");
    let path = dir.join("f.safetensors");
    real_field().save(&path).unwrap();
    let (field, occ) = Field::load(&path).unwrap();
    assert_eq!(field.config.res, [128, 110, 34]);
    assert!(occ.is_some());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn non_finite_parameters_are_refused_with_tensor_and_index() {
    let dir = scratch("nan");
    for (tensor, index, value) in [
        ("density.plane", 12_345, f32::NAN),
        ("color.axis", 7, f32::INFINITY),
        ("decoder.0.weight", 0, f32::NEG_INFINITY),
    ] {
        let mut f = real_field();
        let shape = f.shape_of(tensor).unwrap().to_vec();
        let mut v = f.get_f32(tensor, &shape).unwrap().to_vec();
        v[index] = value;
        v[index + 1] = f32::NAN; // only the first bad value is reported
        f.insert_f32(tensor, &shape, v);
        let (e, msg) = load_err(&f, &dir, "nan.safetensors");
        assert!(
            matches!(&e, FieldError::NonFinite { tensor: t, index: i, .. } if t == tensor && *i == index),
            "{msg}"
        );
        assert!(
            msg.contains(&format!(
                "tensor \"{tensor}\" has a non-finite value ({value}) at index {index}"
            )),
            "{msg}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn finite_parameters_too_large_to_decode_are_refused() {
    // found by the fuzz harness: eight values of 3e38 in a field's planes passed the finite
    // check and rendered NaN
    let dir = scratch("huge-values");
    let tensor = "density.plane";
    let mut f = real_field();
    let shape = f.shape_of(tensor).unwrap().to_vec();
    let mut v = f.get_f32(tensor, &shape).unwrap().to_vec();
    v[99] = 3.0e38;
    f.insert_f32(tensor, &shape, v);
    let (e, msg) = load_err(&f, &dir, "huge.safetensors");
    assert!(
        matches!(&e, FieldError::ParameterRange { tensor: t, index: 99, .. } if t == tensor),
        "{msg}"
    );
    assert!(msg.contains("tensor \"density.plane\" has a value of 300000000000000000000000000000000000000 at index 99"), "{msg}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn huge_resolutions_are_refused_before_allocating() {
    let dir = scratch("huge");
    // 100000^2 x (16 + 48) values would be a 2.5 TB allocation
    let f = with_config(&real_field(), |c| c["res"] = serde_json::json!([100_000, 100_000, 34]));
    let (e, msg) = load_err(&f, &dir, "huge.safetensors");
    assert!(matches!(&e, FieldError::Config { key, .. } if key == "res[0]"), "{msg}");
    assert!(msg.contains("config \"res[0]\" is 100000, expected 2 to 4096"), "{msg}");
    for (key, value, needle) in [
        (
            "density_channels",
            serde_json::json!(100_000),
            "config \"density_channels\" is 100000, expected 1 to 256",
        ),
        (
            "color_channels",
            serde_json::json!(0),
            "config \"color_channels\" is 0, expected 1 to 256",
        ),
        ("basis_dim", serde_json::json!(1u64 << 40), "config \"basis_dim\" is 1099511627776"),
        (
            "decoder",
            serde_json::json!({"Mlp": {"hidden": [64, 0], "view_freqs": 2}}),
            "config \"decoder.Mlp.hidden[1]\" is 0",
        ),
        (
            "decoder",
            serde_json::json!({"Mlp": {"hidden": [64], "view_freqs": 40}}),
            "config \"decoder.Mlp.view_freqs\" is 40, expected 0 to 16",
        ),
        (
            "decoder",
            serde_json::json!({"Sh": {"degree": 9}}),
            "config \"decoder.Sh.degree\" is 9, expected 0 to 2",
        ),
    ] {
        let f = with_config(&real_field(), |c| c[key] = value);
        let (e, msg) = load_err(&f, &dir, "bounds.safetensors");
        assert!(matches!(e, FieldError::Config { .. }), "{msg}");
        assert!(msg.contains(needle), "expected {needle:?} in {msg}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_config_that_does_not_fit_the_tensors_names_expected_and_actual() {
    let dir = scratch("fit");
    // within bounds, but not the resolution the planes were trained at
    let f = with_config(&real_field(), |c| c["res"] = serde_json::json!([64, 64, 34]));
    let (e, msg) = load_err(&f, &dir, "fit.safetensors");
    assert!(
        matches!(&e, FieldError::Shape { tensor, expected, actual, .. }
            if tensor == "density.plane" && expected == &[64, 64, 16] && actual == &[110, 128, 16]),
        "{msg}"
    );
    assert!(msg.contains("has shape [110, 128, 16], expected [64, 64, 16]"), "{msg}");
    let f = with_config(&real_field(), |c| c["basis_dim"] = serde_json::json!(20));
    let (_, msg) = load_err(&f, &dir, "fit.safetensors");
    assert!(
        msg.contains("tensor \"color.basis.weight\" has shape [27, 48], expected [20, 48]"),
        "{msg}"
    );
    // a tensor the config implies is missing
    let mut f = real_field();
    f.tensors.remove("density.axis");
    let (_, msg) = load_err(&f, &dir, "fit.safetensors");
    assert!(msg.contains("missing tensor \"density.axis\""), "{msg}");
    // an occupancy grid without cells
    let mut f = real_field();
    f.insert_u8("occupancy", &[0, 55, 64], vec![]);
    let (_, msg) = load_err(&f, &dir, "fit.safetensors");
    assert!(msg.contains("\"occupancy\" has shape [0, 55, 64]"), "{msg}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn render_settings_and_boxes_must_be_usable() {
    let dir = scratch("render");
    for (key, value, needle) in [
        (
            "step_ratio",
            serde_json::json!(0.0),
            "config \"step_ratio\" is 0.0, expected a march step of 0.05 to 4 voxels",
        ),
        ("step_ratio", serde_json::json!(-0.5), "config \"step_ratio\" is -0.5"),
        ("step_ratio", serde_json::json!(1e39), "config \"step_ratio\" is inf"),
        (
            "distance_scale",
            serde_json::json!(0.0),
            "config \"distance_scale\" is 0.0, expected a positive finite number",
        ),
        ("density_shift", serde_json::json!(-1e39), "config \"density_shift\" is -inf"),
        (
            "aabb",
            serde_json::json!([[1, -3, 0], [-1, 3, 1]]),
            "config \"aabb\" is [[1.0, -3.0, 0.0], [-1.0, 3.0, 1.0]], expected [[xmin, ymin, zmin], [xmax, ymax, zmax]] with xmin below xmax",
        ),
        ("aabb", serde_json::json!([[-1, -3, 0], [1, 3, 0]]), "with zmin below zmax"),
        ("aabb", serde_json::json!([[-1, -3, 0], [1, 3, 1e30]]), "finite coordinates within 1e6"),
    ] {
        let f = with_config(&real_field(), |c| c[key] = value);
        let (e, msg) = load_err(&f, &dir, "render.safetensors");
        assert!(matches!(e, FieldError::Config { .. }), "{msg}");
        assert!(msg.contains(needle), "expected {needle:?} in {msg}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

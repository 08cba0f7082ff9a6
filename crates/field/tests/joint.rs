//! Scenes trained together share their vertical axes, basis and decoders bit for bit and keep
//! their own planes; a new scene fitted against a frozen shared set leaves it untouched; a
//! joint run resumed from its checkpoints continues exactly; one scene trained "jointly" is
//! the plain trainer.

use assetfield_core::{Aabb3, TensorFile};
use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_field::joint::first_shared_difference;
use assetfield_field::{
    Field, FieldConfig, GridRule, JointTrainer, ModelKind, TrainConfig, Trainer, joint_configs,
    render_view, share_config,
};
use assetfield_synth::{SynthOptions, synthesize};
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

fn root() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root =
            std::env::temp_dir().join(format!("assetfield-field-joint-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(&root).unwrap();
        root
    })
}

const ASSETS: &str = r#"assets: {
    "red": Asset(parts: [Box(center: (0, 0, 0.3), size: (0.6, 0.6, 0.6), color: (0.85, 0.2, 0.15))]),
    "blue": Asset(parts: [Cylinder(base: (0, 0, 0), radius: 0.3, height: 0.8, color: (0.15, 0.3, 0.8))]),
    "green": Asset(parts: [Sphere(center: (0, 0, 0.35), radius: 0.35, color: (0.2, 0.7, 0.3))]),
}"#;

/// Two small scenes that share the blue cylinder, of different sizes; made once per binary.
fn scene(name: &str) -> PathBuf {
    static MADE: OnceLock<()> = OnceLock::new();
    MADE.get_or_init(|| {
        for (name, layout) in [
            (
                "alpha",
                r#"Instance(asset: "red", at: (-0.8, 0.0), yaw: 20), Instance(asset: "blue", at: (0.8, 0.3))"#,
            ),
            (
                "beta",
                r#"Instance(asset: "blue", at: (-1.2, 0.0)), Instance(asset: "green", at: (1.0, -0.2)), Instance(asset: "blue", at: (0.2, 0.9))"#,
            ),
        ] {
            let script = root().join(format!("{name}.ron"));
            std::fs::write(&script, format!("Scene({ASSETS}, layout: [{layout}])")).unwrap();
            let opts = SynthOptions {
                views: Some(24),
                test_views: Some(3),
                resolution: Some(40),
                samples_per_side: Some(1),
                ..Default::default()
            };
            synthesize(&script, &opts, &root().join(name), true, None, &mut |_, _| {}).unwrap();
        }
    });
    root().join(name)
}

fn load(name: &str, split: Split) -> Dataset {
    Dataset::load(&scene(name), split, &LoadOptions::default()).unwrap()
}

fn psnr(field: &Field, test: &Dataset) -> f32 {
    let (mut se, mut n) = (0.0f64, 0usize);
    for f in &test.frames {
        let img = render_view(field, None, &f.camera, Vec3::ONE);
        se += img.iter().zip(&f.image.rgb).map(|(a, b)| ((a - b) as f64).powi(2)).sum::<f64>();
        n += img.len();
    }
    (-10.0 * (se / n as f64).log10()) as f32
}

fn boxes() -> [Aabb3; 2] {
    [
        Aabb3::new(Vec3::new(-1.3, -1.0, -0.05), Vec3::new(1.3, 1.0, 0.75)),
        Aabb3::new(Vec3::new(-1.7, -0.8, -0.05), Vec3::new(1.5, 1.4, 0.9)),
    ]
}

fn tiny(kind: ModelKind, iters: u64) -> (TrainConfig, FieldConfig) {
    let mut cfg = TrainConfig::new(kind);
    cfg.batch = 1024;
    cfg.iters = iters;
    cfg.plane_res_start = 24;
    cfg.plane_res_final = 48;
    cfg.upsample_at = vec![0.3];
    cfg.occupancy_at = vec![0.5];
    let mut fc = FieldConfig::new(kind, boxes()[0], 48);
    fc.density_channels = 8;
    fc.color_channels = 12;
    (cfg, fc)
}

#[test]
fn joint_configs_share_one_grid_and_hold_every_box() {
    let (_, template) = tiny(ModelKind::Standard, 1);
    let configs = joint_configs(&template, &boxes(), 48).unwrap();
    assert_eq!(configs[0].sharing_mismatch(&configs[1]), None);
    let voxel = configs[0].voxel_size();
    for (c, b) in configs.iter().zip(boxes()) {
        let a = c.aabb();
        assert!(a.min.cmple(b.min + 1e-6).all() && a.max.cmpge(b.max - 1e-6).all(), "{a:?} {b:?}");
        let v = c.voxel_size();
        assert!((v - voxel).abs().max_element() < 1e-5 * voxel.x, "{v} vs {voxel}");
    }
    // the longest side (beta's 3.2) gets the 48 texels
    assert_eq!(configs[1].res[0], 48);
    assert_eq!(configs[0].res[2], configs[1].res[2]);
    assert_eq!(configs[0].aabb[0][2], -0.05);
    // at every stage of coarse to fine the vertical axes keep one length
    for stage in [24, 30, 37, 48] {
        let res: Vec<[usize; 3]> = configs
            .iter()
            .map(|c| {
                let rule = GridRule { final_res: Some(c.res), ..GridRule::default() };
                rule.resolution(c, stage, 48)
            })
            .collect();
        assert_eq!(res[0][2], res[1][2], "stage {stage}: {res:?}");
        if stage == 48 {
            assert_eq!(res, vec![configs[0].res, configs[1].res]);
        }
    }
    assert!((configs[0].aabb[1][2] - 0.9).abs() < voxel.z, "{:?}", configs[0].aabb);
    // a box of another vertical range, or another texel, cannot share
    let mut other = configs[1].clone();
    other.aabb[1][2] += 0.3;
    assert!(configs[0].sharing_mismatch(&other).unwrap().key.contains("zmax"));
    let mut other = configs[1].clone();
    other.res[0] += 3;
    assert!(configs[0].sharing_mismatch(&other).unwrap().key.contains("texel"));
    // the VM baseline has no ground planes to keep apart
    let (_, vm) = tiny(ModelKind::Vm, 1);
    assert!(joint_configs(&vm, &boxes(), 48).is_err());
}

fn joint_learns(kind: ModelKind) {
    // past 500 iterations, when the resolution step that waits for them comes
    let (cfg, template) = tiny(kind, 560);
    let configs = joint_configs(&template, &boxes(), 48).unwrap();
    let train = [load("alpha", Split::Train), load("beta", Split::Train)];
    let test = [load("alpha", Split::Test), load("beta", Split::Test)];
    let tc = cfg;
    let scenes = [(&train[0], configs[0].clone()), (&train[1], configs[1].clone())];
    let mut j = JointTrainer::new(&scenes, &tc).unwrap();
    let start: Vec<f32> = j.scenes.iter().zip(&test).map(|(t, d)| psnr(&t.field, d)).collect();
    assert_eq!(first_shared_difference(&j.scenes[0].field, &j.scenes[1].field), None);
    while !j.finished() {
        let s = j.step();
        assert_eq!(s.len(), 2);
        assert_eq!(first_shared_difference(&j.scenes[0].field, &j.scenes[1].field), None);
    }
    for (k, (t, d)) in j.scenes.iter().zip(&test).enumerate() {
        let end = psnr(&t.field, d);
        assert!(end > start[k] + 6.0 && end > 20.0, "{kind:?} scene {k}: {} -> {end}", start[k]);
        assert_eq!(t.field.config.res, configs[k].res, "both reach the final grid");
    }
    // each scene has its own planes
    let p = |t: &Trainer| t.field.params.tensor("density.plane").unwrap().to_vec();
    assert_ne!(p(&j.scenes[0]), p(&j.scenes[1]));
}

#[test]
fn two_s_fields_train_together_with_bit_identical_shared_tensors() {
    joint_learns(ModelKind::Standard);
}

#[test]
fn two_i_fields_train_together_with_bit_identical_shared_tensors() {
    joint_learns(ModelKind::Integrated);
}

#[test]
fn one_scene_trained_jointly_is_the_plain_trainer() {
    let (cfg, template) = tiny(ModelKind::Standard, 40);
    let configs = joint_configs(&template, &boxes()[..1], 48).unwrap();
    let train = load("alpha", Split::Train);
    let mut tc = TrainConfig { upsample_at: vec![0.5], ..cfg };
    let mut j = JointTrainer::new(&[(&train, configs[0].clone())], &tc).unwrap();
    tc.grid.final_res = Some(configs[0].res);
    let mut t = Trainer::new(&train, configs[0].clone(), tc);
    while !t.finished() {
        let a = t.step();
        let b = j.step();
        assert_eq!(a.psnr.to_bits(), b[0].psnr.to_bits(), "iteration {}", a.iter);
    }
    assert!(j.finished());
    assert_eq!(t.field.params.data, j.scenes[0].field.params.data);
}

#[test]
fn a_joint_run_resumes_exactly_from_its_checkpoints() {
    let (cfg, template) = tiny(ModelKind::Standard, 60);
    let configs = joint_configs(&template, &boxes(), 48).unwrap();
    let train = [load("alpha", Split::Train), load("beta", Split::Train)];
    let tc = TrainConfig { upsample_at: vec![0.5], occupancy_at: vec![], ..cfg };
    let scenes = [(&train[0], configs[0].clone()), (&train[1], configs[1].clone())];
    let mut whole = JointTrainer::new(&scenes, &tc).unwrap();
    let mut part = JointTrainer::new(&scenes, &tc).unwrap();
    for _ in 0..25 {
        part.step();
    }
    let dir = root().join("resume");
    std::fs::create_dir_all(&dir).unwrap();
    let paths: Vec<PathBuf> =
        ["a", "b"].iter().map(|n| dir.join(format!("{n}.ckpt.safetensors"))).collect();
    for (t, p) in part.scenes.iter().zip(&paths) {
        t.save_checkpoint(p).unwrap();
    }
    let refs: Vec<&Path> = paths.iter().map(PathBuf::as_path).collect();
    let mut resumed = JointTrainer::resume(&[&train[0], &train[1]], &refs, None, None).unwrap();
    assert_eq!(resumed.iter(), 25);
    while !whole.finished() {
        whole.step();
    }
    while !resumed.finished() {
        resumed.step();
    }
    for (a, b) in whole.scenes.iter().zip(&resumed.scenes) {
        assert_eq!(a.field.params.data, b.field.params.data);
    }
    // checkpoints of different runs are refused, naming the tensor
    let mut other = JointTrainer::new(&scenes, &TrainConfig { seed: 7, ..tc.clone() }).unwrap();
    other.step();
    other.scenes[1].save_checkpoint(&paths[1]).unwrap();
    part.scenes[0].save_checkpoint(&paths[0]).unwrap();
    let e = JointTrainer::resume(&[&train[0], &train[1]], &refs, None, None).unwrap_err();
    assert!(e.to_string().contains("not of one joint run"), "{e}");
}

#[test]
fn a_new_scene_fits_its_planes_against_frozen_shared_tensors() {
    // a trained source: alpha alone
    let (cfg, fc) = tiny(ModelKind::Standard, 200);
    let train_a = load("alpha", Split::Train);
    let mut a = Trainer::new(&train_a, fc, cfg.clone());
    while !a.finished() {
        a.step();
    }
    // beta against alpha's shared tensors
    let (config, rule) = share_config(&a.field.config, boxes()[1]).unwrap();
    assert_eq!(a.field.config.sharing_mismatch(&config), None);
    let train_b = load("beta", Split::Train);
    let test_b = load("beta", Split::Test);
    let tc = TrainConfig { grid: rule, iters: 300, ..cfg };
    let mut b = Trainer::new(&train_b, config.clone(), tc);
    b.field.copy_shared_from(&a.field);
    let start = psnr(&b.field, &test_b);
    while !b.finished() {
        b.step();
    }
    let end = psnr(&b.field, &test_b);
    assert!(end > start + 6.0 && end > 20.0, "{start} -> {end}");
    assert_eq!(b.field.config.res[2], config.res[2]);
    assert_eq!(first_shared_difference(&a.field, &b.field), None);
    // the checkpoint keeps the rule: a resumed run keeps the shared tensors frozen too
    let p = root().join("share.ckpt.safetensors");
    b.save_checkpoint(&p).unwrap();
    let mut again = Trainer::resume(&train_b, &p, Some(320), None).unwrap();
    while !again.finished() {
        again.step();
    }
    assert_eq!(first_shared_difference(&a.field, &again.field), None);
    let f = TensorFile::load(&p).unwrap();
    assert!(f.meta("train").unwrap().contains("frozen_shared\":true"));
}

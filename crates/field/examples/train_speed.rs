//! Quick training-speed probe on a dataset folder (release build):
//! `cargo run --release -p assetfield-field --example train_speed -- runs/conference_room s 30000 300`
//! (dataset, model s|i|vm, scheduled iterations, iterations to run)

use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_field::{FieldConfig, ModelKind, TrainConfig, Trainer};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir =
        std::path::PathBuf::from(args.get(1).map(String::as_str).unwrap_or("runs/conference_room"));
    let kind = match args.get(2).map(String::as_str) {
        Some("i") => ModelKind::Integrated,
        Some("vm") => ModelKind::Vm,
        _ => ModelKind::Standard,
    };
    let iters: u64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(30_000);
    let steps: u64 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(iters);
    let data = Dataset::load(&dir, Split::Train, &LoadOptions::default()).expect("dataset");
    let synth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("synth.json")).expect("synth.json"))
            .unwrap();
    let a = &synth["scene_aabb"];
    let v = |i: usize| {
        glam::Vec3::new(
            a[i][0].as_f64().unwrap() as f32,
            a[i][1].as_f64().unwrap() as f32,
            a[i][2].as_f64().unwrap() as f32,
        )
    };
    let aabb = assetfield_core::Aabb3::new(v(0) - 0.05, v(1) + 0.05);
    let mut cfg = TrainConfig::new(kind);
    cfg.iters = iters;
    cfg.seconds =
        std::env::var("MINUTES").ok().and_then(|m| m.parse::<f64>().ok()).map(|m| m * 60.0);
    let fc = FieldConfig::new(kind, aabb, 300);
    let mut t = Trainer::new(&data, fc, cfg);
    let start = std::time::Instant::now();
    let mut last = std::time::Instant::now();
    while !t.finished() && t.iter < steps {
        let s = t.step();
        if s.iter.is_multiple_of(20) {
            println!(
                "iter {:5}  psnr {:6.2}  samples/ray {:6.1}  {:6.1} ms/iter  res {:?}  occupancy {:?}",
                s.iter,
                s.psnr,
                s.samples as f64 / 4096.0,
                last.elapsed().as_secs_f64() * 1000.0 / 20.0,
                t.field.config.res,
                t.occupancy.as_ref().map(|o| o.fill())
            );
            last = std::time::Instant::now();
        }
    }
    println!("{} iterations in {:.1} s", t.iter, start.elapsed().as_secs_f64());
    if let Ok(test) = Dataset::load(&dir, Split::Test, &LoadOptions::default()) {
        let (mut p, mut s) = (0.0, 0.0);
        let t0 = std::time::Instant::now();
        for f in &test.frames {
            let img = assetfield_field::render_view(
                &t.field,
                t.occupancy.as_ref(),
                &f.camera,
                glam::Vec3::ONE,
            );
            p += assetfield_core::metrics::psnr(&img, &f.image.rgb);
            s += assetfield_core::metrics::ssim(
                &img,
                &f.image.rgb,
                f.image.width as usize,
                f.image.height as usize,
                3,
            );
        }
        let n = test.frames.len() as f32;
        println!(
            "test: PSNR {:.2} dB, SSIM {:.4} over {} views ({:.2} s per view)",
            p / n,
            s / n,
            test.frames.len(),
            t0.elapsed().as_secs_f64() / n as f64
        );
    }
}

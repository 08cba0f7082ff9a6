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
    // synth.json's scene box, else the NeRF-synthetic cube
    let aabb = match std::fs::read_to_string(dir.join("synth.json")) {
        Ok(text) => {
            let synth: serde_json::Value = serde_json::from_str(&text).expect("synth.json");
            let a = &synth["scene_aabb"];
            let v = |i: usize| {
                glam::Vec3::new(
                    a[i][0].as_f64().unwrap() as f32,
                    a[i][1].as_f64().unwrap() as f32,
                    a[i][2].as_f64().unwrap() as f32,
                )
            };
            assetfield_core::Aabb3::new(v(0) - 0.05, v(1) + 0.05)
        }
        Err(_) => assetfield_core::Aabb3::new(glam::Vec3::splat(-1.5), glam::Vec3::splat(1.5)),
    };
    let mut cfg = TrainConfig::new(kind);
    cfg.iters = iters;
    if let Some(e) = std::env::var("EARLY").ok().and_then(|m| m.parse::<u64>().ok()) {
        cfg.occupancy_every_early = e;
    }
    if std::env::var("CLOCK").is_ok_and(|c| c == "cpu") {
        cfg.clock = assetfield_field::Clock::Cpu;
    }
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
                "iter {:5}  psnr {:6.2}  samples/ray {:6.1} colour {:5.1}  {:6.1} ms/iter  res {:?}  occupancy {:?}",
                s.iter,
                s.psnr,
                s.samples as f64 / 4096.0,
                s.color_samples as f64 / 4096.0,
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
        let every = std::env::var("TEST_EVERY").ok().and_then(|m| m.parse().ok()).unwrap_or(1);
        let frames: Vec<_> = test.frames.iter().step_by(every).collect();
        for f in &frames {
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
        let n = frames.len() as f32;
        println!(
            "test: PSNR {:.2} dB, SSIM {:.4} over {} views ({:.2} s per view)",
            p / n,
            s / n,
            frames.len(),
            t0.elapsed().as_secs_f64() / n as f64
        );
    }
}

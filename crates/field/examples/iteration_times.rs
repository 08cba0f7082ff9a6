//! Training iteration times on one fixed state, for builds compared back to back (this file
//! also compiles against older trainers, such as 195016c's, when copied into their tree):
//!
//! `cargo run --release -p assetfield-field --example iteration_times -- DATA STATE [ITERS] [KEY=VALUE ...]`
//!
//! The first run trains 300 iterations of the S model at the final 300-texel plane (the
//! field bench's warm-up), builds an occupancy grid and saves that state to the checkpoint
//! STATE; every later run, of this build or another, resumes it, with this build's default
//! training settings (`KEY=VALUE` overrides one of them, e.g. `density_grad_alpha=0`), and
//! times ITERS iterations (default 12). `GRID=scheduled` keeps the scheduled grids'
//! threshold with the early grids off; by default the first iteration (300, a multiple of
//! the early grids' period) builds the trainer's early grid.
//!
//! Prints every iteration's milliseconds on one line (`TIMES ...`), then samples per ray.
//! The machine's noise comes in bursts: run the builds in turn several times and take, per
//! iteration, the fastest of the runs (`scripts/iteration_times.py`).

use assetfield_core::Aabb3;
use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_field::{FieldConfig, ModelKind, TrainConfig, Trainer};
use std::path::PathBuf;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(dir), Some(state)) = (args.first(), args.get(1)) else {
        eprintln!("usage: iteration_times DATA STATE [ITERS] [KEY=VALUE ...]");
        std::process::exit(2);
    };
    let (dir, state) = (PathBuf::from(dir), PathBuf::from(state));
    let iters: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(12);
    let data = Dataset::load(&dir, Split::Train, &LoadOptions::default()).expect("dataset");
    let kind = ModelKind::Standard;
    let mut t = if state.exists() {
        Trainer::resume(&data, &state, None, None).expect("state")
    } else {
        let mut cfg = TrainConfig::new(kind);
        cfg.iters = 30_000;
        cfg.plane_res_start = 300;
        let aabb = Aabb3::new(glam::Vec3::splat(-1.5), glam::Vec3::splat(1.5));
        let mut t = Trainer::new(&data, FieldConfig::new(kind, aabb, 300), cfg);
        for _ in 0..300 {
            t.step();
        }
        t.rebuild_occupancy();
        t.save_checkpoint(&state).expect("save the state");
        t
    };
    // this build's settings, whichever build saved the state, then the overrides
    let mut settings = serde_json::to_value(TrainConfig::new(kind)).expect("settings");
    for key in ["iters", "plane_res_start"] {
        settings[key] = serde_json::to_value(&t.config).expect("settings")[key].clone();
    }
    for kv in args.iter().skip(3) {
        let (k, v) = kv.split_once('=').expect("KEY=VALUE");
        settings[k] = serde_json::from_str(v).expect("a JSON value");
    }
    t.config = serde_json::from_value(settings).expect("settings");
    if std::env::var("GRID").is_ok_and(|g| g == "scheduled") {
        t.config.occupancy_every_early = 0;
        t.rebuild_occupancy();
    }
    let mut times = Vec::new();
    let mut samples = 0;
    for _ in 0..iters {
        let start = Instant::now();
        samples += t.step().samples;
        times.push(format!("{:.1}", start.elapsed().as_secs_f64() * 1e3));
    }
    println!("TIMES {}", times.join(" "));
    println!("samples per ray {:.1}", samples as f64 / iters as f64 / t.config.batch as f64);
}

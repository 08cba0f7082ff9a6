//! Field training and rendering throughput: one 4096-ray training iteration (forward, backward
//! and Adam) and one full-frame render, on the default scene (synthesised on the fly at
//! 400 x 400) and on the real lego scene when ../shared/data is present.
//!
//! Each field is first trained for a short warm-up at the final plane resolution (300) so that
//! the density has formed; training is then measured with two occupancy grids in turn: the
//! trainer's early grid (a young, hazy field that rays march nearly everywhere, the first
//! few percent of a run) and the scheduled grids' threshold (most of a run). Rendering is
//! measured with the second.
//!
//! Training is reported twice on the same schedule: per ray (4096 per iteration) and per sample
//! (the samples the march evaluates after occupancy skipping, counted over a few iterations
//! before the measurement). Both are wall-clock rates of the whole machine (2 worker
//! threads here): per CPU-second they are half as high.
//!
//! `cargo bench -p assetfield-benches --bench field`

use assetfield_benches::scene;
use assetfield_core::Aabb3;
use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_field::{FieldConfig, ModelKind, TrainConfig, Trainer, render_view};
use assetfield_synth::{SynthOptions, synthesize};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use std::hint::black_box;
use std::path::PathBuf;

const WARMUP_ITERS: u64 = 300;
/// Iterations over which the samples per iteration are counted (after the warm-up).
const SAMPLE_PROBE_ITERS: u64 = 10;

fn default_scene() -> (PathBuf, Aabb3) {
    let dir = std::env::temp_dir().join("assetfield-bench-conference_room");
    if !dir.join("transforms_train.json").exists() {
        synthesize(
            &scene("conference_room"),
            &SynthOptions::default(),
            &dir,
            true,
            None,
            &mut |_, _| {},
        )
        .unwrap();
    }
    let synth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("synth.json")).unwrap()).unwrap();
    let v = |k: usize| {
        Vec3::from(std::array::from_fn::<f32, 3, _>(|a| {
            synth["scene_aabb"][k][a].as_f64().unwrap() as f32
        }))
    };
    (dir, Aabb3::new(v(0) - 0.05, v(1) + 0.05))
}

fn lego() -> Option<(PathBuf, Aabb3)> {
    let dir =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/nerf_synthetic_lego_400");
    dir.is_dir().then(|| (dir, Aabb3::new(Vec3::splat(-1.5), Vec3::splat(1.5))))
}

fn bench_scene(c: &mut Criterion, name: &str, dir: PathBuf, aabb: Aabb3) {
    let train = Dataset::load(&dir, Split::Train, &LoadOptions::default()).unwrap();
    let test = Dataset::load(
        &dir,
        Split::Test,
        &LoadOptions { max_frames: Some(1), ..Default::default() },
    )
    .unwrap();
    // BENCH_MODELS=s (or s,vm, the default) picks the models: their warm-ups are long
    let models = std::env::var("BENCH_MODELS").unwrap_or_else(|_| "s,vm".into());
    let kinds = [ModelKind::Standard, ModelKind::Vm];
    for kind in kinds.into_iter().filter(|k| models.split(',').any(|m| m == k.name())) {
        // final plane resolution, as at the end of a run
        let mut cfg = TrainConfig::new(kind);
        cfg.iters = 30_000;
        cfg.plane_res_start = 300;
        let mut t = Trainer::new(&train, FieldConfig::new(kind, aabb, 300), cfg);
        for _ in 0..WARMUP_ITERS {
            t.step();
        }
        t.rebuild_occupancy();
        // two occupancy grids in turn: the trainer's early grid, which keeps all but clearly
        // emptied space (its first iteration here, a multiple of the early grids' period,
        // builds one: a young, hazy field marched nearly everywhere), then the scheduled
        // grids' TensoRF threshold with the early grids off (where a run spends most of
        // its time)
        for state in ["early grid", "scheduled grid"] {
            if state == "scheduled grid" {
                t.config.occupancy_every_early = 0;
                t.rebuild_occupancy();
            }
            // samples per iteration in this state (the march after occupancy skipping),
            // over a few iterations: the second throughput of the same kernel
            let probe: usize = (0..SAMPLE_PROBE_ITERS).map(|_| t.step().samples).sum();
            let samples = (probe as u64 / SAMPLE_PROBE_ITERS).max(1);
            let mut g = c.benchmark_group(format!("{name} {}, {state}", kind.name()));
            g.sample_size(10);
            g.throughput(Throughput::Elements(4096));
            g.bench_function("train iteration, 4096 rays (elements = rays)", |b| {
                b.iter(|| black_box(t.step()))
            });
            g.throughput(Throughput::Elements(samples));
            let id = format!("train iteration, {samples} samples (elements = samples)");
            g.bench_function(id, |b| b.iter(|| black_box(t.step())));
            g.finish();
        }
        let mut g = c.benchmark_group(format!("{name} {}", kind.name()));
        let cam = test.frames[0].camera;
        let (w, h) = (cam.intrinsics.width as u64, cam.intrinsics.height as u64);
        g.throughput(Throughput::Elements(w * h));
        g.bench_function(format!("render {w}x{h} frame (elements = rays)"), |b| {
            b.iter(|| render_view(black_box(&t.field), t.occupancy.as_ref(), &cam, Vec3::ONE))
        });
        g.finish();
    }
}

fn fields(c: &mut Criterion) {
    let (dir, aabb) = default_scene();
    bench_scene(c, "conference_room", dir, aabb);
    match lego() {
        Some((dir, aabb)) => bench_scene(c, "lego", dir, aabb),
        None => eprintln!("skipping lego: ../shared/data/nerf_synthetic_lego_400 not found"),
    }
}

criterion_group!(benches, fields);
criterion_main!(benches);

//! GPU rendering of a composed scene (issue 6) on whatever wgpu adapter exists (Mesa's
//! lavapipe without a GPU): the synthetic scene of `assetfield_gpu::bench_scene` (a floor and
//! chairs and tables in a 30 x 30 m box, ground planes of 301 x 301 texels, occupancy grid
//! kept on the device):
//! - `render_gpu/frame/RES/N`: one RES x RES frame of a layout of N instances;
//! - `render_gpu/batch/RES/N/B`: B random layouts of N instances, each rasterised (with its
//!   occupancy grid) and rendered at RES x RES in one `render_layouts` call (throughput in
//!   layouts per second).
//!
//! Sizes come from the environment (lavapipe is slow; the defaults take a few minutes with
//! `-- --quick`): `ASSETFIELD_BENCH_RES` (800), `ASSETFIELD_BENCH_INSTANCES` (50),
//! `ASSETFIELD_BENCH_BATCH` (4 layouts), `ASSETFIELD_BENCH_BATCH_RES` (200),
//! `ASSETFIELD_BENCH_SAMPLES` (10, criterion's minimum). Without an adapter it prints
//! `SKIPPED: no wgpu adapter (...)` and measures nothing.
//!
//! `cargo bench -p assetfield-benches --bench render_gpu -- --quick`

use assetfield_gpu::bench_scene::{BenchScene, SplitMix};
use assetfield_gpu::{GpuComposer, GpuContext, GpuError, Layout};
use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use std::time::Duration;

fn env(name: &str, default: usize) -> usize {
    match std::env::var(name) {
        Ok(v) => v.trim().parse().unwrap_or_else(|_| panic!("{name}={v:?} is not a count")),
        Err(_) => default,
    }
}

fn bench(c: &mut Criterion) {
    let ctx = match GpuContext::new() {
        Ok(ctx) => ctx,
        Err(GpuError::NoAdapter(reason)) => {
            println!("SKIPPED: no wgpu adapter ({reason}); render_gpu measured nothing");
            return;
        }
        Err(e) => panic!("render_gpu: {e}"),
    };
    println!("render_gpu: {}", ctx.describe());
    let res = env("ASSETFIELD_BENCH_RES", 800) as u32;
    let n = env("ASSETFIELD_BENCH_INSTANCES", 50);
    let batch = env("ASSETFIELD_BENCH_BATCH", 4);
    let batch_res = env("ASSETFIELD_BENCH_BATCH_RES", 200) as u32;
    let samples = env("ASSETFIELD_BENCH_SAMPLES", 10).max(10);
    let scene = BenchScene::synthetic(1).unwrap();
    let mut rng = SplitMix::new(7);
    let layout = scene.random_layout(n, &mut rng);
    let layouts: Vec<Layout> = (0..batch).map(|_| scene.random_layout(n, &mut rng)).collect();
    let mut gpu = GpuComposer::new(&ctx, &scene.composition, &scene.templates).unwrap();
    let bg = scene.background;

    let mut g = c.benchmark_group("render_gpu");
    g.sample_size(samples)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(5));
    let cam = scene.cameras(1, res);
    gpu.rasterise(&layout, None).unwrap();
    gpu.render(&cam, bg).unwrap(); // compiles the pipelines on lavapipe
    g.throughput(Throughput::Elements(u64::from(res) * u64::from(res)));
    g.bench_function(format!("frame/{res}/{n}"), |b| b.iter(|| gpu.render(&cam, bg).unwrap()));
    if batch > 0 {
        let cams = scene.cameras(1, batch_res);
        g.throughput(Throughput::Elements(batch as u64));
        g.bench_function(format!("batch/{batch_res}/{n}/{batch}"), |b| {
            b.iter(|| gpu.render_layouts(&layouts, &cams, bg).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

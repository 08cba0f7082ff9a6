//! Ground-truth synthesis: layout resolution, BVH construction and ray tracing throughput.
//!
//! `cargo bench -p assetfield-benches --bench synth`

use assetfield_benches::scene;
use assetfield_synth::synth::{SynthConfig, camera_rig};
use assetfield_synth::{Light, Scene, load_scene};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

fn resolve_layouts(c: &mut Criterion) {
    let path = scene("dining_hall");
    let (script, assets, _) = load_scene(&path).unwrap();
    c.bench_function("resolve dining_hall layout (49 instances)", |b| {
        b.iter(|| assetfield_layout::resolve(black_box(&script), &assets).unwrap())
    });
}

fn render_views(c: &mut Criterion) {
    let mut g = c.benchmark_group("ray tracing");
    g.sample_size(10);
    for name in ["conference_room", "warehouse"] {
        let (script, assets, layout) = load_scene(&scene(name)).unwrap();
        let world = Scene::new(&layout, &assets, Light::from_script(script.lighting.as_ref()));
        let cfg = SynthConfig { resolution: 200, ..SynthConfig::DEFAULT };
        let rig = camera_rig(&world.bounds(), &cfg);
        let cam = rig[7].camera;
        let rays = 200 * 200 * (cfg.samples_per_side * cfg.samples_per_side) as u64;
        g.throughput(Throughput::Elements(rays));
        g.bench_function(format!("{name} 200x200 view, 2x2 AA (elements = rays)"), |b| {
            b.iter(|| world.render(black_box(&cam), cfg.samples_per_side))
        });
    }
    g.finish();
    let mut g = c.benchmark_group("scene build");
    for name in ["conference_room", "dining_hall"] {
        let (_, assets, layout) = load_scene(&scene(name)).unwrap();
        g.bench_function(
            format!("{name}: instance BVH over {} instances", layout.instances.len()),
            |b| b.iter(|| Scene::new(black_box(&layout), &assets, Light::default())),
        );
    }
    g.finish();
}

criterion_group!(benches, resolve_layouts, render_views);
criterion_main!(benches);

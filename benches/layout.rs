//! Layout scripts: what loading and resolving costs as scripts grow. N single `Instance`
//! lines (N = 4000, 8000, 16000), alone and with N / 4 `Move` edits of distinct instances,
//! and a `Scatter` of N / 8 instances clear of them. Resolution used to be quadratic in N
//! (16000 lines took 16 s); it should now grow about linearly.
//!
//! `cargo bench -p assetfield-benches --bench layout`.

use assetfield_layout::{PartsCatalog, load_str, resolve};
use criterion::{Criterion, criterion_group, criterion_main};
use std::fmt::Write;
use std::path::Path;

/// A script of `n` instances on a grid 2 apart, `moves` of them moved, and a scatter of `scatter`
/// instances among them.
fn script(n: usize, moves: usize, scatter: usize) -> String {
    let mut s = String::from(
        "Scene(\n    assets: {\n        \"a\": Asset(parts: [Box(center: (0, 0, 0.5), size: (0.5, 0.5, 1), color: (1, 0, 0))]),\n    },\n    layout: [\n",
    );
    for k in 0..n {
        let _ = writeln!(
            s,
            "        Instance(asset: \"a\", at: ({}, {})),",
            2 * (k % 100),
            2 * (k / 100)
        );
    }
    if scatter > 0 {
        let _ = writeln!(
            s,
            "        Scatter(asset: \"a\", region: Rect(min: (0, 0), max: (200, {})), count: {scatter}, min_distance: 0.6, seed: 1),",
            2 * (n / 100)
        );
    }
    s.push_str("    ],\n    edits: [\n");
    for k in 0..moves {
        let _ = writeln!(s, "        Move(target: \"instance{}\", by: (0.1, 0)),", k * 4);
    }
    s.push_str("    ],\n)\n");
    s
}

fn load_and_resolve(text: &str) -> usize {
    let loaded = load_str(Path::new("bench.ron"), text).expect("loads");
    let layout = resolve(&loaded, &PartsCatalog::from_script(&loaded)).expect("resolves");
    layout.instances.len()
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("layout");
    g.sample_size(10);
    for n in [4000usize, 8000, 16000] {
        let plain = script(n, 0, 0);
        g.bench_function(format!("instances/{n}"), |b| b.iter(|| load_and_resolve(&plain)));
        let edited = script(n, n / 4, 0);
        g.bench_function(format!("instances_and_moves/{n}"), |b| {
            b.iter(|| load_and_resolve(&edited))
        });
        let scattered = script(n, 0, n / 8);
        g.bench_function(format!("instances_and_scatter/{n}"), |b| {
            b.iter(|| load_and_resolve(&scattered))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

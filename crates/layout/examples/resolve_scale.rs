//! How load + resolve time grows with a script: N single `Instance` lines (default 4000,
//! 8000 and 16000), alone, with N / 4 `Move` edits of distinct instances, and with a
//! `Scatter` of N / 8 instances clear of them (the criterion bench `layout` of
//! `assetfield-benches` measures the same scripts more carefully).
//!
//! `cargo run --release -p assetfield-layout --example resolve_scale [N...]`

use assetfield_layout::{PartsCatalog, load_str, resolve};
use std::fmt::Write;
use std::path::Path;
use std::time::Instant;

/// A script of `n` instances on a grid 2 apart, `moves` of them moved, and a scatter of
/// `scatter` instances among them.
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

fn main() {
    let ns: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let ns = if ns.is_empty() { vec![4000, 8000, 16000] } else { ns };
    for n in ns {
        for (what, text) in [
            ("instances", script(n, 0, 0)),
            ("+ moves", script(n, n / 4, 0)),
            ("+ scatter", script(n, 0, n / 8)),
        ] {
            let t0 = Instant::now();
            let loaded = load_str(Path::new("scale.ron"), &text).expect("loads");
            let t1 = Instant::now();
            let layout = resolve(&loaded, &PartsCatalog::from_script(&loaded)).expect("resolves");
            let t2 = Instant::now();
            println!(
                "{n:>6} {what:<10} ({:>6} instances): load {:.3} s, resolve {:.3} s, total {:.3} s",
                layout.instances.len(),
                (t1 - t0).as_secs_f64(),
                (t2 - t1).as_secs_f64(),
                (t2 - t0).as_secs_f64()
            );
        }
    }
}

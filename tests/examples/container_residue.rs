//! What a mined library's container leaves where its objects were: per entry, the summed
//! column opacity over the entry's box (`source_box`) against a ring of the container's
//! empty ground around it (between 3 and 6 texels out, away from every other entry), as the
//! editor's `a_removed_instance_leaves_no_trace` test measures one removal.
//!
//!   cargo run --release -p assetfield-tests --example container_residue -- LIB [LIB ...]
//!
//! Prints one line per entry whose footprint holds more than its ring by over 10% (of the
//! ring, or of 0.1 where the ring is nearly empty: residue), and a summary line per library
//! with those and the entries whose footprint holds less (a ring that takes in a wall or a
//! floor's edge). `AF_GAP=TEXELS` moves the ring out (the default 3 lies inside the halo
//! that mining fills round every object, 6 texels for a blur of 3; 7 lies beyond it).
//! `AF_MAP=NAME` draws the column opacity around entry NAME (`.` at or under
//! its ring's, digits tenths over it, `#` double or more).

use assetfield_scene::AssetLibrary;
use glam::Vec2;
use std::path::Path;

/// Texels between an entry's box and its ring, and the ring's width.
const RING_GAP: f32 = 3.0;

fn main() {
    let libs: Vec<String> = std::env::args().skip(1).collect();
    if libs.is_empty() {
        eprintln!("usage: container_residue LIB [LIB ...]");
        std::process::exit(2);
    }
    for lib in libs {
        if let Err(e) = measure(Path::new(&lib)) {
            eprintln!("{lib}: {e}");
            std::process::exit(1);
        }
    }
}

fn measure(dir: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let lib = AssetLibrary::open(dir)?;
    let comp = lib.composition(&lib.default_canvas())?;
    let [cols, rows, _] = comp.field.config.res;
    let opacity = assetfield_tests::column_opacity(&comp.field);
    let g = comp.grid;
    let gap = std::env::var("AF_GAP").ok().and_then(|v| v.parse().ok()).unwrap_or(RING_GAP);
    let margin = gap * g.step.x.max(g.step.y);
    let boxes: Vec<[f32; 4]> = lib.index.entries.iter().map(|e| e.source_box).collect();
    let within = |b: &[f32; 4], p: Vec2, m: f32| {
        p.x >= b[0] - m && p.x <= b[2] + m && p.y >= b[1] - m && p.y <= b[3] + m
    };
    let (mut over, mut under, mut worst, mut n) = (0usize, 0usize, (0f32, String::new()), 0usize);
    for (k, e) in lib.index.entries.iter().enumerate() {
        let b = &boxes[k];
        let (mut inside, mut ring) = (Vec::new(), Vec::new());
        for r in 0..rows {
            for c in 0..cols {
                let p = g.min + Vec2::new(c as f32 * g.step.x, r as f32 * g.step.y);
                let o = opacity[r * cols + c];
                if within(b, p, 0.0) {
                    inside.push(o);
                } else if within(b, p, 2.0 * margin)
                    && !within(b, p, margin)
                    && !boxes.iter().enumerate().any(|(j, ob)| j != k && within(ob, p, margin))
                {
                    ring.push(o);
                }
            }
        }
        if inside.is_empty() || ring.is_empty() {
            continue;
        }
        n += 1;
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        let (a, f) = (mean(&inside), mean(&ring));
        let rel = (a - f) / f.max(0.1);
        under += usize::from(rel < -0.1);
        if rel > 0.1 {
            over += 1;
            println!(
                "{} {}: footprint {a:.3}, ring {f:.3} ({:+.0}%)",
                dir.display(),
                e.name,
                100.0 * (a - f) / f.max(0.1)
            );
        }
        if std::env::var("AF_MAP").ok().as_deref() == Some(e.name.as_str()) {
            let (c0, c1) = (
                ((b[0] - 3.0 * margin - g.min.x) / g.step.x).max(0.0) as usize,
                (((b[2] + 3.0 * margin - g.min.x) / g.step.x) as usize).min(cols - 1),
            );
            let (r0, r1) = (
                ((b[1] - 3.0 * margin - g.min.y) / g.step.y).max(0.0) as usize,
                (((b[3] + 3.0 * margin - g.min.y) / g.step.y) as usize).min(rows - 1),
            );
            for r in (r0..=r1).rev() {
                let line: String = (c0..=c1)
                    .map(|c| {
                        let p = g.min + Vec2::new(c as f32 * g.step.x, r as f32 * g.step.y);
                        let o = opacity[r * cols + c];
                        let d = ((o / f.max(0.1) - 1.0) * 10.0).round() as i32;
                        let ch = if d <= 0 {
                            '.'
                        } else if d < 10 {
                            char::from(b'0' + d as u8)
                        } else {
                            '#'
                        };
                        if within(b, p, 0.0) { ch.to_ascii_uppercase() } else { ch }
                    })
                    .collect();
                println!("|{line}|");
            }
        }
        if rel > worst.0 {
            worst = (rel, e.name.clone());
        }
    }
    println!(
        "{}: {over} of {n} entries' footprints hold more than their ring by over 10% (worst {}, {:+.0}%); {under} hold less",
        dir.display(),
        if worst.1.is_empty() { "none" } else { worst.1.as_str() },
        100.0 * worst.0
    );
    Ok(())
}

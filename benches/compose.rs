//! Scene composer: what an edit costs. A 300 x 300 ground plane (30 x 30 m at 0.1 m texels,
//! 16 density + 48 colour channels, the default field sizes), 1.2 m patches, and 10, 100 or
//! 1000 instances:
//! - `move_one/N`: move one instance and run a frame (redraws its old and new footprint);
//! - `full/N`: redraw the whole plane from scratch;
//! - `relayout/N`: move and turn every instance, then run a frame (a random layout).
//!
//! `cargo bench -p assetfield-benches --bench compose`

use assetfield_core::{Aabb3, GroundTransform};
use assetfield_field::{Field, FieldConfig, ModelKind};
use assetfield_scene::{Composer, Composition, FeaturePatch, TexelRect};
use criterion::{Criterion, criterion_group, criterion_main};
use glam::{Vec2, Vec3};
use std::sync::Arc;

struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn scene(n: usize) -> (Composer, Vec<bevy_ecs::entity::Entity>) {
    let aabb = Aabb3::new(Vec3::new(-15.0, -15.0, 0.0), Vec3::new(15.0, 15.0, 2.0));
    let field = Field::new(FieldConfig::new(ModelKind::Standard, aabb, 301), 1);
    let comp = Composition::new(field).unwrap();
    let grid = comp.grid;
    let spec = |name: &str| comp.field.params.spec(name).unwrap().clone();
    let (d, c) = (spec("density.plane"), spec("color.plane"));
    let data = &comp.field.params.data;
    let rect = TexelRect { r0: 100, c0: 100, r1: 112, c1: 112 };
    let (patch, _) = FeaturePatch::cut(
        "chair",
        &grid,
        &data[d.offset..][..d.len],
        &data[c.offset..][..c.len],
        rect,
        |_, _| 1.0,
    )
    .unwrap();
    let mut composer = Composer::new(comp);
    composer.set_template("chair", "chair", Arc::new(patch)).unwrap();
    let mut rng = Rng(7);
    let ents = (0..n)
        .map(|i| {
            let t = GroundTransform::new(
                Vec2::new(rng.f() * 28.0 - 14.0, rng.f() * 28.0 - 14.0),
                rng.f() * 360.0,
                1.0,
                0.0,
            );
            composer.spawn(&format!("chair[{i}]"), "chair", t).unwrap()
        })
        .collect();
    composer.update();
    (composer, ents)
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("compose");
    g.sample_size(20);
    for n in [10usize, 100, 1000] {
        let (mut composer, ents) = scene(n);
        let mut flip = false;
        g.bench_function(format!("move_one/{n}"), |b| {
            b.iter(|| {
                flip = !flip;
                let x = if flip { 3.0 } else { -3.0 };
                composer
                    .set_placement(ents[0], GroundTransform::new(Vec2::new(x, 2.0), 30.0, 1.0, 0.0))
                    .unwrap();
                composer.update();
            })
        });
        g.bench_function(format!("full/{n}"), |b| b.iter(|| composer.rasterise_everything()));
        let mut rng = Rng(11);
        g.bench_function(format!("relayout/{n}"), |b| {
            b.iter(|| {
                for e in &ents {
                    let t = GroundTransform::new(
                        Vec2::new(rng.f() * 28.0 - 14.0, rng.f() * 28.0 - 14.0),
                        rng.f() * 360.0,
                        1.0,
                        0.0,
                    );
                    composer.set_placement(*e, t).unwrap();
                }
                composer.update();
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

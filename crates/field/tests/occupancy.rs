//! The occupancy grid: built a column at a time, it must equal the point-wise rule (a cell is
//! occupied when one march step's opacity at its centre or any corner exceeds the threshold),
//! for every model; a regional update must equal a full rebuild.

use assetfield_core::{Aabb3, Rect2};
use assetfield_field::{Field, FieldConfig, ModelKind, Occupancy};
use glam::{Vec2, Vec3};

fn field(kind: ModelKind, seed: u64) -> Field {
    let aabb = Aabb3::new(Vec3::new(-1.5, -1.0, 0.0), Vec3::new(1.5, 1.0, 1.2));
    let mut cfg = FieldConfig::new(kind, aabb, 40);
    cfg.density_channels = 12; // 8 lanes and a tail
    let mut f = Field::new(cfg, seed);
    // a density that varies in space: scale the planes so some cells pass the threshold
    for spec in f.params.specs.clone() {
        if spec.name.contains("density") {
            for (k, v) in f.params.data[spec.offset..][..spec.len].iter_mut().enumerate() {
                *v = *v * 40.0 + ((k % 17) as f32 - 8.0) * 0.3;
            }
        }
    }
    f
}

fn naive(f: &Field, res: [usize; 3], threshold: f32) -> Vec<bool> {
    let a = f.config.aabb();
    let cell = a.extent() / Vec3::new(res[0] as f32, res[1] as f32, res[2] as f32);
    let step = f.config.step_size() * f.config.distance_scale;
    let dense = |p: Vec3| 1.0 - (-f.density(p) * step).exp() > threshold;
    let mut out = Vec::new();
    for k in 0..res[2] {
        for j in 0..res[1] {
            for i in 0..res[0] {
                let lo = a.min + Vec3::new(i as f32, j as f32, k as f32) * cell;
                let mut any = dense(lo + cell * 0.5);
                for b in 0..8 {
                    let o = Vec3::new((b & 1) as f32, ((b >> 1) & 1) as f32, (b >> 2) as f32);
                    any |= dense(lo + o * cell);
                }
                out.push(any);
            }
        }
    }
    out
}

#[test]
fn columns_match_the_pointwise_rule_for_every_model() {
    for kind in [ModelKind::Standard, ModelKind::Integrated, ModelKind::Vm] {
        let f = field(kind, 3);
        // density_column is density, bit for bit
        let zs: Vec<f32> = (0..29).map(|k| k as f32 * 0.043).collect();
        let (mut scratch, mut out) = (Vec::new(), vec![0.0; zs.len()]);
        f.density_column(0.37, -0.61, &zs, &mut scratch, &mut out);
        for (z, got) in zs.iter().zip(&out) {
            assert_eq!(got.to_bits(), f.density(Vec3::new(0.37, -0.61, *z)).to_bits(), "{kind:?}");
        }
        let res = [23, 17, 11];
        // VM sums three plane-line pairs: a higher threshold keeps its grid mixed
        let threshold = if kind == ModelKind::Vm { 0.9 } else { 0.01 };
        let occ = Occupancy::from_field(&f, res, threshold);
        let want = naive(&f, res, threshold);
        let got: Vec<bool> = occ.cells_u8().iter().map(|c| *c != 0).collect();
        let differ = got.iter().zip(&want).filter(|(a, b)| a != b).count();
        let occupied = want.iter().filter(|c| **c).count();
        assert!(occupied > 20 && occupied < want.len() - 20, "{kind:?}: a mixed grid ({occupied})");
        // fast_expm1 against libm exp may flip a cell sitting exactly on the threshold
        assert!(differ <= 2, "{kind:?}: {differ} cells differ");
    }
}

#[test]
fn a_regional_update_equals_a_full_rebuild() {
    let before = field(ModelKind::Standard, 5);
    let after = field(ModelKind::Standard, 9);
    let res = [30, 20, 12];
    let mut occ = Occupancy::from_field(&before, res, 0.01);
    // the whole box in two regions
    occ.update_region(&after, Rect2::new(Vec2::new(-1.5, -1.0), Vec2::new(0.1, 1.0)), 0.01);
    occ.update_region(&after, Rect2::new(Vec2::new(0.0, -1.0), Vec2::new(1.5, 1.0)), 0.01);
    let full = Occupancy::from_field(&after, res, 0.01);
    assert_eq!(occ.cells_u8(), full.cells_u8());
    // a small region changes only the columns it touches
    let mut part = Occupancy::from_field(&before, res, 0.01);
    part.update_region(&after, Rect2::new(Vec2::new(-0.2, -0.2), Vec2::new(0.2, 0.2)), 0.01);
    let (p, b, a) =
        (part.cells_u8(), Occupancy::from_field(&before, res, 0.01).cells_u8(), full.cells_u8());
    let mut touched = 0;
    for (k, ((x, y), z)) in p.iter().zip(&b).zip(&a).enumerate() {
        let (i, j) = (k % res[0], (k / res[0]) % res[1]);
        let inside = (13..=17).contains(&i) && (8..=12).contains(&j);
        if inside {
            assert_eq!(x, z, "cell {k} inside the region follows the new field");
            touched += 1;
        } else {
            assert_eq!(x, y, "cell {k} outside the region keeps its value");
        }
    }
    assert!(touched > 0);
}

/// The march leaps over empty cells (and empty bricks of cells) and starts and ends in the occupied cells' box, yet
/// evaluates exactly the lattice points a point-by-point walk finds occupied: on a random
/// grid (a sparse one and one with a single occupied cell), for rays in every direction,
/// axis-parallel ones included, with a density that never stops a ray (no stopping
/// transmittance).
#[test]
fn leaping_over_empty_cells_keeps_every_occupied_sample() {
    use assetfield_core::Ray;
    use assetfield_field::march::forward;
    use assetfield_field::{MarchSettings, MarchWork};
    // the initial field (features near 0) and no shift: every sample's opacity is well
    // inside (0, 1), so every occupied lattice point is kept and no ray stops
    let aabb = Aabb3::new(Vec3::new(-1.5, -1.0, 0.0), Vec3::new(1.5, 1.0, 1.2));
    let mut f = Field::new(FieldConfig::new(ModelKind::Standard, aabb, 40), 5);
    f.config.density_shift = 0.0;
    let res = [13, 9, 7];
    let mut seed = 12345u64;
    let mut next = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 40) as f32 / (1u64 << 24) as f32
    };
    let sparse: Vec<u8> =
        (0..res.iter().product::<usize>()).map(|_| u8::from(next() < 0.15)).collect();
    let mut single = vec![0u8; sparse.len()];
    single[(4 * res[1] + 3) * res[0] + 6] = 1;
    let a = f.config.aabb();
    let step = f.config.step_size();
    let settings = MarchSettings {
        weight_threshold: 1.0,
        stop_transmittance: 0.0,
        max_samples: 4096,
        ..MarchSettings::default()
    };
    let mut rays = Vec::new();
    for _ in 0..300 {
        let o = Vec3::new(next() * 8.0 - 4.0, next() * 8.0 - 4.0, next() * 4.0 - 1.0);
        let t = a.min + a.extent() * Vec3::new(next(), next(), next());
        rays.push(Ray { origin: o, dir: (t - o).normalize() });
    }
    for d in [Vec3::X, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z] {
        for _ in 0..20 {
            let t = a.min + a.extent() * Vec3::new(next(), next(), next());
            rays.push(Ray { origin: t - d * 5.0, dir: d });
        }
    }
    // and a few occupied cells: whole bricks of the bitfield are empty, partly empty or
    // cut by the grid's border (13 x 9 x 7 is no multiple of the 4-cell brick)
    let few: Vec<u8> = (0..sparse.len()).map(|_| u8::from(next() < 0.02)).collect();
    for cells in [sparse, single, few] {
        let occ = Occupancy::from_cells(&f, res, &cells);
        assert_eq!(occ.cells_u8(), cells, "the bitfield keeps every cell");
        let mut w = MarchWork::default();
        let jitter: Vec<f32> = rays.iter().map(|_| next()).collect();
        forward(&f, Some(&occ), &rays, Some(&jitter), Vec3::ONE, &settings, &mut w);
        // the walk point by point over the same lattice
        let mut expected = 0;
        for (ray, j) in rays.iter().zip(&jitter) {
            if let Some((t0, t1)) = a.intersect(ray.origin, ray.dir.recip(), f32::INFINITY) {
                let first = t0 + step * j;
                for k in 0..settings.max_samples {
                    let t = first + k as f32 * step;
                    if t >= t1 {
                        break;
                    }
                    expected += usize::from(occ.occupied(ray.origin + ray.dir * t));
                }
            }
        }
        assert!(expected > 0);
        assert_eq!(w.samples, expected);
    }
}

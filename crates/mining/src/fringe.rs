//! An object's faint fringe: what reaches past the blur of its edge.
//!
//! A footprint is where the first round's evidence passes its threshold. Round every object
//! the evidence then falls to the floor's over the blur of the edge: the first ring of
//! texels outside a footprint holds some density (half the evidence threshold, the share
//! the first round calls "some density") round half the objects found. Thin parts
//! that the field leaves faint do not stop there: a plant's leaves stay under the
//! threshold, the smoothing takes the strokes that pass it off the dense crown, and the
//! object is boxed on its core, a box too small for its leaves. Such a fringe still holds
//! some density on average further out, where an edge's blur no longer reaches.
//!
//! So each object on the ground is given the rings round its footprint (texels by their
//! Euclidean distance from it, one texel wide) on its own side of its neighbours (nearer
//! to it than to any other object, on no object). When every ring out to
//! [`DetectParams::fringe_ring`](crate::detect::DetectParams::fringe_ring) holds some
//! density on average, the object takes the texels of those rings that hold some density,
//! and no more: past the rings it was judged on, leaves and the haze a young field leaves
//! over the floor look alike (haze fanning out from a scene's middle holds some density
//! four rings out round a pine). A halo one texel wide, what haze is made of round a solid
//! object, takes nothing.

use crate::detect::{Detection, Detections};
use crate::image::{Mask, PixelRect};
use crate::planes::PlaneGrid;
use rayon::prelude::*;

/// Plane texels, (row, column).
type Texels = Vec<(usize, usize)>;

/// What [`grow_fringes`] added to one detection.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FringeGrowth {
    /// The detection.
    pub detection: usize,
    /// How many rings round its footprint held some density on average (the run, which
    /// may reach past the rings taken).
    pub rings: usize,
    /// Texels added to its footprint.
    pub texels: usize,
}

/// Squared Euclidean distance from every texel of a `rows x cols` plane to the nearest
/// texel where `site` holds, with that texel's index (`usize::MAX` and infinity with no
/// site). Exact (Felzenszwalb and Huttenlocher's lower envelope of parabolas, by columns
/// then by rows).
pub fn nearest_site(rows: usize, cols: usize, site: &[bool]) -> (Vec<f64>, Vec<usize>) {
    // along each column: the distance in rows to the nearest site of that column, its row
    let mut down = vec![f64::INFINITY; rows * cols];
    let mut down_row = vec![usize::MAX; rows * cols];
    for c in 0..cols {
        let mut last: Option<usize> = None;
        for r in 0..rows {
            if site[r * cols + c] {
                last = Some(r);
            }
            if let Some(l) = last {
                down[r * cols + c] = (r - l) as f64;
                down_row[r * cols + c] = l;
            }
        }
        let mut next: Option<usize> = None;
        for r in (0..rows).rev() {
            if site[r * cols + c] {
                next = Some(r);
            }
            if let Some(n) = next
                && ((n - r) as f64) < down[r * cols + c]
            {
                down[r * cols + c] = (n - r) as f64;
                down_row[r * cols + c] = n;
            }
        }
    }
    // along each row: the lower envelope of the parabolas rooted at every column
    let mut dist = vec![f64::INFINITY; rows * cols];
    let mut index = vec![usize::MAX; rows * cols];
    let mut f = vec![f64::INFINITY; cols];
    let mut hull: Vec<usize> = Vec::with_capacity(cols);
    let mut from: Vec<f64> = Vec::with_capacity(cols);
    for r in 0..rows {
        for c in 0..cols {
            let d = down[r * cols + c];
            f[c] = d * d;
        }
        hull.clear();
        from.clear();
        for q in (0..cols).filter(|&q| f[q].is_finite()) {
            let qf = q as f64;
            loop {
                let Some(&p) = hull.last() else {
                    hull.push(q);
                    from.push(f64::NEG_INFINITY);
                    break;
                };
                let pf = p as f64;
                let s = ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
                if from.last().is_some_and(|&z| s <= z) {
                    hull.pop();
                    from.pop();
                    continue;
                }
                hull.push(q);
                from.push(s);
                break;
            }
        }
        if hull.is_empty() {
            continue;
        }
        let mut k = 0;
        for c in 0..cols {
            let x = c as f64;
            while k + 1 < hull.len() && from[k + 1] < x {
                k += 1;
            }
            let q = hull[k];
            let dx = x - q as f64;
            dist[r * cols + c] = dx * dx + f[q];
            index[r * cols + c] = down_row[r * cols + q] * cols + q;
        }
    }
    (dist, index)
}

/// Grow every detection on the ground by its faint fringe (see the module docs), judged
/// on `det.evidence` against half of `det.threshold`; `gate_ring` is the ring out to which
/// a fringe must hold, and the rings it then takes (0 takes nothing:
/// [`crate::detect::DetectParams::validate`] refuses it). Detections standing on others
/// keep their footprints (their rings lie on their support). Returns what grew, by
/// detection id.
pub fn grow_fringes(det: &mut Detections, gate_ring: usize) -> Vec<FringeGrowth> {
    let (rows, cols) = (det.grid.rows, det.grid.cols);
    if det.evidence.len() != rows * cols || gate_ring == 0 {
        return Vec::new();
    }
    let some = 0.5 * det.threshold;
    let on_ground = |d: &Detection| d.parent.is_none();
    // every texel any detection covers, and which ground detection covers it
    let mut occupied = vec![false; rows * cols];
    let mut owner = vec![usize::MAX; rows * cols];
    for d in &det.detections {
        for (r, c) in footprint_texels(d) {
            occupied[r * cols + c] = true;
            if on_ground(d) {
                owner[r * cols + c] = d.id;
            }
        }
    }
    let sites: Vec<bool> = owner.iter().map(|&o| o != usize::MAX).collect();
    // a free texel's nearest object is the side it lies on, and its distance to that
    // object's footprint is its distance to the nearest site: one transform serves all
    let (dist2, nearest) = nearest_site(rows, cols, &sites);
    // each object's side: the free texels nearer to it than to any other object on the
    // ground, in plane order
    let mut zones: Vec<Vec<usize>> = vec![Vec::new(); det.detections.len()];
    for i in (0..rows * cols).filter(|&i| !occupied[i] && nearest[i] != usize::MAX) {
        zones[owner[nearest[i]]].push(i);
    }
    // per detection that grows: its id, the texels it takes, how many rings held (each
    // judged on the footprints as mined, in parallel; the growth is applied after)
    let grown: Vec<(usize, Texels, usize)> = det
        .detections
        .par_iter()
        .filter(|d| on_ground(d))
        .filter_map(|d| {
            let zone = &zones[d.id];
            // mean evidence per ring (ring k: distance in (k - 1, k])
            let mut sums: Vec<(f64, usize)> = Vec::new();
            for &i in zone {
                let k = dist2[i].sqrt().ceil() as usize;
                if sums.len() < k {
                    sums.resize(k, (0.0, 0));
                }
                sums[k - 1].0 += f64::from(det.evidence[i]);
                sums[k - 1].1 += 1;
            }
            let rings =
                sums.iter().take_while(|&&(s, n)| n > 0 && s / n as f64 >= f64::from(some)).count();
            if rings < gate_ring {
                return None;
            }
            // the rings judged, not the rest of the run: past them leaves and haze look alike
            let reach = (gate_ring * gate_ring) as f64;
            let added: Texels = zone
                .iter()
                .copied()
                .filter(|&i| dist2[i] <= reach && det.evidence[i] >= some)
                .map(|i| (i / cols, i % cols))
                .collect();
            (!added.is_empty()).then_some((d.id, added, rings))
        })
        .collect();
    let mut out = Vec::with_capacity(grown.len());
    for (id, added, rings) in grown {
        let d = &mut det.detections[id];
        let texels = added.len();
        take_texels(d, &added, &det.grid);
        tracing::debug!(detection = id, rings, texels, "faint fringe taken");
        out.push(FringeGrowth { detection: id, rings, texels });
    }
    out
}

/// The plane texels (row, column) of `d`'s footprint.
fn footprint_texels(d: &Detection) -> impl Iterator<Item = (usize, usize)> + '_ {
    let m = &d.footprint;
    (0..m.rows).flat_map(move |r| {
        (0..m.cols).filter(move |&c| m.get(r, c)).map(move |c| (d.rect.r0 + r, d.rect.c0 + c))
    })
}

/// `d` with the plane texels `added` in its footprint and its own texels, its box, world
/// box and area grown to hold them.
fn take_texels(d: &mut Detection, added: &[(usize, usize)], grid: &PlaneGrid) {
    let Some(reach) = PixelRect::of_texels(added.iter().copied()) else { return };
    let rect = d.rect.union(&reach);
    // the footprint and own texels as they were, moved onto the grown box, plus `added`
    let grown = |m: &Mask| {
        let mut g = Mask::from_fn(rect.rows(), rect.cols(), |_, _| false);
        g.paste_at(m, d.rect.r0 - rect.r0, d.rect.c0 - rect.c0);
        for &(r, c) in added {
            g.set(r - rect.r0, c - rect.c0, true);
        }
        g
    };
    let (footprint, own) = (grown(&d.footprint), grown(&d.own));
    d.area = footprint.count() as f32 * grid.texel_area();
    d.rect = rect;
    d.footprint = footprint;
    d.own = own;
    d.world = grid.rect_to_world(rect);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::scene;

    fn square(n: usize, r0: usize, c0: usize, side: usize) -> Mask {
        crate::test_support::rect_mask(n, n, r0, c0, r0 + side, c0 + side)
    }

    /// A brute-force nearest site for the exact transform to match.
    fn brute(rows: usize, cols: usize, site: &[bool]) -> Vec<f64> {
        (0..rows * cols)
            .map(|i| {
                let (r, c) = ((i / cols) as f64, (i % cols) as f64);
                (0..rows * cols)
                    .filter(|&j| site[j])
                    .map(|j| {
                        let (sr, sc) = ((j / cols) as f64, (j % cols) as f64);
                        (r - sr).powi(2) + (c - sc).powi(2)
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    #[test]
    fn the_distance_transform_is_exact() {
        let (rows, cols) = (13, 17);
        let mut s = 12345u64;
        let site: Vec<bool> = (0..rows * cols)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (s >> 33).is_multiple_of(23)
            })
            .collect();
        let (d, idx) = nearest_site(rows, cols, &site);
        assert_eq!(d, brute(rows, cols, &site));
        for i in 0..rows * cols {
            let j = idx[i];
            assert!(site[j]);
            let dr = (i / cols) as f64 - (j / cols) as f64;
            let dc = (i % cols) as f64 - (j % cols) as f64;
            assert_eq!(dr * dr + dc * dc, d[i]);
        }
        let (none, idx) = nearest_site(3, 4, &[false; 12]);
        assert!(none.iter().all(|d| d.is_infinite()) && idx.iter().all(|&i| i == usize::MAX));
    }

    /// A 6 x 6 crown at (17, 17) (evidence 1, the threshold 0.5) in strokes of faint
    /// evidence (0.4: over half the threshold) out to `reach` texels past each side, two
    /// texels of three (on a diagonal of gaps), the rest 0.
    fn plant(n: usize, reach: usize) -> (Mask, Vec<f32>) {
        let crown = square(n, 17, 17, 6);
        let leaves = square(n, 17 - reach, 17 - reach, 6 + 2 * reach);
        let ev = (0..n * n)
            .map(|i| {
                let (r, c) = (i / n, i % n);
                if crown.get(r, c) {
                    1.0
                } else if leaves.get(r, c) && (r + c) % 3 != 0 {
                    0.4
                } else {
                    0.0
                }
            })
            .collect();
        (crown, ev)
    }

    #[test]
    fn a_fringe_past_the_edge_is_taken_out_to_the_rings_judged() {
        let n = 40;
        let (crown, ev) = plant(n, 6);
        let mut det = scene(std::slice::from_ref(&crown));
        det.evidence = ev.clone();
        let grew = grow_fringes(&mut det, 2);
        assert_eq!(grew.len(), 1, "{grew:?}");
        // the strokes hold some density 6 rings out, and the two rings judged are taken
        assert!(grew[0].rings >= 6, "{grew:?}");
        let d = &det.detections[0];
        assert_eq!(d.rect, PixelRect::new(15, 15, 25, 25));
        // every faint texel within two texels of the crown, and nothing further out
        let (dist2, _) =
            nearest_site(n, n, &(0..n * n).map(|i| crown.get(i / n, i % n)).collect::<Vec<_>>());
        let expected = (0..n * n)
            .filter(|&i| dist2[i] > 0.0 && dist2[i] <= 4.0 && ev[i] >= 0.5 * det.threshold)
            .count();
        assert_eq!(grew[0].texels, expected);
        assert_eq!(d.footprint.count(), 36 + grew[0].texels);
        assert_eq!(d.own.count(), d.footprint.count());
        assert_eq!(d.world, det.grid.rect_to_world(d.rect));
    }

    #[test]
    fn a_halo_one_texel_wide_takes_nothing() {
        let n = 40;
        let crown = square(n, 17, 17, 6);
        let ring1 = square(n, 16, 16, 8);
        let ev: Vec<f32> = (0..n * n)
            .map(|i| {
                let (r, c) = (i / n, i % n);
                if crown.get(r, c) {
                    1.0
                } else if ring1.get(r, c) {
                    0.4
                } else {
                    0.05
                }
            })
            .collect();
        let mut det = scene(std::slice::from_ref(&crown));
        det.evidence = ev;
        let before = det.detections[0].clone();
        assert!(grow_fringes(&mut det, 2).is_empty());
        assert_eq!(det.detections[0], before);
        // with the gate at the first ring, the halo is taken
        assert_eq!(grow_fringes(&mut det, 1).len(), 1);
        assert_eq!(det.detections[0].rect, PixelRect::new(16, 16, 24, 24));
    }

    #[test]
    fn a_fringe_stops_where_a_neighbour_is_nearer() {
        let n = 40;
        let (crown, mut ev) = plant(n, 6);
        // a neighbour 2 texels right of the crown, on faint evidence all round
        let other = square(n, 17, 25, 6);
        for r in 10..30 {
            for c in 23..25 {
                ev[r * n + c] = 0.4;
            }
        }
        for r in 0..n {
            for c in 0..n {
                if other.get(r, c) {
                    ev[r * n + c] = 1.0;
                }
            }
        }
        let mut det = scene(&[crown, other]);
        det.evidence = ev;
        grow_fringes(&mut det, 2);
        let (a, b) = (&det.detections[0], &det.detections[1]);
        // the plant takes its leaves, and of the gap's texels only the one nearer to it than
        // to its neighbour (column 23; column 24 is nearer to the neighbour)
        assert!(a.rect.r0 == 15 && a.rect.c0 == 15, "{:?}", a.rect);
        assert!(a.rect.c1 == 24 && b.rect.c0 >= 24, "{:?} {:?}", a.rect, b.rect);
        for (r, c) in footprint_texels(a) {
            assert!(!footprint_texels(b).any(|t| t == (r, c)));
        }
    }

    #[test]
    fn an_object_standing_on_another_keeps_its_footprint() {
        let n = 40;
        let (crown, ev) = plant(n, 6);
        let table = square(n, 12, 12, 16);
        let mut det = scene(&[table, crown]);
        det.evidence = ev;
        det.detections[1].parent = Some(0);
        det.detections[0].children = vec![1];
        let before = det.detections[1].clone();
        let grew = grow_fringes(&mut det, 2);
        assert!(grew.iter().all(|g| g.detection != 1));
        assert_eq!(det.detections[1], before);
    }
}

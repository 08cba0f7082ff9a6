//! A bounding volume hierarchy over boxes, stored as a flat array of nodes. Used twice:
//! over the primitives of each asset, and over the instances of a scene.

use assetfield_core::Aabb3;
use glam::Vec3;

#[derive(Debug, Clone, Copy)]
struct Node {
    bounds: Aabb3,
    /// Interior: index of the left child (right = left + 1). Leaf: first item in `order`.
    first: u32,
    /// 0 for interior nodes, else the number of items in the leaf.
    count: u32,
}

/// A BVH over items identified by their index in the slice given to [`Bvh::build`].
#[derive(Debug, Clone, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
}

const LEAF_SIZE: usize = 4;
const BINS: usize = 12;

impl Bvh {
    /// Build with a binned surface-area heuristic.
    pub fn build(boxes: &[Aabb3]) -> Self {
        let mut bvh = Bvh {
            nodes: Vec::with_capacity(2 * boxes.len().max(1)),
            order: (0..boxes.len() as u32).collect(),
        };
        if boxes.is_empty() {
            return bvh;
        }
        let centroids: Vec<Vec3> = boxes.iter().map(Aabb3::center).collect();
        bvh.nodes.push(Node { bounds: Aabb3::EMPTY, first: 0, count: boxes.len() as u32 });
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            let (first, count) = (bvh.nodes[n].first as usize, bvh.nodes[n].count as usize);
            let items = &mut bvh.order[first..first + count];
            let bounds = items.iter().fold(Aabb3::EMPTY, |b, &i| b.union(&boxes[i as usize]));
            bvh.nodes[n].bounds = bounds;
            if count <= LEAF_SIZE {
                continue;
            }
            let cb = items.iter().fold(Aabb3::EMPTY, |mut b, &i| {
                b.grow(centroids[i as usize]);
                b
            });
            let Some((axis, split)) = best_split(items, boxes, &centroids, &cb) else {
                continue;
            };
            // partition items by the chosen plane
            let mut mid = 0;
            for k in 0..items.len() {
                if centroids[items[k] as usize][axis] < split {
                    items.swap(k, mid);
                    mid += 1;
                }
            }
            if mid == 0 || mid == count {
                mid = count / 2;
                items.sort_by(|a, b| {
                    centroids[*a as usize][axis].total_cmp(&centroids[*b as usize][axis])
                });
            }
            let left = bvh.nodes.len();
            bvh.nodes.push(Node { bounds: Aabb3::EMPTY, first: first as u32, count: mid as u32 });
            bvh.nodes.push(Node {
                bounds: Aabb3::EMPTY,
                first: (first + mid) as u32,
                count: (count - mid) as u32,
            });
            bvh.nodes[n].first = left as u32;
            bvh.nodes[n].count = 0;
            stack.push(left);
            stack.push(left + 1);
        }
        bvh
    }

    pub fn bounds(&self) -> Aabb3 {
        self.nodes.first().map(|n| n.bounds).unwrap_or(Aabb3::EMPTY)
    }

    /// Visit the items whose boxes the ray may hit, nearest subtree first. `hit(item, t_max)`
    /// returns the hit distance if the item is hit closer than `t_max`; the search shrinks
    /// to it. Returns the nearest hit `(t, item)`.
    #[inline]
    pub fn traverse(
        &self,
        origin: Vec3,
        dir: Vec3,
        mut t_max: f32,
        mut hit: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(f32, u32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = dir.recip();
        let mut best = None;
        let mut stack = [0u32; 64];
        let mut sp = 0;
        self.nodes[0].bounds.intersect(origin, inv, t_max)?;
        stack[sp] = 0;
        sp += 1;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if node.count > 0 {
                for &item in &self.order[node.first as usize..(node.first + node.count) as usize] {
                    if let Some(t) = hit(item, t_max)
                        && t < t_max
                    {
                        t_max = t;
                        best = Some((t, item));
                    }
                }
                continue;
            }
            let (l, r) = (node.first, node.first + 1);
            let tl = self.nodes[l as usize].bounds.intersect(origin, inv, t_max).map(|x| x.0);
            let tr = self.nodes[r as usize].bounds.intersect(origin, inv, t_max).map(|x| x.0);
            match (tl, tr) {
                (Some(a), Some(b)) => {
                    let (near, far) = if a <= b { (l, r) } else { (r, l) };
                    stack[sp] = far;
                    stack[sp + 1] = near;
                    sp += 2;
                }
                (Some(_), None) => {
                    stack[sp] = l;
                    sp += 1;
                }
                (None, Some(_)) => {
                    stack[sp] = r;
                    sp += 1;
                }
                (None, None) => {}
            }
        }
        best
    }
}

fn half_area(b: &Aabb3) -> f32 {
    if b.is_empty() {
        return 0.0;
    }
    let e = b.extent();
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// The (axis, plane) with the lowest SAH cost over binned candidates.
fn best_split(
    items: &[u32],
    boxes: &[Aabb3],
    centroids: &[Vec3],
    cb: &Aabb3,
) -> Option<(usize, f32)> {
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in 0..3 {
        let (lo, hi) = (cb.min[axis], cb.max[axis]);
        if hi - lo < 1e-9 {
            continue;
        }
        let mut bins = [(Aabb3::EMPTY, 0usize); BINS];
        let scale = BINS as f32 / (hi - lo);
        for &i in items {
            let b = (((centroids[i as usize][axis] - lo) * scale) as usize).min(BINS - 1);
            bins[b].0 = bins[b].0.union(&boxes[i as usize]);
            bins[b].1 += 1;
        }
        for s in 1..BINS {
            let (mut lb, mut ln, mut rb, mut rn) = (Aabb3::EMPTY, 0, Aabb3::EMPTY, 0);
            for b in &bins[..s] {
                lb = lb.union(&b.0);
                ln += b.1;
            }
            for b in &bins[s..] {
                rb = rb.union(&b.0);
                rn += b.1;
            }
            if ln == 0 || rn == 0 {
                continue;
            }
            let cost = half_area(&lb) * ln as f32 + half_area(&rb) * rn as f32;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, lo + s as f32 / scale));
            }
        }
    }
    best.map(|(_, a, s)| (a, s))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_nearest_of_many_boxes() {
        // a line of unit boxes along x; a ray from the left must hit box 0 first
        let boxes: Vec<Aabb3> = (0..100)
            .map(|i| {
                Aabb3::new(
                    Vec3::new(i as f32 * 2.0, 0.0, 0.0),
                    Vec3::new(i as f32 * 2.0 + 1.0, 1.0, 1.0),
                )
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        let o = Vec3::new(-5.0, 0.5, 0.5);
        let hit = bvh.traverse(o, Vec3::X, f32::INFINITY, |i, tmax| {
            boxes[i as usize].intersect(o, Vec3::X.recip(), tmax).map(|x| x.0)
        });
        assert_eq!(hit.map(|h| h.1), Some(0));
        // a ray from the right hits the last box
        let o2 = Vec3::new(500.0, 0.5, 0.5);
        let d = -Vec3::X;
        let hit = bvh.traverse(o2, d, f32::INFINITY, |i, tmax| {
            boxes[i as usize].intersect(o2, d.recip(), tmax).map(|x| x.0)
        });
        assert_eq!(hit.map(|h| h.1), Some(99));
        // and a ray that passes above everything hits nothing
        let o3 = Vec3::new(-5.0, 0.5, 3.0);
        assert!(bvh.traverse(o3, Vec3::X, f32::INFINITY, |_, _| Some(0.0)).is_none());
    }

    #[test]
    fn brute_force_agrees_on_random_boxes() {
        let mut s = 12345u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let boxes: Vec<Aabb3> = (0..300)
            .map(|_| {
                let c = Vec3::new(rnd(), rnd(), rnd()) * 10.0;
                let e = Vec3::new(rnd(), rnd(), rnd()) * 0.5 + 0.05;
                Aabb3::new(c - e, c + e)
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        for _ in 0..200 {
            let o = Vec3::new(rnd(), rnd(), rnd()) * 14.0 - 2.0;
            let d = (Vec3::new(rnd(), rnd(), rnd()) - 0.5).normalize();
            let t =
                |i: u32, tmax: f32| boxes[i as usize].intersect(o, d.recip(), tmax).map(|x| x.0);
            let brute = (0..boxes.len() as u32)
                .filter_map(|i| t(i, f32::INFINITY).map(|tt| (tt, i)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let fast = bvh.traverse(o, d, f32::INFINITY, t);
            assert_eq!(brute.map(|b| b.0), fast.map(|f| f.0));
        }
    }
}

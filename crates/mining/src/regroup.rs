//! Grouping the entries of a cross-scene library again, together (paper Sec. 3.4, Fig. 8):
//! after `library merge`, each scene's entries keep the categories their own scene gave
//! them; [`regroup`] describes all of them at once with the grouping every scene's mining
//! uses (label histograms of the colour-plane features at each object's own texels, their
//! Jensen-Shannon divergence plus the shape and vertical-profile terms) and unites
//! categories **across scenes** by average linkage below the separation cut
//! ([`unite_across_sources`]), so that one category spans scenes; then it picks each
//! category's template (the medoid) and poses every member relative to it (yaw search on the
//! density patches). It needs entries described in one feature space: libraries whose
//! shared tensors are identical (scenes trained together, or fitted with `train --share`).
//!
//! A scene's own categories are kept as they are (two categories of one scene never become
//! one, and no category is split): its mining decided them with evidence a library no
//! longer holds (the scene's opacity threshold and detections), and clustering every entry
//! anew from its patch alone split categories that each scene had right (measured on the
//! validation pair of the README: per-scene ARI 1.000 fell to 0.885).

use std::collections::BTreeSet;

use crate::agglomerative::{DistanceMatrix, Merge};
use crate::copies::blurred;
use crate::error::{MiningError, Result, check_interrupt};
use crate::group::{GroupOptions, Grouping, Samples, Shape, group_samples_with};
use crate::image::{Mask, PlaneImage};
use crate::medoid::medoid;
use crate::planes::OpacityVolume;
use crate::yaw::{YawOptions, estimate_yaw_weighted};
use assetfield_field::Field;
use assetfield_library::{Category, Entry, EntryKind, Library, field_with_shared};
use glam::Vec2;
use rayon::prelude::*;

/// Opacity above which a voxel counts as occupied in an entry's vertical profile: a
/// library keeps no scene's own threshold, so the scale-free middle of the opacity range
/// (more likely opaque than not) stands for all of them.
pub const PROFILE_VOXEL_THRESHOLD: f32 = 0.5; // fixed: the middle

/// Smallest sample weight (opacity) of an own texel, so that a faint texel still counts.
const MIN_SAMPLE_WEIGHT: f32 = 1e-3; // fixed: a weight floor (every texel counts)

/// What [`regroup`] measured and decided.
#[derive(Debug, Clone)]
pub struct Regrouped {
    pub categories: Vec<Category>,
    /// The entries with their new categories, kinds, yaws, positions and residuals.
    pub entries: Vec<Entry>,
    /// The grouping (its `category` is every entry's index into `categories`).
    pub grouping: Grouping,
}

/// An entry's own patch as a small field over its texels with the library's shared
/// tensors (its density plane the entry's), to read its opacity columns.
fn entry_field(lib: &Library, e: &Entry, density: &[f32]) -> Result<Field> {
    let (h, w) = e.patch_size;
    let t = Vec2::new(lib.index.texel_size.0, lib.index.texel_size.1);
    let min = e.box_centre() - Vec2::new((w - 1) as f32, (h - 1) as f32) * t * 0.5;
    // a patch of one texel still needs two nodes per axis
    let (cols, rows) = (w.max(2), h.max(2));
    let mut f = field_with_shared(lib.config.on_ground_window(min, cols, rows, t), &lib.shared)?;
    let spec = f.params.spec("density.plane").cloned().ok_or(MiningError::MissingTensor {
        source_name: "shared field".into(),
        name: "density.plane".into(),
        purpose: "an entry's opacity".into(),
    })?;
    let nd = lib.index.channels.0;
    let plane = &mut f.params.data[spec.offset..spec.offset + spec.len];
    for r in 0..rows {
        for c in 0..cols {
            let src = (r.min(h - 1) * w + c.min(w - 1)) * nd;
            plane[(r * cols + c) * nd..][..nd].copy_from_slice(&density[src..src + nd]);
        }
    }
    Ok(f)
}

/// Per entry: its samples (colour features at its own texels, weighted by the column's
/// opacity), its shape and its vertical profile from its base up.
struct Described {
    colour: Vec<f32>,
    weights: Vec<f32>,
    shape: Shape,
    profile: Vec<f64>,
}

fn describe(lib: &Library, e: &Entry, blur: usize) -> Result<Described> {
    let (h, w) = e.patch_size;
    let (nd, nc) = lib.index.channels;
    let d = lib.patches.get_f32(&e.density, &[h, w, nd])?;
    let c = lib.patches.get_f32(&e.color, &[h, w, nc])?;
    let m = lib.patches.get_u8(&e.mask, &[h, w])?;
    let mask = Mask::from_fn(h, w, |r, col| m[r * w + col] != 0);
    let field = entry_field(lib, e, d)?;
    let vol = OpacityVolume::from_field(&field)?;
    let base = (((e.base - vol.z0) / vol.dz).round().max(0.0) as usize).min(vol.nz);
    let mut profile = vec![0f64; vol.nz];
    let (mut colour, mut weights) = (Vec::new(), Vec::new());
    for r in 0..h {
        for col in 0..w {
            if !mask.get(r, col) {
                continue;
            }
            let column = vol.column(r, col);
            for (k, v) in column[base..].iter().enumerate() {
                if *v > PROFILE_VOXEL_THRESHOLD {
                    profile[k] += 1.0;
                }
            }
            let opacity = column.iter().copied().fold(0.0f32, f32::max);
            weights.push(opacity.max(MIN_SAMPLE_WEIGHT));
            colour.extend_from_slice(&c[(r * w + col) * nc..][..nc]);
        }
    }
    let t = lib.index.texel_size;
    Ok(Described {
        colour,
        weights,
        shape: Shape::of_footprint(&mask, [t.0, t.1], e.extent.2),
        // normalised by the blur
        profile: blurred(&profile, blur),
    })
}

/// Group every entry of `lib` (a merged library) again, together, with `opts` (the
/// grouping, vertical blur and yaw search of `assetfield mine`), then choose templates and
/// pose the members. Entries are renamed nowhere; categories become `cat000`, `cat001`,
/// ... in order of first appearance.
pub fn regroup(lib: &Library, opts: &RegroupOptions) -> Result<Regrouped> {
    let entries = &lib.index.entries;
    let n = entries.len();
    if n == 0 {
        return Err(MiningError::InvalidParameter {
            name: "library",
            reason: "the library has no entries to group".into(),
        });
    }
    let described: Vec<Described> =
        entries.par_iter().map(|e| describe(lib, e, opts.blur_levels)).collect::<Result<_>>()?;
    check_interrupt()?;
    let nc = lib.index.channels.1;
    let mut samples = Samples { dim: nc, ..Default::default() };
    for (i, d) in described.iter().enumerate() {
        samples.points.extend_from_slice(&d.colour);
        samples.weights.extend_from_slice(&d.weights);
        samples.owner.extend(std::iter::repeat_n(i as u32, d.weights.len()));
    }
    if let Some(i) = described.iter().position(|d| d.weights.is_empty()) {
        return Err(MiningError::InvalidParameter {
            name: "library",
            reason: format!(
                "entry {:?} has an empty mask: nothing to group it by",
                entries[i].name
            ),
        });
    }
    let shapes: Vec<Shape> = described.iter().map(|d| d.shape).collect();
    let profiles: Vec<Vec<f64>> = described.into_iter().map(|d| d.profile).collect();
    let mut gopts = opts.group.clone();
    gopts.labels = gopts.labels.min(samples.len());
    let mut grouping = group_samples_with(&samples, n, &shapes, &profiles, &gopts)?;
    check_interrupt()?;
    let (category, merges) =
        unite_across_sources(entries, &grouping.distance, gopts.min_separation)?;
    let k = category.iter().max().map_or(0, |&m| m + 1);
    grouping.cut = format!(
        "each scene's categories kept, {} united across scenes below {}: {k} categories",
        merges.len(),
        gopts.min_separation
    );
    (grouping.category, grouping.n_categories, grouping.merges) = (category, k, merges);
    let poses = pose_members(lib, &grouping.category, &grouping.distance, &opts.yaw)?;
    let texel = Vec2::new(lib.index.texel_size.0, lib.index.texel_size.1);
    let mut out = entries.clone();
    let k = grouping.n_categories;
    let mut categories: Vec<Category> = (0..k)
        .map(|c| Category {
            name: format!("cat{c:03}"),
            template: entries[poses.templates[c]].name.clone(),
            members: Vec::new(),
        })
        .collect();
    for (i, e) in out.iter_mut().enumerate() {
        let c = grouping.category[i];
        let t = poses.templates[c];
        categories[c].members.push(e.name.clone());
        e.category = categories[c].name.clone();
        e.kind = if t == i { EntryKind::Template } else { EntryKind::Instance };
        let (yaw_deg, offset, residual) = poses.fits[i];
        e.yaw_deg = yaw_deg;
        e.residual = residual;
        e.matched_on = Some("density".into());
        // where the template's pivot lands on this entry
        let centre = entries[i].box_centre() + Vec2::from(offset) * texel;
        let p = centre + Vec2::from_angle(yaw_deg.to_radians()).rotate(entries[t].pivot_offset());
        e.position = (p.x, p.y);
    }
    Ok(Regrouped { categories, entries: out, grouping })
}

/// Start from the library's categories (entries with the same category name) and merge, by
/// average linkage over `distance` (entry by entry), the closest pair of groups that share
/// no source scene while their linkage is below `threshold` (the separation cut of
/// `mine`); groups that share a scene stay apart. Returns every entry's group (`0..k`, in
/// order of first appearance) and the merges made (ids as in [`Merge`]: `0..g` the
/// starting groups, merge `t` makes group `g + t`).
pub fn unite_across_sources(
    entries: &[Entry],
    distance: &DistanceMatrix,
    threshold: f64,
) -> Result<(Vec<usize>, Vec<Merge>)> {
    let n = entries.len();
    if distance.n() != n {
        return Err(MiningError::SizeMismatch {
            what: "distance matrix vs entries",
            left: distance.n(),
            right: n,
        });
    }
    struct Group<'a> {
        name: &'a str,
        /// Merge id (see [`Merge`]).
        id: usize,
        members: Vec<usize>,
        sources: BTreeSet<usize>,
    }
    // the starting groups: one per category name, in order of first appearance
    let mut groups: Vec<Group> = Vec::new();
    for (i, e) in entries.iter().enumerate() {
        match groups.iter_mut().find(|g| g.name == e.category) {
            Some(g) => {
                g.members.push(i);
                g.sources.insert(e.source);
            }
            None => groups.push(Group {
                name: &e.category,
                id: groups.len(),
                members: vec![i],
                sources: BTreeSet::from([e.source]),
            }),
        }
    }
    let starting = groups.len();
    // sum of the entry distances between every two groups (a merge adds one group's row and
    // column to the other's); the average linkage is the sum over the product of the sizes
    let mut sum: Vec<Vec<f64>> = groups
        .iter()
        .map(|a| {
            groups
                .iter()
                .map(|b| {
                    a.members
                        .iter()
                        .flat_map(|&i| b.members.iter().map(move |&j| (i, j)))
                        .map(|(i, j)| distance.get(i, j).unwrap_or(f64::INFINITY))
                        .sum()
                })
                .collect()
        })
        .collect();
    let linkage = |groups: &[Group], sum: &[Vec<f64>], a: usize, b: usize| {
        sum[a][b] / (groups[a].members.len() * groups[b].members.len()) as f64
    };
    // the pairs that may unite (no scene in common), nearest first
    let candidates = |groups: &[Group], sum: &[Vec<f64>]| {
        let mut pairs: Vec<(usize, usize, f64)> = (0..groups.len())
            .flat_map(|a| (a + 1..groups.len()).map(move |b| (a, b)))
            .filter(|&(a, b)| groups[a].sources.is_disjoint(&groups[b].sources))
            .map(|(a, b)| (a, b, linkage(groups, sum, a, b)))
            .collect();
        pairs.sort_by(|x, y| x.2.total_cmp(&y.2));
        pairs
    };
    let pairs = candidates(&groups, &sum);
    for (a, g) in groups.iter().enumerate() {
        if let Some(&(x, y, d)) = pairs.iter().find(|&&(x, y, _)| x == a || y == a) {
            let other = groups[if x == a { y } else { x }].name;
            tracing::debug!(
                category = g.name,
                nearest = other,
                linkage = d,
                threshold,
                "nearest category of another scene"
            );
        }
    }
    let mut merges = Vec::new();
    while let Some(&(a, b, d)) = candidates(&groups, &sum).first().filter(|p| p.2 < threshold) {
        // b (> a) joins a: its column and row add to a's, then go
        for row in sum.iter_mut() {
            row[a] += row[b];
        }
        let row_b = sum.remove(b);
        for (v, vb) in sum[a].iter_mut().zip(&row_b) {
            *v += vb;
        }
        for row in sum.iter_mut() {
            row.remove(b);
        }
        let gb = groups.remove(b);
        let ga = &mut groups[a];
        merges.push(Merge {
            a: ga.id.min(gb.id),
            b: ga.id.max(gb.id),
            distance: d,
            size: ga.members.len() + gb.members.len(),
        });
        ga.id = starting + merges.len() - 1;
        ga.members.extend(gb.members);
        ga.sources.extend(gb.sources);
    }
    // groups keep the order of their first member, so their index is the category
    let mut category = vec![0usize; n];
    for (k, g) in groups.iter().enumerate() {
        for &i in &g.members {
            category[i] = k;
        }
    }
    Ok((category, merges))
}

/// Templates (medoids) and every member's (yaw, offset in texels, residual) against its
/// template's density patch.
struct MemberPoses {
    templates: Vec<usize>,
    fits: Vec<(f32, (f32, f32), f32)>,
}

fn pose_members(
    lib: &Library,
    category: &[usize],
    distance: &DistanceMatrix,
    yaw: &YawOptions,
) -> Result<MemberPoses> {
    let n = category.len();
    let k = category.iter().max().map_or(0, |&m| m + 1);
    let templates: Vec<usize> = (0..k)
        .map(|c| medoid(distance, &(0..n).filter(|&i| category[i] == c).collect::<Vec<_>>()))
        .collect::<Result<_>>()?;
    let nd = lib.index.channels.0;
    // every entry's density patch and mask weights, once
    let patches: Vec<(PlaneImage, Vec<f32>)> = lib
        .index
        .entries
        .par_iter()
        .map(|e| {
            let (h, w) = e.patch_size;
            let d = lib.patches.get_f32(&e.density, &[h, w, nd])?.to_vec();
            let m = lib.patches.get_u8(&e.mask, &[h, w])?;
            Ok((PlaneImage::new(h, w, nd, d)?, m.iter().map(|&b| f32::from(b.min(1))).collect()))
        })
        .collect::<Result<_>>()?;
    let fits = (0..n)
        .into_par_iter()
        .map(|i| {
            let t = templates[category[i]];
            if t == i {
                return (0.0, (0.0, 0.0), 0.0);
            }
            let ((tp, tw), (ip, iw)) = (&patches[t], &patches[i]);
            // a pair that cannot be matched keeps the template's orientation, residual -1
            match estimate_yaw_weighted(tp, Some(tw), ip, Some(iw), yaw) {
                Ok(fit) => (fit.yaw_deg, fit.offset, fit.residual),
                Err(_) => (0.0, (0.0, 0.0), -1.0),
            }
        })
        .collect();
    Ok(MemberPoses { templates, fits })
}

/// Parameters of a regrouping: the grouping, vertical blur and yaw search of `mine`.
#[derive(Debug, Clone, Default)]
pub struct RegroupOptions {
    pub group: GroupOptions,
    /// The vertical blur of the profiles, in levels (`DetectParams::blur_levels`).
    pub blur_levels: usize,
    pub yaw: YawOptions,
}

impl RegroupOptions {
    /// The settings `assetfield mine` groups and poses with by default.
    pub fn from_mining(opts: &crate::pipeline::MineOptions) -> Self {
        RegroupOptions {
            group: opts.group.clone(),
            blur_levels: opts.detect.blur_levels,
            yaw: opts.pose.yaw,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(name: &str, category: &str, source: usize) -> Entry {
        Entry { source, ..Entry::named(name, category) }
    }

    /// Entries a0, a1 (scene 0, category A), b0 (scene 0, category B), c0, c1 (scene 1,
    /// category C); distances from a table of category pairs.
    fn fixture(ab: f64, ac: f64, bc: f64) -> (Vec<Entry>, DistanceMatrix) {
        let entries = vec![
            entry("a0", "s0/A", 0),
            entry("a1", "s0/A", 0),
            entry("b0", "s0/B", 0),
            entry("c0", "s1/C", 1),
            entry("c1", "s1/C", 1),
        ];
        let cat = |i: usize| ["A", "A", "B", "C", "C"][i];
        let d = DistanceMatrix::from_fn(5, |i, j| match (cat(i), cat(j)) {
            (x, y) if x == y => 0.01,
            ("A", "B") | ("B", "A") => ab,
            ("A", "C") | ("C", "A") => ac,
            _ => bc,
        })
        .unwrap();
        (entries, d)
    }

    #[test]
    fn unites_the_nearest_category_of_another_scene_only() {
        // B is nearer to C than A is, and A is nearer still to B (same scene: never one)
        let (entries, d) = fixture(0.02, 0.10, 0.05);
        let (category, merges) = unite_across_sources(&entries, &d, 0.12).unwrap();
        assert_eq!(category, vec![0, 0, 1, 1, 1]);
        assert_eq!(merges.len(), 1);
        assert!((merges[0].distance - 0.05).abs() < 1e-12);
        assert_eq!((merges[0].a, merges[0].b, merges[0].size), (1, 2, 3));
    }

    #[test]
    fn keeps_every_category_when_nothing_is_near_enough() {
        let (entries, d) = fixture(0.02, 0.5, 0.3);
        let (category, merges) = unite_across_sources(&entries, &d, 0.12).unwrap();
        // no scene's category is split or joined with another of its scene
        assert_eq!(category, vec![0, 0, 1, 2, 2]);
        assert!(merges.is_empty());
    }

    #[test]
    fn a_united_category_takes_no_second_partner_from_a_scene_it_holds() {
        // a third scene's category D near both A and C: after A+C (nearest) unites, D joins
        // them; B (scene 0 again) never does
        let entries = vec![
            entry("a0", "s0/A", 0),
            entry("b0", "s0/B", 0),
            entry("c0", "s1/C", 1),
            entry("d0", "s2/D", 2),
        ];
        let table = [
            [0.0, 0.01, 0.02, 0.05],
            [0.01, 0.0, 0.03, 0.06],
            [0.02, 0.03, 0.0, 0.04],
            [0.05, 0.06, 0.04, 0.0],
        ];
        let d = DistanceMatrix::from_fn(4, |i, j| table[i][j]).unwrap();
        let (category, merges) = unite_across_sources(&entries, &d, 0.12).unwrap();
        assert_eq!(category, vec![0, 1, 0, 0]);
        assert_eq!(merges.len(), 2);
        // the second merge joins the new group (id 4 = 4 starting groups + merge 0)
        assert_eq!((merges[1].a, merges[1].b), (3, 4));
    }

    #[test]
    fn a_distance_matrix_of_another_size_is_an_error() {
        let (entries, _) = fixture(0.1, 0.1, 0.1);
        let d = DistanceMatrix::from_fn(3, |_, _| 0.0).unwrap();
        assert!(matches!(
            unite_across_sources(&entries, &d, 0.12),
            Err(MiningError::SizeMismatch { .. })
        ));
    }
}

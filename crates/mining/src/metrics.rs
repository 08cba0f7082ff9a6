//! Mining quality against a ground-truth layout (`gt_layout.json`).
//!
//! * **Detection**: predicted and ground-truth bird's-eye-view boxes are matched greedily by
//!   decreasing IoU, a pair counting when its IoU is at least the threshold (0.5); precision,
//!   recall and F1 follow. Containers (floors, rooms) are not objects.
//! * **Grouping**: the adjusted Rand index between predicted categories and ground-truth
//!   categories over the matched detections.
//! * **Yaw**: each instance's yaw relative to its category's template against the ground
//!   truth's relative yaw, `pred - (gt_instance - gt_template)`, wrapped modulo the object's
//!   `yaw_symmetry_deg` (objects with symmetry 0, round ones, are skipped, as are templates
//!   and instances whose template was not matched or belongs to another ground-truth
//!   category).
//! * **Position**: distance between the predicted placement and the ground-truth position on
//!   the ground plane, over the matched detections.

use assetfield_core::Rect2;
use assetfield_core::ground::yaw_difference;
use assetfield_layout::GtLayout;
use glam::Vec2;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What [`evaluate`] needs of one mined instance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Predicted {
    pub world: Rect2,
    pub category: usize,
    /// Index (into the predictions) of the template of this instance's category.
    pub template: usize,
    /// Yaw relative to the template, degrees counter-clockwise.
    pub yaw_rel: f32,
    pub position: Vec2,
}

/// Per ground-truth-matched detection.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InstanceMetrics {
    pub detection: usize,
    pub gt_id: Option<u32>,
    pub gt_category: Option<String>,
    pub category: usize,
    pub iou: f32,
    pub is_template: bool,
    pub yaw_rel_deg: f32,
    pub gt_yaw_rel_deg: Option<f32>,
    pub yaw_error_deg: Option<f32>,
    pub position_error: Option<f32>,
}

/// Per predicted category.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CategoryMetrics {
    pub category: usize,
    pub members: usize,
    pub matched: usize,
    /// Ground-truth categories of the matched members, with counts.
    pub gt_categories: BTreeMap<String, usize>,
    pub template_gt_id: Option<u32>,
    pub yaw_median_deg: Option<f32>,
    pub yaw_max_deg: Option<f32>,
}

/// Everything [`evaluate`] measures. `None` values mean "nothing to measure" (e.g. no yaw
/// pair); they serialise as `null`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    pub precision: f32,
    pub recall: f32,
    pub f1: f32,
    pub ari: f32,
    pub yaw_median_deg: Option<f32>,
    pub yaw_max_deg: Option<f32>,
    pub position_median: Option<f32>,
    pub iou_threshold: f32,
    pub predicted: usize,
    pub ground_truth: usize,
    pub matched: usize,
    pub yaw_pairs: usize,
    pub per_category: Vec<CategoryMetrics>,
    pub per_instance: Vec<InstanceMetrics>,
    /// Ground-truth objects no detection matched: (id, category).
    pub missed: Vec<(u32, String)>,
}

fn median(v: &mut [f32]) -> Option<f32> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f32::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) })
}

/// Adjusted Rand index of two labellings of the same items (Hubert & Arabie). Both
/// labellings trivial in the same way (all items in one cluster, or all apart) give 1.
pub fn adjusted_rand_index<A: Ord + Clone, B: Ord + Clone>(a: &[A], b: &[B]) -> f32 {
    let n = a.len().min(b.len());
    if n < 2 {
        return 1.0;
    }
    let c2 = |x: usize| (x * x.saturating_sub(1) / 2) as f64;
    let mut table: BTreeMap<(A, B), usize> = BTreeMap::new();
    let mut ra: BTreeMap<A, usize> = BTreeMap::new();
    let mut rb: BTreeMap<B, usize> = BTreeMap::new();
    for i in 0..n {
        *table.entry((a[i].clone(), b[i].clone())).or_default() += 1;
        *ra.entry(a[i].clone()).or_default() += 1;
        *rb.entry(b[i].clone()).or_default() += 1;
    }
    let index: f64 = table.values().map(|&v| c2(v)).sum();
    let sa: f64 = ra.values().map(|&v| c2(v)).sum();
    let sb: f64 = rb.values().map(|&v| c2(v)).sum();
    let expected = sa * sb / c2(n);
    let max = 0.5 * (sa + sb);
    if (max - expected).abs() < 1e-12 {
        return if (index - expected).abs() < 1e-12 { 1.0 } else { 0.0 };
    }
    ((index - expected) / (max - expected)) as f32
}

/// Greedy matching by decreasing IoU: `(pred, gt, iou)` pairs with IoU >= `threshold`.
pub fn match_boxes(pred: &[Rect2], gt: &[Rect2], threshold: f32) -> Vec<(usize, usize, f32)> {
    let mut pairs: Vec<(usize, usize, f32)> = Vec::new();
    for (i, p) in pred.iter().enumerate() {
        for (j, g) in gt.iter().enumerate() {
            let iou = p.iou(g);
            if iou >= threshold && iou > 0.0 {
                pairs.push((i, j, iou));
            }
        }
    }
    pairs.sort_by(|a, b| b.2.total_cmp(&a.2).then(a.0.cmp(&b.0)).then(a.1.cmp(&b.1)));
    let (mut used_p, mut used_g) = (vec![false; pred.len()], vec![false; gt.len()]);
    let mut out = Vec::new();
    for (i, j, iou) in pairs {
        if !used_p[i] && !used_g[j] {
            used_p[i] = true;
            used_g[j] = true;
            out.push((i, j, iou));
        }
    }
    out.sort_by_key(|m| m.0);
    out
}

/// Measure predictions against the ground truth (see the module docs).
pub fn evaluate(preds: &[Predicted], gt: &GtLayout, iou_threshold: f32) -> Metrics {
    let gt_boxes: Vec<Rect2> = gt
        .instances
        .iter()
        .map(|g| {
            let b = g.bev_aabb;
            Rect2::new(Vec2::new(b[0], b[1]), Vec2::new(b[2], b[3]))
        })
        .collect();
    let pred_boxes: Vec<Rect2> = preds.iter().map(|p| p.world).collect();
    let matches = match_boxes(&pred_boxes, &gt_boxes, iou_threshold);
    let mut gt_of: Vec<Option<(usize, f32)>> = vec![None; preds.len()];
    for &(i, j, iou) in &matches {
        gt_of[i] = Some((j, iou));
    }
    let m = matches.len() as f32;
    let precision = if preds.is_empty() { 0.0 } else { m / preds.len() as f32 };
    let recall = if gt.instances.is_empty() { 0.0 } else { m / gt.instances.len() as f32 };
    let f1 = if precision + recall > 0.0 {
        2.0 * precision * recall / (precision + recall)
    } else {
        0.0
    };
    let pa: Vec<usize> = matches.iter().map(|&(i, _, _)| preds[i].category).collect();
    let pb: Vec<String> =
        matches.iter().map(|&(_, j, _)| gt.instances[j].category.clone()).collect();
    let ari = if matches.is_empty() { 0.0 } else { adjusted_rand_index(&pa, &pb) };

    let mut per_instance = Vec::new();
    let mut yaw_errors = Vec::new();
    let mut pos_errors = Vec::new();
    for (i, p) in preds.iter().enumerate() {
        let g = gt_of[i].map(|(j, _)| &gt.instances[j]);
        let is_template = p.template == i;
        let mut gt_rel = None;
        let mut yaw_err = None;
        if let (Some(g), false) = (g, is_template)
            && let Some((tj, _)) = gt_of.get(p.template).copied().flatten()
        {
            let t = &gt.instances[tj];
            if t.category == g.category && g.yaw_symmetry_deg > 0.0 {
                let rel = g.yaw_deg - t.yaw_deg;
                gt_rel = Some(rel);
                let e = yaw_difference(p.yaw_rel, rel, g.yaw_symmetry_deg.min(360.0));
                yaw_err = Some(e);
                yaw_errors.push(e);
            }
        }
        let pos_err = g.map(|g| (p.position - Vec2::new(g.position[0], g.position[1])).length());
        if let Some(e) = pos_err {
            pos_errors.push(e);
        }
        per_instance.push(InstanceMetrics {
            detection: i,
            gt_id: g.map(|g| g.id),
            gt_category: g.map(|g| g.category.clone()),
            category: p.category,
            iou: gt_of[i].map_or(0.0, |(_, iou)| iou),
            is_template,
            yaw_rel_deg: p.yaw_rel,
            gt_yaw_rel_deg: gt_rel,
            yaw_error_deg: yaw_err,
            position_error: pos_err,
        });
    }
    let n_cat = preds.iter().map(|p| p.category + 1).max().unwrap_or(0);
    let per_category = (0..n_cat)
        .map(|c| {
            let members: Vec<&InstanceMetrics> =
                per_instance.iter().filter(|x| x.category == c).collect();
            let mut gt_categories = BTreeMap::new();
            for x in &members {
                if let Some(g) = &x.gt_category {
                    *gt_categories.entry(g.clone()).or_insert(0) += 1;
                }
            }
            let mut errs: Vec<f32> = members.iter().filter_map(|x| x.yaw_error_deg).collect();
            let template = members.iter().find(|x| x.is_template);
            CategoryMetrics {
                category: c,
                members: members.len(),
                matched: members.iter().filter(|x| x.gt_id.is_some()).count(),
                gt_categories,
                template_gt_id: template.and_then(|t| t.gt_id),
                yaw_max_deg: errs.iter().copied().reduce(f32::max),
                yaw_median_deg: median(&mut errs),
            }
        })
        .collect();
    let matched_gt: Vec<bool> = {
        let mut v = vec![false; gt.instances.len()];
        for &(_, j, _) in &matches {
            v[j] = true;
        }
        v
    };
    let missed = gt
        .instances
        .iter()
        .zip(&matched_gt)
        .filter(|(_, m)| !**m)
        .map(|(g, _)| (g.id, g.category.clone()))
        .collect();
    let yaw_pairs = yaw_errors.len();
    Metrics {
        precision,
        recall,
        f1,
        ari,
        yaw_max_deg: yaw_errors.iter().copied().reduce(f32::max),
        yaw_median_deg: median(&mut yaw_errors),
        position_median: median(&mut pos_errors),
        iou_threshold,
        predicted: preds.len(),
        ground_truth: gt.instances.len(),
        matched: matches.len(),
        yaw_pairs,
        per_category,
        per_instance,
        missed,
    }
}

impl Metrics {
    /// A one-paragraph summary.
    pub fn summary(&self) -> String {
        let opt = |v: Option<f32>, unit: &str| {
            v.map_or_else(|| "n/a".to_string(), |x| format!("{x:.2}{unit}"))
        };
        format!(
            "detection: {} of {} ground-truth objects found with {} detections (IoU >= {}): \
             precision {:.3}, recall {:.3}, F1 {:.3}; grouping: ARI {:.3} over the matched \
             detections; yaw relative to the templates: median error {}, max {} over {} \
             instances; position: median error {} (world units){}",
            self.matched,
            self.ground_truth,
            self.predicted,
            self.iou_threshold,
            self.precision,
            self.recall,
            self.f1,
            self.ari,
            opt(self.yaw_median_deg, " deg"),
            opt(self.yaw_max_deg, " deg"),
            self.yaw_pairs,
            opt(self.position_median, ""),
            if self.missed.is_empty() {
                String::new()
            } else {
                format!(
                    "; missed: {}",
                    self.missed
                        .iter()
                        .map(|(id, c)| format!("#{id} {c}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        )
    }
}

/// One scene's scores in a merged library (its entries against its ground truth).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneScore {
    pub library: String,
    pub entries: usize,
    pub ground_truth: usize,
    pub matched: usize,
    pub precision: f32,
    pub recall: f32,
    pub f1: f32,
    /// ARI of the scene's matched entries under the merged library's categories.
    pub ari: f32,
}

/// `metrics.json` of a merged library with ground truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CrossSceneMetrics {
    /// ARI over the matched entries of every scene together, against their ground-truth
    /// categories (category names shared between the scenes' ground truths).
    pub cross_scene_ari: f32,
    /// Matched entries of all scenes.
    pub matched: usize,
    pub categories: usize,
    /// Categories with members from more than one scene.
    pub categories_spanning_scenes: usize,
    /// Ground-truth categories found in more than one scene, and how many of them the
    /// merged library puts in one category (all their matched entries together).
    pub shared_gt_categories: usize,
    pub shared_gt_categories_united: usize,
    pub iou_threshold: f32,
    pub per_scene: Vec<SceneScore>,
    /// Per matched entry: (entry, ground-truth category, merged category).
    pub matches: Vec<(String, String, String)>,
}

/// Score a merged library: each scene's entries (`scene_of[i]`: the input of entry `i`)
/// against that scene's ground truth (BEV IoU at least `iou_threshold`), and the ARI over
/// all matched entries together.
pub fn cross_scene_metrics(
    index: &assetfield_library::LibraryIndex,
    scene_of: &[usize],
    names: &[String],
    gts: &[GtLayout],
    iou_threshold: f32,
) -> CrossSceneMetrics {
    use std::collections::BTreeSet;
    let cat_index: BTreeMap<&str, usize> =
        index.categories.iter().enumerate().map(|(k, c)| (c.name.as_str(), k)).collect();
    let mut matches = Vec::new();
    let mut per_scene = Vec::new();
    for (s, gt) in gts.iter().enumerate() {
        let ids: Vec<usize> =
            (0..index.entries.len()).filter(|&i| scene_of.get(i) == Some(&s)).collect();
        let local: BTreeMap<&str, usize> =
            ids.iter().enumerate().map(|(k, &i)| (index.entries[i].name.as_str(), k)).collect();
        let preds: Vec<Predicted> = ids
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let e = &index.entries[i];
                let b = e.source_box;
                let category = cat_index.get(e.category.as_str()).copied().unwrap_or(usize::MAX);
                let template = index
                    .categories
                    .get(category)
                    .and_then(|c| local.get(c.template.as_str()).copied())
                    .unwrap_or(k);
                Predicted {
                    world: Rect2::new(Vec2::new(b[0], b[1]), Vec2::new(b[2], b[3])),
                    category,
                    template,
                    yaw_rel: e.yaw_deg,
                    position: e.pivot_world(),
                }
            })
            .collect();
        let m = evaluate(&preds, gt, iou_threshold);
        for inst in &m.per_instance {
            if let Some(g) = &inst.gt_category {
                let e = &index.entries[ids[inst.detection]];
                matches.push((e.name.clone(), g.clone(), e.category.clone()));
            }
        }
        per_scene.push(SceneScore {
            library: names.get(s).cloned().unwrap_or_default(),
            entries: ids.len(),
            ground_truth: m.ground_truth,
            matched: m.matched,
            precision: m.precision,
            recall: m.recall,
            f1: m.f1,
            ari: m.ari,
        });
    }
    let gt_labels: Vec<&str> = matches.iter().map(|m| m.1.as_str()).collect();
    let ours: Vec<&str> = matches.iter().map(|m| m.2.as_str()).collect();
    let cross_scene_ari =
        if matches.is_empty() { 0.0 } else { adjusted_rand_index(&ours, &gt_labels) };
    let scene_by_name: BTreeMap<&str, usize> = index
        .entries
        .iter()
        .enumerate()
        .map(|(i, e)| (e.name.as_str(), scene_of.get(i).copied().unwrap_or(0)))
        .collect();
    let spanning = index
        .categories
        .iter()
        .filter(|c| {
            c.members
                .iter()
                .filter_map(|m| scene_by_name.get(m.as_str()))
                .collect::<BTreeSet<_>>()
                .len()
                > 1
        })
        .count();
    // ground-truth categories matched in several scenes, and whether they stay together
    let mut by_gt: BTreeMap<&str, (BTreeSet<usize>, BTreeSet<&str>)> = BTreeMap::new();
    for (name, g, c) in &matches {
        let e = by_gt.entry(g.as_str()).or_default();
        e.0.insert(scene_by_name.get(name.as_str()).copied().unwrap_or(0));
        e.1.insert(c.as_str());
    }
    let shared: Vec<_> = by_gt.values().filter(|(scenes, _)| scenes.len() > 1).collect();
    CrossSceneMetrics {
        cross_scene_ari,
        matched: matches.len(),
        categories: index.categories.len(),
        categories_spanning_scenes: spanning,
        shared_gt_categories: shared.len(),
        shared_gt_categories_united: shared.iter().filter(|(_, cats)| cats.len() == 1).count(),
        iou_threshold,
        per_scene,
        matches,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use assetfield_layout::GtInstance;

    fn gt_inst(id: u32, cat: &str, x: f32, y: f32, yaw: f32, sym: f32) -> GtInstance {
        GtInstance {
            id,
            category: cat.into(),
            position: [x, y, 0.0],
            yaw_deg: yaw,
            scale: 1.0,
            bev_aabb: [x - 0.5, y - 0.5, x + 0.5, y + 0.5],
            yaw_symmetry_deg: sym,
            supported_by: None,
            key: String::new(),
            asset: String::new(),
            top: 1.0,
        }
    }

    fn pred(x: f32, y: f32, category: usize, template: usize, yaw_rel: f32) -> Predicted {
        Predicted {
            world: Rect2::new(Vec2::new(x - 0.5, y - 0.5), Vec2::new(x + 0.5, y + 0.5)),
            category,
            template,
            yaw_rel,
            position: Vec2::new(x, y),
        }
    }

    fn layout(instances: Vec<GtInstance>) -> GtLayout {
        GtLayout {
            instances,
            containers: Vec::new(),
            scene: "t".into(),
            extent: [0.0; 4],
            conventions: String::new(),
        }
    }

    #[test]
    fn ari_known_values() {
        assert_eq!(adjusted_rand_index(&[0, 0, 1, 1], &["a", "a", "b", "b"]), 1.0);
        // label names do not matter
        assert_eq!(adjusted_rand_index(&[1, 1, 0, 0], &[0, 0, 1, 1]), 1.0);
        // scikit-learn: adjusted_rand_score([0,0,1,1],[0,0,1,2]) = 0.5714285714
        let v = adjusted_rand_index(&[0, 0, 1, 1], &[0, 0, 1, 2]);
        assert!((v - 0.571_428_6).abs() < 1e-5, "{v}");
        // adjusted_rand_score([0,0,0,1,1,1],[0,0,1,1,2,2]) = 0.2424242424
        let v = adjusted_rand_index(&[0, 0, 0, 1, 1, 1], &[0, 0, 1, 1, 2, 2]);
        assert!((v - 0.242_424_24).abs() < 1e-5, "{v}");
        assert_eq!(adjusted_rand_index(&[0, 0, 0], &[5, 5, 5]), 1.0);
    }

    #[test]
    fn detection_grouping_yaw_and_symmetry() {
        let gt = layout(vec![
            gt_inst(1, "chair", 0.0, 0.0, 10.0, 360.0),
            gt_inst(2, "chair", 3.0, 0.0, 100.0, 360.0),
            gt_inst(3, "table", 6.0, 0.0, 0.0, 180.0),
            gt_inst(4, "table", 9.0, 0.0, 170.0, 180.0),
            gt_inst(5, "plant", 12.0, 0.0, 0.0, 0.0),
            gt_inst(6, "plant", 15.0, 0.0, 45.0, 0.0),
            gt_inst(7, "chair", 30.0, 0.0, 0.0, 360.0),
        ]);
        let preds = vec![
            pred(0.0, 0.0, 0, 0, 0.0),
            pred(3.1, 0.0, 0, 0, 92.0), // 2 deg off
            pred(6.0, 0.0, 1, 2, 0.0),
            // a table turned by 170 looks like -10 under 2-fold symmetry: 349 is 1 deg off
            pred(9.0, 0.0, 1, 2, 349.0),
            pred(12.0, 0.0, 2, 4, 0.0),
            pred(15.0, 0.0, 2, 4, 123.0), // round: skipped
            pred(50.0, 50.0, 3, 6, 0.0),  // a false positive
        ];
        let m = evaluate(&preds, &gt, 0.5);
        assert_eq!((m.matched, m.predicted, m.ground_truth), (6, 7, 7));
        assert!((m.precision - 6.0 / 7.0).abs() < 1e-6 && (m.recall - 6.0 / 7.0).abs() < 1e-6);
        assert!((m.f1 - 6.0 / 7.0).abs() < 1e-6);
        assert_eq!(m.ari, 1.0);
        assert_eq!(m.yaw_pairs, 2);
        assert!((m.yaw_max_deg.unwrap() - 2.0).abs() < 1e-4, "{:?}", m.yaw_max_deg);
        assert!((m.yaw_median_deg.unwrap() - 1.5).abs() < 1e-4);
        assert!(m.position_median.unwrap() < 0.11);
        assert_eq!(m.missed, vec![(7, "chair".to_string())]);
        assert_eq!(m.per_category[1].yaw_max_deg, Some(1.0));
        let s = m.summary();
        assert!(s.contains("F1 0.857") && s.contains("#7 chair"), "{s}");
        // a shifted box no longer matches
        let mut shifted = preds.clone();
        shifted[0].world = Rect2::new(Vec2::new(0.2, 0.2), Vec2::new(1.2, 1.2));
        assert_eq!(evaluate(&shifted, &gt, 0.5).matched, 5);
    }

    #[test]
    fn mis_grouped_instances_do_not_count_for_yaw() {
        let gt = layout(vec![
            gt_inst(1, "chair", 0.0, 0.0, 0.0, 360.0),
            gt_inst(2, "stool", 3.0, 0.0, 50.0, 360.0),
        ]);
        let preds = vec![pred(0.0, 0.0, 0, 0, 0.0), pred(3.0, 0.0, 0, 0, 10.0)];
        let m = evaluate(&preds, &gt, 0.5);
        assert_eq!(m.yaw_pairs, 0);
        assert_eq!(m.yaw_median_deg, None);
        assert_eq!(m.ari, 0.0);
    }
}

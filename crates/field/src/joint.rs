//! Several scenes trained together (paper Sec. 3.4, "expandable asset library"): every scene
//! keeps its own box, ground planes, occupancy grid, optimiser moments for its planes and
//! rays, while the tensors that are not ground planes (vertical axes, colour basis, decoders,
//! I-AssetField's guidance MLPs) are one set, trained by the rays of all scenes and
//! bit-identical in every scene's field. Objects mined from such fields are described in one
//! feature space, so a library can group them across scenes and place them in each other's
//! scenes.
//!
//! For the shared vertical axis to mean the same heights everywhere, the scenes share a
//! vertical range (the union of their boxes'), a voxel size (the plane resolution along the
//! longest side of any box; every box is grown to whole voxels, so texels are equal and
//! patches move between scenes unscaled) and the density's distance scale (from the largest
//! extent of any box). [`share_config`] fits a new scene's box to an existing shared set in
//! the same way, for training its planes alone against frozen shared tensors.

use crate::config::{FieldConfig, ModelKind, SharingMismatch, distance_scale_for};
use crate::io::FieldError;
use crate::model::Field;
use crate::train::{GridRule, StepStats, TrainConfig, Trainer};
use assetfield_core::Aabb3;
use assetfield_data::Dataset;
use std::path::Path;
use std::time::Instant;

/// Grow `len` to a whole number of voxels (at least one).
fn whole_voxels(len: f32, voxel: f32) -> f32 {
    // a length already within 1e-3 voxels of a whole count keeps it
    (len / voxel - 1e-3).ceil().max(1.0) * voxel
}

/// Configurations for scenes trained together, from one configuration `template` (model,
/// channels, decoder, semantic channels; its box is ignored) and each scene's box: the
/// vertical range is the union of the boxes' ranges; `plane_res` texels span the longest
/// side of any box, which fixes one voxel size; each box keeps its minimum corner and grows
/// to whole voxels; one distance scale for all. Each configuration is at its final grid
/// ([`JointTrainer::new`] trains up to it).
pub fn joint_configs(
    template: &FieldConfig,
    boxes: &[Aabb3],
    plane_res: usize,
) -> Result<Vec<FieldConfig>, FieldError> {
    let invalid = |message: String| FieldError::Invalid { path: "joint training".into(), message };
    if boxes.is_empty() {
        return Err(invalid("no scene to train".into()));
    }
    if template.kind == ModelKind::Vm {
        return Err(invalid(
            "a TensoRF-VM field has no ground planes to keep per scene and nothing to share: train s or i".into(),
        ));
    }
    let zmin = boxes.iter().map(|b| b.min.z).fold(f32::INFINITY, f32::min);
    let zmax = boxes.iter().map(|b| b.max.z).fold(f32::NEG_INFINITY, f32::max);
    let longest = boxes.iter().map(|b| b.extent().x.max(b.extent().y)).fold(0.0f32, f32::max);
    if !(longest.is_finite() && longest > 0.0 && zmax > zmin && zmax.is_finite()) {
        return Err(invalid(format!("the scene boxes are empty or not finite: {boxes:?}")));
    }
    let voxel = longest / (plane_res.max(2) - 1) as f32;
    let height = whole_voxels(zmax - zmin, voxel);
    let snapped: Vec<Aabb3> = boxes
        .iter()
        .map(|b| {
            let e = b.extent();
            let min = glam::Vec3::new(b.min.x, b.min.y, zmin);
            let size = glam::Vec3::new(whole_voxels(e.x, voxel), whole_voxels(e.y, voxel), height);
            Aabb3::new(min, min + size)
        })
        .collect();
    let largest = snapped.iter().map(|b| b.extent().max_element()).fold(0.0f32, f32::max);
    Ok(snapped
        .iter()
        .map(|b| {
            let mut c = template.clone();
            c.aabb = [b.min.to_array(), b.max.to_array()];
            c.distance_scale = distance_scale_for(largest);
            c.res = c.resolution_for_voxel(voxel);
            c
        })
        .collect())
}

/// The configuration of a new scene with box `own` that shares the tensors of `shared` (a
/// field or a library's shared configuration): `shared`'s model, networks, vertical range
/// and resolution, distance scale and texel size (per axis); `own`'s ground box, grown to
/// whole texels. Returns it (at its final grid) and the [`GridRule`] of its training: the
/// planes alone, the vertical axis at its length throughout.
pub fn share_config(
    shared: &FieldConfig,
    own: Aabb3,
) -> Result<(FieldConfig, GridRule), FieldError> {
    let invalid = |message: String| FieldError::Invalid { path: "--share".into(), message };
    if shared.kind == ModelKind::Vm {
        return Err(invalid("a TensoRF-VM field has no ground planes and nothing to share".into()));
    }
    let texel = shared.voxel_size();
    let e = own.extent();
    if !(e.x > 0.0 && e.y > 0.0 && e.is_finite()) {
        return Err(invalid(format!("the new scene's box is empty or not finite: {own:?}")));
    }
    let (sx, sy) = (whole_voxels(e.x, texel.x), whole_voxels(e.y, texel.y));
    let mut c = shared.clone();
    c.aabb = [
        [own.min.x, own.min.y, shared.aabb[0][2]],
        [own.min.x + sx, own.min.y + sy, shared.aabb[1][2]],
    ];
    let n = |len: f32, t: f32| (len / t).round() as usize + 1;
    c.res = [n(sx, texel.x), n(sy, texel.y), shared.res[2]];
    let rule = GridRule { final_res: Some(c.res), vertical_fixed: true, frozen_shared: true };
    Ok((c, rule))
}

/// Scenes in training together.
#[derive(Debug)]
pub struct JointTrainer {
    /// One trainer per scene, in the order given; their shared tensors are equal.
    pub scenes: Vec<Trainer>,
}

fn cannot_share(a: usize, b: usize, m: SharingMismatch) -> FieldError {
    FieldError::Invalid {
        path: "joint training".into(),
        message: format!("scenes {a} and {b} cannot share their tensors: {m}"),
    }
}

impl JointTrainer {
    /// Start training `scenes` (each a dataset and its final configuration, from
    /// [`joint_configs`]) together; each scene's grid follows [`GridRule::final_res`]. Scene `k` draws its planes and rays from seed `config.seed + k`; the
    /// shared tensors start as scene 0's.
    pub fn new(
        scenes: &[(&Dataset, FieldConfig)],
        config: &TrainConfig,
    ) -> Result<Self, FieldError> {
        for (k, (_, c)) in scenes.iter().enumerate().skip(1) {
            if let Some(m) = scenes[0].1.sharing_mismatch(c) {
                return Err(cannot_share(0, k, m));
            }
        }
        let mut trainers: Vec<Trainer> = scenes
            .iter()
            .enumerate()
            .map(|(k, (data, fc))| {
                let mut tc = config.clone();
                tc.seed = config.seed.wrapping_add(k as u64);
                tc.grid.final_res = Some(fc.res);
                Trainer::new(data, fc.clone(), tc)
            })
            .collect();
        let (first, rest) = trainers.split_first_mut().ok_or_else(|| FieldError::Invalid {
            path: "joint training".into(),
            message: "no scene to train".into(),
        })?;
        for t in rest {
            t.field.copy_shared_from(&first.field);
        }
        Ok(JointTrainer { scenes: trainers })
    }

    /// Continue a joint run from one checkpoint per scene (same order as `data`). The
    /// checkpoints must come from one run: the same iteration and bit-identical shared
    /// tensors.
    pub fn resume(
        data: &[&Dataset],
        checkpoints: &[&Path],
        iters: Option<u64>,
        seconds: Option<f64>,
    ) -> Result<Self, FieldError> {
        let scenes: Vec<Trainer> = data
            .iter()
            .zip(checkpoints)
            .map(|(d, p)| Trainer::resume(d, p, iters, seconds))
            .collect::<Result<_, _>>()?;
        let first = scenes.first().ok_or_else(|| FieldError::Invalid {
            path: "joint training".into(),
            message: "no checkpoint to resume".into(),
        })?;
        for (k, t) in scenes.iter().enumerate().skip(1) {
            let path = checkpoints[k].display().to_string();
            if t.iter != first.iter {
                return Err(FieldError::Invalid {
                    path,
                    message: format!(
                        "at iteration {}, but {} is at {}: the checkpoints are not of one joint run",
                        t.iter,
                        checkpoints[0].display(),
                        first.iter
                    ),
                });
            }
            if let Some(name) = first_shared_difference(&first.field, &t.field) {
                return Err(FieldError::Invalid {
                    path,
                    message: format!(
                        "shared tensor \"{name}\" differs from {}'s: the checkpoints are not of one joint run",
                        checkpoints[0].display()
                    ),
                });
            }
        }
        Ok(JointTrainer { scenes })
    }

    /// Fraction of the run done (scene 0's clock and iterations; all step together).
    pub fn progress(&self) -> f64 {
        self.scenes.first().map_or(1.0, Trainer::progress)
    }

    pub fn finished(&self) -> bool {
        self.progress() >= 1.0
    }

    /// Seconds of training so far.
    pub fn elapsed(&self) -> f64 {
        self.scenes.first().map_or(0.0, Trainer::elapsed)
    }

    /// Iterations done (the same for every scene).
    pub fn iter(&self) -> u64 {
        self.scenes.first().map_or(0, |t| t.iter)
    }

    /// One iteration: every scene's batch (its own rays, planes and occupancy), the shared
    /// tensors' gradients summed over the scenes, one Adam step per scene (identical on the
    /// shared tensors, which are then made bit-identical). Returns each scene's figures.
    pub fn step(&mut self) -> Vec<StepStats> {
        let t0 = Instant::now();
        let progress = self.progress();
        // resolution steps change the vertical axis's length: all scenes step together (the
        // schedule depends on progress only, the same for every scene)
        for t in &mut self.scenes {
            t.schedule(progress);
        }
        let mut stats: Vec<StepStats> = self.scenes.iter_mut().map(Trainer::gradients).collect();
        self.sum_shared_gradients();
        for (t, s) in self.scenes.iter_mut().zip(&stats) {
            t.apply_with(progress, s.psnr);
        }
        if let Some((first, rest)) = self.scenes.split_first_mut() {
            for t in rest {
                t.field.copy_shared_from(&first.field);
            }
        }
        let seconds = t0.elapsed().as_secs_f64();
        for s in &mut stats {
            s.seconds = seconds;
        }
        stats
    }

    /// The gradient of the sum of the scenes' losses with respect to the shared tensors,
    /// written into every scene's gradient buffer (added in scene order: deterministic).
    fn sum_shared_gradients(&mut self) {
        if self.scenes.len() < 2 {
            return;
        }
        let names: Vec<String> =
            self.scenes[0].field.shared_ranges().iter().map(|(n, _)| n.to_string()).collect();
        let mut sum = Vec::new();
        for name in &names {
            let range = |t: &Trainer| {
                let s = t.field.params.spec(name).expect("sharing fields have the same tensors");
                s.offset..s.offset + s.len
            };
            let r0 = range(&self.scenes[0]);
            sum.clear();
            sum.extend_from_slice(&self.scenes[0].grad[r0]);
            for t in &self.scenes[1..] {
                for (a, b) in sum.iter_mut().zip(&t.grad[range(t)]) {
                    *a += b;
                }
            }
            for t in &mut self.scenes {
                let r = range(t);
                t.grad[r].copy_from_slice(&sum);
            }
        }
    }
}

/// The first shared tensor whose values differ bit for bit between two fields.
pub fn first_shared_difference(a: &Field, b: &Field) -> Option<String> {
    for (name, r) in a.shared_ranges() {
        let Some(s) = b.params.spec(name) else { return Some(name.to_string()) };
        let (x, y) = (&a.params.data[r], &b.params.data[s.offset..s.offset + s.len]);
        if x.len() != y.len() || x.iter().zip(y).any(|(p, q)| p.to_bits() != q.to_bits()) {
            return Some(name.to_string());
        }
    }
    None
}

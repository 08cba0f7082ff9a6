//! Adam with a learning rate per parameter group (grids vs networks), applied in parallel
//! over slices of the flat parameter buffer.

use crate::params::{Group, ParamSet};
use rayon::prelude::*;

#[derive(Debug, Clone)]
pub struct Adam {
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
    m: Vec<f32>,
    v: Vec<f32>,
    t: u32,
}

impl Adam {
    pub fn new(n: usize) -> Self {
        Adam { beta1: 0.9, beta2: 0.99, eps: 1e-8, m: vec![0.0; n], v: vec![0.0; n], t: 0 }
    }

    /// The optimiser state `(m, v, t)` for checkpoints.
    pub fn state(&self) -> (&[f32], &[f32], u32) {
        (&self.m, &self.v, self.t)
    }

    /// Restore a state saved with [`Adam::state`].
    pub fn set_state(&mut self, m: Vec<f32>, v: Vec<f32>, t: u32) {
        self.m = m;
        self.v = v;
        self.t = t;
    }

    /// Forget the moments (after the parameter layout changed, as TensoRF does on upsampling).
    pub fn reset(&mut self, n: usize) {
        self.m = vec![0.0; n];
        self.v = vec![0.0; n];
        self.t = 0;
    }

    /// One update: `lr(group)` gives each group's current learning rate.
    pub fn step(&mut self, params: &mut ParamSet, grad: &[f32], lr: impl Fn(Group) -> f32) {
        let s = self.begin();
        for spec in &params.specs {
            let r = spec.offset..spec.offset + spec.len;
            let alpha = s.alpha(lr(spec.group));
            let (p, g, m, v) = (
                &mut params.data[r.clone()],
                &grad[r.clone()],
                &mut self.m[r.clone()],
                &mut self.v[r],
            );
            p.par_chunks_mut(4096)
                .zip(g.par_chunks(4096))
                .zip(m.par_chunks_mut(4096))
                .zip(v.par_chunks_mut(4096))
                .for_each(|(((p, g), m), v)| s.update(alpha, p, g, m, v));
        }
    }

    /// Count a step and give its constants, for a caller that updates the parameters slice by
    /// slice itself ([`AdamStep::update`]; the training loop does, block by block, right
    /// after summing a block's gradient).
    pub fn begin(&mut self) -> AdamStep {
        self.t += 1;
        let (b1, b2) = (self.beta1, self.beta2);
        AdamStep {
            b1,
            b2,
            eps: self.eps,
            c1: 1.0 - b1.powi(self.t as i32),
            c2: 1.0 - b2.powi(self.t as i32),
        }
    }

    /// The moments `(m, v)`, to update slices of them with [`AdamStep::update`].
    pub fn moments_mut(&mut self) -> (&mut [f32], &mut [f32]) {
        (&mut self.m, &mut self.v)
    }
}

/// The constants of one Adam step (see [`Adam::begin`]).
#[derive(Debug, Clone, Copy)]
pub struct AdamStep {
    b1: f32,
    b2: f32,
    eps: f32,
    /// Bias corrections of the first and second moments.
    c1: f32,
    c2: f32,
}

impl AdamStep {
    /// The step size of learning rate `lr` with the first moment's bias correction.
    pub fn alpha(&self, lr: f32) -> f32 {
        lr / self.c1
    }

    /// Update parameters `p` with gradients `g` and their moments `m`, `v` (equal lengths);
    /// `alpha` from [`AdamStep::alpha`]. Element by element, so any split of a buffer into
    /// slices gives the same result, bit for bit.
    #[inline]
    pub fn update(&self, alpha: f32, p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32]) {
        let (b1, b2, eps, c2) = (self.b1, self.b2, self.eps, self.c2);
        for k in 0..p.len() {
            m[k] = b1 * m[k] + (1.0 - b1) * g[k];
            v[k] = b2 * v[k] + (1.0 - b2) * g[k] * g[k];
            p[k] -= alpha * m[k] / ((v[k] / c2).sqrt() + eps);
        }
    }
}

//! All trainable tensors of a field in one flat `Vec<f32>`, each a named slice with a shape
//! and an optimiser group. Gradients and Adam moments use the same layout.

use serde::{Deserialize, Serialize};

/// Optimiser group: grids (planes, axes) and networks (basis, MLPs) get their own rates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Group {
    Grid,
    Network,
}

/// One named tensor inside the flat buffer.
#[derive(Debug, Clone, PartialEq)]
pub struct TensorSpec {
    pub name: String,
    pub shape: Vec<usize>,
    pub offset: usize,
    pub len: usize,
    pub group: Group,
}

/// Named tensors over one flat buffer.
#[derive(Debug, Clone, Default)]
pub struct ParamSet {
    pub specs: Vec<TensorSpec>,
    pub data: Vec<f32>,
}

impl ParamSet {
    /// Append a tensor; `init(k)` gives its k-th value. Returns the tensor's offset.
    pub fn add(
        &mut self,
        name: &str,
        shape: &[usize],
        group: Group,
        mut init: impl FnMut(usize) -> f32,
    ) -> usize {
        let len: usize = shape.iter().product();
        let offset = self.data.len();
        self.data.extend((0..len).map(&mut init));
        self.specs.push(TensorSpec {
            name: name.to_string(),
            shape: shape.to_vec(),
            offset,
            len,
            group,
        });
        offset
    }

    pub fn spec(&self, name: &str) -> Option<&TensorSpec> {
        self.specs.iter().find(|s| s.name == name)
    }

    pub fn tensor(&self, name: &str) -> Option<&[f32]> {
        self.spec(name).map(|s| &self.data[s.offset..s.offset + s.len])
    }

    pub fn len(&self) -> usize {
        self.data.len()
    }

    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
}

//! One flat parameter vector for a whole model, cut into named groups.
//!
//! Every module (VM volume, MLP layer, embedding) allocates its tensors here and keeps their
//! offsets; gradients, Adam moments and checkpoints are flat vectors of the same layout. A group
//! carries the learning-rate class its tensors are optimised with (volumes vs networks).

use super::real::Real;
use std::ops::Range;

/// The learning-rate class of a tensor (the reference trains volumes and networks with
/// different rates).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum LrClass {
    /// Explicit grids (VM planes and lines).
    Volume,
    /// MLP weights, biases and the VM basis matrices.
    Network,
    /// Per-image embeddings and pose corrections (blur models).
    Embedding,
}

/// One named tensor in the flat vector.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    /// Dotted name, e.g. `coarse.density.0.w`.
    pub name: String,
    /// Position in the flat vector.
    pub range: Range<usize>,
    /// Learning-rate class.
    pub class: LrClass,
}

/// The layout of a model's parameters: the named tensors in allocation order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Layout {
    /// All tensors, contiguous and in allocation order.
    pub tensors: Vec<Tensor>,
}

impl Layout {
    /// Appends a tensor of `len` values and returns its offset.
    pub fn alloc(&mut self, name: impl Into<String>, len: usize, class: LrClass) -> usize {
        let start = self.len();
        self.tensors.push(Tensor { name: name.into(), range: start..start + len, class });
        start
    }

    /// Total number of parameters.
    pub fn len(&self) -> usize {
        self.tensors.last().map_or(0, |t| t.range.end)
    }

    /// True when no tensor has been allocated.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The tensor called `name`.
    pub fn get(&self, name: &str) -> Option<&Tensor> {
        self.tensors.iter().find(|t| t.name == name)
    }

    /// A zero vector of this layout (gradients, moments).
    pub fn zeros<R: Real>(&self) -> Vec<R> {
        vec![R::zero(); self.len()]
    }
}

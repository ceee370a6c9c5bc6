//! The flat parameter buffer holding every variable's value.

use crate::variable::Variable;

/// All variables' parameters in one buffer, indexed by vertex index.
///
/// Solvers back up and restore the state by copying [`Values::params`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Values {
    params: Vec<f64>,
    offsets: Vec<usize>,
}

impl Values {
    /// Appends a variable; returns its vertex index.
    pub(crate) fn push<V: Variable<D>, const D: usize>(&mut self, value: &V) -> usize {
        let off = self.params.len();
        self.params.resize(off + V::PARAMS, 0.0);
        value.write_params(&mut self.params[off..]);
        self.offsets.push(off);
        self.offsets.len() - 1
    }

    /// Number of variables.
    pub fn len(&self) -> usize {
        self.offsets.len()
    }

    /// Whether there are no variables.
    pub fn is_empty(&self) -> bool {
        self.offsets.is_empty()
    }

    /// The variable at `index` as type `V` (the caller knows its type).
    #[inline]
    pub fn get<V: Variable<D>, const D: usize>(&self, index: usize) -> V {
        let off = self.offsets[index];
        V::from_params(&self.params[off..off + V::PARAMS])
    }

    /// Overwrites the variable at `index`.
    pub fn set<V: Variable<D>, const D: usize>(&mut self, index: usize, value: &V) {
        let off = self.offsets[index];
        value.write_params(&mut self.params[off..off + V::PARAMS]);
    }

    /// The parameters of the variable at `index`.
    pub fn params_of(&self, index: usize) -> &[f64] {
        let end = self
            .offsets
            .get(index + 1)
            .copied()
            .unwrap_or(self.params.len());
        &self.params[self.offsets[index]..end]
    }

    /// Mutable parameters of the variable at `index`.
    pub fn params_of_mut(&mut self, index: usize) -> &mut [f64] {
        let end = self
            .offsets
            .get(index + 1)
            .copied()
            .unwrap_or(self.params.len());
        &mut self.params[self.offsets[index]..end]
    }

    /// All parameters, in vertex order.
    pub fn params(&self) -> &[f64] {
        &self.params
    }

    /// All parameters, mutable (for restoring a backup of the same graph).
    pub fn params_mut(&mut self) -> &mut [f64] {
        &mut self.params
    }
}

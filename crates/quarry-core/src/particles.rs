//! Particle-filter vocabulary: resamplers and landmark stores.

use crate::{CoreError, LandmarkId};
use rand_core::RngCore;

/// Draws ancestor indices from normalised particle weights.
pub trait Resampler {
    /// Returns `weights.len()` ancestor indices. The weights are linear (not log) and must sum
    /// to 1 within rounding; all-zero or non-finite weights are an error.
    fn ancestors(&self, weights: &[f64], rng: &mut dyn RngCore) -> Result<Vec<usize>, CoreError>;
}

/// A per-particle map of landmarks, indexed by dense [`LandmarkId`]s `0..len`.
///
/// `Clone` is what resampling calls: a persistent implementation makes it O(1) and shares
/// structure, so that writing one landmark costs O(log M).
pub trait LandmarkStore<T>: Clone {
    /// The landmark `id`, if present.
    fn get(&self, id: LandmarkId) -> Option<&T>;
    /// Replaces landmark `id`; an id `>= len()` is an error.
    fn set(&mut self, id: LandmarkId, value: T) -> Result<(), CoreError>;
    /// Appends a landmark and returns its id.
    fn push(&mut self, value: T) -> LandmarkId;
    /// Number of landmarks.
    fn len(&self) -> usize;
    /// True when there is no landmark.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

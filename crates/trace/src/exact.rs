//! The voxel-exact modes: density (optical depth summed voxel by voxel, so no step-size error),
//! the first-hit modes (depth, first-hit density, brick hue) and the step count. Each is a
//! `Visitor` of the hierarchical walk walked down to single voxels.

use crate::dda::Flow;
use crate::walk::{Holder, Visitor};

/// Optical depth (`absorb · τ`) beyond which a density ray stops: `T < 2.1e-9`.
pub const OPAQUE_DEPTH: f64 = 20.0;

/// Sums `τ = Σ max(v, 0) · length` over the voxels a ray crosses; counts traversal steps.
pub(crate) struct Density {
    /// Length units per unit of `t`.
    pub per_t: f64,
    pub absorb: f64,
    pub tau: f64,
    pub steps: u32,
}

impl Visitor for Density {
    fn skip(&self, max: f32) -> bool {
        // NaN never reaches here (the loader refuses it); `!(max > 0)` would skip it anyway.
        !(max > 0.0)
    }
    fn voxels(&self) -> bool {
        true
    }
    fn span(&mut self, ta: f64, tb: f64, v: f32, _: Holder) -> Flow {
        self.tau += v as f64 * (tb - ta) * self.per_t;
        if self.absorb * self.tau >= OPAQUE_DEPTH {
            Flow::Stop
        } else {
            Flow::Go
        }
    }
    fn count(&mut self) {
        self.steps += 1;
    }
}

/// The first span whose value exceeds `cutoff`.
pub(crate) struct FirstHit {
    pub cutoff: f32,
    /// `(t, value, holder)` of the hit.
    pub hit: Option<(f64, f32, Holder)>,
}

impl Visitor for FirstHit {
    fn skip(&self, max: f32) -> bool {
        !(max > self.cutoff)
    }
    fn voxels(&self) -> bool {
        true
    }
    fn span(&mut self, ta: f64, _tb: f64, v: f32, h: Holder) -> Flow {
        self.hit = Some((ta, v, h));
        Flow::Stop
    }
}

//! The voxel-exact modes: density (optical depth summed voxel by voxel, so no step-size error),
//! the first-hit modes (depth, first-hit density, brick hue) and the step count. Each is a
//! `Visitor` of the hierarchical walk walked down to single voxels.

use crate::dda::Flow;
use crate::walk::{Holder, Visitor};
use vdbcook_scene::{Emission, BLACKBODY_TABLE_LEN};

/// Optical depth (`absorb · τ`) beyond which a density ray stops: `T < 2.1e-9`.
pub const OPAQUE_DEPTH: f64 = 20.0;

/// Sums `τ = Σ max(v, 0) · length` over the voxels a ray crosses; counts traversal steps. With
/// emission, also the emitted light that reaches the eye: over a voxel segment of length `ℓ`
/// with value `v`, `T_before · E(v) · ℓ · φ(absorb·v·ℓ)`, `φ(x) = (1 − e^{−x})/x` (exact for a
/// constant segment).
pub(crate) struct Density<'e> {
    /// Length units per unit of `t`.
    pub per_t: f64,
    pub absorb: f64,
    pub tau: f64,
    pub steps: u32,
    pub emission: Option<(Emission, &'e [[f32; 4]; BLACKBODY_TABLE_LEN])>,
    /// Emitted radiance gathered so far.
    pub light: [f64; 3],
}

/// `(1 − e^{−x})/x`, its series below 1e-3 (where the quotient loses digits).
pub fn phi(x: f64) -> f64 {
    if x < 1e-3 {
        1.0 - x / 2.0 + x * x / 6.0
    } else {
        (1.0 - (-x).exp()) / x
    }
}

impl Visitor for Density<'_> {
    fn skip(&self, max: f32) -> bool {
        // NaN never reaches here (the loader refuses it); `!(max > 0)` would skip it anyway.
        !(max > 0.0)
    }
    fn voxels(&self) -> bool {
        true
    }
    fn span(&mut self, ta: f64, tb: f64, v: f32, _: Holder) -> Flow {
        let len = (tb - ta) * self.per_t;
        if let Some((e, table)) = &self.emission {
            let r = e.radiance(table, v);
            if r != [0.0; 3] {
                let w = (-self.absorb * self.tau).exp() * len * phi(self.absorb * v as f64 * len);
                for (l, r) in self.light.iter_mut().zip(r) {
                    *l += w * r as f64;
                }
            }
        }
        self.tau += v as f64 * len;
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

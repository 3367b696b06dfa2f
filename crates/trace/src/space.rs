//! Rays carried into cell space (index + ½, see `vdbcook_scene::Affine::cells`), keeping the
//! world-distance parameter, and their clip to a box.

use vdbcook_scene::length;

/// A ray in cell space (index + ½, see `vdbcook_scene::Affine::cells`), `p(t) = o + t·d`, where `t` is the
/// distance travelled in *world* units (the world direction was unit length); `per_t` converts
/// `t` to the chosen length unit.
#[derive(Debug, Clone, Copy)]
pub struct IndexRay {
    pub o: [f64; 3],
    pub d: [f64; 3],
    /// `1 / d` per axis (±∞ where `d` is 0; unused there).
    pub inv: [f64; 3],
    /// Length units per unit of `t` (voxels per world unit along this ray, or 1).
    pub per_t: f64,
}

impl IndexRay {
    /// `o` in cell space, `d` the cell-space image of a unit world direction.
    pub fn new(o: [f64; 3], d: [f64; 3], voxel_units: bool) -> IndexRay {
        let inv = d.map(|c| if c == 0.0 { f64::INFINITY } else { 1.0 / c });
        let per_t = if voxel_units { length(d) } else { 1.0 };
        IndexRay { o, d, inv, per_t }
    }

    #[inline(always)]
    pub fn at(&self, t: f64) -> [f64; 3] {
        [
            self.o[0] + t * self.d[0],
            self.o[1] + t * self.d[1],
            self.o[2] + t * self.d[2],
        ]
    }

    /// The `t` interval (from `t ≥ 0`) inside the half-open box `[0, ext)`; `None` if empty. An
    /// axis the ray does not move along must hold the origin inside `[0, ext)`.
    pub fn clip(&self, ext: [f64; 3]) -> Option<(f64, f64)> {
        self.clip_box([0.0; 3], ext)
    }

    /// The same ray in a cell space scaled by `s` (a level of detail: `s = 2^−k`, exact in
    /// binary), keeping `t` and `per_t`.
    pub fn scaled(&self, s: f64) -> IndexRay {
        IndexRay {
            o: self.o.map(|c| c * s),
            d: self.d.map(|c| c * s),
            inv: self.inv.map(|c| c / s),
            per_t: self.per_t,
        }
    }

    /// The `t` interval (from `t ≥ 0`) inside the half-open box `[lo, hi)`; `None` if empty. An
    /// axis the ray does not move along must hold the origin inside `[lo, hi)`.
    pub fn clip_box(&self, lo: [f64; 3], hi: [f64; 3]) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for i in 0..3 {
            if self.d[i] == 0.0 {
                if !(self.o[i] >= lo[i] && self.o[i] < hi[i]) {
                    return None;
                }
            } else {
                let a = (lo[i] - self.o[i]) * self.inv[i];
                let b = (hi[i] - self.o[i]) * self.inv[i];
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        (t1 > t0 && t1.is_finite()).then_some((t0, t1))
    }
}

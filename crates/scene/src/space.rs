//! From world space to the tracers' cell space: the inverse of `index_to_world` shifted by half a
//! voxel (OpenVDB centres voxel `i` on index `i`; the walks want voxel `i` to be the unit cell
//! `[i, i+1)`), the depth range of a box seen from an eye, and the few vector helpers both need.

use crate::TraceError;

/// An affine map `x ↦ A·x + b` and its inverse.
#[derive(Debug, Clone, Copy)]
pub struct Affine {
    pub a: [[f64; 3]; 3],
    pub b: [f64; 3],
    pub inv_a: [[f64; 3]; 3],
}

/// `m · v`.
pub fn mul3(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2])
}

/// Euclidean length.
pub fn length(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `v / |v|` (NaN for the zero vector: callers check the length first).
pub fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = length(v);
    v.map(|c| c / n)
}

impl Affine {
    /// From a row-major, column-vector 4×4 (`world = M · [i j k 1]ᵀ`). Refuses a projective last
    /// row, non-finite entries and a (nearly) singular linear part.
    pub fn from_matrix(m: &[[f64; 4]; 4]) -> Result<Affine, TraceError> {
        if m.iter().flatten().any(|v| !v.is_finite()) {
            return Err(TraceError::Transform("non-finite entry".into()));
        }
        if m[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(TraceError::Transform(format!(
                "last row {:?} is not [0 0 0 1] (frustum maps are not supported)",
                m[3]
            )));
        }
        let a = [0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2]]);
        let b = [m[0][3], m[1][3], m[2][3]];
        // Inverse by the adjugate: inv = adj(A) / det(A).
        let c = |r: usize, k: usize| {
            let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
            let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
            a[r1][k1] * a[r2][k2] - a[r1][k2] * a[r2][k1]
        };
        let det = a[0][0] * c(0, 0) + a[0][1] * c(0, 1) + a[0][2] * c(0, 2);
        let scale = a.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
        if !(det.abs() > 1e-12 * scale * scale * scale) || scale == 0.0 {
            return Err(TraceError::Transform(format!("singular (det {det:e})")));
        }
        // adj(A)[r][k] = cofactor(k, r).
        let inv_a = [0, 1, 2].map(|r| [0, 1, 2].map(|k| c(k, r) / det));
        Ok(Affine { a, b, inv_a })
    }

    /// The map from the tracer's **cell space** to world for an asset whose `index_to_world` is
    /// `m`. OpenVDB puts the value of voxel `i` at `m · i` (its nearest-point sampler rounds, so
    /// the voxel covers `[i − ½, i + ½)` of index space); the walk wants voxel `i` to be the cell
    /// `[i, i + 1)`, so cell point `c` is index point `c − ½`: `world = m · (c − ½)`. Every ray
    /// the tracers (CPU and GPU) carry from world space goes through this map; nothing else in
    /// them knows about the half voxel.
    pub fn cells(m: &[[f64; 4]; 4]) -> Result<Affine, TraceError> {
        let mut xf = Affine::from_matrix(m)?;
        let h = mul3(&xf.a, [0.5; 3]);
        xf.b = [0, 1, 2].map(|i| xf.b[i] - h[i]);
        Ok(xf)
    }

    pub fn world_of(&self, p: [f64; 3]) -> [f64; 3] {
        let v = mul3(&self.a, p);
        [0, 1, 2].map(|i| v[i] + self.b[i])
    }

    pub fn index_of(&self, w: [f64; 3]) -> [f64; 3] {
        mul3(&self.inv_a, [0, 1, 2].map(|i| w[i] - self.b[i]))
    }

    pub fn dir_to_index(&self, d: [f64; 3]) -> [f64; 3] {
        mul3(&self.inv_a, d)
    }
}

/// World distances mapped to white (`near`) and black (`far`) in `Depth` mode: the nearest and
/// farthest world corner of the index-space box `bbox` (`[lo, hi)`) from `eye` (world), `near`
/// = 0 with the eye inside the box, and `far = near + 1` if the two would not differ.
pub fn depth_range(xf: &Affine, bbox: ([f64; 3], [f64; 3]), eye: [f64; 3]) -> [f64; 2] {
    let (lo, hi) = bbox;
    let (mut near, mut far) = (f64::INFINITY, 0.0f64);
    for c in 0..8 {
        let p = [0, 1, 2].map(|a| if c >> a & 1 == 0 { lo[a] } else { hi[a] });
        let w = xf.world_of(p);
        let d = length([0, 1, 2].map(|a| w[a] - eye[a]));
        near = near.min(d);
        far = far.max(d);
    }
    let e = xf.index_of(eye);
    if (0..3).all(|a| e[a] >= lo[a] && e[a] < hi[a]) {
        near = 0.0;
    }
    if !(far > near) {
        far = near + 1.0;
    }
    [near, far]
}

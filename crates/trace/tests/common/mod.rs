//! Helpers of the tracer tests: the hand-built assets (from the test kit, shared with the
//! runtime's tests), box-shaped content, and exact slab lengths to check ray integrals against.
#![allow(dead_code)]

pub use vdbcook_testkit::*;

use std::collections::BTreeMap;

use vdbcook_asset::*;
use vdbcook_scene::Camera;

/// Leaves covering the half-open index box `[lo, hi)` with density `v` (0 outside the box):
/// leaves entirely inside alternate between tile and constant brick (by leaf parity), partial
/// leaves are bricks.
pub fn box_leaves(lo: [i64; 3], hi: [i64; 3], v: f32, leaves: &mut BTreeMap<[i64; 3], Leaf>) {
    let l0 = lo.map(|c| c.div_euclid(8));
    let l1 = hi.map(|c| (c - 1).div_euclid(8));
    for lz in l0[2]..=l1[2] {
        for ly in l0[1]..=l1[1] {
            for lx in l0[0]..=l1[0] {
                let o = [lx * 8, ly * 8, lz * 8];
                let inside = (0..3).all(|a| o[a] >= lo[a] && o[a] + 8 <= hi[a]);
                let leaf = if inside && (lx + ly + lz) % 2 == 0 {
                    Leaf::Tile(v)
                } else {
                    let mut vals = vec![0.0f32; BRICK_VOXELS];
                    for (i, val) in vals.iter_mut().enumerate() {
                        let p = [
                            o[0] + (i / 64) as i64,
                            o[1] + (i / 8 % 8) as i64,
                            o[2] + (i % 8) as i64,
                        ];
                        if (0..3).all(|a| p[a] >= lo[a] && p[a] < hi[a]) {
                            *val = v;
                        }
                    }
                    Leaf::Brick(vals)
                };
                leaves.insert(o, leaf);
            }
        }
    }
}

/// `[lo, hi)` ∩ ray `o + t d` for `t ≥ 0`: the length of the parameter interval (0 if empty);
/// a zero direction component must have `lo ≤ o < hi`.
pub fn slab_length(o: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] >= hi[a] {
                return 0.0;
            }
        } else {
            let u = (lo[a] - o[a]) / d[a];
            let v = (hi[a] - o[a]) / d[a];
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
    }
    (t1 - t0).max(0.0)
}

/// `[lo, hi)` ∩ ray for `t ≥ 0` as a parameter interval, if not empty.
pub fn slab_interval(o: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] >= hi[a] {
                return None;
            }
        } else {
            let u = (lo[a] - o[a]) / d[a];
            let v = (hi[a] - o[a]) / d[a];
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
    }
    (t1 > t0).then_some((t0, t1))
}

/// index → world = R_z(deg) · diag(sc) · index + t, with its closed-form inverse.
#[derive(Clone, Copy)]
pub struct RotScale {
    pub deg: f64,
    pub sc: [f64; 3],
    pub t: [f64; 3],
}

impl RotScale {
    pub fn matrix(self) -> [[f64; 4]; 4] {
        rotated(self.deg, self.sc, self.t)
    }
    pub fn to_world(self, p: [f64; 3]) -> [f64; 3] {
        let (sn, c) = self.deg.to_radians().sin_cos();
        let q = [p[0] * self.sc[0], p[1] * self.sc[1], p[2] * self.sc[2]];
        [
            c * q[0] - sn * q[1] + self.t[0],
            sn * q[0] + c * q[1] + self.t[1],
            q[2] + self.t[2],
        ]
    }
    pub fn dir_to_index(self, d: [f64; 3]) -> [f64; 3] {
        let (sn, c) = self.deg.to_radians().sin_cos();
        [
            (c * d[0] + sn * d[1]) / self.sc[0],
            (-sn * d[0] + c * d[1]) / self.sc[1],
            d[2] / self.sc[2],
        ]
    }
    pub fn to_index(self, p: [f64; 3]) -> [f64; 3] {
        self.dir_to_index([p[0] - self.t[0], p[1] - self.t[1], p[2] - self.t[2]])
    }
}

/// The constant box the closed-form tests share: voxels `BOX_LO ..= BOX_HI − 1` (two root
/// regions along x) of value `v`, tiles and constant and partial bricks (`box_leaves`), under
/// `index → world = BOX_S · index + BOX_T`, f32 bricks.
pub const BOX_LO: [i64; 3] = [100, 6, 20];
pub const BOX_HI: [i64; 3] = [150, 37, 53];
pub const BOX_S: f64 = 0.5;
pub const BOX_T: [f64; 3] = [1.0, 2.0, 3.0];

pub fn constant_box(v: f32) -> Asset {
    boxes(&[(BOX_LO, BOX_HI, v)])
}

/// [`constant_box`]'s transform: `index → world = BOX_S · index + BOX_T`.
pub fn box_xf() -> [[f64; 4]; 4] {
    [
        [BOX_S, 0.0, 0.0, BOX_T[0]],
        [0.0, BOX_S, 0.0, BOX_T[1]],
        [0.0, 0.0, BOX_S, BOX_T[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// Constant boxes `[lo, hi)` of value `v` (each in leaves of its own: a later box replaces the
/// leaves it shares with an earlier one) under [`constant_box`]'s transform, f32.
pub fn boxes(list: &[([i64; 3], [i64; 3], f32)]) -> Asset {
    let mut f = FrameSpec::default();
    for &(lo, hi, v) in list {
        box_leaves(lo, hi, v, &mut f.leaves);
    }
    build([2, 1, 1], box_xf(), 0.0, &[f], PayloadFormat::F32)
}

/// A porous medium on the whole leaves of `[lo, hi)` (multiples of 8): each voxel holds `v`
/// or nothing, by [`porous_voxel`] (about half of them full), under [`constant_box`]'s
/// transform, f32 bricks. Its shadows vary from voxel to voxel, which a light volume's cells
/// see only as samples.
pub fn porous(lo: [i64; 3], hi: [i64; 3], v: f32) -> Asset {
    let mut f = FrameSpec::default();
    for lz in (lo[2]..hi[2]).step_by(8) {
        for ly in (lo[1]..hi[1]).step_by(8) {
            for lx in (lo[0]..hi[0]).step_by(8) {
                let vals = (0..BRICK_VOXELS)
                    .map(|i| {
                        let p = [
                            lx + (i / 64) as i64,
                            ly + (i / 8 % 8) as i64,
                            lz + (i % 8) as i64,
                        ];
                        if porous_voxel(p) {
                            v
                        } else {
                            0.0
                        }
                    })
                    .collect();
                f.leaves.insert([lx, ly, lz], Leaf::Brick(vals));
            }
        }
    }
    build([2, 1, 1], box_xf(), 0.0, &[f], PayloadFormat::F32)
}

/// Whether voxel `p` of [`porous`] is full (a hash of its index).
pub fn porous_voxel(p: [i64; 3]) -> bool {
    let mut h = (p[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (p[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (p[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    h & 1 == 1
}

/// Cell point → world under [`constant_box`]'s transform (voxel `i` is the cell `[i, i+1)`,
/// centred on world `BOX_S·i + BOX_T`).
pub fn box_world(p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| (p[a] - 0.5) * BOX_S + BOX_T[a])
}

/// The centre of [`constant_box`] in cell space.
pub fn box_centre() -> [f64; 3] {
    [0, 1, 2].map(|a| (BOX_LO[a] + BOX_HI[a]) as f64 / 2.0)
}

/// A camera in front of [`constant_box`] (−z side, 40 world units) looking at its centre.
pub fn box_camera() -> Camera {
    let c = box_world(box_centre());
    Camera {
        eye: [c[0], c[1], c[2] - 40.0],
        look_at: c,
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 40.0,
    }
}

/// Single scattering along the axis of a slab of depth `depth` voxels, extinction `kappa` per
/// voxel, albedo `albedo`, a sun of irradiance `e` with one Henyey–Greenstein lobe `g`: the
/// radiance with the sun straight behind the camera (scattering cosine −1, shadow path from
/// depth s is s), `α·p(−1)·E·(1 − e^{−2κD})/2`, and straight ahead (cosine +1, shadow path
/// D − s), `α·p(1)·E·κD·e^{−κD}`.
pub fn single_scatter_closed_forms(
    g: f64,
    albedo: f64,
    e: f64,
    kappa: f64,
    depth: f64,
) -> [f64; 2] {
    let hg = |mu: f64| {
        (1.0 - g * g) / (4.0 * std::f64::consts::PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
    };
    [
        albedo * hg(-1.0) * e * (1.0 - (-2.0 * kappa * depth).exp()) / 2.0,
        albedo * hg(1.0) * e * kappa * depth * (-kappa * depth).exp(),
    ]
}

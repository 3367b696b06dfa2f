//! What a render is asked to do — the pinhole camera, the mode and the medium settings — and the
//! CPU-side math that turns them into the tracer's uniform: the camera basis, the inverse of
//! `index_to_world`, the default framing. The runtime keeps its own small types (it must not
//! depend on the CPU tracer); their fields and definitions match `vdbcook_trace`'s one for one,
//! so the same camera and settings give the same image on both.

use crate::RuntimeError;

/// A pinhole camera in world space (image row 0 at the top; `up` need not be orthogonal to the
/// view). Same definition as `vdbcook_trace::Camera`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub eye: [f64; 3],
    pub look_at: [f64; 3],
    pub up: [f64; 3],
    pub fov_y_deg: f64,
}

/// What a pixel shows (definitions: `vdbcook_trace`'s crate docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    Density,
    Depth,
    FirstHitDensity,
    BrickHue,
    Steps,
    /// Not implemented on the GPU yet ([`RuntimeError::Unsupported`]).
    SingleScatter,
    /// Not implemented on the GPU yet ([`RuntimeError::Unsupported`]).
    DeltaTracking,
}

impl Mode {
    /// The modes the GPU tracer implements.
    pub const GPU: [Mode; 5] = [
        Mode::Density,
        Mode::Depth,
        Mode::FirstHitDensity,
        Mode::BrickHue,
        Mode::Steps,
    ];
    /// The shader's mode number.
    pub(crate) fn code(self) -> Option<u32> {
        match self {
            Mode::Density => Some(0),
            Mode::Depth => Some(1),
            Mode::FirstHitDensity => Some(2),
            Mode::BrickHue => Some(3),
            Mode::Steps => Some(4),
            Mode::SingleScatter | Mode::DeltaTracking => None,
        }
    }
}

/// The length that `absorb`, `scatter`, `step`, `shadow_step` and `gain` are measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LengthUnit {
    /// Index-space length (one voxel edge = 1), as `vdb_render`.
    Voxel,
    /// World-space length.
    World,
}

/// Everything but the camera, the frame and the image size (the target's). Field meanings and
/// defaults as `vdbcook_trace::RenderSettings`.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    pub mode: Mode,
    pub absorb: f32,
    pub scatter: f32,
    pub light_dir: [f32; 3],
    pub light_color: [f32; 3],
    pub step: f32,
    pub shadow_step: f32,
    pub cutoff: f32,
    pub gain: f32,
    pub spp: u32,
    pub first_sample: u32,
    pub seed: u32,
    pub unit: LengthUnit,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            mode: Mode::Density,
            absorb: 0.1,
            scatter: 1.5,
            light_dir: [0.3, 0.3, 0.0],
            light_color: [0.7, 0.7, 0.7],
            step: 1.0,
            shadow_step: 3.0,
            cutoff: 0.005,
            gain: 0.2,
            spp: 16,
            first_sample: 0,
            seed: 1,
            unit: LengthUnit::Voxel,
        }
    }
}

/// Largest image side accepted (as the CPU tracer).
pub const MAX_SIDE: u32 = 16384;
/// Smallest march step accepted.
pub const MIN_STEP: f32 = 1e-3;

impl Settings {
    /// Refuses settings that would leave a loop unbounded or put NaN into a pixel (the CPU
    /// tracer's rules), and modes the GPU does not implement.
    pub fn validate(&self) -> Result<(), RuntimeError> {
        let bad = |m: String| Err(RuntimeError::Setting(m));
        for (name, v) in [
            ("absorb", self.absorb),
            ("scatter", self.scatter),
            ("cutoff", self.cutoff),
            ("gain", self.gain),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} = {v} (must be finite and ≥ 0)"));
            }
        }
        for (name, v) in [("step", self.step), ("shadow-step", self.shadow_step)] {
            if !(v.is_finite() && v >= MIN_STEP) {
                return bad(format!("{name} = {v} (must be ≥ {MIN_STEP})"));
            }
        }
        if self
            .light_color
            .iter()
            .any(|c| !(c.is_finite() && *c >= 0.0))
        {
            return bad(format!("light colour {:?}", self.light_color));
        }
        let l = self.light_dir;
        let n = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        if !(n.is_finite() && n > 1e-6) {
            return bad(format!("light direction {l:?} has no direction"));
        }
        if self.spp == 0 || self.spp > 1 << 16 {
            return bad(format!("spp = {} (1..=65536)", self.spp));
        }
        if self.mode.code().is_none() {
            return Err(RuntimeError::Unsupported(format!(
                "mode {:?} (GPU modes: {:?})",
                self.mode,
                Mode::GPU
            )));
        }
        Ok(())
    }
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub(crate) fn length(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}
pub(crate) fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = length(v);
    v.map(|c| c / n)
}
fn dot(p: [f64; 3], q: [f64; 3]) -> f64 {
    p[0] * q[0] + p[1] * q[1] + p[2] * q[2]
}

/// The camera's basis for a `width × height` image: pixel `(i, j)` looks along
/// `normalize(forward + (2(i+½)/W − 1)·right + (1 − 2(j+½)/H)·up)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Basis {
    pub forward: [f64; 3],
    pub right: [f64; 3],
    pub up: [f64; 3],
}

impl Camera {
    /// The basis (same rules as the CPU tracer: an `up` parallel to the view uses +Z, then +X).
    pub(crate) fn basis(&self, width: u32, height: u32) -> Result<Basis, RuntimeError> {
        let all = self.eye.iter().chain(&self.look_at).chain(&self.up);
        if all.clone().any(|v| !v.is_finite()) || !self.fov_y_deg.is_finite() {
            return Err(RuntimeError::Camera(format!(
                "non-finite value in {self:?}"
            )));
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 179.0) {
            return Err(RuntimeError::Camera(format!(
                "fov {} (must be in (0, 179) degrees)",
                self.fov_y_deg
            )));
        }
        let f = [0, 1, 2].map(|i| self.look_at[i] - self.eye[i]);
        if !(length(f) > 0.0) {
            return Err(RuntimeError::Camera("eye and look-at coincide".into()));
        }
        let forward = normalize(f);
        let mut right = [0.0; 3];
        for up in [self.up, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]] {
            let r = cross(forward, up);
            if length(r) > 1e-9 * length(up).max(1e-300) {
                right = normalize(r);
                break;
            }
        }
        let up = cross(right, forward);
        let h = (self.fov_y_deg.to_radians() * 0.5).tan();
        let w = h * width as f64 / height as f64;
        Ok(Basis {
            forward,
            right: right.map(|c| c * w),
            up: up.map(|c| c * h),
        })
    }

    /// The default view of an index-space box (`[lo, hi)`) under `index_to_world`: seen from the
    /// direction (1, 0.6, 1.4) off its centre (Y up), 40° vertical field of view, just far enough
    /// that every corner projects within 80% of the image half-extents — the CPU tracer's
    /// `Camera::framing` applied to the box [`crate::GpuVolume::frame_bbox`] returns.
    pub fn framing_box(
        index_to_world: &[[f64; 4]; 4],
        bbox: ([f64; 3], [f64; 3]),
        aspect: f64,
    ) -> Result<Camera, RuntimeError> {
        let xf = Affine::from_matrix(index_to_world)?;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for c in 0..8 {
            let p = [0, 1, 2].map(|a| {
                if c >> a & 1 == 0 {
                    bbox.0[a]
                } else {
                    bbox.1[a]
                }
            });
            let w = xf.world_of(p);
            for a in 0..3 {
                lo[a] = lo[a].min(w[a]);
                hi[a] = hi[a].max(w[a]);
            }
        }
        let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
        let fov_y_deg: f64 = 40.0;
        let aspect = if aspect.is_finite() && aspect > 0.0 {
            aspect
        } else {
            1.0
        };
        let half_y = (fov_y_deg.to_radians() * 0.5).tan();
        let half = [half_y * aspect, half_y].map(|h| 0.8 * h);
        let dir = normalize([1.0, 0.6, 1.4]);
        let probe = Camera {
            eye: [0, 1, 2].map(|a| centre[a] + dir[a]),
            look_at: centre,
            up: [0.0, 1.0, 0.0],
            fov_y_deg,
        };
        let b = probe.basis(1, 1)?;
        let (r, u) = (normalize(b.right), normalize(b.up));
        let mut dist = 1e-9f64;
        for c in 0..8 {
            let p = [0, 1, 2].map(|a| if c >> a & 1 == 0 { lo[a] } else { hi[a] } - centre[a]);
            let z = dot(p, b.forward);
            dist = dist
                .max(dot(p, r).abs() / half[0] - z)
                .max(dot(p, u).abs() / half[1] - z)
                .max(-z * 1.01);
        }
        Ok(Camera {
            eye: [0, 1, 2].map(|a| centre[a] + dist * dir[a]),
            look_at: centre,
            up: [0.0, 1.0, 0.0],
            fov_y_deg,
        })
    }
}

/// An affine map `x ↦ A·x + b` and its inverse (from a row-major, column-vector 4×4).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Affine {
    pub a: [[f64; 3]; 3],
    pub b: [f64; 3],
    pub inv_a: [[f64; 3]; 3],
}

impl Affine {
    /// Refuses a projective last row, non-finite entries and a (nearly) singular linear part.
    pub fn from_matrix(m: &[[f64; 4]; 4]) -> Result<Affine, RuntimeError> {
        if m.iter().flatten().any(|v| !v.is_finite()) {
            return Err(RuntimeError::Transform("non-finite entry".into()));
        }
        if m[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(RuntimeError::Transform(format!(
                "last row {:?} is not [0 0 0 1]",
                m[3]
            )));
        }
        let a = [0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2]]);
        let b = [m[0][3], m[1][3], m[2][3]];
        let c = |r: usize, k: usize| {
            let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
            let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
            a[r1][k1] * a[r2][k2] - a[r1][k2] * a[r2][k1]
        };
        let det = a[0][0] * c(0, 0) + a[0][1] * c(0, 1) + a[0][2] * c(0, 2);
        let scale = a.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
        if !(det.abs() > 1e-12 * scale * scale * scale) || scale == 0.0 {
            return Err(RuntimeError::Transform(format!("singular (det {det:e})")));
        }
        let inv_a = [0, 1, 2].map(|r| [0, 1, 2].map(|k| c(k, r) / det));
        Ok(Affine { a, b, inv_a })
    }

    pub fn world_of(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|r| dot(self.a[r], p) + self.b[r])
    }

    pub fn index_of(&self, w: [f64; 3]) -> [f64; 3] {
        let v = [0, 1, 2].map(|i| w[i] - self.b[i]);
        [0, 1, 2].map(|r| dot(self.inv_a[r], v))
    }
}

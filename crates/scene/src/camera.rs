//! The pinhole camera (eye, look-at, up, vertical field of view), its primary rays, and the
//! default view that frames a frame's stored bounding box from a three-quarter direction. The GPU
//! runtime (`vdbcook-runtime`) uses these same definitions for its uniform and its framing.

use vdbcook_asset::{Asset, LeafRef, BRICK_VOXELS, EMPTY, L2_SPAN, TILE_BIT};

use crate::space::{length, normalize, Affine};
use crate::TraceError;

/// A pinhole camera in world space. Image row 0 is the top; `up` need not be orthogonal to the
/// view direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub eye: [f64; 3],
    pub look_at: [f64; 3],
    pub up: [f64; 3],
    pub fov_y_deg: f64,
}

/// The camera's orthonormal basis, scaled by the half-extents of the image plane at distance 1.
#[derive(Debug, Clone, Copy)]
pub struct Basis {
    pub forward: [f64; 3],
    pub right: [f64; 3],
    pub up: [f64; 3],
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

impl Camera {
    /// The basis for an image of `width × height`: pixel `(i, j)` looks along
    /// `forward + (2(i+½)/W − 1)·right + (1 − 2(j+½)/H)·up`, normalized, where `|up| = tan(fov/2)`
    /// and `|right| = |up| · W/H`. An `up` parallel to the view uses world +Z instead (+X if that
    /// is parallel too).
    pub fn basis(&self, width: u32, height: u32) -> Result<Basis, TraceError> {
        let all = self.eye.iter().chain(&self.look_at).chain(&self.up);
        if all.clone().any(|v| !v.is_finite()) || !self.fov_y_deg.is_finite() {
            return Err(TraceError::Camera(format!("non-finite value in {self:?}")));
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 179.0) {
            return Err(TraceError::Camera(format!(
                "fov {} (must be in (0, 179) degrees)",
                self.fov_y_deg
            )));
        }
        let f = [0, 1, 2].map(|i| self.look_at[i] - self.eye[i]);
        if !(length(f) > 0.0) {
            return Err(TraceError::Camera("eye and look-at coincide".into()));
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

    /// Unit world direction of the ray through the centre of pixel `(i, j)`.
    pub fn ray_dir(&self, i: u32, j: u32, width: u32, height: u32) -> Result<[f64; 3], TraceError> {
        Ok(self.basis(width, height)?.dir(i, j, width, height))
    }

    /// The default view of `frame`: seen from the direction (1, 0.6, 1.4) off the centre of
    /// the world bounding box of its stored content (Y up) with a 40° vertical field of view,
    /// just far enough that every corner of every stored box ([`stored_boxes`]: tiled regions,
    /// tile leaves, each brick's non-background voxels) projects within 80% of the image's
    /// half-width and half-height — so the content, not its bounding box, fills the frame.
    /// A frame that stores nothing is framed by the stored bounding boxes of all frames, or the
    /// root extent when no frame stores anything.
    pub fn framing(asset: &Asset, frame: usize, aspect: f64) -> Result<Camera, TraceError> {
        Camera::framing_up(asset, frame, aspect, [0.0, 1.0, 0.0])
    }

    /// [`Camera::framing`] in a world whose up axis is `up` (one of ±X, ±Y, ±Z: Blender's
    /// volumes are Z-up): the same three-quarter view, turned so that `up` is up.
    pub fn framing_up(
        asset: &Asset,
        frame: usize,
        aspect: f64,
        up: [f64; 3],
    ) -> Result<Camera, TraceError> {
        if frame >= asset.frame_count() {
            return Err(TraceError::Frame {
                frame,
                frames: asset.frame_count(),
            });
        }
        let mut boxes = stored_boxes(asset, frame);
        if boxes.is_empty() {
            // One box per frame (their stored bounding boxes): a long sequence's every brick
            // would be a large list for a fallback.
            boxes = (0..asset.frame_count())
                .filter_map(|f| stored_bbox(asset, f))
                .collect();
        }
        if boxes.is_empty() {
            boxes.push(([0.0; 3], asset.header.root_dims.map(|d| d as f64 * 128.0)));
        }
        Camera::framing_boxes(&asset.header.index_to_world, &boxes, aspect, up)
    }

    /// The default view of the index-space box `bbox` (`[lo, hi)`) under `index_to_world`: as
    /// [`Camera::framing`] with the box's eight corners as the content.
    pub fn framing_box(
        index_to_world: &[[f64; 4]; 4],
        bbox: ([f64; 3], [f64; 3]),
        aspect: f64,
    ) -> Result<Camera, TraceError> {
        Camera::framing_boxes(index_to_world, &[bbox], aspect, [0.0, 1.0, 0.0])
    }

    /// The default view of the corners of cell-space boxes under `index_to_world`: looking at
    /// the centre of their world bounding box from the direction (1, 0.6, 1.4) (Y up, 40°
    /// vertical field of view), just far enough that each corner projects within 80% of the
    /// image's half-extents and lies in front of the eye.
    fn framing_boxes(
        index_to_world: &[[f64; 4]; 4],
        boxes: &[([f64; 3], [f64; 3])],
        aspect: f64,
        up: [f64; 3],
    ) -> Result<Camera, TraceError> {
        let xf = Affine::cells(index_to_world)?;
        let points = || {
            boxes
                .iter()
                .flat_map(|b| corners(*b))
                .map(|p| xf.world_of(p))
        };
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for w in points() {
            lo = min3(lo, w);
            hi = max3(hi, w);
        }
        let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
        let fov_y_deg: f64 = 40.0;
        let aspect = if aspect.is_finite() && aspect > 0.0 {
            aspect
        } else {
            1.0
        };
        let half_y = (fov_y_deg.to_radians() * 0.5).tan();
        let half = [half_y * aspect, half_y].map(|h| FILL * h);
        // The eye looks at the centre from `dir`; put it just far enough that each point
        // projects within FILL of the image half-extents: for a point at (x, y) across and z
        // along the view (from the centre), |x| ≤ half·(dist + z).
        let dir = normalize(up_frame([1.0, 0.6, 1.4], up));
        let up = up_frame([0.0, 1.0, 0.0], up);
        let probe = Camera {
            eye: [0, 1, 2].map(|a| centre[a] + dir[a]),
            look_at: centre,
            up,
            fov_y_deg,
        };
        let b = probe.basis(1, 1)?;
        let (r, u) = (normalize(b.right), normalize(b.up));
        let dot = |p: [f64; 3], q: [f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        let mut dist = 1e-9f64;
        for w in points() {
            let p = [0, 1, 2].map(|a| w[a] - centre[a]);
            let z = dot(p, b.forward);
            dist = dist
                .max(dot(p, r).abs() / half[0] - z)
                .max(dot(p, u).abs() / half[1] - z)
                // Every point in front of the eye.
                .max(-z * 1.01);
        }
        Ok(Camera {
            eye: [0, 1, 2].map(|a| centre[a] + dist * dir[a]),
            look_at: centre,
            up,
            fov_y_deg,
        })
    }
}

/// The world's up axis by the source's convention (`SourceInfo::up`): Z for Blender's files,
/// else Y.
pub fn source_up(asset: &Asset) -> [f64; 3] {
    match asset.header.source.up.as_str() {
        "z" => [0.0, 0.0, 1.0],
        "x" => [1.0, 0.0, 0.0],
        _ => [0.0, 1.0, 0.0],
    }
}

/// `v` of a Y-up world turned (by a rotation) into the world whose up axis is `up`, the
/// axis-aligned unit vector it is nearest to (Y when `up` is not finite or zero).
pub fn up_frame(v: [f64; 3], up: [f64; 3]) -> [f64; 3] {
    let a = (0..3)
        .max_by(|&i, &j| up[i].abs().total_cmp(&up[j].abs()))
        .unwrap_or(1);
    if !(up[a].abs() > 0.0 && up[a].is_finite()) {
        return v;
    }
    let neg = up[a] < 0.0;
    let [x, y, z] = v;
    match (a, neg) {
        (0, false) => [y, -x, z],
        (0, true) => [-y, x, z],
        (2, false) => [x, -z, y],
        (2, true) => [x, z, -y],
        (_, true) => [x, -y, -z],
        _ => v,
    }
}

/// The inverse of [`up_frame`]: `v` of the world whose up axis is `up` in the Y-up frame.
pub fn from_up_frame(v: [f64; 3], up: [f64; 3]) -> [f64; 3] {
    let col = |e: [f64; 3]| up_frame(e, up);
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    [
        dot(col([1.0, 0.0, 0.0]), v),
        dot(col([0.0, 1.0, 0.0]), v),
        dot(col([0.0, 0.0, 1.0]), v),
    ]
}

/// The eight corners of a box.
fn corners((lo, hi): ([f64; 3], [f64; 3])) -> impl Iterator<Item = [f64; 3]> {
    (0..8).map(move |c| [0, 1, 2].map(|a| if c >> a & 1 == 0 { lo[a] } else { hi[a] }))
}

impl Basis {
    /// The unit world direction of pixel `(i, j)` of a `width`×`height` image (the camera
    /// contract in `vdbcook-trace`'s docs: row 0 at the top, through the pixel centre).
    #[inline]
    pub fn dir(&self, i: u32, j: u32, width: u32, height: u32) -> [f64; 3] {
        let x = 2.0 * (i as f64 + 0.5) / width as f64 - 1.0;
        let y = 1.0 - 2.0 * (j as f64 + 0.5) / height as f64;
        normalize([0, 1, 2].map(|a| self.forward[a] + x * self.right[a] + y * self.up[a]))
    }
}

/// Fraction of the image half-extents the default view's box may reach.
const FILL: f64 = 0.8;

fn min3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| a[i].min(b[i]))
}
fn max3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| a[i].max(b[i]))
}

/// Cell-space box `[lo, hi)` of what `frame` stores: the union of [`stored_boxes`]; `None` for
/// an empty frame.
pub fn stored_bbox(asset: &Asset, frame: usize) -> Option<([f64; 3], [f64; 3])> {
    stored_boxes(asset, frame)
        .into_iter()
        .reduce(|a, b| (min3(a.0, b.0), max3(a.1, b.1)))
}

/// Cell-space boxes `[lo, hi)` of what `frame` stores other than the background: each tiled
/// region and tile leaf whose value is not the background, and per brick the box of its voxels
/// that differ from the background, found through
/// `root_entry` / `leaf_at` (16³ probes per L2 node) and `decode_brick`.
pub fn stored_boxes(asset: &Asset, frame: usize) -> Vec<([f64; 3], [f64; 3])> {
    let d = asset.header.root_dims.map(|x| x as i64);
    let span = L2_SPAN as i64;
    let background = asset.header.background;
    let mut boxes = Vec::new();
    let mut values = [0.0f32; BRICK_VOXELS];
    let cube = |o: [i64; 3], size: i64| (o.map(|c| c as f64), o.map(|c| (c + size) as f64));
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                let o = [x * span, y * span, z * span];
                let e = asset.root_entry(frame, o);
                if e == EMPTY {
                    continue;
                }
                if e & TILE_BIT != 0 {
                    if asset.tiles[(e & !TILE_BIT) as usize] != background {
                        boxes.push(cube(o, span));
                    }
                    continue;
                }
                for s in 0..16 * 16 * 16i64 {
                    let l = [
                        o[0] + 8 * (s % 16),
                        o[1] + 8 * (s / 16 % 16),
                        o[2] + 8 * (s / 256),
                    ];
                    match asset.leaf_at(frame, l) {
                        LeafRef::Empty => {}
                        LeafRef::Tile(v) if v != background => boxes.push(cube(l, 8)),
                        LeafRef::Tile(_) => {}
                        LeafRef::Brick(b) => {
                            // Voxels holding something other than the background.
                            asset.decode_brick(b, &mut values);
                            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
                            for (i, v) in values.iter().enumerate() {
                                if *v != background {
                                    let x = [i as i64 / 64, i as i64 / 8 % 8, i as i64 % 8];
                                    let (a, b) = cube([0, 1, 2].map(|k| l[k] + x[k]), 1);
                                    lo = min3(lo, a);
                                    hi = max3(hi, b);
                                }
                            }
                            if lo[0] <= hi[0] {
                                boxes.push((lo, hi));
                            }
                        }
                    }
                }
            }
        }
    }
    boxes
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each of the six axes: `up_frame` is a rotation (lengths and handedness kept) taking +Y to
    /// the axis, and `from_up_frame` undoes it.
    #[test]
    fn up_frames_are_rotations_and_invert() {
        let axes = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        for up in axes {
            assert_eq!(up_frame([0.0, 1.0, 0.0], up), up);
            let (x, y) = (up_frame([1.0, 0.0, 0.0], up), up_frame([0.0, 1.0, 0.0], up));
            assert_eq!(
                cross(x, y),
                up_frame([0.0, 0.0, 1.0], up),
                "{up:?}: a reflection"
            );
            for v in [[1.0, 0.6, 1.4], [-2.0, 3.0, 0.5]] {
                assert_eq!(from_up_frame(up_frame(v, up), up), v, "{up:?}");
            }
        }
        // Not an axis: the nearest one; nothing usable: Y.
        assert_eq!(up_frame([0.0, 1.0, 0.0], [0.1, 0.2, 0.9]), [0.0, 0.0, 1.0]);
        assert_eq!(up_frame([1.0, 2.0, 3.0], [0.0; 3]), [1.0, 2.0, 3.0]);
        assert_eq!(up_frame([1.0, 2.0, 3.0], [f64::NAN; 3]), [1.0, 2.0, 3.0]);
    }
}

//! Levels of detail for primary rays by pixel footprint (requirement 3.1.5 of the design; the
//! lit mode, `RenderSettings::primary_lod`). Far from the eye one pixel covers many voxels, and a
//! march that reads one full-resolution voxel per step both aliases (each pixel sees one thin
//! line through the volume) and pays for voxels no pixel resolves. An asset cooked with
//! `--lod` holds the box-filtered levels, so a ray reads level `k` where its pixel spans
//! `2^k` voxels or more, and steps `2^k` times farther: texture mip-mapping, along the ray.
//!
//! Defined once, here, so the CPU tracer (`vdbcook-trace`'s `lit` module) and the GPU march
//! (`lit_primary` in `shaders/trace.wgsl`) split a ray at the same distances.
//!
//! A ray's pixel spans `f(t) = t·θ·v` full-resolution voxels at world distance `t`, where `θ`
//! is the camera's pixel angle ([`pixel_angle`]) and `v` the voxels per world unit along the
//! ray (the length of its cell-space direction). Level `k` is read for `t ∈ [t_k, t_{k+1})`,
//! `t_0 = 0`, `t_k = 2^k / (θ·v)` ([`level_start`]), and the top stored level beyond.

/// The angle between neighbouring pixel rays at the image centre: `2·tan(fov/2)/height`.
pub fn pixel_angle(fov_y_deg: f64, height: u32) -> f64 {
    2.0 * (fov_y_deg.to_radians() * 0.5).tan() / f64::from(height.max(1))
}

/// `t_k`, where level `k` begins along a ray of pixel angle `theta` and `voxels_per_t` voxels
/// per world unit (0 for `k = 0`; +∞ when the footprint never grows).
pub fn level_start(k: u32, theta: f64, voxels_per_t: f64) -> f64 {
    if k == 0 {
        return 0.0;
    }
    let grow = theta * voxels_per_t;
    if grow > 0.0 {
        f64::from(1u32 << k.min(31)) / grow
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pixel_spans_two_to_the_k_voxels_where_level_k_begins() {
        // 90° vertical field of view over 100 rows: θ = 2·tan(45°)/100 = 0.02.
        let theta = pixel_angle(90.0, 100);
        assert!((theta - 0.02).abs() < 1e-12);
        // Two voxels per world unit: level k begins where t·0.02·2 = 2^k.
        for k in 1..6 {
            let t = level_start(k, theta, 2.0);
            assert!(
                (t * theta * 2.0 - f64::from(1u32 << k)).abs() < 1e-9,
                "level {k}: {t}"
            );
        }
        assert_eq!(level_start(0, theta, 2.0), 0.0);
        assert_eq!(level_start(3, theta, 0.0), f64::INFINITY);
    }
}

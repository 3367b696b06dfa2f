//! The volume WGSL for an engine's own shaders: the bindings at the bind-group index the engine
//! chooses, and the world-to-index matrix its `vdb_sample` needs. `VOLUME_WGSL` (tree access,
//! `vdb_value`, `vdb_value_nearest`, `vdb_sample`, the DDA, `vdb_optical_depth`) reads nothing
//! but the volume's own bindings, so an engine's material shader can include it next to its own
//! groups; the runtime's pipelines use group 0.

use glam::{DMat4, Mat4};

use crate::{GpuVolume, LIGHT_WGSL, SHADOW_WGSL, VOLUME_WGSL};

/// [`VOLUME_WGSL`] with the volume's bindings in bind group `group` instead of 0. Bind
/// [`GpuVolume::bind_group`] at that index of the engine's pipeline layout, and pass
/// [`GpuVolume::pipeline_constants`] as the pipeline's constants.
pub fn volume_wgsl(group: u32) -> String {
    VOLUME_WGSL.replace("@group(0)", &format!("@group({group})"))
}

/// The sun's shadows for an engine's own shaders: [`LIGHT_WGSL`] and [`SHADOW_WGSL`] with the
/// shadow bindings in bind group `group`, defining `vdb_sun_transmittance(world) -> f32`. Bind
/// [`crate::SunShadows::bind_group`] at that index ([`crate::VolumeDrawer::shadow_layout`] in
/// the pipeline layout). Independent of [`volume_wgsl`]: a shader may include both.
pub fn shadow_wgsl(group: u32) -> String {
    format!(
        "{LIGHT_WGSL}\n{}",
        SHADOW_WGSL.replace("@group(0)", &format!("@group({group})"))
    )
}

/// The matrix `vdb_sample` takes for an instance placed by `world_from_volume`: world space to
/// the asset's index space, the inverse of `world_from_volume · index_to_world` (computed in f64,
/// then rounded to f32). `None` if that transform cannot be inverted.
pub fn world_to_index(volume: &GpuVolume, world_from_volume: glam::Affine3A) -> Option<Mat4> {
    let m = volume.index_to_world();
    let index_to_world = DMat4::from_cols_array_2d(&[
        [m[0][0], m[1][0], m[2][0], m[3][0]],
        [m[0][1], m[1][1], m[2][1], m[3][1]],
        [m[0][2], m[1][2], m[2][2], m[3][2]],
        [m[0][3], m[1][3], m[2][3], m[3][3]],
    ]);
    let full = Mat4::from(world_from_volume).as_dmat4() * index_to_world;
    let det = full.determinant();
    (det.is_finite() && det.abs() > 1e-300).then(|| full.inverse().as_mat4())
}

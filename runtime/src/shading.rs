//! The one packing of a lit march for the GPU, shared by the renderer (`render.rs`, the
//! tracer's lit mode) and the engine drawer (`draw.rs`): [`ShadingUniform`] holds what the
//! light, the medium's phase and emission and the integrator's knobs give every sample, and
//! [`LitPlace`] what one march (a drawer instance, the renderer's one volume) adds in its own
//! cell space — extinction and albedo, its light volumes, the near field. Both mirror
//! `shaders/lit.wgsl` (`VdbShading`, `VdbLitPlace`; checked member by member below), whose
//! functions both pipelines call, so a new lighting term is one field here, one there and its
//! use in `lit.wgsl`. Every quantity is computed as `vdbcook_trace::Tracer::new` computes it: in
//! f64, then f32.

use bytemuck::{Pod, Zeroable};
use vdbcook_scene::{
    light_dirs, normalize, sky_diffusion, Affine, Filter, Integrator, LengthUnit, LightGrid,
    Lighting, Medium, MsModel, BLACKBODY_TABLE_LEN,
};

/// `VdbShading` of `lit.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub(crate) struct ShadingUniform {
    /// xyz: the unit world direction toward the sun; w: the march step.
    pub sun: [f32; 4],
    /// xyz: the sun's irradiance; w: `near_scatter`.
    pub sun_color: [f32; 4],
    /// xyz: the sky's radiance; w: 1 for trilinear density.
    pub sky: [f32; 4],
    /// g0, g1, the first lobe's weight, the phase's mean cosine.
    pub phase: [f32; 4],
    /// The octave falloff (a, b, c).
    pub ms: [f32; 4],
    /// Octaves of the sun's multiple scattering; 0: the diffusion model.
    pub octaves: u32,
    pub seed: u32,
    /// 1: lengths per voxel.
    pub voxel_units: u32,
    pub _pad: u32,
    /// Range (K), intensity, w 1 when the march's own channel glows; the blackbody table.
    pub emission: [f32; 4],
    pub emit_table: [[f32; 4]; BLACKBODY_TABLE_LEN],
}

impl ShadingUniform {
    /// The uniform of `medium` lit by `lighting` and sampled by `integrator`; `own_emission`:
    /// whether the emission (if any) glows from the march's own channel (else it comes from
    /// another one, drawn by the caller's own pass).
    pub fn new(
        medium: &Medium,
        lighting: &Lighting,
        integrator: &Integrator,
        own_emission: bool,
    ) -> ShadingUniform {
        let l = normalize(lighting.light_dir.map(|c| c as f64)).map(|c| c as f32);
        let c = lighting.light_color;
        let s = lighting.sky;
        let g = medium.phase_g;
        let mean_cos = vdbcook_scene::phase_mean_cos(g, medium.phase_w);
        ShadingUniform {
            sun: [l[0], l[1], l[2], integrator.step],
            sun_color: [c[0], c[1], c[2], lighting.near_scatter],
            sky: [
                s[0],
                s[1],
                s[2],
                (integrator.filter == Filter::Trilinear) as u32 as f32,
            ],
            phase: [g[0], g[1], medium.phase_w, mean_cos as f32],
            ms: [lighting.ms[0], lighting.ms[1], lighting.ms[2], 0.0],
            octaves: match lighting.ms_model {
                MsModel::Octaves => lighting.ms_octaves,
                MsModel::Diffusion => 0,
            },
            seed: integrator.seed,
            voxel_units: (medium.unit == LengthUnit::Voxel) as u32,
            _pad: 0,
            emission: medium.emission.map_or([0.0; 4], |e| {
                [
                    e.range[0],
                    e.range[1],
                    e.intensity,
                    own_emission as u32 as f32,
                ]
            }),
            emit_table: medium
                .emission
                .map_or([[0.0; 4]; BLACKBODY_TABLE_LEN], |e| e.table()),
        }
    }
}

/// `VdbLitPlace` of `lit.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub(crate) struct LitPlace {
    /// xyz: the cell-space image of the unit world direction toward the sun; w: extinction.
    pub sun_cell: [f32; 4],
    /// xyz: length per cell-space unit along each axis; w: the albedo.
    pub axis: [f32; 4],
    /// Frame 0's light volume: corner and cell edge; cells and base element.
    pub lv_lo0: [f32; 4],
    pub lv_dims0: [u32; 4],
    /// Frame 1's.
    pub lv_lo1: [f32; 4],
    pub lv_dims1: [u32; 4],
    /// Per frame: the near field in voxels, a cell's edge in the length unit.
    pub near: [f32; 4],
    /// The full-resolution root offsets of frames 0 and 1.
    pub roots: [u32; 4],
    /// k of the sky's source; the crossfade weight of frame 1; 1 where the drawer dithers a
    /// crossfade's samples between its frames (`LitCrossfade::Dither`, `draw.wgsl`'s `draw_lit`).
    pub misc: [f32; 4],
}

impl LitPlace {
    /// The placement of a march in the cell space of `xf`: `medium` with its density scaled by
    /// `density_scale`, lit by `lighting`, over `frames` (one, or two crossfaded with weight
    /// `weight` of the second): each its light grid, its light volume's base element and its
    /// full-resolution root offset.
    pub fn new(
        xf: &Affine,
        medium: &Medium,
        lighting: &Lighting,
        density_scale: f32,
        frames: &[(&LightGrid, u32, u32)],
        weight: f32,
    ) -> LitPlace {
        let (k, albedo) = medium.extinction_albedo();
        let extinction = k * density_scale as f64;
        let l = xf.dir_to_index(normalize(lighting.light_dir.map(|c| c as f64)));
        let (_, axis) = light_dirs(xf, lighting.light_dir, medium.unit);
        let shortest = axis.into_iter().fold(f64::INFINITY, f64::min);
        let lv = |n: usize| {
            let (grid, base, root) = frames[n.min(frames.len() - 1)];
            (
                [grid.lo[0], grid.lo[1], grid.lo[2], grid.cell].map(|v| v as f32),
                [grid.dims[0], grid.dims[1], grid.dims[2], base],
                [
                    grid.near_voxels(lighting.sun_near) as f32,
                    (shortest * grid.cell) as f32,
                ],
                root,
            )
        };
        let (f0, f1) = (lv(0), lv(1));
        LitPlace {
            sun_cell: [l[0], l[1], l[2], extinction].map(|v| v as f32),
            axis: [axis[0], axis[1], axis[2], albedo].map(|v| v as f32),
            lv_lo0: f0.0,
            lv_dims0: f0.1,
            lv_lo1: f1.0,
            lv_dims1: f1.1,
            near: [f0.2[0], f0.2[1], f1.2[0], f1.2[1]],
            roots: [f0.3, f1.3, 0, 0],
            misc: [
                sky_diffusion(albedo, medium.phase_g, medium.phase_w, lighting.ms_sky) as f32,
                if frames.len() > 1 { weight } else { 0.0 },
                0.0,
                0.0,
            ],
        }
    }

    /// The light volumes' base elements, once placed (`LightPass::prepare`).
    pub fn set_bases(&mut self, b0: u32, b1: u32) {
        self.lv_dims0[3] = b0;
        self.lv_dims1[3] = b1;
    }

    /// A crossfade's samples each from one frame (`LitCrossfade::Dither`; the drawer's alone).
    pub fn set_dither(&mut self) {
        self.misc[2] = 1.0;
    }
}

/// The WGSL the tracer and the drawer start from: the volume, the light-volume helpers and the
/// lit march's light with its light volumes at group `group` and its uniform read from the
/// WGSL expression `shading`.
pub(crate) fn lit_source(group: u32, shading: &str) -> String {
    format!(
        "{}\n{}\n{}",
        crate::VOLUME_WGSL,
        crate::LIGHT_WGSL,
        crate::LIT_WGSL
            .replace("{{LIT_GROUP}}", &group.to_string())
            .replace("{{SHADING}}", shading)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout_check::{assert_mirrors, rust_layout};

    fn lit_test_source() -> String {
        format!(
            "{}\nvar<private> shading_test: VdbShading;\nconst LIT_NEAR: bool = true;",
            lit_source(3, "shading_test")
        )
    }

    #[test]
    fn shading_and_placement_mirror_the_wgsl() {
        assert_mirrors(
            &lit_test_source(),
            "VdbShading",
            rust_layout!(ShadingUniform {
                sun,
                sun_color,
                sky,
                phase,
                ms,
                octaves,
                seed,
                voxel_units,
                _pad,
                emission,
                emit_table,
            }),
        );
        assert_mirrors(
            &lit_test_source(),
            "VdbLitPlace",
            rust_layout!(LitPlace {
                sun_cell,
                axis,
                lv_lo0,
                lv_dims0,
                lv_lo1,
                lv_dims1,
                near,
                roots,
                misc,
            }),
        );
    }
}

//! Drawing volumes into an engine's frame: the engine owns the device, the queue, the command
//! encoder, the depth buffer and the colour target; this module owns pipelines and the small
//! per-draw buffers, and records work into the engine's encoder without blocking or submitting.
//!
//! - [`View`]: the engine's view and projection matrices (perspective or orthographic, standard
//!   or reversed Z, finite or infinite far plane), viewport and jitter. A pixel's ray comes from
//!   unprojecting its centre (+ jitter, in pixels) through `proj⁻¹` into view space (starting at
//!   the eye for a perspective projection, on the near plane for an orthographic one) and then
//!   into world space through `view⁻¹`. [`ViewRays`] is that math in f64 (the GPU does it in f32).
//! - [`Instance`]: where a volume is (`world_from_volume`, composed with the asset's
//!   `index_to_world`), which time of its flip-book (a fractional time crossfades two frames),
//!   how dense and which colour.
//! - [`VolumeDrawer`]: per uploaded volume and colour format, [`VolumeDrawer::record`] records a
//!   compute pass (`shaders/draw.wgsl`: per pixel, every instance's density march cut at the
//!   scene depth, composited front to back into premultiplied radiance and transmittance
//!   `(L, T)` in an `Rgba16Float` texture) and a render pass (`shaders/composite.wgsl`: the
//!   blend unit computes `out = L + T·scene` on the colour target, any blendable format).
//!
//! The density march is the CPU tracer's Density mode (`vdbcook_trace::Tracer::optical_depth`
//! is its reference): `T = exp(−absorb·scale·τ)` with `τ` the exact sum of voxel values times
//! segment lengths; the volume is flat-lit: `L = tint·(1 − T)`. A crossfade samples the per-voxel
//! lerp of the two frames, which for this march is the lerp of their optical depths.
//! `docs/engine.md` walks through the use.

use bytemuck::{Pod, Zeroable};
use glam::{Affine3A, DMat4, DVec3, DVec4, Mat4, Vec2, Vec3};
use wgpu::util::DeviceExt;

use vdbcook_scene::{
    box_union, light_dirs, light_span, Affine, DiffusionInputs, Integrator, LightGrid, Lighting,
    Medium, Mode, MsModel, RenderSettings, MAX_SIDE,
};

use std::sync::Arc;

use crate::light::{FrameAt, LightEntry, LightParams, LightPass};
use crate::shading::{LitPlace, ShadingUniform};

use crate::upload::{Bound, GpuVolume};
use crate::{Result, RuntimeError};

/// The light volumes one draw needs (deduplicated), and the diffusion inputs of each
/// (`MsModel::Diffusion`), as `LightPass::prepare` takes them.
#[derive(Default)]
struct LitVolumes {
    volumes: Vec<LightParams>,
    diffusion: Vec<Option<DiffusionInputs>>,
}

/// The engine drawer's compute shader (needs [`VOLUME_WGSL`](crate::VOLUME_WGSL) before it).
pub const DRAW_WGSL: &str = include_str!("../../shaders/draw.wgsl");
/// The engine drawer's composite pass (a module of its own).
pub const COMPOSITE_WGSL: &str = include_str!("../../shaders/composite.wgsl");

/// The format of the `(L, T)` texture between the two passes.
const LT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
const WORKGROUP: u32 = 8;

/// The colour-target formats the composite blends onto.
pub const DRAW_COLOR_FORMATS: [wgpu::TextureFormat; 6] = [
    wgpu::TextureFormat::Rgba8Unorm,
    wgpu::TextureFormat::Rgba8UnormSrgb,
    wgpu::TextureFormat::Bgra8Unorm,
    wgpu::TextureFormat::Bgra8UnormSrgb,
    wgpu::TextureFormat::Rgba16Float,
    wgpu::TextureFormat::Rgb10a2Unorm,
];

/// The depth formats the drawer reads (as `texture_depth_2d`: the stored depth in [0, 1] either
/// way; `Depth24Plus` may be 24-bit unorm or f32, whichever the adapter keeps).
pub const DRAW_DEPTH_FORMATS: [wgpu::TextureFormat; 2] = [
    wgpu::TextureFormat::Depth32Float,
    wgpu::TextureFormat::Depth24Plus,
];

/// The engine's camera for one draw: its view matrix (world → view space), projection (view
/// space → clip space, wgpu's NDC: depth in [0, 1]), viewport in pixels (the size of the colour
/// and depth targets) and sub-pixel jitter in pixels (TAA), added to every pixel centre.
///
/// Any invertible projection works for perspective ones (standard or reversed Z, finite or
/// infinite far plane). For orthographic ones (last row `[0 0 0 1]`) view space is taken to be
/// right-handed (the camera looks down −Z, as glam's `*_rh` functions), which decides which of the
/// two depth planes is the near one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    pub view: Mat4,
    pub proj: Mat4,
    pub viewport: (u32, u32),
    pub jitter: Vec2,
}

impl View {
    /// A view without jitter, validated ([`View::rays`]).
    pub fn new(view: Mat4, proj: Mat4, viewport: (u32, u32)) -> Result<View> {
        let v = View {
            view,
            proj,
            viewport,
            jitter: Vec2::ZERO,
        };
        v.rays()?;
        Ok(v)
    }

    /// A right-handed look-at camera at `eye` toward `target` with a reversed-Z infinite
    /// perspective projection (`fov_y` vertical, radians; `aspect` = width / height; `near` > 0).
    pub fn look_at(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        fov_y: f32,
        aspect: f32,
        near: f32,
        viewport: (u32, u32),
    ) -> Result<View> {
        let bad = |m: String| Err(RuntimeError::Camera(m));
        if !(fov_y > 0.0 && fov_y < std::f32::consts::PI) {
            return bad(format!("fov_y {fov_y} rad (0 < fov_y < π)"));
        }
        if !(aspect > 0.0 && aspect.is_finite() && near > 0.0 && near.is_finite()) {
            return bad(format!(
                "aspect {aspect}, near {near} (both finite and > 0)"
            ));
        }
        let f = target - eye;
        if !eye.is_finite() || !target.is_finite() || !(f.length() > 0.0) {
            return bad(format!("eye {eye} and target {target} (distinct, finite)"));
        }
        if !(f.normalize().cross(up).length() > 1e-6 * up.length()) || up.length() == 0.0 {
            return bad(format!("up {up} is parallel to the view direction"));
        }
        View::new(
            glam::camera::rh::view::look_at_mat4(eye, target, up),
            glam::camera::rh::proj::directx::perspective_infinite_reverse(fov_y, aspect, near),
            viewport,
        )
    }

    /// Validates the view and returns its ray math: refuses a viewport side outside
    /// `1..=MAX_SIDE`, non-finite entries or jitter, and a singular view or projection matrix.
    pub fn rays(&self) -> Result<ViewRays> {
        let (w, h) = self.viewport;
        if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
            return Err(RuntimeError::Target(format!(
                "viewport {w}x{h} (each side 1..={MAX_SIDE})"
            )));
        }
        if !self.jitter.is_finite() {
            return Err(RuntimeError::Camera(format!("jitter {}", self.jitter)));
        }
        let view = self.view.as_dmat4();
        let proj = self.proj.as_dmat4();
        check_invertible("view", &view)?;
        check_invertible("projection", &proj)?;
        let view_from_clip = proj.inverse();
        let world_from_view = view.inverse();
        let perspective = proj.row(3) != DVec4::new(0.0, 0.0, 0.0, 1.0);
        let mut rays = ViewRays {
            view_from_clip,
            world_from_view,
            perspective,
            forward: DVec3::ZERO,
            near_ndc: 0.0,
            viewport: (w, h),
            jitter: self.jitter.as_dvec2(),
        };
        let centre = |z| rays.unproject(0.0, 0.0, z);
        if perspective {
            match centre(0.5) {
                Some(p) if p.length() > 0.0 && p.is_finite() => {}
                _ => {
                    return Err(RuntimeError::Camera(
                        "the projection maps no point in front of the eye to depth 0.5".into(),
                    ))
                }
            }
        } else {
            let (Some(p0), Some(p1)) = (centre(0.0), centre(1.0)) else {
                return Err(RuntimeError::Camera(
                    "orthographic projection with a depth plane at infinity".into(),
                ));
            };
            let d = p1 - p0;
            if !(d.length() > 0.0) || !d.is_finite() {
                return Err(RuntimeError::Camera(
                    "orthographic projection with near = far".into(),
                ));
            }
            // Right-handed view space: the camera looks down −Z.
            let (near_ndc, forward) = if d.z < 0.0 { (0.0, d) } else { (1.0, -d) };
            rays.near_ndc = near_ndc;
            rays.forward = forward.normalize();
        }
        Ok(rays)
    }
}

/// Refuses a non-finite or (nearly) singular matrix: `|det|` below `1e-12` of the product of its
/// column lengths (Hadamard's bound), so the test does not depend on the scene's units.
fn check_invertible(what: &str, m: &DMat4) -> Result<()> {
    if !m.is_finite() {
        return Err(RuntimeError::Camera(format!(
            "{what} matrix has a non-finite entry"
        )));
    }
    let bound: f64 = (0..4).map(|c| m.col(c).length()).product();
    let det = m.determinant();
    if !(det.abs() > 1e-12 * bound) {
        return Err(RuntimeError::Camera(format!(
            "{what} matrix is singular (det {det:e}); it must be invertible"
        )));
    }
    Ok(())
}

/// A validated [`View`]'s ray math in f64: what the GPU computes per pixel in f32 (the CPU
/// reference of the tests, and picking for an engine).
#[derive(Debug, Clone, Copy)]
pub struct ViewRays {
    view_from_clip: DMat4,
    world_from_view: DMat4,
    perspective: bool,
    /// Orthographic: the unit view-space direction of every ray.
    forward: DVec3,
    /// Orthographic: the NDC depth of the near plane (0, or 1 with reversed Z).
    near_ndc: f64,
    viewport: (u32, u32),
    jitter: glam::DVec2,
}

impl ViewRays {
    /// The view-space point of NDC `(x, y, z)`, `None` at infinity.
    fn unproject(&self, x: f64, y: f64, z: f64) -> Option<DVec3> {
        let h = self.view_from_clip * DVec4::new(x, y, z, 1.0);
        (h.w.abs() > 1e-30).then(|| h.truncate() / h.w)
    }

    fn ndc(&self, px: u32, py: u32) -> (f64, f64) {
        let (w, h) = self.viewport;
        let cx = px as f64 + 0.5 + self.jitter.x;
        let cy = py as f64 + 0.5 + self.jitter.y;
        (2.0 * cx / w as f64 - 1.0, 1.0 - 2.0 * cy / h as f64)
    }

    /// View-space origin and unit direction of pixel `(px, py)` (row 0 at the top).
    fn view_ray(&self, px: u32, py: u32) -> (DVec3, DVec3) {
        let (x, y) = self.ndc(px, py);
        if self.perspective {
            let p = self.unproject(x, y, 0.5).unwrap_or(DVec3::NEG_Z);
            (DVec3::ZERO, p.normalize())
        } else {
            let o = self.unproject(x, y, self.near_ndc).unwrap_or(DVec3::ZERO);
            (o, self.forward)
        }
    }

    /// Whether the projection is a perspective one (rays start at the eye).
    pub fn perspective(&self) -> bool {
        self.perspective
    }

    /// The world ray of pixel `(px, py)`: origin (the eye, or the pixel on the near plane) and
    /// unit direction. `t` along it is world distance.
    pub fn ray(&self, px: u32, py: u32) -> (DVec3, DVec3) {
        let (o, d) = self.view_ray(px, py);
        let dw = self.world_from_view.transform_vector3(d);
        (self.world_from_view.transform_point3(o), dw.normalize())
    }

    /// The world distance along pixel `(px, py)`'s ray to the scene depth `depth` (an NDC depth
    /// as stored in a `Depth32Float` buffer), or `∞` where that depth is at infinity.
    pub fn depth_distance(&self, px: u32, py: u32, depth: f32) -> f64 {
        let (x, y) = self.ndc(px, py);
        let (o, d) = self.view_ray(px, py);
        let Some(p) = self.unproject(x, y, depth as f64) else {
            return f64::INFINITY;
        };
        let s = self.world_from_view.transform_vector3(d).length();
        (p - o).dot(d) * s
    }

    /// The world position of the eye (perspective) or of the near plane's centre.
    fn eye(&self) -> DVec3 {
        let o = if self.perspective {
            DVec3::ZERO
        } else {
            self.unproject(0.0, 0.0, self.near_ndc)
                .unwrap_or(DVec3::ZERO)
        };
        self.world_from_view.transform_point3(o)
    }
}

/// One placed volume: where (`world_from_volume` maps the volume's world space — the asset's
/// `index_to_world` image — into the engine's world), when (`time` in frames: an integer shows
/// that frame, a fraction crossfades frames `⌊time⌋` and `⌊time⌋ + 1` by the per-voxel density
/// lerp; must lie in `[0, frames − 1]`), how dense (`density_scale` ≥ 0 multiplies the medium's
/// absorption) and which colour (`tint` ≥ 0: the flat-lit radiance is `tint·(1 − T)`). On a
/// volume set ([`GpuVolume::upload_set`]) `asset` picks the asset (its index in the set; 0 for
/// a volume of one asset); `time` counts that asset's frames.
///
/// `light_stride` (lit instances; 0 or 1, the default: every frame's own light) lights the
/// flip-book's frames in spans of `n`: frames `[k·n, k·n + n)` share one light volume, built from
/// the span's middle frame over the span's joint content box, so a playing effect builds a light
/// volume every `n` frames instead of every frame. The near field toward the sun is still walked
/// through the drawn frame; the light volume's far shadow and multiple scattering lag or lead
/// by up to `n / 2` frames (`vdbcook bench --light-stride N` states the image error beside the
/// time). Set it while an effect plays and back to 1 when it stops: a still frame then gets
/// its exact light (`docs/engine.md` §6, "Light every n frames").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instance {
    pub world_from_volume: Affine3A,
    pub time: f32,
    pub density_scale: f32,
    pub tint: Vec3,
    pub asset: usize,
    pub light_stride: u32,
}

impl Default for Instance {
    fn default() -> Self {
        Instance {
            world_from_volume: Affine3A::IDENTITY,
            time: 0.0,
            density_scale: 1.0,
            tint: Vec3::ONE,
            asset: 0,
            light_stride: 1,
        }
    }
}

impl Instance {
    /// Frame 0 at `world_from_volume`, density scale 1, white.
    pub fn at(world_from_volume: Affine3A) -> Instance {
        Instance {
            world_from_volume,
            ..Default::default()
        }
    }

    /// The `index_to_world` of this instance (row-major, column vectors, as the asset header's):
    /// `world_from_volume · index_to_world`. A CPU tracer given an asset with this transform
    /// draws what the drawer draws for the instance.
    pub fn index_to_world(&self, index_to_world: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
        let m = self.world_from_volume;
        let w = |r: usize, c: usize| -> f64 {
            if c == 3 {
                m.translation[r] as f64
            } else {
                m.matrix3.col(c)[r] as f64
            }
        };
        let mut out = [[0.0; 4]; 4];
        for (r, row) in out.iter_mut().enumerate().take(3) {
            for (c, v) in row.iter_mut().enumerate() {
                *v = (0..3).map(|k| w(r, k) * index_to_world[k][c]).sum::<f64>()
                    + if c == 3 { w(r, 3) } else { 0.0 };
            }
        }
        out[3] = [0.0, 0.0, 0.0, 1.0];
        out
    }

    /// The two frames and the weight of the second: `(⌊time⌋, ⌊time⌋ + 1, time − ⌊time⌋)`, the
    /// second frame equal to the first when the weight is 0. Refuses a time outside
    /// `[0, frames − 1]` (or NaN).
    pub fn frames(&self, frames: usize) -> Result<(usize, usize, f32)> {
        let t = self.time;
        let last = frames.saturating_sub(1) as f32;
        if frames == 0 || !(t >= 0.0 && t <= last) {
            return Err(RuntimeError::Setting(format!(
                "instance time {t} outside [0, {last}] (frames of the asset: {frames})"
            )));
        }
        let f0 = t.floor();
        let a = t - f0;
        let f0 = f0 as usize;
        Ok(if a > 0.0 {
            (f0, f0 + 1, a)
        } else {
            (f0, f0, 0.0)
        })
    }

    fn validate(&self) -> Result<()> {
        if !self.world_from_volume.is_finite() {
            return Err(RuntimeError::Transform(
                "instance world_from_volume has a non-finite entry".into(),
            ));
        }
        if !(self.density_scale >= 0.0 && self.density_scale.is_finite()) {
            return Err(RuntimeError::Setting(format!(
                "instance density_scale {} (finite, ≥ 0)",
                self.density_scale
            )));
        }
        if !(self.tint.is_finite() && self.tint.min_element() >= 0.0) {
            return Err(RuntimeError::Setting(format!(
                "instance tint {} (finite, ≥ 0)",
                self.tint
            )));
        }
        Ok(())
    }
}

/// How the drawer shades its instances, in the types the CPU tracer and the renderer take: the
/// medium (absorption per length unit — `Voxel`: per voxel of the instance, `World`: per world
/// unit — scattering, phase, emission), and with `lighting` the lit march (sun, sky, phase and
/// multiple scattering through light volumes, as the tracer's lit mode) reading the
/// integrator's `step`, `seed` and `filter`; `lighting: None` draws the flat-lit density march.
/// An instance's extinction is `(absorb + scatter) · density_scale` per unit density, its albedo
/// `scatter / (absorb + scatter)`; its radiance is `tint ⊙ L` with `L` the march's. Each lit
/// instance gets a light volume per frame of its crossfade, in its own cell space
/// (`light_res` cells along the frame's content box), rebuilt when the frame, the instance's
/// rotation or scale, the light or the medium changes (`docs/engine.md`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Shading {
    pub medium: Medium,
    pub lighting: Option<Lighting>,
    pub integrator: Integrator,
}

impl Shading {
    /// The shading of tracer settings: lit where the mode is.
    pub fn of_settings(s: &RenderSettings) -> Shading {
        Shading {
            medium: s.medium.clone(),
            lighting: (s.integrator.mode == Mode::Lit).then(|| s.lighting.clone()),
            integrator: s.integrator.clone(),
        }
    }

    /// The tracer settings of a render with this shading (what the CPU tracer draws for the
    /// drawer's instances, and what is validated): the lit mode with `lighting`, else density.
    /// The drawer marches in steps (`March::Steps`): it reads the density by point lookups and
    /// has no voxel spans to follow (only its near field toward the sun walks voxels).
    pub fn settings(&self) -> RenderSettings {
        RenderSettings {
            medium: self.medium.clone(),
            lighting: self.lighting.clone().unwrap_or_default(),
            integrator: Integrator {
                mode: if self.lighting.is_some() {
                    Mode::Lit
                } else {
                    Mode::Density
                },
                march: vdbcook_scene::March::Steps,
                ..self.integrator.clone()
            },
            ..Default::default()
        }
    }
}

/// Where a draw lands: the engine's colour target (a view of mip 0 of a 2D texture of the
/// drawer's format, `RENDER_ATTACHMENT` usage, single-sampled, the view's viewport size) and
/// optionally its depth (a view of a [`DRAW_DEPTH_FORMATS`] 2D texture of the same size with
/// `TEXTURE_BINDING` usage, written with the same projection). Without depth rays run to the
/// volume's end.
#[derive(Debug, Clone, Copy)]
pub struct DrawTarget<'a> {
    pub color: &'a wgpu::TextureView,
    pub depth: Option<&'a wgpu::TextureView>,
}

/// The drawer's WGSL: the volume, the light-volume helpers, the drawer with the lit march, its
/// trilinear density, its near field, the interleaving sweep and the emission pass compiled in
/// or out.
fn draw_source(v: Variant) -> String {
    let Variant {
        lit,
        trilinear,
        near,
        interleave,
        emit,
    } = v;
    let flag = |on: bool| if on { "true" } else { "false" };
    format!(
        "{}\n{}",
        crate::shading::lit_source(2, "draw_view.shading"),
        DRAW_WGSL
            .replace("{{DRAW_LIT}}", flag(lit))
            .replace("{{DRAW_TRILINEAR}}", flag(trilinear))
            .replace("{{LIT_NEAR}}", flag(near))
            .replace("{{DRAW_INTERLEAVE}}", flag(interleave))
            .replace("{{DRAW_EMIT}}", flag(emit))
    )
}

/// The `DrawView` uniform of `draw.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct DrawView {
    view_from_clip: [[f32; 4]; 4],
    world_from_view: [[f32; 4]; 4],
    forward: [f32; 4],
    viewport: [u32; 2],
    jitter: [f32; 2],
    near_ndc: f32,
    instance_count: u32,
    has_depth: u32,
    /// The emission pass's channel (the pass itself is the `DRAW_EMIT` variant).
    emit_channel: u32,
    /// The pixel of the dispatch's first invocation (the covered rectangle's corner).
    origin: [u32; 2],
    /// The reduced-resolution march's blocks `[half_lo, half_hi)` of `block`² pixels (0: off).
    half_lo: [u32; 2],
    half_hi: [u32; 2],
    block: u32,
    _pad: u32,
    /// The light, phase, emission, step and seed (the renderer's packing too).
    shading: ShadingUniform,
}

/// One element of the `draw_instances` array of `draw.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct DrawInstance {
    cell_from_world: [[f32; 4]; 3],
    tint_absorb: [f32; 4],
    box_lo: [f32; 4],
    box_hi: [f32; 4],
    /// Where the emission channel may glow (both frames), empty: lo > hi.
    emit_lo: [f32; 4],
    emit_hi: [f32; 4],
    frame_root0: u32,
    frame_root1: u32,
    /// 1: lit (`place` holds its light volumes), 0: flat.
    lit: u32,
    /// The instance's asset in the volume set.
    asset: u32,
    /// The lit march's medium and light volumes in the instance's cell space.
    place: LitPlace,
}

/// One element of `vdb_shadow_instances` (`shaders/shadow.wgsl`): a lit instance's world → cell
/// rows, the cell-space direction toward the sun with the extinction, and its light volumes.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct ShadowInstance {
    cell_from_world: [[f32; 4]; 3],
    sun: [f32; 4],
    lo0: [f32; 4],
    dims0: [u32; 4],
    lo1: [f32; 4],
    dims1: [u32; 4],
    weight: [f32; 4],
}

/// The sun's shadows of one frame's lit instances for an engine's own shaders: bind
/// `bind_group` at the group given to [`crate::shadow_wgsl`], in a pipeline whose layout has
/// [`VolumeDrawer::shadow_layout`] there, and call `vdb_sun_transmittance(world_position)`.
pub struct SunShadows {
    pub bind_group: wgpu::BindGroup,
    /// How many instances cast shadows (the lit ones with content in their frames).
    pub casters: usize,
    /// The light volumes read (kept from being overwritten while this is held).
    _light: Option<Arc<LightEntry>>,
}

/// One draw's uniforms: the view and the instances (grown when a draw has more). A draw holds
/// its slot until it is dropped; a slot no draw holds is reused.
struct DrawSlot {
    view: wgpu::Buffer,
    instances: wgpu::Buffer,
    capacity: usize,
}

/// A draw made ready by [`VolumeDrawer::prepare`]: everything [`VolumeDrawer::record`] binds,
/// with the uniforms written and the light volumes built. Keep it until the encoder it was
/// recorded into is submitted (or dropped): it holds the buffers the draw reads, which a later
/// `prepare` would otherwise reuse.
#[must_use = "a prepared draw holds what the draw reads: record it, and keep it until its encoder is submitted"]
pub struct PreparedDraw {
    /// The pipeline variant (`Variant::index`).
    variant: usize,
    group: wgpu::BindGroup,
    /// The reduced-resolution pass's group (`MarchResolution::Half`, `Quarter`) and its blocks
    /// (x, y).
    half_group: Option<wgpu::BindGroup>,
    half_blocks: [u32; 2],
    light_group: wgpu::BindGroup,
    composite_group: wgpu::BindGroup,
    color: wgpu::TextureView,
    /// The pixels the instances can cover: x, y, width, height.
    rect: [u32; 4],
    _slot: Arc<DrawSlot>,
    _light: Option<Arc<LightEntry>>,
}

impl std::fmt::Debug for PreparedDraw {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PreparedDraw")
            .field("empty", &self.is_empty())
            .field("variant", &Variant::of_index(self.variant))
            .field("covered", &self.rect)
            .finish_non_exhaustive()
    }
}

impl PreparedDraw {
    /// The pixels the draw covers (x, y, width, height): its dispatch and its composite's
    /// scissor; nothing outside is read or written.
    pub fn covered(&self) -> [u32; 4] {
        self.rect
    }
    /// Nothing to draw: no instance has content where the view looks (no instance, or none
    /// whose box projects onto a pixel).
    fn is_empty(&self) -> bool {
        self.rect[2] == 0 || self.rect[3] == 0
    }
}

/// The `(L, T)` texture of one viewport size and the composite's bind group over it.
struct LtTexture {
    size: (u32, u32),
    view: wgpu::TextureView,
    /// The reduced-resolution march's (L, T) per block.
    half: wgpu::TextureView,
    composite_group: wgpu::BindGroup,
}

/// An `(L, T)` texture of `size`, written as storage and read by `textureLoad`.
fn lt_view(device: &wgpu::Device, size: (u32, u32), label: &str) -> wgpu::TextureView {
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: size.0,
                height: size.1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: LT_FORMAT,
            usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
        .create_view(&Default::default())
}

/// Draws instances of one uploaded volume into an engine's frame (one colour format). Create it
/// once; [`VolumeDrawer::record`] each frame (any number of times per encoder).
pub struct VolumeDrawer {
    /// The draw pipelines by [`Variant::index`] (code a draw cannot reach is left out:
    /// software Vulkan pays for it). The flat one and the default lighting's are made with the
    /// drawer, the others by [`VolumeDrawer::warm_up`] or the first `prepare` that needs them;
    /// `record` never compiles.
    pipelines: Vec<Option<wgpu::ComputePipeline>>,
    /// The draws' uniforms (see [`DrawSlot`]).
    slots: Vec<Arc<DrawSlot>>,
    /// The lit instances' light volumes.
    light: LightPass,
    /// The layout of `SunShadows::bind_group`.
    shadow_layout: wgpu::BindGroupLayout,
    draw_layout: wgpu::BindGroupLayout,
    composite_pipeline: wgpu::RenderPipeline,
    composite_layout: wgpu::BindGroupLayout,
    vol: Bound,
    color_format: wgpu::TextureFormat,
    dummy_depth: wgpu::TextureView,
    lt: Option<LtTexture>,
    interleave: Interleave,
    /// The reduced-resolution march's pipelines by [`Variant::index`] (made while it is on).
    half_pipelines: Vec<Option<wgpu::ComputePipeline>>,
    resolution: MarchResolution,
    lit_crossfade: LitCrossfade,
    /// Displayed frames a light volume is built ahead over (0: none).
    light_ahead: u32,
    /// 1×1 `(L, T)` textures bound where a pass writes (0) or reads (1) no half-resolution
    /// texture (two: one texture may not be written and read in one dispatch).
    lt_stand_in: [wgpu::TextureView; 2],
}

/// How many rays a draw marches: one per pixel, or one per block of 2×2 (`Half`) or 4×4
/// (`Quarter`) pixels where every pixel's scene depth lies beyond the volumes on its ray,
/// bilinearly upsampled, with the pixels next to a depth edge among the volumes or an
/// occluder's edge marched at full resolution (`draw_half_main` in `draw.wgsl`). Half costs about a
/// quarter of the march where nothing cuts the volumes, Quarter about a sixteenth; their error
/// against `Full` is measured in `docs/engine.md` §6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MarchResolution {
    /// One ray per pixel (the default; exact against the CPU tracer).
    #[default]
    Full,
    /// One ray per 2×2 block away from depth edges, upsampled bilinearly.
    Half,
    /// One ray per 4×4 block away from depth edges, upsampled bilinearly.
    Quarter,
}

impl MarchResolution {
    /// Pixels per block side (1: one ray per pixel).
    pub fn block(self) -> u32 {
        match self {
            MarchResolution::Full => 1,
            MarchResolution::Half => 2,
            MarchResolution::Quarter => 4,
        }
    }
}

/// How the lit march crosses an instance between two frames of its flip-book (a fractional
/// time). Reading both frames' density and light (the sun's depth, the near field walked toward
/// the sun, the diffusion's sun and sky) at every sample costs about 1.6–2× a whole frame lit
/// (`docs/engine.md` §6). The flat march is unaffected: it always lerps the frames' optical
/// depths exactly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LitCrossfade {
    /// Each sample reads both frames, lerps their densities, their depths toward the sun and
    /// their diffusion light: no grain, about 1.6–2× the cost of a whole frame lit. The default.
    #[default]
    Lerp,
    /// Each sample is one frame's, density and light: frame 1 on a fraction `weight` of a ray's
    /// samples, spread evenly along it (a golden-ratio sequence from a per-pixel offset seeded by
    /// `Integrator::seed`), frame 0 on the rest, so the lit march reads what a whole frame's
    /// reads (1.0–1.1× a whole frame; the emission pass and the interleaved march's piece
    /// depths still read both frames). Its mean over a ray is the frames' lerp to within
    /// the sequence's spread and a second-order term in the frames' difference; the residue is a
    /// per-pixel grain where neighbouring frames differ: invisible on a slowly changing cloud,
    /// visible on a detailed fast simulation (`vdbcook bench` states it as `crossfade_error`).
    /// For a pipeline with a temporal filter (TAA) that varies `Integrator::seed` per frame, so
    /// the grain averages out.
    Dither,
}

/// When a draw interleaves its instances along each ray (the sweep that cuts rays where
/// instances overlap and mixes their media there) rather than marching each whole, front to
/// back in the order of their distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interleave {
    /// When two instances' world bounds overlap (the default; exact wherever instances do not
    /// overlap, where the sweep is not needed and costs more).
    #[default]
    Auto,
    /// Always (the sweep: right whatever overlaps, slower).
    Always,
    /// Never: each instance marched whole in distance order (wrong where instances overlap
    /// along a ray; for a caller that knows they do not).
    Never,
}

impl VolumeDrawer {
    /// Builds the pipelines for `volume` and colour targets of `color_format` (one of
    /// [`DRAW_COLOR_FORMATS`]).
    pub fn new(
        device: &wgpu::Device,
        volume: &GpuVolume,
        color_format: wgpu::TextureFormat,
    ) -> Result<VolumeDrawer> {
        if !DRAW_COLOR_FORMATS.contains(&color_format) {
            return Err(RuntimeError::Target(format!(
                "colour format {color_format:?} (the drawer blends onto {DRAW_COLOR_FORMATS:?})"
            )));
        }
        // Refuses a non-affine or singular index_to_world up front.
        Affine::cells(volume.index_to_world())?;
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty,
            count: None,
        };
        let draw_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook draw"),
            entries: &[
                entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<DrawView>() as u64
                        ),
                    },
                ),
                entry(
                    1,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<DrawInstance>() as u64,
                        ),
                    },
                ),
                entry(
                    2,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                entry(
                    3,
                    wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: LT_FORMAT,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                ),
                entry(
                    4,
                    wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: LT_FORMAT,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                ),
                entry(
                    5,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
            ],
        });
        let light = LightPass::new(device, volume);
        let composite_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("vdbcook composite"),
            source: wgpu::ShaderSource::Wgsl(COMPOSITE_WGSL.into()),
        });
        let composite_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook composite"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let composite_pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("vdbcook composite"),
                bind_group_layouts: &[Some(&composite_layout)],
                immediate_size: 0,
            });
        let composite_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("vdbcook composite"),
            layout: Some(&composite_pipeline_layout),
            vertex: wgpu::VertexState {
                module: &composite_module,
                entry_point: Some("composite_vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &composite_module,
                entry_point: Some("composite_fs"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: color_format,
                    // out.rgb = L + T·scene.rgb; out.a = scene.a.
                    blend: Some(wgpu::BlendState {
                        color: wgpu::BlendComponent {
                            src_factor: wgpu::BlendFactor::One,
                            dst_factor: wgpu::BlendFactor::SrcAlpha,
                            operation: wgpu::BlendOperation::Add,
                        },
                        alpha: wgpu::BlendComponent {
                            src_factor: wgpu::BlendFactor::Zero,
                            dst_factor: wgpu::BlendFactor::One,
                            operation: wgpu::BlendOperation::Add,
                        },
                    }),
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let dummy_depth = device
            .create_texture(&wgpu::TextureDescriptor {
                label: Some("vdbcook no depth"),
                size: wgpu::Extent3d {
                    width: 1,
                    height: 1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Depth32Float,
                usage: wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            })
            .create_view(&Default::default());
        let shadow_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook sun shadows"),
            entries: &[0, 1].map(|binding| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::all(),
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: true },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }),
        });
        let lt_stand_in = [
            lt_view(device, (1, 1), "vdbcook draw (half stand-in, written)"),
            lt_view(device, (1, 1), "vdbcook draw (half stand-in, read)"),
        ];
        let mut drawer = VolumeDrawer {
            pipelines: vec![None; Variant::COUNT],
            half_pipelines: vec![None; Variant::COUNT],
            resolution: MarchResolution::Full,
            lit_crossfade: LitCrossfade::default(),
            light_ahead: 0,
            lt_stand_in,
            shadow_layout,
            light,
            draw_layout,
            composite_pipeline,
            composite_layout,
            vol: Bound::of(volume),
            color_format,
            dummy_depth,
            lt: None,
            slots: Vec::new(),
            interleave: Interleave::Auto,
        };
        // The flat pipeline and the default lighting's (nearest density, the near field).
        drawer.pipeline(device, Variant::default());
        drawer.pipeline(
            device,
            Variant {
                lit: true,
                near: true,
                ..Default::default()
            },
        );
        Ok(drawer)
    }

    /// Draws from `volume` from now on, keeping the pipelines: for a [`crate::StreamingVolume`]
    /// after its window moved (`stream.volume()`; instance times are then window-local).
    /// Refuses ([`RuntimeError::Rebind`]) a volume laid out differently from the one this
    /// drawer was built for. Work recorded before still reads the old window's topology.
    pub fn rebind(&mut self, volume: &GpuVolume) -> Result<()> {
        self.vol.rebind(volume)?;
        self.light.invalidate();
        Ok(())
    }

    /// Makes the next lit draw rebuild its light volumes (it rebuilds by itself when frames,
    /// instances' rotations or scales, the light or the medium change; the builds are submitted
    /// by `prepare` itself, so a dropped encoder leaves none unbuilt).
    pub fn invalidate_light_volumes(&self) {
        self.light.invalidate();
    }

    /// Light volumes this drawer's `prepare` calls have built and reused so far: a flip-book
    /// crossfade whose pair moves on by one frame builds one volume and copies the other from
    /// the build before (a GPU copy), and a repeated pair reuses its whole build.
    pub fn light_builds(&self) -> crate::LightBuilds {
        self.light.counts()
    }

    /// The layout of [`SunShadows::bind_group`] (for an engine's pipeline layout).
    pub fn shadow_layout(&self) -> &wgpu::BindGroupLayout {
        &self.shadow_layout
    }

    /// Builds (and submits) the light volumes of `instances` under `shading`'s lighting, as
    /// [`VolumeDrawer::prepare`] would (a later draw of the same instances and shading reads
    /// the same build), and returns the bind group through which an engine's shaders read the
    /// sun's transmittance at any world point (`vdb_sun_transmittance` in
    /// [`crate::shadow_wgsl`]): keep it while a pass that binds it is pending. Refuses a
    /// shading without lighting (`RuntimeError::Setting`). Creates one small buffer and a bind
    /// group.
    pub fn sun_shadows(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        instances: &[Instance],
        shading: &Shading,
    ) -> Result<SunShadows> {
        if shading.lighting.is_none() {
            return Err(RuntimeError::Setting(
                "sun shadows need Shading::lighting (the light volumes of the lit mode)".into(),
            ));
        }
        let (mut draws, [volumes, _], _) = self.instances(DVec3::ZERO, instances, shading)?;
        // The unit cell-space direction toward the sun: each lit instance's light volume's.
        let suns: Vec<[f32; 4]> = draws
            .iter()
            .filter(|d| d.lit != 0)
            .map(|d| volumes.volumes[d.place.lv_dims0[3] as usize].sun)
            .collect();
        let build = self.build_lights(device, queue, &mut draws, &volumes)?;
        let mut casters: Vec<ShadowInstance> = draws
            .iter()
            .filter(|d| d.lit != 0)
            .zip(suns)
            .map(|(d, sun)| {
                let p = &d.place;
                ShadowInstance {
                    cell_from_world: d.cell_from_world,
                    sun: [sun[0], sun[1], sun[2], p.sun_cell[3]],
                    lo0: p.lv_lo0,
                    dims0: p.lv_dims0,
                    lo1: p.lv_lo1,
                    dims1: p.lv_dims1,
                    weight: [p.misc[1], 0.0, 0.0, 0.0],
                }
            })
            .collect();
        let count = casters.len();
        if casters.is_empty() {
            // An array of one instance that casts nothing (extinction 0).
            casters.push(ShadowInstance::zeroed());
        }
        let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vdbcook sun shadows"),
            contents: bytemuck::cast_slice(&casters),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let pool = build.as_ref().map_or_else(
            || {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("vdbcook sun shadows (no light volume)"),
                    size: 8,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                })
            },
            |b| b.pool.clone(),
        );
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook sun shadows"),
            layout: &self.shadow_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: pool.as_entire_binding(),
                },
            ],
        });
        Ok(SunShadows {
            bind_group,
            casters: count,
            _light: build,
        })
    }

    /// The colour format this drawer blends onto.
    pub fn color_format(&self) -> wgpu::TextureFormat {
        self.color_format
    }

    fn check_targets(&self, target: &DrawTarget, (w, h): (u32, u32)) -> Result<()> {
        self.check_color(target.color, (w, h))?;
        if let Some(d) = target.depth {
            let d = d.texture();
            if !DRAW_DEPTH_FORMATS.contains(&d.format()) {
                return Err(RuntimeError::Target(format!(
                    "depth format {:?} (the drawer reads {DRAW_DEPTH_FORMATS:?}; a depth-stencil \
                     format needs its depth copied out)",
                    d.format()
                )));
            }
            if (d.width(), d.height()) != (w, h)
                || d.sample_count() != 1
                || !d.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING)
            {
                return Err(RuntimeError::Target(format!(
                    "depth texture {}x{} ({} samples, usage {:?}): needs the viewport size \
                     {w}x{h}, one sample and TEXTURE_BINDING",
                    d.width(),
                    d.height(),
                    d.sample_count(),
                    d.usage()
                )));
            }
        }
        Ok(())
    }

    /// A colour view the drawer can composite onto at viewport size `w`×`h`: its format, that
    /// size, one sample, `RENDER_ATTACHMENT`.
    fn check_color(&self, color: &wgpu::TextureView, (w, h): (u32, u32)) -> Result<()> {
        let c = color.texture();
        if c.format() != self.color_format {
            return Err(RuntimeError::Target(format!(
                "colour target format {:?}, the drawer was built for {:?}",
                c.format(),
                self.color_format
            )));
        }
        if (c.width(), c.height()) != (w, h)
            || c.sample_count() != 1
            || !c.usage().contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
        {
            return Err(RuntimeError::Target(format!(
                "colour target {}x{} ({} samples, usage {:?}): needs the viewport size {w}x{h}, \
                 one sample and RENDER_ATTACHMENT",
                c.width(),
                c.height(),
                c.sample_count(),
                c.usage()
            )));
        }
        Ok(())
    }

    /// The `(L, T)` texture for `size`, created when the size changes.
    fn lt_texture(&mut self, device: &wgpu::Device, size: (u32, u32)) -> &LtTexture {
        if self.lt.as_ref().map(|l| l.size) != Some(size) {
            let view = lt_view(device, size, "vdbcook draw (L, T)");
            // Blocks of 2×2 pixels at most (4×4 blocks use its corner).
            let half = lt_view(
                device,
                (size.0.div_ceil(2), size.1.div_ceil(2)),
                "vdbcook draw (L, T) per block",
            );
            let composite_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vdbcook composite"),
                layout: &self.composite_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                }],
            });
            self.lt = Some(LtTexture {
                size,
                view,
                half,
                composite_group,
            });
        }
        self.lt.as_ref().expect("just created")
    }

    /// The shading checked, then the GPU instances in front-to-back order (by the distance
    /// from the eye, or the near plane's centre, to the centre of each instance's box; ties keep
    /// the caller's order), leaving out instances with nothing > 0 in their frames and nothing
    /// glowing, the light volumes the lit ones need and those of the frames after their pairs
    /// (only with `light_ahead`), and each instance's box (content and emission) as its eight
    /// world corners.
    #[allow(clippy::type_complexity)]
    fn instances(
        &self,
        eye: DVec3,
        instances: &[Instance],
        shading: &Shading,
    ) -> Result<(Vec<DrawInstance>, [LitVolumes; 2], Vec<[DVec3; 8]>)> {
        let medium = &shading.medium;
        shading
            .settings()
            .validate(self.vol.frames)
            .map_err(|e| RuntimeError::Setting(format!("shading: {e}")))?;
        let mut out = Vec::with_capacity(instances.len());
        let mut volumes = LitVolumes::default();
        let mut ahead = LitVolumes::default();
        for (i, inst) in instances.iter().enumerate() {
            inst.validate()
                .map_err(|e| RuntimeError::Setting(format!("instance {i}: {e}")))?;
            let Some(meta) = self.vol.assets.get(inst.asset) else {
                return Err(RuntimeError::Setting(format!(
                    "instance {i}: asset {} is not in the volume ({} asset(s))",
                    inst.asset,
                    self.vol.assets.len()
                )));
            };
            let (f0, f1, a) = inst
                .frames(meta.frames)
                .map_err(|e| RuntimeError::Setting(format!("instance {i}: {e}")))?;
            let xf = Affine::cells(&inst.index_to_world(&meta.index_to_world))
                .map_err(|e| RuntimeError::Transform(format!("instance {i}: {e}")))?;
            let union = |boxes: [Option<([f64; 3], [f64; 3])>; 2]| {
                boxes.into_iter().flatten().reduce(box_union)
            };
            let emit_box = match &medium.emission {
                Some(e) => union([meta.emission_box(e, f0)?, meta.emission_box(e, f1)?]),
                None => None,
            };
            let content = union([meta.content[f0], meta.content[f1]]);
            // An instance with nothing > 0 in its frames and nothing glowing draws nothing.
            let Some((lo, hi)) = content.or(emit_box) else {
                continue;
            };
            let (blo, bhi) = union([content, emit_box]).expect("one of them");
            let corners: [DVec3; 8] = std::array::from_fn(|c| {
                let p = [0, 1, 2].map(|k| if c >> k & 1 == 0 { blo[k] } else { bhi[k] });
                DVec3::from(xf.world_of(p))
            });
            let centre = xf.world_of([0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k])));
            let distance = (DVec3::from(centre) - eye).length();
            // world → cell: c = inv_a·(w − b).
            let shift = [0, 1, 2].map(|r| (0..3).map(|k| xf.inv_a[r][k] * xf.b[k]).sum::<f64>());
            let row = |r: usize| {
                let m = xf.inv_a[r];
                [m[0] as f32, m[1] as f32, m[2] as f32, -shift[r] as f32]
            };
            let v4 = |v: [f64; 3], w: f32| [v[0] as f32, v[1] as f32, v[2] as f32, w];
            let (clo, chi) = content.map_or(([1.0; 4], [0.0; 4]), |(l, h)| (v4(l, a), v4(h, 0.0)));
            let absorb = medium.absorb * inst.density_scale;
            let t = inst.tint;
            let roots = [f0, f1].map(|f| (f * meta.root_len) as u32);
            let mut d = DrawInstance {
                cell_from_world: [row(0), row(1), row(2)],
                tint_absorb: [t.x, t.y, t.z, absorb],
                // The crossfade weight rides in `box_lo.w` even when the box is empty.
                box_lo: [clo[0], clo[1], clo[2], a],
                box_hi: chi,
                emit_lo: emit_box.map_or([1.0; 4], |b| v4(b.0, 0.0)),
                emit_hi: emit_box.map_or([0.0; 4], |b| v4(b.1, 0.0)),
                frame_root0: roots[0],
                frame_root1: roots[1],
                lit: 0,
                asset: inst.asset as u32,
                place: LitPlace::zeroed(),
            };
            if let Some(l) = &shading.lighting {
                d.lit = 1;
                let (k, albedo) = medium.extinction_albedo();
                let extinction = k * inst.density_scale as f64;
                // A light volume per frame of the crossfade, in the instance's cell space; the
                // bases hold their indices in `volumes` until `prepare` places them.
                // (With a light stride, the light of each frame's span.)
                let lit_by = [f0, f1].map(|f| light_span(f, inst.light_stride, &meta.content));
                let grids =
                    lit_by.map(|(_, b)| LightGrid::with_levels(b, l.light_res, meta.lod().0));
                // The light volume of frame `f` over `grid`, and (only for a volume not listed
                // yet) its diffusion inputs.
                let volume = |grid: &LightGrid, f: usize| {
                    let at = FrameAt {
                        asset: inst.asset as u32,
                        frame_root: (f * meta.root_len) as u32,
                        lod: meta.lod(),
                    };
                    LightParams::new(
                        grid,
                        &xf,
                        (l.light_dir, l.ms_model),
                        extinction,
                        medium.unit,
                        at,
                    )
                };
                let inputs = |grid: &LightGrid| {
                    (l.ms_model == MsModel::Diffusion).then(|| {
                        DiffusionInputs::new(
                            grid,
                            light_dirs(&xf, l.light_dir, medium.unit),
                            extinction,
                            albedo,
                            (medium.phase_g, medium.phase_w),
                            l.ms_gather,
                        )
                    })
                };
                let pair = [0, 1].map(|n| volume(&grids[n], lit_by[n].0));
                let mut idx = [0u32; 2];
                for (n, (grid, &lp)) in grids.iter().zip(&pair).enumerate() {
                    idx[n] = volumes
                        .volumes
                        .iter()
                        .position(|v| *v == lp)
                        .unwrap_or_else(|| {
                            volumes.volumes.push(lp);
                            volumes.diffusion.push(inputs(grid));
                            volumes.volumes.len() - 1
                        }) as u32;
                }
                // The flip-book frame after the pair (the first after the last: effects loop;
                // with a light stride, the first frame of the next span), whose light a drawer
                // building light ahead builds next.
                let n = inst.light_stride.max(1) as usize;
                let next = (f1 / n + 1).saturating_mul(n);
                let next = if next >= meta.frames { 0 } else { next };
                if self.light_ahead > 0 {
                    let (key, b) = light_span(next, inst.light_stride, &meta.content);
                    let grid = LightGrid::with_levels(b, l.light_res, meta.lod().0);
                    let lp = volume(&grid, key);
                    if !pair.contains(&lp) && !ahead.volumes.contains(&lp) {
                        ahead.volumes.push(lp);
                        ahead.diffusion.push(inputs(&grid));
                    }
                }
                d.place = LitPlace::new(
                    &xf,
                    medium,
                    l,
                    inst.density_scale,
                    &[(&grids[0], idx[0], roots[0]), (&grids[1], idx[1], roots[1])],
                    a,
                );
                if self.lit_crossfade == LitCrossfade::Dither {
                    d.place.set_dither();
                }
            }
            out.push((distance, d, corners));
        }
        out.sort_by(|x, y| x.0.total_cmp(&y.0));
        let corners = out.iter().map(|x| x.2).collect();
        Ok((
            out.into_iter().map(|(_, d, _)| d).collect(),
            [volumes, ahead],
            corners,
        ))
    }

    /// Builds (and submits) the light volumes `volumes` unless a kept build has them, and points
    /// each lit instance of `draws` at its volumes' base elements (until then they hold their
    /// indices in `volumes`). `None` without light volumes.
    fn build_lights(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        draws: &mut [DrawInstance],
        volumes: &LitVolumes,
    ) -> Result<Option<Arc<LightEntry>>> {
        if volumes.volumes.is_empty() {
            return Ok(None);
        }
        let b = self.light.prepare(
            device,
            queue,
            &self.vol.group,
            &volumes.volumes,
            &volumes.diffusion,
        )?;
        for d in draws.iter_mut().filter(|d| d.lit != 0) {
            let p = &mut d.place;
            p.set_bases(
                b.bases[p.lv_dims0[3] as usize],
                b.bases[p.lv_dims1[3] as usize],
            );
        }
        Ok(Some(b))
    }

    /// Makes every pipeline variant now (lit or flat; trilinear density, the near field, the
    /// emission pass on or off; overlapping instances interleaved or not: 20 pipelines), so
    /// that no later `prepare` compiles one (a second or more each on software Vulkan).
    /// [`VolumeDrawer::warm_up_for`] makes only those one shading needs.
    pub fn warm_up(&mut self, device: &wgpu::Device) {
        for i in 0..Variant::COUNT {
            let v = Variant::of_index(i);
            if v.index() == i {
                self.pipeline(device, v);
            }
        }
    }

    /// Sets when draws interleave their instances ([`Interleave`]; `Auto` by default).
    pub fn set_interleave(&mut self, interleave: Interleave) {
        self.interleave = interleave;
    }

    /// Sets how many rays later draws march ([`MarchResolution`]; `Full` by default). The
    /// half-resolution pipelines are made by the next `prepare` or `warm_up` that needs them.
    pub fn set_march_resolution(&mut self, resolution: MarchResolution) {
        self.resolution = resolution;
    }

    /// How many rays draws march ([`MarchResolution`]).
    pub fn march_resolution(&self) -> MarchResolution {
        self.resolution
    }

    /// Sets how the lit march crosses instances between two frames ([`LitCrossfade`];
    /// `Lerp` by default).
    pub fn set_lit_crossfade(&mut self, light: LitCrossfade) {
        self.lit_crossfade = light;
    }

    /// How the lit march crosses instances between two frames ([`LitCrossfade`]).
    pub fn lit_crossfade(&self) -> LitCrossfade {
        self.lit_crossfade
    }

    /// Builds each lit instance's next light volume ahead, over `displayed_frames` calls of
    /// [`VolumeDrawer::prepare`] (0, the default: no building ahead). With it, `prepare` also
    /// builds the light volume of the flip-book frame after each instance's pair (after the
    /// last frame, the first: it assumes forward, looping play), one volume after the other,
    /// each call a share of the work (whole dispatches by estimated cost) such that the volumes
    /// asked for are built in `displayed_frames` calls; when the time moves on to such a frame
    /// its volume is copied rather than built inside that displayed frame. A flip-book at 24
    /// fps shown at 60 changes frame every 2 or 3 displayed frames: `2` spreads each build over
    /// the frames before it is needed. The light drawn stays the exact build (the same bits);
    /// what moves is when the work happens. A volume needed before its build completes is
    /// finished (or built) at once. Of no use while the light, the medium or an instance's
    /// rotation or scale changes every frame (each frame then needs new volumes; up to one
    /// build a call goes unused), nor for effects played backwards or not looping (one unused
    /// build at the end). Costs a second scratch while on (the solve's, about
    /// `light_res³ · 69` bytes, and the density's, `light_res³ · 4`); 0 frees it.
    /// `docs/engine.md` §6 has its figures.
    pub fn set_light_ahead(&mut self, displayed_frames: u32) {
        self.light_ahead = displayed_frames;
        if displayed_frames == 0 {
            self.light.drop_ahead();
        }
    }

    /// Displayed frames a light volume is built ahead over (0: none).
    pub fn light_ahead(&self) -> u32 {
        self.light_ahead
    }

    /// Makes the pipelines draws under `shading` use (with and without overlapping instances).
    pub fn warm_up_for(&mut self, device: &wgpu::Device, shading: &Shading) {
        for interleave in [false, true] {
            let v = Variant::of_shading(shading, interleave);
            self.pipeline(device, v);
        }
    }

    /// The pipeline of variant `v`, made if missing.
    fn pipeline(&mut self, device: &wgpu::Device, v: Variant) {
        let i = v.index();
        let half = self.resolution != MarchResolution::Full;
        if self.pipelines[i].is_some() && (!half || self.half_pipelines[i].is_some()) {
            return;
        }
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("vdbcook draw"),
            source: wgpu::ShaderSource::Wgsl(draw_source(v).into()),
        });
        let layouts = [&self.draw_layout, &self.light.read_layout];
        if self.pipelines[i].is_none() {
            self.pipelines[i] = Some(self.vol.compute_pipeline(
                device,
                "vdbcook draw",
                &module,
                "draw_main",
                &layouts,
            ));
        }
        if half && self.half_pipelines[i].is_none() {
            self.half_pipelines[i] = Some(self.vol.compute_pipeline(
                device,
                "vdbcook draw (half resolution)",
                &module,
                "draw_half_main",
                &layouts,
            ));
        }
    }

    /// A slot for a draw of `n` instances: one no draw holds (grown if too small), else new.
    fn slot(&mut self, device: &wgpu::Device, n: usize) -> Arc<DrawSlot> {
        let free = self.slots.iter().position(|s| Arc::strong_count(s) == 1);
        if let Some(i) = free {
            if self.slots[i].capacity >= n {
                return self.slots[i].clone();
            }
            self.slots.swap_remove(i);
        }
        let capacity = n.next_power_of_two().max(4);
        let slot = Arc::new(DrawSlot {
            view: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vdbcook draw view"),
                size: std::mem::size_of::<DrawView>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            instances: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vdbcook draw instances"),
                size: (capacity * std::mem::size_of::<DrawInstance>()) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            capacity,
        });
        self.slots.push(slot.clone());
        slot
    }

    /// Gets the draw of `instances` seen through `view` onto `target` ready: checks everything,
    /// orders the instances front to back, builds (and submits on `queue`) the light volumes
    /// the lit ones need unless a kept build has them, makes the pipeline variant the shading
    /// needs if missing, writes the view and instance uniforms (`Queue::write_buffer`: they
    /// take effect at the next submission) into a slot of their own, and finds the pixels the
    /// instances can cover (their boxes projected; the whole viewport where a box reaches
    /// behind the eye). Then [`VolumeDrawer::record`] it into the encoder of that submission;
    /// keep the [`PreparedDraw`] until then. Any number of draws may be prepared and recorded
    /// per submission (each composites over what the draws recorded before it left).
    #[allow(clippy::too_many_arguments)]
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &DrawTarget,
        view: &View,
        instances: &[Instance],
        shading: &Shading,
    ) -> Result<PreparedDraw> {
        let rays = view.rays()?;
        let medium = &shading.medium;
        if !(medium.absorb >= 0.0 && medium.absorb.is_finite()) {
            return Err(RuntimeError::Setting(format!(
                "absorb {} (finite, ≥ 0)",
                medium.absorb
            )));
        }
        let size = view.viewport;
        self.check_targets(target, size)?;
        let (mut gpu_instances, [volumes, ahead], corners) =
            self.instances(rays.eye(), instances, shading)?;
        let rect = coverage(view, &corners);
        let build = self.build_lights(device, queue, &mut gpu_instances, &volumes)?;
        if self.light_ahead > 0 && shading.lighting.is_some() {
            let (v, d) = (&ahead.volumes, &ahead.diffusion);
            let spread = self.light_ahead;
            self.light
                .ahead(device, queue, &self.vol.group, v, d, spread);
        }
        let light_group = build
            .as_ref()
            .map_or_else(|| self.light.empty_group.clone(), |b| b.read.clone());
        let interleave = match self.interleave {
            Interleave::Auto => boxes_overlap(&corners),
            Interleave::Always => true,
            Interleave::Never => false,
        };
        let variant = Variant::of_shading(shading, interleave);
        self.pipeline(device, variant);
        // The reduced-resolution march's blocks: those holding a covered pixel.
        let block = self.resolution.block();
        let half = block > 1 && !gpu_instances.is_empty();
        let block = if half { block } else { 0 };
        let [rx, ry, rw, rh] = rect;
        let b = block.max(1);
        let (half_lo, half_hi) = (
            [rx / b, ry / b],
            [(rx + rw).div_ceil(b), (ry + rh).div_ceil(b)],
        );
        let m4 = |m: &DMat4| m.as_mat4().to_cols_array_2d();
        // The emission pass: every flat instance's, and lit ones' from another channel (the lit
        // march glows its own).
        let channel = medium.emission.map_or(0, |e| e.channel);
        let params = DrawView {
            view_from_clip: m4(&rays.view_from_clip),
            world_from_view: m4(&rays.world_from_view),
            forward: [
                rays.forward.x as f32,
                rays.forward.y as f32,
                rays.forward.z as f32,
                rays.perspective as u32 as f32,
            ],
            viewport: [size.0, size.1],
            jitter: [view.jitter.x, view.jitter.y],
            near_ndc: rays.near_ndc as f32,
            instance_count: gpu_instances.len() as u32,
            has_depth: target.depth.is_some() as u32,
            emit_channel: channel as u32,
            origin: [rect[0], rect[1]],
            half_lo,
            half_hi,
            block,
            _pad: 0,
            shading: ShadingUniform::new(
                medium,
                &shading.lighting.clone().unwrap_or_default(),
                &shading.integrator,
                channel == 0,
            ),
        };
        let slot = self.slot(device, gpu_instances.len().max(1));
        queue.write_buffer(&slot.view, 0, bytemuck::bytes_of(&params));
        if !gpu_instances.is_empty() {
            queue.write_buffer(&slot.instances, 0, bytemuck::cast_slice(&gpu_instances));
        }
        let depth = target.depth.unwrap_or(&self.dummy_depth).clone();
        let lt = self.lt_texture(device, size);
        let (lt_view, half_view, composite_group) =
            (lt.view.clone(), lt.half.clone(), lt.composite_group.clone());
        // Pass one (half resolution) writes the blocks at binding 4; pass two (every pixel)
        // reads them at binding 5; stand-ins fill the other binding.
        let [stand_in_w, stand_in_r] = &self.lt_stand_in;
        let draw_group = |written: &wgpu::TextureView, read: &wgpu::TextureView| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vdbcook draw"),
                layout: &self.draw_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: slot.view.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: slot.instances.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&depth),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::TextureView(&lt_view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: wgpu::BindingResource::TextureView(written),
                    },
                    wgpu::BindGroupEntry {
                        binding: 5,
                        resource: wgpu::BindingResource::TextureView(read),
                    },
                ],
            })
        };
        let (group, half_group) = if half {
            (
                draw_group(stand_in_w, &half_view),
                Some(draw_group(&half_view, stand_in_r)),
            )
        } else {
            (draw_group(stand_in_w, stand_in_r), None)
        };
        Ok(PreparedDraw {
            variant: variant.index(),
            group,
            half_group,
            half_blocks: [half_hi[0] - half_lo[0], half_hi[1] - half_lo[1]],
            light_group,
            composite_group,
            color: target.color.clone(),
            rect,
            _slot: slot,
            _light: build,
        })
    }

    /// Records a prepared draw into `encoder`: a compute pass over the covered pixels that
    /// writes `(L, T)` per pixel, then a render pass that blends `out = L + T·scene` onto the
    /// target's colour (loaded and stored, scissored to the covered pixels). It records
    /// commands only: it creates no buffer, bind group or pipeline and writes nothing through
    /// the queue (it has no device to). Instances of this volume composite front to back per
    /// pixel (ordered by distance, see `docs/engine.md`); draws composite in the order they are
    /// recorded.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder, draw: &PreparedDraw) {
        self.record_to(encoder, draw, &draw.color);
    }

    /// [`VolumeDrawer::record`] onto `color` instead of the colour view the draw was prepared
    /// with: for an engine whose colour target alternates between textures after `prepare`
    /// (Bevy's post-processing flips two main textures per target, and a later camera on the
    /// same target finds the other one). `color` must be a view of the same kind the draw was
    /// prepared for — the drawer's colour format, the draw's viewport size, one sample,
    /// `RENDER_ATTACHMENT` — else nothing is recorded and the error says why. The depth stays
    /// the prepared one (it is read by the draw's bind group).
    pub fn record_onto(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        draw: &PreparedDraw,
        color: &wgpu::TextureView,
    ) -> Result<()> {
        let p = draw.color.texture();
        self.check_color(color, (p.width(), p.height()))?;
        self.record_to(encoder, draw, color);
        Ok(())
    }

    /// What [`VolumeDrawer::record`] records, compositing onto `color`.
    fn record_to(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        draw: &PreparedDraw,
        color: &wgpu::TextureView,
    ) {
        if draw.is_empty() {
            return;
        }
        let [x, y, w, h] = draw.rect;
        // One compute pass of the draw's variant: the reduced-resolution blocks (if any), then
        // every covered pixel.
        let mut dispatch =
            |label, pipelines: &[Option<wgpu::ComputePipeline>], group, [w, h]: [u32; 2]| {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(label),
                    timestamp_writes: None,
                });
                pass.set_pipeline(pipelines[draw.variant].as_ref().expect("made by prepare"));
                pass.set_bind_group(0, &self.vol.group, &[]);
                pass.set_bind_group(1, group, &[]);
                pass.set_bind_group(2, &draw.light_group, &[]);
                pass.dispatch_workgroups(w.div_ceil(WORKGROUP), h.div_ceil(WORKGROUP), 1);
            };
        if let Some(half_group) = &draw.half_group {
            dispatch(
                "vdbcook draw (reduced resolution)",
                &self.half_pipelines,
                half_group,
                draw.half_blocks,
            );
        }
        dispatch("vdbcook draw", &self.pipelines, &draw.group, [w, h]);
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("vdbcook composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: color,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_scissor_rect(x, y, w, h);
        pass.set_pipeline(&self.composite_pipeline);
        pass.set_bind_group(0, &draw.composite_group, &[]);
        pass.draw(0..3, 0..1);
    }

    /// [`VolumeDrawer::prepare`] and [`VolumeDrawer::record`] in one call; returns the prepared
    /// draw, to keep until `encoder` is submitted.
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &DrawTarget,
        view: &View,
        instances: &[Instance],
        shading: &Shading,
    ) -> Result<PreparedDraw> {
        let d = self.prepare(device, queue, target, view, instances, shading)?;
        self.record(encoder, &d);
        Ok(d)
    }
}

/// The pixels (x, y, width, height) boxes of world corners `boxes` can cover seen through
/// `view`: the union of their projections grown by two pixels (the jitter and the rasterizing
/// Which `draw_main` a draw runs: lit or flat, and the code a draw may skip compiled out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Variant {
    lit: bool,
    /// Trilinear density in the lit march (flat draws read no density by point).
    trilinear: bool,
    /// The near field toward the sun (lit only).
    near: bool,
    /// Some instances' boxes overlap: the sweep that interleaves them along each ray.
    interleave: bool,
    /// The emission pass (flat: any emission; lit: emission from another channel than the
    /// density, which the lit march does not glow itself).
    emit: bool,
}

impl Variant {
    const COUNT: usize = 32;
    /// Its slot in `VolumeDrawer::pipelines` (flat variants ignore the lit flags).
    fn index(self) -> usize {
        let lit = self.lit as usize;
        lit | (lit & self.trilinear as usize) << 1
            | (lit & self.near as usize) << 2
            | (self.interleave as usize) << 3
            | (self.emit as usize) << 4
    }
    /// The variant draws under `shading` run (`interleave`: some instances' boxes overlap).
    fn of_shading(shading: &Shading, interleave: bool) -> Variant {
        let lit = shading.lighting.is_some();
        Variant {
            lit,
            trilinear: shading.integrator.filter == vdbcook_scene::Filter::Trilinear,
            near: shading.lighting.as_ref().is_some_and(|l| l.sun_near > 0.0),
            interleave,
            emit: shading
                .medium
                .emission
                .is_some_and(|e| !lit || e.channel > 0),
        }
    }
    fn of_index(i: usize) -> Variant {
        Variant {
            lit: i & 1 != 0,
            trilinear: i & 2 != 0,
            near: i & 4 != 0,
            interleave: i & 8 != 0,
            emit: i & 16 != 0,
        }
    }
}

/// Whether any two of the instances' boxes (eight world corners each) overlap, by their
/// world-axis bounds (conservative: a rotated box's bounds are larger than the box).
fn boxes_overlap(boxes: &[[DVec3; 8]]) -> bool {
    let bounds: Vec<(DVec3, DVec3)> = boxes
        .iter()
        .map(|c| {
            c.iter()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(*p), hi.max(*p))
                })
        })
        .collect();
    // Sweep along x: each box against those that start before it ends.
    let mut order: Vec<usize> = (0..bounds.len()).collect();
    order.sort_by(|&a, &b| bounds[a].0.x.total_cmp(&bounds[b].0.x));
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            if bounds[b].0.x >= bounds[a].1.x {
                break;
            }
            let (la, ha) = bounds[a];
            let (lb, hb) = bounds[b];
            if la.y < hb.y && lb.y < ha.y && la.z < hb.z && lb.z < ha.z {
                return true;
            }
        }
    }
    false
}

/// The pixels (x, y, width, height) boxes of world corners `boxes` can cover seen through
/// `view`: the union of their projections grown by two pixels (the jitter and the rasterizing
/// of edges), clamped to the viewport; the whole viewport where a box reaches behind the eye.
fn coverage(view: &View, boxes: &[[DVec3; 8]]) -> [u32; 4] {
    let (w, h) = view.viewport;
    let clip = view.proj.as_dmat4() * view.view.as_dmat4();
    let (mut lo, mut hi) = (
        glam::DVec2::splat(f64::INFINITY),
        glam::DVec2::splat(f64::NEG_INFINITY),
    );
    for corners in boxes {
        let mut behind = 0;
        let (mut blo, mut bhi) = (lo, hi);
        for c in corners {
            let p = clip * c.extend(1.0);
            if !(p.w > 1e-9 * (p.x.abs() + p.y.abs() + p.z.abs()).max(1e-30)) {
                behind += 1;
                continue;
            }
            let ndc = glam::DVec2::new(p.x / p.w, p.y / p.w);
            let px = glam::DVec2::new(
                (ndc.x + 1.0) * 0.5 * w as f64,
                (1.0 - ndc.y) * 0.5 * h as f64,
            );
            blo = blo.min(px);
            bhi = bhi.max(px);
        }
        match behind {
            0 => (lo, hi) = (blo, bhi),
            8 => {}
            _ => return [0, 0, w, h],
        }
    }
    if !(lo.x <= hi.x && lo.y <= hi.y) {
        return [0, 0, 0, 0];
    }
    let j = view.jitter.as_dvec2().abs();
    let x0 = (lo.x - 2.0 - j.x).floor().clamp(0.0, w as f64) as u32;
    let y0 = (lo.y - 2.0 - j.y).floor().clamp(0.0, h as f64) as u32;
    let x1 = (hi.x + 2.0 + j.x).ceil().clamp(0.0, w as f64) as u32;
    let y1 = (hi.y + 2.0 + j.y).ceil().clamp(0.0, h as f64) as u32;
    [x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    /// The Rust mirrors of `draw.wgsl`'s structs have the WGSL layouts (laid out by naga).
    #[test]
    fn draw_structs_mirror_the_wgsl() {
        use crate::layout_check::{assert_mirrors, rust_layout};
        let source = draw_source(Variant::of_index(Variant::COUNT - 1));
        assert_mirrors(
            &source,
            "DrawView",
            rust_layout!(DrawView {
                view_from_clip,
                world_from_view,
                forward,
                viewport,
                jitter,
                near_ndc,
                instance_count,
                has_depth,
                emit_channel,
                origin,
                half_lo,
                half_hi,
                block,
                _pad,
                shading,
            }),
        );
        assert_mirrors(
            &source,
            "DrawInstance",
            rust_layout!(DrawInstance {
                cell_from_world,
                tint_absorb,
                box_lo,
                box_hi,
                emit_lo,
                emit_hi,
                frame_root0,
                frame_root1,
                lit,
                asset,
                place,
            }),
        );
    }

    #[test]
    fn shadow_instance_mirrors_the_wgsl() {
        use crate::layout_check::{assert_mirrors, rust_layout};
        assert_mirrors(
            &crate::shadow_wgsl(0),
            "VdbShadowInstance",
            rust_layout!(ShadowInstance {
                cell_from_world,
                sun,
                lo0,
                dims0,
                lo1,
                dims1,
                weight,
            }),
        );
    }

    #[test]
    fn view_rays_perspective_and_orthographic() {
        let eye = Vec3::new(1.0, 2.0, 10.0);
        let v = View::look_at(
            eye,
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::Y,
            1.0,
            2.0,
            0.1,
            (200, 100),
        )
        .unwrap();
        let r = v.rays().unwrap();
        assert!(r.perspective());
        let (o, d) = r.ray(100, 50);
        assert!((o - eye.as_dvec3()).length() < 1e-5);
        // Pixel (100, 50) sits half a pixel right of and below the centre.
        assert!(d.z < -0.999 && d.x > 0.0 && d.y < 0.0, "{d}");
        // Reversed Z: depth 0 is at infinity, 1 at the near plane.
        assert_eq!(r.depth_distance(100, 50, 0.0), f64::INFINITY);
        let t = r.depth_distance(100, 50, 0.01);
        assert!((t * d.z.abs() - 10.0).abs() < 1e-3, "{t}");

        let ortho = View::new(
            glam::camera::rh::view::look_at_mat4(eye, Vec3::new(1.0, 2.0, 0.0), Vec3::Y),
            glam::camera::rh::proj::directx::orthographic(-4.0, 4.0, -2.0, 2.0, 1.0, 21.0),
            (8, 4),
        )
        .unwrap();
        let r = ortho.rays().unwrap();
        let (o, d) = r.ray(0, 0);
        assert!((d - DVec3::NEG_Z).length() < 1e-9);
        assert!(
            (o - DVec3::new(1.0 - 3.5, 2.0 + 1.5, 9.0)).length() < 1e-5,
            "{o}"
        );
        assert!((r.depth_distance(0, 0, 0.5) - 10.0).abs() < 1e-5);
        // The same with reversed Z (near and far swapped).
        let rev = View::new(
            ortho.view,
            glam::camera::rh::proj::directx::orthographic(-4.0, 4.0, -2.0, 2.0, 21.0, 1.0),
            (8, 4),
        )
        .unwrap()
        .rays()
        .unwrap();
        let (o2, d2) = rev.ray(0, 0);
        assert!(
            (o2 - o).length() < 1e-5 && (d2 - d).length() < 1e-9,
            "{o2} {d2}"
        );
        assert!((rev.depth_distance(0, 0, 0.25) - 15.0).abs() < 1e-5);
    }

    #[test]
    fn singular_views_and_bad_times_are_errors() {
        let proj = glam::camera::rh::proj::directx::perspective(1.0, 1.0, 0.1, 100.0);
        let e = View::new(Mat4::ZERO, proj, (4, 4)).unwrap_err();
        assert!(matches!(e, RuntimeError::Camera(_)), "{e}");
        assert!(e.to_string().contains("singular"), "{e}");
        let mut p = proj;
        p.z_axis = Vec4::ZERO;
        assert!(View::new(Mat4::IDENTITY, p, (4, 4)).is_err());
        assert!(View::new(Mat4::IDENTITY, proj, (0, 4)).is_err());
        let i = Instance {
            time: 2.5,
            ..Default::default()
        };
        assert_eq!(i.frames(4).unwrap(), (2, 3, 0.5));
        assert_eq!(Instance { time: 3.0, ..i }.frames(4).unwrap(), (3, 3, 0.0));
        assert!(i.frames(3).is_err());
        for t in [-0.5, f32::NAN, 3.5] {
            assert!(Instance { time: t, ..i }.frames(4).is_err(), "{t}");
        }
    }

    #[test]
    fn instance_index_to_world_composes() {
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 2.0, 2.0),
            glam::Quat::from_rotation_z(0.5),
            Vec3::new(1.0, -3.0, 4.0),
        );
        let i2w = [
            [0.5, 0.0, 0.0, 10.0],
            [0.0, 0.5, 0.0, 20.0],
            [0.0, 0.0, 0.5, 30.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let c = Instance::at(m).index_to_world(&i2w);
        let p = [3.0, -1.0, 7.0];
        let direct = m.transform_point3(Vec3::new(
            (0.5 * p[0] + 10.0) as f32,
            (0.5 * p[1] + 20.0) as f32,
            (0.5 * p[2] + 30.0) as f32,
        ));
        for r in 0..3 {
            let v = c[r][0] * p[0] + c[r][1] * p[1] + c[r][2] * p[2] + c[r][3];
            assert!((v - direct[r] as f64).abs() < 1e-4, "{r}: {v} vs {direct}");
        }
        assert_eq!(c[3], [0.0, 0.0, 0.0, 1.0]);
    }
}

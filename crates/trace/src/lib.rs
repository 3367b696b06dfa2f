//! `vdbcook-trace`: the CPU reference tracer of the flip-book asset. `vdbcook render --backend
//! cpu` draws with it on any machine, and the GPU runtime's images are tested against it, so
//! every definition below is a contract the WGSL must follow. The vocabulary both share (camera
//! and framing, settings and their validation, the affine transform, the depth range, the
//! content box) lives in the small `vdbcook-scene` crate, re-exported here; the runtime depends
//! on that crate, not on this one.
//!
//! # Spaces
//! - **Voxel positions follow OpenVDB**: the value of voxel `i` (asset index; the asset's
//!   `index_to_world`, row-major for column vectors, folds in the cook's index offset) sits at
//!   world `index_to_world · i`, and nearest lookup gives it the index-space box `[i − ½, i + ½)³`
//!   (OpenVDB's point sampler rounds to the nearest index; Houdini, Blender and `vdb_render` agree).
//! - **Cell space** (what the walk sees): index + ½, so voxel `i` is the unit cell `[i, i+1)³`
//!   and `floor` finds it. World → cell is the inverse of [`Affine::cells`], which must be
//!   affine; it is the only place the half voxel appears. A ray is `p(t) = o + t·d` with `d` the
//!   cell-space image of a *unit world* direction, so `t` is world distance from the eye. The
//!   root extent is `[0, 128·root_dims)` in cell space; outside it the density is 0, inside it
//!   unstored space holds `header.background`. Boxes in this crate's API (`stored_bbox`,
//!   `content_box`, [`Camera::framing_box`]) are in cell space: `[lo, hi)` covers voxels
//!   `lo ..= hi − 1`.
//! - **Length unit** (`RenderSettings::unit`): `Voxel` (default, as `vdb_render`): a length `Δt`
//!   counts `Δt·|d|` (index-space length); `World`: `Δt`. `absorb`, `scatter`, `step`,
//!   `shadow_step` and `gain` are per that unit.
//! - **Camera**: pinhole, `fov_y_deg` vertical; pixel `(i, j)` (row 0 at the top) looks along
//!   `normalize(f + (2(i+½)/W − 1)·tan(fov/2)·(W/H)·r + (1 − 2(j+½)/H)·tan(fov/2)·u)`, with `f`
//!   toward the look-at point, `r = normalize(f × up)`, `u = r × f`.
//!
//! # Traversal
//! Clip to the root extent (from `t = 0`: the eye may be inside), then a DDA over 128³ regions;
//! `EMPTY` regions are background spans, tiled regions constant spans; an L2 node is passed
//! over when its `l2_ranges` max says so, else a DDA over its 16³ leaf slots (empty slot =
//! background, tile = constant, brick passed over by its `brick_ranges` max), and inside a brick
//! either a voxel DDA or the whole brick span (modes that sample it themselves). Tie-breaking and
//! bounds: `dda`'s module docs. A mode passes over a node, leaf or voxel of max `m` when:
//! density/steps/delta `m ≤ 0`; first-hit modes `m ≤ cutoff`; single scatter `m < cutoff` or
//! `m ≤ 0`. Steps: one per region, leaf slot and voxel visited.
//!
//! Modes that sample by position (single scatter, delta tracking and their shadow rays) count no
//! steps, so their walk may go coarser without changing the spans it reports: inside an L2 node
//! it first passes over 4³-slot blocks by their max, and since they pass over values `≤ 0` they
//! walk only the part of the ray inside the frame's content box (the leaves whose max is not
//! `≤ 0`). The crossing parameters are the same formulas, so the images are the same (`walk`).
//!
//! # Modes (`Sample::rgba` display colour, `Sample::value` raw quantity)
//! - **Density**: `τ = Σ max(v, 0)·ℓ` over the voxels crossed (`ℓ` = segment length in the
//!   unit) — exact, no step error — stopping once `absorb·τ ≥ 20`; `T = exp(−absorb·τ)`;
//!   rgba = `(1−T, 1−T, 1−T, 1)`, value = `T`. With `emission` (the voxel values mapped to blackbody
//!   light, `vdbcook_scene::Emission`), rgb also gains the emitted light that reaches the eye: over a
//!   segment of length `ℓ` with value `v`, `T_before · E(v) · ℓ · (1 − e^{−x})/x`,
//!   `x = absorb·v·ℓ` (exact for the constant segment), `E` read from the blackbody table of the
//!   range (`blackbody_table`, linear interpolation) in f32 on both tracers.
//! - **Depth**: the first voxel (or constant span) with value `> cutoff`, entered at world
//!   distance `t`: value = `t`, rgb = `1 − clamp((t − near)/(far − near), 0, 1)`, alpha 1, where
//!   near/far are the nearest/farthest world corner distances of the frame's stored box from the
//!   eye (near = 0 with the eye inside it). Miss: rgba 0, value −1.
//! - **FirstHitDensity**: the same hit; value = its value `v`, rgb = `clamp(v / frame max)`.
//! - **BrickHue**: the same hit; in a brick `b`: rgb = `hsv(fract(0.618034·b), 0.75, 1)`,
//!   value = `b`; a tile or background hit: rgb 0.5, value −2.
//! - **Steps**: the density walk's step count `n`: value = `n`, rgb = heat map of `n / 256`
//!   (black, blue, green, yellow, red at 0, ¼, ½, ¾, 1), alpha 1.
//! - **SingleScatter** (`vdb_render`'s `VolumeRender`, gray coefficients, nearest sampling):
//!   samples at `s = k·step` (integer `k`, length from the eye) inside spans not passed over;
//!   `σ` = the voxel value; a sample with `σ < cutoff` or `σ ≤ 0` is ignored; else
//!   `ΔT = exp(−(absorb+scatter)·σ·step)`, `L += albedo·T_s·T·(1−ΔT)`, `T *= ΔT`, stop once
//!   `3T² < cutoff`; `albedo = scatter/(absorb+scatter)`. `T_s`: from the sample point toward
//!   `light_dir`, samples at `s' = k·shadow_step` (`k ≥ 1`), `T_s *= exp(−(absorb+scatter)·σ'·
//!   shadow_step/(1 + gain·s'))` for `σ' ≥ cutoff`, stop once `3T_s² < cutoff`. rgb =
//!   `light_color·L`, alpha = `1 − T`, value = `T`. Each march takes at most 2²⁰ samples.
//!   With `emission`, each counted sample also adds `T · E(σ) · step · (1 − e^{−x})/x`,
//!   `x = (absorb+scatter)·σ·step`, to rgb (before `T` takes the sample's attenuation).
//! - **DeltaTracking**: per sample `k ∈ [first_sample, first_sample + spp)` a path with the
//!   random stream `Rng::new(seed, y·W + x, k)`: free flights against the span majorant
//!   `(absorb+scatter)·m` (`m` = tile value or brick max), a tentative collision is real with
//!   probability `σ/m`; at the first real one the path ends, scoring (with probability albedo)
//!   a ratio-tracking shadow weight `Π (1 − μ/μ̄)` with `μ = (absorb+scatter)·σ/(1 + gain·s')`.
//!   rgb = `light_color · mean score`, alpha = `1 − escaped fraction`, value = escaped fraction
//!   (its mean is Density's `T` with `absorb+scatter` as the absorption). With `emission`, the
//!   path also gathers `E / μ̄` at each tentative collision (the majorant at least `1/step`
//!   where a span can emit), added to rgb. Unbiased except: at
//!   most 2¹⁶ events per path (then absorbed) and shadow weights below 1e-6 end as 0.
//!
//! - **Reference** (physically based; module `reference`): per sample a path with the stream
//!   `Rng64::new(seed, y·W + x, k)` (SplitMix64: CPU only, period 2⁶⁴): free flights by delta tracking (as above, extinction
//!   `μ = (absorb+scatter)·σ`); at a real collision the throughput is multiplied by the albedo,
//!   the sun adds `throughput · p(d·l) · light_color · T_sun` (`T_sun` by ratio tracking, no
//!   `gain`), then Russian roulette when the throughput is below 1 and a new direction from the
//!   dual-lobe Henyey–Greenstein phase `p = w·HG(g₀) + (1−w)·HG(g₁)` (`phase_g`, `phase_w`;
//!   `HG(g, μ) = (1−g²)/(4π(1+g²−2gμ)^{3/2})`, `μ` the cosine between the path direction and
//!   the next one, forward for `g > 0`). A path that scattered and leaves adds
//!   `throughput · sky`; a primary ray that leaves unscattered adds nothing. rgb = mean
//!   radiance `L` (premultiplied), alpha = `1 − T`, value = `T` (the escaped fraction), so
//!   `L + T·background` composites. With `emission`, every flight also gathers
//!   `throughput · E / μ̄` at each tentative collision (majorant at least `1/step` where a
//!   span can emit). Unbiased except: at most `bounces` scattering events and
//!   2¹⁶ tentative collisions per flight (then absorbed), shadow weights below 1e-6 end as 0.
//! - **Lit** (module `lit`, the game-speed approximation of Reference: same medium, sun, sky,
//!   phase): a light volume of optical depths toward the sun and the sky and a diffusion solve
//!   of their scattered light (or octaves of it), then a march by steps or by voxels with
//!   energy-conserving integration, the depth toward the sun walked exactly near each sample;
//!   the `lit` module docs define it exactly. rgb = `L` (premultiplied), alpha
//!   `1 − T`, value `T`.
//!
//! `step`, `shadow_step`, `cutoff` and `gain` follow `vdb_render`'s `-step`, `-shadowstep`,
//! `-cutoff` and `-gain` (defaults 1, 3, 0.005, 0.2; `absorb` 0.1, `scatter` 1.5, light
//! direction (0.3, 0.3, 0) toward the light, colour 0.7), but `vdb_render` samples trilinearly;
//! here voxels are nearest, so images agree to within that filtering.

// `!(a > b)` is how this crate refuses NaN along with the ordered case; keep that form.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod color;
mod dda;
mod delta;
pub mod diffusion;
mod exact;
mod image;
mod lit;
mod reference;
mod render;
mod rng;
mod scatter;
mod space;
pub mod vdb_render;
mod walk;

/// The integration tests' hand-built assets, for the unit tests of the walk.
#[cfg(test)]
#[path = "../tests/common/mod.rs"]
mod test_common;

pub use color::{brick_color, heat, STEPS_FULL_SCALE};
pub use delta::{MAX_EVENTS, MIN_SHADOW_WEIGHT};
pub use exact::OPAQUE_DEPTH;
pub use image::Image;
pub use lit::{
    exp_piece, lit_jitter, segment_sun, sky_depth, LightVolume, LIT_MAX_SKY_DEPTH, LIT_MIN_TRANS,
    SEGMENT_END, SEGMENT_JOIN,
};
pub use render::{render, Sample, Scratch, Tracer};
pub use rng::{pcg_hash, Rng, Rng64};
pub use scatter::MAX_MARCH_SAMPLES;
pub use space::IndexRay;
pub use walk::Holder;
// The shared view and parameter maths (one definition for this tracer and the GPU runtime).
pub use vdbcook_scene::{
    blackbody_rgb, blackbody_table, channel_max, channel_named, content_box, depth_range,
    fire_convention, from_up_frame, linear_to_srgb8, source_up, srgb_to_linear, stored_bbox,
    stored_boxes, up_frame, Affine, Basis, Camera, Display, Emission, Filter, FireConvention,
    Integrator, LengthUnit, LevelChain, LightGrid, Lighting, March, Medium, Mode, MsModel, Output,
    RenderSettings, Tonemap, TraceError, DEFAULT_NEAR_SCATTER, DEFAULT_SUN_NEAR, DRAPER_KELVIN,
    HEAT_NAMES, KELVIN_MIN_MAX, KELVIN_PER_UNIT, MAX_BOUNCES, MAX_LIGHT_RES, MAX_MS_GATHER,
    MAX_MS_OCTAVES, MAX_MS_SKY, MAX_PHASE_G, MAX_SIDE, MAX_SPP, MIN_STEP,
};
pub use vdbcook_scene::{
    length, level_start, light_dirs, normalize, octave_source, pixel_angle, sky_diffusion,
    sky_source,
};

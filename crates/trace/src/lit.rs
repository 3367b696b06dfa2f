//! `Mode::Lit`: the game-speed approximation of the reference (same medium, sun, sky and
//! phase), as the GPU runs it (`shaders/light.wgsl`, `trace.wgsl`'s `lit_primary`).
//!
//! 1. **Light volume**, once per frame and light (`LightVolume::build`), over
//!    `vdbcook_scene::LightGrid` (cubic cells, `light_res` along the content box's longest side):
//!    - density pass: a cell's density `D` is the mean of `max(v, 0)` over `sub³` nearest-voxel
//!      reads at the centres of its `sub³` sub-cells, `sub = clamp(⌈cell⌉, 1, 4)`: a box filter
//!      up to cells of 4 voxels where a cell is a whole number of voxels (otherwise some voxels
//!      are read twice and others once: an aliasing the images move with, `docs/rendering.md`,
//!      "what the density pass's aliasing hides"); wider cells read one voxel in every `cell/4`
//!      per axis (they alias: large assets at a low `light_res`) unless the asset has levels of
//!      detail (`cook --lod`): then cells snap to whole voxels of the level `k` with `cell/2^k ≤ 4`
//!      (`LightGrid::with_levels`) and read it (`LightGrid::density_level`), an exact box filter
//!      of any cell width; with the diffusion model, from the same samples, the cell's transport
//!      density for the solve's faces (`vdbcook_scene::transport_density`);
//!    - sun pass: `τ_sun` at a cell centre is the exact optical depth toward the light (`l̂`,
//!      in cell space) from the centre to the grid's far side through the voxels of the level
//!      the density pass read ([`sun_depth_exact`]: the density mode's voxel walk). A sample of
//!      the depth, not of the cells' mean density: the exponential of a depth through blurred
//!      densities is too dark on average where the density jumps from voxel to voxel
//!      (`docs/rendering.md`, "The sun pass walks the voxels"). The walk is split where the
//!      ray leaves the cell: the depth from there is where the sun's beam enters the cell, the
//!      diffusion solve's source;
//!    - sky pass: the optical depths toward the six axis directions (`cell·(D(c)/2 + Σ D beyond)`,
//!      exact for the piecewise-constant `D`), combined into the one depth `τ_sky` whose
//!      transmittance is their mean: `e^{−σ·τ_sky} = ⅙ Σ e^{−σ·τ_axis}` (σ the extinction).
//!
//!    Depths are in the settings' length unit, before the extinction; stored as f32.
//! 2. **Primary march** (`March::resolve`: `March::Auto`, the default, takes the voxel march on
//!    a frame where one step through its densest voxel has optical depth ≥
//!    `LIT_VOXEL_DEPTH`, else steps):
//!    - steps (`March::Steps`, and any trilinear march): samples at `s = (k + j)·step` from the
//!      eye (`j ∈ [0, 1)` a per-pixel jitter from `pcg_hash`, which turns banding at large steps
//!      into noise), `ρ` the nearest voxel or (`Filter::Trilinear`) the trilinear density
//!      (`Tracer::trilinear_density`; the walk still passes over spans whose max is ≤ 0, so the
//!      half-voxel fringe the filter puts outside stored content is not sampled), each sample's
//!      density standing for a step centred on it;
//!    - voxels (`March::Voxels`, [`VoxelMarch`]): the voxels the walk crosses, each cut into
//!      equal segments of at most `step`, each of its own voxel's density;
//!
//!    per segment of optical depth `x = σ·ρ·len`, energy-conserving: `L += T·α·S·(1 − e^{−x})`,
//!    `T *= e^{−x}` (exact for a constant source over the segment, so the image does not drift
//!    with the step size), `S` read where the segment's light is scattered on average
//!    ([`mean_depth`]), its sun's direct term integrated across the segment where the near
//!    field was walked, from the depths walked at its ends and there ([`segment_sun`]); stops
//!    once `T < LIT_MIN_TRANS`.
//! 3. **Source** `S = sun·… + sky·…` at that point: the sun's depth `τ_sun` from the light
//!    volume (trilinear), or, within `sun_near` cells where one cell is optically thick
//!    (`LIT_NEAR_DEPTH`) and the ray's `T ≥ LIT_NEAR_TRANS`, walked voxel by voxel and the
//!    light volume's only beyond (`Tracer::sun_depth`: the near field); then
//!    `MsModel::Diffusion` (default): single scattering `p(μ)·e^{−σ·τ_sun}` plus the diffusion
//!    solve's sun light, and its sky light as the sky's whole source, both read to first order
//!    `φ/4π + 3ḡ·J·ω/4π` (`LightVolume::diffuse_at`, `crate::diffusion`; exactly the sky at
//!    albedo 1: the white furnace holds), and where the near field was walked the
//!    once-scattered sunlight below the cells (`vdbcook_scene::near_scatter_source`: the
//!    walked transmittance's excess over the cells', which the solve's source averaged away,
//!    by the first flight's fluence at a surface, `RenderSettings::near_scatter`); or
//!    `MsModel::Octaves`: the sun's by
//!    `vdbcook_scene::octave_source`, octave `i` with the dual-lobe phase's `g` scaled by `c^i`
//!    at `μ = d·l`, and the sky's (a uniform sky, isotropic) by `vdbcook_scene::sky_source` of
//!    the light volume's `τ_sky`, what the medium takes out of the sky's beam attenuated as
//!    diffusion would (also exactly the sky at albedo 1).
//!
//! rgba = `(L + emission, 1 − T)`, value = `T`, like the other shaded modes.

#[cfg(feature = "parallel")]
use rayon::prelude::*;
pub use vdbcook_scene::LIT_NEAR_TRANS;
use vdbcook_scene::{
    light_dirs, near_scatter_source, normalize, octave_source, sky_diffusion, sky_source,
    sun_pass_stop, transport_density, Affine, Filter, LevelChain, LightGrid, MsModel,
    RenderSettings, LIT_NEAR_DEPTH, MAX_MS_OCTAVES, MAX_SUB,
};

use crate::diffusion::{self, Diffusion, DiffusionInputs};

use crate::dda::{ceil_f64, Flow};
use crate::space::IndexRay;
use crate::walk::{BrickCache, Grid, Holder, SpanSampler, Visitor};
use crate::Tracer;
use vdbcook_scene::phase;

/// Transmittance below which a `Lit` ray stops (what is left counts as opaque).
pub const LIT_MIN_TRANS: f64 = 1e-4;

/// The light volume: per cell `(τ_sun, τ_sky)` (see the module docs).
#[derive(Debug, Clone)]
pub struct LightVolume {
    pub grid: LightGrid,
    pub density: Vec<f32>,
    pub tau: Vec<[f32; 2]>,
    /// Per cell the sun's optical depth where its beam enters the cell (length units): from
    /// where the ray from the centre toward the sun leaves it (`LightGrid::centre_exit`), the
    /// diffusion solve's source (0 under `MsModel::Octaves`, which has none).
    pub sun_entry: Vec<f32>,
    /// `MsModel::Diffusion`: per cell the sun's scattered light and the sky's light, `φ/4π`
    /// and the flux `J/4π` (`crate::diffusion::solve`); empty for the octaves model.
    pub diffusion: Diffusion,
    /// Length (in the settings' unit) per cell-space unit along each axis (`light_dirs`): the
    /// metric the flux is in.
    pub axis_len: [f64; 3],
    /// The phase's mean cosine `ḡ` (the first-order read of the diffuse light).
    pub mean_cos: f64,
    /// The unit cell-space direction toward the sun.
    pub sun: [f64; 3],
    /// A cell's edge in the settings' length unit (the shortest, where voxels are not cubes).
    pub cell_len: f64,
}

impl LightVolume {
    /// Builds the light volume of the frame `frame` walks (its `Grid`, which the sun pass
    /// walks where the density pass reads full resolution) over `bbox` (the frame's content
    /// box; a span's joint box under a light stride, `Tracer::with_light_from`) for the
    /// settings' light and medium (`extinction` = absorb + scatter).
    pub(crate) fn build(
        frame: &Grid,
        bbox: Option<([f64; 3], [f64; 3])>,
        xf: &Affine,
        s: &RenderSettings,
        extinction: f64,
    ) -> LightVolume {
        let (asset, walked, frame) = (frame.asset, frame, frame.frame);
        let chain = LevelChain::of(asset);
        let grid = LightGrid::with_levels(bbox, s.lighting.light_res, chain);
        let [nx, ny, _] = grid.dims.map(|d| d as usize);
        let slab = nx * ny;
        let n = grid.cells();

        // Density pass, one z slab per task: each cell's mean density and, for the diffusion
        // solve, its transport density (`vdbcook_scene::transport_density`).
        let inputs = DiffusionInputs::of_settings(&grid, xf, s);
        let solve = s.lighting.ms_model == MsModel::Diffusion;
        let mut density = vec![0.0f32; n];
        let mut transport = vec![0.0f32; n];
        // With levels of detail, wide cells read the coarser level (`LightGrid::density_level`).
        let (level, shift, sub) = grid.density_level(chain);
        let (sub, set) = (sub as usize, asset.lod_set(frame, level));
        let fill = |(z, (out, moves)): (usize, (&mut [f32], &mut [f32]))| {
            let mut values = [0.0f64; (MAX_SUB * MAX_SUB * MAX_SUB) as usize];
            let values = &mut values[..sub * sub * sub];
            for y in 0..ny {
                for x in 0..nx {
                    let c = [x, y, z];
                    let mut sum = 0.0f64;
                    for (k, value) in values.iter_mut().enumerate() {
                        let q = [k % sub, (k / sub) % sub, k / (sub * sub)];
                        let a = [0, 1, 2].map(|i| {
                            let f = (c[i] as f64 + (q[i] as f64 + 0.5) / sub as f64) * grid.cell;
                            ((grid.lo[i] + f).floor() as i64) >> shift
                        });
                        let v = asset.value(set, a);
                        *value = if v > 0.0 { v as f64 } else { 0.0 };
                        sum += *value;
                    }
                    out[x + nx * y] = (sum / (sub * sub * sub) as f64) as f32;
                    if solve {
                        moves[x + nx * y] =
                            transport_density(values, sub, inputs.h, extinction) as f32;
                    }
                }
            }
        };
        #[cfg(feature = "parallel")]
        density
            .par_chunks_mut(slab)
            .zip(transport.par_chunks_mut(slab))
            .enumerate()
            .for_each(fill);
        #[cfg(not(feature = "parallel"))]
        density
            .chunks_mut(slab)
            .zip(transport.chunks_mut(slab))
            .enumerate()
            .for_each(fill);

        // Sun pass, per cell: the exact optical depth toward the light from the cell's centre
        // to the grid's far side, through the voxels of the level the density pass read (the
        // density mode's voxel sum; with the diffusion model it stops at the opaque depth).
        let ((l, sun_len), axis_len) = light_dirs(xf, s.lighting.light_dir, s.medium.unit);
        let mut tau = vec![[0.0f32; 2]; n];
        // τ_sun where the sun's beam enters each cell (the solve's source).
        let mut entry = vec![0.0f32; n];
        // A coarser level's own walk grid; full resolution's is the frame's.
        let coarse = (set != frame).then(|| Grid::new(asset, set));
        let voxels = coarse.as_ref().unwrap_or(walked);
        let stop = sun_pass_stop(s.lighting.ms_model, extinction);
        let sun = |(z, (out, entry)): (usize, (&mut [[f32; 2]], &mut [f32]))| {
            let mut cache = BrickCache::default();
            for y in 0..ny {
                for x in 0..nx {
                    let p = grid.centre([x as u32, y as u32, z as u32]);
                    let [t, e] = sun_depth_exact(
                        voxels,
                        &grid,
                        p,
                        (l, sun_len),
                        shift,
                        (stop, solve),
                        &mut cache,
                    );
                    out[x + nx * y][0] = t as f32;
                    entry[x + nx * y] = e as f32;
                }
            }
        };
        #[cfg(feature = "parallel")]
        tau.par_chunks_mut(slab)
            .zip(entry.par_chunks_mut(slab))
            .enumerate()
            .for_each(sun);
        #[cfg(not(feature = "parallel"))]
        tau.chunks_mut(slab)
            .zip(entry.chunks_mut(slab))
            .enumerate()
            .for_each(sun);

        // Sky: the depths toward the six axis directions, half the cell's own density plus the
        // cells beyond, from running sums along each axis.
        let mut t_mean = vec![0.0f64; n];
        let mut tau_mean = vec![0.0f64; n];
        for a in 0..3 {
            let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
            let len = grid.cell * axis_len[a];
            for v in 0..grid.dims[va] {
                for u in 0..grid.dims[ua] {
                    let cell = |k: u32| {
                        let mut c = [0u32; 3];
                        (c[a], c[ua], c[va]) = (k, u, v);
                        grid.index(c)
                    };
                    let total: f64 = (0..grid.dims[a]).map(|k| density[cell(k)] as f64).sum();
                    let mut before = 0.0f64;
                    for k in 0..grid.dims[a] {
                        let i = cell(k);
                        let own = density[i] as f64;
                        for d in [before + own / 2.0, total - before - own / 2.0] {
                            let t = d.max(0.0) * len;
                            tau_mean[i] += t / 6.0;
                            t_mean[i] += (-extinction * t).exp() / 6.0;
                        }
                        before += own;
                    }
                }
            }
        }
        for (i, t) in tau.iter_mut().enumerate() {
            t[1] = sky_depth(t_mean[i], tau_mean[i], extinction) as f32;
        }
        let diffusion = match s.lighting.ms_model {
            MsModel::Octaves => Diffusion::default(),
            MsModel::Diffusion => {
                diffusion::solve(&grid, &density, &transport, |i| entry[i] as f64, &inputs)
            }
        };
        LightVolume {
            grid,
            density,
            tau,
            sun_entry: entry,
            diffusion,
            axis_len,
            mean_cos: inputs.mean_cos(),
            sun: l,
            cell_len: inputs.h.into_iter().fold(f64::INFINITY, f64::min),
        }
    }

    /// `MsModel::Diffusion`'s diffuse light scattered at cell-space point `p` toward `eye`
    /// (the unit direction from `p` to the eye, in length units per axis: [`Self::eye_dir`]),
    /// per unit sun irradiance and unit sky radiance: `[sun, sky]`, each `φ/4π + 3ḡ·J·ω/4π`
    /// (at least 0) with `φ` and `J` trilinear weighted by the cells' densities (empty cells
    /// hold the boundary's light and would bleed into the medium's edge); the boundary's
    /// `[0, 1]` where all eight are empty.
    pub fn diffuse_at(&self, p: [f64; 3], eye: [f64; 3]) -> [f64; 2] {
        let d = &self.diffusion;
        let (mut phi, mut flux, mut den) = ([0.0f64; 2], [[0.0f64; 3]; 2], 0.0f64);
        for (i, w) in self.grid.taps(p) {
            let wd = w * self.density[i] as f64;
            for f in 0..2 {
                phi[f] += wd * d.phi[i][f] as f64;
                for (sum, &j) in flux[f].iter_mut().zip(&d.flux[i][f]) {
                    *sum += wd * j as f64;
                }
            }
            den += wd;
        }
        if !(den > 0.0) {
            // No medium around `p` (a segment's read point past the medium's edge): the light
            // outside it, none of the sun's scattered light and the sky itself.
            return [0.0, 1.0];
        }
        [0, 1].map(|f| {
            let jw: f64 = (0..3).map(|a| flux[f][a] * eye[a]).sum();
            ((phi[f] + 3.0 * self.mean_cos * jw) / den).max(0.0)
        })
    }

    /// The unit direction toward the eye of a ray along cell-space `dir`, in length units per
    /// axis (the metric of the diffusion's flux).
    pub fn eye_dir(&self, dir: [f64; 3]) -> [f64; 3] {
        normalize([0, 1, 2].map(|a| -dir[a] * self.axis_len[a]))
    }

    /// The sun's optical depth (length units) at cell-space point `p`, anywhere: inside the
    /// grid the lookup at `p`; outside it, the lookup where the ray from `p` toward the sun
    /// (unit cell-space `l`) enters the grid (the depth stored there is the rest of that ray);
    /// 0 when that ray misses the grid. What an engine's shadow lookup
    /// (`vdb_sun_transmittance` in `shaders/shadow.wgsl`) computes.
    pub fn sun_depth_at(&self, p: [f64; 3], l: [f64; 3]) -> f64 {
        let g = &self.grid;
        let hi = [0, 1, 2].map(|a| g.lo[a] + g.dims[a] as f64 * g.cell);
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            if l[a] == 0.0 {
                if !(p[a] >= g.lo[a] && p[a] <= hi[a]) {
                    return 0.0;
                }
            } else {
                let (u, v) = ((g.lo[a] - p[a]) / l[a], (hi[a] - p[a]) / l[a]);
                t0 = t0.max(u.min(v));
                t1 = t1.min(u.max(v));
            }
        }
        if !(t1 >= t0) {
            return 0.0;
        }
        self.lookup([0, 1, 2].map(|a| p[a] + t0 * l[a]))[0]
    }

    /// `(τ_sun, τ_sky)` at cell-space point `p` (trilinear).
    pub fn lookup(&self, p: [f64; 3]) -> [f64; 2] {
        let mut out = [0.0f64; 2];
        for (i, w) in self.grid.taps(p) {
            out[0] += w * self.tau[i][0] as f64;
            out[1] += w * self.tau[i][1] as f64;
        }
        out
    }
}

/// The exact optical depths (in the settings' unit) toward the light from cell-space point `p`
/// (a cell's centre) to the far side of the light volume's `grid`, through the voxels of
/// `voxels` (a level whose voxels are `2^shift` wide; `l` the unit cell-space direction toward
/// the light, `sun_len` the length per cell-space unit along it): the light volume's sun pass.
/// `[τ, τ_entry]`: from `p`, and from where the ray leaves `p`'s cell
/// (`LightGrid::centre_exit`: where the sun's beam enters the cell, the diffusion solve's
/// source); one walk split there, `τ` the two pieces' sum. The walk beyond the cell stops once
/// `stop·τ` reaches the opaque depth (`vdbcook_scene::sun_pass_stop`); the cell's own few
/// voxels are summed whole. Without `split` (the octaves model, which has no source) one walk
/// from `p` and `τ_entry` 0, as the GPU's `lv_sun_main` does.
pub(crate) fn sun_depth_exact(
    voxels: &Grid,
    grid: &LightGrid,
    p: [f64; 3],
    (l, sun_len): ([f64; 3], f64),
    shift: u32,
    (stop, split): (f64, bool),
    cache: &mut BrickCache,
) -> [f64; 2] {
    let inv = l.map(|c| if c == 0.0 { f64::INFINITY } else { 1.0 / c });
    let ray = IndexRay {
        o: p,
        d: l,
        inv,
        per_t: sun_len,
    }
    .scaled(0.5f64.powi(shift as i32));
    let exit = grid.exit(p, l);
    if !split {
        return [
            crate::render::optical_depth(voxels, &ray, 0.0, exit, stop, cache),
            0.0,
        ];
    }
    let at = grid.centre_exit(l).min(exit);
    let entry = crate::render::optical_depth(voxels, &ray, at, exit, stop, cache);
    let own = crate::render::optical_depth(voxels, &ray, 0.0, at, 0.0, cache);
    [own + entry, entry]
}

/// The depth whose transmittance is the six directions' mean transmittance `t_mean` (their
/// mean depth `tau_mean` where there is no extinction); at most `LIT_MAX_SKY_DEPTH / σ`.
pub fn sky_depth(t_mean: f64, tau_mean: f64, extinction: f64) -> f64 {
    if extinction > 0.0 {
        (-(t_mean.max((-LIT_MAX_SKY_DEPTH).exp())).ln() / extinction).max(0.0)
    } else {
        tau_mean
    }
}

/// Largest sky optical depth kept (`e^{−80}` is far below what an image shows).
pub const LIT_MAX_SKY_DEPTH: f64 = 80.0;

/// The mean depth, as a fraction of the step, at which light entering a step of optical depth
/// `x` is scattered (`1/x − 1/(eˣ − 1)`: ½ when thin, the mean free path when thick).
pub fn mean_depth(x: f64) -> f64 {
    // Below ½ the series (the closed form cancels in f32, which the GPU computes it in).
    if x < 0.5 {
        let x2 = x * x;
        0.5 - x / 12.0 + x * x2 / 720.0 - x * x2 * x2 / 30240.0
    } else {
        1.0 / x - 1.0 / x.exp_m1()
    }
}

/// The sun's direct light a segment of optical depth `x` scatters, per unit of its
/// `1 − e^{−x}`, where the near field was walked: `∫₀¹ x·e^{−xu}·e^{−d(u)} du / (1 − e^{−x})`
/// (`u` the fraction of the segment), the sun's optical depth `d(u)` walked at the segment's
/// entry, at its mean scattering depth `m = mean_depth(x)` and at its exit (`d`, each σ·τ) and
/// linear between them: per piece `∫ e^{−E(u)} du` with `E(u) = x·u + d(u)` linear, exactly
/// ([`exp_piece`]). The depth along a segment bends where the sun's ray leaves the medium
/// through a nearby face (a face lit at a grazing sun: about 9 optical depths per voxel there,
/// against 1.6 along the ray's own path), which one read at the mean depth cannot follow:
/// that read, with a gain for the depth's fall along the ray's angle to the sun (until
/// 2026-11-27), left a dense cube's grazing face at 0.32 of the reference's single scattering
/// under the voxel march (now 0.99) and the WDAS cloud's at 0.944 (now 0.995). The GPU's
/// `lv_segment_sun`.
pub fn segment_sun(x: f64, m: f64, d: [f64; 3]) -> f64 {
    let em = x * m + d[1];
    (exp_piece(d[0], em, m) + exp_piece(em, x + d[2], 1.0 - m)) / crate::exact::phi(x)
}

/// Where a segment's ends are walked, as a fraction of it from each end: just inside, so that
/// an end on the medium's outer face (a voxel segment's ends are voxel faces) is in the content
/// box in the GPU's f32 as in f64 (on the face, rounding put it outside on one side and the
/// walk read 0 where the other read the light volume). The GPU's `LV_SEGMENT_END`.
pub const SEGMENT_END: f64 = 1e-3;

/// How close (a fraction of its length) a segment must start to the last one's end for the
/// march to reuse the sun's depth walked there as its entry's: contiguous segments meet to
/// rounding, a skipped gap is a step or more (the GPU's `LV_SEGMENT_JOIN`).
pub const SEGMENT_JOIN: f64 = 1e-3;

/// `∫₀^l e^{−E(v)} dv` for `E` linear from `a` to `b` over `l`: `l·(e^{−a} − e^{−b})/(b − a)`,
/// `l·e^{−(a+b)/2}·(1 + g²/24)` for `|g = b − a| < 10⁻²` (the series of `sinh(g/2)/(g/2)`;
/// the difference cancels there in f32, which the GPU's `lv_exp_piece` computes it in).
pub fn exp_piece(a: f64, b: f64, l: f64) -> f64 {
    let g = b - a;
    if g.abs() < 1e-2 {
        l * (-0.5 * (a + b)).exp() * (1.0 + g * g / 24.0)
    } else {
        l * ((-a).exp() - (-b).exp()) / g
    }
}

/// The per-pixel jitter of the primary samples, in `[0, 1)` (24 bits, exact in f32).
pub fn lit_jitter(seed: u32, pixel: u32) -> f64 {
    (crate::pcg_hash(seed ^ crate::pcg_hash(pixel)) >> 8) as f64 / (1u32 << 24) as f64
}

impl Tracer<'_> {
    /// `Filter::Trilinear`'s density at cell-space point `p`: the voxel centres sit at
    /// `a + ½`, each tap is `max(v, 0)` (NaN reads 0), read through the tree (`Asset::value`),
    /// so neighbouring bricks, tiles and unstored space join without seams.
    pub fn trilinear_density(&self, p: [f64; 3]) -> f64 {
        self.trilinear_density_in(self.grid.frame, p)
    }

    /// The sun's optical depth (length units, before the extinction) at cell-space point `q`
    /// of density `rho`: the first `settings.sun_near` light-volume cells toward the sun walked
    /// exactly (the density mode's voxel sum), the light volume's depth where that walk ends
    /// beyond (`sun_depth_at`: 0 once the ray has left the grid). The light volume's lookup at
    /// `q` alone where there is no near field (`LightGrid::near_voxels`), where one cell's
    /// optical depth at density `rho` is below `LIT_NEAR_DEPTH` (a medium the cells resolve:
    /// its depth changes little across one), or where the primary ray's transmittance `trans`
    /// is below [`LIT_NEAR_TRANS`]. Returns that depth, the light volume's lookup at `q` (the
    /// same where no near field was walked) and whether it was walked: `([τ, τ_cells], walked)`
    /// (the flag, not the depths' difference, decides: a walk can end on the lookup's value to
    /// the last bit in f32 and not in f64, and the GPU's `lit_walks` decides the same way).
    pub(crate) fn sun_depth(
        &self,
        lv: &LightVolume,
        q: [f64; 3],
        rho: f64,
        trans: f64,
        cache: &mut BrickCache,
    ) -> ([f64; 2], bool) {
        let near = lv.grid.near_voxels(self.settings.lighting.sun_near);
        let cell_depth = self.extinction * rho * lv.cell_len;
        let cells = lv.lookup(q)[0];
        if !(near > 0.0) || !(cell_depth >= LIT_NEAR_DEPTH) || !(trans >= LIT_NEAR_TRANS) {
            return ([cells, cells], false);
        }
        ([self.near_sun_depth(lv, q, near, cache), cells], true)
    }

    /// The depth toward the sun from `q` with the near field walked, wherever `q` is (the ends
    /// of a segment whose mean depth walked: [`segment_sun`]).
    pub(crate) fn walked_sun_depth(
        &self,
        lv: &LightVolume,
        q: [f64; 3],
        cache: &mut BrickCache,
    ) -> f64 {
        let near = lv.grid.near_voxels(self.settings.lighting.sun_near);
        self.near_sun_depth(lv, q, near, cache)
    }

    /// The near field's depth toward the sun from `q` over `near` voxels, the light volume's
    /// beyond (`Tracer::sun_depth`).
    fn near_sun_depth(
        &self,
        lv: &LightVolume,
        q: [f64; 3],
        near: f64,
        cache: &mut BrickCache,
    ) -> f64 {
        let ray = self.light_ray(q);
        let Some((t0, t1)) = ray.clip(self.extent) else {
            return 0.0;
        };
        // World distance of `near` voxels along the light.
        let t_near = near / vdbcook_scene::length(ray.d);
        // The whole near field, without the density walk's opaque stop: the octaves read
        // `e^{−bⁱ·σ·τ}` with `bⁱ` down to 0, where a depth cut at the stop would shine through.
        let tau = if t1.min(t_near) > t0 {
            crate::render::optical_depth(&self.grid, &ray, t0, t1.min(t_near), 0.0, cache)
        } else {
            0.0
        };
        if t_near >= t1 {
            return tau;
        }
        tau + lv.sun_depth_at(ray.at(t_near), lv.sun)
    }

    /// [`Tracer::trilinear_density`] in root set `set` (a level of detail: `p` in its cell
    /// space).
    pub(crate) fn trilinear_density_in(&self, set: usize, p: [f64; 3]) -> f64 {
        self.trilinear_in(set, 0, p)
    }

    /// [`Tracer::trilinear_density_in`] of channel `c` (another channel's emission, smoothed).
    pub(crate) fn trilinear_in(&self, set: usize, c: usize, p: [f64; 3]) -> f64 {
        let u = p.map(|x| x - 0.5);
        let base = u.map(|c| c.floor());
        let f = [0, 1, 2].map(|a| u[a] - base[a]);
        let mut sum = 0.0f64;
        for k in 0..8 {
            let mut a = [0i64; 3];
            let mut w = 1.0f64;
            for (axis, ax) in a.iter_mut().enumerate() {
                let hi = k >> axis & 1 == 1;
                *ax = base[axis] as i64 + hi as i64;
                w *= if hi { f[axis] } else { 1.0 - f[axis] };
            }
            let v = self.grid.asset.value_c(set, a, c);
            if v > 0.0 {
                sum += w * v as f64;
            }
        }
        sum
    }
}

/// The primary march of one `Lit` ray.
pub(crate) struct LitMarch<'a, 't> {
    pub tracer: &'t Tracer<'a>,
    pub lv: &'t LightVolume,
    /// Bricks read by the near field's walks toward the sun (`Tracer::sun_depth`).
    pub shadow: &'t mut BrickCache,
    /// The unit direction toward the eye in the diffusion's metric (`LightVolume::eye_dir`).
    pub eye: [f64; 3],
    /// The ray in full-resolution cell space (the light volume's lookups, the sample grid).
    pub ray: IndexRay,
    /// The level of detail being walked (`Tracer::lit`): its root set, `2^−level` (full
    /// resolution to the level's cell space) and the step there (`step·2^level`, in the unit).
    pub set: usize,
    pub scale: f64,
    pub step: f64,
    pub jitter: f64,
    pub trans: f64,
    pub rad: [f64; 3],
    pub emit: [f64; 3],
    pub budget: u64,
    /// The sun's phase per octave at this ray's `μ`.
    pub sun_phase: [f64; MAX_MS_OCTAVES as usize],
    /// The last segment's end (length along the ray) and the sun's depth walked there, where
    /// the near field was walked: the next segment, if it starts there, reuses it as its
    /// entry's ([`segment_sun`]).
    pub exit: Option<(f64, f64)>,
    /// `k` of the sky's source (`vdbcook_scene::sky_diffusion`).
    pub sky_k: f64,
}

impl<'a, 't> LitMarch<'a, 't> {
    pub fn new(
        tracer: &'t Tracer<'a>,
        lv: &'t LightVolume,
        shadow: &'t mut BrickCache,
        ray: IndexRay,
        dir: [f64; 3],
        pixel: u32,
    ) -> Self {
        let s = &tracer.settings;
        let mu = {
            let (d, l) = (
                normalize(dir),
                normalize(s.lighting.light_dir.map(|c| c as f64)),
            );
            d[0] * l[0] + d[1] * l[1] + d[2] * l[2]
        };
        let mut sun_phase = [0.0; MAX_MS_OCTAVES as usize];
        let mut ci = 1.0f32;
        for p in sun_phase.iter_mut().take(s.lighting.ms_octaves as usize) {
            *p = phase(s.medium.phase_g.map(|g| g * ci), s.medium.phase_w, mu);
            ci *= s.lighting.ms[2];
        }
        LitMarch {
            tracer,
            lv,
            shadow,
            eye: lv.eye_dir(ray.d),
            ray,
            set: tracer.grid.frame,
            scale: 1.0,
            step: s.integrator.step as f64,
            jitter: lit_jitter(s.integrator.seed, pixel),
            trans: 1.0,
            rad: [0.0; 3],
            emit: [0.0; 3],
            budget: crate::scatter::MAX_MARCH_SAMPLES,
            sun_phase,
            exit: None,
            sky_k: sky_diffusion(
                tracer.albedo,
                s.medium.phase_g,
                s.medium.phase_w,
                s.lighting.ms_sky,
            ),
        }
    }
}

impl LitMarch<'_, '_> {
    /// Integrates the segment of the ray from length `sa` (in the unit, from the ray's origin)
    /// over `len` through density `rho`: its emission, then [`LitMarch::light`].
    fn add(&mut self, sa: f64, len: f64, rho: f64) -> Flow {
        let t = self.tracer;
        let x = t.extinction * rho * len;
        t.step_emission(&mut self.emit, self.trans, len, x, rho as f32);
        self.light(sa, len, x, rho)
    }

    /// The scattered light of the segment from length `sa` over `len` of optical depth `x`
    /// (mean density `rho`):
    /// `L += T·α·S·(1 − e^{−x})`, `T *= e^{−x}`, the source read where the segment's light is
    /// scattered on average (its mean depth `len·mean_depth(x)`: light is scattered at depth
    /// `m` into it with density ∝ e^{−σs}). Stop once `T < LIT_MIN_TRANS` or the sample
    /// budget is spent.
    fn light(&mut self, sa: f64, len: f64, x: f64, rho: f64) -> Flow {
        if self.budget == 0 {
            return Flow::Stop;
        }
        self.budget -= 1;
        let t = self.tracer;
        let s = &t.settings;
        let (ext, albedo) = (t.extinction, t.albedo);
        let e = (-x).exp();
        let md = mean_depth(x);
        let m = len * md;
        let q = self.ray.at((sa + m) / self.ray.per_t);
        let ([ts, ts_cells], walked) = t.sun_depth(self.lv, q, rho, self.trans, self.shadow);
        // The sun's transmittance at `q`, and its mean over the segment's scattering where
        // the near field was walked (the light volume's depth alone changes with the cells'
        // mean density, and is read only where a cell is thin or the ray dark): the depth
        // walked at the segment's ends too, the entry's from the last segment where this one
        // starts at its end.
        let direct = (-ext * ts).exp();
        let direct_mean = if walked {
            // The ends from the mean-depth point, not from the ray's origin: in the GPU's f32 a
            // point far along the ray moves by more than a dense medium's skin, and the ends
            // must keep their place relative to the read between them.
            let from_q = IndexRay { o: q, ..self.ray };
            let at = |u: f64| from_q.at((u * len - m) / from_q.per_t);
            let entry = match self.exit {
                Some((end, tau)) if (sa - end).abs() <= SEGMENT_JOIN * len => tau,
                _ => t.walked_sun_depth(self.lv, at(SEGMENT_END), self.shadow),
            };
            let exit = t.walked_sun_depth(self.lv, at(1.0 - SEGMENT_END), self.shadow);
            self.exit = Some((sa + len, exit));
            segment_sun(x, md, [entry, ts, exit].map(|v| ext * v))
        } else {
            self.exit = None;
            direct
        };
        let (sun, sky) = match s.lighting.ms_model {
            MsModel::Octaves => (
                octave_source(ext * ts, s.lighting.ms, s.lighting.ms_octaves, |i| {
                    self.sun_phase[i as usize]
                }) + self.sun_phase[0] * (direct_mean - direct),
                sky_source(ext * self.lv.lookup(q)[1], self.sky_k),
            ),
            MsModel::Diffusion => {
                let [diffuse_sun, diffuse_sky] = self.lv.diffuse_at(q, self.eye);
                (
                    self.sun_phase[0] * direct_mean
                        + (diffuse_sun
                            + near_scatter_source(
                                s.lighting.near_scatter as f64,
                                albedo,
                                direct_mean,
                                (-ext * ts_cells).exp(),
                            ))
                        .max(0.0),
                    diffuse_sky,
                )
            }
        };
        let w = self.trans * albedo * (1.0 - e);
        for c in 0..3 {
            self.rad[c] +=
                w * (s.lighting.light_color[c] as f64 * sun + s.lighting.sky[c] as f64 * sky);
        }
        self.trans *= e;
        if self.trans < LIT_MIN_TRANS {
            Flow::Stop
        } else {
            Flow::Go
        }
    }
}

/// `March::Steps` (and any trilinear march): samples every `step` from the eye, jittered; the
/// step's segment is centred on its sample.
impl SpanSampler for LitMarch<'_, '_> {
    fn skip_max(&self, max: f32) -> bool {
        !(max > 0.0)
    }
    fn sample_span(
        &mut self,
        ta: f64,
        tb: f64,
        _max: f32,
        value: impl Fn([f64; 3]) -> f32,
    ) -> Flow {
        let t = self.tracer;
        let step = self.step;
        let ray = self.ray;
        let (sa, sb) = (ta * ray.per_t, tb * ray.per_t);
        let mut k = ceil_f64(sa / step - self.jitter).max(0.0);
        loop {
            let sd = (k + self.jitter) * step;
            if !(sd < sb) {
                return Flow::Go;
            }
            k += 1.0;
            // The sample in the level's cell space (the walk's and the values').
            let p = ray.at(sd / ray.per_t).map(|c| c * self.scale);
            let rho = match t.settings.integrator.filter {
                Filter::Nearest => value(p) as f64,
                Filter::Trilinear => t.trilinear_density_in(self.set, p),
            };
            if !(rho > 0.0) {
                continue;
            }
            if self.add(sd - 0.5 * step, step, rho) == Flow::Stop {
                return Flow::Stop;
            }
        }
    }
}

/// `March::Voxels`: the march over the walk's voxel spans (a brick's voxels one by one, a
/// constant tile as one span), each cut into `n = max(⌈len/step − 10⁻³⌉, 1)` equal segments
/// (the 10⁻³ keeps a span of exactly `k` steps at `k` segments through the GPU's f32).
pub(crate) struct VoxelMarch<'m, 'a, 't>(pub &'m mut LitMarch<'a, 't>);

/// Segments of a span `len` long at most `step` each (`VoxelMarch`; the GPU's `lit_span`).
pub fn segments(len: f64, step: f64) -> f64 {
    (len / step - 1e-3).ceil().max(1.0)
}

impl Visitor for VoxelMarch<'_, '_, '_> {
    fn skip(&self, max: f32) -> bool {
        !(max > 0.0)
    }
    fn voxels(&self) -> bool {
        true
    }
    fn span(&mut self, ta: f64, tb: f64, v: f32, _: Holder) -> Flow {
        if !(v > 0.0) {
            return Flow::Go;
        }
        let m = &mut *self.0;
        let per_t = m.ray.per_t;
        let all = (tb - ta) * per_t;
        let n = segments(all, m.step);
        let len = all / n;
        for j in 0..n as u64 {
            if m.add(ta * per_t + j as f64 * len, len, v as f64) == Flow::Stop {
                return Flow::Stop;
            }
        }
        Flow::Go
    }
}

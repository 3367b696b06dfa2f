//! Per-render state (`Tracer`: the inverse transform, the light in index space, the depth range)
//! and the per-ray dispatch to the modes; `render` runs it over the image rows (with rayon under the default `parallel` feature).

#[cfg(feature = "parallel")]
use rayon::prelude::*;
use vdbcook_asset::Asset;

use crate::color::{brick_color, heat, STEPS_FULL_SCALE};
use crate::dda::{walk_cells, Flow};
use crate::delta::{Path, MAX_EVENTS};
use crate::exact::{Density, FirstHit};
use crate::lit::{LightVolume, LitMarch, VoxelMarch};
use crate::rng::{Rng, Rng64};
use crate::scatter::{Primary, MAX_MARCH_SAMPLES};
use crate::space::IndexRay;
use crate::walk::{extent, walk, BrickCache, Grid, Holder};
use crate::Image;
use vdbcook_scene::{
    depth_range, length, level_start, normalize, stored_bbox, Affine, Camera, Emission, LengthUnit,
    LevelChain, March, Mode, RenderSettings, TraceError, BLACKBODY_TABLE_LEN,
};

/// What one primary ray produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Display colour (see the crate docs per mode).
    pub rgba: [f32; 4],
    /// The mode's raw quantity.
    pub value: f32,
    /// Traversal steps of the walk (density walk in `Density` and `Steps`; 0 elsewhere).
    pub steps: u32,
}

impl Sample {
    /// Adds light drawn after the march (a channel's emission) to the colour.
    fn add_light(&mut self, e: [f64; 3]) {
        for (o, e) in self.rgba.iter_mut().zip(e) {
            *o += e as f32;
        }
    }
}

/// Per-thread scratch: decoded-brick caches for primary and shadow rays.
#[derive(Default)]
pub struct Scratch {
    pub(crate) primary: BrickCache,
    pub(crate) shadow: BrickCache,
}

/// Everything fixed for one render of one asset frame from one camera.
pub struct Tracer<'a> {
    /// The frame to walk, with its per-block maxima.
    pub(crate) grid: Grid<'a>,
    /// `Mode::Lit`'s march on this frame (`March::resolve`: `Steps` or `Voxels`).
    pub(crate) march: March,
    pub(crate) settings: RenderSettings,
    pub(crate) xf: Affine,
    pub(crate) extent: [f64; 3],
    /// A ray toward the light (`d`: the index-space image of the unit world direction toward
    /// it) from the index origin, so its `1/d` and `per_t` are computed once.
    light_ray: IndexRay,
    /// `absorb + scatter` and `scatter / (absorb + scatter)` (0 when both are 0).
    pub(crate) extinction: f64,
    pub(crate) albedo: f64,
    /// World distances mapped to white and black in `Depth` mode.
    pub depth_range: [f64; 2],
    /// The frame's max value (`FirstHitDensity` maps it to white).
    pub value_max: f32,
    /// The blackbody table of `settings.emission`'s range.
    pub(crate) emit_table: [[f32; 4]; BLACKBODY_TABLE_LEN],
    /// The light volume of `Mode::Lit` (built in `new`; `None` in the other modes).
    pub(crate) light: Option<LightVolume>,
    /// `Mode::Lit` with `primary_lod` on an asset with levels of detail: the frame at levels
    /// `1..` (`levels[k − 1]` is level `k`), and the camera's pixel angle
    /// (`vdbcook_scene::pixel_angle`). Empty otherwise: every ray reads full resolution.
    pub(crate) levels: Vec<Grid<'a>>,
    pub(crate) pixel_angle: f64,
    /// Emission read from another channel than the rendered one (`Emission::channel > 0`;
    /// `settings.emission` is then `None`, and this is added after the mode's march).
    pub(crate) channel_emission: Option<ChannelEmission>,
    /// The rendered channel's own emission as [`Tracer::emission_until`] walks it (its content
    /// box found once, on first use).
    own_emission: std::sync::OnceLock<ChannelEmission>,
}

/// Emission from channel `channel` of a multi-channel asset, drawn by [`Tracer::trace`] after the
/// mode's march: `∫ T(s) · E(c(s)) ds` over the voxels of `bbox` (where the channel is above the
/// emission's floor), `T` the transmittance of channel 0 from the eye with the mode's extinction
/// (`absorb` in `Density`, `absorb + scatter` in `SingleScatter` and `Lit`), each voxel exact
/// for nearest-voxel values: `T · E · ℓ · φ(σℓ)`. The Monte Carlo modes (`DeltaTracking`,
/// `Reference`) take it by the track-length estimator instead: each free flight adds
/// `∫ E ds` up to where it collided, whose mean is the same `∫ T E ds`.
pub(crate) struct ChannelEmission {
    emission: Emission,
    channel: usize,
    /// Cell-space box outside which the channel does not glow (`None`: it glows nowhere).
    bbox: Option<([f64; 3], [f64; 3])>,
}

impl<'a> Tracer<'a> {
    /// Validates the settings and the transform and precomputes per-render constants.
    pub fn new(
        asset: &'a Asset,
        camera: &Camera,
        settings: &RenderSettings,
    ) -> Result<Tracer<'a>, TraceError> {
        Self::with_light_from(asset, camera, settings, None)
    }

    /// [`Tracer::new`] whose lit mode takes its light volume from frame `light.0` over the
    /// cell-space box `light.1` (`None`: the output frame's own light over its content box):
    /// what the engine drawer draws for an instance with a light stride
    /// (`vdbcook_scene::light_span`), the light of a span's middle frame over the span's joint
    /// box. The march, its near field and emission read the output frame.
    #[allow(clippy::type_complexity)]
    pub fn with_light_from(
        asset: &'a Asset,
        camera: &Camera,
        settings: &RenderSettings,
        light: Option<(usize, Option<([f64; 3], [f64; 3])>)>,
    ) -> Result<Tracer<'a>, TraceError> {
        settings.validate(asset.frame_count())?;
        let light = light.unwrap_or_else(|| {
            let f = settings.output.frame;
            (f, vdbcook_scene::content_box(asset, f))
        });
        if light.0 >= asset.frame_count() {
            return Err(TraceError::Setting(format!(
                "light frame {} is not in the asset ({} frame(s))",
                light.0,
                asset.frame_count()
            )));
        }
        camera.basis(settings.output.width, settings.output.height)?;
        let mut settings = settings.clone();
        let mut channel_emission = None;
        if let Some(e) = settings.medium.emission.filter(|e| e.channel > 0) {
            if e.channel >= asset.channel_count() {
                return Err(TraceError::Setting(format!(
                    "emission channel {} is not in the asset ({} channel(s))",
                    e.channel,
                    asset.channel_count()
                )));
            }
            // Where the channel exceeds its background, or everywhere when its background
            // glows itself (the runtime's renderer takes the same box).
            let bg = asset.header.channel_background(e.channel);
            let bbox = if e.range[0] >= bg {
                vdbcook_scene::content_box_above(asset, settings.output.frame, e.channel, bg)
            } else {
                Some(([0.0; 3], extent(asset)))
            };
            channel_emission = Some(ChannelEmission {
                emission: e,
                channel: e.channel,
                bbox,
            });
        }
        let emit_table = settings
            .medium
            .emission
            .map(|e| e.table())
            .unwrap_or([[0.0; 4]; BLACKBODY_TABLE_LEN]);
        if channel_emission.is_some() {
            settings.medium.emission = None;
        }
        let settings = &settings;
        let xf = Affine::cells(&asset.header.index_to_world)?;
        let l = settings.lighting.light_dir.map(|c| c as f64);
        let light_index = xf.dir_to_index(normalize(l));
        let (extinction, albedo) = settings.medium.extinction_albedo();
        // Depth range: nearest and farthest corner of the frame's stored box (0 if the eye is
        // inside it).
        let ext = extent(asset);
        let bbox = stored_bbox(asset, settings.output.frame).unwrap_or(([0.0; 3], ext));
        let depth_range = depth_range(&xf, bbox, camera.eye);
        let value_max = asset.frame_range(settings.output.frame, 0)[1];
        let grid = Grid::new(asset, settings.output.frame);
        let light = (settings.integrator.mode == Mode::Lit).then(|| {
            let other = (light.0 != settings.output.frame).then(|| Grid::new(asset, light.0));
            let of = other.as_ref().unwrap_or(&grid);
            LightVolume::build(of, light.1, &xf, settings, extinction)
        });
        let levels = if settings.integrator.mode == Mode::Lit && settings.integrator.primary_lod {
            // Primary rays by footprint read one level per octave: the levels from full
            // resolution on that skip none (none above it in a `--lod-from` asset).
            (1..LevelChain::of(asset).consecutive())
                .map(|k| Grid::new(asset, asset.lod_set(settings.output.frame, k)))
                .collect()
        } else {
            Vec::new()
        };
        Ok(Tracer {
            march: March::resolve(settings, value_max),
            grid,
            levels,
            pixel_angle: vdbcook_scene::pixel_angle(camera.fov_y_deg, settings.output.height),
            settings: settings.clone(),
            xf,
            extent: ext,
            light_ray: IndexRay::new(
                [0.0; 3],
                light_index,
                settings.medium.unit == LengthUnit::Voxel,
            ),
            extinction,
            albedo,
            depth_range,
            value_max: if value_max > 0.0 { value_max } else { 1.0 },
            emit_table,
            light,
            channel_emission,
            own_emission: std::sync::OnceLock::new(),
        })
    }

    /// The sun's transmittance through the volume at world point `p` (`Mode::Lit` only: `None`
    /// in the other modes): `exp(−(absorb + scatter)·τ)` with `τ` the light volume's depth
    /// toward the sun there (`LightVolume::sun_depth_at`) — what an engine darkens its own
    /// geometry with under the smoke.
    pub fn sun_transmittance(&self, p: [f64; 3]) -> Option<f64> {
        let lv = self.light.as_ref()?;
        let tau = lv.sun_depth_at(self.xf.index_of(p), normalize(self.light_ray.d));
        Some((-self.extinction * tau).exp())
    }

    /// Adds the emission (`settings.emission`; nothing without) of one fixed step of value `v`
    /// and optical depth `x`, reached with transmittance `trans`: `T · E(v) · step · φ(x)`, the
    /// emission absorbed as the step attenuates (the scatter and lit marches).
    pub(crate) fn step_emission(&self, emit: &mut [f64; 3], trans: f64, step: f64, x: f64, v: f32) {
        if let Some(e) = &self.settings.medium.emission {
            let r = e.radiance(&self.emit_table, v);
            let w = trans * step * crate::exact::phi(x);
            for (a, r) in emit.iter_mut().zip(r) {
                *a += w * r as f64;
            }
        }
    }

    /// The light volume (`Mode::Lit` only).
    pub fn light_volume(&self) -> Option<&LightVolume> {
        self.light.as_ref()
    }

    pub(crate) fn voxel_units(&self) -> bool {
        self.settings.medium.unit == LengthUnit::Voxel
    }

    /// The ray from index point `p` toward the light (= `IndexRay::new(p, light_index, …)`).
    #[inline]
    pub(crate) fn light_ray(&self, p: [f64; 3]) -> IndexRay {
        IndexRay {
            o: p,
            ..self.light_ray
        }
    }

    /// The density march's optical depth `τ` (in the settings' length unit, before `absorb`)
    /// along the world ray from `origin` along `dir` (normalized here), for world distances
    /// `t ∈ [0, t_max]` only: the `Density` mode's sum (whatever `settings.mode` is) with the ray
    /// cut at `t_max` — a scene's depth — and the same stop once `absorb·τ ≥ OPAQUE_DEPTH`.
    /// `T = exp(−absorb·τ)`; `t_max = ∞` gives the `Density` mode's `T`.
    ///
    /// The reference of the runtime's engine drawer (`VolumeDrawer`): an instance is a tracer
    /// of the asset with `index_to_world` premultiplied by the instance's transform, its density
    /// scale multiplies `absorb`, and a crossfade between frames `f` and `f + 1` with weight `a`
    /// is `(1 − a)·τ_f + a·τ_{f+1}`. As `τ` is linear in the voxel values, that is the march
    /// through the per-voxel lerp `(1 − a)·v_f + a·v_{f+1}` exactly, except where a frame's
    /// march stops at the opaque depth (both transmittances are then below `e^−20·…`).
    pub fn optical_depth(
        &self,
        origin: [f64; 3],
        dir: [f64; 3],
        t_max: f64,
        scratch: &mut Scratch,
    ) -> f64 {
        let ray = self.primary_ray(origin, dir);
        match ray.clip(self.extent) {
            Some((t0, t1)) if t1.min(t_max) > t0 => {
                let absorb = self.settings.medium.absorb as f64;
                optical_depth(
                    &self.grid,
                    &ray,
                    t0,
                    t1.min(t_max),
                    absorb,
                    &mut scratch.primary,
                )
            }
            _ => 0.0,
        }
    }

    /// The index-space ray from world point `eye` along world direction `dir` (normalized
    /// here).
    fn primary_ray(&self, eye: [f64; 3], dir: [f64; 3]) -> IndexRay {
        IndexRay::new(
            self.xf.index_of(eye),
            self.xf.dir_to_index(normalize(dir)),
            self.voxel_units(),
        )
    }

    /// Traces one primary ray from world point `eye` along world direction `dir` (normalized
    /// here). `pixel` seeds delta tracking (`y·width + x` in `render`).
    pub fn trace(&self, eye: [f64; 3], dir: [f64; 3], pixel: u32, scratch: &mut Scratch) -> Sample {
        let ray = self.primary_ray(eye, dir);
        let mut out = self.trace_mode(ray, dir, pixel, scratch);
        if let Some(ce) = &self.channel_emission {
            let ext = match self.settings.integrator.mode {
                Mode::Density => self.settings.medium.absorb as f64,
                // Drawn inside their own flights.
                Mode::DeltaTracking | Mode::Reference => return out,
                _ => self.extinction,
            };
            out.add_light(self.emission_of_channel(ce, &ray, ext, f64::INFINITY, scratch));
        }
        out
    }

    /// [`ChannelEmission`] along `ray` up to `t_end`: the voxels of its box the ray crosses
    /// inside the root extent, behind channel 0's optical depth from the ray's entry into the
    /// extent with extinction `ext` (0: no attenuation, the track-length estimator's segment).
    pub(crate) fn emission_of_channel(
        &self,
        ce: &ChannelEmission,
        ray: &IndexRay,
        ext: f64,
        t_end: f64,
        scratch: &mut Scratch,
    ) -> [f64; 3] {
        let mut light = [0.0f64; 3];
        let (Some((lo, hi)), Some((t0, t1))) = (ce.bbox, ray.clip(self.extent)) else {
            return light;
        };
        // The trilinear filter reads both channels at each part's midpoint, over the box grown
        // by the taps' reach (one voxel).
        let smooth = self.settings.integrator.filter == crate::Filter::Trilinear;
        let grow = if smooth { 1.0 } else { 0.0 };
        let (lo, hi) = (lo.map(|c| c - grow), hi.map(|c| c + grow));
        let Some((a, b)) = ray.clip_box(lo, hi) else {
            return light;
        };
        let (a, b) = (a.max(t0), b.min(t1).min(t_end));
        if !(a < b) {
            return light;
        }
        // Channel 0's optical depth from the extent's entry to the box's.
        let tau = if a > t0 && ext > 0.0 {
            optical_depth(&self.grid, ray, t0, a, ext, &mut scratch.primary)
        } else {
            0.0
        };
        let mut trans = (-ext * tau).exp();
        let asset = self.grid.asset;
        let frame = self.settings.output.frame;
        let (clo, chi) = (lo.map(|c| c as i64), hi.map(|c| c as i64));
        walk_cells(ray, 1.0, clo, chi, a, b, |cell, ta, tb| {
            let l = (tb - ta) * ray.per_t;
            // The part's midpoint (cell space).
            let mid = ray.at(0.5 * (ta + tb));
            let rho = match (ext > 0.0, smooth) {
                (false, _) => 0.0,
                (true, true) => self.trilinear_in(frame, 0, mid) as f32,
                (true, false) => asset.value(frame, cell),
            };
            let x = if rho > 0.0 { ext * rho as f64 * l } else { 0.0 };
            let v = if smooth {
                self.trilinear_in(frame, ce.channel, mid) as f32
            } else {
                asset.value_c(frame, cell, ce.channel)
            };
            let r = ce.emission.radiance(&self.emit_table, v);
            let w = trans * l * crate::exact::phi(x);
            for (o, r) in light.iter_mut().zip(r) {
                *o += w * r as f64;
            }
            trans *= (-x).exp();
            if trans < 1e-6 {
                Flow::Stop
            } else {
                Flow::Go
            }
        });
        light
    }

    /// [`Tracer::trace`] without emission from another channel.
    fn trace_mode(
        &self,
        ray: IndexRay,
        dir: [f64; 3],
        pixel: u32,
        scratch: &mut Scratch,
    ) -> Sample {
        let s = &self.settings;
        let clip = ray.clip(self.extent);
        let miss = |value: f32, alpha: f32| Sample {
            rgba: [0.0, 0.0, 0.0, alpha],
            value,
            steps: 0,
        };
        match s.integrator.mode {
            Mode::Density | Mode::Steps => {
                let mut v = Density {
                    per_t: ray.per_t,
                    absorb: s.medium.absorb as f64,
                    tau: 0.0,
                    steps: 0,
                    emission: s.medium.emission.map(|e| (e, &self.emit_table)),
                    light: [0.0; 3],
                };
                if let Some((t0, t1)) = clip {
                    walk(&self.grid, &ray, t0, t1, &mut scratch.primary, &mut v);
                }
                let t = (-(s.medium.absorb as f64) * v.tau).exp() as f32;
                if s.integrator.mode == Mode::Density {
                    // Flat-lit grey `1 − T`, plus the emitted light.
                    let g = [0, 1, 2].map(|c| (1.0 - t) + v.light[c] as f32);
                    Sample {
                        rgba: [g[0], g[1], g[2], 1.0],
                        value: t,
                        steps: v.steps,
                    }
                } else {
                    let c = heat(v.steps as f64 / STEPS_FULL_SCALE);
                    Sample {
                        rgba: [c[0], c[1], c[2], 1.0],
                        value: v.steps as f32,
                        steps: v.steps,
                    }
                }
            }
            Mode::Depth | Mode::FirstHitDensity | Mode::BrickHue => {
                let mut v = FirstHit {
                    cutoff: s.integrator.cutoff,
                    hit: None,
                };
                if let Some((t0, t1)) = clip {
                    walk(&self.grid, &ray, t0, t1, &mut scratch.primary, &mut v);
                }
                let Some((t, value, holder)) = v.hit else {
                    return miss(-1.0, 0.0);
                };
                let (rgb, value) = match s.integrator.mode {
                    Mode::Depth => {
                        let [n, f] = self.depth_range;
                        let g = (1.0 - ((t - n) / (f - n)).clamp(0.0, 1.0)) as f32;
                        ([g; 3], t as f32)
                    }
                    Mode::FirstHitDensity => {
                        let g = (value / self.value_max).clamp(0.0, 1.0);
                        ([g; 3], value)
                    }
                    _ => match holder {
                        Holder::Brick(b) => (brick_color(b), b as f32),
                        _ => ([0.5; 3], -2.0),
                    },
                };
                Sample {
                    rgba: [rgb[0], rgb[1], rgb[2], 1.0],
                    value,
                    steps: 0,
                }
            }
            Mode::SingleScatter => {
                let Some((t0, t1)) = clip else {
                    return miss(1.0, 0.0);
                };
                let mut v = Primary {
                    tracer: self,
                    ray,
                    shadow_cache: &mut scratch.shadow,
                    trans: 1.0,
                    lum: 0.0,
                    emit: [0.0; 3],
                    budget: MAX_MARCH_SAMPLES,
                };
                walk(&self.grid, &ray, t0, t1, &mut scratch.primary, &mut v);
                let (lum, trans) = (v.lum, v.trans);
                let c =
                    [0, 1, 2].map(|i| (s.lighting.light_color[i] as f64 * lum + v.emit[i]) as f32);
                Sample {
                    rgba: [c[0], c[1], c[2], (1.0 - trans) as f32],
                    value: trans as f32,
                    steps: 0,
                }
            }
            Mode::DeltaTracking => {
                let Some((t0, t1)) = clip else {
                    return miss(1.0, 0.0);
                };
                let (mut lum, mut escaped, mut emitted) = (0.0f64, 0u32, [0.0f64; 3]);
                for k in 0..s.integrator.spp {
                    let sample = s.integrator.first_sample.wrapping_add(k);
                    let mut v = Path {
                        tracer: self,
                        ray,
                        rng: Rng::new(s.integrator.seed, pixel, sample),
                        shadow_cache: &mut scratch.shadow,
                        escaped: true,
                        lum: 0.0,
                        emitted: [0.0; 3],
                        events: MAX_EVENTS,
                        end_t: t1,
                    };
                    walk(&self.grid, &ray, t0, t1, &mut scratch.primary, &mut v);
                    lum += v.lum;
                    escaped += v.escaped as u32;
                    let end_t = v.end_t;
                    for (a, e) in emitted.iter_mut().zip(v.emitted) {
                        *a += e;
                    }
                    if let Some(ce) = &self.channel_emission {
                        // The track-length estimator over the flight.
                        let e = self.emission_of_channel(ce, &ray, 0.0, end_t, scratch);
                        for (a, e) in emitted.iter_mut().zip(e) {
                            *a += e;
                        }
                    }
                }
                let n = s.integrator.spp as f64;
                let trans = escaped as f64 / n;
                let c = [0, 1, 2]
                    .map(|i| ((s.lighting.light_color[i] as f64 * lum + emitted[i]) / n) as f32);
                Sample {
                    rgba: [c[0], c[1], c[2], (1.0 - trans) as f32],
                    value: trans as f32,
                    steps: 0,
                }
            }
            Mode::Lit => self.lit(ray, dir, clip, f64::INFINITY, pixel, scratch),
            Mode::Reference => {
                if clip.is_none() {
                    return miss(1.0, 0.0);
                }
                let d = normalize(dir);
                let (mut l, mut escaped) = ([0.0f64; 3], 0u32);
                for k in 0..s.integrator.spp {
                    let mut rng = Rng64::new(
                        s.integrator.seed,
                        pixel,
                        s.integrator.first_sample.wrapping_add(k),
                    );
                    let (li, esc) = self.reference_path(ray.o, d, &mut rng, scratch);
                    for (a, b) in l.iter_mut().zip(li) {
                        *a += b;
                    }
                    escaped += esc as u32;
                }
                let n = s.integrator.spp as f64;
                let trans = escaped as f64 / n;
                let c = l.map(|c| (c / n) as f32);
                Sample {
                    rgba: [c[0], c[1], c[2], (1.0 - trans) as f32],
                    value: trans as f32,
                    steps: 0,
                }
            }
        }
    }
}

/// The `Density` walk's optical depth `τ` of channel 0 in `grid` along `ray` for
/// `t ∈ [t0, t1]`, stopping once `absorb·τ ≥ OPAQUE_DEPTH` (never with `absorb` 0): the one
/// exact voxel sum of the density mode, the near field and the light volume's sun pass.
pub(crate) fn optical_depth(
    grid: &Grid,
    ray: &IndexRay,
    t0: f64,
    t1: f64,
    absorb: f64,
    cache: &mut BrickCache,
) -> f64 {
    let mut v = Density {
        per_t: ray.per_t,
        absorb,
        tau: 0.0,
        steps: 0,
        emission: None,
        light: [0.0; 3],
    };
    walk(grid, ray, t0, t1, cache, &mut v);
    v.tau
}

impl Tracer<'_> {
    /// `Mode::Lit` along `ray` (world direction `dir`), clipped to `clip` and cut at world
    /// distance `t_max` (a scene's depth: samples beyond are not taken).
    fn lit(
        &self,
        ray: IndexRay,
        dir: [f64; 3],
        clip: Option<(f64, f64)>,
        t_max: f64,
        pixel: u32,
        scratch: &mut Scratch,
    ) -> Sample {
        let (Some((t0, t1)), Some(lv)) = (clip, self.light.as_ref()) else {
            return Sample {
                rgba: [0.0; 4],
                value: 1.0,
                steps: 0,
            };
        };
        let Scratch { primary, shadow } = scratch;
        let mut v = LitMarch::new(self, lv, shadow, ray, dir, pixel);
        let t1 = t1.min(t_max);
        // Level k over [t_k, t_{k+1}) (`vdbcook_scene::level_start`; one level without levels).
        let grow = length(ray.d);
        for k in 0..=self.levels.len() {
            let a = t0.max(level_start(k as u32, self.pixel_angle, grow));
            let b = if k == self.levels.len() {
                t1
            } else {
                t1.min(level_start(k as u32 + 1, self.pixel_angle, grow))
            };
            if !(b > a) {
                continue;
            }
            let (grid, scale) = match k {
                0 => (&self.grid, 1.0),
                _ => (&self.levels[k - 1], 1.0 / f64::from(1u32 << k)),
            };
            v.set = grid.frame;
            v.scale = scale;
            v.step = self.settings.integrator.step as f64 / scale;
            // The level's cell space is full resolution's scaled by 2^−k.
            let lray = ray.scaled(scale);
            let flow = if self.march == March::Voxels {
                walk(grid, &lray, a, b, primary, &mut VoxelMarch(&mut v))
            } else {
                walk(grid, &lray, a, b, primary, &mut v)
            };
            if flow == Flow::Stop {
                break;
            }
        }
        let c = [0, 1, 2].map(|i| (v.rad[i] + v.emit[i]) as f32);
        Sample {
            rgba: [c[0], c[1], c[2], (1.0 - v.trans) as f32],
            value: v.trans as f32,
            steps: 0,
        }
    }

    /// [`Tracer::trace`] with the ray cut at world distance `t_max` from `eye` (what an
    /// engine's depth buffer allows; the samples are those of the uncut ray before `t_max`), for
    /// `Mode::Lit` only: other modes are traced uncut (the density mode's cut march is
    /// [`Tracer::optical_depth`]).
    pub fn trace_until(
        &self,
        eye: [f64; 3],
        dir: [f64; 3],
        t_max: f64,
        pixel: u32,
        scratch: &mut Scratch,
    ) -> Sample {
        if self.settings.integrator.mode != Mode::Lit {
            return self.trace(eye, dir, pixel, scratch);
        }
        let ray = self.primary_ray(eye, dir);
        let mut out = self.lit(ray, dir, ray.clip(self.extent), t_max, pixel, scratch);
        if let Some(ce) = &self.channel_emission {
            out.add_light(self.emission_of_channel(ce, &ray, self.extinction, t_max, scratch));
        }
        out
    }

    /// The density mode's emission along the ray from `eye` up to world distance `t_max`,
    /// voxel by voxel behind the density's optical depth with `absorb` (what
    /// [`Tracer::optical_depth`] cuts at a depth leaves out): the channel of
    /// `settings.medium.emission`, the rendered one (its values above 0, the content box)
    /// included. For the rendered channel it is the density walk's own emission, each voxel
    /// summed apart instead of a constant span at once (equal up to rounding). Nothing
    /// without emission.
    pub fn emission_until(
        &self,
        eye: [f64; 3],
        dir: [f64; 3],
        t_max: f64,
        scratch: &mut Scratch,
    ) -> [f64; 3] {
        let ray = self.primary_ray(eye, dir);
        let absorb = self.settings.medium.absorb as f64;
        let ce = match (&self.channel_emission, self.settings.medium.emission) {
            (Some(ce), _) => ce,
            (None, Some(e)) => self.own_emission.get_or_init(|| ChannelEmission {
                emission: e,
                channel: 0,
                bbox: vdbcook_scene::content_box(self.grid.asset, self.settings.output.frame),
            }),
            (None, None) => return [0.0; 3],
        };
        self.emission_of_channel(ce, &ray, absorb, t_max, scratch)
    }
}

/// Renders `settings.frame` of `asset` from `camera`. Refuses a frame index out of range,
/// settings out of range, a degenerate camera and a non-affine or singular transform.
pub fn render(
    asset: &Asset,
    camera: &Camera,
    settings: &RenderSettings,
) -> Result<Image, TraceError> {
    let tracer = Tracer::new(asset, camera, settings)?;
    let (w, h) = (settings.output.width, settings.output.height);
    let basis = camera.basis(w, h)?;
    let mut rgba = vec![0.0f32; w as usize * h as usize * 4];
    let mut value = vec![0.0f32; w as usize * h as usize];
    let trace_row = |scratch: &mut Scratch, (j, (row, vrow)): (usize, (&mut [f32], &mut [f32]))| {
        let j = j as u32;
        for i in 0..w {
            let dir = basis.dir(i, j, w, h);
            let px = tracer.trace(camera.eye, dir, j * w + i, scratch);
            row[4 * i as usize..4 * i as usize + 4].copy_from_slice(&px.rgba);
            vrow[i as usize] = px.value;
        }
    };
    // Rows on rayon's pool with the `parallel` feature (default); one thread without it (the
    // runtime turns it off: engines get the tracer's definitions without a thread pool).
    #[cfg(feature = "parallel")]
    rgba.par_chunks_mut(w as usize * 4)
        .zip(value.par_chunks_mut(w as usize))
        .enumerate()
        .for_each_init(Scratch::default, trace_row);
    #[cfg(not(feature = "parallel"))]
    {
        let mut scratch = Scratch::default();
        rgba.chunks_mut(w as usize * 4)
            .zip(value.chunks_mut(w as usize))
            .enumerate()
            .for_each(|x| trace_row(&mut scratch, x));
    }
    Ok(Image {
        width: w,
        height: h,
        rgba,
        value,
    })
}

//! `vdb_render`'s single-scattering integrator (OpenVDB `tools::VolumeRender`), re-derived on
//! the hierarchical walk: fixed steps on a grid anchored at the ray origin, shadow rays toward
//! one directional light with the `gain` falloff, and the cutoffs that end rays early. Spans
//! whose max is below the cutoff are skipped whole (their samples would be ignored anyway).

use crate::dda::{ceil_f64, Flow};
use crate::space::IndexRay;
use crate::walk::{walk, BrickCache, SpanSampler};
use crate::Tracer;

/// Most samples one march (primary or shadow) takes before it stops.
pub const MAX_MARCH_SAMPLES: u64 = 1 << 20;

/// Calls `f(s, p)` for each grid sample `s = k·step` (length units from the ray origin, `k`
/// integer, `k ≥ k_min`) with `s ∈ [ta·per_t, tb·per_t)`, `p` its index-space point; stops on `Flow::Stop`
/// or when `budget` runs out.
fn samples(
    ray: &IndexRay,
    step: f64,
    k_min: f64,
    ta: f64,
    tb: f64,
    budget: &mut u64,
    mut f: impl FnMut(f64, [f64; 3]) -> Flow,
) -> Flow {
    let (sa, sb) = (ta * ray.per_t, tb * ray.per_t);
    let mut k = ceil_f64(sa / step).max(k_min);
    while k * step < sb {
        if *budget == 0 {
            return Flow::Stop;
        }
        *budget -= 1;
        let s = k * step;
        if f(s, ray.at(s / ray.per_t)) == Flow::Stop {
            return Flow::Stop;
        }
        k += 1.0;
    }
    Flow::Go
}

/// The primary ray: pixel luminance (before the light colour) and transmittance.
pub(crate) struct Primary<'a, 't> {
    pub tracer: &'t Tracer<'a>,
    pub ray: IndexRay,
    pub shadow_cache: &'t mut BrickCache,
    pub trans: f64,
    pub lum: f64,
    /// Emitted light gathered (with `settings.emission`).
    pub emit: [f64; 3],
    pub budget: u64,
}

impl Primary<'_, '_> {
    fn march(&mut self, ta: f64, tb: f64, value: impl Fn([f64; 3]) -> f32) -> Flow {
        let s = &self.tracer.settings;
        let (step, cutoff) = (s.integrator.step as f64, s.integrator.cutoff as f64);
        let ext = self.tracer.extinction;
        let albedo = self.tracer.albedo;
        let ray = self.ray;
        let mut budget = self.budget;
        let flow = samples(&ray, step, 0.0, ta, tb, &mut budget, |_, p| {
            let sigma = value(p) as f64;
            if sigma < cutoff || sigma <= 0.0 {
                return Flow::Go;
            }
            let x = ext * sigma * step;
            let dt = (-x).exp();
            self.tracer
                .step_emission(&mut self.emit, self.trans, step, x, sigma as f32);
            let ts = self.tracer.shadow_march(p, self.shadow_cache);
            self.lum += albedo * ts * self.trans * (1.0 - dt);
            self.trans *= dt;
            if 3.0 * self.trans * self.trans < cutoff {
                Flow::Stop
            } else {
                Flow::Go
            }
        });
        self.budget = budget;
        flow
    }
}

fn below_cutoff(max: f32, cutoff: f32) -> bool {
    !(max >= cutoff && max > 0.0)
}

impl SpanSampler for Primary<'_, '_> {
    fn skip_max(&self, max: f32) -> bool {
        below_cutoff(max, self.tracer.settings.integrator.cutoff)
    }
    fn sample_span(
        &mut self,
        ta: f64,
        tb: f64,
        _max: f32,
        value: impl Fn([f64; 3]) -> f32,
    ) -> Flow {
        self.march(ta, tb, value)
    }
}

/// A shadow ray's transmittance toward the light.
struct Shadow<'a, 't> {
    tracer: &'t Tracer<'a>,
    ray: IndexRay,
    trans: f64,
    budget: u64,
}

impl Shadow<'_, '_> {
    fn march(&mut self, ta: f64, tb: f64, value: impl Fn([f64; 3]) -> f32) -> Flow {
        let s = &self.tracer.settings;
        let (step, cutoff, gain) = (
            s.integrator.shadow_step as f64,
            s.integrator.cutoff as f64,
            s.integrator.gain as f64,
        );
        let ext = self.tracer.extinction;
        let ray = self.ray;
        let mut budget = self.budget;
        let mut trans = self.trans;
        // As in vdb_render, whose shadow rays start just past t = 0: no sample at the point itself.
        let flow = samples(&ray, step, 1.0, ta, tb, &mut budget, |sd, p| {
            let d = value(p) as f64;
            if d < cutoff || d <= 0.0 {
                return Flow::Go;
            }
            trans *= (-ext * d * step / (1.0 + sd * gain)).exp();
            if 3.0 * trans * trans < cutoff {
                Flow::Stop
            } else {
                Flow::Go
            }
        });
        self.budget = budget;
        self.trans = trans;
        flow
    }
}

impl SpanSampler for Shadow<'_, '_> {
    fn skip_max(&self, max: f32) -> bool {
        below_cutoff(max, self.tracer.settings.integrator.cutoff)
    }
    fn sample_span(
        &mut self,
        ta: f64,
        tb: f64,
        _max: f32,
        value: impl Fn([f64; 3]) -> f32,
    ) -> Flow {
        self.march(ta, tb, value)
    }
}

impl Tracer<'_> {
    /// Transmittance from index point `p` toward the light (`vdb_render`'s shadow march).
    pub(crate) fn shadow_march(&self, p: [f64; 3], cache: &mut BrickCache) -> f64 {
        let ray = self.light_ray(p);
        let Some((t0, t1)) = ray.clip(self.extent) else {
            return 1.0;
        };
        let mut v = Shadow {
            tracer: self,
            ray,
            trans: 1.0,
            budget: MAX_MARCH_SAMPLES,
        };
        walk(&self.grid, &ray, t0, t1, cache, &mut v);
        v.trans
    }
}

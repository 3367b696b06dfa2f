//! Delta (Woodcock) tracking of the single-scattering medium: free-flight distances sampled
//! against piecewise-constant majorants from the walk (the value of a tile or empty span, the
//! `brick_ranges` max of a brick), null collisions rejected by the real density; at a real
//! collision the path scatters with probability `scatter / (absorb + scatter)` and scores the
//! light times a ratio-tracking estimate of the shadow transmittance. Unbiased: its mean is the
//! continuous limit of `SingleScatter` (step → 0, no cutoffs).

use crate::dda::Flow;
use crate::rng::{Rng, Uniform};
use crate::space::IndexRay;
use crate::walk::{walk, BrickCache, SpanSampler};
use crate::Tracer;

/// Most tentative collisions one path (or one shadow ray) samples before it stops; a primary
/// path that runs out counts as absorbed, a shadow ray keeps its estimate so far.
pub const MAX_EVENTS: u32 = 1 << 16;
/// Shadow weight below which ratio tracking stops (bias below 1e-6).
pub const MIN_SHADOW_WEIGHT: f64 = 1e-6;

/// Free flight over `[ta, tb]` against majorant `mu_bar` (per length unit): calls `at(s, p, rng)`
/// at each tentative collision (`s` in length units from the ray origin) until it says stop, the
/// span ends (`Go`) or the event budget runs out (`Stop`).
pub(crate) fn track<R: Uniform>(
    ray: &IndexRay,
    mu_bar: f64,
    ta: f64,
    tb: f64,
    rng: &mut R,
    events: &mut u32,
    mut at: impl FnMut(f64, [f64; 3], &mut R) -> Flow,
) -> Flow {
    if !(mu_bar > 0.0) {
        return Flow::Go;
    }
    let (mut s, sb) = (ta * ray.per_t, tb * ray.per_t);
    loop {
        if *events == 0 {
            return Flow::Stop;
        }
        *events -= 1;
        s -= (1.0 - rng.uniform()).ln() / mu_bar;
        if !(s < sb) {
            return Flow::Go;
        }
        if at(s, ray.at(s / ray.per_t), rng) == Flow::Stop {
            return Flow::Stop;
        }
    }
}

/// One primary path.
pub(crate) struct Path<'a, 't> {
    pub tracer: &'t Tracer<'a>,
    pub ray: IndexRay,
    pub rng: Rng,
    pub shadow_cache: &'t mut BrickCache,
    /// Set when the path left the volume.
    pub escaped: bool,
    /// Light scored (before the light colour).
    pub lum: f64,
    /// Emission gathered (with `settings.emission`; the collision estimator of
    /// `reference::Flight`: `E / μ̄` at each tentative collision, the majorant at least `1/step`
    /// where the span can emit).
    pub emitted: [f64; 3],
    pub events: u32,
    /// Where the flight ended (`t`): its real collision, or the end of the walk (set by the
    /// caller) if it escaped.
    pub end_t: f64,
}

impl Path<'_, '_> {
    /// Whether a span of max `max` can emit.
    fn emits(&self, max: f32) -> bool {
        self.tracer
            .settings
            .medium
            .emission
            .is_some_and(|e| max > e.range[0])
    }

    fn flight(&mut self, ta: f64, tb: f64, max: f32, value: impl Fn([f64; 3]) -> f32) -> Flow {
        let ext = self.tracer.extinction;
        let base = ext * max as f64;
        let emission = self
            .tracer
            .settings
            .medium
            .emission
            .filter(|_| self.emits(max));
        let mu_bar = match emission {
            Some(_) => base.max(1.0 / self.tracer.settings.integrator.step as f64),
            None => base,
        };
        let boosted = mu_bar != base;
        let table = &self.tracer.emit_table;
        let mut emitted = [0.0f64; 3];
        let ray = self.ray;
        let mut rng = self.rng;
        let mut events = self.events;
        let tracer = self.tracer;
        let mut lum = 0.0;
        let cache = &mut *self.shadow_cache;
        let mut end_t = self.end_t;
        let flow = track(&ray, mu_bar, ta, tb, &mut rng, &mut events, |s, p, rng| {
            let v = value(p);
            let sigma = (v as f64).max(0.0);
            if let Some(e) = &emission {
                for (a, r) in emitted.iter_mut().zip(e.radiance(table, v)) {
                    *a += r as f64 / mu_bar;
                }
            }
            let null = if boosted {
                rng.uniform() * mu_bar >= ext * sigma
            } else {
                rng.uniform() * max as f64 >= sigma
            };
            if null {
                return Flow::Go; // null collision
            }
            end_t = s / ray.per_t;
            if rng.uniform() < tracer.albedo {
                lum = tracer.ratio_shadow(p, tracer.settings.integrator.gain as f64, rng, cache);
            }
            Flow::Stop
        });
        self.end_t = end_t;
        self.rng = rng;
        self.events = events;
        self.lum += lum;
        for (a, e) in self.emitted.iter_mut().zip(emitted) {
            *a += e;
        }
        if flow == Flow::Stop {
            // A real collision, or the event budget ran out (counted as absorbed).
            self.escaped = false;
        }
        flow
    }
}

impl SpanSampler for Path<'_, '_> {
    fn skip_max(&self, max: f32) -> bool {
        !self.emits(max) && (!(max > 0.0) || self.tracer.extinction == 0.0)
    }
    fn sample_span(&mut self, ta: f64, tb: f64, max: f32, value: impl Fn([f64; 3]) -> f32) -> Flow {
        self.flight(ta, tb, max, value)
    }
}

/// Ratio tracking toward the light.
struct Ratio<'a, 't, R> {
    tracer: &'t Tracer<'a>,
    /// Shadow extinction at distance `s` is divided by `1 + gain·s` (0: physical).
    gain: f64,
    ray: IndexRay,
    rng: R,
    weight: f64,
    events: u32,
}

impl<R: Uniform + Copy> Ratio<'_, '_, R> {
    fn flight(&mut self, ta: f64, tb: f64, max: f32, value: impl Fn([f64; 3]) -> f32) -> Flow {
        let ext = self.tracer.extinction;
        let gain = self.gain;
        let mu_bar = ext * max as f64;
        let ray = self.ray;
        let mut rng = self.rng;
        let mut events = self.events;
        let mut weight = self.weight;
        let flow = track(&ray, mu_bar, ta, tb, &mut rng, &mut events, |s, p, _| {
            let mu = ext * (value(p) as f64).max(0.0) / (1.0 + gain * s);
            weight *= 1.0 - mu / mu_bar;
            if weight < MIN_SHADOW_WEIGHT {
                weight = 0.0;
                Flow::Stop
            } else {
                Flow::Go
            }
        });
        self.rng = rng;
        self.events = events;
        self.weight = weight;
        flow
    }
}

impl<R: Uniform + Copy> SpanSampler for Ratio<'_, '_, R> {
    fn skip_max(&self, max: f32) -> bool {
        !(max > 0.0) || self.tracer.extinction == 0.0
    }
    fn sample_span(&mut self, ta: f64, tb: f64, max: f32, value: impl Fn([f64; 3]) -> f32) -> Flow {
        self.flight(ta, tb, max, value)
    }
}

impl Tracer<'_> {
    /// Ratio-tracking estimate of the transmittance from index point `p` toward the light, the
    /// extinction at distance `s` divided by `1 + gain·s`.
    pub(crate) fn ratio_shadow<R: Uniform + Copy>(
        &self,
        p: [f64; 3],
        gain: f64,
        rng: &mut R,
        cache: &mut BrickCache,
    ) -> f64 {
        let ray = self.light_ray(p);
        let Some((t0, t1)) = ray.clip(self.extent) else {
            return 1.0;
        };
        let mut v = Ratio {
            tracer: self,
            gain,
            ray,
            rng: *rng,
            weight: 1.0,
            events: MAX_EVENTS,
        };
        walk(&self.grid, &ray, t0, t1, cache, &mut v);
        *rng = v.rng;
        v.weight
    }
}

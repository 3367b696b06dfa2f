//! The physically based reference (`Mode::Reference`): a path tracer with multiple scattering
//! through the same medium as delta tracking (extinction `absorb + scatter` per unit density
//! per length unit, albedo `scatter / (absorb + scatter)`), which approximations are judged by.
//!
//! One path per sample: a free flight by delta tracking against the walk's span majorants; at a
//! real collision the throughput takes the albedo, the sun is added by next-event estimation
//! (`phase(d·l) · light_color · T_sun`, `T_sun` by ratio tracking, no `gain` falloff), and a new
//! direction is drawn from the dual-lobe Henyey–Greenstein phase (weight 1: the mixture is
//! sampled exactly). A scattered path that leaves the volume adds `throughput · sky`; a
//! primary ray that leaves without a collision adds nothing and counts toward the
//! transmittance `T` (so the image composites as `L + T·background`, like the other modes).
//! Russian roulette once the throughput is below 1 (survival probability = throughput, then
//! weight 1). Unbiased except: paths end after `bounces` scattering events or `MAX_EVENTS`
//! tentative collisions in one flight (counted as absorbed), shadow weights below
//! `MIN_SHADOW_WEIGHT` end as 0.
//!
//! With `emission`, every flight gathers the emission it crosses by a collision estimator (see
//! `Flight`), weighted by the path's throughput: emitted light is absorbed, scattered and
//! seen through the medium like any other (no next-event estimation toward emitters).
//!
//! Phase convention: `d` is the path's direction (from the eye), `ω'` the next one; light
//! arriving along `−ω'` leaves toward the eye along `−d`, so the scattering cosine is `d·ω'` and
//! for the sun (`l` toward it) `d·l`. `HG(g, μ) = (1 − g²) / (4π (1 + g² − 2gμ)^{3/2})`,
//! normalized over the sphere, forward-peaked for `g > 0`.

use crate::dda::Flow;
use crate::delta::{track, MAX_EVENTS};
use crate::rng::Rng64;
use crate::space::IndexRay;
use crate::walk::{walk, SpanSampler};
use crate::{Scratch, Tracer};
use vdbcook_scene::{normalize, phase, Emission, BLACKBODY_TABLE_LEN};

/// A cosine drawn from `HG(g, ·)` (inverse CDF; uniform for `|g| < 1e-4`).
fn sample_hg(g: f64, u: f64) -> f64 {
    if g.abs() < 1e-4 {
        return 1.0 - 2.0 * u;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// A unit direction at cosine `mu` to unit `d`, azimuth `phi`.
fn around(d: [f64; 3], mu: f64, phi: f64) -> [f64; 3] {
    // An orthonormal frame (t, b, d) (Duff et al. 2017).
    let sign = 1.0f64.copysign(d[2]);
    let a = -1.0 / (sign + d[2]);
    let b = d[0] * d[1] * a;
    let t = [1.0 + sign * d[0] * d[0] * a, sign * b, -sign * d[0]];
    let bb = [b, sign + d[1] * d[1] * a, -d[1]];
    let st = (1.0 - mu * mu).max(0.0).sqrt();
    let (sp, cp) = phi.sin_cos();
    normalize([0, 1, 2].map(|i| mu * d[i] + st * (cp * t[i] + sp * bb[i])))
}

/// The first real collision along a ray by delta tracking, and the emission met on the way.
///
/// Emission is gathered by a collision estimator: every tentative collision at `p` (before
/// the first real one, which included) adds `throughput · E(p) / μ̄`, whose expectation is
/// `throughput · ∫ T(s) E(s) ds`. Where the span can emit (its max is above the emission
/// range's low end) the majorant is at least `1 / step` (one tentative collision per step on
/// average), so a weakly or non-absorbing emitter is still sampled; a tentative collision is
/// then real with probability `μ/μ̄`.
struct Flight<'e> {
    ray: IndexRay,
    extinction: f64,
    rng: Rng64,
    events: u32,
    /// The collision point (cell space) and its `t`, once found.
    hit: Option<([f64; 3], f64)>,
    /// The event budget ran out (the path counts as absorbed).
    exhausted: bool,
    /// The settings' emission, its table, and the majorant floor `1 / step`.
    emission: Option<(Emission, &'e [[f32; 4]; BLACKBODY_TABLE_LEN], f64)>,
    throughput: f64,
    emitted: [f64; 3],
}

impl Flight<'_> {
    fn emits(&self, max: f32) -> bool {
        self.emission.is_some_and(|(e, _, _)| max > e.range[0])
    }
}

impl SpanSampler for Flight<'_> {
    fn skip_max(&self, max: f32) -> bool {
        !self.emits(max) && (!(max > 0.0) || self.extinction == 0.0)
    }
    fn sample_span(&mut self, ta: f64, tb: f64, max: f32, value: impl Fn([f64; 3]) -> f32) -> Flow {
        let base = self.extinction * max as f64;
        let emission = self.emission.filter(|_| self.emits(max));
        let mu_bar = match emission {
            Some((_, _, floor)) => base.max(floor),
            None => base,
        };
        let boosted = mu_bar != base;
        let (ext, throughput, per_t) = (self.extinction, self.throughput, self.ray.per_t);
        let mut emitted = [0.0f64; 3];
        let mut hit = None;
        let flow = track(
            &self.ray,
            mu_bar,
            ta,
            tb,
            &mut self.rng,
            &mut self.events,
            |t, p, rng| {
                let v = value(p);
                let sigma = (v as f64).max(0.0);
                if let Some((e, table, _)) = &emission {
                    let r = e.radiance(table, v);
                    for (a, r) in emitted.iter_mut().zip(r) {
                        *a += throughput * r as f64 / mu_bar;
                    }
                }
                let null = if boosted {
                    rng.uniform() * mu_bar >= ext * sigma
                } else {
                    rng.uniform() * max as f64 >= sigma
                };
                if null {
                    return Flow::Go;
                }
                hit = Some((p, t / per_t));
                Flow::Stop
            },
        );
        for (a, e) in self.emitted.iter_mut().zip(emitted) {
            *a += e;
        }
        self.hit = hit;
        self.exhausted = flow == Flow::Stop && hit.is_none();
        flow
    }
}

impl Tracer<'_> {
    /// One reference path from cell point `o` along the unit *world* direction `d`: its
    /// radiance and whether it left the volume without a collision.
    pub(crate) fn reference_path(
        &self,
        mut o: [f64; 3],
        mut d: [f64; 3],
        rng: &mut Rng64,
        scratch: &mut Scratch,
    ) -> ([f64; 3], bool) {
        let s = &self.settings;
        let l_world = normalize(s.lighting.light_dir.map(|c| c as f64));
        let sun = s.lighting.light_color.iter().any(|&c| c > 0.0);
        let (mut radiance, mut throughput) = ([0.0f64; 3], 1.0f64);
        for bounce in 0..=s.integrator.bounces {
            let ray = IndexRay::new(o, self.xf.dir_to_index(d), self.voxel_units());
            let mut f = Flight {
                ray,
                extinction: self.extinction,
                rng: *rng,
                events: MAX_EVENTS,
                hit: None,
                exhausted: false,
                emission: s
                    .medium
                    .emission
                    .map(|e| (e, &self.emit_table, 1.0 / s.integrator.step as f64)),
                throughput,
                emitted: [0.0; 3],
            };
            let clip = ray.clip(self.extent);
            if let Some((t0, t1)) = clip {
                walk(&self.grid, &ray, t0, t1, &mut scratch.primary, &mut f);
            }
            *rng = f.rng;
            for (r, e) in radiance.iter_mut().zip(f.emitted) {
                *r += e;
            }
            if let (Some(ce), Some((_, t1))) = (&self.channel_emission, clip) {
                // Another channel's emission by the track-length estimator: `∫ E ds` up to the
                // collision (or the exit), whose mean is `∫ T E ds`.
                let end = f.hit.map_or(t1, |(_, t)| t);
                let e = self.emission_of_channel(ce, &ray, 0.0, end, scratch);
                for (r, e) in radiance.iter_mut().zip(e) {
                    *r += throughput * e;
                }
            }
            let Some((p, _)) = f.hit else {
                if f.exhausted {
                    return (radiance, false);
                }
                if bounce == 0 {
                    return (radiance, true);
                }
                for (r, sky) in radiance.iter_mut().zip(s.lighting.sky) {
                    *r += throughput * sky as f64;
                }
                return (radiance, false);
            };
            if bounce == s.integrator.bounces {
                break;
            }
            throughput *= self.albedo;
            if sun && throughput > 0.0 {
                let mu = d[0] * l_world[0] + d[1] * l_world[1] + d[2] * l_world[2];
                let w = throughput * phase(s.medium.phase_g, s.medium.phase_w, mu);
                if w > 0.0 {
                    let t = self.ratio_shadow(p, 0.0, rng, &mut scratch.shadow);
                    for (r, c) in radiance.iter_mut().zip(s.lighting.light_color) {
                        *r += w * t * c as f64;
                    }
                }
            }
            if throughput < 1.0 {
                if !(rng.uniform() < throughput) {
                    break;
                }
                throughput = 1.0;
            }
            let g = if rng.uniform() < s.medium.phase_w as f64 {
                s.medium.phase_g[0]
            } else {
                s.medium.phase_g[1]
            };
            let mu = sample_hg(g as f64, rng.uniform());
            d = around(d, mu, std::f64::consts::TAU * rng.uniform());
            o = p;
        }
        (radiance, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The phase integrates to 1 over the sphere, and the sampler's cosines follow it: the
    /// histogram of 400k draws against the density `2π·phase(μ)` in 20 bins.
    #[test]
    fn phase_is_normalized_and_sampled_as_it_is_defined() {
        for (g, w) in [([0.0, 0.0], 1.0), ([0.8, -0.3], 0.7), ([-0.6, 0.2], 0.5)] {
            let n = 200_000;
            let integral: f64 = (0..n)
                .map(|k| {
                    let mu = -1.0 + 2.0 * (k as f64 + 0.5) / n as f64;
                    2.0 * std::f64::consts::PI * phase(g, w, mu) * 2.0 / n as f64
                })
                .sum();
            assert!((integral - 1.0).abs() < 1e-4, "{g:?}: ∫ = {integral}");
            let mut rng = Rng64::new(7, 0, 0);
            let bins = 20;
            let mut hist = vec![0u32; bins];
            let draws = 400_000;
            for _ in 0..draws {
                let lobe = if rng.uniform() < w as f64 { g[0] } else { g[1] };
                let mu = sample_hg(lobe as f64, rng.uniform());
                hist[(((mu + 1.0) / 2.0 * bins as f64) as usize).min(bins - 1)] += 1;
            }
            for (b, &h) in hist.iter().enumerate() {
                let (a, c) = (
                    -1.0 + 2.0 * b as f64 / bins as f64,
                    -1.0 + 2.0 * (b + 1) as f64 / bins as f64,
                );
                let m = 1000;
                let p: f64 = (0..m)
                    .map(|k| {
                        let mu = a + (c - a) * (k as f64 + 0.5) / m as f64;
                        2.0 * std::f64::consts::PI * phase(g, w, mu) * (c - a) / m as f64
                    })
                    .sum();
                let want = p * draws as f64;
                let sd = want.sqrt().max(1.0);
                assert!(
                    (h as f64 - want).abs() < 5.0 * sd + 1e-3 * draws as f64,
                    "{g:?} bin {b}: {h} draws, expected {want:.0}"
                );
            }
        }
    }

    /// `around` gives unit vectors at the asked cosine, for axes along every sign.
    #[test]
    fn around_keeps_the_cosine() {
        let mut rng = Rng64::new(3, 1, 2);
        for _ in 0..1000 {
            let d = normalize([0, 1, 2].map(|_| rng.uniform() * 2.0 - 1.0));
            let mu = rng.uniform() * 2.0 - 1.0;
            let w = around(d, mu, rng.uniform() * std::f64::consts::TAU);
            let dot = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
            let len = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
            assert!((dot - mu).abs() < 1e-9 && (len - 1.0).abs() < 1e-12);
        }
    }
}

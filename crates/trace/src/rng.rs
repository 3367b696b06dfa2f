//! The random numbers of delta tracking: a 32-bit PCG (LCG step + RXS-M-XS output permutation,
//! O'Neill 2014), seeded per (seed, pixel, sample index) by hashing, so sample `k` of a pixel is
//! the same whichever batch computes it (progressive rendering) and a GPU can reproduce it with
//! u32 arithmetic only.

/// One PCG step of `x` followed by its output permutation (also used as a hash).
#[inline]
pub fn pcg_hash(x: u32) -> u32 {
    let state = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// A stream of uniform numbers for one (seed, pixel, sample).
#[derive(Debug, Clone, Copy)]
pub struct Rng {
    state: u32,
}

impl Rng {
    pub fn new(seed: u32, pixel: u32, sample: u32) -> Rng {
        Rng {
            state: pcg_hash(seed ^ pcg_hash(pixel ^ pcg_hash(sample))),
        }
    }

    /// Uniform in `[0, 1)`, 24 bits (exact in f32 too).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        self.state = self
            .state
            .wrapping_mul(747_796_405)
            .wrapping_add(2_891_336_453);
        let s = self.state;
        let word = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277_803_737);
        (((word >> 22) ^ word) >> 8) as f64 * (1.0 / 16_777_216.0)
    }
}

/// The random numbers of the reference path tracer (CPU only, so not bound to u32 arithmetic):
/// SplitMix64 (Steele, Lea, Flood 2014) from a state seeded by hashing (seed, pixel, sample).
/// Its period is 2⁶⁴, so the streams of one image — each path draws hundreds to thousands of
/// numbers — do not run into each other as streams of a 2³² cycle would.
#[derive(Debug, Clone, Copy)]
pub struct Rng64 {
    state: u64,
}

fn splitmix(x: &mut u64) -> u64 {
    *x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng64 {
    pub fn new(seed: u32, pixel: u32, sample: u32) -> Rng64 {
        let mut h = (seed as u64) << 32 | pixel as u64;
        let a = splitmix(&mut h);
        let mut h2 = a ^ (sample as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
        Rng64 {
            state: splitmix(&mut h2),
        }
    }

    /// Uniform in `[0, 1)`, 53 bits.
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        (splitmix(&mut self.state) >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }
}

/// A source of uniform numbers in `[0, 1)`: the free-flight and ratio-tracking code serves
/// both generators.
pub trait Uniform {
    fn uniform(&mut self) -> f64;
}

impl Uniform for Rng {
    #[inline]
    fn uniform(&mut self) -> f64 {
        Rng::uniform(self)
    }
}

impl Uniform for Rng64 {
    #[inline]
    fn uniform(&mut self) -> f64 {
        Rng64::uniform(self)
    }
}

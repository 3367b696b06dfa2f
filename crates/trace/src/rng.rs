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

//! The seeded generator of the tests. Before the test kit, five test files each carried their
//! own copy of this xorshift64* (same shifts, same multiplier), so it is kept bit for bit: a
//! seed draws the same numbers it always did.

/// Xorshift64* (Vigna): shifts 12, 25, 27, multiplier `0x2545F4914F6CDD1D`. The state must not
/// be 0. Deterministic and dependency-free, so failures reproduce everywhere.
#[derive(Debug, Clone)]
pub struct XorShift(pub u64);

impl XorShift {
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in [0, 1).
    pub fn f(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.f()
    }

    /// In `0..n` (`0` when `n` is 0), by remainder.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }

    /// The top byte of the next draw.
    pub fn byte(&mut self) -> u8 {
        (self.next_u64() >> 56) as u8
    }

    /// A uniformly distributed unit vector.
    pub fn dir(&mut self) -> [f64; 3] {
        loop {
            let v = [0; 3].map(|_| self.range(-1.0, 1.0));
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if n > 0.1 && n <= 1.0 {
                return v.map(|c| c / n);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stream of the copies this replaced (the value pinned from the first one).
    #[test]
    fn same_stream_as_before() {
        let mut r = XorShift(0x9E37_79B9_7F4A_7C15);
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..1000 {
            s ^= s >> 12;
            s ^= s << 25;
            s ^= s >> 27;
            assert_eq!(r.next_u64(), s.wrapping_mul(0x2545F4914F6CDD1D));
        }
    }
}

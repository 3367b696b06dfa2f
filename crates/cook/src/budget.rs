//! Budget stage: the error bound every brick is held to. A bound given per channel holds as
//! given; a lossy cook without one gets the default artefact guard, 10% of each channel's value
//! range (`encode::default_budget`); `--max-bytes SIZE` (seed requirement 3.1.1: games budget
//! memory per effect) finds the smallest bound whose **GPU bytes** fit — topology plus atlas,
//! what a runtime holds and what `info`/`cook --json` report as `bytes.topology + bytes.atlas` —
//! because that is the memory a game plans; the file is zstd-compressed and smaller.
//!
//! The size search is over one fraction `t` of every channel's value range (a channel's bound is
//! `t · range`): lossless f32 first (if it fits, nothing is lost), then a bisection on log `t`
//! between a millionth and the whole range, each step the cook's own cluster guard and encode at
//! that bound (the same per-brick format choice and GPU-read slack as `--max-error`), whose bytes
//! are counted exactly from the pool's topology and the encode's payloads (`gpu_bytes`, checked
//! against the assembled asset). Deterministic: the steps depend only on the pool and the options.

use crate::encode::Encoded;

/// Bisection steps on log t: 12 steps resolve the 10⁶ span to a factor of 1.0034.
const STEPS: usize = 12;
/// The smallest bound tried, as a fraction of the value range.
const LOWEST_OF_RANGE: f64 = 1e-6;

/// What the search settled on.
pub struct Found {
    /// The fraction of each channel's value range to cook with (`None`: lossless f32 fits).
    pub fraction: Option<f64>,
    /// GPU bytes of that cook.
    pub gpu_bytes: u64,
    /// Cooks tried.
    pub trials: usize,
}

/// GPU bytes of a cook whose topology without tiles is `fixed_topology`, whose pool already holds
/// `base_tiles` tile values, and whose bricks were encoded as `enc`: tiles 4 bytes each, every
/// stored brick its payload plus its value range and quantization range (8 bytes each).
pub fn gpu_bytes(fixed_topology: u64, base_tiles: usize, enc: &Encoded) -> u64 {
    let stored: u64 = enc.brick_counts.iter().sum();
    let payload: u64 = enc.payloads.iter().map(|p| p.len() as u64).sum();
    fixed_topology + 4 * (base_tiles + enc.new_tiles.len()) as u64 + payload + 16 * stored
}

/// The smallest fraction whose cook fits `max_bytes`: `lossless` bytes first (f32, nothing
/// lost), then `bytes_at(t)`, the GPU bytes of the cook at fraction `t` of each channel's range.
/// `fixed_topology` (the topology without tiles) names what no bound can shrink in the error.
pub fn search(
    lossless: u64,
    fixed_topology: u64,
    max_bytes: u64,
    mut bytes_at: impl FnMut(f64) -> Result<u64, String>,
) -> Result<Found, String> {
    if lossless <= max_bytes {
        return Ok(Found {
            fraction: None,
            gpu_bytes: lossless,
            trials: 0,
        });
    }
    let mut trials = 0;
    let mut at = |t: f64| -> Result<u64, String> {
        trials += 1;
        bytes_at(t)
    };
    let at_hi = at(1.0)?;
    if at_hi > max_bytes {
        return Err(format!(
            "even the coarsest bound (every voxel within the whole value range) needs {at_hi} \
             GPU bytes, over --max-bytes {max_bytes}: the topology alone is {fixed_topology} \
             bytes (+4 per tile); cook fewer frames or a coarser grid"
        ));
    }
    let at_lo = at(LOWEST_OF_RANGE)?;
    if at_lo <= max_bytes {
        return Ok(Found {
            fraction: Some(LOWEST_OF_RANGE),
            gpu_bytes: at_lo,
            trials,
        });
    }
    // Invariant: `lo` does not fit, `best` (= 1 at first) fits.
    let (mut lo, mut best, mut best_bytes) = (LOWEST_OF_RANGE, 1.0f64, at_hi);
    for _ in 0..STEPS {
        let mid = (lo * best).sqrt();
        let b = at(mid)?;
        if b <= max_bytes {
            (best, best_bytes) = (mid, b);
        } else {
            lo = mid;
        }
    }
    Ok(Found {
        fraction: Some(best),
        gpu_bytes: best_bytes,
        trials,
    })
}

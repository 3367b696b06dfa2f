//! `cook --max-bytes SIZE`: a size budget instead of an error budget (seed requirement 3.1.1;
//! games budget memory per effect). The budget is on the asset's **GPU bytes** — topology plus
//! atlas, what a runtime holds and what `info`/`cook --json` report as `bytes.topology +
//! bytes.atlas` — because that is the memory a game plans; the file is zstd-compressed and
//! smaller. The search finds the smallest error bound E whose `--max-error E` cook fits: lossless
//! f32 first (if it fits, nothing is lost), then a bisection on log E between a millionth of the
//! value range and the whole range, each step one encode (`encode::encode`, the same per-brick
//! format choice and GPU-read slack as `--max-error`) whose bytes are counted exactly from the
//! pool's topology and the encode's payloads (`gpu_bytes`, checked against the written asset).
//! Deterministic: the steps depend only on the pool and the options.

use vdbcook_asset::{PayloadFormat, BRICK_VOXELS};

use crate::encode::{self, EncodeOptions, Encoded};

/// Bisection steps on log E: 12 steps resolve the 10⁶ span to a factor of 1.0034.
const STEPS: usize = 12;
/// The smallest bound tried, as a fraction of the value range.
const LOWEST_OF_RANGE: f64 = 1e-6;

/// What the search settled on.
pub struct Found {
    /// The bound to cook with (`None`: lossless f32 fits).
    pub max_error: Option<f32>,
    /// GPU bytes of that cook.
    pub gpu_bytes: u64,
    /// Encodes tried.
    pub trials: usize,
}

/// Parses a size: `123`, `64K`/`64KB` (10³), `32M`/`32MB`, `1G`/`1GB`, `64KiB` (2¹⁰), `32MiB`,
/// `1GiB` (case-insensitive suffix, optional space, integer or decimal number).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let n: f64 = num
        .parse()
        .map_err(|_| format!("'{s}' is not a size (e.g. 500000, 64KiB, 32MiB, 1.5GB)"))?;
    let mult: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" => 1e3,
        "m" | "mb" => 1e6,
        "g" | "gb" => 1e9,
        "kib" => 1024.0,
        "mib" => 1024.0 * 1024.0,
        "gib" => 1024.0 * 1024.0 * 1024.0,
        u => {
            return Err(format!(
                "unknown size unit '{u}' in '{s}' (B, K, M, G, KiB, MiB, GiB)"
            ))
        }
    };
    let v = n * mult;
    if !(v.is_finite() && (1.0..1.8e19).contains(&v)) {
        return Err(format!(
            "'{s}' is out of range: SIZE must be 1 byte to 16 EiB"
        ));
    }
    Ok(v.round() as u64)
}

/// GPU bytes of a cook whose topology without tiles is `fixed_topology`, whose pool already holds
/// `base_tiles` tile values, and whose bricks were encoded as `enc`: tiles 4 bytes each, every
/// stored brick its payload plus its value range and quantization range (8 bytes each).
pub fn gpu_bytes(fixed_topology: u64, base_tiles: usize, enc: &Encoded) -> u64 {
    let stored: u64 = enc.brick_counts.iter().sum();
    let payload: u64 = enc.payloads.iter().map(|p| p.len() as u64).sum();
    fixed_topology + 4 * (base_tiles + enc.new_tiles.len()) as u64 + payload + 16 * stored
}

/// The smallest bound whose cook of `bricks` fits `max_bytes`, trying f32 first. `eopts` gives
/// the format list's start and the encoder settings (its `max_error` is ignored); `range` is the
/// value range (`max − min`, background included). `trial(E, bytes)` is told each step.
pub fn search(
    bricks: &[f32],
    eopts: &EncodeOptions,
    fixed_topology: u64,
    base_tiles: usize,
    range: f32,
    max_bytes: u64,
    mut trial: impl FnMut(f32, u64),
) -> Result<Found, String> {
    let n = (bricks.len() / BRICK_VOXELS) as u64;
    let lossless = fixed_topology
        + 4 * base_tiles as u64
        + n * (PayloadFormat::F32.bytes_per_brick() as u64 + 16);
    if lossless <= max_bytes {
        return Ok(Found {
            max_error: None,
            gpu_bytes: lossless,
            trials: 0,
        });
    }
    let mut trials = 0;
    let mut bytes_at = |e: f32| -> Result<u64, String> {
        let o = EncodeOptions {
            max_error: Some(e),
            lossy_tiles: true,
            ..*eopts
        };
        let b = gpu_bytes(fixed_topology, base_tiles, &encode::encode(bricks, &o)?);
        trials += 1;
        trial(e, b);
        Ok(b)
    };
    let r = (range as f64).max(f32::MIN_POSITIVE as f64);
    let hi = r as f32;
    let at_hi = bytes_at(hi)?;
    if at_hi > max_bytes {
        return Err(format!(
            "even the coarsest bound (every voxel within the whole value range, {hi:e}) needs \
             {at_hi} GPU bytes, over --max-bytes {max_bytes}: the topology alone is \
             {fixed_topology} bytes (+4 per tile); cook fewer frames or a coarser grid"
        ));
    }
    let lo = (r * LOWEST_OF_RANGE) as f32;
    let at_lo = bytes_at(lo)?;
    if at_lo <= max_bytes {
        return Ok(Found {
            max_error: Some(lo),
            gpu_bytes: at_lo,
            trials,
        });
    }
    // Invariant: `lo` does not fit, `best` (= hi at first) fits.
    let (mut lo, mut best, mut best_bytes) = (lo as f64, hi as f64, at_hi);
    for _ in 0..STEPS {
        let mid = (lo * best).sqrt();
        let b = bytes_at(mid as f32)?;
        if b <= max_bytes {
            (best, best_bytes) = (mid, b);
        } else {
            lo = mid;
        }
    }
    Ok(Found {
        max_error: Some(best as f32),
        gpu_bytes: best_bytes,
        trials,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_decimal_and_binary_units() {
        assert_eq!(parse_size("500000"), Ok(500_000));
        assert_eq!(parse_size("64KiB"), Ok(65_536));
        assert_eq!(parse_size("32MiB"), Ok(32 * 1024 * 1024));
        assert_eq!(parse_size("1.5GB"), Ok(1_500_000_000));
        assert_eq!(parse_size("2 mb"), Ok(2_000_000));
        for bad in ["", "MiB", "12 parsecs", "-5", "0", "1e400", "nan"] {
            assert!(parse_size(bad).is_err(), "{bad:?} should be refused");
        }
    }
}

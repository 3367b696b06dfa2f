//! Encode stage: turns the deduplicated f32 brick pool into per-format atlases. Without
//! `--max-error` every brick takes `--format`. With `--max-error E`, each brick takes the first
//! representation in the candidate list whose decoded voxels are all within E of the source —
//! a (lossy) tile value, then the formats cheapest first (`PayloadFormat::BY_COST`: packed1,
//! BC7, packed2, packed3, BC4, packed4..packed7, unorm8, f16, f32; the packed widths left out
//! with `--no-packed`) — starting at `--format` when one is given ("this format where it meets
//! E, fall back where it does not"). Every check decodes
//! with the same CPU decoders `eval` and the runtime's reference use, and adds, per voxel, what a
//! GPU's native read may differ from that decode (`payload::read_codes_per_voxel`: for BC4 the
//! bound of the voxel's block, for BC7 1 code of the brick's range), so E holds on the GPU, not
//! only on the CPU. A lossy cook without
//! `--max-error` gets a default budget (`default_budget`) that only guards: bricks over it fall
//! back along the same list, and no brick becomes a lossy tile, so no lossy cook is unguarded
//! and none is coarser than its format.

use rayon::prelude::*;
use vdbcook_asset::payload::{self, vox_index};
use vdbcook_asset::{PayloadFormat, RangeMode, BRICK_VOXELS, FORMATS, TILE_BIT};

use crate::bc4fit;
use crate::bcenc::{encode_bc7, Bc7Quality};

#[derive(Clone, Copy, Debug)]
pub struct EncodeOptions {
    pub format: PayloadFormat,
    /// `--format` was given explicitly (matters only with `max_error`).
    pub format_given: bool,
    pub max_error: Option<f32>,
    /// Whether bricks within `max_error` of one value become (lossy) tiles: yes for a given
    /// `--max-error`; a default budget only guards the chosen format (it never makes a cook
    /// coarser than its format).
    pub lossy_tiles: bool,
    pub range: RangeMode,
    pub bc7_quality: Bc7Quality,
    /// Whether `max_error` may pick the packed widths (`--no-packed` clears it: assets older
    /// runtimes read, format version 6 or below).
    pub packed: bool,
}

impl EncodeOptions {
    /// The candidates `max_error` tries, cheapest first: from `--format` when given.
    pub fn candidates(&self) -> Vec<PayloadFormat> {
        let all: Vec<PayloadFormat> = PayloadFormat::BY_COST
            .into_iter()
            .filter(|f| self.packed || f.packed_bits().is_none() || *f == self.format)
            .collect();
        let from = if self.format_given {
            all.iter().position(|&f| f == self.format).unwrap_or(0)
        } else {
            0
        };
        all[from..].to_vec()
    }
}

/// How many bricks went to each representation.
#[derive(Debug, Default, Clone, Copy)]
pub struct Representation {
    pub tile: u64,
    pub per_format: [u64; FORMATS],
}

pub struct Encoded {
    /// For each input brick: its final ref (brick index in format-grouped order, or
    /// `TILE_BIT | k` — the k-th of `new_tiles` — when it became a tile).
    pub remap: Vec<u32>,
    pub payloads: [Vec<u8>; FORMATS],
    pub brick_counts: [u64; FORMATS],
    /// Per final brick `[lo, hi]` of its quantization range (`[0, 0]` for float formats).
    pub brick_quant: Vec<[f32; 2]>,
    /// Per final brick `[min, max]` of its decoded values.
    pub brick_ranges: Vec<[f32; 2]>,
    /// Decoded values of every *input* brick (voxel order), whatever it became; empty when the
    /// encoding was lossless (decoded = input, see [`Encoded::decoded_or`]).
    pub decoded: Vec<f32>,
    /// Tile values created from bricks (to append to the pool's tiles).
    pub new_tiles: Vec<f32>,
    pub representation: Representation,
}

/// The default `--max-error` of a lossy cook, as a fraction of the sequence's value range
/// (`max − min` over every stored value and the background): why this value, `docs/accuracy.md`.
pub const DEFAULT_BUDGET_OF_RANGE: f32 = 0.1;

/// The budget a lossy cook without `--max-error` gets: [`DEFAULT_BUDGET_OF_RANGE`] of the value
/// range `[lo, hi]` (a constant volume's range is 0: then any positive budget keeps it exact).
pub fn default_budget(range: [f32; 2]) -> f32 {
    let r = (range[1] as f64 - range[0] as f64).max(0.0);
    let e = (DEFAULT_BUDGET_OF_RANGE as f64 * r) as f32;
    if e > 0.0 && e.is_finite() {
        e
    } else {
        f32::MIN_POSITIVE
    }
}

impl Encoded {
    /// Input brick `b`'s stored representation: its format, bytes and quantization range
    /// (`None`: it became a tile).
    fn stored(&self, b: usize) -> Option<(PayloadFormat, &[u8], [f32; 2])> {
        let r = self.remap[b];
        if r & TILE_BIT != 0 {
            return None;
        }
        let (f, i) = vdbcook_asset::locate_brick(&self.brick_counts, r as u64)
            .expect("remap points into the pool");
        let per = f.bytes_per_brick();
        Some((
            f,
            &self.payloads[f.rank()][i * per..(i + 1) * per],
            self.brick_quant[r as usize],
        ))
    }

    /// For every voxel of input brick `b` (voxel order), how far a GPU's native read
    /// of its representation may be from `decoded`, in value units
    /// ([`payload::read_codes_per_voxel`]; 0 for tiles and exact formats).
    pub fn voxel_slack(&self, b: usize, out: &mut [f32; BRICK_VOXELS]) {
        let Some((f, bytes, quant)) = self.stored(b) else {
            out.fill(0.0);
            return;
        };
        payload::read_codes_per_voxel(f, bytes, out);
        let code = payload::codes_to_value(1.0, quant);
        out.iter_mut().for_each(|c| *c *= code);
    }

    /// The most a GPU's native read of any voxel of input brick `b` may be from `decoded`
    /// ([`payload::brick_read_slack`]; 0 for tiles and exact formats).
    pub fn brick_slack(&self, b: usize) -> f32 {
        self.stored(b).map_or(0.0, |(f, bytes, quant)| {
            payload::brick_read_slack(f, bytes, quant)
        })
    }

    /// Decoded values of the input bricks (`input` itself when the encoding was lossless).
    pub fn decoded_or<'a>(&'a self, input: &'a [f32]) -> &'a [f32] {
        if self.decoded.is_empty() {
            input
        } else {
            &self.decoded
        }
    }
}

/// Value range of one brick.
fn range_of(v: &[f32]) -> [f32; 2] {
    let (lo, hi) = v
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &x| {
            (if x < lo { x } else { lo }, if x > hi { x } else { hi })
        });
    [lo, hi]
}

/// Encodes `bricks` (indices into the pool) in one format; returns bytes per brick, in order.
fn encode_batch(
    format: PayloadFormat,
    pool: &[f32],
    idx: &[usize],
    quant: &[[f32; 2]],
    q: Bc7Quality,
) -> Vec<u8> {
    let brick = |b: usize| &pool[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
    match format {
        PayloadFormat::F32 | PayloadFormat::F16 => {
            let mut out = Vec::with_capacity(idx.len() * format.bytes_per_brick());
            for &b in idx {
                payload::encode_float(format, brick(b), &mut out);
            }
            out
        }
        PayloadFormat::Unorm8 => {
            let mut out = Vec::with_capacity(idx.len() * BRICK_VOXELS);
            for &b in idx {
                out.extend_from_slice(&payload::encode_unorm8(brick(b), quant[b][0], quant[b][1]));
            }
            out
        }
        PayloadFormat::Bc4 => {
            let bricks: Vec<[u8; 256]> = idx
                .par_iter()
                .map(|&b| bc4fit::encode_brick(brick(b), quant[b][0], quant[b][1]))
                .collect();
            bricks.concat()
        }
        f if f.packed_bits().is_some() => {
            let bits = f.packed_bits().expect("packed");
            let bricks: Vec<Vec<u8>> = idx
                .par_iter()
                .map(|&b| payload::encode_packed(brick(b), bits, quant[b][0], quant[b][1]))
                .collect();
            bricks.concat()
        }
        _ => {
            // BC7: brick i as 2 slices of 8×8 RGBA texels (an 8×16 tile); texel (x, y) of slice s
            // holds z = 4s..4s+3 in R, G, B, A.
            let tiles = tile_bytes(idx, 4, 16, |b, t| {
                let [lo, hi] = quant[b];
                let v = brick(b);
                for s in 0..2 {
                    for y in 0..8 {
                        for x in 0..8 {
                            for c in 0..4 {
                                t[4 * (8 * (8 * s + y) + x) + c] =
                                    payload::quantize(v[vox_index(x, y, 4 * s + c)], lo, hi);
                            }
                        }
                    }
                }
            });
            encode_tiled(&tiles, idx.len(), 16, 4, 16, |w, h, px| {
                encode_bc7(w, h, px, q)
            })
        }
    }
}

/// Each brick's 8-texel-wide tile (`rows` rows of `bpp`-byte texels), filled by `fill`.
fn tile_bytes(
    idx: &[usize],
    bpp: usize,
    rows: usize,
    fill: impl Fn(usize, &mut [u8]) + Sync,
) -> Vec<u8> {
    let per = 8 * rows * bpp;
    let mut tiles = vec![0u8; idx.len() * per];
    tiles
        .par_chunks_mut(per)
        .zip(idx.par_iter())
        .for_each(|(t, &b)| fill(b, t));
    tiles
}

/// Bricks per surface row: the BC encoders vectorise across the blocks of a row, so an 8-texel
/// wide surface would leave most SIMD lanes idle (measured: BC7 12× slower).
const TILES_PER_ROW: usize = 64;

/// Lays the 8-wide tiles side by side (TILES_PER_ROW per row), encodes the surface with `enc`,
/// and returns the blocks regrouped per brick (block-row-major inside each tile).
fn encode_tiled(
    tiles: &[u8],
    n: usize,
    rows: usize,
    bpp: usize,
    block_bytes: usize,
    enc: impl Fn(u32, u32, &[u8]) -> Vec<u8>,
) -> Vec<u8> {
    if n == 0 {
        return Vec::new();
    }
    let k = TILES_PER_ROW.min(n);
    let bands = n.div_ceil(k);
    let width = 8 * k;
    let mut surface = vec![0u8; width * rows * bands * bpp];
    for i in 0..n {
        let (cx, cy) = (i % k, i / k);
        for r in 0..rows {
            let src = &tiles[(i * rows + r) * 8 * bpp..(i * rows + r + 1) * 8 * bpp];
            let dst = ((cy * rows + r) * width + 8 * cx) * bpp;
            surface[dst..dst + 8 * bpp].copy_from_slice(src);
        }
    }
    let blocks = enc(width as u32, (rows * bands) as u32, &surface);
    let blocks_per_row = width / 4;
    let tile_block_rows = rows / 4;
    let mut out = Vec::with_capacity(n * 2 * tile_block_rows * block_bytes);
    for i in 0..n {
        let (cx, cy) = (i % k, i / k);
        for by in 0..tile_block_rows {
            for bx in 0..2 {
                let b = (cy * tile_block_rows + by) * blocks_per_row + 2 * cx + bx;
                out.extend_from_slice(&blocks[b * block_bytes..(b + 1) * block_bytes]);
            }
        }
    }
    out
}

pub fn encode(pool: &[f32], opts: &EncodeOptions) -> Result<Encoded, String> {
    encode_budgets(pool, opts, None)
}

/// [`encode`] with a budget per brick (`budgets[b]`, each at most `opts.max_error`, which must be
/// set): a multi-channel pool, where a brick is held to the smallest budget of the channels that
/// use it.
pub fn encode_budgets(
    pool: &[f32],
    opts: &EncodeOptions,
    budgets: Option<&[f32]>,
) -> Result<Encoded, String> {
    let n = pool.len() / BRICK_VOXELS;
    let brick = |b: usize| &pool[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
    let ranges: Vec<[f32; 2]> = pool.par_chunks(BRICK_VOXELS).map(range_of).collect();
    let quant: Vec<[f32; 2]> = match opts.range {
        RangeMode::Brick => ranges.clone(),
        RangeMode::Global => {
            let g = ranges
                .iter()
                .fold([f32::INFINITY, f32::NEG_INFINITY], |a, r| {
                    [a[0].min(r[0]), a[1].max(r[1])]
                });
            vec![g; n]
        }
    };
    let quant_of = |f: PayloadFormat, b: usize| {
        if f.is_quantized() {
            quant[b]
        } else {
            [0.0, 0.0]
        }
    };
    // One format for every brick: encode in pool order, no checks, no copies.
    if opts.max_error.is_none() {
        let f = opts.format;
        let all: Vec<usize> = (0..n).collect();
        if f == PayloadFormat::F16 {
            if let Some(v) = payload::check_representable(f, pool) {
                return Err(format!(
                    "value {v} is beyond the range of f16 (±{}); cook with --format f32",
                    payload::F16_MAX
                ));
            }
        }
        let bytes = encode_batch(f, pool, &all, &quant, opts.bc7_quality);
        let mut payloads: [Vec<u8>; FORMATS] = Default::default();
        let mut brick_counts = [0u64; FORMATS];
        brick_counts[f.rank()] = n as u64;
        let (decoded, brick_ranges) = if f == PayloadFormat::F32 {
            (Vec::new(), ranges)
        } else {
            let per = f.bytes_per_brick();
            let mut d = vec![0f32; pool.len()];
            d.par_chunks_mut(BRICK_VOXELS)
                .enumerate()
                .for_each(|(b, out)| {
                    payload::decode_brick(
                        f,
                        &bytes[b * per..(b + 1) * per],
                        quant_of(f, b),
                        out.try_into().expect("512"),
                    );
                });
            let r = d.par_chunks(BRICK_VOXELS).map(range_of).collect();
            (d, r)
        };
        if decoded.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "some bricks do not decode to finite values in {}",
                f.name()
            ));
        }
        payloads[f.rank()] = bytes;
        let mut representation = Representation::default();
        representation.per_format[f.rank()] = n as u64;
        return Ok(Encoded {
            remap: (0..n as u32).collect(),
            payloads,
            brick_counts,
            brick_quant: (0..n).map(|b| quant_of(f, b)).collect(),
            brick_ranges,
            decoded,
            new_tiles: Vec::new(),
            representation,
        });
    }
    let e_all = opts.max_error.expect("checked") as f64;
    let e_of = |b: usize| budgets.map_or(e_all, |v| v[b] as f64);
    // Candidates, cheapest first.
    let formats = &opts.candidates()[..];
    let mut decoded = vec![0f32; pool.len()];
    // Per brick: None (pending), a tile, or (format, batch, index in batch).
    #[derive(Clone, Copy)]
    enum Choice {
        Pending,
        Tile(f32),
        Stored(PayloadFormat, usize, usize),
    }
    let mut choice = vec![Choice::Pending; n];
    // A brick whose values all lie within E of their midpoint becomes a tile.
    for b in (0..n).filter(|_| opts.lossy_tiles) {
        let [lo, hi] = ranges[b];
        let mid = lo + (hi - lo) * 0.5;
        let e = e_of(b);
        if brick(b).iter().all(|&v| ((v - mid) as f64).abs() <= e) {
            choice[b] = Choice::Tile(mid);
            decoded[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS].fill(mid);
        }
    }
    let mut pending: Vec<usize> = (0..n)
        .filter(|&b| matches!(choice[b], Choice::Pending))
        .collect();
    let mut batches: Vec<Vec<u8>> = Vec::new();
    for (fi, &f) in formats.iter().enumerate() {
        if pending.is_empty() {
            break;
        }
        let last = fi + 1 == formats.len();
        if f == PayloadFormat::F16 && !last {
            // Bricks beyond f16's range skip it (they end in f32).
            let (fit, skip): (Vec<usize>, Vec<usize>) = pending
                .iter()
                .partition(|&&b| payload::check_representable(f, brick(b)).is_none());
            if !skip.is_empty() {
                let mut rest = fit;
                rest.extend(skip.iter().copied());
                pending = rest;
            }
        }
        let bytes = encode_batch(f, pool, &pending, &quant, opts.bc7_quality);
        let per = f.bytes_per_brick();
        let mut dec = vec![0f32; pending.len() * BRICK_VOXELS];
        let errs: Vec<f64> = dec
            .par_chunks_mut(BRICK_VOXELS)
            .zip(pending.par_iter())
            .enumerate()
            .map(|(k, (out, &b))| {
                let representable =
                    f != PayloadFormat::F16 || payload::check_representable(f, brick(b)).is_none();
                if !representable {
                    return f64::INFINITY;
                }
                payload::decode_brick(
                    f,
                    &bytes[k * per..(k + 1) * per],
                    quant_of(f, b),
                    out.try_into().expect("512"),
                );
                // What any GPU may read: the CPU decode's error plus each voxel's
                // native slack.
                let mut codes = [0f32; BRICK_VOXELS];
                payload::read_codes_per_voxel(f, &bytes[k * per..(k + 1) * per], &mut codes);
                // In f32 as `Encoded::voxel_slack` computes it, so the report's bound is this one.
                let code = payload::codes_to_value(1.0, quant_of(f, b));
                out.iter()
                    .zip(brick(b))
                    .zip(codes)
                    .map(|((a, s), c)| (*a as f64 - *s as f64).abs() + (c * code) as f64)
                    .fold(
                        0.0f64,
                        |m, x| if x.is_nan() { f64::INFINITY } else { m.max(x) },
                    )
            })
            .collect();
        let batch = batches.len();
        let mut still = Vec::new();
        for (k, (&b, &err)) in pending.iter().zip(&errs).enumerate() {
            let e = e_of(b);
            if err <= e || (last && err.is_finite()) {
                decoded[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]
                    .copy_from_slice(&dec[k * BRICK_VOXELS..(k + 1) * BRICK_VOXELS]);
                choice[b] = Choice::Stored(f, batch, k);
            } else if last {
                return Err(format!(
                    "brick {b} cannot be stored within {e} even in {}",
                    f.name()
                ));
            } else {
                still.push(b);
            }
        }
        batches.push(bytes);
        pending = still;
    }
    // Group by format (cheapest first), keeping input order inside a group.
    let mut remap = vec![0u32; n];
    let mut payloads: [Vec<u8>; FORMATS] = Default::default();
    let mut brick_counts = [0u64; FORMATS];
    let mut brick_quant = Vec::new();
    let mut brick_ranges = Vec::new();
    let mut new_tiles = Vec::new();
    let mut representation = Representation::default();
    let mut next = 0u32;
    for f in PayloadFormat::ORDER {
        for b in 0..n {
            if let Choice::Stored(bf, batch, k) = choice[b] {
                if bf == f {
                    let per = f.bytes_per_brick();
                    remap[b] = next;
                    next += 1;
                    payloads[f.rank()].extend_from_slice(&batches[batch][k * per..(k + 1) * per]);
                    brick_counts[f.rank()] += 1;
                    brick_quant.push(quant_of(f, b));
                    brick_ranges.push(range_of(&decoded[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]));
                }
            }
        }
        representation.per_format[f.rank()] = brick_counts[f.rank()];
    }
    for b in 0..n {
        if let Choice::Tile(v) = choice[b] {
            remap[b] = TILE_BIT | new_tiles.len() as u32;
            new_tiles.push(v);
            representation.tile += 1;
        }
    }
    Ok(Encoded {
        remap,
        payloads,
        brick_counts,
        brick_quant,
        brick_ranges,
        decoded,
        new_tiles,
        representation,
    })
}

/// The clustering guard: a brick stays a member of its cluster only if the *decoded* centroid
/// (`centroid_values` encoded with `opts` as `centroids`), plus what a GPU's native read of it may
/// add, is within
/// `opts.max_error` of each of the brick's voxels; other members are released (`None`) and keep
/// their own data. Returns how many were released. No budget: nothing is checked.
pub fn guard_members(
    bricks: &[f32],
    centroid_values: &[f32],
    centroids: &Encoded,
    member_of: &mut [Option<u32>],
    opts: &EncodeOptions,
) -> usize {
    let Some(e) = opts.max_error else {
        return 0;
    };
    let mut released = 0;
    for (b, m) in member_of.iter_mut().enumerate() {
        if let Some(c) = *m {
            let c = c as usize;
            let dec =
                &centroids.decoded_or(centroid_values)[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS];
            let src = &bricks[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
            let mut slack = [0f32; BRICK_VOXELS];
            centroids.voxel_slack(c, &mut slack);
            if dec
                .iter()
                .zip(src)
                .zip(slack)
                .any(|((d, s), k)| (*d as f64 - *s as f64).abs() + k as f64 > e as f64)
            {
                *m = None;
                released += 1;
            }
        }
    }
    released
}

#[cfg(test)]
mod tests {
    //! Where each payload method fails, and the guard: on generated bricks, each failure shows
    //! without the guard and is gone with it. Truth is the source values themselves.

    use super::*;
    use crate::build::{build_frame, NonFinite};
    use crate::pool::Pool;

    fn opts(format: PayloadFormat, max_error: Option<f32>, range: RangeMode) -> EncodeOptions {
        EncodeOptions {
            format,
            format_given: true,
            max_error,
            lossy_tiles: true,
            range,
            bc7_quality: Bc7Quality::Fast,
            // These tests are about the BC formats' failures; packed widths have their own.
            packed: false,
        }
    }

    /// Max |decoded − source| per pool brick.
    fn errors(pool: &[f32], enc: &Encoded) -> Vec<f32> {
        pool.chunks(BRICK_VOXELS)
            .zip(enc.decoded_or(pool).chunks(BRICK_VOXELS))
            .map(|(s, d)| {
                s.iter()
                    .zip(d)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f32::max)
            })
            .collect()
    }

    fn brick(f: impl Fn(usize, usize, usize) -> f32) -> Vec<f32> {
        let mut v = vec![0f32; BRICK_VOXELS];
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..8 {
                    v[vox_index(x, y, z)] = f(x, y, z);
                }
            }
        }
        v
    }

    #[test]
    fn faint_gradient_fails_under_global_unorm8_and_per_brick_range_fixes_it() {
        // A dense brick near 1 beside a faint one (1e-3 .. 1e-2), like the top of a fire.
        let dense = brick(|x, y, z| 0.9 + 0.1 * ((x + y + z) as f32 / 21.0));
        let faint = brick(|x, y, z| 1e-3 + 9e-3 * ((x * 64 + y * 8 + z) as f32 / 511.0));
        let pool: Vec<f32> = dense.iter().chain(&faint).copied().collect();
        let rel = |enc: &Encoded| {
            faint
                .iter()
                .zip(&enc.decoded[BRICK_VOXELS..])
                .map(|(s, d)| (d - s).abs() / s)
                .fold(0.0, f32::max)
        };
        let global = encode(&pool, &opts(PayloadFormat::Unorm8, None, RangeMode::Global)).unwrap();
        assert!(
            rel(&global) > 0.2,
            "global-range unorm8 should lose the faint brick (relative error {})",
            rel(&global)
        );
        let per_brick =
            encode(&pool, &opts(PayloadFormat::Unorm8, None, RangeMode::Brick)).unwrap();
        assert!(
            rel(&per_brick) < 0.02,
            "per-brick range keeps it (relative error {})",
            rel(&per_brick)
        );
        // The error bound is the guard even with a global range: the faint brick falls back.
        let guarded = encode(
            &pool,
            &opts(PayloadFormat::Unorm8, Some(1e-5), RangeMode::Global),
        )
        .unwrap();
        assert!(errors(&pool, &guarded).iter().all(|&e| e <= 1e-5));
    }

    #[test]
    fn spikes_break_bc7_and_max_error_falls_back_for_exactly_those_bricks() {
        let smooth = |k: usize| brick(move |x, y, z| 0.3 + 0.02 * (x + y + z + k) as f32);
        let spiky = |k: usize| {
            brick(move |x, y, z| {
                if (x * 7 + y * 3 + z + k).is_multiple_of(37) {
                    1.0
                } else {
                    0.0
                }
            })
        };
        let kinds = [false, true, false, true, false, false, true, false];
        let pool: Vec<f32> = kinds
            .iter()
            .enumerate()
            .flat_map(|(k, &s)| if s { spiky(k) } else { smooth(k) })
            .collect();
        let e = 0.02f32;
        let bc7 = encode(&pool, &opts(PayloadFormat::Bc7, None, RangeMode::Brick)).unwrap();
        let errs = errors(&pool, &bc7);
        let worst_spiky = kinds
            .iter()
            .zip(&errs)
            .filter(|(s, _)| **s)
            .map(|(_, e)| *e)
            .fold(0.0, f32::max);
        assert!(
            worst_spiky > 10.0 * e,
            "isolated spikes should break BC7 (error {worst_spiky})"
        );
        let guarded = encode(&pool, &opts(PayloadFormat::Bc7, Some(e), RangeMode::Brick)).unwrap();
        let errs = errors(&pool, &guarded);
        assert!(
            errs.iter().all(|&x| x <= e),
            "every voxel within E: {errs:?}"
        );
        // Exactly the bricks BC7 cannot hold within E fall back; every smooth brick stays BC7.
        let unguarded = errors(&pool, &bc7);
        let n_bc7 = guarded.brick_counts[PayloadFormat::Bc7.rank()] as u32;
        let mut fell_back = 0;
        for (b, &s) in kinds.iter().enumerate() {
            let in_bc7 = guarded.remap[b] & TILE_BIT == 0 && guarded.remap[b] < n_bc7;
            // Within E as a GPU may read it: the CPU decode's error plus BC7's native slack.
            let q = range_of(&pool[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]);
            assert_eq!(
                in_bc7,
                unguarded[b] + payload::native_read_slack(PayloadFormat::Bc7, q) <= e,
                "brick {b} (spiky: {s}, BC7 error {})",
                unguarded[b]
            );
            assert!(s || in_bc7, "smooth brick {b} left BC7");
            fell_back += !in_bc7 as usize;
        }
        assert!(fell_back > 0);
    }

    #[test]
    fn bc4_must_fit_as_any_gpu_reads_it_not_only_as_the_cpu_decodes_it() {
        // A smooth ramp over 0.2: BC4's CPU decode is close, but a GPU may read each
        // block's texels up to its read slack off it (`payload::bc4_block_read_codes`: at least
        // one code of the brick's range, 0.0008). A budget the CPU decode meets but the GPU's may
        // not must move the brick out of BC4; the bound with the slack keeps it.
        let ramp = brick(|x, y, z| 0.2 * (x * 64 + y * 8 + z) as f32 / 511.0);
        let plain = encode(&ramp, &opts(PayloadFormat::Bc4, None, RangeMode::Brick)).unwrap();
        let mut slack = [0f32; BRICK_VOXELS];
        plain.voxel_slack(0, &mut slack);
        let decoded = plain.decoded_or(&ramp);
        let cpu = errors(&ramp, &plain)[0];
        let any_gpu = (0..BRICK_VOXELS)
            .map(|v| (decoded[v] - ramp[v]).abs() + slack[v])
            .fold(0.0, f32::max);
        assert!(
            slack.iter().all(|&k| k >= 0.2 / 255.0),
            "every voxel keeps a code of slack"
        );
        assert!(slack.iter().all(|&k| k <= plain.brick_slack(0)));
        assert!(cpu > 0.0 && any_gpu > cpu, "cpu {cpu}, any gpu {any_gpu}");
        let g = encode(
            &ramp,
            &opts(PayloadFormat::Bc4, Some(cpu), RangeMode::Brick),
        )
        .unwrap();
        assert_eq!(
            g.brick_counts[PayloadFormat::Bc4.rank()],
            0,
            "the CPU decode ({cpu}) meets its own error, a GPU's read ({any_gpu}) may not: not BC4"
        );
        assert!(errors(&ramp, &g)[0] + g.brick_slack(0) <= cpu);
        let roomy = any_gpu * (1.0 + 1e-6);
        let k = encode(
            &ramp,
            &opts(PayloadFormat::Bc4, Some(roomy), RangeMode::Brick),
        )
        .unwrap();
        assert_eq!(k.brick_counts[PayloadFormat::Bc4.rank()], 1);
        assert_eq!(k.payloads, plain.payloads);
    }

    #[test]
    fn bc7_smears_sharp_edges_and_the_budget_holds_while_smooth_bricks_stay_bc7() {
        // An oblique step 0 → 1 through the brick (a smoke front, a flame boundary): BC7 shares
        // endpoints across 4×4 texels of four z-voxels each, so an edge crossing a texel's four
        // channels cannot be fitted; smooth bricks beside it are fine.
        let edge = |k: usize| brick(move |x, y, z| ((x + 2 * y + 3 * z + k) > 12) as u8 as f32);
        let smooth = |k: usize| brick(move |x, y, z| 0.4 + 0.01 * (x + y + z + k) as f32);
        let pool: Vec<f32> = (0..6)
            .flat_map(|k| if k % 2 == 0 { edge(k) } else { smooth(k) })
            .collect();
        let e = 0.05f32;
        let plain = encode(&pool, &opts(PayloadFormat::Bc7, None, RangeMode::Brick)).unwrap();
        let errs = errors(&pool, &plain);
        let worst_edge = (0..6).step_by(2).map(|b| errs[b]).fold(0.0, f32::max);
        assert!(
            worst_edge > e,
            "BC7 should smear the edge (error {worst_edge})"
        );
        let g = encode(&pool, &opts(PayloadFormat::Bc7, Some(e), RangeMode::Brick)).unwrap();
        let ge = errors(&pool, &g);
        for (b, err) in ge.iter().enumerate() {
            let slack = g.brick_slack(b);
            assert!(err + slack <= e, "brick {b}: {err} + {slack}");
        }
        // The smooth bricks stay BC7.
        let n_bc7 = g.brick_counts[PayloadFormat::Bc7.rank()] as u32;
        for b in (1..6).step_by(2) {
            assert!(
                g.remap[b] & TILE_BIT != 0 || g.remap[b] < n_bc7,
                "smooth {b} left BC7"
            );
        }
    }

    #[test]
    fn bc4_over_a_tiny_range_far_from_zero_meets_f32_resolution() {
        // Values 1000 + tiny steps: the brick range (≈ 5e-4) is a few f32 ulps of 1000 (6.1e-5).
        // Whatever BC4's CPU decode lands on, a GPU may read a code of that range (2e-6) off it,
        // so under a budget below that the brick leaves BC4 (here for unorm8, whose 255 levels
        // land on the source's f32 values exactly).
        let v = brick(|x, y, z| 1000.0 + 6.1035156e-5 * ((x + y + z) % 9) as f32);
        let plain = encode(&v, &opts(PayloadFormat::Bc4, None, RangeMode::Brick)).unwrap();
        let [lo, hi] = range_of(&v);
        assert!(hi > lo && plain.brick_slack(0) >= (hi - lo) / 255.0);
        let e = 1e-6f32;
        let g = encode(&v, &opts(PayloadFormat::Bc4, Some(e), RangeMode::Brick)).unwrap();
        assert_eq!(g.brick_counts[PayloadFormat::Bc4.rank()], 0);
        assert!(
            errors(&v, &g)[0] + g.brick_slack(0) <= e,
            "{}",
            errors(&v, &g)[0]
        );
    }

    #[test]
    fn clustering_high_variance_bricks_is_blocky_and_the_guard_releases_them() {
        // Noisy bricks around different means, clustered with a threshold that admits them all:
        // members land far from their centroid. The guard releases exactly the members whose
        // decoded centroid (plus its GPU slack) misses E; the rest are within E.
        let mut pool = Vec::new();
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        for b in 0..24 {
            let mean = 0.2 + 0.6 * (b % 4) as f32 / 3.0;
            pool.extend((0..BRICK_VOXELS).map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                mean + 0.3 * ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5)
            }));
        }
        let copts = crate::cluster::ClusterOptions {
            clusters: 3,
            iterations: 5,
            variance_threshold: 10.0,
            seed: 1,
        };
        let r = crate::cluster::cluster(&pool, &copts);
        let e = 0.05f32;
        let o = opts(PayloadFormat::Bc7, Some(e), RangeMode::Brick);
        let ce = encode(&r.centroids, &o).unwrap();
        let cen = ce.decoded_or(&r.centroids);
        let miss = |b: usize, c: u32| {
            let c = c as usize;
            pool[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]
                .iter()
                .zip(&cen[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS])
                .map(|(s, d)| (s - d).abs() + ce.brick_slack(c))
                .fold(0.0, f32::max)
        };
        let worst = (0..24)
            .filter_map(|b| r.member_of[b].map(|c| miss(b, c)))
            .fold(0.0, f32::max);
        assert!(
            worst > 4.0 * e,
            "unguarded clustering should be blocky ({worst})"
        );
        let mut member_of = r.member_of.clone();
        let released = guard_members(&pool, &r.centroids, &ce, &mut member_of, &o);
        assert!(released > 0);
        for (b, (&before, &after)) in r.member_of.iter().zip(&member_of).enumerate() {
            match (before, after) {
                (Some(c), Some(_)) => assert!(miss(b, c) <= e, "kept member {b}: {}", miss(b, c)),
                (Some(c), None) => assert!(miss(b, c) > e, "released member {b} was within E"),
                _ => {}
            }
        }
    }

    #[test]
    fn values_outside_0_1_decode_in_source_units() {
        let v = brick(|x, y, z| -5.0 + 39.0 * ((x + 2 * y + 3 * z) as f32 / 42.0));
        let (lo, hi) = (-5.0f32, 34.0f32);
        for (f, tol) in [
            (PayloadFormat::F32, 0.0),
            (PayloadFormat::F16, 0.02),
            (PayloadFormat::Unorm8, (hi - lo) / 510.0 + 1e-4),
            (PayloadFormat::Bc4, (hi - lo) * 4.5 / 255.0),
            (PayloadFormat::Bc7, (hi - lo) * 6.0 / 255.0),
        ] {
            let enc = encode(&v, &opts(f, None, RangeMode::Brick)).unwrap();
            let err = errors(&v, &enc)[0];
            assert!(err <= tol, "{}: error {err} > {tol}", f.name());
            let mean = |s: &[f32]| s.iter().map(|&x| x as f64).sum::<f64>() / s.len() as f64;
            assert!(
                (mean(enc.decoded_or(&v)) - mean(&v)).abs() < tol as f64 + 1e-6,
                "{}: mean shifted",
                f.name()
            );
            let (dlo, dhi) = enc
                .decoded_or(&v)
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
            assert!(
                dlo < -4.0 && dhi > 33.0,
                "{}: decoded range {dlo}..{dhi}",
                f.name()
            );
        }
    }

    #[test]
    fn constant_bricks_cost_no_atlas_space_in_any_format() {
        use vdbcook_vdb::{FloatGrid, Leaf, MapKind, Tile, TileLevel, Transform};
        let grid = || FloatGrid {
            background: 0.0,
            leaves: vec![
                Leaf {
                    origin: [0, 0, 0],
                    mask: [u64::MAX; 8],
                },
                Leaf {
                    origin: [8, 0, 0],
                    mask: [u64::MAX; 8],
                },
            ],
            values: [
                vec![0.25f32; 512],
                (0..512).map(|i| i as f32 / 512.0).collect(),
            ]
            .concat(),
            tiles: vec![Tile {
                origin: [16, 0, 0],
                level: TileLevel::L8,
                value: 0.5,
                active: true,
            }],
            transform: Transform {
                kind: MapKind::UniformScale,
                index_to_world: [
                    [1.0, 0.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0, 0.0],
                    [0.0, 0.0, 1.0, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                ],
                frustum: None,
            },
            converted_from_double: false,
        };
        for f in PayloadFormat::ORDER {
            let mut pool = Pool::new(1, true);
            pool.add_frame(&[Some(
                build_frame(
                    grid(),
                    NonFinite {
                        replace_with: None,
                        hint: true,
                    },
                    false,
                )
                .unwrap(),
            )]);
            // One real brick (the ramp); the constant leaf and the tile are tile values.
            assert_eq!(pool.brick_count(), 1, "{}", f.name());
            assert_eq!(pool.tiles.len(), 2);
            let enc = encode(&pool.bricks, &opts(f, None, RangeMode::Brick)).unwrap();
            let bytes: usize = enc.payloads.iter().map(|p| p.len()).sum();
            assert_eq!(
                bytes,
                f.bytes_per_brick(),
                "{}: only the ramp brick takes atlas space",
                f.name()
            );
        }
    }

    /// A brick whose 512 values take `levels` distinct values `lo + k·step`, scattered.
    fn levelled(levels: u32, lo: f32, step: f32) -> Vec<f32> {
        brick(|x, y, z| lo + step * ((x * 5 + y * 3 + z * 7 + x * y * z) as u32 % levels) as f32)
    }

    #[test]
    fn packed_widths_store_each_brick_at_the_fewest_bits_that_hold_the_bound() {
        // Two levels need one bit, 4 levels two, 16 levels (at k/15: packed4 codes 17k) four,
        // whatever the offset; 8 levels three (their codes round(255k/7) are within half a code
        // of k/7). Random-looking level patterns defeat BC7's and BC4's 4×4 palettes.
        let e = 0.0025;
        let cases = [
            (levelled(2, 3.0, 1.0), PayloadFormat::Packed1),
            (levelled(4, -1.0, 0.5), PayloadFormat::Packed2),
            (levelled(8, 0.0, 1.0 / 7.0), PayloadFormat::Packed3),
            (levelled(16, 0.0, 1.0 / 15.0), PayloadFormat::Packed4),
        ];
        let pool: Vec<f32> = cases.iter().flat_map(|(v, _)| v.clone()).collect();
        let mut o = opts(PayloadFormat::Bc7, Some(e), RangeMode::Brick);
        o.format_given = false;
        o.packed = true;
        let enc = encode(&pool, &o).unwrap();
        for (b, (_, want)) in cases.iter().enumerate() {
            let (f, _) = vdbcook_asset::locate_brick(&enc.brick_counts, enc.remap[b] as u64)
                .expect("stored");
            assert_eq!(f, *want, "brick {b}");
        }
        let worst = errors(&pool, &enc).into_iter().fold(0.0, f32::max);
        assert!(worst <= e, "max error {worst} over {e}");
        // Packed decodes are exact on any GPU: no read slack is added.
        assert!((0..cases.len()).all(|b| enc.brick_slack(b) == 0.0));
        // `--no-packed` keeps to the older formats, within the same bound.
        o.packed = false;
        let old = encode(&pool, &o).unwrap();
        assert!(PayloadFormat::PACKED
            .iter()
            .all(|f| old.brick_counts[f.rank()] == 0));
        let worst = errors(&pool, &old).into_iter().fold(0.0, f32::max);
        assert!(worst <= e, "max error {worst} over {e} without packed");
        let bytes = |x: &Encoded| x.payloads.iter().map(|p| p.len()).sum::<usize>();
        assert!(
            bytes(&enc) < bytes(&old),
            "{} !< {}",
            bytes(&enc),
            bytes(&old)
        );
    }
}

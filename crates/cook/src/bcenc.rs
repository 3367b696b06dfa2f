//! BC4 / BC7 block encoders for the payload's texture formats, on top of Intel's ISPC texture
//! compressor (`intel_tex_2`, prebuilt kernels, one thread per call).
//!
//! The cooker compresses large atlases, so a surface is cut into horizontal strips of whole block
//! rows and each strip is compressed by its own call on the rayon pool. Strip boundaries depend
//! only on the surface width (never on the thread count) and every block is encoded from its own
//! 16 texels, so the output is the same bytes whatever the pool size.
//!
//! Output is block-row-major: block `(bx, by)` starts at `(by * width / 4 + bx) * block_bytes`.

use intel_tex_2::{bc4, bc7, RSurface, RgbaSurface};
use rayon::prelude::*;

/// BC7 encoder effort, fastest first (`intel_tex_2`'s alpha profiles: all four channels carry data).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bc7Quality {
    UltraFast,
    VeryFast,
    Fast,
    Basic,
    Slow,
}

impl Bc7Quality {
    pub const ALL: [Bc7Quality; 5] = [
        Bc7Quality::UltraFast,
        Bc7Quality::VeryFast,
        Bc7Quality::Fast,
        Bc7Quality::Basic,
        Bc7Quality::Slow,
    ];

    /// Parses a name as printed by [`Bc7Quality::name`] (case-insensitive, `_` accepted for `-`).
    pub fn parse(s: &str) -> Option<Self> {
        let wanted = s.trim().to_ascii_lowercase().replace('_', "-");
        Self::ALL.into_iter().find(|q| q.name() == wanted)
    }

    pub fn name(self) -> &'static str {
        match self {
            Bc7Quality::UltraFast => "ultra-fast",
            Bc7Quality::VeryFast => "very-fast",
            Bc7Quality::Fast => "fast",
            Bc7Quality::Basic => "basic",
            Bc7Quality::Slow => "slow",
        }
    }

    fn settings(self) -> bc7::EncodeSettings {
        match self {
            Bc7Quality::UltraFast => bc7::alpha_ultra_fast_settings(),
            Bc7Quality::VeryFast => bc7::alpha_very_fast_settings(),
            Bc7Quality::Fast => bc7::alpha_fast_settings(),
            Bc7Quality::Basic => bc7::alpha_basic_settings(),
            Bc7Quality::Slow => bc7::alpha_slow_settings(),
        }
    }
}

const BC4_BLOCK_BYTES: usize = 8;
const BC7_BLOCK_BYTES: usize = 16;
/// Blocks per strip: enough work per call to hide the task overhead, small enough to balance.
const BC4_STRIP_BLOCKS: usize = 4096;
const BC7_STRIP_BLOCKS: usize = 256;

fn check_surface(width: u32, height: u32, len: usize, channels: usize) {
    assert!(
        width.is_multiple_of(4) && height.is_multiple_of(4),
        "BC surfaces need sizes that are multiples of 4, got {width}x{height}"
    );
    assert_eq!(
        len,
        width as usize * height as usize * channels,
        "texel buffer does not match a {width}x{height} surface with {channels} channel(s)"
    );
}

/// Runs `compress(strip_texels, strip_height, strip_output)` over strips of whole block rows.
/// Called with (blocks announced, blocks done) as strips are compressed, when set (the CLI's
/// progress display).
pub static PROGRESS_HOOK: std::sync::OnceLock<fn(u64, u64)> = std::sync::OnceLock::new();

fn encode_strips(
    width: u32,
    height: u32,
    texels: &[u8],
    channels: usize,
    block_bytes: usize,
    strip_blocks: usize,
    compress: impl Fn(&[u8], u32, &mut [u8]) + Sync,
) -> Vec<u8> {
    let blocks_x = width as usize / 4;
    let blocks_y = height as usize / 4;
    let mut out = vec![0u8; blocks_x * blocks_y * block_bytes];
    if out.is_empty() {
        return out;
    }
    if let Some(hook) = PROGRESS_HOOK.get() {
        hook((blocks_x * blocks_y) as u64, 0);
    }
    let strip_rows = (strip_blocks / blocks_x).max(1);
    let row_texel_bytes = 4 * width as usize * channels;
    out.par_chunks_mut(strip_rows * blocks_x * block_bytes)
        .enumerate()
        .for_each(|(strip, dst)| {
            let rows = dst.len() / (blocks_x * block_bytes);
            let start = strip * strip_rows * row_texel_bytes;
            let src = &texels[start..start + rows * row_texel_bytes];
            compress(src, 4 * rows as u32, dst);
            if let Some(hook) = PROGRESS_HOOK.get() {
                hook(0, (rows * blocks_x) as u64);
            }
        });
    out
}

/// R8 surface (width, height multiples of 4, row-major) -> BC4 blocks, block-row-major.
pub fn encode_bc4_intel(width: u32, height: u32, texels: &[u8]) -> Vec<u8> {
    check_surface(width, height, texels.len(), 1);
    encode_strips(
        width,
        height,
        texels,
        1,
        BC4_BLOCK_BYTES,
        BC4_STRIP_BLOCKS,
        |data, rows, dst| {
            let surface = RSurface {
                data,
                width,
                height: rows,
                stride: width,
            };
            bc4::compress_blocks_into(&surface, dst);
        },
    )
}

/// RGBA8 surface -> BC7 blocks, block-row-major.
pub fn encode_bc7(width: u32, height: u32, rgba: &[u8], quality: Bc7Quality) -> Vec<u8> {
    check_surface(width, height, rgba.len(), 4);
    let settings = quality.settings();
    encode_strips(
        width,
        height,
        rgba,
        4,
        BC7_BLOCK_BYTES,
        BC7_STRIP_BLOCKS,
        |data, rows, dst| {
            let surface = RgbaSurface {
                data,
                width,
                height: rows,
                stride: width * 4,
            };
            bc7::compress_blocks_into(&settings, &surface, dst);
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use vdbcook_asset::bc::{decode_bc4_block, decode_bc7_block};

    /// Decodes a BC4 surface back to R8 with the asset crate's decoder.
    fn decode_bc4(width: u32, height: u32, blocks: &[u8]) -> Vec<u8> {
        let (w, bx) = (width as usize, width as usize / 4);
        let mut out = vec![0u8; w * height as usize];
        for (i, block) in blocks.chunks_exact(8).enumerate() {
            let texels = decode_bc4_block(block.try_into().unwrap());
            let (x0, y0) = (4 * (i % bx), 4 * (i / bx));
            for (t, &v) in texels.iter().enumerate() {
                out[(y0 + t / 4) * w + x0 + t % 4] = v;
            }
        }
        out
    }

    fn decode_bc7(width: u32, height: u32, blocks: &[u8]) -> Vec<u8> {
        let (w, bx) = (width as usize, width as usize / 4);
        let mut out = vec![0u8; 4 * w * height as usize];
        for (i, block) in blocks.chunks_exact(16).enumerate() {
            let texels = decode_bc7_block(block.try_into().unwrap());
            let (x0, y0) = (4 * (i % bx), 4 * (i / bx));
            for (t, rgba) in texels.iter().enumerate() {
                let at = 4 * ((y0 + t / 4) * w + x0 + t % 4);
                out[at..at + 4].copy_from_slice(rgba);
            }
        }
        out
    }

    fn max_abs_error(a: &[u8], b: &[u8]) -> u8 {
        a.iter().zip(b).map(|(x, y)| x.abs_diff(*y)).max().unwrap()
    }

    fn mean_abs_error(a: &[u8], b: &[u8]) -> f64 {
        let sum: u64 = a
            .iter()
            .zip(b)
            .map(|(x, y)| u64::from(x.abs_diff(*y)))
            .sum();
        sum as f64 / a.len() as f64
    }

    // The test kit's seeded xorshift64*.
    use vdbcook_testkit::XorShift as Rng;

    fn noise(len: usize, seed: u64) -> Vec<u8> {
        let mut rng = Rng(seed);
        (0..len).map(|_| rng.byte()).collect()
    }

    /// Linear ramp: each 4x4 block spans at most a few units, so BC4's 8-value palette fits it.
    fn ramp_r8(width: u32, height: u32) -> Vec<u8> {
        let (w, h) = (width as usize, height as usize);
        let mut v = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                v.push(((x + 2 * y) * 255 / (w + 2 * h - 3)) as u8);
            }
        }
        v
    }

    /// A smooth density-like field in [0, 1] (sums of low-frequency waves).
    fn density(x: f64, y: f64, z: f64) -> f64 {
        let tau = std::f64::consts::TAU;
        let s = 0.5
            + 0.25 * (tau * (x / 97.0 + 0.1)).sin() * (tau * (y / 61.0)).cos()
            + 0.15 * (tau * (z / 53.0 + y / 173.0)).sin()
            + 0.08 * (tau * (x / 29.0 - z / 37.0)).cos();
        s.clamp(0.0, 1.0)
    }

    /// Smooth RGBA as the asset packs it: channel c is z-slice c of a smooth density field.
    fn smooth_rgba(width: u32, height: u32) -> Vec<u8> {
        let (w, h) = (width as usize, height as usize);
        let mut v = Vec::with_capacity(4 * w * h);
        for y in 0..h {
            for x in 0..w {
                for z in 0..4 {
                    let d = density(x as f64, y as f64, z as f64);
                    v.push((d * 255.0).round() as u8);
                }
            }
        }
        v
    }

    fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(f)
    }

    #[test]
    fn quality_names_round_trip() {
        for q in Bc7Quality::ALL {
            assert_eq!(Bc7Quality::parse(q.name()), Some(q));
        }
        assert_eq!(Bc7Quality::parse("ULTRA_FAST"), Some(Bc7Quality::UltraFast));
        assert_eq!(Bc7Quality::parse("Very-Fast"), Some(Bc7Quality::VeryFast));
        assert_eq!(Bc7Quality::parse("medium"), None);
        assert_eq!(Bc7Quality::parse(""), None);
    }

    #[test]
    fn output_sizes_and_empty_surfaces() {
        assert_eq!(encode_bc4_intel(8, 12, &[7; 96]).len(), 6 * 8);
        assert_eq!(
            encode_bc7(8, 12, &[7; 384], Bc7Quality::UltraFast).len(),
            6 * 16
        );
        assert!(encode_bc4_intel(0, 8, &[]).is_empty());
        assert!(encode_bc7(8, 0, &[], Bc7Quality::Fast).is_empty());
    }

    #[test]
    #[should_panic(expected = "multiples of 4")]
    fn rejects_unaligned_sizes() {
        encode_bc4_intel(6, 4, &[0; 24]);
    }

    #[test]
    fn bc4_constant_blocks_are_exact() {
        for v in [0u8, 1, 77, 128, 254, 255] {
            let data = vec![v; 16 * 16];
            let decoded = decode_bc4(16, 16, &encode_bc4_intel(16, 16, &data));
            assert_eq!(decoded, data, "constant {v}");
        }
    }

    #[test]
    fn bc4_linear_ramp_within_two_units() {
        // 256 x 64: each block spans at most (3 + 2·3)·255/381 ≈ 6 units, so palette steps are
        // under one unit apart and the decoded value must be within 2/255 of the source.
        let (w, h) = (256, 64);
        let src = ramp_r8(w, h);
        let decoded = decode_bc4(w, h, &encode_bc4_intel(w, h, &src));
        assert!(max_abs_error(&src, &decoded) <= 2);
    }

    #[test]
    fn bc4_noise_error_is_bounded() {
        // White noise: each block spans about the full range, so the palette step is ≈ 255/7 and
        // the best index is within half a step (18); the mean must be far below that.
        let (w, h) = (64, 64);
        let src = noise(64 * 64, 1);
        let decoded = decode_bc4(w, h, &encode_bc4_intel(w, h, &src));
        assert!(max_abs_error(&src, &decoded) <= 19);
        assert!(mean_abs_error(&src, &decoded) < 10.0);
    }

    #[test]
    fn bc7_constant_blocks_are_near_exact() {
        for rgba in [[0u8, 0, 0, 0], [255, 255, 255, 255], [12, 200, 77, 130]] {
            let data: Vec<u8> = rgba.repeat(16 * 16);
            for q in [Bc7Quality::UltraFast, Bc7Quality::Basic] {
                let decoded = decode_bc7(16, 16, &encode_bc7(16, 16, &data, q));
                assert!(max_abs_error(&data, &decoded) <= 1, "{rgba:?} {q:?}");
            }
        }
    }

    #[test]
    fn bc7_smooth_rgba_within_a_few_units() {
        let (w, h) = (128, 64);
        let src = smooth_rgba(w, h);
        for q in Bc7Quality::ALL {
            let decoded = decode_bc7(w, h, &encode_bc7(w, h, &src, q));
            let (max, mean) = (
                max_abs_error(&src, &decoded),
                mean_abs_error(&src, &decoded),
            );
            assert!(max <= 4, "{q:?}: max error {max}");
            assert!(mean < 1.0, "{q:?}: mean error {mean}");
        }
    }

    #[test]
    fn bc7_noise_error_is_bounded() {
        // Independent noise in 4 channels is BC7's worst case; the error stays well under the
        // mean error of a constant guess (≈ 64) and the encoder's own choice must be honoured by
        // the decoder (a misread mode, partition or index would send the mean far higher).
        let (w, h) = (32, 32);
        let src = noise(4 * 32 * 32, 2);
        for q in [Bc7Quality::UltraFast, Bc7Quality::Basic] {
            let decoded = decode_bc7(w, h, &encode_bc7(w, h, &src, q));
            let mean = mean_abs_error(&src, &decoded);
            assert!(mean < 40.0, "{q:?}: mean error {mean}");
        }
    }

    #[test]
    fn bc7_decoder_matches_encoder_on_every_mode() {
        // Each 4x4 block gets its own character (flat, two-colour edge, three regions, ramps in
        // different channels, alpha-only detail), so the encoder picks a spread of modes and
        // partitions. The error the decoder sees must be small for every block: a decoder that
        // misreads a mode's layout produces large errors on the blocks of that mode.
        let (w, h) = (64u32, 64u32);
        let mut rng = Rng(3);
        let mut src = vec![0u8; 4 * 64 * 64];
        for by in 0..16usize {
            for bx in 0..16usize {
                let kind = (by * 16 + bx) % 6;
                let colors: Vec<[u8; 4]> = (0..3)
                    .map(|_| [rng.byte(), rng.byte(), rng.byte(), rng.byte()])
                    .collect();
                let split = rng.next_u64() % 4;
                for t in 0..16usize {
                    let (x, y) = (t % 4, t / 4);
                    let px: [u8; 4] = match kind {
                        0 => colors[0],
                        1 => colors[usize::from((x + y) as u64 > split + 1)],
                        2 => colors[(x * 3 / 4 + y * 3 / 4) % 3],
                        3 => {
                            let f = (x + 4 * y) as u32;
                            let mut c = colors[0];
                            c[0] = (u32::from(c[0]) * (15 - f) / 15 + 255 * f / 15) as u8;
                            c
                        }
                        4 => {
                            let mut c = colors[1];
                            c[3] = (x * 60 + y * 5) as u8;
                            c
                        }
                        _ => {
                            let f = (x + y) as u32;
                            let lerp = |a: u8, b: u8| {
                                ((u32::from(a) * (6 - f) + u32::from(b) * f) / 6) as u8
                            };
                            let (a, b) = (colors[0], colors[2]);
                            [
                                lerp(a[0], b[0]),
                                lerp(a[1], b[1]),
                                lerp(a[2], b[2]),
                                lerp(a[3], b[3]),
                            ]
                        }
                    };
                    let at = 4 * ((4 * by + y) * 64 + 4 * bx + x);
                    src[at..at + 4].copy_from_slice(&px);
                }
            }
        }
        let mut modes_seen = [0usize; 9];
        for q in Bc7Quality::ALL {
            let blocks = encode_bc7(w, h, &src, q);
            for b in blocks.chunks_exact(16) {
                modes_seen[(b[0].trailing_zeros() as usize).min(8)] += 1;
            }
            let decoded = decode_bc7(w, h, &blocks);
            let mean = mean_abs_error(&src, &decoded);
            // Per block kind, the worst texel error.
            let mut kind_max = [0u8; 6];
            for (i, (a, b)) in src.chunks_exact(4).zip(decoded.chunks_exact(4)).enumerate() {
                let (bx, by) = ((i % 64) / 4, i / 64 / 4);
                let kind = (by * 16 + bx) % 6;
                kind_max[kind] = kind_max[kind].max(max_abs_error(a, b));
            }
            assert!(mean < 6.0, "{q:?}: mean error {mean}");
            // Flat and two-region blocks fit one / two subsets up to endpoint quantization;
            // ramps fit a line up to the index weights (k/6 vs w/64: ≤ 7 units). Three RGBA
            // regions (kind 2) have no exact mode with alpha, so they only count in the mean.
            let bound = [2, 2, u8::MAX, 4, 8, 10];
            for kind in 0..6 {
                assert!(
                    kind_max[kind] <= bound[kind],
                    "{q:?}: kind {kind} max error {} ({kind_max:?})",
                    kind_max[kind]
                );
            }
        }
        assert_eq!(modes_seen[8], 0, "encoder wrote reserved blocks");
        let used = modes_seen[..8].iter().filter(|&&n| n > 0).count();
        assert!(used >= 4, "only {used} modes exercised: {modes_seen:?}");
    }

    #[test]
    fn bc7_decoder_matches_encoder_on_opaque_modes() {
        // The alpha profiles never choose the colour-only modes 0-3 (0 and 2 have 3 subsets);
        // the encoder's opaque profile does, on busy RGB blocks. Per mode, the decoded error must
        // be that of a real fit: independent noise differs from a wrong guess by ≈ 85 on average,
        // a 3-subset fit of 16 noisy texels gets far below that.
        let (w, h) = (64u32, 64u32);
        let mut src = noise(4 * 64 * 64, 8);
        for px in src.chunks_exact_mut(4) {
            px[3] = 255;
        }
        let blocks = bc7::compress_blocks(
            &bc7::opaque_slow_settings(),
            &RgbaSurface {
                data: &src,
                width: w,
                height: h,
                stride: 4 * w,
            },
        );
        let decoded = decode_bc7(w, h, &blocks);
        // Per mode: (blocks, summed error over RGB).
        let mut per_mode = [(0usize, 0u64); 9];
        for (i, b) in blocks.chunks_exact(16).enumerate() {
            let m = (b[0].trailing_zeros() as usize).min(8);
            let (x0, y0) = (4 * (i % 16), 4 * (i / 16));
            per_mode[m].0 += 1;
            for t in 0..16 {
                let at = 4 * ((y0 + t / 4) * 64 + x0 + t % 4);
                for c in 0..3 {
                    per_mode[m].1 += u64::from(src[at + c].abs_diff(decoded[at + c]));
                }
            }
        }
        assert!(
            per_mode[0].0 > 0 && per_mode[2].0 > 0,
            "modes 0/2 not exercised: {per_mode:?}"
        );
        assert_eq!(per_mode[8].0, 0);
        for (m, &(n, sum)) in per_mode.iter().enumerate().filter(|(_, p)| p.0 > 0) {
            let mean = sum as f64 / (n * 48) as f64;
            assert!(mean < 25.0, "mode {m}: mean error {mean} over {n} blocks");
        }
        assert!(decoded.chunks_exact(4).all(|p| p[3] == 255));
    }

    #[test]
    fn strips_match_one_whole_surface_call() {
        // Cutting into strips must not change any block: compare with one call over the surface.
        // 1024 wide: BC4 strips are 16 block rows, BC7 strips 1 block row; 200 rows leave a
        // partial last BC4 strip.
        let (w, h) = (1024, 200);
        let r8 = noise(1024 * 200, 4);
        let whole = bc4::compress_blocks(&RSurface {
            data: &r8,
            width: w,
            height: h,
            stride: w,
        });
        assert_eq!(encode_bc4_intel(w, h, &r8), whole);

        let rgba = smooth_rgba(w, h);
        let q = Bc7Quality::VeryFast;
        let whole = bc7::compress_blocks(
            &q.settings(),
            &RgbaSurface {
                data: &rgba,
                width: w,
                height: h,
                stride: 4 * w,
            },
        );
        assert_eq!(encode_bc7(w, h, &rgba, q), whole);
    }

    #[test]
    fn output_is_identical_for_one_and_two_threads() {
        let (w, h) = (256, 256);
        let r8 = noise(256 * 256, 5);
        let mut rgba = smooth_rgba(w, h);
        for (v, n) in rgba.iter_mut().zip(noise(4 * 256 * 256, 6)) {
            *v = v.saturating_add(n % 16);
        }
        let one = with_threads(1, || {
            (
                encode_bc4_intel(w, h, &r8),
                encode_bc7(w, h, &rgba, Bc7Quality::Fast),
            )
        });
        let two = with_threads(2, || {
            (
                encode_bc4_intel(w, h, &r8),
                encode_bc7(w, h, &rgba, Bc7Quality::Fast),
            )
        });
        assert!(one.0 == two.0, "BC4 output depends on the thread count");
        assert!(one.1 == two.1, "BC7 output depends on the thread count");
    }
}

//! The content box of a frame: the cell-space box outside which every leaf holds values `≤ 0`.
//! The sampling modes of both tracers (single scatter, delta tracking and their shadow rays)
//! clip their rays to it, so it is defined once, here, from the asset's tree and value ranges
//! alone (no payload is decoded).

use vdbcook_asset::{Asset, EMPTY, L2_SPAN, TILE_BIT};

/// The box `[lo, hi)` (cell units: voxel `i` is `[i, i+1)`) outside which every leaf of `frame`
/// holds values `≤ 0`, or `None` when there is no such leaf.
///
/// A region or leaf counts by its bound: an unstored region or leaf slot by the background, a
/// tile by its value, a brick by its `brick_ranges` max. NaN counts as content (`!(m ≤ 0)`), as
/// the walks visit NaN.
pub fn content_box(asset: &Asset, frame: usize) -> Option<([f64; 3], [f64; 3])> {
    content_box_above(asset, frame, 0, 0.0)
}

/// [`content_box`] of channel `c` with values `≤ floor` counting as nothing (an emission
/// channel's box: where it glows).
pub fn content_box_above(
    asset: &Asset,
    frame: usize,
    c: usize,
    floor: f32,
) -> Option<([f64; 3], [f64; 3])> {
    let background = asset.header.channel_background(c);
    let d = asset.header.root_dims.map(|d| d as usize);
    let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
    // Grows the box by the cube of edge `size` at `o` if its max `m` is not `≤ 0`.
    let mut grow = |o: [i64; 3], size: i64, m: f32| {
        if !(m <= floor) {
            for a in 0..3 {
                lo[a] = lo[a].min(o[a]);
                hi[a] = hi[a].max(o[a] + size);
            }
        }
    };
    let span = L2_SPAN as i64;
    for (i, &e) in asset.frame_roots(frame).iter().enumerate() {
        let r = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
        let o = r.map(|c| c as i64 * span);
        if e == EMPTY {
            grow(o, span, background);
            continue;
        }
        if e & TILE_BIT != 0 {
            grow(o, span, asset.tiles[(e & !TILE_BIT) as usize]);
            continue;
        }
        // Missing slots hold the background (mask layout: `for_each_slot_max`).
        let node = e as usize;
        for (w, &word) in asset.l2_mask(node).iter().enumerate() {
            let (z, yb) = (w / 4, w % 4);
            let leaf_origin = |bit: usize| {
                let (x, y) = (bit % 16, 4 * yb + bit / 16);
                [
                    o[0] + 8 * x as i64,
                    o[1] + 8 * y as i64,
                    o[2] + 8 * z as i64,
                ]
            };
            if !(background <= floor) {
                let mut empty = !word;
                while empty != 0 {
                    grow(leaf_origin(empty.trailing_zeros() as usize), 8, background);
                    empty &= empty - 1;
                }
            }
        }
        for_each_slot_max_c(asset, node, c, |w, bit, v| {
            let (z, yb) = (w / 4, w % 4);
            let (x, y) = (bit % 16, 4 * yb + bit / 16);
            let l = [
                o[0] + 8 * x as i64,
                o[1] + 8 * y as i64,
                o[2] + 8 * z as i64,
            ];
            grow(l, 8, v);
        });
    }
    (0..3)
        .all(|a| lo[a] < hi[a])
        .then(|| (lo.map(|c| c as f64), hi.map(|c| c as f64)))
}

/// Calls `f(w, bit, max)` for every present leaf slot of L2 node `node`, in slot order: its mask
/// word `w`, its bit in that word, and its value bound (a tile's value, a brick's
/// `brick_ranges` max). Mask word `w` holds slots `x + 16·(y + 16·z)` with `z = w / 4`,
/// `y / 4 = w % 4`, bit `x + 16·(y % 4)`; the refs follow in slot order from `l2_base[node]`.
pub fn for_each_slot_max(asset: &Asset, node: usize, f: impl FnMut(usize, usize, f32)) {
    for_each_slot_max_c(asset, node, 0, f)
}

/// [`for_each_slot_max`] of channel `c` (a slot where `c` is its background has its background
/// as the bound).
pub fn for_each_slot_max_c(
    asset: &Asset,
    node: usize,
    c: usize,
    mut f: impl FnMut(usize, usize, f32),
) {
    let nch = asset.channel_count();
    let mut k = asset.l2_base[node] as usize;
    for (w, &word) in asset.l2_mask(node).iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            let bit = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let r = asset.l3_refs[k * nch + c];
            k += 1;
            let v = if r == EMPTY {
                asset.header.channel_background(c)
            } else if r & TILE_BIT != 0 {
                asset.tiles[(r & !TILE_BIT) as usize]
            } else {
                asset.brick_ranges[r as usize][1]
            };
            f(w, bit, v);
        }
    }
}

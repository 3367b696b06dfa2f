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

/// The smallest box `[lo, hi)` holding both boxes.
pub fn box_union(a: ([f64; 3], [f64; 3]), b: ([f64; 3], [f64; 3])) -> ([f64; 3], [f64; 3]) {
    (
        [0, 1, 2].map(|k| a.0[k].min(b.0[k])),
        [0, 1, 2].map(|k| a.1[k].max(b.1[k])),
    )
}

/// The light a frame gets under a light stride of `n` (the engine drawer's
/// `Instance::light_stride`: a playing effect lit by one light volume per `n` frames): frame
/// `f` of a flip-book whose frames have the content boxes `boxes` lies in the span
/// `[k·n, k·n + n)` (cut at the last frame), lit by the light volume of the span's middle frame
/// (`k·n + (len − 1)/2`, the earlier of two middles; where that frame is empty, the nearest
/// frame of the span with content, the earlier on a tie) over the union of the span's boxes, so
/// that every frame of the span lies inside it. Returns that frame and box; `n ≤ 1` gives `f`
/// and its own box.
#[allow(clippy::type_complexity)]
pub fn light_span(
    f: usize,
    n: u32,
    boxes: &[Option<([f64; 3], [f64; 3])>],
) -> (usize, Option<([f64; 3], [f64; 3])>) {
    let n = n.max(1) as usize;
    if n == 1 || f >= boxes.len() {
        return (f, boxes.get(f).copied().flatten());
    }
    let start = f / n * n;
    let end = (start + n).min(boxes.len());
    let union = boxes[start..end]
        .iter()
        .flatten()
        .copied()
        .reduce(box_union);
    let middle = start + (end - start - 1) / 2;
    let key = (0..end - start)
        .flat_map(|d| [middle.checked_sub(d), Some(middle + d)])
        .flatten()
        .find(|&g| (start..end).contains(&g) && boxes[g].is_some())
        .unwrap_or(middle);
    (key, union)
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

#[cfg(test)]
mod tests {
    use super::light_span;

    #[test]
    fn a_light_span_is_its_middle_frame_over_its_joint_box() {
        let b = |x: f64| Some(([x, 0.0, 0.0], [x + 1.0, 2.0, 3.0]));
        let boxes = [b(0.0), b(4.0), None, b(-2.0), b(1.0), b(7.0), b(3.0)];
        // Stride 1 (and 0): the frame's own light.
        for n in [0, 1] {
            for f in 0..boxes.len() {
                assert_eq!(light_span(f, n, &boxes), (f, boxes[f]));
            }
        }
        // Stride 3: spans [0, 3), [3, 6), [6, 7); middles 1, 4, 6.
        let want = |key: usize, lo: f64, hi: f64| (key, Some(([lo, 0.0, 0.0], [hi, 2.0, 3.0])));
        for f in 0..3 {
            assert_eq!(light_span(f, 3, &boxes), want(1, 0.0, 5.0), "frame {f}");
        }
        for f in 3..6 {
            assert_eq!(light_span(f, 3, &boxes), want(4, -2.0, 8.0), "frame {f}");
        }
        assert_eq!(light_span(6, 3, &boxes), want(6, 3.0, 4.0));
        // Stride 2: the earlier middle of an even span; an empty middle frame gives way to the
        // span's frame with content (its box is the span's).
        assert_eq!(light_span(1, 2, &boxes), want(0, 0.0, 5.0));
        assert_eq!(light_span(2, 2, &boxes), want(3, -2.0, -1.0));
        // Stride 5 over [0, 5): middle 2 is empty; 1 and 3 are as near, the earlier wins.
        assert_eq!(light_span(4, 5, &boxes), want(1, -2.0, 5.0));
        // Past the asset: the frame alone, no box.
        assert_eq!(light_span(9, 2, &boxes), (9, None));
        // A stride longer than the asset: one span.
        assert_eq!(light_span(6, 100, &boxes), want(3, -2.0, 8.0));
        assert_eq!(light_span(0, 2, &[None, None]), (0, None));
    }
}

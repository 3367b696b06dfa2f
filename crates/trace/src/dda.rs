//! One level of the traversal: a 3D DDA (Amanatides & Woo) over cubic cells of one size,
//! restricted to a box of cells, between two ray parameters. The hierarchy (`walk`) nests it.
//!
//! Robustness rules (the GPU follows the same ones):
//! - the start cell is `floor(p(t0) / size)` clamped into the box, so a start point a rounding
//!   error outside its parent node still lands in it;
//! - cell boundaries are recomputed from the cell index (`(boundary − o) / d`), never accumulated,
//!   so every level computes bit-identical crossing parameters for a shared boundary;
//! - an axis the ray does not move along has its crossing at +∞ (never stepped);
//! - ties step the lowest axis first (x, then y, then z); the zero-length segment a tie leaves is
//!   not reported;
//! - segments are `[max(ta, previous end), min(crossing, t1)]`, so they never overlap or run
//!   backwards and their lengths sum to exactly `t1 − t0` when the ray stays in the box;
//! - the loop runs at most (cells across x + y + z + 3) times: a line crosses fewer boundaries.

use crate::space::IndexRay;

/// Whether a walk goes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    Go,
    Stop,
}

/// `x.floor() as i64`, without the libm call `floor` is on baseline x86-64 (same result for every
/// `x`, NaN and infinities included: `as` truncates toward zero and saturates).
#[inline(always)]
pub(crate) fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) > x {
        i.saturating_sub(1)
    } else {
        i
    }
}

/// `x.ceil()`, inlined: exact through `i64` below 2⁵² in magnitude (beyond it every float is an
/// integer already); only the sign of a zero result may differ, which no caller observes.
#[inline(always)]
pub(crate) fn ceil_f64(x: f64) -> f64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let i = x as i64;
        (i + ((i as f64) < x) as i64) as f64
    } else {
        x.ceil()
    }
}

/// Calls `f(cell, ta, tb)` for each cell of edge `size` (a power of two) in `[lo, hi)` (cell
/// coordinates) that the ray crosses for `t ∈ [t0, t1]`, in ray order, with `ta < tb`. Inlined
/// into each level of the walk, so `size` and the box are constants there.
#[inline(always)]
pub(crate) fn walk_cells(
    ray: &IndexRay,
    size: f64,
    lo: [i64; 3],
    hi: [i64; 3],
    t0: f64,
    t1: f64,
    mut f: impl FnMut([i64; 3], f64, f64) -> Flow,
) -> Flow {
    // `!(t1 > t0)` also refuses NaN.
    if !(t1 > t0) {
        return Flow::Go;
    }
    debug_assert!(size > 0.0 && (size.to_bits() & ((1u64 << 52) - 1)) == 0);
    // Exact: `size` is a power of two.
    let inv_size = 1.0 / size;
    let p = ray.at(t0);
    let mut cell = [0i64; 3];
    let mut step = [0i64; 3];
    let mut next = [f64::INFINITY; 3];
    for i in 0..3 {
        // Saturates and maps NaN to 0 (as `floor() as i64`); the clamp keeps the cell in the box.
        cell[i] = floor_i64(p[i] * inv_size).clamp(lo[i], hi[i] - 1);
        next[i] = crossing(ray, size, cell[i], i, &mut step[i]);
    }
    let budget: i64 = (hi[0] - lo[0]) + (hi[1] - lo[1]) + (hi[2] - lo[2]) + 3;
    let mut tm = t0;
    for _ in 0..budget {
        let a = if next[0] <= next[1] && next[0] <= next[2] {
            0
        } else if next[1] <= next[2] {
            1
        } else {
            2
        };
        let tn = next[a];
        // `tn.min(t1).max(tm)` without the NaN handling (`t1` and `tm` are never NaN here, and a
        // NaN `tn` gives `t1` either way).
        let te = if tn < t1 { tn } else { t1 };
        let te = if te > tm { te } else { tm };
        if te > tm && f(cell, tm, te) == Flow::Stop {
            return Flow::Stop;
        }
        if !(tn < t1) {
            break;
        }
        tm = te;
        cell[a] += step[a];
        if cell[a] < lo[a] || cell[a] >= hi[a] {
            break;
        }
        next[a] = crossing(ray, size, cell[a], a, &mut step[a]);
    }
    Flow::Go
}

/// The parameter where the ray leaves `cell` along `axis` (and the step direction).
#[inline(always)]
fn crossing(ray: &IndexRay, size: f64, cell: i64, axis: usize, step: &mut i64) -> f64 {
    let d = ray.d[axis];
    if d > 0.0 {
        *step = 1;
        ((cell + 1) as f64 * size - ray.o[axis]) * ray.inv[axis]
    } else if d < 0.0 {
        *step = -1;
        (cell as f64 * size - ray.o[axis]) * ray.inv[axis]
    } else {
        *step = 0;
        f64::INFINITY
    }
}

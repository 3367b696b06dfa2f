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

/// Calls `f(cell, ta, tb)` for each cell of edge `size` in `[lo, hi)` (cell coordinates) that
/// the ray crosses for `t ∈ [t0, t1]`, in ray order, with `ta < tb`.
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
    let p = ray.at(t0);
    let mut cell = [0i64; 3];
    let mut step = [0i64; 3];
    let mut next = [f64::INFINITY; 3];
    for i in 0..3 {
        let c = (p[i] / size).floor();
        // `as` saturates and maps NaN to 0; the clamp keeps the cell in the box.
        cell[i] = (c as i64).clamp(lo[i], hi[i] - 1);
        next[i] = crossing(ray, size, cell[i], i, &mut step[i]);
    }
    let budget: i64 = (0..3).map(|i| hi[i] - lo[i]).sum::<i64>() + 3;
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
        let te = tn.min(t1).max(tm);
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
#[inline]
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

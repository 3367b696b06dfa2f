//! Display colours of the diagnostic modes: a hue per brick index and the step-count heat map.

/// `hsv(h, s, 1)` with `h` in turns.
pub fn hue(h: f64, s: f64) -> [f32; 3] {
    let h6 = (h - h.floor()) * 6.0;
    let k = |n: f64| {
        let x = (n + h6) % 6.0;
        let c = (x.min(4.0 - x)).clamp(0.0, 1.0);
        (1.0 - s * c) as f32
    };
    [k(5.0), k(3.0), k(1.0)]
}

/// The brick-hue colour of brick `b`: hue = fract(b · 0.618034) (golden-ratio spacing, so
/// neighbouring indices differ), saturation 0.75.
pub fn brick_color(b: u32) -> [f32; 3] {
    hue(b as f64 * 0.618_034, 0.75)
}

/// Steps at which the heat map reaches its top colour.
pub const STEPS_FULL_SCALE: f64 = 256.0;

/// Heat map of `x ∈ [0, 1]` (clamped): black → blue → green → yellow → red at 0, ¼, ½, ¾, 1.
pub fn heat(x: f64) -> [f32; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
    ];
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        1.0
    } * 4.0;
    let i = (x.floor() as usize).min(3);
    let f = (x - i as f64) as f32;
    [0, 1, 2].map(|c| STOPS[i][c] + (STOPS[i + 1][c] - STOPS[i][c]) * f)
}

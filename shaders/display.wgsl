// The colour pipeline on the GPU: `vdbcook_scene::Display` (crates/scene/src/display.rs) is its
// definition and the tests hold the two together. Radiance times the exposure scale (2^EV), a
// tone map (curve 0: clamp; 1: Khronos PBR Neutral; 2: Narkowicz's ACES fit), then the sRGB
// transfer curve where the target does not apply it itself.

fn display_pbr_neutral(c_in: vec3<f32>) -> vec3<f32> {
    let x = min(c_in.r, min(c_in.g, c_in.b));
    let offset = select(0.04, x - 6.25 * x * x, x < 0.08);
    var c = c_in - vec3<f32>(offset);
    let peak = max(c.r, max(c.g, c.b));
    if (peak < 0.76) {
        return c;
    }
    let d = 1.0 - 0.76;
    let new_peak = 1.0 - d * d / (peak + d - 0.76);
    c = c * (new_peak / peak);
    let g = 1.0 - 1.0 / (0.15 * (peak - new_peak) + 1.0);
    return clamp(mix(c, vec3<f32>(new_peak), g), vec3<f32>(0.0), vec3<f32>(1.0));
}

fn display_aces(c: vec3<f32>) -> vec3<f32> {
    let x = 0.6 * c;
    // Above 1, the same rational divided through by x² (no overflow toward +inf).
    let y = max(x, vec3<f32>(1.0));
    let far = (2.51 + 0.03 / y) / (2.43 + 0.59 / y + 0.14 / (y * y));
    let near = x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14);
    return clamp(select(near, far, x > vec3<f32>(1.0)), vec3<f32>(0.0), vec3<f32>(1.0));
}

// Radiance to display-linear values in [0, 1]: NaN and negatives to 0, +inf and anything above
// 1e30 to 1e30 (white), before and after the exposure (`DISPLAY_MAX`).
fn display_map(rgb: vec3<f32>, scale: f32, curve: u32) -> vec3<f32> {
    // `max` alone may keep a NaN on some drivers: a NaN fails every comparison.
    let big = vec3<f32>(1.0e30);
    let c = min(min(select(vec3<f32>(0.0), rgb, rgb >= vec3<f32>(0.0)), big) * scale, big);
    if (curve == 1u) {
        return display_pbr_neutral(c);
    }
    if (curve == 2u) {
        return display_aces(c);
    }
    return clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
}

fn display_srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let x = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
    return select(1.055 * pow(x, vec3<f32>(1.0 / 2.4)) - 0.055, 12.92 * x, x <= vec3<f32>(0.0031308));
}

fn display_srgb_decode(c: vec3<f32>) -> vec3<f32> {
    return select(pow((c + 0.055) / 1.055, vec3<f32>(2.4)), c / 12.92, c <= vec3<f32>(0.04045));
}

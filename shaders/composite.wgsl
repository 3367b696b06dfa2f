// composite.wgsl — the engine drawer's second pass (`vdbcook_runtime::VolumeDrawer`): it exists
// so that the volume lands on an engine's colour target of any renderable format (8-bit, sRGB,
// BGRA, 10-bit, half float) through the blend unit, which a compute pass cannot write. A
// full-screen triangle reads the (L, T) texture `draw.wgsl` wrote (premultiplied radiance,
// transmittance) and the pipeline's blend state (colour: src factor One, dst factor SrcAlpha;
// alpha: the target's alpha kept) computes `out = L + T·scene`.

@group(0) @binding(0) var composite_lt: texture_2d<f32>;

@vertex
fn composite_vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the viewport: (-1, -1), (3, -1), (-1, 3).
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn composite_fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    return textureLoad(composite_lt, vec2<i32>(pos.xy), 0);
}

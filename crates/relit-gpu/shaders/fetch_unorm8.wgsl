// 8-bit storage: four pixels per 32-bit word, the lowest byte first; plane strides are
// multiples of 4. The stored value is q / 255; the per-plane scale and bias undo it.
@group(0) @binding(3) var<storage, read> planes: array<u32>;

fn fetch(plane: u32, p: u32) -> f32 {
    let i = plane * span.a.y + p;
    return unpack4x8unorm(planes[i >> 2u])[i & 3u];
}

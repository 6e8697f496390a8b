// 8-bit storage: four pixels per 32-bit word, the lowest byte first; plane strides are
// multiples of 4. The stored number is the integer code q (0–255); the per-plane scale
// and offset give the value, offset + scale · q.
@group(0) @binding(3) var<storage, read> planes: array<u32>;

fn fetch(plane: u32, p: u32) -> f32 {
    let i = plane * span.a.y + p;
    return f32((planes[i >> 2u] >> (8u * (i & 3u))) & 0xFFu);
}

// f16 storage: two pixels per 32-bit word, the lower half first; plane strides are even.
@group(0) @binding(3) var<storage, read> planes: array<u32>;

fn fetch(plane: u32, p: u32) -> f32 {
    let i = plane * span.a.y + p;
    let pair = unpack2x16float(planes[i >> 1u]);
    return select(pair.x, pair.y, (i & 1u) == 1u);
}

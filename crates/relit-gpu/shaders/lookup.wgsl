// A codebook file's frame: every pixel takes the colour its entry was relit to.
// The entries' colours come from relight.wgsl over the C × 1 image of entries.

struct Span {
    // x0, y0, region width, region height
    a: vec4<u32>,
    // image width, threads per row of workgroups, -, -
    b: vec4<u32>,
}

@group(0) @binding(0) var<uniform> span: Span;
// The entries' relit colours, RGB per entry.
@group(0) @binding(1) var<storage, read> colours: array<f32>;
// Two 16-bit indices per word, the even pixel in the low half.
@group(0) @binding(2) var<storage, read> indices: array<u32>;
@group(0) @binding(3) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x + gid.y * span.b.y;
    let w = span.a.z;
    if t >= w * span.a.w {
        return;
    }
    let p = (span.a.y + t / w) * span.b.x + span.a.x + t % w;
    let word = indices[p >> 1u];
    let i = select(word & 0xffffu, word >> 16u, (p & 1u) == 1u);
    out[3u * t] = colours[3u * i];
    out[3u * t + 1u] = colours[3u * i + 1u];
    out[3u * t + 2u] = colours[3u * i + 2u];
}

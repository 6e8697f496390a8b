// The device's plain read rate, the bound a relight frame is measured against: every
// invocation sums a grid-strided run of vec4 values. The sum is written only when it
// equals a value no real data sums to, so the loads cannot be dropped and the writes
// cost nothing.

struct Probe {
    count: u32,
    threads: u32,
};

@group(0) @binding(0) var<storage, read> source: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> sink: array<vec4<f32>>;
@group(0) @binding(2) var<uniform> probe: Probe;

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    var sum = vec4<f32>(0.0);
    for (var i = id.x; i < probe.count; i += probe.threads) {
        sum += source[i];
    }
    if (sum.x == -1.5e38) {
        sink[id.x % 64u] = sum;
    }
}

// relit's relighting kernel: one invocation per output pixel of a region of interest.
//
// A storage-specific file (fetch_*.wgsl) is prepended; it declares binding 3 (the
// planes of one slab of rows) and `fetch(plane, p)`, the stored value of plane
// `plane` (= 3i + c, docs/conventions.md) at slab-local pixel `p`.
//
// Directional and environment lights arrive as passes: one weight per plane, already
// folded with exposure, colours and the per-plane scale of quantised storage (its bias
// enters `offset`). Linear maps need one pass whatever the number of such lights;
// display-referred maps need one per light, decoded from sRGB before adding.
// Positional lights evaluate the SH basis per pixel with the trig-free recurrence of
// crates/relit/src/basis/sh.rs, fused with the dot product so no per-pixel array of
// basis values is kept.

struct Setup {
    // width, k, bands, display (1 = maps are sRGB-encoded)
    dims: vec4<u32>,
    // K_lm (m = 0) and √2·K_lm (m > 0) at index l * 8 + m
    norm: array<vec4<f32>, 16>,
    // value = scale * stored + bias, per coefficient i (xyz = channels)
    scale: array<vec4<f32>, 64>,
    bias: array<vec4<f32>, 64>,
}

struct Span {
    // first image row of the slab, plane stride in pixels, ROI x of this dispatch, its first image row
    a: vec4<u32>,
    // ROI width, rows in this dispatch
    b: vec4<u32>,
}

struct Pass {
    tint: vec4<f32>,
    offset: vec4<f32>,
    w: array<vec4<f32>, 64>,
}

struct PosLight {
    // xyz position; w: attenuation (0 inverse square, 1 c0 / d, 2 none)
    position: vec4<f32>,
    // xyz rgb (colour × intensity × exposure); w: c0
    rgb: vec4<f32>,
    // xyz unit axis from the light into the scene; w: 1 for a spotlight
    axis: vec4<f32>,
    // x cos(outer cone), y cos(inner cone)
    cone: vec4<f32>,
}

struct Frame {
    // passes, positional lights
    counts: vec4<u32>,
    passes: array<Pass, 16>,
    lights: array<PosLight, 32>,
}

@group(0) @binding(0) var<uniform> setup: Setup;
@group(0) @binding(1) var<uniform> span: Span;
@group(0) @binding(2) var<storage, read> frame: Frame;
@group(0) @binding(4) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> out: array<f32>;

// The raw stored values of coefficient i (three planes) at pixel p.
fn raw(i: u32, p: u32) -> vec3<f32> {
    return vec3<f32>(fetch(3u * i, p), fetch(3u * i + 1u, p), fetch(3u * i + 2u, p));
}

// The coefficient values of coefficient i at pixel p (quantisation undone).
fn coef(i: u32, p: u32) -> vec3<f32> {
    return fma(raw(i, p), setup.scale[i].xyz, setup.bias[i].xyz);
}

fn srgb_to_linear(v: vec3<f32>) -> vec3<f32> {
    let c = clamp(v, vec3<f32>(0.0), vec3<f32>(1.0));
    return select(c / 12.92, pow((c + 0.055) / 1.055, vec3<f32>(2.4)), c > vec3<f32>(0.04045));
}

fn norm(l: u32, m: u32) -> f32 {
    let j = l * 8u + m;
    return setup.norm[j / 4u][j % 4u];
}

// Σ_i c_i(p) Y_i(d) for a unit light vector d: the recurrence of basis/sh.rs.
fn shade(p: u32, d: vec3<f32>) -> vec3<f32> {
    let bands = setup.dims.z;
    var cm = 1.0;
    var sm = 0.0;
    var pmm = 1.0;
    var acc = vec3<f32>(0.0);
    for (var m = 0u; m < bands; m++) {
        if m > 0u {
            let c = d.x * cm - d.y * sm;
            let s = d.x * sm + d.y * cm;
            cm = c;
            sm = s;
            pmm *= -f32(2u * m - 1u);
        }
        var p_prev = 0.0;
        var p_cur = pmm;
        for (var l = m; l < bands; l++) {
            if l == m + 1u {
                p_prev = p_cur;
                p_cur = f32(2u * m + 1u) * d.z * pmm;
            } else if l > m + 1u {
                let next = (f32(2u * l - 1u) * d.z * p_cur - f32(l + m - 1u) * p_prev) / f32(l - m);
                p_prev = p_cur;
                p_cur = next;
            }
            let base = l * (l + 1u);
            let kp = norm(l, m) * p_cur;
            if m == 0u {
                acc += kp * coef(base, p);
            } else {
                acc += (kp * cm) * coef(base + m, p) + (kp * sm) * coef(base - m, p);
            }
        }
    }
    return acc;
}

// The RGB factor (colour × falloff × cone) of positional light j toward a surface
// point at distance `dist` seen along unit light vector `l`.
fn light_factor(j: u32, l: vec3<f32>, dist: f32) -> vec3<f32> {
    let light = frame.lights[j];
    let d = max(dist, 1e-9);
    var a = 1.0;
    let kind = light.position.w;
    if kind < 0.5 {
        a = 1.0 / (d * d);
    } else if kind < 1.5 {
        a = light.rgb.w / d;
    }
    if light.axis.w > 0.5 {
        let cos_angle = dot(-l, light.axis.xyz);
        let outer = light.cone.x;
        let inner = light.cone.y;
        var cone = 1.0;
        if cos_angle < inner {
            if cos_angle <= outer || inner <= outer {
                cone = 0.0;
            } else {
                let t = (cos_angle - outer) / (inner - outer);
                cone = t * t * (3.0 - 2.0 * t);
            }
        }
        a *= cone;
    }
    return light.rgb.xyz * a;
}

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = gid.x + gid.y * groups.x * 256u;
    let w = span.b.x;
    if t >= w * span.b.y {
        return;
    }
    let x = span.a.z + t % w;
    let y = span.a.w + t / w;
    let p = (y - span.a.x) * setup.dims.x + x;
    let k = setup.dims.y;
    let display = setup.dims.w == 1u;

    var rgb = vec3<f32>(0.0);
    let passes = frame.counts.x;
    for (var j = 0u; j < passes; j++) {
        var acc = frame.passes[j].offset.xyz;
        for (var i = 0u; i < k; i++) {
            acc = fma(frame.passes[j].w[i].xyz, raw(i, p), acc);
        }
        if display {
            acc = srgb_to_linear(acc);
        }
        rgb += frame.passes[j].tint.xyz * acc;
    }

    let lights = frame.counts.y;
    if lights > 0u {
        let surface = positions[p];
        if surface.w > 0.5 {
            for (var j = 0u; j < lights; j++) {
                let to_light = frame.lights[j].position.xyz - surface.xyz;
                let dist = length(to_light);
                if dist > 1e-12 {
                    let l = to_light / dist;
                    let f = light_factor(j, l, dist);
                    if any(f != vec3<f32>(0.0)) {
                        var v = shade(p, l);
                        if display {
                            v = srgb_to_linear(v);
                        }
                        rgb += f * v;
                    }
                }
            }
        }
    }
    out[3u * t] = rgb.x;
    out[3u * t + 1u] = rgb.y;
    out[3u * t + 2u] = rgb.z;
}

// relit's relighting kernel: one invocation per output pixel of a region of interest.
//
// A storage-specific file (fetch_*.wgsl) is prepended; it declares binding 3 (the
// planes of one slab of rows) and `fetch(plane, p)`, the stored number of plane
// `plane` (= 3i + c, docs/conventions.md) at slab-local pixel `p`.
//
// Directional and environment lights arrive as passes: one weight per plane, already
// folded with exposure, colours and the per-plane scale of quantised storage (its
// offset enters `Pass.offset`). Linear maps need one pass whatever the number of such
// lights; display-referred maps need one per light, decoded from sRGB before adding.
// Lights with a position need the basis at every pixel's own light vector. The shader
// knows no basis: it reads the weights from the basis' weight table (binding 7,
// relit::basis::WeightTable), the bilinear blend of the four vertices of an octahedral
// map around the light vector, fused with the dot product so that no per-pixel array
// of weights is kept.
// Projectors and area lights follow crates/relit/src/engine/kernels/lights.rs (the f32
// form of relit::light::{projector, area}): a projector weights its light vector with
// its slide, sampled bilinearly where the surface point projects; an area light sums
// its stratified emitter samples, the strata shifted per image pixel by the 64-bit hash
// of AreaLight::shift, done exactly in 32-bit halves.

struct Setup {
    // width, k, cells per side N of the weight table, display (1 = maps are sRGB-encoded)
    dims: vec4<u32>,
    // value = offset + scale · q for the stored number q, per coefficient i (xyz = channels)
    scale: array<vec4<f32>, 64>,
    offset: array<vec4<f32>, 64>,
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

struct Projector {
    // xyz position; w: attenuation (as PosLight)
    position: vec4<f32>,
    // xyz unit axis; w: c0
    forward: vec4<f32>,
    // xyz unit vector toward the slide's right; w: tan(horizontal half-angle)
    right: vec4<f32>,
    // xyz unit vector toward the slide's up; w: tan(vertical half-angle)
    up: vec4<f32>,
    // xyz rgb (colour × intensity × exposure)
    rgb: vec4<f32>,
    // offset of the slide in `slides` (floats), its width, height, 1 if it has texels
    slide: vec4<u32>,
}

struct Area {
    // xyz centre; w: 0 rectangle, 1 disk
    center: vec4<f32>,
    // rectangle: edge u; disk: unit φ = 0 axis, w radius
    u: vec4<f32>,
    // rectangle: edge v; disk: unit φ = π/2 axis
    v: vec4<f32>,
    // xyz unit normal of the emitting face; w: 1 if two-sided
    normal: vec4<f32>,
    // xyz rgb (colour × intensity × exposure); w: area / samples
    rgb: vec4<f32>,
    // samples, columns, rows of the strata
    strata: vec4<u32>,
}

struct Frame {
    // passes, point and spot lights, projectors, area lights
    counts: vec4<u32>,
    passes: array<Pass, 96>,
    lights: array<PosLight, 32>,
    projectors: array<Projector, 8>,
    areas: array<Area, 8>,
}

@group(0) @binding(0) var<uniform> setup: Setup;
@group(0) @binding(1) var<uniform> span: Span;
@group(0) @binding(2) var<storage, read> frame: Frame;
@group(0) @binding(4) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> out: array<f32>;
// The projectors' slides: linear RGB, row-major from the top, three floats a texel.
@group(0) @binding(6) var<storage, read> slides: array<f32>;
// The basis' weight table (WeightTable::values in half floats, as the CPU engine and
// the viewer hold it), four weights a 64-bit load: weights 4g … 4g+3 of vertex (i, j)
// of the (N+1)×(N+1) grid at (j·(N+1) + i)·⌈k/4⌉ + g, zero past k.
@group(0) @binding(7) var<storage, read> table: array<vec2<u32>>;

// The raw stored values of coefficient i (three planes) at pixel p.
fn raw(i: u32, p: u32) -> vec3<f32> {
    return vec3<f32>(fetch(3u * i, p), fetch(3u * i + 1u, p), fetch(3u * i + 2u, p));
}

// The coefficient values of coefficient i at pixel p (quantisation undone).
fn coef(i: u32, p: u32) -> vec3<f32> {
    return fma(raw(i, p), setup.scale[i].xyz, setup.offset[i].xyz);
}

fn srgb_to_linear(v: vec3<f32>) -> vec3<f32> {
    let c = clamp(v, vec3<f32>(0.0), vec3<f32>(1.0));
    return select(c / 12.92, pow((c + 0.055) / 1.055, vec3<f32>(2.4)), c > vec3<f32>(0.04045));
}

// -1 for negative values, 1 otherwise (zero included): the fold's sign in
// octahedral_uv, which WGSL's sign() (0 at 0) is not.
fn fold_sign(v: vec2<f32>) -> vec2<f32> {
    return select(vec2<f32>(1.0), vec2<f32>(-1.0), v < vec2<f32>(0.0));
}

// The table offsets of the four vertices around unit vector d and their bilinear
// weights, in the order of WeightTable::corners (which defines the lookup; this is
// its f32 transcription).
struct Corners {
    at: vec4<u32>,
    w: vec4<f32>,
}

fn corners(d: vec3<f32>) -> Corners {
    let n = setup.dims.z;
    let groups = (setup.dims.y + 3u) / 4u;
    var p = d.xy / (abs(d.x) + abs(d.y) + abs(d.z));
    if d.z < 0.0 {
        p = (vec2<f32>(1.0) - abs(p.yx)) * fold_sign(p);
    }
    let x = (0.5 * p + 0.5) * f32(n);
    let ij = min(vec2<u32>(max(floor(x), vec2<f32>(0.0))), vec2<u32>(n - 1u));
    let f = x - vec2<f32>(ij);
    let side = n + 1u;
    let v00 = ij.y * side + ij.x;
    let g = vec2<f32>(1.0) - f;
    return Corners(
        vec4<u32>(v00, v00 + 1u, v00 + side, v00 + side + 1u) * groups,
        vec4<f32>(g.x * g.y, f.x * g.y, g.x * f.y, f.x * f.y),
    );
}

// Weights 4g … 4g+3 of the basis at the corners c: WeightTable::sample's blend, in its
// order.
fn weights(c: Corners, g: u32) -> vec4<f32> {
    return c.w.x * vertex(c.at.x + g) + c.w.y * vertex(c.at.y + g) + c.w.z * vertex(c.at.z + g) + c.w.w * vertex(c.at.w + g);
}

// Four weights of the table at `at`.
fn vertex(at: u32) -> vec4<f32> {
    let h = table[at];
    return vec4<f32>(unpack2x16float(h.x), unpack2x16float(h.y));
}

// Σ_i w_i c_i(p) for weights 4g … 4g+3 of `w` (those below k).
fn dot_group(w: vec4<f32>, g: u32, p: u32) -> vec3<f32> {
    let k = setup.dims.y;
    let i = 4u * g;
    var acc = vec3<f32>(w.x) * coef(i, p);
    if i + 1u < k {
        acc = fma(vec3<f32>(w.y), coef(i + 1u, p), acc);
    }
    if i + 2u < k {
        acc = fma(vec3<f32>(w.z), coef(i + 2u, p), acc);
    }
    if i + 3u < k {
        acc = fma(vec3<f32>(w.w), coef(i + 3u, p), acc);
    }
    return acc;
}

// Σ_i c_i(p) b_i(d) for a unit light vector d.
fn shade(p: u32, d: vec3<f32>) -> vec3<f32> {
    let c = corners(d);
    let groups = (setup.dims.y + 3u) / 4u;
    var acc = vec3<f32>(0.0);
    for (var g = 0u; g < groups; g++) {
        acc += dot_group(weights(c, g), g, p);
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

// proj[i] += w · b_i(d) for a unit vector d, four weights a vec4: an area light's
// samples summed in the basis, dotted with the coefficients once.
fn project(d: vec3<f32>, w: f32, proj: ptr<function, array<vec4<f32>, 16>>) {
    let c = corners(d);
    let groups = (setup.dims.y + 3u) / 4u;
    for (var g = 0u; g < groups; g++) {
        (*proj)[g] = fma(vec4<f32>(w), weights(c, g), (*proj)[g]);
    }
}

// The value of light vector l at pixel p (decoded from sRGB on display-referred maps)
// times the RGB weight w; channels of weight 0 add nothing, even where the
// coefficients are not finite (as the CPU engine's add_weighted).
fn weighted(p: u32, l: vec3<f32>, w: vec3<f32>, display: bool) -> vec3<f32> {
    var v = shade(p, l);
    if display {
        v = srgb_to_linear(v);
    }
    return select(w * v, vec3<f32>(0.0), w == vec3<f32>(0.0));
}

// Texel (x, y) of the slide at `offset`, `width` texels a row.
fn texel(offset: u32, width: u32, x: u32, y: u32) -> vec3<f32> {
    let i = offset + 3u * (y * width + x);
    return vec3<f32>(slides[i], slides[i + 1u], slides[i + 2u]);
}

// Projector j at surface point `at` of pixel p (PreparedProjector::illuminate).
fn projector(j: u32, at: vec3<f32>, p: u32, display: bool) -> vec3<f32> {
    let pr = frame.projectors[j];
    if pr.slide.w == 0u {
        return vec3<f32>(0.0);
    }
    let to_light = pr.position.xyz - at;
    let r = length(to_light);
    if !(r > 1e-12) {
        return vec3<f32>(0.0);
    }
    let l = to_light / r;
    let dist = max(r, 1e-9);
    var a = 1.0;
    let kind = pr.position.w;
    if kind < 0.5 {
        a = 1.0 / (dist * dist);
    } else if kind < 1.5 {
        a = pr.forward.w / dist;
    }
    let d = at - pr.position.xyz;
    let z = dot(d, pr.forward.xyz);
    let sx = dot(d, pr.right.xyz) / (z * pr.right.w);
    let sy = dot(d, pr.up.xyz) / (z * pr.up.w);
    if !(z > 1e-9 && abs(sx) <= 1.0 && abs(sy) <= 1.0) {
        return vec3<f32>(0.0);
    }
    // Slide pixel coordinates: x right, y down, centres at half-integers.
    let sw = pr.slide.y;
    let sh = pr.slide.z;
    let w = f32(sw);
    let h = f32(sh);
    let fx = clamp((sx + 1.0) * 0.5 * w - 0.5, 0.0, w - 1.0);
    let fy = clamp((1.0 - sy) * 0.5 * h - 0.5, 0.0, h - 1.0);
    let x0 = u32(fx);
    let y0 = u32(fy);
    let x1 = min(x0 + 1u, sw - 1u);
    let y1 = min(y0 + 1u, sh - 1u);
    let tx = fx - f32(x0);
    let ty = fy - f32(y0);
    let o = pr.slide.x;
    let top = texel(o, sw, x0, y0) * (1.0 - tx) + texel(o, sw, x1, y0) * tx;
    let bottom = texel(o, sw, x0, y1) * (1.0 - tx) + texel(o, sw, x1, y1) * tx;
    let weight = pr.rgb.xyz * (top * (1.0 - ty) + bottom * ty) * a;
    if all(weight == vec3<f32>(0.0)) {
        return vec3<f32>(0.0);
    }
    return weighted(p, l, weight, display);
}

// The high 32 bits of the 64-bit product of a and b (16-bit limbs).
fn mul_hi32(a: u32, b: u32) -> u32 {
    let a0 = a & 0xFFFFu;
    let a1 = a >> 16u;
    let b0 = b & 0xFFFFu;
    let b1 = b >> 16u;
    let p00 = a0 * b0;
    let p01 = a0 * b1;
    let p10 = a1 * b0;
    let p11 = a1 * b1;
    let mid = (p00 >> 16u) + (p01 & 0xFFFFu) + (p10 & 0xFFFFu);
    return p11 + (p01 >> 16u) + (p10 >> 16u) + (mid >> 16u);
}

// a · b mod 2^64, 64-bit values as (lo, hi).
fn mul64(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    return vec2<u32>(a.x * b.x, mul_hi32(a.x, b.x) + a.x * b.y + a.y * b.x);
}

// a ^ (a >> s) for 0 < s < 32.
fn xor_shift64(a: vec2<u32>, s: u32) -> vec2<u32> {
    return a ^ vec2<u32>((a.x >> s) | (a.y << (32u - s)), a.y >> s);
}

// The strata shift (jx, jy) in [0, 1)² of image pixel `pixel` (row · width + column):
// AreaLight::shift (crates/relit/src/light/area.rs).
fn cranley_patterson(pixel: u32) -> vec2<f32> {
    var h = mul64(vec2<u32>(pixel, 0u), vec2<u32>(0x7F4A7C15u, 0x9E3779B9u)) ^ vec2<u32>(0xD192ED03u, 0xD1B54A32u);
    h = xor_shift64(h, 31u);
    h = mul64(h, vec2<u32>(0x1CE4E5B9u, 0xBF58476Du));
    h = xor_shift64(h, 29u);
    return vec2<f32>(f32(h.x), f32(h.y)) * (1.0 / 4294967296.0);
}

// Area light j at surface point `at` of pixel p, image pixel `pixel`
// (AreaLight::illuminate). Linear maps: the samples summed in the basis, one dot with
// the coefficients; display-referred maps: every sample's value decoded.
fn area(j: u32, at: vec3<f32>, p: u32, pixel: u32, display: bool) -> vec3<f32> {
    let light = frame.areas[j];
    let n = light.strata.x;
    let columns = light.strata.y;
    let rows = light.strata.z;
    let shift = cranley_patterson(pixel);
    let disk = light.center.w > 0.5;
    let two_sided = light.normal.w > 0.5;
    let su = 2.0 / f32(columns);
    let sv = 2.0 / f32(rows);
    let inv_columns = 1.0 / f32(columns);
    let tau = 6.283185307179586;
    var proj: array<vec4<f32>, 16>;
    var total = 0.0;
    var acc = vec3<f32>(0.0);
    for (var k = 0u; k < n; k++) {
        let column = f32(k % columns);
        let row = f32(k / columns);
        var x: vec3<f32>;
        if disk {
            let r = light.u.w * sqrt((column + shift.x) * inv_columns);
            let phi = tau * ((row + shift.y) / f32(rows));
            x = light.center.xyz + light.u.xyz * (r * cos(phi)) + light.v.xyz * (r * sin(phi));
        } else {
            let a = (column + shift.x) * su - 1.0;
            let b = (row + shift.y) * sv - 1.0;
            x = light.center.xyz + light.u.xyz * a + light.v.xyz * b;
        }
        let d = x - at;
        let r2 = dot(d, d);
        if !(r2 > 1e-18) {
            continue;
        }
        let inv = 1.0 / sqrt(r2);
        let l = d * inv;
        var cos_e = -dot(l, light.normal.xyz);
        if two_sided {
            cos_e = abs(cos_e);
        }
        if !(cos_e > 0.0) {
            continue;
        }
        let g = light.rgb.w * cos_e * inv * inv;
        if display {
            acc += weighted(p, l, light.rgb.xyz * g, display);
        } else {
            project(l, g, &proj);
            total += g;
        }
    }
    if display || !(total > 0.0) {
        return acc;
    }
    var v = vec3<f32>(0.0);
    let groups = (setup.dims.y + 3u) / 4u;
    for (var g = 0u; g < groups; g++) {
        v += dot_group(proj[g], g, p);
    }
    return select(light.rgb.xyz * v, vec3<f32>(0.0), light.rgb.xyz == vec3<f32>(0.0));
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
    let projectors = frame.counts.z;
    let areas = frame.counts.w;
    if lights + projectors + areas > 0u {
        let surface = positions[p];
        if surface.w > 0.5 {
            // EXTRA_LIGHTS (prepended by engine.rs) is false in the pipeline for frames
            // without projector or area lights, which compiles their code out: with it,
            // lavapipe ran every other frame ~1.7× slower (directional 31 → 17 fps).
            if EXTRA_LIGHTS {
                for (var j = 0u; j < projectors; j++) {
                    rgb += projector(j, surface.xyz, p, display);
                }
                let pixel = y * setup.dims.x + x;
                for (var j = 0u; j < areas; j++) {
                    rgb += area(j, surface.xyz, p, pixel, display);
                }
            }
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

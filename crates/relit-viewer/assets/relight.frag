#version 300 es
// Lazy relighting: every frame, each pixel on screen finds the source pixel it shows and
// relights it from the coefficient layers (crates/relit-viewer/src/bundle.rs): one
// weight vec4 per layer for every light with one light vector (directional and
// environment lights folded on the CPU), and for lights with a position the basis'
// weights at each pixel's own light vector, L = S − P with P = O + d·V from the file's
// camera and depth, as the CPU engine does. The shader knows no basis: it reads the
// weights from the basis' weight table (uTable), as table.js does.
precision highp float;
precision highp int;
precision highp sampler2DArray;

#define MAX_LAYERS 48
#define MAX_LIGHTS 8
#define MAX_AREA_SAMPLES 64

uniform highp sampler2DArray uPlanes;
// CODEBOOK (defined by renderer.js): uPlanes holds a codebook's entries, 256 to a row,
// and uIndices each pixel's entry.
uniform highp usampler2D uIndices;
// The weight table (half floats, the values table.js reads): texel (i, j) of layer l
// holds weights 4l … 4l+3 of vertex (i, j) of the (N+1)×(N+1) octahedral grid
// (crates/relit/src/basis/table.rs).
uniform highp sampler2DArray uTable;
uniform int uTableN;            // cells per side N
uniform highp sampler2D uDepth;
uniform vec2 uDepthSize;        // uDepth's size: the image's, or a tiled bundle's overview's
uniform sampler2D uSlide0;
uniform sampler2D uSlide1;
uniform sampler2D uSlide2;
uniform sampler2D uSlide3;

// N_LAYERS (layers per colour channel) is defined by renderer.js when it compiles the
// shader for a file, so that every loop has constant bounds.
uniform vec4 uScale[MAX_LAYERS];// value = uOffset + uScale · texel, per layer component
uniform vec4 uOffset[MAX_LAYERS];
uniform vec4 uW[MAX_LAYERS];    // folded uniform lights, per layer
uniform bool uHasUniform;
uniform bool uDisplay;          // display-referred (sRGB) maps
uniform bool uHasDepth;
uniform vec2 uImage;            // width, height in pixels
uniform bool uSmooth;           // bilinear coefficients (and depth where it is continuous)
uniform float uMaxLod;          // mip levels − 1 when the view shrinks the image, else 0
uniform vec2 uPlanesSize;       // the planes texture's size: the image's, or a tiled bundle's overview
uniform float uPlanesLod;       // the level of the image the planes texture holds (0, or the overview's)
// Display-referred maps: an environment's lights, row 0 the directions, row 1 the RGB.
uniform highp sampler2D uEnvLights;
uniform int uNumEnv;

#if TILED
// A tiled bundle (renderer.js setupTiles): tiles of level uLevel held in the atlas's
// slots, uPages giving each tile of the level its slot + 1 (0: not held, the overview
// stands in).
uniform highp sampler2DArray uAtlas;
uniform highp usampler2D uPages;
uniform int uLevel;             // the level tiles are read from; −1: the overview alone
uniform vec2 uLevelSize;
uniform int uTileSide;
uniform int uSlotsPerRow;
uniform highp sampler2D uDepthAtlas; // each held tile's depth, in its slot
#endif

uniform int uViewMode;          // 0 flat pan/zoom, 1 perspective view of a panorama
uniform vec2 uCanvas;
uniform vec2 uCenter;           // flat: image position at the canvas centre
uniform float uZoom;            // flat: screen pixels per image pixel
uniform bool uWrapX;            // panoramas: columns wrap around
uniform mat3 uView;             // perspective: view ray (x, y, 1) -> panorama camera frame
uniform float uTanHalfFov;

uniform int uProj;              // 0 perspective, 1 orthographic, 2 cylindrical, 3 equirectangular
uniform vec2 uHalf;             // planar: half width and height of the image plane
uniform float uSpan;            // cylindrical: height span of the unit cylinder
uniform vec3 uEye;
uniform mat3 uPose;             // columns right, up, back

uniform float uExposure;        // 2^stops
uniform vec3 uBackground;

uniform int uNumLights;
uniform int uLType[MAX_LIGHTS]; // 0 directional (display maps only), 1 point, 2 spot, 3 projector, 4 area rect, 5 area disk
uniform vec3 uLPos[MAX_LIGHTS]; // area: centre
uniform vec3 uLDir[MAX_LIGHTS]; // directional: toward the light; spot/projector: unit axis into the scene; area: unit normal
uniform vec3 uLRgb[MAX_LIGHTS];
uniform vec2 uLAtt[MAX_LIGHTS]; // mode (0 1/d², 1 c0/d, 2 none), c0; area: area per sample, disk radius
uniform vec4 uLCone[MAX_LIGHTS];// spot: cos outer, cos inner; projector: tan½x, tan½y, slide; area: columns, rows, samples, two-sided
uniform vec3 uLRight[MAX_LIGHTS];// projector: right; area: rect u, disk φ = 0 axis
uniform vec3 uLUp[MAX_LIGHTS];  // projector: up; area: rect v, disk φ = π/2 axis

out vec4 outColor;

const float PI = 3.14159265358979;

float srgbToLinear(float v) {
  return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}
float linearToSrgb(float v) {
  v = clamp(v, 0.0, 1.0);
  return v <= 0.0031308 ? v * 12.92 : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

// x wrapped into [0, width) (mod alone can round up to width itself).
float wrapColumn(float x) {
  x -= uImage.x * floor(x / uImage.x);
  return x >= uImage.x ? 0.0 : x;
}

// The source position (continuous pixel coordinates) shown at this fragment; false
// when the fragment shows nothing.
bool sourcePosition(out vec2 pos) {
  pos = vec2(0.0);
  vec2 frag = vec2(gl_FragCoord.x, uCanvas.y - gl_FragCoord.y);
  if (uViewMode == 0) {
    pos = uCenter + (frag - 0.5 * uCanvas) / uZoom;
    if (uWrapX) pos.x = wrapColumn(pos.x);
  } else {
    vec2 ndc = (2.0 * frag - uCanvas) / uCanvas.y;
    vec3 d = uView * vec3(ndc.x * uTanHalfFov, -ndc.y * uTanHalfFov, 1.0);
    float r = length(d.xz);
    float az = atan(d.x, -d.z);
    pos.x = wrapColumn((az / (2.0 * PI) + 0.5) * uImage.x);
    if (uProj == 3) {
      pos.y = (0.5 - atan(d.y, r) / PI) * uImage.y;
    } else {
      if (r < 1e-12) return false;
      pos.y = (0.5 - d.y / r / uSpan) * uImage.y;
    }
  }
  return pos.x >= 0.0 && pos.y >= 0.0 && pos.x < uImage.x && pos.y < uImage.y;
}

// The surface point at continuous image position (x, y) at depth d: P = O + d·V with
// the ray of crates/relit/src/camera/*.rs (pixel centres at +0.5).
vec3 surfacePoint(vec2 at, float d) {
  float x = at.x, y = at.y;
  vec3 o = vec3(0.0), v;
  if (uProj == 0) {
    float u = (2.0 * x / uImage.x - 1.0) * uHalf.x, w = (1.0 - 2.0 * y / uImage.y) * uHalf.y;
    v = normalize(vec3(u, w, -1.0));
  } else if (uProj == 1) {
    o = vec3((2.0 * x / uImage.x - 1.0) * uHalf.x, (1.0 - 2.0 * y / uImage.y) * uHalf.y, 0.0);
    v = vec3(0.0, 0.0, -1.0);
  } else if (uProj == 2) {
    float phi = (x / uImage.x - 0.5) * 2.0 * PI;
    float h = (0.5 - y / uImage.y) * uSpan;
    v = vec3(sin(phi), h, -cos(phi)) / sqrt(1.0 + h * h);
  } else {
    float phi = (x / uImage.x - 0.5) * 2.0 * PI;
    float lat = (0.5 - y / uImage.y) * PI;
    v = vec3(cos(lat) * sin(phi), sin(lat), -cos(lat) * cos(phi));
  }
  return uEye + uPose * (o + d * v);
}

float foldSign(float v) { return v < 0.0 ? -1.0 : 1.0; }

// The basis' weights at unit light vector L, four per vec4: the bilinear blend of the
// table's four vertices around L (table.js `corners` and `sample`, WeightTable in
// crates/relit/src/basis/table.rs).
void basisWeights(vec3 L, out vec4 Y[N_LAYERS]) {
  vec2 p = L.xy / (abs(L.x) + abs(L.y) + abs(L.z));
  if (L.z < 0.0) p = (1.0 - abs(p.yx)) * vec2(foldSign(p.x), foldSign(p.y));
  vec2 x = (0.5 * p + 0.5) * float(uTableN);
  ivec2 i = min(ivec2(max(floor(x), 0.0)), ivec2(uTableN - 1));
  vec2 f = x - vec2(i), g = 1.0 - f;
  for (int l = 0; l < N_LAYERS; l++) {
    Y[l] = g.x * g.y * texelFetch(uTable, ivec3(i, l), 0) + f.x * g.y * texelFetch(uTable, ivec3(i.x + 1, i.y, l), 0)
         + g.x * f.y * texelFetch(uTable, ivec3(i.x, i.y + 1, l), 0) + f.x * f.y * texelFetch(uTable, ivec3(i + 1, l), 0);
  }
}

float attenuation(int i, float d) {
  d = max(d, 1e-9);
  int mode = int(uLAtt[i].x + 0.5);
  if (mode == 0) return 1.0 / (d * d);
  if (mode == 1) return uLAtt[i].y / d;
  return 1.0;
}

vec3 slide(int s, vec2 uv) {
  if (s == 0) return texture(uSlide0, uv).rgb;
  if (s == 1) return texture(uSlide1, uv).rgb;
  if (s == 2) return texture(uSlide2, uv).rgb;
  return texture(uSlide3, uv).rgb;
}

// ---- the strata shift of area lights: AreaLight::shift (crates/relit/src/light/area.rs),
// a 64-bit integer hash of the pixel index, exactly, with 64-bit values as (lo, hi)
// pairs of 32-bit uints (GLSL ES 3.00 has neither 64-bit integers nor umulExtended).

// The high 32 bits of the 64-bit product of a and b (16-bit limbs).
uint mulHi32(uint a, uint b) {
  uint a0 = a & 0xFFFFu, a1 = a >> 16, b0 = b & 0xFFFFu, b1 = b >> 16;
  uint p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
  uint mid = (p00 >> 16) + (p01 & 0xFFFFu) + (p10 & 0xFFFFu);
  return p11 + (p01 >> 16) + (p10 >> 16) + (mid >> 16);
}
// a · b mod 2^64.
uvec2 mul64(uvec2 a, uvec2 b) {
  return uvec2(a.x * b.x, mulHi32(a.x, b.x) + a.x * b.y + a.y * b.x);
}
// a ^ (a >> s) for 0 < s < 32.
uvec2 xorShift64(uvec2 a, int s) {
  return a ^ uvec2((a.x >> uint(s)) | (a.y << uint(32 - s)), a.y >> uint(s));
}
// The per-pixel shift (jx, jy) in [0, 1)² of pixel `pixel` (row · width + column).
vec2 cranleyPatterson(uint pixel) {
  uvec2 h = mul64(uvec2(pixel, 0u), uvec2(0x7F4A7C15u, 0x9E3779B9u)) ^ uvec2(0xD192ED03u, 0xD1B54A32u);
  h = xorShift64(h, 31);
  h = mul64(h, uvec2(0x1CE4E5B9u, 0xBF58476Du));
  h = xorShift64(h, 29);
  return vec2(float(h.x), float(h.y)) * (1.0 / 4294967296.0);
}

#if TILED
// Texel p of level uLevel (columns wrapped on panoramas, edges clamped, as the planes
// texture's sampler does) in the atlas; x < 0 where its tile is not held.
ivec2 atlasTexel(ivec2 p) {
  ivec2 size = ivec2(uLevelSize);
  p.x = uWrapX ? (p.x % size.x + size.x) % size.x : clamp(p.x, 0, size.x - 1);
  p.y = clamp(p.y, 0, size.y - 1);
  ivec2 tile = p / uTileSide;
  int page = int(texelFetch(uPages, tile, 0).r);
  if (page == 0) return ivec2(-1);
  int slot = page - 1;
  return ivec2(slot % uSlotsPerRow, slot / uSlotsPerRow) * uTileSide + p - tile * uTileSide;
}

// The coefficients at pos from the tiles of uLevel: bilinear between the four nearest
// texels (by hand: they may sit in different slots), or the nearest; false where a
// tile they need is not held.
bool tiledCoefficients(vec2 pos, out vec4 C[3 * N_LAYERS]) {
  vec2 at = pos * uLevelSize / uImage;
  if (uSmooth) {
    vec2 q = at - 0.5;
    ivec2 i0 = ivec2(floor(q));
    vec2 f = q - floor(q);
    ivec2 a = atlasTexel(i0), b = atlasTexel(i0 + ivec2(1, 0));
    ivec2 c = atlasTexel(i0 + ivec2(0, 1)), d = atlasTexel(i0 + ivec2(1, 1));
    if (a.x < 0 || b.x < 0 || c.x < 0 || d.x < 0) return false;
    for (int l = 0; l < 3 * N_LAYERS; l++) {
      vec4 top = mix(texelFetch(uAtlas, ivec3(a, l), 0), texelFetch(uAtlas, ivec3(b, l), 0), f.x);
      vec4 bottom = mix(texelFetch(uAtlas, ivec3(c, l), 0), texelFetch(uAtlas, ivec3(d, l), 0), f.x);
      C[l] = uOffset[l] + uScale[l] * mix(top, bottom, f.y);
    }
  } else {
    ivec2 a = atlasTexel(ivec2(floor(at)));
    if (a.x < 0) return false;
    for (int l = 0; l < 3 * N_LAYERS; l++) C[l] = uOffset[l] + uScale[l] * texelFetch(uAtlas, ivec3(a, l), 0);
  }
  return true;
}
#endif

// The depth of texel t of uDepth; columns wrap on panoramas, other edges clamp.
float depthTexel(ivec2 t) {
  ivec2 size = ivec2(uDepthSize);
  t.x = uWrapX ? (t.x % size.x + size.x) % size.x : clamp(t.x, 0, size.x - 1);
  t.y = clamp(t.y, 0, size.y - 1);
  return texelFetch(uDepth, t, 0).r;
}

// The depth of texel t of the level depth is read at: the tiles of uLevel (fromTiles;
// −1 where its tile is not held) or uDepth.
float levelDepth(ivec2 t, bool fromTiles) {
#if TILED
  if (fromTiles) {
    ivec2 a = atlasTexel(t);
    return a.x < 0 ? -1.0 : texelFetch(uDepthAtlas, a, 0).r;
  }
#endif
  return depthTexel(t);
}

// The depth at pos, read at a level of `size` texels, and the image position its surface
// point is taken at: bilinear between the four nearest texel centres where they agree
// within 15 % (one continuous surface), otherwise the nearest texel's depth at its
// centre, so that no point floats between a foreground edge and the background. At
// texel centres both are that texel exactly. False where a tile it needs is not held.
bool surfaceDepth(vec2 pos, vec2 size, bool fromTiles, out float depth, out vec2 at) {
  vec2 s = size / uImage, p = pos * s;
  depth = 0.0;
  at = pos;
  if (uSmooth) {
    vec2 q = p - 0.5, f = q - floor(q);
    ivec2 i = ivec2(floor(q));
    float d00 = levelDepth(i, fromTiles), d10 = levelDepth(i + ivec2(1, 0), fromTiles);
    float d01 = levelDepth(i + ivec2(0, 1), fromTiles), d11 = levelDepth(i + ivec2(1, 1), fromTiles);
    float lo = min(min(d00, d10), min(d01, d11)), hi = max(max(d00, d10), max(d01, d11));
    if (lo < 0.0) return false;
    if (lo > 0.0 && hi <= 1.15 * lo) {
      depth = mix(mix(d00, d10, f.x), mix(d01, d11, f.x), f.y);
      return true;
    }
  }
  ivec2 t = min(ivec2(floor(p)), ivec2(size) - 1);
  float d = levelDepth(t, fromTiles);
  if (d < 0.0) return false;
  depth = d;
  at = (vec2(t) + 0.5) / s;
  return true;
}

void main() {
  vec2 pos;
  bool inside = sourcePosition(pos);
  // The mip level: log2 of the texels per screen pixel, from derivatives taken before
  // any branch that is not uniform (uMaxLod is 0 unless the view shrinks the image).
  // Panorama columns wrap: of x and x shifted by half the width, take the one whose
  // derivative does not cross the seam here.
  float lod = 0.0;
  if (uSmooth && uMaxLod > 0.0) {
    vec2 dx = dFdx(pos), dy = dFdy(pos);
    if (uWrapX) {
      float x2 = pos.x + (pos.x < 0.5 * uImage.x ? 0.5 : -0.5) * uImage.x;
      float dx2 = dFdx(x2), dy2 = dFdy(x2);
      if (abs(dx2) < abs(dx.x)) dx.x = dx2;
      if (abs(dy2) < abs(dy.x)) dy.x = dy2;
    }
    lod = clamp(log2(max(length(dx), length(dy))), 0.0, uMaxLod);
  }
  if (!inside) { outColor = vec4(uBackground, 1.0); return; }
  ivec2 t = min(ivec2(floor(pos)), ivec2(uImage) - 1);
  vec4 C[3 * N_LAYERS];
#if CODEBOOK
  // Each pixel's coefficients are its entry's. Smoothing blends the four nearest
  // pixels' entries by hand (entries cannot be filtered as a texture), as the planes'
  // bilinear filter would; a view that shrinks the image reads level 0 only.
  if (uSmooth) {
    vec2 q = pos - 0.5;
    vec2 f = fract(q);
    ivec2 i0 = ivec2(floor(q));
    ivec2 last = ivec2(uImage) - 1;
    for (int l = 0; l < 3 * N_LAYERS; l++) C[l] = vec4(0.0);
    for (int c = 0; c < 4; c++) {
      ivec2 o = ivec2(c & 1, c >> 1);
      ivec2 p = i0 + o;
      // Columns wrap on panoramas, clamp otherwise; rows clamp.
      p.x = uWrapX ? (p.x + int(uImage.x)) % int(uImage.x) : clamp(p.x, 0, last.x);
      p.y = clamp(p.y, 0, last.y);
      float w = (o.x == 1 ? f.x : 1.0 - f.x) * (o.y == 1 ? f.y : 1.0 - f.y);
      uint e = texelFetch(uIndices, p, 0).r;
      ivec2 et = ivec2(int(e % 256u), int(e / 256u));
      for (int l = 0; l < 3 * N_LAYERS; l++) C[l] += w * texelFetch(uPlanes, ivec3(et, l), 0);
    }
    for (int l = 0; l < 3 * N_LAYERS; l++) C[l] = uOffset[l] + uScale[l] * C[l];
  } else {
    uint e = texelFetch(uIndices, t, 0).r;
    ivec2 et = ivec2(int(e % 256u), int(e / 256u));
    for (int l = 0; l < 3 * N_LAYERS; l++) C[l] = uOffset[l] + uScale[l] * texelFetch(uPlanes, ivec3(et, l), 0);
  }
#else
  bool tiled = false;
#if TILED
  if (uLevel >= 0) tiled = tiledCoefficients(pos, C);
#endif
  if (!tiled && uSmooth) {
    // Filtered coefficients (relighting is linear in them, so this filters the relit
    // image): bilinear within a level, trilinear between the mip levels of the
    // footprint when the view shrinks the image; level 0 exactly wherever a texel
    // covers a screen pixel or more. The planes texture repeats horizontally on
    // panoramas and clamps otherwise; a tiled bundle's overview is level uPlanesLod.
    vec2 uv = pos / uImage;
    float planesLod = max(lod - uPlanesLod, 0.0);
    for (int l = 0; l < 3 * N_LAYERS; l++) C[l] = uOffset[l] + uScale[l] * textureLod(uPlanes, vec3(uv, float(l)), planesLod);
  } else if (!tiled) {
    ivec2 tp = uPlanesLod > 0.0 ? min(ivec2(floor(pos * uPlanesSize / uImage)), ivec2(uPlanesSize) - 1) : t;
    for (int l = 0; l < 3 * N_LAYERS; l++) C[l] = uOffset[l] + uScale[l] * texelFetch(uPlanes, ivec3(tp, l), 0);
  }
#endif

  vec3 col = vec3(0.0);
  if (uHasUniform) {
    vec3 u = vec3(0.0);
    for (int j = 0; j < N_LAYERS; j++) {
      u.r += dot(C[j], uW[j]);
      u.g += dot(C[N_LAYERS + j], uW[N_LAYERS + j]);
      u.b += dot(C[2 * N_LAYERS + j], uW[2 * N_LAYERS + j]);
    }
    if (uDisplay) u = vec3(srgbToLinear(clamp(u.r, 0.0, 1.0)), srgbToLinear(clamp(u.g, 0.0, 1.0)), srgbToLinear(clamp(u.b, 0.0, 1.0)));
    col += u;
  }
  if (uNumEnv > 0) {
    // An environment on display-referred maps: each of its lights decoded on its own.
    vec4 Y[N_LAYERS];
    for (int e = 0; e < uNumEnv; e++) {
      basisWeights(texelFetch(uEnvLights, ivec2(e, 0), 0).xyz, Y);
      vec3 v = vec3(0.0);
      for (int j = 0; j < N_LAYERS; j++) {
        v.r += dot(C[j], Y[j]);
        v.g += dot(C[N_LAYERS + j], Y[j]);
        v.b += dot(C[2 * N_LAYERS + j], Y[j]);
      }
      col += texelFetch(uEnvLights, ivec2(e, 1), 0).xyz * vec3(srgbToLinear(clamp(v.r, 0.0, 1.0)), srgbToLinear(clamp(v.g, 0.0, 1.0)), srgbToLinear(clamp(v.b, 0.0, 1.0)));
    }
  }
  if (uNumLights > 0) {
    // Depth from the tiles of the level drawn where they are held (a tiled bundle),
    // otherwise from uDepth.
    vec2 at = pos;
    float depth = 0.0;
    bool gotDepth = !uHasDepth;
#if TILED
    if (!gotDepth && uLevel >= 0) gotDepth = surfaceDepth(pos, uLevelSize, true, depth, at);
#endif
    if (!gotDepth) surfaceDepth(pos, uDepthSize, false, depth, at);
    bool hasPoint = depth > 0.0;
    vec3 P = hasPoint ? surfacePoint(at, depth) : vec3(0.0);
    vec4 Y[N_LAYERS];
    for (int i = 0; i < uNumLights; i++) {
      int type = uLType[i];
      vec3 rgb = uLRgb[i], L;
      if (type >= 4) {
        // An area light (AreaLight::illuminate): n stratified samples of the emitter,
        // the strata shifted per source pixel; each sample a light vector of weight
        // area/n · cos θ_e / r². Linear maps: the samples' weights summed, one dot;
        // display-referred maps: every sample's value decoded, as the CPU engine does.
        if (!hasPoint) continue;
        int columns = int(uLCone[i].x + 0.5), rows = int(uLCone[i].y + 0.5), n = int(uLCone[i].z + 0.5);
        bool twoSided = uLCone[i].w > 0.5;
        vec2 j = cranleyPatterson(uint(t.y) * uint(uImage.x) + uint(t.x));
        vec4 S[N_LAYERS];
        for (int q = 0; q < N_LAYERS; q++) S[q] = vec4(0.0);
        vec3 v = vec3(0.0);
        float total = 0.0;
        for (int k = 0; k < MAX_AREA_SAMPLES; k++) {
          if (k >= n) break;
          float s = (float(k % columns) + j.x) / float(columns);
          float tt = (float(k / columns) + j.y) / float(rows);
          vec3 x;
          if (type == 4) {
            x = uLPos[i] + uLRight[i] * (2.0 * s - 1.0) + uLUp[i] * (2.0 * tt - 1.0);
          } else {
            float r = uLAtt[i].y * sqrt(s), phi = 2.0 * PI * tt;
            x = uLPos[i] + uLRight[i] * (r * cos(phi)) + uLUp[i] * (r * sin(phi));
          }
          vec3 d = x - P;
          float r2 = dot(d, d);
          if (!(r2 > 1e-18)) continue;
          vec3 l = d * inversesqrt(r2);
          float cosE = -dot(l, uLDir[i]);
          if (twoSided) cosE = abs(cosE);
          if (cosE <= 0.0) continue;
          float g = uLAtt[i].x * cosE / r2;
          basisWeights(l, Y);
          if (uDisplay) {
            vec3 e = vec3(0.0);
            for (int q = 0; q < N_LAYERS; q++) {
              e.r += dot(C[q], Y[q]);
              e.g += dot(C[N_LAYERS + q], Y[q]);
              e.b += dot(C[2 * N_LAYERS + q], Y[q]);
            }
            v += g * vec3(srgbToLinear(clamp(e.r, 0.0, 1.0)), srgbToLinear(clamp(e.g, 0.0, 1.0)), srgbToLinear(clamp(e.b, 0.0, 1.0)));
          } else {
            for (int q = 0; q < N_LAYERS; q++) S[q] += g * Y[q];
          }
          total += g;
        }
        if (total <= 0.0) continue;
        if (!uDisplay) {
          for (int q = 0; q < N_LAYERS; q++) {
            v.r += dot(C[q], S[q]);
            v.g += dot(C[N_LAYERS + q], S[q]);
            v.b += dot(C[2 * N_LAYERS + q], S[q]);
          }
        }
        col += rgb * v;
        continue;
      }
      if (type == 0) {
        L = uLDir[i];
      } else {
        if (!hasPoint) continue;
        vec3 toLight = uLPos[i] - P;
        float dist = length(toLight);
        if (dist <= 0.0) continue;
        L = toLight / dist;
        if (type == 2) {
          float ca = dot(-L, uLDir[i]), outer = uLCone[i].x, inner = uLCone[i].y, f;
          if (ca >= inner) f = 1.0;
          else if (ca <= outer || inner <= outer) f = 0.0;
          else { float s = (ca - outer) / (inner - outer); f = s * s * (3.0 - 2.0 * s); }
          if (f <= 0.0) continue;
          rgb *= f;
        } else if (type == 3) {
          vec3 dp = P - uLPos[i];
          float z = dot(dp, uLDir[i]);
          if (z <= 1e-9) continue;
          float sx = dot(dp, uLRight[i]) / (z * uLCone[i].x);
          float sy = dot(dp, uLUp[i]) / (z * uLCone[i].y);
          if (abs(sx) > 1.0 || abs(sy) > 1.0) continue;
          rgb *= slide(int(uLCone[i].z + 0.5), vec2((sx + 1.0) * 0.5, (1.0 - sy) * 0.5));
        }
        rgb *= attenuation(i, dist);
      }
      basisWeights(L, Y);
      vec3 v = vec3(0.0);
      for (int j = 0; j < N_LAYERS; j++) {
        v.r += dot(C[j], Y[j]);
        v.g += dot(C[N_LAYERS + j], Y[j]);
        v.b += dot(C[2 * N_LAYERS + j], Y[j]);
      }
      if (uDisplay) v = vec3(srgbToLinear(clamp(v.r, 0.0, 1.0)), srgbToLinear(clamp(v.g, 0.0, 1.0)), srgbToLinear(clamp(v.b, 0.0, 1.0)));
      col += rgb * v;
    }
  }
  col *= uExposure;
  outColor = vec4(linearToSrgb(col.r), linearToSrgb(col.g), linearToSrgb(col.b), 1.0);
}

// WebGL2 renderer: coefficient layers in a texture array, relit per screen pixel by
// relight.frag. Also the CPU-side geometry (screen -> source pixel -> surface point)
// used to place lights by clicking.
import { normalize, cross, rotationYawPitchRoll } from './vec.js';
import { weightTable, halvesToFloats, sample } from './table.js';
import { environmentWeights, windowFactors } from './environment.js';
import { lightRgb, attenuationOf } from './lights.js';

const MAX_LIGHTS = 8, MAX_SLIDES = 4;
/** Texture units: planes, depth, the slides, the weight table. */
const TABLE_UNIT = 2 + MAX_SLIDES;
// A codebook image's indices (one 16-bit entry a pixel).
const INDEX_UNIT = TABLE_UNIT + 1;
// A tiled bundle's atlas of resident tiles and the page table of the level drawn.
const ATLAS_UNIT = INDEX_UNIT + 1, PAGES_UNIT = ATLAS_UNIT + 1;
// Environment lights of display-referred maps: a float texture of two rows (directions,
// RGB), as many columns as lights (four environments of the 64 lights a bundle ships).
const ENV_UNIT = PAGES_UNIT + 1, MAX_ENV_LIGHTS = 256;
// A tiled bundle's depth of the resident tiles, in the atlas's slots.
const DEPTH_ATLAS_UNIT = ENV_UNIT + 1;
/** Tiles fetched at once. */
const TILE_FETCHES = 6;
/** Most GPU memory the atlas of tiles takes. */
const ATLAS_BYTES = 768 * 1024 * 1024;
/** Samples per area light the shader takes at most (relight.frag MAX_AREA_SAMPLES). */
export const MAX_AREA_SAMPLES = 64;

async function fetchOk(url, kind) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return kind === 'json' ? r.json() : kind === 'text' ? r.text() : kind === 'blob' ? r.blob() : r.arrayBuffer();
}

/** An area light as shader uniforms (AreaLight in crates/relit/src/light/area.rs):
 *  centre, unit normal, the two edge or axis vectors, strata and the area per sample;
 *  null for a degenerate shape. */
export function areaUniforms(light) {
  const wanted = light.samples != null ? light.samples : 16;
  const n = Math.min(wanted, MAX_AREA_SAMPLES);
  const columns = Math.ceil(Math.sqrt(n)), rows = Math.ceil(n / columns);
  const shape = light.shape || {};
  let entry;
  if (shape.rect) {
    const { center, u, v } = shape.rect;
    const c = cross(u, v), normal = normalize(c);
    if (!normal) return null;
    entry = { type: 4, pos: center, dir: normal, right: u, up: v, area: 4 * Math.hypot(...c), radius: 0 };
  } else if (shape.disk) {
    const { center, normal, radius } = shape.disk;
    const f = diskFrame(normal);
    if (!f || !(radius > 0)) return null;
    entry = { type: 5, pos: center, dir: f.n, right: f.a, up: f.b, area: Math.PI * radius * radius, radius };
  } else return null;
  entry.att = [entry.area / n, entry.radius];
  entry.cone = [columns, rows, n, light.two_sided ? 1 : 0];
  entry.capped = wanted > n;
  return entry;
}

/** A disk's unit normal n and unit axes a (φ = 0), b (φ = π/2), a × b = n: the frame of
 *  `disk_frame` in crates/relit/src/light/area.rs. */
export function diskFrame(normal) {
  const n = normalize(normal);
  if (!n) return null;
  const helper = Math.abs(n[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
  const a = normalize(cross(helper, n));
  return { n, a, b: cross(n, a) };
}

export class Renderer {
  constructor(canvas) {
    this.canvas = canvas;
    const gl = canvas.getContext('webgl2', { preserveDrawingBuffer: true, antialias: false, alpha: false, premultipliedAlpha: false });
    if (!gl) throw new Error('this browser has no WebGL2');
    this.gl = gl;
    this.slides = new Map(); // name -> { tex, aspect }
    this.envCache = new Map();
    this.warnings = [];
    /** Bilinear interpolation of the coefficients (false: nearest texel). */
    this.smooth = true;
  }

  /** Load the shaders and the data folder (`base` ends with a slash). */
  async load(base = 'data/') {
    const gl = this.gl;
    const [vs, fs, info] = await Promise.all([fetchOk('quad.vert', 'text'), fetchOk('relight.frag', 'text'), fetchOk(base + 'info.json', 'json')]);
    if (info.format !== 'relit-web') throw new Error('info.json is not a relit-web bundle');
    if (info.version !== 2) throw new Error(`info.json is version ${info.version} of the relit-web format; this viewer reads version 2`);
    this.info = info;
    // A codebook image: the layers hold the entries (info.codebook), each pixel an index.
    const book = info.codebook || null;
    this.codebook = book;
    // A tiled bundle (crates/relit-viewer/src/tiles.rs): the layers hold the overview,
    // the finer levels arrive as tiles.
    const tiles = info.tiles || null;
    this.tiles = tiles;
    const defines = `#version 300 es\n#define N_LAYERS ${info.layers_per_channel}\n#define CODEBOOK ${book ? 1 : 0}\n#define TILED ${tiles ? 1 : 0}\n`;
    this.program = this.compile(vs, fs.replace('#version 300 es\n', defines));
    this.uniforms = {};
    const n = gl.getProgramParameter(this.program, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) {
      const u = gl.getActiveUniform(this.program, i);
      const name = u.name.replace(/\[0\]$/, '');
      this.uniforms[name] = gl.getUniformLocation(this.program, u.name);
    }
    const { width: W, height: H } = info;
    const maxSide = gl.getParameter(gl.MAX_TEXTURE_SIZE);
    if (W > maxSide || H > maxSide) throw new Error(`the image (${W}×${H}) exceeds this GPU's textures (${maxSide})`);
    const layers = info.layers.length;
    // The layers' own size: the image's, the codebook's rows of entries, or the
    // overview's.
    const [LW, LH] = book ? [book.width, book.height] : tiles ? tiles.levels[tiles.overview] : [W, H];
    this.planesSize = [LW, LH];
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    this.planes = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.planes);
    const u8 = info.storage === 'u8';
    // Mipmaps for views that shrink the image (generateMipmap needs a renderable
    // format: RGBA8 always, RGBA16F with EXT_color_buffer_float; without it, level 0).
    // Entries are fetched by index, never filtered as a texture: no mipmaps for them.
    const mips = !book && (u8 || !!gl.getExtension('EXT_color_buffer_float'));
    this.mipLevels = mips ? Math.floor(Math.log2(Math.max(LW, LH))) + 1 : 1;
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, this.mipLevels, u8 ? gl.RGBA8 : gl.RGBA16F, LW, LH, layers);
    // Filtering (RGBA8 and RGBA16F are filterable in WebGL2; the shader picks the level
    // and uses texelFetch instead when smoothing is off). Panorama columns wrap around.
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, mips ? gl.LINEAR_MIPMAP_LINEAR : gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_S, this.wrapsColumns(info) ? gl.REPEAT : gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    await Promise.all(info.layers.map(async (layer, l) => {
      if (u8) {
        const blob = await fetchOk(base + layer.file, 'blob');
        const bmp = await createImageBitmap(blob, { premultiplyAlpha: 'none', colorSpaceConversion: 'none' });
        gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.planes);
        gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, l, LW, LH, 1, gl.RGBA, gl.UNSIGNED_BYTE, bmp);
        bmp.close();
      } else {
        const buf = await fetchOk(base + layer.file, 'buffer');
        if (buf.byteLength !== LW * LH * 8) throw new Error(`${layer.file}: ${buf.byteLength} bytes, expected ${LW * LH * 8}`);
        gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.planes);
        gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, l, LW, LH, 1, gl.RGBA, gl.HALF_FLOAT, new Uint16Array(buf));
      }
    }));
    if (this.mipLevels > 1) {
      gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.planes);
      gl.generateMipmap(gl.TEXTURE_2D_ARRAY);
    }
    this.indexTex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + INDEX_UNIT);
    gl.bindTexture(gl.TEXTURE_2D, this.indexTex);
    this.setNearest(gl.TEXTURE_2D);
    if (book) {
      const buf = await fetchOk(base + book.indices.file, 'buffer');
      if (buf.byteLength !== W * H * 2) throw new Error(`${book.indices.file}: ${buf.byteLength} bytes, expected ${W * H * 2}`);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.R16UI, W, H, 0, gl.RED_INTEGER, gl.UNSIGNED_SHORT, new Uint16Array(buf));
    } else {
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.R16UI, 1, 1, 0, gl.RED_INTEGER, gl.UNSIGNED_SHORT, new Uint16Array([0]));
    }
    this.depthTex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, this.depthTex);
    this.setNearest(gl.TEXTURE_2D);
    if (info.depth) {
      // The image's size, or a tiled bundle's overview's (its tiles carry the rest).
      const DW = info.depth.width || W, DH = info.depth.height || H;
      const buf = await fetchOk(base + info.depth.file, 'buffer');
      if (buf.byteLength !== DW * DH * 4) throw new Error(`${info.depth.file}: ${buf.byteLength} bytes, expected ${DW * DH * 4}`);
      this.depth = new Float32Array(buf);
      this.depthSize = [DW, DH];
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.R32F, DW, DH, 0, gl.RED, gl.FLOAT, this.depth);
    } else {
      this.depth = null;
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.R32F, 1, 1, 0, gl.RED, gl.FLOAT, new Float32Array([0]));
    }
    this.dummySlide = gl.createTexture();
    gl.activeTexture(gl.TEXTURE2);
    gl.bindTexture(gl.TEXTURE_2D, this.dummySlide);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, 1, 1, 0, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array([255, 255, 255, 255]));
    this.setNearest(gl.TEXTURE_2D);
    await this.loadTable(base);
    this.environments = new Map(await Promise.all((info.environments || []).map(async (e) => {
      const lights = new Float32Array(await fetchOk(base + e.file, 'buffer'));
      if (lights.length !== 6 * e.lights) throw new Error(`${e.file}: ${lights.length} values, expected ${6 * e.lights}`);
      return [e.map, lights];
    })));
    this.setupCamera();
    if (tiles) this.setupTiles(base);
    this.vao = gl.createVertexArray();
    return info;
  }

  /** The atlas that holds the tiles fetched (a texture array of `slots` tile-sized
   *  slots, one layer per coefficient layer), the page table of the level drawn, and
   *  the bookkeeping of which tile sits in which slot. */
  setupTiles(base) {
    const gl = this.gl, t = this.tiles, T = t.side, layers = this.info.layers.length;
    const maxSide = Math.floor(gl.getParameter(gl.MAX_TEXTURE_SIZE) / T);
    // Enough slots for twice the tiles a screen-sized (or canvas-sized, if larger)
    // view needs at 1:1, within ATLAS_BYTES and the GPU's texture size.
    const dpr = window.devicePixelRatio || 1;
    const sw = Math.max(screen.width * dpr, this.canvas.width), sh = Math.max(screen.height * dpr, this.canvas.height);
    const screenTiles = (Math.ceil(sw / T) + 1) * (Math.ceil(sh / T) + 1);
    const fit = Math.max(4, Math.floor(ATLAS_BYTES / (T * T * (8 * layers + (this.depth ? 4 : 0)))));
    const want = Math.max(4, Math.min(2 * screenTiles, fit, maxSide * maxSide));
    const perRow = Math.min(maxSide, Math.ceil(Math.sqrt(want)));
    const rows = Math.ceil(want / perRow);
    this.atlas = { perRow, slots: perRow * rows, tex: gl.createTexture() };
    gl.activeTexture(gl.TEXTURE0 + ATLAS_UNIT);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.atlas.tex);
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, 1, gl.RGBA16F, perRow * T, rows * T, layers);
    this.setNearest(gl.TEXTURE_2D_ARRAY);
    // Each tile's depth beside its coefficients, in the same slot (1×1 without depth).
    this.depthAtlas = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + DEPTH_ATLAS_UNIT);
    gl.bindTexture(gl.TEXTURE_2D, this.depthAtlas);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.R32F, this.depth ? perRow * T : 1, this.depth ? rows * T : 1);
    this.setNearest(gl.TEXTURE_2D);
    const [cols, lines] = this.tileGrid(0);
    this.pages = { data: new Uint16Array(cols * lines), tex: gl.createTexture() };
    gl.activeTexture(gl.TEXTURE0 + PAGES_UNIT);
    gl.bindTexture(gl.TEXTURE_2D, this.pages.tex);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.R16UI, cols, lines);
    this.setNearest(gl.TEXTURE_2D);
    this.tileBase = base;
    this.resident = new Map(); // "level/x/y" -> { slot, used: the last frame that needed it }
    this.freeSlots = Array.from({ length: this.atlas.slots }, (_, i) => this.atlas.slots - 1 - i);
    this.inflight = new Set();
    this.wanted = [];
    this.frame = 0;
    /** Tiles fetched and their bytes; views that needed more tiles than the atlas holds. */
    this.tileStats = { tiles: 0, bytes: 0, failed: 0, overflowed: 0 };
    /** Called when a tile arrives (the app redraws). */
    this.onTile = null;
  }

  /** Tiles across and down level `level`. */
  tileGrid(level) {
    const [w, h] = this.tiles.levels[level], T = this.tiles.side;
    return [Math.ceil(w / T), Math.ceil(h / T)];
  }

  /** The level `view` reads tiles of: the level nearest the largest footprint of a
   *  screen pixel (GL's nearest mip level), or −1 where that is the overview's or
   *  coarser (the overview then draws it all, with its own mipmaps). */
  tileLevel(view) {
    const level = Math.max(0, Math.round(Math.log2(Math.max(1, this.footprint(view)))));
    return level >= this.tiles.overview ? -1 : level;
  }

  /** The tiles of `level` the shader reads for `view`: those under the bilinear
   *  footprint of canvas points 8 pixels apart and along the edges (a tile spans tens
   *  of canvas pixels or more at the level chosen, so none falls between them). */
  visibleTiles(view, level) {
    const [lw, lh] = this.tiles.levels[level], T = this.tiles.side, W = this.info.width, H = this.info.height;
    const cw = this.canvas.width, ch = this.canvas.height, wrap = this.isPanorama;
    const keys = new Set();
    const axis = (n) => { const a = []; for (let v = 0.5; v < n; v += 8) a.push(v); if (a[a.length - 1] < n - 0.5) a.push(n - 0.5); return a; };
    const xs = axis(cw), ys = axis(ch);
    for (const cy of ys) for (const cx of xs) {
      const p = this.sourcePosition(view, cx, cy);
      if (!p) continue;
      const qx = (p[0] * lw) / W - 0.5, qy = (p[1] * lh) / H - 0.5;
      const x0 = Math.floor(qx), y0 = Math.floor(qy);
      for (const x of [x0, x0 + 1]) for (const y of [y0, y0 + 1]) {
        const tx = wrap ? ((x % lw) + lw) % lw : Math.min(lw - 1, Math.max(0, x));
        const ty = Math.min(lh - 1, Math.max(0, y));
        keys.add(`${level}/${Math.floor(tx / T)}/${Math.floor(ty / T)}`);
      }
    }
    return keys;
  }

  /** Mark the tiles `view` needs, start fetching those missing, and fill the page
   *  table of the level drawn; returns that level (−1: the overview alone). A view that
   *  needs more tiles than the atlas holds (a canvas larger than the screen it was
   *  sized for) is drawn from the next coarser level whose tiles fit, rather than
   *  evicting tiles it needs and fetching them again forever. */
  updateTiles(view) {
    const gl = this.gl;
    let level = this.tileLevel(view);
    this.frame++;
    this.wanted = [];
    if (level < 0) return level;
    let needed = this.visibleTiles(view, level);
    if (needed.size > this.atlas.slots) {
      this.tileStats.overflowed++;
      while (needed.size > this.atlas.slots && level + 1 < this.tiles.overview) needed = this.visibleTiles(view, ++level);
      if (needed.size > this.atlas.slots) return -1;
    }
    const [cols, lines] = this.tileGrid(level);
    const pages = this.pages.data.subarray(0, cols * lines).fill(0);
    for (const key of needed) {
      const r = this.resident.get(key);
      if (r) {
        r.used = this.frame;
        const [, x, y] = key.split('/').map(Number);
        pages[y * cols + x] = r.slot + 1;
      } else this.wanted.push(key);
    }
    gl.activeTexture(gl.TEXTURE0 + PAGES_UNIT);
    gl.bindTexture(gl.TEXTURE_2D, this.pages.tex);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, cols, lines, gl.RED_INTEGER, gl.UNSIGNED_SHORT, pages);
    this.pumpTiles();
    return level;
  }

  /** Whether tiles the last frame needed are still on their way. */
  tilesPending() {
    return !!this.tiles && (this.inflight.size > 0 || this.wanted.some((key) => !this.resident.has(key)));
  }

  /** Fetch wanted tiles, TILE_FETCHES at a time. */
  pumpTiles() {
    for (const key of this.wanted) {
      if (this.inflight.size >= TILE_FETCHES) break;
      if (this.inflight.has(key) || this.resident.has(key)) continue;
      this.inflight.add(key);
      this.fetchTile(key).catch((err) => {
        this.tileStats.failed++;
        this.warnings.push(`tile ${key}: ${err.message}`);
      }).finally(() => {
        this.inflight.delete(key);
        if (this.onTile) this.onTile();
        this.pumpTiles();
      });
    }
  }

  /** Fetch one tile into a free slot, or the one least recently needed (not by the last
   *  frame); a tile with no slot to go to is dropped. */
  async fetchTile(key) {
    const gl = this.gl, t = this.tiles, T = t.side, layers = this.info.layers.length;
    const [level, x, y] = key.split('/').map(Number);
    const [lw, lh] = t.levels[level];
    const tw = Math.min(T, lw - x * T), th = Math.min(T, lh - y * T);
    const url = this.tileBase + t.path.replace('{level}', level).replace('{x}', x).replace('{y}', y);
    const buf = await fetchOk(url, 'buffer');
    // The layers, then the tile's depth where the file has one (crates/relit-viewer/src/tiles.rs).
    const coefficientBytes = tw * th * 8 * layers, expected = coefficientBytes + (this.depth ? tw * th * 4 : 0);
    if (buf.byteLength !== expected) throw new Error(`${buf.byteLength} bytes, expected ${expected}`);
    this.tileStats.tiles++;
    this.tileStats.bytes += buf.byteLength;
    let slot = this.freeSlots.pop();
    if (slot === undefined) {
      let oldest = null;
      for (const [k, r] of this.resident) if (r.used < this.frame && (!oldest || r.used < oldest[1].used)) oldest = [k, r];
      if (!oldest) return;
      this.resident.delete(oldest[0]);
      slot = oldest[1].slot;
    }
    const halves = new Uint16Array(buf, 0, coefficientBytes / 2);
    const sx = (slot % this.atlas.perRow) * T, sy = Math.floor(slot / this.atlas.perRow) * T;
    gl.activeTexture(gl.TEXTURE0 + ATLAS_UNIT);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.atlas.tex);
    for (let l = 0; l < layers; l++) {
      gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, sx, sy, l, tw, th, 1, gl.RGBA, gl.HALF_FLOAT, halves.subarray(l * tw * th * 4, (l + 1) * tw * th * 4));
    }
    // Kept on the CPU too, for picking.
    const depth = this.depth ? new Float32Array(buf, coefficientBytes, tw * th) : null;
    if (depth) {
      gl.activeTexture(gl.TEXTURE0 + DEPTH_ATLAS_UNIT);
      gl.bindTexture(gl.TEXTURE_2D, this.depthAtlas);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, sx, sy, tw, th, gl.RED, gl.FLOAT, depth);
    }
    // A tile the latest frame wants is in use by it: evicting it for the next one that
    // frame wants would fetch the two in turn for ever (a view needing most slots).
    this.resident.set(key, { slot, used: this.wanted.includes(key) ? this.frame : 0, depth, width: tw });
  }

  /** The basis' weight table (half floats): decoded for directional and environment
   *  lights, and uploaded as it is for the shader, an RGBA16F array of four weights a
   *  texel, one layer per four coefficients (the layout of the coefficient layers), so
   *  that both read the same values. */
  async loadTable(base) {
    const gl = this.gl, info = this.info, wt = info.weights, k = info.k, n = info.layers_per_channel;
    if (wt.format !== 'f16le') throw new Error(`weight table format ${wt.format}`);
    const bits = new Uint16Array(await fetchOk(base + wt.file, 'buffer'));
    this.table = weightTable(wt.resolution, k, halvesToFloats(bits));
    const side = wt.resolution + 1;
    const texels = new Uint16Array(4 * side * side * n);
    for (let v = 0; v < side * side; v++) {
      for (let i = 0; i < k; i++) texels[4 * ((i >> 2) * side * side + v) + (i & 3)] = bits[v * k + i];
    }
    this.tableTex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + TABLE_UNIT);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.tableTex);
    gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGBA16F, side, side, n, 0, gl.RGBA, gl.HALF_FLOAT, texels);
    this.setNearest(gl.TEXTURE_2D_ARRAY);
  }

  wrapsColumns(info) {
    const t = info.camera.projection.type;
    return t === 'cylindrical' || t === 'equirectangular';
  }

  setNearest(target) {
    const gl = this.gl;
    gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(target, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(target, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  }

  compile(vsText, fsText) {
    const gl = this.gl;
    const shader = (type, text) => {
      const s = gl.createShader(type);
      gl.shaderSource(s, text);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error('shader: ' + gl.getShaderInfoLog(s));
      return s;
    };
    const p = gl.createProgram();
    gl.attachShader(p, shader(gl.VERTEX_SHADER, vsText));
    gl.attachShader(p, shader(gl.FRAGMENT_SHADER, fsText));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error('program: ' + gl.getProgramInfoLog(p));
    return p;
  }

  /** Camera constants of the file (crates/relit/src/camera/*.rs). */
  setupCamera() {
    const cam = this.info.camera, W = this.info.width, H = this.info.height;
    const proj = cam.projection;
    const c = { proj: 0, half: [1, 1], span: 1 };
    if (proj.type === 'planar' && proj.fov_y_deg != null) {
      c.proj = 0;
      const hh = Math.tan((proj.fov_y_deg * Math.PI) / 360);
      c.half = [hh * W / H, hh];
    } else if (proj.type === 'planar') {
      c.proj = 1;
      const hh = (cam.orthographic_height != null ? cam.orthographic_height : 2) / 2;
      c.half = [hh * W / H, hh];
    } else if (proj.type === 'cylindrical') {
      c.proj = 2;
      c.span = proj.fov_y_deg != null ? 2 * Math.tan((proj.fov_y_deg * Math.PI) / 360) : (2 * Math.PI * H) / W;
    } else {
      c.proj = 3;
    }
    const pose = cam.pose || { eye: [0, 0, 0], right: [1, 0, 0], up: [0, 1, 0], back: [0, 0, 1] };
    c.pose = pose;
    this.cam = c;
    this.isPanorama = c.proj >= 2;
  }

  /** The world ray (origin, unit dir) through continuous image position (x, y) of the
   *  file's camera (crates/relit/src/camera/*.rs), and its point at depth d. */
  rayAt(x, y, d = 0) {
    const { proj, half, span, pose } = this.cam, W = this.info.width, H = this.info.height;
    let o = [0, 0, 0], v;
    if (proj === 0) v = normalize([(2 * x / W - 1) * half[0], (1 - 2 * y / H) * half[1], -1]);
    else if (proj === 1) { o = [(2 * x / W - 1) * half[0], (1 - 2 * y / H) * half[1], 0]; v = [0, 0, -1]; }
    else if (proj === 2) {
      const phi = (x / W - 0.5) * 2 * Math.PI, h = (0.5 - y / H) * span, s = 1 / Math.sqrt(1 + h * h);
      v = [Math.sin(phi) * s, h * s, -Math.cos(phi) * s];
    } else {
      const phi = (x / W - 0.5) * 2 * Math.PI, lat = (0.5 - y / H) * Math.PI;
      v = [Math.cos(lat) * Math.sin(phi), Math.sin(lat), -Math.cos(lat) * Math.cos(phi)];
    }
    const toWorld = (p) => [0, 1, 2].map(k => pose.right[k] * p[0] + pose.up[k] * p[1] + pose.back[k] * p[2]);
    const origin = toWorld(o).map((val, k) => val + pose.eye[k]);
    const dir = toWorld(v);
    return { origin, dir, point: origin.map((val, k) => val + d * dir[k]) };
  }

  /** The view ray at canvas position (cx, cy) (canvas pixels from the top left) of the
   *  perspective view, in the panorama's camera frame (not unit length). */
  viewRay(view, cx, cy) {
    const cw = this.canvas.width, ch = this.canvas.height;
    const m = this.viewMatrix(view), t = Math.tan((view.fov * Math.PI) / 360);
    const nx = ((2 * cx - cw) / ch) * t, ny = -((2 * cy - ch) / ch) * t;
    return [0, 1, 2].map(k => m[0][k] * nx + m[1][k] * ny + m[2][k]);
  }

  /** The continuous source position shown at canvas position (cx, cy), or null: the
   *  same mapping as relight.frag's sourcePosition. */
  sourcePosition(view, cx, cy) {
    const W = this.info.width, H = this.info.height, cw = this.canvas.width, ch = this.canvas.height;
    const wrap = (x) => { x -= W * Math.floor(x / W); return x >= W ? 0 : x; };
    let px, py;
    if (view.mode === 'flat' || !this.isPanorama) {
      px = view.center[0] + (cx - 0.5 * cw) / view.zoom;
      py = view.center[1] + (cy - 0.5 * ch) / view.zoom;
      if (this.isPanorama) px = wrap(px);
    } else {
      const d = this.viewRay(view, cx, cy);
      const r = Math.hypot(d[0], d[2]);
      px = wrap((Math.atan2(d[0], -d[2]) / (2 * Math.PI) + 0.5) * W);
      py = this.cam.proj === 3 ? (0.5 - Math.atan2(d[1], r) / Math.PI) * H : (0.5 - d[1] / r / this.cam.span) * H;
    }
    if (!(px >= 0 && py >= 0 && px < W && py < H)) return null;
    return [px, py];
  }

  /** The source pixel shown at canvas position (canvas pixels), or null. */
  sourcePixel(view, cx, cy) {
    const p = this.sourcePosition(view, cx, cy);
    return p && [Math.floor(p[0]), Math.floor(p[1])];
  }

  /** The direction (world, unit, toward the light) a directional light aimed at canvas
   *  position (cx, cy) gets: on a panorama the camera ray seen there (the light comes
   *  from where you point, depth or not); on a planar image the light-sphere mapping
   *  of the canvas (centre: toward the camera, the shorter side's edge: grazing). */
  directionAt(view, cx, cy) {
    const pose = this.cam.pose;
    const toWorld = (p) => [0, 1, 2].map(k => pose.right[k] * p[0] + pose.up[k] * p[1] + pose.back[k] * p[2]);
    if (this.isPanorama) {
      if (view.mode !== 'flat') return normalize(toWorld(this.viewRay(view, cx, cy)));
      const p = this.sourcePosition(view, cx, cy);
      return p ? this.rayAt(p[0], p[1]).dir : null;
    }
    const cw = this.canvas.width, ch = this.canvas.height, s = Math.min(cw, ch) / 2;
    let x = (cx - cw / 2) / s, y = -(cy - ch / 2) / s;
    const r = Math.hypot(x, y);
    if (r > 1) { x /= r; y /= r; }
    return normalize(toWorld([x, y, Math.sqrt(Math.max(0, 1 - x * x - y * y))]));
  }

  /** Columns right, up, forward of the view camera in the panorama's camera frame. */
  viewMatrix(view) {
    const yaw = (view.yaw * Math.PI) / 180, pitch = (view.pitch * Math.PI) / 180;
    const f = [Math.sin(yaw) * Math.cos(pitch), Math.sin(pitch), -Math.cos(yaw) * Math.cos(pitch)];
    const r = normalize(cross(f, [0, 1, 0])) || [1, 0, 0];
    const u = cross(r, f);
    return [r, u, f];
  }

  /** Depth and surface point at canvas position, or null where nothing was hit. */
  pick(view, cx, cy) {
    const p = this.sourcePosition(view, cx, cy);
    if (!p) return null;
    const px = [Math.floor(p[0]), Math.floor(p[1])];
    const at = this.depthAt(p);
    if (!at || !(at.depth > 0)) return { pixel: px, depth: 0 };
    return { pixel: px, depth: at.depth, ...this.rayAt(at.x, at.y, at.depth) };
  }

  /** The depth at image position p as relight.frag reads it unsmoothed, and the image
   *  position of its texel's centre: from the tile of the level drawn where it is held,
   *  otherwise from the depth texture (level 0's, or a tiled bundle's overview's). */
  depthAt(p) {
    if (!this.depth) return null;
    const W = this.info.width, H = this.info.height;
    const texel = (size, read) => {
      // Level 0's texel exactly as floor(p) (a scaling there could round across an edge).
      const at = (v, n, full) => Math.min(Math.floor(n === full ? v : (v * n) / full), n - 1);
      const tx = at(p[0], size[0], W), ty = at(p[1], size[1], H);
      const depth = read(tx, ty);
      return depth === undefined ? null : { depth, x: ((tx + 0.5) * W) / size[0], y: ((ty + 0.5) * H) / size[1] };
    };
    const level = this.tiles ? this.drawnLevel : -1;
    if (level >= 0) {
      const T = this.tiles.side;
      const held = texel(this.tiles.levels[level], (tx, ty) => {
        const r = this.resident.get(`${level}/${Math.floor(tx / T)}/${Math.floor(ty / T)}`);
        return r && r.depth ? r.depth[(ty % T) * r.width + (tx % T)] : undefined;
      });
      if (held) return held;
    }
    return texel(this.depthSize, (tx, ty) => this.depth[ty * this.depthSize[0] + tx]);
  }

  /** Load a slide image (URL or Blob) for projectors under `name`. */
  async loadSlide(name, source) {
    const gl = this.gl;
    const blob = source instanceof Blob ? source : await fetchOk(source, 'blob');
    const bmp = await createImageBitmap(blob, { premultiplyAlpha: 'none', colorSpaceConversion: 'none' });
    const tex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE2);
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.SRGB8_ALPHA8, gl.RGBA, gl.UNSIGNED_BYTE, bmp);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    this.slides.set(name, { tex, aspect: bmp.width / bmp.height });
    bmp.close();
  }

  /** An environment light's weights (colour aside): its quadrature turned by
   *  yaw/pitch/roll, times the window's factors (`window`: those of environment.js
   *  `windowFactors`, or null). */
  envWeights(light, window) {
    const env = this.environments.get(light.map);
    if (!env) return null;
    const key = JSON.stringify([light.map, light.yaw_deg || 0, light.pitch_deg || 0, light.roll_deg || 0, window]);
    if (!this.envCache.has(key)) {
      if (this.envCache.size > 64) this.envCache.clear();
      const R = rotationYawPitchRoll(light.yaw_deg || 0, light.pitch_deg || 0, light.roll_deg || 0);
      const e = environmentWeights(this.table, env, R);
      if (window) for (const w of e) for (let i = 0; i < w.length; i++) w[i] *= window[i];
      this.envCache.set(key, e);
    }
    return this.envCache.get(key);
  }

  /** Turn a rig into shader uniforms: uniform lights folded into one weight per plane,
   *  lights with a position passed one by one. */
  prepare(rig) {
    const info = this.info, k = info.k, n = info.layers_per_channel;
    const display = info.color_space === 'srgb';
    const w = [new Float64Array(k), new Float64Array(k), new Float64Array(k)];
    let hasUniform = false;
    const pos = [];
    // Display-referred maps: environment lights as [direction, rgb] pairs.
    const envLights = [];
    const warnings = [];
    rig.lights.forEach((light, idx) => {
      const rgb = lightRgb(light);
      if (light.type === 'directional') {
        const L = normalize(light.direction);
        if (!L) { warnings.push(`light ${idx + 1}: zero direction`); return; }
        if (display) { pos.push({ type: 0, dir: L, rgb }); return; }
        const y = sample(this.table, L);
        for (let c = 0; c < 3; c++) for (let i = 0; i < k; i++) w[c][i] += rgb[c] * y[i];
        hasUniform = true;
      } else if (light.type === 'environment' && display) {
        // Display-referred maps: the bundle ships the environment's median-cut lights,
        // each decoded on its own in the shader (no window: it weighs a projection's bands).
        const env = this.environments.get(light.map);
        if (!env) { warnings.push(`light ${idx + 1}: environment map “${light.map}” is not in this bundle`); return; }
        const R = rotationYawPitchRoll(light.yaw_deg || 0, light.pitch_deg || 0, light.roll_deg || 0);
        for (let o = 0; o < env.length; o += 6) {
          const x = env[o], y = env[o + 1], z = env[o + 2];
          envLights.push([R[0][0] * x + R[0][1] * y + R[0][2] * z, R[1][0] * x + R[1][1] * y + R[1][2] * z, R[2][0] * x + R[2][1] * y + R[2][2] * z],
            [rgb[0] * env[o + 3], rgb[1] * env[o + 4], rgb[2] * env[o + 5]]);
        }
      } else if (light.type === 'environment') {
        let window;
        try { window = windowFactors(info.basis.windows, light.window, info.basis.name); } catch (err) { warnings.push(`light ${idx + 1}: ${err.message}`); return; }
        const e = this.envWeights(light, window);
        if (!e) { warnings.push(`light ${idx + 1}: environment map “${light.map}” is not in this bundle`); return; }
        for (let c = 0; c < 3; c++) for (let i = 0; i < k; i++) w[c][i] += rgb[c] * e[c][i];
        hasUniform = true;
      } else if (light.type === 'point' || light.type === 'spot' || light.type === 'projector') {
        if (!this.depth) { warnings.push(`light ${idx + 1}: ${light.type} lights need a depth map, this file has none`); return; }
        const att = attenuationOf(light.attenuation);
        const entry = { pos: light.position, rgb, att, dir: [0, 0, 1], cone: [0, 0, 0, 0], right: [1, 0, 0], up: [0, 1, 0] };
        if (light.type === 'point') entry.type = 1;
        else if (light.type === 'spot') {
          entry.type = 2;
          entry.dir = normalize(light.direction) || [0, -1, 0];
          const soft = light.softness_deg != null ? light.softness_deg : 5;
          entry.cone = [Math.cos((light.cone_deg * Math.PI) / 180), Math.cos((Math.max(0, light.cone_deg - soft) * Math.PI) / 180), 0, 0];
        } else {
          const s = this.slides.get(light.slide);
          if (!s) { warnings.push(`light ${idx + 1}: load the slide “${light.slide}” to see this projector`); return; }
          const slot = [...this.slides.keys()].indexOf(light.slide);
          if (slot >= MAX_SLIDES) { warnings.push(`light ${idx + 1}: at most ${MAX_SLIDES} slides`); return; }
          entry.type = 3;
          const f = normalize(light.direction) || [0, 0, -1];
          const r = normalize(cross(f, light.up || [0, 1, 0])) || [1, 0, 0];
          entry.dir = f; entry.right = r; entry.up = cross(r, f);
          const ty = Math.tan((light.fov_deg * Math.PI) / 360);
          entry.cone = [ty * s.aspect, ty, slot, 0];
        }
        pos.push(entry);
      } else if (light.type === 'area') {
        if (!this.depth) { warnings.push(`light ${idx + 1}: area lights need a depth map, this file has none`); return; }
        const a = areaUniforms(light);
        if (!a) { warnings.push(`light ${idx + 1}: the area light's shape is degenerate`); return; }
        if (a.capped) warnings.push(`light ${idx + 1}: ${light.samples} samples, the viewer takes at most ${MAX_AREA_SAMPLES} (relit relight takes them all)`);
        pos.push({ ...a, rgb });
      } else {
        warnings.push(`light ${idx + 1}: ${light.type} lights are not shown by the viewer`);
      }
    });
    if (pos.length > MAX_LIGHTS) { warnings.push(`only the first ${MAX_LIGHTS} lights with a position are shown`); pos.length = MAX_LIGHTS; }
    const uw = new Float32Array(4 * 3 * n);
    for (let c = 0; c < 3; c++) for (let i = 0; i < k; i++) uw[4 * (c * n) + i] = w[c][i];
    if (envLights.length / 2 > MAX_ENV_LIGHTS) { warnings.push(`only the first ${MAX_ENV_LIGHTS} environment lights are shown`); envLights.length = 2 * MAX_ENV_LIGHTS; }
    this.prepared = { uw, hasUniform, pos, display, envLights };
    this.warnings = warnings;
    return warnings;
  }

  /** Whether `view` shrinks the image enough to need mipmaps: flat views below 1:1;
   *  perspective views where the largest footprint found on a grid of canvas points
   *  (one-pixel differences, columns unwrapped) exceeds √2 texels, i.e. where a GL
   *  nearest-mip filter would leave level 0 (the rectilinear view always stretches its
   *  edges a little past 1:1). */
  minifies(view) {
    return this.footprint(view) > ((view.mode === 'flat' || !this.isPanorama) ? 1 : Math.SQRT2);
  }

  /** The largest footprint of a canvas pixel, in image pixels: 1 / zoom for flat views;
   *  for perspective views the largest found on a grid of canvas points (one-pixel
   *  differences, columns unwrapped). */
  footprint(view) {
    if (view.mode === 'flat' || !this.isPanorama) return 1 / view.zoom;
    const W = this.info.width, cw = this.canvas.width, ch = this.canvas.height;
    const unwrap = (d) => (d > W / 2 ? d - W : d < -W / 2 ? d + W : d);
    let most = 0;
    for (let gy = 0; gy <= 6; gy++) for (let gx = 0; gx <= 8; gx++) {
      const cx = 0.5 + (gx / 8) * (cw - 2), cy = 0.5 + (gy / 6) * (ch - 2);
      const p = this.sourcePosition(view, cx, cy);
      if (!p) continue;
      for (const [ex, ey] of [[1, 0], [0, 1]]) {
        const q = this.sourcePosition(view, cx + ex, cy + ey);
        if (q) most = Math.max(most, Math.hypot(unwrap(q[0] - p[0]), q[1] - p[1]));
      }
    }
    return most;
  }

  /** Draw one frame of `view` with the rig last prepared; `exposure` in stops. */
  draw(view, exposure = 0, background = [0.08, 0.08, 0.09]) {
    const gl = this.gl, U = this.uniforms, info = this.info, p = this.prepared;
    const n = info.layers_per_channel;
    gl.viewport(0, 0, this.canvas.width, this.canvas.height);
    gl.useProgram(this.program);
    gl.bindVertexArray(this.vao);
    const set = (name, fn, ...args) => { if (U[name] != null) gl[fn](U[name], ...args); };
    gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.planes);
    // Trilinear only where the view shrinks the image (it reads twice the texels);
    // bilinear from level 0 otherwise, whatever level the shader asks for.
    // A tiled bundle's overview stands in for the finer levels: its mipmaps always on.
    const minify = this.mipLevels > 1 && this.smooth && this.minifies(view);
    const trilinear = minify || (this.tiles && this.mipLevels > 1);
    if (trilinear !== this.trilinear) {
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, trilinear ? gl.LINEAR_MIPMAP_LINEAR : gl.LINEAR);
      this.trilinear = trilinear;
    }
    this.minifying = minify;
    const level = this.tiles ? this.updateTiles(view) : -1;
    this.drawnLevel = level;
    gl.activeTexture(gl.TEXTURE1); gl.bindTexture(gl.TEXTURE_2D, this.depthTex);
    set('uPlanes', 'uniform1i', 0);
    set('uDepth', 'uniform1i', 1);
    const slideTex = [...this.slides.values()];
    for (let s = 0; s < MAX_SLIDES; s++) {
      gl.activeTexture(gl.TEXTURE2 + s);
      gl.bindTexture(gl.TEXTURE_2D, slideTex[s] ? slideTex[s].tex : this.dummySlide);
      set('uSlide' + s, 'uniform1i', 2 + s);
    }
    gl.activeTexture(gl.TEXTURE0 + TABLE_UNIT); gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.tableTex);
    set('uTable', 'uniform1i', TABLE_UNIT);
    gl.activeTexture(gl.TEXTURE0 + INDEX_UNIT); gl.bindTexture(gl.TEXTURE_2D, this.indexTex);
    set('uIndices', 'uniform1i', INDEX_UNIT);
    set('uTableN', 'uniform1i', this.table.n);
    // value = offset + scale · q; an 8-bit layer's sampler returns q / 255.
    const perTexel = info.storage === 'u8' ? 255 : 1;
    const scale = new Float32Array(4 * 3 * n), offset = new Float32Array(4 * 3 * n);
    info.layers.forEach((l, i) => { scale.set(l.scale.map(s => s * perTexel), 4 * i); offset.set(l.offset, 4 * i); });
    set('uScale', 'uniform4fv', scale);
    set('uOffset', 'uniform4fv', offset);
    set('uW', 'uniform4fv', p.uw);
    set('uHasUniform', 'uniform1i', p.hasUniform ? 1 : 0);
    set('uDisplay', 'uniform1i', p.display ? 1 : 0);
    set('uHasDepth', 'uniform1i', this.depth ? 1 : 0);
    if (this.depth) set('uDepthSize', 'uniform2f', ...this.depthSize);
    set('uImage', 'uniform2f', info.width, info.height);
    set('uSmooth', 'uniform1i', this.smooth ? 1 : 0);
    // Levels between the image and the planes texture (a tiled bundle's overview).
    const planesLod = this.tiles ? this.tiles.overview : 0;
    set('uMaxLod', 'uniform1f', this.minifying ? planesLod + this.mipLevels - 1 : 0);
    set('uPlanesSize', 'uniform2f', ...this.planesSize);
    set('uPlanesLod', 'uniform1f', planesLod);
    if (this.tiles) {
      gl.activeTexture(gl.TEXTURE0 + ATLAS_UNIT); gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.atlas.tex);
      gl.activeTexture(gl.TEXTURE0 + PAGES_UNIT); gl.bindTexture(gl.TEXTURE_2D, this.pages.tex);
      set('uAtlas', 'uniform1i', ATLAS_UNIT);
      set('uPages', 'uniform1i', PAGES_UNIT);
      set('uLevel', 'uniform1i', level);
      if (level >= 0) set('uLevelSize', 'uniform2f', ...this.tiles.levels[level]);
      set('uTileSide', 'uniform1i', this.tiles.side);
      set('uSlotsPerRow', 'uniform1i', this.atlas.perRow);
      gl.activeTexture(gl.TEXTURE0 + DEPTH_ATLAS_UNIT); gl.bindTexture(gl.TEXTURE_2D, this.depthAtlas);
      set('uDepthAtlas', 'uniform1i', DEPTH_ATLAS_UNIT);
    }
    const flat = view.mode === 'flat' || !this.isPanorama;
    set('uViewMode', 'uniform1i', flat ? 0 : 1);
    set('uCanvas', 'uniform2f', this.canvas.width, this.canvas.height);
    set('uCenter', 'uniform2f', view.center[0], view.center[1]);
    set('uZoom', 'uniform1f', view.zoom);
    set('uWrapX', 'uniform1i', this.isPanorama ? 1 : 0);
    const m = this.viewMatrix(view);
    set('uView', 'uniformMatrix3fv', false, new Float32Array([...m[0], ...m[1], ...m[2]]));
    set('uTanHalfFov', 'uniform1f', Math.tan((view.fov * Math.PI) / 360));
    const c = this.cam;
    set('uProj', 'uniform1i', c.proj);
    set('uHalf', 'uniform2f', c.half[0], c.half[1]);
    set('uSpan', 'uniform1f', c.span);
    set('uEye', 'uniform3fv', new Float32Array(c.pose.eye));
    set('uPose', 'uniformMatrix3fv', false, new Float32Array([...c.pose.right, ...c.pose.up, ...c.pose.back]));
    set('uExposure', 'uniform1f', Math.pow(2, exposure));
    set('uBackground', 'uniform3f', ...background);
    const L = p.pos, N = L.length;
    set('uNumLights', 'uniform1i', N);
    const E = p.envLights.length / 2;
    set('uNumEnv', 'uniform1i', E);
    gl.activeTexture(gl.TEXTURE0 + ENV_UNIT);
    if (!this.envTex) { this.envTex = gl.createTexture(); gl.bindTexture(gl.TEXTURE_2D, this.envTex); this.setNearest(gl.TEXTURE_2D); }
    gl.bindTexture(gl.TEXTURE_2D, this.envTex);
    const texels = new Float32Array(4 * 2 * Math.max(E, 1));
    for (let e = 0; e < E; e++) { texels.set(p.envLights[2 * e], 4 * e); texels.set(p.envLights[2 * e + 1], 4 * (E + e)); }
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, Math.max(E, 1), 2, 0, gl.RGBA, gl.FLOAT, texels);
    set('uEnvLights', 'uniform1i', ENV_UNIT);
    if (N > 0) {
      const f3 = (key) => new Float32Array(L.flatMap(e => e[key]));
      set('uLType', 'uniform1iv', new Int32Array(L.map(e => e.type)));
      set('uLPos', 'uniform3fv', new Float32Array(L.flatMap(e => e.pos || [0, 0, 0])));
      set('uLDir', 'uniform3fv', f3('dir'));
      set('uLRgb', 'uniform3fv', f3('rgb'));
      set('uLAtt', 'uniform2fv', new Float32Array(L.flatMap(e => e.att || [2, 0])));
      set('uLCone', 'uniform4fv', f3('cone'));
      set('uLRight', 'uniform3fv', new Float32Array(L.flatMap(e => e.right || [1, 0, 0])));
      set('uLUp', 'uniform3fv', new Float32Array(L.flatMap(e => e.up || [0, 1, 0])));
    }
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }

  /** Wait for the GPU (a one-pixel read-back). */
  finish() {
    const gl = this.gl, px = new Uint8Array(4);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
  }

  /** The canvas as RGBA bytes, top row first. */
  readPixels() {
    const gl = this.gl, w = this.canvas.width, h = this.canvas.height;
    const buf = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, buf);
    const out = new Uint8Array(w * h * 4);
    for (let y = 0; y < h; y++) out.set(buf.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    return out;
  }
}

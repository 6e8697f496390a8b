// End-to-end test of `relit view` in headless Chromium (SwiftShader WebGL2), driven by
// Playwright through the page's own controls (DOM, mouse, touch, keyboard): reads the
// canvas back and compares it with `relit relight` (the CPU engine) for the same rig,
// checks the geometry of the perspective views and of lights placed on the image
// against the camera models (crates/relit/src/camera), measures frame times and saves
// a screenshot.
//
//   node viewer.test.mjs --relit target/release/relit --out target/viewer-test \
//        --playwright target/viewer-node [--chromium /usr/bin/chromium] [--only a,b]
//
// Tolerances (8-bit sRGB, all pixels and channels): PSNR ≥ 40 dB against the CPU
// engine at native resolution for every light type, area lights included (35 dB for the projector, whose
// slide the browser and the CPU sample differently at its edges); perspective views
// against a resampling of the CPU image through the camera model: ≥ 99 % of samples
// within 2 levels (nearest texel; the rest are texel-boundary ties between f32 and f64)
// and the centre column within 2 levels at 1:1 (bilinear); positions from clicks
// within 2e-4 (the panel rounds to 1e-4).
import { createRequire } from 'node:module';
import { spawn, execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import net from 'node:net';
import path from 'node:path';
import zlib from 'node:zlib';
import http from 'node:http';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith('--') ? acc.concat([[a.slice(2), all[i + 1]]]) : acc), []));
const relit = path.resolve(args.relit || 'target/release/relit');
const out = path.resolve(args.out || 'target/viewer-test');
const chromiumPath = args.chromium || '/usr/bin/chromium';
const only = args.only ? new Set(args.only.split(',')) : null;
const require = createRequire(path.resolve(args.playwright || 'target/viewer-node') + '/');
const { chromium } = require('playwright-core');
const MIN_PSNR = 40;

fs.rmSync(out, { recursive: true, force: true });
fs.mkdirSync(out, { recursive: true });
const log = (...a) => console.log('[viewer-test]', ...a);
const run = (...a) => execFileSync(relit, a, { stdio: ['ignore', 'pipe', 'inherit'] }).toString();

// ---- PNG decoding (8-bit RGB/RGBA, non-interlaced: what relit and Chromium write) ----
function decodePng(buf) {
  let pos = 8, w, h, ct, idat = [];
  while (pos < buf.length) {
    const len = buf.readUInt32BE(pos), type = buf.toString('ascii', pos + 4, pos + 8), data = buf.subarray(pos + 8, pos + 8 + len);
    if (type === 'IHDR') {
      w = data.readUInt32BE(0); h = data.readUInt32BE(4); ct = data[9];
      if (data[8] !== 8 || data[12] !== 0 || (ct !== 2 && ct !== 6)) throw new Error('unsupported PNG');
    } else if (type === 'IDAT') idat.push(data);
    pos += 12 + len;
  }
  const bpp = ct === 6 ? 4 : 3, stride = w * bpp, raw = zlib.inflateSync(Buffer.concat(idat));
  const px = new Uint8Array(w * h * bpp);
  for (let y = 0; y < h; y++) {
    const f = raw[y * (stride + 1)], line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let x = 0; x < stride; x++) {
      const a = x >= bpp ? px[y * stride + x - bpp] : 0, b = y > 0 ? px[(y - 1) * stride + x] : 0, c = x >= bpp && y > 0 ? px[(y - 1) * stride + x - bpp] : 0;
      let v = line[x];
      if (f === 1) v += a; else if (f === 2) v += b; else if (f === 3) v += (a + b) >> 1;
      else if (f === 4) { const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c); v += pa <= pb && pa <= pc ? a : pb <= pc ? b : c; }
      px[y * stride + x] = v & 255;
    }
  }
  const rgb = new Uint8Array(w * h * 3);
  for (let i = 0; i < w * h; i++) for (let k = 0; k < 3; k++) rgb[3 * i + k] = px[bpp * i + k];
  return { w, h, rgb };
}

function encodePng(w, h, rgb) {
  const crcTable = Array.from({ length: 256 }, (_, n) => { let c = n; for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1; return c >>> 0; });
  const crc = (b) => { let c = 0xffffffff; for (const x of b) c = crcTable[(c ^ x) & 255] ^ (c >>> 8); return (c ^ 0xffffffff) >>> 0; };
  const chunk = (type, data) => { const len = Buffer.alloc(4); len.writeUInt32BE(data.length); const td = Buffer.concat([Buffer.from(type), data]); const c = Buffer.alloc(4); c.writeUInt32BE(crc(td)); return Buffer.concat([len, td, c]); };
  const ihdr = Buffer.alloc(13); ihdr.writeUInt32BE(w, 0); ihdr.writeUInt32BE(h, 4); ihdr[8] = 8; ihdr[9] = 2;
  const raw = Buffer.alloc(h * (3 * w + 1));
  for (let y = 0; y < h; y++) Buffer.from(rgb.subarray(3 * w * y, 3 * w * (y + 1))).copy(raw, y * (3 * w + 1) + 1);
  return Buffer.concat([Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]), chunk('IHDR', ihdr), chunk('IDAT', zlib.deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]);
}

/** A Radiance .hdr (flat RGBE scanlines): `sky` above the horizon, `ground` below, a
 *  bright disc `sun` at (u, v) of radius r. */
function writeHdr(file, w, h, { sky, ground, sun, at, r }) {
  const head = Buffer.from(`#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y ${h} +X ${w}\n`);
  const px = Buffer.alloc(w * h * 4);
  for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
    const v = (y + 0.5) / h, u = (x + 0.5) / w;
    let c = v < 0.5 ? sky : ground;
    if (Math.hypot(u - at[0], v - at[1]) < r) c = sun;
    const m = Math.max(...c), e = Math.ceil(Math.log2(m) + 1e-9), s = 256 / 2 ** e;
    const o = 4 * (y * w + x);
    px[o] = Math.min(255, Math.floor(c[0] * s)); px[o + 1] = Math.min(255, Math.floor(c[1] * s)); px[o + 2] = Math.min(255, Math.floor(c[2] * s)); px[o + 3] = e + 128;
    if (px[o] === 2 && px[o + 1] === 2) px[o + 1] = 3; // never look like an RLE marker
  }
  fs.writeFileSync(file, Buffer.concat([head, px]));
}

function compare(a, b) {
  if (a.length !== b.length) throw new Error(`sizes differ: ${a.length} vs ${b.length}`);
  let se = 0, max = 0, over2 = 0;
  for (let i = 0; i < a.length; i++) { const d = Math.abs(a[i] - b[i]); se += d * d; if (d > max) max = d; if (d > 2) over2++; }
  const mse = se / a.length;
  return { psnr: mse === 0 ? Infinity : 10 * Math.log10((255 * 255) / mse), max_abs: max, frac_over_2: over2 / a.length };
}
const meanAbsDiff = (a, b) => { let s = 0; for (let i = 0; i < a.length; i++) s += Math.abs(a[i] - b[i]); return s / a.length; };

/** CPU seconds (user + system) used so far by this process's descendants: the browser's
 *  processes (SwiftShader's threads among them) and the servers (idle while frames are
 *  timed). Linux /proc; 0 elsewhere. */
function browserCpuSeconds() {
  if (!fs.existsSync('/proc/self/stat')) return 0;
  const parent = new Map(), ticks = new Map();
  for (const d of fs.readdirSync('/proc')) {
    if (!/^\d+$/.test(d)) continue;
    try {
      const st = fs.readFileSync(`/proc/${d}/stat`, 'utf8');
      const f = st.slice(st.lastIndexOf(')') + 2).split(' ');
      parent.set(+d, +f[1]); ticks.set(+d, +f[11] + +f[12]);
    } catch { /* the process ended */ }
  }
  let sum = 0;
  for (const [pid, t] of ticks) {
    for (let p = parent.get(pid), hops = 0; p > 1 && hops < 64; p = parent.get(p), hops++) if (p === process.pid) { sum += t; break; }
  }
  return sum / 100;
}

// ---- the camera models (crates/relit/src/camera/*.rs), written out independently ----
const TAU = 2 * Math.PI;
const norm3 = (v) => { const n = Math.hypot(...v); return v.map(x => x / n); };
const cross3 = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
/** The world ray through continuous image position (x, y) of `info`'s camera. */
function cameraRay(info, x, y) {
  const cam = info.camera, W = info.width, H = info.height, proj = cam.projection;
  let v;
  if (proj.type === 'cylindrical') {
    const span = proj.fov_y_deg != null ? 2 * Math.tan(proj.fov_y_deg * Math.PI / 360) : TAU * H / W;
    const phi = (x / W - 0.5) * TAU, h = (0.5 - y / H) * span;
    v = [Math.sin(phi), h, -Math.cos(phi)].map(c => c / Math.sqrt(1 + h * h));
  } else if (proj.type === 'equirectangular') {
    const phi = (x / W - 0.5) * TAU, lat = (0.5 - y / H) * Math.PI;
    v = [Math.cos(lat) * Math.sin(phi), Math.sin(lat), -Math.cos(lat) * Math.cos(phi)];
  } else {
    const hh = Math.tan(proj.fov_y_deg * Math.PI / 360), hw = hh * W / H;
    v = norm3([(2 * x / W - 1) * hw, (1 - 2 * y / H) * hh, -1]);
  }
  const p = cam.pose;
  const world = (q) => [0, 1, 2].map(k => p.right[k] * q[0] + p.up[k] * q[1] + p.back[k] * q[2]);
  return { origin: p.eye, dir: world(v) };
}
/** The panorama position of a camera-frame direction d (Camera::pixel), or null. */
function panoramaPixel(info, d) {
  const W = info.width, H = info.height, proj = info.camera.projection, r = Math.hypot(d[0], d[2]);
  let x = (Math.atan2(d[0], -d[2]) / TAU + 0.5) * W;
  if (x >= W) x -= W;
  let y;
  if (proj.type === 'cylindrical') {
    const span = proj.fov_y_deg != null ? 2 * Math.tan(proj.fov_y_deg * Math.PI / 360) : TAU * H / W;
    y = (0.5 - d[1] / r / span) * H;
  } else y = (0.5 - Math.atan2(d[1], r) / Math.PI) * H;
  return y >= 0 && y < H ? [x, y] : null;
}
/** A pinhole view turned by yaw (about up, toward +x) and pitch (up), vertical field of
 *  view fov: the camera-frame ray through canvas position (cx, cy). */
function pinholeRay(yawDeg, pitchDeg, fovDeg, cw, ch, cx, cy) {
  const yaw = yawDeg * Math.PI / 180, pitch = pitchDeg * Math.PI / 180, t = Math.tan(fovDeg * Math.PI / 360);
  const f = [Math.sin(yaw) * Math.cos(pitch), Math.sin(pitch), -Math.cos(yaw) * Math.cos(pitch)];
  const r = norm3(cross3(f, [0, 1, 0])), u = cross3(r, f);
  const nx = (2 * cx - cw) / ch * t, ny = -(2 * cy - ch) / ch * t;
  return [0, 1, 2].map(k => r[k] * nx + u[k] * ny + f[k]);
}
const BACKGROUND = [20, 20, 23]; // the viewer's background, 0.08, 0.08, 0.09 × 255
/** The CPU image `img` seen through the perspective view: nearest texel. */
function resampleView(info, img, view, cw, ch) {
  const outPx = new Uint8Array(cw * ch * 3);
  for (let j = 0; j < ch; j++) for (let i = 0; i < cw; i++) {
    const p = panoramaPixel(info, pinholeRay(view.yaw, view.pitch, view.fov, cw, ch, i + 0.5, j + 0.5));
    const o = 3 * (j * cw + i);
    if (!p) { outPx.set(BACKGROUND, o); continue; }
    const s = 3 * (Math.floor(p[1]) * img.w + Math.floor(p[0]));
    outPx.set(img.rgb.subarray(s, s + 3), o);
  }
  return outPx;
}
const srgbToLinear = (v) => (v <= 0.04045 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4);
const linearToSrgb8 = (v) => { v = Math.min(1, Math.max(0, v)); return Math.round(255 * (v <= 0.0031308 ? v * 12.92 : 1.055 * v ** (1 / 2.4) - 0.055)); };
/** The CPU image magnified in the flat view (centre, zoom), bilinear in linear light
 *  (smooth) or nearest texel, columns wrapping. */
function magnify(img, center, zoom, cw, ch, smooth) {
  const lin = Float64Array.from(img.rgb, (v) => srgbToLinear(v / 255));
  const outPx = new Uint8Array(cw * ch * 3);
  const at = (x, y, k) => lin[3 * (Math.min(img.h - 1, Math.max(0, y)) * img.w + (((x % img.w) + img.w) % img.w)) + k];
  for (let j = 0; j < ch; j++) for (let i = 0; i < cw; i++) {
    const px = center[0] + (i + 0.5 - cw / 2) / zoom, py = center[1] + (j + 0.5 - ch / 2) / zoom;
    for (let k = 0; k < 3; k++) {
      let v;
      if (smooth) {
        const qx = px - 0.5, qy = py - 0.5, x0 = Math.floor(qx), y0 = Math.floor(qy), fx = qx - x0, fy = qy - y0;
        v = (1 - fy) * ((1 - fx) * at(x0, y0, k) + fx * at(x0 + 1, y0, k)) + fy * ((1 - fx) * at(x0, y0 + 1, k) + fx * at(x0 + 1, y0 + 1, k));
        outPx[3 * (j * cw + i) + k] = linearToSrgb8(v);
      } else outPx[3 * (j * cw + i) + k] = img.rgb[3 * (Math.floor(py) * img.w + Math.floor(px)) + k];
    }
  }
  return outPx;
}

/** The CPU image shrunk by `f` (a power of two): f×f box averages in linear light, what
 *  the mip level log2(f) of the coefficients relights to. */
function shrink(img, f) {
  const w = img.w / f, h = img.h / f, outPx = new Uint8Array(w * h * 3);
  for (let j = 0; j < h; j++) for (let i = 0; i < w; i++) for (let k = 0; k < 3; k++) {
    let sum = 0;
    for (let y = 0; y < f; y++) for (let x = 0; x < f; x++) sum += srgbToLinear(img.rgb[3 * ((j * f + y) * img.w + i * f + x) + k] / 255);
    outPx[3 * (j * w + i) + k] = linearToSrgb8(sum / (f * f));
  }
  return outPx;
}

// ---- the scenes -------------------------------------------------------------------------
const work = path.join(out, 'work');
fs.mkdirSync(work);
const W = 1024, H = 256;
const t0 = Date.now();
run('capture', 'box', '--lights', 'fibonacci:48', '--camera', 'cylindrical', '--size', `${W}x${H}`, '--supersample', '2', '--out', path.join(work, 'cap'), '-q');
run('fit', path.join(work, 'cap', 'capture.json'), '--basis', 'sh:16', '--objective', 'linear', '-o', path.join(work, 'pano.exr'));
// Small equirectangular and planar (pinhole) files for the geometry of those cameras.
run('capture', 'box', '--lights', 'fibonacci:24', '--camera', 'equirect', '--size', '256x128', '--out', path.join(work, 'cap-eq'), '-q');
run('fit', path.join(work, 'cap-eq', 'capture.json'), '--basis', 'sh:9', '--objective', 'linear', '-o', path.join(work, 'equirect.exr'));
run('capture', 'box', '--lights', 'fibonacci:24', '--camera', 'perspective:60', '--size', '192x128', '--out', path.join(work, 'cap-pl'), '-q');
run('fit', path.join(work, 'cap-pl', 'capture.json'), '--basis', 'sh:9', '--objective', 'linear', '-o', path.join(work, 'planar.exr'));
writeHdr(path.join(work, 'sky.hdr'), 64, 32, { sky: [0.3, 0.45, 0.8], ground: [0.12, 0.1, 0.08], sun: [8, 7, 5], at: [0.65, 0.3], r: 0.06 });
writeHdr(path.join(work, 'sunset.hdr'), 64, 32, { sky: [0.6, 0.3, 0.15], ground: [0.05, 0.05, 0.07], sun: [12, 5, 1], at: [0.2, 0.45], r: 0.07 });
log(`capture + fit of a ${W}×${H} k=16 cylindrical panorama (and small equirectangular, planar files): ${((Date.now() - t0) / 1000).toFixed(1)} s`);
const slide = new Uint8Array(32 * 24 * 3);
for (let y = 0; y < 24; y++) for (let x = 0; x < 32; x++) { const on = ((x >> 2) + (y >> 2)) & 1; slide.set(on ? [255, 230, 40] : [30, 60, 255], 3 * (32 * y + x)); }
fs.writeFileSync(path.join(work, 'slide.png'), encodePng(32, 24, slide));
const ENVS = ['--env', path.join(work, 'sky.hdr'), '--env', path.join(work, 'sunset.hdr')];

function startServer(file, extra = []) {
  return new Promise((resolve, reject) => {
    const p = spawn(relit, ['view', file, ...extra], { stdio: ['ignore', 'pipe', 'inherit'] });
    let buf = '';
    p.stdout.on('data', (d) => { buf += d; const m = buf.match(/http:\/\/\S+/); if (m) resolve({ proc: p, url: m[0] }); });
    p.on('exit', (code) => reject(new Error(`relit view exited with ${code}`)));
  });
}
const fetchBytes = (url) => new Promise((resolve, reject) => http.get(url, (res) => { const c = []; res.on('data', (d) => c.push(d)); res.on('end', () => resolve(Buffer.concat(c))); }).on('error', reject));
const close = (a, b, tol) => a.length === b.length && a.every((v, i) => Math.abs(v - b[i]) <= tol);

const results = { tolerance: `8-bit sRGB PSNR >= ${MIN_PSNR} dB (projector 35 dB)`, comparisons: {}, checks: {}, frame_ms: {}, sections_s: {} };
let failed = false;
const servers = [];
function expect(name, ok, detail) {
  results.checks[name] = { ok: !!ok, detail };
  log(`${ok ? 'ok  ' : 'FAIL'} ${name}${detail !== undefined ? ': ' + (typeof detail === 'string' ? detail : JSON.stringify(detail)) : ''}`);
  if (!ok) failed = true;
}
async function section(name, fn) {
  if (only && !only.has(name)) return;
  const t = Date.now();
  try { await fn(); } catch (err) { expect(`${name} (ran through)`, false, err.stack || String(err)); }
  results.sections_s[name] = (Date.now() - t) / 1000;
}

const browser = await chromium.launch({ executablePath: chromiumPath, headless: true, args: ['--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--ignore-gpu-blocklist', '--no-sandbox'] });
try {
  const context = await browser.newContext({ viewport: { width: 1400, height: 760 }, hasTouch: true, acceptDownloads: true });
  const page = await context.newPage();
  page.on('console', (m) => { if (m.type() === 'error') log('page error:', m.text()); });
  page.on('pageerror', (e) => log('page exception:', e.message));
  const cdp = await context.newCDPSession(page);
  let current = null; // { exr, info, url }

  async function open(exr, extra = [], size = [W, H]) {
    const s = await startServer(exr, extra);
    servers.push(s.proc);
    await page.goto(s.url);
    await page.evaluate(() => window.relit.ready);
    const info = await page.evaluate(() => window.relit.info);
    await page.evaluate(([w, h]) => { window.relit.setCanvasSize(w, h); window.relit.setView({ mode: 'flat', center: [w / 2, h / 2], zoom: 1 }); }, size);
    results.renderer = results.renderer || await page.evaluate(() => { const gl = document.createElement('canvas').getContext('webgl2'); const e = gl.getExtension('WEBGL_debug_renderer_info'); return e ? gl.getParameter(e.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER); });
    current = { exr, info, url: s.url };
    return s.url;
  }
  const rig = () => page.evaluate(() => window.relit.getRig());
  const view = () => page.evaluate(() => window.relit.getView());
  const setView = (v) => page.evaluate((v) => window.relit.setView(v), v);
  const setRig = (r) => page.evaluate((r) => window.relit.setRig(r), r);
  async function canvas() {
    const [w, h, b64] = await page.evaluate(() => { const px = window.relit.readPixels(); let s = ''; for (let i = 0; i < px.length; i += 4) s += String.fromCharCode(px[i], px[i + 1], px[i + 2]); const c = document.getElementById('view'); return [c.width, c.height, btoa(s)]; });
    return { w, h, rgb: new Uint8Array(Buffer.from(b64, 'base64')) };
  }
  async function cpuRender(name, lights, rigFile) {
    if (!rigFile) { rigFile = path.join(work, `${name}.rig.json`); fs.writeFileSync(rigFile, JSON.stringify({ lights }, null, 2)); }
    let cpuFile = path.join(out, `${name}.cpu.png`);
    const exposure = await page.evaluate(() => Number(document.getElementById('exposure').value));
    if (JSON.parse(fs.readFileSync(rigFile, 'utf8')).keyframes) {
      // An animation: its first frame (`--frames 1` renders the first keyframe's time).
      const dir = path.join(out, `${name}.cpu`);
      run('relight', current.exr, '--rig', rigFile, '--exposure', String(exposure), '--frames', '1', '--out', dir);
      cpuFile = path.join(dir, 'frame_0000.png');
    } else run('relight', current.exr, '--rig', rigFile, '--exposure', String(exposure), '-o', cpuFile);
    return decodePng(fs.readFileSync(cpuFile));
  }
  /** Compare the canvas (flat, 1:1) with `relit relight` of the viewer's rig. */
  async function check(name, minPsnr = MIN_PSNR, rigFile) {
    const lights = (await rig()).lights;
    const cpu = await cpuRender(name, lights, rigFile);
    const gpu = await canvas();
    fs.writeFileSync(path.join(out, `${name}.viewer.png`), encodePng(gpu.w, gpu.h, gpu.rgb));
    const r = compare(gpu.rgb, cpu.rgb);
    const warnings = await page.evaluate(() => window.relit.warnings);
    results.comparisons[name] = { ...r, rig: lights, warnings, min_psnr: minPsnr };
    const ok = r.psnr >= minPsnr && warnings.length === 0;
    log(`${ok ? 'ok  ' : 'FAIL'} ${name}: PSNR ${r.psnr.toFixed(2)} dB, max |diff| ${r.max_abs}, ${(100 * r.frac_over_2).toFixed(3)}% of samples off by > 2 (need ≥ ${minPsnr} dB)${warnings.length ? ' warnings: ' + warnings : ''}`);
    if (!ok) failed = true;
    return gpu;
  }
  const box = async (sel = '#view') => page.locator(sel).boundingBox();
  /** Expected light position for a click at canvas position (cx, cy) in the flat 1:1
   *  view: the camera ray through that pixel's centre × its depth × (1 − lift). */
  async function placedAt(cx, cy, lift = 0.15) {
    const v = await view();
    const i = Math.floor(v.center[0] + (cx - W / 2) / v.zoom), j = Math.floor(v.center[1] + (cy - H / 2) / v.zoom);
    const depth = new Float32Array(new Uint8Array(await fetchBytes(current.url + 'data/depth.f32')).buffer);
    const d = depth[j * current.info.width + i];
    const ray = cameraRay(current.info, i + 0.5, j + 0.5);
    return { pixel: [i, j], depth: d, position: ray.origin.map((o, k) => o + (1 - lift) * d * ray.dir[k]) };
  }
  const card = (n) => page.locator('.light').nth(n);

  await section('panel', async () => {
    const url = await open(path.join(work, 'pano.exr'), ENVS);
    // `relit view` listens on loopback only unless --host says otherwise.
    const port = Number(new URL(url).port);
    expect('relit view prints a 127.0.0.1 URL', new URL(url).hostname === '127.0.0.1', url);
    const lan = Object.values(os.networkInterfaces()).flat().find((a) => a && a.family === 'IPv4' && !a.internal);
    if (lan) {
      const refused = await new Promise((resolve) => { const s = net.connect({ host: lan.address, port, timeout: 2000 }); s.on('connect', () => { s.destroy(); resolve(false); }); s.on('error', () => resolve(true)); s.on('timeout', () => { s.destroy(); resolve(true); }); });
      expect(`relit view is not reachable on ${lan.address}`, refused);
    } else log('no non-loopback IPv4 interface: skipped the reachability check');

    // 1. A directional light through the DOM controls of the first light card.
    await card(0).locator('select[data-field="type"]').selectOption('directional');
    await card(0).locator('[data-field="direction.0"]').fill('-0.4');
    await card(0).locator('[data-field="direction.1"]').fill('0.6');
    await card(0).locator('[data-field="direction.2"]').fill('0.7');
    await card(0).locator('input[data-field="color"]').fill('#ffd9b3');
    await card(0).locator('[data-field="intensity"]').fill('1.5');
    await check('directional');
    const hud = await page.locator('#frame-time').textContent();
    expect('frame time shown', /^\d+(\.\d+)? ms\/frame · 1024×256$/.test(hud), hud);

    // 2. A point light: change the type, place it by clicking the image; the position
    //    must be the camera ray through the clicked pixel × depth, lifted by 15 %.
    await card(0).locator('select[data-field="type"]').selectOption('point');
    await card(0).locator('button[data-tool="place"]').click();
    const b = await box();
    const click = [Math.round(0.55 * W) + 0.3, Math.round(0.6 * H) + 0.6];
    await page.mouse.click(b.x + click[0], b.y + click[1]);
    let want = await placedAt(...click);
    let got = (await rig()).lights[0].position;
    expect('place on image: position = ray × depth × (1 − lift)', close(got, want.position, 2e-4), { pixel: want.pixel, depth: want.depth, expected: want.position, got });
    // Dragging moves it: the position follows the pixel under the cursor.
    const to = [0.42 * W + 0.5, 0.75 * H + 0.5];
    await page.mouse.move(b.x + click[0], b.y + click[1]);
    await page.mouse.down();
    await page.mouse.move(b.x + to[0], b.y + to[1], { steps: 6 });
    await page.mouse.up();
    want = await placedAt(...to);
    got = (await rig()).lights[0].position;
    expect('drag on image moves the point light', close(got, want.position, 2e-4), { pixel: want.pixel, expected: want.position, got });
    // Back to the first spot with a touch tap (the same tool, touch input).
    await page.touchscreen.tap(b.x + click[0], b.y + click[1]);
    want = await placedAt(...click);
    got = (await rig()).lights[0].position;
    expect('tap on image places the point light', close(got, want.position, 2e-4), { expected: want.position, got });
    await card(0).locator('button[data-tool="place"]').click(); // tool off
    await card(0).locator('[data-field="intensity"]').fill('2');
    await check('point');

    // 3. Two lights together (directional + point) with the "add light" button.
    await page.locator('#new-type').selectOption('directional');
    await page.locator('#add-light').click();
    await card(1).locator('[data-field="direction.0"]').fill('0.8');
    const before = await check('point+directional');

    // 4. The light sphere: drag on it; the direction is the sphere point under the cursor.
    const sphere = card(1).locator('canvas.sphere');
    const sb = await sphere.boundingBox();
    const r = 110 / 2 - 6, c = [sb.x + sb.width / 2, sb.y + sb.height / 2];
    await page.mouse.move(c[0], c[1]);
    await page.mouse.down();
    await page.mouse.move(c[0] + 0.3 * r, c[1] - 0.2 * r, { steps: 4 });
    await page.mouse.move(c[0] - 0.5 * r, c[1] - 0.4 * r, { steps: 4 });
    await page.mouse.up();
    const sx = -0.5, sy = 0.4, dir = [sx, sy, Math.sqrt(1 - sx * sx - sy * sy)];
    got = (await rig()).lights[1].direction;
    expect('light-sphere drag sets the direction', close(got, dir, 2e-3), { expected: dir, got });
    const typed = await card(1).locator('[data-field="direction.0"]').inputValue();
    expect('the direction fields follow the sphere', Math.abs(Number(typed) - got[0]) < 1e-9, typed);
    const after = await check('sphere-drag');
    expect('dragging the sphere changes the image', meanAbsDiff(before.rgb, after.rgb) > 1, `mean |diff| ${meanAbsDiff(before.rgb, after.rgb).toFixed(2)}`);
    await page.keyboard.down('Shift');
    await page.mouse.move(c[0] + 0.6 * r, c[1]);
    await page.mouse.down();
    await page.mouse.up();
    await page.keyboard.up('Shift');
    got = (await rig()).lights[1].direction;
    expect('shift on the sphere: far hemisphere', close(got, [0.6, 0, -0.8], 2e-3), got);
    await page.touchscreen.tap(c[0], c[1] + 0.6 * r);
    got = (await rig()).lights[1].direction;
    expect('a tap on the sphere sets the direction', close(got, [0, -0.6, 0.8], 2e-3), got);

    // 5. Aim a directional light on the image: it comes from the camera ray seen there.
    await card(1).locator('button[data-tool="aim"]').click();
    const aim = [0.3 * W + 0.5, 0.2 * H + 0.5];
    await page.mouse.click(b.x + aim[0], b.y + aim[1]);
    const ray = cameraRay(current.info, aim[0], aim[1]); // flat 1:1: canvas = image position
    got = (await rig()).lights[1].direction;
    expect('aim on image: directional light from the ray there', close(got, ray.dir, 2e-4), { expected: ray.dir, got });
    await page.keyboard.press('Escape');
    await check('aimed-directional');

    // 6. A spot aimed on the image: its axis points at the clicked surface point.
    const pos = (await rig()).lights[0].position;
    await setRig({ lights: [{ type: 'spot', position: pos, direction: [0.2, -0.5, -1], cone_deg: 35, softness_deg: 8, intensity: 3 }] });
    await card(0).locator('button[data-tool="aim"]').click();
    const spotAt = [0.5 * W + 0.5, 0.8 * H + 0.5];
    await page.mouse.click(b.x + spotAt[0], b.y + spotAt[1]);
    const hit = await placedAt(spotAt[0], spotAt[1], 0);
    const axis = norm3(hit.position.map((v, k) => v - pos[k]));
    got = (await rig()).lights[0].direction;
    expect('aim on image: spot axis toward the clicked point', close(got, axis, 2e-4), { expected: axis, got });
    await page.keyboard.press('Escape');
    await check('spot');

    // 6b. Area lights (AreaLight: stratified samples, the strata shifted per pixel by
    //     the CPU engine's 64-bit hash): added with the button, the centre placed on
    //     the image like a point light, then shape, edges, samples and sidedness set in
    //     the card. A rectangle, then the same light turned into a two-sided disk.
    await setRig({ lights: [] });
    await page.locator('#new-type').selectOption('area');
    await page.locator('#add-light').click();
    expect('add light: an area light (rectangle, 16 samples)', (await rig()).lights[0].shape.rect && (await rig()).lights[0].samples === 16, (await rig()).lights[0]);
    await card(0).locator('button[data-tool="place"]').click();
    const areaAt = [0.47 * W + 0.5, 0.7 * H + 0.5];
    await page.mouse.click(b.x + areaAt[0], b.y + areaAt[1]);
    await page.keyboard.press('Escape');
    want = await placedAt(...areaAt);
    got = (await rig()).lights[0].shape.rect.center;
    expect('place on image: area light centre = ray × depth × (1 − lift)', close(got, want.position, 2e-4), { pixel: want.pixel, expected: want.position, got });
    const fillVec = async (key, v) => { for (let i = 0; i < 3; i++) await card(0).locator(`[data-field="${key}.${i}"]`).fill(String(v[i])); };
    await fillVec('center', [0.4, 0.9, 1.0]);
    await fillVec('u', [0.35, 0, 0.1]);
    await fillVec('v', [0, -0.1, 0.3]);
    await card(0).locator('[data-field="samples"]').fill('32');
    await card(0).locator('[data-field="intensity"]').fill('3');
    await card(0).locator('input[data-field="color"]').fill('#ffe6cc');
    const areaRect = await check('area-rect');
    await card(0).locator('select[data-field="shape"]').selectOption('disk');
    await fillVec('normal', [0.3, -1, 0.2]);
    await card(0).locator('[data-field="radius"]').fill('0.3');
    await card(0).locator('[data-field="samples"]').fill('24');
    await card(0).locator('input[data-field="two_sided"]').check();
    const areaDisk = await check('area-disk-two-sided');
    // The strata shift is the CPU engine's per-pixel hash, not just any shift: with a
    // constant shift the rectangle still scores ~50 dB but ~2 % of samples are off by
    // more than 2 levels.
    const areaOff = ['area-rect', 'area-disk-two-sided'].map((n) => results.comparisons[n].frac_over_2);
    expect('area lights: the strata shift per pixel is the CPU engine\'s (≤ 0.1 % of samples off by > 2)', areaOff.every((f) => f <= 0.001), areaOff);
    const diskLight = (await rig()).lights[0];
    expect('the area card edits the rig', diskLight.shape.disk && diskLight.two_sided === true && diskLight.samples === 24 && diskLight.shape.disk.radius === 0.3, diskLight);
    expect('a disk differs from the rectangle', meanAbsDiff(areaRect.rgb, areaDisk.rgb) > 0.5, `mean |diff| ${meanAbsDiff(areaRect.rgb, areaDisk.rgb).toFixed(2)}`);

    // 7. A projector whose slide is opened in its card, and a fill light.
    await setRig({ lights: [{ type: 'projector', position: pos, direction: [0.1, -0.2, -1], fov_deg: 50, slide: 'none.png', intensity: 3 }, { type: 'directional', direction: [0, 1, 1], intensity: 0.3 }] });
    await card(0).locator('input[type="file"]').setInputFiles(path.join(work, 'slide.png'));
    await page.waitForFunction(() => window.relit.getRig().lights[0].slide === 'slide.png' && window.relit.warnings.length === 0);
    await check('projector', 35);
    // Remove the fill light with its ✕ button.
    await card(1).locator('button.remove').click();
    const left = (await rig()).lights;
    expect('✕ removes a light', left.length === 1 && left[0].type === 'projector', left.map((l) => l.type));
    // Exposure slider: the same as `relit relight --exposure`.
    await page.locator('#exposure').fill('1.5');
    await check('projector-exposure+1.5', 35);
    await page.locator('#exposure').fill('0');

    // 8. Environment: map chosen in the panel, then turned by yaw/pitch/roll sliders.
    await setRig({ lights: [{ type: 'environment', map: 'sky.hdr', yaw_deg: 0, pitch_deg: 0, roll_deg: 0, window: { type: 'none' }, intensity: 0.5 }] });
    const sky = await check('environment-sky');
    await card(0).locator('select[data-field="map"]').selectOption('sunset.hdr');
    const sunset = await check('environment-sunset');
    expect('choosing another environment map changes the image', meanAbsDiff(sky.rgb, sunset.rgb) > 2, `mean |diff| ${meanAbsDiff(sky.rgb, sunset.rgb).toFixed(2)}`);
    let prev = sunset;
    for (const [key, value] of [['yaw_deg', '70'], ['pitch_deg', '25'], ['roll_deg', '-15']]) {
      await card(0).locator(`input[data-field="${key}"]`).fill(value);
      const now = await check(`environment-${key.replace('_deg', '')}`);
      expect(`environment ${key} slider changes the image`, meanAbsDiff(prev.rgb, now.rgb) > 0.3, `mean |diff| ${meanAbsDiff(prev.rgb, now.rgb).toFixed(2)}`);
      prev = now;
    }
    expect('an SH file offers the band windows', !(await card(0).locator('select[data-field="window"]').isDisabled()));
    await card(0).locator('select[data-field="window"]').selectOption('hann');
    await check('environment-hann');
    await setRig({ lights: [{ type: 'environment', map: 'sky.hdr', yaw_deg: -40, window: { type: 'laplacian', lambda: 0.02 }, intensity: 0.5 }] });
    await check('environment-laplacian-own-lambda');
  });

  await section('rig-files', async () => {
    if (!current) await open(path.join(work, 'pano.exr'), ENVS);
    const pos = [0.5, 0.4, 1.2];
    await page.evaluate(async (b64) => {
      const bytes = Uint8Array.from(atob(b64), (ch) => ch.charCodeAt(0));
      await window.relit.loadSlide('slide.png', new Blob([bytes], { type: 'image/png' }));
    }, fs.readFileSync(path.join(work, 'slide.png')).toString('base64'));
    await setRig({ lights: [
      { type: 'directional', direction: [-0.3, 0.7, 0.6], color: [1, 0.9, 0.8], intensity: 0.8 },
      { type: 'point', position: pos, intensity: 1.5, attenuation: { inverse_distance: 1.2 } },
      { type: 'spot', position: pos, direction: [0.1, -0.6, -0.8], cone_deg: 40, softness_deg: 6, color: [0.4, 0.6, 1], intensity: 2 },
      { type: 'projector', position: pos, direction: [0, -0.2, -1], up: [0, 1, 0], fov_deg: 45, slide: 'slide.png', intensity: 1.5, attenuation: 'none' },
      { type: 'environment', map: 'sunset.hdr', yaw_deg: 30, pitch_deg: -10, roll_deg: 5, window: { type: 'lanczos' }, intensity: 0.4 },
      { type: 'area', shape: { rect: { center: [-0.3, 0.9, 1.1], u: [0.3, 0, 0], v: [0, 0, 0.25] } }, color: [1, 0.8, 0.6], intensity: 2, samples: 20 },
      { type: 'area', shape: { disk: { center: [0.6, 0.3, 0.9], normal: [-0.5, -0.2, 0.4], radius: 0.2 } }, two_sided: true, intensity: 1.5 },
    ] });
    const download = async (button) => { const [dl] = await Promise.all([page.waitForEvent('download'), page.locator(button).click()]); return dl; };
    // Save: the file is the rig's JSON, and the CLI renders it like the viewer.
    const saved = path.join(work, 'saved-rig.json');
    await (await download('#save-rig')).saveAs(saved);
    const text = fs.readFileSync(saved, 'utf8');
    expect('saved rig is the rig JSON', JSON.stringify(JSON.parse(text)) === JSON.stringify(await rig()));
    const shown = await check('saved-rig-vs-relit-relight', 35, saved);
    // Load it back (after changing the rig): identical rig and identical pixels.
    await setRig({ lights: [{ type: 'directional', direction: [1, 0, 0] }] });
    await page.locator('#load-rig').setInputFiles(saved);
    await page.waitForFunction(() => window.relit.getRig().lights.length === 7);
    const resaved = path.join(work, 'resaved-rig.json');
    await (await download('#save-rig')).saveAs(resaved);
    expect('load rig then save rig gives the identical file', fs.readFileSync(resaved, 'utf8') === text);
    const reloaded = await canvas();
    expect('loaded rig renders identical pixels', Buffer.compare(Buffer.from(reloaded.rgb), Buffer.from(shown.rgb)) === 0, `mean |diff| ${meanAbsDiff(reloaded.rgb, shown.rgb)}`);
    // Screenshot button: a PNG of exactly the canvas.
    const shot = path.join(out, 'screenshot-button.png');
    await (await download('#screenshot')).saveAs(shot);
    const png = decodePng(fs.readFileSync(shot));
    expect('screenshot button saves the canvas', png.w === W && png.h === H && Buffer.compare(Buffer.from(png.rgb), Buffer.from(reloaded.rgb)) === 0, `${png.w}×${png.h}`);
    // An animation file (`relit relight --rig … --frames N` takes them): its first keyframe.
    const anim = path.join(work, 'anim-rig.json');
    const firstKey = [{ type: 'point', position: [0.2, 0.5, 1.3], intensity: 2 }, { type: 'directional', direction: [0.5, 0.5, 0.7], intensity: 0.5 }];
    fs.writeFileSync(anim, JSON.stringify({ keyframes: [{ time: 0, lights: firstKey }, { time: 1, lights: [{ ...firstKey[0], position: [-1, 0.5, 1] }, firstKey[1]] }] }));
    await page.locator('#load-rig').setInputFiles(anim);
    await page.waitForFunction(() => window.relit.getRig().lights.length === 2);
    expect('an animation file loads its first keyframe', JSON.stringify((await rig()).lights) === JSON.stringify(firstKey));
    const note = await page.locator('#warnings').textContent();
    await check('animation-first-keyframe', MIN_PSNR, anim);
    expect('the panel says it shows the first keyframe', note.includes('animation of 2 keyframes'), note);
    // A broken rig file is refused with a message, and the rig stays as it was.
    const bad = path.join(work, 'bad-rig.json');
    fs.writeFileSync(bad, JSON.stringify({ lights: [{ type: 'point', positon: [0, 0, 0] }] }));
    await page.locator('#load-rig').setInputFiles(bad);
    await page.waitForFunction(() => document.getElementById('warnings').textContent.includes('could not load'));
    expect('a bad rig file is refused', (await rig()).lights.length === 2, await page.locator('#warnings').textContent());
  });

  await section('navigation', async () => {
    if (!current) await open(path.join(work, 'pano.exr'), ENVS);
    // Only the view state is checked here, so a small canvas keeps SwiftShader quick.
    const cw = 320, ch = 80;
    await page.evaluate(([w, h]) => window.relit.setCanvasSize(w, h), [cw, ch]);
    await setRig({ lights: [{ type: 'directional', direction: [-0.4, 0.6, 0.7] }] });
    const b = await box();
    const at = (p) => [b.x + p[0], b.y + p[1]];
    // Mouse, flat view: drag pans by the drag / zoom; the wheel zooms about the cursor.
    await setView({ mode: 'flat', center: [W / 2, H / 2], zoom: 2 });
    let v0 = await view();
    await page.mouse.move(...at([200, 30]));
    await page.mouse.down();
    await page.mouse.move(...at([140, 70]), { steps: 4 });
    await page.mouse.up();
    let v = await view();
    expect('mouse drag pans the flat view', close(v.center, [v0.center[0] + 30, v0.center[1] - 20], 1e-6), v.center);
    v0 = v;
    const cur = [90, 25];
    const under = (vv, p) => [vv.center[0] + (p[0] - cw / 2) / vv.zoom, vv.center[1] + (p[1] - ch / 2) / vv.zoom];
    await page.mouse.move(...at(cur));
    await page.mouse.wheel(0, -200);
    await page.waitForFunction((z) => window.relit.getView().zoom > z, v0.zoom);
    v = await view();
    expect('wheel zooms in about the cursor', v.zoom > v0.zoom && close(under(v, cur), under(v0, cur), 1e-6), { zoom: [v0.zoom, v.zoom], under: [under(v0, cur), under(v, cur)] });
    // Keyboard, flat view: arrows pan 20 px (shift 80), +/- zoom by 1.25, 0 resets.
    await page.locator('#view').focus();
    v0 = await view();
    await page.keyboard.press('ArrowRight');
    await page.keyboard.press('Shift+ArrowDown');
    v = await view();
    expect('arrow keys pan the flat view', close(v.center, [v0.center[0] + 20 / v0.zoom, v0.center[1] + 80 / v0.zoom], 1e-6), v.center);
    await page.keyboard.press('+');
    expect('+ zooms in', Math.abs((await view()).zoom - 1.25 * v.zoom) < 1e-9);
    await page.keyboard.press('-');
    await page.keyboard.press('-');
    expect('- zooms out', Math.abs((await view()).zoom - 0.8 * v.zoom) < 1e-9);
    // Panorama (perspective) view: yaw/pitch from drags and keys, fov from zoom.
    await page.keyboard.press('0');
    v = await view();
    expect('0 resets to the default perspective view', v.mode === 'pano' && v.yaw === 0 && v.pitch === 0 && v.fov === 75 && (await page.locator('#fov').inputValue()) === '75', v);
    await page.keyboard.press('ArrowLeft');
    await page.keyboard.press('ArrowUp');
    v0 = v; v = await view();
    const deg = 75 / ch; // degrees per canvas pixel at fov 75
    expect('arrow keys turn the perspective view', Math.abs(v.yaw - (v0.yaw - 20 * deg)) < 1e-9 && Math.abs(v.pitch - 20 * deg) < 1e-9, { yaw: v.yaw, pitch: v.pitch });
    await page.keyboard.press('=');
    expect('+ narrows the field of view', Math.abs((await view()).fov - 75 / 1.25) < 1e-9);
    await page.keyboard.press('0');
    // Touch: one finger pans (look around), two fingers pinch-zoom.
    // CDP touch events, fingers as [x, y, id]: touchStart/touchMove list the fingers
    // down, touchEnd the fingers lifted (none listed: all).
    const touch = (type, pts) => cdp.send('Input.dispatchTouchEvent', { type, touchPoints: pts.map(([x, y, id]) => ({ x: b.x + x, y: b.y + y, id })) });
    v0 = await view();
    await touch('touchStart', [[200, 30, 0]]);
    for (let s = 1; s <= 4; s++) await touch('touchMove', [[200 - 5 * s, 30 + 2 * s, 0]]);
    await touch('touchEnd', []);
    v = await view();
    expect('one-finger drag pans the perspective view', Math.abs(v.yaw - (v0.yaw + 20 * deg)) < 1e-6 && Math.abs(v.pitch - (v0.pitch + 8 * deg)) < 1e-6, { yaw: v.yaw, pitch: v.pitch });
    v0 = v;
    await touch('touchStart', [[140, 40, 0]]);
    await touch('touchStart', [[140, 40, 0], [180, 40, 1]]);
    for (let s = 1; s <= 4; s++) await touch('touchMove', [[140 - 5 * s, 40, 0], [180 + 5 * s, 40, 1]]);
    await touch('touchEnd', [[200, 40, 1]]);
    await touch('touchEnd', []);
    v = await view();
    expect('pinch (×2 apart) halves the field of view', Math.abs(v.fov - v0.fov / 2) < 1e-6 && Math.abs(v.yaw - v0.yaw) < 1.5, { fov: [v0.fov, v.fov], yaw: [v0.yaw, v.yaw] });
    // Pinch in the flat view: zoom ×2 about the fingers' midpoint, which stays put.
    await setView({ mode: 'flat', center: [W / 2, H / 2], zoom: 1 });
    v0 = await view();
    await touch('touchStart', [[100, 30, 0]]);
    await touch('touchStart', [[100, 30, 0], [140, 46, 1]]);
    for (let s = 1; s <= 4; s++) await touch('touchMove', [[100 - 5 * s, 30 - 2 * s, 0], [140 + 5 * s, 46 + 2 * s, 1]]);
    await touch('touchEnd', [[160, 54, 1]]);
    await touch('touchEnd', []);
    v = await view();
    const mid = [120, 38];
    expect('pinch zooms the flat view about the midpoint', Math.abs(v.zoom - 2) < 1e-6 && close(under(v, mid), under(v0, mid), 1e-6), { zoom: v.zoom, under: [under(v0, mid), under(v, mid)] });
    // After a pinch, the finger left down pans on.
    v0 = await view();
    await touch('touchStart', [[100, 30, 0]]);
    await touch('touchStart', [[100, 30, 0], [140, 46, 1]]);
    await touch('touchEnd', [[100, 30, 0]]);
    for (let s = 1; s <= 3; s++) await touch('touchMove', [[140 + 4 * s, 46, 1]]);
    await touch('touchEnd', []);
    v = await view();
    expect('the finger left after a pinch pans', close(v.center, [v0.center[0] - 12 / v0.zoom, v0.center[1]], 1e-6), { before: v0.center, after: v.center });
    await page.evaluate(([w, h]) => window.relit.setCanvasSize(w, h), [W, H]);
    await setView({ mode: 'flat', center: [W / 2, H / 2], zoom: 1 });
  });

  await section('geometry', async () => {
    if (!current || !current.exr.endsWith('pano.exr')) await open(path.join(work, 'pano.exr'), ENVS);
    const lights = [{ type: 'directional', direction: [-0.4, 0.6, 0.7] }, { type: 'point', position: [0.5, 0.6, 1.4], intensity: 1.5 }];
    await setRig({ lights });
    const cpu = await cpuRender('geometry', lights);
    // (a) 1:1 at the centre of a cylindrical panorama: a view 256 high with
    //     tan(fov/2) = π·256/1024 shows the panorama's centre column, row for row.
    await page.evaluate(() => window.relit.setCanvasSize(512, 256));
    const fov1 = 2 * Math.atan(Math.PI * 256 / W) * 180 / Math.PI;
    await setView({ mode: 'pano', yaw: 0, pitch: 0, fov: fov1 });
    let g = await canvas();
    const colView = [], colPano = [];
    for (let j = 0; j < 256; j++) for (let k = 0; k < 3; k++) { colView.push(g.rgb[3 * (j * 512 + 256) + k]); colPano.push(cpu.rgb[3 * (j * W + 512) + k]); }
    const cc = compare(colView, colPano);
    results.comparisons['perspective centre column vs panorama column 512'] = cc;
    expect('perspective view at 1:1 shows the panorama centre column (bilinear)', cc.max_abs <= 2, cc);
    // (b) Whole views, nearest texel, against the CPU image resampled through the
    //     camera model and an ideal pinhole (which keeps straight lines straight).
    await page.evaluate(() => window.relit.setSmooth(false));
    for (const v of [{ yaw: 0, pitch: 0, fov: fov1 }, { yaw: 35, pitch: 15, fov: 100 }, { yaw: -50, pitch: -30, fov: 60 }]) {
      await setView({ mode: 'pano', ...v });
      g = await canvas();
      const want = resampleView(current.info, cpu, v, 512, 256);
      const r = compare(g.rgb, want);
      const name = `perspective cylindrical yaw ${v.yaw} pitch ${v.pitch} fov ${v.fov.toFixed(1)}`;
      results.comparisons[name] = r;
      fs.writeFileSync(path.join(out, `geometry-cyl-${v.yaw}.viewer.png`), encodePng(512, 256, g.rgb));
      fs.writeFileSync(path.join(out, `geometry-cyl-${v.yaw}.expected.png`), encodePng(512, 256, want));
      expect(name, r.frac_over_2 <= 0.01 && r.psnr >= 30, r);
    }
    // Place a point light by clicking the perspective view: the pixel under the cursor
    // through the pinhole and the camera model, × its depth × (1 − lift).
    await page.evaluate(() => window.relit.setSmooth(true));
    const pv = { yaw: -50, pitch: -10, fov: 60 };
    await setView({ mode: 'pano', ...pv });
    await setRig({ lights: [{ type: 'point', position: [0, 1, 0], intensity: 2 }] });
    await card(0).locator('button[data-tool="place"]').click();
    const gb = await box(), clickAt = [300.5, 180.5];
    await page.mouse.click(gb.x + clickAt[0], gb.y + clickAt[1]);
    await page.keyboard.press('Escape');
    const src = panoramaPixel(current.info, pinholeRay(pv.yaw, pv.pitch, pv.fov, 512, 256, ...clickAt));
    const [pi, pj] = [Math.floor(src[0]), Math.floor(src[1])];
    const depthMap = new Float32Array(new Uint8Array(await fetchBytes(current.url + 'data/depth.f32')).buffer);
    const pr = cameraRay(current.info, pi + 0.5, pj + 0.5), pd = depthMap[pj * W + pi];
    const placed = pr.origin.map((o, k) => o + 0.85 * pd * pr.dir[k]);
    const gotPos = (await rig()).lights[0].position;
    expect('place on the perspective view: the pixel under the cursor', close(gotPos, placed, 2e-4), { pixel: [pi, pj], expected: placed, got: gotPos });
    await setRig({ lights });
    // (c) Magnified flat view: bilinear equals bilinear interpolation of the relit image
    //     (in linear light); nearest equals the CPU pixels.
    await page.evaluate(() => window.relit.setCanvasSize(256, 128));
    const center = [521.3, 140.7], zoom = 4;
    for (const smooth of [false, true]) {
      await page.evaluate((s) => window.relit.setSmooth(s), smooth);
      await setView({ mode: 'flat', center, zoom });
      g = await canvas();
      const want = magnify(cpu, center, zoom, 256, 128, smooth);
      const r = compare(g.rgb, want);
      const name = `flat ×4 ${smooth ? 'bilinear' : 'nearest'} vs CPU ${smooth ? 'bilinear (linear light)' : 'pixels'}`;
      results.comparisons[name] = r;
      fs.writeFileSync(path.join(out, `zoom4-${smooth ? 'bilinear' : 'nearest'}.viewer.png`), encodePng(256, 128, g.rgb));
      expect(name, smooth ? r.psnr >= 35 : r.frac_over_2 <= 0.001, r);
    }
    // (d) Shrunk flat view (¼): mipmapped, the CPU image's 4×4 box averages; the
    //     nearest texel aliases (reported for contrast).
    await page.evaluate(() => window.relit.setCanvasSize(256, 64));
    const small = shrink(cpu, 4), shrunk = {};
    for (const smooth of [false, true]) {
      await page.evaluate((s) => window.relit.setSmooth(s), smooth);
      await setView({ mode: 'flat', center: [512, 128], zoom: 0.25 });
      g = await canvas();
      fs.writeFileSync(path.join(out, `shrink4-${smooth ? 'mipmap' : 'nearest'}.viewer.png`), encodePng(256, 64, g.rgb));
      shrunk[smooth] = compare(g.rgb, small);
      results.comparisons[`flat ×¼ ${smooth ? 'mipmapped' : 'nearest'} vs CPU 4×4 box average`] = shrunk[smooth];
    }
    expect('flat ×¼ mipmapped vs CPU 4×4 box average (nearest for contrast)', shrunk[true].psnr >= 35 && shrunk[true].psnr > shrunk[false].psnr + 5, { mipmapped: shrunk[true], nearest: shrunk[false] });
    await page.evaluate(() => window.relit.setSmooth(true));
    // (e) Equirectangular: tilted views (toward the pole, where it differs most).
    await open(path.join(work, 'equirect.exr'), [], [256, 128]);
    const eqLights = [{ type: 'directional', direction: [-0.4, 0.6, 0.7] }];
    await setRig({ lights: eqLights });
    const eqCpu = await check('equirect-directional');
    const eqPoint = [{ type: 'point', position: [0.4, 0.8, 1.5], intensity: 1.5 }];
    await setRig({ lights: eqPoint });
    await check('equirect-point');
    await setRig({ lights: eqLights });
    // Across the seam (column 0 = column W): a flat ½ view centred next to it must be
    // the CPU image's 2×2 averages rolled by about half a turn, no line where the
    // columns wrap (the seam falls inside a 2×2 fragment quad, between canvas columns
    // 62 and 63, where the derivatives see it).
    await page.evaluate(() => window.relit.setCanvasSize(128, 64));
    await setView({ mode: 'flat', center: [2, 64], zoom: 0.5 });
    g = await canvas();
    const half = shrink(eqCpu, 2), rolled = new Uint8Array(half.length);
    for (let j = 0; j < 64; j++) for (let i = 0; i < 128; i++) rolled.set(half.subarray(3 * (j * 128 + (i + 65) % 128), 3 * (j * 128 + (i + 65) % 128) + 3), 3 * (j * 128 + i));
    const seam = compare(g.rgb, rolled), seamCols = [];
    for (let j = 0; j < 64; j++) for (const i of [62, 63]) for (let k = 0; k < 3; k++) seamCols.push(Math.abs(g.rgb[3 * (j * 128 + i) + k] - rolled[3 * (j * 128 + i) + k]));
    seam.seam_columns_max_abs = Math.max(...seamCols);
    results.comparisons['flat ½ across the panorama seam vs CPU 2×2 average'] = seam;
    expect('mipmapped view across the panorama seam', seam.psnr >= 35 && seam.seam_columns_max_abs <= 8, seam);
    await page.evaluate(() => window.relit.setSmooth(false));
    await page.evaluate(() => window.relit.setCanvasSize(384, 256));
    for (const v of [{ yaw: 20, pitch: -35, fov: 80 }, { yaw: 10, pitch: -65, fov: 100 }]) {
      await setView({ mode: 'pano', ...v });
      g = await canvas();
      const want = resampleView(current.info, eqCpu, v, 384, 256);
      const r = compare(g.rgb, want);
      const name = `perspective equirectangular yaw ${v.yaw} pitch ${v.pitch} fov ${v.fov}`;
      results.comparisons[name] = r;
      fs.writeFileSync(path.join(out, `geometry-eq-${v.yaw}.viewer.png`), encodePng(384, 256, g.rgb));
      expect(name, r.frac_over_2 <= 0.01 && r.psnr >= 30, r);
    }
    await page.evaluate(() => window.relit.setSmooth(true));
    // (f) A planar (pinhole) image: flat view only; point light placed by a click.
    await open(path.join(work, 'planar.exr'), [], [192, 128]);
    expect('planar image: no perspective view to choose', await page.locator('#view-mode').isDisabled());
    await setRig({ lights: [{ type: 'point', position: [0, 1, 1], intensity: 2 }] });
    await card(0).locator('button[data-tool="place"]').click();
    const pb = await box();
    await page.mouse.click(pb.x + 96.5, pb.y + 90.5);
    const v = await view();
    const i = Math.floor(v.center[0] + (96.5 - 96) / v.zoom), j = Math.floor(v.center[1] + (90.5 - 64) / v.zoom);
    const depth = new Float32Array(new Uint8Array(await fetchBytes(current.url + 'data/depth.f32')).buffer);
    const ray = cameraRay(current.info, i + 0.5, j + 0.5), d = depth[j * 192 + i];
    const want = ray.origin.map((o, k) => o + 0.85 * d * ray.dir[k]);
    const got = (await rig()).lights[0].position;
    expect('planar: place on image uses the pinhole ray', close(got, want, 2e-4), { expected: want, got });
    await page.keyboard.press('Escape');
    await check('planar-point');
    const z0 = (await view()).zoom;
    await page.mouse.move(pb.x + 50, pb.y + 40);
    await page.mouse.wheel(0, 300);
    await page.waitForFunction((z) => window.relit.getView().zoom < z, z0);
    await page.mouse.move(pb.x + 100, pb.y + 60);
    await page.mouse.down();
    await page.mouse.move(pb.x + 80, pb.y + 50, { steps: 2 });
    await page.mouse.up();
    const pvz = await view();
    expect('planar image: wheel zooms, drag pans (flat)', pvz.mode === 'flat' && pvz.zoom < z0 && Math.abs(pvz.center[0] - (v.center[0] + (50 - 96) / z0 - (50 - 96) / pvz.zoom + 20 / pvz.zoom)) < 1e-6, pvz);
  });

  await section('frame-times', async () => {
    // Wall time per frame, and CPU time per frame of the browser's processes
    // (SwiftShader's threads among them), which other load on a shared machine does not
    // change: the figure to compare shader versions by. k = 16 and 25.
    const pano25 = path.join(work, 'pano25.exr');
    run('fit', path.join(work, 'cap', 'capture.json'), '--basis', 'sh:25', '--objective', 'linear', '-o', pano25);
    const pos = [0.5, 0.6, 1.4];
    const rigs = {
      directional: [{ type: 'directional', direction: [-0.4, 0.6, 0.7] }],
      point: [{ type: 'point', position: pos, intensity: 2 }],
      'area (rect, 16 samples)': [{ type: 'area', shape: { rect: { center: [0.4, 0.9, 1.0], u: [0.35, 0, 0.1], v: [0, -0.1, 0.3] } }, intensity: 3 }],
      'directional+point+environment': [{ type: 'directional', direction: [-0.4, 0.6, 0.7] }, { type: 'point', position: pos, intensity: 2 }, { type: 'environment', map: 'sky.hdr', intensity: 0.3 }],
    };
    for (const [k, exr] of [[25, pano25], [16, path.join(work, 'pano.exr')]]) {
      await open(exr, ENVS);
      for (const [mode, v] of [['flat', { mode: 'flat', center: [W / 2, H / 2], zoom: 1 }], ['perspective', { mode: 'pano', yaw: 20, pitch: 5, fov: 75 }]]) {
        await setView(v);
        for (const [name, lights] of Object.entries(rigs)) {
          await setRig({ lights });
          await page.evaluate(() => window.relit.renderSync());
          const cpu0 = browserCpuSeconds();
          const r = await page.evaluate(() => window.relit.benchmark(4));
          r.cpu_ms = (browserCpuSeconds() - cpu0) / r.frames * 1000;
          results.frame_ms[`k=${k} ${mode} 1024x256, ${name}`] = r;
        }
      }
    }
    for (const [k, v] of Object.entries(results.frame_ms)) log(`frame time ${k}: median ${v.median.toFixed(1)} ms (min ${v.min.toFixed(1)}, max ${v.max.toFixed(1)}), CPU ${v.cpu_ms.toFixed(0)} ms`);

    // Screenshot of the whole page: perspective view, panel with three lights.
    await setRig({ lights: rigs['directional+point+environment'] });
    const frames = await page.evaluate(() => window.relit.frames);
    await page.evaluate(() => { window.relit.setCanvasSize(null); window.relit.setView({ mode: 'pano', yaw: 20, pitch: -8, fov: 80 }); });
    await page.waitForFunction((n) => window.relit.frames > n, frames);
    await page.screenshot({ path: path.join(out, 'viewer-screenshot.png') });
    log(`screenshot: ${path.join(out, 'viewer-screenshot.png')}`);
  });

  await section('export-web', async () => {
    // `relit export-web` (8-bit quantised planes) hosted by a plain static file server.
    const site = path.join(work, 'site');
    run('export-web', path.join(work, 'pano.exr'), site, '--viewer', 'relit', '--storage', 'u8', ...ENVS);
    const types = { html: 'text/html', js: 'text/javascript', css: 'text/css', json: 'application/json', png: 'image/png' };
    const stat = http.createServer((req, res) => {
      const rel = decodeURIComponent(new URL(req.url, 'http://x').pathname).replace(/^\/+/, '') || 'index.html';
      const file = path.join(site, rel);
      if (!file.startsWith(site + path.sep) || !fs.existsSync(file)) { res.writeHead(404); res.end(); return; }
      res.writeHead(200, { 'Content-Type': types[rel.split('.').pop()] || 'application/octet-stream' });
      res.end(fs.readFileSync(file));
    });
    await new Promise((r) => stat.listen(0, '127.0.0.1', r));
    try {
      await page.goto(`http://127.0.0.1:${stat.address().port}/`);
      await page.evaluate(() => window.relit.ready);
      current = { exr: path.join(work, 'pano.exr'), info: await page.evaluate(() => window.relit.info), url: `http://127.0.0.1:${stat.address().port}/` };
      await page.evaluate(([w, h]) => { window.relit.setCanvasSize(w, h); window.relit.setView({ mode: 'flat', center: [w / 2, h / 2], zoom: 1 }); }, [W, H]);
      await card(0).locator('[data-field="direction.0"]').fill('-0.4');
      await check('export-web-u8-directional');
      await setRig({ lights: [{ type: 'point', position: [0.5, 0.6, 1.4], intensity: 2 }] });
      await check('export-web-u8-point');
      await setRig({ lights: [{ type: 'environment', map: 'sunset.hdr', yaw_deg: 30, intensity: 0.5 }] });
      await check('export-web-u8-environment');
    } finally { stat.close(); }
  });

  await section('other-basis', async () => {
    // Every family other than SH: the viewer relights each from the weight table in
    // info.json, knowing no basis, and its frames match `relit relight` (the CPU engine,
    // which evaluates each basis itself or from its own tables) for every light type.
    const rigs = {
      point: [{ type: 'point', position: [0, 1, 1], intensity: 2 }],
      spot: [{ type: 'spot', position: [0.2, 1.2, 0.8], direction: [0, -0.6, -1], cone_deg: 30, softness_deg: 6, intensity: 3 }],
      area: [{ type: 'area', shape: { rect: { center: [0, 1.4, 0.5], u: [0.3, 0, 0], v: [0, 0, 0.25] } }, intensity: 3, samples: 16 }],
      environment: [{ type: 'environment', map: 'sky.hdr', yaw_deg: 30, pitch_deg: -10, intensity: 0.5 }],
    };
    for (const basis of ['hsh:16', 'ptm:6', 'bilinear:16', 'rbf:16', 'sg:16']) {
      const exr = path.join(work, `other-${basis.replace(':', '-')}.exr`);
      run('fit', path.join(work, 'cap-pl', 'capture.json'), '--basis', basis, '--objective', 'linear', '-o', exr);
      await open(exr, ENVS, [192, 128]);
      expect(`the viewer names the basis (${basis})`, current.info.basis.name === basis, current.info.basis.name);
      await setRig({ lights: [{ type: 'directional', direction: [-0.4, 0.6, 0.7], color: [1, 0.9, 0.8], intensity: 1.2 }, { type: 'directional', direction: [0.5, 0.2, 0.8], intensity: 0.4 }] });
      await check(`${basis} directional`);
      for (const [name, lights] of Object.entries(rigs)) {
        await setRig({ lights });
        await check(`${basis} ${name}`);
      }
      await setRig({ lights: rigs.environment });
      const win = card(0).locator('select[data-field="window"]');
      const hint = await card(0).locator('[data-hint="window"]').textContent().catch(() => '');
      expect(`no band windows for ${basis} (no bands), and the panel says why`, await win.isDisabled() && hint.includes(basis), hint);
    }
    // Display-referred maps: each light decoded from sRGB on its own, an environment as
    // the median-cut lights the bundle ships for such maps, as `relit relight` does.
    const display = path.join(work, 'other-display.exr');
    run('fit', path.join(work, 'cap-pl', 'capture.json'), '--basis', 'hsh:16', '--space', 'srgb', '-o', display);
    await open(display, ENVS, [192, 128]);
    expect('the viewer reads display-referred maps', current.info.color_space === 'srgb', current.info.color_space);
    for (const [name, lights] of Object.entries(rigs)) {
      await setRig({ lights });
      await check(`display-referred ${name}`);
    }
  });

  await section('compressed', async () => {
    // Compressed files, principal components and a codebook: the viewer relights the
    // planes they decode to with the projected basis (K′ combinations of sh:16, from its
    // weight table) and matches `relit relight` of the same file. Principal components
    // per block decode into the fit's own basis (each block's projection undone); a
    // codebook of the residual into K′ + R planes.
    for (const [name, flags] of [
      ['pca', ['--layout', 'ycc', '--components', '6', '--codec', 'jpeg:90']],
      ['codebook', ['--layout', 'ycc', '--components', '9', '--codebook', '256']],
      ['blocks', ['--layout', 'ycc', '--components', '6', '--codec', 'jpeg:90', '--pca-block', '128']],
      // A codebook of the residual: 6 planes and the next 6 components from 64 entries,
      // decoded into 12 planes of the projected basis.
      ['residual', ['--layout', 'ycc', '--components', '6', '--codec', 'jpeg:90', '--codebook', '64', '--residual', '6']],
    ]) {
      const rlz = path.join(work, `pano-${name}.rlz`);
      run('convert', path.join(work, 'pano.exr'), '-o', rlz, ...flags);
      await open(rlz, ENVS);
      if (name === 'blocks') expect('the viewer reads the blocks file in the fit\'s basis', current.info.basis.name === 'sh:16', current.info.basis.name);
      else expect(`the viewer reads the ${name} file's projected basis`, current.info.basis.name.startsWith('sh:16→'), current.info.basis.name);
      // A codebook file arrives as its entries and one index a pixel, not expanded.
      const book = current.info.codebook;
      expect(`the ${name} file ${name === 'codebook' ? 'arrives as entries and indices' : 'arrives as planes'}`,
        name === 'codebook' ? !!book && book.entries === 256 && book.width === 256 && book.height === 1 : !book, book);
      await setRig({ lights: [{ type: 'directional', direction: [-0.4, 0.6, 0.7], color: [1, 0.9, 0.8], intensity: 1.2 }] });
      const cpuFrame = await check(`rlz ${name} directional`) && await cpuRender(`rlz ${name} directional`, (await rig()).lights);
      // Magnified: the codebook's hand-made bilinear blend of four pixels' entries (and
      // the planes' filter) against bilinear interpolation of the relit image.
      await page.evaluate(() => window.relit.setCanvasSize(256, 128));
      const center = [521.3, 140.7], zoom = 4;
      for (const smooth of [false, true]) {
        await page.evaluate((s) => window.relit.setSmooth(s), smooth);
        await setView({ mode: 'flat', center, zoom });
        const g = await canvas();
        const r = compare(g.rgb, magnify(cpuFrame, center, zoom, 256, 128, smooth));
        const label = `rlz ${name} flat ×4 ${smooth ? 'bilinear' : 'nearest'} vs CPU`;
        results.comparisons[label] = r;
        expect(label, smooth ? r.psnr >= 35 : r.frac_over_2 <= 0.001, r);
      }
      await page.evaluate(([w, h]) => { window.relit.setCanvasSize(w, h); window.relit.setView({ mode: 'flat', center: [w / 2, h / 2], zoom: 1 }); }, [W, H]);
      await setRig({ lights: [{ type: 'point', position: [0, 1, 1], intensity: 2 }] });
      await check(`rlz ${name} point`);
    }
  });

  await section('tiled', async () => {
    // The same file whole and tiled (64-pixel tiles, the overview level 3 at 128×32):
    // zoomed in, the tiles the view needs arrive and the frame equals the whole
    // bundle's; zoomed out, tiles of the level the view needs (or the overview alone)
    // stand in for the whole texture's mipmaps; only the tiles under the view cross
    // the wire.
    const exr = path.join(work, 'pano.exr');
    const size = [256, 128];
    const lights = [{ type: 'directional', direction: [-0.4, 0.6, 0.7], color: [1, 0.9, 0.8], intensity: 1.2 }, { type: 'point', position: [0, 1, 1], intensity: 2 }];
    const views = [
      // Level 0: the same texels blended with the same weights (by hand in the tiles,
      // by the sampler in the whole texture): equal within one level of rounding.
      ['flat ×4 bilinear', { mode: 'flat', center: [521.3, 140.7], zoom: 4 }, true, 'equal'],
      ['flat ×4 nearest', { mode: 'flat', center: [521.3, 140.7], zoom: 4 }, false, 'equal'],
      ['flat ×1 across the seam', { mode: 'flat', center: [1010, 100], zoom: 1 }, true, 'equal'],
      ['perspective 1:1', { mode: 'pano', yaw: 40, pitch: 5, fov: 50 }, true, 'equal'],
      // Coarser: the server's means of level 0 against the GPU's mipmaps.
      ['flat ÷4 (level 2 tiles)', { mode: 'flat', center: [512, 128], zoom: 0.25 }, true, 40],
      ['flat ÷16 (the overview)', { mode: 'flat', center: [512, 128], zoom: 1 / 16 }, true, 40],
    ];
    const frames = {}, picks = {};
    for (const tiled of [false, true]) {
      await open(exr, tiled ? ['--tiles', '64', '--overview-mib', '0.5'] : ['--tiles', 'off'], size);
      const t = current.info.tiles;
      if (tiled) expect('a tiled bundle: 64-pixel tiles, overview level 3', t && t.side === 64 && t.overview === 3, t);
      else expect('--tiles off: whole layers', !t, t);
      // The depth map arrives whole only with whole layers; a tiled bundle ships the
      // overview's and each tile carries its own.
      const d = current.info.depth;
      expect(`${tiled ? 'a tiled bundle ships the overview\'s depth (128×32)' : 'whole layers ship the whole depth (1024×256)'}`,
        d && (tiled ? d.width === 128 && d.height === 32 : d.width === 1024 && d.height === 256), d);
      await setRig({ lights });
      await page.evaluate(() => window.relit.settle()); // the first view's tiles, counted apart
      for (const [name, v, smooth] of views) {
        await page.evaluate((s) => window.relit.setSmooth(s), smooth);
        await setView(v);
        const before = await page.evaluate(() => window.relit.tileStats && { ...window.relit.tileStats });
        const stats = await page.evaluate(() => window.relit.settle());
        if (name === 'flat ×1 across the seam') {
          // Frame time with every tile there: the tiles' hand-made bilinear blend and
          // page look-ups against the sampler's filtering of the whole texture.
          results.frame_ms[`tiled section, ${tiled ? 'tiles' : 'whole layers'}, 256×128`] = await page.evaluate(() => window.relit.benchmark(15));
        }
        const g = await canvas();
        frames[`${tiled} ${name}`] = g;
        picks[`${tiled} ${name}`] = await page.evaluate(() => window.relit.pick(128.3, 64.6));
        if (tiled) {
          fs.writeFileSync(path.join(out, `tiled ${name}.viewer.png`), encodePng(g.w, g.h, g.rgb));
          results.comparisons[`tiled ${name} fetched`] = { tiles: stats.tiles - before.tiles, bytes: stats.bytes - before.bytes };
        }
      }
    }
    const whole = 1024 * 256 * current.info.layers.length * 8;
    for (const [name, , , want] of views) {
      const r = compare(frames[`true ${name}`].rgb, frames[`false ${name}`].rgb);
      results.comparisons[`tiled ${name} vs whole`] = r;
      if (want === 'equal') expect(`tiled ${name}: the frame equals the whole bundle's (max |diff| ≤ 1)`, r.max_abs <= 1, r);
      else expect(`tiled ${name}: the frame matches the whole bundle's (≥ ${want} dB)`, r.psnr >= want, r);
    }
    // Picking reads the depth the view draws with: at level 0 the tiles' own, equal to
    // the whole map's; coarser, a level's mean of the hit depths under the texel.
    let hits = 0;
    for (const [name, , , want] of views) {
      const [a, b] = [picks[`false ${name}`], picks[`true ${name}`]];
      const rel = Math.abs(b.depth - a.depth) / a.depth;
      results.comparisons[`tiled ${name} pick`] = { whole: a.depth, tiled: b.depth, relative: rel };
      if (want === 'equal') {
        if (a.depth > 0) hits++;
        expect(`tiled ${name}: a click finds the whole map's depth and point`, b.depth === a.depth &&
          (!(a.depth > 0) || a.point.every((v, k) => Math.abs(v - b.point[k]) < 1e-9)), { whole: a, tiled: b });
      } else {
        expect(`tiled ${name}: a click finds a depth (a coarser level's, within 25 % of the whole map's)`, b.depth > 0 && rel < 0.25, { whole: a, tiled: b });
      }
    }
    expect('the clicks at level 0 hit a surface in three views or more', hits >= 3, hits);
    const zoomed = results.comparisons['tiled flat ×4 bilinear fetched'];
    expect('zoomed ×4 into a 256×128 canvas: at most 4 tiles of level 0 fetched, under 8 % of the whole layers',
      zoomed.tiles <= 4 && zoomed.bytes < 0.08 * whole, { ...zoomed, whole_layers_bytes: whole, fraction: zoomed.bytes / whole });
    const overview = results.comparisons['tiled flat ÷16 (the overview) fetched'];
    expect('a view coarser than the overview fetches no tile', overview.tiles === 0, overview);
    const stats = await page.evaluate(() => window.relit.tileStats);
    expect('no tile failed or overflowed the atlas', stats.failed === 0 && stats.overflowed === 0, stats);
    // A compressed file of planes is tiled the same way (its tiles decoded by region).
    const rlz = path.join(work, 'pano-tiled.rlz');
    run('convert', exr, '-o', rlz, '--layout', 'ycc', '--components', '6', '--codec', 'jpeg:90');
    const rlzFrames = [];
    for (const tiled of [false, true]) {
      await open(rlz, tiled ? ['--tiles', '64', '--overview-mib', '0.2'] : ['--tiles', 'off'], size);
      if (tiled) expect('a .rlz file of planes is tiled on request', !!current.info.tiles, current.info.tiles);
      await setRig({ lights });
      await page.evaluate(() => window.relit.setSmooth(true));
      await setView(views[0][1]);
      await page.evaluate(() => window.relit.settle());
      rlzFrames.push(await canvas());
    }
    const r = compare(rlzFrames[0].rgb, rlzFrames[1].rgb);
    results.comparisons['tiled .rlz flat ×4 vs whole'] = r;
    expect('tiled .rlz flat ×4: the frame equals the whole bundle\'s (max |diff| ≤ 1)', r.max_abs <= 1, r);
    // A .rlz file with mip levels: zoomed out, its own level 2's tiles stand in for the
    // whole texture's mipmaps as an EXR's levels do (the server reads that level's
    // tiles, not level 0's).
    const rlzMip = path.join(work, 'pano-tiled-mip.rlz');
    run('convert', exr, '-o', rlzMip, '--layout', 'ycc', '--components', '6', '--codec', 'jpeg:90', '--mip-tiles', '64');
    const mipFrames = [];
    for (const [file, flags] of [[rlz, ['--tiles', 'off']], [rlzMip, ['--tiles', '64', '--overview-mib', '0.2']]]) {
      await open(file, flags, size);
      await setRig({ lights });
      await page.evaluate(() => window.relit.setSmooth(true));
      await setView(views[4][1]);
      await page.evaluate(() => window.relit.settle());
      mipFrames.push(await canvas());
    }
    const m = compare(mipFrames[0].rgb, mipFrames[1].rgb);
    results.comparisons['tiled .rlz with mip levels ÷4 vs whole'] = m;
    expect('tiled .rlz with mip levels, ÷4 (its level 2): the frame matches the whole bundle\'s (≥ 40 dB)', m.psnr >= 40, m);
  });
} finally {
  await browser.close();
  for (const p of servers) p.kill();
}
fs.writeFileSync(path.join(out, 'results.json'), JSON.stringify(results, null, 2));
log(`renderer: ${results.renderer}; sections (s): ${JSON.stringify(results.sections_s)}; results in ${path.join(out, 'results.json')}`);
if (failed) { log('FAILED'); process.exit(1); }
log('passed');

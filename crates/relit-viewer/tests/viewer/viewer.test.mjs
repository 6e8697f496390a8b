// End-to-end test of `relit view` in headless Chromium (SwiftShader WebGL2):
// sets lights through the page's own controls, reads the canvas back and compares it
// with `relit relight` (the CPU engine) for the same rig; measures frame times and
// saves screenshots.
//
//   node viewer.test.mjs --relit target/release/relit --out target/viewer-test \
//        --playwright target/viewer-node [--chromium /usr/bin/chromium]
//
// Tolerance: 8-bit sRGB PSNR ≥ 40 dB over all pixels and channels, for a directional
// light and for a point light placed by clicking the image (half-float planes).
import { createRequire } from 'node:module';
import { spawn, execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import zlib from 'node:zlib';
import http from 'node:http';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith('--') ? acc.concat([[a.slice(2), all[i + 1]]]) : acc), []));
const relit = path.resolve(args.relit || 'target/release/relit');
const out = path.resolve(args.out || 'target/viewer-test');
const chromiumPath = args.chromium || '/usr/bin/chromium';
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

/** A Radiance .hdr (flat RGBE scanlines) of a sky: blue above, warm sun, dark ground. */
function writeSkyHdr(file, w, h) {
  const head = Buffer.from(`#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y ${h} +X ${w}\n`);
  const px = Buffer.alloc(w * h * 4);
  for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
    const v = (y + 0.5) / h, u = (x + 0.5) / w;
    let c = v < 0.5 ? [0.3, 0.45, 0.8] : [0.12, 0.1, 0.08];
    if (Math.hypot(u - 0.65, v - 0.3) < 0.06) c = [8, 7, 5];
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

// ---- the scene --------------------------------------------------------------------------
const work = path.join(out, 'work');
fs.mkdirSync(work);
const W = 1024, H = 256;
const t0 = Date.now();
run('capture', 'box', '--lights', 'fibonacci:48', '--camera', 'cylindrical', '--size', `${W}x${H}`, '--out', path.join(work, 'cap'), '-q');
run('fit', path.join(work, 'cap', 'capture.json'), '--bands', '4', '--objective', 'linear', '-o', path.join(work, 'pano.exr'));
writeSkyHdr(path.join(work, 'sky.hdr'), 64, 32);
log(`capture + fit of a ${W}×${H} k=16 cylindrical panorama: ${((Date.now() - t0) / 1000).toFixed(1)} s`);
const slide = new Uint8Array(32 * 24 * 3);
for (let y = 0; y < 24; y++) for (let x = 0; x < 32; x++) { const on = ((x >> 2) + (y >> 2)) & 1; slide.set(on ? [255, 230, 40] : [30, 60, 255], 3 * (32 * y + x)); }
fs.writeFileSync(path.join(work, 'slide.png'), encodePng(32, 24, slide));

function startServer(extra = []) {
  return new Promise((resolve, reject) => {
    const p = spawn(relit, ['view', path.join(work, 'pano.exr'), '--env', path.join(work, 'sky.hdr'), ...extra], { stdio: ['ignore', 'pipe', 'inherit'] });
    let buf = '';
    p.stdout.on('data', (d) => { buf += d; const m = buf.match(/http:\/\/\S+/); if (m) resolve({ proc: p, url: m[0] }); });
    p.on('exit', (code) => reject(new Error(`relit view exited with ${code}`)));
  });
}

const results = { tolerance: `8-bit sRGB PSNR >= ${MIN_PSNR} dB`, comparisons: {}, frame_ms: {} };
let failed = false;
const servers = [];
const browser = await chromium.launch({ executablePath: chromiumPath, headless: true, args: ['--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--ignore-gpu-blocklist', '--no-sandbox'] });
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 760 } });
  page.on('console', (m) => { if (m.type() === 'error') log('page error:', m.text()); });
  page.on('pageerror', (e) => log('page exception:', e.message));

  async function open(extra) {
    const s = await startServer(extra);
    servers.push(s.proc);
    await page.goto(s.url);
    await page.evaluate(() => window.relit.ready);
    await page.evaluate(([w, h]) => { window.relit.setCanvasSize(w, h); window.relit.setView({ mode: 'flat', center: [w / 2, h / 2], zoom: 1 }); }, [W, H]);
    results.renderer = await page.evaluate(() => { const gl = document.createElement('canvas').getContext('webgl2'); const e = gl.getExtension('WEBGL_debug_renderer_info'); return e ? gl.getParameter(e.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER); });
    return s.url;
  }

  async function check(name, minPsnr = MIN_PSNR) {
    const rig = await page.evaluate(() => window.relit.getRig());
    const rigFile = path.join(work, `${name}.rig.json`);
    fs.writeFileSync(rigFile, JSON.stringify(rig, null, 2));
    const cpuFile = path.join(out, `${name}.cpu.png`);
    run('relight', path.join(work, 'pano.exr'), '--rig', rigFile, '-o', cpuFile);
    const cpu = decodePng(fs.readFileSync(cpuFile));
    const b64 = await page.evaluate(() => { const px = window.relit.readPixels(); let s = ''; for (let i = 0; i < px.length; i += 4) s += String.fromCharCode(px[i], px[i + 1], px[i + 2]); return btoa(s); });
    const gpu = new Uint8Array(Buffer.from(b64, 'base64'));
    fs.writeFileSync(path.join(out, `${name}.viewer.png`), encodePng(W, H, gpu));
    const r = compare(gpu, cpu.rgb);
    const warnings = await page.evaluate(() => window.relit.warnings);
    results.comparisons[name] = { ...r, rig: rig.lights, warnings, min_psnr: minPsnr };
    const ok = r.psnr >= minPsnr && warnings.length === 0;
    log(`${ok ? 'ok  ' : 'FAIL'} ${name}: PSNR ${r.psnr.toFixed(2)} dB, max |diff| ${r.max_abs}, ${(100 * r.frac_over_2).toFixed(3)}% of samples off by > 2 (need ≥ ${minPsnr} dB)${warnings.length ? ' warnings: ' + warnings : ''}`);
    if (!ok) failed = true;
  }

  await open([]);
  // 1. A directional light through the DOM controls of the first light card.
  const card = page.locator('.light').first();
  await card.locator('select[data-field="type"]').selectOption('directional');
  await card.locator('[data-field="direction.0"]').fill('-0.4');
  await card.locator('[data-field="direction.1"]').fill('0.6');
  await card.locator('[data-field="direction.2"]').fill('0.7');
  await card.locator('input[data-field="color"]').fill('#ffd9b3');
  await card.locator('[data-field="intensity"]').fill('1.5');
  await check('directional');

  // 2. A point light: change the type, place it by clicking the image, set its intensity.
  await card.locator('select[data-field="type"]').selectOption('point');
  await page.locator('.light').first().locator('button[data-tool="place"]').click();
  const box = await page.locator('#view').boundingBox();
  await page.mouse.click(box.x + 0.55 * box.width, box.y + 0.6 * box.height);
  await page.locator('.light').first().locator('[data-field="intensity"]').fill('2');
  await check('point');

  // 3. Two lights together (directional + point) with the "add light" button.
  await page.locator('#new-type').selectOption('directional');
  await page.locator('#add-light').click();
  await page.locator('.light').nth(1).locator('[data-field="direction.0"]').fill('0.8');
  await check('point+directional');

  // 4. Spot, projector and environment lights set through the rig hook.
  const pos = (await page.evaluate(() => window.relit.getRig())).lights[0].position;
  await page.evaluate((p) => window.relit.setRig({ lights: [{ type: 'spot', position: p, direction: [0.2, -0.5, -1], cone_deg: 35, softness_deg: 8, intensity: 3 }] }), pos);
  await check('spot');
  await page.evaluate(async (b64) => {
    const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
    await window.relit.loadSlide('slide.png', new Blob([bytes], { type: 'image/png' }));
  }, fs.readFileSync(path.join(work, 'slide.png')).toString('base64'));
  await page.evaluate((p) => window.relit.setRig({ lights: [{ type: 'projector', position: p, direction: [0.1, -0.2, -1], fov_deg: 50, slide: 'slide.png', intensity: 3 }, { type: 'directional', direction: [0, 1, 1], intensity: 0.3 }] }), pos);
  await check('projector', 35);
  await page.evaluate(() => window.relit.setRig({ lights: [{ type: 'environment', map: 'sky.hdr', yaw_deg: 40, pitch_deg: 10, roll_deg: -5, window: { type: 'hann' }, intensity: 0.5 }] }));
  await check('environment');

  // 5. Frame times for the 1024×256 k=16 panorama (median of synchronised frames).
  await page.evaluate(() => window.relit.setRig({ lights: [{ type: 'directional', direction: [-0.4, 0.6, 0.7] }] }));
  results.frame_ms['flat 1024x256, directional'] = await page.evaluate(() => window.relit.benchmark(15));
  await page.evaluate((p) => window.relit.setRig({ lights: [{ type: 'point', position: p, intensity: 2 }] }), pos);
  results.frame_ms['flat 1024x256, point'] = await page.evaluate(() => window.relit.benchmark(15));
  await page.evaluate((p) => window.relit.setRig({ lights: [{ type: 'directional', direction: [-0.4, 0.6, 0.7] }, { type: 'point', position: p, intensity: 2 }, { type: 'environment', map: 'sky.hdr', intensity: 0.3 }] }), pos);
  await page.evaluate(() => { window.relit.setCanvasSize(1024, 576); window.relit.setView({ mode: 'pano', yaw: 20, pitch: 5, fov: 80 }); });
  results.frame_ms['perspective 1024x576, directional+point+environment'] = await page.evaluate(() => window.relit.benchmark(15));
  for (const [k, v] of Object.entries(results.frame_ms)) log(`frame time ${k}: median ${v.median.toFixed(1)} ms (min ${v.min.toFixed(1)}, max ${v.max.toFixed(1)})`);

  // 6. Screenshot of the whole page: perspective view, light panel with three lights.
  await page.evaluate(() => { window.relit.setCanvasSize(null); });
  await page.waitForTimeout(300);
  await page.evaluate(() => window.relit.renderSync());
  await page.screenshot({ path: path.join(out, 'viewer-screenshot.png') });
  log(`screenshot: ${path.join(out, 'viewer-screenshot.png')}`);

  // 7. `relit export-web` (8-bit quantised planes) hosted by a plain static file server.
  const site = path.join(work, 'site');
  run('export-web', path.join(work, 'pano.exr'), site, '--storage', 'u8', '--env', path.join(work, 'sky.hdr'));
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
    await page.evaluate(([w, h]) => { window.relit.setCanvasSize(w, h); window.relit.setView({ mode: 'flat', center: [w / 2, h / 2], zoom: 1 }); }, [W, H]);
    await page.locator('.light').first().locator('[data-field="direction.0"]').fill('-0.4');
    await check('export-web-u8-directional');
    await page.evaluate((p) => window.relit.setRig({ lights: [{ type: 'point', position: p, intensity: 2 }] }), pos);
    await check('export-web-u8-point');
  } finally { stat.close(); }
} finally {
  await browser.close();
  for (const p of servers) p.kill();
}
fs.writeFileSync(path.join(out, 'results.json'), JSON.stringify(results, null, 2));
log(`renderer: ${results.renderer}; results in ${path.join(out, 'results.json')}`);
if (failed) { log('FAILED'); process.exit(1); }
log('passed');

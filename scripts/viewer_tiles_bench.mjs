// What a tiled view of a big file costs: `relit view FILE` (tiles chosen as `relit view`
// chooses them, or --tiles N), headless Chromium at a 1280×720 canvas, a few views; for
// each, the tiles and bytes the browser fetched, the bytes the server read from the file
// (its /proc/PID/io `rchar`, an independent count) and the time until every tile the
// view needs had arrived, against the whole layers' bytes.
//
//   node scripts/viewer_tiles_bench.mjs --relit target/release/relit --file BIG.exr|BIG.rlz \
//        --playwright target/viewer-node [--chromium /usr/bin/chromium] [--tiles auto] [--json]
import { createRequire } from 'node:module';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith('--') ? acc.concat([[a.slice(2), all[i + 1] && !all[i + 1].startsWith('--') ? all[i + 1] : true]]) : acc), []));
if (!args.file) { console.error('usage: viewer_tiles_bench.mjs --relit BIN --file FILE.exr --playwright DIR [--chromium PATH] [--tiles auto|N] [--json]'); process.exit(2); }
const relit = path.resolve(args.relit || 'target/release/relit');
const require = createRequire(path.resolve(args.playwright || 'target/viewer-node') + '/');
const { chromium } = require('playwright-core');
const [CW, CH] = [1280, 720];

const rchar = (pid) => Number(/rchar: (\d+)/.exec(fs.readFileSync(`/proc/${pid}/io`, 'utf8'))[1]);
const rss = (pid) => Number(/VmHWM:\s+(\d+) kB/.exec(fs.readFileSync(`/proc/${pid}/status`, 'utf8'))[1]) / 1024;

const t0 = Date.now();
const server = spawn(relit, ['view', args.file, '--tiles', String(args.tiles || 'auto')], { stdio: ['ignore', 'pipe', 'inherit'] });
const url = await new Promise((resolve, reject) => {
  let buf = '';
  server.stdout.on('data', (d) => { buf += d; const m = buf.match(/http:\/\/\S+/); if (m) resolve(m[0]); });
  server.on('exit', (code) => reject(new Error(`relit view exited with ${code}`)));
});
const startup = { seconds: (Date.now() - t0) / 1000, read_bytes: rchar(server.pid), peak_mib: rss(server.pid) };
const fileBytes = fs.statSync(args.file).size;
const browser = await chromium.launch({ executablePath: args.chromium || '/usr/bin/chromium', headless: true, args: ['--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--ignore-gpu-blocklist', '--no-sandbox'] });
const rows = [];
try {
  const page = await (await browser.newContext({ viewport: { width: 1400, height: 800 } })).newPage();
  page.on('pageerror', (e) => console.error('page exception:', e.message));
  const loadStart = Date.now();
  await page.goto(url);
  await page.evaluate(() => window.relit.ready);
  const info = await page.evaluate(() => window.relit.info);
  // What the page fetched to show its first frame: the overview's layers, the depth
  // map (the overview's in a tiled bundle, else the whole image's) and the rest.
  const loaded = await page.evaluate(() => performance.getEntriesByType('resource').reduce((a, r) => {
    a.bytes += r.encodedBodySize; if (r.name.endsWith('/data/depth.f32')) a.depth_bytes += r.encodedBodySize; return a;
  }, { bytes: 0, depth_bytes: 0 }));
  const W = info.width, H = info.height;
  const whole = W * H * info.layers_per_channel * 3 * 8;
  await page.evaluate(([w, h]) => window.relit.setCanvasSize(w, h), [CW, CH]);
  // Time the transfer, not the software renderer: no redraw at each tile's arrival.
  await page.evaluate(() => window.relit.setProgressive(false));
  const views = [
    ['flat 1:1, centre', { mode: 'flat', center: [W / 2, H / 2], zoom: 1 }],
    ['flat 1:1, another place', { mode: 'flat', center: [W / 5, H / 3], zoom: 1 }],
    ['flat ×4', { mode: 'flat', center: [W / 3, H / 2], zoom: 4 }],
    ['flat ×1/4 (level 2)', { mode: 'flat', center: [W / 2, H / 2], zoom: 0.25 }],
    ['perspective, 60° field', { mode: 'pano', yaw: 20, pitch: 0, fov: 60 }],
    ['flat, whole width', { mode: 'flat', center: [W / 2, H / 2], zoom: CW / W }],
  ].filter(([name]) => !name.startsWith('perspective') || ['cylindrical', 'equirectangular'].includes(info.projection.type));
  await page.evaluate((v) => window.relit.setView(v), views[0][1]);
  const first = await page.evaluate(() => window.relit.settle(600000));
  rows.push({ view: 'first frame (load + ' + views[0][0] + ')', seconds: (Date.now() - loadStart) / 1000, tiles: first ? first.tiles : 0, bytes: first ? first.bytes : 0 });
  for (const [name, v] of views) {
    const before = await page.evaluate(() => ({ ...(window.relit.tileStats || { tiles: 0, bytes: 0 }) }));
    const readBefore = rchar(server.pid);
    const t = Date.now();
    await page.evaluate((v) => window.relit.setView(v), v);
    const after = await page.evaluate(() => window.relit.settle(600000)) || { tiles: 0, bytes: 0 };
    const seconds = (Date.now() - t) / 1000;
    const frame = await page.evaluate(() => window.relit.benchmark(3));
    rows.push({ view: name, seconds, frame_ms: frame.median, tiles: after.tiles - before.tiles, bytes: after.bytes - before.bytes, server_read_bytes: rchar(server.pid) - readBefore });
  }
  const stats = await page.evaluate(() => window.relit.tileStats);
  const result = { file: args.file, size: [W, H], k: info.k, tiles: info.tiles, file_bytes: fileBytes, whole_layer_bytes: whole, canvas: [CW, CH], server_startup: startup, load: loaded, depth: info.depth, server_peak_mib: rss(server.pid), views: rows, totals: stats };
  if (args.json) console.log(JSON.stringify(result, null, 2));
  else {
    console.log(`${args.file}: ${W}×${H}, k = ${info.k}, file ${(fileBytes / 1e6).toFixed(1)} MB, whole layers ${(whole / 1e6).toFixed(1)} MB; tiles ${info.tiles ? info.tiles.side + ' px, overview level ' + info.tiles.overview : 'none'}`);
    console.log(`server start ${startup.seconds.toFixed(1)} s, read ${(startup.read_bytes / 1e6).toFixed(1)} MB, peak ${startup.peak_mib.toFixed(0)} MiB (at the end: ${result.server_peak_mib.toFixed(0)} MiB)`);
    console.log(`page load fetched ${(loaded.bytes / 1e6).toFixed(1)} MB, of it the depth map ${(loaded.depth_bytes / 1e6).toFixed(1)} MB${info.depth ? ` (${info.depth.width || W}×${info.depth.height || H})` : ''}`);
    console.log('| view (1280×720 canvas) | s until every tile arrived (2 frames included) | frame ms | tiles | MB fetched | % of whole layers | MB the server read |');
    console.log('|---|---:|---:|---:|---:|---:|---:|');
    for (const r of rows) console.log(`| ${r.view} | ${r.seconds.toFixed(2)} | ${r.frame_ms != null ? r.frame_ms.toFixed(0) : '—'} | ${r.tiles} | ${(r.bytes / 1e6).toFixed(1)} | ${(100 * r.bytes / whole).toFixed(2)} | ${r.server_read_bytes != null ? (r.server_read_bytes / 1e6).toFixed(1) : '—'} |`);
  }
} finally {
  await browser.close();
  server.kill();
}

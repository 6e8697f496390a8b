// Drives the real OpenLIME client (shared/clients/openlime) in headless Chromium
// (SwiftShader WebGL2) over relight/OpenLIME web folders: serves the client and each
// folder on 127.0.0.1 (an ephemeral port, HTTP Range requests as tarzoom needs),
// opens `rti.html` at the folder's size, calls `setLight(x, y)` for each light and
// saves the page as `OUT/NAME-I.png`. Prints one JSON line: per folder, the console
// errors and the screenshots. The comparison with relit is the caller's
// (crates/relit-cli/tests/web.rs).
//
//   node openlime.mjs --client DIR --playwright DIR --chromium PATH --out DIR --cases FILE
//
// FILE: [{"name", "folder", "layout", "width", "height", "lights": [[x, y], …]}, …]
import { createRequire } from 'node:module';
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith('--') ? acc.concat([[a.slice(2), all[i + 1]]]) : acc), []));
const require = createRequire(path.resolve(args.playwright) + '/');
const { chromium } = require('playwright-core');
const cases = JSON.parse(fs.readFileSync(args.cases, 'utf8'));
const out = path.resolve(args.out);
fs.mkdirSync(out, { recursive: true });

const roots = { lime: path.resolve(args.client) };
for (const c of cases) roots[c.name] = path.resolve(c.folder);
const types = { '.html': 'text/html', '.js': 'text/javascript', '.json': 'application/json', '.jpg': 'image/jpeg', '.png': 'image/png', '.dzi': 'application/xml' };
const server = http.createServer((req, res) => {
  // Chromium asks for an icon on its own; only the page's requests count.
  if (req.url === '/favicon.ico') { res.writeHead(204); res.end(); return; }
  const [, root, ...rest] = decodeURIComponent(req.url.split('?')[0]).split('/');
  const base = roots[root];
  const file = base && path.resolve(base, rest.join('/'));
  if (!file || !file.startsWith(base + path.sep) || !fs.existsSync(file) || !fs.statSync(file).isFile()) {
    res.writeHead(404); res.end(); return;
  }
  const data = fs.readFileSync(file);
  const headers = { 'Content-Type': types[path.extname(file)] || 'application/octet-stream', 'Accept-Ranges': 'bytes' };
  const range = /bytes=(\d+)-(\d*)/.exec(req.headers.range || '');
  if (range) {
    const start = +range[1], end = range[2] ? Math.min(+range[2], data.length - 1) : data.length - 1;
    res.writeHead(206, { ...headers, 'Content-Range': `bytes ${start}-${end}/${data.length}`, 'Content-Length': end - start + 1 });
    res.end(data.subarray(start, end + 1));
  } else {
    res.writeHead(200, { ...headers, 'Content-Length': data.length });
    res.end(data);
  }
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const port = server.address().port;

const browser = await chromium.launch({ executablePath: args.chromium, headless: true, args: ['--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--ignore-gpu-blocklist', '--no-sandbox'] });
const report = [];
try {
  for (const c of cases) {
    const page = await browser.newPage({ viewport: { width: c.width, height: c.height }, deviceScaleFactor: 1 });
    const errors = [];
    page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
    page.on('pageerror', (e) => errors.push(String(e)));
    page.on('requestfailed', (r) => errors.push(`request failed: ${r.url()}`));
    page.on('response', (r) => { if (r.status() >= 400) errors.push(`HTTP ${r.status()}: ${r.url()}`); });
    const shots = [];
    try {
      await page.goto(`http://127.0.0.1:${port}/lime/rti.html?url=/${c.name}/info.json&layout=${c.layout}`);
      await page.waitForFunction(() => window.limeReady === true, null, { timeout: 60000 });
      for (const [i, [x, y]] of c.lights.entries()) {
        await page.evaluate(([x, y]) => window.setLight(x, y), [x, y]);
        // Tiles arrive asynchronously; the frame is settled when two shots agree.
        let previous = null;
        for (let tries = 0; tries < 40; tries++) {
          await page.waitForTimeout(250);
          const shot = await page.screenshot({ type: 'png' });
          if (previous && shot.equals(previous)) break;
          previous = shot;
        }
        const file = path.join(out, `${c.name}-${i}.png`);
        fs.writeFileSync(file, previous);
        shots.push(file);
      }
    } catch (e) {
      errors.push(String(e));
    }
    report.push({ name: c.name, errors, shots });
    await page.close();
  }
} finally {
  await browser.close();
  server.close();
}
console.log(JSON.stringify(report));

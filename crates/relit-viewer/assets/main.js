// The viewer: loads data/info.json and its layers, keeps the rig and the view, handles
// mouse, touch and keyboard, and redraws on demand (each draw relights only the pixels
// on screen).
import { Renderer } from './renderer.js';
import { Panel } from './panel.js';
import { newLight, checkRig, rigOfFile, rigToJson, areaCenter } from './lights.js';
import { normalize, sub } from './vec.js';

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);

const app = {
  base: params.get('data') || 'data/',
  rig: { lights: [] },
  exposure: 0,
  selected: -1,
  tool: 'view',
  view: null,
  fixedSize: null,
  frameMs: NaN,
  frames: 0,
  progressive: true, // a tiled bundle redraws as each tile arrives
};

function defaultView(r) {
  const W = r.info.width, H = r.info.height;
  const c = canvasEl.width, d = canvasEl.height;
  const zoom = Math.min(c / W, d / H);
  return { mode: r.isPanorama ? 'pano' : 'flat', center: [W / 2, H / 2], zoom: r.isPanorama ? Math.max(zoom, d / H) : zoom, yaw: 0, pitch: 0, fov: 75 };
}

const canvasEl = $('view');
let renderer, panel, pending = 0; // pending: the requested animation frame

function resize() {
  if (app.fixedSize) {
    [canvasEl.width, canvasEl.height] = app.fixedSize;
    canvasEl.style.width = app.fixedSize[0] + 'px';
    canvasEl.style.height = app.fixedSize[1] + 'px';
  } else {
    canvasEl.style.width = canvasEl.style.height = '';
    const dpr = window.devicePixelRatio || 1, b = canvasEl.getBoundingClientRect();
    canvasEl.width = Math.max(1, Math.round(b.width * dpr));
    canvasEl.height = Math.max(1, Math.round(b.height * dpr));
  }
  request();
}

function request() {
  if (pending || !renderer) return;
  pending = requestAnimationFrame(() => { pending = 0; renderNow(); });
}

function renderNow() {
  if (pending) { cancelAnimationFrame(pending); pending = 0; }
  const t0 = performance.now();
  renderer.draw(app.view, app.exposure);
  renderer.finish();
  app.frameMs = performance.now() - t0;
  app.frames++;
  $('frame-time').textContent = `${app.frameMs.toFixed(1)} ms/frame · ${canvasEl.width}×${canvasEl.height}`;
}

app.changed = (structural) => {
  const warnings = renderer.prepare(app.rig);
  $('warnings').textContent = warnings.join('\n');
  if (structural) panel.build();
  request();
};
app.refreshSpheres = () => {};
app.setTool = (tool) => {
  app.tool = tool;
  canvasEl.classList.toggle('tool', tool !== 'view');
};

// ---- pointer, wheel, touch, keyboard -------------------------------------------------
const pointers = new Map();
let drag = null;

function canvasPos(e) {
  const b = canvasEl.getBoundingClientRect();
  return [((e.clientX - b.left) * canvasEl.width) / b.width, ((e.clientY - b.top) * canvasEl.height) / b.height];
}

function applyTool(pos) {
  const light = app.rig.lights[app.selected];
  if (!light) return;
  const say = (text) => { $('warnings').textContent = text; };
  if (app.tool === 'aim' && light.type === 'directional') {
    // The light comes from where the cursor points (no depth needed).
    const d = renderer.directionAt(app.view, pos[0], pos[1]);
    if (!d) { say('outside the image'); return; }
    light.direction = d.map(v => Math.round(v * 1e4) / 1e4);
  } else {
    const hit = renderer.pick(app.view, pos[0], pos[1]);
    if (!hit || !(hit.depth > 0)) { say('nothing was hit there (no depth)'); return; }
    if (app.tool === 'place' && light.position) {
      const lift = Math.min(0.95, Math.max(0, parseFloat($('lift').value) || 0));
      light.position = hit.origin.map((o, k) => Math.round((o + (1 - lift) * hit.depth * hit.dir[k]) * 1e4) / 1e4);
    } else if (app.tool === 'place' && areaCenter(light)) {
      const lift = Math.min(0.95, Math.max(0, parseFloat($('lift').value) || 0));
      (light.shape.rect || light.shape.disk).center = hit.origin.map((o, k) => Math.round((o + (1 - lift) * hit.depth * hit.dir[k]) * 1e4) / 1e4);
    } else if (app.tool === 'aim' && light.direction && light.position) {
      const d = normalize(sub(hit.point, light.position));
      if (d) light.direction = d.map(v => Math.round(v * 1e4) / 1e4);
    } else return;
  }
  panel.refresh();
  app.changed(false);
}

function zoomBy(factor, at) {
  const v = app.view;
  if (v.mode === 'pano' && renderer.isPanorama) {
    v.fov = Math.min(140, Math.max(5, v.fov / factor));
    $('fov').value = v.fov;
  } else {
    const cw = canvasEl.width, ch = canvasEl.height;
    const p = at || [cw / 2, ch / 2];
    const before = [v.center[0] + (p[0] - cw / 2) / v.zoom, v.center[1] + (p[1] - ch / 2) / v.zoom];
    v.zoom = Math.min(64, Math.max(0.02, v.zoom * factor));
    v.center = [before[0] - (p[0] - cw / 2) / v.zoom, before[1] - (p[1] - ch / 2) / v.zoom];
  }
  request();
}

function panBy(dx, dy) {
  const v = app.view;
  if (v.mode === 'pano' && renderer.isPanorama) {
    const degPerPx = v.fov / canvasEl.height;
    v.yaw = (v.yaw - dx * degPerPx) % 360;
    v.pitch = Math.min(89, Math.max(-89, v.pitch + dy * degPerPx));
  } else {
    v.center = [v.center[0] - dx / v.zoom, v.center[1] - dy / v.zoom];
  }
  request();
}

canvasEl.addEventListener('pointerdown', (e) => {
  canvasEl.focus();
  canvasEl.setPointerCapture(e.pointerId);
  const pos = canvasPos(e);
  pointers.set(e.pointerId, pos);
  if (pointers.size === 1) {
    drag = { last: pos, tool: app.tool !== 'view' && e.button === 0 };
    if (drag.tool) applyTool(pos);
  } else drag = null; // two fingers: pinch (see pointermove)
});
canvasEl.addEventListener('pointermove', (e) => {
  const pos = canvasPos(e);
  if (!pointers.has(e.pointerId)) {
    const hit = renderer && renderer.pick(app.view, pos[0], pos[1]);
    $('hover').textContent = hit ? `px ${hit.pixel[0]},${hit.pixel[1]}${hit.depth > 0 ? ' depth ' + hit.depth.toFixed(3) : ''}` : '';
    return;
  }
  const prev = pointers.get(e.pointerId);
  if (pointers.size === 2) {
    // Pinch: what was under the fingers' midpoint follows it (pan), then zoom by the
    // change of their distance about the new midpoint.
    const other = [...pointers.entries()].find(([id]) => id !== e.pointerId)[1];
    const d0 = Math.hypot(prev[0] - other[0], prev[1] - other[1]), d1 = Math.hypot(pos[0] - other[0], pos[1] - other[1]);
    const m0 = [(prev[0] + other[0]) / 2, (prev[1] + other[1]) / 2], m1 = [(pos[0] + other[0]) / 2, (pos[1] + other[1]) / 2];
    panBy(m1[0] - m0[0], m1[1] - m0[1]);
    if (d0 > 0 && d1 > 0) zoomBy(d1 / d0, m1);
  } else if (drag && pointers.size === 1) {
    if (drag.tool) applyTool(pos);
    else panBy(pos[0] - drag.last[0], pos[1] - drag.last[1]);
    drag.last = pos;
  }
  pointers.set(e.pointerId, pos);
});
const up = (e) => {
  pointers.delete(e.pointerId);
  // After a pinch the finger still down pans on (never applies a tool).
  drag = pointers.size === 1 ? { last: [...pointers.values()][0], tool: false } : null;
};
canvasEl.addEventListener('pointerup', up);
canvasEl.addEventListener('pointercancel', up);
canvasEl.addEventListener('wheel', (e) => { e.preventDefault(); zoomBy(Math.exp(-e.deltaY * 0.0015), canvasPos(e)); }, { passive: false });
window.addEventListener('keydown', (e) => {
  if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement || e.target instanceof HTMLTextAreaElement) return;
  if (e.ctrlKey || e.metaKey || e.altKey) return; // leave the browser's own shortcuts (Ctrl +/-/0) alone
  const step = e.shiftKey ? 80 : 20;
  const keys = { ArrowLeft: () => panBy(step, 0), ArrowRight: () => panBy(-step, 0), ArrowUp: () => panBy(0, step), ArrowDown: () => panBy(0, -step),
    '+': () => zoomBy(1.25), '=': () => zoomBy(1.25), '-': () => zoomBy(0.8), '0': resetView,
    Escape: () => { app.setTool('view'); panel.build(); } };
  if (keys[e.key]) { keys[e.key](); e.preventDefault(); }
});
window.addEventListener('resize', resize);

// ---- panel controls ------------------------------------------------------------------
$('view-mode').addEventListener('change', () => { app.view.mode = $('view-mode').value; request(); });
$('fov').addEventListener('input', () => { app.view.fov = Number($('fov').value); request(); });
$('exposure').addEventListener('input', () => { app.exposure = Number($('exposure').value); $('exposure-out').value = app.exposure; request(); });
function resetView() { app.view = defaultView(renderer); syncViewControls(); request(); }
$('reset-view').addEventListener('click', resetView);
$('smooth').addEventListener('change', () => { renderer.smooth = $('smooth').checked; request(); });
$('add-light').addEventListener('click', () => {
  app.rig.lights.push(newLight($('new-type').value, renderer.info));
  app.selected = app.rig.lights.length - 1;
  app.changed(true);
});
$('save-rig').addEventListener('click', () => download(new Blob([rigToJson(app.rig)], { type: 'application/json' }), 'rig.json'));
$('load-rig').addEventListener('change', async () => {
  const f = $('load-rig').files[0];
  if (!f) return;
  try {
    const { rig, note } = rigOfFile(JSON.parse(await f.text()));
    setRig(rig);
    if (note) $('warnings').textContent = [note, $('warnings').textContent].filter(Boolean).join('\n');
  } catch (err) { $('warnings').textContent = `could not load ${f.name}: ${err.message}`; }
  $('load-rig').value = '';
});
$('screenshot').addEventListener('click', () => { renderNow(); canvasEl.toBlob(b => download(b, 'relit-screenshot.png'), 'image/png'); });

function download(blob, name) {
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob);
  a.download = name;
  document.body.append(a);
  a.click();
  setTimeout(() => { URL.revokeObjectURL(a.href); a.remove(); }, 1000);
}

function syncViewControls() {
  $('view-mode').value = app.view.mode;
  $('fov').value = app.view.fov;
  $('view-mode').disabled = !renderer.isPanorama;
}

function setRig(rig) {
  checkRig(rig);
  app.rig = { lights: rig.lights };
  app.selected = rig.lights.length ? 0 : -1;
  app.changed(true);
}

// ---- start ---------------------------------------------------------------------------
async function start() {
  try {
    renderer = new Renderer(canvasEl);
    const info = await renderer.load(app.base);
    renderer.onTile = () => { if (app.progressive) request(); }; // a tile arrived: draw again
    $('source').textContent = `${info.source} · ${info.width}×${info.height} · ${info.basis.name} · ${info.projection.type} · ${info.storage}${info.tiles ? ` · ${info.tiles.side}-px tiles` : ''}`;
    panel = new Panel(app, $('lights'));
    app.renderer = renderer;
    app.info = info;
    app.refreshSpheres = () => panel.refresh();
    resize();
    app.view = defaultView(renderer);
    syncViewControls();
    app.rig = { lights: [newLight('directional', info)] };
    app.selected = 0;
    app.changed(true);
    $('status').textContent = '';
  } catch (err) {
    $('status').textContent = 'error: ' + err.message;
    console.error(err);
    throw err;
  }
}
const ready = start();

// Hooks for scripts and tests (the UI above does the same through the DOM).
window.relit = {
  ready,
  get info() { return renderer.info; },
  get frameMs() { return app.frameMs; },
  get warnings() { return renderer.warnings; },
  getRig: () => JSON.parse(rigToJson(app.rig)),
  setRig,
  setView: (v) => { Object.assign(app.view, v); syncViewControls(); request(); },
  getView: () => ({ ...app.view }),
  setExposure: (s) => { app.exposure = s; request(); },
  /** Bilinear (true) or nearest-texel (false) sampling of the coefficients. */
  setSmooth: (on) => { renderer.smooth = !!on; $('smooth').checked = !!on; request(); },
  /** Fix the canvas to w×h device pixels (null: follow the layout). */
  setCanvasSize: (w, h) => { app.fixedSize = w ? [w, h] : null; resize(); },
  renderSync: () => { renderNow(); return app.frameMs; },
  /** The canvas as RGBA bytes, top row first (drawn first if a redraw is pending). */
  readPixels: () => { if (pending || !app.frames) renderNow(); return Array.from(renderer.readPixels()); },
  /** Frames drawn so far. */
  get frames() { return app.frames; },
  /** Median milliseconds of `n` synchronised frames. */
  benchmark: (n = 20) => {
    const t = [];
    for (let i = 0; i < n; i++) { const t0 = performance.now(); renderer.draw(app.view, app.exposure); renderer.finish(); t.push(performance.now() - t0); }
    t.sort((a, b) => a - b);
    return { median: t[t.length >> 1], min: t[0], max: t[t.length - 1], frames: n, width: canvasEl.width, height: canvasEl.height };
  },
  /** Draw until every tile the view needs has arrived (tiled bundles); the tiles
   *  fetched so far and their bytes. */
  settle: async (timeoutMs = 60000) => {
    const t0 = performance.now();
    for (;;) {
      renderNow(); // finds the tiles the view needs and asks for the missing ones
      if (!renderer.tilesPending()) return renderer.tileStats || null;
      while (renderer.tilesPending()) {
        if (performance.now() - t0 > timeoutMs) throw new Error('tiles still pending after ' + timeoutMs + ' ms');
        await new Promise((r) => setTimeout(r, 10));
      }
    }
  },
  /** Whether a tile's arrival redraws the view (on by default; benchmarks of the
   *  transfer alone turn it off). */
  setProgressive: (on) => { app.progressive = !!on; },
  get tileStats() { return renderer.tileStats || null; },
  /** What a click at canvas position (cx, cy) finds: its pixel, depth, ray and surface
   *  point (renderer.pick). */
  pick: (cx, cy) => renderer.pick(app.view, cx, cy),
  loadSlide: async (name, url) => { await renderer.loadSlide(name, url); app.changed(false); },
};

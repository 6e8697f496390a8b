// The light panel: one card per light of the rig, bound to the rig's JSON objects.
import { TYPES, newLight, convertArea } from './lights.js';
import { diskFrame, MAX_AREA_SAMPLES } from './renderer.js';
import { normalize } from './vec.js';

const h = (tag, attrs = {}, ...children) => {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === 'class') el.className = v;
    else if (k.startsWith('on')) el.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) el.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat()) if (c != null) el.append(c);
  return el;
};

const toHex = (c) => '#' + c.map(v => Math.round(Math.min(1, Math.max(0, v)) * 255).toString(16).padStart(2, '0')).join('');
const fromHex = (s) => [1, 3, 5].map(i => parseInt(s.slice(i, i + 2), 16) / 255);
const fmt = (v) => (Math.round(v * 1e4) / 1e4).toString();

export class Panel {
  /** `app` gives: rig, info, selected, tool, changed(structural), setTool(tool). */
  constructor(app, root) {
    this.app = app;
    this.root = root;
  }

  build() {
    const { rig } = this.app;
    this.root.replaceChildren(...rig.lights.map((l, i) => this.card(l, i)));
  }

  card(light, index) {
    const app = this.app;
    const card = h('div', { class: 'light' + (app.selected === index ? ' selected' : ''), 'data-index': index });
    card.addEventListener('pointerdown', () => { if (app.selected !== index) { app.selected = index; this.markSelected(); } });
    const typeSelect = h('select', { 'data-field': 'type', 'aria-label': 'light type' },
      TYPES.map(t => h('option', { value: t, selected: t === light.type }, t)));
    typeSelect.addEventListener('change', () => {
      app.rig.lights[index] = newLight(typeSelect.value, app.info, light);
      app.changed(true);
    });
    const remove = h('button', { type: 'button', class: 'remove', title: 'remove this light', onclick: () => {
      app.rig.lights.splice(index, 1);
      if (app.selected >= app.rig.lights.length) app.selected = app.rig.lights.length - 1;
      app.changed(true);
    } }, '✕');
    card.append(h('header', {}, h('b', {}, `#${index + 1}`), typeSelect, remove));

    const color = h('input', { type: 'color', 'data-field': 'color', value: toHex(light.color || [1, 1, 1]) });
    color.addEventListener('input', () => { light.color = fromHex(color.value); app.changed(false); });
    const intensity = this.number(light, 'intensity', light.intensity != null ? light.intensity : 1, 0.1);
    card.append(h('div', { class: 'row' }, h('label', {}, 'colour ', color), h('label', {}, 'intensity ', intensity)));

    if (light.position) {
      card.append(this.vector(light, 'position', 'position'));
      card.append(h('div', { class: 'row' }, this.toolButton('place', index, 'place on image')));
    }
    if (light.direction) {
      const label = light.type === 'directional' ? 'direction (toward the light)' : 'direction (into the scene)';
      const vec = this.vector(light, 'direction', label);
      card.append(vec);
      const sphere = this.sphere(light, vec);
      const row = h('div', { class: 'row' }, sphere);
      row.append(this.toolButton('aim', index, 'aim on image'));
      card.append(row);
    }
    if (light.type === 'spot') {
      card.append(h('div', { class: 'row' },
        h('label', {}, 'cone° ', this.number(light, 'cone_deg', light.cone_deg, 1)),
        h('label', {}, 'softness° ', this.number(light, 'softness_deg', light.softness_deg != null ? light.softness_deg : 5, 1))));
    }
    if (light.type === 'projector') {
      const file = h('input', { type: 'file', accept: 'image/*' });
      const name = h('input', { type: 'text', 'data-field': 'slide', value: light.slide, size: 12 });
      name.addEventListener('change', () => { light.slide = name.value; app.changed(false); });
      file.addEventListener('change', async () => {
        const f = file.files[0];
        if (!f) return;
        light.slide = f.name;
        await app.renderer.loadSlide(f.name, f);
        app.changed(true);
      });
      card.append(h('div', { class: 'row' }, h('label', {}, 'fov° ', this.number(light, 'fov_deg', light.fov_deg, 1))));
      card.append(h('div', { class: 'row' }, 'slide ', name, h('label', { class: 'file-button' }, 'open…', file)));
    }
    if (light.position) card.append(this.attenuation(light));
    if (light.type === 'area') this.area(light, index, card);
    if (light.type === 'environment') {
      const envs = app.info.environments || [];
      const sel = h('select', { 'data-field': 'map' }, envs.map(e => h('option', { value: e.map, selected: e.map === light.map }, e.map)));
      if (!envs.length) sel.append(h('option', {}, '(no maps: relit view … --env MAP.hdr)'));
      sel.addEventListener('change', () => { light.map = sel.value; app.changed(true); });
      const env = envs.find(e => e.map === light.map);
      card.append(h('div', { class: 'row' }, 'map ', sel));
      if (env) card.append(h('img', { src: app.base + env.preview, width: 256, height: 128, alt: 'environment map', style: 'width:100%;image-rendering:pixelated' }));
      for (const key of ['yaw_deg', 'pitch_deg', 'roll_deg']) {
        const out = h('output', {}, fmt(light[key] || 0));
        const range = h('input', { type: 'range', min: -180, max: 180, step: 1, value: light[key] || 0, 'data-field': key });
        range.addEventListener('input', () => { light[key] = Number(range.value); out.value = range.value; app.changed(false); });
        card.append(h('label', {}, key.replace('_deg', '') + ' ', range, ' ', out));
      }
      // Windows scale a basis' bands; a file whose basis has none carries no factors
      // (info.basis.windows), and the control says why it is off.
      const basis = app.info.basis;
      const win = h('select', { 'data-field': 'window', disabled: !basis.windows }, ['none', 'hann', 'lanczos', 'laplacian'].map(t => h('option', { value: t, selected: ((light.window || {}).type || 'none') === t }, t)));
      win.addEventListener('change', () => { light.window = { type: win.value }; app.changed(false); });
      card.append(h('label', {}, 'window ', win));
      if (!basis.windows) card.append(h('p', { class: 'hint', 'data-hint': 'window' }, `Windows scale a basis' bands against ringing; ${basis.name} has none, so no window applies.`));
    }
    return card;
  }

  /** An area light's controls: shape, centre (placed on the image like a point
   *  light), the rectangle's half edges u, v (it emits toward u × v) or the disk's
   *  normal and radius, samples and two-sidedness. */
  area(light, index, card) {
    const app = this.app;
    const kind = light.shape && light.shape.disk ? 'disk' : 'rect';
    const body = light.shape[kind];
    const shape = h('select', { 'data-field': 'shape', 'aria-label': 'area light shape' },
      ['rect', 'disk'].map(t => h('option', { value: t, selected: t === kind }, t === 'rect' ? 'rectangle' : 'disk')));
    shape.addEventListener('change', () => { convertArea(light, shape.value, diskFrame); app.changed(true); });
    card.append(h('div', { class: 'row' }, h('label', {}, 'shape ', shape)));
    card.append(this.vector(body, 'center', 'centre'));
    card.append(h('div', { class: 'row' }, this.toolButton('place', index, 'place on image')));
    if (kind === 'rect') {
      card.append(this.vector(body, 'u', 'half edge u (emits toward u × v)'));
      card.append(this.vector(body, 'v', 'half edge v'));
    } else {
      card.append(this.vector(body, 'normal', 'normal (emitting side)'));
      card.append(h('div', { class: 'row' }, h('label', {}, 'radius ', this.number(body, 'radius', body.radius, 0.05))));
    }
    const samples = h('input', { type: 'number', min: 1, max: 4096, step: 1, value: light.samples != null ? light.samples : 16, 'data-field': 'samples' });
    samples.addEventListener('input', () => {
      const v = Math.round(parseFloat(samples.value));
      if (v >= 1 && v <= 4096) { light.samples = v; app.changed(false); }
    });
    const two = h('input', { type: 'checkbox', 'data-field': 'two_sided', checked: !!light.two_sided });
    two.addEventListener('change', () => { light.two_sided = two.checked; app.changed(false); });
    card.append(h('div', { class: 'row' }, h('label', {}, 'samples ', samples), h('label', {}, two, ' two-sided')));
    card.append(h('p', { class: 'hint' }, `The viewer takes up to ${MAX_AREA_SAMPLES} samples per pixel, with the CPU engine's strata and per-pixel shift (identical to relit relight up to ${MAX_AREA_SAMPLES}); saved rigs keep the number set here.`));
  }

  markSelected() {
    [...this.root.children].forEach((c, i) => c.classList.toggle('selected', i === this.app.selected));
  }

  number(obj, key, value, step) {
    const input = h('input', { type: 'number', step, value: fmt(value), 'data-field': key });
    input.addEventListener('input', () => {
      const v = parseFloat(input.value);
      if (isFinite(v)) { obj[key] = v; this.app.changed(false); }
    });
    return input;
  }

  vector(light, key, label) {
    const inputs = [0, 1, 2].map(i => {
      const input = h('input', { type: 'number', step: 0.05, value: fmt(light[key][i]), 'data-field': `${key}.${i}`, 'aria-label': `${key} ${'xyz'[i]}` });
      input.addEventListener('input', () => {
        const v = parseFloat(input.value);
        if (isFinite(v)) { light[key][i] = v; this.app.changed(false); this.app.refreshSpheres(); }
      });
      return input;
    });
    const el = h('div', { class: 'vec', 'data-vector': key }, h('div', {}, label), h('div', { class: 'row' }, 'x', inputs[0], 'y', inputs[1], 'z', inputs[2]));
    el.update = () => inputs.forEach((inp, i) => { if (document.activeElement !== inp) inp.value = fmt(light[key][i]); });
    return el;
  }

  /** The light-sphere widget: the unit disc is the hemisphere facing the camera (z > 0),
   *  seen from the camera; drag to set the direction, shift-drag for the far side. */
  sphere(light, vec) {
    const size = 110, r = size / 2 - 6;
    const cv = h('canvas', { class: 'sphere', width: size, height: size, title: 'drag to set the direction; shift: far hemisphere' });
    const draw = () => {
      const g = cv.getContext('2d');
      g.clearRect(0, 0, size, size);
      const grad = g.createRadialGradient(size / 2, size / 2, 2, size / 2, size / 2, r);
      grad.addColorStop(0, '#3a3f4a'); grad.addColorStop(1, '#1b1d22');
      g.fillStyle = grad; g.beginPath(); g.arc(size / 2, size / 2, r, 0, 2 * Math.PI); g.fill();
      g.strokeStyle = '#555'; g.beginPath(); g.moveTo(size / 2 - r, size / 2); g.lineTo(size / 2 + r, size / 2); g.moveTo(size / 2, size / 2 - r); g.lineTo(size / 2, size / 2 + r); g.stroke();
      const d = normalize(light.direction);
      if (!d) return;
      g.fillStyle = g.strokeStyle = '#ffd166';
      g.beginPath(); g.arc(size / 2 + d[0] * r, size / 2 - d[1] * r, 5, 0, 2 * Math.PI);
      if (d[2] >= 0) g.fill(); else { g.lineWidth = 2; g.stroke(); g.lineWidth = 1; }
    };
    const set = (e) => {
      const b = cv.getBoundingClientRect();
      let x = (e.clientX - b.left - b.width / 2) / (r * b.width / size), y = -(e.clientY - b.top - b.height / 2) / (r * b.height / size);
      const rr = Math.hypot(x, y);
      if (rr > 1) { x /= rr; y /= rr; }
      const z = Math.sqrt(Math.max(0, 1 - x * x - y * y)) * (e.shiftKey ? -1 : 1);
      light.direction = [x, y, z].map(v => Math.round(v * 1e4) / 1e4);
      vec.update(); draw(); this.app.changed(false);
    };
    cv.addEventListener('pointerdown', (e) => { cv.setPointerCapture(e.pointerId); set(e); });
    cv.addEventListener('pointermove', (e) => { if (cv.hasPointerCapture(e.pointerId)) set(e); });
    cv.redraw = () => { draw(); vec.update(); };
    draw();
    return cv;
  }

  toolButton(tool, index, label) {
    const app = this.app;
    const b = h('button', { type: 'button', class: app.tool === tool && app.selected === index ? 'on' : '', 'data-tool': tool }, label);
    b.addEventListener('click', () => {
      app.selected = index;
      app.setTool(app.tool === tool ? 'view' : tool);
      this.build();
    });
    return b;
  }

  attenuation(light) {
    const a = light.attenuation == null ? 'inverse_square' : light.attenuation;
    const mode = typeof a === 'object' ? 'inverse_distance' : a;
    const sel = h('select', { 'data-field': 'attenuation' }, ['inverse_square', 'inverse_distance', 'none'].map(t => h('option', { value: t, selected: t === mode }, t)));
    const c0 = h('input', { type: 'number', step: 0.1, value: typeof a === 'object' ? a.inverse_distance : 1, 'aria-label': 'c0' });
    const apply = () => {
      light.attenuation = sel.value === 'inverse_distance' ? { inverse_distance: parseFloat(c0.value) || 1 } : sel.value;
      c0.style.display = sel.value === 'inverse_distance' ? '' : 'none';
      this.app.changed(false);
    };
    sel.addEventListener('change', apply);
    c0.addEventListener('input', apply);
    c0.style.display = mode === 'inverse_distance' ? '' : 'none';
    return h('div', { class: 'row' }, h('label', {}, 'falloff ', sel), c0);
  }

  /** Redraw spheres and vector fields after a light moved from elsewhere. */
  refresh() {
    this.root.querySelectorAll('.sphere').forEach(c => c.redraw && c.redraw());
    this.root.querySelectorAll('.vec').forEach(v => v.update && v.update());
  }
}

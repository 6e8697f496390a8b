// The light-rig JSON shared with the CLI (`relit relight --rig`) and the library
// (crates/relit/src/light/mod.rs): the viewer edits these objects directly, so a saved
// rig is exactly what the CLI reads.

export const TYPES = ['directional', 'point', 'spot', 'projector', 'area', 'environment'];

/** Colour × intensity. */
export function lightRgb(light) {
  const c = light.color || [1, 1, 1];
  const i = light.intensity != null ? light.intensity : 1;
  return [c[0] * i, c[1] * i, c[2] * i];
}

/** [mode, c0]: 0 inverse square, 1 c0/d, 2 none (serde form of `Attenuation`). */
export function attenuationOf(a) {
  if (a == null || a === 'inverse_square') return [0, 0];
  if (a === 'none') return [2, 0];
  if (typeof a === 'object' && a.inverse_distance != null) return [1, Number(a.inverse_distance)];
  throw new Error(`unknown attenuation ${JSON.stringify(a)}`);
}

/** A new light of `type` with sensible defaults for the scene `info`. */
export function newLight(type, info, from) {
  const keep = from ? { color: from.color, intensity: from.intensity } : {};
  const color = keep.color || [1, 1, 1];
  const intensity = keep.intensity != null ? keep.intensity : 1;
  const at = from && (from.position || areaCenter(from));
  const pos = at ? [...at] : [0, 0.5, -1];
  switch (type) {
    case 'directional':
      return { type, direction: from && from.type === 'directional' ? [...from.direction] : [-0.5, 0.5, 0.7], color, intensity };
    case 'point':
      return { type, position: pos, color, intensity, attenuation: 'inverse_square' };
    case 'spot':
      return { type, position: pos, direction: [0, -1, -0.3], cone_deg: 30, softness_deg: 5, color, intensity, attenuation: 'inverse_square' };
    case 'projector':
      return { type, position: pos, direction: [0, 0, -1], up: [0, 1, 0], fov_deg: 40, slide: 'slide.png', color, intensity, attenuation: 'inverse_square' };
    case 'area':
      // A 0.5 × 0.5 square facing down (u × v = −y), 16 samples (the CLI's default).
      return { type, shape: { rect: { center: pos, u: [0.25, 0, 0], v: [0, 0, 0.25] } }, color, intensity, two_sided: false, samples: 16 };
    case 'environment': {
      const env = (info.environments || [])[0];
      return { type, map: env ? env.map : 'sky.hdr', yaw_deg: 0, pitch_deg: 0, roll_deg: 0, window: { type: 'none' }, color, intensity };
    }
    default:
      throw new Error(`unknown light type ${type}`);
  }
}

const FIELDS = {
  directional: ['direction', 'color', 'intensity'],
  point: ['position', 'color', 'intensity', 'attenuation'],
  spot: ['position', 'direction', 'cone_deg', 'softness_deg', 'color', 'intensity', 'attenuation'],
  projector: ['position', 'direction', 'up', 'fov_deg', 'slide', 'color', 'intensity', 'attenuation'],
  area: ['shape', 'color', 'intensity', 'two_sided', 'samples'],
  environment: ['map', 'yaw_deg', 'pitch_deg', 'roll_deg', 'window', 'color', 'intensity'],
};

/** The centre of an area light (either shape), or null for other lights. */
export function areaCenter(light) {
  if (!light || light.type !== 'area' || !light.shape) return null;
  const s = light.shape.rect || light.shape.disk;
  return s ? s.center : null;
}

/** The same area light with the other shape (`rect` or `disk`): same centre, normal and
 *  area. A disk's axes a, b (a × b = n) become the square's half edges. */
export function convertArea(light, to, frame) {
  const s = light.shape;
  if (to === 'disk' && s.rect) {
    const { center, u, v } = s.rect;
    const c = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    const len = Math.hypot(...c);
    const round = (x) => Math.round(x * 1e4) / 1e4;
    light.shape = { disk: { center, normal: len > 0 ? c.map(x => round(x / len)) : [0, -1, 0], radius: round(Math.sqrt(4 * len / Math.PI)) || 0.25 } };
  } else if (to === 'rect' && s.disk) {
    const { center, normal, radius } = s.disk;
    const f = frame(normal);
    const h = (radius * Math.sqrt(Math.PI)) / 2, round = (x) => Math.round(x * 1e4) / 1e4;
    light.shape = f ? { rect: { center, u: f.a.map(x => round(h * x)), v: f.b.map(x => round(h * x)) } } : { rect: { center, u: [0.25, 0, 0], v: [0, 0, 0.25] } };
  }
  return light;
}

const vec3 = (v, what) => {
  if (!Array.isArray(v) || v.length !== 3 || v.some(x => typeof x !== 'number' || !isFinite(x))) throw new Error(`${what} must be three finite numbers`);
  return v;
};

/** Check a parsed rig (the same rules as the library, in short); throws with the light. */
export function checkRig(rig) {
  if (!rig || !Array.isArray(rig.lights)) throw new Error('a rig is { "lights": [ … ] }');
  for (const key of Object.keys(rig)) if (key !== 'lights') throw new Error(`unknown field “${key}” in the rig (animations: load one keyframe's rig)`);
  rig.lights.forEach((l, i) => {
    const where = `lights[${i}]`;
    if (!FIELDS[l.type]) throw new Error(`${where}: unknown type “${l.type}”`);
    for (const key of Object.keys(l)) if (key !== 'type' && !FIELDS[l.type].includes(key)) throw new Error(`${where}: unknown field “${key}” for a ${l.type} light`);
    if (l.color != null) vec3(l.color, `${where}.color`);
    if (l.intensity != null && !isFinite(l.intensity)) throw new Error(`${where}.intensity must be finite`);
    if (l.direction != null) vec3(l.direction, `${where}.direction`);
    if (l.position != null) vec3(l.position, `${where}.position`);
    if (['point', 'spot', 'projector'].includes(l.type) && l.position == null) throw new Error(`${where}: needs a position`);
    if (['directional', 'spot', 'projector'].includes(l.type) && l.direction == null) throw new Error(`${where}: needs a direction`);
    if (l.attenuation != null) attenuationOf(l.attenuation);
    if (l.type === 'area') checkArea(l, where);
  });
  return rig;
}

/** An area light's shape and options (AreaLight::validate, in short). */
function checkArea(l, where) {
  const s = l.shape;
  if (!s || typeof s !== 'object' || Object.keys(s).length !== 1 || !(s.rect || s.disk)) throw new Error(`${where}.shape must be { "rect": { … } } or { "disk": { … } }`);
  const [kind, body] = Object.entries(s)[0];
  const fields = kind === 'rect' ? ['center', 'u', 'v'] : ['center', 'normal', 'radius'];
  if (!body || typeof body !== 'object') throw new Error(`${where}.shape.${kind} must be an object`);
  for (const key of Object.keys(body)) if (!fields.includes(key)) throw new Error(`${where}: unknown field “${key}” for a ${kind} area light`);
  for (const key of fields) if (body[key] == null) throw new Error(`${where}.shape.${kind}: needs ${key}`);
  vec3(body.center, `${where}.shape.${kind}.center`);
  if (kind === 'rect') {
    const u = vec3(body.u, `${where}.shape.rect.u`), v = vec3(body.v, `${where}.shape.rect.v`);
    const c = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    if (!(Math.hypot(...c) > 0)) throw new Error(`${where}: a rectangular light needs two non-parallel edges`);
  } else {
    const n = vec3(body.normal, `${where}.shape.disk.normal`);
    if (!(Math.hypot(...n) > 0)) throw new Error(`${where}: a disk light needs a non-zero normal`);
    if (typeof body.radius !== 'number' || !(body.radius > 0 && isFinite(body.radius))) throw new Error(`${where}: a disk light needs a positive radius`);
  }
  if (l.samples != null && !(Number.isInteger(l.samples) && l.samples >= 1 && l.samples <= 4096)) throw new Error(`${where}: an area light needs 1 to 4096 samples`);
  if (l.two_sided != null && typeof l.two_sided !== 'boolean') throw new Error(`${where}.two_sided must be true or false`);
}

/** What a rig file shows: the rig itself, or an animation's first keyframe (as
 *  `relit relight --rig` renders without --frames). Returns { rig, note }. */
export function rigOfFile(json) {
  if (json && json.keyframes !== undefined) {
    const keys = json.keyframes;
    if (!Array.isArray(keys) || !keys.length) throw new Error('an animation needs at least one keyframe');
    for (const key of Object.keys(json)) if (key !== 'keyframes') throw new Error(`unknown field “${key}” in the animation`);
    const first = keys[0];
    if (!first || typeof first.time !== 'number' || !isFinite(first.time)) throw new Error('keyframes[0]: time must be a finite number');
    return { rig: checkRig({ lights: first.lights }), note: `animation of ${keys.length} keyframes: showing the first (t = ${first.time}); save rig writes a plain rig` };
  }
  return { rig: checkRig(json), note: '' };
}

/** The rig as the JSON text the CLI reads. */
export function rigToJson(rig) {
  return JSON.stringify({ lights: rig.lights }, null, 2) + '\n';
}

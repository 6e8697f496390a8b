// Environment lights in the viewer: e'_i = ∫ E(Rᵀω) b_i(ω) dω = Σ_t I_t b_i(R ω_t) for
// a map turned by R (docs/conventions.md, *Environment maps*), over the directional
// lights the bundle ships for the map (data/env/N.f32: unit direction ω_t and RGB
// intensity I_t = Σ E ΔΩ of the texels each gathers; crates/relit-viewer/src/bundle.rs),
// with the basis' weights from its table at each turned direction.
import { sample } from './table.js';

/** The weights [r, g, b] (k each) of an environment's quadrature `lights` (six floats
 *  a light: direction xyz, intensity rgb) turned by the row-major rotation R. */
export function environmentWeights(table, lights, R) {
  const k = table.k;
  const out = [new Float64Array(k), new Float64Array(k), new Float64Array(k)];
  const b = new Float64Array(k);
  for (let o = 0; o < lights.length; o += 6) {
    const x = lights[o], y = lights[o + 1], z = lights[o + 2], er = lights[o + 3], eg = lights[o + 4], eb = lights[o + 5];
    if (er === 0 && eg === 0 && eb === 0) continue;
    sample(table, [R[0][0] * x + R[0][1] * y + R[0][2] * z, R[1][0] * x + R[1][1] * y + R[1][2] * z, R[2][0] * x + R[2][1] * y + R[2][2] * z], b);
    for (let i = 0; i < k; i++) { out[0][i] += er * b[i]; out[1][i] += eg * b[i]; out[2][i] += eb * b[i]; }
  }
  return out;
}

/** Per-coefficient factors of an environment window on a file whose basis has bands
 *  (`info.basis.windows`), or null when the window changes nothing; throws for a
 *  window on a basis without bands, which relit relight refuses too. */
export function windowFactors(windows, win, basisName) {
  const type = (win && win.type) || 'none';
  if (type === 'none') return null;
  if (!windows) throw new Error(`the ${type} window scales a basis' bands and ${basisName} has none: use the window “none” with this file`);
  if (type === 'laplacian' && win.lambda != null) return windows.laplacian_eigenvalues.map(e => 1 / (1 + win.lambda * e * e));
  const f = windows.factors[type];
  if (!f) throw new Error(`unknown window “${type}”`);
  return f;
}

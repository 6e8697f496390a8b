// Real orthonormal spherical harmonics with the Condon–Shortley phase, flat index
// l(l+1)+m (docs/conventions.md), mirroring crates/relit/src/basis/sh.rs, plus the
// rotation and windowing of environment projections (crates/relit/src/envmap.rs).

export const MAX_BANDS = 8;

/** K_lm for m = 0 and √2·K_lm for m > 0, indexed l*8+m. */
export function shNorm(bands) {
  const norm = new Float64Array(MAX_BANDS * MAX_BANDS);
  for (let l = 0; l < bands; l++) {
    for (let m = 0; m <= l; m++) {
      let ratio = 1;
      for (let f = l - m + 1; f <= l + m; f++) ratio /= f;
      const k = Math.sqrt(((2 * l + 1) / (4 * Math.PI)) * ratio);
      norm[l * MAX_BANDS + m] = m === 0 ? k : Math.SQRT2 * k;
    }
  }
  return norm;
}

/** Y_i(d) for a unit vector d = [x, y, z]; returns bands² values. */
export function shEval(bands, d, norm = shNorm(bands)) {
  const [x, y, z] = d;
  const out = new Float64Array(bands * bands);
  let cm = 1, sm = 0, pmm = 1;
  for (let m = 0; m < bands; m++) {
    if (m > 0) {
      const c = x * cm - y * sm, s = x * sm + y * cm;
      cm = c; sm = s;
      pmm *= -(2 * m - 1);
    }
    let pPrev = 0, pCur = pmm;
    for (let l = m; l < bands; l++) {
      if (l === m + 1) { pPrev = pCur; pCur = (2 * m + 1) * z * pmm; }
      else if (l > m + 1) {
        const next = ((2 * l - 1) * z * pCur - (l + m - 1) * pPrev) / (l - m);
        pPrev = pCur; pCur = next;
      }
      const base = l * (l + 1), k = norm[l * MAX_BANDS + m];
      if (m === 0) out[base] = k * pCur;
      else { out[base + m] = k * pCur * cm; out[base - m] = k * pCur * sm; }
    }
  }
  return out;
}

export function normalize(v) {
  const n = Math.hypot(v[0], v[1], v[2]);
  return n > 0 && isFinite(n) ? [v[0] / n, v[1] / n, v[2] / n] : null;
}
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
export const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
export const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
export const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
export const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];

/** Right-handed rotation by `angle` radians about unit `axis`, row-major 3×3. */
export function rotationAboutAxis(axis, angle) {
  const a = normalize(axis), s = Math.sin(angle), c = Math.cos(angle), t = 1 - c;
  return [
    [c + t * a[0] * a[0], t * a[0] * a[1] - s * a[2], t * a[0] * a[2] + s * a[1]],
    [t * a[1] * a[0] + s * a[2], c + t * a[1] * a[1], t * a[1] * a[2] - s * a[0]],
    [t * a[2] * a[0] - s * a[1], t * a[2] * a[1] + s * a[0], c + t * a[2] * a[2]],
  ];
}
export function matMul(a, b) {
  return [0, 1, 2].map(r => [0, 1, 2].map(c => a[r][0] * b[0][c] + a[r][1] * b[1][c] + a[r][2] * b[2][c]));
}
export const matApply = (m, v) => [dot(m[0], v), dot(m[1], v), dot(m[2], v)];

/** R = R_y(yaw)·R_x(pitch)·R_z(roll), degrees (docs/conventions.md, environment maps). */
export function rotationYawPitchRoll(yawDeg, pitchDeg, rollDeg) {
  const r = Math.PI / 180;
  return matMul(rotationAboutAxis([0, 1, 0], yawDeg * r),
    matMul(rotationAboutAxis([1, 0, 0], pitchDeg * r), rotationAboutAxis([0, 0, 1], rollDeg * r)));
}

/** Gauss–Legendre nodes and weights on [-1, 1] (Newton on P_n). */
function gaussLegendre(n) {
  const x = new Float64Array(n), w = new Float64Array(n);
  for (let i = 0; i < n; i++) {
    let z = Math.cos(Math.PI * (i + 0.75) / (n + 0.5)), dp = 1;
    for (let it = 0; it < 100; it++) {
      let p0 = 1, p1 = z;
      for (let k = 2; k <= n; k++) { const p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k; p0 = p1; p1 = p2; }
      dp = n * (z * p1 - p0) / (z * z - 1);
      const dz = p1 / dp; z -= dz;
      if (Math.abs(dz) < 1e-15) break;
    }
    x[i] = z; w[i] = 2 / ((1 - z * z) * dp * dp);
  }
  return { x, w };
}

/** A spherical quadrature exact for polynomials of degree ≤ 2(bands−1) (products of
 *  two functions of `bands` bands): Gauss–Legendre in z times equispaced azimuths. */
const quadratureCache = new Map();
function quadrature(bands) {
  if (quadratureCache.has(bands)) return quadratureCache.get(bands);
  const nz = bands + 1, nphi = 2 * bands + 2;
  const { x, w } = gaussLegendre(nz);
  const dirs = [], weights = [];
  for (let i = 0; i < nz; i++) {
    const s = Math.sqrt(Math.max(0, 1 - x[i] * x[i]));
    for (let j = 0; j < nphi; j++) {
      const phi = (2 * Math.PI * (j + 0.5)) / nphi;
      dirs.push([s * Math.cos(phi), s * Math.sin(phi), x[i]]);
      weights.push(w[i] * 2 * Math.PI / nphi);
    }
  }
  const q = { dirs, weights };
  quadratureCache.set(bands, q);
  return q;
}

/** Band factors h_l of a window (crates/relit/src/envmap.rs, Window::factors). */
export function windowFactors(win, bands) {
  const type = (win && win.type) || 'none';
  const out = [];
  for (let l = 0; l < bands; l++) {
    const x = Math.PI * l / bands;
    let h = 1;
    if (type === 'hann') h = 0.5 * (1 + Math.cos(x));
    else if (type === 'lanczos') h = l === 0 ? 1 : Math.sin(x) / x;
    else if (type === 'laplacian') {
      const top = bands - 1;
      const lambda = win.lambda != null ? win.lambda : (bands > 1 ? 1 / (top * top * (top + 1) * (top + 1)) : 0);
      const ll = l * (l + 1);
      h = 1 / (1 + lambda * ll * ll);
    }
    out.push(h);
  }
  return out;
}

/** Rotate an environment's SH projection by R (E'(ω) = E(Rᵀω)) and window it:
 *  e'_i = ∫ f(ω) Y_i(Rω) dω with f the band-limited map, by an exact quadrature. */
export function environmentWeights(coefficients, bands, R, win) {
  const k = bands * bands, norm = shNorm(bands), { dirs, weights } = quadrature(bands);
  const out = [new Float64Array(k), new Float64Array(k), new Float64Array(k)];
  for (let q = 0; q < dirs.length; q++) {
    const y = shEval(bands, dirs[q], norm);
    const yr = shEval(bands, matApply(R, dirs[q]), norm);
    for (let c = 0; c < 3; c++) {
      let f = 0;
      for (let i = 0; i < k; i++) f += coefficients[c][i] * y[i];
      f *= weights[q];
      for (let i = 0; i < k; i++) out[c][i] += f * yr[i];
    }
  }
  const h = windowFactors(win, bands);
  for (let l = 0; l < bands; l++) for (let i = l * l; i < (l + 1) * (l + 1); i++) for (let c = 0; c < 3; c++) out[c][i] *= h[l];
  return out;
}

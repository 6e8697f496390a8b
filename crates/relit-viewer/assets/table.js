// The basis' weight table (crates/relit/src/basis/table.rs, shipped as data/weights.f16):
// the k weights of any basis at the (N+1)² vertices of an octahedral map of the sphere.
// The viewer knows no basis; every light's weights come from here. This is the one
// JavaScript definition of the lookup, a transcription of WeightTable::corners and
// WeightTable::sample (relight.frag's basisWeights is the GLSL one); the test
// crates/relit-viewer/tests/table_js.rs holds it to the Rust table.

/** A table: `n` cells a side, `k` weights per vertex, vertex (i, j) (i along u) at
 *  `values[(j·(n+1) + i)·k ..]`. */
export function weightTable(n, k, values) {
  if (values.length !== (n + 1) * (n + 1) * k) throw new Error(`a weight table of ${n} cells a side and ${k} weights needs ${(n + 1) * (n + 1) * k} values, got ${values.length}`);
  return { n, k, values };
}

/** The values of little-endian IEEE half floats (the table ships as data/weights.f16). */
export function halvesToFloats(bits) {
  const out = new Float32Array(bits.length);
  for (let i = 0; i < bits.length; i++) {
    const h = bits[i], s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 31, m = h & 1023;
    out[i] = e === 0 ? s * m * 2 ** -24 : e === 31 ? (m ? NaN : s * Infinity) : s * (1 + m / 1024) * 2 ** (e - 15);
  }
  return out;
}

const sign = (v) => (v < 0 ? -1 : 1);

/** (u, v) in [0, 1]² of unit vector d on the octahedral map (z is the pole). */
export function octahedralUv(d) {
  const s = Math.abs(d[0]) + Math.abs(d[1]) + Math.abs(d[2]);
  let px = d[0] / s, py = d[1] / s;
  if (d[2] < 0) {
    const ax = Math.abs(px), ay = Math.abs(py);
    px = (1 - ay) * sign(px);
    py = (1 - ax) * sign(py);
  }
  return [0.5 * px + 0.5, 0.5 * py + 0.5];
}

/** The offsets into `values` of the four vertices around d, and their bilinear weights. */
export function corners(table, d) {
  const n = table.n, k = table.k;
  const [u, v] = octahedralUv(d);
  const x = u * n, y = v * n;
  const i = Math.min(Math.max(Math.floor(x), 0), n - 1), j = Math.min(Math.max(Math.floor(y), 0), n - 1);
  const fx = x - i, fy = y - j, side = n + 1, v00 = j * side + i;
  return {
    at: [v00 * k, (v00 + 1) * k, (v00 + side) * k, (v00 + side + 1) * k],
    w: [(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy],
  };
}

/** The k weights at unit vector d, bilinearly interpolated (into `out` if given). */
export function sample(table, d, out = new Float64Array(table.k)) {
  const { at, w } = corners(table, d), t = table.values;
  for (let i = 0; i < table.k; i++) out[i] = w[0] * t[at[0] + i] + w[1] * t[at[1] + i] + w[2] * t[at[2] + i] + w[3] * t[at[3] + i];
  return out;
}

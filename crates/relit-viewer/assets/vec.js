// Small vector and rotation helpers for the viewer (light directions, frames, the
// rotation of environment lights).

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

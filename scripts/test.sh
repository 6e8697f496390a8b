#!/usr/bin/env bash
# The project's test command: builds everything and runs every test (unit, CLI,
# doc tests, the GPU tests on software Vulkan, the browser tests in headless Chromium,
# and the real-data tests when ../shared/data is present).
set -euo pipefail
cd "$(dirname "$0")/.."

# Tests that cannot run here (no GPU adapter, no ../shared/data, no Node) say why in
# this log (relit::skip); the list is printed at the end. In CI (CI=true, set by
# .ci/run) a missing tool fails its test instead, and so does missing shared data
# where ../shared exists; RELIT_NO_SKIPS=1 makes every skip a failure.
skip_log="$PWD/target/test-skips.txt"
mkdir -p target && : >"$skip_log"
export RELIT_SKIP_LOG="$skip_log"
in_ci() { [ "${CI:-}" = "true" ] || [ "${CI:-}" = "1" ]; }

# What the build needs (scripts/prepare.sh: the Rust toolchain, nasm for the JPEG
# decoder's SIMD code) and what the GPU and browser tests need, installed before any
# test runs: Mesa's software Vulkan (lavapipe) for wgpu, Chromium, Node and npm
# (apt-get), and playwright-core (npm, into the git-ignored target/viewer-node). Best
# effort: a test whose tool is still missing skips with the reason (or fails in CI).
missing=()
dpkg -s mesa-vulkan-drivers >/dev/null 2>&1 || missing+=(mesa-vulkan-drivers)
if [ "${RELIT_SKIP_VIEWER_TEST:-0}" != "1" ]; then
  command -v chromium >/dev/null 2>&1 || missing+=(chromium)
  command -v node >/dev/null 2>&1 || missing+=(nodejs)
  command -v npm >/dev/null 2>&1 || missing+=(npm)
fi
# shellcheck source=scripts/prepare.sh
source scripts/prepare.sh
prepare_build "${missing[@]}"
if command -v npm >/dev/null 2>&1 && [ ! -d target/viewer-node/node_modules/playwright-core ]; then
  mkdir -p target/viewer-node
  (cd target/viewer-node && { [ -f package.json ] || echo '{"private":true}' >package.json; } &&
    npm install --no-audit --no-fund --silent playwright-core >&2) ||
    echo "npm could not install playwright-core: the browser tests will skip" >&2
fi

# Release mode: the real-data tests fit whole captures and are 5-10x faster optimised.
cargo test --workspace --release --locked "$@"

# The browser viewer (crates/relit-viewer): `relit view` in headless Chromium with
# SwiftShader WebGL2, driven by Playwright; compares the canvas with `relit relight`.
# Set RELIT_SKIP_VIEWER_TEST=1 to skip it (logged like any other skip).
viewer_skip() {
  echo "viewer test: SKIPPED — $1" >&2
  echo "viewer test (scripts/test.sh): $1" >>"$skip_log"
  if [ "${RELIT_NO_SKIPS:-0}" = "1" ] || in_ci; then
    echo "viewer test: failing instead (RELIT_NO_SKIPS=1 or CI=true)" >&2
    return 1
  fi
}
viewer_test() {
  if [ "${RELIT_SKIP_VIEWER_TEST:-0}" = "1" ]; then
    viewer_skip "RELIT_SKIP_VIEWER_TEST=1"
    return
  fi
  for tool in chromium node npm; do
    if ! command -v "$tool" >/dev/null 2>&1; then
      viewer_skip "$tool is not installed and could not be installed"
      return
    fi
  done
  if [ ! -d target/viewer-node/node_modules/playwright-core ]; then
    viewer_skip "npm could not install playwright-core (no registry access?)"
    return
  fi
  cargo build --release --locked -p relit-cli
  node crates/relit-viewer/tests/viewer/viewer.test.mjs --relit target/release/relit \
    --out target/viewer-test --playwright target/viewer-node --chromium "$(command -v chromium)"
}
viewer_test

# The sharded fit on a real Slurm (docs/cluster.md): a one-node cluster on localhost,
# a job array of parts, a dependent merge, identical relit images (about a minute).
# It starts daemons as root; RELIT_SKIP_SLURM_TEST=1 skips it (logged).
slurm_test() {
  local why=""
  if [ "${RELIT_SKIP_SLURM_TEST:-0}" = "1" ]; then
    why="RELIT_SKIP_SLURM_TEST=1"
  elif [ "$(id -u)" -ne 0 ]; then
    why="it starts slurmctld and slurmd as root (run as root, or scripts/cluster/slurm_test.sh with sudo)"
  fi
  if [ -n "$why" ]; then
    echo "slurm test: SKIPPED — $why" >&2
    echo "slurm test (scripts/test.sh): $why" >>"$skip_log"
    if [ "${RELIT_NO_SKIPS:-0}" = "1" ] || in_ci; then
      echo "slurm test: failing instead (RELIT_NO_SKIPS=1 or CI=true)" >&2
      return 1
    fi
    return
  fi
  RELIT="$PWD/target/release/relit" scripts/cluster/slurm_test.sh
}
slurm_test

if [ -s "$skip_log" ]; then
  echo "tests skipped ($(sort -u "$skip_log" | wc -l)), because something they need is missing here:" >&2
  sort -u "$skip_log" | sed 's/^/  /' >&2
else
  echo "no test skipped" >&2
fi

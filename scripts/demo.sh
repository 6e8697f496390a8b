#!/usr/bin/env bash
# The README's main job on a fresh machine: what the build needs (scripts/prepare.sh:
# the Rust toolchain, nasm for the JPEG decoder's SIMD code), then `relit demo` on the
# built-in scene, writing ./relit-demo. Arguments go to `relit demo` (`--json`, …).
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/prepare.sh
source scripts/prepare.sh
prepare_build
exec cargo run --release -- demo "$@"

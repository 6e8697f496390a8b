#!/usr/bin/env bash
# The project's test command: builds everything and runs every test (unit, CLI,
# doc tests, and the real-data tests when ../shared/data is present).
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v cargo >/dev/null 2>&1; then
  echo "cargo not found: installing the Rust toolchain with rustup" >&2
  curl -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal
  # shellcheck disable=SC1091
  source "$HOME/.cargo/env"
fi

# Release mode: the real-data tests fit whole captures and are 5-10x faster optimised.
cargo test --workspace --release --locked "$@"

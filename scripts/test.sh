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

# The GPU tests run on Mesa's software Vulkan (lavapipe) where no GPU driver is present;
# without any adapter they print why they skip.
if command -v apt-get >/dev/null 2>&1 && ! dpkg -s mesa-vulkan-drivers >/dev/null 2>&1; then
  echo "installing mesa-vulkan-drivers (Vulkan for the GPU tests)" >&2
  sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo -n"
  { $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq mesa-vulkan-drivers; } >&2 ||
    echo "could not install mesa-vulkan-drivers: the GPU tests will skip" >&2
fi

# Release mode: the real-data tests fit whole captures and are 5-10x faster optimised.
cargo test --workspace --release --locked "$@"

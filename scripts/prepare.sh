# Sourced by scripts/demo.sh and scripts/test.sh (the README's two commands): what a
# build of relit needs on a fresh machine, installed where it can be, best effort.
#
# prepare_build [PACKAGE...]
#   * the Rust toolchain, with rustup, when `cargo` is missing;
#   * with apt-get (as root, or through `sudo -n`): `nasm` when missing, and the Debian
#     PACKAGEs given (those the caller found missing), in one go;
#   * a mozjpeg-sys built before `nasm` was there, rebuilt. mozjpeg-sys decides when it
#     is built whether libjpeg-turbo gets its SIMD code (assembled by nasm) and cargo
#     never rebuilds it when nasm appears, so such a build decodes photographs in
#     portable C for good: a fit of photographs takes about a quarter longer
#     (`relit doctor` says which decoder runs).

prepare_build() {
  if ! command -v cargo >/dev/null 2>&1; then
    echo "cargo not found: installing the Rust toolchain with rustup" >&2
    curl -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal
    # shellcheck disable=SC1091
    source "$HOME/.cargo/env"
  fi
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo -n"
  local missing=("$@")
  command -v nasm >/dev/null 2>&1 || missing+=(nasm)
  if [ ${#missing[@]} -gt 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing ${missing[*]}" >&2
    { $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}"; } >&2 ||
      echo "apt-get could not install ${missing[*]}: going on without them" >&2
  fi
  if command -v nasm >/dev/null 2>&1 &&
    grep -qs "SIMD won't be enabled" target/release/build/mozjpeg-sys-*/output; then
    echo "mozjpeg-sys was built without nasm: rebuilding it with libjpeg-turbo's SIMD" >&2
    cargo clean --release -p mozjpeg-sys >&2
  fi
}

#!/usr/bin/env bash
# CI steps of the bindings (called from .ci/run; runnable alone from the repository root):
#   1. Debian's libllvm19 for Mitsuba's llvm_ad_rgb variant (installed only when missing);
#   2. a venv with mitsuba==3.9.1, numpy, pytest (pip's cache makes a warm run fast);
#   3. the C ABI: header current (cbindgen test), golden values current, the C and C++
#      examples built with the system cc/c++ against the static library, and run;
#   4. `pip install ./bindings/python` (the documented command; one release build of the
#      wheel, without the `train` feature, so burn is never compiled for it);
#   5. pytest: unit tests, the Dr.Jit runtime against the Rust scalar path on every fixture
#      blob, Mitsuba χ² on every fixture sampler through the evaluated plugin and on each
#      sampler in the symbolic plugin (every material with NEUSAMPLE_FULL_TESTS=1), the
#      wrong-pdf controls, the render tests (NEUSAMPLE_REQUIRE_MITSUBA=1: a missing Mitsuba or
#      Dr.Jit LLVM backend fails instead of skipping). `pytest --durations=20` prints where
#      the time goes: the symbolic plugin's runs, which compile their own Dr.Jit kernels.
# Environment: CARGO_TARGET_DIR (default target/), NEUSAMPLE_VENV (default target/ci-venv),
# NEUSAMPLE_BINDINGS_CARGO_TESTED=1 when `cargo test --workspace` ran just before (step 3's
# cargo tests are then not rebuilt with another feature set).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
target=${CARGO_TARGET_DIR:-$root/target}
venv=${NEUSAMPLE_VENV:-$target/ci-venv}
start=$(date +%s)
step() { echo; echo "=== bindings: $* ($(( $(date +%s) - start ))s)"; }

step "libllvm19 (Mitsuba llvm_ad_rgb)"
if ! ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* >/dev/null 2>&1 \
   && ! ls /usr/lib/x86_64-linux-gnu/libLLVM-19.so* >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ]; then
    apt-get -o DPkg::Lock::Timeout=600 update -qq && DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -qq libllvm19 >/dev/null
  else
    sudo apt-get -o DPkg::Lock::Timeout=600 update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -qq libllvm19 >/dev/null
  fi
fi
ls /usr/lib/x86_64-linux-gnu/libLLVM*19* | head -1

step "venv ($venv)"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
"$venv/bin/python" -m pip install -q --disable-pip-version-check "mitsuba==3.9.1" numpy pytest
"$venv/bin/python" -c "import mitsuba, drjit; print('mitsuba', mitsuba.__version__, 'drjit', drjit.__version__)"

step "C ABI: header and golden values current"
if [ "${NEUSAMPLE_BINDINGS_CARGO_TESTED:-0}" = 1 ]; then
  echo "already run by cargo test --workspace (header.rs, golden.rs)"
else
  cargo test -p neusample-capi -p neusample-owned
fi

step "C ABI: C and C++ examples (system compilers)"
# `cargo test --workspace` already built the static library (crate-type staticlib) with the
# workspace's unified features; `--no-run` only checks it is fresh. It leaves the library in
# `deps/` (only `cargo build` copies it up). `-p neusample-capi` alone would resolve other
# features and rebuild core and every dependency a second time.
if [ "${NEUSAMPLE_BINDINGS_CARGO_TESTED:-0}" = 1 ]; then
  cargo test --workspace --no-run
  lib="$target/debug/deps/libneusample_capi.a"
else
  cargo build --profile test -p neusample-capi
  lib="$target/debug/libneusample_capi.a"
fi
mkdir -p "$target/capi"
cc -std=c99 -Wall -Wextra -Werror -pedantic -O2 -Ibindings/c/include \
  bindings/c/examples/check.c "$lib" -lm -lpthread -ldl -o "$target/capi/check_c"
c++ -std=c++17 -Wall -Wextra -Werror -O2 -Ibindings/c/include \
  bindings/c/examples/pbrt_bxdf.cpp "$lib" -lm -lpthread -ldl -o "$target/capi/pbrt_bxdf"
"$target/capi/check_c" fixtures | tail -3
"$target/capi/pbrt_bxdf" fixtures

step "Python package: pip install ./bindings/python"
CARGO_TARGET_DIR="$target" "$venv/bin/python" -m pip install -q --disable-pip-version-check \
  --force-reinstall --no-deps ./bindings/python
"$venv/bin/python" -c "import neusample; print('neusample', neusample.__version__, neusample.__file__)"

step "pytest (unit, Dr.Jit vs Rust, Mitsuba χ² symbolic + evaluated, controls, renders)"
cd bindings/python/tests
NEUSAMPLE_REQUIRE_MITSUBA=1 "$venv/bin/python" -m pytest -q -p no:cacheprovider --durations=20 .
cd "$root"

step "bindings done"

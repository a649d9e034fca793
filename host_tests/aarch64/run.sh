#!/usr/bin/env bash
# The aarch64 build under emulation: cross-compiles the batched-vs-scalar tests
# (`host_tests/tests/wavefront.rs`) and the measured material's tests
# (`bindings/owned/tests/measured.rs`: agreement with Mitsuba's values, the chunked path
# against the scalar one bit for bit) for aarch64-unknown-linux-gnu and runs them with
# qemu-user, so that the NEON path (Isa::Neon: the dense layers' NEON tiles) and the
# portable path are checked against the scalar path as on an ARM machine. Installs what it
# needs (rustup target, Debian's cross gcc for linking, qemu-user). Emulation checks results,
# not speed. Usage: bash host_tests/aarch64/run.sh [extra `cargo test` arguments]
set -euo pipefail
cd "$(dirname "$0")/../.."
TARGET=aarch64-unknown-linux-gnu

rustup target add "$TARGET" >/dev/null 2>&1 || rustup target add "$TARGET"
missing=()
command -v aarch64-linux-gnu-gcc >/dev/null 2>&1 || missing+=(gcc-aarch64-linux-gnu libc6-dev-arm64-cross)
command -v qemu-aarch64 >/dev/null 2>&1 || missing+=(qemu-user)
if [ ${#missing[@]} -gt 0 ]; then
    echo "installing ${missing[*]} (apt)"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get -o DPkg::Lock::Timeout=600 update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get -o DPkg::Lock::Timeout=600 install -y -qq "${missing[@]}" >/dev/null
fi

export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu"
# One cargo call for both packages: their features unify, so the core is compiled once.
cargo test -p neusample-host-tests -p neusample-owned --target "$TARGET" \
    --test wavefront --test measured "$@"

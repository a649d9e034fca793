#!/usr/bin/env bash
# GPU check of neusample: build the samplers, the neural material
# (features, eval) and the measured material (eval, pdf, its own sampler) to SPIR-V with
# rust-gpu, validate the module, run each of them on a Vulkan device (lavapipe on CI) and
# compare each output record with the CPU; then measure their code size on thumbv7em.
#
# Exit status: 0 passed; 1 failed (build, validation or a CPU/GPU mismatch); 3 skipped
# because a prerequisite (pinned nightly, apt packages, a Vulkan device) cannot be had here —
# always announced by a loud "GPU CHECK SKIPPED: <reason>" line. Never passes silently.
#
# Environment: NEUSAMPLE_GPU_TARGET_DIR (default <repo>/target/gpu), NEUSAMPLE_GPU_RECORDS
# (records per sampler / material entry point, default 16384), NEUSAMPLE_GPU_SKIP_EMBEDDED=1
# to skip the size step.
set -uo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/../.." && pwd)"
TOOLCHAIN="$(sed -n 's/^channel *= *"\(.*\)"/\1/p' "$HERE/rust-toolchain.toml")"
TARGET_DIR="${NEUSAMPLE_GPU_TARGET_DIR:-$REPO/target/gpu}"
RECORDS="${NEUSAMPLE_GPU_RECORDS:-16384}"
SPV="$TARGET_DIR/neusample-gpu.spv"
NICE="nice -n 19"

skip() {
    echo "=================================================================="
    echo "GPU CHECK SKIPPED: $*"
    echo "=================================================================="
    exit 3
}
fail() {
    echo "GPU CHECK FAILED: $*"
    exit 1
}
now() { date +%s; }
T0=$(now)

# --- prerequisites ---------------------------------------------------------------------
missing=()
command -v spirv-val >/dev/null 2>&1 || missing+=(spirv-tools)
dpkg -s mesa-vulkan-drivers >/dev/null 2>&1 || missing+=(mesa-vulkan-drivers)
dpkg -s libvulkan1 >/dev/null 2>&1 || missing+=(libvulkan1)
if [ ${#missing[@]} -gt 0 ]; then
    echo "installing ${missing[*]} (apt)"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    ($SUDO apt-get -o DPkg::Lock::Timeout=600 update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get -o DPkg::Lock::Timeout=600 install -y -qq "${missing[@]}") \
        >/dev/null 2>&1 || skip "cannot install ${missing[*]} with apt-get"
fi
command -v rustup >/dev/null 2>&1 || skip "rustup not found (the rust-gpu toolchain $TOOLCHAIN is installed with it)"
if ! rustup toolchain list | grep -q "^$TOOLCHAIN"; then
    echo "installing toolchain $TOOLCHAIN (rust-src, rustc-dev, llvm-tools)"
    rustup toolchain install "$TOOLCHAIN" --profile minimal \
        --component rust-src,rustc-dev,llvm-tools >/dev/null 2>&1 \
        || skip "cannot download the pinned toolchain $TOOLCHAIN"
fi
rustup component list --toolchain "$TOOLCHAIN" --installed 2>/dev/null | grep -q rustc-dev \
    || rustup component add --toolchain "$TOOLCHAIN" rust-src rustc-dev llvm-tools >/dev/null 2>&1 \
    || skip "cannot add rust-src/rustc-dev/llvm-tools to $TOOLCHAIN"
mkdir -p "$TARGET_DIR"
export CARGO_TARGET_DIR="$TARGET_DIR"
T1=$(now)
echo "[gpu] prerequisites ready in $((T1 - T0)) s (toolchain $TOOLCHAIN)"

# --- build the shader ------------------------------------------------------------------
cd "$HERE" || fail "cd $HERE"
$NICE cargo "+$TOOLCHAIN" build --release -p neusample-gpu-builder || fail "building the shader builder (spirv-builder)"
T2=$(now)
echo "[gpu] shader builder (spirv-builder + rustc_codegen_spirv) built in $((T2 - T1)) s"
$NICE cargo "+$TOOLCHAIN" run --release -q -p neusample-gpu-builder -- "$SPV" || fail "building the SPIR-V module (rust-gpu)"
T3=$(now)
echo "[gpu] SPIR-V module built in $((T3 - T2)) s: $(stat -c %s "$SPV") bytes"
spirv-val --target-env vulkan1.2 "$SPV" || fail "spirv-val rejected $SPV"
echo "[gpu] spirv-val: module valid (vulkan1.2)"

# --- run on the device and compare with the CPU ----------------------------------------
$NICE cargo "+$TOOLCHAIN" build --release -q -p neusample-gpu-runner || fail "building the runner"
T4=$(now)
if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "${XDG_RUNTIME_DIR:-}" ]; then
    XDG_RUNTIME_DIR="$(mktemp -d)"
    chmod 700 "$XDG_RUNTIME_DIR"
    export XDG_RUNTIME_DIR
fi
"$TARGET_DIR/release/neusample-gpu-runner" "$SPV" "$RECORDS"
rc=$?
T5=$(now)
echo "[gpu] runner built in $((T4 - T3)) s, ran in $((T5 - T4)) s"
case $rc in
    0) ;;
    2) skip "no usable Vulkan device (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1)" ;;
    *) fail "CPU/GPU mismatch (see the table above)" ;;
esac

# --- embedded code size (thumbv7em, stable toolchain) ----------------------------------
if [ "${NEUSAMPLE_GPU_SKIP_EMBEDDED:-0}" != 1 ]; then
    if rustup target list --toolchain stable --installed 2>/dev/null | grep -q thumbv7em-none-eabihf \
        || rustup target add --toolchain stable thumbv7em-none-eabihf >/dev/null 2>&1; then
        (cd "$HERE/embedded-size" && $NICE cargo +stable build -q --release --target thumbv7em-none-eabihf) \
            || fail "building the thumbv7em size probe"
        ELF="$TARGET_DIR/thumbv7em-none-eabihf/release/neusample-embedded-size"
        SIZE="$(command -v arm-none-eabi-size || command -v llvm-size || command -v size)"
        echo "[embedded] thumbv7em-none-eabihf, opt-level s, LTO: $ELF"
        if [ -n "$SIZE" ]; then
            "$SIZE" -A "$ELF" | grep -E '^\.(text|rodata|data|bss) '
        fi
        NM="$(command -v arm-none-eabi-nm || command -v llvm-nm || true)"
        if [ -n "$NM" ]; then
            echo "[embedded] per-sampler (and material) entry functions (bytes, shared helpers such as libm not included):"
            "$NM" -S --size-sort "$ELF" | while read -r _ sz _ name; do
                case "$name" in ns_*) printf '  %-22s %6d\n' "$name" "$((16#$sz))" ;; esac
            done
        fi
    else
        echo "[embedded] size step not run: cannot add the thumbv7em-none-eabihf target to stable"
    fi
fi
echo "[gpu] total $(( $(now) - T0 )) s"
echo "GPU CHECK PASSED"

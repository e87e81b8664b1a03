#!/usr/bin/env bash
# The firmware on QEMU's netduinoplus2 (STM32F405): build, boot, test, benchmark.
#
#   bash scripts/qemu.sh build         # target/qemu/pbcard-qemu.elf (demo, e2e), pbcard-bench.elf and
#                                      #   pbcard-bench-dma.elf (the F411's DMA receive emulated)
#   bash scripts/qemu.sh run [SERIAL]  # boot pbcard-qemu.elf, decoded log on stdout; USART1 on
#                                      #   SERIAL (QEMU -serial syntax; default: a Unix socket,
#                                      #   e.g. `pty` or `tcp:127.0.0.1:5020,server=on,wait=off`)
#   bash scripts/qemu.sh demo          # README command 1 without the setup step
#   bash scripts/qemu.sh test          # the end-to-end tests (host-tests/tests/qemu.rs)
#   bash scripts/qemu.sh bench         # the instruction-count benchmark tables (README "Benchmark"):
#                                      #   per-character receive, then the DMA receive (`--dma`)
#
# The board is a cargo feature of the one RTIC application: `--no-default-features --features
# qemu` (or `bench`, which adds the TIM2 instrumentation). The default build stays the F411.
set -euo pipefail
# The QEMU firmware logs at "info" (the tests and the demo read those logs); the F411 default
# is "warn" (.cargo/config.toml).
export DEFMT_LOG=${DEFMT_LOG:-info}
cd "$(dirname "$0")/.."
HOST=$(bash scripts/host-triple)
TARGET_DIR=${CARGO_TARGET_DIR:-target}
case $TARGET_DIR in /*) ;; *) TARGET_DIR=$PWD/$TARGET_DIR ;; esac # tests run in host-tests/
OUT=$TARGET_DIR/qemu
ELF=$TARGET_DIR/thumbv7em-none-eabihf/release/pbcard
export PBCARD_QEMU_ELF=${PBCARD_QEMU_ELF:-$OUT/pbcard-qemu.elf}
export PBCARD_BENCH_ELF=${PBCARD_BENCH_ELF:-$OUT/pbcard-bench.elf}
export PBCARD_BENCH_DMA_ELF=${PBCARD_BENCH_DMA_ELF:-$OUT/pbcard-bench-dma.elf}

build_one() { # feature, output file
  cargo build --release --no-default-features --features "$1"
  mkdir -p "$OUT"
  cp "$ELF" "$2"
}

build() {
  case "${1:-all}" in
    qemu) build_one qemu "$PBCARD_QEMU_ELF" ;;
    bench) build_one bench "$PBCARD_BENCH_ELF"; build_one bench-dma "$PBCARD_BENCH_DMA_ELF" ;;
    all) build_one qemu "$PBCARD_QEMU_ELF"; build_one bench "$PBCARD_BENCH_ELF"; build_one bench-dma "$PBCARD_BENCH_DMA_ELF" ;;
    *) echo "build: qemu, bench or all" >&2; exit 2 ;;
  esac
}

defmt_print() {
  if command -v defmt-print >/dev/null; then echo defmt-print; else echo "${CARGO_HOME:-$HOME/.cargo}/bin/defmt-print"; fi
}

case "${1:-}" in
  build) build "${2:-all}" ;;
  run)
    build qemu
    SERIAL=${2:-unix:$OUT/usart1.sock,server=on,wait=off}
    echo "USART1: $SERIAL   (Ctrl-C ends QEMU)" >&2
    # With `pty`, QEMU names the pseudo-terminal in a first text line on stdout (the defmt stream).
    first_line() { if [ "$SERIAL" = pty ]; then IFS= read -r l; echo "USART1: $l" >&2; fi; cat; }
    qemu-system-arm -M netduinoplus2 -display none -monitor none -nodefaults \
      -semihosting-config enable=on,target=native -serial "$SERIAL" -kernel "$PBCARD_QEMU_ELF" \
      | first_line | "$(defmt_print)" -e "$PBCARD_QEMU_ELF"
    ;;
  demo)
    build qemu
    exec cargo run -q -p host-tests --bin qemu_demo --target "$HOST"
    ;;
  test)
    build qemu
    PBCARD_QEMU_REQUIRED=1 exec cargo test -q -p host-tests --target "$HOST" --test qemu -- --nocapture
    ;;
  bench)
    build bench
    cargo run -q -p host-tests --bin qemu_bench --target "$HOST"
    exec cargo run -q -p host-tests --bin qemu_bench --target "$HOST" -- --dma
    ;;
  *) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 2 ;;
esac

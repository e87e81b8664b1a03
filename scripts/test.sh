#!/usr/bin/env bash
# Runs every test of the project (the README's test command; CI runs it through .ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
HOST=$(bash scripts/host-triple)
export CARGO_TERM_COLOR=never
# Everything below is also kept in a log, for the closing count of tests run.
LOG=$(mktemp)
exec > >(tee "$LOG") 2>&1

echo "== format (the workspace and the fuzz crate, its own workspace)"
cargo fmt --all -- --check
(cd fuzz && cargo fmt -- --check)

echo "== clippy: protocol library (host and firmware target, with its tests) and host-tests, -D warnings"
cargo clippy -p pbcard -p pbcard-sim -p pbcard-dpm -p pbcard-profile -p pbcard-link -p pbcard-dp -p pbcard-fdl --lib --target "$HOST" -- -D warnings
cargo clippy -p pbcard -p pbcard-sim -p pbcard-dpm -p pbcard-profile -p pbcard-link -p pbcard-dp -p pbcard-fdl --lib -- -D warnings
cargo clippy -p pbcard -p pbcard-sim -p pbcard-dpm -p pbcard-profile -p pbcard-link -p pbcard-dp -p pbcard-fdl --lib --tests --target "$HOST" -- -D warnings
cargo clippy -p host-tests --all-targets --target "$HOST" -- -D warnings
# The profile layer's test support (the one fake drive table, the mailbox) alone, host and
# firmware target (no_std).
cargo clippy -p pbcard-profile --features test-support --lib --target "$HOST" -- -D warnings
cargo clippy -p pbcard-profile --features test-support --lib -- -D warnings
echo "== rustdoc of the protocol crates: no broken or private intra-doc links, -D warnings"
RUSTDOCFLAGS="-D warnings" cargo doc -q -p pbcard -p pbcard-sim -p pbcard-dpm -p pbcard-profile -p pbcard-link -p pbcard-dp -p pbcard-fdl -p dpm-host --no-deps --target "$HOST"
RUSTDOCFLAGS="-D warnings" cargo doc -q -p pbcard-profile --features test-support --no-deps --target "$HOST"

echo "== firmware: release build for the STM32F411 (thumbv7em-none-eabihf), the card alone: no simulation linked, footprint"
# The shipped log level (.cargo/config.toml), whatever the caller's shell exports: the
# footprint's limits are for it.
DEFMT_LOG=warn cargo build --release
bash scripts/footprint.sh
# The simulation is a crate above the card (pbcard-sim): the card-only firmware does not depend on it.
if cargo tree -q -p pbcard-firmware --target thumbv7em-none-eabihf -e normal | grep -q pbcard-sim; then
    echo "FAIL: the card-only firmware depends on pbcard-sim (the simulation)" >&2
    exit 1
fi
echo "the card-only firmware's dependency tree holds no pbcard-sim"

echo "== firmware: QEMU netduinoplus2 builds (features qemu, bench, bench-dma) and clippy of the firmware builds, -D warnings"
bash scripts/qemu.sh build
arm-none-eabi-size "${CARGO_TARGET_DIR:-target}/qemu/pbcard-qemu.elf"
DEFMT_LOG=warn cargo clippy --bins -- -D warnings
# The developer's F411 build whose panic log names file and line (7.7 KiB more flash).
DEFMT_LOG=warn cargo clippy --bins --features panic-location -- -D warnings
# The QEMU builds as scripts/qemu.sh builds them (DEFMT_LOG=info: the bench counts are info logs).
DEFMT_LOG=info cargo clippy --bins --no-default-features --features bench -- -D warnings
DEFMT_LOG=info cargo clippy --bins --no-default-features --features bench-dma -- -D warnings

echo "== unit tests beside the code (protocol library on the host: pbcard and the crates of its stack, pbcard-sim, pbcard-dpm, pbcard-profile, pbcard-link, pbcard-dp and pbcard-fdl)"
cargo test -p pbcard -p pbcard-sim -p pbcard-dpm -p pbcard-profile -p pbcard-link -p pbcard-dp -p pbcard-fdl --lib --target "$HOST"
echo "== the card's unit tests in the QEMU benchmark build (feature bench: the bench-only modules Bench 32/32, 244/244 beside the GSD's)"
cargo test -p pbcard -p pbcard-sim --lib --features pbcard-sim/bench --target "$HOST"
cargo clippy -p pbcard -p pbcard-sim --lib --tests --features pbcard-sim/bench --target "$HOST" -- -D warnings

echo "== host-tests: profirust master on a simulated bus, GSD cross-check, scripted services,"
echo "   and end to end: the firmware in QEMU brought to data exchange by profirust over a socket"
cc -std=c99 -pedantic -Wall -Wextra -Werror -Ic-host/include -fsyntax-only c-host/src/pbcard_host.c c-host/test/drive.c
PBCARD_QEMU_REQUIRED=1 cargo test -p host-tests --target "$HOST"

echo "== pyprofibus (PyPI) as a second independent master: soft slave #9 (PPO 4, PPO 2) and QEMU firmware #33 (ST1)"
bash scripts/pyprofibus.sh

echo "== soft slave: clippy and its own tests (the pty end-to-end run is in host-tests)"
cargo clippy -p pbcard-softslave --all-targets --target "$HOST" -- -D warnings
cargo test -p pbcard-softslave --target "$HOST"

echo "== bus monitor: clippy and its tests (recorded card session, manuals' examples, CLI, live pty)"
cargo clippy -p pbcard-monitor --all-targets --target "$HOST" -- -D warnings
cargo test -p pbcard-monitor --target "$HOST"

echo "== dpm-host: the host-side reference implementation (std on the host, no_std on the firmware target)"
cargo clippy -p dpm-host --all-targets --target "$HOST" -- -D warnings
cargo clippy -p dpm-host --no-default-features -- -D warnings
cargo test -p dpm-host --target "$HOST"

echo "== benchmark: instructions from the last request byte to the first response byte (QEMU -icount)"
cargo run -q -p host-tests --bin qemu_bench --target "$HOST"
echo "== benchmark: the F411's DMA receive (≥ 3 Mbit/s) emulated: last character (IDLE) to the first response byte"
cargo run -q -p host-tests --bin qemu_bench --target "$HOST" -- --dma

echo "== fuzz smoke: every parser and the whole slave under libFuzzer (stable, --sanitizer none)"
FUZZ_SECONDS=${FUZZ_SECONDS:-15} bash scripts/fuzz-smoke.sh

# Closing line: the Rust tests that ran (every suite above passed, or this line is not reached).
total=$(grep -ao 'test result: ok\. [0-9]* passed' "$LOG" | awk '{s += $4} END {print s + 0}')
echo "tests: $total passed, 0 failed"

#!/usr/bin/env bash
# Runs every test of the project (the README's test command; CI runs it through .ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
HOST=$(bash scripts/host-triple)
export CARGO_TERM_COLOR=never

echo "== format"
cargo fmt --all -- --check

echo "== clippy: protocol library (host and firmware target), -D warnings"
cargo clippy --lib --target "$HOST" -- -D warnings
cargo clippy --lib -- -D warnings

echo "== firmware: release build for the STM32F411 (thumbv7em-none-eabihf)"
cargo build --release
arm-none-eabi-size target/thumbv7em-none-eabihf/release/pbcard

echo "== unit tests beside the code (protocol library on the host)"
cargo test --lib --target "$HOST"

echo "== host-tests: profirust master on a simulated bus, GSD cross-check, scripted services"
cargo test -p host-tests --target "$HOST"

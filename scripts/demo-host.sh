#!/usr/bin/env bash
# The host-only demo: profirust's DP master brings the protocol core to data exchange on
# profirust's simulated line (no firmware, no QEMU).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec cargo run -q -p host-tests --bin demo --target "$(bash scripts/host-triple)"

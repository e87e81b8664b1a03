#!/usr/bin/env bash
# The live demo (README command 1): profirust's DP master brings our slave to data exchange.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec cargo run -q -p host-tests --bin demo --target "$(bash scripts/host-triple)"

#!/usr/bin/env bash
# The live demo (README command 1): the firmware boots in QEMU (netduinoplus2), profirust's DP
# master on the host brings it to data exchange over USART1 and runs the drive for a few
# seconds. The profirust-only demo on a simulated line is scripts/demo-host.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec bash scripts/qemu.sh demo

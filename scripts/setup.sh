#!/usr/bin/env bash
# Installs what the build and the tests need on a fresh machine (idempotent, quiet when done).
set -euo pipefail
need_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

# The firmware target (a fresh machine has only the host's std).
if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
  rustup target add thumbv7em-none-eabihf
fi

# Debian packages: arm-none-eabi-size for the footprint figures, QEMU for the firmware's
# end-to-end test, demo and benchmark (netduinoplus2).
missing=()
command -v arm-none-eabi-size >/dev/null || missing+=(binutils-arm-none-eabi)
command -v qemu-system-arm >/dev/null || missing+=(qemu-system-arm)
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]} (apt)" >&2
  need_root apt-get update -qq
  need_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# defmt-print decodes the QEMU firmware's log (defmt over semihosting); ~2 min to build once.
if ! command -v defmt-print >/dev/null && [ ! -x "${CARGO_HOME:-$HOME/.cargo}/bin/defmt-print" ]; then
  echo "setup: cargo install defmt-print --locked (about 2 minutes, once)" >&2
  cargo install defmt-print --locked --quiet
fi

#!/usr/bin/env bash
# Installs what the build and the tests need on a fresh machine (idempotent, quiet when done).
set -euo pipefail
need_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

# The firmware target (a fresh machine has only the host's std).
if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
  rustup target add thumbv7em-none-eabihf
fi

# Debian packages: arm-none-eabi-size for the footprint figures.
missing=()
command -v arm-none-eabi-size >/dev/null || missing+=(binutils-arm-none-eabi)
if [ ${#missing[@]} -gt 0 ]; then
  need_root apt-get update -qq
  need_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi

#!/usr/bin/env bash
# The card-only F411 firmware's footprint (issue 13 item 1): run after `cargo build --release`
# (default features: board-f411, no `sim-drive`).
#
# 1. Fails when the ELF contains the simulation: anything of the crate `pbcard-sim` (the
#    simulated drive `pbcard_sim::drive::`, `SimDrive`, the bench
#    `pbcard_sim::bench::Application` — the card-only build does not even compile that crate,
#    `scripts/test.sh` checks its dependency tree) or the drive's side of the DPM
#    transport (`dpm::host::`, in the crate `pbcard-dpm` — the host reference implementation the simulated drive
#    runs —, `dpm::spi::SpiHost`, `dpm::spi::Loopback`). The shipped card is the SPI *slave*
#    (`dpm::spi::SpiSlave` / `WireImage`); the drive's control board is the host, so nothing
#    of the host side belongs in the card. (Symbols of functions LTO inlined are not in the
#    table; the bench's entry points and its large step functions are not inlined.)
# 2. Prints text / data / bss (arm-none-eabi-size) and checks the issue's limits: flash
#    (text + data) ≤ 96 KiB, RAM (data + bss) ≤ 32 KiB: the script fails above either
#    (`ENFORCE_FLASH=no` / `ENFORCE_RAM=no`: reported with the biggest symbols instead;
#    README "Footprint").
#
# Usage: bash scripts/footprint.sh [ELF]   (default target/thumbv7em-none-eabihf/release/pbcard)
set -euo pipefail
cd "$(dirname "$0")/.."
ELF=${1:-${CARGO_TARGET_DIR:-target}/thumbv7em-none-eabihf/release/pbcard}
FLASH_LIMIT=$((96 * 1024))
RAM_LIMIT=$((32 * 1024))
# Both limits are enforced (issue 13 item 1): session 15 got the flash under 96 KiB (92 820 B,
# 90.6 KiB: the shipped panic handler logs no location, README "Footprint"); RAM is 31.3 KiB.
# `ENFORCE_FLASH=no` reports instead of failing — for the `panic-location` build (100 656 B).
ENFORCE_FLASH=${ENFORCE_FLASH:-yes}
ENFORCE_RAM=${ENFORCE_RAM:-yes}

if [[ ! -f "$ELF" ]]; then
    echo "footprint: $ELF not found (build it with: cargo build --release)" >&2
    exit 1
fi

fail=0
symbols=$(arm-none-eabi-nm -C "$ELF")
# The simulation's symbols: the pattern, and what it is.
checks=(
    'pbcard_sim::|the simulation crate (pbcard-sim: the simulated drive, the bench)'
    'SimDrive|the simulated drive (SimDrive)'
    'bench::Application|the bench (pbcard_sim::bench::Application)'
    'dpm::host::|the drive-side host implementation (dpm::host)'
    'dpm::spi::SpiHost|the SPI master side (dpm::spi::SpiHost)'
    'dpm::spi::Loopback|the in-process SPI card (dpm::spi::Loopback)'
)
for c in "${checks[@]}"; do
    pat=${c%%|*}
    what=${c#*|}
    hits=$(grep -F -- "$pat" <<<"$symbols" || true)
    if [[ -n "$hits" ]]; then
        echo "footprint: FAIL: the card-only ELF contains $what:" >&2
        head -10 <<<"$hits" >&2
        fail=1
    fi
done
[[ $fail == 0 ]] && echo "footprint: no simulation symbols (pbcard_sim::, SimDrive, bench::Application, dpm::host::, SpiHost, Loopback)"

# Berkeley text / data / bss as arm-none-eabi-size prints them. With cortex-m-rt's linker
# script the initialised `.data` (RAM, copied from flash at start) is counted in `text` (its
# load image) and not in `data`, and `bss` includes `.uninit` (the RTIC resources); so the
# limits are checked on the sections (`size -A`): flash = every section in the flash region
# (0x0800_0000..) plus `.data`'s load image, RAM = every section in SRAM (0x2000_0000..).
read -r text data bss _ < <(arm-none-eabi-size "$ELF" | awk 'NR == 2 {print $1, $2, $3, $4}')
read -r flash ram dotdata < <(arm-none-eabi-size -A -d "$ELF" | awk '
    $3 >= 134217728 && $3 < 536870912 {f += $2}
    $3 >= 536870912 && $3 < 805306368 {r += $2}
    $1 == ".data" {d = $2}
    END {print f + d, r, d + 0}')
kib() { awk -v b="$1" 'BEGIN {printf "%.1f KiB", b / 1024}'; }
echo "footprint: arm-none-eabi-size: text $text, data $data, bss $bss (.data $dotdata B is in text)"
echo "footprint: flash (text + .data load image) $flash B = $(kib "$flash") (limit $(kib $FLASH_LIMIT))"
echo "footprint: RAM (.data + .bss + .uninit)    $ram B = $(kib "$ram") (limit $(kib $RAM_LIMIT); the stack comes on top)"

above=""
check_limit() { # name value limit enforce
    local name=$1 value=$2 limit=$3 enforce=$4
    if ((value <= limit)); then
        echo "footprint: $name within its limit"
    elif [[ $enforce == yes ]]; then
        echo "footprint: FAIL: $name $value B above its limit $limit B" >&2
        fail=1
    else
        echo "footprint: NOTE: $name $value B is $((value - limit)) B above the issue's limit $limit B (reported, not enforced: ENFORCE_FLASH / ENFORCE_RAM = no)"
        above="$above $name"
    fi
}
check_limit flash "$flash" "$FLASH_LIMIT" "$ENFORCE_FLASH"
check_limit RAM "$ram" "$RAM_LIMIT" "$ENFORCE_RAM"
if [[ -n "$above" ]]; then
    echo "footprint: the 25 biggest symbols (bytes, nm type, name):"
    arm-none-eabi-nm -C --size-sort -S "$ELF" | tail -25 | while read -r _ size type name; do
        printf '%8d %s %s\n' "$((16#$size))" "$type" "$name"
    done
fi
exit $fail

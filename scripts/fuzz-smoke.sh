#!/usr/bin/env bash
# Fuzz smoke run: every cargo-fuzz target in fuzz/ for a bounded time, starting from the seed
# corpora in fuzz/seeds/<target>/ (copied to a temporary corpus directory, so nothing new is
# left in the tree). Exits non-zero if any target crashes; the crashing input is kept in
# fuzz/artifacts/<target>/ (git-ignored) and printed in hex. The targets are every [[bin]] of
# fuzz/Cargo.toml (`cargo fuzz list`): the bus-side parsers (telegram, framer, phy_line,
# dp_params, dpv1_pdu, im_records, pkw, profidrive), the whole slave (slave, node_dpv1), the line's fast
# path against the core alone (fast_path) and the DPM (dpm_spi;
# dpm_host_blocks: arbitrary drive-written bytes into a running card) and the bus monitor
# (monitor_capture: the capture format; monitor_decode: cutter + decoder over arbitrary bytes).
#
#   FUZZ_SECONDS=20        seconds per target (default 20)
#   FUZZ_TARGETS="a b"     targets to run (default: all of `cargo fuzz list`)
#   FUZZ_SANITIZER=none    none (default) | address
#   FUZZ_TIMEOUT=30        seconds one input may take before libFuzzer calls it a hang. The
#                          clock is wall time: on a loaded machine an input that needs 1 ms of
#                          CPU has been seen to "time out", so a timeout is re-run once alone
#                          and only counts as a failure if it hangs again.
#
# Stable Rust, no nightly: cargo-fuzz defaults to AddressSanitizer, which it enables with
# `-Zsanitizer=address` — a nightly-only flag, so a plain `cargo fuzz run` fails on stable
# ("the option `Z` is only accepted on the nightly compiler"). With `--sanitizer none`
# cargo-fuzz passes only stable flags (-Cpasses=sancov-module, -Cllvm-args=..., --cfg fuzzing,
# -Cdebug-assertions), so the libFuzzer build works on stable as is; the protocol core is
# #![forbid(unsafe_code)], so ASan would add little. FUZZ_SANITIZER=address instead sets
# RUSTC_BOOTSTRAP=1 (lets the stable rustc accept -Z flags) and deletes
# fuzz/target/.rustc_info.json: cargo caches the failed rustc probe of an earlier run without
# RUSTC_BOOTSTRAP there and would keep failing with the same error.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
SECONDS_PER_TARGET=${FUZZ_SECONDS:-20}
SANITIZER=${FUZZ_SANITIZER:-none}
TIMEOUT=${FUZZ_TIMEOUT:-30}
export CARGO_TERM_COLOR=never

if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "== installing cargo-fuzz (cargo install cargo-fuzz --locked)"
  cargo install cargo-fuzz --locked
fi

if [ "$SANITIZER" != none ]; then
  export RUSTC_BOOTSTRAP=1
  rm -f fuzz/target/.rustc_info.json
fi
# cargo-fuzz passes --target itself; fuzz/.cargo/config.toml keeps other cargo commands in
# fuzz/ on the host too (the root config defaults to the firmware target).
FUZZ=(cargo fuzz)
BUILD_OPTS=(--sanitizer "$SANITIZER")

cd fuzz
TARGETS=${FUZZ_TARGETS:-$("${FUZZ[@]}" list)}
echo "== building fuzz targets (release + debug assertions, sanitizer: $SANITIZER)"
"${FUZZ[@]}" build "${BUILD_OPTS[@]}"

WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
failed=()
for t in $TARGETS; do
  corpus="$WORK/$t"
  mkdir -p "$corpus"
  if [ -d "seeds/$t" ]; then
    cp seeds/"$t"/* "$corpus"/ 2>/dev/null || true
  fi
  echo "== fuzz $t for ${SECONDS_PER_TARGET}s ($(find "$corpus" -type f | wc -l) seeds)"
  mkdir -p "artifacts/$t"
  # slow-unit-* files are only libFuzzer's note of a slow input (wall time, see FUZZ_TIMEOUT).
  before=$(find "artifacts/$t" -type f ! -name 'slow-unit-*' | wc -l)
  touch "$WORK/$t.start"
  log="$WORK/$t.log"
  set +e
  "${FUZZ[@]}" run "${BUILD_OPTS[@]}" "$t" "$corpus" -- \
    -max_total_time="$SECONDS_PER_TARGET" -timeout="$TIMEOUT" -rss_limit_mb=1024 -print_final_stats=1 \
    >"$log" 2>&1
  rc=$?
  set -e
  grep -E '^(stat::number_of_executed_units|stat::new_units_added|Done [0-9]+ runs)' "$log" || true
  after=$(find "artifacts/$t" -type f ! -name 'slow-unit-*' | wc -l)
  if [ $rc -ne 0 ] || [ "$after" -gt "$before" ]; then
    bad=0
    [ "$after" -gt "$before" ] || bad=1 # failed without an artifact (build error, OOM ...)
    for a in $(find "artifacts/$t" -type f ! -name 'slow-unit-*' -newer "$WORK/$t.start"); do
      if [[ $(basename "$a") == timeout-* ]] &&
        "${FUZZ[@]}" run "${BUILD_OPTS[@]}" "$t" "$a" -- -timeout="$TIMEOUT" >/dev/null 2>&1; then
        echo "!! $t: $a timed out but re-ran within ${TIMEOUT}s alone: machine load, not counted"
        rm -f "$a"
        continue
      fi
      bad=1
      echo "!! crashing input $ROOT/fuzz/$a:"
      od -An -tx1 -v "$a" | tr -d ' \n' | fold -w 96
      echo
      echo "!! reproduce: (cd fuzz && cargo fuzz run --sanitizer $SANITIZER $t $a)"
    done
    if [ $bad -ne 0 ]; then
      failed+=("$t")
      echo "!! $t FAILED (exit $rc):"
      { grep -A2 'panicked at' "$log" | head -6; grep -E 'ERROR: libFuzzer|SUMMARY|ALARM' "$log"; } ||
        grep -v -E '^#[0-9]+' "$log" | tail -40
    fi
  fi
done

if [ ${#failed[@]} -gt 0 ]; then
  echo "== FUZZ SMOKE FAILED: ${failed[*]}"
  exit 1
fi
echo "== fuzz smoke passed:" $TARGETS

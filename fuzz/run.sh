#!/usr/bin/env bash
# Builds the AFL++ harness on the stable toolchain and fuzzes each target in turn on one core
# until it has run EXECS executions, then prints one line of results per target.
#
#   fuzz/run.sh [TARGET ...]          # default: every target
#   EXECS=1000000 fuzz/run.sh         # executions per target (default 1000000)
#
# Needs `cargo install cargo-afl` once (it builds AFL++ from the sources it ships). Outputs,
# crashes included, go to target/afl/out/TARGET; see fuzz/README.md.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
execs="${EXECS:-1000000}"
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(dataset-pair dataset-ron telemetry-csv truth-csv scenario-ron config-ron import-map magcal-ron joint-sets)
fi
afl_dir="$root/target/afl"

# A target directory of its own: the instrumented build uses other RUSTFLAGS, which would
# otherwise rebuild (and then invalidate) the normal artifacts in target/release.
cargo afl build --release -p pdcal-fuzz --features afl --target-dir "$afl_dir"

# Cores and the CPU governor are shared with other work here: no core pinning, no check of
# the frequency governor. Without a UI, the progress goes to the log.
export AFL_NO_AFFINITY=1 AFL_SKIP_CPUFREQ=1 AFL_NO_UI=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1
# afl-fuzz kills the harness, which then cannot remove its scratch files: one directory
# for the whole run, in memory where possible, removed here.
PDCAL_FUZZ_SCRATCH="$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d)"
export PDCAL_FUZZ_SCRATCH
trap 'rm -rf "$PDCAL_FUZZ_SCRATCH"' EXIT
printf '%-14s %10s %9s %9s %7s %7s %6s\n' target execs seconds execs/s corpus crashes hangs
for target in "${targets[@]}"; do
    out="$afl_dir/out/$target"
    rm -rf "$out"
    mkdir -p "$out"
    # -G: inputs stay below 16 KiB, so executions stay fast; a huge cell still fits.
    cargo afl fuzz -i "fuzz/seeds/$target" -o "$out" -x fuzz/dict/pdcal.dict -G 16384 \
        -E "$execs" -- "$afl_dir/release/fuzz" "$target" >"$out/log.txt" 2>&1 \
        || { echo "$target: afl-fuzz failed, see $out/log.txt" >&2; exit 1; }
    stat() { sed -n "s/^$1 *: *//p" "$out/default/fuzzer_stats"; }
    printf '%-14s %10s %9s %9s %7s %7s %6s\n' "$target" "$(stat execs_done)" \
        "$(stat run_time)" "$(stat execs_per_sec)" "$(stat corpus_count)" \
        "$(stat saved_crashes)" "$(stat saved_hangs)"
done

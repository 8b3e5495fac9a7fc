#!/usr/bin/env bash
# Runs every fuzz target for SECONDS each (default 60), JOBS at a time:
#   fuzz/run.sh [SECONDS] [TARGET...]
# With RUNS=N in the environment a target also stops after N executions
# (the issue's long run: RUNS=1000000 fuzz/run.sh 1800).
# libFuzzer runs with -rss_limit_mb=1024 (an input that makes the reader
# allocate over 1 GB is a crash) and -timeout=1 (over 1 s on one input is a
# crash). The committed seeds (fuzz/corpus/TARGET, plus pipelines/*.toml for
# pipeline_toml) are read only; what the fuzzer adds goes to fuzz/work/
# (not committed), crash inputs to fuzz/artifacts/TARGET/. Prints one line
# per target (executions, coverage) and exits 1 when any target failed.
# With DEADLINE=EPOCH_SECONDS in the environment (CI's time budget) each
# target gets at most SECONDS and no more than its share of the time left
# after the build (3 s of it for starting the target); a target whose
# share falls below 5 s is skipped and said so (not counted as a pass), as
# is every target when the build itself does not finish in time, and a
# target still running at DEADLINE is stopped and named as skipped.
# JOBS=N: targets run N at a time (default: one per core).
# Needs the nightly toolchain and cargo-fuzz (`cargo install --locked cargo-fuzz`).
set -uo pipefail
cd "$(dirname "$0")"
secs="${1:-60}"
shift || true
targets=("$@")
if [ "${#targets[@]}" -eq 0 ]; then
  targets=(y4m cine mraw wav mask calibration_json pipeline_toml scene_toml wire studio_http)
fi
# -a: debug assertions (integer overflow is a crash); -s none: no sanitizer
# (the parsers are safe Rust: no unsafe in crates/io).
flags=(-a -s none)
# The targets that read paths write their input to a scratch file here.
scratch_base=/dev/shm
[ -d "$scratch_base" ] || scratch_base="${TMPDIR:-/tmp}"
VIBROSCOPE_FUZZ_DIR=$(mktemp -d "$scratch_base/vibroscope-fuzz.XXXXXX") || exit 1
export VIBROSCOPE_FUZZ_DIR
trap 'rm -rf "$VIBROSCOPE_FUZZ_DIR"' EXIT
# COMMAND...: run it, within DEADLINE when that is set; 124 when it was
# cut off there, or not started for want of 5 s.
bounded() {
  [ -n "${DEADLINE:-}" ] || { "$@"; return; }
  local left=$((DEADLINE - $(date +%s)))
  [ "$left" -ge 5 ] || return 124
  timeout "$left" "$@"
}
# The build is bounded by the deadline too (it takes 4-8 min from scratch).
bounded cargo +nightly fuzz build "${flags[@]}"
rc=$?
if [ "$rc" -eq 124 ] && [ -n "${DEADLINE:-}" ]; then
  echo "fuzz: SKIPPED, no time to finish the build before DEADLINE; run fuzz/run.sh $secs by hand"
  exit 0
fi
[ "$rc" -eq 0 ] || exit 1
# Targets run JOBS at a time (default: one per core; each libFuzzer
# process is single-threaded), each its SECONDS: ten targets of 30 s take
# 2.5 min on two cores where one after another they took 5. Each target's
# lines are printed together when it ends; a failure or a skip leaves a
# mark in $marks.
jobs=${JOBS:-$(nproc 2>/dev/null || echo 1)}
[ "$jobs" -ge 1 ] 2>/dev/null || jobs=1
marks=$(mktemp -d "${TMPDIR:-/tmp}/vibroscope-fuzz-marks.XXXXXX") || exit 1
trap 'rm -rf "$VIBROSCOPE_FUZZ_DIR" "$marks"' EXIT
# TARGET RUN_SECS: one target's run, its report on stdout.
one() {
  local t=$1 run_secs=$2 work log seeds attempt rc art cpu runs cov took rss slow
  work="work/$t"
  mkdir -p "$work" "artifacts/$t"
  seeds=("corpus/$t")
  [ "$t" = pipeline_toml ] && seeds+=(../pipelines)
  log="work/$t.log"
  for attempt in 1 2 3; do
    # Under DEADLINE the run itself is bounded too: libFuzzer's
    # -max_total_time does not count loading the corpus, and a retry
    # below starts the clock again.
    bounded cargo +nightly fuzz run "${flags[@]}" "$t" "$work" "${seeds[@]}" -- \
      -max_total_time="$run_secs" -rss_limit_mb=1024 -timeout=1 -max_len=65536 \
      -artifact_prefix="artifacts/$t/" -print_final_stats=1 ${RUNS:+-runs=$RUNS} >"$log" 2>&1
    rc=$?
    # libFuzzer's timeout is wall-clock: on a loaded machine a process
    # starved of CPU for a second looks like a slow input. Run the input
    # alone and count its CPU time (user + system, all threads); only 1 s
    # or more of CPU (or any other failure) is a finding.
    art=$(grep -o "artifact_prefix='[^']*'; Test unit written to [^ ]*" "$log" | grep -o '[^ ]*$')
    [ "$rc" -ne 0 ] && grep -q 'ERROR: libFuzzer: timeout' "$log" && [ -f "$art" ] || break
    TIMEFORMAT='%U %S'
    cpu=$( { time "target/x86_64-unknown-linux-gnu/release/$t" -timeout=60 -rss_limit_mb=1024 "$art" >/dev/null 2>&1 || echo failed; } 2>&1 | tail -1)
    echo "fuzz $t: timeout on $art: alone it takes ${cpu} s CPU (user system)"
    case "$cpu" in *failed*) break ;; esac
    awk -v c="$cpu" 'BEGIN { split(c, a, " "); exit !(a[1] + a[2] >= 1) }' && break
    echo "fuzz $t: under 1 s of CPU alone: the machine was loaded, not the input slow; running again"
    mv "$art" "work/$t.spurious-$(basename "$art")"
  done
  if [ "$rc" -eq 124 ] && [ -n "${DEADLINE:-}" ]; then
    echo "fuzz $t: SKIPPED, stopped at DEADLINE before it finished; run fuzz/run.sh $secs $t by hand"
    touch "$marks/skipped.$t"
    return
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+' "$log" | tail -1)
  if [ "$rc" -eq 0 ]; then
    took=$(grep -o 'Done [0-9]* runs in [0-9]* second' "$log" | grep -o '[0-9]* second' | grep -o '[0-9]*')
    rss=$(grep -o 'stat::peak_rss_mb: *[0-9]*' "$log" | grep -o '[0-9]*$')
    slow=$(grep -o 'stat::slowest_unit_time_sec: *[0-9]*' "$log" | grep -o '[0-9]*$')
    echo "fuzz $t: ok, ${runs:-?} runs in ${took:-$run_secs} s, ${cov:-no coverage line}, peak RSS ${rss:-?} MB, slowest input ${slow:-?} s"
  else
    echo "fuzz $t: FAILED (exit $rc), see fuzz/$log; crash input in fuzz/artifacts/$t/"
    grep -E 'panicked|ERROR: libFuzzer|SUMMARY' "$log" | head -5
    touch "$marks/failed.$t"
  fi
}
left_targets=${#targets[@]}
running=0
for t in "${targets[@]}"; do
  if [ "$running" -ge "$jobs" ]; then
    wait -n
    running=$((running - 1))
  fi
  run_secs=$secs
  if [ -n "${DEADLINE:-}" ]; then
    # The targets not started yet share the time left, JOBS at once.
    lanes=$((left_targets < jobs ? left_targets : jobs))
    share=$(( (DEADLINE - $(date +%s)) * lanes / left_targets - 3 ))
    [ "$share" -lt "$run_secs" ] && run_secs=$share
  fi
  left_targets=$((left_targets - 1))
  if [ "$run_secs" -lt 5 ]; then
    echo "fuzz $t: SKIPPED, the time budget is spent (DEADLINE); run fuzz/run.sh $secs $t by hand"
    touch "$marks/skipped.$t"
    continue
  fi
  one "$t" "$run_secs" >"$marks/out.$t" 2>&1 &
  running=$((running + 1))
done
wait
failed=()
skipped=()
for t in "${targets[@]}"; do
  [ -f "$marks/out.$t" ] && cat "$marks/out.$t"
  [ -f "$marks/failed.$t" ] && failed+=("$t")
  [ -f "$marks/skipped.$t" ] && skipped+=("$t")
done
[ "${#skipped[@]}" -gt 0 ] && echo "fuzz: skipped for time: ${skipped[*]}"
if [ "${#failed[@]}" -gt 0 ]; then
  echo "fuzz: failed: ${failed[*]}"
  exit 1
fi

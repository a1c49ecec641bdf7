#!/usr/bin/env bash
# Coverage-guided fuzzing of tessera's readers of stranger-made bytes, on stable Rust:
# builds the fuzz targets of fuzz/ (libFuzzer through the libfuzzer-sys crate, with the
# coverage instrumentation `cargo fuzz build -s none` asks rustc for), then runs each for a
# bounded time from its seeds (fuzz/corpus/TARGET and fuzz/findings/TARGET), printing its
# executions and coverage. Exits 1 if any target crashed (a panic, an abort, an allocation
# above its ceiling, a timeout), naming and keeping the input under fuzz/artifacts/TARGET/.
#
#   fuzz/ci.sh                      every target, FUZZ_SECONDS (default 17) each
#   FUZZ_SECONDS=300 fuzz/ci.sh part request
#   FUZZ_FINDINGS=0 fuzz/ci.sh      without fuzz/findings as seeds (a known finding not yet
#                                   fixed crashes its target at once)
#   FUZZ_BUILD=shared fuzz/ci.sh    instrument only tessera and the targets, reusing the
#                                   dependencies a `cargo test --release` built (.ci/run)
#   FUZZ_SECONDS=0 fuzz/ci.sh       build only
#
# The build (FUZZ_BUILD=own, the default) instruments every crate, dependencies too (the
# TOML, PNG, EXR and HTTP parsers), in fuzz/target (FUZZ_TARGET_DIR): the build for fuzzing
# at length. FUZZ_BUILD=shared builds in the workspace's target directory with the profile
# the caller's CARGO_PROFILE_RELEASE_* give, so that only tessera, the targets and the
# libFuzzer crate compile: a third of the time, for a fuzzer that sees the dependencies'
# code as a black box (their crashes are still crashes) and learns from tessera's alone.
#
# Needs cargo (stable is enough) and a C++ compiler (libfuzzer-sys compiles libFuzzer);
# as root it installs g++ with apt-get when there is none. New inputs that add coverage go
# to fuzz/runs/TARGET (ignored by git); see fuzz/README.md to keep a finding.
set -euo pipefail
cd "$(dirname "$0")"
started=$(date +%s)
say() { echo "fuzz/ci.sh: $* (at $(($(date +%s) - started)) s)" >&2; }

seconds=${FUZZ_SECONDS:-17}
all=(scene png_recipe exr_header part request result image)
if [ $# -gt 0 ]; then targets=("$@"); else targets=("${all[@]}"); fi
# The largest input of each target (bytes): checks.rs's MAX_LEN.
declare -A max_len=([scene]=65536 [png_recipe]=65536 [exr_header]=65536 [part]=65536 [request]=12288 [result]=65536 [image]=65536)
for t in "${targets[@]}"; do
  [ -n "${max_len[$t]:-}" ] || { echo "fuzz/ci.sh: no target $t (targets: ${all[*]})" >&2; exit 2; }
done

if ! command -v c++ >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    say "installing g++ (libfuzzer-sys compiles libFuzzer's C++)"
    apt-get update -q
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q g++
  else
    echo "fuzz/ci.sh: needs a C++ compiler (c++) to build libFuzzer" >&2
    exit 1
  fi
fi

# What cargo-fuzz passes with `--sanitizer none`: SanitizerCoverage's inline 8-bit edge
# counters, the table of their PCs and comparison tracing, which libFuzzer reads; all stable.
instrument="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing"
# tessera's own code keeps its debug assertions and overflow checks, so that an overflow in
# a size computation is a finding, not a wrapped number; optimised lightly, which halves its
# build and costs executions per second, not coverage.
profile=(--config 'profile.release.package.tessera.debug-assertions=true'
  --config 'profile.release.package.tessera.overflow-checks=true'
  --config 'profile.release.package.tessera.opt-level=1'
  --config 'profile.release.package.tessera.debug="line-tables-only"')
bins=()
for t in "${targets[@]}"; do bins+=(--bin "$t"); done
case "${FUZZ_BUILD:-own}" in
  own)
    # The profile is this script's, whatever a caller set for its own builds.
    for v in $(compgen -e | grep -E '^(CARGO_PROFILE_|CARGO_ENCODED_RUSTFLAGS$|CARGO_BUILD_RUSTFLAGS$)' || true); do
      unset "$v"
    done
    profile+=(--config 'profile.release.lto=false' --config 'profile.release.codegen-units=16'
      --config 'profile.release.opt-level=1' --config 'profile.release.panic="abort"'
      --config 'profile.release.incremental=false'
      --config 'profile.release.debug="line-tables-only"')
    # Every crate instrumented; given with an explicit --target, so build scripts and
    # proc-macros are not.
    export RUSTFLAGS="$instrument"
    export CARGO_TARGET_DIR=${FUZZ_TARGET_DIR:-$PWD/target}
    triple=$(rustc -vV | sed -n 's/^host: //p')
    target=(--target "$triple")
    bin=$CARGO_TARGET_DIR/$triple/release
    # The result target imports what it accepts into a results database.
    features=(--features results)
    ;;
  shared)
    # The same flags and target as the tests' build, so that their dependencies are reused;
    # the instrumentation goes to the workspace's own crates only.
    export FUZZ_RUSTFLAGS="$instrument"
    export RUSTC_WORKSPACE_WRAPPER=$PWD/instrumented-rustc
    target=()
    bin=${CARGO_TARGET_DIR:-$PWD/../target}/release
    # Without the result target's database import (the tests' corpus replay has it).
    features=()
    ;;
  *)
    echo "fuzz/ci.sh: FUZZ_BUILD is own or shared, not ${FUZZ_BUILD}" >&2
    exit 2
    ;;
esac
say "building ${targets[*]} (${FUZZ_BUILD:-own} build, $(rustc --version))"
cargo build --release --locked -p tessera-fuzz "${target[@]}" "${features[@]}" "${profile[@]}" \
  "${bins[@]}"
say "built"
[ "$seconds" = 0 ] && exit 0

failed=()
for t in "${targets[@]}"; do
  runs=runs/$t
  artifacts=artifacts/$t
  mkdir -p "$runs" "$artifacts"
  seeds=(corpus/"$t")
  if [ "${FUZZ_FINDINGS:-1}" != 0 ] && [ -d findings/"$t" ]; then seeds+=(findings/"$t"); fi
  log=$(mktemp)
  say "$t: fuzzing for $seconds s from ${seeds[*]}"
  t0=$(date +%s)
  set +e
  # New inputs go to runs/ (the first directory); the seeds are only read.
  "$bin/$t" "$runs" "${seeds[@]}" \
    -max_total_time="$seconds" -max_len="${max_len[$t]}" -timeout=20 -rss_limit_mb=4096 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" >"$log" 2>&1
  rc=$?
  set -e
  took=$(($(date +%s) - t0))
  runs_done=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  per_sec=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  last=$(grep -E '^#[0-9]+[[:space:]]+(DONE|INITED|NEW|REDUCE|pulse|RELOAD)' "$log" | tail -1 || true)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
  corp=$(sed -n 's/.* corp: \([0-9]*\)\/.*/\1/p' <<<"$last")
  echo "fuzz: $t: ${runs_done:-?} executions in $took s (${per_sec:-?}/s), coverage ${cov:-?} edges, ${ft:-?} features, corpus ${corp:-?} inputs"
  if [ "$rc" != 0 ]; then
    failed+=("$t")
    echo "fuzz: $t FAILED (libFuzzer exit $rc); the end of its log:"
    grep -v -E '^(#[0-9]+|INFO:|WARNING: Failed to find function)' "$log" | tail -40
    for f in $(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log"); do
      [ -f "$f" ] || continue
      echo "fuzz: $t: the input is fuzz/$f ($(stat -c %s "$f") bytes); replay it with"
      echo "  $bin/$t fuzz/$f"
      if [ "$(stat -c %s "$f")" -le 16384 ]; then
        echo "fuzz: $t: the input in base64 (base64 -d > input):"
        base64 -w 100 "$f"
      fi
    done
  fi
  rm -f "$log"
done

if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: ${#failed[@]} of ${#targets[@]} targets failed: ${failed[*]}; see fuzz/README.md" >&2
  exit 1
fi
say "${#targets[@]} targets fuzzed, no crash"

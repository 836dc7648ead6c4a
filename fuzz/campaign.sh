#!/usr/bin/env bash
# Runs fuzz targets one after another, each for SECONDS (default 600) of coverage-guided
# libFuzzer on the stable toolchain, and appends one line per target to LOG (default
# fuzz/campaign.log): executions, coverage, and any crash or slow unit libFuzzer reported.
# Usage: fuzz/campaign.sh [target ...]   (no target: every [[bin]] in fuzz/Cargo.toml)
# Environment: SECONDS_PER_TARGET, LOG. Needs cargo-fuzz (`cargo install cargo-fuzz --locked`).
set -u
cd "$(dirname "$0")"
secs=${SECONDS_PER_TARGET:-600}
log=${LOG:-campaign.log}
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  mapfile -t targets < <(sed -n 's/^name = "\(.*\)"$/\1/p' Cargo.toml | grep -v '^quarry-fuzz$')
fi
for t in "${targets[@]}"; do
  out=$(mktemp)
  start=$(date -u +%FT%TZ)
  nice -n 19 timeout $((secs + 300)) cargo fuzz run --sanitizer none "$t" -- \
    -max_total_time="$secs" -rss_limit_mb=2048 >"$out" 2>&1
  rc=$?
  done_line=$(grep -E '^Done [0-9]+ runs' "$out" | tail -1)
  cov=$(grep -E '^#[0-9]+' "$out" | tail -1 | awk '{print $3, $4}')
  found=$(grep -E 'panicked at|Test unit written' "$out" | head -2 | tr '\n' ' ')
  echo "$t | start $start | exit $rc | $done_line | $cov | $found" >>"$log"
  rm -f "$out"
done

#!/usr/bin/env bash
# README command 1's job (scripts/demo_job.sh) on this build: it must exit 0 and print, for each of
# its three trackings (ground-truth normals, learned normals, the shading's inverse), the final
# error and the RMSE in mm and rad, under 1 mm (they read 0.15-0.72 mm), and the update rate.
#   demo_job_test.sh BUILD_DIR OUT_DIR
set -euo pipefail
build="$1"
out="$2"
rm -rf "$out"
log="$(bash "$(dirname "${BASH_SOURCE[0]}")/../../scripts/demo_job.sh" "$build" "$out" 2>&1)"
grep -v "ETA" <<<"$log"  # the job's report, less its progress lines
fail() {
  echo "FAIL: $1" >&2
  exit 1
}
count() { grep -cE "$1" <<<"$log" || true; }
[[ "$(count '^== tracking from the ground-truth normals$')" == 1 ]] || fail "no ground-truth tracking"
[[ "$(count '^== tracking from the colour images \(learned normals')" == 1 ]] ||
  fail "no learned-normals tracking"
[[ "$(count '^== tracking from the colour images \(no network')" == 1 ]] ||
  fail "no tracking through the shading's inverse"
for what in "final error" "RMSE"; do
  lines="$(grep -E "^$what +[0-9.]+ mm +[0-9.]+ rad$" <<<"$log" || true)"
  [[ "$(wc -l <<<"$lines")" == 3 && -n "$lines" ]] ||
    fail "expected three '$what' lines in mm and rad"
  awk '{ if ($(NF-3) + 0 >= 1.0) exit 1 }' <<<"$lines" || fail "a '$what' of 1 mm or more"
done
[[ "$(count '^per-frame update median [0-9.]+ ms \([0-9.]+ Hz\)')" == 3 ]] ||
  fail "expected three update rates"
echo "PASS: three trackings, their errors and rates printed"

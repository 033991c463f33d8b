#!/usr/bin/env bash
# examples/online_tracking (the libraries' online API, frames rendered in memory) tracks the
# default scene as `patchgraph track --normals shading` tracks its render with the pose noise off:
# the same final error and RMSE, which are under 1 mm and 0.05 rad; a scene it cannot read is an
# error naming the file, exit 1.
#   online_example_test.sh BUILD_DIR OUT_DIR
set -euo pipefail
build="$1"
out="$2"
scene="$(dirname "${BASH_SOURCE[0]}")/../../scenes/default.json"
rm -rf "$out"
mkdir -p "$out"
fail() {
  echo "FAIL: $1" >&2
  exit 1
}
example="$("$build/examples/online_tracking" "$scene")" || fail "online_tracking exited $?"
echo "$example"
"$build/tools/tacsim" render "$scene" --outputs color -q --out "$out/default"
tool="$("$build/tools/patchgraph" track "$out/default" --normals shading --vision-noise 0 \
  --ee-noise 0 -q --out "$out/track")"
echo "$tool"
# "final error 0.008 mm 0.0029 rad; RMSE 0.372 mm 0.0255 rad over 60 frames"
numbers="$(grep -E '^final error [0-9.]+ mm [0-9.]+ rad; RMSE [0-9.]+ mm [0-9.]+ rad over 60 frames$' \
  <<<"$example" | awk '{ print $3, $5, $8, $10 }')"
[[ -n "$numbers" ]] || fail "no final error and RMSE line from the example"
expected="$(grep -E '^(final error|RMSE) +[0-9.]+ mm +[0-9.]+ rad$' <<<"$tool" |
  awk '{ printf "%s %s ", $(NF-3), $(NF-1) }' | sed 's/ $//')"
[[ "$numbers" == "$expected" ]] || fail "the example's '$numbers' is not the tool's '$expected'"
awk '{ if ($1 >= 1.0 || $2 >= 0.05 || $3 >= 1.0 || $4 >= 0.05) exit 1 }' <<<"$numbers" ||
  fail "an error of 1 mm or 0.05 rad or more: $numbers"
[[ "$(grep -cE '^frame +[0-9]+ +contact ' <<<"$example")" == 7 ]] || fail "expected 7 frame lines"
set +e
message="$("$build/examples/online_tracking" "$out/none.json" 2>&1)"
code=$?
set -e
[[ "$code" == 1 ]] || fail "a missing scene exited $code, not 1"
grep -q "^error: .*$out/none.json" <<<"$message" || fail "the error does not name the file: $message"
echo "PASS: the example tracks as the tool does ($numbers) and names a missing scene"

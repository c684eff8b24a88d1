# Shared checks for the program tests, sourced by tests/programs/<prog>/*.sh, which
# tests/run-program-tests.sh runs from their own folder with $BIN and a scratch $TMPDIR set.
set -euo pipefail

fail() { echo "$*"; exit 1; }

# expect_error RC WANT REGEX: the exit status RC is WANT and $TMPDIR/err holds exactly one
# line, matching REGEX (errors are one GNU-style line, program first).
expect_error() {
  [ "$1" -eq "$2" ] || fail "exit $1, expected $2"
  [ "$(wc -l <"$TMPDIR/err")" -eq 1 ] || fail "expected one stderr line, got: $(cat "$TMPDIR/err")"
  grep -q "$3" "$TMPDIR/err" || fail "stderr does not match $3: $(cat "$TMPDIR/err")"
}

# check_help PROG: --help exits 0 with a manual starting "Usage: PROG ", its defaults as written
# (0.97, not 0.96999999999999997); a bad option exits 2
# with one stderr line "PROG: … (see --help)" and nothing on stdout.
check_help() {
  local prog=$1 out rc=0
  out=$("$BIN/$prog" --help) || fail "$prog --help failed"
  grep -q "^Usage: $prog " <<<"$out" || fail "$prog --help: no 'Usage: $prog ' line"
  ! grep -E '\(=-?[0-9]+\.[0-9]{9,}' <<<"$out" || fail "$prog --help: defaults not as written"
  "$BIN/$prog" --no-such-option >"$TMPDIR/out" 2>"$TMPDIR/err" || rc=$?
  expect_error "$rc" 2 "^$prog: .*(see --help)$"
  [ ! -s "$TMPDIR/out" ] || fail "$prog --no-such-option wrote to stdout"
}

# check_version PROG: --version exits 0 with one line "PROG (shapesim) <version>" on stdout.
check_version() {
  local prog=$1 out
  out=$("$BIN/$prog" --version) || fail "$prog --version failed"
  [ "$(wc -l <<<"$out")" -eq 1 ] || fail "$prog --version: expected one line, got: $out"
  grep -q "^$prog (shapesim) ." <<<"$out" || fail "$prog --version: got: $out"
}

# The shipped HDF-N cut, and its catalogues made by the programs under test, in the current
# directory: hdf_sources (sources.jsonl, stamps.fits), hdf_models (+ shapelets.jsonl),
# hdf_morphology (+ morph.json). Each fails the test when a program does.
HDF_DATA=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../share/data/hdfn" && pwd)
HDF_IMAGE=$HDF_DATA/hdfn_f814w_v2.fits
hdf_sources() {
  "$BIN/shapesim-detect" "$HDF_IMAGE" --weight "$HDF_DATA/hdfn_f814w_v2_weight.fits" \
    --zero-point 22.08 --gain 865200 --stamps stamps.fits -q >sources.jsonl || fail "shapesim-detect failed"
}
hdf_models() {
  hdf_sources
  "$BIN/shapesim-decompose" -q -j 2 <sources.jsonl >shapelets.jsonl || fail "shapesim-decompose failed"
}
hdf_morphology() {
  hdf_models
  "$BIN/shapesim-smooth" -q <shapelets.jsonl >morph.json || fail "shapesim-smooth failed"
}

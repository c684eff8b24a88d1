#!/usr/bin/env bash
# --filter: SExtractor's default.conv (shipped in share/data/sextractor) is the built-in
# default, so the output is byte-identical; a malformed or missing filter file is one error
# line naming it, before any output is written.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-detect
data=$(cd ../../../share/data && pwd)
image=$data/hdfn/hdfn_f814w_v2.fits
weight=$data/hdfn/hdfn_f814w_v2_weight.fits

cd "$TMPDIR"
"$BIN/$prog" "$image" --weight "$weight" -q >default.jsonl || fail "default filter run failed"
"$BIN/$prog" "$image" --weight "$weight" -q --filter "$data/sextractor/default.conv" \
  >conv.jsonl || fail "--filter default.conv failed"
[ -s default.jsonl ] || fail "no output"
cmp default.jsonl conv.jsonl || fail "--filter default.conv differs from the default filter"

# bad_filter FILE: exit 1, one line "shapesim-detect: FILE…", nothing written.
bad_filter() {
  local rc=0
  "$BIN/$prog" "$image" --zero-point 22.08 --filter "$1" --stamps stamps.fits \
    >out 2>err || rc=$?
  expect_error "$rc" 1 "^$prog: $1"
  [ ! -s out ] || fail "--filter $1: wrote to stdout"
  [ ! -e stamps.fits ] || fail "--filter $1: left stamps.fits behind"
}
printf 'CONV NORM\n# rows of different lengths\n1 2 1\n2 4\n1 2 1\n' >ragged.conv
bad_filter ragged.conv
printf '1 2 1\n2 4 2\n1 2 1\n' >no-header.conv
bad_filter no-header.conv
printf 'CONV NORM\n1 two 1\n' >not-a-number.conv
bad_filter not-a-number.conv
printf 'CONV NORM\n# no rows\n' >no-rows.conv
bad_filter no-rows.conv
: >empty.conv
bad_filter empty.conv
bad_filter no-such.conv

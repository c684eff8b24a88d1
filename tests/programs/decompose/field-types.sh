#!/usr/bin/env bash
# shapesim-decompose with a record field of the wrong type that the fitting uses (pixel_scale,
# zero_point a string; pixel_scale missing), at -j 2 and -j 1: never a crash or an "internal
# error" — either an input error (exit 1, one line naming the record's line and the field) or
# a warning naming the object, which is skipped (exit 0, the other records written). A null
# zero_point is no zero point: every record written, that one without "mag".
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-decompose

cd "$TMPDIR"
hdf_sources
mv sources.jsonl all.jsonl
head -n 8 all.jsonl >eight.jsonl
[ "$(wc -l <eight.jsonl)" -eq 8 ] || fail "fewer than 8 sources from shapesim-detect"
bad_id=$(sed -n 5p eight.jsonl | grep -o '^{"schema":"[^"]*","id":"[^"]*"' |
  sed 's/.*"id":"//; s/"$//')

# check FIELD VALUE: line 5's FIELD set to the JSON VALUE (empty: removed).
check() {
  local field=$1 value=$2 j rc
  if [ -n "$value" ]; then
    sed "5s/\"$field\":[^,]*,/\"$field\":$value,/" eight.jsonl >edited.jsonl
  else
    sed "5s/\"$field\":[^,]*,//" eight.jsonl >edited.jsonl
  fi
  ! cmp -s eight.jsonl edited.jsonl || fail "no $field in the records"
  for j in 2 1; do
    rc=0
    "$BIN/$prog" -j "$j" <edited.jsonl >out 2>err || rc=$?
    case $rc in
      1) expect_error "$rc" 1 "^shapesim-decompose: -:5: $field: " ;;
      0) grep -q "^shapesim-decompose: warning: object $bad_id .*$field" err ||
           fail "$field, -j $j: exit 0 without a warning naming object $bad_id: $(cat err)"
         [ "$(wc -l <out)" -eq 7 ] || fail "$field, -j $j: $(wc -l <out) records, expected 7" ;;
      *) fail "$field, -j $j: exit $rc (crash): $(head -3 err)" ;;
    esac
    ! grep -q -i 'internal error\|terminate' err || fail "$field, -j $j: $(head -3 err)"
  done
}
check pixel_scale '"0.04"'
check pixel_scale ''
check zero_point '"22.08"'

sed '5s/"zero_point":[^,]*,/"zero_point":null,/' eight.jsonl >null.jsonl
grep -q '"zero_point":null' null.jsonl || fail "no zero_point in the records"
"$BIN/$prog" -q -j 2 <null.jsonl >out || fail "zero_point null: the run failed"
[ "$(wc -l <out)" -eq 8 ] || fail "zero_point null: $(wc -l <out) records, expected 8"
! sed -n 5p out | grep -q '"mag":' || fail "zero_point null: the record has a mag"
sed -n 4p out | grep -q '"mag":' || fail "the records with a zero point have no mag"

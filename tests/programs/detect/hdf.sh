#!/usr/bin/env bash
# shapesim-detect on the shipped HDF-N cut with every output: exit 0, galaxies on stdout as
# shapesim.source/1 lines (250–330 of them; SExtractor finds 293 with the same settings),
# stars (--star-threshold 0.6, so there are some) in --stars, and in --stamps exactly the
# three HDUs <id>.image, <id>.weight, <id>.mask of every galaxy and star record.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-detect
data=$(cd ../../../share/data/hdfn && pwd)

# check_jsonl FILE SCHEMA: every line a JSON object of SCHEMA (parsed with jq or python3 when
# installed; otherwise only its shape is checked).
check_jsonl() {
  local file=$1 schema=$2
  if command -v jq >/dev/null; then
    jq -e -s --arg s "$schema" 'all(type == "object" and .schema == $s)' "$file" >/dev/null ||
      fail "$file: not all lines are JSON objects with schema $schema"
  elif command -v python3 >/dev/null; then
    python3 -c 'import json, sys
for n, line in enumerate(open(sys.argv[1]), 1):
    r = json.loads(line)
    assert isinstance(r, dict) and r.get("schema") == sys.argv[2], f"line {n}"' \
      "$file" "$schema" || fail "$file: not all lines are JSON objects with schema $schema"
  fi
  ! grep -v -q "^{\"schema\":\"$schema\",.*}\$" "$file" ||
    fail "$file: a line is not {\"schema\":\"$schema\",…}: $(grep -v -m1 "^{\"schema\":\"$schema\"" "$file")"
}
# field FILE NAME: the string values of NAME, one per line.
field() { grep -o "\"$2\":\"[^\"]*\"" "$1" | sed "s/^\"$2\":\"\(.*\)\"\$/\1/"; }
# extnames FITS: the EXTNAME of every HDU (headers are ASCII cards).
extnames() { LC_ALL=C grep -a -o "EXTNAME = '[^']*'" "$1" | sed "s/^EXTNAME = '\(.*\)'\$/\1/; s/ *\$//"; }
is_fits() {
  [ "$(head -c 30 "$1")" = "SIMPLE  =                    T" ] || fail "$1: not a FITS file"
  [ $(( $(wc -c <"$1") % 2880 )) -eq 0 ] || fail "$1: size is not a multiple of 2880 bytes"
}

cd "$TMPDIR"
rc=0
"$BIN/$prog" "$data/hdfn_f814w_v2.fits" --weight "$data/hdfn_f814w_v2_weight.fits" \
  --zero-point 22.08 --stamps stamps.fits --stars stars.jsonl --segmentation seg.fits \
  >galaxies.jsonl 2>err || rc=$?
[ "$rc" -eq 0 ] || fail "exit $rc: $(cat err)"
n=$(wc -l <galaxies.jsonl)
[ "$n" -ge 250 ] && [ "$n" -le 330 ] || fail "$n galaxies, expected 250–330"
check_jsonl galaxies.jsonl shapesim.source/1
[ -f stars.jsonl ] || fail "--stars file missing"
[ ! -s stars.jsonl ] || check_jsonl stars.jsonl shapesim.source/1
[ "$(field galaxies.jsonl id | sort | uniq -d)" = "" ] || fail "duplicate ids"
[ "$(field galaxies.jsonl stamp_file | sort -u)" = stamps.fits ] || fail "stamp_file is not stamps.fits"
is_fits stamps.fits
is_fits seg.fits
[ "$(extnames seg.fits)" = SEGMENTATION ] || fail "seg.fits: HDUs $(extnames seg.fits | tr '\n' ' ')"

# expect_stamps RECORDS...: stamps.fits holds exactly the three planes of every record.
expect_stamps() {
  cat "$@" | field /dev/stdin stamp_hdu | sed 's/.*/&.image\n&.weight\n&.mask/' | sort >want
  [ "$(wc -l <want)" -eq $(( 3 * $(cat "$@" | wc -l) )) ] || fail "a record has no stamp_hdu"
  extnames stamps.fits | sort >got
  diff want got >/dev/null || fail "stamps.fits HDUs differ from the records': $(diff want got | head -5)"
}
expect_stamps galaxies.jsonl stars.jsonl

# With stars: they leave stdout for --stars and keep their stamps.
"$BIN/$prog" "$data/hdfn_f814w_v2.fits" --weight "$data/hdfn_f814w_v2_weight.fits" -q \
  --zero-point 22.08 --star-threshold 0.6 --stamps stamps.fits --stars stars.jsonl \
  >galaxies2.jsonl || fail "--star-threshold 0.6 run failed"
s=$(wc -l <stars.jsonl)
[ "$s" -gt 0 ] || fail "no stars at --star-threshold 0.6"
check_jsonl stars.jsonl shapesim.source/1
[ $(( $(wc -l <galaxies2.jsonl) + s )) -eq "$n" ] ||
  fail "galaxies + stars = $(wc -l <galaxies2.jsonl) + $s, expected $n objects"
! grep -q '"kind":"galaxy"' stars.jsonl || fail "a galaxy in --stars"
expect_stamps galaxies2.jsonl stars.jsonl

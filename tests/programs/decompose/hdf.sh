#!/usr/bin/env bash
# shapesim-decompose on the shipped HDF-N cut, after shapesim-detect: exit 0 and no warning;
# one shapesim.shapelet/1 record per source line (same ids, same order), each with n_max ≤ 15,
# a numeric chi2r and exactly one of the flags converged / not_converged (most converged);
# --models holds <id>.data, <id>.model, <id>.residual for every record, in that order, and
# with --ids only the HDUs of those ids.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-decompose
data=$(cd ../../../share/data/hdfn && pwd)

# ids FILE: the id of every line (records start {"schema":…,"id":…}).
ids() { grep -o '^{"schema":"[^"]*","id":"[^"]*"' "$1" | sed 's/.*"id":"\(.*\)"$/\1/'; }
# extnames FITS: the EXTNAME of every HDU (headers are ASCII cards).
extnames() {
  LC_ALL=C grep -a -o "EXTNAME = '[^']*'" "$1" | sed "s/^EXTNAME = '\(.*\)'\$/\1/; s/ *\$//"
}
is_fits() {
  [ "$(head -c 30 "$1")" = "SIMPLE  =                    T" ] || fail "$1: not a FITS file"
  [ $(( $(wc -c <"$1") % 2880 )) -eq 0 ] || fail "$1: size is not a multiple of 2880 bytes"
}
# expect_models FITS IDS_FILE: FITS holds exactly <id>.data/.model/.residual per id, in order.
expect_models() {
  is_fits "$1"
  sed 's/.*/&.data\n&.model\n&.residual/' "$2" >want
  extnames "$1" >got
  diff want got >/dev/null || fail "$1: HDUs differ from the records': $(diff want got | head -5)"
}

cd "$TMPDIR"
"$BIN/shapesim-detect" "$data/hdfn_f814w_v2.fits" --weight "$data/hdfn_f814w_v2_weight.fits" \
  --zero-point 22.08 --stamps stamps.fits -q >sources.jsonl || fail "shapesim-detect failed"
n=$(wc -l <sources.jsonl)
[ "$n" -ge 250 ] || fail "only $n sources from shapesim-detect"

rc=0
"$BIN/$prog" -j 2 --models models.fits <sources.jsonl >shapelets.jsonl 2>err || rc=$?
[ "$rc" -eq 0 ] || fail "exit $rc: $(cat err)"
! grep -q warning err || fail "warnings on the HDF: $(grep -m3 warning err)"
[ "$(wc -l <shapelets.jsonl)" -eq "$n" ] || fail "$(wc -l <shapelets.jsonl) records for $n sources"
ids sources.jsonl >source_ids
ids shapelets.jsonl >shapelet_ids
[ "$(wc -l <shapelet_ids)" -eq "$n" ] || fail "a record does not start with schema and id"
diff source_ids shapelet_ids >/dev/null ||
  fail "ids or their order differ from the sources': $(diff source_ids shapelet_ids | head -5)"

# Every record: the schema, n_max ≤ 15, chi2r a number, one of converged / not_converged.
! grep -v -q '^{"schema":"shapesim\.shapelet/1",.*}$' shapelets.jsonl ||
  fail "a line is not {\"schema\":\"shapesim.shapelet/1\",…}"
[ "$(grep -c '"n_max":[0-9][0-9]*[,}]' shapelets.jsonl)" -eq "$n" ] ||
  fail "a record has no integer n_max"
bad=$(grep -o '"n_max":[0-9]*' shapelets.jsonl | cut -d: -f2 | awk '$1 > 15' | head -1)
[ -z "$bad" ] || fail "n_max $bad > 15"
[ "$(grep -c '"chi2r":-\?[0-9]' shapelets.jsonl)" -eq "$n" ] || fail "a record has no numeric chi2r"
[ "$(grep -c '"flags":\[[^]]*"\(not_\)\?converged"' shapelets.jsonl)" -eq "$n" ] ||
  fail "a record has neither converged nor not_converged in its flags"
converged=$(grep -c '"flags":\[[^]]*"converged"' shapelets.jsonl || true)
[ $(( 2 * converged )) -gt "$n" ] || fail "only $converged of $n converged"
if command -v jq >/dev/null; then
  jq -e -s --arg n "$n" '
    length == ($n | tonumber) and
    all(.[]; type == "object" and .schema == "shapesim.shapelet/1" and (.id | type) == "string"
        and (.n_max | type) == "number" and .n_max == (.n_max | floor)
        and .n_max >= 0 and .n_max <= 15
        and (.chi2r | type) == "number" and .chi2r >= 0
        and ([.flags[] | select(. == "converged" or . == "not_converged")] | length) == 1
        and (.coeffs | type) == "array")' shapelets.jsonl >/dev/null ||
    fail "jq: a record breaks the schema checks"
elif command -v python3 >/dev/null; then
  python3 -c 'import json, sys
for n, line in enumerate(open(sys.argv[1]), 1):
    r = json.loads(line)
    assert r["schema"] == "shapesim.shapelet/1" and isinstance(r["id"], str), f"line {n}"
    assert isinstance(r["n_max"], int) and 0 <= r["n_max"] <= 15, f"line {n}: n_max"
    assert isinstance(r["chi2r"], (int, float)) and r["chi2r"] >= 0, f"line {n}: chi2r"
    assert sum(f in ("converged", "not_converged") for f in r["flags"]) == 1, f"line {n}: flags"' \
    shapelets.jsonl || fail "python3: a record breaks the schema checks"
fi
expect_models models.fits shapelet_ids

# --ids: only those objects' images (every record is still written).
head -n 10 sources.jsonl >ten.jsonl
[ "$(ids ten.jsonl | grep -c '^[12]$')" -eq 2 ] ||
  fail "ids 1 and 2 are not among the first sources"
"$BIN/$prog" -q --ids 1,2 --models some.fits <ten.jsonl >ten_shapelets.jsonl ||
  fail "--ids 1,2 run failed"
[ "$(wc -l <ten_shapelets.jsonl)" -eq 10 ] ||
  fail "--ids: $(wc -l <ten_shapelets.jsonl) records, expected 10"
head -n 10 shapelets.jsonl | cmp -s - ten_shapelets.jsonl ||
  fail "--ids: the records differ from the full run's"
ids ten.jsonl | grep '^[12]$' >wanted_ids
expect_models some.fits wanted_ids

# --stars: a bright star put 3 px from object 1 flags it "bright_star"; objects far from it
# are not flagged, and without --stars nothing is.
! grep -q '"bright_star"' ten_shapelets.jsonl || fail "bright_star without --stars"
python3 -c 'import json, sys
r = json.loads(open(sys.argv[1]).readline())
assert r["id"] == "1", r["id"]
star = {"schema": "shapesim.source/1", "id": "s1", "x": r["x"] + 3.0, "y": r["y"],
        "flux": 1e6, "a": 2.0, "b": 2.0, "kron_radius": 3.5, "flags": [], "kind": "star"}
print(json.dumps(star))' ten.jsonl >star.jsonl || fail "could not write the star record"
"$BIN/$prog" -q --stars star.jsonl <ten.jsonl >starred.jsonl || fail "--stars run failed"
grep '^{"schema":"shapesim.shapelet/1","id":"1"' starred.jsonl | grep '"bright_star"' >/dev/null ||
  fail "--stars: object 1, 3 px from a bright star, is not flagged bright_star"
flagged=$(grep -c '"bright_star"' starred.jsonl || true)
[ "$flagged" -lt 10 ] || fail "--stars: all $flagged objects flagged"
rc=0
"$BIN/$prog" -q --stars missing.jsonl <ten.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 '^shapesim-decompose: missing\.jsonl: cannot open'

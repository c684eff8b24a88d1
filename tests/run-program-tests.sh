#!/usr/bin/env bash
# Run program test scripts: each gets $BIN and a private scratch $TMPDIR; exit 77 = skipped.
set -uo pipefail
pass=0 fail=0 skip=0 failed=()
for t in "$@"; do
  scratch=$(mktemp -d)
  (cd "$(dirname "$t")" && TMPDIR="$scratch" bash "$(basename "$t")") >"$scratch.log" 2>&1
  rc=$?
  case $rc in
    0) pass=$((pass + 1)) ;;
    77) skip=$((skip + 1)); echo "SKIP $t" ;;
    *) fail=$((fail + 1)); failed+=("$t"); echo "FAIL $t (exit $rc)"; sed 's/^/    /' "$scratch.log" | tail -n 20 ;;
  esac
  rm -rf "$scratch" "$scratch.log"
done
echo "program tests: $pass passed, $fail failed, $skip skipped"
[ "$fail" -eq 0 ]

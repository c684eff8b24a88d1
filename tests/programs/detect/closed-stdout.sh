#!/usr/bin/env bash
# Output that cannot be written (stdout closed) is a failure: exit 1 and one clear stderr line,
# never a silent exit 0 (app::run_main checks stdout after the program's work).
set -euo pipefail
prog=shapesim-detect

rc=0
"$BIN/$prog" --help >&- 2>"$TMPDIR/err" || rc=$?
[ "$rc" -eq 1 ] || { echo "exit $rc, expected 1"; exit 1; }
lines=$(wc -l <"$TMPDIR/err")
[ "$lines" -eq 1 ] || { echo "expected one stderr line:"; cat "$TMPDIR/err"; exit 1; }
grep -q "^$prog: -: write failed: " "$TMPDIR/err"

#!/usr/bin/env bash
# shapesim-measure --help: exit 0 and a manual naming the program; a bad option: exit 2, one line
# on stderr ("program: … (see --help)"), nothing on stdout.
set -euo pipefail
prog=shapesim-measure

out=$("$BIN/$prog" --help)
grep -q "^Usage: $prog " <<<"$out"

rc=0
"$BIN/$prog" --no-such-option >"$TMPDIR/out" 2>"$TMPDIR/err" || rc=$?
[ "$rc" -eq 2 ] || { echo "exit $rc, expected 2"; exit 1; }
lines=$(wc -l <"$TMPDIR/err")
[ "$lines" -eq 1 ] || { echo "expected one stderr line:"; cat "$TMPDIR/err"; exit 1; }
grep -q "^$prog: .*(see --help)$" "$TMPDIR/err"
[ ! -s "$TMPDIR/out" ]

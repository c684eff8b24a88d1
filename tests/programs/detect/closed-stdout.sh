#!/usr/bin/env bash
# Output that cannot be written (stdout closed) is a failure: exit 1 and one clear stderr line,
# never a silent exit 0 (app::run_main checks stdout after the program's work).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-detect

rc=0
"$BIN/$prog" --help >&- 2>"$TMPDIR/err" || rc=$?
expect_error "$rc" 1 "^$prog: -: write failed: "

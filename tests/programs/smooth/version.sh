#!/usr/bin/env bash
# shapesim-smooth --version: exit 0, one line "shapesim-smooth (shapesim) <version>" on stdout.
set -euo pipefail
prog=shapesim-smooth

out=$("$BIN/$prog" --version)
[ "$(wc -l <<<"$out")" -eq 1 ]
grep -q "^$prog (shapesim) ." <<<"$out"

#!/usr/bin/env bash
# shapesim-sample --version: exit 0, one line "shapesim-sample (shapesim) <version>" on stdout.
set -euo pipefail
prog=shapesim-sample

out=$("$BIN/$prog" --version)
[ "$(wc -l <<<"$out")" -eq 1 ]
grep -q "^$prog (shapesim) ." <<<"$out"

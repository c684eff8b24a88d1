#!/usr/bin/env bash
# shapesim-detect --version: exit 0, one line "shapesim-detect (shapesim) <version>" on stdout.
set -euo pipefail
prog=shapesim-detect

out=$("$BIN/$prog" --version)
[ "$(wc -l <<<"$out")" -eq 1 ]
grep -q "^$prog (shapesim) ." <<<"$out"

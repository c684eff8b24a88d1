#!/usr/bin/env bash
# shapesim-measure --version: exit 0, one line "shapesim-measure (shapesim) <version>" on stdout.
set -euo pipefail
prog=shapesim-measure

out=$("$BIN/$prog" --version)
[ "$(wc -l <<<"$out")" -eq 1 ]
grep -q "^$prog (shapesim) ." <<<"$out"
